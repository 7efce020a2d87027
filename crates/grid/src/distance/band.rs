//! Stage 1 of the unsigned distance: the data sorted in space, and exact
//! distances in a band of nodes around every datum.

use super::primitives::dist2;
use super::{DataSet, NO_DATUM};
use crate::spec::for_each_in_box;
use crate::GridSpec;
use rayon::prelude::*;

/// Layers (along the last axis) per slab of the parallel band stage; fixed,
/// so the work split never depends on the thread count.
const SLAB_LAYERS: usize = 4;

/// Working state of one grid node.
#[derive(Clone, Copy)]
pub(super) struct Node<const D: usize> {
    /// Squared distance to `foot` (INFINITY when no datum yet).
    pub d2: f64,
    /// Nearest point of `datum` to this node: a point on the datum, so
    /// its distance to another node bounds that node's distance to the
    /// datum from above at the cost of a point distance, whatever the kind.
    pub foot: [f64; D],
    /// Closest datum known so far (in sorted order), or [`NO_DATUM`].
    pub datum: u32,
}

impl<const D: usize> Node<D> {
    pub const EMPTY: Self = Node {
        d2: f64::INFINITY,
        foot: [f64::NAN; D],
        datum: NO_DATUM,
    };
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

/// Stage 1: exact squared distances and closest data at the nodes within
/// `radii[kind]` of each datum (points, segments, triangles), with their
/// feet; the other nodes stay empty. Parallel over fixed slabs; ties go to
/// the smaller (sorted) datum index, so the result does not depend on the
/// order data are applied in.
pub(super) fn exact_band<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    radii: [f64; 3],
) -> Vec<Node<D>> {
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
    let mut keys = vec![EMPTY_KEY; spec.node_count()];
    keys.par_chunks_mut(SLAB_LAYERS * layer)
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(s, (keys, bin))| {
            let slab_first = s * SLAB_LAYERS;
            let slab_last = (slab_first + SLAB_LAYERS).min(spec.dims[last_axis]) - 1;
            let mut slab = Slab {
                keys,
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
    keys.into_par_iter()
        .enumerate()
        .map(|(l, key)| match key {
            EMPTY_KEY => Node::EMPTY,
            key => {
                let datum = key as u32;
                let p = spec.position(spec.unlinear(l));
                let foot = data.closest_point(datum as usize, &p);
                Node {
                    d2: dist2(&p, &foot),
                    foot,
                    datum,
                }
            }
        })
        .collect()
}

/// A node's best offer so far: the squared distance as `f32` bits (which
/// order like the numbers, as they are not negative) above the datum
/// index, so the smallest key is the nearest datum, ties going to the
/// smaller index, and keeping the better of two offers is an integer
/// `min` with no branch. The `f32` rounding (relative 6e-8 in d²) can only
/// pick, among data at equal distance to that precision, the one with the
/// smaller index; distances are recomputed exactly afterwards.
type Key = u64;

const EMPTY_KEY: Key = u64::MAX;

#[inline(always)]
fn key(d2: f64, datum: u32) -> Key {
    ((d2 as f32).to_bits() as u64) << 32 | datum as u64
}

/// The keys of the nodes of one slab, indexed by global linear index minus
/// `offset`, and scratch space for [`point_ball`].
struct Slab<'a, const D: usize> {
    keys: &'a mut [Key],
    offset: usize,
    /// Per axis, squared offsets of the box's node coordinates from a point.
    offsets: [Vec<f64>; D],
}

/// Point `q` (datum `i`): every node within `radius`, by rows along axis 0
/// clipped to the ball (points are the dense kind; the ball is half the
/// box). Rows are short, so the per-row work is a few additions.
fn point_ball<const D: usize>(
    spec: &GridSpec<D>,
    q: &[f64; D],
    i: u32,
    radius: f64,
    (first, mut last): ([usize; D], [usize; D]),
    slab: &mut Slab<D>,
) {
    let (h, inv_h) = (spec.spacing, 1.0 / spec.spacing);
    let r2 = radius * radius;
    let strides = spec.strides();
    for a in 1..D {
        let offsets = &mut slab.offsets[a];
        offsets.clear();
        offsets
            .extend((first[a]..=last[a]).map(|j| (spec.origin[a] + j as f64 * h - q[a]).powi(2)));
    }
    let (x_first, x_last) = (first[0] as f64, last[0] as f64);
    // Node coordinate of `q` along axis 0, in cells.
    let qx = (q[0] - spec.origin[0]) * inv_h;
    let x0 = spec.origin[0] - q[0];
    last[0] = first[0];
    for_each_in_box(first, last, |row| {
        let off_row: f64 = (1..D).map(|a| slab.offsets[a][row[a] - first[a]]).sum();
        if off_row > r2 {
            return;
        }
        // Row nodes within the ball, with slack for rounding (a node
        // slightly outside does no harm). Both ends are clamped to the box
        // first, so they are not negative and `as` rounds towards zero.
        let half = (r2 - off_row).sqrt() * inv_h + 1e-9;
        let (lo, hi) = ((qx - half).max(x_first), (qx + half).min(x_last));
        if hi < lo {
            return;
        }
        let lo = lo as usize + usize::from((lo as usize as f64) < lo);
        let hi = hi as usize;
        let start: usize = (1..D).map(|a| row[a] * strides[a]).sum::<usize>() - slab.offset;
        for (x, k) in (lo..=hi).zip(&mut slab.keys[start + lo..=start + hi]) {
            let dx = x0 + x as f64 * h;
            *k = (*k).min(key(dx * dx + off_row, i));
        }
    });
}

/// Any datum `i`: every node of the box `first..=last`.
fn datum_box<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    i: u32,
    (first, last): ([usize; D], [usize; D]),
    slab: &mut Slab<D>,
) {
    for_each_in_box(first, last, |idx| {
        let p = spec.position(*idx);
        let k = &mut slab.keys[spec.linear(*idx) - slab.offset];
        *k = (*k).min(key(data.distance_squared(i as usize, &p), i));
    });
}
