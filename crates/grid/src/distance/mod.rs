//! Unsigned distance from every grid node to a mixed data set of points,
//! segments and triangles, with the index of the closest datum.
//!
//! Two stages, both O(N + M) for N nodes and M data:
//!
//! 1. **Exact band** ([`band`]). Every node within `band_cells` cells of a
//!    datum gets the exact distance to that datum (and the datum's nearest
//!    point, its "foot"); a node keeps the smallest. A node whose value
//!    ends up at most the band radius is final: its nearest datum lies
//!    within the band radius, so it was evaluated. When propagating, the
//!    band of points reaches [`NEAR_CELLS`] cells, so that distances to
//!    points are exact there, and that of segments and triangles at least
//!    [`MIN_PROPAGATED_BAND`] cells, which propagation needs as seeds.
//! 2. **Propagation** ([`propagate`]). Cone sweeps plane by plane along
//!    each axis carry the closest data to every other node; near segments and
//!    triangles, rounds of neighbour offers settle the nodes to a local
//!    fixed point. Accuracy (tests, against brute force): exact within
//!    [`NEAR_CELLS`] cells of points, within 0.05 h near segments and
//!    triangles, and within 0.2 h farther out (measured: up to 0.17 h).
//!
//! The hot loops of both stages are also compiled for AVX-512, chosen at
//! run time (see `crate::simd`), with the same results bit for bit. For
//! data of points only, the feet are the points themselves, kept once
//! per datum rather than per node.
//!
//! Values: near the data (and at every node of a point), the exact distance
//! to the node's closest datum; farther from segments and triangles, the
//! distance to the foot passed on to the node, a point of that datum, so
//! never below the true distance. The closest datum is chosen by `f32`
//! squared distances: data whose distances agree to a relative 6e-8 tie,
//! so a value may exceed the true distance by that share of it.
//!
//! Both stages run in parallel over disjoint parts of the grid with fixed
//! tie-breaking (the smaller datum index), so the result is the same for
//! any number of threads.

mod band;
mod cone_sweep;
mod primitives;
mod propagate;
pub(crate) mod rescale;

pub use primitives::{segment_closest, segment_dist2, triangle_closest, triangle_dist2};
pub use propagate::NEAR_CELLS;

use crate::{Field, GridError, GridSpec};
use band::{exact_band, SortedData};
use primitives::dist2;
use rayon::prelude::*;
use surfrecon_geom::{DVec3, Geometry, TriMesh};

/// `closest` entry of nodes that have no datum (empty band, no propagation).
pub const NO_DATUM: u32 = u32::MAX;

/// Smallest exact band (cells) that propagation starts from. Propagation
/// passes on only data that some node already holds, so a datum whose
/// band holds no node, or whose nodes all hold nearer data, is missed by
/// the nodes farther out that it is nearest to. Measured against brute
/// force (600 random small meshes, triangle soups and mixed 2D data
/// each, resolutions 2–23): the largest error beyond the band is 0.43 h
/// from a 0.75-cell band, 0.27 h from 1 cell, 0.09 h from 1.5 and 2
/// cells, 0.07 h from 3 (the default); from a band of 0 some nodes were
/// reached by no datum at all.
pub const MIN_PROPAGATED_BAND: f64 = 2.0;

/// Points, segments and triangles in `D` dimensions. Datum indices (as in
/// [`DistanceField::closest`]) count points first, then segments, then
/// triangles. In 2D a triangle is a filled region (distance 0 inside).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DataSet<const D: usize> {
    pub points: Vec<[f64; D]>,
    pub segments: Vec<[[f64; D]; 2]>,
    pub triangles: Vec<[[f64; D]; 3]>,
}

/// One datum of a [`DataSet`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Datum<const D: usize> {
    Point([f64; D]),
    Segment([[f64; D]; 2]),
    Triangle([[f64; D]; 3]),
}

/// Distances and closest data at the nodes of a grid.
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceField<const D: usize> {
    /// Unsigned distance per node (`INFINITY` where no datum reached); see
    /// the module docs for what it measures far from the data.
    pub field: Field<D>,
    /// Index of the closest datum per node ([`NO_DATUM`] where none).
    pub closest: Vec<u32>,
}

/// Tuning of [`unsigned_distance_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistanceOptions {
    /// Radius, in cells, of the exactly computed band around each datum.
    /// When propagating, the band is at least [`MIN_PROPAGATED_BAND`]
    /// cells wide (and [`NEAR_CELLS`] around points).
    pub band_cells: f64,
    /// Fill the whole grid by closest-datum sweeping. With `false`
    /// (narrow-band mode), nodes within the band get their exact distance
    /// and the others stay at `INFINITY` or, near the band's edge, at the
    /// distance to some datum; either way above the band radius, so
    /// clamping to it gives the exact band.
    pub propagate: bool,
}

impl Default for DistanceOptions {
    fn default() -> Self {
        DistanceOptions {
            band_cells: 3.0,
            propagate: true,
        }
    }
}

impl<const D: usize> DataSet<D> {
    /// Datum index ranges of the points, the segments and the triangles.
    pub fn kind_ranges(&self) -> [std::ops::Range<usize>; 3] {
        let (np, ns) = (self.points.len(), self.segments.len());
        [0..np, np..np + ns, np + ns..self.len()]
    }

    /// Number of data (points + segments + triangles).
    pub fn len(&self) -> usize {
        self.points.len() + self.segments.len() + self.triangles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether every datum is a point (no segments or triangles).
    pub fn only_points(&self) -> bool {
        self.segments.is_empty() && self.triangles.is_empty()
    }

    /// Datum number `i`, or `None` when out of range.
    pub fn datum(&self, i: usize) -> Option<Datum<D>> {
        let (np, ns) = (self.points.len(), self.segments.len());
        if i < np {
            Some(Datum::Point(self.points[i]))
        } else if i < np + ns {
            Some(Datum::Segment(self.segments[i - np]))
        } else {
            self.triangles.get(i - np - ns).map(|&t| Datum::Triangle(t))
        }
    }

    /// Exact distance from `p` to datum `i`. Requires `i < self.len()`.
    #[inline]
    pub fn distance(&self, i: usize, p: &[f64; D]) -> f64 {
        self.distance_squared(i, p).sqrt()
    }

    /// Exact squared distance from `p` to datum `i`. Requires `i < self.len()`.
    #[inline(always)]
    pub fn distance_squared(&self, i: usize, p: &[f64; D]) -> f64 {
        let (np, ns) = (self.points.len(), self.segments.len());
        if i < np {
            dist2(p, &self.points[i])
        } else if i < np + ns {
            let [a, b] = &self.segments[i - np];
            segment_dist2(p, a, b)
        } else {
            let [a, b, c] = &self.triangles[i - np - ns];
            triangle_dist2(p, a, b, c)
        }
    }

    /// The point of datum `i` nearest to `p`. Requires `i < self.len()`.
    #[inline(always)]
    pub fn closest_point(&self, i: usize, p: &[f64; D]) -> [f64; D] {
        let (np, ns) = (self.points.len(), self.segments.len());
        if i < np {
            self.points[i]
        } else if i < np + ns {
            let [a, b] = &self.segments[i - np];
            segment_closest(p, a, b)
        } else {
            let [a, b, c] = &self.triangles[i - np - ns];
            triangle_closest(p, a, b, c)
        }
    }

    /// Bounding box of datum `i`. Requires `i < self.len()`.
    pub fn datum_bounds(&self, i: usize) -> ([f64; D], [f64; D]) {
        let (np, ns) = (self.points.len(), self.segments.len());
        let corners: &[[f64; D]] = if i < np {
            std::slice::from_ref(&self.points[i])
        } else if i < np + ns {
            &self.segments[i - np]
        } else {
            &self.triangles[i - np - ns]
        };
        let mut lo = corners[0];
        let mut hi = corners[0];
        for c in &corners[1..] {
            for a in 0..D {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        (lo, hi)
    }

    /// Bounding box of all data, `None` when empty.
    pub fn bounds(&self) -> Option<([f64; D], [f64; D])> {
        (0..self.len())
            .map(|i| self.datum_bounds(i))
            .reduce(|(lo, hi), (l, h)| {
                (
                    std::array::from_fn(|a| lo[a].min(l[a])),
                    std::array::from_fn(|a| hi[a].max(h[a])),
                )
            })
    }

    /// Refuse empty sets, non-finite coordinates and more data than a `u32`
    /// index can name.
    pub fn validate(&self) -> Result<(), GridError> {
        if self.is_empty() {
            return Err(GridError::InvalidInput(
                "no data to measure distance to".into(),
            ));
        }
        if self.len() >= NO_DATUM as usize {
            return Err(GridError::InvalidInput(format!(
                "{} data exceed the supported {}",
                self.len(),
                NO_DATUM - 1
            )));
        }
        for i in 0..self.len() {
            let (lo, hi) = self.datum_bounds(i);
            if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
                return Err(GridError::InvalidInput(format!(
                    "datum {i} ({:?}) has a non-finite coordinate",
                    self.datum(i).map(kind_name).unwrap_or("?")
                )));
            }
        }
        Ok(())
    }

    /// The data of a geometry: its triangles, the segments of its polylines,
    /// and the vertices used by neither (isolated points). In 2D the z
    /// coordinate is dropped. Refuses out-of-range vertex indices.
    pub fn from_geometry(geometry: &Geometry) -> Result<Self, GridError> {
        let verts = &geometry.points.positions;
        let at = |i: u32, what: &str, k: usize| -> Result<[f64; D], GridError> {
            let v = verts.get(i as usize).ok_or_else(|| {
                GridError::InvalidInput(format!(
                    "{what} {k} refers to vertex {i} but there are only {} vertices",
                    verts.len()
                ))
            })?;
            Ok(project(*v))
        };
        let mut used = vec![false; verts.len()];
        let mut data = DataSet::default();
        for (k, t) in geometry.triangles.iter().enumerate() {
            data.triangles.push([
                at(t[0], "triangle", k)?,
                at(t[1], "triangle", k)?,
                at(t[2], "triangle", k)?,
            ]);
            t.iter().for_each(|&i| used[i as usize] = true);
        }
        for (k, line) in geometry.lines.iter().enumerate() {
            for &i in line {
                at(i, "polyline", k)?;
                used[i as usize] = true;
            }
            for w in line.windows(2) {
                data.segments
                    .push([project(verts[w[0] as usize]), project(verts[w[1] as usize])]);
            }
            if line.len() == 1 {
                data.points.push(project(verts[line[0] as usize]));
            }
        }
        let isolated = verts.iter().zip(&used).filter(|(_, &u)| !u);
        data.points.extend(isolated.map(|(v, _)| project(*v)));
        Ok(data)
    }

    /// The triangles of a mesh (datum index = triangle index).
    pub fn from_mesh(mesh: &TriMesh) -> Result<Self, GridError> {
        let mut data = DataSet::default();
        for (k, t) in mesh.triangles.iter().enumerate() {
            let mut tri = [[0.0; D]; 3];
            for (c, &i) in t.iter().enumerate() {
                let v = mesh.vertices.get(i as usize).ok_or_else(|| {
                    GridError::InvalidInput(format!(
                        "triangle {k} refers to vertex {i} but the mesh has {} vertices",
                        mesh.vertices.len()
                    ))
                })?;
                tri[c] = project(*v);
            }
            data.triangles.push(tri);
        }
        Ok(data)
    }
}

fn kind_name<const D: usize>(d: Datum<D>) -> &'static str {
    match d {
        Datum::Point(_) => "point",
        Datum::Segment(_) => "segment",
        Datum::Triangle(_) => "triangle",
    }
}

/// First `D` coordinates of a 3D vector (zero-padded beyond 3).
fn project<const D: usize>(v: DVec3) -> [f64; D] {
    std::array::from_fn(|a| if a < 3 { v[a] } else { 0.0 })
}

/// Unsigned distance with default options (band of 3 cells, propagated over
/// the whole grid). See [`unsigned_distance_with`].
pub fn unsigned_distance<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
) -> Result<DistanceField<D>, GridError> {
    unsigned_distance_with(data, spec, &DistanceOptions::default())
}

/// Unsigned distance from every node of `spec` to `data`, with the index of
/// the closest datum. Checks the memory need first and
/// refuses invalid data or options.
pub fn unsigned_distance_with<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    options: &DistanceOptions,
) -> Result<DistanceField<D>, GridError> {
    data.validate()?;
    if !(options.band_cells >= 0.0 && options.band_cells.is_finite()) {
        return Err(GridError::InvalidInput(format!(
            "band must be a finite non-negative number of cells, got {}",
            options.band_cells
        )));
    }
    if let Some(s) = rescale::unit_scale(data, spec) {
        let mut scaled = unsigned_distance_with(&data.scaled(s), &spec.scaled(s), options)?;
        scaled.field.spec = *spec;
        scaled.field.values.par_iter_mut().for_each(|v| *v /= s);
        return Ok(scaled);
    }
    // Per node at the peak: the datum and its foot (kept per datum for
    // points only), and the band's distance or the output distance (the
    // output datum reuses the working one).
    let foot_bytes = if data.only_points() { 0 } else { 4 * D };
    spec.check_memory(4 + foot_bytes + 8)?;
    let sorted = SortedData::new(data, spec);
    // Propagation needs seeds around every datum (see
    // `MIN_PROPAGATED_BAND`), and dense point samples hide points between
    // the nodes from it, so the exact band of points reaches over the
    // whole near region.
    let (radius, point_radius) = match options.propagate {
        true => (
            options.band_cells.max(MIN_PROPAGATED_BAND),
            options.band_cells.max(NEAR_CELLS),
        ),
        false => (options.band_cells, options.band_cells),
    };
    let (radius, point_radius) = (radius * spec.spacing, point_radius * spec.spacing);
    let radii = [point_radius, radius, radius];
    let final_radius = data
        .kind_ranges()
        .iter()
        .zip(radii)
        .filter(|(kind, _)| !kind.is_empty())
        .map(|(_, r)| r)
        .fold(f64::INFINITY, f64::min);
    let mut closest = exact_band(&sorted.data, spec, radii);
    if options.propagate {
        let final_below = (final_radius / spec.spacing).powi(2) as f32;
        propagate::propagate_closest(&sorted.data, spec, final_below, &mut closest);
    }
    let data = &sorted.data;
    // Beyond the settled region and the exact band, segments and
    // triangles take the distance to the foot passed on to them
    // (closest-point propagation): the feet sample the data as densely as
    // the band's nodes, and an exact distance to each node's datum would
    // cost as much as all the passes. Within the band it is exact (a
    // 10-cell band used to end at 6 cells, with f32 feet beyond).
    let exact_within = match options.propagate {
        true => ((NEAR_CELLS + 1.0).max(radius / spec.spacing) as f32).powi(2),
        false => f32::INFINITY,
    };
    let values = (0..spec.node_count())
        .into_par_iter()
        .map(|l| match closest.datum[l] {
            NO_DATUM => f64::INFINITY,
            i => {
                let idx = spec.unlinear(l);
                if i as usize >= data.points.len() {
                    let foot = closest.foot(l);
                    if band::cells_dist2(&idx.map(|k| k as f32), &foot) > exact_within {
                        let d2: f64 = (0..D)
                            .map(|a| (idx[a] as f64 - foot[a] as f64).powi(2))
                            .sum();
                        return d2.sqrt() * spec.spacing;
                    }
                }
                data.distance(i as usize, &spec.position(idx))
            }
        })
        .collect();
    let mut datum = closest.datum;
    datum
        .par_iter_mut()
        .filter(|c| **c != NO_DATUM)
        .for_each(|c| *c = sorted.original[*c as usize]);
    Ok(DistanceField {
        field: Field {
            spec: *spec,
            values,
        },
        closest: datum,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use surfrecon_geom::shapes;

    fn rng(seed: u64) -> rand_pcg::Pcg64 {
        rand_pcg::Pcg64::seed_from_u64(seed)
    }

    fn random_point<const D: usize>(r: &mut rand_pcg::Pcg64, lo: f64, hi: f64) -> [f64; D] {
        std::array::from_fn(|_| r.random_range(lo..hi))
    }

    /// Bound on the far-field error, in cells (see `propagate`'s docs).
    const FAR_TOLERANCE: f64 = 0.2;

    /// Grid of `n` cells along each axis over the unit box, 3 cells padding.
    fn unit_grid<const D: usize>(n: usize) -> GridSpec<D> {
        GridSpec::from_bounds([0.0; D], [1.0; D], crate::GridSize::Resolution(n), 3).unwrap()
    }

    /// Max error (in cells) within 5 h of the data and beyond, against brute
    /// force; also checks that every value is the distance to its datum.
    fn errors<const D: usize>(data: &DataSet<D>, df: &DistanceField<D>) -> (f64, f64) {
        let spec = df.field.spec;
        let h = spec.spacing;
        (0..spec.node_count())
            .into_par_iter()
            .map(|l| {
                let p = spec.position(spec.unlinear(l));
                let exact = (0..data.len())
                    .map(|i| data.distance_squared(i, &p))
                    .fold(f64::INFINITY, f64::min)
                    .sqrt();
                let got = df.field.values[l];
                let own = data.distance(df.closest[l] as usize, &p);
                if exact <= 5.0 * h {
                    assert_eq!(got, own, "near, the distance to the closest datum");
                }
                // Far away, the distance to a foot on that datum, rounded.
                let rounding = 1e-4 * h;
                assert!(got >= own - rounding, "at least the distance to its datum");
                assert!(got >= exact - rounding, "never below the true distance");
                let e = (got - exact) / h;
                if exact <= 5.0 * h {
                    (e, 0.0)
                } else {
                    (0.0, e)
                }
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
    }

    fn check<const D: usize>(name: &str, data: &DataSet<D>, spec: &GridSpec<D>) -> (f64, f64) {
        let df = unsigned_distance(data, spec).unwrap();
        let (near, far) = errors(data, &df);
        println!("{name}: max error within 5h {near:.2e} h, far field {far:.2e} h");
        assert!(near <= 0.05, "{name}: near error {near} h");
        assert!(far <= FAR_TOLERANCE, "{name}: far error {far} h");
        (near, far)
    }

    #[test]
    fn random_points_2d_match_brute_force() {
        let mut r = rng(1);
        let data = DataSet::<2> {
            points: (0..300).map(|_| random_point(&mut r, 0.0, 1.0)).collect(),
            ..Default::default()
        };
        let (_, far) = check("2D random points", &data, &unit_grid(160));
        assert!(far <= FAR_TOLERANCE, "far error {far} h");
    }

    #[test]
    fn points_on_grids_with_short_rows_match_brute_force() {
        // Rows along axis 0 shorter than a chunk of the exact band, and
        // about as long as one ball.
        let mut r = rng(5);
        for width in [0.1, 0.4] {
            let points = (0..200)
                .map(|_| {
                    let p: [f64; 3] = random_point(&mut r, 0.0, 1.0);
                    [p[0] * width, p[1], p[2]]
                })
                .collect();
            let data = DataSet::<3> {
                points,
                ..Default::default()
            };
            let spec = GridSpec::from_bounds(
                [0.0; 3],
                [width, 1.0, 1.0],
                crate::GridSize::Resolution(40),
                3,
            )
            .unwrap();
            check(
                &format!("3D points, {} nodes along x", spec.dims[0]),
                &data,
                &spec,
            );
        }
    }

    #[test]
    fn polygon_and_points_2d_match_brute_force() {
        // Structured: a circle polyline, a filled triangle and a few points.
        let n = 64;
        let ring: Vec<[f64; 2]> = (0..n)
            .map(|k| {
                let t = k as f64 / n as f64 * std::f64::consts::TAU;
                [0.5 + 0.35 * t.cos(), 0.5 + 0.35 * t.sin()]
            })
            .collect();
        let data = DataSet::<2> {
            points: vec![[0.5, 0.5], [0.1, 0.9], [0.95, 0.05]],
            segments: (0..n).map(|k| [ring[k], ring[(k + 1) % n]]).collect(),
            triangles: vec![[[0.0, 0.0], [0.2, 0.05], [0.05, 0.25]]],
        };
        check("2D circle + triangle + points", &data, &unit_grid(200));
    }

    #[test]
    fn random_mixed_3d_match_brute_force() {
        let mut r = rng(2);
        let mut data = DataSet::<3> {
            points: (0..150).map(|_| random_point(&mut r, 0.0, 1.0)).collect(),
            ..Default::default()
        };
        for _ in 0..60 {
            let a = random_point(&mut r, 0.0, 1.0);
            let b = std::array::from_fn(|k| a[k] + r.random_range(-0.2..0.2));
            data.segments.push([a, b]);
        }
        for _ in 0..60 {
            let a = random_point(&mut r, 0.0, 1.0);
            let b = std::array::from_fn(|k| a[k] + r.random_range(-0.2..0.2));
            let c = std::array::from_fn(|k| a[k] + r.random_range(-0.2..0.2));
            data.triangles.push([a, b, c]);
        }
        check("3D random points/segments/triangles", &data, &unit_grid(40));
    }

    #[test]
    fn torus_mesh_3d_matches_brute_force() {
        let mesh = shapes::torus(0.3, 0.12, 24, 12);
        let mesh = TriMesh {
            vertices: mesh
                .vertices
                .iter()
                .map(|v| *v + DVec3::splat(0.5))
                .collect(),
            ..mesh
        };
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        check("3D torus triangles", &data, &unit_grid(48));
    }

    #[test]
    fn godunov_sweeping_from_the_band_is_less_accurate() {
        // Same exact band, then either closest-datum propagation or plain
        // Godunov fast sweeping with the band frozen.
        let mesh = shapes::icosphere(DVec3::splat(0.5), 0.35, 2);
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let spec = unit_grid::<3>(32);
        let cpp = unsigned_distance(&data, &spec).unwrap();
        let band_only = DistanceOptions {
            propagate: false,
            ..Default::default()
        };
        let mut godunov = unsigned_distance_with(&data, &spec, &band_only)
            .unwrap()
            .field;
        let radius = band_only.band_cells * spec.spacing;
        let frozen: Vec<bool> = godunov.values.iter().map(|&v| v <= radius).collect();
        crate::sweep::fast_sweep(&mut godunov, &frozen);
        let (mut e_cpp, mut e_god) = (0.0f64, 0.0f64);
        for l in 0..spec.node_count() {
            let p = spec.position(spec.unlinear(l));
            let exact = (0..data.len())
                .map(|i| data.distance(i, &p))
                .fold(f64::INFINITY, f64::min);
            e_cpp = e_cpp.max((cpp.field.values[l] - exact).abs() / spec.spacing);
            e_god = e_god.max((godunov.values[l] - exact).abs() / spec.spacing);
        }
        println!("sphere mesh, max error: closest-datum {e_cpp:.2e} h, Godunov {e_god:.2e} h");
        assert!(e_cpp <= FAR_TOLERANCE && e_god > 5.0 * e_cpp.max(0.01));
    }

    #[test]
    fn closest_index_names_the_nearest_datum_kind() {
        let data = DataSet::<3> {
            points: vec![[0.0, 0.0, 0.0]],
            segments: vec![[[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]],
            triangles: vec![[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]],
        };
        let spec = unit_grid::<3>(10);
        let df = unsigned_distance(&data, &spec).unwrap();
        let at = |p: [f64; 3]| {
            let g = spec.to_grid(p).map(|x| x.round() as usize);
            df.closest[spec.linear(g)]
        };
        assert_eq!(at([0.0, 0.0, 0.1]), 0);
        assert_eq!(at([1.0, 0.5, 0.1]), 1);
        assert_eq!(at([0.2, 0.2, 0.9]), 2);
        assert!(matches!(data.datum(1), Some(Datum::Segment(_))));
        assert_eq!(data.datum(3), None);
    }

    #[test]
    fn same_result_for_any_thread_count() {
        let mut r = rng(3);
        let data = DataSet::<3> {
            points: (0..500).map(|_| random_point(&mut r, 0.0, 1.0)).collect(),
            ..Default::default()
        };
        let spec = unit_grid::<3>(30);
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| unsigned_distance(&data, &spec).unwrap())
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn same_result_with_any_vector_instructions() {
        let mut r = rng(4);
        let mut data = DataSet::<3> {
            points: (0..300).map(|_| random_point(&mut r, 0.0, 1.0)).collect(),
            ..Default::default()
        };
        data.segments = (0..20)
            .map(|_| [0; 2].map(|_| random_point(&mut r, 0.2, 0.8)))
            .collect();
        data.triangles = (0..20)
            .map(|_| [0; 3].map(|_| random_point(&mut r, 0.2, 0.8)))
            .collect();
        let spec = unit_grid::<3>(40);
        let widest = unsigned_distance(&data, &spec).unwrap();
        let baseline = crate::simd::with_baseline(|| unsigned_distance(&data, &spec).unwrap());
        assert_eq!(widest, baseline);
    }

    #[test]
    fn narrow_band_is_exact_inside_and_empty_outside() {
        let data = DataSet::<2> {
            segments: vec![[[0.2, 0.5], [0.8, 0.5]]],
            ..Default::default()
        };
        let spec = unit_grid::<2>(50);
        let options = DistanceOptions {
            band_cells: 3.0,
            propagate: false,
        };
        let df = unsigned_distance_with(&data, &spec, &options).unwrap();
        for l in 0..spec.node_count() {
            let exact = data.distance(0, &spec.position(spec.unlinear(l)));
            if exact <= 3.0 * spec.spacing {
                assert_eq!(df.field.values[l], exact);
                assert_eq!(df.closest[l], 0);
            } else if df.closest[l] == NO_DATUM {
                assert_eq!(df.field.values[l], f64::INFINITY);
            } else {
                assert!(df.field.values[l] >= exact && exact > 3.0 * spec.spacing);
            }
        }
    }

    #[test]
    fn triangle_distance_matches_dense_sampling() {
        let mut r = rng(4);
        for _ in 0..200 {
            let [a, b, c, p]: [[f64; 3]; 4] =
                std::array::from_fn(|_| random_point(&mut r, -1.0, 1.0));
            let exact = triangle_dist2(&p, &a, &b, &c).sqrt();
            let n = 200;
            let mut sampled = f64::INFINITY;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let q: [f64; 3] =
                        std::array::from_fn(|k| a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]));
                    sampled = sampled.min(dist2(&p, &q).sqrt());
                }
            }
            assert!(
                exact <= sampled + 1e-12 && sampled - exact < 0.02,
                "{exact} {sampled}"
            );
        }
        // Degenerate triangles and 2D filled triangles.
        let d = triangle_dist2(
            &[0.0, 1.0, 0.0],
            &[0.0; 3],
            &[1.0, 0.0, 0.0],
            &[2.0, 0.0, 0.0],
        );
        assert_eq!(d, 1.0);
        assert!(triangle_dist2(&[0.2, 0.2], &[0.0, 0.0], &[1.0, 0.0], &[0.0, 1.0]) < 1e-30);
        assert_eq!(segment_dist2(&[3.0, 4.0], &[0.0, 0.0], &[0.0, 0.0]), 25.0);
    }

    #[test]
    fn refuses_bad_data() {
        let spec = unit_grid::<2>(8);
        assert!(unsigned_distance(&DataSet::<2>::default(), &spec).is_err());
        let nan = DataSet::<2> {
            points: vec![[0.0, f64::NAN]],
            ..Default::default()
        };
        let msg = unsigned_distance(&nan, &spec).unwrap_err().to_string();
        assert!(
            msg.contains("datum 0") && msg.contains("non-finite"),
            "{msg}"
        );
        let bad_band = DistanceOptions {
            band_cells: -1.0,
            ..Default::default()
        };
        let one = DataSet::<2> {
            points: vec![[0.5, 0.5]],
            ..Default::default()
        };
        assert!(unsigned_distance_with(&one, &spec, &bad_band).is_err());
        let geometry = Geometry {
            triangles: vec![[0, 1, 7]],
            ..Geometry::from_points(surfrecon_geom::PointCloud::new(vec![DVec3::ZERO; 3]))
        };
        let msg = DataSet::<3>::from_geometry(&geometry)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("triangle 0 refers to vertex 7"), "{msg}");
    }

    #[test]
    fn geometry_gives_triangles_segments_and_isolated_points() {
        let v = |x: f64| DVec3::new(x, 0.0, 0.0);
        let geometry = Geometry {
            points: surfrecon_geom::PointCloud::new((0..8).map(|k| v(k as f64)).collect()),
            triangles: vec![[0, 1, 2]],
            lines: vec![vec![3, 4, 5], vec![6]],
        };
        let data = DataSet::<2>::from_geometry(&geometry).unwrap();
        assert_eq!(data.triangles.len(), 1);
        assert_eq!(data.segments.len(), 2);
        assert_eq!(data.points, vec![[6.0, 0.0], [7.0, 0.0]]);
    }
}
