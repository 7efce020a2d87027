//! Morph a sphere into an ellipsoid with a few correspondences.

use surfrecon_geom::metrics::TriangleBvh;
use surfrecon_geom::shapes::{icosphere, sample_surface};
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_svm::warp::{fit_warp, WarpOptions};
use surfrecon_svm::{fit, FitOptions};

const AXES: DVec3 = DVec3::new(1.3, 1.0, 0.8);

fn ellipsoid() -> TriMesh {
    let mut m = icosphere(DVec3::ZERO, 1.0, 5);
    for v in &mut m.vertices {
        *v *= AXES;
    }
    m.normals = None;
    m
}

#[test]
fn sphere_morphs_onto_an_ellipsoid() {
    let sphere = icosphere(DVec3::ZERO, 1.0, 5);
    let target = ellipsoid();
    let sp = sample_surface(&sphere, 4000, 1);
    let tp = sample_surface(&target, 4000, 2);
    let (f1, r1) = fit(
        &sp.positions,
        sp.normals.as_ref().unwrap(),
        &FitOptions::default(),
    )
    .unwrap();
    let (f2, _) = fit(
        &tp.positions,
        tp.normals.as_ref().unwrap(),
        &FitOptions::default(),
    )
    .unwrap();
    let diag = r1.diameter;
    // Samples on and near the source surface.
    let mut samples = Vec::new();
    for (p, n) in sp
        .positions
        .iter()
        .zip(sp.normals.as_ref().unwrap())
        .step_by(2)
    {
        for t in [-0.03, 0.0, 0.03] {
            samples.push(*p + *n * t);
        }
    }
    let pairs: Vec<(DVec3, DVec3)> = DVec3::AXES
        .iter()
        .flat_map(|a| [*a, -*a])
        .map(|a| (a, a * AXES))
        .collect();
    let (warp, reports) =
        fit_warp(&f1, &f2, &samples, &pairs, diag, &WarpOptions::default()).unwrap();
    for (x, z) in &pairs {
        let moved = *x + warp.displacement(*x);
        assert!(
            moved.distance(*z) < 1e-3 * diag,
            "pair {x} -> {moved}, want {z}; {reports:?}"
        );
    }
    let bvh = TriangleBvh::new(&target);
    let mut worst: f64 = 0.0;
    for v in &sphere.vertices {
        let moved = *v + warp.displacement(*v);
        let d = bvh.closest(moved).unwrap().distance;
        worst = worst.max(d);
    }
    assert!(
        worst < 0.01 * diag,
        "vertex off the target by {:.3}% of the diagonal; {reports:?}",
        100.0 * worst / diag
    );
}
