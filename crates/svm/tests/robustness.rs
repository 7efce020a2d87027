//! Robustness (the paper's Figure 6 and Figure 4): uniform outliers, noise,
//! and a hole in the sampling.

use rand::{Rng, SeedableRng};
use surfrecon_geom::metrics::{evaluate, topology, EvalOptions, Surface};
use surfrecon_geom::shapes::{icosphere, sample_surface};
use surfrecon_geom::{DVec3, PointCloud};
use surfrecon_svm::mesh::{mesh_model, MeshOptions};
use surfrecon_svm::{fit, FitOptions, FitReport, Loss};

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

/// Components of the mesh of a fit with `loss` alone: the sample checks
/// (isolated samples, consistency with coarser levels) are off, so the two
/// losses see the same training data, as in the paper's comparison.
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

/// A closed, bumpy, bunny-sized test shape: a sphere whose radius varies
/// with direction, r(u) = 1 + 0.25 u_x u_y + 0.2 u_z², sampled with its
/// exact normals.
fn blob() -> surfrecon_geom::TriMesh {
    let mut mesh = icosphere(DVec3::ZERO, 1.0, 5);
    for v in &mut mesh.vertices {
        let u = v.normalize();
        *v = u * (1.0 + 0.25 * u.x * u.y + 0.2 * u.z * u.z);
    }
    mesh.normals = None;
    mesh
}

/// A standard normal deviate (Box–Muller).
fn gaussian(rng: &mut impl Rng) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Fit with the default options, mesh seeded by every input point (so any
/// blob around a stray point would be found), and return the mesh's
/// component count, Chamfer-L1 distance to `truth` relative to the
/// diagonal, and the fit report.
fn reconstruct_defaults(
    pc: &PointCloud,
    truth: &surfrecon_geom::TriMesh,
) -> (usize, f64, FitReport) {
    let normals = pc.normals.as_ref().unwrap();
    let (model, report) = fit(&pc.positions, normals, &FitOptions::default()).unwrap();
    let opts = MeshOptions {
        resolution: 64,
        ..Default::default()
    };
    let (mesh, _) = mesh_model(&model, &pc.positions, pc.bounds(), &opts).unwrap();
    let t = topology(&mesh);
    assert!(t.watertight, "{t:?}");
    let eval = evaluate(
        &Surface::Mesh(mesh),
        &Surface::Mesh(truth.clone()),
        &EvalOptions {
            samples: 20_000,
            seed: 3,
        },
    )
    .unwrap();
    let diag = surfrecon_geom::Aabb::from_points(&truth.vertices).diagonal();
    (t.components, eval.chamfer_l1 / diag, report)
}

#[test]
fn one_percent_gaussian_noise_gives_one_closed_surface() {
    let truth = blob();
    let mut pc = sample_surface(&truth, 8000, 11);
    let diag = surfrecon_geom::Aabb::from_points(&truth.vertices).diagonal();
    let sigma = 0.01 * diag;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(23);
    for p in &mut pc.positions {
        *p += DVec3::new(gaussian(&mut rng), gaussian(&mut rng), gaussian(&mut rng)) * sigma;
    }
    let (components, chamfer, report) = reconstruct_defaults(&pc, &truth);
    assert_eq!(components, 1);
    assert!(
        (report.noise / sigma - 1.0).abs() < 0.3,
        "noise estimated as {} for σ = {sigma}",
        report.noise
    );
    // Within half the noise level of the true surface on average.
    assert!(
        chamfer < 0.0045,
        "Chamfer {:.3}% of the diagonal",
        100.0 * chamfer
    );
}

#[test]
fn five_percent_outliers_in_the_box_give_one_closed_surface() {
    let truth = blob();
    let mut pc = sample_surface(&truth, 7600, 12);
    let bounds = pc.bounds();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(29);
    let normals = pc.normals.as_mut().unwrap();
    for _ in 0..400 {
        let t = DVec3::new(rng.random(), rng.random(), rng.random());
        pc.positions
            .push(bounds.min + t * (bounds.max - bounds.min));
        let n = DVec3::new(gaussian(&mut rng), gaussian(&mut rng), gaussian(&mut rng));
        normals.push(n.normalize_or(DVec3::Z));
    }
    let (components, chamfer, report) = reconstruct_defaults(&pc, &truth);
    assert_eq!(components, 1);
    assert!(
        chamfer < 0.001,
        "Chamfer {:.3}% of the diagonal",
        100.0 * chamfer
    );
    // Many outliers are recognized as isolated (those far from the
    // surface and from each other), and no more than were added.
    assert!((50..=400).contains(&report.isolated), "{}", report.isolated);
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

/// A sphere whose normals on a cap (as orientation propagation can leave
/// them where scans overlap) point inward: with `reorient_normals` the fit
/// turns them round and the surface is the sphere, without a pit.
#[test]
fn a_flipped_patch_of_normals_is_turned_round() {
    let mut pc = sample_surface(&icosphere(DVec3::ZERO, 1.0, 5), 6000, 3);
    let normals = pc.normals.as_mut().unwrap();
    let cap: Vec<usize> = (0..pc.positions.len())
        .filter(|&i| pc.positions[i].z > 0.95)
        .collect();
    for &i in &cap {
        normals[i] = -normals[i];
    }
    let opts = FitOptions {
        reorient_normals: true,
        ..Default::default()
    };
    let (model, report) = fit(&pc.positions, pc.normals.as_ref().unwrap(), &opts).unwrap();
    assert!(
        report.normals_flipped >= cap.len() * 9 / 10 && report.normals_flipped <= cap.len() + 20,
        "{} flipped, cap of {}",
        report.normals_flipped,
        cap.len()
    );
    let opts = MeshOptions {
        resolution: 64,
        ..Default::default()
    };
    let (mesh, _) = mesh_model(&model, &pc.positions, pc.bounds(), &opts).unwrap();
    let t = topology(&mesh);
    assert!(t.watertight && t.components == 1 && t.euler == 2, "{t:?}");
    let worst = mesh
        .vertices
        .iter()
        .map(|v| (v.length() - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.02, "farthest vertex {worst} off the sphere");
}
