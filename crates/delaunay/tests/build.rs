//! `bulk_load` on random, degenerate and bad inputs: exact validity,
//! volume equal to the convex hull's, clear errors.

mod common;
use common::*;
use rand::Rng;
use surfrecon_delaunay::{DVec3, DelaunayError, Triangulation};

#[test]
fn uniform_random_points() {
    let points = uniform(20_000, 1);
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, points.len());
    assert_eq!(tri.merged_duplicates(), 0);
    assert_hull_convex(&tri);
    assert_close(tri.volume(), hull_facet_volume(&tri), 1e-12);
    // A random set fills most of the unit cube; ~6.5 tets per point.
    assert!(tri.volume() > 0.95 && tri.volume() < 1.0);
    let per_point = tri.num_tets() as f64 / points.len() as f64;
    assert!((6.0..7.0).contains(&per_point), "{per_point}");
}

#[test]
fn small_random_sets_match_brute_force() {
    for seed in 0..20 {
        let points = uniform(12 + seed as usize * 3, seed);
        let tri = Triangulation::bulk_load(&points).unwrap();
        assert_valid(&tri, points.len());
        assert_globally_delaunay(&tri);
        assert_close(tri.volume(), brute_force_hull_volume(&points), 1e-12);
    }
}

#[test]
fn lattice_20_cubed() {
    let points = lattice(20);
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, points.len());
    assert_hull_convex(&tri);
    // Every tet has integer corners: volumes are exact multiples of 1/6.
    assert_eq!(tri.volume(), 19.0f64.powi(3));
    assert_eq!(hull_facet_volume(&tri), 19.0f64.powi(3));
}

#[test]
fn small_lattice_is_globally_delaunay() {
    let points = lattice(5);
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, points.len());
    assert_globally_delaunay(&tri);
    assert_eq!(tri.volume(), 64.0);
}

#[test]
fn exactly_cospherical_integer_points() {
    // 25² = 625 has many representations as a sum of three squares.
    let points = integer_sphere(625);
    assert_eq!(points.len(), 150);
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, points.len());
    assert_globally_delaunay(&tri);
    assert_hull_convex(&tri);
    assert_close(tri.volume(), hull_facet_volume(&tri), 1e-12);
    assert_eq!(tri.num_hull_facets(), 2 * points.len() - 4);
}

#[test]
fn points_on_a_sphere() {
    let mut r = rng(7);
    let points: Vec<DVec3> = (0..5000)
        .map(|_| {
            let d = DVec3::new(r.random(), r.random(), r.random()) * 2.0 - 1.0;
            d.normalize_or(DVec3::X) * 3.0
        })
        .collect();
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, points.len());
    assert_hull_convex(&tri);
    assert_close(tri.volume(), hull_facet_volume(&tri), 1e-12);
    let ball = 4.0 / 3.0 * std::f64::consts::PI * 27.0;
    assert!(tri.volume() < ball && tri.volume() > 0.98 * ball);
}

#[test]
fn duplicates_are_merged() {
    let mut points = uniform(1000, 3);
    for i in 0..200 {
        points.push(points[i * 3]);
    }
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, 1000);
    assert_eq!(tri.merged_duplicates(), 200);
    for i in 0..200 {
        let copy = tri.vertex_of_input(1000 + i).unwrap();
        let original = tri.vertex_of_input(i * 3).unwrap();
        assert_eq!(copy, original);
        assert!(tri.contains_vertex(copy));
        assert_eq!(tri.point(copy), points[i * 3]);
    }
    // Every vertex maps back to an input point at its position.
    for v in tri.vertices() {
        let i = tri.input_of_vertex(v).unwrap();
        assert_eq!(points[i], tri.point(v));
    }
    let mut lattice_twice = lattice(4);
    lattice_twice.extend(lattice(4));
    let tri = Triangulation::bulk_load(&lattice_twice).unwrap();
    assert_valid(&tri, 64);
    assert_eq!(tri.merged_duplicates(), 64);
    assert_eq!(tri.volume(), 27.0);
}

#[test]
fn near_coplanar_slab() {
    let mut r = rng(11);
    let points: Vec<DVec3> = (0..3000)
        .map(|_| DVec3::new(r.random(), r.random(), r.random::<f64>() * 1e-9))
        .collect();
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, points.len());
    assert_hull_convex(&tri);
    assert_close(tri.volume(), hull_facet_volume(&tri), 1e-9);
    assert!(tri.volume() > 0.0 && tri.volume() < 1e-9);
    let small: Vec<DVec3> = points[..30].to_vec();
    let tri = Triangulation::bulk_load(&small).unwrap();
    assert_valid(&tri, small.len());
    assert_globally_delaunay(&tri);
}

#[test]
fn a_lattice_plane_with_one_point_off_it() {
    let mut points: Vec<DVec3> = lattice(6).into_iter().filter(|p| p.z == 0.0).collect();
    points.push(DVec3::new(2.5, 2.5, 1.0));
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, points.len());
    assert_globally_delaunay(&tri);
    assert_close(tri.volume(), 25.0 / 3.0, 1e-14);
}

#[test]
fn degenerate_inputs_are_errors() {
    let few = [DVec3::ZERO, DVec3::X, DVec3::Y];
    assert_eq!(
        Triangulation::bulk_load(&few).unwrap_err(),
        DelaunayError::TooFewPoints { count: 3 }
    );
    assert_eq!(
        Triangulation::bulk_load(&[]).unwrap_err(),
        DelaunayError::TooFewPoints { count: 0 }
    );
    let same = [DVec3::ONE; 10];
    assert_eq!(
        Triangulation::bulk_load(&same).unwrap_err(),
        DelaunayError::AllIdentical { count: 10 }
    );
    let line: Vec<DVec3> = (0..50).map(|i| DVec3::splat(i as f64 * 0.1)).collect();
    assert_eq!(
        Triangulation::bulk_load(&line).unwrap_err(),
        DelaunayError::AllCollinear { count: 50 }
    );
    // On a line but for rounding: exactly coplanar (y = 2x exactly), not
    // exactly collinear; said to be collinear.
    let rounded: Vec<DVec3> = (0..500)
        .map(|i| DVec3::new(0.1, 0.2, 0.3) * (i as f64 / 499.0))
        .collect();
    assert_eq!(
        Triangulation::bulk_load(&rounded).unwrap_err(),
        DelaunayError::AllCollinear { count: 500 }
    );
    let plane: Vec<DVec3> = lattice(5)
        .into_iter()
        .map(|p| DVec3::new(p.x, p.y, p.x + 2.0 * p.y))
        .collect();
    assert_eq!(
        Triangulation::bulk_load(&plane).unwrap_err(),
        DelaunayError::AllCoplanar { count: 125 }
    );
    let mut bad = uniform(10, 5);
    bad[7].y = f64::NAN;
    assert_eq!(
        Triangulation::bulk_load(&bad).unwrap_err(),
        DelaunayError::NonFinite { index: 7 }
    );
    bad[7].y = f64::INFINITY;
    assert_eq!(
        Triangulation::bulk_load(&bad).unwrap_err(),
        DelaunayError::NonFinite { index: 7 }
    );
}

#[test]
fn four_points_make_one_tetrahedron() {
    let points = [DVec3::ZERO, DVec3::Y, DVec3::X, DVec3::Z];
    let tri = Triangulation::bulk_load(&points).unwrap();
    assert_valid(&tri, 4);
    assert_eq!((tri.num_tets(), tri.num_hull_facets()), (1, 4));
    assert_eq!(tri.volume(), 1.0 / 6.0);
}
