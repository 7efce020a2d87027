//! Pulls the extracted surface onto exact data it does not reach, where the
//! grid cannot: the tip of a cone thinner than a cell, which the level set
//! ends a few cells short of, and the apex of a narrow wedge (a fin meeting
//! the body at about 55°), which the flow leaves filled two or three cells deep.
//! Snapping ([`crate::refine`]) moves vertices onto data within a cell;
//! these data have no vertex that near.
//!
//! Each far datum pulls the surface around its closest surface point by the
//! gap between them, fading out within [`PULL_RADIUS_CELLS`]. Only data
//! that are part of a sampled surface pull: the tip of a line of samples
//! (a cone's), or a point on the surface its neighbours sample whose
//! neighbours the mesh misses too (a wedge's apex line). A stray point off
//! the surface, which cleaning kept, has neighbours the mesh reaches.

use crate::refine::{collapsed, undo_crossing_moves, undo_degenerating_moves};
use rayon::prelude::*;
use surfrecon_geom::fairing::area_weighted_normals;
use surfrecon_geom::metrics::{vertex_faces, TriangleBvh, VertexFaces};
use surfrecon_geom::normals::symmetric_eigen3;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, TriMesh};

/// Data farther than this many cells from the surface are far.
const FAR_CELLS: f64 = 0.5;

/// Data farther than this many cells are left alone: no tip the level
/// set's grid ends short of lies that far out. The surface's pulls keep to
/// it whatever the caller's reach for tips ([`reach_far_points`]).
pub const MAX_PULL_CELLS: f64 = 8.0;

/// A pull moves the surface within this many cells of the closest point.
const PULL_RADIUS_CELLS: f64 = 1.5;

/// Within this many cells of the closest point the surface moves by the
/// whole gap: the clusters of nearly coinciding vertices that marching
/// cubes leaves on a thin part then move as one (unequal shifts would turn
/// their tiny triangles over).
const PULL_CORE_CELLS: f64 = 0.5;

/// A tip takes a vertex within this many cells of its closest point.
const TIP_VERTEX_CELLS: f64 = 1.0;

/// A cone's end as marching cubes leaves it is often a cluster of nearly
/// coinciding vertices whose triangles (of this many square cells, or
/// less) point anywhere: when its foremost vertex is moved onto the tip,
/// they may turn over without folding the surface.
const DEGENERATE_AREA_CELLS: f64 = 1e-6;

/// Pull, then measure again: a pull centred between vertices moves them
/// only part of the way.
const PULL_ROUNDS: usize = 3;

/// Neighbours that decide whether a far datum belongs to a sampled surface.
const NEIGHBOURS: usize = 8;

/// Move the vertices of `mesh` (grid spacing `spacing`) so that it reaches
/// the far data of `points` that belong to a sampled surface, and the far
/// points of `dropped` (those cleaning removed as strays) that tip a line
/// of `points`: a thin cone's last sample lies farther from the rest than
/// cleaning allows. Tips up to `max_tip_cells` cells off the surface are
/// reached ([`MAX_PULL_CELLS`] for the level set; a method whose surface
/// ends farther short of thin tips may reach farther: the tip test, not
/// the distance, tells a tip from a stray). Moves that would collapse or
/// turn over a triangle are undone. Returns the number of points pulled
/// onto.
pub fn reach_far_points(
    mesh: &mut TriMesh,
    points: &[DVec3],
    dropped: &[DVec3],
    spacing: f64,
    max_tip_cells: f64,
) -> usize {
    let far = FAR_CELLS * spacing;
    let tree = KdTree::new(points);
    let distances = distances_beyond(mesh, points, far);
    let sampled = SampledSurface {
        points,
        tree: &tree,
        distances: &distances,
        far,
        gap: sampling_gap(points, &tree),
        spacing,
    };
    let pullable = |d: f64| d > far && d < MAX_PULL_CELLS * spacing;
    let tip_reachable = |d: f64| d > far && d < max_tip_cells * spacing;
    let candidates: Vec<usize> = (0..points.len())
        .filter(|&i| pullable(distances[i]) || tip_reachable(distances[i]))
        .collect();
    let tipping: Vec<bool> = (candidates.par_iter())
        .map(|&i| tip_reachable(distances[i]) && sampled.tips_a_line(points[i], Some(i)))
        .collect();
    let mut tips: Vec<DVec3> = (candidates.iter().zip(&tipping))
        .filter(|&(_, &t)| t)
        .map(|(&i, _)| points[i])
        .collect();
    let surface: Vec<DVec3> = (candidates.iter().zip(&tipping))
        .filter(|&(&i, &t)| !t && pullable(distances[i]) && sampled.on_missed_surface(points[i], i))
        .map(|(&i, _)| points[i])
        .collect();
    let dropped_distances = distances_beyond(mesh, dropped, far);
    tips.extend(
        (dropped.iter().zip(&dropped_distances))
            .filter(|&(&p, &d)| tip_reachable(d) && sampled.tips_a_line(p, None))
            .map(|(&p, _)| p),
    );
    let before = mesh.vertices.clone();
    // Triangles of less than `oriented` area had no direction to keep.
    let oriented = DEGENERATE_AREA_CELLS * spacing * spacing;
    let undo = |mesh: &mut TriMesh, from: &[DVec3]| {
        undo_degenerating_moves(mesh, from, |old, new| {
            collapsed(old, new) || (old.length() >= oriented && turned_over(old, new))
        })
    };
    // The pulls neither move the tips' vertices nor undo them.
    let pinned = extend_to_tips(mesh, &tips, far, TIP_VERTEX_CELLS * spacing, oriented);
    let with_tips = mesh.vertices.clone();
    for _ in 0..PULL_ROUNDS {
        let (core, radius) = (PULL_CORE_CELLS * spacing, PULL_RADIUS_CELLS * spacing);
        if !pull_towards(mesh, &surface, &pinned, far, core, radius) {
            break;
        }
        undo(mesh, &with_tips);
    }
    // Pulls on both sheets of a thin fin's rim, or beside a tip's fan, can
    // fold faces through each other (harness: 315 crossing pairs over 8
    // of 56 rows, 13 left after this): those pulls are put back. The tips'
    // moves stay (putting them back cut the thin spikes again).
    undo_crossing_moves(mesh, &with_tips);
    // Two tips on one position (duplicate samples) would weld two vertices.
    undo_degenerating_moves(mesh, &before, |_, _| false);
    tips.len() + surface.len()
}

/// Move, for each of `tips` farther than `far`, a vertex of the surface
/// within `core` of its closest point onto it: the foremost towards it
/// whose fan neither turns over nor collapses (triangles of less than
/// `oriented` area point anywhere and are not asked). The fan becomes the
/// cone's last stretch, as thin as the cone there; pulling the whole end
/// along with a falloff would stretch its many tiny triangles until some
/// turned over. Where no vertex can go alone (an end lopsided off the
/// tip's axis, whose fan would turn over), the foremost that can goes with
/// its ring carried part of the way ([`RING_CARRIED`]). The farthest tip
/// takes a vertex first (the samples before it on the same cone then lie
/// along the new fan). Returns which vertices moved for a tip.
fn extend_to_tips(
    mesh: &mut TriMesh,
    tips: &[DVec3],
    far: f64,
    core: f64,
    oriented: f64,
) -> Vec<bool> {
    if tips.is_empty() {
        return vec![false; mesh.vertices.len()];
    }
    let bvh = TriangleBvh::new(mesh);
    let vertex_tree = KdTree::new(&mesh.vertices);
    let fans = vertex_faces(&mesh.triangles, mesh.vertices.len());
    let mut found: Vec<_> = (tips.iter())
        .filter_map(|&p| bvh.closest(p).filter(|c| c.distance > far).map(|c| (p, c)))
        .collect();
    found.sort_by(|a, b| b.1.distance.total_cmp(&a.1.distance));
    let mut taken = vec![false; mesh.vertices.len()];
    for (p, closest) in found {
        let towards = p - closest.point;
        let corners = mesh.triangles[closest.triangle].map(|i| i as usize);
        let ahead = |v: &usize| (mesh.vertices[*v] - closest.point).dot(towards);
        let mut candidates: Vec<usize> = (vertex_tree.within(closest.point, core).into_iter())
            .map(|n| n.index)
            .chain(corners)
            .filter(|&v| !taken[v])
            .collect();
        candidates.sort_by(|a, b| ahead(b).total_cmp(&ahead(a)));
        candidates.dedup();
        let keeps_fans =
            |moves: &[(usize, DVec3)]| fans_keep_their_sides(mesh, &fans, moves, oriented);
        let alone = candidates
            .iter()
            .map(|&v| vec![(v, p)])
            .find(|m| keeps_fans(m));
        let carried = |v: usize| {
            let ring: Vec<usize> = ring_of(mesh, &fans, v).filter(|&r| !taken[r]).collect();
            RING_CARRIED.iter().find_map(|&share| {
                let shift = share * (p - mesh.vertices[v]);
                let moves: Vec<_> = std::iter::once((v, p))
                    .chain(ring.iter().map(|&r| (r, mesh.vertices[r] + shift)))
                    .collect();
                keeps_fans(&moves).then_some(moves)
            })
        };
        let moves = alone.or_else(|| candidates.iter().find_map(|&v| carried(v)));
        for (v, to) in moves.into_iter().flatten() {
            mesh.vertices[v] = to;
            taken[v] = true;
        }
    }
    taken
}

/// The shares of a tip's move that the ring of its vertex goes along,
/// tried in turn, when no vertex can go alone: at the whole move the fan
/// only translates, and the faces beyond the ring stretch instead.
const RING_CARRIED: [f64; 3] = [0.5, 0.75, 1.0];

/// The other vertices of the faces around `v`.
fn ring_of<'a>(
    mesh: &'a TriMesh,
    fans: &'a VertexFaces,
    v: usize,
) -> impl Iterator<Item = usize> + 'a {
    let mut ring: Vec<usize> = (fans.of(v).iter())
        .flat_map(|&t| mesh.triangles[t as usize].map(|i| i as usize))
        .filter(|&r| r != v)
        .collect();
    ring.sort_unstable();
    ring.dedup();
    ring.into_iter()
}

/// Whether moving the vertices as `moves` says leaves every face around
/// them uncollapsed and not turned over (faces of less than `oriented`
/// area point anywhere and are not asked).
fn fans_keep_their_sides(
    mesh: &TriMesh,
    fans: &VertexFaces,
    moves: &[(usize, DVec3)],
    oriented: f64,
) -> bool {
    let moved_to = |i: u32| {
        (moves.iter())
            .find(|&&(v, _)| v == i as usize)
            .map_or(mesh.vertices[i as usize], |&(_, to)| to)
    };
    let normal = |[a, b, c]: [DVec3; 3]| (b - a).cross(c - a);
    moves.iter().all(|&(v, _)| {
        fans.of(v).iter().all(|&t| {
            let corners = mesh.triangles[t as usize];
            let old = normal(corners.map(|i| mesh.vertices[i as usize]));
            let new = normal(corners.map(moved_to));
            !collapsed(old, new) && (old.length() < oriented || !turned_over(old, new))
        })
    })
}

/// Turned by more than about 100° (a cone's end cap, pulled out into its
/// tip, turns by 90° and stays).
fn turned_over(old: DVec3, new: DVec3) -> bool {
    new.dot(old) < -0.2 * new.length() * old.length()
}

/// Distance from each point to the mesh where it exceeds `far`, else a
/// value of at most `far` (the distance to the nearest vertex, when that
/// is within `far`): the reach asks only which data lie farther than
/// `far`, and after snapping most data lie on a vertex, which a k-d tree
/// finds several times faster than the closest triangle.
fn distances_beyond(mesh: &TriMesh, points: &[DVec3], far: f64) -> Vec<f64> {
    let vertex_tree = KdTree::new(&mesh.vertices);
    let mut distances: Vec<f64> = (points.par_iter())
        .map(|&p| vertex_tree.nearest(p).map_or(f64::INFINITY, |n| n.distance))
        .collect();
    let beyond: Vec<usize> = (0..points.len()).filter(|&i| distances[i] > far).collect();
    let exact = distances_to(mesh, &beyond.iter().map(|&i| points[i]).collect::<Vec<_>>());
    for (i, d) in beyond.into_iter().zip(exact) {
        distances[i] = d;
    }
    distances
}

/// Exact distance from each point to the mesh.
fn distances_to(mesh: &TriMesh, points: &[DVec3]) -> Vec<f64> {
    let bvh = TriangleBvh::new(mesh);
    points
        .par_iter()
        .map(|&p| bvh.closest(p).map_or(f64::INFINITY, |c| c.distance))
        .collect()
}

/// One round of pulls towards the `targets` still farther than `far`: each
/// moves the vertices (but the `pinned`) within `radius` of its closest
/// surface point that face the same way, by its gap with a smooth fall-off; where pulls
/// overlap their weighted mean. Returns whether anything moved.
fn pull_towards(
    mesh: &mut TriMesh,
    targets: &[DVec3],
    pinned: &[bool],
    far: f64,
    core: f64,
    radius: f64,
) -> bool {
    if targets.is_empty() {
        return false;
    }
    let bvh = TriangleBvh::new(mesh);
    let normals = area_weighted_normals(&mesh.vertices, &mesh.triangles);
    let vertex_tree = KdTree::new(&mesh.vertices);
    let mut weight = vec![0.0; mesh.vertices.len()];
    let mut shift = vec![DVec3::ZERO; mesh.vertices.len()];
    for &p in targets {
        let Some(closest) = bvh.closest(p).filter(|c| c.distance > far) else {
            continue;
        };
        let [a, b, c] = mesh.corners(closest.triangle);
        let facing = (b - a).cross(c - a);
        for v in vertex_tree.within(closest.point, radius) {
            if pinned[v.index] || normals[v.index].dot(facing) <= 0.0 {
                continue;
            }
            let w = fall_off(v.distance, core, radius);
            weight[v.index] += w;
            shift[v.index] += (p - closest.point) * w;
        }
    }
    let mut moved = false;
    for (i, &w) in weight.iter().enumerate() {
        if w > 0.0 {
            mesh.vertices[i] += shift[i] / w.max(1.0);
            moved = true;
        }
    }
    moved
}

/// Weight of a pull at `distance` from its centre: 1 within `core`, then
/// falling smoothly to 0 at `radius`.
fn fall_off(distance: f64, core: f64, radius: f64) -> f64 {
    let t = ((distance - core) / (radius - core)).clamp(0.0, 1.0);
    (1.0 - t * t).powi(2)
}

/// Typical gap between neighbouring `points` (indexed by `tree`): the 95th
/// percentile of the distance from a point to its nearest other point
/// (over at most 20,000 evenly strided points; duplicates left out); 0 for
/// fewer than two distinct points.
pub(crate) fn sampling_gap(points: &[DVec3], tree: &KdTree) -> f64 {
    let stride = (points.len() / 20_000).max(1);
    let mut gaps: Vec<f64> = points
        .par_iter()
        .step_by(stride)
        .filter_map(|&p| tree.knn(p, 2).get(1).map(|n| n.distance))
        .filter(|g| *g > 0.0)
        .collect();
    if gaps.is_empty() {
        return 0.0;
    }
    gaps.sort_by(|a, b| a.total_cmp(b));
    gaps[(gaps.len() - 1) * 95 / 100]
}

/// The data, their distances to the mesh and their sampling, to tell data
/// on a sampled surface from strays.
struct SampledSurface<'a> {
    points: &'a [DVec3],
    tree: &'a KdTree,
    distances: &'a [f64],
    far: f64,
    gap: f64,
    spacing: f64,
}

/// A point's nearest neighbours (itself left out) and their spread.
struct Neighbourhood {
    indices: Vec<usize>,
    distances: Vec<f64>,
    centre: DVec3,
    /// Variances along the principal directions, ascending.
    variances: [f64; 3],
    directions: [DVec3; 3],
}

impl SampledSurface<'_> {
    /// The nearest points to `p` but `own` (its index, if it is one).
    fn neighbourhood(&self, p: DVec3, own: Option<usize>) -> Option<Neighbourhood> {
        let found: Vec<_> = (self.tree.knn(p, NEIGHBOURS + 1).into_iter())
            .filter(|n| Some(n.index) != own)
            .take(NEIGHBOURS)
            .collect();
        if found.len() < NEIGHBOURS {
            return None;
        }
        let count = found.len() as f64;
        let centre = found.iter().map(|n| self.points[n.index]).sum::<DVec3>() / count;
        let mut cov = [[0.0; 3]; 3];
        for n in &found {
            let d = (self.points[n.index] - centre).to_array();
            (0..3).for_each(|r| (0..3).for_each(|c| cov[r][c] += d[r] * d[c] / (count - 1.0)));
        }
        let (variances, directions) = symmetric_eigen3(cov);
        Some(Neighbourhood {
            indices: found.iter().map(|n| n.index).collect(),
            distances: found.iter().map(|n| n.distance).collect(),
            centre,
            variances,
            directions,
        })
    }

    /// The neighbours of `p` lie along a tube thinner than a cell and `p`
    /// continues it beyond their last: a thin cone's tip sample, which the
    /// sampling leaves farther from the rest than the usual gap.
    fn tips_a_line(&self, p: DVec3, own: Option<usize>) -> bool {
        let Some(near) = self.neighbourhood(p, own) else {
            return false;
        };
        let [flat, wide, long] = near.variances;
        if near.distances[0] > 8.0 * self.gap
            || long < 2.5 * wide
            || (flat + wide).sqrt() > self.spacing
        {
            return false;
        }
        let Some(axis) = near.directions[2].try_normalize() else {
            return false;
        };
        let offset = p - near.centre;
        let along = offset.dot(axis).abs();
        let across = (offset - axis * offset.dot(axis)).length();
        let last = (near.indices.iter())
            .map(|&j| (self.points[j] - near.centre).dot(axis).abs())
            .fold(0.0, f64::max);
        along > last && across <= (0.5 * self.spacing).max(0.25 * along)
    }

    /// Point `i` lies on the surface its neighbours sample, and the mesh
    /// misses some of them too: a stray point off a surface the mesh
    /// follows has neighbours it reaches.
    fn on_missed_surface(&self, p: DVec3, i: usize) -> bool {
        let Some(near) = self.neighbourhood(p, Some(i)) else {
            return false;
        };
        if near.distances[0] > 1.5 * self.gap {
            return false;
        }
        let Some(normal) = near.directions[0].try_normalize() else {
            return false;
        };
        let median = near.distances[NEIGHBOURS / 2];
        let off_plane = (p - near.centre).dot(normal).abs();
        let missed = (near.indices.iter())
            .filter(|&&j| self.distances[j] > self.far)
            .count();
        off_plane <= 0.3 * median && missed >= 2
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::shapes::{icosphere, sample_surface};

    const H: f64 = 0.05;

    fn distance(mesh: &TriMesh, p: DVec3) -> f64 {
        distances_to(mesh, &[p])[0]
    }

    /// A unit sphere's samples and the mesh of the sphere alone.
    fn sphere(seed: u64) -> (TriMesh, Vec<DVec3>) {
        let mesh = icosphere(DVec3::ZERO, 1.0, 5);
        let points = sample_surface(&mesh, 20_000, seed).positions;
        (mesh, points)
    }

    /// Rings of three samples on a cone along +x from the unit sphere,
    /// radius 0.015 at the sphere to 0.003 at x = 1.3 (a cell is 0.05).
    fn cone() -> Vec<DVec3> {
        (0..10)
            .flat_map(|ring| {
                let x = 1.0 + 0.03 * ring as f64;
                let r = 0.015 - 0.0012 * ring as f64;
                (0..3).map(move |k| {
                    let a = (k as f64 + 0.3 * ring as f64) * std::f64::consts::TAU / 3.0;
                    DVec3::new(x, r * a.cos(), r * a.sin())
                })
            })
            .collect()
    }

    #[test]
    fn a_cone_is_reached_to_its_tip_and_a_stray_point_pulls_nothing() {
        let (mut mesh, mut points) = sphere(3);
        let cone = cone();
        let tip = DVec3::new(1.33, 0.0, 0.0);
        let stray = DVec3::new(0.0, 0.0, -1.0 - 3.0 * H);
        points.extend(cone.iter().chain([&tip, &stray]));
        assert!(reach_far_points(&mut mesh, &points, &[], H, MAX_PULL_CELLS) > 0);
        let far = FAR_CELLS * H;
        assert!(distance(&mesh, tip) <= far, "tip {}", distance(&mesh, tip));
        let missed = cone
            .iter()
            .filter(|&&p| distance(&mesh, p) > 2.0 * far)
            .count();
        assert!(
            missed <= 3,
            "{missed} of the cone's samples missed by a cell"
        );
        assert!(
            (distance(&mesh, stray) - 3.0 * H).abs() < 0.1 * H,
            "the stray point pulled"
        );
        // No two vertices on one position: manifold after welding.
        let mut at: Vec<[u64; 3]> = (mesh.vertices.iter())
            .map(|v| v.to_array().map(f64::to_bits))
            .collect();
        at.sort_unstable();
        assert!(at.windows(2).all(|w| w[0] != w[1]));
    }

    /// The faces around a cone's end as the level set left them on a
    /// harness input, and the cone's tip sample, grid spacing and far
    /// distance, from tests/data/lopsided_cone_end.obj.
    fn lopsided_cone_end() -> (TriMesh, DVec3, f64, f64) {
        let text = include_str!("../tests/data/lopsided_cone_end.obj");
        let numbers = |line: &str| -> Vec<f64> {
            line.split_whitespace()
                .filter_map(|w| w.parse().ok())
                .collect()
        };
        let mut mesh = TriMesh {
            vertices: vec![],
            triangles: vec![],
            normals: None,
        };
        let mut tip = vec![];
        for line in text.lines() {
            let values = numbers(line);
            match line.split_whitespace().next() {
                Some("v") => mesh.vertices.push(DVec3::from_slice(&values)),
                Some("f") => mesh.triangles.push([0, 1, 2].map(|k| values[k] as u32 - 1)),
                Some("#") if line.starts_with("# tip") => tip = values,
                _ => {}
            }
        }
        (mesh, DVec3::from_slice(&tip), tip[3], tip[4])
    }

    #[test]
    fn a_tip_no_vertex_can_take_alone_is_reached_with_a_ring_carried_along() {
        let (mesh, tip, spacing, far) = lopsided_cone_end();
        let fans = vertex_faces(&mesh.triangles, mesh.vertices.len());
        let oriented = DEGENERATE_AREA_CELLS * spacing * spacing;
        let core = TIP_VERTEX_CELLS * spacing;
        // None of the vertices near the tip's closest point can go alone.
        let closest = TriangleBvh::new(&mesh).closest(tip).unwrap().point;
        let alone = |v: usize| fans_keep_their_sides(&mesh, &fans, &[(v, tip)], oriented);
        let near = (0..mesh.vertices.len()).filter(|&v| mesh.vertices[v].distance(closest) <= core);
        assert!(!near.clone().any(alone) && near.count() > 1);
        let mut moved = mesh.clone();
        extend_to_tips(
            &mut moved,
            &[tip],
            far,
            TIP_VERTEX_CELLS * spacing,
            oriented,
        );
        assert!(moved.vertices.contains(&tip), "the tip not reached");
        let moves: Vec<(usize, DVec3)> = (0..mesh.vertices.len())
            .filter(|&v| moved.vertices[v] != mesh.vertices[v])
            .map(|v| (v, moved.vertices[v]))
            .collect();
        assert!(fans_keep_their_sides(&mesh, &fans, &moves, oriented));
    }

    #[test]
    fn a_tip_beyond_the_level_sets_reach_is_reached_when_the_caller_allows() {
        // On a grid of half the spacing the tip lies 13 cells out: beyond
        // the level set's reach, within a caller's (the SVM's) wider one.
        let h = H / 2.0;
        let tip = DVec3::new(1.33, 0.0, 0.0);
        let reached = |max_tip_cells: f64| {
            let (mut mesh, mut points) = sphere(5);
            points.extend(cone());
            points.push(tip);
            reach_far_points(&mut mesh, &points, &[], h, max_tip_cells);
            distance(&mesh, tip) <= FAR_CELLS * h
        };
        assert!(!reached(MAX_PULL_CELLS));
        assert!(reached(2.0 * MAX_PULL_CELLS));
    }

    #[test]
    fn a_tip_cleaning_dropped_is_reached_when_it_continues_its_line() {
        let (mut mesh, mut points) = sphere(4);
        points.extend(cone());
        // On the cone's line, and beside it (a stray cleaning dropped too).
        let dropped = [DVec3::new(1.33, 0.0, 0.0), DVec3::new(1.15, 0.2, 0.0)];
        reach_far_points(&mut mesh, &points, &dropped, H, MAX_PULL_CELLS);
        assert!(distance(&mesh, dropped[0]) <= FAR_CELLS * H);
        assert!(
            distance(&mesh, dropped[1]) > 2.0 * H,
            "the stray beside the line reached"
        );
    }
}
