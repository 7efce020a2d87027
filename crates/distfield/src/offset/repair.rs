//! Error-driven repair of an offset field's samples.
//!
//! The search minimizes a sum of squares over each sample's cells, which
//! is a poor proxy for the largest error: where a feature line bends or
//! two lines meet within a cell, the sum is lowest with the surface a
//! little off everywhere, or far off at one point. Construction knows
//! the mesh, so it measures the surface against it in both directions
//! around the fitted cells, and at each place above [`TARGET`], worst
//! first, lets the samples near the worst point try other positions:
//! small steps, their nearest surface point, feature points in reach,
//! the other side where they lie on the surface. A try is scored by the
//! largest error over every cell it changes and the cells around the
//! place; the best one that lowers it is kept, up to
//! [`MOVES_PER_PLACE`] per place.

use super::{
    cell_triangles, corner_nodes, node_position, on_outer_layer, on_surface_values, Movable, Search,
};
use crate::features::{closest_on_segment, thinned_by_cell, CellFeatures};
use crate::query::lattice_points;
use crate::refine::block;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use surfrecon_geom::metrics::closest_point_on_triangle;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::GridSpec;

/// Dihedral angle above which mesh edges count as creases: the cells
/// around them are measured too (fandisk has 28° creases, below the
/// feature angle, cut by 0.14 h).
pub(crate) const CREASE_ANGLE_DEG: f64 = 20.0;
/// Error (in spacings) above which a place is repaired.
pub(crate) const TARGET: f64 = 0.1;
/// Moves kept at one place at most.
const MOVES_PER_PLACE: usize = 3;
/// Error (in spacings) above which a place where no single move helps
/// tries pairs of moves.
const PAIRS_ABOVE: f64 = 0.125;
/// Feature and crease points one sample tries at most.
const MAX_FEATURE_TRIES: usize = 24;
/// Pairs of moves tried at one place at most.
const MAX_PAIRS: usize = 1000;
/// Least gain (in spacings) for a move to be kept.
const GAIN: f64 = 0.005;
/// Samples within this many spacings of a place's worst point try moves.
const REACH: f64 = 1.2;
/// Measuring points per spacing at most, along each axis.
pub(crate) const THINNED: f64 = 4.0;
/// Distance (in spacings) counted for a mesh point with no surface near.
const FAR: f64 = 2.0;

/// Points on the mesh (its vertices and ten points inside each triangle,
/// the lattice the error measurements use) by the cell containing them.
pub(crate) struct MeshPoints {
    by_cell: HashMap<usize, Vec<DVec3>>,
}

impl MeshPoints {
    /// At most one point per [`THINNED`]-th of a cell along each axis,
    /// vertices first: a mesh much finer than the grid would otherwise
    /// give each measurement thousands of points (fandisk at 16 cells).
    pub(crate) fn new(mesh: &TriMesh, spec: &GridSpec<3>) -> Self {
        let inner = (0..mesh.triangles.len()).flat_map(|t| lattice_points(mesh.corners(t), 4));
        let points = mesh.vertices.iter().copied().chain(inner);
        Self::from_points(spec, points)
    }

    /// [`Self::new`] for points already on the true surface.
    pub(crate) fn from_points(
        spec: &GridSpec<3>,
        points: impl Iterator<Item = DVec3> + Clone,
    ) -> Self {
        Self {
            by_cell: thinned_by_cell(spec, points, THINNED, 0),
        }
    }

    fn in_cell(&self, cell: usize) -> &[DVec3] {
        self.by_cell.get(&cell).map(Vec::as_slice).unwrap_or(&[])
    }
}

/// An error and where it is.
#[derive(Clone, Copy, Debug)]
struct Worst {
    error: f64,
    at: DVec3,
}

impl Worst {
    const NONE: Self = Self {
        error: 0.0,
        at: DVec3::ZERO,
    };

    fn max(self, other: Self) -> Self {
        if other.error > self.error {
            other
        } else {
            self
        }
    }
}

/// The measurements of one field.
struct Gauge<'s, 'a> {
    search: &'s Search<'a>,
    points: &'s MeshPoints,
    /// Mesh edges above [`CREASE_ANGLE_DEG`] by cell.
    creases: &'s BTreeMap<usize, CellFeatures>,
}

/// The triangles of some cells.
type Surface = HashMap<usize, Vec<[DVec3; 3]>>;

impl Gauge<'_, '_> {
    fn spec(&self) -> &GridSpec<3> {
        self.search.spec
    }

    /// The triangles marching cubes makes in each of `cells`.
    fn surface(&self, field: &impl Movable, cells: impl Iterator<Item = usize>) -> Surface {
        cells
            .map(|c| {
                let corners =
                    corner_nodes(self.spec(), c).map(|n| (field.position(n), field.value(n)));
                (c, cell_triangles(&corners))
            })
            .collect()
    }

    /// The largest distance from `triangles` (their corners and a
    /// lattice inside each) to the mesh.
    fn off(&self, triangles: &[[DVec3; 3]]) -> Worst {
        let mut worst = Worst::NONE;
        for p in triangles
            .iter()
            .flat_map(|&t| t.into_iter().chain(lattice_points(t, 4)))
        {
            let d = self.search.query.signed_distance(p).abs();
            if d > worst.error {
                worst = Worst { error: d, at: p };
            }
        }
        worst
    }

    /// The largest distance from the mesh points in `cell` to the
    /// triangles of the cells around it, or `floor` if that is larger
    /// (a point stops at the first triangle nearer than the largest so
    /// far).
    fn back<'t>(
        &self,
        cell: usize,
        surface: &dyn Fn(usize) -> &'t [[DVec3; 3]],
        floor: Worst,
    ) -> Worst {
        let points = self.points.in_cell(cell);
        if points.is_empty() {
            return floor;
        }
        let around: Vec<[DVec3; 3]> = block(self.spec(), cell, 1)
            .flat_map(|c| surface(c).iter().copied())
            .collect();
        let mut worst = floor;
        let far = FAR * self.spec().spacing;
        for &p in points {
            let mut nearest = far;
            for t in &around {
                nearest = nearest.min(p.distance(closest_point_on_triangle(p, *t)));
                if nearest <= worst.error {
                    break;
                }
            }
            if nearest > worst.error {
                worst = Worst {
                    error: nearest,
                    at: p,
                };
            }
        }
        worst
    }
}

/// Repair the samples of `field` around every place where its surface
/// strays from the mesh by more than [`TARGET`] spacings (see the module
/// doc). Returns the places above it and how many moves were kept.
pub(crate) fn repair(
    search: &Search,
    field: &mut impl Movable,
    points: &MeshPoints,
    creases: &BTreeMap<usize, CellFeatures>,
) -> (usize, usize) {
    let gauge = Gauge {
        search,
        points,
        creases,
    };
    let spec = *search.spec;
    let h = spec.spacing;
    let fitted: BTreeSet<usize> = (search.cells.keys().chain(creases.keys()))
        .flat_map(|&c| block(&spec, c, 1))
        .collect();
    let surface = gauge.surface(&*field, fitted.iter().flat_map(|&c| block(&spec, c, 1)));
    let empty: Vec<[DVec3; 3]> = Vec::new();
    let of = |c: usize| surface.get(&c).unwrap_or(&empty).as_slice();
    let fitted: Vec<usize> = fitted.into_iter().collect();
    let mut places: Vec<(f64, usize)> = fitted
        .par_iter()
        .map(|&c| (gauge.back(c, &of, gauge.off(of(c))).error, c))
        .filter(|&(e, _)| e > TARGET * h)
        .collect();
    places.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut kept = 0;
    for &(_, place) in &places {
        for _ in 0..MOVES_PER_PLACE {
            match best_move(&gauge, &*field, place) {
                Some(m) => {
                    for (n, p, v) in m {
                        field.set(n, p, v);
                    }
                    kept += 1;
                }
                None => break,
            }
        }
    }
    (places.len(), kept)
}

/// The move of a sample near `place`'s worst point that lowers the
/// largest error over the cells around the place and those the move
/// changes, by at least [`GAIN`], most; None if the place is within
/// [`TARGET`] or nothing helps.
fn best_move(gauge: &Gauge, field: &impl Movable, place: usize) -> Option<Move> {
    let spec = gauge.spec();
    let h = spec.spacing;
    // A move changes cells up to three from the place (a neighbour put
    // back on its node), whose errors see the triangles two further.
    let surface = gauge.surface(field, block(spec, place, 5));
    let empty: Vec<[DVec3; 3]> = Vec::new();
    let of = |c: usize| surface.get(&c).unwrap_or(&empty).as_slice();
    let worst = gauge.back(place, &of, gauge.off(of(place)));
    if worst.error <= TARGET * h {
        return None;
    }
    let around: Vec<usize> = block(spec, place, 1).collect();
    let samples: BTreeSet<usize> = around
        .iter()
        .flat_map(|&c| corner_nodes(spec, c))
        .filter(|&n| !on_outer_layer(spec, n) && field.position(n).distance(worst.at) <= REACH * h)
        .collect();
    let samples: Vec<usize> = samples.into_iter().collect();
    let moves: Vec<Move> = samples
        .par_iter()
        .flat_map_iter(|&n| tries(gauge, field, n))
        .collect();
    // Per move, its own cells and those whose mesh points may find their
    // nearest triangle there, with the cells around the place.
    let cells_of = |m: &Move| -> (BTreeSet<usize>, BTreeSet<usize>) {
        let own: BTreeSet<usize> = (m.iter())
            .flat_map(|&(n, _, _)| gauge.search.cells_around(n))
            .collect();
        let touched = (own.iter())
            .flat_map(|&c| block(spec, c, 1))
            .chain(around.iter().copied())
            .collect();
        (own, touched)
    };
    let cells: Vec<(BTreeSet<usize>, BTreeSet<usize>)> = moves.iter().map(cells_of).collect();
    let region: BTreeSet<usize> = cells.iter().flat_map(|(_, t)| t.iter().copied()).collect();
    let now: HashMap<usize, (Worst, Worst)> = region
        .into_par_iter()
        .map(|c| (c, (gauge.off(of(c)), gauge.back(c, &of, Worst::NONE))))
        .collect();
    let errors_now = |c: usize| {
        now.get(&c)
            .copied()
            .unwrap_or_else(|| (gauge.off(of(c)), gauge.back(c, &of, Worst::NONE)))
    };
    let gain = |m: &Move, own: &BTreeSet<usize>, touched: &BTreeSet<usize>| {
        let mut old = Worst::NONE;
        let mut new = Worst::NONE;
        for &c in touched {
            let (o, b) = errors_now(c);
            old = old.max(o).max(b);
            if !own.contains(&c) {
                new = new.max(o);
            }
        }
        let view = Overlay {
            base: field,
            moves: m.clone(),
        };
        let changed: Surface = gauge.surface(&view, own.iter().copied());
        let after = |c: usize| changed.get(&c).map_or_else(|| of(c), Vec::as_slice);
        for &c in own {
            new = new.max(gauge.off(after(c)));
        }
        // A try stops once it cannot gain enough.
        for &c in touched {
            if old.error - new.error < GAIN * h {
                break;
            }
            new = gauge.back(c, &after, new);
        }
        old.error - new.error
    };
    let gains: Vec<f64> = (moves.par_iter().zip(&cells))
        .map(|(m, (own, touched))| gain(m, own, touched))
        .collect();
    if let Some(k) = largest(&gains, GAIN * h) {
        return Some(moves[k].clone());
    }
    if worst.error <= PAIRS_ABOVE * h {
        return None;
    }
    // A sample moved onto a corner may cut the line it leaves until a
    // second sample moves onto that line: try such pairs, with the first
    // moves of largest single gain, about [`MAX_PAIRS`] (coarse grids,
    // whose cells hold many corners, offer tens of thousands).
    let mut firsts: Vec<usize> = (0..moves.len())
        .filter(|&k| onto_corner(gauge.search, &moves[k]))
        .collect();
    firsts.sort_by(|&a, &b| gains[b].total_cmp(&gains[a]).then(a.cmp(&b)));
    let seconds_per_first = moves.len().max(1);
    firsts.truncate(MAX_PAIRS.div_ceil(seconds_per_first));
    firsts.sort_unstable();
    let pairs: Vec<Move> = (firsts.iter().map(|&k| &moves[k]))
        .flat_map(|first| {
            let view = Overlay {
                base: field,
                moves: first.clone(),
            };
            let moved = first.last().map(|m| m.0);
            (samples.iter())
                .filter(|&&n| Some(n) != moved)
                .flat_map(|&n| tries(gauge, &view, n))
                .map(|second| [first.clone(), second].concat())
                .collect::<Vec<Move>>()
        })
        .collect();
    let gains: Vec<f64> = pairs
        .par_iter()
        .map(|m| {
            let (own, touched) = cells_of(m);
            gain(m, &own, &touched)
        })
        .collect();
    largest(&gains, GAIN * h).map(|k| pairs[k].clone())
}

/// The index of the largest of `gains` of at least `least`, the first of
/// equal ones.
fn largest(gains: &[f64], least: f64) -> Option<usize> {
    (0..gains.len())
        .filter(|&k| gains[k] >= least)
        .fold(None, |best, k| match best {
            Some(b) if gains[b] >= gains[k] => Some(b),
            _ => Some(k),
        })
}

/// Whether the last sample of `m` goes onto a corner or bend of a
/// feature line in its cells.
fn onto_corner(search: &Search, m: &Move) -> bool {
    let Some(&(n, p, _)) = m.last() else {
        return false;
    };
    (search.cells_around(n))
        .filter_map(|c| search.cells.get(&c))
        .any(|f| f.corners.iter().chain(&f.bends).any(|&q| q == p))
}

/// Samples to move, in order: (sample, position, value).
type Move = Vec<(usize, DVec3, f64)>;

/// A field seen with some of its samples moved.
struct Overlay<'f, F> {
    base: &'f F,
    moves: Move,
}

impl<F: Movable> Movable for Overlay<'_, F> {
    fn value(&self, node: usize) -> f64 {
        let moved = self.moves.iter().rev().find(|m| m.0 == node);
        moved.map_or_else(|| self.base.value(node), |m| m.2)
    }
    fn position(&self, node: usize) -> DVec3 {
        let moved = self.moves.iter().rev().find(|m| m.0 == node);
        moved.map_or_else(|| self.base.position(node), |m| m.1)
    }
    fn set(&mut self, node: usize, position: DVec3, value: f64) {
        self.moves.push((node, position, value));
    }
}

/// The legal moves sample `n` may try: steps of h/8 and h/4 along the
/// axes, its nearest surface point, feature points in its cells, and the
/// other side where it lies on the surface. A position that would make a
/// cell concave is tried with a neighbour put back on its node first,
/// where that makes room (a sample off its node can block the way to a
/// corner just inside the next box).
fn tries(gauge: &Gauge, field: &impl Movable, n: usize) -> Vec<Move> {
    let search = gauge.search;
    let spec = search.spec;
    let h = spec.spacing;
    let here = field.position(n);
    let mut places: Vec<DVec3> = vec![here, search.query.closest_point(here)];
    for step in [0.125 * h, 0.25 * h] {
        for k in 0..6 {
            let mut d = DVec3::ZERO;
            d[k / 2] = if k % 2 == 0 { step } else { -step };
            places.push(here + d);
        }
    }
    let home = node_position(spec, n);
    let reach = 0.5 * h * (1.0 - 1e-9);
    let in_reach = |p: &DVec3| (*p - home).abs().max_element() <= reach;
    // Points on features and creases: their cells' corners and bends, and
    // the points of their pieces nearest the sample; the nearest
    // [`MAX_FEATURE_TRIES`] of them (a coarse cell holds dozens).
    let mut on_features = search.feature_points_near(n, here);
    for f in search.cells_around(n).filter_map(|c| gauge.creases.get(&c)) {
        on_features.extend(f.corners.iter().chain(&f.bends));
        on_features.extend(
            f.pieces
                .iter()
                .map(|&[a, b]| closest_on_segment(here, a, b)),
        );
    }
    on_features.retain(in_reach);
    if on_features.len() > MAX_FEATURE_TRIES {
        on_features.sort_by(|a, b| a.distance(here).total_cmp(&b.distance(here)));
        on_features.dedup();
        on_features.truncate(MAX_FEATURE_TRIES);
    }
    places.extend(on_features);
    let mut out = Vec::new();
    for p in places.into_iter().filter(in_reach) {
        let first: Move = if search.stays_convex(field, n, p) {
            Vec::new()
        } else {
            match make_room(search, field, n, p) {
                Some(m) => vec![m],
                None => continue,
            }
        };
        let view = Overlay {
            base: field,
            moves: first.clone(),
        };
        for v in on_surface_values(search.query.signed_distance(p), h) {
            if first.is_empty() && (p, v) == (here, field.value(n)) {
                continue;
            }
            if let Some(v) = search.same_topology(&view, n, v) {
                let mut m = first.clone();
                m.push((n, p, v));
                out.push(m);
            }
        }
    }
    out
}

/// A neighbour of `n` put back on its node (legally) so that `n` may go
/// to `p` keeping every cell convex, if one does.
fn make_room(
    search: &Search,
    field: &impl Movable,
    n: usize,
    p: DVec3,
) -> Option<(usize, DVec3, f64)> {
    let spec = search.spec;
    let h = spec.spacing;
    let neighbours: BTreeSet<usize> = (search.cells_around(n))
        .flat_map(|c| corner_nodes(spec, c))
        .filter(|&m| m != n && !on_outer_layer(spec, m))
        .collect();
    neighbours.into_iter().find_map(|m| {
        let home = node_position(spec, m);
        if field.position(m) == home || !search.stays_convex(field, m, home) {
            return None;
        }
        let v = on_surface_values(search.query.signed_distance(home), h)
            .into_iter()
            .find_map(|v| search.same_topology(field, m, v))?;
        let view = Overlay {
            base: field,
            moves: vec![(m, home, v)],
        };
        search.stays_convex(&view, n, p).then_some((m, home, v))
    })
}
