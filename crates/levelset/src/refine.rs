//! Final touches on the extracted surface, where the grid's resolution
//! limits it: vertices near the data move onto the data's local fit (and,
//! for exact points, beside sharp edges onto the nearest point's plane),
//! and the patches spanning gaps in scanned data are faired.
//!
//! The evolved zero set lies on the data only to a fraction of a cell and
//! spans holes with a minimal surface, which sags into the body. Snapping
//! ([`project_onto_points`]) places the supported vertices between the
//! samples; where the fit is not one sheet (a sharp edge) the plane of the
//! nearest point's face does; fairing ([`fair`]) replaces each sagging
//! patch with the smoothest fill that meets the surrounding surface with
//! its slope, and [`fit_to_rim`] then bends it onto the curvature the rim's
//! data continue. All only move vertices, so the mesh stays watertight, and
//! moves that would fold or flatten a triangle are undone. Data beyond a
//! cell's reach are pulled onto by [`crate::reach`].

use crate::cleaning::{project_onto_points, SurfaceFit};
use crate::rim_fit::{fit_to_rim, normals_near, RimData};
use rayon::prelude::*;
use surfrecon_geom::fairing::{area_weighted_normals, fair, FairingOptions};
use surfrecon_geom::intersections::{intersections_of, self_intersections};
use surfrecon_geom::normals::normal_beside_edges;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, TriMesh};

/// Vertices within this many cells of a data point are supported: they
/// are snapped, the others may be faired.
pub const SUPPORT_CELLS: f64 = 2.0;

/// Data points per local fit when snapping.
const SNAP_NEIGHBOURS: usize = 16;

/// Data this many cells apart along a vertex normal lie on separate sheets
/// (both sides of a fin a few cells thick); one sheet's samples lie within
/// a fraction of a cell of each other there.
const SHEET_GAP_CELLS: f64 = 1.0;

/// Data points per plane fit beside sharp edges (few, so that a
/// neighbourhood on one face is found close to the edge; harness shapes:
/// 10 better than 16 on box, fandisk, bunny and spikes).
const PLANE_NEIGHBOURS: usize = 10;

/// Gaps are faired only when at least this share of the vertices is
/// supported: a scan with holes. Sparse data (a few curves, slices) give
/// no reliable slopes to continue, and keep the paper's weighted minimal
/// surface.
const SUPPORTED_SHARE: f64 = 0.75;

/// What [`refine_surface`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefineStats {
    /// Vertices moved onto the data's local fit.
    pub snapped: usize,
    /// Vertices moved onto the tangent plane of their nearest data point
    /// (where the fit did not take them: beside sharp edges).
    pub snapped_to_planes: usize,
    /// Of those, vertices then moved onto the line where their plane meets
    /// a neighbour's across a sharp edge.
    pub snapped_to_edges: usize,
    /// Vertices of faired gap patches.
    pub faired: usize,
    /// Largest distance a faired vertex moved (world units).
    pub max_fairing_shift: f64,
    /// Faired vertices then moved onto the rim data's quadric (exact
    /// points only).
    pub fitted_to_rim: usize,
    /// Far data the surface was pulled onto ([`crate::reach`]).
    pub reached_far_points: usize,
    /// Moved vertices put back where their faces crossed others
    /// ([`undo_crossing_moves`]).
    pub uncrossed: usize,
}

/// What [`refine_surface`] may do besides snapping onto the data's fit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefineOptions {
    /// Fair the patches over gaps when the data cover most of the surface.
    pub fair_gaps: bool,
    /// The points are exact samples (not smoothed by cleaning): where the
    /// fit fails, beside sharp edges, vertices may go onto the tangent
    /// plane of their nearest point, and faired gap patches onto the
    /// rim's quadric. Noisy points would pass their noise on.
    pub exact_points: bool,
}

/// Snap `mesh` onto `points` (the cleaned point data) and, as `options`
/// allow, onto the planes beside sharp edges and fair the patches over
/// the gaps. `normals` are the points' (either sign), or empty: then they
/// are estimated where a gap needs them. `spacing` is the grid spacing the
/// mesh came from.
pub fn refine_surface(
    mesh: &mut TriMesh,
    points: &[DVec3],
    normals: &[DVec3],
    spacing: f64,
    options: RefineOptions,
) -> RefineStats {
    let mut stats = RefineStats::default();
    if points.is_empty() || mesh.vertices.is_empty() {
        return stats;
    }
    let reach = SUPPORT_CELLS * spacing;
    let computed;
    let vertex_normals = match &mesh.normals {
        Some(n) => n,
        None => {
            computed = area_weighted_normals(&mesh.vertices, &mesh.triangles);
            &computed
        }
    };
    let fit = SurfaceFit {
        dim: 3,
        reach,
        neighbours: SNAP_NEIGHBOURS,
        sheet_gap: SHEET_GAP_CELLS * spacing,
    };
    // One index of the points for both snapping steps.
    let tree = KdTree::new(points);
    let on_grid = mesh.vertices.clone();
    let projection = project_onto_points(&mut mesh.vertices, vertex_normals, points, &tree, &fit);
    if options.exact_points {
        let beside_edges: Vec<bool> = (projection.supported.iter().zip(&projection.fitted))
            .map(|(&supported, &fitted)| supported && !fitted)
            .collect();
        let before = mesh.vertices.clone();
        let planes =
            project_onto_nearest_planes(&mut mesh.vertices, points, &tree, &beside_edges, spacing);
        stats.snapped_to_planes = undo_degenerating_moves(mesh, &before, folded);
        // A vertex whose plane move was undone may still reach the line
        // (the same undo judges that move): its plane stays.
        let before = mesh.vertices.clone();
        onto_edges_of_planes(mesh, &planes, spacing);
        stats.snapped_to_edges = undo_degenerating_moves(mesh, &before, folded);
    }
    // Snaps onto the fit can land two vertices on one point too, or flatten
    // a triangle to nothing (between sparse slices): undone, as the planes'
    // moves are, but a sliver may turn over (refusing that cost up to 6% of
    // the harness's CD).
    let moved = undo_degenerating_moves(mesh, &on_grid, collapsed);
    stats.snapped = moved.saturating_sub(stats.snapped_to_planes);
    if options.fair_gaps {
        // Unsupported vertices did not move, so their support stands.
        let free: Vec<bool> = projection.supported.iter().map(|s| !s).collect();
        let unsupported = free.iter().filter(|&&f| f).count();
        if unsupported as f64 <= (1.0 - SUPPORTED_SHARE) * free.len() as f64 {
            let faired = fair(mesh, &free, &FairingOptions::default());
            stats.faired = faired.moved;
            stats.max_fairing_shift = faired.max_shift;
            // Noise's curvature would be continued too: noisy scans keep
            // the faired fill (the merged raw bunny scans: CD 6.40 → 6.62e-5).
            if faired.moved > 0 && options.exact_points {
                stats.fitted_to_rim = bend_onto_rim(mesh, &free, points, normals, &tree, spacing);
            }
        }
    }
    stats
}

/// [`fit_to_rim`] for the faired vertices (`free`), kernels at least
/// [`SUPPORT_CELLS`] wide; moves that fold a triangle are undone.
fn bend_onto_rim(
    mesh: &mut TriMesh,
    free: &[bool],
    points: &[DVec3],
    normals: &[DVec3],
    tree: &KdTree,
    spacing: f64,
) -> usize {
    let min_width = SUPPORT_CELLS * spacing;
    let estimated;
    let normals = if normals.len() == points.len() {
        normals
    } else {
        let v = &mesh.vertices;
        estimated = normals_near(v, free, points, tree, min_width, SNAP_NEIGHBOURS);
        &estimated
    };
    let data = RimData {
        points,
        normals,
        tree,
    };
    let faired = mesh.vertices.clone();
    let vertex_normals = area_weighted_normals(&mesh.vertices, &mesh.triangles);
    fit_to_rim(&mut mesh.vertices, &vertex_normals, free, &data, min_width);
    let kept = undo_degenerating_moves(mesh, &faired, folded);
    // Vertices whose fit was refused would stand as dents among the bent
    // ones: faired again between them.
    let unbent: Vec<bool> = (0..free.len())
        .map(|v| free[v] && mesh.vertices[v] == faired[v])
        .collect();
    if kept > 0 && unbent.contains(&true) {
        let before = mesh.vertices.clone();
        fair(mesh, &unbent, &FairingOptions::default());
        undo_degenerating_moves(mesh, &before, folded);
    }
    if let Some(n) = &mut mesh.normals {
        let bent = area_weighted_normals(&mesh.vertices, &mesh.triangles);
        for (v, normal) in n.iter_mut().enumerate() {
            if mesh.vertices[v] != faired[v] {
                *normal = bent[v];
            }
        }
    }
    kept
}

/// Move each vertex marked in `which` onto the tangent plane of its nearest
/// data point (fitted by [`normal_beside_edges`]) where that moves it at
/// most one cell of `spacing`. Beside a sharp edge the vertex is on the
/// rounded grid surface; the nearest point's plane is that of the face it
/// belongs to, so the mesh follows both faces up to the edge.
fn project_onto_nearest_planes(
    vertices: &mut [DVec3],
    points: &[DVec3],
    tree: &KdTree,
    which: &[bool],
    spacing: f64,
) -> Vec<Option<Plane>> {
    if points.len() < PLANE_NEIGHBOURS {
        return vec![None; vertices.len()];
    }
    vertices
        .par_iter_mut()
        .zip(which)
        .map(|(v, &w)| {
            let near = tree.nearest(*v).filter(|_| w)?;
            let p = points[near.index];
            let n = normal_beside_edges(points, tree, near.index, PLANE_NEIGHBOURS);
            let foot = *v - n * n.dot(*v - p);
            (foot.distance(*v) <= spacing).then(|| {
                *v = foot;
                Plane {
                    point: p,
                    normal: n,
                }
            })
        })
        .collect()
}

/// A face's plane beside a sharp edge.
#[derive(Clone, Copy, Debug)]
struct Plane {
    point: DVec3,
    normal: DVec3,
}

/// Planes whose normals' cosine is below this meet at a sharp edge.
const EDGE_COSINE: f64 = 0.87;

/// Move each vertex on a plane, whose ring holds vertices on one other
/// plane across a sharp edge, onto the two planes' line where it is nearer
/// that line than those neighbours and within half a cell: the triangles
/// across the edge otherwise cut it off by up to a cell.
fn onto_edges_of_planes(mesh: &mut TriMesh, planes: &[Option<Plane>], spacing: f64) {
    let (at, triangles) = (&mesh.vertices, &mesh.triangles);
    let faces = surfrecon_geom::metrics::vertex_faces(triangles, at.len());
    let moves: Vec<(usize, DVec3)> = (0..at.len())
        .into_par_iter()
        .filter_map(|v| {
            let own = planes[v]?;
            let ring = (faces.of(v).iter()).flat_map(|&f| triangles[f as usize]);
            let across: Vec<usize> = ring
                .filter(|&w| w as usize != v)
                .map(|w| w as usize)
                .filter(|&w| {
                    planes[w].is_some_and(|q| q.normal.dot(own.normal).abs() < EDGE_COSINE)
                })
                .collect();
            let other = planes[*across.first()?]?;
            let on_line = |x: DVec3| closest_on_line(own, other, x);
            let target = on_line(at[v])?;
            let gap = target.distance(at[v]);
            let nearest_across = across.iter().all(|&w| {
                planes[w].is_some_and(|q| q.normal.dot(other.normal).abs() >= EDGE_COSINE)
                    && on_line(at[w]).is_some_and(|t| t.distance(at[w]) > gap)
            });
            (nearest_across && gap <= 0.5 * spacing).then_some((v, target))
        })
        .collect();
    for (v, target) in moves {
        mesh.vertices[v] = target;
    }
}

/// The point of the line where planes `a` and `b` meet nearest to `x`.
fn closest_on_line(a: Plane, b: Plane, x: DVec3) -> Option<DVec3> {
    let c = a.normal.dot(b.normal);
    let det = 1.0 - c * c;
    if det < 1e-6 {
        return None;
    }
    let (ra, rb) = (a.normal.dot(x - a.point), b.normal.dot(x - b.point));
    let s = (ra - c * rb) / det;
    let t = (rb - c * ra) / det;
    Some(x - a.normal * s - b.normal * t)
}

/// Put back every moved vertex (one differing from `before`) of a
/// triangle whose normals (area vectors) before and after the moves are
/// `degenerate`, and every moved vertex that landed on another vertex's
/// position, until none is left: the mesh stays manifold after welding by
/// position. Returns the number of vertices that keep their move.
pub(crate) fn undo_degenerating_moves(
    mesh: &mut TriMesh,
    before: &[DVec3],
    degenerate: impl Fn(DVec3, DVec3) -> bool + Sync,
) -> usize {
    let normal = |v: &[DVec3], t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| v[i as usize]);
        (b - a).cross(c - a)
    };
    loop {
        let vertices = &mesh.vertices;
        let moved = |i: u32| vertices[i as usize] != before[i as usize];
        let mut undo: Vec<u32> = mesh
            .triangles
            .par_iter()
            .filter(|t| t.iter().any(|&i| moved(i)))
            .filter(|t| degenerate(normal(before, t), normal(vertices, t)))
            .flat_map_iter(|t| t.iter().copied().filter(|&i| moved(i)))
            .collect();
        undo.extend(coincident(vertices).filter(|&i| moved(i)));
        if undo.is_empty() {
            return (0..before.len() as u32).filter(|&i| moved(i)).count();
        }
        for i in undo {
            mesh.vertices[i as usize] = before[i as usize];
        }
    }
}

/// The vertices that share their position (bit for bit) with another
/// vertex, each once: runs of equal positions after a parallel sort (a
/// serial hash map of all positions took 0.1 s per call on 300k vertices).
fn coincident(vertices: &[DVec3]) -> impl Iterator<Item = u32> {
    let mut keyed: Vec<([u64; 3], u32)> = (vertices.par_iter().enumerate())
        .map(|(i, v)| (v.to_array().map(f64::to_bits), i as u32))
        .collect();
    keyed.par_sort_unstable();
    let shared = |i: usize| {
        (i > 0 && keyed[i - 1].0 == keyed[i].0)
            || (i + 1 < keyed.len() && keyed[i + 1].0 == keyed[i].0)
    };
    let found: Vec<u32> = (0..keyed.len())
        .filter(|&i| shared(i))
        .map(|i| keyed[i].1)
        .collect();
    found.into_iter()
}

/// Rounds of [`undo_crossing_moves`] that put back one vertex per crossing
/// pair, then all six, before every moved vertex goes back.
const FARTHEST_ONLY_ROUNDS: usize = 8;
const UNCROSSING_ROUNDS: usize = 16;

/// Put back (to `before`, a mesh without self-intersections, such as the
/// marching-cubes surface) moved vertices of the pairs of faces that cross,
/// until none do: snapping neighbours onto different sheets or planes can
/// fold a sliver through the next face. First only the vertex of each pair
/// that moved farthest, then all of the pair's, after
/// [`UNCROSSING_ROUNDS`] rounds every moved vertex. Returns the number of
/// vertices put back.
pub fn undo_crossing_moves(mesh: &mut TriMesh, before: &[DVec3]) -> usize {
    let moved_by = |m: &TriMesh, v: u32| m.vertices[v as usize].distance(before[v as usize]);
    let moved = |m: &TriMesh, v: u32| m.vertices[v as usize] != before[v as usize];
    let moved_face = |m: &TriMesh, f: u32| m.triangles[f as usize].iter().any(|&v| moved(m, v));
    // Only pairs with a moved face can give vertices to put back; the
    // others crossed before and stay as they are. The pairs are kept from
    // round to round, and only the faces around the vertices put back are
    // tested again (the whole mesh takes 0.5 s at 600k faces).
    let faces: Vec<u32> = (0..mesh.triangles.len() as u32)
        .into_par_iter()
        .filter(|&f| moved_face(mesh, f))
        .collect();
    let mut crossing = crossings_of(mesh, &faces);
    crossing.retain(|pair| pair.iter().any(|&f| moved_face(mesh, f)));
    let mut put_back = 0;
    for round in 0.. {
        // The last rounds put back every moved vertex while any pair
        // crosses, moved or not.
        if crossing.is_empty() && (round < UNCROSSING_ROUNDS || self_intersections(mesh).is_empty())
        {
            break;
        }
        let pair_vertices = |pair: &[u32; 2]| pair.map(|f| mesh.triangles[f as usize]).concat();
        let mut vertices: Vec<u32> = match round {
            r if r < FARTHEST_ONLY_ROUNDS => (crossing.iter())
                .filter_map(|pair| {
                    let farthest = pair_vertices(pair)
                        .into_iter()
                        .max_by(|&a, &b| moved_by(mesh, a).total_cmp(&moved_by(mesh, b)));
                    farthest.filter(|&v| moved_by(mesh, v) > 0.0)
                })
                .collect(),
            r if r < UNCROSSING_ROUNDS => crossing.iter().flat_map(pair_vertices).collect(),
            _ => (0..before.len() as u32).collect(),
        };
        vertices.retain(|&v| moved(mesh, v));
        if vertices.is_empty() {
            break; // crossing before the moves too: nothing of ours
        }
        vertices.sort_unstable();
        vertices.dedup();
        for &v in &vertices {
            mesh.vertices[v as usize] = before[v as usize];
        }
        put_back += vertices.len();
        let changed = faces_around(mesh, &vertices);
        crossing.retain(|pair| pair.iter().all(|f| changed.binary_search(f).is_err()));
        crossing.extend(crossings_of(mesh, &changed));
        crossing.retain(|pair| pair.iter().any(|&f| moved_face(mesh, f)));
        crossing.sort_unstable();
        crossing.dedup();
    }
    put_back
}

/// The crossing pairs holding one of `faces`: the test of the whole mesh
/// when they are many (it is cheaper per face), with other pairs too.
fn crossings_of(mesh: &TriMesh, faces: &[u32]) -> Vec<[u32; 2]> {
    if faces.len() * WHOLE_MESH_SHARE > mesh.triangles.len() {
        self_intersections(mesh)
    } else {
        intersections_of(mesh, faces)
    }
}

/// [`crossings_of`] tests the whole mesh when more than one face in this
/// many is asked for.
const WHOLE_MESH_SHARE: usize = 8;

/// The faces (sorted) with a corner among `vertices` (sorted).
fn faces_around(mesh: &TriMesh, vertices: &[u32]) -> Vec<u32> {
    (0..mesh.triangles.len() as u32)
        .into_par_iter()
        .filter(|&f| {
            mesh.triangles[f as usize]
                .iter()
                .any(|v| vertices.binary_search(v).is_ok())
        })
        .collect()
}

/// A moved triangle keeps at least this share of its area, measured along
/// its old normal (a turned-over triangle has a negative share).
const MIN_AREA_KEPT: f64 = 0.05;

/// Turned over, or below [`MIN_AREA_KEPT`] of its area.
fn folded(old: DVec3, new: DVec3) -> bool {
    new.dot(old) <= MIN_AREA_KEPT * old.length_squared()
}

/// Of no area any more (a millionth of its old area, or less).
pub(crate) fn collapsed(old: DVec3, new: DVec3) -> bool {
    new.length_squared() <= 1e-12 * old.length_squared() && old != DVec3::ZERO
}
