//! `surfrecon convert` and `surfrecon info` end to end.

mod common;
use common::surfrecon;

use std::path::Path;
use std::process::Output;
use surfrecon_geom::io::{self, Format};
use surfrecon_geom::{shapes, DVec3, Geometry, PointCloud};

fn arg(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn sphere() -> Geometry {
    let mut g = Geometry::from_mesh(shapes::icosphere(DVec3::ZERO, 2.0, 2));
    g.points.normals = Some(g.points.positions.iter().map(|p| p.normalize()).collect());
    g
}

#[test]
fn convert_chain_keeps_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("sphere.ply");
    io::write(&ply, &sphere()).unwrap();
    let obj = dir.path().join("sphere.obj");
    let off = dir.path().join("sphere.off");
    let back = dir.path().join("back.ply");
    for (from, to) in [(&ply, &obj), (&obj, &off), (&off, &back)] {
        let out = surfrecon(&["convert", arg(from), arg(to)]);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    assert_eq!(io::read(&back).unwrap(), sphere());
}

#[test]
fn convert_ascii_and_format_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("points.dat");
    std::fs::write(&input, "0 0 0\n1 0 0\n0 1 0.5\n").unwrap();
    let output = dir.path().join("points.out");
    let out = surfrecon(&[
        "convert",
        arg(&input),
        arg(&output),
        "--from",
        "xyz",
        "--to",
        "ply",
        "--ascii",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&output).unwrap();
    assert!(text.starts_with("ply\nformat ascii 1.0\n"), "{text}");
    let g = io::read_as(&output, Format::Ply).unwrap();
    assert_eq!(g.points.positions[2], DVec3::new(0.0, 1.0, 0.5));
}

#[test]
fn failed_conversion_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("broken.obj");
    std::fs::write(&input, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap();
    let output = dir.path().join("out.ply");
    let out = surfrecon(&["convert", arg(&input), arg(&output)]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("error: ") && err.contains("broken.obj: line 4"),
        "{err}"
    );
    assert!(err.contains("out of range"), "{err}");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "only the input"
    );
}

#[test]
fn points_to_stl_is_refused_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cloud.xyz");
    io::write(
        &input,
        &Geometry::from_points(PointCloud::new(vec![DVec3::X, DVec3::Y])),
    )
    .unwrap();
    let output = dir.path().join("cloud.stl");
    let out = surfrecon(&["convert", arg(&input), arg(&output)]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("triangles"), "{}", stderr(&out));
    assert!(!output.exists());
}

#[test]
fn unknown_formats_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("scan.pcd");
    std::fs::write(&input, "x").unwrap();
    let out = surfrecon(&["info", arg(&input)]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("unknown file format"),
        "{}",
        stderr(&out)
    );
    let out = surfrecon(&["convert", arg(&input), "out.ply", "--from", "pcd"]);
    assert!(!out.status.success());
}

#[test]
fn info_json_reports_counts_bounds_and_spacing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grid.xyz");
    // A 10 x 10 grid with step 0.25 in the plane z = 2.
    let points = (0..100)
        .map(|i| DVec3::new((i % 10) as f64 * 0.25, (i / 10) as f64 * 0.25, 2.0))
        .collect();
    io::write(&path, &Geometry::from_points(PointCloud::new(points))).unwrap();
    let out = surfrecon(&["--json", "info", arg(&path)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["points"], 100);
    assert_eq!(v["triangles"], 0);
    assert_eq!(v["has_normals"], false);
    assert_eq!(v["bounds"]["max"], serde_json::json!([2.25, 2.25, 2.0]));
    let diagonal = v["diagonal"].as_f64().unwrap();
    assert!((diagonal - 2.25 * 2f64.sqrt()).abs() < 1e-12);
    assert!((v["mean_spacing"].as_f64().unwrap() - 0.25).abs() < 1e-12);
}

#[test]
fn info_text_on_a_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.ply");
    io::write(&path, &sphere()).unwrap();
    let out = surfrecon(&["info", arg(&path)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("points        162"), "{text}");
    assert!(text.contains("triangles     320"), "{text}");
    assert!(text.contains("normals       yes"), "{text}");
}
