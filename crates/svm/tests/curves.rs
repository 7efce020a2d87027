//! Closed surfaces spanning sparse curve networks (Hermite fit of the
//! normals implied at the crossings): the shape between the curves, its
//! topology, and every curve point on the surface.

use std::f64::consts::PI;
use surfrecon_geom::curves::{chain_points, Curve, CurveNetwork};
use surfrecon_geom::metrics::{closest_point_on_triangle, topology};
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_svm::curve_network::{reconstruct_from_curves, CurveFitOptions};

/// Distance from `p` to the nearest triangle of `mesh` (brute force).
fn distance_to_mesh(mesh: &TriMesh, p: DVec3) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let corners = t.map(|i| mesh.vertices[i as usize]);
            p.distance(closest_point_on_triangle(p, corners))
        })
        .fold(f64::INFINITY, f64::min)
}

fn reconstruct(curves: Vec<Curve>) -> TriMesh {
    let network = CurveNetwork::new(curves);
    let options = CurveFitOptions {
        resolution: Some(80),
        ..Default::default()
    };
    reconstruct_from_curves(&network, &options).expect("fit").0
}

#[test]
fn sphere_from_three_great_circles_and_two_latitudes() {
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let o = DVec3::new(1.0, -2.0, 0.5);
    let lat = 0.5f64; // ±30°
    let curves = vec![
        Curve::circle(o, x, y, 1.0, 180),
        Curve::circle(o, y, z, 1.0, 180),
        Curve::circle(o, z, x, 1.0, 180),
        Curve::circle(o + lat.sin() * z, x, y, lat.cos(), 160),
        Curve::circle(o - lat.sin() * z, x, y, lat.cos(), 160),
    ];
    let mesh = reconstruct(curves.clone());
    let topo = topology(&mesh);
    assert!(
        topo.watertight && topo.edge_manifold && topo.vertex_manifold,
        "{topo:?}"
    );
    assert_eq!((topo.components, topo.euler), (1, 2), "{topo:?}");
    for v in &mesh.vertices {
        let r = v.distance(o);
        assert!((r - 1.0).abs() < 0.02, "radius {r} at {v}");
    }
    for p in curves.iter().flat_map(|c| c.points.iter().step_by(10)) {
        assert!(
            distance_to_mesh(&mesh, *p) < 0.01,
            "curve point {p} not reached"
        );
    }
}

/// Torus R = 1, r = 0.35 around z: four meridians and the outer, inner,
/// top and bottom parallels; given as points along the curves, unordered.
#[test]
fn torus_from_eight_cross_section_circles_has_genus_one() {
    let (big, small) = (1.0, 0.35);
    let mut curves = vec![
        Curve::circle(DVec3::ZERO, DVec3::X, DVec3::Y, big + small, 300),
        Curve::circle(DVec3::ZERO, DVec3::X, DVec3::Y, big - small, 200),
        Curve::circle(small * DVec3::Z, DVec3::X, DVec3::Y, big, 250),
        Curve::circle(-small * DVec3::Z, DVec3::X, DVec3::Y, big, 250),
    ];
    for k in 0..4 {
        let a = 0.5 * PI * k as f64 + 0.4;
        let radial = DVec3::new(a.cos(), a.sin(), 0.0);
        curves.push(Curve::circle(big * radial, radial, DVec3::Z, small, 70));
    }
    let mut points: Vec<DVec3> = curves.iter().flat_map(|c| c.points.clone()).collect();
    // Unordered, as a scanner or a segmentation would give them.
    points.sort_by(|a, b| {
        (a.x * 7.3 + a.y * 3.1)
            .sin()
            .total_cmp(&(b.x * 7.3 + b.y * 3.1).sin())
    });
    let chained = chain_points(&points).expect("points along curves");
    assert_eq!(chained.len(), 8);
    let mesh = reconstruct(chained);
    let topo = topology(&mesh);
    assert!(
        topo.watertight && topo.edge_manifold && topo.vertex_manifold,
        "{topo:?}"
    );
    assert_eq!((topo.components, topo.euler), (1, 0), "{topo:?}");
    let torus_distance = |p: DVec3| {
        let ring = big * DVec3::new(p.x, p.y, 0.0).normalize();
        (p.distance(ring) - small).abs()
    };
    let worst = mesh
        .vertices
        .iter()
        .map(|v| torus_distance(*v))
        .fold(0.0, f64::max);
    assert!(worst < 0.05 * small, "vertex {worst} off the torus");
    for p in points.iter().step_by(20) {
        assert!(
            distance_to_mesh(&mesh, *p) < 0.01,
            "curve point {p} not reached"
        );
    }
}

fn reconstruct_with_report(
    curves: Vec<Curve>,
    join_pieces: bool,
) -> (TriMesh, surfrecon_svm::curve_network::CurveFitReport) {
    let network = CurveNetwork::new(curves);
    let options = CurveFitOptions {
        resolution: Some(80),
        join_pieces,
        ..Default::default()
    };
    reconstruct_from_curves(&network, &options).expect("fit")
}

/// A sphere of radius 1 at the origin from its three great circles, as
/// sections by the planes x = 0, y = 0, z = 0.
fn three_circle_sphere(centre: DVec3) -> Vec<Curve> {
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    vec![
        Curve::circle(centre, x, y, 1.0, 180),
        Curve::circle(centre, y, z, 1.0, 180),
        Curve::circle(centre, z, x, 1.0, 180),
    ]
}

/// Sections of one object: a sphere (three great circles) with an ear
/// whose tip two more sections cut (two crossing loops in the planes
/// x = 0.55 and y = 0.55 above the sphere), nothing cutting the ear's
/// stem: the loops are a network of their own, which the fit alone spans
/// with a piece of its own floating above the sphere.
#[test]
fn an_ear_tip_cut_by_its_own_sections_is_joined_to_the_body() {
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let tip = DVec3::new(0.55, 0.55, 1.2);
    let mut curves = three_circle_sphere(DVec3::ZERO);
    curves.push(Curve::circle(tip, y, z, 0.25, 60));
    curves.push(Curve::circle(tip, x, z, 0.25, 60));
    let (apart, _) = reconstruct_with_report(curves.clone(), false);
    assert_eq!(
        topology(&apart).components,
        2,
        "the fit alone leaves the tip apart"
    );

    let (mesh, report) = reconstruct_with_report(curves.clone(), true);
    let topo = topology(&mesh);
    assert!(
        topo.watertight && topo.edge_manifold && topo.vertex_manifold,
        "{topo:?}"
    );
    assert_eq!((topo.components, topo.euler), (1, 2), "{topo:?}");
    let joining = report.joining.expect("joining report");
    assert_eq!((joining.pieces_before, joining.pieces_joined), (2, 1));
    for p in curves.iter().flat_map(|c| c.points.iter().step_by(10)) {
        assert!(
            distance_to_mesh(&mesh, *p) < 0.01,
            "curve point {p} not reached"
        );
    }
    // A neck, not a wire: it is at least a fifth as thick as the tip
    // (0.5 across) where it leaves the sphere's surface.
    let axis = (tip - tip.normalize()).normalize();
    let halfway = tip.normalize() + 0.5 * (tip.length() - 1.25) * axis;
    let across = axis.cross(z).normalize();
    let radius = mesh
        .vertices
        .iter()
        .filter(|v| (**v - halfway).dot(axis).abs() < 0.03)
        .map(|v| (*v - halfway).dot(across).abs())
        .fold(0.0, f64::max);
    assert!(radius > 0.05, "neck radius {radius}");
}

/// Sections of two objects: two spheres side by side, each from its three
/// great circles. The planes y = 0 and z = 0 of both pass through the gap
/// and show no neck there, so the pieces stay apart.
#[test]
fn spheres_whose_section_planes_cross_the_gap_stay_apart() {
    let mut curves = three_circle_sphere(DVec3::ZERO);
    curves.extend(three_circle_sphere(DVec3::new(2.3, 0.0, 0.0)));
    let (mesh, report) = reconstruct_with_report(curves, true);
    assert_eq!(topology(&mesh).components, 2);
    let joining = report.joining.expect("joining report");
    assert_eq!((joining.pieces_joined, joining.pieces_left_apart), (0, 1));
    assert!(!joining.gaps[0].bridged, "{:?}", joining.gaps);
}
