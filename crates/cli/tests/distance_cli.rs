//! End-to-end tests of `surfrecon distance`: real files in a temporary
//! directory, the real binary, its output files, stdout/stderr and exit code.

mod common;
use common::{json_of, path_str, surfrecon};

use std::path::{Path, PathBuf};
use std::process::Output;
use surfrecon_geom::shapes::icosphere;
use surfrecon_geom::{io, DVec3, Geometry};
use surfrecon_grid::field_io::{read_field, AnyField};

/// A failed run: exit code 1, one `error:` line naming `needle`.
fn assert_fails_with(out: &Output, needle: &str) {
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("error: ") && err.contains(needle), "{err}");
}

fn write_sphere(dir: &Path, name: &str, drop_triangle: bool) -> PathBuf {
    let path = dir.join(name);
    let mut mesh = icosphere(DVec3::ZERO, 1.0, 3);
    if drop_triangle {
        mesh.triangles.pop();
    }
    io::write(&path, &Geometry::from_mesh(mesh)).unwrap();
    path
}

#[test]
fn signed_sphere_field_round_trips_through_nrrd() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_sphere(dir.path(), "sphere.ply", false);
    let output = dir.path().join("sphere.nrrd");
    let out = surfrecon(&[
        "distance",
        path_str(&input),
        "-o",
        path_str(&output),
        "--signed",
        "--resolution",
        "32",
        "--padding",
        "2",
        "--json",
    ]);
    let v = json_of(&out);
    assert_eq!(v["dims"], serde_json::json!([37, 37, 37]));
    assert_eq!(v["signed"], true);
    assert!(v["seconds"]["compute"].as_f64().unwrap() >= 0.0);
    let AnyField::D3(field) = read_field(&output).unwrap() else {
        panic!("expected a 3D field");
    };
    let spec = field.spec;
    assert_eq!(spec.dims, [37, 37, 37]);
    for l in 0..spec.node_count() {
        let p = DVec3::from_array(spec.position(spec.unlinear(l)));
        let exact = p.length() - 1.0;
        // Icosphere of 1280 triangles: within its chord sag of the sphere.
        assert!((field.values[l] - exact).abs() < 0.02, "at {p}");
    }
}

#[test]
fn flat_points_give_a_2d_field() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("pts.xyz");
    std::fs::write(&input, "0 0 0\n1 0 0\n0 2 0\n").unwrap();
    let output = dir.path().join("pts.vtk");
    let out = surfrecon(&[
        "distance",
        path_str(&input),
        "-o",
        path_str(&output),
        "--spacing",
        "0.1",
        "--json",
    ]);
    let v = json_of(&out);
    assert_eq!(v["dimension"], 2);
    let AnyField::D2(field) = read_field(&output).unwrap() else {
        panic!("expected a 2D field");
    };
    let data = [[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]];
    for l in 0..field.spec.node_count() {
        let p = field.spec.position(field.spec.unlinear(l));
        let exact = data
            .iter()
            .map(|d| ((p[0] - d[0]).powi(2) + (p[1] - d[1]).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        assert!((field.values[l] - exact).abs() < 1e-5, "at {p:?}");
    }
}

#[test]
fn band_clamps_far_values() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_sphere(dir.path(), "sphere.obj", false);
    let output = dir.path().join("band.nrrd");
    let out = surfrecon(&[
        "distance",
        path_str(&input),
        "-o",
        path_str(&output),
        "--signed",
        "--band",
        "0.2",
        "--resolution",
        "24",
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let AnyField::D3(field) = read_field(&output).unwrap() else {
        panic!("expected a 3D field");
    };
    assert!(field.values.iter().all(|v| v.abs() <= 0.2));
    assert!(field.values.contains(&-0.2) && field.values.contains(&0.2));
}

#[test]
fn open_mesh_is_refused_for_signed_unless_allowed() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_sphere(dir.path(), "holey.ply", true);
    let output = dir.path().join("holey.nrrd");
    let args = [
        "distance",
        path_str(&input),
        "-o",
        path_str(&output),
        "--signed",
        "--resolution",
        "16",
    ];
    let out = surfrecon(&args);
    assert_fails_with(&out, "holey.ply");
    assert_fails_with(&out, "not closed: 3 boundary edges");
    assert!(!output.exists(), "no output after a failure");
    let out = surfrecon(&[&args[..], &["--allow-open"]].concat());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(output.exists());
}

#[test]
fn bad_options_and_huge_grids_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_sphere(dir.path(), "s.ply", false);
    let output = dir.path().join("s.nrrd");
    let run = |extra: &[&str]| {
        let base = ["distance", path_str(&input), "-o", path_str(&output)];
        surfrecon(&[&base[..], extra].concat())
    };
    assert_fails_with(&run(&["--spacing=-1"]), "--spacing must be a positive");
    assert_fails_with(&run(&["--band", "0"]), "--band must be a positive");
    assert_fails_with(
        &run(&["--resolution", "0"]),
        "--resolution must be at least 1",
    );
    assert_fails_with(&run(&["--spacing", "0.0005"]), "--resolution");
    assert_fails_with(&run(&["--2d", "--signed"]), "2D");
    let clash = run(&["--resolution", "8", "--spacing", "0.1"]);
    assert_eq!(clash.status.code(), Some(2), "clap usage error");
    let missing = surfrecon(&["distance", "/nonexistent/x.ply", "-o", path_str(&output)]);
    assert_fails_with(&missing, "/nonexistent/x.ply");
    assert!(!output.exists());
}
