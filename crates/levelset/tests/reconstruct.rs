//! End-to-end reconstructions of shapes whose exact surface is known.

use std::collections::HashMap;
use surfrecon_geom::shapes::{icosphere, sample_surface, torus};
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_levelset::{
    reconstruct_2d, reconstruct_3d, Input, ReconstructParams, Reconstruction3,
};

/// Watertight (every edge in exactly two triangles, consistently oriented),
/// Euler characteristic, connected components.
fn topology(mesh: &TriMesh) -> (bool, i64, usize) {
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
        }
    }
    let mut count: HashMap<(u32, u32), usize> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let watertight = !mesh.triangles.is_empty()
        && count.values().all(|&c| c == 2)
        && edges.values().all(|&o| o == 0);
    let used: std::collections::HashSet<u32> = mesh.triangles.iter().flatten().copied().collect();
    let euler = used.len() as i64 - count.len() as i64 + mesh.triangles.len() as i64;
    // Components by union-find over triangle edges.
    let mut parent: Vec<u32> = (0..mesh.vertices.len() as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            parent[a as usize] = b;
        }
    }
    let roots: std::collections::HashSet<u32> =
        used.iter().map(|&v| find(&mut parent, v)).collect();
    (watertight, euler, roots.len())
}

/// Mean two-sided distance between the mesh and an analytic surface given
/// by its exact distance function and a dense sample of it.
fn chamfer(mesh: &TriMesh, surface_distance: impl Fn(DVec3) -> f64, samples: &[DVec3]) -> f64 {
    let to_surface: f64 = mesh
        .vertices
        .iter()
        .map(|&v| surface_distance(v).abs())
        .sum::<f64>()
        / mesh.vertices.len() as f64;
    let tree = surfrecon_geom::spatial::KdTree::new(&mesh.vertices);
    let to_mesh: f64 = samples
        .iter()
        .map(|&s| tree.nearest(s).unwrap().distance)
        .sum::<f64>()
        / samples.len() as f64;
    0.5 * (to_surface + to_mesh)
}

/// Whether every convection and flow stage stopped by its convergence test.
fn ended_by_convergence(report: &surfrecon_levelset::Report) -> bool {
    report
        .convection
        .iter()
        .chain(&report.flow)
        .chain(&report.settle)
        .all(|s| s.converged)
}

fn params(resolution: usize) -> ReconstructParams {
    ReconstructParams {
        resolution: Some(resolution),
        ..Default::default()
    }
}

#[test]
fn sphere_from_points() {
    let points = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 4000, 1).positions;
    let r = reconstruct_3d(&Input::from_points(points), &params(40)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let h = r.report.spacing;
    let exact = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 5000, 2).positions;
    let c = chamfer(&r.mesh, |v| v.length() - 1.0, &exact);
    eprintln!(
        "sphere: {:?} chamfer {c} h {h} report {:?}",
        (watertight, euler, comps),
        r.report
    );
    assert!(watertight);
    assert_eq!(euler, 2);
    assert_eq!(comps, 1);
    assert!(c < 0.5 * h, "chamfer {c} vs h {h}");
    assert!(ended_by_convergence(&r.report), "{:?}", r.report);
}

#[test]
fn torus_from_points() {
    let shape = torus(1.0, 0.4, 96, 48);
    let points = sample_surface(&shape, 6000, 3).positions;
    let r = reconstruct_3d(&Input::from_points(points), &params(48)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let h = r.report.spacing;
    let exact = sample_surface(&shape, 5000, 4).positions;
    let dist = |v: DVec3| (DVec3::new(v.x, v.y, 0.0).length() - 1.0).hypot(v.z) - 0.4;
    let c = chamfer(&r.mesh, dist, &exact);
    eprintln!(
        "torus: {:?} chamfer {c} h {h} report {:?}",
        (watertight, euler, comps),
        r.report
    );
    assert!(watertight);
    assert_eq!(euler, 0);
    assert_eq!(comps, 1);
    assert!(c < 0.5 * h, "chamfer {c} vs h {h}");
    assert!(ended_by_convergence(&r.report), "{:?}", r.report);
}

#[test]
fn circle_and_polygon_in_2d() {
    let circle: Vec<DVec3> = (0..300)
        .map(|i| {
            let t = i as f64 / 300.0 * std::f64::consts::TAU;
            DVec3::new(t.cos(), t.sin(), 0.0)
        })
        .collect();
    let r = reconstruct_2d(&Input::from_points(circle), &params(80)).unwrap();
    eprintln!(
        "circle: {} lines report {:?}",
        r.curves.lines.len(),
        r.report
    );
    assert_eq!(r.curves.lines.len(), 1);
    let line = &r.curves.lines[0];
    assert_eq!(line.first(), line.last(), "curve must be closed");
    for &i in line {
        let v = r.curves.vertices[i as usize];
        assert!(
            (v.length() - 1.0).abs() < r.report.spacing,
            "vertex at radius {}",
            v.length()
        );
    }
}

/// Largest distance of a mesh vertex from the unit sphere at the origin.
fn max_unit_sphere_error(mesh: &TriMesh) -> f64 {
    mesh.vertices
        .iter()
        .map(|v| (v.length() - 1.0).abs())
        .fold(0.0, f64::max)
}

fn rng(seed: u64) -> rand_pcg::Pcg64 {
    use rand::SeedableRng;
    rand_pcg::Pcg64::seed_from_u64(seed)
}

fn torus_distance(v: DVec3) -> f64 {
    (DVec3::new(v.x, v.y, 0.0).length() - 1.0).hypot(v.z) - 0.4
}

/// Points of the torus (R = 1, r = 0.4) in the patch around the outer
/// equator at angle 0 that the hole test removes.
fn in_hole(p: DVec3) -> bool {
    let u = p.y.atan2(p.x);
    u.abs() < 0.3 && p.z.abs() < 0.22 && p.x > 1.0
}

#[test]
fn torus_hole_is_filled_smoothly() {
    let shape = torus(1.0, 0.4, 96, 48);
    let points: Vec<DVec3> = sample_surface(&shape, 7000, 5)
        .positions
        .into_iter()
        .filter(|&p| !in_hole(p))
        .collect();
    let r = reconstruct_3d(&Input::from_points(points), &params(48)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let h = r.report.spacing;
    let tree = surfrecon_geom::spatial::KdTree::new(&r.mesh.vertices);
    let hole: Vec<DVec3> = sample_surface(&shape, 20000, 6)
        .positions
        .into_iter()
        .filter(|&p| in_hole(p))
        .collect();
    let worst = hole
        .iter()
        .map(|&p| tree.nearest(p).unwrap().distance)
        .fold(0.0, f64::max);
    let in_hole_vertices: Vec<f64> = r
        .mesh
        .vertices
        .iter()
        .filter(|&&v| in_hole(v) || in_hole(v * 1.05))
        .map(|&v| torus_distance(v))
        .collect();
    eprintln!(
        "hole: {:?} worst {worst} h {h} hole vertices {} max dev {:?}",
        (watertight, euler, comps),
        in_hole_vertices.len(),
        in_hole_vertices.iter().map(|d| d.abs()).fold(0.0, f64::max)
    );
    assert!(watertight);
    assert_eq!(euler, 0, "still a torus");
    assert_eq!(comps, 1);
    assert!(
        !hole.is_empty() && worst < 2.0 * h,
        "hole covered: worst {worst}, h {h}"
    );
    // The patch is a smooth (minimal) surface: it bends with the torus but
    // less, so it stays within the sagitta of the gap.
    assert!(in_hole_vertices.iter().all(|d| d.abs() < 2.0 * h));
}

#[test]
fn a_spheres_missing_cap_is_filled_on_the_sphere() {
    // The cap of chord radius 0.5 has no samples; the rim's points and
    // normals fix the sphere's curvature, so the fill follows it (fairing
    // alone left it up to 0.033 below the sphere here, 1.3 cells).
    let in_cap = |p: DVec3| p.z > 0.0 && p.x.hypot(p.y) < 0.5;
    let cloud = sample_surface(&icosphere(DVec3::ZERO, 1.0, 6), 9000, 8);
    let (points, normals): (Vec<DVec3>, Vec<DVec3>) = cloud
        .positions
        .iter()
        .zip(cloud.normals.unwrap())
        .filter(|(p, _)| !in_cap(**p))
        .unzip();
    let input = Input {
        points,
        normals,
        ..Default::default()
    };
    let r = reconstruct_3d(&input, &params(64)).unwrap();
    assert_eq!(topology(&r.mesh), (true, 2, 1));
    assert!(r.report.refine.fitted_to_rim > 0);
    let cap: Vec<f64> = (r.mesh.vertices.iter())
        .filter(|&&v| v.z > 0.0 && v.x.hypot(v.y) < 0.45)
        .map(|v| (v.length() - 1.0).abs())
        .collect();
    let worst = cap.iter().fold(0.0, |a: f64, &b| a.max(b));
    assert!(
        cap.len() > 50 && worst < 0.005,
        "cap off the sphere by {worst}"
    );
}

fn sphere_curves() -> surfrecon_geom::Polylines {
    let mut vertices = Vec::new();
    let mut lines = Vec::new();
    let n = 120;
    let mut circle = |f: &dyn Fn(f64) -> DVec3| {
        let start = vertices.len() as u32;
        vertices.extend((0..n).map(|i| f(i as f64 / n as f64 * std::f64::consts::TAU)));
        let mut line: Vec<u32> = (start..start + n as u32).collect();
        line.push(start);
        lines.push(line);
    };
    for k in 0..4 {
        let phi = k as f64 * std::f64::consts::PI / 4.0;
        circle(&|t| DVec3::new(t.cos() * phi.cos(), t.cos() * phi.sin(), t.sin()));
    }
    for lat in [-50f64, 0.0, 50.0] {
        let (c, s) = (lat.to_radians().cos(), lat.to_radians().sin());
        circle(&|t| DVec3::new(c * t.cos(), c * t.sin(), s));
    }
    surfrecon_geom::Polylines { vertices, lines }
}

#[test]
fn sphere_from_longitudes_and_latitudes() {
    let curves = sphere_curves();
    let input = Input::from_geometry(&surfrecon_geom::Geometry::from_polylines(curves));
    let r = reconstruct_3d(&input, &params(40)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let h = r.report.spacing;
    let worst = max_unit_sphere_error(&r.mesh);
    eprintln!(
        "curves: {:?} worst {worst} h {h} report {:?}",
        (watertight, euler, comps),
        r.report
    );
    assert!(watertight);
    assert_eq!((euler, comps), (2, 1));
    assert!(worst < 2.0 * h, "worst {worst} vs h {h}");
}

#[test]
fn non_uniform_noisy_sphere_gives_one_closed_surface() {
    use rand::Rng;
    let mut g = rng(9);
    let dense = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 8000, 7).positions;
    // Density falls tenfold from the top half to the bottom half.
    let sigma = 0.005 * (2.0 * 3f64.sqrt());
    let points: Vec<DVec3> = dense
        .into_iter()
        .filter(|p| p.z > 0.0 || g.random::<f64>() < 0.1)
        .collect::<Vec<_>>()
        .into_iter()
        .map(|p| p + sigma * DVec3::new(gauss(&mut g), gauss(&mut g), gauss(&mut g)))
        .collect();
    let r = reconstruct_3d(&Input::from_points(points), &params(40)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let worst = max_unit_sphere_error(&r.mesh);
    eprintln!(
        "nonuniform: {:?} worst {worst} report {:?}",
        (watertight, euler, comps),
        r.report
    );
    assert!(watertight);
    assert_eq!((euler, comps), (2, 1));
    assert!(worst < 3.0 * r.report.spacing);
}

#[test]
fn polygon_in_2d() {
    // Points along the edges of a triangle.
    let corners = [
        DVec3::new(-1.0, -0.8, 0.0),
        DVec3::new(1.2, -0.6, 0.0),
        DVec3::new(0.1, 1.0, 0.0),
    ];
    let mut points = Vec::new();
    for k in 0..3 {
        let (a, b) = (corners[k], corners[(k + 1) % 3]);
        points.extend((0..60).map(|i| a.lerp(b, i as f64 / 60.0)));
    }
    let r = reconstruct_2d(&Input::from_points(points.clone()), &params(80)).unwrap();
    let h = r.report.spacing;
    assert_eq!(r.curves.lines.len(), 1);
    let line = &r.curves.lines[0];
    assert_eq!(line.first(), line.last());
    let edge_distance = |v: DVec3| {
        (0..3)
            .map(|k| {
                let (a, b) = (corners[k], corners[(k + 1) % 3]);
                let t = ((v - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                (a + t * (b - a)).distance(v)
            })
            .fold(f64::INFINITY, f64::min)
    };
    let worst = line
        .iter()
        .map(|&i| edge_distance(r.curves.vertices[i as usize]))
        .fold(0.0, f64::max);
    eprintln!("polygon: worst {worst} h {h}");
    // The curvature term of the flow rounds the sharp corners by about a
    // cell (convection alone stays within h/2); the edges stay on the data.
    assert!(worst < 1.5 * h, "worst {worst} vs h {h}");
}

#[test]
fn convection_alone_reaches_the_data() {
    let points = sample_surface(&torus(1.0, 0.4, 96, 48), 6000, 11).positions;
    let p = ReconstructParams {
        steps: 0,
        ..params(48)
    };
    let r = reconstruct_3d(&Input::from_points(points.clone()), &p).unwrap();
    let h = r.report.spacing;
    let tree = surfrecon_geom::spatial::KdTree::new(&points);
    let near = r
        .mesh
        .vertices
        .iter()
        .filter(|&&v| tree.nearest(v).unwrap().distance < h)
        .count();
    let share = near as f64 / r.mesh.vertices.len() as f64;
    eprintln!("convection: share {share} report {:?}", r.report);
    assert!(r.report.flow.iter().all(|f| f.steps == 0));
    assert!(
        share > 0.9,
        "only {share} of the vertices within h of the data"
    );
}

#[test]
fn two_levels_match_the_single_level_accuracy() {
    let points = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 6000, 12).positions;
    let p = ReconstructParams {
        levels: Some(2),
        full_field: true,
        ..params(48)
    };
    let r = reconstruct_3d(&Input::from_points(points), &p).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let h = r.report.spacing;
    assert_eq!(r.report.levels, 2);
    assert_eq!(
        r.report.flow.len(),
        2,
        "the coarsest and the finest level evolve"
    );
    let exact = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 5000, 13).positions;
    let c = chamfer(&r.mesh, |v| v.length() - 1.0, &exact);
    assert!(watertight && euler == 2 && comps == 1);
    assert!(c < 0.5 * h, "chamfer {c} vs h {h}");
    // The full field is a signed distance everywhere: compare with the
    // exact sphere distance at every node (first-order sweeping: ≤ 2h).
    let field = r.field.as_ref().expect("full field asked for");
    let spec = field.spec;
    let worst = (0..spec.node_count())
        .map(|l| {
            let [x, y, z] = spec.position(spec.unlinear(l));
            (field.values[l] - (DVec3::new(x, y, z).length() - 1.0)).abs()
        })
        .fold(0.0, f64::max);
    assert!(worst < 2.0 * h, "signed distance off by {worst} (h {h})");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    use surfrecon_levelset::LevelsetError;
    let empty = reconstruct_3d(&Input::default(), &ReconstructParams::default());
    assert!(matches!(empty, Err(LevelsetError::InvalidInput(_))));
    let nan = Input::from_points(vec![DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 0.0)]);
    assert!(matches!(
        reconstruct_3d(&nan, &ReconstructParams::default()),
        Err(LevelsetError::InvalidInput(_))
    ));
    let pts = Input::from_points(vec![DVec3::ZERO, DVec3::ONE]);
    for bad in [
        ReconstructParams {
            p: 0.5,
            ..Default::default()
        },
        ReconstructParams {
            band: 1.0,
            ..Default::default()
        },
        ReconstructParams {
            resolution: Some(0),
            ..Default::default()
        },
        ReconstructParams {
            epsilon: Some(-1.0),
            ..Default::default()
        },
        ReconstructParams {
            levels: Some(0),
            ..Default::default()
        },
    ] {
        let r = reconstruct_3d(&pts, &bad);
        assert!(
            matches!(r, Err(LevelsetError::InvalidParameter { .. })),
            "{bad:?}"
        );
    }
    // Degenerate but valid data: one point, or two, still give a closed
    // (tiny) surface rather than a failure.
    let one = reconstruct_3d(&Input::from_points(vec![DVec3::ONE]), &params(8)).unwrap();
    assert!(topology(&one.mesh).0 || one.mesh.triangles.is_empty());
    let two = reconstruct_3d(&pts, &params(16)).unwrap();
    assert!(topology(&two.mesh).0 || two.mesh.triangles.is_empty());
}

/// Box–Muller standard normal sample.
fn gauss(g: &mut rand_pcg::Pcg64) -> f64 {
    use rand::Rng;
    let (u, v): (f64, f64) = (g.random::<f64>().max(1e-300), g.random());
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn sphere_points(n: usize, seed: u64) -> Vec<DVec3> {
    sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), n, seed).positions
}

#[test]
fn outliers_make_no_surface_of_their_own() {
    use rand::Rng;
    let mut g = rng(21);
    let mut points = sphere_points(5000, 22);
    // 5% of points uniform in the bounding box of the sphere, like a scan
    // with stray returns: most fall inside or far outside the surface.
    let outliers = points.len() / 20;
    points.extend(
        (0..outliers)
            .map(|_| DVec3::new(g.random(), g.random(), g.random()) * 2.2 - DVec3::splat(1.1)),
    );
    let r = reconstruct_3d(&Input::from_points(points), &params(40)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let h = r.report.spacing;
    let exact = sphere_points(5000, 23);
    let c = chamfer(&r.mesh, |v| v.length() - 1.0, &exact);
    eprintln!(
        "outliers: {:?} chamfer {c} h {h} cleaning {:?}",
        (watertight, euler, comps),
        r.report.cleaning
    );
    assert!(r.report.cleaning.outliers > outliers / 2);
    assert!(watertight);
    assert_eq!((euler, comps), (2, 1));
    assert!(c < 0.5 * h, "chamfer {c} vs h {h}");
    assert!(ended_by_convergence(&r.report), "{:?}", r.report);
}

#[test]
fn strong_noise_is_averaged_out() {
    let mut g = rng(31);
    // Gaussian noise of 1% of the bounding box diagonal (2√3).
    let sigma = 0.01 * 2.0 * 3f64.sqrt();
    let points: Vec<DVec3> = sphere_points(8000, 32)
        .into_iter()
        .map(|p| p + sigma * DVec3::new(gauss(&mut g), gauss(&mut g), gauss(&mut g)))
        .collect();
    let raw = ReconstructParams {
        clean: false,
        ..params(64)
    };
    let with = reconstruct_3d(&Input::from_points(points.clone()), &params(64)).unwrap();
    let without = reconstruct_3d(&Input::from_points(points), &raw).unwrap();
    // Mean distance of the output vertices from the sphere.
    let deviation = |m: &TriMesh| {
        m.vertices
            .iter()
            .map(|v| (v.length() - 1.0).abs())
            .sum::<f64>()
            / m.vertices.len() as f64
    };
    let (d_with, d_without) = (deviation(&with.mesh), deviation(&without.mesh));
    let (watertight, euler, comps) = topology(&with.mesh);
    eprintln!(
        "noise σ {sigma}: deviation {d_with} (raw points {d_without}), h {}, {:?}",
        with.report.spacing,
        (watertight, euler, comps)
    );
    assert!(watertight);
    assert_eq!((euler, comps), (2, 1));
    // Well inside the noise, and clearly better than on the raw points.
    assert!(d_with < 0.3 * sigma, "deviation {d_with} vs σ {sigma}");
    assert!(d_with < 0.85 * d_without, "{d_with} vs raw {d_without}");
    assert!(ended_by_convergence(&with.report), "{:?}", with.report);
}

#[test]
fn scan_holes_are_closed_without_handles() {
    // Three ball-shaped holes of radius 0.35 (10% of the bounding box
    // diagonal) cut out of a sampled sphere, as in a scan with missing
    // patches: the result is one closed surface of genus 0.
    let centres = [
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.0, 0.6, 0.8),
        DVec3::new(-0.6, -0.8, 0.0),
    ];
    let points: Vec<DVec3> = sphere_points(8000, 41)
        .into_iter()
        .filter(|p| centres.iter().all(|c| p.distance(*c) > 0.35))
        .collect();
    let r = reconstruct_3d(&Input::from_points(points.clone()), &params(48)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    let h = r.report.spacing;
    let worst = max_unit_sphere_error(&r.mesh);
    eprintln!(
        "scan holes: {:?} worst {worst} h {h}",
        (watertight, euler, comps)
    );
    assert!(watertight);
    assert_eq!((euler, comps), (2, 1), "genus 0, one piece");
    // The faired patches over the holes continue the sphere's curvature.
    assert!(r.report.refine.faired > 0, "{:?}", r.report.refine);
    assert!(worst < 0.55 * h, "worst {worst} vs h {h}");
    assert!(ended_by_convergence(&r.report), "{:?}", r.report);
    // Without refinement the minimal surfaces sag by most of a cell.
    let plain = ReconstructParams {
        refine: false,
        ..params(48)
    };
    let sagging = reconstruct_3d(&Input::from_points(points), &plain).unwrap();
    let sag = max_unit_sphere_error(&sagging.mesh);
    // (Faired 0.21 h and sag 1.2 h with the distance to the points
    // alone; with the points' tangent disks the unrefined patch sags less,
    // 0.97 h, but the faired one keeps 0.50 h at the hole's centre.)
    assert!(sag > 1.8 * worst, "sag {sag} vs faired {worst}");
}

#[test]
fn band_memory_follows_the_surface_area() {
    // The same sphere at two resolutions, one level each: the band's
    // blocks (and the distance's) grow like the area (×4 per doubling of
    // the resolution), far below the volume's ×8.
    let points = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 20_000, 21).positions;
    let exact = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 5000, 22).positions;
    let run = |resolution: usize| {
        let p = ReconstructParams {
            levels: Some(1),
            ..params(resolution)
        };
        let r = reconstruct_3d(&Input::from_points(points.clone()), &p).unwrap();
        let (watertight, euler, comps) = topology(&r.mesh);
        assert!(watertight && euler == 2 && comps == 1);
        let h = r.report.spacing;
        let c = chamfer(&r.mesh, |v| v.length() - 1.0, &exact);
        assert!(c < 0.5 * h, "chamfer {c} vs h {h} at {resolution}");
        // Extraction from the blocks equals extraction from the dense φ.
        let dense = surfrecon_grid::marching::marching_cubes(&r.dense_field(), 0.0);
        assert_eq!(dense.triangles.len(), r.mesh.triangles.len());
        let nodes: usize = r.report.dims.iter().product();
        (r.report, nodes)
    };
    let (coarse, coarse_nodes) = run(48);
    let (fine, fine_nodes) = run(96);
    let ratio = |a: usize, b: usize| b as f64 / a as f64;
    let blocks = ratio(coarse.band_blocks, fine.band_blocks);
    let distance = ratio(coarse.distance_blocks, fine.distance_blocks);
    let bytes = ratio(coarse.band_bytes, fine.band_bytes);
    assert!((3.0..5.0).contains(&blocks), "band blocks ×{blocks}");
    assert!(
        (3.0..5.5).contains(&distance),
        "distance blocks ×{distance}"
    );
    assert!(bytes < 5.5, "band bytes ×{bytes}");
    eprintln!("band blocks ×{blocks}, distance blocks ×{distance}, band bytes ×{bytes}");
    // The grid itself grew like the volume (less its fixed padding).
    assert!(ratio(coarse_nodes, fine_nodes) > 5.0);
    // And the band's blocks hold a minor share of the fine grid already.
    let share = (fine.band_blocks * 512) as f64 / fine_nodes as f64;
    assert!(share < 0.5, "band blocks hold {share} of the grid");
}

#[test]
fn contour_slice_stacks_take_the_interpolation_path() {
    // Twelve circular contours of the unit sphere, perpendicular to y.
    let mut points = Vec::new();
    for k in 0..12 {
        let y = -1.0 + (k as f64 + 0.5) / 6.0;
        let r = (1.0 - y * y).sqrt();
        for i in 0..200 {
            let t = i as f64 / 200.0 * std::f64::consts::TAU;
            points.push(DVec3::new(r * t.cos(), y, r * t.sin()));
        }
    }
    let input = Input::from_points(points);
    let r = reconstruct_3d(&input, &ReconstructParams::default()).unwrap();
    assert_eq!(r.report.slices, Some((1, 12)));
    let (watertight, euler, comps) = topology(&r.mesh);
    assert!(watertight);
    assert_eq!((euler, comps), (2, 1));
    let worst = r
        .mesh
        .vertices
        .iter()
        .filter(|v| v.y.abs() < 0.75)
        .map(|v| (v.length() - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.03, "worst {worst}");
    // Turned off, the same data go through the 3D level set.
    let params = ReconstructParams {
        slices: false,
        ..params(32)
    };
    let evolved = reconstruct_3d(&input, &params).unwrap();
    assert_eq!(evolved.report.slices, None);
    assert!(topology(&evolved.mesh).0);
}

#[test]
fn oriented_normals_keep_the_outside_out_of_wide_holes() {
    // Two overlapping tori (R = 1, r = 0.35, centres 1.9 apart: genus 2)
    // missing three ball-shaped patches of radius 6% of the diagonal, as
    // in the peer harness: without normals the exterior floods the tubes
    // and the walls collapse into a crumpled double sheet. With them the
    // result is one piece of genus 2: clean points are densified along
    // their normals, which keeps the flood out; noisy ones are not, and
    // the normals' winding number seals the inside.
    let tube =
        |v: DVec3, cx: f64| (DVec3::new(v.x - cx, v.y, 0.0).length() - 1.0).hypot(v.z) - 0.35;
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for (cx, other) in [(0.0, 1.9), (1.9, 0.0)] {
        let mut shape = torus(1.0, 0.35, 128, 64);
        shape.vertices.iter_mut().for_each(|v| v.x += cx);
        let cloud = sample_surface(&shape, 11000, 17 + cx as u64);
        for (p, n) in cloud.positions.iter().zip(cloud.normals.unwrap()) {
            if tube(*p, other) > 0.0 {
                points.push(*p);
                normals.push(n);
            }
        }
    }
    let diagonal = DVec3::new(4.6, 2.7, 0.7).length();
    let holes = [
        DVec3::new(0.0, 1.35, 0.0),
        DVec3::new(1.9, -1.0, 0.35),
        DVec3::new(-0.65, 0.0, 0.0),
    ];
    let keep: Vec<usize> = (0..points.len())
        .filter(|&i| {
            holes
                .iter()
                .all(|c| points[i].distance(*c) > 0.06 * diagonal)
        })
        .collect();
    let input = Input {
        points: keep.iter().map(|&i| points[i]).collect(),
        normals: keep.iter().map(|&i| normals[i]).collect(),
        ..Default::default()
    };
    // Noisy, the same points are not densified: the sealing keeps them.
    let mut g = rng(23);
    let sigma = 0.002 * diagonal;
    let noisy = Input {
        points: input
            .points
            .iter()
            .map(|p| *p + DVec3::new(gauss(&mut g), gauss(&mut g), gauss(&mut g)) * sigma)
            .collect(),
        ..input.clone()
    };
    let sealed = reconstruct_3d(&noisy, &ReconstructParams::default()).unwrap();
    assert_eq!(sealed.report.densified, 0);
    assert!(
        sealed.report.sealed_nodes > 0,
        "the flood got in and sealing was kept"
    );
    assert_eq!(
        topology(&sealed.mesh),
        (true, -2, 1),
        "one closed piece of genus 2"
    );
    let r = reconstruct_3d(&input, &ReconstructParams::default()).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    assert!(watertight);
    assert_eq!((euler, comps), (-2, 1), "one piece of genus 2");
    // And it fits the tori: every vertex near one of the two surfaces (the
    // patches over the holes, 0.32 wide on a tube of radius 0.35, sag).
    let worst = r
        .mesh
        .vertices
        .iter()
        .map(|&v| tube(v, 0.0).min(tube(v, 1.9)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.15, "worst {worst}");
    // Without normals the same points fall apart.
    let plain = reconstruct_3d(
        &Input {
            normals: Vec::new(),
            ..input
        },
        &ReconstructParams::default(),
    )
    .unwrap();
    assert_ne!(
        topology(&plain.mesh).1,
        -2,
        "the plain run was expected to flood"
    );
}

/// A unit sphere crossed by a plate 0.06 thick at y = -0.6 (its upper
/// face meets the sphere at 53°), sampled with normals: each part's
/// points outside the other part, those where `keep` holds.
fn sphere_and_plate(
    sphere_points: usize,
    plate_points: usize,
    keep: impl Fn(&DVec3) -> bool,
) -> Input {
    let (plate_lo, plate_hi) = (DVec3::new(-1.4, -0.63, -0.3), DVec3::new(-0.2, -0.57, 0.3));
    let in_plate = |p: &DVec3| p.cmpgt(plate_lo).all() && p.cmplt(plate_hi).all();
    let sphere = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), sphere_points, 5);
    let plate = sample_surface(
        &surfrecon_geom::shapes::cuboid(plate_lo, plate_hi),
        plate_points,
        6,
    );
    let mut input = Input::default();
    let mut add = |cloud: &surfrecon_geom::PointCloud, outside_other: &dyn Fn(&DVec3) -> bool| {
        for (p, n) in cloud.positions.iter().zip(cloud.normals.as_ref().unwrap()) {
            if outside_other(p) && keep(p) {
                input.points.push(*p);
                input.normals.push(*n);
            }
        }
    };
    add(&sphere, &|p| !in_plate(p));
    add(&plate, &|p| p.length() > 1.0);
    input
}

/// One closed piece of genus 0 whose farthest input point is within
/// `max` of the diagonal.
fn assert_one_closed_sphere_reaching(r: &Reconstruction3, points: &[DVec3], max: f64) {
    assert_eq!(
        topology(&r.mesh),
        (true, 2, 1),
        "one closed piece of genus 0"
    );
    let fit = surfrecon_geom::data_fit::data_fit(&r.mesh, points).unwrap();
    assert!(
        fit.max < max,
        "farthest point {:.2}% of the diagonal at {:?}",
        100.0 * fit.max,
        fit.farthest
    );
}

#[test]
fn a_hole_does_not_web_a_narrow_wedge() {
    // A unit sphere crossed by a plate 0.06 thick at y = -0.6 (its upper
    // face meets the sphere at 53°), oriented points, and a ball-shaped
    // hole of radius 0.35 on the far side. The outer contour closes that
    // hole only at ε ≈ 0.3, which also fills the wedge, and the evolution
    // did not open it again: a web from the plate to the sphere left the
    // points in the wedge 4.1% of the diagonal off the surface. The
    // normals seal the hole at the starting ε instead.
    let hole = DVec3::new(0.5, 0.6, 0.62).normalize();
    let input = sphere_and_plate(8000, 2000, |p| p.distance(hole) > 0.35);
    let r = reconstruct_3d(&input, &ReconstructParams::default()).unwrap();
    assert_one_closed_sphere_reaching(&r, &input.points, 0.02);
    assert!(
        r.report.sealed_nodes > 0,
        "the hole was sealed by the normals"
    );
}

#[test]
fn the_fine_level_reopens_a_wedge_the_coarse_level_filled() {
    // A unit sphere crossed by a plate 0.06 thick at y = -0.6 (its upper
    // face meets the sphere at 53°), 18k points without normals, no hole,
    // on two levels. The coarse level fills the wedge between plate and
    // sphere a coarse cell deep and the fine convection stalls on its
    // bisector: the points at its apex were 2.71% of the diagonal off the
    // surface. The fine level re-tags around them: 1.85%.
    // On three levels each finer level re-tags what its coarser one
    // filled (only the finest did: 2.99%; now 2.27%).
    let input = Input::from_points(sphere_and_plate(16000, 4000, |_| true).points);
    for levels in [2, 3] {
        let params = ReconstructParams {
            levels: Some(levels),
            ..Default::default()
        };
        let r = reconstruct_3d(&input, &params).unwrap();
        let bound = if levels == 2 { 0.022 } else { 0.026 };
        assert_one_closed_sphere_reaching(&r, &input.points, bound);
        assert!(r.report.reopened_near_points > 0, "points were buried");
    }
}

#[test]
fn slices_of_a_torus_keep_its_hole() {
    // A torus (R = 1, r = 0.4) cut by 12 planes across z: every slice is
    // two concentric closed contours (polylines). The disk inside the
    // inner one is a hole, which the 2D level set cannot reach from the
    // border; the nesting of the contours says so.
    let mut segments = Vec::new();
    for k in 0..12 {
        let z = -0.36 + k as f64 * 0.72 / 11.0;
        let half = (0.4f64 * 0.4 - z * z).sqrt();
        for radius in [1.0 - half, 1.0 + half] {
            let n = 160;
            let at = |i: usize| {
                let t = i as f64 / n as f64 * std::f64::consts::TAU;
                DVec3::new(radius * t.cos(), radius * t.sin(), z)
            };
            segments.extend((0..n).map(|i| [at(i), at((i + 1) % n)]));
        }
    }
    let input = Input {
        segments,
        ..Default::default()
    };
    let r = reconstruct_3d(&input, &ReconstructParams::default()).unwrap();
    assert_eq!(r.report.slices, Some((2, 12)));
    let (watertight, euler, comps) = topology(&r.mesh);
    assert!(watertight);
    assert_eq!((euler, comps), (0, 1), "one piece of genus 1");
    // Nothing of the surface inside the hole (r < 0.6 at every z).
    let in_hole = r
        .mesh
        .vertices
        .iter()
        .filter(|v| v.x.hypot(v.y) < 0.5)
        .count();
    assert_eq!(in_hole, 0);
}

/// Points of a unit sphere with four thin cones (base radius 0.08–0.14,
/// 0.8 long beyond the sphere), uniform by area, none inside another part.
fn spiky_sphere_points() -> Vec<DVec3> {
    use rand::Rng;
    let cones = [
        (DVec3::X, 0.08),
        (DVec3::NEG_X, 0.10),
        (DVec3::new(0.0, 0.6, 0.8), 0.12),
        (DVec3::new(0.0, -0.8, 0.6), 0.14),
    ];
    let inside_cone = |p: DVec3| {
        cones.iter().any(|&(u, rb)| {
            let t = (p.dot(u) - 1.0) / 0.8;
            (0.0..1.0).contains(&t) && (p - p.dot(u) * u).length() < rb * (1.0 - t)
        })
    };
    let mut points: Vec<DVec3> = sphere_points(6000, 31)
        .into_iter()
        .filter(|&p| !inside_cone(p))
        .collect();
    let mut g = rng(32);
    for &(u, rb) in &cones {
        let e1 = u.any_orthonormal_vector();
        let e2 = u.cross(e1);
        // Lateral area π rb √(rb² + L²) at the sphere's sampling density.
        let n = (std::f64::consts::PI * rb * 0.8 * 6000.0 / (4.0 * std::f64::consts::PI)) as usize;
        for _ in 0..n {
            // Area density along the axis falls linearly to the tip.
            let t = 1.0 - g.random::<f64>().sqrt();
            let a = g.random::<f64>() * std::f64::consts::TAU;
            let r = rb * (1.0 - t);
            points.push(u * (1.0 + 0.8 * t) + r * (a.cos() * e1 + a.sin() * e2));
        }
    }
    points
}

#[test]
fn thin_spikes_are_kept_to_their_tips() {
    let points = spiky_sphere_points();
    for levels in [1, 2] {
        let p = ReconstructParams {
            levels: Some(levels),
            ..params(64)
        };
        let r = reconstruct_3d(&Input::from_points(points.clone()), &p).unwrap();
        let (watertight, euler, comps) = topology(&r.mesh);
        assert!(watertight && euler == 2 && comps == 1, "{levels} levels");
        // Every point within two cells of the surface (mesh vertices lie
        // within a cell of each other) but a few lone samples at the very
        // tips, which cleaning drops as outliers; none beyond four cells.
        let h = r.report.spacing;
        let tree = surfrecon_geom::spatial::KdTree::new(&r.mesh.vertices);
        let distances: Vec<f64> = points
            .iter()
            .map(|&q| tree.nearest(q).unwrap().distance)
            .collect();
        let far = distances.iter().filter(|&&d| d > 2.0 * h).count();
        let worst = distances.iter().copied().fold(0.0, f64::max);
        eprintln!("{levels} levels: {far} points beyond 2h, worst {worst}, h {h}");
        assert!(
            far <= points.len() / 1000,
            "{levels} levels: {far} points beyond 2h"
        );
        assert!(
            worst < 4.0 * h,
            "{levels} levels: a point {worst} from the surface (h {h})"
        );
        // Exact distances to the surface: the cones' last samples, which
        // the grid ends short of (3.6 cells), are reached too. (Issue #15
        // asks 0.5% of the diagonal at the harness's 20k points, where a
        // cell is 0.35% of it.)
        let fit = surfrecon_geom::data_fit::data_fit(&r.mesh, &points).unwrap();
        let farthest = fit.max * fit.diagonal / h;
        assert!(
            farthest <= 1.5,
            "{levels} levels: a point {farthest} cells from the surface, at {:?}",
            fit.farthest
        );
    }
}

/// Clean points sparser than the grid: the distance to their tangent
/// disks (surfels) keeps the surface on the sampled sphere between them
/// instead of bulging and dimpling around each point.
#[test]
fn sparse_clean_points_are_joined_along_their_tangent_planes() {
    let points = sphere_points(3000, 11);
    let r = reconstruct_3d(&Input::from_points(points), &params(100)).unwrap();
    let (watertight, euler, comps) = topology(&r.mesh);
    assert!(watertight && euler == 2 && comps == 1);
    assert_eq!(r.report.surfels, 3000);
    let errors: Vec<f64> = r
        .mesh
        .vertices
        .iter()
        .map(|v| (v.length() - 1.0).abs())
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let max = errors.iter().fold(0.0f64, |m, &e| m.max(e));
    // Distances to the points alone: mean 0.055 h, max 0.59 h.
    let h = r.report.spacing;
    assert!(
        mean < 0.045 * h && max < 0.45 * h,
        "mean {mean}, max {max}, h {h}"
    );
}

/// A plate of half width 1 and thickness 0.08 (about two sampling gaps),
/// 6000 area-uniform samples with their normals.
fn thin_plate_with_normals(g: &mut rand_pcg::Pcg64) -> Input {
    use rand::Rng;
    let (half, thickness) = (1.0, PLATE_THICKNESS);
    let mut input = Input::default();
    // Area-uniform samples of the plate's box: the two faces and the rim.
    let rim = 8.0 * half * thickness;
    let faces = 8.0 * half * half;
    while input.points.len() < 6000 {
        let (u, w): (f64, f64) = (g.random_range(-half..half), g.random_range(-1.0..1.0));
        let (p, n) = if g.random::<f64>() * (faces + rim) < faces {
            let z = 0.5 * thickness * w.signum();
            (
                DVec3::new(u, g.random_range(-half..half), z),
                DVec3::new(0.0, 0.0, z.signum()),
            )
        } else {
            let z = 0.5 * thickness * w;
            match g.random_range(0..4) {
                0 => (DVec3::new(half, u, z), DVec3::X),
                1 => (DVec3::new(-half, u, z), -DVec3::X),
                2 => (DVec3::new(u, half, z), DVec3::Y),
                _ => (DVec3::new(u, -half, z), -DVec3::Y),
            }
        };
        input.points.push(p);
        input.normals.push(n);
    }
    input
}

const PLATE_THICKNESS: f64 = 0.08;

/// One closed piece whose vertices away from the rim lie on the plate's
/// faces: the mean distance, in cells.
fn plate_face_offset(r: &Reconstruction3) -> f64 {
    let (watertight, euler, comps) = topology(&r.mesh);
    assert!(
        watertight && euler == 2 && comps == 1,
        "{:?}",
        (watertight, euler, comps)
    );
    let off: Vec<f64> = r
        .mesh
        .vertices
        .iter()
        .filter(|v| v.x.abs().max(v.y.abs()) < 0.8)
        .map(|v| (v.z.abs() - 0.5 * PLATE_THICKNESS).abs())
        .collect();
    off.iter().sum::<f64>() / off.len() as f64 / r.report.spacing
}

/// A plate about two sampling gaps thick, sampled with normals: the
/// corners of the points' tangent disks join them, so the faces crumple
/// less at grid scale.
#[test]
fn a_sparsely_sampled_thin_plate_keeps_flat_faces() {
    let input = thin_plate_with_normals(&mut rng(5));
    let r = reconstruct_3d(&input, &ReconstructParams::default()).unwrap();
    assert!(r.report.densified >= 3 * 5990);
    // Without the corners: 0.67 h (0.49 h with them).
    let mean = plate_face_offset(&r);
    eprintln!("plate faces: mean offset {mean} h");
    assert!(mean < 0.55, "mean {mean} h");
}

/// The same plate with 5% stray points (random normals) in a box around
/// it: cleaning drops most, and the points whose normals agree with their
/// neighbours' keep their disks, so the faces stay as flat as without
/// strays; the strays that survive get none.
#[test]
fn stray_points_do_not_cost_the_clean_points_their_disks() {
    use rand::Rng;
    let mut g = rng(5);
    let mut input = thin_plate_with_normals(&mut g);
    for _ in 0..300 {
        let p = DVec3::new(g.random(), g.random(), g.random()) * 2.0 - DVec3::ONE;
        input.points.push(p * DVec3::new(1.1, 1.1, 0.3));
        let n = DVec3::new(gauss(&mut g), gauss(&mut g), gauss(&mut g));
        input.normals.push(n.normalize());
    }
    let r = reconstruct_3d(&input, &ReconstructParams::default()).unwrap();
    let stats = &r.report.cleaning;
    let kept = input.points.len() - stats.outliers;
    eprintln!("strays: {stats:?}, densified {}", r.report.densified);
    let mean = plate_face_offset(&r);
    eprintln!("plate faces: mean offset {mean} h");
    assert!(stats.outliers > 6, "cleaning counts the data clean");
    // Without per-point disks none at all, and 0.120 h (0.045 h with).
    assert!(r.report.densified >= 3 * 5900, "{}", r.report.densified);
    let strays_kept = kept.saturating_sub(6000);
    assert!(r.report.densified <= 3 * (6000 + strays_kept / 4));
    assert!(mean < 0.08, "mean {mean} h");
}

fn box_distance(p: DVec3, half: DVec3) -> f64 {
    let q = p.abs() - half;
    q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
}

/// `n` samples of the box of half sizes `half`, turned off the grid's axes
/// (so no edge lies along grid lines), and the turn.
/// Mean distance from points along the edges of the box of half sizes
/// `half`, turned by `turn`, to `mesh`: how far its edges are cut off.
fn edge_cut(mesh: &TriMesh, half: DVec3, turn: glam::DQuat) -> f64 {
    let bvh = surfrecon_geom::metrics::TriangleBvh::new(mesh);
    let mut distances = Vec::new();
    for axis in 0..3 {
        for corner in 0..4 {
            let signs = [
                (corner & 1) as f64 * 2.0 - 1.0,
                (corner >> 1) as f64 * 2.0 - 1.0,
            ];
            for k in 1..20 {
                let mut p = [0.0; 3];
                p[axis] = half[axis] * (k as f64 / 10.0 - 1.0);
                p[(axis + 1) % 3] = signs[0] * half[(axis + 1) % 3];
                p[(axis + 2) % 3] = signs[1] * half[(axis + 2) % 3];
                let q = turn * DVec3::from_array(p);
                distances.push(bvh.closest(q).unwrap().point.distance(q));
            }
        }
    }
    distances.iter().sum::<f64>() / distances.len() as f64
}

fn turned_box_points(half: DVec3, n: usize, seed: u64) -> (Vec<DVec3>, glam::DQuat) {
    let turn = glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 0.5, 0.2);
    let cube = surfrecon_geom::shapes::cuboid(-half, half);
    let points = sample_surface(&cube, n, seed)
        .positions
        .iter()
        .map(|&p| turn * p)
        .collect();
    (points, turn)
}

#[test]
fn refined_surface_follows_sharp_edges_of_exact_points() {
    use surfrecon_levelset::refine::{refine_surface, RefineOptions};
    let half = DVec3::new(0.5, 0.4, 0.3);
    let (points, turn) = turned_box_points(half, 8000, 3);
    let unrefined = ReconstructParams {
        refine: false,
        ..params(40)
    };
    let r = reconstruct_3d(&Input::from_points(points.clone()), &unrefined).unwrap();
    let h = r.report.spacing;
    let near_edge_error = |options: RefineOptions| {
        let mut mesh = r.mesh.clone();
        let stats = refine_surface(&mut mesh, &points, &[], h, options);
        let (watertight, euler, _) = topology(&mesh);
        assert!(
            watertight && euler == 2,
            "{options:?}: {watertight} {euler}"
        );
        let errors: Vec<f64> = mesh
            .vertices
            .iter()
            .map(|&v| turn.inverse() * v)
            .filter(|p| {
                // Within two cells of two faces at once: beside an edge.
                let gaps = (half - p.abs()).abs().to_array();
                gaps.iter().filter(|&&g| g < 2.0 * h).count() >= 2
            })
            .map(|p| box_distance(p, half).abs() / h)
            .collect();
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        let cut = edge_cut(&mesh, half, turn) / h;
        eprintln!(
            "{options:?}: {stats:?}, mean error beside edges {mean} h over {}, edges cut by {cut} h",
            errors.len()
        );
        (mean, cut)
    };
    let fitted_only = near_edge_error(RefineOptions {
        fair_gaps: true,
        exact_points: false,
    });
    let with_planes = near_edge_error(RefineOptions {
        fair_gaps: true,
        exact_points: true,
    });
    assert!(
        with_planes.0 < 0.6 * fitted_only.0,
        "beside edges: {with_planes:?} h with the planes, {fitted_only:?} h without"
    );
    // The vertices nearest the edges on the planes' lines: cut by 0.32 h
    // (0.37 h with the planes alone, 0.49 h without).
    assert!(
        with_planes.1 < 0.7 * fitted_only.1,
        "edges cut: {with_planes:?} h with the planes, {fitted_only:?} h without"
    );
}

/// Points with normals closer than half a cell apart are not densified
/// with their tangent disks' corners (four times the points for nothing
/// the grid shows); the surface stays as close (24 cells: chamfer 0.186 h
/// either way).
#[test]
fn points_denser_than_the_grid_are_not_densified() {
    let points = sphere_points(8000, 31);
    let normals = points.iter().map(|p| p.normalize()).collect();
    let input = Input {
        points,
        normals,
        ..Input::default()
    };
    let exact = sphere_points(5000, 32);
    for (resolution, densified) in [(24, false), (96, true)] {
        let r = reconstruct_3d(&input, &params(resolution)).unwrap();
        assert_eq!(r.report.densified > 0, densified, "{resolution} cells");
        let h = r.report.spacing;
        let c = chamfer(&r.mesh, |v| v.length() - 1.0, &exact);
        eprintln!("{resolution} cells: chamfer {c}, h {h}");
        assert!(c < 0.25 * h, "chamfer {c} vs h {h}");
        assert_eq!(topology(&r.mesh), (true, 2, 1));
    }
}

/// Snapping neighbours onto the two faces beside a sharp edge (and onto
/// the sheets of thin parts) can fold a sliver through the next face; those
/// moves are put back, so the refined surface crosses itself nowhere, as
/// the marching-cubes surface does not.
#[test]
fn the_refined_surface_does_not_cross_itself() {
    let (points, _) = turned_box_points(DVec3::splat(0.5), 20_000, 9);
    let r = reconstruct_3d(&Input::from_points(points), &params(96)).unwrap();
    let crossing = surfrecon_geom::intersections::self_intersections(&r.mesh);
    assert!(crossing.is_empty(), "{} crossing pairs", crossing.len());
    assert!(
        r.report.refine.uncrossed > 0,
        "the snapping crossed nowhere"
    );
    assert_eq!(topology(&r.mesh), (true, 2, 1));
}
