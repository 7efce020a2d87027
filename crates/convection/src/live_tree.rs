//! The points of the decimation's front in a hierarchy of bounding boxes
//! that knows how many points under each box are still live, for the one
//! query the front asks: the Delaunay apex behind a facet.
//!
//! The apex is the first inner point that the spheres through the facet's
//! corners meet as they sweep from its outer side to its inner side (centre
//! `c(t) = c₀ + t·n`, radius `√(r₀² + t²)`, `t` rising). Once a candidate
//! at `t` is known, only points inside the ball of that sphere and on the
//! inner side can beat it, so whole boxes drop out: those with no live
//! point, those wholly on the outer side, those outside the current ball.
//! Near the apex that ball's inner part is a thin lens on the facet, which
//! few boxes reach, however many points the facet's diametral ball holds
//! (a radius query visited them all: 145 s at the Dragon scale).
//!
//! The tree is implicit (node `k` has children `2k`, `2k + 1`; leaves from
//! `leaf_base`, each holding `LEAF` consecutive points of `order`, the
//! last ones empty) and splits space like a k-d tree: siblings hold the
//! points on either side of a plane across their parent's longest extent,
//! so their boxes do not overlap (chunks of a Hilbert order did, and a
//! facet's ball met about 18 leaves for 12 points inside it).

use surfrecon_delaunay::DVec3;

const LEAF: usize = 16;

// A leaf's live slots are the bits of a `u32`.
const _: () = assert!(LEAF <= 32);

pub(crate) struct LiveTree {
    /// Point indices, leaf by leaf.
    order: Vec<u32>,
    /// Their coordinates, in the same order, one array per axis (the
    /// search tests a leaf's slots against a sphere all at once; padded to
    /// whole leaves). Which are live is in the leaves' masks.
    coordinates: [Vec<f64>; 3],
    /// Position of each point in `order`.
    slot: Vec<u32>,
    /// Box and live count per node, in single precision: the search walks
    /// ~270 nodes per facet and is bound by memory, and two siblings then
    /// share a cache line.
    nodes: Nodes,
    /// Per inner node, how its children's points are separated (fixed
    /// when the tree is built, all points live).
    splits: Vec<Split>,
    leaf_base: usize,
}

/// Along `axis`, every point under the left child is at most `left_max`
/// and every point under the right child at least `right_min`.
#[derive(Clone, Copy)]
struct Split {
    axis: u8,
    left_max: f32,
    right_min: f32,
}

/// A node's box (rounded outward to `f32`; empty boxes are inverted) and
/// the number of live points under it; a leaf also has one bit per slot
/// set while that slot's point is live (in the node's padding: a leaf scan
/// then visits its live points only, three quarters of them being gone by
/// the end of a decimation).
#[derive(Clone, Copy, PartialEq)]
#[repr(C, align(32))]
struct Node {
    lo: [f32; 3],
    live: u32,
    hi: [f32; 3],
    mask: u32,
}

impl Node {
    fn new([lo, hi]: [DVec3; 2], live: u32, mask: u32) -> Self {
        Node {
            lo: lo.to_array().map(round_down),
            live,
            hi: hi.to_array().map(round_up),
            mask,
        }
    }

    fn bounds(&self) -> [DVec3; 2] {
        [
            DVec3::from_array(self.lo.map(f64::from)),
            DVec3::from_array(self.hi.map(f64::from)),
        ]
    }

    /// The box holding both boxes.
    fn union_box(&self, other: &Node) -> ([f32; 3], [f32; 3]) {
        let lo = std::array::from_fn(|k| self.lo[k].min(other.lo[k]));
        let hi = std::array::from_fn(|k| self.hi[k].max(other.hi[k]));
        (lo, hi)
    }
}

/// The nodes by number, siblings `2k` and `2k + 1` in one 64-byte cache
/// line (the walk tests both children of a node together; a `Vec<Node>`
/// is only 32-byte aligned, and half its pairs could straddle two lines).
struct Nodes(Vec<Siblings>);

#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Siblings([Node; 2]);

impl std::ops::Index<usize> for Nodes {
    type Output = Node;

    fn index(&self, node: usize) -> &Node {
        &self.0[node / 2].0[node % 2]
    }
}

impl std::ops::IndexMut<usize> for Nodes {
    fn index_mut(&mut self, node: usize) -> &mut Node {
        &mut self.0[node / 2].0[node % 2]
    }
}

/// The largest `f32` not above `x` (a box only ever grows by rounding).
fn round_down(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x {
        y.next_down()
    } else {
        y
    }
}

/// The smallest `f32` not below `x`.
fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x {
        y.next_up()
    } else {
        y
    }
}

/// The sphere pencil through a facet's corners: centre `c₀ + t·n`, squared
/// radius `r₀² + t²` (`n` the unit inner normal).
#[derive(Clone, Copy)]
pub(crate) struct Pencil {
    pub centre: DVec3,
    pub radius: f64,
    pub normal: DVec3,
    /// Added to every radius and to the half-space test, so that rounding
    /// (and the front's jitter) never prunes a box holding a candidate.
    pub slack: f64,
}

impl Pencil {
    /// The sphere at `t`, grown by the slack.
    fn ball(&self, t: f64) -> Ball {
        let reach = (self.radius * self.radius + t * t).sqrt() + self.slack;
        Ball {
            centre: self.centre + t * self.normal,
            reach2: reach * reach,
        }
    }

    /// The pencil parameter at which the sphere passes through `p` (an
    /// inner point: the lower, the earlier it is met).
    pub fn t(&self, p: DVec3) -> f64 {
        let height = self.normal.dot(p - self.centre);
        let t = (p.distance_squared(self.centre) - self.radius * self.radius) / (2.0 * height);
        // Points on the facet's plane inside its circle: met first of all.
        if height > 0.0 {
            t.max(-1e6 * self.radius)
        } else {
            -1e6 * self.radius
        }
    }

    /// For a best at `t` clearly inside the diametral ball, a ball about
    /// the circumcentre `c₀` holding every inner point that may still beat
    /// it. A later best is inside the diametral ball too (`t` below
    /// `−10⁻³r₀`, and a near-tie moves `t` by at most `10⁻⁶` of the
    /// scale), so it has `t < 0`, or a height rounded to 0 (then its `t`
    /// is clamped at `−10⁶r₀` but it still passes a sphere's test): with
    /// height `η > 0` and `|p − c₀ − t·n| ≤ R + s` (`R² = r₀² + t²`, `s`
    /// the slack), `|p − c₀|² ≤ r₀² + 2tη + 2Rs + s² < r₀² + 2Rs + s²`,
    /// and `R` stays below `10⁶r₀ + r₀` with the clamp. Near the apex the
    /// sphere of the best reaches far to the outer side, where the front's
    /// kept points are; this ball does not.
    fn lens(&self, t: f64) -> Option<Ball> {
        if t >= -1e-3 * self.radius {
            return None;
        }
        let (r, s) = (self.radius, self.slack);
        let largest = 1e6 * r + r + s;
        // Grown by the slack again for the rounding of this bound.
        let reach = (r * r + 2.0 * largest * s + s * s).sqrt() + s;
        Some(Ball {
            centre: self.centre,
            reach2: reach * reach,
        })
    }

    /// Whether the box reaches the inner side (less the slack).
    fn above_plane(&self, [lo, hi]: [DVec3; 2]) -> bool {
        let half = (hi - lo) / 2.0;
        let top = self.normal.dot(lo + half - self.centre) + self.normal.abs().dot(half);
        top > -self.slack
    }
}

/// A sphere of the pencil, as a centre and squared radius.
#[derive(Clone, Copy)]
struct Ball {
    centre: DVec3,
    reach2: f64,
}

impl Ball {
    /// Squared distance from the centre to a box.
    fn gap2(&self, [lo, hi]: [DVec3; 2]) -> f64 {
        (lo - self.centre)
            .max(self.centre - hi)
            .max(DVec3::ZERO)
            .length_squared()
    }

    fn holds(&self, p: DVec3) -> bool {
        p.distance_squared(self.centre) <= self.reach2
    }
}

impl LiveTree {
    /// All `points` live.
    pub fn new(points: &[DVec3]) -> Self {
        let leaf_base = points.len().div_ceil(LEAF).next_power_of_two();
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut axes = vec![0u8; leaf_base];
        for (node, axis) in split_in_halves(points, &mut order, leaf_base * LEAF, 1) {
            axes[node] = axis;
        }
        let mut slot = vec![0u32; points.len()];
        for (k, &i) in order.iter().enumerate() {
            slot[i as usize] = k as u32;
        }
        let empty = [DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)];
        let mut tree = LiveTree {
            coordinates: std::array::from_fn(|axis| {
                let mut along: Vec<f64> = order.iter().map(|&i| points[i as usize][axis]).collect();
                along.resize(order.len().next_multiple_of(LEAF), f64::INFINITY);
                along
            }),
            order,
            slot,
            nodes: Nodes(vec![Siblings([Node::new(empty, 0, 0); 2]); leaf_base]),
            splits: Vec::new(),
            leaf_base,
        };
        for leaf in 0..points.len().div_ceil(LEAF) {
            let live = (points.len() - leaf * LEAF).min(LEAF) as u32;
            let mask = ((1u64 << live) - 1) as u32;
            tree.nodes[leaf_base + leaf].mask = mask;
            tree.nodes[leaf_base + leaf] = Node::new(tree.live_box(leaf), live, mask);
        }
        for node in (1..leaf_base).rev() {
            let (l, r) = (tree.nodes[2 * node], tree.nodes[2 * node + 1]);
            let (lo, hi) = l.union_box(&r);
            tree.nodes[node] = Node {
                lo,
                live: l.live + r.live,
                hi,
                mask: 0,
            };
        }
        tree.splits = (0..leaf_base)
            .map(|node| {
                let axis = axes[node] as usize;
                Split {
                    axis: axes[node],
                    left_max: tree.nodes[2 * node].hi[axis],
                    right_min: tree.nodes[2 * node + 1].lo[axis],
                }
            })
            .collect();
        tree
    }

    /// The deepest node whose children's split keeps everything outside
    /// its subtree away from the box `[lo, hi]`: the only subtree that can
    /// hold a point inside it (boxes rounded outward keep this safe).
    fn subtree_holding(&self, [lo, hi]: [DVec3; 2]) -> usize {
        let mut node = 1;
        while node < self.leaf_base {
            let split = self.splits[node];
            let axis = split.axis as usize;
            node = if hi[axis] < f64::from(split.right_min) {
                2 * node
            } else if lo[axis] > f64::from(split.left_max) {
                2 * node + 1
            } else {
                break;
            };
        }
        node
    }

    /// Point `i` is no longer live (call once per point). The boxes shrink
    /// to the live points left: most points of a decimated front die, and a
    /// box kept at its full size would keep meeting balls it holds nothing
    /// for.
    pub fn remove(&mut self, i: usize) {
        let leaf = self.slot[i] as usize / LEAF;
        let mut node = self.leaf_base + leaf;
        let Node { live, mask, .. } = self.nodes[node];
        let mask = mask & !(1 << (self.slot[i] as usize % LEAF));
        self.nodes[node].mask = mask;
        self.nodes[node] = Node::new(self.live_box(leaf), live - 1, mask);
        let mut boxes_changed = true;
        while node > 1 {
            node /= 2;
            self.nodes[node].live -= 1;
            if boxes_changed {
                let (l, r) = (self.nodes[2 * node], self.nodes[2 * node + 1]);
                let (lo, hi) = l.union_box(&r);
                // Once a box stays, its ancestors' unions do too.
                boxes_changed = (lo, hi) != (self.nodes[node].lo, self.nodes[node].hi);
                (self.nodes[node].lo, self.nodes[node].hi) = (lo, hi);
            }
        }
    }

    /// The box of the leaf's live points (inverted when none is left).
    fn live_box(&self, leaf: usize) -> [DVec3; 2] {
        let mut bounds = [DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)];
        for k in self.live_slots(leaf) {
            bounds = [
                bounds[0].min(self.position(k)),
                bounds[1].max(self.position(k)),
            ];
        }
        bounds
    }

    /// The slots of the leaf's live points, ascending.
    fn live_slots(&self, leaf: usize) -> impl Iterator<Item = usize> {
        let mut mask = self.nodes[self.leaf_base + leaf].mask;
        std::iter::from_fn(move || {
            let bit = mask.trailing_zeros() as usize;
            mask &= mask.wrapping_sub(1);
            (bit < LEAF).then_some(leaf * LEAF + bit)
        })
    }

    /// Live points strictly beyond the plane through `origin` with unit
    /// normal `normal` (by more than `slack`) and within `reach` of `origin`.
    pub fn beyond_plane(&self, origin: DVec3, normal: DVec3, reach: f64, slack: f64) -> Vec<usize> {
        let ball = Ball {
            centre: origin,
            reach2: reach * reach,
        };
        let mut found = Vec::new();
        let mut stack = vec![1usize];
        while let Some(node) = stack.pop() {
            let [lo, hi] = self.nodes[node].bounds();
            let half = (hi - lo) / 2.0;
            let top = normal.dot(lo + half - origin) + normal.abs().dot(half);
            if self.nodes[node].live == 0 || top <= slack || ball.gap2([lo, hi]) > ball.reach2 {
                continue;
            }
            if node < self.leaf_base {
                stack.extend([2 * node, 2 * node + 1]);
                continue;
            }
            for k in self.live_slots(node - self.leaf_base) {
                let p = self.position(k);
                if ball.holds(p) && normal.dot(p - origin) > slack {
                    found.push(self.order[k] as usize);
                }
            }
        }
        found
    }

    /// The candidate that `better` prefers among the live points (of those
    /// given to [`LiveTree::new`]) the pencil
    /// meets on the inner side before the diametral ball (`t ≤ 0`), or
    /// `None`. `candidate(i, p)` says whether a live point `i` at `p` may be
    /// an apex at all (not a corner, exactly on the inner side; `p` is its
    /// position as given, from the leaf just read: looking it up by `i`
    /// was a cache miss per point tested); `better(q, s)` decides
    /// exactly whether `q` beats `s` where their `t` nearly tie. With
    /// `first_inside`, any point inside the diametral ball will do (the
    /// question is only whether the facet's Gabriel property fails).
    pub fn apex(
        &self,
        pencil: &Pencil,
        corners: [usize; 3],
        first_inside: bool,
        candidate: impl Fn(usize, DVec3) -> bool,
        better: impl Fn(usize, usize) -> bool,
    ) -> Option<usize> {
        let mut search = Search {
            pencil,
            candidate,
            better,
            best: None,
            ball: pencil.ball(0.0),
            lens: None,
            wins: 0,
            first_inside,
            done: false,
        };
        // The corners' own leaves first: the apex is usually near them, and
        // a good first candidate shrinks the sphere for the rest.
        let seeds = corners.map(|c| self.slot[c] as usize / LEAF);
        for (n, &leaf) in seeds.iter().enumerate() {
            if !seeds[..n].contains(&leaf) && !search.done {
                self.scan_leaf(leaf, &mut search);
            }
        }
        // Then depth first, the box nearer the current sphere's centre
        // first; the tree is at most 40 levels deep. Children are tested
        // when their parent is opened (their gaps order them anyway); a
        // child is tested again when popped only if a better point came
        // since (each entry keeps the count of wins it was tested at).
        let mut stack = [Entry::default(); 64];
        let mut depth = 1;
        // Below the root: the walk from it tested ~20 boxes per search on
        // the way down to the ball.
        stack[0] = Entry {
            node: self.subtree_holding(search.reach_box()) as u32,
            wins: u32::MAX,
            holds: false,
        };
        while depth > 0 && !search.done {
            depth -= 1;
            let Entry { node, wins, holds } = stack[depth];
            let node = node as usize;
            let holds = match wins == search.wins {
                true => holds,
                false => self.test(node, &search).0,
            };
            if !holds {
                continue;
            }
            if node >= self.leaf_base {
                if !seeds.contains(&(node - self.leaf_base)) {
                    self.scan_leaf(node - self.leaf_base, &mut search);
                }
                continue;
            }
            let (l, r) = (2 * node, 2 * node + 1);
            let (tl, tr) = (self.test(l, &search), self.test(r, &search));
            let entry = |node: usize, (holds, _): (bool, f64)| Entry {
                node: node as u32,
                wins: search.wins,
                holds,
            };
            let (near, far) = match tl.1 <= tr.1 {
                true => (entry(l, tl), entry(r, tr)),
                false => (entry(r, tr), entry(l, tl)),
            };
            stack[depth] = far;
            stack[depth + 1] = near;
            depth += 2;
        }
        search.best.map(|(i, _)| i)
    }

    /// Whether the node may hold a point that beats the search's best so
    /// far, and its box's squared gap to the current sphere's centre.
    fn test<C, B>(&self, node: usize, search: &Search<'_, C, B>) -> (bool, f64)
    where
        B: Fn(usize, usize) -> bool,
    {
        let here = &self.nodes[node];
        let bounds = here.bounds();
        let gap2 = search.ball.gap2(bounds);
        (here.live > 0 && search.may_hold(bounds, gap2), gap2)
    }

    fn position(&self, k: usize) -> DVec3 {
        let [x, y, z] = &self.coordinates;
        DVec3::new(x[k], y[k], z[k])
    }

    /// Offer the leaf's live points inside the current sphere, in slot
    /// order. The slots are tested against the sphere all at once; when an
    /// offer wins, the sphere shrinks and the slots after it are tested
    /// again (each slot meets the sphere current at its turn).
    fn scan_leaf<C, B>(&self, leaf: usize, search: &mut Search<'_, C, B>)
    where
        C: Fn(usize, DVec3) -> bool,
        B: Fn(usize, usize) -> bool,
    {
        let base = leaf * LEAF;
        let mut todo = u64::from(self.nodes[self.leaf_base + leaf].mask);
        'sphere: while todo != 0 {
            let mut inside = todo & u64::from(self.slots_inside(base, search.ball));
            while inside != 0 {
                let slot = inside.trailing_zeros() as usize;
                inside &= inside - 1;
                let (i, p) = (self.order[base + slot] as usize, self.position(base + slot));
                if (search.candidate)(i, p) {
                    let wins = search.wins;
                    search.offer(i, p);
                    if search.wins != wins {
                        todo &= !((2u64 << slot) - 1);
                        continue 'sphere;
                    }
                }
            }
            break;
        }
    }

    /// One bit per slot of the leaf starting at `base` inside `ball`
    /// (exactly [`Ball::holds`]; a loop without branches).
    fn slots_inside(&self, base: usize, ball: Ball) -> u32 {
        let [x, y, z] = self.coordinates.each_ref().map(|c| &c[base..base + LEAF]);
        let mut inside = 0;
        for slot in 0..LEAF {
            let p = DVec3::new(x[slot], y[slot], z[slot]);
            inside |= u32::from(ball.holds(p)) << slot;
        }
        inside
    }
}

/// Nodes above this many points split their halves in parallel (the tree
/// is built while the normals are estimated; each half's order depends on
/// its own points only).
const PARALLEL_SPLIT: usize = 1 << 14;

/// Orders `order` (the points under one node, `capacity` slots) so that
/// the first `capacity / 2` slots hold the points lowest along the points'
/// longest extent, recursively down to leaves: the left subtree is filled
/// first, as the implicit layout wants. Returns each split node's axis.
fn split_in_halves(
    points: &[DVec3],
    order: &mut [u32],
    capacity: usize,
    node: usize,
) -> Vec<(usize, u8)> {
    let mut axes = Vec::new();
    if capacity <= LEAF || order.len() <= 1 {
        return axes;
    }
    let half = capacity / 2;
    axes.extend(split_node(points, order, half).map(|axis| (node, axis)));
    let (left, right) = order.split_at_mut(half.min(order.len()));
    let [l, r] = [2 * node, 2 * node + 1];
    let (left, right) = match left.len() + right.len() > PARALLEL_SPLIT {
        true => rayon::join(
            || split_in_halves(points, left, half, l),
            || split_in_halves(points, right, half, r),
        ),
        false => (
            split_in_halves(points, left, half, l),
            split_in_halves(points, right, half, r),
        ),
    };
    axes.extend(left);
    axes.extend(right);
    axes
}

/// Puts the `half` points lowest along the points' longest extent first
/// (none to do if they fit in `half`), returning that axis.
fn split_node(points: &[DVec3], order: &mut [u32], half: usize) -> Option<u8> {
    if order.len() <= half {
        return None;
    }
    let (lo, hi) = order.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &i| (lo.min(points[i as usize]), hi.max(points[i as usize])),
    );
    let axis = (hi - lo).max_position();
    let along = |i: &u32| points[*i as usize][axis];
    order.select_nth_unstable_by(half, |a, b| along(a).total_cmp(&along(b)).then(a.cmp(b)));
    Some(axis as u8)
}

/// A node on the apex search's stack, tested when its parent was opened.
#[derive(Clone, Copy, Default)]
struct Entry {
    node: u32,
    /// The search's win count at that test, and its verdict.
    wins: u32,
    holds: bool,
}

/// The state of one apex search.
struct Search<'a, C, B> {
    pencil: &'a Pencil,
    candidate: C,
    better: B,
    best: Option<(usize, f64)>,
    /// The sphere of the best so far (the diametral ball before one).
    ball: Ball,
    /// Once the best is clearly inside the diametral ball, a ball about
    /// the facet's circumcentre holding the inner part of `ball`.
    lens: Option<Ball>,
    /// How many times a better point was found.
    wins: u32,
    /// Stop at the first point clearly inside the diametral ball.
    first_inside: bool,
    done: bool,
}

impl<C, B: Fn(usize, usize) -> bool> Search<'_, C, B> {
    fn offer(&mut self, i: usize, p: DVec3) {
        let ti = self.pencil.t(p);
        let wins = match self.best {
            None => ti <= self.pencil.slack,
            Some((s, ts)) => {
                // Rounding cannot swap clearly separated values; near-ties
                // go to the exact test.
                let tie = 1e-6 * (self.pencil.radius + ti.abs() + ts.abs());
                ti < ts - tie || (ti <= ts + tie && (self.better)(i, s))
            }
        };
        if wins {
            self.best = Some((i, ti));
            self.ball = self.pencil.ball(ti);
            self.lens = self.pencil.lens(ti);
            self.wins += 1;
            self.done = self.first_inside && ti < -self.pencil.slack;
        }
    }

    /// Whether a box (`gap2` from the sphere's centre) may hold a point
    /// that beats the best so far.
    fn may_hold(&self, bounds: [DVec3; 2], gap2: f64) -> bool {
        gap2 <= self.ball.reach2
            && self.pencil.above_plane(bounds)
            && self
                .lens
                .is_none_or(|lens| lens.gap2(bounds) <= lens.reach2)
    }

    /// A box around every point that may beat the best so far.
    fn reach_box(&self) -> [DVec3; 2] {
        let corners = |ball: Ball| {
            let reach = ball.reach2.sqrt();
            [ball.centre - reach, ball.centre + reach]
        };
        let [lo, hi] = corners(self.ball);
        match self.lens {
            Some(lens) => {
                let [lens_lo, lens_hi] = corners(lens);
                [lo.max(lens_lo), hi.min(lens_hi)]
            }
            None => [lo, hi],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Points in a slab (so the k-d splits are uneven), three quarters of
    /// them removed: the boxes shrink, and every query must still see
    /// exactly the live points a scan of all of them sees.
    fn thinned_tree(rng: &mut rand_pcg::Pcg64) -> (Vec<DVec3>, Vec<bool>, LiveTree) {
        let points: Vec<DVec3> = (0..3001)
            .map(|_| {
                let mut coordinate = || rng.random_range(-1.0..1.0);
                DVec3::new(coordinate(), 0.3 * coordinate(), 0.05 * coordinate()) * 0.123_456_7
            })
            .collect();
        let mut tree = LiveTree::new(&points);
        let alive: Vec<bool> = (0..points.len())
            .map(|_| rng.random_range(0..4) == 0)
            .collect();
        for (i, _) in alive.iter().enumerate().filter(|(_, live)| !**live) {
            tree.remove(i);
        }
        (points, alive, tree)
    }

    #[test]
    fn queries_after_removals_match_a_scan_of_the_live_points() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let (points, alive, tree) = thinned_tree(&mut rng);
        let live = || (0..points.len()).filter(|&i| alive[i]);
        let mut apexes = 0;
        for _ in 0..2000 {
            // Small facets near the data: many balls straddle a split.
            let a = points[rng.random_range(0..points.len())];
            let mut offset = || DVec3::from_array([0; 3].map(|_| rng.random_range(-0.01..0.01)));
            let [b, c] = [a + offset(), a + offset()];
            let (u, v) = (b - a, c - a);
            let normal = u.cross(v).normalize();
            let centre = a
                + (u.length_squared() * v.cross(u.cross(v))
                    + v.length_squared() * u.cross(v).cross(u))
                    / (2.0 * u.cross(v).length_squared());
            let radius = centre.distance(a);
            if !radius.is_finite() || radius > 0.1 {
                continue;
            }
            // The slab query.
            let mut expected: Vec<usize> = live()
                .filter(|&i| {
                    points[i].distance(centre) <= 2.0 * radius
                        && normal.dot(points[i] - centre) > 0.0
                })
                .collect();
            let mut found = tree.beyond_plane(centre, normal, 2.0 * radius, 0.0);
            found.sort_unstable();
            expected.sort_unstable();
            assert_eq!(found, expected);
            // The apex: the lowest pencil parameter among live inner points.
            let pencil = Pencil {
                centre,
                radius,
                normal,
                slack: 0.0,
            };
            let inner = |i: usize| normal.dot(points[i] - centre) > 1e-12;
            let expected = live()
                .filter(|&i| inner(i) && pencil.t(points[i]) <= 0.0)
                .min_by(|&p, &q| pencil.t(points[p]).total_cmp(&pencil.t(points[q])));
            let candidate = |i: usize, p: DVec3| p == points[i] && inner(i);
            let found = tree.apex(&pencil, [0, 1, 2], false, candidate, |q, s| q < s);
            assert_eq!(found, expected);
            apexes += usize::from(found.is_some());
            // Asked only whether a live inner point is inside the diametral
            // ball: one is returned exactly when one exists.
            let inside = |i: usize| inner(i) && pencil.t(points[i]) < 0.0;
            match tree.apex(&pencil, [0, 1, 2], true, candidate, |q, s| q < s) {
                Some(i) => assert!(inside(i), "point {i} is not inside"),
                None => assert!(live().all(|i| !inside(i))),
            }
        }
        assert!(apexes > 500, "{apexes} facets with an apex");
    }
}
