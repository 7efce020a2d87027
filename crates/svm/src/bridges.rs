//! Thin parts the meshing grid misses: where f is negative in a tube
//! narrower than a grid cell (a cone's tip, a thin wire), grid nodes fall
//! outside it and marching cubes cuts the tube into separate crumbs, or
//! drops them as specks, although f's inside is one piece. Before marching
//! cubes, every piece of inside nodes but the largest is joined to a nearby
//! other piece when f is negative all along the straight segment between
//! an inside node of each, by a chain of edge-adjacent nodes set inside:
//! the mesh then keeps f's topology there, as a tube about half a cell
//! thick (the part itself is thinner than a cell, so no grid shows it
//! faithfully).
//!
//! Only straight joins are checked: between two inside nodes of a convex
//! part (a cone, a cylinder) the segment stays inside, while for separate
//! parts (two bodies, a stray blob) f turns positive on the way. Where f
//! pinches a sampled part (a cone's tip beyond a positive blip), the join
//! is also allowed if the data run on across the pinch: an input point
//! lies within half a cell of every check point where f is not negative.
//!
//! A part thinner than a cell can also lie between the nodes altogether
//! (a fin's rim, a cone's tip): [`join_and_reach_thin_parts`] then sets
//! the nodes next to its samples inside, where f shows the part just
//! behind them.
//!
//! The other way round, f can leave a sheet about a cell thick barely open
//! across a node or few (a fin entering a body at an acute angle):
//! [`fill_pinholes`] closes such holes, which the grid cannot show either.

use crate::cells::{FastMap, FastSet};
use crate::mesh::Implicit;
use crate::mesh::SPECK_CELLS;
use glam::DVec3;
use surfrecon_geom::disjoint_sets::DisjointSets;
use surfrecon_geom::spatial::KdTree;
use surfrecon_grid::pieces::node_path;
use surfrecon_grid::GridSpec;

/// Farthest two inside nodes may be apart, in cells, to be joined (4:
/// harness spikes non-uniform kept a cone tip 5 cells off the body).
pub const BRIDGE_CELLS: i64 = 6;

/// f is checked along a join at this fraction of a cell.
const CHECK_STEP: f64 = 0.25;

/// Value given to the nodes of a join, in cells (inside): the tube then
/// passes about a quarter of a cell around the chain.
const BRIDGE_DEPTH: f64 = 0.25;

/// The six face neighbours of a node.
const FACES: [[i64; 3]; 6] = [
    [1, 0, 0],
    [-1, 0, 0],
    [0, 1, 0],
    [0, -1, 0],
    [0, 0, 1],
    [0, 0, -1],
];

/// Node values of the band by packed node coordinates.
struct Band<'a> {
    nodes: &'a mut Vec<([usize; 3], f64)>,
    index: FastMap<usize>,
    dims: [usize; 3],
}

impl<'a> Band<'a> {
    fn new(nodes: &'a mut Vec<([usize; 3], f64)>, dims: [usize; 3]) -> Self {
        let index = nodes
            .iter()
            .enumerate()
            .map(|(i, (n, _))| (pack(n.map(|c| c as i64)), i))
            .collect();
        Band { nodes, index, dims }
    }

    fn value(&self, n: [i64; 3]) -> Option<f64> {
        self.slot(n).map(|i| self.nodes[i].1)
    }

    fn slot(&self, n: [i64; 3]) -> Option<usize> {
        let inside = (0..3).all(|a| n[a] >= 0 && (n[a] as usize) < self.dims[a]);
        inside.then(|| self.index.get(&pack(n)).copied()).flatten()
    }

    /// Set node `n` inside to at least `depth` (adding it when not yet
    /// evaluated).
    fn set_inside(&mut self, n: [i64; 3], depth: f64) {
        match self.slot(n) {
            Some(i) => self.nodes[i].1 = self.nodes[i].1.min(-depth),
            None => {
                self.index.insert(pack(n), self.nodes.len());
                self.nodes.push((n.map(|c| c as usize), -depth));
            }
        }
    }
}

fn pack(n: [i64; 3]) -> u64 {
    n[0] as u64 | (n[1] as u64) << 21 | (n[2] as u64) << 42
}

/// Where f turns positive on a join, a sample within this many cells of
/// every such point still allows it: the data run on across the gap, so
/// f pinches a sampled part there (harness spikes outliers: the +x cone's
/// tip a crumb beyond such a pinch, samples within 0.2 cells of its
/// axis). Two separate bodies two cells apart leave the gap's middle a
/// cell from their samples, so they stay apart. Noisy seeds may lie
/// their noise farther off (see [`bridge_thin_parts`]).
const SAMPLED_GAP_CELLS: f64 = 0.5;

/// Join the pieces of inside nodes of `nodes` that `model` joins below the
/// grid's resolution (see the module doc), or that the data `seeds` join
/// across a pinch of f: a seed within [`SAMPLED_GAP_CELLS`] plus
/// `data_noise` (the data's RMS distance from the surface) of every point
/// where f is not negative. Noise scatters a thin part's samples off its wall
/// and the fit then pinches it below the noise's scale (harness spikes
/// with 0.25% and 1% noise: the +x cone, 1.4 cells thick at its root, cut
/// there over 2.4 cells, its nearest cleaned samples up to 1.25 cells off
/// the axis). Returns the number of joins. Nodes added by a join are
/// appended (the caller sorts).
pub fn bridge_thin_parts(
    model: &(impl Implicit + ?Sized),
    spec: &GridSpec<3>,
    seeds: &KdTree,
    data_noise: f64,
    nodes: &mut Vec<([usize; 3], f64)>,
) -> usize {
    let mut band = Band::new(nodes, spec.dims);
    let (inside, mut pieces) = inside_pieces(&band);
    let candidates = join_candidates(&band, &inside, &mut pieces);
    if candidates.is_empty() {
        return 0;
    }
    // Check every candidate's segment in one batch of evaluations.
    let position = |i: usize| DVec3::from_array(spec.position(band.nodes[i].0));
    let mut samples = Vec::new();
    let mut ranges = Vec::new();
    for c in &candidates {
        let (pa, pb) = (position(c.from), position(c.to));
        let steps = ((pa.distance(pb) / (CHECK_STEP * spec.spacing)).ceil() as usize).max(2);
        let start = samples.len();
        samples.extend((1..steps).map(|k| pa.lerp(pb, k as f64 / steps as f64)));
        ranges.push(start..samples.len());
    }
    let values = model.values_grouped(&samples, &[(0..samples.len() as u32).collect()]);
    let sampled = |p: DVec3| {
        seeds
            .nearest(p)
            .is_some_and(|n| n.distance <= SAMPLED_GAP_CELLS * spec.spacing + data_noise)
    };
    // Inside all along, or sampled wherever f is not.
    let inside_all_along = |k: usize| {
        ranges[k]
            .clone()
            .all(|i| values[i] < 0.0 || sampled(samples[i]))
    };
    // Pairs of pieces nearest first; per pair the shortest join inside.
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by_key(|&k| (candidates[k].nearest, candidates[k].squared, k));
    let mut joins = 0;
    for k in order {
        let c = candidates[k];
        if pieces.find(c.from) == pieces.find(c.to) || !inside_all_along(k) {
            continue;
        }
        pieces.union(c.from, c.to);
        let (na, nb) = (band.nodes[c.from].0, band.nodes[c.to].0);
        for n in node_path(na.map(|v| v as i64), nb.map(|v| v as i64)) {
            band.set_inside(n, BRIDGE_DEPTH * spec.spacing);
        }
        joins += 1;
    }
    joins
}

/// A node where f is positive by less than this many cells may lie in a
/// sheet f leaves pinched open (see [`fill_pinholes`]).
const PINCH_CELLS: f64 = 0.25;

/// Nodes a pinhole may span at most (in the sheet's plane).
const PINHOLE_NODES: usize = 4;

/// Holes through a sheet narrower than the grid can show, where f all but
/// closes: where a sheet about a cell thick meets a body at an acute angle
/// (harness spikes: the fin's thin end where it enters the sphere), the
/// fit's inside can fall just short of the sheet's middle, f dipping
/// between its faces to barely above 0 (+0.0001 over a node or two, the
/// cell 0.024), and marching cubes opens a hole through the sheet there: a
/// handle the shape does not have. Such a pinhole is a face-connected
/// set of at most [`PINHOLE_NODES`] nodes in one grid plane across an
/// axis, each positive by less than [`PINCH_CELLS`] and lower than both
/// its neighbours along that axis (a dip through the sheet) or than one
/// with the other inside and outside beyond (the sheet's inside stepping
/// to the next node layer there: spikes' fin at 0.25 % noise, 0.015 thick
/// where f barely closes), ringed in that plane by inside nodes. Its
/// nodes are set inside as a join's are, as a speck of f (a piece a cell
/// or two wide) is dropped. A gap between
/// two surfaces is no dip (f rises towards its middle), and a wider hole
/// or one where f stays clearly positive is kept. Returns the number of
/// nodes filled.
pub fn fill_pinholes(spec: &GridSpec<3>, nodes: &mut Vec<([usize; 3], f64)>) -> usize {
    let mut band = Band::new(nodes, spec.dims);
    let depth = PINCH_CELLS * spec.spacing;
    let mut filled: Vec<[i64; 3]> = Vec::new();
    for axis in 0..3 {
        let dips: FastSet = (0..band.nodes.len())
            .filter(|&i| dips_across(&band, i, axis, depth))
            .map(|i| pack(band.nodes[i].0.map(|c| c as i64)))
            .collect();
        let mut seen = FastSet::default();
        for i in 0..band.nodes.len() {
            let start = band.nodes[i].0.map(|c| c as i64);
            if !dips.contains(&pack(start)) || !seen.insert(pack(start)) {
                continue;
            }
            if let Some(hole) = ringed_pinhole(&band, &dips, &mut seen, start, axis) {
                filled.extend(hole);
            }
        }
    }
    for &n in &filled {
        band.set_inside(n, BRIDGE_DEPTH * spec.spacing);
    }
    filled.len()
}

/// Whether node `i` is positive by less than `depth` and lies in a sheet
/// f leaves pinched open along `axis`: lower than both its neighbours
/// along it (the sheet's middle layer dips), or a step: lower than one of
/// them, the other inside with outside beyond it (a sheet thinner than a
/// cell crossing between two node layers: its inside steps from one layer
/// to the next, and where the step's node falls just short of 0 the two
/// layers' inside nodes touch only across a cell's diagonal, which
/// marching cubes opens into a hole). Inside two nodes deep is a thick
/// body's face, whose dimples are no holes; both neighbours inside is a
/// gap between two surfaces.
fn dips_across(band: &Band, i: usize, axis: usize, depth: f64) -> bool {
    let (n, v) = band.nodes[i];
    if !(0.0..depth).contains(&v) {
        return false;
    }
    let along = |d: i64| {
        let mut m = n.map(|c| c as i64);
        m[axis] += d;
        band.value(m)
    };
    let higher = |d: i64| along(d).is_some_and(|w| w > v);
    let one_node_thick =
        |d: i64| along(d).is_some_and(|w| w < 0.0) && along(2 * d).is_some_and(|w| w > 0.0);
    (higher(-1) && higher(1))
        || (higher(-1) && one_node_thick(1))
        || (higher(1) && one_node_thick(-1))
}

/// The face-connected set of `dips` in the plane across `axis` through
/// `start` (marked in `seen`), if it has at most [`PINHOLE_NODES`] nodes
/// and every other in-plane neighbour of it is inside.
fn ringed_pinhole(
    band: &Band,
    dips: &FastSet,
    seen: &mut FastSet,
    start: [i64; 3],
    axis: usize,
) -> Option<Vec<[i64; 3]>> {
    let in_plane: Vec<[i64; 3]> = FACES.iter().filter(|d| d[axis] == 0).copied().collect();
    let mut hole = vec![start];
    let mut ringed = true;
    let mut k = 0;
    while k < hole.len() {
        let n = hole[k];
        k += 1;
        for d in &in_plane {
            let m = [n[0] + d[0], n[1] + d[1], n[2] + d[2]];
            if dips.contains(&pack(m)) {
                if seen.insert(pack(m)) {
                    hole.push(m);
                }
            } else if !band.value(m).is_some_and(|w| w < 0.0) {
                ringed = false;
            }
        }
    }
    (ringed && hole.len() <= PINHOLE_NODES).then_some(hole)
}

/// How far behind a sample (against ∇f), in cells, f must be negative
/// for the sample to lie on a part thinner than a cell.
const BEHIND: [f64; 3] = [0.25, 0.5, 0.75];

/// A cell behind the sample f must be positive again: the part ends within
/// a cell. A thick body whose surface only clips the cell is left alone
/// (f there is about −1 cell), so its mesh is not pushed outward.
const THROUGH: f64 = 1.0;

/// Samples on a part thinner than a cell that no grid node reaches: where
/// the part narrows under a cell (a fin's rim, a cone's tip) all corners of
/// a sample's cell can lie outside f although f is negative just behind
/// the sample, and marching cubes then ends the part short of its data
/// (harness spikes at 300k points: the +x cone's tip 6.7% of the diagonal
/// off, the fin's rim 0.8%). For each such sample (all corners of its cell
/// evaluated and outside, f negative a fraction of a cell behind it along
/// −∇f and positive again a cell behind), the corner nearest that inside
/// point is set inside as a join's nodes are, if it connects to the inside
/// nodes, so the mesh reaches the sample as a sheet or tube about half a
/// cell thick, which the refinement onto the points then fits. Returns the
/// number of joins and of nodes left set. The reach runs before the joins:
/// on a tip f cuts into crumbs, the nodes grown from the crumbs let the
/// joins tie them to the body (300k spikes: the +x cone reached to x 2.07
/// rather than 1.95). `data_noise` as in [`bridge_thin_parts`].
pub fn join_and_reach_thin_parts(
    model: &(impl Implicit + ?Sized),
    spec: &GridSpec<3>,
    seeds: &[DVec3],
    data_noise: f64,
    nodes: &mut Vec<([usize; 3], f64)>,
) -> (usize, usize) {
    let anchors = nodes_of_pieces_beyond_specks(&Band::new(nodes, spec.dims));
    let mut band = Band::new(nodes, spec.dims);
    let wanted = nodes_to_reach_thin_samples(model, spec, seeds, &band);
    // The nodes to set, with their values (to undo a set, see below).
    let set: Vec<([i64; 3], f64)> = wanted
        .into_iter()
        .filter_map(|n| band.value(n).filter(|&v| v >= 0.0).map(|v| (n, v)))
        .collect();
    let depth = BRIDGE_DEPTH * spec.spacing;
    grow_from_inside(&mut band, set.iter().map(|(n, _)| *n).collect(), depth);
    let joins = bridge_thin_parts(model, spec, &KdTree::new(seeds), data_noise, nodes);
    let reached = keep_where_anchored(&mut Band::new(nodes, spec.dims), &anchors, &set);
    (joins, reached)
}

/// The nodes to set inside so that the mesh reaches samples on parts
/// thinner than a cell (see [`join_and_reach_thin_parts`]).
fn nodes_to_reach_thin_samples(
    model: &(impl Implicit + ?Sized),
    spec: &GridSpec<3>,
    seeds: &[DVec3],
    band: &Band,
) -> Vec<[i64; 3]> {
    let missed: Vec<(DVec3, [i64; 3])> = seeds
        .iter()
        .filter_map(|&p| {
            let cell = cell_of(spec, p)?;
            all_corners_outside(band, cell).then_some((p, cell))
        })
        .collect();
    if missed.is_empty() {
        return Vec::new();
    }
    let points: Vec<DVec3> = missed.iter().map(|(p, _)| *p).collect();
    let inward: Vec<DVec3> = model
        .gradients(&points)
        .into_iter()
        .map(|g| -g.normalize_or_zero())
        .collect();
    // f behind each sample at the depths of BEHIND, then at THROUGH.
    let depths: Vec<f64> = BEHIND.iter().copied().chain([THROUGH]).collect();
    let probes: Vec<DVec3> = points
        .iter()
        .zip(&inward)
        .flat_map(|(&p, &d)| depths.iter().map(move |&t| p + d * (t * spec.spacing)))
        .collect();
    let groups = probes_by_block(&missed, depths.len());
    let values = model.values_grouped(&probes, &groups);
    let mut wanted: Vec<[i64; 3]> = Vec::new();
    for (k, (_, cell)) in missed.iter().enumerate() {
        if inward[k] == DVec3::ZERO {
            continue;
        }
        let row = &values[k * depths.len()..(k + 1) * depths.len()];
        let (behind, through) = row.split_at(BEHIND.len());
        let Some(deepest) = (0..BEHIND.len())
            .filter(|&j| behind[j] < 0.0)
            .min_by(|&a, &b| behind[a].total_cmp(&behind[b]))
        else {
            continue;
        };
        if through[0] <= 0.0 {
            continue;
        }
        let inside_point = probes[k * depths.len() + deepest];
        wanted.push(nearest_corner(spec, *cell, inside_point));
    }
    wanted.sort_unstable();
    wanted.dedup();
    wanted
}

/// Sets inside those of the `wanted` nodes that connect, through face
/// neighbours among them, to a node already inside.
fn grow_from_inside(band: &mut Band, mut wanted: Vec<[i64; 3]>, depth: f64) {
    loop {
        let touches_inside = |n: &[i64; 3]| {
            FACES.iter().any(|d| {
                band.value([n[0] + d[0], n[1] + d[1], n[2] + d[2]])
                    .is_some_and(|v| v < 0.0)
            })
        };
        let (ready, waiting): (Vec<_>, Vec<_>) = wanted.into_iter().partition(touches_inside);
        if ready.is_empty() {
            return;
        }
        for n in ready {
            band.set_inside(n, depth);
        }
        wanted = waiting;
    }
}

/// Of the nodes `set` (with their values before), those now inside stay so
/// only on pieces holding an `anchor` (a node of a piece beyond a speck's
/// size before the reach, or joined to one); the others get their values
/// back: grown from a crumb of f that no join ties to the body, they would
/// make it a piece of its own beside the part (harness spikes with holes:
/// past a cone's tip, where f itself ends short of the data). Returns how
/// many stay set.
fn keep_where_anchored(band: &mut Band, anchors: &FastSet, set: &[([i64; 3], f64)]) -> usize {
    let anchored = nodes_of_anchored_pieces(band, anchors);
    let mut kept = 0;
    for &(n, before) in set {
        let Some(i) = band.slot(n) else { continue };
        if band.nodes[i].1 >= 0.0 {
            continue;
        }
        if anchored.contains(&pack(n)) {
            kept += 1;
        } else {
            band.nodes[i].1 = before;
        }
    }
    kept
}

/// The face-connected pieces of inside nodes: (inside node slots, sets).
fn inside_pieces(band: &Band) -> (Vec<usize>, DisjointSets) {
    let inside: Vec<usize> = (0..band.nodes.len())
        .filter(|&i| band.nodes[i].1 < 0.0)
        .collect();
    let mut pieces = DisjointSets::new(band.nodes.len());
    for &i in &inside {
        let n = band.nodes[i].0.map(|c| c as i64);
        for d in FACES {
            let m = [n[0] + d[0], n[1] + d[1], n[2] + d[2]];
            if let Some(j) = band.slot(m).filter(|&j| band.nodes[j].1 < 0.0) {
                pieces.union(i, j);
            }
        }
    }
    (inside, pieces)
}

/// Packed coordinates of the inside nodes whose face-connected piece spans
/// at least [`SPECK_CELLS`] (its box's diagonal, in cells).
fn nodes_of_pieces_beyond_specks(band: &Band) -> FastSet {
    let (inside, mut pieces) = inside_pieces(band);
    let mut boxes: FastMap<([usize; 3], [usize; 3])> = FastMap::default();
    for &i in &inside {
        let n = band.nodes[i].0;
        let b = boxes.entry(pieces.find(i) as u64).or_insert((n, n));
        b.0 = std::array::from_fn(|a| b.0[a].min(n[a]));
        b.1 = std::array::from_fn(|a| b.1[a].max(n[a]));
    }
    let beyond_speck = |(lo, hi): &([usize; 3], [usize; 3])| {
        let squared: usize = (0..3).map(|a| (hi[a] - lo[a]).pow(2)).sum();
        squared as f64 >= SPECK_CELLS * SPECK_CELLS
    };
    inside
        .into_iter()
        .filter(|&i| {
            boxes
                .get(&(pieces.find(i) as u64))
                .is_some_and(beyond_speck)
        })
        .map(|i| pack(band.nodes[i].0.map(|c| c as i64)))
        .collect()
}

/// Packed coordinates of the inside nodes on pieces holding an anchor.
fn nodes_of_anchored_pieces(band: &Band, anchors: &FastSet) -> FastSet {
    let (inside, mut pieces) = inside_pieces(band);
    let key = |i: usize| pack(band.nodes[i].0.map(|c| c as i64));
    let roots: FastSet = inside
        .iter()
        .filter(|&&i| anchors.contains(&key(i)))
        .map(|&i| pieces.find(i) as u64)
        .collect();
    inside
        .into_iter()
        .filter(|&i| roots.contains(&(pieces.find(i) as u64)))
        .map(key)
        .collect()
}

/// Cells per edge of the blocks the probes are evaluated in.
const PROBE_BLOCK: i64 = 4;

/// The probes' indices (`per_sample` consecutive ones per sample) grouped
/// by the block of cells their sample lies in: the model gathers its
/// centres once per group, and one group over a whole model's samples
/// (300k spikes) gathered nearly every centre for each probe.
fn probes_by_block(missed: &[(DVec3, [i64; 3])], per_sample: usize) -> Vec<Vec<u32>> {
    let mut keyed: Vec<([i64; 3], usize)> = missed
        .iter()
        .enumerate()
        .map(|(k, (_, cell))| (cell.map(|c| c.div_euclid(PROBE_BLOCK)), k))
        .collect();
    keyed.sort_unstable();
    keyed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|same| {
            same.iter()
                .flat_map(|&(_, k)| (k * per_sample..(k + 1) * per_sample).map(|i| i as u32))
                .collect()
        })
        .collect()
}

/// The grid cell (its lowest node) holding `p`, if inside the grid.
fn cell_of(spec: &GridSpec<3>, p: DVec3) -> Option<[i64; 3]> {
    let g = spec.to_grid(p.to_array());
    let cell = g.map(|c| c.floor() as i64);
    (0..3)
        .all(|a| cell[a] >= 0 && cell[a] + 1 < spec.dims[a] as i64)
        .then_some(cell)
}

/// Whether all eight corners of `cell` were evaluated and are outside.
fn all_corners_outside(band: &Band, cell: [i64; 3]) -> bool {
    (0..8).all(|c| {
        let n = [
            cell[0] + (c & 1),
            cell[1] + ((c >> 1) & 1),
            cell[2] + ((c >> 2) & 1),
        ];
        band.value(n).is_some_and(|v| v >= 0.0)
    })
}

/// The corner of `cell` nearest `p`.
fn nearest_corner(spec: &GridSpec<3>, cell: [i64; 3], p: DVec3) -> [i64; 3] {
    let g = spec.to_grid(p.to_array());
    std::array::from_fn(|a| cell[a] + i64::from(g[a] - cell[a] as f64 >= 0.5))
}

/// A possible join: two inside nodes of different pieces.
#[derive(Clone, Copy)]
struct Candidate {
    from: usize,
    to: usize,
    /// Squared length in cells.
    squared: i64,
    /// The shortest candidate's squared length between the same two pieces.
    nearest: i64,
}

/// Joins tried per pair of pieces at most (the shortest ones).
const CANDIDATES_PER_PAIR: usize = 64;

/// For every piece but the largest: pairs of one of its boundary nodes and
/// an inside node of another piece within [`BRIDGE_CELLS`], shortest first
/// per pair of pieces (at most [`CANDIDATES_PER_PAIR`] each).
fn join_candidates(band: &Band, inside: &[usize], pieces: &mut DisjointSets) -> Vec<Candidate> {
    let mut sizes: FastMap<usize> = FastMap::default();
    for &i in inside {
        *sizes.entry(pieces.find(i) as u64).or_default() += 1;
    }
    if sizes.len() < 2 {
        return Vec::new();
    }
    let largest = sizes
        .iter()
        .max_by_key(|(root, size)| (**size, std::cmp::Reverse(**root)))
        .map(|(root, _)| *root as usize);
    let mut found: Vec<((usize, usize), i64, usize, usize)> = Vec::new();
    for &i in inside {
        let root = pieces.find(i);
        if Some(root) == largest {
            continue;
        }
        let n = band.nodes[i].0.map(|c| c as i64);
        let on_boundary = FACES.iter().any(|d| {
            band.value([n[0] + d[0], n[1] + d[1], n[2] + d[2]])
                .is_none_or(|v| v >= 0.0)
        });
        if !on_boundary {
            continue;
        }
        let r = BRIDGE_CELLS;
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    let d2 = dx * dx + dy * dy + dz * dz;
                    let m = [n[0] + dx, n[1] + dy, n[2] + dz];
                    let Some(j) = band.slot(m).filter(|&j| band.nodes[j].1 < 0.0) else {
                        continue;
                    };
                    let other = pieces.find(j);
                    if other != root && d2 <= r * r {
                        found.push(((root.min(other), root.max(other)), d2, i, j));
                    }
                }
            }
        }
    }
    found.sort_unstable();
    let mut out = Vec::new();
    for same in found.chunk_by(|a, b| a.0 == b.0) {
        let nearest = same[0].1;
        out.extend(
            same.iter()
                .take(CANDIDATES_PER_PAIR)
                .map(|&(_, squared, from, to)| Candidate {
                    from,
                    to,
                    squared,
                    nearest,
                }),
        );
    }
    out
}
