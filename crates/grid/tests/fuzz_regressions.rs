//! Inputs found by the structured fuzz targets (`fuzz/`, target
//! `distance`), replayed.

use surfrecon_geom::shapes::icosphere;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::distance::{unsigned_distance_with, DataSet, DistanceOptions};
use surfrecon_grid::sdf::signed_distance;
use surfrecon_grid::{GridSize, GridSpec};

/// The fuzzer's mesh: a once-subdivided icosphere stretched by
/// (3.5, 0.5, 3) and scaled by `scale`.
fn stretched_sphere(scale: f64) -> TriMesh {
    let mut mesh = icosphere(DVec3::ZERO, 1.0, 1);
    for v in &mut mesh.vertices {
        *v *= DVec3::new(3.5, 0.5, 3.0) * scale;
    }
    mesh
}

fn grid(mesh: &TriMesh, resolution: usize, padding: usize) -> GridSpec<3> {
    let bounds = surfrecon_geom::Aabb::from_points(&mesh.vertices);
    let (lo, hi) = (bounds.min.to_array(), bounds.max.to_array());
    GridSpec::from_bounds(lo, hi, GridSize::Resolution(resolution), padding).unwrap()
}

/// Inside a convex mesh: behind every face.
fn inside_convex(mesh: &TriMesh, p: DVec3) -> bool {
    mesh.triangles.iter().all(|t| {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        (b - a).cross(c - a).dot(p - a) < 0.0
    })
}

/// Around 1e150 the winding numbers' triple products overflowed and the
/// signs came out wrong (node 44 of this 5 x 2 x 5 grid, well outside the
/// mesh, was signed inside). Fixed by computing on a copy scaled by a power
/// of two: the field must be the unit-sized one times the scale, and every
/// node off the surface signed by the convex inside test.
#[test]
fn signed_distance_of_huge_and_tiny_meshes_matches_the_unit_sized_one() {
    let unit = stretched_sphere(1.0);
    let unit_field = signed_distance(&unit, &grid(&unit, 4, 0), None).unwrap();
    for scale in [1e150, 1e-200, 1e300] {
        let mesh = stretched_sphere(scale);
        let spec = grid(&mesh, 4, 0);
        assert_eq!(spec.dims, [5, 2, 5], "the fuzzer's grid");
        let field = signed_distance(&mesh, &spec, None).unwrap();
        for (node, (&v, &u)) in field.values.iter().zip(&unit_field.values).enumerate() {
            let p = DVec3::from_array(spec.position(spec.unlinear(node)));
            assert!(
                (v / scale - u).abs() <= 1e-9 * u.abs().max(1.0),
                "scale {scale:e}, node {node}: {v:e} against {u} at unit size"
            );
            if u.abs() > 1e-9 {
                assert_eq!(
                    v < 0.0,
                    inside_convex(&mesh, p),
                    "scale {scale:e}, node {node}"
                );
            }
        }
    }
}

/// Unsigned distances in 2D and 3D at 1e150 and 1e-200: brute force
/// agrees at every node (squared distances used to overflow or underflow).
#[test]
fn unsigned_distance_at_extreme_scales_matches_brute_force() {
    let unit = DataSet::<3> {
        points: vec![[0.0, 0.0, 0.0], [1.0, 0.5, 0.0], [0.25, 1.0, 0.75]],
        segments: vec![[[0.0, 1.0, 0.0], [1.0, 1.0, 1.0]]],
        triangles: vec![[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 0.5, 1.0]]],
    };
    let times = |p: &[f64; 3], s: f64| p.map(|c| c * s);
    for scale in [1.0, 1e150, 1e-200] {
        let data = DataSet::<3> {
            points: unit.points.iter().map(|p| times(p, scale)).collect(),
            segments: unit
                .segments
                .iter()
                .map(|g| g.each_ref().map(|p| times(p, scale)))
                .collect(),
            triangles: unit
                .triangles
                .iter()
                .map(|t| t.each_ref().map(|p| times(p, scale)))
                .collect(),
        };
        let (lo, hi) = data.bounds().unwrap();
        let spec = GridSpec::from_bounds(lo, hi, GridSize::Resolution(6), 2).unwrap();
        let field = unsigned_distance_with(&data, &spec, &DistanceOptions::default()).unwrap();
        for (node, &v) in field.field.values.iter().enumerate() {
            let p = times(&spec.position(spec.unlinear(node)), 1.0 / scale);
            let exact = (0..unit.len())
                .map(|i| unit.distance(i, &p) * scale)
                .fold(f64::INFINITY, f64::min);
            // Rounding of node positions: relative to the data's size.
            let tol = 1e-12 * scale;
            assert!(
                v >= exact - tol && v <= exact + 0.2 * spec.spacing + tol,
                "scale {scale:e}, node {node}: {v:e} against {exact:e}"
            );
        }
    }
}
