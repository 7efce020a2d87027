//! End-to-end tests of `extract`, `shell` and `unshell` through the binary.

mod common;
use common::{path_str, surfrecon};

use surfrecon_geom::{io, metrics, DVec3};
use surfrecon_grid::field_io::{read_field, write_field, AnyField};
use surfrecon_grid::{Field, Field2, Field3, GridSpec};

fn sphere_field(n: usize) -> Field3 {
    let spec = GridSpec {
        origin: [-1.0; 3],
        spacing: 2.0 / (n - 1) as f64,
        dims: [n; 3],
    };
    let c = DVec3::new(0.03, -0.02, 0.01);
    let values = (0..spec.node_count())
        .map(|l| (DVec3::from_array(spec.position(spec.unlinear(l))) - c).length() - 0.6)
        .collect();
    Field { spec, values }
}

fn circle_field() -> Field2 {
    let spec = GridSpec {
        origin: [-1.0; 2],
        spacing: 0.05,
        dims: [41, 41],
    };
    let values = (0..spec.node_count())
        .map(|l| {
            let p = spec.position(spec.unlinear(l));
            p[0].hypot(p[1]) - 0.5
        })
        .collect();
    Field { spec, values }
}

#[test]
fn extract_3d_field_gives_watertight_mesh_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let field = dir.path().join("sphere.nrrd");
    write_field(&field, &sphere_field(30)).unwrap();
    let mesh = dir.path().join("sphere.ply");
    let out = surfrecon(&["--json", "extract", path_str(&field), "-o", path_str(&mesh)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["result"]["watertight"], true);
    assert_eq!(summary["result"]["euler"], 2);
    let topo = metrics::topology(&io::read(&mesh).unwrap().to_mesh());
    assert!(topo.watertight && topo.edge_manifold && topo.vertex_manifold);
    // A shifted level: --iso takes negative values.
    let inner = dir.path().join("inner.obj");
    let out = surfrecon(&[
        "extract",
        path_str(&field),
        "-o",
        path_str(&inner),
        "--iso",
        "-0.2",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r = io::read(&inner).unwrap().bounds().size().x / 2.0;
    assert!((r - 0.4).abs() < 0.02, "radius {r}");
}

#[test]
fn extract_2d_field_gives_closed_obj_curves() {
    let dir = tempfile::tempdir().unwrap();
    let field = dir.path().join("circle.vtk");
    write_field(&field, &circle_field()).unwrap();
    let curves = dir.path().join("circle.obj");
    let out = surfrecon(&["extract", path_str(&field), "-o", path_str(&curves)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let geom = io::read(&curves).unwrap();
    assert_eq!(geom.lines.len(), 1);
    assert_eq!(geom.lines[0].first(), geom.lines[0].last());
    // Curves cannot go to a mesh-only format; nothing is written.
    let ply = dir.path().join("circle.ply");
    let out = surfrecon(&["extract", path_str(&field), "-o", path_str(&ply)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains(".obj"));
    assert!(!ply.exists());
}

#[test]
fn bad_inputs_fail_with_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let field = dir.path().join("sphere.nrrd");
    write_field(&field, &sphere_field(10)).unwrap();
    let mesh = dir.path().join("m.ply");
    let out = surfrecon(&[
        "extract",
        path_str(&field),
        "-o",
        path_str(&mesh),
        "--iso",
        "5",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("never crosses"),
        "{err}"
    );
    assert!(!mesh.exists());
    let broken = dir.path().join("broken.nrrd");
    let bytes = std::fs::read(&field).unwrap();
    std::fs::write(&broken, &bytes[..bytes.len() / 2]).unwrap();
    for cmd in ["extract", "shell"] {
        let out = surfrecon(&[cmd, path_str(&broken), "-o", path_str(&mesh)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1));
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.starts_with("error:") && err.contains("broken.nrrd") && err.contains("truncated"),
            "{err}"
        );
    }
    let out = surfrecon(&["unshell", path_str(&field), "-o", path_str(&mesh)]);
    assert!(!out.status.success());
}

#[test]
fn shell_then_unshell_restores_the_field_near_the_surface() {
    let dir = tempfile::tempdir().unwrap();
    let original = sphere_field(32);
    let field = dir.path().join("sdf.nrrd");
    write_field(&field, &original).unwrap();
    let shell = dir.path().join("sdf.shell");
    let out = surfrecon(&["--json", "shell", path_str(&field), "-o", path_str(&shell)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(summary["size_ratio"].as_f64().unwrap() > 5.0, "{summary}");
    let rebuilt = dir.path().join("rebuilt.vtk");
    let out = surfrecon(&["unshell", path_str(&shell), "-o", path_str(&rebuilt)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let AnyField::D3(back) = read_field(&rebuilt).unwrap() else {
        panic!("expected a 3D field");
    };
    assert_eq!(back.spec, original.spec);
    let h = original.spec.spacing;
    for (a, b) in original.values.iter().zip(&back.values) {
        assert_eq!(*a < 0.0, *b < 0.0);
        assert!((a - b).abs() < h, "{a} vs {b}");
    }
    let on_shell = surfrecon_grid::shell::Shell::from_field(&original).indices;
    assert!(!on_shell.is_empty());
    for l in on_shell {
        let (a, b) = (original.values[l as usize], back.values[l as usize]);
        assert!((a - b).abs() <= 1e-6 * h, "shell node {l}: {a} vs {b}");
    }
}
