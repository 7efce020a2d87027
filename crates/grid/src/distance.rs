//! Unsigned distance from every grid node to a mixed data set of points,
//! segments and triangles, with the index of the closest datum.
//!
//! Two stages, both O(N + M) for N nodes and M data:
//!
//! 1. **Exact band.** Every node within `band_cells` cells of a datum's
//!    bounding box gets the exact distance to that datum (and the datum's
//!    nearest point, its "foot"); a node keeps the smallest. A node whose
//!    value ends up at most the band radius is final: its nearest datum lies
//!    within the band radius, so it was evaluated. The grid is cut into
//!    fixed slabs along the last axis, data are binned per slab, and slabs
//!    run in parallel; ties go to the smaller datum index, so the result is
//!    the same for any number of threads.
//! 2. **Closest-datum sweeping.** Gauss–Seidel sweeps in the 2^D alternating
//!    orders of fast sweeping (see [`crate::sweep`]), where a node tries the
//!    closest data of its neighbours and keeps the exact distance to the
//!    best one (closest-point propagation). Information travels along the
//!    same characteristics as in Godunov fast sweeping, but the value
//!    carried is an exact distance to a real datum instead of a first-order
//!    approximation, so the field stays near-exact far from the data. It
//!    ends at a fixed point (see [`propagate_closest`]).
//!
//! Why no Godunov value is mixed in: a candidate distance is an upper bound
//! of the true distance and exact whenever the propagated datum is the true
//! nearest one, which fails only where Voronoi cells get thinner than a cell,
//! by little. The first-order Godunov value is off by O(h) and
//! *under*estimates where fronts converge (inside curved data), so keeping
//! `min(Godunov, candidate)` would pull those errors into the field. The
//! test `godunov_sweeping_from_the_band_is_less_accurate` measures both.

use crate::sweep::for_each_node_ordered;
use crate::{Field, GridError, GridSpec};
use rayon::prelude::*;
use surfrecon_geom::{DVec3, Geometry, TriMesh};

/// `closest` entry of nodes that have no datum (empty band, no propagation).
pub const NO_DATUM: u32 = u32::MAX;

/// Layers (along the last axis) per slab of the parallel band stage; fixed,
/// so the work split never depends on the thread count.
const SLAB_LAYERS: usize = 4;

/// Bound on closest-datum sweep rounds (2^D sweeps each); convergence
/// normally takes two.
const MAX_ROUNDS: usize = 64;

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
    /// Unsigned distance per node (`INFINITY` where no datum reached).
    pub field: Field<D>,
    /// Index of the closest datum per node ([`NO_DATUM`] where none).
    pub closest: Vec<u32>,
}

/// Tuning of [`unsigned_distance_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistanceOptions {
    /// Radius, in cells, of the exactly computed band around each datum.
    pub band_cells: f64,
    /// Fill the whole grid by closest-datum sweeping; `false` leaves nodes
    /// outside the band at `INFINITY` (narrow-band mode).
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
    /// Number of data (points + segments + triangles).
    pub fn len(&self) -> usize {
        self.points.len() + self.segments.len() + self.triangles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
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

/// Unsigned distance with default options (band of 2 cells, propagated over
/// the whole grid). See [`unsigned_distance_with`].
pub fn unsigned_distance<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
) -> Result<DistanceField<D>, GridError> {
    unsigned_distance_with(data, spec, &DistanceOptions::default())
}

/// Unsigned distance from every node of `spec` to `data`, with the index of
/// the closest datum. Checks the memory need (12 bytes per node) first and
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
    // Distance, closest datum and its foot point per node.
    spec.check_memory(std::mem::size_of::<(f64, u32, [f64; D])>())?;
    let radius = options.band_cells * spec.spacing;
    let (sorted, original) = spatially_sorted(data, spec);
    let data = &sorted;
    let mut nodes = Nodes::new(spec.node_count());
    exact_band(data, spec, radius, &mut nodes);
    if options.propagate {
        propagate_closest(data, spec, radius, &mut nodes);
    }
    let Nodes {
        mut values,
        mut closest,
        ..
    } = nodes;
    // Exact distance to the chosen datum (the sweeps compared distances to
    // propagated foot points, which are upper bounds).
    values
        .par_iter_mut()
        .zip(closest.par_iter_mut())
        .enumerate()
        .for_each(|(l, (v, c))| {
            if *c != NO_DATUM {
                *v = data.distance(*c as usize, &spec.position(spec.unlinear(l)));
                *c = original[*c as usize];
            }
        });
    Ok(DistanceField {
        field: Field {
            spec: *spec,
            values,
        },
        closest,
    })
}

/// Working state per node during the computation.
struct Nodes<const D: usize> {
    /// Squared distance to the foot point (INFINITY when none yet).
    values: Vec<f64>,
    /// Closest datum known so far.
    closest: Vec<u32>,
    /// Nearest point of that datum to the node where it was found exactly;
    /// propagated with the datum so that trying a neighbour's candidate
    /// costs a point distance, whatever the datum kind, with no lookup.
    feet: Vec<[f64; D]>,
}

impl<const D: usize> Nodes<D> {
    fn new(n: usize) -> Self {
        Nodes {
            values: vec![f64::INFINITY; n],
            closest: vec![NO_DATUM; n],
            feet: vec![[f64::NAN; D]; n],
        }
    }
}

/// A copy of `data` with each kind (points, segments, triangles) ordered by
/// the grid node nearest its bounding-box centre, so data close in space
/// are close in memory (the sweeps look data up by neighbouring nodes; in
/// input order those reads miss the cache). Also returns, per sorted index,
/// the original index.
fn spatially_sorted<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
) -> (DataSet<D>, Vec<u32>) {
    let key = |i: usize| -> usize {
        let (lo, hi) = data.datum_bounds(i);
        let idx = std::array::from_fn(|a| {
            let g = ((lo[a] + hi[a]) * 0.5 - spec.origin[a]) / spec.spacing;
            g.round().clamp(0.0, (spec.dims[a] - 1) as f64) as usize
        });
        spec.linear(idx)
    };
    let (np, ns) = (data.points.len(), data.segments.len());
    let mut original = Vec::with_capacity(data.len());
    for range in [0..np, np..np + ns, np + ns..data.len()] {
        let mut keyed: Vec<(usize, u32)> =
            range.into_par_iter().map(|i| (key(i), i as u32)).collect();
        keyed.par_sort_unstable();
        original.extend(keyed.into_iter().map(|(_, i)| i));
    }
    let sorted = DataSet {
        points: original[..np]
            .iter()
            .map(|&i| data.points[i as usize])
            .collect(),
        segments: original[np..np + ns]
            .iter()
            .map(|&i| data.segments[i as usize - np])
            .collect(),
        triangles: original[np + ns..]
            .iter()
            .map(|&i| data.triangles[i as usize - np - ns])
            .collect(),
    };
    (sorted, original)
}

/// Range of node indices within `radius` of the box `lo..hi`, clamped to
/// the grid; `None` when it misses the grid.
fn node_box<const D: usize>(
    spec: &GridSpec<D>,
    (lo, hi): ([f64; D], [f64; D]),
    radius: f64,
) -> Option<([usize; D], [usize; D])> {
    let mut first = [0usize; D];
    let mut last = [0usize; D];
    for a in 0..D {
        let top = (spec.dims[a] - 1) as f64;
        let f = ((lo[a] - radius - spec.origin[a]) / spec.spacing).ceil();
        let l = ((hi[a] + radius - spec.origin[a]) / spec.spacing).floor();
        if f > top || l < 0.0 || f > l {
            return None;
        }
        first[a] = f.max(0.0) as usize;
        last[a] = l.min(top) as usize;
    }
    Some((first, last))
}

/// Visit every node index in the box `first..=last` (axis 0 fastest).
#[inline(always)]
fn for_each_in_box<const D: usize>(
    first: [usize; D],
    last: [usize; D],
    mut visit: impl FnMut(&[usize; D]),
) {
    let mut idx = first;
    loop {
        visit(&idx);
        let mut a = 0;
        loop {
            if a == D {
                return;
            }
            if idx[a] < last[a] {
                idx[a] += 1;
                break;
            }
            idx[a] = first[a];
            a += 1;
        }
    }
}

/// Stage 1: squared exact distances, closest data and foot points at the
/// nodes within `radius` of each datum's bounding box; parallel over fixed
/// slabs. Ties go to the smaller (sorted) datum index, so the result does
/// not depend on the order data are applied in.
fn exact_band<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    radius: f64,
    nodes: &mut Nodes<D>,
) {
    let last_axis = D - 1;
    let layer = spec.strides()[last_axis];
    let slabs = spec.dims[last_axis].div_ceil(SLAB_LAYERS);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); slabs];
    for i in 0..data.len() {
        if let Some((first, last)) = node_box(spec, data.datum_bounds(i), radius) {
            for bin in &mut bins[first[last_axis] / SLAB_LAYERS..=last[last_axis] / SLAB_LAYERS] {
                bin.push(i as u32);
            }
        }
    }
    let chunk = SLAB_LAYERS * layer;
    nodes
        .values
        .par_chunks_mut(chunk)
        .zip(nodes.closest.par_chunks_mut(chunk))
        .zip(nodes.feet.par_chunks_mut(chunk))
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(s, (((vals, ids), feet), bin))| {
            let slab_first = s * SLAB_LAYERS;
            let slab_last = (slab_first + SLAB_LAYERS).min(spec.dims[last_axis]) - 1;
            for &i in bin {
                let Some((mut first, mut last)) =
                    node_box(spec, data.datum_bounds(i as usize), radius)
                else {
                    continue;
                };
                first[last_axis] = first[last_axis].max(slab_first);
                last[last_axis] = last[last_axis].min(slab_last);
                for_each_in_box(first, last, |idx| {
                    let l = spec.linear(*idx) - slab_first * layer;
                    let p = spec.position(*idx);
                    let foot = data.closest_point(i as usize, &p);
                    let d2 = dist2(&p, &foot);
                    if d2 < vals[l] || (d2 == vals[l] && i < ids[l]) {
                        vals[l] = d2;
                        ids[l] = i;
                        feet[l] = foot;
                    }
                });
            }
        });
}

/// Stage 2: closest-datum fast sweeping; returns the number of sweeps. A node tries the candidates
/// (datum + foot point) of its neighbours, axis and diagonal (diagonals
/// matter: a Voronoi cell can be too thin to hold an axis-connected chain
/// of nodes), and adopts the nearest datum. Sweeps run in the 2^D
/// alternating orders, so a candidate travels in every direction.
///
/// The first round uses only the 2^D - 1 upwind neighbours of each order
/// (cheap, and it carries nearly every node to its final datum). Then
/// sweeps with locking follow: every node is open once, later only the
/// neighbours of nodes that changed; an open node tries all 3^D - 1
/// neighbours. A sweep that changes nothing leaves every node closed, i.e.
/// each has tried the current candidate of every neighbour: a fixed point.
/// Nodes of the exact band are final throughout.
fn propagate_closest<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    radius: f64,
    nodes: &mut Nodes<D>,
) -> usize {
    let stencil = Stencil::new(spec);
    let final_below = radius * radius;
    let mut sweeps = 0;
    for order in 0..1usize << D {
        sweeps += 1;
        for_each_node_ordered(&spec.dims, order, |l, idx| {
            if nodes.values[l] > final_below {
                let room = stencil.room(idx);
                update_node(data, spec, nodes, l, idx, room, &stencil.upwind[order]);
            }
        });
    }
    let mut open: Vec<bool> = nodes.values.par_iter().map(|&v| v > final_below).collect();
    for _ in 0..MAX_ROUNDS {
        for order in 0..1usize << D {
            sweeps += 1;
            let mut changed = false;
            for_each_node_ordered(&spec.dims, order, |l, idx| {
                if !open[l] {
                    return;
                }
                open[l] = false;
                let room = stencil.room(idx);
                if update_node(data, spec, nodes, l, idx, room, &stencil.all) {
                    changed = true;
                    for &(down, up, offset, _) in &stencil.all {
                        if room.allows(down, up) {
                            let n = (l as isize + offset) as usize;
                            open[n] = nodes.values[n] > final_below;
                        }
                    }
                }
            });
            if !changed {
                return sweeps;
            }
        }
    }
    sweeps
}

/// Try the candidates of the neighbours `offsets` of node `l`; adopt the
/// nearest datum if it beats the node's own. Returns whether it changed.
#[inline(always)]
fn update_node<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    nodes: &mut Nodes<D>,
    l: usize,
    idx: &[usize; D],
    room: Room,
    offsets: &[(usize, usize, isize, f64)],
) -> bool {
    let points = data.points.len();
    let p = spec.position(*idx);
    let (mut best, mut best_id) = (nodes.values[l], nodes.closest[l]);
    let mut tried = best_id;
    let interior = room.is_full::<D>();
    for &(down, up, offset, step) in offsets {
        if !interior && !room.allows(down, up) {
            continue;
        }
        let n = (l as isize + offset) as usize;
        let c = nodes.closest[n];
        if c == NO_DATUM || c == tried || c == best_id {
            continue;
        }
        tried = c;
        let mut d2 = dist2(&p, &nodes.feet[n]);
        if c as usize >= points {
            // The foot of `n` is within `step` of this node's foot on the
            // same (convex) datum, so the exact distance is at least
            // sqrt(d2) - step.
            if d2.sqrt() - step >= best.sqrt() {
                continue;
            }
            d2 = data.distance_squared(c as usize, &p);
        }
        if d2 < best || (d2 == best && c < best_id) {
            (best, best_id) = (d2, c);
        }
    }
    if best_id == nodes.closest[l] {
        return false;
    }
    // Own exact foot on the adopted datum: copying the neighbour's would let
    // feet lag along long segments and large triangles.
    let foot = data.closest_point(best_id as usize, &p);
    nodes.values[l] = dist2(&p, &foot);
    nodes.closest[l] = best_id;
    nodes.feet[l] = foot;
    true
}

/// The 3^D - 1 neighbour offsets of a node (axis and diagonal).
struct Stencil<const D: usize> {
    dims: [usize; D],
    /// Axes stepped down along (bit mask), axes stepped up along, linear
    /// offset and length of the step, per neighbour.
    all: Vec<(usize, usize, isize, f64)>,
    /// Per sweep order, the 2^D - 1 neighbours on the side the sweep comes
    /// from (order bit a set: axis a runs backwards).
    upwind: Vec<Vec<(usize, usize, isize, f64)>>,
}

/// Which axes a node may step down (bit set: index > 0) and up along.
#[derive(Clone, Copy)]
struct Room {
    down: usize,
    up: usize,
}

impl Room {
    /// Every step is possible (the node is not on the grid boundary).
    #[inline(always)]
    fn is_full<const D: usize>(self) -> bool {
        let all = (1 << D) - 1;
        self.down == all && self.up == all
    }

    #[inline(always)]
    fn allows(self, down: usize, up: usize) -> bool {
        down & !self.down == 0 && up & !self.up == 0
    }
}

impl<const D: usize> Stencil<D> {
    fn new(spec: &GridSpec<D>) -> Self {
        let strides = spec.strides();
        let mut all = Vec::new();
        for code in 0..3usize.pow(D as u32) {
            let (mut down, mut up, mut offset, mut rest) = (0usize, 0usize, 0isize, code);
            for (a, &stride) in strides.iter().enumerate() {
                match rest % 3 {
                    1 => {
                        down |= 1 << a;
                        offset -= stride as isize;
                    }
                    2 => {
                        up |= 1 << a;
                        offset += stride as isize;
                    }
                    _ => {}
                }
                rest /= 3;
            }
            if down | up != 0 {
                let axes = (down | up).count_ones() as f64;
                all.push((down, up, offset, spec.spacing * axes.sqrt()));
            }
        }
        let upwind = (0..1usize << D)
            .map(|order| {
                let (backward, forward) = (order, !order & ((1 << D) - 1));
                all.iter()
                    .filter(|&&(down, up, _, _)| down & !forward == 0 && up & !backward == 0)
                    .copied()
                    .collect()
            })
            .collect();
        Stencil {
            dims: spec.dims,
            all,
            upwind,
        }
    }

    #[inline(always)]
    fn room(&self, idx: &[usize; D]) -> Room {
        let mut room = Room { down: 0, up: 0 };
        for (a, (&i, &n)) in idx.iter().zip(&self.dims).enumerate() {
            room.down |= usize::from(i > 0) << a;
            room.up |= usize::from(i + 1 < n) << a;
        }
        room
    }
}

#[inline(always)]
fn sub<const D: usize>(a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|k| a[k] - b[k])
}

#[inline(always)]
fn dot<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    (0..D).map(|k| a[k] * b[k]).sum()
}

#[inline(always)]
fn dist2<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    let d = sub(a, b);
    dot(&d, &d)
}

/// Squared distance from `p` to the segment `a..b` (a point when a = b).
#[inline]
pub fn segment_dist2<const D: usize>(p: &[f64; D], a: &[f64; D], b: &[f64; D]) -> f64 {
    dist2(p, &segment_closest(p, a, b))
}

/// The point of segment `a..b` nearest to `p`.
#[inline]
pub fn segment_closest<const D: usize>(p: &[f64; D], a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    let ab = sub(b, a);
    let len2 = dot(&ab, &ab);
    let t = if len2 > 0.0 {
        (dot(&sub(p, a), &ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    std::array::from_fn(|k| a[k] + t * ab[k])
}

/// Squared distance from `p` to the triangle `a, b, c` (any dimension).
#[inline]
pub fn triangle_dist2<const D: usize>(
    p: &[f64; D],
    a: &[f64; D],
    b: &[f64; D],
    c: &[f64; D],
) -> f64 {
    dist2(p, &triangle_closest(p, a, b, c))
}

/// The point of triangle `a, b, c` nearest to `p`, in any dimension:
/// classify `p` against the Voronoi regions of the corners, edges and face
/// using dot products only; degenerate triangles fall back to their edges.
#[inline]
pub fn triangle_closest<const D: usize>(
    p: &[f64; D],
    a: &[f64; D],
    b: &[f64; D],
    c: &[f64; D],
) -> [f64; D] {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let (d1, d2) = (dot(&ab, &ap), dot(&ac, &ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(&ab, &bp), dot(&ac, &bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(&ab, &cp), dot(&ac, &cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return segment_closest(p, a, b);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return segment_closest(p, a, c);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 >= d3 && d5 >= d6 {
        return segment_closest(p, b, c);
    }
    let sum = va + vb + vc;
    if sum.is_nan() || sum <= 0.0 {
        let edges = [
            segment_closest(p, a, b),
            segment_closest(p, a, c),
            segment_closest(p, b, c),
        ];
        return edges
            .into_iter()
            .min_by(|x, y| dist2(p, x).total_cmp(&dist2(p, y)))
            .unwrap_or(*a);
    }
    let (v, w) = (vb / sum, vc / sum);
    std::array::from_fn(|k| a[k] + v * ab[k] + w * ac[k])
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
                assert_eq!(got, own, "value is the distance to the closest datum");
                assert!(got >= exact - 1e-12, "never below the true distance");
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
        assert!(far <= 0.05);
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
        assert!(e_cpp < 0.1 && e_god > 5.0 * e_cpp.max(0.01));
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
