//! End-to-end: `surfrecon reconstruct --method convection`.

mod common;
use common::{json_of, path_str as s, surfrecon};

use surfrecon_geom::metrics::topology;
use surfrecon_geom::shapes::{sample_surface, torus};
use surfrecon_geom::{io, Geometry, PointCloud};

#[test]
fn convection_interpolates_a_torus_and_reports_its_stages() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("torus.ply");
    let mut pc = sample_surface(&torus(1.0, 0.4, 120, 48), 4000, 7);
    pc.normals = None;
    io::write(&input, &Geometry::from_points(pc.clone())).unwrap();
    let out = dir.path().join("out.obj");
    let run = surfrecon(&[
        "--json",
        "reconstruct",
        s(&input),
        "-o",
        s(&out),
        "--method",
        "convection",
    ]);
    let json = json_of(&run);
    let report = &json["convection"];
    assert_eq!(report["points"], 4000);
    assert_eq!(report["kept_points"], 4000);
    assert_eq!(report["boundary_edges"], 0);
    for key in ["facets", "pockets_opened", "thin_parts", "thin_facet_pairs"] {
        assert!(report[key].is_u64(), "{key}: {json}");
    }
    for stage in ["delaunay", "convection", "pockets", "output"] {
        assert!(report["seconds"][stage].as_f64().unwrap() >= 0.0, "{json}");
    }
    let mesh = io::read(&out).unwrap().to_mesh();
    let t = topology(&mesh);
    assert!(t.watertight && t.vertex_manifold, "{t:?}");
    assert_eq!((t.components, t.euler), (1, 0));
    assert_eq!(report["facets"], t.faces);
    // Vertices are the input points, in input order, then those added on
    // curved edges.
    let added = report["curved_edges_split"].as_u64().unwrap() as usize;
    assert_eq!(mesh.vertices.len(), 4000 + added);
    for (v, p) in mesh.vertices.iter().zip(&pc.positions) {
        assert!(v.distance(*p) < 1e-6 * (1.0 + p.length()));
    }
}

#[test]
fn convection_rejects_flat_input_and_an_out_of_range_rho() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat.xyz");
    let points: Vec<_> = (0..30)
        .map(|i| glam::DVec3::new((i % 6) as f64, (i / 6) as f64, 0.5))
        .collect();
    io::write(&flat, &Geometry::from_points(PointCloud::new(points))).unwrap();
    let out = dir.path().join("out.ply");
    let run = surfrecon(&[
        "reconstruct",
        s(&flat),
        "-o",
        s(&out),
        "--method",
        "convection",
    ]);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("coplanar"), "{err}");
    assert!(!out.exists(), "no output file after a failure");

    let run = surfrecon(&[
        "reconstruct",
        s(&flat),
        "-o",
        s(&out),
        "--method",
        "convection",
        "--rho",
        "1.5",
    ]);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("rho = 1.5"), "{err}");
    assert!(!out.exists(), "no output file after a failure");
}

/// `--brush`: a finer radius around a spot keeps more points (all of the
/// extra ones within the brush); a malformed brush is one clear error.
#[test]
fn convection_brush_keeps_more_points_where_it_refines() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("torus.ply");
    let mut pc = sample_surface(&torus(1.0, 0.4, 120, 48), 4000, 9);
    pc.normals = None;
    io::write(&input, &Geometry::from_points(pc.clone())).unwrap();
    let run = |out: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "--json",
            "reconstruct",
            s(&input),
            "-o",
            s(out),
            "--method",
            "convection",
            "--rho",
            "0.03",
        ];
        args.extend_from_slice(extra);
        surfrecon(&args)
    };
    let (plain, brushed) = (dir.path().join("plain.ply"), dir.path().join("brush.ply"));
    let kept = |json: &serde_json::Value| {
        json["convection"]["points"].as_u64().unwrap()
            - json["convection"]["decimated"].as_u64().unwrap()
    };
    let a = json_of(&run(&plain, &[]));
    let b = json_of(&run(&brushed, &["--brush", "1.4,0,0,0.5,0.002"]));
    assert!(kept(&b) > kept(&a), "{} vs {}", kept(&b), kept(&a));
    let mesh = io::read(&brushed).unwrap().to_mesh();
    let used_near = |mesh: &surfrecon_geom::TriMesh| {
        let mut used = vec![false; mesh.vertices.len()];
        for &v in mesh.triangles.iter().flatten() {
            used[v as usize] = true;
        }
        let centre = glam::DVec3::new(1.4, 0.0, 0.0);
        (0..used.len())
            .filter(|&i| used[i] && mesh.vertices[i].distance(centre) < 0.5)
            .count()
    };
    let plain_mesh = io::read(&plain).unwrap().to_mesh();
    assert!(used_near(&mesh) > 2 * used_near(&plain_mesh));
    let t = topology(&mesh);
    assert!(t.watertight && t.vertex_manifold, "{t:?}");

    let bad = run(&dir.path().join("bad.ply"), &["--brush", "1,0,0,0.5"]);
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("X,Y,Z,R,RHO_C"), "{err}");
}

/// A sphere's sample with no point above z = 0.9: by default the cap's
/// cover is removed (one hole, reported on stderr and in `--json`);
/// `--cover-holes` keeps the sphere closed; `--open-holes` is accepted
/// and changes nothing.
#[test]
fn convection_leaves_an_unsampled_cap_open_unless_asked_to_cover_it() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("capless.xyz");
    let sphere = surfrecon_geom::shapes::icosphere(glam::DVec3::ZERO, 1.0, 5);
    let points: Vec<_> = sample_surface(&sphere, 6000, 3)
        .positions
        .into_iter()
        .filter(|p| p.z < 0.9)
        .collect();
    io::write(&input, &Geometry::from_points(PointCloud::new(points))).unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "--json",
            "reconstruct",
            s(&input),
            "-o",
            s(&out),
            "--method",
            "convection",
        ];
        args.extend_from_slice(extra);
        let run = surfrecon(&args);
        (json_of(&run), run, io::read(&out).unwrap().to_mesh())
    };

    let (json, plain, open) = run("open.ply", &[]);
    let report = &json["convection"];
    assert_eq!(report["sampling_holes_opened"], 1, "{json}");
    let t = topology(&open);
    assert!(t.edge_manifold && t.vertex_manifold, "{t:?}");
    assert_eq!((t.components, t.euler), (1, 1), "a disk: {t:?}");
    assert_eq!(report["boundary_edges"], t.boundary_edges);
    // The rim is the sample's edge below z = 0.9.
    let mut rim = std::collections::HashSet::new();
    for &[a, b, c] in &open.triangles {
        rim.extend([(a, b), (b, c), (c, a)]);
    }
    let rim_z: Vec<f64> = rim
        .iter()
        .filter(|&&(a, b)| !rim.contains(&(b, a)))
        .map(|&(a, _)| open.vertices[a as usize].z)
        .collect();
    assert!(rim_z.iter().all(|&z| (0.8..0.9).contains(&z)), "{rim_z:?}");
    let err = String::from_utf8_lossy(&plain.stderr);
    assert!(err.contains("left 1 hole(s) in the sampling open"), "{err}");

    let (json, _, mesh) = run("covered.ply", &["--cover-holes"]);
    assert_eq!(json["convection"]["sampling_holes_opened"], 0);
    assert_eq!(json["convection"]["boundary_edges"], 0);
    let t = topology(&mesh);
    assert!(t.watertight && t.vertex_manifold, "{t:?}");
    assert_eq!((t.components, t.euler), (1, 2));

    let (_, quiet, again) = run("again.ply", &["--open-holes", "--quiet"]);
    assert_eq!(again.triangles, open.triangles);
    assert!(
        quiet.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&quiet.stderr)
    );
}
