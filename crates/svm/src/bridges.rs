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
//! parts (two bodies, a stray blob) f turns positive on the way.

use crate::cells::FastMap;
use crate::mesh::Implicit;
use glam::DVec3;
use surfrecon_geom::disjoint_sets::DisjointSets;
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

impl Band<'_> {
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

/// Join the pieces of inside nodes of `nodes` that `model` joins below the
/// grid's resolution (see the module doc); returns the number of joins.
/// Nodes added by a join are appended (the caller sorts).
pub fn bridge_thin_parts(
    model: &(impl Implicit + ?Sized),
    spec: &GridSpec<3>,
    nodes: &mut Vec<([usize; 3], f64)>,
) -> usize {
    let index: FastMap<usize> = nodes
        .iter()
        .enumerate()
        .map(|(i, (n, _))| (pack(n.map(|c| c as i64)), i))
        .collect();
    let mut band = Band {
        nodes,
        index,
        dims: spec.dims,
    };
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
    let inside_all_along = |k: usize| values[ranges[k].clone()].iter().all(|&f| f < 0.0);
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
        for n in chain(na.map(|v| v as i64), nb.map(|v| v as i64)) {
            band.set_inside(n, BRIDGE_DEPTH * spec.spacing);
        }
        joins += 1;
    }
    joins
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

/// Nodes from `a` to `b`, each a face neighbour of the one before: steps
/// along the axis with the most left to go.
fn chain(a: [i64; 3], b: [i64; 3]) -> Vec<[i64; 3]> {
    let mut out = vec![a];
    let mut at = a;
    while at != b {
        let axis = (0..3)
            .max_by_key(|&k| ((b[k] - at[k]).abs(), std::cmp::Reverse(k)))
            .unwrap_or(0);
        at[axis] += (b[axis] - at[axis]).signum();
        out.push(at);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_are_face_connected_and_end_at_both_nodes() {
        let c = chain([0, 0, 0], [3, -2, 1]);
        assert_eq!(c.first(), Some(&[0, 0, 0]));
        assert_eq!(c.last(), Some(&[3, -2, 1]));
        assert_eq!(c.len(), 7);
        for w in c.windows(2) {
            let steps: i64 = (0..3).map(|k| (w[1][k] - w[0][k]).abs()).sum();
            assert_eq!(steps, 1);
        }
    }
}
