//! Stage 1 of the unsigned distance: the data sorted in space, and exact
//! distances in a band of nodes around every datum.

use super::primitives::dist2;
use super::{DataSet, NO_DATUM};
use crate::simd::widest;
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
    pub feet: Feet<D>,
}

/// The nearest point of a node's datum to the node (for points, the
/// point): a point on the datum, so its distance to another node bounds
/// that node's distance to the datum from above, whatever the kind.
pub(super) enum Feet<const D: usize> {
    /// Data of points only: a node's foot is its datum, so one per datum
    /// suffices (4 bytes per node instead of 4 + 4·D, and fewer memory
    /// lines to touch per node).
    OfPoints(Vec<[f32; D]>),
    /// One per node, indexed like the nodes.
    PerNode(Vec<[f32; D]>),
}

impl<const D: usize> Closest<D> {
    /// Foot of node `l` (NaN when it has no datum).
    #[inline(always)]
    pub fn foot(&self, l: usize) -> [f32; D] {
        match &self.feet {
            Feet::OfPoints(points) => foot_of_point(points, self.datum[l]),
            Feet::PerNode(feet) => feet[l],
        }
    }

    /// Squared distance, in cells², from node `l` at `idx` to its foot.
    #[inline(always)]
    pub fn d2(&self, l: usize, idx: &[f32; D]) -> f32 {
        cells_dist2(idx, &self.foot(l))
    }

    /// Give node `l` datum `c` with foot `foot` (implied when the feet
    /// are the points).
    pub fn set(&mut self, l: usize, c: u32, foot: [f32; D]) {
        self.datum[l] = c;
        if let Feet::PerNode(feet) = &mut self.feet {
            feet[l] = foot;
        }
    }
}

/// Foot of datum `c` when the feet are the points: the point, or NaN for
/// [`NO_DATUM`].
#[inline(always)]
pub(super) fn foot_of_point<const D: usize>(points: &[[f32; D]], c: u32) -> [f32; D] {
    points.get(c as usize).copied().unwrap_or([f32::NAN; D])
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
            widest(
                #[inline(always)]
                || {
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
                },
            )
        });
    drop(d2);
    let feet = if data.only_points() {
        Feet::OfPoints(data.points.par_iter().map(|p| to_cells(spec, p)).collect())
    } else {
        Feet::PerNode(
            datum
                .par_iter()
                .enumerate()
                .map(|(l, &c)| match c {
                    NO_DATUM => [f32::NAN; D],
                    c => {
                        let p = spec.position(spec.unlinear(l));
                        to_cells(spec, &data.closest_point(c as usize, &p))
                    }
                })
                .collect(),
        )
    };
    Closest { datum, feet }
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

/// Point `q` (datum `i`): every node within `radius`, by rows along
/// axis 0. Each row within the ball takes whole chunks over the box's
/// span, so no row is clipped to the ball: the nodes beyond it get exact
/// offers too, which do no harm (for the usual 5-cell radius, the span of
/// 11 nodes is one chunk).
#[inline(always)]
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
    // Offsets along the row from the whole and fractional parts of `q`'s
    // coordinate: exact whatever the grid size.
    let q_whole = qc[0].floor() as i64;
    let q_frac = (qc[0] - q_whole as f64) as f32;
    let first_dx = |x: usize| (x as i64 - q_whole) as i32;
    let (row_len, span) = (spec.dims[0], first[0]..=last[0]);
    last[0] = first[0];
    for_each_in_box(first, last, |row| {
        let off_row: f32 = (1..D).map(|a| slab.offsets[a][row[a] - first[a]]).sum();
        if off_row > r2 {
            return;
        }
        let start: usize = (1..D).map(|a| row[a] * strides[a]).sum::<usize>() - slab.offset;
        let (d2, datum) = (
            &mut slab.d2[start..][..row_len],
            &mut slab.datum[start..][..row_len],
        );
        if row_len < CHUNK {
            return span.clone().for_each(|x| {
                let (d2, datum) = (&mut d2[x], &mut datum[x]);
                let (d2, datum) = (std::array::from_mut(d2), std::array::from_mut(datum));
                offer_chunk(d2, datum, first_dx(x), q_frac, off_row, i)
            });
        }
        // Chunks from the span's start (within the grid's row), the last
        // one ending at the span's end.
        let mut x = (*span.start()).min(row_len - CHUNK);
        loop {
            let d2: &mut [f32; CHUNK] = (&mut d2[x..x + CHUNK]).try_into().expect("a chunk");
            let datum: &mut [u32; CHUNK] = (&mut datum[x..x + CHUNK]).try_into().expect("a chunk");
            offer_chunk(d2, datum, first_dx(x), q_frac, off_row, i);
            if x + CHUNK > *span.end() {
                break;
            }
            x = (x + CHUNK).min(span.end() + 1 - CHUNK);
        }
    });
}

/// Nodes per [`offer_chunk`]: a loop over a row's exact length would run
/// in its scalar tail; a fixed width vectorizes. 16 holds the span of the
/// usual 5-cell ball (11 nodes) and fills an AVX-512 register.
const CHUNK: usize = 16;

/// Offer a point to consecutive nodes of a row (all of `d2`, `datum`):
/// the first lies `first_dx` whole cells past the point's whole coordinate
/// along the row, `q_frac` its fractional part; `off_row` is the squared
/// offset of the row. Branch-free, so that it vectorizes.
#[inline(always)]
fn offer_chunk<const N: usize>(
    d2: &mut [f32; N],
    datum: &mut [u32; N],
    first_dx: i32,
    q_frac: f32,
    off_row: f32,
    i: u32,
) {
    // Selects by masks on local copies: LLVM turns `if` selects on memory
    // into branches, which mispredict about every other node.
    let (mut best, mut owner) = (*d2, *datum);
    for k in 0..N {
        let dx = (first_dx + k as i32) as f32 - q_frac;
        let offer = dx * dx + off_row;
        let take = 0u32.wrapping_sub(u32::from(offer < best[k]));
        best[k] = f32::from_bits((offer.to_bits() & take) | (best[k].to_bits() & !take));
        owner[k] = (i & take) | (owner[k] & !take);
    }
    (*d2, *datum) = (best, owner);
}

/// Any datum `i`: every node of the box `first..=last`, by rows along
/// axis 0. Two lower bounds of the distance spare most exact evaluations:
/// a triangle's plane and the datum's bounding ball. A node whose best
/// offer so far is nearer than either bound keeps it.
#[inline(always)]
fn datum_box<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    i: u32,
    (first, mut last): ([usize; D], [usize; D]),
    slab: &mut Slab<D>,
) {
    let (h, inv_h2) = (spec.spacing, spec.spacing.powi(-2));
    let plane = data
        .triangles
        .get((i as usize).wrapping_sub(data.points.len() + data.segments.len()))
        .and_then(unit_normal);
    let (centre, ball) = bounding_ball(data, i as usize);
    let row_len = last[0] - first[0] + 1;
    last[0] = first[0];
    for_each_in_box(first, last, |row| {
        let mut p = spec.position(*row);
        let start = spec.linear(*row) - slab.offset;
        // Height over the plane along the row: `height + slope * k`.
        let (height, slope) = match &plane {
            Some((n, a)) => ((0..D).map(|c| n[c] * (p[c] - a[c])).sum(), n[0] * h),
            None => (0.0, 0.0),
        };
        for k in 0..row_len {
            p[0] = spec.origin[0] + (first[0] + k) as f64 * h;
            let above_plane = (height + slope * k as f64).abs();
            let off_ball = dist2(&p, &centre).sqrt() - ball;
            let bound = above_plane.max(off_ball).max(0.0);
            if (bound * bound * inv_h2) as f32 >= slab.d2[start + k] {
                continue;
            }
            let d2 = (data.distance_squared(i as usize, &p) * inv_h2) as f32;
            slab.offer(start + k, d2, i);
        }
    });
}

/// Centre and radius of a ball holding datum `i`: the centre of its
/// bounding box and the largest distance to a corner (rounded up).
fn bounding_ball<const D: usize>(data: &DataSet<D>, i: usize) -> ([f64; D], f64) {
    let (lo, hi) = data.datum_bounds(i);
    let centre = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
    let farthest = |corners: &[[f64; D]]| {
        corners
            .iter()
            .map(|c| dist2(c, &centre))
            .fold(0.0, f64::max)
    };
    let radius = match data.datum(i) {
        Some(super::Datum::Segment(s)) => farthest(&s),
        Some(super::Datum::Triangle(t)) => farthest(&t),
        _ => 0.0,
    }
    .sqrt();
    (centre, radius * (1.0 + 1e-12))
}

/// Unit normal and a corner of a 3D triangle; `None` in other dimensions
/// and for degenerate triangles.
pub(super) fn unit_normal<const D: usize>(t: &[[f64; D]; 3]) -> Option<([f64; D], [f64; D])> {
    if D != 3 {
        return None;
    }
    let e = |k: usize, c: usize| t[k][c] - t[0][c];
    let n = [
        e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1),
        e(1, 2) * e(2, 0) - e(1, 0) * e(2, 2),
        e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0),
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    (len > 0.0 && len.is_finite()).then(|| (std::array::from_fn(|c| n[c] / len), t[0]))
}
