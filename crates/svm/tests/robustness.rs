//! Robustness (the paper's Figure 6 and Figure 4): uniform outliers, and a
//! hole in the sampling.

use rand::{Rng, SeedableRng};
use surfrecon_geom::metrics::topology;
use surfrecon_geom::shapes::{icosphere, sample_surface};
use surfrecon_geom::{DVec3, PointCloud};
use surfrecon_svm::mesh::{mesh_model, MeshOptions};
use surfrecon_svm::{fit, FitOptions, Loss};

/// A sampled sphere plus 5% points uniform in its bounding box, with random
/// unit normals (as a normal estimator would give isolated points).
fn sphere_with_outliers() -> PointCloud {
    let mut pc = sample_surface(&icosphere(DVec3::ZERO, 1.0, 5), 4000, 3);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(17);
    let normals = pc.normals.as_mut().unwrap();
    for _ in 0..200 {
        let p = DVec3::new(rng.random(), rng.random(), rng.random()) * 2.4 - DVec3::splat(1.2);
        let n = DVec3::new(rng.random(), rng.random(), rng.random()) - DVec3::splat(0.5);
        pc.positions.push(p);
        normals.push(n.normalize());
    }
    pc
}

fn components(pc: &PointCloud, loss: Loss, c: f64) -> usize {
    let opts = FitOptions {
        loss,
        c,
        ..Default::default()
    };
    let (model, _) = fit(&pc.positions, pc.normals.as_ref().unwrap(), &opts).unwrap();
    let mesh_opts = MeshOptions {
        resolution: 64,
        ..Default::default()
    };
    // Every input point seeds the surface-following meshing, outliers too,
    // so blobs around them would be found.
    let (mesh, _) = mesh_model(&model, &pc.positions, pc.bounds(), &mesh_opts).unwrap();
    let t = topology(&mesh);
    assert!(t.watertight, "{t:?}");
    t.components
}

#[test]
fn outliers_leave_no_spurious_pieces_with_the_epsilon_insensitive_loss() {
    let pc = sphere_with_outliers();
    assert_eq!(components(&pc, Loss::EpsilonInsensitive, 1.0), 1);
}

#[test]
fn outliers_give_spurious_pieces_with_the_squared_loss() {
    let pc = sphere_with_outliers();
    assert!(components(&pc, Loss::Squared, 1.0) > 1);
}

#[test]
fn a_hole_in_a_sampled_sphere_is_closed_smoothly() {
    let full = sample_surface(&icosphere(DVec3::ZERO, 1.0, 5), 5000, 8);
    // Remove a cap of angular radius ~35° around +z.
    let keep: Vec<usize> = (0..full.len())
        .filter(|&i| full.positions[i].z < 0.82)
        .collect();
    let points: Vec<DVec3> = keep.iter().map(|&i| full.positions[i]).collect();
    let normals: Vec<DVec3> = keep
        .iter()
        .map(|&i| full.normals.as_ref().unwrap()[i])
        .collect();
    let (model, report) = fit(&points, &normals, &FitOptions::default()).unwrap();
    let (mesh, _) = mesh_model(
        &model,
        &points,
        surfrecon_geom::Aabb::from_points(&points),
        &MeshOptions {
            resolution: 64,
            ..Default::default()
        },
    )
    .unwrap();
    let t = topology(&mesh);
    assert!(t.watertight && t.components == 1 && t.euler == 2, "{t:?}");
    // Over the hole the surface stays close to the sphere and is smooth:
    // the zero crossing along the z axis is near z = 1, and normals there
    // point up.
    let top = (0..200)
        .map(|i| 0.8 + i as f64 * 0.002)
        .find(|&z| model.value(DVec3::new(0.0, 0.0, z)) >= 0.0)
        .expect("surface crosses the z axis above the hole");
    assert!(
        (top - 1.0).abs() < 0.05 * report.diameter,
        "crossing at z = {top}"
    );
    for v in mesh.vertices.iter().filter(|v| v.z > 0.9) {
        let n = model.gradient(*v).normalize();
        assert!(n.dot(v.normalize()) > 0.9, "normal {n} at {v}");
    }
}
