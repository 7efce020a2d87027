//! Quality metrics: how close a reconstruction is to a reference surface, and
//! the topology facts of a mesh.
//!
//! [`evaluate`] compares two [`Surface`]s (a mesh or a point set each) and
//! returns an [`EvalReport`]; [`topology`] counts a mesh's vertices, edges and
//! faces and checks it for holes and non-manifold spots. The exact
//! point-to-mesh distances come from a [`TriangleBvh`].
//!
//! Definitions (A = candidate samples, B = reference samples; `d(a, B)` is
//! the distance from `a` to the reference *surface*: exact to its triangles
//! when it is a mesh, to its nearest point when it is a point set):
//! - Chamfer-L1 = ( mean_a d(a, B) + mean_b d(b, A) ) / 2
//! - Chamfer-L2 = ( mean_a d(a, B)^2 + mean_b d(b, A)^2 ) / 2 (squared
//!   distances, not their root)
//! - Hausdorff = max( max_a d(a, B), max_b d(b, A) )
//! - F-score at threshold t: precision = share of A with d(a, B) <= t, recall
//!   = share of B with d(b, A) <= t, F = 2PR / (P + R); t is 0.5% and 1% of
//!   the reference bounding-box diagonal.
//! - normal consistency = mean over both directions of |n_a . n_b| for each
//!   sample and its closest point on the other surface (absolute, so it does
//!   not depend on orientation); only when both sides have normals.

use crate::disjoint_sets::DisjointSets;
use crate::spatial::KdTree;
use crate::{shapes, Aabb, GeomError, Geometry, PointCloud, TriMesh};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// One side of a comparison.
#[derive(Clone, Debug)]
pub enum Surface {
    /// Sampled uniformly by area; distances *to* it are exact to its faces.
    Mesh(TriMesh),
    /// Used as is (every point is a sample); normals optional.
    Points(PointCloud),
}

impl From<Geometry> for Surface {
    /// A geometry with triangles is a mesh; anything else its points.
    fn from(g: Geometry) -> Self {
        if g.is_mesh() {
            Surface::Mesh(g.to_mesh())
        } else {
            Surface::Points(g.points)
        }
    }
}

/// How [`evaluate`] samples the surfaces.
#[derive(Clone, Copy, Debug)]
pub struct EvalOptions {
    /// Samples drawn from each mesh (point sets are used whole).
    pub samples: usize,
    /// Seed of the sampling, so a run can be repeated exactly.
    pub seed: u64,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            samples: 100_000,
            seed: 0,
        }
    }
}

/// The scores of a candidate against a reference (see the module docs for
/// the definitions). Serializes to exactly the documented JSON keys; the
/// topology fields are `None` (JSON null) when the candidate is a point set.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    /// Mean of the two directed mean distances.
    pub chamfer_l1: f64,
    /// Mean of the two directed mean squared distances.
    pub chamfer_l2: f64,
    /// Largest distance in either direction.
    pub hausdorff: f64,
    /// F-score at 0.5% of the reference diagonal.
    pub fscore_0_5pct: f64,
    /// F-score at 1% of the reference diagonal.
    pub fscore_1pct: f64,
    /// Mean |n_a . n_b| of closest pairs; `None` unless both sides have normals.
    pub normal_consistency: Option<f64>,
    /// Vertices of the candidate mesh (all of them), or its point count.
    pub vertices: usize,
    /// Triangles of the candidate (0 for a point set).
    pub faces: usize,
    /// Every edge in exactly two faces.
    pub watertight: Option<bool>,
    /// Both edge- and vertex-manifold.
    pub manifold: Option<bool>,
    /// Pieces connected through shared vertices.
    pub components: Option<usize>,
    /// V - E + F over the vertices used by faces.
    pub euler: Option<i64>,
    /// Bounding-box diagonal of the reference, the F-score length scale.
    pub diagonal: f64,
    /// Full topology of a mesh candidate (not serialized: the JSON keys are
    /// fixed; the CLI prints it in the human table).
    #[serde(skip)]
    pub topology: Option<Topology>,
    /// Number of candidate and reference samples used.
    #[serde(skip)]
    pub sample_counts: (usize, usize),
}

/// |cos| of the angle between two normals: files may hold normals of any
/// length (the fuzzer found a consistency of 2); a zero normal agrees with
/// nothing.
fn cosine(a: DVec3, b: DVec3) -> f64 {
    a.normalize_or_zero().dot(b.normalize_or_zero()).abs()
}

/// Largest coordinate magnitude [`evaluate`] measures.
const MAX_COORDINATE: f64 = 1e100;

/// The vertices or points of a surface.
fn surface_positions(surface: &Surface) -> impl Iterator<Item = &DVec3> {
    match surface {
        Surface::Mesh(m) => m.vertices.iter(),
        Surface::Points(p) => p.positions.iter(),
    }
}

/// Score `candidate` against `reference`. Errors when either side has no
/// points or no area to sample.
pub fn evaluate(
    candidate: &Surface,
    reference: &Surface,
    options: &EvalOptions,
) -> Result<EvalReport, GeomError> {
    // Squared distances between points past 1e100 leave the f64 range
    // (the fuzzer found NaN Chamfer distances near 1e300).
    for (surface, name) in [(candidate, "candidate"), (reference, "reference")] {
        if surface_positions(surface).any(|p| p.abs().max_element() > MAX_COORDINATE) {
            return Err(GeomError::InvalidInput(format!(
                "{name}: coordinates beyond {MAX_COORDINATE:e} are not supported; rescale both surfaces"
            )));
        }
    }
    let diagonal = reference_bounds(reference).diagonal();
    let cand = samples_of(candidate, options.samples, options.seed, "candidate")?;
    // A different stream for the reference, so a surface compared with
    // itself is not matched sample-for-sample by construction.
    let refs = samples_of(
        reference,
        options.samples,
        options.seed ^ 0x5eed,
        "reference",
    )?;
    let forward = distances_to(&cand, reference);
    let backward = distances_to(&refs, candidate);
    let fscore = |t: f64| f_score(forward.share_within(t), backward.share_within(t));
    let topology = match candidate {
        Surface::Mesh(m) => Some(topology(m)),
        Surface::Points(_) => None,
    };
    Ok(EvalReport {
        chamfer_l1: 0.5 * (forward.mean() + backward.mean()),
        chamfer_l2: 0.5 * (forward.mean_squared() + backward.mean_squared()),
        hausdorff: forward.max().max(backward.max()),
        fscore_0_5pct: fscore(0.005 * diagonal),
        fscore_1pct: fscore(0.01 * diagonal),
        normal_consistency: forward
            .normal_agreement()
            .zip(backward.normal_agreement())
            .map(|(a, b)| 0.5 * (a + b)),
        vertices: match candidate {
            Surface::Mesh(m) => m.vertices.len(),
            Surface::Points(p) => p.len(),
        },
        faces: topology.as_ref().map_or(0, |t| t.faces),
        watertight: topology.as_ref().map(|t| t.watertight),
        manifold: topology
            .as_ref()
            .map(|t| t.edge_manifold && t.vertex_manifold),
        components: topology.as_ref().map(|t| t.components),
        euler: topology.as_ref().map(|t| t.euler),
        diagonal,
        topology,
        sample_counts: (cand.positions.len(), refs.positions.len()),
    })
}

fn reference_bounds(s: &Surface) -> Aabb {
    match s {
        Surface::Mesh(m) => m.bounds(),
        Surface::Points(p) => p.bounds(),
    }
}

/// Harmonic mean of precision and recall (0 when both are 0).
fn f_score(precision: f64, recall: f64) -> f64 {
    if precision + recall > 0.0 {
        2.0 * precision * recall / (precision + recall)
    } else {
        0.0
    }
}

/// Sample positions with their normals (when known).
struct Samples {
    positions: Vec<DVec3>,
    normals: Option<Vec<DVec3>>,
}

fn samples_of(s: &Surface, count: usize, seed: u64, role: &str) -> Result<Samples, GeomError> {
    check_surface(s, role)?;
    let cloud = match s {
        Surface::Mesh(m) => shapes::sample_surface(m, count, seed),
        Surface::Points(p) => p.clone(),
    };
    if cloud.is_empty() {
        let what = match s {
            Surface::Mesh(_) => "mesh has no area to sample (or no samples were asked for)",
            Surface::Points(_) => "point set is empty",
        };
        return Err(GeomError::InvalidInput(format!("{role} {what}")));
    }
    Ok(Samples {
        positions: cloud.positions,
        normals: cloud.normals,
    })
}

/// Reject what would make the metrics meaningless (non-finite coordinates)
/// or could not be sampled (triangles naming missing vertices).
fn check_surface(s: &Surface, role: &str) -> Result<(), GeomError> {
    let positions = match s {
        Surface::Mesh(m) => &m.vertices,
        Surface::Points(p) => &p.positions,
    };
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(GeomError::InvalidInput(format!(
            "{role} point {i} has a non-finite coordinate"
        )));
    }
    if let Surface::Mesh(m) = s {
        let n = m.vertices.len();
        if let Some((t, tri)) = m
            .triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
        {
            return Err(GeomError::InvalidInput(format!(
                "{role} triangle {t} refers to vertex {} but there are only {n} vertices",
                tri.iter().max().unwrap_or(&0)
            )));
        }
    }
    Ok(())
}

/// Distances from samples to a surface, with the normal agreement at each.
struct Directed {
    distances: Vec<f64>,
    /// |n_sample . n_closest| per sample, when both normals are known.
    agreement: Option<Vec<f64>>,
}

impl Directed {
    fn mean(&self) -> f64 {
        self.distances.iter().sum::<f64>() / self.distances.len() as f64
    }

    fn mean_squared(&self) -> f64 {
        self.distances.iter().map(|d| d * d).sum::<f64>() / self.distances.len() as f64
    }

    fn max(&self) -> f64 {
        self.distances.iter().fold(0.0, |m, &d| m.max(d))
    }

    fn share_within(&self, t: f64) -> f64 {
        let n = self.distances.iter().filter(|&&d| d <= t).count();
        n as f64 / self.distances.len() as f64
    }

    fn normal_agreement(&self) -> Option<f64> {
        let a = self.agreement.as_ref()?;
        Some(a.iter().sum::<f64>() / a.len() as f64)
    }
}

/// Distance from each sample to `target` (exact for a mesh), in parallel.
fn distances_to(samples: &Samples, target: &Surface) -> Directed {
    // (distance, normal of the closest point of the target if known)
    let closest: Vec<(f64, Option<DVec3>)> = match target {
        Surface::Mesh(mesh) => {
            let bvh = TriangleBvh::new(mesh);
            let face_normals: Vec<DVec3> = (0..mesh.triangles.len())
                .map(|t| face_normal(mesh.corners(t)))
                .collect();
            samples
                .positions
                .par_iter()
                .map(|&p| match bvh.closest(p) {
                    Some(c) => (c.distance, Some(face_normals[c.triangle])),
                    None => (f64::INFINITY, None),
                })
                .collect()
        }
        Surface::Points(cloud) => {
            let tree = KdTree::new(&cloud.positions);
            samples
                .positions
                .par_iter()
                .map(|&p| match tree.nearest(p) {
                    Some(n) => (n.distance, cloud.normals.as_ref().map(|ns| ns[n.index])),
                    None => (f64::INFINITY, None),
                })
                .collect()
        }
    };
    let agreement = samples.normals.as_ref().and_then(|own| {
        own.iter()
            .zip(&closest)
            .map(|(n, (_, m))| m.map(|m| cosine(*n, m)))
            .collect::<Option<Vec<f64>>>()
    });
    Directed {
        distances: closest.iter().map(|c| c.0).collect(),
        agreement,
    }
}

fn face_normal([a, b, c]: [DVec3; 3]) -> DVec3 {
    (b - a).cross(c - a).normalize_or_zero()
}

/// Closest point on the triangle `abc` to `p` (exact; a degenerate triangle
/// is treated as its edges).
pub fn closest_point_on_triangle(p: DVec3, [a, b, c]: [DVec3; 3]) -> DVec3 {
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    if nn > 0.0 && nn.is_finite() {
        // Project onto the plane; if the foot is inside, it is the answer,
        // otherwise the closest point lies on the boundary.
        let q = p - n * ((p - a).dot(n) / nn);
        let inside = (b - a).cross(q - a).dot(n) >= 0.0
            && (c - b).cross(q - b).dot(n) >= 0.0
            && (a - c).cross(q - c).dot(n) >= 0.0;
        if inside {
            return q;
        }
    }
    [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(s, e)| closest_point_on_segment(p, s, e))
        .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
        .unwrap_or(a)
}

/// Closest point on the segment `s`-`e` to `p`.
pub fn closest_point_on_segment(p: DVec3, s: DVec3, e: DVec3) -> DVec3 {
    let d = e - s;
    let len2 = d.length_squared();
    if len2.is_nan() || len2 <= 0.0 {
        return s;
    }
    s + d * ((p - s).dot(d) / len2).clamp(0.0, 1.0)
}

/// The answer of [`TriangleBvh::closest`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestTriangle {
    /// Index of the triangle in the mesh.
    pub triangle: usize,
    /// The closest point on it.
    pub point: DVec3,
    /// Distance from the query to `point`.
    pub distance: f64,
}

/// Bounding-volume hierarchy over a mesh's triangles for exact closest-point
/// queries (branch and bound: boxes farther than the best hit are skipped).
pub struct TriangleBvh {
    nodes: Vec<BvhNode>,
    /// Triangle indices in leaf order.
    order: Vec<u32>,
    corners: Vec<[DVec3; 3]>,
}

struct BvhNode {
    bounds: Aabb,
    kind: BvhKind,
}

enum BvhKind {
    /// A range of `TriangleBvh::order`.
    Leaf { start: u32, count: u32 },
    /// Indices of the two children in `TriangleBvh::nodes`.
    Inner { left: u32, right: u32 },
}

const LEAF_SIZE: usize = 4;

/// Levels at the top of the tree whose two halves are built in parallel
/// (8 subtrees: the serial build was most of the reach step's wait).
const PARALLEL_LEVELS: usize = 3;

/// What every subtree's build reads.
struct BuildInput<'a> {
    corners: &'a [[DVec3; 3]],
    centroids: &'a [DVec3],
}

/// Build the subtree over `order` (which starts at `first` in the whole
/// order) into `nodes`, root first, then the left subtree, then the right
/// (children numbered by their place in `nodes`); returns the root's index.
fn build(
    nodes: &mut Vec<BvhNode>,
    order: &mut [u32],
    first: usize,
    input: &BuildInput,
    level: usize,
) -> u32 {
    let bounds = order
        .iter()
        .flat_map(|&t| input.corners[t as usize])
        .fold(Aabb::EMPTY, Aabb::grow);
    let id = nodes.len() as u32;
    if order.len() <= LEAF_SIZE {
        let kind = BvhKind::Leaf {
            start: first as u32,
            count: order.len() as u32,
        };
        nodes.push(BvhNode { bounds, kind });
        return id;
    }
    // Median split along the widest spread of the centroids.
    let spread = order
        .iter()
        .fold(Aabb::EMPTY, |b, &t| b.grow(input.centroids[t as usize]))
        .size();
    let axis = if spread.x >= spread.y && spread.x >= spread.z {
        0
    } else if spread.y >= spread.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        input.centroids[a as usize][axis].total_cmp(&input.centroids[b as usize][axis])
    });
    // Placeholder, patched once the children exist.
    nodes.push(BvhNode {
        bounds,
        kind: BvhKind::Leaf { start: 0, count: 0 },
    });
    let (low, high) = order.split_at_mut(mid);
    let (left, right) = if level < PARALLEL_LEVELS {
        let subtree = |order: &mut [u32], first: usize| {
            let mut sub = Vec::new();
            build(&mut sub, order, first, input, level + 1);
            sub
        };
        let (l, r) = rayon::join(|| subtree(low, first), || subtree(high, first + mid));
        (append_subtree(nodes, l), append_subtree(nodes, r))
    } else {
        let left = build(nodes, low, first, input, level + 1);
        (left, build(nodes, high, first + mid, input, level + 1))
    };
    nodes[id as usize].kind = BvhKind::Inner { left, right };
    id
}

/// Append the nodes of a subtree built on its own (children numbered
/// from its root at 0), renumbered to their places; returns its root's.
fn append_subtree(nodes: &mut Vec<BvhNode>, sub: Vec<BvhNode>) -> u32 {
    let offset = nodes.len() as u32;
    nodes.extend(sub.into_iter().map(|mut node| {
        if let BvhKind::Inner { left, right } = &mut node.kind {
            *left += offset;
            *right += offset;
        }
        node
    }));
    offset
}

impl TriangleBvh {
    /// Index the triangles of `mesh` (out-of-range indices are skipped).
    pub fn new(mesh: &TriMesh) -> Self {
        let nv = mesh.vertices.len();
        let mut order: Vec<u32> = Vec::with_capacity(mesh.triangles.len());
        let corners: Vec<[DVec3; 3]> = mesh
            .triangles
            .par_iter()
            .map(|t| {
                if t.iter().all(|&i| (i as usize) < nv) {
                    t.map(|i| mesh.vertices[i as usize])
                } else {
                    [DVec3::NAN; 3]
                }
            })
            .collect();
        for (t, c) in corners.iter().enumerate() {
            if c.iter().all(|v| v.is_finite()) {
                order.push(t as u32);
            }
        }
        let centroids: Vec<DVec3> = corners
            .par_iter()
            .map(|[a, b, c]| (*a + *b + *c) / 3.0)
            .collect();
        let mut nodes = Vec::new();
        if !order.is_empty() {
            let input = BuildInput {
                corners: &corners,
                centroids: &centroids,
            };
            build(&mut nodes, &mut order, 0, &input, 0);
        }
        TriangleBvh {
            nodes,
            order,
            corners,
        }
    }

    /// The closest point of the mesh to `p`, or `None` for a mesh without
    /// usable triangles.
    pub fn closest(&self, p: DVec3) -> Option<ClosestTriangle> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best: Option<ClosestTriangle> = None;
        let mut best_d2 = f64::INFINITY;
        let mut stack = vec![0u32];
        while let Some(id) = stack.pop() {
            let node = &self.nodes[id as usize];
            if box_distance_squared(&node.bounds, p) >= best_d2 {
                continue;
            }
            match node.kind {
                BvhKind::Leaf { start, count } => {
                    for &t in &self.order[start as usize..(start + count) as usize] {
                        let q = closest_point_on_triangle(p, self.corners[t as usize]);
                        let d2 = q.distance_squared(p);
                        if d2 < best_d2 || best.is_none() {
                            best_d2 = d2;
                            best = Some(ClosestTriangle {
                                triangle: t as usize,
                                point: q,
                                distance: d2.sqrt(),
                            });
                        }
                    }
                }
                BvhKind::Inner { left, right } => {
                    // Push the farther child first so the nearer is searched
                    // first and tightens the bound early.
                    let dl = box_distance_squared(&self.nodes[left as usize].bounds, p);
                    let dr = box_distance_squared(&self.nodes[right as usize].bounds, p);
                    if dl <= dr {
                        stack.extend([right, left]);
                    } else {
                        stack.extend([left, right]);
                    }
                }
            }
        }
        best
    }
}

fn box_distance_squared(b: &Aabb, p: DVec3) -> f64 {
    let d = (b.min - p).max(p - b.max).max(DVec3::ZERO);
    d.length_squared()
}

/// Counts and checks of a triangle mesh.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Topology {
    /// All vertices, used by a face or not.
    pub vertices: usize,
    /// Vertices used by at least one face (the V of the Euler characteristic).
    pub referenced_vertices: usize,
    pub faces: usize,
    /// Distinct undirected edges.
    pub edges: usize,
    /// Edges in exactly one face (the rims of holes).
    pub boundary_edges: usize,
    /// Edges in more than two faces.
    pub nonmanifold_edges: usize,
    /// Vertices whose faces form more than one fan.
    pub nonmanifold_vertices: usize,
    /// Every edge is shared by exactly two faces (and there is a face).
    pub watertight: bool,
    /// No edge is in more than two faces.
    pub edge_manifold: bool,
    /// The faces around every vertex form one fan (connected through the
    /// edges at that vertex).
    pub vertex_manifold: bool,
    /// Connected pieces, faces being connected through shared vertices (so
    /// two pieces touching at one vertex count as one, which is then flagged
    /// as not vertex-manifold).
    pub components: usize,
    /// V - E + F with V the referenced vertices (unused vertices would
    /// otherwise each add 1).
    pub euler: i64,
}

/// Topology of `mesh`. Faces with a repeated vertex contribute only their
/// proper edges; indices beyond the vertex list count as vertices of their own.
pub fn topology(mesh: &TriMesh) -> Topology {
    let max_index = mesh
        .triangles
        .iter()
        .flatten()
        .max()
        .map_or(0, |&i| i as usize + 1);
    let n = mesh.vertices.len().max(max_index);
    let faces_at = vertex_faces(&mesh.triangles, n);
    let referenced = (0..n).filter(|&v| !faces_at.of(v).is_empty()).count();
    let (edges, boundary, nonmanifold_edges) = edge_counts(&mesh.triangles);
    let nonmanifold_vertices = (0..n)
        .into_par_iter()
        .filter(|&v| fans_at(v as u32, faces_at.of(v), &mesh.triangles) > 1)
        .count();
    let faces = mesh.triangles.len();
    Topology {
        vertices: mesh.vertices.len(),
        referenced_vertices: referenced,
        faces,
        edges,
        boundary_edges: boundary,
        nonmanifold_edges,
        nonmanifold_vertices,
        watertight: faces > 0 && boundary == 0 && nonmanifold_edges == 0,
        edge_manifold: nonmanifold_edges == 0,
        vertex_manifold: nonmanifold_vertices == 0,
        components: components(&mesh.triangles, n, &faces_at),
        euler: referenced as i64 - edges as i64 + faces as i64,
    }
}

/// (distinct edges, edges in one face, edges in more than two faces).
fn edge_counts(triangles: &[[u32; 3]]) -> (usize, usize, usize) {
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
        .filter(|(a, b)| a != b)
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.par_sort_unstable();
    let (mut distinct, mut boundary, mut nonmanifold) = (0, 0, 0);
    for run in edges.chunk_by(|x, y| x == y) {
        distinct += 1;
        match run.len() {
            1 => boundary += 1,
            2 => {}
            _ => nonmanifold += 1,
        }
    }
    (distinct, boundary, nonmanifold)
}

/// Faces around each vertex, in compressed rows (a face with a repeated
/// vertex is listed once at it).
pub struct VertexFaces {
    offsets: Vec<usize>,
    faces: Vec<u32>,
}

impl VertexFaces {
    /// The faces around vertex `v`.
    pub fn of(&self, v: usize) -> &[u32] {
        &self.faces[self.offsets[v]..self.offsets[v + 1]]
    }
}

/// The faces around each of the `n` vertices of `triangles`.
pub fn vertex_faces(triangles: &[[u32; 3]], n: usize) -> VertexFaces {
    let mut offsets = vec![0usize; n + 1];
    for t in triangles {
        for (k, &v) in t.iter().enumerate() {
            // A face with a repeated vertex is listed once at it.
            if !t[..k].contains(&v) {
                offsets[v as usize + 1] += 1;
            }
        }
    }
    for v in 0..n {
        offsets[v + 1] += offsets[v];
    }
    let mut fill = offsets[..n].to_vec();
    let mut faces = vec![0u32; offsets[n]];
    for (f, t) in triangles.iter().enumerate() {
        for (k, &v) in t.iter().enumerate() {
            if !t[..k].contains(&v) {
                faces[fill[v as usize]] = f as u32;
                fill[v as usize] += 1;
            }
        }
    }
    VertexFaces { offsets, faces }
}

/// Number of fans at vertex `v`: groups of its faces connected through
/// shared edges at `v` (0 for an unused vertex, 1 for a manifold one).
fn fans_at(v: u32, faces: &[u32], triangles: &[[u32; 3]]) -> usize {
    if faces.len() <= 1 {
        return faces.len();
    }
    // (other vertex of an edge at v, local face index): faces listing the
    // same other vertex share that edge.
    let mut spokes: Vec<(u32, u32)> = Vec::with_capacity(2 * faces.len());
    for (local, &f) in faces.iter().enumerate() {
        for &u in &triangles[f as usize] {
            if u != v {
                spokes.push((u, local as u32));
            }
        }
    }
    spokes.sort_unstable();
    let mut sets = DisjointSets::new(faces.len());
    for run in spokes.chunk_by(|x, y| x.0 == y.0) {
        for pair in run.windows(2) {
            sets.union(pair[0].1 as usize, pair[1].1 as usize);
        }
    }
    (0..faces.len()).filter(|&i| sets.find(i) == i).count()
}

/// Connected pieces of the mesh (faces joined through shared vertices).
fn components(triangles: &[[u32; 3]], n: usize, faces_at: &VertexFaces) -> usize {
    let mut sets = DisjointSets::new(n);
    for &[a, b, c] in triangles {
        sets.union(a as usize, b as usize);
        sets.union(b as usize, c as usize);
    }
    (0..n)
        .filter(|&v| !faces_at.of(v).is_empty() && sets.find(v) == v)
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{cuboid, icosphere, torus};
    use rand::{Rng, SeedableRng};

    fn options(samples: usize) -> EvalOptions {
        EvalOptions { samples, seed: 9 }
    }

    /// Fuzz input (target `eval`): normals of length 2 gave a normal
    /// consistency of 2; now measured on unit directions.
    #[test]
    fn normal_consistency_ignores_normal_lengths() {
        let sphere = icosphere(DVec3::ZERO, 1.0, 1);
        let cloud = |scale: f64| {
            Surface::Points(PointCloud {
                positions: sphere.vertices.clone(),
                normals: Some(sphere.vertices.iter().map(|v| *v * scale).collect()),
                scalars: None,
            })
        };
        let r = evaluate(&cloud(2.0), &cloud(-3.0), &options(64)).unwrap();
        assert!((r.normal_consistency.unwrap() - 1.0).abs() < 1e-12, "{r:?}");
    }

    /// Fuzz input (target `eval`): a cube near 4e300 against a flattened
    /// icosahedron gave NaN Chamfer distances; now an error.
    #[test]
    fn huge_coordinates_are_refused() {
        let mut cube = cuboid(DVec3::splat(-1.0), DVec3::ONE);
        cube.vertices
            .iter_mut()
            .for_each(|v| *v *= DVec3::new(3.25, 4.0, 4.0) * 1e300);
        let mut flat = icosphere(DVec3::ZERO, 1.0, 0);
        flat.vertices
            .iter_mut()
            .for_each(|v| *v *= DVec3::new(0.0, 4.0, 2.25));
        let e = evaluate(&Surface::Mesh(cube), &Surface::Mesh(flat), &options(64)).unwrap_err();
        assert!(
            e.to_string().contains("candidate: coordinates beyond"),
            "{e}"
        );
    }

    #[test]
    fn closest_point_matches_dense_search() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let mut v = || DVec3::new(rng.random(), rng.random(), rng.random());
        for _ in 0..200 {
            let tri = [v(), v(), v()];
            let p = 2.0 * v() - DVec3::splat(0.5);
            let found = closest_point_on_triangle(p, tri).distance(p);
            // Dense barycentric grid: never closer than the exact answer, and
            // within the grid resolution of it.
            let steps = 200;
            let mut dense = f64::INFINITY;
            for i in 0..=steps {
                for j in 0..=steps - i {
                    let (u, w) = (i as f64 / steps as f64, j as f64 / steps as f64);
                    let q = tri[0] + u * (tri[1] - tri[0]) + w * (tri[2] - tri[0]);
                    dense = dense.min(q.distance(p));
                }
            }
            assert!(found <= dense + 1e-12, "{found} > {dense}");
            assert!(dense - found < 0.02, "{found} vs {dense}");
        }
        // Degenerate triangles act as segments or points.
        let p = DVec3::new(0.5, 1.0, 0.0);
        let flat = [DVec3::ZERO, DVec3::X, 2.0 * DVec3::X];
        assert!((closest_point_on_triangle(p, flat) - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
        assert_eq!(closest_point_on_triangle(p, [DVec3::ONE; 3]), DVec3::ONE);
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        let mesh = torus(2.0, 0.7, 24, 12);
        let bvh = TriangleBvh::new(&mesh);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
        for _ in 0..300 {
            let p = DVec3::new(rng.random(), rng.random(), rng.random()) * 8.0 - DVec3::splat(4.0);
            let brute = (0..mesh.triangles.len())
                .map(|t| closest_point_on_triangle(p, mesh.corners(t)).distance(p))
                .fold(f64::INFINITY, f64::min);
            let hit = bvh.closest(p).unwrap();
            assert!((hit.distance - brute).abs() < 1e-12);
            let via_triangle = closest_point_on_triangle(p, mesh.corners(hit.triangle));
            assert!((via_triangle.distance(p) - brute).abs() < 1e-12);
        }
        assert!(TriangleBvh::new(&TriMesh::default())
            .closest(DVec3::ZERO)
            .is_none());
    }

    #[test]
    fn mesh_against_itself_scores_perfectly() {
        let mesh = Surface::Mesh(torus(1.0, 0.3, 48, 24));
        let r = evaluate(&mesh, &mesh, &options(20_000)).unwrap();
        assert!(r.chamfer_l1 < 1e-12 && r.chamfer_l2 < 1e-20 && r.hausdorff < 1e-12);
        assert_eq!((r.fscore_0_5pct, r.fscore_1pct), (1.0, 1.0));
        assert!((r.normal_consistency.unwrap() - 1.0).abs() < 1e-9);
        assert_eq!(r.sample_counts, (20_000, 20_000));
        assert_eq!(
            (r.watertight, r.manifold, r.components, r.euler),
            (Some(true), Some(true), Some(1), Some(0))
        );
        let expect_diagonal = DVec3::new(2.6, 2.6, 0.6).length();
        assert!((r.diagonal - expect_diagonal).abs() < 0.01);
    }

    #[test]
    fn scaled_sphere_gives_analytic_distance() {
        let r = 2.0;
        let inner = Surface::Mesh(icosphere(DVec3::ONE, r, 5));
        let outer = Surface::Mesh(icosphere(DVec3::ONE, 1.01 * r, 5));
        let expect = 0.01 * r;
        let report = evaluate(&outer, &inner, &options(20_000)).unwrap();
        assert!(
            (report.chamfer_l1 - expect).abs() < 0.05 * expect,
            "{}",
            report.chamfer_l1
        );
        assert!((report.chamfer_l2 - expect * expect).abs() < 0.1 * expect * expect);
        assert!(
            (report.hausdorff - expect).abs() < 0.05 * expect,
            "{}",
            report.hausdorff
        );
        // The reference diagonal is 6.93: the 0.02 offset is within both
        // thresholds (0.035, 0.069); an offset of 0.06 only within the wider.
        assert_eq!(report.fscore_0_5pct, 1.0);
        let far = Surface::Mesh(icosphere(DVec3::ONE, 1.03 * r, 5));
        let report = evaluate(&far, &inner, &options(20_000)).unwrap();
        assert_eq!((report.fscore_0_5pct, report.fscore_1pct), (0.0, 1.0));
    }

    #[test]
    fn point_sets_are_compared_by_nearest_points() {
        let a = PointCloud::new(vec![DVec3::ZERO, DVec3::X]);
        let b = PointCloud::new(vec![
            DVec3::ZERO,
            DVec3::new(1.0, 3.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
        ]);
        let r = evaluate(&Surface::Points(a), &Surface::Points(b), &options(10)).unwrap();
        // a->b: 0, 1 ; b->a: 0, 3, 1
        assert!((r.chamfer_l1 - 0.5 * (0.5 + 4.0 / 3.0)).abs() < 1e-12);
        assert!((r.chamfer_l2 - 0.5 * (0.5 + 10.0 / 3.0)).abs() < 1e-12);
        assert_eq!(r.hausdorff, 3.0);
        assert_eq!(r.fscore_1pct, f_score(0.5, 1.0 / 3.0));
        assert_eq!(
            (r.vertices, r.faces, r.watertight, r.normal_consistency),
            (2, 0, None, None)
        );
        let json = serde_json::to_value(&r).unwrap();
        let keys: Vec<&str> = json
            .as_object()
            .unwrap()
            .keys()
            .map(|k| k.as_str())
            .collect();
        let mut expect = [
            "chamfer_l1",
            "chamfer_l2",
            "hausdorff",
            "fscore_0_5pct",
            "fscore_1pct",
            "normal_consistency",
            "vertices",
            "faces",
            "watertight",
            "manifold",
            "components",
            "euler",
            "diagonal",
        ];
        expect.sort();
        let mut keys = keys;
        keys.sort();
        assert_eq!(keys, expect);
    }

    #[test]
    fn empty_inputs_are_errors() {
        let mesh = Surface::Mesh(icosphere(DVec3::ZERO, 1.0, 1));
        let empty = Surface::Points(PointCloud::default());
        assert!(evaluate(&mesh, &empty, &options(100)).is_err());
        assert!(evaluate(&empty, &mesh, &options(100)).is_err());
        let flat = Surface::Mesh(TriMesh {
            vertices: vec![DVec3::ZERO, DVec3::X, 2.0 * DVec3::X],
            triangles: vec![[0, 1, 2]],
            normals: None,
        });
        let err = evaluate(&flat, &mesh, &options(100)).unwrap_err();
        assert!(
            err.to_string().contains("candidate mesh has no area"),
            "{err}"
        );
        let broken = Surface::Mesh(TriMesh {
            vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            triangles: vec![[0, 1, 2], [0, 1, 7]],
            normals: None,
        });
        let err = evaluate(&mesh, &broken, &options(100)).unwrap_err();
        assert!(
            err.to_string()
                .contains("reference triangle 1 refers to vertex 7"),
            "{err}"
        );
        let nan = Surface::Points(PointCloud::new(vec![DVec3::ZERO, DVec3::NAN]));
        let err = evaluate(&nan, &mesh, &options(100)).unwrap_err();
        assert!(
            err.to_string()
                .contains("candidate point 1 has a non-finite"),
            "{err}"
        );
    }

    #[test]
    fn closed_shapes_have_expected_topology() {
        for (mesh, euler) in [
            (icosphere(DVec3::ZERO, 1.0, 3), 2),
            (torus(2.0, 0.5, 32, 16), 0),
            (cuboid(DVec3::ZERO, DVec3::ONE), 2),
        ] {
            let t = topology(&mesh);
            assert_eq!(t.euler, euler);
            assert!(t.watertight && t.edge_manifold && t.vertex_manifold);
            assert_eq!(
                (t.components, t.boundary_edges, t.faces),
                (1, 0, mesh.triangles.len())
            );
            assert_eq!(t.edges * 2, t.faces * 3);
        }
    }

    #[test]
    fn open_and_nonmanifold_meshes_are_flagged() {
        let mut open = icosphere(DVec3::ZERO, 1.0, 2);
        open.triangles.pop();
        open.vertices.push(DVec3::splat(5.0)); // unused: not in V of Euler
        let t = topology(&open);
        assert!(!t.watertight && t.edge_manifold && t.vertex_manifold);
        assert_eq!(
            (t.boundary_edges, t.euler, t.vertices, t.referenced_vertices),
            (3, 1, 163, 162)
        );

        // Two closed boxes sharing one corner: a bow-tie vertex.
        let mut bowtie = cuboid(DVec3::ZERO, DVec3::ONE);
        let other = cuboid(DVec3::ONE, DVec3::splat(2.0));
        // Corner 7 of the first box is (1,1,1) = corner 0 of the second.
        let map = |i: u32| if i == 0 { 7 } else { i + 7 };
        bowtie.vertices.extend(&other.vertices[1..]);
        bowtie
            .triangles
            .extend(other.triangles.iter().map(|t| t.map(map)));
        let t = topology(&bowtie);
        assert!(t.watertight && t.edge_manifold && !t.vertex_manifold);
        assert_eq!((t.nonmanifold_vertices, t.components), (1, 1));

        // A third face on an edge of a closed box.
        let mut fin = cuboid(DVec3::ZERO, DVec3::ONE);
        fin.vertices.push(DVec3::new(0.5, -1.0, 0.5));
        fin.triangles.push([0, 1, 8]);
        let t = topology(&fin);
        assert!(!t.edge_manifold && !t.watertight);
        assert_eq!((t.nonmanifold_edges, t.boundary_edges), (1, 2));

        // Separate pieces count separately.
        let mut two = icosphere(DVec3::ZERO, 1.0, 1);
        let n = two.vertices.len() as u32;
        let far = icosphere(DVec3::splat(4.0), 1.0, 1);
        two.vertices.extend(&far.vertices);
        two.triangles
            .extend(far.triangles.iter().map(|t| t.map(|i| i + n)));
        let t = topology(&two);
        assert_eq!((t.components, t.euler), (2, 4));
        assert!(t.watertight && t.vertex_manifold);
    }

    #[test]
    fn topology_of_odd_input_does_not_panic() {
        let empty = topology(&TriMesh::default());
        assert!(!empty.watertight && empty.components == 0 && empty.euler == 0);
        let odd = TriMesh {
            vertices: vec![DVec3::ZERO; 2],
            triangles: vec![[0, 0, 1], [0, 5, 1]],
            normals: None,
        };
        let t = topology(&odd);
        assert_eq!(t.faces, 2);
        assert!(!t.watertight);
    }
}
