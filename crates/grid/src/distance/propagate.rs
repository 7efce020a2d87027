//! Stage 2 of the unsigned distance: closest data for the nodes outside
//! the exact band.
//!
//! **Line passes.** For each axis in turn, every grid line parallel to it
//! gathers the data its nodes hold, each with its foot point, and gives
//! every node of the line the nearest of them. Along the line a foot at
//! coordinate `v`, at squared distance `c` from the line, is at squared
//! distance `(t - v)² + c` from the node at `t`; the nearest foot per node
//! is the lower envelope of these parabolas, found in one ordered walk.
//! After the D axes every node has been offered data from every node:
//! this is the separable Euclidean distance transform, exact for data on
//! grid lines. Data off the lines rank slightly differently seen from a
//! line than from a node off it, so a node can end with a datum a little
//! farther than the nearest (measured: up to 0.1-0.3 h far from the data
//! after two rounds). Lines are independent, so they run in parallel and
//! the result does not depend on the thread count.
//!
//! **Settling near the data.** Within [`NEAR_CELLS`] cells of segments and
//! triangles, Jacobi rounds of neighbour offers bring the nodes to a local
//! fixed point (see [`settle_near`]). Points need none: their exact band
//! already covers that region, because dense samples hide points between
//! the nodes, where no propagation can find them.

use super::band::Node;
use super::primitives::dist2;
use super::{DataSet, NO_DATUM};
use crate::spec::for_each_in_box;
use crate::GridSpec;
use rayon::prelude::*;

/// Within this many cells of the data, distances are exact for points
/// (their exact band reaches this far) and settled to a local fixed point
/// for segments and triangles.
pub const NEAR_CELLS: f64 = 5.0;

/// Rounds of passes over all axes. The second round brings data found by
/// the last axis back to the first: far-field errors drop from up to ~1 h
/// to ~0.1-0.3 h on the test data, for about a third more time.
const PASS_ROUNDS: usize = 2;

/// Give every node outside the band (squared distance above
/// `final_below`) a closest datum: line passes, then settling near the data.
pub(super) fn propagate_closest<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    final_below: f64,
    nodes: &mut [Node<D>],
) {
    for axis in (0..D).cycle().take(D * PASS_ROUNDS) {
        line_passes(spec, final_below, nodes, axis);
    }
    // Candidates are upper bounds, off by a fraction of a cell.
    let near = ((NEAR_CELLS + 1.0) * spec.spacing).powi(2);
    if data.points.len() < data.len() {
        settle_near(data, spec, final_below, near, nodes);
    }
}

/// A foot point offered along a line: `(t - v)² + c` at line coordinate `t`.
#[derive(Clone, Copy)]
struct Site<const D: usize> {
    v: f64,
    c: f64,
    datum: u32,
    foot: [f64; D],
}

/// The envelope pass over every line parallel to `axis`.
fn line_passes<const D: usize>(
    spec: &GridSpec<D>,
    final_below: f64,
    nodes: &mut [Node<D>],
    axis: usize,
) {
    // Lines across axis 0 go in bundles of neighbours along axis 0, so that
    // gathering them reads whole runs of memory rather than one node per
    // cache line.
    const BUNDLE: usize = 16;
    let strides = spec.strides();
    let bundle = if axis == 0 { 1 } else { BUNDLE };
    let mut outer = spec.dims;
    outer[axis] = 1;
    outer[0] = outer[0].div_ceil(bundle);
    let mut bundles = Vec::with_capacity(spec.node_count() / spec.dims[axis] / bundle + 1);
    for_each_in_box([0; D], outer.map(|n| n - 1), |idx| {
        let mut first = *idx;
        first[0] *= bundle;
        let width = bundle.min(spec.dims[0] - first[0]);
        bundles.push((spec.linear(first), width));
    });
    let shared = LineAccess::new(nodes);
    let (len, stride) = (spec.dims[axis], strides[axis]);
    bundles.par_iter().for_each_init(
        || (vec![Vec::new(); bundle], Vec::new(), Vec::new()),
        |(lines, sites, hull), &(start, width)| {
            // SAFETY: each bundle of lines is visited by one task only, and
            // lines parallel to one axis share no node.
            for line in &mut lines[..width] {
                line.clear();
            }
            for j in 0..len {
                for (b, line) in lines[..width].iter_mut().enumerate() {
                    line.push(unsafe { shared.get(start + j * stride + b) });
                }
            }
            for (b, line) in lines[..width].iter_mut().enumerate() {
                let base = spec.position(spec.unlinear(start + b));
                if lower_envelope(line, &base, axis, sites, hull) {
                    assign_nearest(line, &base, axis, spec.spacing, final_below, sites, hull);
                    for (j, node) in line.iter().enumerate() {
                        unsafe { shared.set(start + j * stride + b, *node) };
                    }
                }
            }
        },
    );
}

/// Collect the sites of a line (nodes from `base` along `axis`) and build
/// their lower envelope in `hull`: (site index, coordinate where it starts
/// to be the lowest). Returns false when the line holds no datum.
fn lower_envelope<const D: usize>(
    line: &[Node<D>],
    base: &[f64; D],
    axis: usize,
    sites: &mut Vec<Site<D>>,
    hull: &mut Vec<(usize, f64)>,
) -> bool {
    sites.clear();
    for node in line {
        let last = sites.last().map(|s: &Site<D>| (s.datum, s.foot));
        if node.datum == NO_DATUM || last == Some((node.datum, node.foot)) {
            continue;
        }
        let c = (0..D)
            .filter(|&b| b != axis)
            .map(|b| (base[b] - node.foot[b]).powi(2))
            .sum();
        sites.push(Site {
            v: node.foot[axis],
            c,
            datum: node.datum,
            foot: node.foot,
        });
    }
    if sites.is_empty() {
        return false;
    }
    sites.sort_unstable_by(|a, b| {
        (a.v, a.c, a.datum)
            .partial_cmp(&(b.v, b.c, b.datum))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    hull.clear();
    hull.push((0, f64::NEG_INFINITY));
    for (q, site) in sites.iter().enumerate().skip(1) {
        loop {
            let &(top, from) = hull.last().expect("the hull keeps its first site");
            let h = &sites[top];
            if site.v == h.v {
                // Same vertex, larger or equal c (sorted): never lower.
                break;
            }
            // Where the parabolas of `h` and `site` cross.
            let cross = 0.5 * (site.v + h.v) + 0.5 * (site.c - h.c) / (site.v - h.v);
            if hull.len() > 1 && cross <= from {
                hull.pop();
            } else {
                hull.push((q, cross));
                break;
            }
        }
    }
    true
}

/// Give every non-final node of the line the lowest site at its coordinate
/// when it beats the node's own datum.
fn assign_nearest<const D: usize>(
    line: &mut [Node<D>],
    base: &[f64; D],
    axis: usize,
    spacing: f64,
    final_below: f64,
    sites: &[Site<D>],
    hull: &[(usize, f64)],
) {
    let mut k = 0;
    for (j, node) in line.iter_mut().enumerate() {
        let t = base[axis] + j as f64 * spacing;
        while k + 1 < hull.len() && hull[k + 1].1 < t {
            k += 1;
        }
        if node.d2 <= final_below {
            continue;
        }
        let site = &sites[hull[k].0];
        let d2 = (t - site.v).powi(2) + site.c;
        if d2 < node.d2 || (d2 == node.d2 && site.datum < node.datum) {
            *node = Node {
                d2,
                foot: site.foot,
                datum: site.datum,
            };
        }
    }
}

/// Jacobi rounds over the nodes near the data: an open node is offered
/// the data of all 3^D - 1 neighbours (diagonals matter: a Voronoi cell
/// can be thinner than a cell), and the neighbours of a changed node open
/// for the next round. Ends when a round changes nothing: then every near
/// node has tried the datum of every neighbour. Reading all before writing
/// keeps the result independent of the thread count.
fn settle_near<const D: usize>(
    data: &DataSet<D>,
    spec: &GridSpec<D>,
    final_below: f64,
    near: f64,
    nodes: &mut [Node<D>],
) {
    let in_scope = |n: &Node<D>| n.d2 > final_below && n.d2 <= near;
    let neighbours = Neighbours::new(spec);
    let mut open: Vec<u32> = (0..nodes.len() as u32)
        .into_par_iter()
        .filter(|&l| in_scope(&nodes[l as usize]))
        .collect();
    while !open.is_empty() {
        let changes: Vec<(u32, Node<D>)> = open
            .par_iter()
            .filter_map(|&l| {
                let idx = spec.unlinear(l as usize);
                let p = spec.position(idx);
                let mut node = nodes[l as usize];
                let mut changed = false;
                // Neighbours in a row often share a datum: offer it once.
                let mut offered = NO_DATUM;
                for (m, step) in neighbours.of(idx) {
                    let n = &nodes[m];
                    if n.datum != offered {
                        offered = n.datum;
                        changed |= offer(data, &p, &mut node, n.datum, &n.foot, step);
                    }
                }
                changed.then_some((l, node))
            })
            .collect();
        for &(l, node) in &changes {
            nodes[l as usize] = node;
        }
        open = changes
            .par_iter()
            .flat_map_iter(|&(l, _)| neighbours.of(spec.unlinear(l as usize)).map(|(m, _)| m))
            .filter(|&m| in_scope(&nodes[m]))
            .map(|m| m as u32)
            .collect();
        open.par_sort_unstable();
        open.dedup();
    }
}

/// Offer datum `c`, whose foot for a node `step` away is `foot`, to `node`
/// at `p`: adopt it, with its own exact foot, if it is nearer (ties: the
/// smaller index). Returns whether it did.
#[inline(always)]
fn offer<const D: usize>(
    data: &DataSet<D>,
    p: &[f64; D],
    node: &mut Node<D>,
    c: u32,
    foot: &[f64; D],
    step: f64,
) -> bool {
    if c == NO_DATUM || c == node.datum {
        return false;
    }
    let mut d2 = dist2(p, foot);
    if c as usize >= data.points.len() {
        // Feet on one convex datum of nodes `step` apart are at most `step`
        // apart, so the exact distance is at least this.
        if d2.sqrt() - step >= node.d2.sqrt() {
            return false;
        }
        d2 = data.distance_squared(c as usize, p);
    }
    if d2 < node.d2 || (d2 == node.d2 && c < node.datum) {
        node.foot = data.closest_point(c as usize, p);
        node.d2 = dist2(p, &node.foot);
        node.datum = c;
        return true;
    }
    false
}

/// The 3^D - 1 axis and diagonal neighbours of a node.
struct Neighbours<const D: usize> {
    dims: [usize; D],
    strides: [usize; D],
    /// Step per axis (-1, 0, 1) and length, per neighbour.
    steps: Vec<([isize; D], f64)>,
}

impl<const D: usize> Neighbours<D> {
    fn new(spec: &GridSpec<D>) -> Self {
        let mut steps = Vec::new();
        for_each_in_box([0; D], [2; D], |code| {
            let step = code.map(|c| c as isize - 1);
            let axes = step.iter().filter(|&&s| s != 0).count();
            if axes > 0 {
                steps.push((step, spec.spacing * (axes as f64).sqrt()));
            }
        });
        Neighbours {
            dims: spec.dims,
            strides: spec.strides(),
            steps,
        }
    }

    /// (linear index, distance) of the neighbours of node `idx` in the grid.
    fn of(&self, idx: [usize; D]) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.steps.iter().filter_map(move |(step, len)| {
            let mut l = 0;
            for a in 0..D {
                let i = idx[a]
                    .checked_add_signed(step[a])
                    .filter(|&i| i < self.dims[a])?;
                l += i * self.strides[a];
            }
            Some((l, *len))
        })
    }
}

/// Shared access to the nodes for parallel passes over disjoint lines:
/// each node is read and written by one task only (the caller's contract
/// on `get` and `set`).
struct LineAccess<'a, const D: usize> {
    ptr: *mut Node<D>,
    len: usize,
    _nodes: std::marker::PhantomData<&'a mut [Node<D>]>,
}

// SAFETY: access goes through `get`/`set`, whose callers guarantee that no
// node is touched by two tasks.
unsafe impl<const D: usize> Sync for LineAccess<'_, D> {}

impl<'a, const D: usize> LineAccess<'a, D> {
    fn new(nodes: &'a mut [Node<D>]) -> Self {
        LineAccess {
            ptr: nodes.as_mut_ptr(),
            len: nodes.len(),
            _nodes: std::marker::PhantomData,
        }
    }

    /// # Safety
    /// No other task touches node `l` meanwhile.
    #[inline(always)]
    unsafe fn get(&self, l: usize) -> Node<D> {
        assert!(l < self.len);
        *self.ptr.add(l)
    }

    /// # Safety
    /// No other task touches node `l` meanwhile.
    #[inline(always)]
    unsafe fn set(&self, l: usize, node: Node<D>) {
        assert!(l < self.len);
        *self.ptr.add(l) = node;
    }
}
