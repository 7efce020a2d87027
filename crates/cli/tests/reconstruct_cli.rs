//! `surfrecon reconstruct` end to end: files in, closed surfaces out.

mod common;
use common::{json_of, path_str, surfrecon};

use std::path::Path;
use surfrecon_geom::metrics::topology;

/// Points on a sphere of radius 1 as an XYZ file (3 columns) or, with
/// `flat`, points on a circle (2 columns: 2D data).
fn write_points(path: &Path, flat: bool) {
    let mut text = String::new();
    let n = 2000;
    for i in 0..n {
        // Fibonacci sphere / evenly spaced circle: deterministic, uniform.
        let t = (i as f64 + 0.5) / n as f64;
        if flat {
            let a = t * std::f64::consts::TAU;
            text.push_str(&format!("{} {}\n", a.cos(), a.sin()));
        } else {
            let z = 1.0 - 2.0 * t;
            let r = (1.0 - z * z).sqrt();
            let a = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            text.push_str(&format!("{} {} {}\n", r * a.cos(), r * a.sin(), z));
        }
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn sphere_points_give_a_closed_mesh_and_json_summary() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sphere.xyz");
    let output = dir.path().join("out.ply");
    let field = dir.path().join("phi.nrrd");
    let shell = dir.path().join("phi.shell");
    write_points(&input, false);
    let summary = json_of(&surfrecon(&[
        "reconstruct",
        "--json",
        "--resolution",
        "32",
        path_str(&input),
        "-o",
        path_str(&output),
        "--field",
        path_str(&field),
        "--shell",
        path_str(&shell),
    ]));
    assert_eq!(summary["method"], "levelset");
    assert_eq!(summary["dimension"], 3);
    assert!(summary["output_counts"]["triangles"].as_u64().unwrap() > 1000);
    assert!(summary["band_nodes"].as_u64().unwrap() > 0);
    // The band lives in a few 8³ blocks near the surface, far fewer than
    // the grid has.
    let blocks = summary["band"]["blocks"].as_u64().unwrap();
    let nodes = summary["grid"]["nodes"].as_u64().unwrap();
    assert!(
        blocks > 0 && blocks * 512 < nodes,
        "{blocks} blocks, {nodes} nodes"
    );
    // Every stage ends by its convergence test, and says so.
    for stage in ["convection", "flow", "settle"] {
        for level in summary[stage].as_array().unwrap() {
            assert_eq!(level["stopped_by"], "convergence", "{stage}: {level}");
        }
    }
    assert_eq!(summary["cleaning"]["outliers_removed"], 0);
    let stages: Vec<&str> = summary["timings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["stage"].as_str().unwrap())
        .collect();
    for stage in ["distance", "tagging", "convection", "flow", "extract"] {
        assert!(
            stages.contains(&stage),
            "missing stage {stage} in {stages:?}"
        );
    }
    let mesh = surfrecon_geom::io::read(&output).unwrap();
    for v in &mesh.points.positions {
        assert!(
            (v.length() - 1.0).abs() < 0.1,
            "vertex at radius {}",
            v.length()
        );
    }
    // Every edge in exactly two triangles: closed.
    let t = topology(&mesh.to_mesh());
    assert!(t.watertight && t.nonmanifold_edges == 0, "{t:?}");
    assert!(std::fs::metadata(&field).unwrap().len() > 0);
    assert!(std::fs::metadata(&shell).unwrap().len() > 0);
}

#[test]
fn two_column_points_give_closed_curves() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("circle.xyz");
    let output = dir.path().join("curve.obj");
    write_points(&input, true);
    let summary = json_of(&surfrecon(&[
        "reconstruct",
        "--json",
        "--resolution",
        "64",
        path_str(&input),
        "-o",
        path_str(&output),
    ]));
    assert_eq!(summary["dimension"], 2);
    assert_eq!(summary["output_counts"]["curves"], 1);
    let curves = surfrecon_geom::io::read(&output).unwrap();
    assert_eq!(curves.lines.len(), 1);
    assert_eq!(curves.lines[0].first(), curves.lines[0].last());
}

#[test]
fn bad_input_and_parameters_fail_with_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.ply");
    let missing = surfrecon(&["reconstruct", "no/such/file.xyz", "-o", path_str(&output)]);
    assert!(!missing.status.success());
    let err = String::from_utf8_lossy(&missing.stderr);
    assert!(
        err.starts_with("error:") && err.contains("no/such/file.xyz"),
        "{err}"
    );

    let input = dir.path().join("sphere.xyz");
    write_points(&input, false);
    let bad_p = surfrecon(&[
        "reconstruct",
        "--p",
        "0.5",
        path_str(&input),
        "-o",
        path_str(&output),
    ]);
    assert!(!bad_p.status.success());
    let err = String::from_utf8_lossy(&bad_p.stderr);
    assert!(err.contains("p") && err.contains("≥ 1"), "{err}");
    assert!(!output.exists(), "a failed run must not leave an output");
}

/// Points along crossing cross-sections of a torus (shipped sample) take
/// the curve-network path and give one closed piece of genus 1 that
/// passes through the curves.
#[test]
fn crossing_curves_give_one_closed_torus() {
    let dir = tempfile::tempdir().unwrap();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/curves/torus_crosscut.xyz");
    let output = dir.path().join("torus.ply");
    let summary = json_of(&surfrecon(&[
        "reconstruct",
        "--json",
        path_str(&input),
        "-o",
        path_str(&output),
    ]));
    assert_eq!(summary["method"], "curve-network");
    assert_eq!(summary["curve_network"]["curves"], 9);
    // Every curve point on the surface (within 0.25% of the diagonal).
    assert_eq!(summary["data_fit"]["points"], 1000);
    assert_eq!(
        summary["data_fit"]["within_0_25pct"], 1.0,
        "{}",
        summary["data_fit"]
    );
    let mesh = surfrecon_geom::io::read(&output).unwrap().to_mesh();
    let topo = topology(&mesh);
    assert!(
        topo.watertight && topo.edge_manifold && topo.vertex_manifold,
        "{topo:?}"
    );
    assert_eq!((topo.components, topo.euler), (1, 0), "{topo:?}");
    // Near the torus (R = 0.75, r = 0.25 about z; diagonal 2.9) everywhere,
    // closer on average.
    let off: Vec<f64> = mesh
        .vertices
        .iter()
        .map(|v| {
            let ring = 0.75 * surfrecon_geom::DVec3::new(v.x, v.y, 0.0).normalize();
            (v.distance(ring) - 0.25).abs()
        })
        .collect();
    let worst = off.iter().copied().fold(0.0, f64::max);
    let mean = off.iter().sum::<f64>() / off.len() as f64;
    assert!(
        worst < 0.04 && mean < 0.006,
        "off the torus: max {worst}, mean {mean}"
    );
    // Opting out gives the level-set path.
    let plain = json_of(&surfrecon(&[
        "reconstruct",
        "--json",
        "--no-curve-network",
        "--resolution",
        "48",
        path_str(&input),
        "-o",
        path_str(&output),
    ]));
    assert_eq!(plain["method"], "levelset");
}

/// Contours on parallel slices stay on the contour-slice path even where
/// two contours of one slice cross each other (no network crossing: the
/// surface normal there is not the plane's).
#[test]
fn crossing_contours_within_slices_stay_a_slice_stack() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("stack.xyz");
    let output = dir.path().join("stack.ply");
    let mut text = String::new();
    for k in 0..6 {
        let z = 0.2 * k as f64;
        for centre in [-0.3, 0.3] {
            for i in 0..160 {
                let a = i as f64 / 160.0 * std::f64::consts::TAU;
                text.push_str(&format!(
                    "{} {} {z}\n",
                    centre + 0.5 * a.cos(),
                    0.5 * a.sin()
                ));
            }
        }
    }
    std::fs::write(&input, text).unwrap();
    let summary = json_of(&surfrecon(&[
        "reconstruct",
        "--json",
        path_str(&input),
        "-o",
        path_str(&output),
    ]));
    assert_eq!(summary["method"], "levelset");
    assert_eq!(summary["slices"]["count"], 6, "{}", summary["slices"]);
}

/// Sections of one object whose ear tip (two crossing loops above a
/// sphere of three great circles) crosses nothing else: joined to the body
/// by default and reported in `--json`; `--keep-pieces` leaves it apart.
#[test]
fn an_ear_tip_apart_is_joined_unless_pieces_are_kept() {
    use surfrecon_geom::curves::Curve;
    use surfrecon_geom::DVec3;
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let tip = DVec3::new(0.55, 0.55, 1.2);
    let curves = [
        Curve::circle(DVec3::ZERO, x, y, 1.0, 180),
        Curve::circle(DVec3::ZERO, y, z, 1.0, 180),
        Curve::circle(DVec3::ZERO, z, x, 1.0, 180),
        Curve::circle(tip, y, z, 0.25, 60),
        Curve::circle(tip, x, z, 0.25, 60),
    ];
    let mut obj = String::new();
    let mut first = 1;
    for c in &curves {
        for p in &c.points {
            obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        let ids: Vec<String> = (first..first + c.points.len())
            .map(|i| i.to_string())
            .collect();
        obj += &format!("l {} {first}\n", ids.join(" "));
        first += c.points.len();
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ear.obj");
    std::fs::write(&input, obj).unwrap();
    let output = dir.path().join("ear.ply");
    let run = |extra: &[&str]| {
        let mut args = vec!["reconstruct", "--json", "--resolution", "64"];
        args.extend_from_slice(extra);
        args.extend([path_str(&input), "-o", path_str(&output)]);
        let summary = json_of(&surfrecon(&args));
        let mesh = surfrecon_geom::io::read(&output).unwrap().to_mesh();
        (summary, topology(&mesh))
    };
    let (summary, topo) = run(&[]);
    assert_eq!((topo.components, topo.euler), (1, 2), "{topo:?}");
    let joining = &summary["curve_network"]["joining"];
    assert_eq!(joining["pieces_before"], 2, "{joining}");
    assert_eq!(joining["pieces_joined"], 1, "{joining}");
    assert_eq!(joining["gaps"][0]["bridged"], true, "{joining}");
    let (kept, topo) = run(&["--keep-pieces"]);
    assert_eq!(topo.components, 2, "{topo:?}");
    assert!(kept["curve_network"].get("joining").is_none(), "{kept}");
}
