//! Holes in the sampling left open instead of covered.
//!
//! The convection closes its surface: where a densely sampled surface has
//! a hole with no samples in it (a scanner's blind spot, such as the
//! bottom of the Stanford bunny), the facets spanning it form a flat
//! cover. [`open_sampling_holes`] (run by default, `Params::open_holes`)
//! finds such covers as patches of faces far larger than the spacing of
//! their own vertices and removes them, so the hole is reported as
//! boundary edges. A patch is opened only when it holds several faces
//! that are large against the spacing (a random sample's own gaps give
//! single faces up to about three spacings long), no sample lies inside
//! it, and removing it leaves a manifold mesh of as many pieces.

use std::collections::HashMap;
use surfrecon_geom::DVec3;

/// When a patch of faces counts as the cover of a hole in the sampling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HoleRule {
    /// A face is large when its longest edge exceeds this many spacings
    /// (of its sparsest vertex); a patch must hold `seeds` such faces.
    pub large: f64,
    /// Faces whose longest edge exceeds this many spacings join the
    /// patch of a large neighbour (the narrow ends of a slot-like hole).
    pub grow: f64,
    /// Large faces a patch must hold to be opened.
    pub seeds: usize,
}

impl Default for HoleRule {
    fn default() -> Self {
        HoleRule {
            large: 3.5,
            grow: 2.0,
            seeds: 3,
        }
    }
}

/// What [`open_sampling_holes`] removed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OpenedHoles {
    /// Patches removed (holes opened).
    pub holes: usize,
    /// Faces removed with them.
    pub faces: usize,
}

/// Remove the patches of `triangles` that cover holes in the sampling
/// (see [`HoleRule`]). `spacing[i]` is the local sample spacing at point
/// `i` (mean distance to its nearest neighbours); faces `kept[f]` are
/// never part of a patch (`kept` empty: none). The mesh must
/// be a manifold; it stays one: faces of a patch around a vertex that
/// would be left with two separate fans stay in place.
pub fn open_sampling_holes(
    triangles: &mut Vec<[u32; 3]>,
    points: &[DVec3],
    spacing: &[f64],
    kept: &[bool],
    rule: &HoleRule,
) -> OpenedHoles {
    let size = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|v| points[v as usize]);
        let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
        let sparsest = t.iter().map(|&v| spacing[v as usize]).fold(0.0, f64::max);
        longest / sparsest
    };
    let ratio: Vec<f64> = triangles.iter().map(size).collect();
    let kept = |f: usize| kept.get(f).copied().unwrap_or(false);
    let patches = patches(triangles, |f| ratio[f] > rule.grow && !kept(f));
    let mut faces_at = vec![0u32; points.len()];
    for &v in triangles.iter().flatten() {
        faces_at[v as usize] += 1;
    }
    let mut doomed = vec![false; triangles.len()];
    for patch in &patches {
        let seeds = patch.iter().filter(|&&f| ratio[f] > rule.large).count();
        if seeds >= rule.seeds && is_a_hole_cover(patch, triangles, &faces_at) {
            for &f in patch {
                doomed[f] = true;
            }
        }
    }
    spare_pinched_vertices(triangles, &mut doomed);
    let before = count_pieces(triangles, points.len());
    let kept: Vec<[u32; 3]> = (0..triangles.len())
        .filter(|&f| !doomed[f])
        .map(|f| triangles[f])
        .collect();
    if count_pieces(&kept, points.len()) != before {
        // Not expected from disks with one rim each; never split the mesh.
        return OpenedHoles::default();
    }
    let opened = OpenedHoles {
        holes: patches
            .iter()
            .filter(|p| p.iter().any(|&f| doomed[f]))
            .count(),
        faces: doomed.iter().filter(|&&d| d).count(),
    };
    let mut index = 0;
    triangles.retain(|_| {
        index += 1;
        !doomed[index - 1]
    });
    opened
}

/// Whether removing `patch` opens one hole in the sampling: no sample
/// inside it (every vertex keeps a face outside the patch, so the data
/// stay on the mesh) and its rim one simple loop (a disk, so removing it
/// splits nothing off). `faces_at[v]`: faces at vertex `v` in the mesh.
fn is_a_hole_cover(patch: &[usize], triangles: &[[u32; 3]], faces_at: &[u32]) -> bool {
    let mut in_patch: HashMap<u32, u32> = HashMap::new();
    let mut edges = std::collections::HashSet::new();
    for &f in patch {
        let [a, b, c] = triangles[f];
        for v in [a, b, c] {
            *in_patch.entry(v).or_default() += 1;
        }
        edges.extend([(a, b), (b, c), (c, a)]);
    }
    if in_patch.iter().any(|(&v, &n)| n == faces_at[v as usize]) {
        return false;
    }
    let mut next: HashMap<u32, u32> = HashMap::new();
    for &(a, b) in &edges {
        if !edges.contains(&(b, a)) && next.insert(a, b).is_some() {
            return false; // the rim passes a vertex twice
        }
    }
    let Some(&start) = next.keys().next() else {
        return false;
    };
    let (mut v, mut steps) = (start, 0);
    loop {
        v = next[&v];
        steps += 1;
        if v == start || steps > next.len() {
            break;
        }
    }
    v == start && steps == next.len()
}

/// Connected components of the faces, joined through shared vertices.
fn count_pieces(triangles: &[[u32; 3]], vertices: usize) -> usize {
    let mut sets = surfrecon_geom::disjoint_sets::DisjointSets::new(vertices);
    for &[a, b, c] in triangles {
        sets.union(a as usize, b as usize);
        sets.union(a as usize, c as usize);
    }
    let mut used = vec![false; vertices];
    for &v in triangles.iter().flatten() {
        used[v as usize] = true;
    }
    (0..vertices)
        .filter(|&v| used[v] && sets.find(v) == v)
        .count()
}

/// Connected sets (through shared edges) of the faces `chosen` selects.
fn patches(triangles: &[[u32; 3]], chosen: impl Fn(usize) -> bool) -> Vec<Vec<usize>> {
    let faces: Vec<usize> = (0..triangles.len()).filter(|&f| chosen(f)).collect();
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for &f in &faces {
        let [a, b, c] = triangles[f];
        for (p, q) in [(a, b), (b, c), (c, a)] {
            by_edge.entry((p.min(q), p.max(q))).or_default().push(f);
        }
    }
    let mut patch_of: HashMap<usize, usize> = HashMap::new();
    let mut out = Vec::new();
    for &start in &faces {
        if patch_of.contains_key(&start) {
            continue;
        }
        let id = out.len();
        patch_of.insert(start, id);
        let mut patch = vec![start];
        let mut next = 0;
        while next < patch.len() {
            let [a, b, c] = triangles[patch[next]];
            next += 1;
            for (p, q) in [(a, b), (b, c), (c, a)] {
                for &g in &by_edge[&(p.min(q), p.max(q))] {
                    if let std::collections::hash_map::Entry::Vacant(e) = patch_of.entry(g) {
                        e.insert(id);
                        patch.push(g);
                    }
                }
            }
        }
        out.push(patch);
    }
    out
}

/// Where the kept faces around a vertex would form several fans (a patch
/// touching itself or another one at a vertex), put back the doomed faces
/// there but the largest run of them in the cyclic order around it, until
/// no such vertex is left. Only doomed faces are put back, so this ends,
/// at worst with the mesh as it was.
fn spare_pinched_vertices(triangles: &[[u32; 3]], doomed: &mut [bool]) {
    let mut faces_at: HashMap<u32, Vec<usize>> = HashMap::new();
    for (f, t) in triangles.iter().enumerate() {
        if doomed[f] {
            for &v in t {
                faces_at.entry(v).or_default();
            }
        }
    }
    for (f, t) in triangles.iter().enumerate() {
        for v in t {
            if let Some(around) = faces_at.get_mut(v) {
                around.push(f);
            }
        }
    }
    let mut suspects: Vec<u32> = faces_at.keys().copied().collect();
    suspects.sort_unstable();
    while let Some(v) = suspects.pop() {
        let around = &faces_at[&v];
        if kept_fans(v, around, triangles, doomed) <= 1 {
            continue;
        }
        let spared = match cyclic_order(v, around, triangles) {
            Some((ring, closed)) => all_but_the_largest_run(&ring, closed, doomed),
            // Not one fan even before: put every doomed face back.
            None => around.iter().copied().filter(|&f| doomed[f]).collect(),
        };
        for f in spared {
            doomed[f] = false;
            suspects.extend(triangles[f].iter().filter(|&&u| u != v));
        }
    }
}

/// The faces `around` vertex `v` in their order around it, when they form
/// one fan, and whether it is a ring (else a chain: a boundary vertex).
fn cyclic_order(v: u32, around: &[usize], triangles: &[[u32; 3]]) -> Option<(Vec<usize>, bool)> {
    let rim = |f: usize| {
        let t = triangles[f];
        let i = t.iter().position(|&u| u == v).expect("face at its vertex");
        [t[(i + 1) % 3], t[(i + 2) % 3]]
    };
    let after = |f: usize| around.iter().copied().find(|&g| rim(g)[0] == rim(f)[1]);
    // A chain starts at the face no other one precedes; a ring anywhere.
    let start = around
        .iter()
        .copied()
        .find(|&f| !around.iter().any(|&g| rim(g)[1] == rim(f)[0]))
        .or(around.first().copied())?;
    let mut ring = vec![start];
    let mut closed = false;
    while let Some(next) = after(*ring.last().expect("not empty")) {
        closed = next == start;
        if closed || ring.len() > around.len() {
            break;
        }
        ring.push(next);
    }
    (ring.len() == around.len()).then_some((ring, closed))
}

/// The doomed faces of `ring` (faces in order around a vertex; `closed`:
/// the last one meets the first) outside its longest run of doomed faces
/// that can stay doomed.
fn all_but_the_largest_run(ring: &[usize], closed: bool, doomed: &[bool]) -> Vec<usize> {
    let n = ring.len();
    // On a ring, runs start after a kept face (there is one, or no fan
    // would be split); on a chain, at its start.
    let first = match closed {
        true => match (0..n).find(|&i| !doomed[ring[i]]) {
            Some(kept) => kept + 1,
            None => return Vec::new(),
        },
        false => 0,
    };
    let mut runs: Vec<Vec<usize>> = Vec::new();
    let mut current = Vec::new();
    for k in 0..n {
        let f = ring[(first + k) % n];
        if doomed[f] {
            current.push(f);
        } else if !current.is_empty() {
            runs.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        runs.push(current);
    }
    // On a chain only a run at one of its ends can stay: one in the middle
    // would split the kept faces in two.
    let at_an_end = |run: &Vec<usize>| run.contains(&ring[0]) || run.contains(&ring[n - 1]);
    let largest = (0..runs.len())
        .filter(|&r| closed || at_an_end(&runs[r]))
        .max_by_key(|&r| runs[r].len());
    runs.into_iter()
        .enumerate()
        .filter(|&(r, _)| Some(r) != largest)
        .flat_map(|(_, run)| run)
        .collect()
}

/// Fans (groups linked through shared edges at `v`) formed by the kept
/// faces among `around`, the faces at `v`.
fn kept_fans(v: u32, around: &[usize], triangles: &[[u32; 3]], doomed: &[bool]) -> usize {
    let kept: Vec<[u32; 2]> = around
        .iter()
        .filter(|&&f| !doomed[f])
        .map(|&f| {
            let t = triangles[f];
            let i = t.iter().position(|&u| u == v).expect("face at its vertex");
            [t[(i + 1) % 3], t[(i + 2) % 3]]
        })
        .collect();
    // A fan is a chain of faces, each one's second rim vertex the next
    // one's first: count chain starts (faces with no predecessor), or one
    // for a closed ring.
    let starts = kept
        .iter()
        .filter(|[first, _]| !kept.iter().any(|[_, second]| second == first))
        .count();
    match (starts, kept.is_empty()) {
        (_, true) => 0,
        (0, false) => 1,
        (s, false) => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A jittered grid of the unit square as a triangulated sheet, with a
    /// square hole of `hole` cells (no samples) triangulated by a fan of
    /// long faces from one rim corner.
    fn sheet_with_hole(n: usize, hole: std::ops::Range<usize>) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut points = Vec::new();
        let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
        for i in 0..=n {
            for j in 0..=n {
                let jitter = ((i * 7 + j * 13) % 5) as f64 * 0.02;
                points.push(DVec3::new(i as f64 + jitter, j as f64 - jitter, 0.0));
            }
        }
        let inside = |i: usize, j: usize| hole.contains(&i) && hole.contains(&j);
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                if inside(i, j) {
                    continue;
                }
                triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        // The rim of the hole, counter-clockwise, covered by a fan.
        let (lo, hi) = (hole.start, hole.end);
        if lo >= hi {
            return (points, triangles);
        }
        let mut rim = Vec::new();
        rim.extend((lo..hi).map(|i| id(i, lo)));
        rim.extend((lo..hi).map(|j| id(hi, j)));
        rim.extend((lo + 1..=hi).rev().map(|i| id(i, hi)));
        rim.extend((lo + 1..=hi).rev().map(|j| id(lo, j)));
        for w in rim[1..].windows(2) {
            triangles.push([rim[0], w[0], w[1]]);
        }
        (points, triangles)
    }

    /// The default rule on a sample whose spacing is 1 everywhere.
    fn open_with_defaults(triangles: &mut Vec<[u32; 3]>, points: &[DVec3]) -> OpenedHoles {
        let spacing = vec![1.0; points.len()];
        open_sampling_holes(triangles, points, &spacing, &[], &HoleRule::default())
    }

    #[test]
    fn a_fan_over_an_unsampled_square_is_removed() {
        let (points, mut triangles) = sheet_with_hole(20, 6..14);
        let before = triangles.len();
        let opened = open_with_defaults(&mut triangles, &points);
        assert_eq!(opened.holes, 1);
        // The fan has 30 faces; the two at its apex lie along the rim
        // (nearly flat, two spacings long) and may stay.
        assert!(opened.faces >= 28, "{opened:?}");
        assert_eq!(triangles.len(), before - opened.faces);
        assert!(triangles.iter().all(|t| longest(&points, t) <= 3.5));
        assert_one_fan_everywhere(&triangles);
        // Every rim vertex is still used: the data stays on the mesh.
        let used: std::collections::HashSet<u32> = triangles.iter().flatten().copied().collect();
        assert_eq!(used.len(), points.len() - 7 * 7);
    }

    fn longest(points: &[DVec3], t: &[u32; 3]) -> f64 {
        let [a, b, c] = t.map(|v| points[v as usize]);
        a.distance(b).max(b.distance(c)).max(c.distance(a))
    }

    fn assert_one_fan_everywhere(triangles: &[[u32; 3]]) {
        let kept = vec![false; triangles.len()];
        for v in triangles.iter().flatten().copied() {
            let around: Vec<usize> = (0..triangles.len())
                .filter(|&f| triangles[f].contains(&v))
                .collect();
            assert_eq!(kept_fans(v, &around, triangles, &kept), 1, "vertex {v}");
        }
    }

    #[test]
    fn large_faces_around_a_sample_stay() {
        // The same square, but with its centre sampled and the cover a fan
        // from it (as between sparse slices): opening it would leave the
        // sample off the mesh.
        let (points, mut triangles) = sheet_with_hole(20, 6..14);
        let centre = (10 * 21 + 10) as u32;
        let rim_fan = triangles.split_off(triangles.len() - 30);
        let mut rim: Vec<u32> = vec![rim_fan[0][0], rim_fan[0][1]];
        rim.extend(rim_fan.iter().map(|t| t[2]));
        for (i, &a) in rim.iter().enumerate() {
            triangles.push([centre, a, rim[(i + 1) % rim.len()]]);
        }
        let before = triangles.clone();
        let opened = open_with_defaults(&mut triangles, &points);
        assert_eq!(opened, OpenedHoles::default());
        assert_eq!(triangles, before);
    }

    #[test]
    fn a_dense_sheet_keeps_every_face() {
        let (points, mut triangles) = sheet_with_hole(12, 0..0);
        let before = triangles.clone();
        let opened = open_with_defaults(&mut triangles, &points);
        assert_eq!(opened, OpenedHoles::default());
        assert_eq!(triangles, before);
    }

    #[test]
    fn a_hole_of_two_spacings_stays_covered() {
        // Its cover has fewer large faces than a patch needs.
        let (points, mut triangles) = sheet_with_hole(12, 5..7);
        let before = triangles.len();
        let opened = open_with_defaults(&mut triangles, &points);
        assert_eq!(opened.holes, 0);
        assert_eq!(triangles.len(), before);
    }

    #[test]
    fn faces_at_a_vertex_two_holes_share_stay() {
        // Two unsampled squares meeting at one corner vertex: opening both
        // would leave that vertex with two fans of kept faces.
        let (points, mut triangles) = sheet_with_hole(20, 2..10);
        let n = 20;
        let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
        // Replace the grid faces of the second square (10..18)² by a fan.
        let inside = |t: &[u32; 3]| {
            t.iter().all(|&v| {
                let (i, j) = (v as usize / (n + 1), v as usize % (n + 1));
                (10..=18).contains(&i) && (10..=18).contains(&j)
            })
        };
        triangles.retain(|t| !inside(t));
        let mut rim = Vec::new();
        rim.extend((10..18).map(|i| id(i, 10)));
        rim.extend((10..18).map(|j| id(18, j)));
        rim.extend((11..=18).rev().map(|i| id(i, 18)));
        rim.extend((11..=18).rev().map(|j| id(10, j)));
        for w in rim[1..].windows(2) {
            triangles.push([rim[0], w[0], w[1]]);
        }
        let opened = open_with_defaults(&mut triangles, &points);
        assert!(opened.holes >= 1, "{opened:?}");
        assert_one_fan_everywhere(&triangles);
        assert!(triangles.iter().any(|t| t.contains(&id(10, 10))));
    }
}
