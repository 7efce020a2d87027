//! Closest-datum sweeps plane by plane: along each axis in both directions,
//! every node of a plane is offered the feet of the 3^(D-1) nodes of the
//! plane before it, and keeps the nearest.
//!
//! A sweep carries a datum forward through the cone of directions within
//! 45° of its axis; the 2·D sweeps together cover every direction, so one
//! round reaches every node. The nodes of a plane read only the plane
//! before, so they update in parallel with a result independent of the
//! thread count. Planes are copied into structure-of-arrays rows, with an
//! empty border, so that the offers run as straight vectorizable loops.

use super::band::{foot_of_point, Closest, Feet};
use super::NO_DATUM;
use crate::simd::widest;
use crate::spec::for_each_in_box;
use crate::GridSpec;
use rayon::prelude::*;

/// One round of cone sweeps: along each axis forward, then backward.
/// Nodes at most `final_below` (cells²) from their foot keep their datum.
pub(super) fn cone_sweeps<const D: usize>(
    spec: &GridSpec<D>,
    final_below: f32,
    closest: &mut Closest<D>,
) {
    for axis in 0..D {
        let shape = PlaneShape::new(spec, axis);
        let mut planes = vec![shape.empty_rows(spec); 2];
        for forward in [true, false] {
            sweep(spec, final_below, closest, &shape, forward, &mut planes);
        }
    }
}

/// A row of a plane, along its row axis, with one empty node at each end.
#[derive(Clone)]
struct Row<const D: usize> {
    datum: Vec<u32>,
    /// Foot coordinates (cells) per axis; NaN for empty nodes, so that
    /// every comparison with them fails.
    foot: [Vec<f32>; D],
}

/// Index in a [`Row`] of its first node (after the border).
const BORDER: usize = 1;

/// How the nodes of a plane across `axis` are laid out in rows along
/// `row_axis` (the first other axis), bordered by empty rows.
#[derive(Clone, Copy)]
struct PlaneShape<const D: usize> {
    axis: usize,
    row_axis: usize,
    /// Rows per axis, counting the border; 1 along `axis` and `row_axis`.
    row_dims: [usize; D],
}

impl<const D: usize> PlaneShape<D> {
    fn new(spec: &GridSpec<D>, axis: usize) -> Self {
        let row_axis = usize::from(axis == 0);
        let row_dims = std::array::from_fn(|b| match b {
            b if b == axis || b == row_axis => 1,
            b => spec.dims[b] + 2,
        });
        PlaneShape {
            axis,
            row_axis,
            row_dims,
        }
    }

    fn empty_rows(&self, spec: &GridSpec<D>) -> Vec<Row<D>> {
        let len = spec.dims[self.row_axis] + 2 * BORDER;
        let empty = Row {
            datum: vec![NO_DATUM; len],
            foot: std::array::from_fn(|_| vec![f32::NAN; len]),
        };
        vec![empty; self.row_dims.iter().product()]
    }

    /// Bordered coordinates of row `index`, or `None` for a border row.
    #[allow(clippy::needless_range_loop)] // `b` indexes three arrays
    fn interior_row(&self, mut index: usize) -> Option<[usize; D]> {
        let mut r = [0; D];
        for b in 0..D {
            r[b] = index % self.row_dims[b];
            index /= self.row_dims[b];
            if self.row_dims[b] > 1 && (r[b] == 0 || r[b] == self.row_dims[b] - 1) {
                return None;
            }
        }
        Some(r)
    }

    /// Index of the row at bordered coordinates `r`.
    fn row_index(&self, r: &[usize; D]) -> usize {
        (0..D).rev().fold(0, |acc, b| acc * self.row_dims[b] + r[b])
    }

    /// The rows beside interior row `r` in the other in-plane axes, and
    /// `r` itself.
    fn neighbour_rows(&self, r: &[usize; D], rows: &mut Vec<usize>) {
        let wide = |b: usize| self.row_dims[b] > 1;
        let first = std::array::from_fn(|b| if wide(b) { r[b] - 1 } else { 0 });
        let last = std::array::from_fn(|b| if wide(b) { r[b] + 1 } else { 0 });
        rows.clear();
        for_each_in_box(first, last, |n| rows.push(self.row_index(n)));
    }

    /// Grid index of the first node of interior row `r` in plane `plane`.
    fn first_node(&self, r: &[usize; D], plane: usize) -> [usize; D] {
        let mut idx: [usize; D] = std::array::from_fn(|b| r[b].saturating_sub(1));
        (idx[self.axis], idx[self.row_axis]) = (plane, 0);
        idx
    }
}

/// Per-task buffers of a sweep: per node of a row, the best offer so far
/// (squared distance in cells²) and where it came from; the neighbour rows.
struct Scratch<const D: usize> {
    /// Node coordinates (cells) per axis.
    position: [Vec<f32>; D],
    best: Vec<f32>,
    source: Vec<u32>,
    neighbours: Vec<usize>,
}

impl<const D: usize> Scratch<D> {
    fn new() -> Self {
        Scratch {
            position: std::array::from_fn(|_| Vec::new()),
            best: Vec::new(),
            source: Vec::new(),
            neighbours: Vec::new(),
        }
    }
}

/// `source` of a node that keeps its own datum.
const OWN: u32 = u32::MAX;

/// One sweep: plane after plane, each node takes the nearest foot among
/// its own and those of the 3^(D-1) nodes beside it in the plane before.
fn sweep<const D: usize>(
    spec: &GridSpec<D>,
    final_below: f32,
    closest: &mut Closest<D>,
    shape: &PlaneShape<D>,
    forward: bool,
    planes: &mut [Vec<Row<D>>],
) {
    let n = spec.dims[shape.axis];
    let grid = GridAccess::new(closest);
    for k in 0..n {
        let plane = if forward { k } else { n - 1 - k };
        let (before, current) = planes.split_at_mut(1);
        let previous = &before[0];
        current[0]
            .par_iter_mut()
            .enumerate()
            .with_min_len(8)
            .for_each_init(Scratch::new, |scratch, (index, row)| {
                let Some(r) = shape.interior_row(index) else {
                    return;
                };
                let first = shape.first_node(&r, plane);
                let (start, stride) = grid.row_start(spec, first, shape.row_axis);
                widest(
                    #[inline(always)]
                    || {
                        // SAFETY: each task touches the nodes of its own row only.
                        unsafe { grid.gather_row(start, stride, row) };
                        if k == 0 {
                            return;
                        }
                        shape.neighbour_rows(&r, &mut scratch.neighbours);
                        if offer_row(&first, shape.row_axis, final_below, previous, row, scratch) {
                            // SAFETY: as above.
                            unsafe { grid.scatter_row(start, stride, row, &scratch.source) };
                        }
                    },
                )
            });
        planes.swap(0, 1);
    }
}

/// Offer the nodes of `row` (the first at grid position `first`) the
/// feet of their neighbours in the plane before, and let each take the
/// nearest when it beats its own. Returns whether any node changed.
#[inline(always)]
fn offer_row<const D: usize>(
    first: &[usize; D],
    row_axis: usize,
    final_below: f32,
    before: &[Row<D>],
    row: &mut Row<D>,
    scratch: &mut Scratch<D>,
) -> bool {
    let len = row.datum.len() - 2 * BORDER;
    let Scratch {
        position,
        best,
        source,
        neighbours,
    } = scratch;
    for (b, p) in position.iter_mut().enumerate() {
        p.clear();
        p.extend((0..len).map(|i| (first[b] + if b == row_axis { i } else { 0 }) as f32));
    }
    best.clear();
    best.resize(len, f32::INFINITY);
    source.clear();
    source.resize(len, OWN);
    offer_shifted(position, &row.foot, BORDER, OWN, best, source);
    // Nodes already final take nothing.
    best.iter_mut()
        .filter(|d2| **d2 <= final_below)
        .for_each(|d2| *d2 = -1.0);
    for (n, &neighbour) in neighbours.iter().enumerate() {
        let feet = &before[neighbour].foot;
        for shift in 0..3 {
            let code = (3 * n + shift) as u32;
            offer_shifted(position, feet, shift, code, best, source);
        }
    }
    let mut changed = false;
    for (i, &s) in source.iter().enumerate() {
        if s != OWN {
            let from = &before[neighbours[s as usize / 3]];
            let j = i + s as usize % 3;
            row.datum[BORDER + i] = from.datum[j];
            for b in 0..D {
                row.foot[b][BORDER + i] = from.foot[b][j];
            }
            changed = true;
        }
    }
    changed
}

/// Offer every node `i` of a row, at `position[b][i]`, the foot at
/// `i + shift` of a neighbour row (`shift` 0, 1, 2 for the node before,
/// beside and after), recorded as `code` when it beats the best so far.
/// Branch-free over equal-length slices, so that it vectorizes.
#[inline(always)]
fn offer_shifted<const D: usize>(
    position: &[Vec<f32>; D],
    feet: &[Vec<f32>; D],
    shift: usize,
    code: u32,
    best: &mut [f32],
    source: &mut [u32],
) {
    let len = best.len();
    let source = &mut source[..len];
    let position: [&[f32]; D] = std::array::from_fn(|b| &position[b][..len]);
    let feet: [&[f32]; D] = std::array::from_fn(|b| &feet[b][shift..shift + len]);
    for i in 0..len {
        let mut d2 = 0.0;
        for b in 0..D {
            let t = position[b][i] - feet[b][i];
            d2 += t * t;
        }
        // NaN (empty node) compares false and is never taken.
        let take = u32::from(d2 < best[i]).wrapping_neg();
        best[i] = f32::from_bits((d2.to_bits() & take) | (best[i].to_bits() & !take));
        source[i] = (code & take) | (source[i] & !take);
    }
}

/// Shared access to the per-node datum and foot of a grid, for tasks that
/// touch disjoint nodes.
struct GridAccess<'a, const D: usize> {
    datum: *mut u32,
    feet: FeetAccess<'a, D>,
    len: usize,
    _closest: std::marker::PhantomData<&'a mut Closest<D>>,
}

/// The feet of [`Feet`], as [`GridAccess`] reaches them.
enum FeetAccess<'a, const D: usize> {
    OfPoints(&'a [[f32; D]]),
    PerNode(*mut [f32; D]),
}

// SAFETY: access goes through `gather_row`/`scatter_row`, whose callers
// guarantee that no node is touched by two tasks.
unsafe impl<const D: usize> Sync for GridAccess<'_, D> {}

impl<'a, const D: usize> GridAccess<'a, D> {
    fn new(closest: &'a mut Closest<D>) -> Self {
        let feet = match &mut closest.feet {
            Feet::OfPoints(points) => FeetAccess::OfPoints(points),
            Feet::PerNode(feet) => {
                assert_eq!(closest.datum.len(), feet.len());
                FeetAccess::PerNode(feet.as_mut_ptr())
            }
        };
        GridAccess {
            datum: closest.datum.as_mut_ptr(),
            feet,
            len: closest.datum.len(),
            _closest: std::marker::PhantomData,
        }
    }

    /// Copy the grid's row from node `start` by `stride` into `row`.
    ///
    /// # Safety
    /// No other task writes these nodes meanwhile.
    #[inline(always)]
    unsafe fn gather_row(&self, start: usize, stride: usize, row: &mut Row<D>) {
        for i in 0..row.datum.len() - 2 * BORDER {
            let l = start + i * stride;
            let c = *self.datum.add(l);
            row.datum[BORDER + i] = c;
            let foot = match self.feet {
                FeetAccess::OfPoints(points) => foot_of_point(points, c),
                FeetAccess::PerNode(feet) => *feet.add(l),
            };
            for (row_foot, f) in row.foot.iter_mut().zip(foot) {
                row_foot[BORDER + i] = f;
            }
        }
    }

    /// Write back the nodes of `row` whose `source` is not [`OWN`].
    ///
    /// # Safety
    /// No other task touches these nodes meanwhile.
    #[inline(always)]
    unsafe fn scatter_row(&self, start: usize, stride: usize, row: &Row<D>, source: &[u32]) {
        for (i, &s) in source.iter().enumerate() {
            if s != OWN {
                let l = start + i * stride;
                *self.datum.add(l) = row.datum[BORDER + i];
                if let FeetAccess::PerNode(feet) = self.feet {
                    *feet.add(l) = std::array::from_fn(|b| row.foot[b][BORDER + i]);
                }
            }
        }
    }

    /// Grid index of node `first` and the stride along `axis`, checking
    /// that the row from `first` along `axis` lies in the grid.
    fn row_start(&self, spec: &GridSpec<D>, first: [usize; D], axis: usize) -> (usize, usize) {
        let (start, stride) = (spec.linear(first), spec.strides()[axis]);
        assert!(start + (spec.dims[axis] - 1 - first[axis]) * stride < self.len);
        (start, stride)
    }
}
