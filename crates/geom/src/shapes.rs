//! Analytic test shapes and uniform surface sampling.
//!
//! Used by tests, benchmarks and the metrics: closed meshes whose exact
//! surface is known (sphere, torus, box) and area-weighted, seeded sampling
//! of any triangle mesh.

use crate::{PointCloud, TriMesh};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use std::collections::HashMap;

/// Geodesic sphere: an icosahedron subdivided `subdivisions` times, outward
/// winding, vertices exactly on the sphere.
pub fn icosphere(center: DVec3, radius: f64, subdivisions: u32) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<DVec3> = [
        (-1., t, 0.),
        (1., t, 0.),
        (-1., -t, 0.),
        (1., -t, 0.),
        (0., -1., t),
        (0., 1., t),
        (0., -1., -t),
        (0., 1., -t),
        (t, 0., -1.),
        (t, 0., 1.),
        (-t, 0., -1.),
        (-t, 0., 1.),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, verts: &mut Vec<DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push((verts[a as usize] + verts[b as usize]).normalize());
                verts.len() as u32 - 1
            })
        };
        tris = tris
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = midpoint(a, b, &mut verts);
                let bc = midpoint(b, c, &mut verts);
                let ca = midpoint(c, a, &mut verts);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    let normals = verts.clone();
    TriMesh {
        vertices: verts.iter().map(|v| center + radius * *v).collect(),
        triangles: tris,
        normals: Some(normals),
    }
}

/// Torus around the z axis: tube centre radius `major`, tube radius `minor`,
/// `nu` segments around z and `nv` around the tube; outward winding.
pub fn torus(major: f64, minor: f64, nu: u32, nv: u32) -> TriMesh {
    let mut vertices = Vec::new();
    let mut normals = Vec::new();
    for i in 0..nu {
        let u = i as f64 / nu as f64 * std::f64::consts::TAU;
        for j in 0..nv {
            let v = j as f64 / nv as f64 * std::f64::consts::TAU;
            let n = DVec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
            let c = DVec3::new(major * u.cos(), major * u.sin(), 0.0);
            vertices.push(c + minor * n);
            normals.push(n);
        }
    }
    let id = |i: u32, j: u32| (i % nu) * nv + (j % nv);
    let mut triangles = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriMesh {
        vertices,
        triangles,
        normals: Some(normals),
    }
}

/// Axis-aligned box from `min` to `max` as 12 outward-wound triangles.
pub fn cuboid(min: DVec3, max: DVec3) -> TriMesh {
    let vertices = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            )
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6], // -z, +z
        [0, 1, 5, 4],
        [2, 6, 7, 3], // -y, +y
        [0, 4, 6, 2],
        [1, 3, 7, 5], // -x, +x
    ];
    let triangles = quads
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect();
    TriMesh {
        vertices,
        triangles,
        normals: None,
    }
}

/// The octahedron with vertices ±x, ±y, ±z (in that order), outward
/// winding: the simplest closed mesh whose every vertex is a sharp corner.
pub fn octahedron() -> TriMesh {
    let vertices = vec![
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ];
    let triangles = [(0, 2), (2, 1), (1, 3), (3, 0)]
        .into_iter()
        .flat_map(|(x, y)| [[x, y, 4], [y, x, 5]])
        .collect();
    TriMesh {
        vertices,
        triangles,
        normals: None,
    }
}

/// `n` points drawn uniformly by area from the mesh surface (seeded, so the
/// same call gives the same points), with the faces' unit normals.
/// Degenerate (zero-area) triangles are never drawn; an empty or zero-area
/// mesh gives an empty cloud.
pub fn sample_surface(mesh: &TriMesh, n: usize, seed: u64) -> PointCloud {
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.corners(t);
        total += 0.5 * (b - a).cross(c - a).length();
        cumulative.push(total);
    }
    if total.is_nan() || total <= 0.0 {
        return PointCloud::default();
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for _ in 0..n {
        let x = rng.random::<f64>() * total;
        let t = cumulative
            .partition_point(|&c| c <= x)
            .min(cumulative.len() - 1);
        let [a, b, c] = mesh.corners(t);
        let (mut u, mut v) = (rng.random::<f64>(), rng.random::<f64>());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        positions.push(a + u * (b - a) + v * (c - a));
        normals.push((b - a).cross(c - a).normalize());
    }
    PointCloud {
        positions,
        normals: Some(normals),
        scalars: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_is_on_sphere_with_expected_area() {
        let m = icosphere(DVec3::ONE, 2.0, 4);
        for v in &m.vertices {
            assert!(((*v - DVec3::ONE).length() - 2.0).abs() < 1e-12);
        }
        let exact = 4.0 * std::f64::consts::PI * 4.0;
        assert!((m.area() - exact).abs() / exact < 0.01);
        assert_eq!(
            m.vertices.len() as i64 - 3 * m.triangles.len() as i64 / 2 + m.triangles.len() as i64,
            2
        );
    }

    #[test]
    fn samples_lie_on_surface_and_face_outward() {
        let m = torus(2.0, 0.5, 64, 32);
        let pc = sample_surface(&m, 1000, 7);
        assert_eq!(pc.len(), 1000);
        for (p, n) in pc.positions.iter().zip(pc.normals.as_ref().unwrap()) {
            let ring = DVec3::new(p.x, p.y, 0.0).normalize() * 2.0;
            assert!(((*p - ring).length() - 0.5).abs() < 0.01);
            assert!(n.dot((*p - ring).normalize()) > 0.9);
        }
        let cube = cuboid(DVec3::ZERO, DVec3::ONE);
        assert!((cube.area() - 6.0).abs() < 1e-12);
        let pc = sample_surface(&cube, 100, 1);
        for (p, n) in pc.positions.iter().zip(pc.normals.unwrap()) {
            assert!((*p - DVec3::splat(0.5)).dot(n) > 0.49);
        }
    }

    #[test]
    fn octahedron_is_closed_and_wound_outward() {
        let mesh = octahedron();
        assert!((mesh.area() - 4.0 * 3f64.sqrt()).abs() < 1e-12);
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
            assert!(
                (b - a).cross(c - a).dot(a + b + c) > 0.0,
                "{t:?} faces inward"
            );
        }
        let mut edges: Vec<(u32, u32)> = mesh
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        // Each directed edge once, and its reverse too: closed, consistently wound.
        assert_eq!(edges.len(), 24);
        assert!(edges
            .iter()
            .all(|&(a, b)| edges.binary_search(&(b, a)).is_ok()));
    }
}
