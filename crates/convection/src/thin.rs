//! Thin parts: parts of the shape thinner than the sampling, which the
//! convection sweeps through (spike tips, the rim of a fin, a thin handle).
//!
//! 1. The paper's selection: the convection pursued in 2D over the sheets
//!    of coupled facets left at convergence ([`convect_sheets`]). A sheet's
//!    front starts at its rim (edges with one sheet triangle, or where
//!    sheets branch) facing inward and shrinks as the 3D convection does,
//!    one dimension down: a front edge `ab` facing triangle `abc` violates
//!    the 2D oriented Gabriel property when `c` lies strictly inside the
//!    circle with diameter `ab` (the angle at `c` is obtuse); the triangle
//!    is then removed and its two other edges join the front. Two fronts
//!    meeting at an edge stop there (the 2D collapse). Membranes spanning
//!    the outside are long, skinny triangles between far-apart parts of the
//!    surface and are eaten from their rim (on the harness bunny all 1,660
//!    sheet triangles go); sheets inside a thin part join near points in
//!    well-shaped triangles, which stop the front.
//! 2. A closed manifold instead of a double-sided sheet (`thicken`): the
//!    output must stay a manifold through the input points, so the kept
//!    sheets are thickened with the swept Delaunay tetrahedra around them
//!    rather than doubled: the small ones (longest edge within a few local
//!    spacings) on both sides of each kept sheet triangle, grown over
//!    connected small swept tetrahedra; then pinched edges of that solid are
//!    closed, points it does not reach are attached one tetrahedron at a
//!    time (a manifold step, the apex being new), and pieces left apart
//!    (a needle swept through over a short stretch) are bridged by the
//!    shortest chain of small tetrahedra.
//! 3. Holes through a thin plate (each a handle of the mesh), where the
//!    plate was swept through and no sheet was kept, are closed by a
//!    topology-controlled growth and erosion over small swept tetrahedra
//!    ([`crate::tunnels`]).

use crate::surface::{OrientedFacet, PseudoSurface};
use crate::tunnels::{close_tunnels, sorted_corners, TunnelClosing};
use std::collections::{HashMap, VecDeque};
use surfrecon_delaunay::{TetId, Triangulation, VertexId};
use surfrecon_geom::DVec3;

/// What [`thicken`] put back.
pub(crate) struct Thickening {
    /// Per tetrahedron slot: swept, but inside a thin part.
    pub restored: Vec<bool>,
    /// Sheet triangles the 2D convection keeps.
    pub sheet_kept: usize,
    /// Tunnels through thin parts closed ([`crate::tunnels`]).
    pub tunnels: TunnelClosing,
}

/// Put back the swept tetrahedra of thin parts (see the module doc).
/// `spacing` is the local sampling spacing per vertex, `size` the growth
/// bound in spacings.
pub(crate) fn thicken(
    surface: &PseudoSurface,
    tri: &Triangulation,
    rank: &[u32],
    spacing: &[f64],
    size: f64,
) -> Thickening {
    let sheet: Vec<OrientedFacet> = surface
        .facets()
        .filter(|&f| surface.is_coupled(f) && f < surface.mirror(f))
        .collect();
    let triangles: Vec<[u32; 3]> = sheet
        .iter()
        .map(|&f| surface.vertices(f).map(|v| v.0))
        .collect();
    let kept = convect_sheets(&triangles, tri.points());
    let widest = |t: TetId| {
        tri.tet_vertices(t)
            .iter()
            .map(|v| spacing[v.index()])
            .fold(0.0, f64::max)
    };
    let swept = |t: TetId| !tri.is_ghost(t) && surface.is_external(t);
    let small = |t: TetId| swept(t) && longest_edge(tri, t) <= size * widest(t);
    let mut seeds = vec![false; tri.tet_slots()];
    for (&f, _) in sheet.iter().zip(&kept).filter(|(_, &k)| k) {
        for t in [f.tet(), surface.mirror(f).tet()] {
            seeds[t.index()] = small(t);
        }
    }
    let restored = keep_attached(surface, tri, seeds, small);
    let mut tunnels = TunnelClosing::default();
    let mut solid: Vec<bool> = (0..restored.len())
        .map(|i| restored[i] || !surface.is_external(TetId(i as u32)))
        .collect();
    if restored.iter().any(|&r| r) {
        let closing =
            |t: TetId| swept(t) && circumradius(tri.tet_points(t)) <= 1.2 * size * widest(t);
        let joining = |t: TetId| swept(t) && longest_edge(tri, t) <= 1.6 * size * widest(t);
        let by_radius = |t: TetId| circumradius(tri.tet_points(t));
        const ROUNDS: usize = 4;
        close_pinched_edges(tri, &mut solid, swept, closing, by_radius, ROUNDS);
        attach_stray_points(tri, rank, &mut solid, joining, 64);
        close_pinched_edges(tri, &mut solid, swept, closing, by_radius, ROUNDS);
        bridge_pieces(tri, rank, &mut solid, joining, 6);
        close_pinched_edges(tri, &mut solid, swept, closing, by_radius, ROUNDS);
        // Holes through a plate swept bare where no sheet was kept: closed
        // with tetrahedra up to the joining size (4 spacings by default;
        // at 2.5 a hole in the sparse part of the harness nonuniform fin,
        // spanned by longer tetrahedra, stayed open). A closing
        // tetrahedron pinches the boundary at one edge; the pinch is closed
        // like the others.
        tunnels = close_tunnels(
            tri,
            rank,
            &mut solid,
            joining,
            |t| longest_edge(tri, t),
            20_000,
        );
        close_pinched_edges(tri, &mut solid, swept, closing, by_radius, ROUNDS);
    }
    Thickening {
        tunnels,
        restored: (0..solid.len())
            .map(|i| solid[i] && surface.is_external(TetId(i as u32)))
            .collect(),
        sheet_kept: kept.iter().filter(|&&k| k).count(),
    }
}

/// Only the `candidate` tetrahedra joined (through facets, over
/// candidates, growing over those passing `grows`) to the unswept solid: a
/// lone restored island would be a separate piece.
fn keep_attached(
    surface: &PseudoSurface,
    tri: &Triangulation,
    candidate: Vec<bool>,
    grows: impl Fn(TetId) -> bool,
) -> Vec<bool> {
    let mut attached = vec![false; candidate.len()];
    let mut stack: Vec<TetId> = tri
        .finite_tets()
        .filter(|&t| candidate[t.index()])
        .filter(|&t| tri.neighbors(t).iter().any(|&u| !surface.is_external(u)))
        .collect();
    for &t in &stack {
        attached[t.index()] = true;
    }
    while let Some(t) = stack.pop() {
        for u in tri.neighbors(t) {
            if !attached[u.index()] && (candidate[u.index()] || grows(u)) {
                attached[u.index()] = true;
                stack.push(u);
            }
        }
    }
    attached
}

/// Radius of the sphere through the four corners (infinite when flat).
fn circumradius([a, b, c, d]: [DVec3; 4]) -> f64 {
    let (u, v, w) = (b - a, c - a, d - a);
    let det = 2.0 * u.dot(v.cross(w));
    if det == 0.0 {
        return f64::INFINITY;
    }
    let centre = (v.cross(w) * u.length_squared()
        + w.cross(u) * v.length_squared()
        + u.cross(v) * w.length_squared())
        / det;
    centre.length()
}

/// Whether `c` lies strictly inside the circle with diameter `ab`.
fn in_diametral_circle(a: DVec3, b: DVec3, c: DVec3) -> bool {
    (a - c).dot(b - c) < 0.0
}

/// Which `triangles` (vertex indices into `points`, any orientation) the 2D
/// convection over the sheets keeps: one flag per triangle.
pub fn convect_sheets(triangles: &[[u32; 3]], points: &[DVec3]) -> Vec<bool> {
    let mut by_edge: HashMap<(u32, u32), Vec<u32>> = HashMap::with_capacity(3 * triangles.len());
    for (i, t) in triangles.iter().enumerate() {
        for (a, b) in edges(t) {
            by_edge.entry(key(a, b)).or_default().push(i as u32);
        }
    }
    let mut kept = vec![true; triangles.len()];
    // (triangle, edge) pairs of the front, facing into the triangle.
    let mut front: VecDeque<(u32, (u32, u32))> = VecDeque::new();
    for (i, t) in triangles.iter().enumerate() {
        for (a, b) in edges(t) {
            if by_edge[&key(a, b)].len() != 2 {
                front.push_back((i as u32, (a, b)));
            }
        }
    }
    while let Some((i, (a, b))) = front.pop_front() {
        if !kept[i as usize] {
            continue;
        }
        let t = triangles[i as usize];
        let Some(&c) = t.iter().find(|&&v| v != a && v != b) else {
            continue;
        };
        let [pa, pb, pc] = [a, b, c].map(|v| points[v as usize]);
        if !in_diametral_circle(pa, pb, pc) {
            continue;
        }
        kept[i as usize] = false;
        for (u, w) in [(b, c), (c, a)] {
            for &j in &by_edge[&key(u, w)] {
                if j != i && kept[j as usize] {
                    front.push_back((j, (u, w)));
                }
            }
        }
    }
    kept
}

fn edges(&[a, b, c]: &[u32; 3]) -> [(u32, u32); 3] {
    [(a, b), (b, c), (c, a)]
}

fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// The tetrahedra around the edge `ab` of tetrahedron `t`, in turning order
/// starting with `t`.
pub(crate) fn edge_ring(tri: &Triangulation, t: TetId, a: VertexId, b: VertexId) -> Vec<TetId> {
    let mut ring = vec![t];
    let others = |t: TetId| {
        let v = tri.tet_vertices(t);
        let mut o = v.iter().enumerate().filter(|(_, &x)| x != a && x != b);
        let (i, _) = o.next().expect("edge in tetrahedron");
        let (j, _) = o.next().expect("edge in tetrahedron");
        (i, j)
    };
    // Cross the facet opposite one free corner, keeping the other: the
    // kept corner is opposite the facet crossed next.
    let (mut cross, _) = others(t);
    let mut current = t;
    loop {
        let keep = tri.tet_vertices(current)[(0..4)
            .find(|&k| k != cross && ![a, b].contains(&tri.tet_vertices(current)[k]))
            .expect("free corner")];
        let (next, _) = tri.mirror(current, cross);
        if next == t || ring.len() > 4096 {
            return ring;
        }
        ring.push(next);
        cross = tri
            .tet_vertices(next)
            .iter()
            .position(|&x| x == keep)
            .expect("shared corner");
        current = next;
    }
}

/// Close pinches of the solid (`solid` per tetrahedron slot) at its edges:
/// where the solid tetrahedra around an edge form several wedges, the
/// gaps between them (all but the one reaching the largest tetrahedron,
/// the outside) are filled when every tetrahedron in them passes `small`.
/// Returns the tetrahedra added.
pub(crate) fn close_pinched_edges(
    tri: &Triangulation,
    solid: &mut [bool],
    swept: impl Fn(TetId) -> bool,
    small: impl Fn(TetId) -> bool,
    size: impl Fn(TetId) -> f64,
    rounds: usize,
) -> usize {
    let mut added = 0;
    for _ in 0..rounds {
        // Only edges of put-back tetrahedra: elsewhere the surface is the
        // convection's own, and its pinches are left to the mesh clean-up.
        let mut edges: HashMap<(u32, u32), TetId> = HashMap::new();
        for t in tri.finite_tets().filter(|&t| solid[t.index()] && swept(t)) {
            for (slot, u) in tri.neighbors(t).into_iter().enumerate() {
                if solid[u.index()] && !tri.is_ghost(u) {
                    continue;
                }
                let [x, y, z] = tri.facet(t, slot);
                for (p, q) in [(x, y), (y, z), (z, x)] {
                    edges.entry(key(p.0, q.0)).or_insert(t);
                }
            }
        }
        let mut sorted: Vec<((u32, u32), TetId)> = edges.into_iter().collect();
        sorted.sort_unstable();
        let mut fill = Vec::new();
        for ((p, q), t) in sorted {
            let ring = edge_ring(tri, t, VertexId(p), VertexId(q));
            fill.extend(gaps_to_fill(&ring, solid, tri, &small, &size));
        }
        let before = added;
        for t in fill {
            if !solid[t.index()] {
                solid[t.index()] = true;
                added += 1;
            }
        }
        if added == before {
            break;
        }
    }
    added
}

/// The runs of non-solid tetrahedra of `ring` to fill: every run but the
/// one holding a ghost or the largest tetrahedron, if all are small.
fn gaps_to_fill(
    ring: &[TetId],
    solid: &[bool],
    tri: &Triangulation,
    small: &impl Fn(TetId) -> bool,
    size: &impl Fn(TetId) -> f64,
) -> Vec<TetId> {
    let Some(start) = ring.iter().position(|t| solid[t.index()]) else {
        return Vec::new();
    };
    let mut runs: Vec<Vec<TetId>> = Vec::new();
    let mut open = false;
    for k in 0..ring.len() {
        let t = ring[(start + k) % ring.len()];
        if solid[t.index()] {
            open = false;
        } else {
            if !open {
                runs.push(Vec::new());
                open = true;
            }
            runs.last_mut().expect("run").push(t);
        }
    }
    if runs.len() < 2 {
        return Vec::new();
    }
    let weight = |run: &Vec<TetId>| {
        run.iter()
            .map(|&t| {
                if tri.is_ghost(t) {
                    f64::INFINITY
                } else {
                    size(t)
                }
            })
            .fold(0.0, f64::max)
    };
    let outside = (0..runs.len())
        .max_by(|&i, &j| weight(&runs[i]).total_cmp(&weight(&runs[j])))
        .expect("runs");
    runs.into_iter()
        .enumerate()
        .filter(|(i, run)| *i != outside && run.iter().all(|&t| !tri.is_ghost(t) && small(t)))
        .flat_map(|(_, run)| run)
        .collect()
}

/// Attach the points the solid does not reach (swept from all sides: the
/// tip of a needle, the rim of a fin): a tetrahedron with such a point as
/// apex, passing `small`, whose opposite facet lies on the solid's
/// boundary, is added; that keeps the boundary manifold, since the apex is
/// new to it. Repeated, so chains of points along a needle join one by one.
/// Returns the tetrahedra added.
pub(crate) fn attach_stray_points(
    tri: &Triangulation,
    rank: &[u32],
    solid: &mut [bool],
    small: impl Fn(TetId) -> bool,
    rounds: usize,
) -> usize {
    let mut on_solid = vec![false; tri.points().len()];
    for t in tri.finite_tets().filter(|&t| solid[t.index()]) {
        for v in tri.tet_vertices(t) {
            on_solid[v.index()] = true;
        }
    }
    let mut stray: Vec<VertexId> = tri.vertices().filter(|v| !on_solid[v.index()]).collect();
    // Attached in input order: each attachment changes what the next sees.
    stray.sort_by_key(|v| rank.get(v.index()).copied().unwrap_or(u32::MAX));
    let mut added = 0;
    for _ in 0..rounds {
        let before = added;
        stray.retain(|&v| {
            let joins = |t: &TetId| {
                let slot = tri.tet_vertices(*t).iter().position(|&x| x == v);
                let (across, _) = tri.mirror(*t, slot.expect("incident"));
                !tri.is_ghost(*t)
                    && !solid[t.index()]
                    && solid[across.index()]
                    && !tri.is_ghost(across)
            };
            let best = tri
                .incident_tets(v)
                .into_iter()
                .filter(joins)
                .filter(|&t| small(t))
                // Ties (around one longest edge) by corners, not by slot.
                .min_by(|&s, &t| {
                    longest_edge(tri, s)
                        .total_cmp(&longest_edge(tri, t))
                        .then(sorted_corners(tri, rank, s).cmp(&sorted_corners(tri, rank, t)))
                });
            let Some(t) = best else {
                return true;
            };
            solid[t.index()] = true;
            on_solid[v.index()] = true;
            added += 1;
            false
        });
        if added == before {
            break;
        }
    }
    added
}

/// Length of the longest edge of `t`.
pub(crate) fn longest_edge(tri: &Triangulation, t: TetId) -> f64 {
    let p = tri.tet_points(t);
    let mut longest: f64 = 0.0;
    for i in 0..4 {
        for j in i + 1..4 {
            longest = longest.max(p[i].distance(p[j]));
        }
    }
    longest
}

/// Join the pieces of the solid (tetrahedra connected through facets) to
/// the largest one, each through the shortest chain of at most `steps`
/// tetrahedra passing `small` (a gap across a needle swept through).
/// Returns the tetrahedra added.
pub(crate) fn bridge_pieces(
    tri: &Triangulation,
    rank: &[u32],
    solid: &mut [bool],
    small: impl Fn(TetId) -> bool,
    steps: usize,
) -> usize {
    const NONE: u32 = u32::MAX;
    let mut piece = vec![NONE; solid.len()];
    let mut sizes = Vec::new();
    for t in tri.finite_tets().filter(|&t| solid[t.index()]) {
        if piece[t.index()] != NONE {
            continue;
        }
        let id = sizes.len() as u32;
        let mut stack = vec![t];
        piece[t.index()] = id;
        let mut size = 0usize;
        while let Some(s) = stack.pop() {
            size += 1;
            for u in tri.neighbors(s) {
                if solid[u.index()] && !tri.is_ghost(u) && piece[u.index()] == NONE {
                    piece[u.index()] = id;
                    stack.push(u);
                }
            }
        }
        sizes.push(size);
    }
    let Some(main) = (0..sizes.len()).max_by_key(|&i| sizes[i]) else {
        return 0;
    };
    let mut added = 0;
    // Smallest pieces first: each search is over its own neighbourhood.
    let mut members: Vec<Vec<TetId>> = vec![Vec::new(); sizes.len()];
    for t in tri.finite_tets().filter(|&t| piece[t.index()] != NONE) {
        members[piece[t.index()] as usize].push(t);
    }
    // Members, and pieces of one size, by corners rather than by slot: the
    // first shortest chain found does not depend on the numbering.
    for m in &mut members {
        m.sort_by_cached_key(|&t| sorted_corners(tri, rank, t));
    }
    let mut order: Vec<usize> = (0..sizes.len()).filter(|&i| i != main).collect();
    order.sort_by_key(|&i| (sizes[i], sorted_corners(tri, rank, members[i][0])));
    for id in order {
        let start = std::mem::take(&mut members[id]);
        if start.is_empty() {
            continue;
        }
        let Some((chain, target)) =
            shortest_bridge(tri, rank, solid, &piece, &start, &small, steps)
        else {
            members[id] = start;
            continue;
        };
        for &t in &chain {
            solid[t.index()] = true;
            added += 1;
        }
        // The joined piece (and its chain) now belongs to the target.
        for &t in start.iter().chain(&chain) {
            piece[t.index()] = target;
        }
        members[target as usize].extend(start.into_iter().chain(chain));
    }
    added
}

/// The neighbours of `t` by their sorted corners (not by slot).
fn neighbours_by_corners(tri: &Triangulation, rank: &[u32], t: TetId) -> [TetId; 4] {
    let mut n = tri.neighbors(t);
    n.sort_by_cached_key(|&u| sorted_corners(tri, rank, u));
    n
}

/// Breadth-first search from `start` (one piece) over non-solid small
/// tetrahedra to one touching another piece: the chain and that piece.
fn shortest_bridge(
    tri: &Triangulation,
    rank: &[u32],
    solid: &[bool],
    piece: &[u32],
    start: &[TetId],
    small: &impl Fn(TetId) -> bool,
    steps: usize,
) -> Option<(Vec<TetId>, u32)> {
    let own = piece[start[0].index()];
    let mut parent: HashMap<TetId, Option<TetId>> = HashMap::new();
    let mut layer: Vec<TetId> = Vec::new();
    for &t in start {
        for u in neighbours_by_corners(tri, rank, t) {
            if !solid[u.index()] && !tri.is_ghost(u) && small(u) && !parent.contains_key(&u) {
                parent.insert(u, None);
                layer.push(u);
            }
        }
    }
    for _ in 0..steps {
        let mut next = Vec::new();
        for &t in &layer {
            for u in neighbours_by_corners(tri, rank, t) {
                let other = piece[u.index()];
                if solid[u.index()] && !tri.is_ghost(u) && other != own && other != u32::MAX {
                    let mut chain = vec![t];
                    let mut at = t;
                    while let Some(Some(p)) = parent.get(&at) {
                        chain.push(*p);
                        at = *p;
                    }
                    return Some((chain, other));
                }
                if !solid[u.index()] && !tri.is_ghost(u) && small(u) && !parent.contains_key(&u) {
                    parent.insert(u, Some(t));
                    next.push(u);
                }
            }
        }
        layer = next;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of right isosceles triangles (a thin part's sheet): every
    /// angle facing the rim is at most 90°, so the front stops at once.
    #[test]
    fn well_shaped_strip_is_kept() {
        let mut points = Vec::new();
        for i in 0..6 {
            points.push(DVec3::new(i as f64, 0.0, 0.0));
            points.push(DVec3::new(i as f64, 1.0, 0.0));
        }
        let mut triangles = Vec::new();
        for i in 0..5u32 {
            triangles.push([2 * i, 2 * i + 2, 2 * i + 1]);
            triangles.push([2 * i + 1, 2 * i + 2, 2 * i + 3]);
        }
        assert!(convect_sheets(&triangles, &points).iter().all(|&k| k));
    }

    /// A fan of skinny triangles between two far-apart rows (a membrane):
    /// the obtuse angles let the front through, all of it goes.
    #[test]
    fn skinny_membrane_is_eaten_from_its_rim() {
        let mut points = Vec::new();
        for i in 0..8 {
            points.push(DVec3::new(i as f64 * 0.1, 0.0, 0.0));
        }
        points.push(DVec3::new(0.35, 0.02, 0.0));
        let triangles: Vec<[u32; 3]> = (0..7u32).map(|i| [i, i + 1, 8]).collect();
        let kept = convect_sheets(&triangles, &points);
        assert!(kept.iter().all(|&k| !k), "{kept:?}");
    }

    /// A mixed sheet: the front eats the obtuse triangle whose long edge
    /// is on the rim and stops at the well-shaped one behind it.
    #[test]
    fn front_stops_at_the_first_well_shaped_triangle() {
        let points = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, 0.1, 0.0), // obtuse apex over the rim edge 0-1
            DVec3::new(0.836, 0.48, 0.0), // nearly equilateral with 2, 1
        ];
        let triangles = vec![[0, 1, 2], [2, 1, 3]];
        assert_eq!(convect_sheets(&triangles, &points), vec![false, true]);
    }
}
