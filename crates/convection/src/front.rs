//! Decimation on the fly, in the order the convection reaches the points
//! (the paper's §3, `Params::decimate_on_the_fly`): a pseudo-surface shrinks
//! from the convex hull towards the points *without* a Delaunay
//! triangulation, each step finding the tetrahedron behind a facet by a
//! search over the live points, and every point that joins the surface at
//! once removes its redundant neighbours by the two criteria of
//! [`crate::decimate`]. The points kept are the first ones the front meets
//! (the extreme ones represent their neighbourhoods); the removed ones
//! never enter a triangulation, and the exact pipeline then runs on the
//! kept points only.
//!
//! - Start: the paper's approximate hull. The hull's points join farthest
//!   from the centroid first, each removing its neighbours (other hull
//!   points too); the hull of what is left is taken again until its corners
//!   are all kept and no live point lies outside it.
//! - Step, per facet `abc` (inside on the side of `(b−a)×(c−a)`): the
//!   Delaunay apex among the live points on the inner side
//!   ([`LiveTree::apex`]); if it lies in the facet's diametral ball (the
//!   oriented Gabriel property fails), the facet is replaced by the other
//!   three faces of its tetrahedron, or collapses with its mirror `acb` if
//!   that is on the surface too (the fronts met). Points only ever leave,
//!   so a facet that once met the property still does.
//! - Robustness: apexes are chosen by the exact in-sphere test with the
//!   triangulation's symbolic perturbation, on the points moved by a fixed
//!   pseudo-random jitter of 1e-6 of the diagonal (exactly coplanar samples
//!   of CAD faces would otherwise leave the hull's flat faces without their
//!   points): the front is a consistent sweep of Delaunay tetrahedra of the
//!   live points. A step budget (8 per point) still guards termination.
//!
//! Not here: pockets and thin parts (the front stops where the Gabriel
//! property holds); the points it never reaches are decimated afterwards in
//! input order, kept points still stopping the disks.

use crate::decimate::{disk_order, grow_disk, grow_disks, Decimation};
use crate::gabriel::in_diametral_ball;
use crate::live_tree::{LiveTree, Pencil};
use crate::reconstruct::bounding_diagonal;
use rayon::prelude::*;
use std::collections::{HashMap, HashSet, VecDeque};
use std::hash::{BuildHasherDefault, Hasher};
use surfrecon_delaunay::predicates::{insphere_sos, orient3d};
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::DVec3;

/// What the front did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrontStats {
    /// Points on the starting convex hull.
    pub hull_points: usize,
    /// Points the front reached (kept), hull included.
    pub reached: usize,
    /// Points removed around the reached ones.
    pub removed: usize,
    /// Tetrahedra swept (facets opened).
    pub opened: usize,
    /// Coupled facet pairs collapsed.
    pub collapsed: usize,
    /// The step budget ran out before the front stopped (the rest was
    /// decimated in input order).
    pub stopped_early: bool,
}

/// Which points to keep, the front deciding first (see the module notes);
/// `normals` are unit vectors, one per point. Falls back to input order
/// entirely when the points have no 3D hull.
pub fn decimate_on_the_fly(
    points: &[DVec3],
    normals: &[DVec3],
    settings: &Decimation,
) -> (Vec<bool>, FrontStats) {
    FrontStart::new(points).decimate(points, normals, settings)
}

/// What the front needs before it needs the normals: the trees over the
/// points and the corners of their convex hull. Built while the normals
/// are estimated (the parts are sequential and the machine has few cores).
pub struct FrontStart {
    tree: KdTree,
    /// The points moved by the front's jitter, and their live tree.
    geometry: Vec<DVec3>,
    jitter: f64,
    live: LiveTree,
    /// The corners of the hull of all points (`None`: no 3D hull).
    hull_corners: Option<Vec<usize>>,
}

impl FrontStart {
    pub fn new(points: &[DVec3]) -> Self {
        let jitter = JITTER * bounding_diagonal(points);
        let geometry = jittered(points, jitter);
        let (tree, (live, hull_corners)) = rayon::join(
            || KdTree::new(points),
            || {
                rayon::join(
                    || LiveTree::new(&geometry),
                    || hull_corners(&geometry, jitter),
                )
            },
        );
        FrontStart {
            tree,
            geometry,
            jitter,
            live,
            hull_corners,
        }
    }

    /// [`decimate_on_the_fly`] of the `points` this was built from.
    pub fn decimate(
        self,
        points: &[DVec3],
        normals: &[DVec3],
        settings: &Decimation,
    ) -> (Vec<bool>, FrontStats) {
        let FrontStart {
            tree,
            geometry,
            jitter,
            live,
            hull_corners,
        } = self;
        let mut front = Front {
            points,
            geometry,
            jitter,
            normals,
            settings,
            tree: &tree,
            live,
            facets: FacetSet::default(),
            queue: VecDeque::new(),
            ahead: Vec::new(),
            keep: vec![true; points.len()],
            decided: vec![false; points.len()],
            stats: FrontStats::default(),
        };
        if let Some(hull) = hull_corners.and_then(|corners| front.decimated_hull(corners)) {
            front.start(&hull);
            front.sweep(8 * points.len() + 1000);
        }
        let Front {
            mut keep,
            mut decided,
            stats,
            ..
        } = front;
        grow_disks(&tree, points, normals, settings, &mut keep, &mut decided);
        (keep, stats)
    }
}

/// The corners of the convex hull of all `points`, ascending. Only points
/// outside the hull of a few extreme points can be corners: the hull is
/// taken of those (a few percent of a scan), which with the axes' extremes
/// among them has the same bounding box, so the same normalized
/// coordinates in the hull's own computation.
fn hull_corners(points: &[DVec3], margin: f64) -> Option<Vec<usize>> {
    let inner = convex_hull(points, &extreme_points(points))?;
    let planes: Vec<(DVec3, f64)> = inner
        .iter()
        .filter_map(|t| {
            let [a, b, c] = t.map(|v| points[v as usize]);
            let normal = (b - a).cross(c - a).try_normalize()?;
            Some((normal, normal.dot(a) - margin))
        })
        .collect();
    let outside_inner = (0..points.len())
        .into_par_iter()
        .filter(|&i| planes.iter().any(|&(n, d)| n.dot(points[i]) >= d))
        .collect::<Vec<usize>>();
    Some(corners_of(&convex_hull(points, &outside_inner)?))
}

/// Directions the extreme points are taken along, besides the axes.
const EXTREME_DIRECTIONS: usize = 64;

/// The points farthest along the axes (both ways) and along directions
/// spread over the sphere (a golden-angle spiral), ascending, distinct.
fn extreme_points(points: &[DVec3]) -> Vec<usize> {
    let mut directions = vec![
        DVec3::X,
        DVec3::Y,
        DVec3::Z,
        -DVec3::X,
        -DVec3::Y,
        -DVec3::Z,
    ];
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    directions.extend((0..EXTREME_DIRECTIONS).map(|k| {
        let z = 1.0 - (2 * k + 1) as f64 / EXTREME_DIRECTIONS as f64;
        let (sin, cos) = (golden * k as f64).sin_cos();
        let r = (1.0 - z * z).sqrt();
        DVec3::new(r * cos, r * sin, z)
    }));
    let none = vec![(f64::NEG_INFINITY, usize::MAX); directions.len()];
    // The larger value, then the lower index: the same for any split.
    let better = |a: (f64, usize), b: (f64, usize)| match b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)) {
        std::cmp::Ordering::Greater => b,
        _ => a,
    };
    let best = points
        .par_iter()
        .enumerate()
        .fold(
            || none.clone(),
            |mut best, (i, p)| {
                for (b, d) in best.iter_mut().zip(&directions) {
                    *b = better(*b, (p.dot(*d), i));
                }
                best
            },
        )
        .reduce(
            || none.clone(),
            |a, b| a.into_iter().zip(b).map(|(a, b)| better(a, b)).collect(),
        );
    let mut extremes: Vec<usize> = best
        .into_iter()
        .map(|(_, i)| i)
        .filter(|&i| i != usize::MAX)
        .collect();
    extremes.sort_unstable();
    extremes.dedup();
    extremes
}

/// The live facets' keys ([`key`] packed in 96 bits). The map is never
/// iterated, so its hash cannot reach the output; std's SipHash was ~3 %
/// of a Dragon run.
type FacetSet = HashSet<u128, BuildHasherDefault<FacetHasher>>;

fn packed([a, b, c]: [u32; 3]) -> u128 {
    u128::from(a) | u128::from(b) << 32 | u128::from(c) << 64
}

/// Two multiply-xorshift rounds (the high bits pick hashbrown's control
/// byte, the low ones the bucket: both must depend on every index).
#[derive(Default)]
struct FacetHasher(u64);

impl Hasher for FacetHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }

    fn write_u128(&mut self, x: u128) {
        let h = (x as u64 ^ 0x243f_6a88_85a3_08d3).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        let h = (h ^ (h >> 32) ^ (x >> 64) as u64).wrapping_mul(0x94d0_49bb_1331_11eb);
        self.0 = h ^ (h >> 32);
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

/// The triangles of the convex hull of `points[subset]`, oriented outward,
/// as indices into `points`; `None` when those points are flat or the hull
/// fails.
fn convex_hull(points: &[DVec3], subset: &[usize]) -> Option<Vec<[u32; 3]>> {
    use parry3d_f64::math::Vector3;
    let coords: Vec<Vector3> = subset
        .iter()
        .map(|&i| Vector3::new(points[i].x, points[i].y, points[i].z))
        .collect();
    let (vertices, triangles) = parry3d_f64::transformation::try_convex_hull(&coords).ok()?;
    // The hull's vertices are copies of input points: find them by value.
    let mut by_value = HashMap::new();
    for &i in subset.iter().rev() {
        by_value.insert(points[i].to_array().map(f64::to_bits), i as u32);
    }
    let index: Vec<u32> = vertices
        .iter()
        .map(|v| by_value.get(&[v.x, v.y, v.z].map(f64::to_bits)).copied())
        .collect::<Option<_>>()?;
    let hull: Vec<[u32; 3]> = triangles
        .iter()
        .map(|t| t.map(|v| index[v as usize]))
        .filter(|[a, b, c]| a != b && b != c && a != c)
        .collect();
    (hull.len() >= 4).then_some(hull)
}

/// Facets whose apexes are searched together (in parallel).
const BATCH: usize = 1024;

/// Rounds of [`Front::decimated_hull`] before giving up on the front.
const HULL_ROUNDS: usize = 16;

/// The front's jitter, a fraction of the bounding-box diagonal: far above
/// rounding (the hull's tolerance is ~1e-14 of its size, and the exact
/// predicates' float filters then decide almost every case), far below any
/// useful decimation radius.
const JITTER: f64 = 1e-6;

/// `points`, each moved by a fixed pseudo-random offset of at most `jitter`
/// per axis (a hash of its index: the same for every run).
fn jittered(points: &[DVec3], jitter: f64) -> Vec<DVec3> {
    let unit = |h: u64| (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0;
    points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            let h = splitmix(i as u64);
            let (h2, h3) = (splitmix(h), splitmix(h ^ 0x9e37_79b9));
            p + jitter * DVec3::new(unit(h), unit(h2), unit(h3))
        })
        .collect()
}

fn splitmix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The distinct vertices of `triangles`, ascending.
fn corners_of(triangles: &[[u32; 3]]) -> Vec<usize> {
    let mut corners: Vec<usize> = triangles.iter().flatten().map(|&v| v as usize).collect();
    corners.sort_unstable();
    corners.dedup();
    corners
}

/// Centre and radius of the circle through `a`, `b`, `c`, and the unit
/// normal along `(b − a) × (c − a)`; `None` for a flat triangle.
fn circumcircle(a: DVec3, b: DVec3, c: DVec3) -> Option<(DVec3, f64, DVec3)> {
    let (u, v) = (b - a, c - a);
    let n = u.cross(v);
    let n2 = n.length_squared();
    if n2 == 0.0 || !n2.is_finite() {
        return None;
    }
    let centre =
        a + (u.length_squared() * v.cross(n) + v.length_squared() * n.cross(u)) / (2.0 * n2);
    Some((centre, centre.distance(a), n / n2.sqrt()))
}

/// Rotation of an oriented triangle starting at its smallest index: the same
/// key for the same oriented facet, another for its mirror.
fn key([a, b, c]: [u32; 3]) -> [u32; 3] {
    if a < b && a < c {
        [a, b, c]
    } else if b < c {
        [b, c, a]
    } else {
        [c, a, b]
    }
}

struct Front<'a> {
    /// The input points: the decimation's criteria and the k-d tree.
    points: &'a [DVec3],
    /// The points moved by at most `jitter` along each axis, for the
    /// front's own geometry: exactly coplanar samples (flat faces of CAD
    /// parts) would leave the hull's flat faces without their points.
    geometry: Vec<DVec3>,
    jitter: f64,
    normals: &'a [DVec3],
    settings: &'a Decimation,
    tree: &'a KdTree,
    /// The jittered points with live counts, for the apex search.
    live: LiveTree,
    /// Live oriented facets by packed key, inside on their normal's side.
    facets: FacetSet,
    queue: VecDeque<[u32; 3]>,
    /// The disk orders of points the next steps may reach, by point,
    /// found ahead in parallel.
    ahead: Vec<(usize, Vec<usize>)>,
    /// `decided && keep`: on the surface; `decided && !keep`: removed.
    keep: Vec<bool>,
    decided: Vec<bool>,
    stats: FrontStats,
}

impl Front<'_> {
    /// The paper's approximate hull: hull points join the surface farthest
    /// from the centroid first, each removing its neighbours (hull points
    /// too); the hull of the points left is taken again until every corner
    /// is a kept point and no live point lies outside. Returns its
    /// triangles, oriented outward.
    /// `first` are the corners of the hull of all points.
    fn decimated_hull(&mut self, first: Vec<usize>) -> Option<Vec<[u32; 3]>> {
        let mut first = Some(first);
        let mut candidates = Vec::new();
        for _ in 0..HULL_ROUNDS {
            let mut corners = match first.take() {
                Some(corners) => corners,
                None => corners_of(&convex_hull(&self.geometry, &candidates)?),
            };
            let centroid =
                corners.iter().map(|&v| self.geometry[v]).sum::<DVec3>() / corners.len() as f64;
            let far = |v: usize| self.geometry[v].distance_squared(centroid);
            corners.sort_by(|&a, &b| far(b).total_cmp(&far(a)).then(a.cmp(&b)));
            self.find_disks_ahead(corners.iter().copied());
            for &v in &corners {
                if !self.decided[v] {
                    self.reach(v);
                }
            }
            corners.retain(|&v| self.keep[v]);
            corners.sort_unstable();
            let hull = convex_hull(&self.geometry, &corners)?;
            let outside = self.live_outside(&hull);
            if outside.is_empty() {
                self.stats.hull_points = corners.len();
                return Some(hull);
            }
            candidates = corners;
            candidates.extend(outside);
        }
        None
    }

    /// Live undecided points strictly outside the hull (`hull` outward).
    /// Such a point is near the hull, within a decimation radius of a
    /// removed corner, so it projects into some facet's circumdisc.
    fn live_outside(&self, hull: &[[u32; 3]]) -> Vec<usize> {
        let reach = self.settings.largest_radius() + 2.0 * self.jitter;
        let mut outside = Vec::new();
        for &f in hull {
            let [a, b, c] = f.map(|v| self.geometry[v as usize]);
            let Some((centre, radius, normal)) = circumcircle(a, b, c) else {
                continue;
            };
            let slack = 1e-12 * (radius + reach);
            let beyond = self
                .live
                .beyond_plane(centre, normal, radius + reach, slack);
            outside.extend(beyond.into_iter().filter(|&i| !self.decided[i]));
        }
        outside.sort_unstable();
        outside.dedup();
        outside
    }

    /// The front starts as the hull, turned inward.
    fn start(&mut self, hull: &[[u32; 3]]) {
        for &[a, b, c] in hull {
            self.add([a, c, b]);
        }
    }

    /// The convection, breadth first. The apexes of the next facets in the
    /// queue are searched in parallel against the points live now; points
    /// only ever leave, so an apex still live when its facet's turn comes
    /// is still the apex (and "none" is still none): the same steps as one
    /// facet at a time.
    fn sweep(&mut self, budget: usize) {
        while !self.queue.is_empty() {
            let batch: Vec<[u32; 3]> = self.queue.drain(..self.queue.len().min(BATCH)).collect();
            let apexes: Vec<(Option<usize>, bool)> = batch
                .par_iter()
                .map(|&f| match self.facets.contains(&packed(f)) {
                    true => {
                        let coupled = self.is_coupled(f);
                        (self.violating_apex(f, coupled), coupled)
                    }
                    false => (None, false),
                })
                .collect();
            let reachable = apexes.iter().filter(|(_, coupled)| !coupled);
            self.find_disks_ahead(reachable.filter_map(|&(apex, _)| apex));
            for (f, (apex, coupled)) in batch.into_iter().zip(apexes) {
                if !self.facets.contains(&packed(f)) {
                    continue; // collapsed since it was queued
                }
                // Searched again if its point was removed since, or if only
                // "violated?" was asked and the facet is no longer coupled.
                let apex = match apex {
                    Some(s)
                        if self.decided[s] && !self.keep[s] || coupled && !self.is_coupled(f) =>
                    {
                        self.violating_apex(f, self.is_coupled(f))
                    }
                    apex => apex,
                };
                let Some(apex) = apex else {
                    continue;
                };
                if self.stats.opened + self.stats.collapsed >= budget {
                    self.stats.stopped_early = true;
                    return;
                }
                self.open(f, apex);
            }
        }
    }

    /// Replace `f` by the other faces of its tetrahedron with `apex`, or
    /// collapse it with its mirror.
    fn open(&mut self, f: [u32; 3], apex: usize) {
        let [a, b, c] = f;
        self.facets.remove(&packed(f));
        if self.facets.remove(&packed(key([a, c, b]))) {
            self.stats.collapsed += 1;
            return;
        }
        self.stats.opened += 1;
        let s = apex as u32;
        for g in [[a, b, s], [b, c, s], [c, a, s]] {
            self.add(g);
        }
        if !self.decided[apex] {
            self.reach(apex);
        }
    }

    /// A new surface facet, queued for its test; a second copy of a live
    /// facet (only possible because this pass is not exact) is dropped.
    fn add(&mut self, f: [u32; 3]) {
        let k = key(f);
        if self.facets.insert(packed(k)) {
            self.queue.push_back(k);
        }
    }

    /// The disk orders of those of `points` not decided yet, in parallel:
    /// a disk's growth is sequential (each removal stops later disks), but
    /// its order depends on the points only.
    fn find_disks_ahead(&mut self, points: impl Iterator<Item = usize>) {
        let mut undecided: Vec<usize> = points.filter(|&p| !self.decided[p]).collect();
        undecided.sort_unstable();
        undecided.dedup();
        self.ahead = undecided
            .into_par_iter()
            .map(|p| (p, disk_order(self.tree, self.points, self.settings, p)))
            .collect();
    }

    /// `p` joins the surface and removes its redundant neighbours.
    fn reach(&mut self, p: usize) {
        self.decided[p] = true;
        self.keep[p] = true;
        self.stats.reached += 1;
        let order = match self.ahead.binary_search_by_key(&p, |(q, _)| *q) {
            Ok(k) => std::mem::take(&mut self.ahead[k].1),
            Err(_) => disk_order(self.tree, self.points, self.settings, p),
        };
        let (live, removed) = (&mut self.live, &mut self.stats.removed);
        grow_disk(
            self.points,
            self.normals,
            self.settings,
            p,
            &order,
            &mut self.keep,
            &mut self.decided,
            |q| {
                live.remove(q);
                *removed += 1;
            },
        );
    }

    /// The Delaunay apex behind `f` among the live points, if it lies in
    /// the facet's diametral ball (the Gabriel property fails). The apex is
    /// chosen by the exact in-sphere test with the triangulation's symbolic
    /// perturbation (input indices as ids), so every facet sees the same
    /// tetrahedra; the ball test is the exact pipeline's own. For a
    /// `coupled` facet any live inner point in the ball is returned.
    fn violating_apex(&self, f: [u32; 3], coupled: bool) -> Option<usize> {
        let [a, b, c] = f.map(|v| self.geometry[v as usize]);
        let (centre, radius, normal) = circumcircle(a, b, c)?;
        let pencil = Pencil {
            centre,
            radius,
            normal,
            slack: 1e-9 * (radius + centre.abs().max_element()),
        };
        let s = self.live.apex(
            &pencil,
            f.map(|v| v as usize),
            coupled,
            |i, p| !f.contains(&(i as u32)) && orient3d(a, b, c, p) > 0.0,
            |q, s| self.inside_circumsphere(f, s, q),
        )?;
        in_diametral_ball(a, b, c, self.geometry[s]).then_some(s)
    }

    /// Whether the mirror of `f` is on the surface too: then `f` collapses
    /// if it violates the property, whatever its apex.
    fn is_coupled(&self, [a, b, c]: [u32; 3]) -> bool {
        self.facets.contains(&packed(key([a, c, b])))
    }

    /// Whether `q` is inside the circumsphere of `f` and its inner point
    /// `s` (then `q` is the better apex).
    fn inside_circumsphere(&self, f: [u32; 3], s: usize, q: usize) -> bool {
        let ids = [f[0], f[1], f[2], s as u32, q as u32];
        insphere_sos(ids.map(|i| self.geometry[i as usize]), ids)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::normals::estimate_normals;
    use surfrecon_geom::shapes::{cuboid, icosphere, sample_surface, torus};

    fn settings(radius: f64) -> Decimation {
        Decimation {
            radius,
            geometric: 0.9,
            topological: 0.95,
            brush: None,
        }
    }

    /// Every removed point lies within the radius of a kept one.
    fn assert_covered(points: &[DVec3], keep: &[bool], radius: f64) {
        let kept: Vec<DVec3> = (0..points.len())
            .filter(|&i| keep[i])
            .map(|i| points[i])
            .collect();
        let tree = KdTree::new(&kept);
        for (i, p) in points.iter().enumerate().filter(|(i, _)| !keep[*i]) {
            let d = tree.nearest(*p).unwrap().distance;
            assert!(d <= radius, "point {i} is {d} from the nearest kept point");
        }
    }

    #[test]
    fn on_a_sphere_the_hull_decides_everything() {
        let points = sample_surface(&icosphere(DVec3::ZERO, 1.0, 5), 4000, 3).positions;
        let normals: Vec<DVec3> = points.iter().map(|p| p.normalize()).collect();
        let (keep, stats) = decimate_on_the_fly(&points, &normals, &settings(0.1));
        let kept = keep.iter().filter(|&&k| k).count();
        assert_eq!(stats.hull_points, kept, "{stats:?}");
        assert_eq!(stats.reached + stats.removed, points.len());
        assert!(kept > 100 && kept < 1000, "{kept} kept");
        assert_covered(&points, &keep, 0.1);
    }

    /// Through the torus's hole the front sweeps concave space: points are
    /// reached inside the hull, the starting hull's points are all kept,
    /// and the removed ones stay covered.
    #[test]
    fn the_front_reaches_into_the_hole_of_a_torus() {
        let points = sample_surface(&torus(1.0, 0.35, 160, 64), 6000, 7).positions;
        let normals = estimate_normals(&points, 12);
        let radius = 0.06;
        let (keep, stats) = decimate_on_the_fly(&points, &normals, &settings(radius));
        assert!(!stats.stopped_early, "{stats:?}");
        assert!(stats.opened > stats.reached, "{stats:?}");
        let kept = keep.iter().filter(|&&k| k).count();
        assert!(stats.reached > stats.hull_points + kept / 4, "{stats:?}");
        assert!(stats.reached * 10 >= kept * 9, "{stats:?}, {kept} kept");
        assert_covered(&points, &keep, radius);
        // The innermost points (on the hole's rim) are not on the hull.
        let inner = (0..points.len())
            .filter(|&i| keep[i])
            .map(|i| points[i].truncate().length())
            .fold(f64::MAX, f64::min);
        assert!(inner < 0.7, "nearest kept point to the axis at {inner}");
    }

    /// The hull taken of the points outside the extremes' hull has the
    /// corners of the hull of all points: on a torus (most points inside),
    /// a sphere with points inside it (most points corners), and a cube's
    /// jittered faces (many points a rounding away from the hull's faces).
    #[test]
    fn hull_corners_match_the_hull_of_all_points() {
        let torus = sample_surface(&torus(1.0, 0.35, 160, 64), 20_000, 3).positions;
        let mut ball = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 3000, 5).positions;
        ball.extend(ball.clone().iter().map(|&p| 0.99 * p));
        let cube = sample_surface(&cuboid(DVec3::ZERO, DVec3::ONE), 20_000, 9).positions;
        for points in [torus, ball, cube] {
            let jitter = JITTER * bounding_diagonal(&points);
            let geometry = jittered(&points, jitter);
            let all: Vec<usize> = (0..points.len()).collect();
            let expected = corners_of(&convex_hull(&geometry, &all).unwrap());
            let found = hull_corners(&geometry, jitter).unwrap();
            assert_eq!(found, expected);
            // The extremes keep the points' bounding box (the hull's own
            // normalization).
            let extremes = extreme_points(&geometry);
            let bounds = |ids: &mut dyn Iterator<Item = usize>| {
                ids.fold([DVec3::INFINITY, DVec3::NEG_INFINITY], |[lo, hi], i| {
                    [lo.min(geometry[i]), hi.max(geometry[i])]
                })
            };
            assert_eq!(
                bounds(&mut extremes.iter().copied()),
                bounds(&mut all.iter().copied())
            );
            assert!(extremes.len() > 20, "{} extremes", extremes.len());
        }
    }
}
