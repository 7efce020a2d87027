//! End-to-end tests of `surfrecon eval` and `surfrecon normals`: real files
//! in a temporary directory, the real binary, its stdout/stderr and exit code.

mod common;
use common::{json_of, path_str, surfrecon};

use std::path::{Path, PathBuf};
use surfrecon_geom::shapes::{icosphere, sample_surface, torus};
use surfrecon_geom::{io, DVec3, Geometry, PointCloud};

fn write_sphere(dir: &Path, name: &str, radius: f64) -> PathBuf {
    let path = dir.join(name);
    let mesh = icosphere(DVec3::ZERO, radius, 4);
    io::write(&path, &Geometry::from_mesh(mesh)).unwrap();
    path
}

#[test]
fn eval_json_scores_scaled_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let reference = write_sphere(dir.path(), "ref.ply", 1.0);
    let candidate = write_sphere(dir.path(), "cand.obj", 1.01);
    let out = surfrecon(&[
        "eval",
        path_str(&candidate),
        "--reference",
        path_str(&reference),
        "--samples",
        "20000",
        "--json",
    ]);
    let v = json_of(&out);
    let keys = [
        "chamfer_l1",
        "chamfer_l2",
        "hausdorff",
        "fscore_0_5pct",
        "fscore_1pct",
        "normal_consistency",
        "vertices",
        "faces",
        "watertight",
        "manifold",
        "components",
        "euler",
        "diagonal",
    ];
    assert_eq!(v.as_object().unwrap().len(), keys.len());
    for k in keys {
        assert!(v.get(k).is_some(), "missing {k}");
    }
    let chamfer = v["chamfer_l1"].as_f64().unwrap();
    assert!((chamfer - 0.01).abs() < 0.0005, "{chamfer}");
    assert_eq!(v["fscore_1pct"], 1.0);
    assert_eq!(v["watertight"], true);
    assert_eq!(v["manifold"], true);
    assert_eq!(v["euler"], 2);
    assert_eq!(v["components"], 1);
    assert_eq!(v["faces"], 20 * 256);
}

#[test]
fn eval_of_mesh_against_itself_prints_table() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("torus.off");
    io::write(&mesh, &Geometry::from_mesh(torus(2.0, 0.5, 32, 16))).unwrap();
    let out = surfrecon(&[
        "eval",
        path_str(&mesh),
        "-r",
        path_str(&mesh),
        "--samples",
        "5000",
    ]);
    assert!(out.status.success());
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("chamfer L1"), "{table}");
    assert!(table.contains("F-score @1%           1.0000"), "{table}");
    assert!(table.contains("euler (V-E+F)         0"), "{table}");
    assert!(table.contains("watertight            yes"), "{table}");
}

#[test]
fn eval_accepts_point_sets() {
    let dir = tempfile::tempdir().unwrap();
    let reference = write_sphere(dir.path(), "ref.ply", 1.0);
    let points = dir.path().join("points.xyz");
    let cloud = sample_surface(&icosphere(DVec3::ZERO, 1.0, 4), 3000, 1);
    io::write(
        &points,
        &Geometry::from_points(PointCloud::new(cloud.positions)),
    )
    .unwrap();
    let out = surfrecon(&[
        "eval",
        path_str(&points),
        "-r",
        path_str(&reference),
        "--json",
    ]);
    let v = json_of(&out);
    // The points lie on the mesh, but the mesh's samples only come within
    // about half the point spacing (0.065) of the points.
    let chamfer = v["chamfer_l1"].as_f64().unwrap();
    assert!(chamfer > 0.0 && chamfer < 0.03, "{chamfer}");
    assert_eq!(v["vertices"], 3000);
    assert!(v["watertight"].is_null() && v["normal_consistency"].is_null());
}

#[test]
fn eval_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let reference = write_sphere(dir.path(), "ref.ply", 1.0);
    let missing = dir.path().join("nope.ply");
    let out = surfrecon(&["eval", path_str(&missing), "-r", path_str(&reference)]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.starts_with("error:") && err.contains("nope.ply"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");

    let out = surfrecon(&[
        "eval",
        path_str(&reference),
        "-r",
        path_str(&reference),
        "--samples",
        "0",
    ]);
    assert_eq!(out.status.code(), Some(1));
}

#[test]
fn normals_command_orients_outward() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("torus.xyz");
    let output = dir.path().join("torus_normals.ply");
    let cloud = sample_surface(&torus(2.0, 0.6, 96, 48), 6000, 3);
    io::write(
        &input,
        &Geometry::from_points(PointCloud::new(cloud.positions.clone())),
    )
    .unwrap();
    let out = surfrecon(&[
        "normals",
        path_str(&input),
        "-o",
        path_str(&output),
        "-k",
        "12",
        "--json",
    ]);
    let v = json_of(&out);
    assert_eq!(v["points"], 6000);
    assert_eq!(v["oriented"], true);
    let result = io::read(&output).unwrap();
    assert_eq!(result.points.positions.len(), 6000);
    let found = result.points.normals.expect("normals written");
    let truth = cloud.normals.unwrap();
    let outward = found
        .iter()
        .zip(&truth)
        .filter(|(a, b)| a.dot(**b) > 0.0)
        .count();
    assert!(outward as f64 >= 0.99 * 6000.0, "{outward}");
}

#[test]
fn normals_command_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("bad.xyz");
    std::fs::write(&input, "0 0 0\n1 1 oops\n").unwrap();
    let output = dir.path().join("out.ply");
    let out = surfrecon(&["normals", path_str(&input), "-o", path_str(&output)]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("bad.xyz") && err.contains("line 2"), "{err}");
    assert!(!output.exists());

    let good = dir.path().join("good.xyz");
    std::fs::write(&good, "0 0 0\n1 0 0\n0 1 0\n").unwrap();
    let out = surfrecon(&[
        "normals",
        path_str(&good),
        "-o",
        path_str(&output),
        "-k",
        "2",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(!output.exists());
}

/// `--data`: the distance from every datum to the mesh, alone or beside
/// the reference scores; a point set cannot be measured against.
#[test]
fn eval_data_reports_how_closely_the_data_is_reached() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = write_sphere(dir.path(), "mesh.ply", 1.0);
    // Points on the sphere's vertices plus one 0.05 outside (diagonal of
    // the data ≈ 2√3, so 0.05 is ≈ 1.4% of it).
    let sphere = icosphere(DVec3::ZERO, 1.0, 4);
    let mut points: Vec<DVec3> = sphere.vertices.iter().step_by(5).copied().collect();
    points.push(1.05 * sphere.vertices[3]);
    let data = dir.path().join("data.xyz");
    let cloud = PointCloud {
        positions: points.clone(),
        ..Default::default()
    };
    io::write(&data, &Geometry::from_points(cloud)).unwrap();
    let v = json_of(&surfrecon(&[
        "eval",
        path_str(&mesh),
        "--data",
        path_str(&data),
        "--json",
    ]));
    let fit = &v["data_fit"];
    assert_eq!(fit["points"], points.len());
    let diagonal = fit["diagonal"].as_f64().unwrap();
    let max = fit["max"].as_f64().unwrap() * diagonal;
    assert!((max - 0.05).abs() < 1e-4, "{fit}");
    let share = (points.len() - 1) as f64 / points.len() as f64;
    assert!(
        (fit["within_1pct"].as_f64().unwrap() - share).abs() < 1e-12,
        "{fit}"
    );
    assert!(v.get("chamfer_l1").is_none());
    // With a reference too: both reports.
    let both = json_of(&surfrecon(&[
        "eval",
        path_str(&mesh),
        "-r",
        path_str(&mesh),
        "--data",
        path_str(&data),
        "--json",
    ]));
    assert!(both["chamfer_l1"].as_f64().is_some() && both["data_fit"]["points"] == points.len());
    // Text table.
    let out = surfrecon(&["eval", path_str(&mesh), "--data", path_str(&data)]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("data within 1%"));
    // Neither option, or a point set as the candidate: one clear error.
    let none = surfrecon(&["eval", path_str(&mesh)]);
    assert!(!none.status.success());
    let points_only = surfrecon(&["eval", path_str(&data), "--data", path_str(&data)]);
    assert!(!points_only.status.success());
    assert!(String::from_utf8_lossy(&points_only.stderr).contains("holds no triangles"));
}

/// `--self-intersections` counts the crossing face pairs: none on a
/// sphere, and the pairs along the circle where two overlapping spheres
/// meet; the key is only there when asked for.
#[test]
fn eval_counts_self_intersections_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let single = write_sphere(dir.path(), "one.ply", 1.0);
    let mut two = icosphere(DVec3::ZERO, 1.0, 2);
    let other = icosphere(DVec3::new(1.0, 0.0, 0.0), 1.0, 2);
    let offset = two.vertices.len() as u32;
    two.normals = None;
    two.vertices.extend(&other.vertices);
    two.triangles
        .extend(other.triangles.iter().map(|t| t.map(|v| v + offset)));
    let pair = dir.path().join("two.ply");
    io::write(&pair, &Geometry::from_mesh(two)).unwrap();
    let count = |path: &Path| {
        let out = surfrecon(&["eval", path_str(path), "--self-intersections", "--json"]);
        json_of(&out)["self_intersecting_pairs"].as_u64().unwrap()
    };
    assert_eq!(count(&single), 0);
    assert!(count(&pair) > 16, "{}", count(&pair));
    let without = json_of(&surfrecon(&[
        "eval",
        path_str(&single),
        "--data",
        path_str(&single),
        "--json",
    ]));
    assert!(without.get("self_intersecting_pairs").is_none());
}
