//! Insertion after `bulk_load`, vertex removal and point location keep the
//! triangulation exactly valid and Delaunay.

mod common;
use common::*;
use rand::seq::SliceRandom;
use rand::Rng;
use surfrecon_delaunay::predicates::orient3d;
use surfrecon_delaunay::{DVec3, DelaunayError, Location, Triangulation, VertexId};

#[test]
fn insert_inside_and_outside_the_hull() {
    let points = uniform(2000, 21);
    let mut tri = Triangulation::bulk_load(&points).unwrap();
    let mut r = rng(22);
    let mut added = Vec::new();
    for _ in 0..500 {
        // Half of them outside the unit cube: the hull grows.
        let p = DVec3::new(r.random(), r.random(), r.random()) * 1.5 - 0.25;
        added.push(tri.insert(p).unwrap());
    }
    assert_valid(&tri, 2500);
    assert_hull_convex(&tri);
    assert_close(tri.volume(), hull_facet_volume(&tri), 1e-12);
    for &v in &added {
        assert!(tri.contains_vertex(v));
    }
    // A duplicate returns the existing vertex and changes nothing.
    let tets = tri.num_tets();
    assert_eq!(tri.insert(tri.point(added[7])).unwrap(), added[7]);
    assert_eq!(
        tri.insert(points[3]).unwrap(),
        tri.vertex_of_input(3).unwrap()
    );
    assert_eq!((tri.num_tets(), tri.num_vertices()), (tets, 2500));
    assert_eq!(
        tri.insert(DVec3::new(f64::NAN, 0.0, 0.0)).unwrap_err(),
        DelaunayError::NonFinite { index: 2500 }
    );
    assert_valid(&tri, 2500);
}

#[test]
fn insert_on_a_lattice_keeps_it_valid() {
    let mut tri = Triangulation::bulk_load(&lattice(6)).unwrap();
    // Face centres, edge midpoints and points on hull faces: all degenerate.
    for p in [
        DVec3::splat(2.5),
        DVec3::new(2.5, 0.0, 2.5),
        DVec3::new(0.0, 2.5, 0.0),
        DVec3::new(5.0, 1.5, 2.0),
    ] {
        tri.insert(p).unwrap();
    }
    for z in 0..6 {
        tri.insert(DVec3::new(6.0, 2.0, z as f64)).unwrap();
    }
    assert_valid(&tri, 216 + 10);
    assert_globally_delaunay(&tri);
    // The cube plus the wedge from its face x = 5 to the segment x = 6,
    // y = 2: cross-section 5 · 1 / 2, length 5.
    assert_close(tri.volume(), 125.0 + 2.5 * 5.0, 1e-12);
}

#[test]
fn remove_random_vertices() {
    let points = uniform(1500, 31);
    let mut tri = Triangulation::bulk_load(&points).unwrap();
    let mut vertices: Vec<VertexId> = tri.vertices().collect();
    vertices.shuffle(&mut rng(32));
    for (k, &v) in vertices[..600].iter().enumerate() {
        tri.remove(v).unwrap();
        if k % 100 == 0 {
            assert_valid(&tri, 1500 - k - 1);
        }
    }
    assert_valid(&tri, 900);
    assert_globally_delaunay(&tri);
    assert_hull_convex(&tri);
    let kept: Vec<DVec3> = vertices[600..].iter().map(|&v| tri.point(v)).collect();
    let fresh = Triangulation::bulk_load(&kept).unwrap();
    assert_eq!(tri.num_tets(), fresh.num_tets());
    assert_close(tri.volume(), fresh.volume(), 1e-12);
    assert_eq!(
        tri.remove(vertices[0]).unwrap_err(),
        DelaunayError::UnknownVertex(vertices[0].0)
    );
    assert!(tri.remove(VertexId::INFINITE).is_err());
}

#[test]
fn remove_then_reinsert_restores_the_count() {
    let points = uniform(3000, 41);
    let mut tri = Triangulation::bulk_load(&points).unwrap();
    let (tets, facets) = (tri.num_tets(), tri.num_hull_facets());
    for i in (0..3000).step_by(7) {
        let v = tri.vertex_of_input(i).unwrap();
        let p = tri.point(v);
        tri.remove(v).unwrap();
        assert_eq!(tri.num_vertices(), 2999);
        tri.insert(p).unwrap();
        assert_eq!(
            (tri.num_tets(), tri.num_hull_facets()),
            (tets, facets),
            "input {i}"
        );
    }
    assert_valid(&tri, 3000);
}

#[test]
fn remove_on_degenerate_inputs() {
    // Lattice: every star is cospherical; hull vertices included.
    let mut tri = Triangulation::bulk_load(&lattice(5)).unwrap();
    let mut vertices: Vec<VertexId> = tri.vertices().collect();
    vertices.shuffle(&mut rng(51));
    for &v in &vertices[..60] {
        tri.remove(v).unwrap();
    }
    assert_valid(&tri, 65);
    assert_globally_delaunay(&tri);
    assert_hull_convex(&tri);
    assert_close(tri.volume(), hull_facet_volume(&tri), 1e-12);

    // Exactly cospherical points.
    let points = integer_sphere(625);
    let mut tri = Triangulation::bulk_load(&points).unwrap();
    for i in (0..points.len()).step_by(3) {
        tri.remove(tri.vertex_of_input(i).unwrap()).unwrap();
    }
    assert_valid(&tri, points.len() - points.len().div_ceil(3));
    assert_globally_delaunay(&tri);
}

#[test]
fn removing_the_apex_over_a_flat_set() {
    // A plane of lattice points, one apex below and one above it: removing
    // the top apex leaves a flat hull face (a hole of no volume).
    let mut points: Vec<DVec3> = lattice(5).into_iter().filter(|p| p.z == 0.0).collect();
    points.push(DVec3::new(2.0, 2.0, 1.0));
    points.push(DVec3::new(1.5, 2.5, -1.0));
    let mut tri = Triangulation::bulk_load(&points).unwrap();
    let top = tri.vertex_of_input(25).unwrap();
    tri.remove(top).unwrap();
    assert_valid(&tri, 26);
    assert_globally_delaunay(&tri);
    assert_close(tri.volume(), 16.0 / 3.0, 1e-14);
    // Removing the other apex too would leave only coplanar points.
    let bottom = tri.vertex_of_input(26).unwrap();
    assert_eq!(
        tri.remove(bottom).unwrap_err(),
        DelaunayError::RemovalWouldFlatten(bottom.0)
    );
    assert_valid(&tri, 26);
}

#[test]
fn locate_finds_the_containing_tetrahedron() {
    let points = uniform(5000, 61);
    let tri = Triangulation::bulk_load(&points).unwrap();
    let mut r = rng(62);
    for _ in 0..2000 {
        let p = DVec3::new(r.random(), r.random(), r.random()) * 1.2 - 0.1;
        match tri.locate(p).unwrap() {
            Location::Inside(t) => {
                assert!(!tri.is_ghost(t));
                for i in 0..4 {
                    let [a, b, c] = tri.facet(t, i).map(|v| tri.point(v));
                    assert!(orient3d(a, b, c, p) >= 0.0);
                }
            }
            Location::Outside(t) => {
                assert!(tri.is_ghost(t));
                let [a, b, c] = tri.tet_vertices(t)[..3].try_into().unwrap();
                assert!(orient3d(tri.point(a), tri.point(b), tri.point(c), p) > 0.0);
            }
        }
    }
    assert!(tri.locate(DVec3::splat(f64::INFINITY)).is_err());
}

#[test]
fn incident_tets_and_neighbors_agree_with_a_scan() {
    let points = uniform(800, 71);
    let tri = Triangulation::bulk_load(&points).unwrap();
    let all: Vec<_> = tri.finite_tets().chain(tri.ghost_tets()).collect();
    for v in tri.vertices().step_by(13) {
        let mut found = tri.incident_tets(v);
        found.sort();
        let mut scanned: Vec<_> = all
            .iter()
            .copied()
            .filter(|&t| tri.tet_vertices(t).contains(&v))
            .collect();
        scanned.sort();
        assert_eq!(found, scanned);
    }
    for &t in &all {
        for (i, n) in tri.neighbors(t).into_iter().enumerate() {
            let (back, j) = tri.mirror(t, i);
            assert_eq!(back, n);
            assert_eq!(tri.mirror(n, j).0, t);
        }
    }
}

/// With change tracking on, the tetrahedra live after an edit are exactly
/// those live before, minus the freed ones, plus the created ones (a slot
/// freed and reused counts as created); the freed ones around an inserted
/// point all had it in their circumsphere.
#[test]
fn tracked_changes_account_for_every_tetrahedron() {
    use std::collections::BTreeSet;
    let points = uniform(1500, 31);
    let mut tri = Triangulation::bulk_load(&points).unwrap();
    let live = |tri: &Triangulation| -> BTreeSet<u32> {
        tri.finite_tets()
            .chain(tri.ghost_tets())
            .map(|t| t.0)
            .collect()
    };
    assert!(tri.take_changes().created.is_empty(), "off by default");
    tri.track_changes(true);
    let mut r = rng(32);
    for step in 0..200 {
        let before = live(&tri);
        if step % 3 == 2 {
            let v = tri.vertices().nth(r.random_range(0..1000)).unwrap();
            tri.remove(v).unwrap();
        } else {
            let p = DVec3::new(r.random(), r.random(), r.random()) * 1.2 - 0.1;
            tri.insert(p).unwrap();
        }
        let changes = tri.take_changes();
        assert!(!changes.freed.is_empty() && !changes.created.is_empty());
        let mut expected: BTreeSet<u32> = before;
        for t in &changes.freed {
            assert!(expected.remove(&t.0), "freed a dead tetrahedron");
        }
        for t in &changes.created {
            assert!(expected.insert(t.0), "created twice");
            assert!(tri.is_live(*t));
        }
        assert_eq!(expected, live(&tri), "step {step}");
    }
    assert_valid(&tri, tri.num_vertices());
    assert!(tri.take_changes().freed.is_empty(), "taken");
}

/// `nearest_vertex` (and `nearest_vertex_from` any vertex) agrees with a
/// brute-force search, for queries inside
/// and outside the hull, on random points and on a lattice (ties: any of
/// the nearest), and after removals.
#[test]
fn nearest_vertex_matches_brute_force() {
    for points in [uniform(3000, 31), lattice(9)] {
        let mut tri = Triangulation::bulk_load(&points).unwrap();
        for (k, v) in tri.vertices().collect::<Vec<_>>().into_iter().enumerate() {
            if k % 3 == 0 {
                tri.remove(v).unwrap();
            }
        }
        let scale = points.iter().fold(0.0f64, |m, p| m.max(p.max_element()));
        let mut r = rng(32);
        for _ in 0..2000 {
            let q = DVec3::new(r.random(), r.random(), r.random()) * 1.6 * scale - 0.3 * scale;
            let v = tri.nearest_vertex(q).unwrap();
            assert!(tri.contains_vertex(v));
            let best = tri
                .vertices()
                .map(|w| tri.point(w).distance(q))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(tri.point(v).distance(q), best, "query {q}");
            // From any start vertex (the walk crosses the whole set).
            let start = tri
                .vertices()
                .nth(r.random_range(0..tri.num_vertices()))
                .unwrap();
            let w = tri.nearest_vertex_from(q, start).unwrap();
            assert_eq!(tri.point(w).distance(q), best, "query {q} from {start:?}");
        }
    }
}

/// Points inserted far outside the box of the loaded points (the box the
/// predicates' static error bounds are computed for), on lattices whose
/// coordinates are not exact in binary, so rounding matters in the many
/// coplanar and cospherical tests: the result stays exactly valid and
/// Delaunay, so the bounds grew with the box.
#[test]
fn insert_far_outside_the_loaded_box_on_lattices() {
    let small: Vec<DVec3> = lattice(4).iter().map(|&p| p * 0.1).collect();
    let mut tri = Triangulation::bulk_load(&small).unwrap();
    for p in lattice(4) {
        tri.insert(p * 70.1 + DVec3::splat(0.3)).unwrap();
    }
    for p in lattice(3) {
        tri.insert(p * -0.7 - DVec3::splat(0.1)).unwrap();
    }
    assert_valid(&tri, 64 + 64 + 27);
    assert_globally_delaunay(&tri);
}

/// A point at the centre of points on a sphere is in conflict with every
/// tetrahedron: the hole is the whole hull, its rim every vertex. With 100
/// vertices the new tetrahedra are glued through the rim's local numbers,
/// with 600 (over their limit of 256) through the edge table; either way
/// the result is the cone from the centre over the hull.
#[test]
fn holes_with_large_rims_are_filled() {
    for n in [100, 600] {
        let mut r = rng(n as u64);
        let points: Vec<DVec3> = (0..n)
            .map(|_| {
                let p = DVec3::new(r.random(), r.random(), r.random()) * 2.0 - 1.0;
                p.normalize()
            })
            .collect();
        let mut tri = Triangulation::bulk_load(&points).unwrap();
        let hull = tri.num_hull_facets();
        tri.insert(DVec3::ZERO).unwrap();
        assert_valid(&tri, n + 1);
        assert_globally_delaunay(&tri);
        assert_eq!((tri.num_tets(), tri.num_hull_facets()), (hull, hull), "{n}");
    }
}
