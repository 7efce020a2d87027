//! Stage 2 of the unsigned distance: closest data for the nodes outside
//! the exact band.
//!
//! **Cone sweeps** (see `cone_sweep`): plane by plane along each axis,
//! forward and backward, every node takes the nearest foot among its own
//! and those of its neighbours in the plane before. One round reaches
//! every node; far from the data a node can end with a datum slightly
//! farther than the nearest (measured: up to ~0.08 h from points, more
//! from segments and triangles, whose far values are distances to feet).
//!
//! **Settling near the data.** Within [`NEAR_CELLS`] cells, Jacobi rounds
//! of neighbour offers with exact distances bring the nodes to a local
//! fixed point (see [`Settle::run`]): there every node has tried the datum
//! of every neighbour. The sweeps rank data by their feet, which for
//! dense samples and for segments and triangles are often not the nearest.

use super::band::{cells_dist2, to_cells, unit_normal, Closest};
use super::{DataSet, NO_DATUM};
use crate::spec::for_each_in_box;
use crate::GridSpec;
use rayon::prelude::*;

/// Within this many cells of the data, distances are settled to a local
/// fixed point.
pub const NEAR_CELLS: f64 = 5.0;

/// Give every node outside the band (squared distance above `final_below`,
/// in cells²) a closest datum: cone sweeps, then settling near the data.
pub(super) fn propagate_closest<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    final_below: f32,
    closest: &mut Closest<D>,
) {
    super::cone_sweep::cone_sweeps(spec, final_below, closest);
    // Candidates are upper bounds, off by a fraction of a cell.
    let near = ((NEAR_CELLS + 1.0) as f32).powi(2);
    if !data.only_points() {
        Settle::new(data, spec, final_below).run(near, closest);
    }
}

/// A node's candidate: datum, foot (grid coordinates) and squared
/// distance to the foot in cells².
#[derive(Clone, Copy)]
struct Candidate<const D: usize> {
    datum: u32,
    foot: [f32; D],
    d2: f32,
}

impl<const D: usize> Candidate<D> {
    /// Is (`d2`, `datum`) better: nearer, ties to the smaller index?
    #[inline(always)]
    fn beaten_by(&self, d2: f32, datum: u32) -> bool {
        d2 < self.d2 || (d2 == self.d2 && datum < self.datum)
    }
}

/// The settling of the nodes near segments and triangles (see
/// [`Settle::run`]).
struct Settle<'a, const D: usize> {
    data: &'a DataSet<D>,
    spec: &'a GridSpec<D>,
    neighbours: Neighbours<D>,
    /// Nodes at most this far from their foot (cells²) are final.
    final_below: f32,
    /// Per triangle (3D only): unit normal and offset of its plane, whose
    /// distance bounds the triangle's from below.
    planes: Vec<Option<([f64; D], f64)>>,
}

impl<'a, const D: usize> Settle<'a, D> {
    fn new(data: &'a DataSet<D>, spec: &'a GridSpec<D>, final_below: f32) -> Self {
        let planes = data
            .triangles
            .par_iter()
            .map(|t| unit_normal(t).map(|(n, a)| (n, (0..D).map(|c| n[c] * a[c]).sum::<f64>())))
            .collect();
        Settle {
            data,
            spec,
            neighbours: Neighbours::new(spec),
            final_below,
            planes,
        }
    }

    /// Jacobi rounds over the nodes near the data (squared distance in
    /// `final_below..=near`, cells², when they start). In the first round
    /// each is offered the data of all its neighbours, evaluated exactly;
    /// afterwards, only the data of neighbours changed by the last round.
    /// Ends when a round changes nothing: then every near node has tried
    /// the datum of every neighbour (an offer refused once stays refused,
    /// as a node only gets nearer data). Reading all before writing keeps
    /// the result independent of the thread count.
    fn run(&self, near: f32, closest: &mut Closest<D>) {
        let scope = nodes_in_shell(self.spec, closest, self.final_below, near);
        // Feet passed on from neighbours are not this node's nearest point
        // of its datum: project once, so offers compare exact distances.
        let own: Vec<[f32; D]> = scope
            .par_iter()
            .map(|&l| self.exact_foot(closest.datum[l as usize], l as usize).0)
            .collect();
        for (&l, foot) in scope.iter().zip(own) {
            closest.set(l as usize, closest.datum[l as usize], foot);
        }
        // Nodes changed by the last round (all count before the first), and
        // the nodes next to them.
        let mut fresh = vec![true; closest.datum.len()];
        let mut beside = vec![false; closest.datum.len()];
        let mut changed: Vec<u32> = Vec::new();
        let mut open = scope.clone();
        loop {
            let changes: Vec<(u32, Candidate<D>)> = open
                .par_iter()
                .filter_map(|&l| {
                    self.settle_node(closest, &fresh, l as usize)
                        .map(|c| (l, c))
                })
                .collect();
            if changes.is_empty() {
                return;
            }
            if changed.is_empty() {
                fresh.fill(false);
            }
            self.mark_beside(&changed, &mut beside, false);
            for &l in &changed {
                fresh[l as usize] = false;
            }
            changed.clear();
            for &(l, c) in &changes {
                closest.set(l as usize, c.datum, c.foot);
                fresh[l as usize] = true;
                changed.push(l);
            }
            self.mark_beside(&changed, &mut beside, true);
            open = scope
                .par_iter()
                .copied()
                .filter(|&l| beside[l as usize])
                .collect();
        }
    }

    /// Set `beside` to `mark` at the neighbours of `nodes`.
    fn mark_beside(&self, nodes: &[u32], beside: &mut [bool], mark: bool) {
        for &l in nodes {
            let idx = self.neighbours.unlinear(l as usize);
            for (m, _) in self.neighbours.of(idx, l as usize) {
                beside[m] = mark;
            }
        }
    }

    /// Nearest point of datum `c` to node `l`, in grid coordinates, and
    /// the node's grid coordinates.
    fn exact_foot(&self, c: u32, l: usize) -> ([f32; D], [f32; D]) {
        let idx = self.neighbours.unlinear(l);
        let p = self.spec.position(idx);
        let foot = to_cells(self.spec, &self.data.closest_point(c as usize, &p));
        (foot, idx.map(|i| i as f32))
    }

    /// A lower bound of the squared distance (cells²) from node `p` to
    /// datum `c`, offered by a neighbour `step` cells away whose foot on it
    /// lies `reach` cells² from `p`.
    fn bound_by_foot(&self, c: u32, reach: f32, step: f32) -> f32 {
        if (c as usize) < self.data.points.len() {
            // A point is its own foot.
            return reach;
        }
        // Feet on one convex datum of nodes `step` apart are at most `step`
        // apart.
        (reach.sqrt() - step).max(0.0).powi(2)
    }

    /// Squared distance (cells²) from `world` to the plane of datum `c`
    /// when it is a triangle (3D), else 0: a lower bound either way.
    fn bound_by_plane(&self, c: u32, world: &[f64; D]) -> f32 {
        let first_triangle = self.data.points.len() + self.data.segments.len();
        let plane = (c as usize)
            .checked_sub(first_triangle)
            .and_then(|t| self.planes[t]);
        let Some((n, offset)) = plane else {
            return 0.0;
        };
        let height = ((0..D).map(|a| n[a] * world[a]).sum::<f64>() - offset) / self.spec.spacing;
        (height * height) as f32
    }

    /// The best of node `l`'s own datum and the data of its neighbours that
    /// are `fresh`, evaluated exactly; `None` when its own stays.
    fn settle_node(&self, closest: &Closest<D>, fresh: &[bool], l: usize) -> Option<Candidate<D>> {
        let idx = self.neighbours.unlinear(l);
        let p = idx.map(|i| i as f32);
        let mut best = Candidate {
            datum: closest.datum[l],
            foot: closest.foot(l),
            d2: closest.d2(l, &p),
        };
        if best.d2 <= self.final_below {
            // Its closest datum lies in the exact band, which offered it.
            return None;
        }
        let own = best.datum;
        // The distinct data offered, each with a lower bound of its squared
        // distance; evaluated nearest bound first, while below the best.
        let mut offers = [(0u32, 0f32); 26];
        let mut count = 0;
        for (m, step) in self.neighbours.of(idx, l) {
            let c = closest.datum[m];
            if !fresh[m] || c == NO_DATUM || c == own {
                continue;
            }
            let lower = self.bound_by_foot(c, closest.d2(m, &p), step);
            match offers[..count].iter_mut().find(|(d, _)| *d == c) {
                Some(offer) => offer.1 = offer.1.max(lower),
                None => {
                    offers[count] = (c, lower);
                    count += 1;
                }
            }
        }
        let offers = &mut offers[..count];
        let world = self.spec.position(idx);
        for (c, lower) in offers.iter_mut() {
            *lower = lower.max(self.bound_by_plane(*c, &world));
        }
        offers.sort_unstable_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        for &(c, lower) in offers.iter() {
            if lower > best.d2 {
                break;
            }
            let (foot, _) = self.exact_foot(c, l);
            let d2 = cells_dist2(&p, &foot);
            if best.beaten_by(d2, c) {
                best = Candidate { datum: c, foot, d2 };
            }
        }
        (best.datum != own).then_some(best)
    }
}

/// The nodes whose squared distance to their foot lies in `above..=upto`
/// (cells²), ascending; one layer of the last axis per parallel task.
fn nodes_in_shell<const D: usize>(
    spec: &GridSpec<D>,
    closest: &Closest<D>,
    above: f32,
    upto: f32,
) -> Vec<u32> {
    let last = D - 1;
    let layer = spec.strides()[last];
    (0..spec.dims[last])
        .into_par_iter()
        .flat_map_iter(|k| {
            let (mut first, mut end) = ([0; D], spec.dims.map(|n| n - 1));
            (first[last], end[last]) = (k, k);
            let mut nodes = Vec::new();
            let mut l = k * layer;
            for_each_in_box(first, end, |idx| {
                let d2 = closest.d2(l, &idx.map(|i| i as f32));
                if d2 > above && d2 <= upto {
                    nodes.push(l as u32);
                }
                l += 1;
            });
            nodes
        })
        .collect()
}

/// The 3^D - 1 axis and diagonal neighbours of the nodes of a grid.
pub(super) struct Neighbours<const D: usize> {
    dims: [usize; D],
    /// Per neighbour: step per axis (-1, 0, 1), linear offset, length in
    /// cells.
    steps: Vec<([isize; D], isize, f32)>,
}

impl<const D: usize> Neighbours<D> {
    pub fn new(spec: &GridSpec<D>) -> Self {
        let strides = spec.strides();
        let mut steps = Vec::new();
        for_each_in_box([0; D], [2; D], |code| {
            let step = code.map(|c| c as isize - 1);
            let axes = step.iter().filter(|&&s| s != 0).count();
            if axes == 0 {
                return;
            }
            let offset = (0..D).map(|a| step[a] * strides[a] as isize).sum();
            steps.push((step, offset, (axes as f32).sqrt()));
        });
        Neighbours {
            dims: spec.dims,
            steps,
        }
    }

    #[inline(always)]
    pub fn unlinear(&self, mut l: usize) -> [usize; D] {
        std::array::from_fn(|a| {
            let i = l % self.dims[a];
            l /= self.dims[a];
            i
        })
    }

    /// (linear index, distance in cells) of the neighbours of node `idx`
    /// (linear index `l`) in the grid.
    #[inline(always)]
    pub fn of(&self, idx: [usize; D], l: usize) -> impl Iterator<Item = (usize, f32)> + '_ {
        let interior = (0..D).all(|a| idx[a] > 0 && idx[a] + 1 < self.dims[a]);
        self.steps.iter().filter_map(move |&(step, offset, len)| {
            let inside = interior
                || (0..D).all(|a| {
                    idx[a]
                        .checked_add_signed(step[a])
                        .is_some_and(|i| i < self.dims[a])
                });
            inside.then(|| ((l as isize + offset) as usize, len))
        })
    }
}
