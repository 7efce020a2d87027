//! End-to-end tests of the feature-keeping fields: `distance --kind
//! odf|udf`, `extract` and `sculpt` on real files with the real binary.

mod common;
use common::{json_of, path_str, surfrecon};

use std::path::{Path, PathBuf};
use std::process::Output;
use surfrecon_geom::metrics::topology;
use surfrecon_geom::shapes::cuboid;
use surfrecon_geom::{io, DVec3, Geometry, TriMesh};

fn assert_fails_with(out: &Output, needle: &str) {
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("error: ") && err.contains(needle), "{err}");
}

/// A box 1.0 × 0.8 × 0.7, turned a little about two axes.
fn write_box(dir: &Path) -> PathBuf {
    let b = cuboid(DVec3::new(-0.5, -0.4, -0.35), DVec3::new(0.5, 0.4, 0.35));
    let r = glam::DMat3::from_rotation_z(0.2) * glam::DMat3::from_rotation_x(0.15);
    let mesh = TriMesh {
        vertices: b.vertices.iter().map(|&v| r * v).collect(),
        ..b
    };
    let path = dir.join("box.ply");
    io::write(&path, &Geometry::from_mesh(mesh)).unwrap();
    path
}

/// The turned box and its unified field at `resolution` cells.
fn box_udf(dir: &Path, resolution: &str) -> (PathBuf, PathBuf) {
    let input = write_box(dir);
    let field = dir.join("box.udf");
    let out = surfrecon(&[
        "distance",
        path_str(&input),
        "-o",
        path_str(&field),
        "--kind",
        "udf",
        "--resolution",
        resolution,
        "--json",
    ]);
    json_of(&out);
    (input, field)
}

fn read_mesh(path: &Path) -> TriMesh {
    io::read(path).unwrap().to_mesh()
}

/// The largest distance from a corner of `shape` to the surface `mesh`
/// (nearest vertex: exact for corners that are mesh vertices).
fn corner_miss(shape: &TriMesh, mesh: &TriMesh) -> f64 {
    shape
        .vertices
        .iter()
        .map(|c| {
            mesh.vertices
                .iter()
                .map(|v| v.distance(*c))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

#[test]
fn udf_and_odf_files_extract_to_closed_surfaces_with_sharp_corners() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_box(dir.path());
    let shape = read_mesh(&input);
    for kind in ["udf", "odf"] {
        let field = dir.path().join(format!("box.{kind}"));
        let out = surfrecon(&[
            "distance",
            path_str(&input),
            "-o",
            path_str(&field),
            "--kind",
            kind,
            "--resolution",
            "20",
            "--json",
        ]);
        let v = json_of(&out);
        assert_eq!(v["kind"], kind);
        let h = v["spacing"].as_f64().unwrap();
        assert!(v["seconds"]["compute"].as_f64().unwrap() >= 0.0);
        let counts = &v[kind];
        if kind == "udf" {
            assert!(counts["feature_points"].as_u64().unwrap() > 0, "{v}");
            assert!(
                counts["sample_positions"].as_u64().unwrap() > 0,
                "samples on corners: {v}"
            );
        } else {
            assert!(counts["samples_moved"].as_u64().unwrap() > 0, "{v}");
            assert!(counts["samples_aligned"].as_u64().unwrap() > 0, "{v}");
        }
        let mesh_path = dir.path().join(format!("box_{kind}.ply"));
        let v = json_of(&surfrecon(&[
            "extract",
            path_str(&field),
            "-o",
            path_str(&mesh_path),
            "--json",
        ]));
        assert_eq!(v["result"]["watertight"], true);
        let mesh = read_mesh(&mesh_path);
        let t = topology(&mesh);
        assert!(
            t.watertight && t.vertex_manifold && t.components == 1 && t.euler == 2,
            "{kind}: {t:?}"
        );
        if kind == "udf" {
            let miss = corner_miss(&shape, &mesh);
            assert!(miss < 0.02 * h, "udf corners within {miss} (h {h})");
        }
    }
}

#[test]
fn sculpting_applies_steps_in_order_and_keeps_the_kind() {
    let dir = tempfile::tempdir().unwrap();
    let (input, field) = box_udf(dir.path(), "20");
    // A sphere added and then carved again leaves the box; carved first
    // and added then, the sphere stays.
    let sphere = "sphere:0.5,0,0,0.25";
    let (a, b) = (dir.path().join("a.udf"), dir.path().join("b.udf"));
    let v = json_of(&surfrecon(&[
        "sculpt",
        path_str(&field),
        "-o",
        path_str(&a),
        "--union",
        sphere,
        "--subtract",
        sphere,
        "--json",
    ]));
    assert_eq!(v["steps"][0]["operation"], "union");
    assert_eq!(v["steps"][1]["operation"], "subtract");
    surfrecon(&[
        "sculpt",
        path_str(&field),
        "-o",
        path_str(&b),
        "--subtract",
        sphere,
        "--union",
        sphere,
        "--quiet",
    ]);
    let surface = |f: &Path| {
        let out = dir.path().join("s.ply");
        json_of(&surfrecon(&[
            "extract",
            path_str(f),
            "-o",
            path_str(&out),
            "--json",
        ]));
        read_mesh(&out)
    };
    let reaches = |m: &TriMesh| {
        m.vertices
            .iter()
            .map(|v| v.x)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let (carved, kept) = (surface(&a), surface(&b));
    // (The box itself reaches x = 0.58.)
    assert!(
        reaches(&kept) > 0.74 && reaches(&carved) < 0.6,
        "{} / {}",
        reaches(&kept),
        reaches(&carved)
    );
    // Drilling through keeps one closed piece, now of genus 1.
    let drilled = dir.path().join("drilled.udf");
    let v = json_of(&surfrecon(&[
        "sculpt",
        path_str(&field),
        "-o",
        path_str(&drilled),
        "--subtract",
        "cylinder:0,0,-1,0,0,1,0.2",
        "--json",
    ]));
    assert!(
        v["steps"][0]["edge_points_kept"].as_u64().unwrap() > 10,
        "{v}"
    );
    let t = topology(&surface(&drilled));
    assert!(t.watertight && t.components == 1 && t.euler == 0, "{t:?}");
    // A regular field stays regular.
    let nrrd = dir.path().join("box.nrrd");
    surfrecon(&[
        "distance",
        path_str(&input),
        "-o",
        path_str(&nrrd),
        "--signed",
        "--resolution",
        "20",
        "--quiet",
    ]);
    let out = dir.path().join("cut.nrrd");
    json_of(&surfrecon(&[
        "sculpt",
        path_str(&nrrd),
        "-o",
        path_str(&out),
        "--subtract",
        sphere,
        "--json",
    ]));
    assert!(out.exists());
}

#[test]
fn bad_fields_tools_and_meshes_get_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let (input, field) = box_udf(dir.path(), "12");
    let out = dir.path().join("out.udf");
    let run = |args: &[&str]| surfrecon(args);
    // Open mesh.
    let mut open = read_mesh(&input);
    open.triangles.pop();
    let open_path = dir.path().join("open.ply");
    io::write(&open_path, &Geometry::from_mesh(open)).unwrap();
    assert_fails_with(
        &run(&[
            "distance",
            path_str(&open_path),
            "-o",
            path_str(&out),
            "--kind",
            "udf",
        ]),
        "not closed",
    );
    // Wrong output extension.
    assert_fails_with(
        &run(&[
            "distance",
            path_str(&input),
            "-o",
            "x.nrrd",
            "--kind",
            "udf",
        ]),
        ".udf file",
    );
    // Truncated field.
    let bytes = std::fs::read(&field).unwrap();
    let cut = dir.path().join("cut.udf");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    assert_fails_with(
        &run(&[
            "extract",
            path_str(&cut),
            "-o",
            path_str(&dir.path().join("m.ply")),
        ]),
        "truncated",
    );
    // Bad tools.
    assert_fails_with(
        &run(&[
            "sculpt",
            path_str(&field),
            "-o",
            path_str(&out),
            "--subtract",
            "sphere:0,0,0",
        ]),
        "sphere:x,y,z,r",
    );
    assert_fails_with(
        &run(&[
            "sculpt",
            path_str(&field),
            "-o",
            path_str(&out),
            "--subtract",
            "sphere:0,0,0,-1",
        ]),
        "positive radius",
    );
    assert_fails_with(
        &run(&[
            "sculpt",
            path_str(&field),
            "-o",
            path_str(&out),
            "--subtract",
            "nothing.ply",
        ]),
        "no such file",
    );
    assert_fails_with(
        &run(&[
            "sculpt",
            path_str(&field),
            "-o",
            path_str(&out),
            "--subtract",
            path_str(&open_path),
        ]),
        "not closed",
    );
    assert_fails_with(
        &run(&["sculpt", path_str(&field), "-o", path_str(&out)]),
        "nothing to do",
    );
    // The kind is kept: a .udf cannot be written as .odf.
    assert_fails_with(
        &run(&[
            "sculpt",
            path_str(&field),
            "-o",
            "x.odf",
            "--subtract",
            "sphere:0,0,0,0.1",
        ]),
        ".udf",
    );
    // A damaged .udf is refused as one; an unknown extension names all four kinds.
    let empty = dir.path().join("empty.udf");
    std::fs::write(&empty, b"").unwrap();
    let mesh_out = dir.path().join("m.ply");
    assert_fails_with(
        &run(&["extract", path_str(&empty), "-o", path_str(&mesh_out)]),
        "truncated: 0 bytes, shorter than the 8-byte magic",
    );
    assert_fails_with(
        &run(&["extract", path_str(&input), "-o", path_str(&mesh_out)]),
        "(supported: nrrd, vtk, odf, udf)",
    );
    // Energy weights: the distance term must be on, the others ≥ 0.
    let odf = dir.path().join("out.odf");
    for (flag, needle) in [
        (
            "--lambda-distance=0",
            "the distance weight must be a positive number, not 0",
        ),
        (
            "--lambda-spring=-1",
            "the spring weight must be a number ≥ 0, not -1",
        ),
        (
            "--lambda-ortho=NaN",
            "the ortho weight must be a number ≥ 0, not NaN",
        ),
        ("--iterations=21", "at most 20 search rounds, not 21"),
    ] {
        let args = [
            "distance",
            path_str(&input),
            "-o",
            path_str(&odf),
            "--kind",
            "odf",
            flag,
        ];
        assert_fails_with(&run(&args), needle);
    }
    assert!(!out.exists() && !odf.exists(), "no output after a failure");
}

/// Write `mesh` to `dir/name`.
fn write_mesh(dir: &Path, name: &str, mesh: TriMesh) -> PathBuf {
    let path = dir.join(name);
    io::write(&path, &Geometry::from_mesh(mesh)).unwrap();
    path
}

/// Tools from files and the third operation: an offset field intersected
/// with a closed mesh (a slab), then united with another field's surface
/// (a small cube's unified field), stays an offset field and lies where
/// the exact boolean does.
#[test]
fn offset_fields_take_mesh_and_field_tools_and_intersect() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_box(dir.path());
    let odf = dir.path().join("box.odf");
    let v = json_of(&surfrecon(&[
        "distance",
        path_str(&input),
        "-o",
        path_str(&odf),
        "--kind",
        "odf",
        "--resolution",
        "20",
        "--json",
    ]));
    let h = v["spacing"].as_f64().unwrap();
    let slab = cuboid(DVec3::new(-2.0, -2.0, -2.0), DVec3::new(0.2, 2.0, 2.0));
    let slab = write_mesh(dir.path(), "slab.ply", slab);
    let cube = cuboid(DVec3::new(0.4, -0.12, -0.12), DVec3::new(0.65, 0.12, 0.12));
    let cube = write_mesh(dir.path(), "cube.ply", cube);
    let cube_field = dir.path().join("cube.udf");
    surfrecon(&[
        "distance",
        path_str(&cube),
        "-o",
        path_str(&cube_field),
        "--kind",
        "udf",
        "--resolution",
        "12",
        "--quiet",
    ]);
    let out = dir.path().join("cut.odf");
    let v = json_of(&surfrecon(&[
        "sculpt",
        path_str(&odf),
        "-o",
        path_str(&out),
        "--intersect",
        path_str(&slab),
        "--union",
        path_str(&cube_field),
        "--json",
    ]));
    assert_eq!(v["steps"][0]["operation"], "intersect");
    assert_eq!(v["steps"][1]["operation"], "union");
    let mesh_path = dir.path().join("cut.ply");
    json_of(&surfrecon(&[
        "extract",
        path_str(&out),
        "-o",
        path_str(&mesh_path),
        "--json",
    ]));
    assert_eq!(&std::fs::read(&out).unwrap()[..5], b"SRODF");
    let mesh = read_mesh(&mesh_path);
    let t = topology(&mesh);
    assert!(
        t.watertight && t.vertex_manifold && t.components == 2 && t.euler == 4,
        "the cut box and the cube: {t:?}"
    );
    let xs: Vec<f64> = mesh.vertices.iter().map(|v| v.x).collect();
    let max_x = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!((max_x - 0.65).abs() < 0.3 * h, "reaches x = {max_x}");
    let in_gap = xs
        .iter()
        .filter(|&&x| x > 0.2 + 0.3 * h && x < 0.4 - 0.3 * h);
    assert_eq!(in_gap.count(), 0, "nothing between the cut and the cube");
}

/// Grids the machine cannot hold are refused before any work, and a
/// self-intersecting mesh is refused by the offset field, each with one
/// clear error; a cut .odf is refused as a .udf is.
#[test]
fn oversized_grids_self_intersections_and_cut_odfs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_box(dir.path());
    let run = |args: &[&str]| surfrecon(args);
    for kind in ["udf", "odf"] {
        let out = dir.path().join(format!("big.{kind}"));
        // 1500 cells: about 2e9 samples, some 90 GB (fails only on a
        // machine with more than 110 GB available).
        let started = std::time::Instant::now();
        assert_fails_with(
            &run(&[
                "distance",
                path_str(&input),
                "-o",
                path_str(&out),
                "--kind",
                kind,
                "--resolution",
                "1500",
            ]),
            "MB available; try --resolution",
        );
        assert!(started.elapsed().as_secs_f64() < 5.0, "refused up front");
    }
    let mut both = cuboid(DVec3::splat(-0.5), DVec3::splat(0.5));
    both.append(&cuboid(
        DVec3::new(-0.1, -0.2, -0.3),
        DVec3::new(0.9, 0.8, 0.7),
    ));
    let crossing = write_mesh(dir.path(), "crossing.ply", both);
    let odf = dir.path().join("x.odf");
    assert_fails_with(
        &run(&[
            "distance",
            path_str(&crossing),
            "-o",
            path_str(&odf),
            "--kind",
            "odf",
            "--resolution",
            "12",
        ]),
        "intersects itself",
    );
    // The unified field takes it (signed by winding number).
    let udf = dir.path().join("x.udf");
    let out = run(&[
        "distance",
        path_str(&crossing),
        "-o",
        path_str(&udf),
        "--kind",
        "udf",
        "--resolution",
        "12",
        "--quiet",
    ]);
    assert!(out.status.success() && udf.exists());
    // A cut .odf.
    run(&[
        "distance",
        path_str(&input),
        "-o",
        path_str(&odf),
        "--kind",
        "odf",
        "--resolution",
        "12",
        "--quiet",
    ]);
    let bytes = std::fs::read(&odf).unwrap();
    let cut = dir.path().join("cut.odf");
    std::fs::write(&cut, &bytes[..bytes.len() - 5]).unwrap();
    assert_fails_with(
        &run(&[
            "extract",
            path_str(&cut),
            "-o",
            path_str(&dir.path().join("m.ply")),
        ]),
        "moved samples announced but",
    );
}
