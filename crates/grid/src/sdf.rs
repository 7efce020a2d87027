//! Signed distance of a closed triangle mesh (negative inside).
//!
//! Magnitude: the unsigned distance to the triangles from
//! [`crate::distance`] (exact near the surface; closest-triangle
//! propagation elsewhere), over the whole grid or only in a narrow band.
//!
//! Sign: regions, then winding numbers. Two neighbouring nodes `a`, `b`
//! with `d(a) + d(b) > h` cannot have the surface between them (a crossing
//! point would be within `d(a)` of `a` and `d(b)` of `b`). The nodes split
//! into connected regions over such "free" edges; in a closed mesh each
//! region lies on one side. Each region is signed by the generalized
//! winding number (inside where it exceeds 1/2), evaluated with a
//! hierarchical approximation (a bounding-volume tree whose far clusters
//! act as dipoles) at a few sample nodes spread over the region. When the
//! samples disagree (a hole wider than a cell lets a region run inside and
//! out), every node of that region gets its own winding number. The
//! winding number degrades gracefully with cracks, holes and
//! self-intersections, so such defects never flip whole regions.

use crate::distance::{unsigned_distance_with, DataSet, DistanceOptions};
use crate::{Field3, GridError, GridSpec};
use rayon::prelude::*;
use std::collections::HashMap;
use surfrecon_geom::{DVec3, TriMesh};

/// Regions at most this large get a winding number at every node.
const SMALL_REGION: usize = 64;
/// Sample nodes per large region.
const REGION_SAMPLES: usize = 24;
/// A tree cluster farther than this many cluster radii counts as a dipole.
const FAR_RATIO: f64 = 2.0;
/// Triangles per leaf of the winding-number tree.
const LEAF_SIZE: usize = 8;

/// Signed distance of `mesh` at the nodes of `spec`, negative inside.
///
/// `band: None` gives the full (dense) field. `band: Some(w)` computes
/// distances only within `w` of the surface and stores `±w` beyond (sign
/// still correct everywhere); `w` must be at least one grid spacing.
/// Refuses empty meshes, bad vertex indices, non-finite coordinates and
/// grids that do not fit in memory. Does not require the mesh to be closed;
/// for open meshes the sign follows the winding number (see module docs).
pub fn signed_distance(
    mesh: &TriMesh,
    spec: &GridSpec<3>,
    band: Option<f64>,
) -> Result<Field3, GridError> {
    if mesh.triangles.is_empty() {
        return Err(GridError::InvalidInput("the mesh has no triangles".into()));
    }
    let data = DataSet::<3>::from_mesh(mesh)?;
    // The sign stage after the distance (which checks its own need):
    // distances, region labels, union-find parents, region order, offsets
    // and inside flags.
    spec.check_memory(8 + 4 + 4 + 4 + 4 + 1)?;
    let options = match band {
        None => DistanceOptions::default(),
        Some(w) if w.is_finite() && w >= spec.spacing => DistanceOptions {
            band_cells: w / spec.spacing,
            propagate: false,
        },
        Some(w) => {
            return Err(GridError::InvalidInput(format!(
                "band must be at least one grid spacing ({}), got {w}",
                spec.spacing
            )))
        }
    };
    let mut field = unsigned_distance_with(&data, spec, &options)?.field;
    if let Some(w) = band {
        field.values.par_iter_mut().for_each(|v| *v = v.min(w));
    }
    let tree = WindingTree::new(&data.triangles);
    let inside = inside_nodes(&field, &tree);
    field
        .values
        .par_iter_mut()
        .zip(inside.par_iter())
        .for_each(|(v, &ins)| {
            if ins {
                *v = -*v;
            }
        });
    Ok(field)
}

/// Refuse a mesh that is not closed: every edge must be shared by exactly
/// two triangles. The message counts boundary and over-shared edges.
pub fn check_closed(mesh: &TriMesh) -> Result<(), GridError> {
    if mesh.triangles.is_empty() {
        return Err(GridError::InvalidInput("the mesh has no triangles".into()));
    }
    let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let boundary = uses.values().filter(|&&n| n == 1).count();
    let over = uses.values().filter(|&&n| n > 2).count();
    if boundary == 0 && over == 0 {
        return Ok(());
    }
    Err(GridError::InvalidInput(format!(
        "the mesh is not closed: {boundary} boundary edges (used by one triangle) and \
         {over} edges used by more than two triangles; a signed distance needs a watertight mesh"
    )))
}

/// Per node: inside the mesh? (see the module docs for the method).
fn inside_nodes(field: &Field3, tree: &WindingTree) -> Vec<bool> {
    let spec = field.spec;
    let regions = Regions::new(field);
    let mut inside = vec![false; spec.node_count()];
    let position = |l: u32| DVec3::from_array(spec.position(spec.unlinear(l as usize)));
    let decided: Vec<Option<bool>> = regions
        .spans
        .par_iter()
        .map(|&(start, len)| {
            if len <= SMALL_REGION {
                return None;
            }
            let nodes = &regions.order[start..start + len];
            let votes: Vec<bool> = (0..REGION_SAMPLES)
                .map(|k| tree.winding_number(position(nodes[k * len / REGION_SAMPLES])) > 0.5)
                .collect();
            let first = votes[0];
            votes.iter().all(|&v| v == first).then_some(first)
        })
        .collect();
    // Regions without a verdict: a winding number per node, interpolated
    // where that is safe.
    let undecided: Vec<u32> = regions
        .spans
        .iter()
        .zip(&decided)
        .filter(|(_, d)| d.is_none())
        .flat_map(|(&(start, len), _)| regions.order[start..start + len].iter().copied())
        .collect();
    let per_node = winding_sides(field, tree, &undecided);
    for (&l, &ins) in undecided.iter().zip(&per_node) {
        inside[l as usize] = ins;
    }
    for (&(start, len), d) in regions.spans.iter().zip(&decided) {
        if let Some(ins) = *d {
            for &l in &regions.order[start..start + len] {
                inside[l as usize] = ins;
            }
        }
    }
    inside
}

/// Coarse lattice steps (in nodes) tried by [`winding_sides`], coarsest
/// first.
const COARSE_STEPS: [usize; 4] = [16, 8, 4, 2];
/// Winding numbers within this of 1/2 at a coarse corner are not trusted
/// to decide the nodes of its cells.
const WINDING_MARGIN: f64 = 0.2;

/// Inside (winding number above 1/2) for each node of `nodes`.
///
/// The winding number is harmonic away from the surface. A node farther
/// from the surface than the diagonal of its cell in a lattice of step S
/// has no surface in that cell; when the winding numbers at the cell's 8
/// corners all lie on one side of 1/2 by [`WINDING_MARGIN`], the node takes
/// that side. Lattices from coarse to fine ([`COARSE_STEPS`]) decide the
/// nodes far, then less far, from the surface; the rest get their own
/// winding number. Leaky regions of scans with holes (all of the grid but
/// the surface's pockets) then cost a few evaluations per coarse cell
/// instead of one per node.
fn winding_sides(field: &Field3, tree: &WindingTree, nodes: &[u32]) -> Vec<bool> {
    let spec = field.spec;
    let mut side: Vec<Option<bool>> = vec![None; nodes.len()];
    for step in COARSE_STEPS {
        let lattice = Lattice::new(&spec, step);
        let diagonal = step as f64 * spec.spacing * 3f64.sqrt();
        let open = |k: usize| side[k].is_none() && field.values[nodes[k] as usize] > diagonal;
        let mut needed = vec![false; lattice.len()];
        for k in (0..nodes.len()).filter(|&k| open(k)) {
            for c in lattice.corners(spec.unlinear(nodes[k] as usize)) {
                needed[c] = true;
            }
        }
        let winding: Vec<f64> = (0..needed.len())
            .into_par_iter()
            .map(|c| match needed[c] {
                true => tree.winding_number(lattice.position(&spec, c)),
                false => f64::NAN,
            })
            .collect();
        let decided: Vec<Option<bool>> = (0..nodes.len())
            .into_par_iter()
            .map(|k| {
                if !open(k) {
                    return side[k];
                }
                let corners = lattice.corners(spec.unlinear(nodes[k] as usize));
                let (lo, hi) = corners
                    .map(|c| winding[c])
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), w| {
                        (lo.min(w), hi.max(w))
                    });
                (lo > 0.5 + WINDING_MARGIN || hi < 0.5 - WINDING_MARGIN).then_some(lo > 0.5)
            })
            .collect();
        side = decided;
    }
    nodes
        .par_iter()
        .zip(&side)
        .map(|(&l, s)| {
            s.unwrap_or_else(|| {
                let p = spec.position(spec.unlinear(l as usize));
                tree.winding_number(DVec3::from_array(p)) > 0.5
            })
        })
        .collect()
}

/// The nodes of a grid whose indices are all multiples of `step` (the
/// last index on each axis clamped to the grid), as a coarse lattice.
struct Lattice {
    step: usize,
    /// Lattice points per axis.
    dims: [usize; 3],
}

impl Lattice {
    fn new(spec: &GridSpec<3>, step: usize) -> Self {
        Lattice {
            step,
            dims: spec.dims.map(|n| (n - 1).div_ceil(step) + 1),
        }
    }

    fn len(&self) -> usize {
        self.dims.iter().product()
    }

    /// Lattice indices of the 8 corners of the cell holding node `idx`.
    fn corners(&self, idx: [usize; 3]) -> impl Iterator<Item = usize> + '_ {
        let cell = idx.map(|i| i / self.step);
        (0..8).map(move |k| {
            let c: [usize; 3] =
                std::array::from_fn(|a| (cell[a] + (k >> a & 1)).min(self.dims[a] - 1));
            c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
        })
    }

    /// Position of lattice point `c`.
    fn position(&self, spec: &GridSpec<3>, c: usize) -> DVec3 {
        let lattice = [
            c % self.dims[0],
            c / self.dims[0] % self.dims[1],
            c / (self.dims[0] * self.dims[1]),
        ];
        let idx = std::array::from_fn(|a| (lattice[a] * self.step).min(spec.dims[a] - 1));
        DVec3::from_array(spec.position(idx))
    }
}

/// Connected regions of nodes over free edges (`d(a) + d(b) > h`).
struct Regions {
    /// All nodes, grouped by region (ascending index within each).
    order: Vec<u32>,
    /// (start in `order`, length) per region.
    spans: Vec<(usize, usize)>,
}

impl Regions {
    /// Layers (along z) per slab of the parallel labelling; fixed, so the
    /// result never depends on the thread count.
    const SLAB_LAYERS: usize = 8;

    /// Label each slab's regions in parallel (a region's label is its
    /// smallest node index), join labels across slab boundaries, and group
    /// the nodes by region in index order.
    fn new(field: &Field3) -> Self {
        let spec = field.spec;
        let layer = spec.strides()[2];
        let mut label = vec![0u32; spec.node_count()];
        label
            .par_chunks_mut(Self::SLAB_LAYERS * layer)
            .enumerate()
            .for_each(|(s, slab)| Self::label_slab(field, s * Self::SLAB_LAYERS * layer, slab));
        let mut parent: Vec<u32> = (0..spec.node_count() as u32).collect();
        for z in (Self::SLAB_LAYERS..spec.dims[2]).step_by(Self::SLAB_LAYERS) {
            for a in (z - 1) * layer..z * layer {
                if Self::free(field, a, a + layer) {
                    union(&mut parent, label[a], label[a + layer]);
                }
            }
        }
        for l in &mut label {
            *l = find(&mut parent, *l);
        }
        drop(parent);
        Self::group(&label)
    }

    /// No surface can cross the edge between nodes `a` and `b`.
    fn free(field: &Field3, a: usize, b: usize) -> bool {
        field.values[a] + field.values[b] > field.spec.spacing
    }

    /// Breadth-first labelling of the regions of one slab (nodes `offset..`).
    fn label_slab(field: &Field3, offset: usize, label: &mut [u32]) {
        let spec = field.spec;
        let strides = spec.strides();
        let mut seen = vec![false; label.len()];
        let mut queue = Vec::new();
        for seed in 0..label.len() {
            if seen[seed] {
                continue;
            }
            seen[seed] = true;
            queue.clear();
            queue.push(seed);
            while let Some(l) = queue.pop() {
                label[l] = (offset + seed) as u32;
                let idx = spec.unlinear(offset + l);
                for a in 0..3 {
                    let lower = (idx[a] > 0).then(|| l.wrapping_sub(strides[a]));
                    let upper = (idx[a] + 1 < spec.dims[a]).then(|| l + strides[a]);
                    for m in lower.into_iter().chain(upper) {
                        if m < label.len() && !seen[m] && Self::free(field, offset + l, offset + m)
                        {
                            seen[m] = true;
                            queue.push(m);
                        }
                    }
                }
            }
        }
    }

    /// Nodes grouped by their region's root, roots and nodes ascending.
    fn group(root: &[u32]) -> Self {
        // Node counts per root, then turned in place into start offsets.
        let mut start = vec![0u32; root.len()];
        for &r in root {
            start[r as usize] += 1;
        }
        let mut spans = Vec::new();
        let mut next = 0u32;
        for s in start.iter_mut() {
            let count = *s;
            if count > 0 {
                spans.push((next as usize, count as usize));
            }
            *s = next;
            next += count;
        }
        let mut order = vec![0u32; root.len()];
        for (l, &r) in root.iter().enumerate() {
            order[start[r as usize] as usize] = l as u32;
            start[r as usize] += 1;
        }
        Regions { order, spans }
    }
}

/// Root of `x` in the union-find forest `parent`, halving the path.
fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// Join the sets of `a` and `b` under the smaller root (so roots are the
/// smallest labels, whatever the order of joins).
fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    let (lo, hi) = (ra.min(rb), ra.max(rb));
    parent[hi as usize] = lo;
}

/// Bounding-volume tree over triangles for fast generalized winding
/// numbers: a cluster far from the query (relative to its radius) is
/// replaced by a dipole, its area-weighted normal at its area centroid.
struct WindingTree {
    triangles: Vec<[DVec3; 3]>,
    nodes: Vec<Cluster>,
}

struct Cluster {
    /// Area-weighted centroid of the triangles.
    centre: DVec3,
    /// Sum of the triangles' vector areas (half cross products).
    vector_area: DVec3,
    /// Largest distance from `centre` to a triangle corner.
    radius: f64,
    /// Triangle range `start..end` in the tree's order.
    start: usize,
    end: usize,
    /// Child cluster indices, `None` for leaves.
    children: Option<(usize, usize)>,
}

impl WindingTree {
    fn new(triangles: &[[[f64; 3]; 3]]) -> Self {
        let triangles: Vec<[DVec3; 3]> =
            triangles.iter().map(|t| t.map(DVec3::from_array)).collect();
        let mut tree = WindingTree {
            triangles,
            nodes: Vec::new(),
        };
        let count = tree.triangles.len();
        tree.build(0, count);
        tree
    }

    /// Build the cluster over triangles `start..end`; returns its index.
    fn build(&mut self, start: usize, end: usize) -> usize {
        let tris = &self.triangles[start..end];
        let mut vector_area = DVec3::ZERO;
        let mut weighted = DVec3::ZERO;
        let mut area_sum = 0.0;
        for [a, b, c] in tris {
            let va = 0.5 * (*b - *a).cross(*c - *a);
            vector_area += va;
            let area = va.length();
            weighted += area * (*a + *b + *c) / 3.0;
            area_sum += area;
        }
        let mean = tris
            .iter()
            .map(|t| (t[0] + t[1] + t[2]) / 3.0)
            .sum::<DVec3>()
            / tris.len() as f64;
        let centre = if area_sum > 0.0 {
            weighted / area_sum
        } else {
            mean
        };
        let radius = tris
            .iter()
            .flatten()
            .map(|p| p.distance(centre))
            .fold(0.0, f64::max);
        let id = self.nodes.len();
        self.nodes.push(Cluster {
            centre,
            vector_area,
            radius,
            start,
            end,
            children: None,
        });
        if end - start > LEAF_SIZE {
            let mid = self.split(start, end);
            let left = self.build(start, mid);
            let right = self.build(mid, end);
            self.nodes[id].children = Some((left, right));
        }
        id
    }

    /// Reorder triangles `start..end` about the median centroid along the
    /// widest axis; returns the split position.
    fn split(&mut self, start: usize, end: usize) -> usize {
        let centroid = |t: &[DVec3; 3]| (t[0] + t[1] + t[2]) / 3.0;
        let (lo, hi) = self.triangles[start..end].iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), t| (lo.min(centroid(t)), hi.max(centroid(t))),
        );
        let axis = (hi - lo).max_position();
        let mid = (start + end) / 2;
        self.triangles[start..end].select_nth_unstable_by(mid - start, |a, b| {
            centroid(a)[axis].total_cmp(&centroid(b)[axis])
        });
        mid
    }

    /// Generalized winding number at `q` (1 inside a closed outward mesh,
    /// 0 outside).
    fn winding_number(&self, q: DVec3) -> f64 {
        let mut total = 0.0;
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let c = &self.nodes[i];
            let r = c.centre - q;
            let dist = r.length();
            if dist > FAR_RATIO * c.radius {
                total += c.vector_area.dot(r) / (dist * dist * dist);
                continue;
            }
            match c.children {
                Some((a, b)) => stack.extend([a, b]),
                None => {
                    total += self.triangles[c.start..c.end]
                        .iter()
                        .map(|t| solid_angle(t, q))
                        .sum::<f64>()
                }
            }
        }
        total / (4.0 * std::f64::consts::PI)
    }
}

/// Signed solid angle of triangle `t` seen from `q` (Van Oosterom and
/// Strackee): positive when `q` is behind the triangle's front side.
fn solid_angle(t: &[DVec3; 3], q: DVec3) -> f64 {
    let [a, b, c] = t.map(|p| p - q);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * num.atan2(den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridSize;
    use surfrecon_geom::shapes;

    fn grid_around(mesh: &TriMesh, cells: usize) -> GridSpec<3> {
        let b = mesh.bounds();
        GridSpec::from_bounds(
            b.min.to_array(),
            b.max.to_array(),
            GridSize::Resolution(cells),
            4,
        )
        .unwrap()
    }

    /// Max |field - exact| (nodes where `exact` is NaN are skipped), checking
    /// signs where |exact| exceeds `sign_margin`.
    fn compare(field: &Field3, exact: impl Fn(DVec3) -> f64 + Sync, sign_margin: f64) -> f64 {
        let spec = field.spec;
        (0..spec.node_count())
            .into_par_iter()
            .map(|l| {
                let p = DVec3::from_array(spec.position(spec.unlinear(l)));
                let (got, want) = (field.values[l], exact(p));
                if want.is_nan() {
                    return 0.0;
                }
                if want.abs() > sign_margin {
                    assert_eq!(
                        got < 0.0,
                        want < 0.0,
                        "sign at {p}: got {got}, exact {want}"
                    );
                }
                (got - want).abs()
            })
            .reduce(|| 0.0, f64::max)
    }

    /// How far the planes of a sphere mesh's flat triangles sink below the
    /// sphere (bounds the Hausdorff distance between mesh and sphere).
    fn sphere_tessellation_error(mesh: &TriMesh, centre: DVec3, radius: f64) -> f64 {
        (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                let n = (b - a).cross(c - a).normalize();
                radius - n.dot(a - centre).abs()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn sphere_matches_exact_sdf() {
        let centre = DVec3::new(0.1, -0.2, 0.3);
        let mesh = shapes::icosphere(centre, 1.0, 4);
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let tess = sphere_tessellation_error(&mesh, centre, 1.0);
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let brute = |p: DVec3| {
            (0..data.len())
                .map(|i| data.distance(i, &p.to_array()))
                .fold(f64::INFINITY, f64::min)
        };
        // Brute force on every 5th node (5120 triangles each), split into
        // within 5 h of the surface and beyond.
        let h = spec.spacing;
        let (near, far) = (0..spec.node_count())
            .into_par_iter()
            .step_by(5)
            .map(|l| {
                let p = DVec3::from_array(spec.position(spec.unlinear(l)));
                let exact = brute(p);
                let e = (field.values[l].abs() - exact).abs();
                if exact <= 5.0 * h {
                    (e, 0.0)
                } else {
                    (0.0, e)
                }
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
        println!(
            "sphere SDF unsigned error: {:.2e} h near, {:.2e} h far",
            near / h,
            far / h
        );
        assert!(near <= 0.05 * h, "near error {near}");
        // Far from the surface, propagation is near-exact (see
        // `distance::propagate`).
        assert!(far <= 0.3 * h, "far error {far}");
        let err = compare(&field, |p| (p - centre).length() - 1.0, tess + far);
        assert!(
            err <= tess + far + 1e-12,
            "error {err}, tessellation {tess}"
        );
    }

    #[test]
    fn cube_with_sharp_edges_is_exact() {
        let (lo, hi) = (DVec3::new(-1.0, -0.5, -0.25), DVec3::new(1.0, 0.5, 0.75));
        let mesh = shapes::cuboid(lo, hi);
        let spec = grid_around(&mesh, 36);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        let exact = |p: DVec3| {
            let q = (p - centre).abs() - half;
            q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
        };
        let err = compare(&field, exact, 1e-9);
        assert!(err < 1e-9, "error {err}");
    }

    #[test]
    fn torus_matches_exact_sdf() {
        let (major, minor) = (1.0, 0.35);
        let mesh = shapes::torus(major, minor, 96, 48);
        let spec = grid_around(&mesh, 48);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let exact = |p: DVec3| {
            let ring = (p.x * p.x + p.y * p.y).sqrt() - major;
            (ring * ring + p.z * p.z).sqrt() - minor
        };
        // Chord sag of the two tessellation directions.
        let sag = (major + minor) * (1.0 - (std::f64::consts::PI / 96.0).cos())
            + minor * (1.0 - (std::f64::consts::PI / 48.0).cos());
        let h = spec.spacing;
        let near = |p: DVec3| exact(p).abs() <= 5.0 * h;
        let near_err = compare(
            &field,
            |p| if near(p) { exact(p) } else { f64::NAN },
            2.0 * sag,
        );
        let far_err = compare(
            &field,
            |p| if near(p) { f64::NAN } else { exact(p) },
            2.0 * sag,
        );
        println!(
            "torus SDF error: near {:.2e} h, far {:.2e} h, sag {:.2e} h",
            near_err / h,
            far_err / h,
            sag / h
        );
        assert!(near_err <= 2.0 * sag, "near error {near_err}, sag {sag}");
        assert!(
            far_err <= 2.0 * sag + 0.3 * h,
            "far error {far_err}, sag {sag}"
        );
    }

    #[test]
    fn sphere_with_a_missing_triangle_still_signs_correctly() {
        let mut mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        mesh.triangles.remove(100);
        assert!(check_closed(&mesh).is_err());
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let tess = sphere_tessellation_error(&mesh, DVec3::ZERO, 1.0);
        // Near the hole the distance is to its rim, so only signs are checked
        // away from the surface.
        compare(&field, |p| p.length() - 1.0, tess + 2.0 * spec.spacing);
    }

    /// A hole many cells wide lets the outside region leak in, so its
    /// nodes are signed by (interpolated) winding numbers: the signs must
    /// equal the exact winding number's at every node.
    #[test]
    fn wide_hole_signs_match_exact_winding_numbers() {
        let mut mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        // Drop every triangle with a corner in a cap around +z.
        mesh.triangles
            .retain(|t| t.iter().all(|&i| mesh.vertices[i as usize].z < 0.8));
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let tree = WindingTree::new(&data.triangles);
        let wrong = (0..spec.node_count())
            .into_par_iter()
            .filter(|&l| {
                let p = DVec3::from_array(spec.position(spec.unlinear(l)));
                let exact = tree.winding_number(p);
                // Exactly on the surface either side is right.
                field.values[l] != 0.0 && (field.values[l] < 0.0) != (exact > 0.5)
            })
            .count();
        assert_eq!(wrong, 0);
    }

    #[test]
    fn overlapping_spheres_sign_as_their_union() {
        let a = shapes::icosphere(DVec3::new(-0.4, 0.0, 0.0), 0.7, 3);
        let b = shapes::icosphere(DVec3::new(0.4, 0.0, 0.0), 0.7, 3);
        let offset = a.vertices.len() as u32;
        let mesh = TriMesh {
            vertices: [a.vertices.clone(), b.vertices.clone()].concat(),
            triangles: a
                .triangles
                .iter()
                .copied()
                .chain(b.triangles.iter().map(|t| t.map(|i| i + offset)))
                .collect(),
            normals: None,
        };
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let tess = sphere_tessellation_error(&a, DVec3::new(-0.4, 0.0, 0.0), 0.7);
        let union = |p: DVec3| {
            let da = (p - DVec3::new(-0.4, 0.0, 0.0)).length() - 0.7;
            let db = (p - DVec3::new(0.4, 0.0, 0.0)).length() - 0.7;
            da.min(db)
        };
        compare(&field, union, tess + 1e-9);
    }

    #[test]
    fn narrow_band_matches_dense_inside_and_clamps_outside() {
        let mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        let spec = grid_around(&mesh, 32);
        let dense = signed_distance(&mesh, &spec, None).unwrap();
        let w = 3.0 * spec.spacing;
        let band = signed_distance(&mesh, &spec, Some(w)).unwrap();
        for (d, b) in dense.values.iter().zip(&band.values) {
            if d.abs() <= w {
                assert_eq!(d, b);
            } else {
                assert_eq!(*b, w.copysign(*d));
            }
        }
        assert!(signed_distance(&mesh, &spec, Some(0.1 * spec.spacing)).is_err());
        assert!(signed_distance(&mesh, &spec, Some(f64::NAN)).is_err());
    }

    #[test]
    fn closed_check_and_bad_meshes() {
        assert!(check_closed(&shapes::torus(1.0, 0.3, 12, 8)).is_ok());
        let mut open = shapes::cuboid(DVec3::ZERO, DVec3::ONE);
        open.triangles.pop();
        let msg = check_closed(&open).unwrap_err().to_string();
        assert!(msg.contains("3 boundary edges"), "{msg}");
        let spec = grid_around(&shapes::cuboid(DVec3::ZERO, DVec3::ONE), 8);
        assert!(signed_distance(&TriMesh::default(), &spec, None).is_err());
        let bad = TriMesh {
            vertices: vec![DVec3::ZERO; 3],
            triangles: vec![[0, 1, 5]],
            normals: None,
        };
        assert!(signed_distance(&bad, &spec, None).is_err());
    }

    #[test]
    fn winding_number_tree_matches_exact_sum() {
        let mesh = shapes::torus(1.0, 0.4, 40, 20);
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let tree = WindingTree::new(&data.triangles);
        for q in [
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.3, 0.1, 0.2),
            DVec3::new(3.0, -2.0, 1.0),
            DVec3::new(0.0, -1.1, 0.1),
        ] {
            let exact: f64 = tree
                .triangles
                .iter()
                .map(|t| solid_angle(t, q))
                .sum::<f64>()
                / (4.0 * std::f64::consts::PI);
            let fast = tree.winding_number(q);
            // The dipole approximation is a few percent off: ample to
            // decide inside (> 1/2) away from the surface.
            assert!((exact - fast).abs() < 0.05, "{q}: {exact} vs {fast}");
        }
    }
}
