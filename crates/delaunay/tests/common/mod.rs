//! Shared by the Delaunay tests: inputs and independent checks.
#![allow(dead_code)] // each test binary uses its own subset

use rand::{Rng, SeedableRng};
use surfrecon_delaunay::predicates::{insphere, orient3d};
use surfrecon_delaunay::{DVec3, Triangulation, VertexId};

pub fn rng(seed: u64) -> rand_pcg::Pcg64 {
    rand_pcg::Pcg64::seed_from_u64(seed)
}

/// `n` points uniform in the unit cube.
pub fn uniform(n: usize, seed: u64) -> Vec<DVec3> {
    let mut r = rng(seed);
    (0..n)
        .map(|_| DVec3::new(r.random(), r.random(), r.random()))
        .collect()
}

/// The `n³` integer lattice points.
pub fn lattice(n: u32) -> Vec<DVec3> {
    let mut points = Vec::new();
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                points.push(DVec3::new(x as f64, y as f64, z as f64));
            }
        }
    }
    points
}

/// Every integer point with x² + y² + z² = r2: exactly cospherical, with
/// many coplanar cocircular subsets.
pub fn integer_sphere(r2: i64) -> Vec<DVec3> {
    let r = (r2 as f64).sqrt() as i64 + 1;
    let mut points = Vec::new();
    for x in -r..=r {
        for y in -r..=r {
            for z in -r..=r {
                if x * x + y * y + z * z == r2 {
                    points.push(DVec3::new(x as f64, y as f64, z as f64));
                }
            }
        }
    }
    points
}

/// Validity (exact) plus the vertex count.
pub fn assert_valid(tri: &Triangulation, vertices: usize) {
    if let Err(e) = tri.validate() {
        panic!("invalid triangulation: {e}");
    }
    assert_eq!(tri.num_vertices(), vertices);
    assert_eq!(tri.vertices().count(), vertices);
}

/// The empty-sphere property against every vertex, by brute force.
pub fn assert_globally_delaunay(tri: &Triangulation) {
    let vertices: Vec<VertexId> = tri.vertices().collect();
    for t in tri.finite_tets() {
        let [a, b, c, d] = tri.tet_points(t);
        for &v in &vertices {
            let s = insphere(a, b, c, d, tri.point(v));
            assert!(s <= 0.0, "vertex {v:?} inside the circumsphere of {t:?}");
        }
    }
}

/// Every vertex on the inner side (or on the plane) of every hull facet:
/// the hull facets bound a convex set containing all points.
pub fn assert_hull_convex(tri: &Triangulation) {
    let vertices: Vec<VertexId> = tri.vertices().collect();
    for [a, b, c] in tri.hull_facets() {
        let (pa, pb, pc) = (tri.point(a), tri.point(b), tri.point(c));
        for &v in &vertices {
            assert!(
                orient3d(pa, pb, pc, tri.point(v)) <= 0.0,
                "{v:?} beyond hull facet {a:?} {b:?} {c:?}"
            );
        }
    }
}

/// Volume enclosed by the hull facets (cones to an inner point).
pub fn hull_facet_volume(tri: &Triangulation) -> f64 {
    let inner = tri.vertices().map(|v| tri.point(v)).sum::<DVec3>() / tri.num_vertices() as f64;
    let six_volume: f64 = tri
        .hull_facets()
        .map(|[a, b, c]| {
            let (pa, pb, pc) = (tri.point(a), tri.point(b), tri.point(c));
            (pb - pa).cross(pc - pa).dot(pa - inner)
        })
        .sum();
    six_volume / 6.0
}

/// Convex hull volume by brute force, for points in general position: a
/// triple is a hull facet when all other points are on one side of it.
pub fn brute_force_hull_volume(points: &[DVec3]) -> f64 {
    let inner = points.iter().sum::<DVec3>() / points.len() as f64;
    let n = points.len();
    let mut volume = 0.0;
    for i in 0..n {
        for j in (i + 1)..n {
            for k in (j + 1)..n {
                let (a, b, c) = (points[i], points[j], points[k]);
                let (mut pos, mut neg) = (false, false);
                for &p in points {
                    let o = orient3d(a, b, c, p);
                    pos |= o > 0.0;
                    neg |= o < 0.0;
                }
                if pos != neg {
                    volume += (b - a).cross(c - a).dot(a - inner).abs() / 6.0;
                }
            }
        }
    }
    volume
}

pub fn assert_close(a: f64, b: f64, rel: f64) {
    assert!((a - b).abs() <= rel * a.abs().max(b.abs()), "{a} vs {b}");
}
