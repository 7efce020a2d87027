//! Mesh fairing: smooth fills for the parts of a surface that no data
//! support.
//!
//! [`fair`] moves the free vertices of a mesh so that the surface there is
//! as smooth as the fixed vertices around it allow: it minimises the sum of
//! squared graph Laplacians over the free vertices and their neighbours,
//! i.e. solves the discrete bi-Laplace equation Δ²x = 0 with the fixed
//! vertices (two rings deep, through the stencil) as boundary values. The
//! fill meets the fixed surface with matching slope, so a hole in a curved
//! surface is spanned by a patch that continues the curvature, not by a
//! flat or sagging membrane. Connectivity never changes.
//!
//! The system is solved per coordinate by conjugate gradients on the free
//! vertices, starting from their current positions.

use crate::{DVec3, TriMesh};
use rayon::prelude::*;

/// Conjugate-gradient limits for [`fair`].
#[derive(Clone, Copy, Debug)]
pub struct FairingOptions {
    /// Iteration cap per coordinate.
    pub max_iterations: usize,
    /// Stop when the residual norm falls below this share of the
    /// right-hand side's.
    pub tolerance: f64,
}

impl Default for FairingOptions {
    fn default() -> Self {
        FairingOptions {
            max_iterations: 4000,
            tolerance: 1e-8,
        }
    }
}

/// What [`fair`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FairingStats {
    /// Free vertices that were moved (those connected to a fixed one).
    pub moved: usize,
    /// Free vertices left as they were: their connected piece of free
    /// vertices touches no fixed vertex, so nothing anchors it.
    pub unanchored: usize,
    /// Largest conjugate-gradient iteration count over the coordinates.
    pub iterations: usize,
    /// Largest distance a vertex moved.
    pub max_shift: f64,
}

/// Fair the vertices with `free[v] == true` (see the module docs).
/// `free` must have one entry per vertex.
pub fn fair(mesh: &mut TriMesh, free: &[bool], options: &FairingOptions) -> FairingStats {
    assert_eq!(free.len(), mesh.vertices.len(), "one flag per vertex");
    let graph = Graph::new(mesh);
    let anchored = anchored_free(&graph, free);
    let unknowns: Vec<usize> = (0..free.len()).filter(|&v| anchored[v]).collect();
    let mut stats = FairingStats {
        moved: unknowns.len(),
        unanchored: free.iter().filter(|&&f| f).count() - unknowns.len(),
        ..Default::default()
    };
    if unknowns.is_empty() {
        return stats;
    }
    let before: Vec<DVec3> = unknowns.iter().map(|&v| mesh.vertices[v]).collect();
    let ring = graph.with_neighbours(&unknowns);
    for axis in 0..3 {
        let mut x: Vec<f64> = mesh.vertices.iter().map(|p| p[axis]).collect();
        let iterations = graph.solve_bilaplace(&mut x, &unknowns, &ring, options);
        stats.iterations = stats.iterations.max(iterations);
        for &v in &unknowns {
            mesh.vertices[v][axis] = x[v];
        }
    }
    stats.max_shift = unknowns
        .iter()
        .zip(&before)
        .map(|(&v, b)| mesh.vertices[v].distance(*b))
        .fold(0.0, f64::max);
    if let Some(normals) = &mut mesh.normals {
        let faired = area_weighted_normals(&mesh.vertices, &mesh.triangles);
        for &v in &unknowns {
            normals[v] = faired[v];
        }
    }
    stats
}

/// Vertex normals as the area-weighted mean of the incident faces'.
pub fn area_weighted_normals(vertices: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; vertices.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            normals[i as usize] += n;
        }
    }
    normals.iter().map(|n| n.normalize_or_zero()).collect()
}

/// Free vertices whose connected piece of free vertices has a fixed
/// neighbour somewhere.
fn anchored_free(graph: &Graph, free: &[bool]) -> Vec<bool> {
    let mut anchored = vec![false; free.len()];
    let mut stack: Vec<usize> = (0..free.len())
        .filter(|&v| free[v] && graph.neighbours(v).iter().any(|&w| !free[w as usize]))
        .collect();
    for &v in &stack {
        anchored[v] = true;
    }
    while let Some(v) = stack.pop() {
        for &w in graph.neighbours(v) {
            let w = w as usize;
            if free[w] && !anchored[w] {
                anchored[w] = true;
                stack.push(w);
            }
        }
    }
    anchored
}

/// Vertex adjacency of a triangle mesh (compressed rows, no duplicates).
struct Graph {
    offsets: Vec<usize>,
    adjacent: Vec<u32>,
}

impl Graph {
    fn new(mesh: &TriMesh) -> Self {
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 6);
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
        pairs.par_sort_unstable();
        pairs.dedup();
        let mut offsets = vec![0usize; mesh.vertices.len() + 1];
        for &(a, _) in &pairs {
            offsets[a as usize + 1] += 1;
        }
        for v in 0..mesh.vertices.len() {
            offsets[v + 1] += offsets[v];
        }
        Graph {
            offsets,
            adjacent: pairs.into_iter().map(|(_, b)| b).collect(),
        }
    }

    fn neighbours(&self, v: usize) -> &[u32] {
        &self.adjacent[self.offsets[v]..self.offsets[v + 1]]
    }

    /// (K x)_v with K = degree − adjacency (the graph Laplacian, up to sign).
    fn laplace_at(&self, x: &[f64], v: usize) -> f64 {
        let n = self.neighbours(v);
        n.len() as f64 * x[v] - n.iter().map(|&w| x[w as usize]).sum::<f64>()
    }

    /// The vertices of `set` and their neighbours, each once.
    fn with_neighbours(&self, set: &[usize]) -> Vec<usize> {
        let mut ring: Vec<usize> = set
            .iter()
            .flat_map(|&v| self.neighbours(v).iter().map(|&w| w as usize))
            .chain(set.iter().copied())
            .collect();
        ring.par_sort_unstable();
        ring.dedup();
        ring
    }

    /// (K² x)_u for the `unknowns` u, with K x evaluated on `ring` (the
    /// unknowns and their neighbours) into `kx`; everything the stencils
    /// read lies there, so the cost follows the number of unknowns.
    fn bilaplace_on(
        &self,
        x: &[f64],
        ring: &[usize],
        unknowns: &[usize],
        kx: &mut [f64],
        out: &mut [f64],
    ) {
        for &w in ring {
            kx[w] = self.laplace_at(x, w);
        }
        for (o, &u) in out.iter_mut().zip(unknowns) {
            *o = self.laplace_at(kx, u);
        }
    }

    /// Solve (K²)_ff x_f = −(K²)_fb x_b for the `unknowns` (f) of `x`, the
    /// other entries (b) staying fixed; conjugate gradients from the
    /// current values. `ring` is the unknowns with their neighbours
    /// ([`Graph::with_neighbours`]). Returns the iterations used.
    fn solve_bilaplace(
        &self,
        x: &mut [f64],
        unknowns: &[usize],
        ring: &[usize],
        options: &FairingOptions,
    ) -> usize {
        let m = unknowns.len();
        let mut kx = vec![0.0; x.len()];
        // The residual at the current x, and the right-hand side's norm
        // (the same with the unknowns at zero).
        let mut r = vec![0.0; m];
        self.bilaplace_on(x, ring, unknowns, &mut kx, &mut r);
        r.iter_mut().for_each(|v| *v = -*v);
        let mut fixed_only = x.to_vec();
        for &u in unknowns {
            fixed_only[u] = 0.0;
        }
        let mut b = vec![0.0; m];
        self.bilaplace_on(&fixed_only, ring, unknowns, &mut kx, &mut b);
        let goal = options.tolerance.powi(2) * b.iter().map(|v| v * v).sum::<f64>();
        // The search direction lives on the unknowns; `full` holds it at
        // their places and zero elsewhere.
        let mut full = vec![0.0; x.len()];
        let mut p = r.clone();
        let mut ap = vec![0.0; m];
        let mut rr: f64 = r.iter().map(|v| v * v).sum();
        for iteration in 0..options.max_iterations {
            if rr <= goal {
                return iteration;
            }
            for (&u, &pv) in unknowns.iter().zip(&p) {
                full[u] = pv;
            }
            self.bilaplace_on(&full, ring, unknowns, &mut kx, &mut ap);
            let pap: f64 = p.iter().zip(&ap).map(|(a, b)| a * b).sum();
            // Converged to rounding (or a NaN): no further step helps.
            if pap.is_nan() || pap <= 0.0 {
                return iteration;
            }
            let alpha = rr / pap;
            for ((&u, pv), (rv, apv)) in unknowns.iter().zip(&p).zip(r.iter_mut().zip(&ap)) {
                x[u] += alpha * pv;
                *rv -= alpha * apv;
            }
            let next: f64 = r.iter().map(|v| v * v).sum();
            let beta = next / rr;
            rr = next;
            for (pv, rv) in p.iter_mut().zip(&r) {
                *pv = rv + beta * *pv;
            }
        }
        options.max_iterations
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;

    /// Vertices of a unit sphere mesh inside a cap around +z are free and
    /// flattened onto the plane of the cap's rim, like a membrane.
    fn flattened_cap(mesh: &mut TriMesh, cap_z: f64) -> Vec<bool> {
        let free: Vec<bool> = mesh.vertices.iter().map(|v| v.z > cap_z).collect();
        for (v, &f) in mesh.vertices.iter_mut().zip(&free) {
            if f {
                v.z = cap_z;
            }
        }
        free
    }

    #[test]
    fn a_flattened_cap_regains_the_sphere() {
        let mut mesh = shapes::icosphere(DVec3::ZERO, 1.0, 4);
        let free = flattened_cap(&mut mesh, 0.8);
        let error = |m: &TriMesh| {
            m.vertices
                .iter()
                .zip(&free)
                .filter(|(_, &f)| f)
                .map(|(v, _)| (v.length() - 1.0).abs())
                .fold(0.0, f64::max)
        };
        let before = error(&mesh);
        let stats = fair(&mut mesh, &free, &FairingOptions::default());
        assert_eq!(stats.moved, free.iter().filter(|&&f| f).count());
        assert!(stats.iterations < FairingOptions::default().max_iterations);
        // The membrane sags 0.2 below the pole; the fair patch continues
        // the sphere's curvature and recovers most of that (a sphere is not
        // exactly biharmonic: measured 0.024 left).
        let after = error(&mesh);
        assert!(before > 0.19 && after < before / 5.0, "{before} -> {after}");
    }

    #[test]
    fn fixed_and_unanchored_vertices_stay() {
        let mut mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        let original = mesh.vertices.clone();
        // Everything free: no anchor, nothing moves.
        let all = vec![true; mesh.vertices.len()];
        let stats = fair(&mut mesh, &all, &FairingOptions::default());
        assert_eq!((stats.moved, stats.unanchored), (0, all.len()));
        assert_eq!(mesh.vertices, original);
        // A cap free: the rest stays bit for bit.
        let free = flattened_cap(&mut mesh, 0.5);
        fair(&mut mesh, &free, &FairingOptions::default());
        for ((v, o), &f) in mesh.vertices.iter().zip(&original).zip(&free) {
            if !f {
                assert_eq!(v, o);
            }
        }
    }
}
