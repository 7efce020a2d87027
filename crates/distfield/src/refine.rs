//! Error-driven repair of a unified field's feature points.
//!
//! Construction knows the mesh, so it can see where the extracted surface
//! strays from it. The rules that pick one point per cell (corners first,
//! the point whose fan passes nearest the cell's features, ...) fail
//! where several features crowd a few cells: two lines through one cell,
//! a line leaving a corner that a sample holds, a line through a cell
//! the surface does not cross. There the surface's error is measured, in
//! both directions, over the block of cells around each place above a
//! target, and the crossed cells of the block try other points: their
//! own candidates, points on the features of neighbours the surface does
//! not cross, the QEF point of their crossings where those bend (also at
//! creases gentler than the feature angle), or none; where that is not
//! enough, a sample near the surface may turn to its other side, and in
//! cells crossed by two feature lines a sample may move onto the line
//! the cell's point does not keep (an offset field's sample in the
//! unified field). What brings the block's surface nearest the mesh is
//! kept, up to three changes per place. Sculpting repairs its changed
//! cells the same way against the exact result ([`Exact`]).

use crate::extract::corner_nodes;
use crate::extract::SampledField;
use crate::features::{cell_of, closest_on_segment, nudge_into, thinned_by_cell, CellFeatures};
use crate::offset::THINNED;
use crate::offset::{may_take, node_position, stays_convex};
use crate::query::{lattice_points, MeshQuery};
use crate::sharp::{clamp_near, is_sharp, owner_cell, Tangent};
use crate::unified::{crop, sample_points, storage_for, Extra, UnifiedField};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};
use surfrecon_geom::metrics::closest_point_on_triangle;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::topology::Neighbourhood;
use surfrecon_grid::GridSpec;

/// Points on the mesh (its vertices and six points inside each triangle,
/// thinned on coarse grids) by the cell containing them.
pub(crate) struct MeshSamples {
    by_cell: HashMap<usize, Vec<DVec3>>,
}

/// The exact surface a field is repaired against.
pub(crate) trait Exact: Sync {
    /// Signed distance to the surface (negative inside).
    fn signed_distance(&self, p: DVec3) -> f64;
    /// The surface's crossings of `cell`'s sign-changing edges with its
    /// outward normals there.
    fn tangents(&self, field: &UnifiedField, cell: usize) -> Vec<Tangent>;
}

impl Exact for MeshQuery {
    fn signed_distance(&self, p: DVec3) -> f64 {
        MeshQuery::signed_distance(self, p)
    }
    fn tangents(&self, field: &UnifiedField, cell: usize) -> Vec<Tangent> {
        crate::unified::crossing_tangents(field, self, cell)
    }
}

impl MeshSamples {
    /// In cells holding more than [`DENSE_CELL`] points, at most one per
    /// [`THINNED`]-th of a cell along each axis, vertices first (as the
    /// offset field's repair measures everywhere).
    pub(crate) fn new(mesh: &TriMesh, spec: &GridSpec<3>) -> Self {
        Self {
            by_cell: thinned_by_cell(spec, mesh_points(mesh), THINNED, DENSE_CELL),
        }
    }

    /// `points` on the surface, binned by cell.
    pub(crate) fn from_points(spec: &GridSpec<3>, points: impl Iterator<Item = DVec3>) -> Self {
        let mut by_cell: HashMap<usize, Vec<DVec3>> = HashMap::new();
        for p in points {
            if let Some(c) = cell_of(spec, p) {
                by_cell.entry(c).or_default().push(p);
            }
        }
        Self { by_cell }
    }

    fn in_cells(&self, cells: impl Iterator<Item = usize>) -> Vec<DVec3> {
        cells
            .filter_map(|c| self.by_cell.get(&c))
            .flatten()
            .copied()
            .collect()
    }
}

/// A mesh's vertices and six points inside each of its triangles.
pub(crate) fn mesh_points(mesh: &TriMesh) -> impl Iterator<Item = DVec3> + Clone + '_ {
    let inner = (0..mesh.triangles.len()).flat_map(|t| lattice_points(mesh.corners(t), 3));
    mesh.vertices.iter().copied().chain(inner)
}

/// Points a cell keeps unthinned (see [`MeshSamples::new`]): as many as
/// a surface crossing it leaves in its [`THINNED`]³ sub-cells at most,
/// about: fandisk at 64 cells keeps every point (its field is the same
/// as unthinned), at 8 and 16 cells it is thinned.
const DENSE_CELL: usize = 64;

/// What [`repair`] changed.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Repaired {
    /// Places whose block was measured above the target.
    pub places: usize,
    /// Cells whose feature point changed or was removed.
    pub changed: usize,
}

/// Error (in spacings) above which the surface around a place is
/// repaired. The repair measures six points per triangle; fandisk's
/// max, measured with 16, was 0.101 h with 0.1, 0.100 h with 0.09 and
/// 0.089 h with 0.08 (43 places instead of about 10).
pub(crate) const TARGET: f64 = 0.08;

/// Tries at a place beyond which, if none helps, its neighbours are
/// skipped (fandisk: 50-73 around its crowded feature lines, 5-12 along
/// creases).
const CROWDED: usize = 24;
/// Changes made one after another at a place while each lowers its
/// error (a turned sample may need another point next to it).
const ROUNDS: usize = 3;
/// Candidate points tried per feature cell (spread over its candidates).
const CANDIDATES_PER_CELL: usize = 4;
/// Cosine of the angle between crossing normals above which a cell's
/// crossings' QEF point is tried (10°: fandisk has creases of 28°, below
/// the feature angle, that cost 0.14 h).
pub(crate) const CREASE_COS: f64 = 0.984_807_753_012_208;
/// Points tried per neighbour the surface does not cross.
const NEIGHBOUR_CANDIDATES: usize = 4;

/// Repair the feature points around every place where the surface of
/// `field` strays from the mesh by more than `target` spacings (see the
/// module doc). `cells` are the mesh's features by cell.
pub(crate) fn repair(
    field: &mut UnifiedField,
    query: &impl Exact,
    samples: &MeshSamples,
    cells: &BTreeMap<usize, CellFeatures>,
    creased: &[usize],
    target: f64,
) -> Repaired {
    let spec = field.spec;
    let mut report = Repaired::default();
    // A crop must fit in the grid.
    if spec.dims.iter().any(|&d| d < SIDE) {
        return report;
    }
    // Places next to one where many tries (crowded features) helped
    // nothing would repeat most of them, at a cost.
    let mut hopeless: Vec<[usize; 3]> = Vec::new();
    let places = places_above(field, query, samples, cells, creased, target * spec.spacing);
    for wave in waves(&spec, &places) {
        let todo: Vec<usize> = wave
            .into_iter()
            .filter(|&c| {
                let idx = spec.unlinear(c);
                !hopeless
                    .iter()
                    .any(|o| (0..3).all(|a| idx[a].abs_diff(o[a]) <= 1))
            })
            .collect();
        let outcomes: Vec<Outcome> = todo
            .par_iter()
            .map(|&c| repair_place(field, query, samples, cells, c, target))
            .collect();
        for (&c, outcome) in todo.iter().zip(outcomes) {
            for (n, action) in &outcome.changes {
                apply(field, *n, action);
            }
            report.places += outcome.measured as usize;
            report.changed += outcome.changes.len();
            if outcome.hopeless {
                hopeless.push(spec.unlinear(c));
            }
        }
    }
    report
}

/// `places` in waves: each place comes one wave after the last earlier
/// place whose repair may touch what its own reads or changes, so the
/// places of a wave may be repaired together and each sees every change
/// it would see were they repaired one after another, in order.
fn waves(spec: &GridSpec<3>, places: &[usize]) -> Vec<Vec<usize>> {
    let reach: Vec<Reach> = places.iter().map(|&c| Reach::of(spec, c)).collect();
    let mut wave_of: Vec<usize> = Vec::with_capacity(places.len());
    let mut waves: Vec<Vec<usize>> = Vec::new();
    for (i, &c) in places.iter().enumerate() {
        let wave = (0..i)
            .filter(|&j| reach[i].touches(&reach[j]))
            .map(|j| wave_of[j] + 1)
            .max()
            .unwrap_or(0);
        wave_of.push(wave);
        if wave == waves.len() {
            waves.push(Vec::new());
        }
        waves[wave].push(c);
    }
    waves
}

/// The samples (inclusive index ranges per axis) the repair of a place
/// may read and change.
struct Reach {
    reads: [[usize; 2]; 3],
    changes: [[usize; 2]; 3],
}

impl Reach {
    fn of(spec: &GridSpec<3>, c: usize) -> Self {
        let idx = spec.unlinear(c);
        let lo = crop_origin(spec, idx);
        // Changes: the corners of the block's cells; reads: the crop and
        // the checks of a change (one sample around them).
        Self {
            reads: std::array::from_fn(|a| {
                [
                    lo[a].min(idx[a].saturating_sub(2)),
                    (lo[a] + SIDE - 1).max(idx[a] + 3),
                ]
            }),
            changes: std::array::from_fn(|a| [idx[a].saturating_sub(1), idx[a] + 2]),
        }
    }

    /// Whether either may change what the other reads.
    fn touches(&self, other: &Reach) -> bool {
        let meet = |x: &[[usize; 2]; 3], y: &[[usize; 2]; 3]| {
            (0..3).all(|a| x[a][0] <= y[a][1] && y[a][0] <= x[a][1])
        };
        meet(&self.changes, &other.reads) || meet(&self.reads, &other.changes)
    }
}

/// The first sample of the crop around the cell at `idx`: the crop stays
/// inside the grid (beside its border there is nothing it leaves out).
fn crop_origin(spec: &GridSpec<3>, idx: [usize; 3]) -> [usize; 3] {
    std::array::from_fn(|a| idx[a].saturating_sub(MARGIN).min(spec.dims[a] - SIDE))
}

/// What [`repair_place`] did at a place.
#[derive(Default)]
struct Outcome {
    /// Its block was measured above the target.
    measured: bool,
    /// The changes kept, in order.
    changes: Vec<(usize, Action)>,
    /// Many tries, none helped.
    hopeless: bool,
}

/// Repair the place at cell `c` of `field` (up to [`ROUNDS`] changes, on
/// a copy made at the first), and say what to apply.
fn repair_place(
    field: &UnifiedField,
    query: &impl Exact,
    samples: &MeshSamples,
    cells: &BTreeMap<usize, CellFeatures>,
    c: usize,
    target: f64,
) -> Outcome {
    let spec = field.spec;
    let h = spec.spacing;
    let mut view = std::borrow::Cow::Borrowed(field);
    let mut outcome = Outcome::default();
    let idx = spec.unlinear(c);
    let lo = crop_origin(&spec, idx);
    for round in 0..ROUNDS {
        let local = crop(&view, lo, SIDE);
        let centre = local.spec.linear(std::array::from_fn(|a| idx[a] - lo[a]));
        let to_local = |n: usize| {
            let at = spec.unlinear(n);
            local.spec.linear(std::array::from_fn(|a| at[a] - lo[a]))
        };
        let place = Place::new(&local, query, samples, centre, &spec);
        let now = place
            .error(&local, query, f64::INFINITY)
            .unwrap_or(f64::INFINITY);
        if now <= target * h {
            break;
        }
        outcome.measured |= round == 0;
        // A sample is a corner of up to eight cells of the block:
        // it is turned or moved once.
        let mut moved = std::collections::HashSet::new();
        let tried: Vec<(usize, Action)> = block(&spec, c, 1)
            .filter(|&n| view.crosses(n))
            .flat_map(|n| {
                actions(&view, query, cells, n)
                    .into_iter()
                    .map(move |a| (n, a))
            })
            .filter(|&(n, a)| match a {
                Action::Turn(k) => moved.insert((corner_nodes(&spec, n)[k], None)),
                Action::Snap {
                    corner,
                    point,
                    inside,
                } => {
                    let key = Some((point.to_array().map(f64::to_bits), inside));
                    moved.insert((corner_nodes(&spec, n)[corner], key))
                }
                _ => true,
            })
            .collect();
        let tries = tried.len();
        // Only a try below both `now` (less the margin a change must
        // gain) and the target can change what is kept (see
        // [`Bound`]): a try whose error already exceeds that, or the
        // best one so far, is left unfinished.
        let evaluate = |list: Vec<(usize, Action)>, bound: &Bound| {
            list.into_par_iter()
                .filter_map(|(n, action)| {
                    let mut trial = local.clone();
                    if !apply(&mut trial, to_local(n), &action) {
                        return None;
                    }
                    let error = place.error(&trial, query, bound.get())?;
                    bound.lower(error);
                    Some((error, n, action))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        };
        let bound = Bound::new((now - GAIN * h).max(target * h));
        // Moving samples is tried only where other points leave the
        // place above the target (most places need none, at half
        // the cost).
        let (moves, points): (Vec<_>, Vec<_>) = tried
            .into_iter()
            .partition(|(_, a)| matches!(a, Action::Turn(_) | Action::Snap { .. }));
        let mut best = evaluate(points, &bound);
        if best.is_none_or(|b| b.0 > target * h) {
            best = best
                .into_iter()
                .chain(evaluate(moves, &bound))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        // Where no single change reaches the target, a whole stretch
        // of a second feature line may need samples on it at once.
        let mut stretch = None;
        if best.is_none_or(|b| b.0 > target * h) {
            stretch = line_snaps(&view, cells, c)
                .into_par_iter()
                .filter_map(|list| {
                    let mut trial = local.clone();
                    let done = list
                        .iter()
                        .filter(|(n, a)| apply(&mut trial, to_local(*n), a))
                        .count();
                    (done > 1).then_some(())?;
                    let error = place.error(&trial, query, bound.get())?;
                    bound.lower(error);
                    Some((error, list))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
        }
        if let Some((error, list)) = stretch {
            if best.is_none_or(|b| error < b.0) && error < now - GAIN * h {
                for (n, action) in &list {
                    apply(view.to_mut(), *n, action);
                }
                outcome.changes.extend(list);
                continue;
            }
        }
        match best.filter(|b| b.0 < now - GAIN * h) {
            Some((_, n, action)) => {
                apply(view.to_mut(), n, &action);
                outcome.changes.push((n, action));
            }
            None => {
                outcome.hopeless = tries > CROWDED && round == 0;
                break;
            }
        }
    }
    outcome
}

/// What a change must lower a place's error by (spacings) to be kept.
const GAIN: f64 = 0.005;

/// The error below which a try at a place can still matter, lowered to
/// the best try's as tries finish (tries run in parallel). A try is only
/// left unfinished once its error is known to exceed the bound, so the
/// best try, and of equal ones the same, is found as if all were
/// finished: the bound never drops below the best try's error. It starts
/// at the larger of `now` less [`GAIN`] (what a kept change must beat)
/// and the target (below which moves are not tried): a best try above it
/// changes nothing either way.
struct Bound(std::sync::atomic::AtomicU64);

impl Bound {
    fn new(start: f64) -> Self {
        // Non-negative floats order as their bits do.
        Self(std::sync::atomic::AtomicU64::new(start.max(0.0).to_bits()))
    }

    fn get(&self) -> f64 {
        f64::from_bits(self.0.load(std::sync::atomic::Ordering::Relaxed))
    }

    fn lower(&self, error: f64) {
        self.0.fetch_min(
            error.max(0.0).to_bits(),
            std::sync::atomic::Ordering::Relaxed,
        );
    }
}

/// One change to a cell's feature points.
#[derive(Debug, Clone, Copy)]
enum Action {
    /// The cell keeps this point alone.
    Replace(DVec3),
    /// The cell keeps no point (its table triangles), nor further ones.
    Remove,
    /// The cell's corner `c` (`x + 2y + 4z`), a sample within
    /// [`TURN_LIMIT`] of the surface, counts as on the other side.
    Turn(usize),
    /// The cell's corner `c` moves onto `point`, a point on a feature of
    /// the cell within the sample's box, at distance 0 on the inside or
    /// the outside.
    Snap {
        corner: usize,
        point: DVec3,
        inside: bool,
    },
    /// The cell keeps its point and adds this one, on its other feature
    /// line (extraction splits the patch between the two).
    Second(DVec3),
}

/// Second points tried per cell crossed by two feature lines.
const SECOND_CANDIDATES: usize = 12;

/// Points on a crowded cell's features tried per corner sample.
const SNAPS_PER_SAMPLE: usize = 2;

/// Samples this close to the surface (in spacings) may be turned to the
/// other side by the repair: the crossings that then collapse onto the
/// sample lie that close to the surface, and which side it takes decides
/// how its cells' crossing loops run (two feature lines a third of a
/// cell apart cross the same loop segment on one side and different
/// ones on the other).
const TURN_LIMIT: f64 = 0.1;

/// What `cell` may try: its own candidates, points on features of
/// neighbours the surface does not cross (within half a cell), the QEF
/// point of its crossings where their normals differ, or no point.
fn actions(
    field: &UnifiedField,
    query: &impl Exact,
    cells: &BTreeMap<usize, CellFeatures>,
    cell: usize,
) -> Vec<Action> {
    let spec = &field.spec;
    let h = spec.spacing;
    let margin = 0.5 * h;
    let now = owned(field, cell);
    let tangents = query.tangents(field, cell);
    let mut out = Vec::new();
    if !now.is_empty() {
        out.push(Action::Remove);
    }
    let corners = corner_nodes(spec, cell);
    out.extend(
        (0..8)
            .filter(|&c| may_turn(field, corners[c]))
            .map(Action::Turn),
    );
    // A flat patch gains nothing from a point on it.
    if is_sharp(&tangents, CREASE_COS) {
        if let Some(q) = crate::sharp::qef_minimizer(&tangents) {
            out.push(Action::Replace(clamp_near(spec, cell, q, margin)));
        }
    }
    let lo = DVec3::from_array(spec.position(spec.unlinear(cell)));
    let reach = |p: &DVec3| {
        let outside = (lo - *p).max(*p - lo - DVec3::splat(h)).max(DVec3::ZERO);
        outside.max_element() <= margin
    };
    for m in block(spec, cell, 1).filter(|&m| m != cell && !field.crosses(m)) {
        if let Some(f) = cells.get(&m) {
            let probes: Vec<DVec3> = f.probes().into_iter().filter(reach).collect();
            let step = (probes.len() / NEIGHBOUR_CANDIDATES).max(1);
            out.extend(
                probes
                    .into_iter()
                    .step_by(step)
                    .map(|p| Action::Replace(clamp_near(spec, cell, p, margin))),
            );
        }
    }
    let Some(f) = cells.get(&cell) else {
        return out;
    };
    if f.lines() > 1 {
        out.extend(snaps(field, cell, &f.probes()));
        if let [first] = now[..] {
            let far: Vec<DVec3> = (f.probes().into_iter())
                .filter(|p| p.distance(first) > h / 3.0)
                .collect();
            let step = (far.len() / SECOND_CANDIDATES).max(1);
            out.extend(
                far.into_iter()
                    .step_by(step)
                    .map(|p| Action::Second(nudge_into(spec, cell, p))),
            );
        }
    }
    let centroid = tangents.iter().map(|t| t.0).sum::<DVec3>() / tangents.len().max(1) as f64;
    let candidates = f.candidates(centroid);
    let step = (candidates.len() / CANDIDATES_PER_CELL).max(1);
    out.extend(
        candidates
            .into_iter()
            .step_by(step)
            .map(|p| Action::Replace(nudge_into(spec, cell, p))),
    );
    out
}

/// The feature points `cell` owns, in the order of the samples storing
/// them.
fn owned(field: &UnifiedField, cell: usize) -> Vec<DVec3> {
    corner_nodes(&field.spec, cell)
        .into_iter()
        .filter_map(|n| match field.extras.get(&(n as u32)) {
            Some(&Extra::FeaturePoint(p)) if owner_cell(&field.spec, n, p) == Some(cell) => Some(p),
            _ => None,
        })
        .collect()
}

/// Whether sample `node` may count as on the other side (see
/// [`Action::Turn`]): near the surface, not moved, and the turn keeps
/// the topology of its cells' surface.
pub(crate) fn may_turn(field: &UnifiedField, node: usize) -> bool {
    let spec = &field.spec;
    let idx = spec.unlinear(node);
    let inner = (0..3).all(|a| idx[a] > 0 && idx[a] + 1 < spec.dims[a]);
    let v = field.values[node];
    inner
        && v.abs() < TURN_LIMIT * spec.spacing
        && !matches!(field.extras.get(&(node as u32)), Some(Extra::Position(_)))
        && may_take(
            &Neighbourhood::new(&spec.strides()),
            node,
            turned(v, spec.spacing),
            |m| field.values[m],
        )
}

/// Where one point per cell keeps one of two feature lines, a sample of
/// the cell moved onto the other line (as an offset field's sample is)
/// makes the crossings of its edges pass through that line: for each
/// corner, the [`SNAPS_PER_SAMPLE`] probes nearest it within its box,
/// on either side.
fn snaps(field: &UnifiedField, cell: usize, probes: &[DVec3]) -> Vec<Action> {
    let spec = &field.spec;
    let half = 0.5 * spec.spacing;
    let mut out = Vec::new();
    for (corner, node) in corner_nodes(spec, cell).into_iter().enumerate() {
        let at = node_position(spec, node);
        let mut near: Vec<DVec3> = probes
            .iter()
            .copied()
            .filter(|p| (*p - at).abs().max_element() < half)
            .collect();
        near.sort_by(|a, b| a.distance(at).total_cmp(&b.distance(at)));
        near.dedup_by(|a, b| a.distance(*b) < 1e-3 * spec.spacing);
        for &point in near.iter().take(SNAPS_PER_SAMPLE) {
            for inside in [true, false] {
                out.push(Action::Snap {
                    corner,
                    point,
                    inside,
                });
            }
        }
    }
    out
}

/// Where two feature lines run through the same cells over a stretch,
/// one point per cell keeps one of them, and moving one sample onto the
/// other (a [`snaps`] try) does not lower the error while the cells
/// beside it still cut that line. So for each feature line through the
/// block around `c` (chains of its cells' pieces), one try moves every
/// sample of the block's crossed cells whose box the line passes through
/// onto the line's point nearest it: keeping its side, all inside, or
/// all outside. Only blocks with a cell crossed by two lines try this.
fn line_snaps(
    field: &UnifiedField,
    cells: &BTreeMap<usize, CellFeatures>,
    c: usize,
) -> Vec<Vec<(usize, Action)>> {
    let spec = &field.spec;
    let half = 0.5 * spec.spacing;
    let around: Vec<usize> = block(spec, c, 1).filter(|&n| field.crosses(n)).collect();
    if !around
        .iter()
        .any(|n| cells.get(n).is_some_and(|f| f.lines() > 1))
    {
        return Vec::new();
    }
    let mut nodes: Vec<usize> = around
        .iter()
        .flat_map(|&n| corner_nodes(spec, n))
        .filter(|n| !matches!(field.extras.get(&(*n as u32)), Some(Extra::Position(_))))
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    let pieces: Vec<[DVec3; 2]> = around
        .iter()
        .filter_map(|n| cells.get(n))
        .flat_map(|f| f.pieces.iter().copied())
        .collect();
    let mut out = Vec::new();
    for line in chains(&pieces, 1e-6 * spec.spacing) {
        let on_line: Vec<(usize, DVec3)> = nodes
            .iter()
            .filter_map(|&n| {
                let at = node_position(spec, n);
                let p = (line.iter())
                    .map(|&[a, b]| closest_on_segment(at, a, b))
                    .min_by(|x, y| x.distance(at).total_cmp(&y.distance(at)))?;
                ((p - at).abs().max_element() < half).then_some((n, p))
            })
            .collect();
        if on_line.len() < 2 {
            continue;
        }
        let sides: [fn(f64) -> bool; 3] = [|v| v < 0.0, |_| true, |_| false];
        for side in sides {
            out.push(
                on_line
                    .iter()
                    .map(|&(n, point)| {
                        let inside = side(field.values[n]);
                        (
                            n,
                            Action::Snap {
                                corner: 0,
                                point,
                                inside,
                            },
                        )
                    })
                    .collect(),
            );
        }
    }
    out
}

/// `pieces` grouped into chains joined end to end (ends within `tolerance`).
fn chains(pieces: &[[DVec3; 2]], tolerance: f64) -> Vec<Vec<[DVec3; 2]>> {
    let n = pieces.len();
    let mut group: Vec<usize> = (0..n).collect();
    fn root(group: &mut [usize], mut i: usize) -> usize {
        while group[i] != i {
            group[i] = group[group[i]];
            i = group[i];
        }
        i
    }
    let touch = |p: &[DVec3; 2], q: &[DVec3; 2]| {
        p.iter()
            .any(|a| q.iter().any(|b| a.distance(*b) <= tolerance))
    };
    for i in 0..n {
        for j in i + 1..n {
            if touch(&pieces[i], &pieces[j]) {
                let (ri, rj) = (root(&mut group, i), root(&mut group, j));
                group[ri] = rj;
            }
        }
    }
    let mut by_root: BTreeMap<usize, Vec<[DVec3; 2]>> = BTreeMap::new();
    for (i, &piece) in pieces.iter().enumerate() {
        let r = root(&mut group, i);
        by_root.entry(r).or_default().push(piece);
    }
    by_root.into_values().collect()
}

/// Move sample `node` onto `point` at distance 0 (see [`Action::Snap`]),
/// if it carries nothing but directed distances (dropped), stays inside
/// the grid, keeps its cells convex and the turn keeps their topology.
fn snap(field: &mut UnifiedField, node: usize, point: DVec3, inside: bool) -> bool {
    let spec = field.spec;
    let idx = spec.unlinear(node);
    let value = if inside { -1e-9 * spec.spacing } else { 0.0 };
    let legal = (0..3).all(|a| idx[a] > 0 && idx[a] + 1 < spec.dims[a])
        && hand_over(field, node)
        && stays_convex(&spec, node, point, |m| field.position(m))
        && may_take(&Neighbourhood::new(&spec.strides()), node, value, |m| {
            field.values[m]
        });
    if legal {
        field.values[node] = value;
        field.extras.insert(node as u32, Extra::Position(point));
    }
    legal
}

/// Whether sample `node` is free to move: it carries nothing but
/// directed distances, or a feature point that another sample of the
/// point's cell can hold (which then gets it).
pub(crate) fn hand_over(field: &mut UnifiedField, node: usize) -> bool {
    let spec = field.spec;
    match field.extras.get(&(node as u32)) {
        None | Some(Extra::Directed(_)) => true,
        Some(Extra::Position(_)) => false,
        Some(&Extra::FeaturePoint(p)) => {
            let Some(cell) = owner_cell(&spec, node, p) else {
                return false;
            };
            let other = corner_nodes(&spec, cell).into_iter().find(|&m| {
                !field.extras.contains_key(&(m as u32)) && owner_cell(&spec, m, p) == Some(cell)
            });
            if let Some(m) = other {
                field.extras.insert(m as u32, Extra::FeaturePoint(p));
                field.extras.remove(&(node as u32));
            }
            other.is_some()
        }
    }
}

/// The value of a sample at `v` turned to the other side, on the surface.
pub(crate) fn turned(v: f64, h: f64) -> f64 {
    if v < 0.0 {
        0.0
    } else {
        -1e-9 * h
    }
}

/// Apply `action` to `cell`; false if no sample can store the point.
fn apply(field: &mut UnifiedField, cell: usize, action: &Action) -> bool {
    let spec = field.spec;
    if let Action::Turn(c) = *action {
        let node = corner_nodes(&spec, cell)[c];
        if !may_turn(field, node) {
            return false;
        }
        field.values[node] = turned(field.values[node], spec.spacing);
        return true;
    }
    if let Action::Snap {
        corner,
        point,
        inside,
    } = *action
    {
        return snap(field, corner_nodes(&spec, cell)[corner], point, inside);
    }
    if let Action::Second(p) = *action {
        let Some(n) = storage_for(field, cell, p) else {
            return false;
        };
        field.extras.insert(n, Extra::FeaturePoint(p));
        return true;
    }
    for n in corner_nodes(&spec, cell) {
        if let Some(&Extra::FeaturePoint(p)) = field.extras.get(&(n as u32)) {
            if owner_cell(&spec, n, p) == Some(cell) {
                field.extras.remove(&(n as u32));
            }
        }
    }
    if let Action::Remove = *action {
        field.cell_points.remove(&(cell as u32));
    }
    match *action {
        Action::Remove | Action::Turn(_) | Action::Snap { .. } | Action::Second(_) => true,
        Action::Replace(p) => match storage_for(field, cell, p) {
            Some(n) => {
                field.extras.insert(n, Extra::FeaturePoint(p));
                true
            }
            None => false,
        },
    }
}

/// The cells within `reach` of `cell` along every axis (itself
/// included), inside the grid.
pub(crate) fn block(
    spec: &GridSpec<3>,
    cell: usize,
    reach: usize,
) -> impl Iterator<Item = usize> + '_ {
    let idx = spec.unlinear(cell);
    let side = 2 * reach + 1;
    (0..side * side * side).filter_map(move |k| {
        let off = [k % side, (k / side) % side, k / (side * side)];
        let mut at = [0usize; 3];
        for a in 0..3 {
            at[a] = (idx[a] + off[a]).checked_sub(reach)?;
            if at[a] + 1 >= spec.dims[a] {
                return None;
            }
        }
        Some(spec.linear(at))
    })
}

/// Samples of margin around a place in the crop [`repair`] scores.
const MARGIN: usize = 3;
/// Samples along each side of that crop.
const SIDE: usize = 2 * MARGIN + 2;

/// A place [`repair`] scores: the surface's error around cell `cell` of
/// a crop, both ways: the surface within a cell of `cell` to the mesh,
/// and the mesh's samples within a cell of it to the surface within two
/// cells.
struct Place {
    cell: usize,
    /// The mesh's samples within a cell of the place.
    samples: Vec<DVec3>,
    /// Distances to the exact surface of the points measured on the
    /// place's surface before any try: most triangles of a try's surface
    /// are the same, and their points need no new query.
    known: HashMap<[u64; 3], f64>,
}

impl Place {
    /// The place around `cell` of the crop `local`; `spec` is the whole
    /// field's grid (the mesh samples are binned by its cells).
    fn new(
        local: &UnifiedField,
        query: &impl Exact,
        samples: &MeshSamples,
        cell: usize,
        spec: &GridSpec<3>,
    ) -> Self {
        let h = spec.spacing;
        let lo = DVec3::from_array(local.spec.position(local.spec.unlinear(cell)));
        let samples = match cell_of(spec, lo + DVec3::splat(0.5 * h)) {
            Some(whole) => samples.in_cells(block(spec, whole, 1)),
            None => Vec::new(),
        };
        let mut place = Place {
            cell,
            samples,
            known: HashMap::new(),
        };
        let (near, _) = place.surface(local);
        let points: Vec<DVec3> = measured_points(&near).collect();
        place.known = points
            .into_par_iter()
            .map(|p| (key(p), query.signed_distance(p).abs()))
            .collect();
        place
    }

    /// The surface of `local` within one and within two cells of the
    /// place (by the triangles' centroids).
    fn surface(&self, local: &UnifiedField) -> (Vec<[DVec3; 3]>, Vec<[DVec3; 3]>) {
        let h = local.spec.spacing;
        let mesh = local.raw_surface();
        let lo = DVec3::from_array(local.spec.position(local.spec.unlinear(self.cell)));
        let within = |t: &[DVec3; 3], reach: f64| {
            let m = (t[0] + t[1] + t[2]) / 3.0;
            m.cmpge(lo - DVec3::splat(reach * h)).all()
                && m.cmple(lo + DVec3::splat((1.0 + reach) * h)).all()
        };
        let wide: Vec<[DVec3; 3]> = (0..mesh.triangles.len())
            .map(|t| mesh.corners(t))
            .filter(|t| within(t, 2.0))
            .collect();
        let near = wide.iter().filter(|t| within(t, 1.0)).copied().collect();
        (near, wide)
    }

    /// The error of `local`'s surface at the place; `None` as soon as it
    /// is known to exceed `bound`.
    fn error(&self, local: &UnifiedField, query: &impl Exact, bound: f64) -> Option<f64> {
        let (near, wide) = self.surface(local);
        let mut off = 0.0f64;
        for p in measured_points(&near) {
            let d = match self.known.get(&key(p)) {
                Some(&d) => d,
                None => query.signed_distance(p).abs(),
            };
            off = off.max(d);
            if off > bound {
                return None;
            }
        }
        farthest_to(&self.samples, &wide, off, bound)
    }
}

/// The points at which the surface is measured against the mesh: each
/// triangle's [`sample_points`] and corners.
fn measured_points(triangles: &[[DVec3; 3]]) -> impl Iterator<Item = DVec3> + '_ {
    sample_points(triangles).chain(triangles.iter().flatten().copied())
}

fn key(p: DVec3) -> [u64; 3] {
    p.to_array().map(f64::to_bits)
}

/// The largest distance from `points` to the triangles, or `floor` if
/// that is larger (points nearer than the largest so far are left as
/// soon as a triangle that near is found; triangles whose bounding
/// sphere lies farther than the nearest so far are skipped). `None` as
/// soon as it is known to exceed `cap`.
fn farthest_to(points: &[DVec3], triangles: &[[DVec3; 3]], floor: f64, cap: f64) -> Option<f64> {
    let spheres: Vec<(DVec3, f64)> = triangles
        .iter()
        .map(|t| {
            let c = (t[0] + t[1] + t[2]) / 3.0;
            (c, t.iter().map(|v| v.distance(c)).fold(0.0, f64::max))
        })
        .collect();
    let mut worst = floor;
    for &p in points {
        let mut nearest = f64::INFINITY;
        for (t, &(c, r)) in triangles.iter().zip(&spheres) {
            if p.distance(c) - r >= nearest {
                continue;
            }
            nearest = nearest.min(p.distance(closest_point_on_triangle(p, *t)));
            if nearest <= worst {
                break;
            }
        }
        worst = worst.max(nearest);
        if worst > cap {
            return None;
        }
    }
    Some(worst)
}

/// Cells near features whose surface (from the whole field) strays from
/// the mesh by more than `limit`, worst first.
fn places_above(
    field: &UnifiedField,
    query: &impl Exact,
    samples: &MeshSamples,
    cells: &BTreeMap<usize, CellFeatures>,
    creased: &[usize],
    limit: f64,
) -> Vec<usize> {
    let spec = field.spec;
    let surface = field.raw_surface();
    let mut by_cell: HashMap<usize, Vec<[DVec3; 3]>> = HashMap::new();
    for t in 0..surface.triangles.len() {
        let tri = surface.corners(t);
        if let Some(c) = cell_of(&spec, (tri[0] + tri[1] + tri[2]) / 3.0) {
            by_cell.entry(c).or_default().push(tri);
        }
    }
    let mut near: Vec<usize> = cells
        .keys()
        .chain(creased)
        .flat_map(|&c| block(&spec, c, 1))
        .collect();
    near.sort_unstable();
    near.dedup();
    let mut errors: Vec<(f64, usize)> = near
        .into_par_iter()
        .filter_map(|c| {
            let own = by_cell.get(&c).map(Vec::as_slice).unwrap_or(&[]);
            let off = sample_points(own)
                .map(|p| query.signed_distance(p).abs())
                .fold(0.0, f64::max);
            let around: Vec<[DVec3; 3]> = block(&spec, c, 1)
                .filter_map(|n| by_cell.get(&n))
                .flatten()
                .copied()
                .collect();
            // Below the limit the error need not be known exactly.
            let e = farthest_to(
                &samples.in_cells(std::iter::once(c)),
                &around,
                off.max(limit),
                f64::INFINITY,
            )?;
            (e > limit).then_some((e, c))
        })
        .collect();
    errors.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    errors.into_iter().map(|(_, c)| c).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Places of one wave never touch; a place touching an earlier one
    /// comes in a later wave (so its repair sees that one's changes).
    #[test]
    fn waves_keep_the_order_of_places_that_touch() {
        let spec = GridSpec {
            origin: [0.0; 3],
            spacing: 1.0,
            dims: [40, 30, 20],
        };
        // A fixed scatter of cells, clusters and the grid's borders included.
        let mut state = 12345u64;
        let mut next = |n: usize| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as usize % n
        };
        let places: Vec<usize> = (0..200)
            .map(|_| spec.linear([next(39), next(29), next(19)]))
            .collect();
        let waves = waves(&spec, &places);
        assert_eq!(waves.iter().map(Vec::len).sum::<usize>(), places.len());
        assert!(waves.len() > 1 && waves.len() < places.len());
        let wave_of = |c: usize| waves.iter().position(|w| w.contains(&c)).unwrap();
        for (i, &a) in places.iter().enumerate() {
            for &b in &places[..i] {
                if a != b && Reach::of(&spec, a).touches(&Reach::of(&spec, b)) {
                    assert!(
                        wave_of(b) < wave_of(a),
                        "{b} touches {a} and comes no earlier"
                    );
                }
            }
        }
        for wave in &waves {
            for (i, &a) in wave.iter().enumerate() {
                for &b in &wave[..i] {
                    assert!(!Reach::of(&spec, a).touches(&Reach::of(&spec, b)));
                }
            }
        }
    }
}
