//! Bad and degenerate inputs give a clear error or a documented result.

use surfrecon_convection::{reconstruct, ConvectionError, Params};
use surfrecon_delaunay::DelaunayError;
use surfrecon_geom::metrics::topology;
use surfrecon_geom::DVec3;

fn cube_corners() -> Vec<DVec3> {
    (0..8)
        .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect()
}

#[test]
fn too_few_points_is_an_error() {
    let points = &cube_corners()[..3];
    let e = reconstruct(points, None, &Params::default()).unwrap_err();
    assert!(matches!(
        e,
        ConvectionError::Delaunay(DelaunayError::TooFewPoints { count: 3 })
    ));
}

#[test]
fn coplanar_and_collinear_points_are_errors() {
    let plane: Vec<DVec3> = (0..50)
        .map(|i| DVec3::new((i % 7) as f64, (i / 7) as f64, 2.0))
        .collect();
    let e = reconstruct(&plane, None, &Params::default()).unwrap_err();
    assert!(
        matches!(
            e,
            ConvectionError::Delaunay(DelaunayError::AllCoplanar { .. })
        ),
        "{e}"
    );
    let line: Vec<DVec3> = (0..10).map(|i| DVec3::splat(i as f64)).collect();
    let e = reconstruct(&line, None, &Params::default()).unwrap_err();
    assert!(
        matches!(
            e,
            ConvectionError::Delaunay(DelaunayError::AllCollinear { .. })
        ),
        "{e}"
    );
}

#[test]
fn non_finite_points_and_bad_normals_are_errors() {
    let mut points = cube_corners();
    let normals = vec![DVec3::Z; 7];
    let e = reconstruct(&points, Some(&normals), &Params::default()).unwrap_err();
    assert_eq!(
        e,
        ConvectionError::NormalCount {
            points: 8,
            normals: 7
        }
    );
    let mut normals = vec![DVec3::Z; 8];
    normals[5] = DVec3::ZERO;
    let e = reconstruct(&points, Some(&normals), &Params::default()).unwrap_err();
    assert_eq!(e, ConvectionError::BadNormal { index: 5 });
    points[2].y = f64::NAN;
    let e = reconstruct(&points, None, &Params::default()).unwrap_err();
    assert!(matches!(
        e,
        ConvectionError::Delaunay(DelaunayError::NonFinite { index: 2 })
    ));
}

/// A cube's corners (cospherical, all on the hull) with every point given
/// twice: duplicates are merged, the hull is the closed result.
#[test]
fn duplicated_cube_corners_give_the_closed_hull() {
    let mut points = cube_corners();
    points.extend(cube_corners());
    let r = reconstruct(&points, None, &Params::default()).unwrap();
    assert_eq!(r.report.duplicates, 8);
    assert_eq!(r.report.kept_points, 8);
    let topo = topology(&r.mesh);
    assert!(topo.watertight && topo.vertex_manifold, "{topo:?}");
    assert_eq!((topo.faces, topo.euler), (12, 2));
    // One copy of each corner is used.
    let mut used: Vec<u32> = r.mesh.triangles.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let mut corners: Vec<[i64; 3]> = used
        .iter()
        .map(|&v| r.mesh.vertices[v as usize].to_array().map(|x| x as i64))
        .collect();
    corners.sort_unstable();
    corners.dedup();
    assert_eq!(corners.len(), 8);
}

/// Many copies of each corner: the neighbours of a corner are its own
/// copies, so normals and spacing must come from the distinct points (with
/// them taken per copy, ten copies gave a tetrahedron, fifty no surface).
#[test]
fn many_copies_of_the_cube_corners_give_the_closed_hull() {
    for copies in [10, 50] {
        let points: Vec<DVec3> = (0..copies).flat_map(|_| cube_corners()).collect();
        let r = reconstruct(&points, None, &Params::default()).unwrap();
        assert_eq!(r.report.duplicates, 8 * (copies - 1), "{copies}");
        assert_eq!(r.report.kept_points, 8, "{copies}");
        let topo = topology(&r.mesh);
        assert!(
            topo.watertight && topo.vertex_manifold,
            "{copies}: {topo:?}"
        );
        assert_eq!((topo.faces, topo.euler), (12, 2), "{copies}");
    }
}

#[test]
fn decimation_settings_out_of_range_are_errors() {
    for (rho, rho_topo) in [(1.5, 0.95), (f64::NAN, 0.95), (-0.1, 0.95), (0.01, 2.0)] {
        let params = Params {
            rho,
            rho_topo,
            ..Params::default()
        };
        let e = reconstruct(&cube_corners(), None, &params).unwrap_err();
        assert!(matches!(e, ConvectionError::BadParameter { .. }), "{e}");
    }
    // Decimating coplanar points still reports the flat input.
    let plane: Vec<DVec3> = (0..50)
        .map(|i| DVec3::new((i % 7) as f64, (i / 7) as f64, 2.0))
        .collect();
    let params = Params {
        rho: 0.2,
        ..Params::default()
    };
    assert!(matches!(
        reconstruct(&plane, None, &params).unwrap_err(),
        ConvectionError::Delaunay(_)
    ));
}

/// Refinement settings out of range, or refinement without decimation
/// (nothing to put back), are errors rather than silently ignored.
#[test]
fn refinement_settings_out_of_range_are_errors() {
    for (rho, refine_alpha, refine_gamma) in [
        (0.01, -1.0, 0.0),
        (0.01, f64::NAN, 0.0),
        (0.01, f64::INFINITY, 0.0),
        (0.01, 0.0, 1.5),
        (0.01, 0.0, f64::NAN),
        (0.0, 1.0, 0.0),
        (0.0, 0.0, 0.5),
    ] {
        let params = Params {
            rho,
            refine_alpha,
            refine_gamma,
            ..Params::default()
        };
        let e = reconstruct(&cube_corners(), None, &params).unwrap_err();
        assert!(matches!(e, ConvectionError::BadParameter { .. }), "{e}");
    }
}
