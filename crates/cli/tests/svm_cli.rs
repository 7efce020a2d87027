//! End-to-end: `surfrecon reconstruct --method svm` and `surfrecon morph`.

mod common;
use common::{json_of, path_str as s, surfrecon};

use std::path::{Path, PathBuf};
use surfrecon_geom::metrics::topology;
use surfrecon_geom::shapes::{icosphere, sample_surface};
use surfrecon_geom::{io, DVec3, Geometry};

/// 3,000 points sampled (with `seed`) on the unit sphere, as `dir/sphere.ply`.
fn write_sphere_points(dir: &Path, seed: u64) -> PathBuf {
    let input = dir.join("sphere.ply");
    let pc = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 3000, seed);
    io::write(&input, &Geometry::from_points(pc)).unwrap();
    input
}

#[test]
fn reconstruct_svm_saves_reloads_and_meshes_a_closed_surface() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_sphere_points(dir.path(), 5);
    let out = dir.path().join("out.ply");
    let model = dir.path().join("m.svm");
    let run = surfrecon(&[
        "--json",
        "reconstruct",
        s(&input),
        "-o",
        s(&out),
        "--method",
        "svm",
        "--resolution",
        "48",
        "--model-out",
        s(&model),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mesh = io::read(&out).unwrap().to_mesh();
    let t = topology(&mesh);
    assert!(t.watertight && t.components == 1, "{t:?}");
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(json["svm"]["centres"].as_u64().unwrap() > 0, "{json}");

    // Mesh the saved model again, smoother, without fitting.
    let again = dir.path().join("again.ply");
    let run = surfrecon(&[
        "reconstruct",
        s(&input),
        "-o",
        s(&again),
        "--method",
        "svm",
        "--resolution",
        "48",
        "--model-in",
        s(&model),
        "--drop-levels",
        "1",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(topology(&io::read(&again).unwrap().to_mesh()).watertight);

    // A malformed model is one clear error line naming the file.
    std::fs::write(&model, b"SRSVMMDL\x01\x00").unwrap();
    let refused = |model: &Path| {
        let run = surfrecon(&[
            "reconstruct",
            s(&input),
            "-o",
            s(&again),
            "--method",
            "svm",
            "--model-in",
            s(model),
        ]);
        assert!(!run.status.success());
        String::from_utf8_lossy(&run.stderr).into_owned()
    };
    let err = refused(&model);
    assert!(err.contains("m.svm") && err.contains("truncated"), "{err}");

    // A missing model is named once, its cause once.
    let err = refused(&dir.path().join("missing.svm"));
    assert_eq!(err.lines().count(), 1, "{err}");
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
}

#[test]
fn svm_c_auto_reports_the_chosen_parameters_and_meshes_well() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_sphere_points(dir.path(), 9);
    let out = dir.path().join("out.ply");
    let run = surfrecon(&[
        "--json",
        "reconstruct",
        s(&input),
        "-o",
        s(&out),
        "--method",
        "svm",
        "--svm-c",
        "auto",
        "--resolution",
        "48",
    ]);
    let json = json_of(&run);
    let fit = &json["svm"]["fit"];
    let trials = fit["selection"].as_array().expect("selection trials");
    assert!(trials.len() >= 2, "{fit}");
    // The reported C and ε are those of the trial with the least error.
    let best = trials
        .iter()
        .min_by(|a, b| {
            let e = |t: &serde_json::Value| t["validation_error"].as_f64().unwrap();
            e(a).total_cmp(&e(b))
        })
        .unwrap();
    assert_eq!(fit["c"], best["c"], "{fit}");
    assert_eq!(fit["epsilon"], best["epsilon"], "{fit}");
    assert!(trials
        .iter()
        .all(|t| t["validation_error"].as_f64().unwrap() > 0.0));

    let mesh = io::read(&out).unwrap().to_mesh();
    let t = topology(&mesh);
    assert!(t.watertight && t.components == 1 && t.euler == 2, "{t:?}");
    // Every vertex within 1% of the diagonal (2√3) of the unit sphere.
    let worst = mesh
        .vertices
        .iter()
        .map(|v| (v.length() - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 0.01 * 2.0 * 3f64.sqrt(),
        "vertex {worst} off the sphere"
    );
}

#[test]
fn morph_writes_frames_from_source_to_target() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src.ply");
    let dst = dir.path().join("dst.ply");
    let sphere = icosphere(DVec3::ZERO, 1.0, 3);
    let mut ellipsoid = sphere.clone();
    for v in &mut ellipsoid.vertices {
        *v *= DVec3::new(1.3, 1.0, 0.8);
    }
    io::write(&src, &Geometry::from_mesh(sphere.clone())).unwrap();
    io::write(&dst, &Geometry::from_mesh(ellipsoid)).unwrap();
    let pairs = dir.path().join("pairs.txt");
    std::fs::write(
        &pairs,
        "# source -> target\n1 0 0 1.3 0 0\n0 0 1  0 0 0.8\n",
    )
    .unwrap();
    let prefix = dir.path().join("m");
    let run = surfrecon(&[
        "morph",
        s(&src),
        s(&dst),
        "--pairs",
        s(&pairs),
        "-o",
        s(&prefix),
        "--frames",
        "3",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let last = io::read(dir.path().join("m_002.ply")).unwrap().to_mesh();
    assert_eq!(last.triangles.len(), sphere.triangles.len());
    let tip = last.vertices.iter().map(|v| v.x).fold(f64::MIN, f64::max);
    assert!((tip - 1.3).abs() < 0.03, "x extent {tip}");

    std::fs::write(&pairs, "1 0 0 1.3 0\n").unwrap();
    let run = surfrecon(&[
        "morph",
        s(&src),
        s(&dst),
        "--pairs",
        s(&pairs),
        "-o",
        s(&prefix),
    ]);
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("line 1"));
}

#[test]
fn morph_refuses_absurd_options_before_fitting() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src.ply");
    io::write(&src, &Geometry::from_mesh(icosphere(DVec3::ZERO, 1.0, 2))).unwrap();
    let prefix = dir.path().join("m");
    for (flag, message) in [
        ("--frames=100000000", "--frames must be between 2"),
        ("--warp-levels=0", "levels: must be between 1 and 16, got 0"),
        (
            "--warp-levels=99",
            "levels: must be between 1 and 16, got 99",
        ),
        (
            "--c-corr=-1",
            "c_corr: must be a non-negative finite number",
        ),
        (
            "--c-dist=NaN",
            "c_dist: must be a non-negative finite number",
        ),
    ] {
        let run = surfrecon(&["morph", s(&src), s(&src), "-o", s(&prefix), flag]);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(
            !run.status.success() && err.contains(message),
            "{flag}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{flag}: {err}");
    }
    let written = std::fs::read_dir(dir.path()).unwrap().count();
    assert_eq!(written, 1, "only the source file is left");
}
