//! Stage 1 of the unsigned distance: the data sorted in space, and exact
//! distances in a band of nodes around every datum.

use super::{DataSet, NO_DATUM};
use crate::spec::for_each_in_box;
use crate::GridSpec;
use rayon::prelude::*;

/// Layers (along the last axis) per slab of the parallel band stage; fixed,
/// so the work split never depends on the thread count.
const SLAB_LAYERS: usize = 4;

/// Closest datum and its foot per node while the distance is computed.
///
/// Feet are kept compact, as `f32` grid coordinates (cells from the
/// origin): they only rank candidates, to ~1e-7 of the grid's extent;
/// the final distances are recomputed exactly from the data.
pub(super) struct Closest<const D: usize> {
    /// Closest datum known so far (in sorted order), or [`NO_DATUM`].
    pub datum: Vec<u32>,
    /// Nearest point of `datum` to the node (for points, the point): a
    /// point on the datum, so its distance to another node bounds that
    /// node's distance to the datum from above, whatever the kind.
    pub foot: Vec<[f32; D]>,
}

impl<const D: usize> Closest<D> {
    /// Squared distance, in cells², from node `idx` (linear `l`) to its foot.
    #[inline(always)]
    pub fn d2(&self, l: usize, idx: &[f32; D]) -> f32 {
        cells_dist2(idx, &self.foot[l])
    }
}

/// Squared distance between two points in grid coordinates.
#[inline(always)]
pub(super) fn cells_dist2<const D: usize>(a: &[f32; D], b: &[f32; D]) -> f32 {
    (0..D).map(|k| (a[k] - b[k]) * (a[k] - b[k])).sum()
}

/// Grid coordinates of a world point, as `f32`.
#[inline(always)]
pub(super) fn to_cells<const D: usize>(spec: &GridSpec<D>, p: &[f64; D]) -> [f32; D] {
    std::array::from_fn(|a| ((p[a] - spec.origin[a]) / spec.spacing) as f32)
}

/// The data with each kind (points, segments, triangles) ordered by the
/// grid node nearest its bounding-box centre, so data close in space are
/// close in memory (neighbouring nodes look up neighbouring data).
pub(super) struct SortedData<const D: usize> {
    pub data: DataSet<D>,
    /// Original index per sorted index.
    pub original: Vec<u32>,
}

impl<const D: usize> SortedData<D> {
    pub fn new(data: &DataSet<D>, spec: &GridSpec<D>) -> Self {
        let key = |i: usize| -> usize {
            let (lo, hi) = data.datum_bounds(i);
            let idx = std::array::from_fn(|a| {
                let g = ((lo[a] + hi[a]) * 0.5 - spec.origin[a]) / spec.spacing;
                g.round().clamp(0.0, (spec.dims[a] - 1) as f64) as usize
            });
            spec.linear(idx)
        };
        let mut keyed: Vec<(usize, u32)> = Vec::with_capacity(data.len());
        for range in data.kind_ranges() {
            let mut kind: Vec<(usize, u32)> =
                range.into_par_iter().map(|i| (key(i), i as u32)).collect();
            kind.par_sort_unstable();
            keyed.extend(kind);
        }
        let original: Vec<u32> = keyed.into_iter().map(|(_, i)| i).collect();
        let [points, segments, triangles] = data.kind_ranges();
        let data = DataSet {
            points: original[points]
                .iter()
                .map(|&i| data.points[i as usize])
                .collect(),
            segments: original[segments.clone()]
                .iter()
                .map(|&i| data.segments[i as usize - segments.start])
                .collect(),
            triangles: original[triangles.clone()]
                .iter()
                .map(|&i| data.triangles[i as usize - triangles.start])
                .collect(),
        };
        SortedData { data, original }
    }
}

/// Stage 1: closest data at the nodes within `radii[kind]` of each datum
/// (points, segments, triangles), with their feet; the other nodes stay
/// empty. Parallel over fixed slabs. Data are applied in index order and
/// only a strictly nearer datum replaces a node's, so ties go to the
/// smaller (sorted) index and the result does not depend on the thread
/// count.
pub(super) fn exact_band<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    radii: [f64; 3],
) -> Closest<D> {
    let last_axis = D - 1;
    let layer = spec.strides()[last_axis];
    let slabs = spec.dims[last_axis].div_ceil(SLAB_LAYERS);
    let kinds = data.kind_ranges();
    let radius_of = |i: usize| radii[kinds.iter().position(|k| k.end > i).unwrap_or(2)];
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); slabs];
    for i in 0..data.len() {
        if let Some((first, last)) = spec.node_box(data.datum_bounds(i), radius_of(i)) {
            for bin in &mut bins[first[last_axis] / SLAB_LAYERS..=last[last_axis] / SLAB_LAYERS] {
                bin.push(i as u32);
            }
        }
    }
    let mut d2 = vec![f32::INFINITY; spec.node_count()];
    let mut datum = vec![NO_DATUM; spec.node_count()];
    d2.par_chunks_mut(SLAB_LAYERS * layer)
        .zip(datum.par_chunks_mut(SLAB_LAYERS * layer))
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(s, ((d2, datum), bin))| {
            let slab_first = s * SLAB_LAYERS;
            let slab_last = (slab_first + SLAB_LAYERS).min(spec.dims[last_axis]) - 1;
            let mut slab = Slab {
                d2,
                datum,
                offset: slab_first * layer,
                offsets: std::array::from_fn(|_| Vec::new()),
            };
            for &i in bin {
                let radius = radius_of(i as usize);
                let Some((mut first, mut last)) =
                    spec.node_box(data.datum_bounds(i as usize), radius)
                else {
                    continue;
                };
                first[last_axis] = first[last_axis].max(slab_first);
                last[last_axis] = last[last_axis].min(slab_last);
                match data.points.get(i as usize) {
                    Some(q) => point_ball(spec, q, i, radius, (first, last), &mut slab),
                    None => datum_box(data, spec, i, (first, last), &mut slab),
                }
            }
        });
    drop(d2);
    let foot = datum
        .par_iter()
        .enumerate()
        .map(|(l, &c)| match c {
            NO_DATUM => [f32::NAN; D],
            c if (c as usize) < data.points.len() => to_cells(spec, &data.points[c as usize]),
            c => {
                let p = spec.position(spec.unlinear(l));
                to_cells(spec, &data.closest_point(c as usize, &p))
            }
        })
        .collect();
    Closest { datum, foot }
}

/// The best offers so far of the nodes of one slab (squared distance in
/// cells², as `f32`, and datum), indexed by global linear index minus
/// `offset`, and scratch space for [`point_ball`]. The `f32` rounding
/// (relative 6e-8) can only choose between data at equal distance to that
/// precision; distances are recomputed exactly afterwards.
struct Slab<'a, const D: usize> {
    d2: &'a mut [f32],
    datum: &'a mut [u32],
    offset: usize,
    /// Per axis, squared offsets (cells²) of the box's node coordinates
    /// from a point.
    offsets: [Vec<f32>; D],
}

impl<const D: usize> Slab<'_, D> {
    /// Offer datum `i` at squared distance `d2` to node `k` of the slab.
    #[inline(always)]
    fn offer(&mut self, k: usize, d2: f32, i: u32) {
        if d2 < self.d2[k] {
            self.d2[k] = d2;
            self.datum[k] = i;
        }
    }
}

/// Point `q` (datum `i`): every node within `radius`, by rows along axis 0
/// clipped to the ball (points are the dense kind; the ball is half the
/// box). Rows are short, so the per-row work is a few additions; the row
/// loop has no branch, so that it vectorizes.
fn point_ball<const D: usize>(
    spec: &GridSpec<D>,
    q: &[f64; D],
    i: u32,
    radius: f64,
    (first, mut last): ([usize; D], [usize; D]),
    slab: &mut Slab<D>,
) {
    let qc = spec.to_grid(*q);
    let r2 = (radius / spec.spacing).powi(2) as f32;
    let strides = spec.strides();
    for a in 1..D {
        let offsets = &mut slab.offsets[a];
        offsets.clear();
        offsets.extend((first[a]..=last[a]).map(|j| ((j as f64 - qc[a]).powi(2)) as f32));
    }
    let (x_first, x_last) = (first[0] as i64, last[0] as i64);
    let qx = qc[0] as f32;
    // Offsets along the row from the whole and fractional parts of `q`'s
    // coordinate: exact whatever the grid size.
    let q_whole = qc[0].floor();
    let q_frac = (qc[0] - q_whole) as f32;
    last[0] = first[0];
    for_each_in_box(first, last, |row| {
        let off_row: f32 = (1..D).map(|a| slab.offsets[a][row[a] - first[a]]).sum();
        if off_row > r2 {
            return;
        }
        // Row nodes within the ball, with slack for rounding (a node
        // slightly outside does no harm).
        let half = (r2 - off_row).sqrt() + 1e-4;
        let lo = ceil(qx - half).max(x_first) as usize;
        let hi = floor(qx + half).min(x_last) as usize;
        if hi < lo {
            return;
        }
        let start: usize = (1..D).map(|a| row[a] * strides[a]).sum::<usize>() - slab.offset;
        let d2 = &mut slab.d2[start + lo..start + hi + 1];
        let datum = &mut slab.datum[start + lo..start + hi + 1];
        let lo_from_q = (lo as i64 - q_whole as i64) as i32;
        for (k, (d2, datum)) in d2.iter_mut().zip(datum.iter_mut()).enumerate() {
            let dx = (lo_from_q + k as i32) as f32 - q_frac;
            let offer = dx * dx + off_row;
            let better = offer < *d2;
            *d2 = if better { offer } else { *d2 };
            *datum = if better { i } else { *datum };
        }
    });
}

/// `x.floor()` for the finite, moderate `x` of grid coordinates; without
/// SSE4.1 the library call would cost more than the rest of a ball row.
#[inline(always)]
fn floor(x: f32) -> i64 {
    let t = x as i64;
    t - i64::from(t as f32 > x)
}

/// `x.ceil()`, as [`floor`].
#[inline(always)]
fn ceil(x: f32) -> i64 {
    let t = x as i64;
    t + i64::from((t as f32) < x)
}

/// Any datum `i`: every node of the box `first..=last`.
fn datum_box<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    i: u32,
    (first, last): ([usize; D], [usize; D]),
    slab: &mut Slab<D>,
) {
    let inv_h2 = spec.spacing.powi(-2);
    for_each_in_box(first, last, |idx| {
        let p = spec.position(*idx);
        let d2 = (data.distance_squared(i as usize, &p) * inv_h2) as f32;
        slab.offer(spec.linear(*idx) - slab.offset, d2, i);
    });
}
