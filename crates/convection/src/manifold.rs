//! Turning the converged pseudo-surface into a manifold triangle mesh.
//!
//! The pseudo-surface is a combinatorial manifold, but its geometric image
//! can pinch: different parts meeting at one edge or one vertex. With the
//! vertices fixed to the input points such places cannot be written as a
//! manifold mesh, so [`make_manifold`] removes the faces there; the rims
//! they leave are boundary edges, of which [`fill_small_holes`] closes the
//! short loops by ear clipping through their own vertices.

use crate::fill::{least_area_triangulation, Surroundings};
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};
use surfrecon_geom::Aabb;
use surfrecon_geom::DVec3;

fn directed_edges(&[a, b, c]: &[u32; 3]) -> [(u32, u32); 3] {
    [(a, b), (b, c), (c, a)]
}

/// The faces' directed edges in compressed rows by start vertex: how many
/// faces run along an edge is read from one short row, with no hashing
/// (a hash map of the edges took 3.6 s per pass on 875k faces).
struct DirectedEdges {
    offsets: Vec<usize>,
    ends: Vec<u32>,
}

impl DirectedEdges {
    fn new(triangles: &[[u32; 3]]) -> Self {
        let (offsets, ends) = rows(triangles, |_, t| directed_edges(t));
        DirectedEdges { offsets, ends }
    }

    fn row(&self, a: u32) -> &[u32] {
        let a = a as usize;
        if a + 1 >= self.offsets.len() {
            return &[];
        }
        &self.ends[self.offsets[a]..self.offsets[a + 1]]
    }

    /// How many faces run along `a → b` (in rows by end vertex: `b → a`).
    fn count(&self, a: u32, b: u32) -> u32 {
        self.row(a).iter().filter(|&&e| e == b).count() as u32
    }

    fn starts(&self) -> u32 {
        self.offsets.len().saturating_sub(1) as u32
    }

    /// Whether some face has the edge {a, b} in either direction.
    fn has_edge(&self, a: u32, b: u32) -> bool {
        self.row(a).contains(&b) || self.row(b).contains(&a)
    }
}

/// [`DirectedEdges`] and the same edges in rows by end vertex: whether
/// `b → a` exists is read from `a`'s own incoming row, next to its
/// outgoing one, rather than from `b`'s row elsewhere in memory (that
/// lookup per edge was a cache miss, 14% of a Dragon-scale run).
struct PairedEdges {
    out: DirectedEdges,
    incoming: DirectedEdges,
}

impl PairedEdges {
    fn new(triangles: &[[u32; 3]]) -> Self {
        let (offsets, ends) = rows(triangles, |_, t| directed_edges(t).map(|(a, b)| (b, a)));
        PairedEdges {
            out: DirectedEdges::new(triangles),
            incoming: DirectedEdges { offsets, ends },
        }
    }

    /// The directed edges from `a` with no face running the other way,
    /// each once (however many faces run along it).
    fn unpaired_from(&self, a: u32) -> impl Iterator<Item = (u32, u32)> + '_ {
        let (row, into) = (self.out.row(a), self.incoming.row(a));
        row.iter()
            .enumerate()
            .filter(move |&(i, e)| !row[..i].contains(e) && !into.contains(e))
            .map(move |(_, &b)| (a, b))
    }
}

/// Compressed rows: `pairs(face index, face)` yields (row, value) entries.
pub(crate) fn rows<I: IntoIterator<Item = (u32, u32)>>(
    triangles: &[[u32; 3]],
    pairs: impl Fn(u32, &[u32; 3]) -> I,
) -> (Vec<usize>, Vec<u32>) {
    let n = triangles
        .iter()
        .flatten()
        .max()
        .map_or(0, |&v| v as usize + 1);
    let mut offsets = vec![0usize; n + 1];
    for (f, t) in triangles.iter().enumerate() {
        for (r, _) in pairs(f as u32, t) {
            offsets[r as usize + 1] += 1;
        }
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut values = vec![0u32; offsets[n]];
    for (f, t) in triangles.iter().enumerate() {
        for (r, x) in pairs(f as u32, t) {
            values[fill[r as usize]] = x;
            fill[r as usize] += 1;
        }
    }
    (offsets, values)
}

/// Remove faces until every edge has at most two faces running it in
/// opposite directions and the faces around every vertex form one fan (the
/// largest fan is kept). Returns the number of faces removed.
pub fn make_manifold(triangles: &mut Vec<[u32; 3]>) -> usize {
    let before = triangles.len();
    // Removing faces never makes an edge bad (counts only drop), but can
    // split the fan of a vertex of a removed face: after the first pass
    // only those vertices are looked at again.
    remove_bad_edge_faces(triangles);
    let mut suspects: Option<Vec<bool>> = None;
    loop {
        let removed = remove_extra_fans(triangles, suspects.as_deref());
        if removed.is_empty() {
            return before - triangles.len();
        }
        let mut marks = vec![false; suspects.map_or(0, |s| s.len())];
        for v in removed.into_iter().flatten() {
            if marks.len() <= v as usize {
                marks.resize(v as usize + 1, false);
            }
            marks[v as usize] = true;
        }
        suspects = Some(marks);
    }
}

fn remove_bad_edge_faces(triangles: &mut Vec<[u32; 3]>) -> usize {
    let counts = PairedEdges::new(triangles);
    let bad = |&(a, b): &(u32, u32)| {
        let forth = counts.out.count(a, b);
        forth > 1 || forth + counts.incoming.count(a, b) > 2
    };
    let before = triangles.len();
    // Decided in parallel (each face on its own), removed in order.
    let keep: Vec<bool> = triangles
        .par_iter()
        .map(|t| !directed_edges(t).iter().any(bad))
        .collect();
    let mut index = 0;
    triangles.retain(|_| {
        index += 1;
        keep[index - 1]
    });
    before - triangles.len()
}

/// Faces around each vertex in compressed rows.
fn vertex_faces(triangles: &[[u32; 3]]) -> (Vec<usize>, Vec<u32>) {
    rows(triangles, |f, t| t.map(|v| (v, f)))
}

/// Remove all but the largest fan at every vertex (only at `suspects`
/// when given); returns the removed faces.
fn remove_extra_fans(triangles: &mut Vec<[u32; 3]>, suspects: Option<&[bool]>) -> Vec<[u32; 3]> {
    let (offsets, faces) = vertex_faces(triangles);
    // Vertices in parallel, each on its own: a face doomed at any of its
    // vertices goes, whichever found it.
    let doomed_faces: Vec<u32> = (0..offsets.len() - 1)
        .into_par_iter()
        .with_min_len(1024)
        .filter(|&v| suspects.is_none_or(|s| s.get(v).copied().unwrap_or(false)))
        .flat_map_iter(|v| {
            let around = &faces[offsets[v]..offsets[v + 1]];
            match around.len() > 1 {
                true => minor_fans(v as u32, around, triangles),
                false => Vec::new(),
            }
        })
        .collect();
    let mut doomed = vec![false; triangles.len()];
    for f in doomed_faces {
        doomed[f as usize] = true;
    }
    let mut removed = Vec::new();
    let mut index = 0;
    triangles.retain(|&t| {
        index += 1;
        if doomed[index - 1] {
            removed.push(t);
        }
        !doomed[index - 1]
    });
    removed
}

/// Group the faces at `v` into fans (joined through edges at `v`); the
/// faces of all but the largest.
fn minor_fans(v: u32, around: &[u32], triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut group: Vec<usize> = (0..around.len()).collect();
    fn root(group: &mut [usize], mut i: usize) -> usize {
        while group[i] != i {
            group[i] = group[group[i]];
            i = group[i];
        }
        i
    }
    // Fans are small (a handful of faces): linear scans, no hashing.
    let mut first_at: Vec<(u32, usize)> = Vec::with_capacity(2 * around.len());
    for (i, &f) in around.iter().enumerate() {
        for &w in triangles[f as usize].iter().filter(|&&w| w != v) {
            if let Some(&(_, j)) = first_at.iter().find(|&&(x, _)| x == w) {
                let (a, b) = (root(&mut group, i), root(&mut group, j));
                group[a] = b;
            } else {
                first_at.push((w, i));
            }
        }
    }
    let roots: Vec<usize> = (0..around.len()).map(|i| root(&mut group, i)).collect();
    let mut sizes = vec![0usize; around.len()];
    for &r in &roots {
        sizes[r] += 1;
    }
    if sizes.iter().filter(|&&s| s > 0).count() < 2 {
        return Vec::new();
    }
    // Largest fan, ties to the smallest root so the result is reproducible.
    let keep = (0..around.len())
        .filter(|&r| sizes[r] > 0)
        .max_by_key(|&r| (sizes[r], std::cmp::Reverse(r)));
    (0..around.len())
        .filter(|&i| Some(roots[i]) != keep)
        .map(|i| around[i])
        .collect()
}

/// Edges with exactly one face.
pub fn boundary_edges(triangles: &[[u32; 3]]) -> usize {
    let counts = PairedEdges::new(triangles);
    (0..counts.out.starts())
        .into_par_iter()
        .with_min_len(1024)
        .map(|a| counts.unpaired_from(a).count())
        .sum()
}

/// Close every boundary loop of at most `max_edges` edges through its own
/// vertices, so a manifold mesh stays manifold and no new face crosses
/// another face: by ear clipping (shortest new diagonal first, passing over
/// ears that would cross), else by the least-area crossing-free
/// triangulation of the loop ([`crate::fill`]). A loop with neither (a
/// face of the mesh pokes through every way of spanning it, as at a
/// cone's sparse tip) is opened wider: its fill and the faces it crossed
/// are removed, the mesh made manifold again, and the larger loop filled
/// in the next round. After the last round such a loop keeps the ear
/// clipping's crossing faces. Returns the number of holes closed: the
/// patches of new faces in the final mesh (a loop closed in one round
/// whose fill a later round opened again into a larger loop counts once).
pub fn fill_small_holes(
    triangles: &mut Vec<[u32; 3]>,
    points: &[DVec3],
    max_edges: usize,
) -> usize {
    if max_edges < 3 {
        return 0;
    }
    let given = triangles.len();
    let mut filled = 0;
    // The mesh's own faces, kept once a round has to open fills again.
    let mut own: Option<HashSet<[u32; 3]>> = None;
    for round in 1..=FILL_ROUNDS {
        let pass = fill_pass(triangles, points, max_edges, round == FILL_ROUNDS);
        filled += pass.closed;
        if pass.to_remove.is_empty() {
            break;
        }
        let own = own.get_or_insert_with(|| triangles[..given].iter().copied().collect());
        let mut doomed = vec![false; triangles.len()];
        for f in pass.to_remove {
            doomed[f as usize] = true;
        }
        let mut index = 0;
        triangles.retain(|_| {
            index += 1;
            !doomed[index - 1]
        });
        make_manifold(triangles);
        // A face the mesh lost here and a later fill makes again is new.
        let present: HashSet<[u32; 3]> = triangles.iter().copied().collect();
        own.retain(|f| present.contains(f));
    }
    match own {
        Some(own) => fill_patches(triangles, &own),
        None => filled,
    }
}

/// Patches (connected through edges) of the faces not in `own`.
fn fill_patches(triangles: &[[u32; 3]], own: &HashSet<[u32; 3]>) -> usize {
    let new: Vec<usize> = (0..triangles.len())
        .filter(|&f| !own.contains(&triangles[f]))
        .collect();
    let mut sets = surfrecon_geom::disjoint_sets::DisjointSets::new(new.len());
    let mut face_at: HashMap<(u32, u32), usize> = HashMap::new();
    for (i, &f) in new.iter().enumerate() {
        for (a, b) in directed_edges(&triangles[f]) {
            if let Some(&j) = face_at.get(&(a.min(b), a.max(b))) {
                sets.union(i, j);
            }
            face_at.insert((a.min(b), a.max(b)), i);
        }
    }
    (0..new.len()).filter(|&i| sets.find(i) == i).count()
}

/// Rounds of hole filling: each may open the loops it could not close
/// without crossings for the next.
const FILL_ROUNDS: usize = 4;

/// One round of [`fill_small_holes`].
struct Pass {
    closed: usize,
    /// Faces to remove before the next round: the fills that crossed and
    /// the faces they crossed.
    to_remove: Vec<u32>,
}

fn fill_pass(
    triangles: &mut Vec<[u32; 3]>,
    points: &[DVec3],
    max_edges: usize,
    last: bool,
) -> Pass {
    let mut pass = Pass {
        closed: 0,
        to_remove: Vec::new(),
    };
    let counts = PairedEdges::new(triangles);
    // Edges the ear clipping adds (the mesh's own are in `counts`).
    let mut edges = NewEdges {
        mesh: &counts.out,
        added: HashSet::new(),
    };
    // A hole runs against its rim faces: rim edge a → b gives hole edge b → a.
    // Found in parallel, entered in vertex order as before.
    let rim: Vec<(u32, u32)> = (0..counts.out.starts())
        .into_par_iter()
        .with_min_len(1024)
        .flat_map_iter(|a| counts.unpaired_from(a))
        .collect();
    let mut next: HashMap<u32, u32> = HashMap::new();
    for (a, b) in rim {
        next.insert(b, a);
    }
    let mut starts: Vec<u32> = next.keys().copied().collect();
    if starts.is_empty() {
        return pass;
    }
    starts.sort_unstable();
    // Loops in vertex order as before; all found first, so that only the
    // faces near some loop are indexed.
    let holes: Vec<Vec<u32>> = starts
        .into_iter()
        .filter_map(|start| take_loop(&mut next, start, max_edges))
        .collect();
    let mut near = Nearby::new(triangles, points, &holes);
    for hole in holes {
        match fill_hole(hole, points, &mut edges, &mut near, triangles) {
            Filled::Clear => pass.closed += 1,
            Filled::Crossing { .. } if last => pass.closed += 1,
            Filled::Crossing { fill, crossed } => {
                pass.to_remove.extend(fill);
                pass.to_remove.extend(crossed);
            }
            Filled::Stuck => {}
        }
    }
    pass
}

/// The faces of the mesh and of the fills so far in a grid of cubes by
/// their boxes, to find every face a hole's fill could cross.
struct Nearby {
    cell: f64,
    /// The faces in each cube that a hole's box meets (no others).
    cells: HashMap<[i64; 3], Vec<u32>>,
    /// Faces over more than [`MAX_CUBES`] cubes, with their boxes, looked
    /// at for every hole.
    large: Vec<(u32, Aabb)>,
}

/// Cubes a face is entered in before it counts as large.
const MAX_CUBES: usize = 64;

impl Nearby {
    fn new(triangles: &[[u32; 3]], points: &[DVec3], holes: &[Vec<u32>]) -> Nearby {
        let mut lengths: Vec<f64> = triangles
            .iter()
            .map(|&[a, b, _]| points[a as usize].distance(points[b as usize]))
            .collect();
        let middle = lengths.len() / 2;
        let median = match lengths.is_empty() {
            true => 1.0,
            false => *lengths.select_nth_unstable_by(middle, f64::total_cmp).1,
        };
        let boxes: Vec<Aabb> = holes.iter().map(|h| bounds_of(h, points)).collect();
        // Cubes about twice the median edge, but no loop over more than
        // 16 along an axis (a long loop of long edges would touch millions).
        let widest = boxes
            .iter()
            .map(|b| b.size().max_element())
            .fold(0.0, f64::max);
        let cell = (2.0 * median).max(widest / 16.0);
        let mut near = Nearby {
            cell: if cell > 0.0 { cell } else { 1.0 },
            cells: HashMap::new(),
            large: Vec::new(),
        };
        for bounds in &boxes {
            for c in near.cubes(bounds).collect::<Vec<_>>() {
                near.cells.entry(c).or_default();
            }
        }
        for (f, &t) in triangles.iter().enumerate() {
            near.add(f as u32, t, points);
        }
        near
    }

    fn key(&self, p: DVec3) -> [i64; 3] {
        (p / self.cell).floor().to_array().map(|x| x as i64)
    }

    /// The cubes a box meets.
    fn cubes(&self, bounds: &Aabb) -> impl Iterator<Item = [i64; 3]> {
        let (lo, hi) = (self.key(bounds.min), self.key(bounds.max));
        (lo[0]..=hi[0]).flat_map(move |x| {
            (lo[1]..=hi[1]).flat_map(move |y| (lo[2]..=hi[2]).map(move |z| [x, y, z]))
        })
    }

    /// Every face whose box meets the box of `vertices`: a face spanning
    /// those vertices lies in their box, so these are all it could cross.
    fn in_box(&self, vertices: &[u32], points: &[DVec3], triangles: &[[u32; 3]]) -> Vec<u32> {
        let bounds = bounds_of(vertices, points);
        let meets = |b: &Aabb| b.overlaps(&bounds);
        let mut faces: Vec<u32> = self
            .cubes(&bounds)
            .filter_map(|c| self.cells.get(&c))
            .flatten()
            .copied()
            .collect();
        faces.extend(self.large.iter().filter(|(_, b)| meets(b)).map(|&(f, _)| f));
        faces.sort_unstable();
        faces.dedup();
        faces.retain(|&f| {
            meets(&Aabb::from_points(
                &triangles[f as usize].map(|v| points[v as usize]),
            ))
        });
        faces
    }

    fn add(&mut self, f: u32, t: [u32; 3], points: &[DVec3]) {
        let bounds = Aabb::from_points(&t.map(|v| points[v as usize]));
        let (lo, hi) = (self.key(bounds.min), self.key(bounds.max));
        let count: i64 = (0..3).map(|a| hi[a] - lo[a] + 1).product();
        if count > MAX_CUBES as i64 {
            self.large.push((f, bounds));
            return;
        }
        let cubes: Vec<[i64; 3]> = self.cubes(&bounds).collect();
        for c in cubes {
            if let Some(faces) = self.cells.get_mut(&c) {
                faces.push(f);
            }
        }
    }
}

fn bounds_of(vertices: &[u32], points: &[DVec3]) -> Aabb {
    let corners: Vec<DVec3> = vertices.iter().map(|&v| points[v as usize]).collect();
    Aabb::from_points(&corners)
}

/// The hole loop through `start` (removed from `next`), if it closes within
/// `max_edges` edges.
fn take_loop(next: &mut HashMap<u32, u32>, start: u32, max_edges: usize) -> Option<Vec<u32>> {
    let mut hole = vec![start];
    let mut v = *next.get(&start)?;
    while v != start {
        if hole.len() >= max_edges {
            return None;
        }
        hole.push(v);
        v = *next.get(&v)?;
    }
    for v in &hole {
        next.remove(v);
    }
    (hole.len() >= 3).then_some(hole)
}

/// The mesh's edges and those ear clipping added.
struct NewEdges<'a> {
    mesh: &'a DirectedEdges,
    added: HashSet<(u32, u32)>,
}

impl NewEdges<'_> {
    fn contains(&self, &(a, b): &(u32, u32)) -> bool {
        self.mesh.has_edge(a, b) || self.added.contains(&(a, b))
    }

    fn insert(&mut self, e: (u32, u32)) {
        self.added.insert(e);
    }
}

/// How a hole was closed.
enum Filled {
    /// With faces that cross nothing.
    Clear,
    /// Only with faces (`fill`, indices) that cross faces of the mesh or
    /// earlier fills (`crossed`).
    Crossing { fill: Vec<u32>, crossed: Vec<u32> },
    /// Not at all: no ear with a new diagonal (the faces found so far are
    /// kept).
    Stuck,
}

/// Close one hole: ear clipping, else the least-area crossing-free
/// triangulation, else the ear clipping's crossing faces.
fn fill_hole(
    hole: Vec<u32>,
    points: &[DVec3],
    edges: &mut NewEdges,
    near: &mut Nearby,
    triangles: &mut Vec<[u32; 3]>,
) -> Filled {
    let nearby = near.in_box(&hole, points, triangles);
    let is_edge = |a: u32, b: u32| edges.contains(&(a.min(b), a.max(b)));
    let around = Surroundings {
        points,
        triangles,
        near: &nearby,
        is_edge: &is_edge,
    };
    let (ears, outcome) = clip_ears(hole.clone(), &around);
    let (faces, outcome) = match outcome {
        Ears::Clear => (ears, Ears::Clear),
        Ears::Crossing | Ears::Stuck => match least_area_triangulation(&hole, &around) {
            Some(found) => (found, Ears::Clear),
            None => (ears, outcome),
        },
    };
    let crossed: Vec<u32> = match outcome {
        Ears::Crossing => nearby
            .iter()
            .copied()
            .filter(|&f| faces.iter().any(|&t| around.meet(t, triangles[f as usize])))
            .collect(),
        _ => Vec::new(),
    };
    let first = triangles.len() as u32;
    for &t in &faces {
        let f = triangles.len() as u32;
        triangles.push(t);
        near.add(f, t, points);
        for (a, b) in directed_edges(&t) {
            edges.insert((a.min(b), a.max(b)));
        }
    }
    match outcome {
        Ears::Clear => Filled::Clear,
        Ears::Crossing => Filled::Crossing {
            fill: (first..triangles.len() as u32).collect(),
            crossed,
        },
        Ears::Stuck => Filled::Stuck,
    }
}

/// How the ear clipping ended: its faces all clear of nearby faces, some
/// crossing, or stopped early for want of an ear with a new diagonal.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Ears {
    Clear,
    Crossing,
    Stuck,
}

/// Ear clipping, shortest new diagonal first; an ear that would cross a
/// nearby face or an ear already cut is passed over for the next shortest,
/// and only when every ear would cross is the shortest taken.
fn clip_ears(mut hole: Vec<u32>, around: &Surroundings) -> (Vec<[u32; 3]>, Ears) {
    let points = around.points;
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut diagonals: Vec<(u32, u32)> = Vec::new();
    let mut crossed = false;
    let crosses = |t: [u32; 3], faces: &[[u32; 3]]| {
        around.crosses_near(t) || faces.iter().any(|&u| around.meet(t, u))
    };
    while hole.len() > 3 {
        let n = hole.len();
        let ear_at = |i: usize| [hole[(i + n - 1) % n], hole[i], hole[(i + 1) % n]];
        let mut ears: Vec<usize> = (0..n)
            .filter(|&i| {
                let [p, _, q] = ear_at(i);
                let e = (p.min(q), p.max(q));
                !(around.is_edge)(p, q) && !diagonals.contains(&e)
            })
            .collect();
        let diagonal = |i: usize| {
            let [p, _, q] = ear_at(i);
            points[p as usize].distance(points[q as usize])
        };
        // Stable: equal diagonals keep the hole's order, as before.
        ears.sort_by(|&i, &j| diagonal(i).total_cmp(&diagonal(j)));
        let Some(&shortest) = ears.first() else {
            return (faces, Ears::Stuck);
        };
        let clear = ears.iter().copied().find(|&i| !crosses(ear_at(i), &faces));
        crossed |= clear.is_none();
        let i = clear.unwrap_or(shortest);
        let [p, v, q] = ear_at(i);
        faces.push([p, v, q]);
        diagonals.push((p.min(q), p.max(q)));
        hole.remove(i);
    }
    let last = [hole[0], hole[1], hole[2]];
    crossed |= crosses(last, &faces);
    faces.push(last);
    match crossed {
        true => (faces, Ears::Crossing),
        false => (faces, Ears::Clear),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::intersections::faces_meet;

    fn octahedron() -> Vec<[u32; 3]> {
        // Vertices 0..6: ±x, ±y, ±z; outward faces.
        vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ]
    }

    fn octahedron_points() -> Vec<DVec3> {
        vec![
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ]
    }

    #[test]
    fn closed_manifold_is_untouched() {
        let mut t = octahedron();
        assert_eq!(make_manifold(&mut t), 0);
        assert_eq!(t.len(), 8);
        assert_eq!(boundary_edges(&t), 0);
    }

    #[test]
    fn two_octahedra_sharing_a_vertex_keep_one_fan() {
        let mut t = octahedron();
        // A second octahedron with its vertex 0 glued to vertex 0.
        let shift = |v: u32| if v == 0 { 0 } else { v + 10 };
        t.extend(octahedron().iter().map(|f| f.map(shift)));
        let removed = make_manifold(&mut t);
        assert_eq!(removed, 4, "the minor fan at the pinch vertex goes");
        assert_eq!(boundary_edges(&t), 4);
    }

    #[test]
    fn fin_on_an_edge_is_removed() {
        let mut t = octahedron();
        // A fin along edge 0-2 makes it non-manifold (three faces).
        t.push([0, 2, 9]);
        make_manifold(&mut t);
        assert!(t.iter().all(|f| !f.contains(&9)));
        assert_eq!(boundary_edges(&t), 4, "both faces at the edge went too");
    }

    #[test]
    fn small_holes_are_closed_and_stay_manifold() {
        let mut t = octahedron();
        t.retain(|f| !f.contains(&4)); // remove the top cap: a 4-edge hole
        assert_eq!(boundary_edges(&t), 4);
        assert_eq!(fill_small_holes(&mut t, &octahedron_points(), 3), 0);
        assert_eq!(fill_small_holes(&mut t, &octahedron_points(), 4), 1);
        assert_eq!(boundary_edges(&t), 0);
        assert_eq!(t.len(), 6);
        assert_eq!(make_manifold(&mut t), 0);
    }

    #[test]
    fn holes_filled_count_patches_of_new_faces_once() {
        // The bottom cap's four faces as fills: one patch, one hole.
        let t = octahedron();
        let own: HashSet<[u32; 3]> = t[..4].iter().copied().collect();
        assert_eq!(fill_patches(&t, &own), 1);
        // Two fills meeting at a vertex only (faces 0 and 2 of the top
        // cap, at vertex 4): two holes.
        let own: HashSet<[u32; 3]> = [1, 3, 4, 5, 6, 7].map(|f| t[f]).into();
        assert_eq!(fill_patches(&t, &own), 2);
        assert_eq!(fill_patches(&t, &t.iter().copied().collect()), 0);
    }

    /// A non-planar quad hole with a face standing under its middle: the
    /// shortest diagonal (a valley through the middle) would cut that
    /// face, the longer one (a ridge above it) does not, and is taken.
    #[test]
    fn hole_filling_passes_over_ears_that_cross_nearby_faces() {
        let points: Vec<DVec3> = [
            [-1.0, 0.0, 0.0], // a
            [0.0, -1.1, 0.5], // b
            [1.0, 0.0, 0.0],  // c
            [0.0, 1.1, 0.5],  // d
            [0.0, -0.3, -1.0],
            [0.0, 0.3, -1.0],
            [0.0, 0.0, 0.25],
        ]
        .map(DVec3::from_array)
        .to_vec();
        // A rim face on the hole's edge a-b, and the standing face beside it.
        let mut triangles = vec![[1, 0, 4], [4, 5, 6]];
        let corners = |t: [u32; 3]| t.map(|v| points[v as usize]);
        let valley = [0, 1, 2];
        assert!(points[0].distance(points[2]) < points[1].distance(points[3]));
        assert!(faces_meet(
            valley,
            &corners(valley),
            [4, 5, 6],
            &corners([4, 5, 6])
        ));
        let counts = PairedEdges::new(&triangles);
        let mut edges = NewEdges {
            mesh: &counts.out,
            added: HashSet::new(),
        };
        let mut near = Nearby::new(&triangles, &points, &[vec![0, 1, 2, 3]]);
        let mut out = triangles.clone();
        let filled = fill_hole(vec![0, 1, 2, 3], &points, &mut edges, &mut near, &mut out);
        assert!(matches!(filled, Filled::Clear));
        triangles = out;
        assert_eq!(triangles.len(), 4);
        for (f, &t) in triangles.iter().enumerate() {
            for &u in &triangles[f + 1..] {
                assert!(
                    !faces_meet(t, &corners(t), u, &corners(u)),
                    "{t:?} crosses {u:?}"
                );
            }
        }
    }
}
