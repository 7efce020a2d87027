//! Convection on sampled closed shapes: the mesh goes through the input
//! points, is a closed 2-manifold of the right genus where the sampling is
//! dense, and lies close to the true surface.

use surfrecon_convection::{reconstruct, Params, Reconstruction};
use surfrecon_geom::metrics::{evaluate, topology, EvalOptions, Surface};
use surfrecon_geom::shapes::{icosphere, sample_surface, torus};
use surfrecon_geom::{DVec3, TriMesh};

fn run(points: &[DVec3]) -> Reconstruction {
    reconstruct(points, None, &Params::default()).unwrap()
}

/// Chamfer L1 between the reconstruction and the true surface, relative to
/// the true surface's bounding-box diagonal.
fn relative_chamfer(mesh: &TriMesh, truth: &TriMesh) -> f64 {
    let options = EvalOptions {
        samples: 20_000,
        seed: 3,
    };
    let r = evaluate(
        &Surface::Mesh(mesh.clone()),
        &Surface::Mesh(truth.clone()),
        &options,
    )
    .unwrap();
    r.chamfer_l1 / r.diagonal
}

fn assert_closed_genus(r: &Reconstruction, points: usize, genus: i64) {
    let topo = topology(&r.mesh);
    eprintln!("{:?}\n{:?}", r.report, topo);
    assert_eq!(
        r.mesh.vertices.len(),
        points,
        "vertices are the input points"
    );
    assert!(topo.watertight && topo.vertex_manifold, "{topo:?}");
    assert_eq!(topo.components, 1);
    assert_eq!(topo.euler, 2 - 2 * genus);
    assert_eq!(r.report.boundary_edges, 0);
}

#[test]
fn sampled_sphere_is_a_closed_sphere_through_the_points() {
    let truth = icosphere(DVec3::ZERO, 1.0, 5);
    let points = sample_surface(&truth, 5000, 1).positions;
    let r = run(&points);
    assert_closed_genus(&r, points.len(), 0);
    // Interpolating: every sample kept on a dense sphere.
    assert_eq!(r.report.kept_points, points.len());
    let cd = relative_chamfer(&r.mesh, &truth);
    assert!(cd < 2e-3, "chamfer {cd}");
}

#[test]
fn sampled_torus_has_genus_one() {
    let truth = torus(1.0, 0.35, 160, 64);
    let points = sample_surface(&truth, 8000, 2).positions;
    let r = run(&points);
    assert_closed_genus(&r, points.len(), 1);
    let cd = relative_chamfer(&r.mesh, &truth);
    assert!(cd < 2e-3, "chamfer {cd}");
}
