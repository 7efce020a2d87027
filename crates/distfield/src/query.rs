//! Exact queries against the source mesh: signed distance at any point and
//! the first surface hit along a grid axis. A thin layer over parry's
//! bounding-volume tree (closest points, ray casts) and its angle-weighted
//! pseudo-normals (inside test), which are exact for closed, consistently
//! oriented meshes.

use crate::DistFieldError;
use parry3d_f64::query::{PointQuery, Ray, RayCast};
use parry3d_f64::shape::{TriMesh as ParryMesh, TriMeshFlags};
use surfrecon_geom::{DVec3, TriMesh};

/// A closed triangle mesh prepared for exact distance queries.
pub struct MeshQuery {
    mesh: ParryMesh,
}

fn to_parry(v: DVec3) -> parry3d_f64::math::Vector {
    parry3d_f64::math::Vector::new(v.x, v.y, v.z)
}

impl MeshQuery {
    /// Index the triangles of `mesh` (which must be closed and oriented
    /// outwards for signs to be right; see [`crate::check_mesh`]).
    pub fn new(mesh: &TriMesh) -> Result<Self, DistFieldError> {
        let vertices = mesh.vertices.iter().map(|&v| to_parry(v)).collect();
        let mesh = ParryMesh::with_flags(vertices, mesh.triangles.clone(), TriMeshFlags::ORIENTED)
            .map_err(|e| {
                DistFieldError::InvalidMesh(format!("cannot index the triangles: {e:?}"))
            })?;
        Ok(Self { mesh })
    }

    /// Signed distance to the surface at `p`, negative inside.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        let proj = self.mesh.project_local_point(to_parry(p), false);
        let q = proj.point;
        let d = DVec3::new(q.x, q.y, q.z).distance(p);
        if proj.is_inside {
            -d
        } else {
            d
        }
    }

    /// The closest point of the surface to `p`.
    pub fn closest_point(&self, p: DVec3) -> DVec3 {
        let q = self.mesh.project_local_point(to_parry(p), false).point;
        DVec3::new(q.x, q.y, q.z)
    }

    /// Distance from `p` along `+axis` to the first surface point, if one
    /// lies within `max`.
    pub fn hit_along(&self, p: DVec3, axis: usize, max: f64) -> Option<f64> {
        let mut dir = DVec3::ZERO;
        dir[axis] = 1.0;
        let ray = Ray::new(to_parry(p), to_parry(dir));
        self.mesh.cast_local_ray(&ray, max, false)
    }

    /// Like [`Self::hit_along`], with the unit normal of the triangle hit
    /// (either way round: parry turns it towards the ray's origin).
    pub fn hit_with_normal(&self, p: DVec3, axis: usize, max: f64) -> Option<(f64, DVec3)> {
        let mut dir = DVec3::ZERO;
        dir[axis] = 1.0;
        let ray = Ray::new(to_parry(p), to_parry(dir));
        let hit = self.mesh.cast_local_ray_and_get_normal(&ray, max, false)?;
        let n = DVec3::new(hit.normal.x, hit.normal.y, hit.normal.z);
        Some((hit.time_of_impact, n.normalize_or_zero()))
    }
}

/// The `side (side + 1) / 2` points of a fixed barycentric lattice inside
/// a triangle (the same for every triangle, none on its edges): where
/// surfaces are measured against each other.
pub fn lattice_points([a, b, c]: [DVec3; 3], side: usize) -> impl Iterator<Item = DVec3> + Clone {
    let n = side as f64;
    (0..side).flat_map(move |i| {
        (0..side - i).map(move |j| {
            let (u, v) = ((i as f64 + 1.0 / 3.0) / n, (j as f64 + 1.0 / 3.0) / n);
            a + (b - a) * u + (c - a) * v
        })
    })
}

/// How far one surface strays from another, sampled at its vertices and
/// at interior points of every triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deviation {
    pub max: f64,
    pub mean: f64,
    /// The sample where the distance is largest.
    pub worst: DVec3,
}

/// Distances from `from` (its vertices and about `per_triangle` points
/// inside each triangle) to the surface `to`: exact point-to-triangle
/// distances.
pub fn deviation(from: &TriMesh, to: &MeshQuery, per_triangle: usize) -> Deviation {
    use rayon::prelude::*;
    let side = (per_triangle as f64).sqrt().ceil().max(1.0) as usize;
    let inner = (0..from.triangles.len())
        .into_par_iter()
        .flat_map_iter(|t| lattice_points(from.corners(t), side));
    let (max, worst, sum, n) = from
        .vertices
        .par_iter()
        .copied()
        .chain(inner)
        .map(|p| (to.signed_distance(p).abs(), p))
        .fold(
            || (0.0f64, DVec3::ZERO, 0.0, 0usize),
            |(m, w, s, n), (d, p)| {
                if d > m {
                    (d, p, s + d, n + 1)
                } else {
                    (m, w, s + d, n + 1)
                }
            },
        )
        .reduce(
            || (0.0, DVec3::ZERO, 0.0, 0),
            |a, b| {
                let (m, w) = if b.0 > a.0 { (b.0, b.1) } else { (a.0, a.1) };
                (m, w, a.2 + b.2, a.3 + b.3)
            },
        );
    Deviation {
        max,
        mean: sum / n.max(1) as f64,
        worst,
    }
}
