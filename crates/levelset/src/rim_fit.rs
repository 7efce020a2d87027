//! Gap patches continued from the data around them.
//!
//! Fairing spans a hole in a scan by the smoothest patch that meets the
//! rim with its slope; minimising the bending energy prefers flat, so the
//! patch sags under a curved surface (a sphere's missing cap, a torus's
//! tube). Here each faired vertex goes onto a quadric fitted to the oriented
//! data around it, with a kernel as wide as the vertex is far from the data:
//! positions and normals of the rim together fix the curvature the patch
//! continues (a Hermite fit; a sphere's cap comes back exactly). Where no
//! one quadric fits the rim (two parts meeting, a sharp crease) the vertex
//! keeps its faired place.

use rayon::prelude::*;
use surfrecon_geom::linalg::solve;
use surfrecon_geom::normals::plane_normal;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::DVec3;

/// The kernel reaches this many widths; beyond, weights are below e⁻⁹.
const KERNEL_REACH: f64 = 3.0;

/// Fewer data than this in the kernel leave the vertex where it is (a
/// quadric has 10 coefficients).
const MIN_DATA: usize = 12;

/// A fit takes every datum within this many kernel widths (weights above
/// e^−2.25 ≈ 0.1) and at most about [`MAX_OUTER_DATA`] of those beyond,
/// evenly thinned and weighted up: a kernel over a wide gap of a dense scan
/// holds tens of thousands of data whose low weights fix ten coefficients
/// no better.
const CORE_WIDTHS: f64 = 1.5;
const MAX_OUTER_DATA: usize = 1024;

/// Re-fits around the moved vertex, and Newton steps onto each fit.
const FITS: usize = 3;
const NEWTON_STEPS: usize = 5;

/// A fit is trusted when the data lie within this share of the kernel
/// width of its zero set (weighted RMS) ...
const MAX_RESIDUAL: f64 = 0.25;
/// ... and its gradient turns from their normals by a weighted mean
/// 1 − cos of at most this (about 34°).
const MAX_NORMAL_DEVIATION: f64 = 0.17;

/// The quadric's ten monomials at `q` and their gradients.
fn monomials(q: DVec3) -> ([f64; 10], [[f64; 10]; 3]) {
    let (x, y, z) = (q.x, q.y, q.z);
    let value = [1.0, x, y, z, x * x, y * y, z * z, x * y, y * z, z * x];
    let gradient = [
        [0.0, 1.0, 0.0, 0.0, 2.0 * x, 0.0, 0.0, y, 0.0, z],
        [0.0, 0.0, 1.0, 0.0, 0.0, 2.0 * y, 0.0, x, z, 0.0],
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0 * z, 0.0, y, x],
    ];
    (value, gradient)
}

/// An implicit quadric around `centre`, in coordinates scaled by `width`.
struct Quadric {
    centre: DVec3,
    width: f64,
    coefficients: [f64; 10],
}

impl Quadric {
    /// Value and world-space gradient at `p`.
    fn at(&self, p: DVec3) -> (f64, DVec3) {
        let (value, gradient) = monomials((p - self.centre) / self.width);
        let dot = |row: &[f64; 10]| row.iter().zip(&self.coefficients).map(|(a, c)| a * c).sum();
        let g = DVec3::new(dot(&gradient[0]), dot(&gradient[1]), dot(&gradient[2]));
        (dot(&value), g / self.width)
    }

    /// Weighted least squares for value 0 and gradient `n` at every datum
    /// within reach, `n` turned to the side of `facing` (the mesh's normal:
    /// given and estimated normals alike may point either way locally).
    fn fit(data: &RimData, centre: DVec3, width: f64, facing: DVec3) -> Option<Self> {
        let near = data.tree.within(centre, KERNEL_REACH * width);
        if near.len() < MIN_DATA {
            return None;
        }
        let mut ata = [[0.0; 10]; 10];
        let mut atb = [0.0; 10];
        // The data in the kernel's core all count; of those beyond, every
        // `stride`-th in the tree's order (spatially even), weighted up by
        // `stride` (the sums keep their expected values).
        let core = CORE_WIDTHS * width;
        let outer = near.iter().filter(|n| n.distance > core).count();
        let stride = outer.div_ceil(MAX_OUTER_DATA).max(1);
        let mut rows = Vec::with_capacity(near.len() - outer + outer.div_ceil(stride));
        let mut outer_seen = 0;
        for n in &near {
            let scale = if n.distance > core {
                outer_seen += 1;
                if (outer_seen - 1) % stride != 0 {
                    continue;
                }
                stride as f64
            } else {
                1.0
            };
            let q = (data.points[n.index] - centre) / width;
            let w = (-q.length_squared()).exp() * scale;
            let normal = data.normals[n.index];
            let normal = if normal.dot(facing) < 0.0 {
                -normal
            } else {
                normal
            };
            let (value, gradient) = monomials(q);
            accumulate(&mut ata, &mut atb, &value, &ALL, 0.0, w);
            for (axis, row) in gradient.iter().enumerate() {
                accumulate(
                    &mut ata,
                    &mut atb,
                    row,
                    &GRADIENT_NONZERO[axis],
                    normal[axis],
                    w,
                );
            }
            rows.push((q, normal, w));
        }
        let coefficients = solve(ata, atb, 10, 1e-12)?;
        let quadric = Quadric {
            centre,
            width,
            coefficients,
        };
        quadric.fits(&rows).then_some(quadric)
    }

    /// Whether the data `(q, normal, weight)` lie on the zero set with the
    /// gradient along their normals (see [`MAX_RESIDUAL`]).
    fn fits(&self, rows: &[(DVec3, DVec3, f64)]) -> bool {
        let (mut off, mut turn, mut total) = (0.0, 0.0, 0.0);
        for &(q, normal, w) in rows {
            let (value, gradient) = self.at(self.centre + q * self.width);
            let length = gradient.length() * self.width;
            if length == 0.0 {
                return false;
            }
            off += w * (value / length).powi(2);
            turn += w * (1.0 - gradient.normalize().dot(normal));
            total += w;
        }
        (off / total).sqrt() <= MAX_RESIDUAL && turn / total <= MAX_NORMAL_DEVIATION
    }

    /// Newton steps from `p` onto the zero set.
    fn project(&self, mut p: DVec3) -> DVec3 {
        for _ in 0..NEWTON_STEPS {
            let (value, gradient) = self.at(p);
            let g2 = gradient.length_squared();
            if g2 == 0.0 {
                break;
            }
            p -= gradient * (value / g2);
        }
        p
    }
}

/// Every monomial, and per axis the monomials whose derivative along it
/// is not identically zero (see [`monomials`]).
const ALL: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9];
const GRADIENT_NONZERO: [[usize; 4]; 3] = [[1, 4, 7, 9], [2, 5, 7, 8], [3, 6, 8, 9]];

/// Add `w`·(row, target) to the normal equations, over the entries
/// `nonzero` of `row` (the others are zero). A zero entry among them adds
/// a product ±0, which leaves every sum as it is (the sums start at +0
/// and never come to −0), so skipping the known zeros instead of testing
/// each entry gives the same sums, bit for bit, with straight loops.
fn accumulate<const N: usize>(
    ata: &mut [[f64; 10]; 10],
    atb: &mut [f64; 10],
    row: &[f64; 10],
    nonzero: &[usize; N],
    target: f64,
    w: f64,
) {
    for &i in nonzero {
        let wi = w * row[i];
        for &j in nonzero {
            ata[i][j] += wi * row[j];
        }
        atb[i] += wi * target;
    }
}

/// Unit normals (either sign) of the `points` a fit around the vertices
/// `which` marks can reach, by plane fits to their `k` nearest points;
/// zero elsewhere. Estimating every point's would cost more than the fits
/// when a dense scan has one small hole.
pub fn normals_near(
    vertices: &[DVec3],
    which: &[bool],
    points: &[DVec3],
    tree: &KdTree,
    min_width: f64,
    k: usize,
) -> Vec<DVec3> {
    let mut needed = vec![false; points.len()];
    for (v, _) in vertices.iter().zip(which).filter(|(_, &w)| w) {
        let width = tree.nearest(*v).map_or(0.0, |n| n.distance).max(min_width);
        // A fit reaches its kernel's reach from a centre moved up to a width.
        for n in tree.within(*v, (KERNEL_REACH + 1.0) * width) {
            needed[n.index] = true;
        }
    }
    (0..points.len())
        .into_par_iter()
        .map(|i| {
            if !needed[i] {
                return DVec3::ZERO;
            }
            let near: Vec<DVec3> = tree
                .knn(points[i], k)
                .iter()
                .map(|n| points[n.index])
                .collect();
            plane_normal(&near)
        })
        .collect()
}

/// The data a gap patch is continued from: points with unit normals (either
/// sign) and their index.
pub struct RimData<'a> {
    pub points: &'a [DVec3],
    pub normals: &'a [DVec3],
    pub tree: &'a KdTree,
}

/// Move each vertex `which` marks onto the quadric fitted to `data` around
/// it (module docs), the kernel as wide as the vertex's distance to the
/// data and at least `min_width`; `normals` are the mesh's vertex normals.
/// A vertex moves at most one kernel width. Returns the moved count.
pub fn fit_to_rim(
    vertices: &mut [DVec3],
    normals: &[DVec3],
    which: &[bool],
    data: &RimData,
    min_width: f64,
) -> usize {
    vertices
        .par_iter_mut()
        .zip(normals)
        .zip(which)
        .filter(|(_, &w)| w)
        .map(|((v, &normal), _)| {
            let Some(nearest) = data.tree.nearest(*v) else {
                return 0;
            };
            let width = nearest.distance.max(min_width);
            let start = *v;
            let mut p = start;
            for _ in 0..FITS {
                match Quadric::fit(data, p, width, normal) {
                    Some(quadric) => p = quadric.project(p),
                    None => break,
                }
            }
            let moved = p != start && p.is_finite() && p.distance(start) <= width;
            if moved {
                *v = p;
            }
            usize::from(moved)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::shapes::{icosphere, sample_surface};

    /// Points of a unit sphere with the cap z > `cap` cut away.
    fn sphere_with_hole(cap: f64) -> (Vec<DVec3>, Vec<DVec3>) {
        let sphere = icosphere(DVec3::ZERO, 1.0, 5);
        let points: Vec<DVec3> = sample_surface(&sphere, 20_000, 3)
            .positions
            .into_iter()
            .filter(|p| p.z <= cap)
            .collect();
        let normals = points.iter().map(|p| p.normalize()).collect();
        (points, normals)
    }

    #[test]
    fn a_flat_patch_over_a_spheres_missing_cap_goes_back_onto_the_sphere() {
        let (points, normals) = sphere_with_hole(0.8);
        let tree = KdTree::new(&points);
        let data = RimData {
            points: &points,
            normals: &normals,
            tree: &tree,
        };
        // The flat fill a sagging patch tends to: the cap's chord disk.
        let mut patch: Vec<DVec3> = (0..200)
            .map(|i| {
                let (r, a) = (0.55 * (i as f64 / 200.0).sqrt(), i as f64 * 2.4);
                DVec3::new(r * a.cos(), r * a.sin(), 0.8)
            })
            .collect();
        let (up, all) = (vec![DVec3::Z; patch.len()], vec![true; patch.len()]);
        let moved = fit_to_rim(&mut patch, &up, &all, &data, 0.02);
        assert_eq!(moved, patch.len());
        let worst = patch
            .iter()
            .map(|p| (p.length() - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.01, "fill off the sphere by {worst}");
    }

    #[test]
    fn both_faces_of_a_thin_plate_are_not_one_quadric() {
        // A vertex between the two faces of a plate thinner than the kernel
        // sees data on both with normals of either sign: no quadric has
        // both faces as its zero set with its gradient along them, so the
        // vertex is not pulled onto either.
        let mut points = Vec::new();
        for i in 0..30 {
            for j in 0..30 {
                let (x, y) = (i as f64 * 0.02 - 0.3, j as f64 * 0.02 - 0.3);
                points.extend([DVec3::new(x, y, 0.0), DVec3::new(x, y, 0.1)]);
            }
        }
        let normals: Vec<DVec3> = (0..points.len())
            .map(|i| if i % 2 == 0 { -DVec3::Z } else { DVec3::Z })
            .collect();
        let tree = KdTree::new(&points);
        let data = RimData {
            points: &points,
            normals: &normals,
            tree: &tree,
        };
        let start = DVec3::new(0.01, 0.01, 0.03);
        let mut v = [start];
        fit_to_rim(&mut v, &[DVec3::Z], &[true], &data, 0.1);
        assert_eq!(v[0], start);
    }
}
