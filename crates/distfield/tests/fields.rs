//! Distance fields that keep corners: exact corner positions against the
//! regular field, closed manifold output, file round trips.

use surfrecon_distfield::grid_for;
use surfrecon_distfield::query::{deviation, lattice_points, MeshQuery};
use surfrecon_distfield::unified::{build_udf, Extra, UdfOptions, UnifiedField};
use surfrecon_geom::metrics::topology;
use surfrecon_geom::shapes::{cuboid, octahedron};
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::{marching::marching_cubes, sdf::signed_distance, GridSize};

/// Rotation by Euler angles (radians) about x, then y, then z.
fn rotate(mesh: &TriMesh, angles: [f64; 3]) -> TriMesh {
    let r = glam::DMat3::from_rotation_z(angles[2])
        * glam::DMat3::from_rotation_y(angles[1])
        * glam::DMat3::from_rotation_x(angles[0]);
    TriMesh {
        vertices: mesh.vertices.iter().map(|&v| r * v).collect(),
        ..mesh.clone()
    }
}

fn rotated_cube() -> TriMesh {
    rotate(
        &cuboid(DVec3::splat(-0.5), DVec3::splat(0.5)),
        [0.3, 0.5, 0.7],
    )
}

/// Distance from each corner of `shape` (its vertices) to `surface`.
fn corner_errors(shape: &TriMesh, surface: &TriMesh) -> Vec<f64> {
    let q = MeshQuery::new(surface).unwrap();
    shape
        .vertices
        .iter()
        .map(|&v| q.signed_distance(v).abs())
        .collect()
}

/// The unified field of `shape` with default options at `size`.
fn udf_of(
    shape: &TriMesh,
    size: GridSize,
) -> (
    surfrecon_distfield::unified::UnifiedField,
    surfrecon_distfield::unified::UdfReport,
) {
    build_udf(
        shape,
        &UdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The offset field of `shape` with default options at `size`.
fn odf_of(
    shape: &TriMesh,
    size: GridSize,
) -> (
    surfrecon_distfield::offset::OffsetField,
    surfrecon_distfield::offset::OdfReport,
) {
    use surfrecon_distfield::offset::{build_odf, OdfOptions};
    build_odf(
        shape,
        &OdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The regular signed distance field of `shape` (2 cells of padding).
fn regular_field(shape: &TriMesh, size: GridSize) -> surfrecon_grid::Field3 {
    signed_distance(shape, &grid_for(shape, size, 2).unwrap(), None).unwrap()
}

/// (max, mean) of the exact distances both ways between `shape` and `mesh`.
fn two_way_error(
    shape: &TriMesh,
    exact: &MeshQuery,
    mesh: &TriMesh,
    per_triangle: usize,
) -> (f64, f64) {
    let there = deviation(mesh, exact, per_triangle);
    let back = deviation(shape, &MeshQuery::new(mesh).unwrap(), per_triangle);
    (there.max.max(back.max), 0.5 * (there.mean + back.mean))
}

fn assert_closed_manifold(mesh: &TriMesh, euler: i64) {
    let t = topology(mesh);
    assert!(t.watertight && t.vertex_manifold, "{t:?}");
    assert_eq!((t.components, t.euler), (1, euler), "{t:?}");
}

/// No two triangles of `mesh` cross (exact test). Before session 35 a
/// sample on the surface left its crossings' cluster of vertices 0.001 h
/// apart, whose slivers pierced their neighbours at sharp edges.
fn assert_no_crossings(mesh: &TriMesh, what: &str) {
    let pairs = surfrecon_geom::intersections::self_intersections(mesh);
    assert!(
        pairs.is_empty(),
        "{what}: {} crossing triangle pairs",
        pairs.len()
    );
}

fn check_corners_kept(shape: TriMesh, cells: usize) {
    let size = GridSize::Resolution(cells);
    let (udf, report) = udf_of(&shape, size);
    let h = udf.spec.spacing;
    let (mesh, extract) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let kept = corner_errors(&shape, &mesh);
    let regular_field = regular_field(&shape, size);
    let regular = corner_errors(&shape, &marching_cubes(&regular_field, 0.0));
    // The regular field's corners are cut by a good part of a cell.
    eprintln!("{report:?} {extract:?}\nudf corners {kept:?}\nregular {regular:?} (h {h})");
    assert!(
        kept.iter().all(|&d| d < 0.02 * h),
        "udf corners {kept:?}, h {h}"
    );
    assert!(
        regular.iter().any(|&d| d > 0.2 * h),
        "the regular field cuts corners: {regular:?}"
    );
    // Everywhere, not only at the corners, the surface is closer than the
    // regular field's. (Not yet everywhere within the issue's 0.1 h: near
    // corners, fans reaching a corner in a cell without sign changes stray
    // by up to 0.32 h; 0.45 h before cells beside an edge joined their
    // neighbour's fan.)
    let exact = MeshQuery::new(&shape).unwrap();
    let regular_mesh = marching_cubes(&regular_field, 0.0);
    let error = |m: &TriMesh| two_way_error(&shape, &exact, m, 9);
    let ((max, mean), (regular_max, regular_mean)) = (error(&mesh), error(&regular_mesh));
    eprintln!(
        "max / mean error: udf {max} / {mean}, regular {regular_max} / {regular_mean}, h {h}"
    );
    assert!(
        max < 0.4 * h && max < regular_max,
        "max error {max} vs regular {regular_max}, h {h}"
    );
    assert!(
        mean < 0.25 * regular_mean,
        "mean error {mean} vs regular {regular_mean}"
    );
}

#[test]
fn udf_keeps_every_corner_of_a_rotated_cube() {
    check_corners_kept(rotated_cube(), 20);
}

#[test]
fn udf_keeps_every_corner_of_an_octahedron() {
    check_corners_kept(rotate(&octahedron(), [0.2, 0.1, 0.4]), 20);
}

/// A 2 × 0.46 × 0.38 bar turned so that its edges cross the grid at
/// every offset from the samples.
fn turned_bar() -> TriMesh {
    rotate(
        &cuboid(DVec3::new(-1.0, -0.23, -0.19), DVec3::new(1.0, 0.23, 0.19)),
        [0.13, 0.07, 0.61],
    )
}

/// A long bar turned so that its edges run across the grid at every
/// offset from the samples: many cells lie beside an edge that passes
/// just outside them, with crossings on both of its faces. Their patches
/// must reach the edge (joined to the neighbour's fan), not cut under it.
/// (Corners are left out: a corner poking into a cell without changing
/// any sample's sign is a different matter.)
#[test]
fn udf_follows_edges_that_pass_beside_cells() {
    let bar = turned_bar();
    let size = GridSize::Resolution(24);
    let (udf, report) = udf_of(&bar, size);
    let h = udf.spec.spacing;
    let (mesh, extract) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let features = surfrecon_distfield::features::Features::detect(&bar, 30.0);
    assert_eq!(features.edges.len(), 12);
    let surface = MeshQuery::new(&mesh).unwrap();
    let mut worst = 0.0f64;
    for [a, b] in features.edges {
        let (a, b) = (bar.vertices[a as usize], bar.vertices[b as usize]);
        worst = worst.max(error_along_edge(&surface, a, b, h));
    }
    let exact = MeshQuery::new(&bar).unwrap();
    let (max, mean) = two_way_error(&bar, &exact, &mesh, 16);
    eprintln!(
        "{report:?} {extract:?}\nedges {worst} h; everywhere max {} h, mean {} h",
        max / h,
        mean / h
    );
    assert!(report.sharp_cells > 0 && extract.merged > 0);
    assert!(worst < 0.1, "an edge is cut by {worst} h");
}

/// A sphere centred on an edge of the turned bar cuts it at two corners
/// where three surfaces meet (the sphere and the edge's two faces), each
/// in a cell of its own that the tool changed. Sculpting must reach them.
#[test]
fn sculpting_keeps_the_corners_where_a_tool_cuts_an_edge() {
    use surfrecon_distfield::sculpt::{sculpt_udf, Operation, Tool};
    let bar = turned_bar();
    let (mut udf, _) = udf_of(&bar, GridSize::Resolution(24));
    let h = udf.spec.spacing;
    let features = surfrecon_distfield::features::Features::detect(&bar, 30.0);
    let mut worst = 0.0f64;
    for (k, &[a, b]) in features.edges.iter().enumerate().step_by(3) {
        let (a, b) = (bar.vertices[a as usize], bar.vertices[b as usize]);
        let (centre, radius) = (a.lerp(b, 0.5), 0.13 + 0.01 * k as f64);
        let tool = Tool::Sphere { centre, radius };
        sculpt_udf(&mut udf, Operation::Subtract, &tool, 0.1).unwrap();
        let along = (b - a).normalize() * radius;
        let (mesh, _) = udf.extract();
        let surface = MeshQuery::new(&mesh).unwrap();
        for corner in [centre - along, centre + along] {
            worst = worst.max(surface.signed_distance(corner).abs() / h);
        }
    }
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    // 0.12 h; 0.91 h before the corners where the object's edges pierce
    // the tool became feature points.
    eprintln!("corners off by {worst} h");
    assert!(worst < 0.15, "a corner is cut by {worst} h");
}

#[test]
fn field_files_round_trip_exactly_and_refuse_truncation() {
    use surfrecon_distfield::format::{read_odf, read_udf, write_odf, write_udf, AnyField};
    use surfrecon_distfield::offset::{build_odf, OdfOptions};
    let shape = rotated_cube();
    let size = GridSize::Resolution(12);
    let dir = tempfile::tempdir().unwrap();
    let (udf, _) = build_udf(
        &shape,
        &UdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap();
    let (odf, _) = build_odf(
        &shape,
        &OdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(!udf.extras.is_empty() && !odf.moved.is_empty());
    let (udf_path, odf_path) = (dir.path().join("c.udf"), dir.path().join("c.odf"));
    write_udf(&udf_path, &udf).unwrap();
    write_odf(&odf_path, &odf).unwrap();
    assert_eq!(read_udf(&udf_path).unwrap(), udf);
    assert_eq!(read_odf(&odf_path).unwrap(), odf);
    // Reading one kind as the other, or any truncated file, is an error.
    assert!(read_udf(&odf_path)
        .unwrap_err()
        .to_string()
        .contains("not a surfrecon"));
    for path in [&udf_path, &odf_path] {
        let bytes = std::fs::read(path).unwrap();
        let cut = dir.path().join("cut");
        for len in [0, 7, 30, 60, bytes.len() / 2, bytes.len() - 1] {
            std::fs::write(&cut, &bytes[..len]).unwrap();
            let err = if path == &udf_path {
                read_udf(&cut).err()
            } else {
                read_odf(&cut).err()
            };
            let message = err.expect("a truncated file is refused").to_string();
            assert!(message.contains("cut:"), "{message}");
            // Read by kind, a cut file is still taken for what its name says.
            let named = dir.path().join(format!(
                "cut.{}",
                if path == &udf_path { "udf" } else { "odf" }
            ));
            std::fs::write(&named, &bytes[..len]).unwrap();
            let message = AnyField::read(&named).unwrap_err().to_string();
            assert!(
                message.contains("truncated") || message.contains(" follow"),
                "{len}: {message}"
            );
        }
    }
}

#[test]
fn odf_moves_samples_onto_the_features_and_lowers_the_error() {
    let shape = rotated_cube();
    let size = GridSize::Resolution(20);
    let (odf, report) = odf_of(&shape, size);
    let h = odf.spec.spacing;
    assert!(
        report.energy_after < 0.6 * report.energy_before,
        "{report:?}"
    );
    let (mesh, _) = odf.extract();
    assert_closed_manifold(&mesh, 2);
    let regular_field = regular_field(&shape, size);
    let regular = marching_cubes(&regular_field, 0.0);
    let exact = MeshQuery::new(&shape).unwrap();
    let error = |m: &TriMesh| two_way_error(&shape, &exact, m, 9);
    let ((max, mean), (regular_max, regular_mean)) = (error(&mesh), error(&regular));
    eprintln!("odf {report:?}\nmax / mean error: odf {max} / {mean}, regular {regular_max} / {regular_mean}, h {h}");
    assert!(max < regular_max && mean < 0.5 * regular_mean);
}

/// The ODF puts samples on corners (and the samples beside them on the
/// right side, crossing the surface where that keeps its topology): every
/// corner of a box, its corners a fraction of a cell off the grid planes
/// (fandisk's worst ODF corners, 0.78 h, were like this: all samples
/// around them outside), and of a rotated cube.
#[test]
fn odf_reaches_the_corners() {
    // 20 cells along x: the far y and z faces lie 0.4 h and 0.2 h off
    // the grid planes.
    let boxed = cuboid(DVec3::ZERO, DVec3::new(1.0, 0.77, 0.66));
    for (name, shape) in [("box", boxed), ("rotated cube", rotated_cube())] {
        let size = GridSize::Resolution(20);
        let (odf, report) = odf_of(&shape, size);
        let h = odf.spec.spacing;
        let (mesh, _) = odf.extract();
        assert_closed_manifold(&mesh, 2);
        let kept = corner_errors(&shape, &mesh);
        let exact = MeshQuery::new(&shape).unwrap();
        let (max, _) = two_way_error(&shape, &exact, &mesh, 9);
        eprintln!(
            "{name}: {report:?}\ncorners {:?} h, max {} h",
            kept.iter().map(|d| d / h).collect::<Vec<_>>(),
            max / h
        );
        // Every corner (the rotated cube's worst 0.027 h; two were cut
        // by 0.34 h before the repair measured the surface against the
        // mesh: the search had settled with their samples' neighbours
        // on the wrong side), and the rest of the surface near it.
        let reached = kept.iter().filter(|&&d| d < 0.05 * h).count();
        assert_eq!(reached, 8, "{name}: {kept:?}, h {h}");
        assert!(max < 0.2 * h, "{name}: max {} h", max / h);
    }
}

/// The half extents of the drilled box (not a cube, so that only its x
/// faces fall on grid nodes).
const HALF: DVec3 = DVec3::new(0.5, 0.4, 0.35);

/// A box with a cylindrical hole drilled along z: points on the exact
/// result (box faces outside the hole, the hole's wall) and on its rims.
fn drilled_box_samples(radius: f64, n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut surface = Vec::new();
    let mut rims = Vec::new();
    let grid = |k: usize| (k as f64 + 0.5) / n as f64 * 2.0 - 1.0;
    for i in 0..n {
        for j in 0..n {
            let (u, v) = (grid(i), grid(j));
            for axis in 0..3 {
                for side in [-1.0, 1.0] {
                    let mut p = DVec3::ZERO;
                    p[axis] = side;
                    p[(axis + 1) % 3] = u;
                    p[(axis + 2) % 3] = v;
                    let p = p * HALF;
                    if p.x.hypot(p.y) > radius {
                        surface.push(p);
                    }
                }
            }
            let angle = (i as f64 + j as f64 / n as f64) / n as f64 * std::f64::consts::TAU;
            surface.push(DVec3::new(
                radius * angle.cos(),
                radius * angle.sin(),
                v * HALF.z,
            ));
        }
        let angle = i as f64 / n as f64 * std::f64::consts::TAU;
        for z in [-HALF.z, HALF.z] {
            rims.push(DVec3::new(radius * angle.cos(), radius * angle.sin(), z));
        }
    }
    (surface, rims)
}

#[test]
fn drilling_a_box_keeps_the_new_circular_edges() {
    use surfrecon_distfield::sculpt::{sculpt_regular, sculpt_udf, Operation};
    let shape = cuboid(-HALF, HALF);
    let size = GridSize::Resolution(24);
    let radius = 0.23;
    let drill = || drill_along_z(radius);
    let (mut udf, _) = build_udf(
        &shape,
        &UdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap();
    let h = udf.spec.spacing;
    let report = sculpt_udf(&mut udf, Operation::Subtract, &drill(), 0.1).unwrap();
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 0);
    let mut regular = regular_field(&shape, size);
    sculpt_regular(&mut regular, Operation::Subtract, &drill());
    let regular = marching_cubes(&regular, 0.0);
    let (surface, rims) = drilled_box_samples(radius, 40);
    let worst = |m: &TriMesh, points: &[DVec3]| {
        let q = MeshQuery::new(m).unwrap();
        let (d, p) = points
            .iter()
            .map(|&p| (q.signed_distance(p).abs(), p))
            .fold((0.0, DVec3::ZERO), |a, b| if b.0 > a.0 { b } else { a });
        eprintln!("farthest: {} h at {p}", d / h);
        d / h
    };
    // Mesh to exact: on the result's surface |max(box, -cylinder)| is the
    // exact distance up to the rims, where it can only underestimate.
    let exact = |p: DVec3| {
        let b = (p.abs() - HALF).max_element();
        b.max(radius - p.x.hypot(p.y)).abs()
    };
    let off = mesh.vertices.iter().map(|&v| exact(v)).fold(0.0, f64::max) / h;
    let (rim, rim_regular) = (worst(&mesh, &rims), worst(&regular, &rims));
    let (all, all_regular) = (worst(&mesh, &surface), worst(&regular, &surface));
    eprintln!("{report:?}\nrims {rim} h (regular {rim_regular}), surface {all} h (regular {all_regular}), vertices off {off} h");
    assert!(report.kept > 0 && report.edge_points > 0);
    assert!(
        rim < 0.02 && rim < 0.1 * rim_regular,
        "rim {rim} h, regular {rim_regular} h"
    );
    assert!(off < 0.15, "vertices {off} h off the exact surface");
    // Not yet the issue's 0.15 h everywhere: along the box's own edges
    // whose faces lie on grid nodes, cells next to the edge cut it by up to
    // half a cell (as the unsculpted field does).
    assert!(
        all < all_regular,
        "surface {all} h, regular {all_regular} h"
    );
}

/// A cylinder of `radius` along z through the whole box.
fn drill_along_z(radius: f64) -> surfrecon_distfield::sculpt::Tool {
    surfrecon_distfield::sculpt::Tool::Cylinder {
        a: DVec3::new(0.0, 0.0, -1.0),
        b: DVec3::new(0.0, 0.0, 1.0),
        radius,
    }
}

/// BENCHMARKS.md's drilled box: turned 30° about z (no face on grid
/// nodes), and the angle.
fn turned_box() -> (TriMesh, f64) {
    let turn_z = 30f64.to_radians();
    (rotate(&cuboid(-HALF, HALF), [0.0, 0.0, turn_z]), turn_z)
}

/// How far `mesh` (a sculpted field's extraction) and the box turned by
/// `turn_z` about z minus a cylinder of `radius` along z lie apart, in
/// spacings `h`: the farthest of `points` (on the mesh) off the exact
/// result, of the result's surface off the mesh, and of its rims.
fn drilled_box_errors(
    mesh: &TriMesh,
    points: impl Iterator<Item = DVec3>,
    radius: f64,
    turn_z: f64,
    h: f64,
) -> (f64, f64, f64) {
    let to_box = glam::DMat3::from_rotation_z(-turn_z);
    // |max(box, -cylinder)| in the box's frame: exact on the result's
    // surface up to the rims, where it can only underestimate.
    let off = points
        .map(|v| {
            let p = to_box * v;
            let b = (p.abs() - HALF).max_element();
            b.max(radius - p.x.hypot(p.y)).abs()
        })
        .fold(0.0, f64::max)
        / h;
    let (surface, rims) = drilled_box_samples(radius, 60);
    let q = MeshQuery::new(mesh).unwrap();
    let farthest = |points: &[DVec3]| {
        let from_box = to_box.transpose();
        let d = |&p: &DVec3| q.signed_distance(from_box * p).abs();
        points.iter().map(d).fold(0.0, f64::max) / h
    };
    let (all, rim) = (farthest(&surface), farthest(&rims));
    eprintln!("surface off the result {off} h; result off the surface {all} h, rims {rim} h");
    (off, all, rim)
}

/// BENCHMARKS.md's named case: the drilled box's block turned 30° about
/// z (so no face lies on grid nodes), 64 cells, minus a cylinder of radius
/// 0.2 along z: the issue's 0.15 h both ways, the rims far closer.
#[test]
fn a_turned_box_minus_a_cylinder_stays_within_the_issues_bound() {
    use surfrecon_distfield::sculpt::{sculpt_udf, Operation};
    let radius = 0.2;
    let (shape, turn_z) = turned_box();
    let (mut udf, _) = udf_of(&shape, GridSize::Resolution(64));
    let h = udf.spec.spacing;
    sculpt_udf(&mut udf, Operation::Subtract, &drill_along_z(radius), 0.1).unwrap();
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 0);
    let (off, all, rim) =
        drilled_box_errors(&mesh, mesh.vertices.iter().copied(), radius, turn_z, h);
    // Session 33: 0.081 h, 0.056 h, rims 0.012 h (against manifold3d's
    // boolean, every vertex and 16 points per triangle: 0.081 / 0.023 h).
    assert!(off < 0.15 && all < 0.15, "{off} h / {all} h");
    assert!(rim < 0.05, "rims {rim} h");
}

/// Fandisk, from ../shared/data beside the repository.
fn fandisk() -> TriMesh {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/fandisk/fandisk.off");
    surfrecon_geom::io::read(&path)
        .unwrap_or_else(|e| panic!("the shared fandisk data is needed beside the repository: {e}"))
        .to_mesh()
}

/// Fandisk (../shared/data) at the paper's resolution: the unified and
/// offset fields are closed single surfaces, far closer to the mesh than
/// the regular field (figures in BENCHMARKS.md).
#[test]
fn fandisk_fields_are_closed_and_closer_than_the_regular_field() {
    use surfrecon_distfield::offset::{build_odf, OdfOptions};
    let shape = fandisk();
    let size = GridSize::Resolution(64);
    let exact = MeshQuery::new(&shape).unwrap();
    let error = |m: &TriMesh| two_way_error(&shape, &exact, m, 4);
    let regular_field = regular_field(&shape, size);
    let h = regular_field.spec.spacing;
    let (regular_max, regular_mean) = error(&marching_cubes(&regular_field, 0.0));
    let (udf, _) = build_udf(
        &shape,
        &UdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap();
    let (udf_mesh, _) = udf.extract();
    let (odf, _) = build_odf(
        &shape,
        &OdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap();
    let (odf_mesh, _) = odf.extract();
    // Every sample stays inside its cell (the box of half a spacing
    // around its node), the repair's moves included.
    for (&n, &p) in &odf.moved {
        let node = DVec3::from_array(odf.spec.position(odf.spec.unlinear(n as usize)));
        let off = (p - node).abs().max_element();
        let h = odf.spec.spacing;
        assert!(
            off < 0.5 * h,
            "sample {n} at {p}, {} h off its node",
            off / h
        );
    }
    for (name, mesh) in [("udf", &udf_mesh), ("odf", &odf_mesh)] {
        assert_closed_manifold(mesh, 2);
        // 4 pairs each before session 35.
        assert_no_crossings(mesh, name);
        let (max, mean) = error(mesh);
        eprintln!(
            "{name}: max {} h, mean {} h (regular {} / {})",
            max / h,
            mean / h,
            regular_max / h,
            regular_mean / h
        );
        assert!(
            max < 0.8 * regular_max,
            "{name} max {max} vs regular {regular_max}"
        );
        // The unified field: 0.19 h (0.28 h before cells crossed by two
        // feature lines re-picked their point by the surface extracted
        // around them; 0.54 h before cells beside an edge joined their
        // neighbour's fan, fans were checked against the crossings'
        // directions and such cells chose the point that cuts both lines
        // least).
        assert!(name != "udf" || max < 0.25 * h, "udf max {} h", max / h);
        // The offset field: 0.135 h (0.137 h before the repair's pair
        // moves, 0.184 h before it made room; 0.218 h before the repair; 0.43 h before the block energy, the convex side first
        // and the fit of the feature cells' neighbours; 0.78 h before
        // samples were aligned with the features and allowed to cross
        // where topology allows).
        assert!(name != "odf" || max < 0.15 * h, "odf max {} h", max / h);
        assert!(
            mean < 0.45 * regular_mean,
            "{name} mean {mean} vs regular {regular_mean}"
        );
    }
}

/// Fandisk's unified field at 64 cells, exact point-to-triangle errors
/// both ways (16 points per triangle, as the bench): exact crossings
/// beside feature points, and the error-driven repair of feature points
/// at 28° creases, at lines passing through cells the surface does not
/// cross and at two lines crossing the same cells, bring the max and the
/// mean down (the issue's goal: ≤ 0.1 h).
#[test]
fn fandisk_udf_error_below_the_repaired_bounds() {
    let shape = fandisk();
    let exact = MeshQuery::new(&shape).unwrap();
    let (udf, report) = udf_of(&shape, GridSize::Resolution(64));
    let h = udf.spec.spacing;
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let (max, mean) = two_way_error(&shape, &exact, &mesh, 16);
    eprintln!("udf: max {} h, mean {} h, {report:?}", max / h, mean / h);
    // Session 18: 0.194 h / 0.0039 h before the repair, 0.177 / 0.0027
    // after; now 0.089 / 0.0027 (samples moved onto the second of two
    // feature lines crossing the same cells, repair from 0.08 h on).
    assert!(max < 0.1 * h, "udf max {} h", max / h);
    assert!(mean < 0.003 * h, "udf mean {} h", mean / h);
    assert!(report.repaired > 0, "{report:?}");
    // The counts are what the field (and its file) stores, after the
    // repair replaced some (session 33: 643 / 1,227 reported, 641 / 1,221
    // stored).
    let stored = |f: fn(&Extra) -> bool| udf.extras.values().filter(|e| f(e)).count();
    assert_eq!(
        (report.directed, report.feature_points, report.positions),
        (
            stored(|e| matches!(e, Extra::Directed(_))),
            stored(|e| matches!(e, Extra::FeaturePoint(_))),
            stored(|e| matches!(e, Extra::Position(_)))
        )
    );
}

/// A box with a shallow roof: the ridge's two faces meet at 25°, below
/// the 30° feature angle, so it is no feature edge, but a crease.
fn roofed_box() -> TriMesh {
    let r = 12.5f64.to_radians().tan();
    let vertices = vec![
        DVec3::new(-1.0, -1.0, -1.0),
        DVec3::new(1.0, -1.0, -1.0),
        DVec3::new(1.0, 1.0, -1.0),
        DVec3::new(-1.0, 1.0, -1.0),
        DVec3::new(-1.0, -1.0, 0.0),
        DVec3::new(1.0, -1.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(-1.0, 1.0, 0.0),
        DVec3::new(0.0, -1.0, r),
        DVec3::new(0.0, 1.0, r),
    ];
    let triangles = vec![
        [0, 2, 1],
        [0, 3, 2],
        [1, 2, 6],
        [1, 6, 5],
        [0, 4, 7],
        [0, 7, 3],
        [0, 1, 5],
        [0, 5, 4],
        [4, 5, 8],
        [3, 7, 6],
        [3, 6, 2],
        [7, 9, 6],
        [5, 6, 9],
        [5, 9, 8],
        [4, 8, 9],
        [4, 9, 7],
    ];
    TriMesh {
        vertices,
        triangles,
        normals: None,
    }
}

/// A crease gentler than the feature angle is kept by the points cells
/// take from their crossings' tangent planes (from 20° between their
/// normals): the ridge of a turned roofed box stays within 0.08 h of the
/// UDF surface (0.058 h; 0.133 h when only the feature angle counted).
#[test]
fn udf_keeps_a_crease_below_the_feature_angle() {
    let shape = rotate(&roofed_box(), [0.3, 0.5, 0.7]);
    let volume: f64 = (0..shape.triangles.len())
        .map(|t| {
            let [a, b, c] = shape.corners(t);
            a.dot(b.cross(c)) / 6.0
        })
        .sum();
    assert!(volume > 0.0, "outward faces: volume {volume}");
    let (udf, report) = udf_of(&shape, GridSize::Resolution(24));
    let h = udf.spec.spacing;
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let surface = MeshQuery::new(&mesh).unwrap();
    let (a, b) = (shape.vertices[8], shape.vertices[9]);
    let ridge = (0..=100)
        .map(|k| surface.signed_distance(a.lerp(b, k as f64 / 100.0)).abs())
        .fold(0.0, f64::max);
    eprintln!("ridge {} h, {report:?}", ridge / h);
    assert!(ridge < 0.08 * h, "ridge {} h", ridge / h);
}

/// Fandisk minus a sphere (BENCHMARKS.md's case, grid as `surfrecon
/// distance --resolution 64`): the new circular edge, where the sphere
/// meets fandisk's faces, stays on the sculpted UDF surface, also where
/// it crosses a cell with an old feature edge and ends in a corner on it.
#[test]
fn sculpting_fandisk_keeps_the_new_edge_beside_old_ones() {
    let (worst, off) = sculpted_fandisk_errors(DVec3::new(2.5, 15.5, -1.3), 1.0);
    // 0.083 h and 0.096 h since the repair knows the result's feature
    // lines (old ridges and the new edge as pieces, so a cell crossed by
    // both may move a sample onto the second; 0.13 h before); 0.13 h and
    // 0.10 h since changed samples hand their feature points back to
    // their cells (a sample moved onto a new corner had taken fandisk's
    // ridge point next to it away: 0.155 h dense); 0.18 h and 0.32 h
    // before the changed cells were repaired against the exact result;
    // 0.52 h and 0.36 h before samples were moved onto the new corners
    // (on the side that fans nearer the result; 0.27 h with that alone)
    // and the changed cells re-picked their points by the surface
    // extracted around them.
    assert!(worst < 0.11, "the new edge is cut by {worst} h");
    assert!(off < 0.125, "the surface leaves the result by {off} h");
}

/// A small sphere centred on one of fandisk's 90° edges (a tool the
/// sculpting was not tuned on): its new edge meets the old one in two
/// corners, with the old edge's two faces cut between them. Session 22:
/// the surface left the result by 0.205 h (the new edge 0.058 h off it)
/// before the repair knew the result's feature lines, 0.089 h (0.043 h)
/// after.
#[test]
fn sculpting_fandisk_keeps_a_sphere_cut_into_an_edge() {
    let (worst, off) = sculpted_fandisk_errors(DVec3::new(3.3, 14.08, -2.48), 0.45);
    assert!(worst < 0.15, "the new edge is cut by {worst} h");
    assert!(off < 0.15, "the surface leaves the result by {off} h");
}

/// Fandisk minus a larger sphere whose new edge leaves fandisk's 89°
/// ridge at about 13°: over 4-5 cells both lines cross the same cells
/// and one feature point per cell keeps one of them (sessions 21-22: the
/// new edge missed the surface by 0.25 h at (2.77, 14.12, −2.28)).
/// Session 24: the repair may move every sample along such a stretch
/// onto the second line at once (`refine::line_snaps`).
#[test]
fn sculpting_fandisk_keeps_a_new_edge_leaving_a_ridge_at_a_shallow_angle() {
    let (worst, off) = sculpted_fandisk_errors(DVec3::new(3.9, 13.6, -1.9), 1.3);
    // Stretch moves alone 0.174 / 0.210 h, main 0.217 / 0.212 h; the goal, 0.15 h,
    // is not met: the stretch's other end, where the new edge meets the
    // ridge again, is still cut (0.215 h densely).
    assert!(worst < 0.19, "the new edge is cut by {worst} h");
    assert!(off < 0.25, "the surface leaves the result by {off} h");
}

/// Fandisk minus a box whose y = 14.25 face meets fandisk's sloped face
/// a fraction of a cell from its ridge: the new edge and the ridge cross
/// the same cells, with a sliver of fandisk's face between them. Session
/// 24: such cells keep a second feature point, on the second line, and
/// extraction splits their patch between the two. The surface stays
/// within 0.15 h of the exact result (0.125 h; 0.252 h with one point
/// per cell), the result within 0.15 h of the surface (0.124 h since
/// session 33's corner sets; 0.208 h before, at the corner where the
/// ridge pierces the box's x face; 0.234 h while a feature point just
/// past a cell's edge leaned on the diagonal neighbour, session 26), and
/// the field with its second points reads back exactly and extracts the
/// same surface.
#[test]
fn sculpting_fandisk_keeps_a_box_cut_beside_a_ridge() {
    use surfrecon_distfield::format::{read_udf, write_udf};
    use surfrecon_distfield::sculpt::{sculpt_udf, Operation, Tool};
    let shape = fandisk();
    let (mut udf, _) = build_udf(
        &shape,
        &UdfOptions {
            size: GridSize::Resolution(64),
            padding: 4,
            ..Default::default()
        },
    )
    .unwrap();
    let h = udf.spec.spacing;
    let tool = Tool::Box {
        min: DVec3::new(2.8, 12.0, -2.0),
        max: DVec3::new(3.4, 14.25, -1.0),
    };
    sculpt_udf(&mut udf, Operation::Subtract, &tool, 0.1).unwrap();
    let seconds = udf.second_points(&udf.feature_points());
    assert!(!seconds.is_empty(), "no cell keeps two feature points");
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    // The exact result's signed distance: exact inside, a lower bound
    // outside (as `sculpted_fandisk_errors`).
    let exact = MeshQuery::new(&shape).unwrap();
    let off = dense_points(&mesh)
        .map(|p| exact.signed_distance(p).max(-tool.signed_distance(p)).abs() / h)
        .fold(0.0, f64::max);
    eprintln!(
        "box cut: surface off the result by {off} h, {} cells with two points",
        seconds.len()
    );
    assert!(off < 0.15, "the surface leaves the result by {off} h");
    // The other way: the result's surface must reach the surface: its new
    // faces (the box's faces inside fandisk), fandisk's surface left
    // outside the box, and the new edge where fandisk's triangle edges
    // cross the box's faces (the new corners among them: the worst place
    // is where fandisk's ridge pierces the box's x face).
    let surface = MeshQuery::new(&mesh).unwrap();
    let cut_faces = box_face_points(tool_min(&tool), tool_max(&tool), h / 8.0)
        .filter(|&p| exact.signed_distance(p) < 0.0);
    let kept_surface = dense_points(&shape).filter(|&p| tool.signed_distance(p) > 0.0);
    // (Found by bisection: the box's distance is not linear along an
    // edge that passes near two of its faces, so interpolating put points
    // up to 0.08 h inside the box.)
    let new_edge = mesh_edges(&shape).filter_map(|[a, b]| {
        let inside = |p: DVec3| tool.signed_distance(p) < 0.0;
        if inside(a) == inside(b) {
            return None;
        }
        let (mut a, mut b) = (a, b);
        for _ in 0..48 {
            let mid = a.lerp(b, 0.5);
            if inside(mid) == inside(a) {
                a = mid;
            } else {
                b = mid;
            }
        }
        Some(a.lerp(b, 0.5))
    });
    let (missed, at) = cut_faces
        .chain(kept_surface)
        .chain(new_edge)
        .map(|p| (surface.signed_distance(p).abs() / h, p))
        .fold((0.0, DVec3::ZERO), |a, b| if b.0 > a.0 { b } else { a });
    eprintln!("box cut: the result off the surface by {missed} h at {at}");
    assert!(
        missed < 0.15,
        "the result lies {missed} h off the surface at {at}"
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.udf");
    write_udf(&path, &udf).unwrap();
    let back = read_udf(&path).unwrap();
    assert_eq!(back, udf);
    assert_eq!(back.second_points(&back.feature_points()), seconds);
    assert_eq!(back.extract().0.triangles, mesh.triangles);
}

fn tool_min(tool: &surfrecon_distfield::sculpt::Tool) -> DVec3 {
    match tool {
        surfrecon_distfield::sculpt::Tool::Box { min, .. } => *min,
        _ => unreachable!("a box"),
    }
}

fn tool_max(tool: &surfrecon_distfield::sculpt::Tool) -> DVec3 {
    match tool {
        surfrecon_distfield::sculpt::Tool::Box { max, .. } => *max,
        _ => unreachable!("a box"),
    }
}

/// The edges of `mesh`'s triangles (each shared edge twice).
fn mesh_edges(mesh: &TriMesh) -> impl Iterator<Item = [DVec3; 2]> + '_ {
    (0..mesh.triangles.len()).flat_map(|t| {
        let [a, b, c] = mesh.corners(t);
        [[a, b], [b, c], [c, a]]
    })
}

/// A lattice of points `step` apart on the six faces of the box
/// `min`-`max`, face by face, in rows.
fn box_face_points(min: DVec3, max: DVec3, step: f64) -> impl Iterator<Item = DVec3> {
    let size = max - min;
    let counts = (size / step).ceil().as_uvec3();
    (0..6).flat_map(move |face| {
        let (axis, side) = (face / 2, [min, max][face % 2]);
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        (0..=counts[u]).flat_map(move |i| {
            (0..=counts[v]).map(move |j| {
                let mut p = side;
                p[u] = (min[u] + i as f64 * step).min(max[u]);
                p[v] = (min[v] + j as f64 * step).min(max[v]);
                p
            })
        })
    })
}

/// Fandisk's UDF (64 cells, padding 4) minus a sphere, against the exact
/// result: the largest distance of points on the new edge to the
/// surface, and of the surface (densely) to the result, in spacings.
fn sculpted_fandisk_errors(centre: DVec3, radius: f64) -> (f64, f64) {
    use surfrecon_distfield::sculpt::{sculpt_udf, Operation, Tool};
    let shape = fandisk();
    let (mut udf, _) = build_udf(
        &shape,
        &UdfOptions {
            size: GridSize::Resolution(64),
            padding: 4,
            ..Default::default()
        },
    )
    .unwrap();
    let h = udf.spec.spacing;
    let tool = Tool::Sphere { centre, radius };
    sculpt_udf(&mut udf, Operation::Subtract, &tool, 0.1).unwrap();
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let exact = MeshQuery::new(&shape).unwrap();
    let edge = sphere_edge_points(&exact, centre, radius, h);
    let surface = MeshQuery::new(&mesh).unwrap();
    let worst = edge
        .iter()
        .map(|&p| surface.signed_distance(p).abs() / h)
        .fold(0.0, f64::max);
    // The surface the other way.
    let off = off_carved_by_sphere(&mesh, &exact, centre, radius, h);
    eprintln!("new edge off the surface by {worst} h; surface off the result by {off} h");
    (worst, off)
}

/// How far `mesh` lies off `exact` minus the sphere, in spacings `h`,
/// densely (every vertex and 10 points per triangle, as
/// `examples/worst.rs`): the result's signed distance is exact inside the
/// result, a lower bound outside.
fn off_carved_by_sphere(
    mesh: &TriMesh,
    exact: &MeshQuery,
    centre: DVec3,
    radius: f64,
    h: f64,
) -> f64 {
    dense_points(mesh)
        .map(|p| {
            exact
                .signed_distance(p)
                .max(radius - p.distance(centre))
                .abs()
                / h
        })
        .fold(0.0, f64::max)
}

/// Points where a sphere meets the surface of `exact` (within 1e-6 h):
/// alternating projections from 2000 points spread over the sphere.
fn sphere_edge_points(exact: &MeshQuery, centre: DVec3, radius: f64, h: f64) -> Vec<DVec3> {
    let n = 2000;
    let on_sphere = |p: DVec3| centre + (p - centre).normalize() * radius;
    let edge: Vec<DVec3> = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let a = std::f64::consts::PI * (1.0 + 5f64.sqrt()) * i as f64;
            let s = (1.0 - z * z).sqrt();
            (0..40).fold(
                centre + DVec3::new(a.cos() * s, a.sin() * s, z) * radius,
                |p, _| on_sphere(exact.closest_point(p)),
            )
        })
        .filter(|&p| exact.signed_distance(p).abs() < 1e-6 * h)
        .collect();
    assert!(edge.len() > 200, "{} points on the new edge", edge.len());
    edge
}

/// BENCHMARKS.md's named case on the offset field (64 cells, as
/// `surfrecon distance --kind odf`): the samples put on the new circular
/// edge and fitted around it keep it, and the surface stays near the
/// exact result. Main before session 34 cut the edge by up to 0.80 h
/// (mean 0.21 h), about the regular field's 0.85 h; session 34 0.40 h at
/// most, at one corner where the sphere meets an old ridge and a third
/// line, near a cell's centre (its sample could not reach it alone),
/// mean 0.01 h; session 36 0.29 h (its neighbours shifted with it).
#[test]
fn sculpting_an_odf_of_fandisk_keeps_the_new_edge() {
    use surfrecon_distfield::sculpt::{sculpt_odf, Operation, Tool};
    let shape = fandisk();
    let (mut odf, _) = odf_of(&shape, GridSize::Resolution(64));
    let h = odf.spec.spacing;
    let (centre, radius) = (DVec3::new(2.5, 15.5, -1.3), 1.0);
    let tool = Tool::Sphere { centre, radius };
    let report = sculpt_odf(&mut odf, Operation::Subtract, &tool).unwrap();
    let (mesh, _) = odf.extract();
    assert_closed_manifold(&mesh, 2);
    let exact = MeshQuery::new(&shape).unwrap();
    let edge = sphere_edge_points(&exact, centre, radius, h);
    let surface = MeshQuery::new(&mesh).unwrap();
    let mut cut: Vec<f64> = (edge.iter())
        .map(|&p| surface.signed_distance(p).abs() / h)
        .collect();
    cut.sort_by(f64::total_cmp);
    let within = cut.iter().filter(|&&d| d < 0.15).count() as f64 / cut.len() as f64;
    let (worst, mean) = (
        cut[cut.len() - 1],
        cut.iter().sum::<f64>() / cut.len() as f64,
    );
    let off = off_carved_by_sphere(&mesh, &exact, centre, radius, h);
    eprintln!("{report:?}\nnew edge: max {worst} h, mean {mean} h, {within} within 0.15 h; surface off the result {off} h");
    assert!(report.kept > 50, "{} samples on the new edge", report.kept);
    assert!(
        within > 0.95 && mean < 0.03,
        "{within} of the edge within 0.15 h, mean {mean} h"
    );
    assert!(worst < 0.32, "the new edge is cut by {worst} h");
    assert!(off < 0.17, "the surface leaves the result by {off} h");
}

/// Fandisk minus the second sphere of BENCHMARKS.md's sculpting cases on
/// the offset field: samples put on the new edge lie on the surface, and
/// their crossings' clusters crossed the triangles beside them (8 pairs
/// before session 35).
#[test]
fn sculpting_an_odf_of_fandisk_makes_no_crossing_triangles() {
    use surfrecon_distfield::sculpt::{sculpt_odf, Operation, Tool};
    let shape = fandisk();
    let (mut odf, _) = odf_of(&shape, GridSize::Resolution(64));
    let tool = Tool::Sphere {
        centre: DVec3::new(3.9, 13.6, -1.9),
        radius: 1.3,
    };
    sculpt_odf(&mut odf, Operation::Subtract, &tool).unwrap();
    let (mesh, report) = odf.extract();
    assert_closed_manifold(&mesh, 2);
    assert!(report.collapsed > 0, "{report:?}");
    assert_no_crossings(&mesh, "fandisk - sphere (3.9, 13.6, -1.9; r 1.3)");
}

/// Fandisk's unified field at the default size (`surfrecon distance
/// --resolution 64`) with a sphere subtracted.
fn fandisk_udf_minus_sphere(centre: DVec3, radius: f64) -> UnifiedField {
    use surfrecon_distfield::sculpt::{sculpt_udf, Operation, Tool};
    let (mut udf, _) = build_udf(&fandisk(), &UdfOptions::default()).unwrap();
    sculpt_udf(
        &mut udf,
        Operation::Subtract,
        &Tool::Sphere { centre, radius },
        0.1,
    )
    .unwrap();
    udf
}

/// Fandisk minus a sphere on the unified field, on the grid of `surfrecon
/// distance --resolution 64`: 18 crossing triangle pairs before session
/// 35 (4 where samples on the surface left clusters of crossings, 13 at
/// fans around sculpted points stored two cells from their cells); the
/// last one, two fans back to back around a point stored at two samples,
/// gone since session 36 (the two vertices joined).
#[test]
fn sculpting_fandisk_leaves_no_fans_around_far_points() {
    let udf = fandisk_udf_minus_sphere(DVec3::new(2.5, 15.5, -1.3), 1.0);
    let h = udf.spec.spacing;
    for (&cell, &p) in &udf.feature_points() {
        let lo = DVec3::from_array(udf.spec.position(udf.spec.unlinear(cell)));
        let off = (lo - p).max(p - lo - DVec3::splat(h)).max(DVec3::ZERO);
        assert!(off.length() <= 0.5 * h, "cell {cell} fans around {p}");
    }
    let (mesh, report) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    assert!(report.joined > 0, "{report:?}");
    assert_no_crossings(&mesh, "fandisk - sphere (2.5, 15.5, -1.3; r 1), unified");
}

/// Fandisk minus the second sphere on the unified field (`surfrecon
/// distance --resolution 64`): two points of the new edge 0.08 h apart in
/// neighbouring cells, whose slivers' flips crossed each other (3 pairs
/// before session 36); the two are merged now.
#[test]
fn sculpting_fandisk_merges_feature_points_a_sliver_apart() {
    let udf = fandisk_udf_minus_sphere(DVec3::new(3.9, 13.6, -1.9), 1.3);
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    assert_no_crossings(&mesh, "fandisk - sphere (3.9, 13.6, -1.9; r 1.3), unified");
}

/// The turned box minus a cylinder (BENCHMARKS.md's named case) on the
/// offset field: the rims are kept as the unified field keeps them.
/// Before session 34: rims cut by 0.59 h (the regular field's 0.59 h);
/// now 0.001 h, and the surface within 0.03 h of the result.
#[test]
fn sculpting_an_odf_of_a_turned_box_keeps_the_rims() {
    use surfrecon_distfield::sculpt::{sculpt_odf, Operation};
    let radius = 0.2;
    let (shape, turn_z) = turned_box();
    let (mut odf, _) = odf_of(&shape, GridSize::Resolution(64));
    let h = odf.spec.spacing;
    sculpt_odf(&mut odf, Operation::Subtract, &drill_along_z(radius)).unwrap();
    let (mesh, _) = odf.extract();
    assert_closed_manifold(&mesh, 0);
    let (off, all, rim) = drilled_box_errors(&mesh, dense_points(&mesh), radius, turn_z, h);
    assert!(rim < 0.05, "rims cut by {rim} h");
    assert!(off < 0.15 && all < 0.15, "{off} h / {all} h");
}

/// Fandisk minus a capped cylinder whose flat cap lies 0-0.85 h beneath a
/// face of fandisk, nearly parallel to it: the wall between them is
/// thinner than a cell, and between two samples on the same side no edge
/// of the grid crossed it. Before session 23 the wall vanished (the hole
/// opened into the pocket beyond it: genus 1, the reference's genus is 0)
/// and the cap lay 1.17 h from the surface at these points; samples moved
/// into the wall keep it (0.42 h). Until session 25 one slot stayed open
/// where the wall meets the pocket's side face: a face whose samples
/// alternate in sign (hole, wall, old material, pocket) joined hole and
/// pocket (genus 1); sculpting now settles such faces by the exact result.
#[test]
fn sculpting_fandisk_keeps_a_wall_thinner_than_a_cell() {
    let cut = fandisk_minus_cylinder(2);
    assert!(cut.thin > 0, "no sample moved into the wall");
    assert_closed_manifold(&cut.mesh, 2);
    assert!(cut.cap < 0.5, "the cap lies {} h from the surface", cut.cap);
    assert!(
        cut.off < 0.5,
        "the surface leaves the result by {} h",
        cut.off
    );
}

/// The same cut on the grid `surfrecon distance` makes (padding 4), where
/// the slot stayed open after session 24 (genus 1, surface 0.434 h off
/// the exact boolean): closed with the exact result's genus 0, and the
/// old concave edge's point no longer pulls the cap's fan 0.43 h up to it.
#[test]
fn sculpting_fandisk_cuts_a_hole_under_a_pocket_without_a_handle() {
    let cut = fandisk_minus_cylinder(4);
    assert_closed_manifold(&cut.mesh, 2);
    assert!(cut.settled > 0, "no face settled");
    assert!(cut.straightened > 0, "no floating edge straightened");
    // (before session 27: cap 0.280 h, surface 0.419 h at the rim cell
    // with no point; with its point, 0.377 h above the wall, where an
    // edge from a floating sample interpolated the pocket's floor 0.46 h
    // too high; with that straightened, 0.206 h where a rim cell holding
    // the floor too, two loops, kept its table triangles; before session
    // 28 the cap 0.228 h, where rim cells under the floor took no point
    // or one between cap and floor; now 0.2225 h, at the corner where
    // fandisk's concave edge passes over the rim)
    assert!(
        cut.cap < 0.225,
        "the cap lies {} h from the surface",
        cut.cap
    );
    assert!(
        cut.off < 0.2,
        "the surface leaves the result by {} h",
        cut.off
    );
}

/// The same cylinder cut from fandisk's offset field at the size
/// `surfrecon distance --kind odf --resolution 64` makes. The cap lies
/// 0.3-0.9 h under fandisk's face and its concave edge: before session
/// 37 min/max left the wall between them without a sample inside, the fit
/// kept that (its moves keep the topology), and the surface had a hole
/// through the wall (genus 1; 0.478 / 0.527 h both ways from the exact
/// result). Samples now move into the wall, also where the other sample
/// of their edge sits on the concave edge (the wall's far face), and the
/// fit leaves them there (moved but not pinned: cap 0.244 h, surface
/// 0.250 h off; pinned: 0.100 h, 0.139 h).
#[test]
fn sculpting_an_odf_of_fandisk_keeps_a_wall_thinner_than_a_cell() {
    use surfrecon_distfield::sculpt::{sculpt_odf, Operation, Tool};
    let shape = fandisk();
    let (mut odf, _) = odf_of(&shape, GridSize::Resolution(64));
    let h = odf.spec.spacing;
    let (a, b, radius) = CYLINDER;
    let tool = Tool::Cylinder { a, b, radius };
    let report = sculpt_odf(&mut odf, Operation::Subtract, &tool).unwrap();
    let (mesh, _) = odf.extract();
    assert_closed_manifold(&mesh, 2);
    assert!(report.thin > 0, "no sample moved into the wall");
    assert_no_crossings(&mesh, "fandisk - cylinder");
    let cap = cap_error(&mesh, h);
    let exact = MeshQuery::new(&shape).unwrap();
    let off = dense_points(&mesh)
        .map(|p| exact.signed_distance(p).max(-tool.signed_distance(p)).abs() / h)
        .fold(0.0, f64::max);
    eprintln!("ODF: cap {cap} h from the surface, surface {off} h off the result");
    assert!(cap < 0.15, "the cap lies {cap} h from the surface");
    assert!(off < 0.15, "the surface leaves the result by {off} h");
}

/// Sculpting itself offers the points one point per cell cannot keep:
/// where fandisk − the cylinder's cap rim runs 0.33 h under the pocket's
/// floor, the rim cells' points keep the floor's concave edge, and their
/// table triangles cut the rim. Points on the rim (and the concave edge's
/// old points) become further points of those cells, and the field is
/// written as `.udf` version 2 and read back equal.
#[test]
fn sculpting_keeps_a_rim_under_a_roof_with_further_points() {
    let (udf, report) = fandisk_minus_cylinder_field(4);
    let h = udf.spec.spacing;
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    assert!(report.further > 0 && !udf.cell_points.is_empty());
    assert_eq!(
        report.further,
        udf.cell_points.values().map(Vec::len).sum::<usize>()
    );
    let cap = cap_error(&mesh, h);
    // (one point per cell: 0.2225 h, at the rim under the concave edge)
    assert!(cap < 0.15, "the cap lies {cap} h from the surface");
    let dir = tempfile::tempdir().unwrap();
    written_as_version_2(&udf, &mesh, &dir.path().join("cut.udf"));
}

/// Write `udf` to `path`: a version 2 file that reads back equal and
/// extracts `mesh`'s vertices again.
fn written_as_version_2(udf: &UnifiedField, mesh: &TriMesh, path: &std::path::Path) {
    use surfrecon_distfield::format::{read_udf, write_udf};
    write_udf(path, udf).unwrap();
    assert_eq!(&std::fs::read(path).unwrap()[..8], b"SRUDF\0\0\x02");
    let back = read_udf(path).unwrap();
    assert_eq!(&back, udf);
    assert_eq!(back.extract().0.vertices, mesh.vertices);
}

/// What [`fandisk_minus_cylinder`] measures.
struct CylinderCut {
    mesh: TriMesh,
    /// Samples moved into thin walls, and raised to settle faces.
    thin: usize,
    settled: usize,
    /// Samples set so that edges from floating samples interpolate exactly.
    straightened: usize,
    /// Largest distance (h) from the cap (a disc, on the exact result) to
    /// the surface.
    cap: f64,
    /// Largest distance (h) from the surface to the result (dense; a lower
    /// bound outside).
    off: f64,
}

/// The cylinder the tests above subtract from fandisk: ends and radius.
const CYLINDER: (DVec3, DVec3, f64) = (
    DVec3::new(3.0, 13.5, -1.6),
    DVec3::new(3.0, 15.0, -1.6),
    0.3,
);

/// Fandisk's UDF (64 cells, `padding`) minus [`CYLINDER`], and the
/// sculpting report.
fn fandisk_minus_cylinder_field(
    padding: usize,
) -> (
    surfrecon_distfield::unified::UnifiedField,
    surfrecon_distfield::sculpt::SculptReport,
) {
    use surfrecon_distfield::sculpt::{sculpt_udf, Operation, Tool};
    let (mut udf, _) = build_udf(
        &fandisk(),
        &UdfOptions {
            size: GridSize::Resolution(64),
            padding,
            ..Default::default()
        },
    )
    .unwrap();
    let (a, b, radius) = CYLINDER;
    let tool = Tool::Cylinder { a, b, radius };
    let report = sculpt_udf(&mut udf, Operation::Subtract, &tool, 0.1).unwrap();
    (udf, report)
}

/// Largest distance (h) from [`CYLINDER`]'s cap (a disc around its end,
/// inside fandisk everywhere, so on the exact result) to `mesh`.
fn cap_error(mesh: &TriMesh, h: f64) -> f64 {
    let (_, b, radius) = CYLINDER;
    let disc: Vec<DVec3> = (0..60)
        .flat_map(|i| (1..=10).map(move |r| (i, r)))
        .map(|(i, r)| {
            let angle = std::f64::consts::TAU * i as f64 / 60.0;
            b + DVec3::new(angle.cos(), 0.0, angle.sin()) * (radius * r as f64 / 10.0)
        })
        .collect();
    let exact = MeshQuery::new(&fandisk()).unwrap();
    assert!(disc.iter().all(|&p| exact.signed_distance(p) < 0.0));
    let surface = MeshQuery::new(mesh).unwrap();
    disc.iter()
        .map(|&p| surface.signed_distance(p).abs() / h)
        .fold(0.0, f64::max)
}

/// [`fandisk_minus_cylinder_field`]'s surface measured against the exact
/// result.
fn fandisk_minus_cylinder(padding: usize) -> CylinderCut {
    use surfrecon_distfield::sculpt::Tool;
    let (udf, report) = fandisk_minus_cylinder_field(padding);
    let h = udf.spec.spacing;
    let (a, b, radius) = CYLINDER;
    let tool = Tool::Cylinder { a, b, radius };
    let (mesh, _) = udf.extract();
    let exact = MeshQuery::new(&fandisk()).unwrap();
    let cap = cap_error(&mesh, h);
    let off = dense_points(&mesh)
        .map(|p| exact.signed_distance(p).max(-tool.signed_distance(p)).abs() / h)
        .fold(0.0, f64::max);
    eprintln!(
        "padding {padding}: cap off the surface by {cap} h; surface off the result by {off} h; {} settled",
        report.settled
    );
    CylinderCut {
        mesh,
        thin: report.thin,
        settled: report.settled,
        straightened: report.straightened,
        cap,
        off,
    }
}

/// A mesh's vertices and 10 points inside each triangle (a 4-step
/// lattice; `examples/worst.rs` takes the same ones).
fn dense_points(mesh: &TriMesh) -> impl Iterator<Item = DVec3> + '_ {
    let inner = (0..mesh.triangles.len()).flat_map(|t| lattice_points(mesh.corners(t), 4));
    mesh.vertices.iter().copied().chain(inner)
}

/// The ODF keeps sharp edges where faces lie just inside grid planes, as
/// fandisk's do (0.04 h and 0.15 h): a box whose y and z faces lie that
/// far inside the planes of nodes, and a bar turned to cross the grid at
/// every offset. Exact point-to-triangle errors both ways.
#[test]
fn odf_keeps_edges_of_faces_just_inside_grid_planes() {
    // 20 cells of h = 0.05 along x; y and z leave 0.08 h and 0.3 h of
    // slack, half of it outside each face.
    let h = 0.05;
    let boxed = cuboid(
        DVec3::ZERO,
        DVec3::new(1.0, (15.0 - 0.08) * h, (13.0 - 0.3) * h),
    );
    for (name, shape, cells) in [("box", boxed, 20), ("turned bar", turned_bar(), 24)] {
        let (odf, report) = odf_of(&shape, GridSize::Resolution(cells));
        let h = odf.spec.spacing;
        let (mesh, _) = odf.extract();
        assert_closed_manifold(&mesh, 2);
        let exact = MeshQuery::new(&shape).unwrap();
        let (max, mean) = two_way_error(&shape, &exact, &mesh, 16);
        eprintln!("{name}: {report:?}\nmax {} h, mean {} h", max / h, mean / h);
        // Box 0.005 h, bar 0.12 h (0.42 h and 0.29 h, means 0.0040 h and
        // 0.0022 h, before the block energy, the convex side first and
        // the fit of the feature cells' neighbours).
        let (max_bound, mean_bound) = if name == "box" {
            (0.05, 0.002)
        } else {
            (0.15, 0.0012)
        };
        assert!(max < max_bound * h, "{name}: max {} h", max / h);
        assert!(mean < mean_bound * h, "{name}: mean {} h", mean / h);
    }
}

/// The turned bar with one long edge chamfered by a face `width` wide:
/// two parallel feature lines that close together cross the same cells.
fn chamfered_bar(width: f64) -> TriMesh {
    let c = width / 2f64.sqrt();
    let section = [
        (-0.23, -0.19),
        (0.23, -0.19),
        (0.23, 0.19 - c),
        (0.23 - c, 0.19),
        (-0.23, 0.19),
    ];
    let vertices: Vec<DVec3> = [-1.0, 1.0]
        .iter()
        .flat_map(|&x| section.iter().map(move |&(y, z)| DVec3::new(x, y, z)))
        .collect();
    let n = section.len() as u32;
    let mut triangles = Vec::new();
    for i in 1..n - 1 {
        triangles.push([n, n + i, n + i + 1]); // x = +1, outward +x
        triangles.push([0, i + 1, i]); // x = -1
    }
    for i in 0..n {
        let j = (i + 1) % n;
        triangles.push([i, j, n + j]);
        triangles.push([i, n + j, n + i]);
    }
    let bar = TriMesh {
        vertices,
        triangles,
        normals: None,
    };
    rotate(&bar, [0.13, 0.07, 0.61])
}

/// Two feature lines 0.4 h apart (a chamfer along the turned bar's edge)
/// cross the same cells and leave them through the same faces: one
/// feature point per cell keeps one of them, and the repair's turned and
/// moved samples (which took fandisk's such place from 0.18 h to below
/// 0.1 h) keep the surface closed but gain little along a whole chamfer:
/// its lines stay 0.21 h off (the same without the moves), 0.17-0.24 h
/// for chamfers 0.3-0.5 h wide at 24 and 31 cells. A regression bound,
/// not the 0.1 h goal.
#[test]
fn udf_keeps_two_feature_lines_crossing_the_same_cells() {
    let size = GridSize::Resolution(24);
    let h = grid_for(&turned_bar(), size, 2).unwrap().spacing;
    let bar = chamfered_bar(0.4 * h);
    let (udf, report) = udf_of(&bar, size);
    assert!((udf.spec.spacing - h).abs() < 1e-3 * h);
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let features = surfrecon_distfield::features::Features::detect(&bar, 30.0);
    assert_eq!(features.edges.len(), 15);
    let surface = MeshQuery::new(&mesh).unwrap();
    // The chamfer's two long edges: between vertices 2-7 and 3-8.
    let mut worst = 0.0f64;
    for (a, b) in [(2, 7), (3, 8)] {
        let (a, b) = (bar.vertices[a], bar.vertices[b]);
        worst = worst.max(error_along_edge(&surface, a, b, h));
    }
    let exact = MeshQuery::new(&bar).unwrap();
    let (max, mean) = two_way_error(&bar, &exact, &mesh, 16);
    eprintln!(
        "{report:?}\nchamfer lines {worst} h; everywhere max {} h, mean {} h",
        max / h,
        mean / h
    );
    assert!(report.repaired > 0, "{report:?}");
    assert!(worst < 0.25, "a chamfer line is cut by {worst} h");
    assert!(max < 0.2 * h, "max {} h", max / h);
}

/// Largest distance, in cells of `h`, from `surface` to the edge `a`–`b`,
/// sampled every 0.05 h and more than 1.5 h from its ends (where other
/// edges meet it).
fn error_along_edge(surface: &MeshQuery, a: DVec3, b: DVec3, h: f64) -> f64 {
    let n = (a.distance(b) / (0.05 * h)) as usize;
    (0..=n)
        .map(|k| a.lerp(b, k as f64 / n as f64))
        .filter(|p| p.distance(a).min(p.distance(b)) > 1.5 * h)
        .map(|p| surface.signed_distance(p).abs() / h)
        .fold(0.0, f64::max)
}

/// A blind hole drilled into a cube from below, its flat end (the cap)
/// 0.22 h above a grid plane and 0.7 h under the cube's top face: the
/// cells around the cap's rim hold two sheets, cap and top face. Their
/// feature points come from one sheet's crossings at a time: the tangent
/// planes of both sheets (opposite normals) put the point between them,
/// and the rim's cells kept their table triangles, which cut the rim.
#[test]
fn sculpting_keeps_a_blind_holes_rim_under_a_thin_roof() {
    use surfrecon_distfield::sculpt::{sculpt_udf, Operation, Tool};
    let cube = cuboid(DVec3::ZERO, DVec3::ONE);
    let (mut udf, _) = udf_of(&cube, GridSize::Resolution(24));
    let h = udf.spec.spacing;
    // The highest grid plane whose cap lies at least 0.5 h under the top.
    let oy = udf.spec.origin[1];
    let plane = oy + ((1.0 - 0.72 * h - oy) / h).floor() * h;
    let cap = plane + 0.22 * h;
    let (radius, centre) = (0.23, DVec3::new(0.47, cap, 0.52));
    let tool = Tool::Cylinder {
        a: DVec3::new(centre.x, -0.5, centre.z),
        b: centre,
        radius,
    };
    sculpt_udf(&mut udf, Operation::Subtract, &tool, 0.1).unwrap();
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let surface = MeshQuery::new(&mesh).unwrap();
    let rim = (0..360)
        .map(|i| {
            let angle = std::f64::consts::TAU * i as f64 / 360.0;
            let p = centre + DVec3::new(angle.cos(), 0.0, angle.sin()) * radius;
            surface.signed_distance(p).abs() / h
        })
        .fold(0.0, f64::max);
    // The surface around the hole's end (the cube's own corners are not
    // at stake here).
    let near_end = |p: &DVec3| {
        let across = DVec3::new(p.x - centre.x, 0.0, p.z - centre.z).length();
        across < radius + 2.0 * h && p.y > cap - 3.0 * h
    };
    let (off, at) = dense_points(&mesh)
        .filter(near_end)
        .map(|p| {
            let exact = (p - DVec3::splat(0.5)).abs() - DVec3::splat(0.5);
            let cube = exact.max(DVec3::ZERO).length() + exact.max_element().min(0.0);
            (cube.max(-tool.signed_distance(p)).abs() / h, p)
        })
        .fold((0.0, DVec3::ZERO), |a, b| if b.0 > a.0 { b } else { a });
    eprintln!(
        "roof {} h thick: rim off the surface by {rim} h, surface off by {off} h at {at}",
        (1.0 - cap) / h
    );
    // (before session 28: rim 0.235 h, surface 0.384 h; now 0.037 h and
    // 0.071 h)
    assert!(rim < 0.1, "the rim lies {rim} h from the surface");
    assert!(off < 0.1, "the surface leaves the result by {off} h");
}

/// Where fandisk's concave edge passes over the cylinder's rim (under
/// the pocket's floor), one point per cell keeps the edge or the rim, not
/// both: the corner is cut by 0.22 h. Given as further points, the corner
/// to the cell whose point keeps the concave edge (it lies 0.015 h below
/// that cell) and the concave edge's old point to the rim cell beside it,
/// extraction fans each cell's sheets around both and reaches the corner;
/// the field with them round-trips through a version 2 `.udf`.
#[test]
fn further_points_keep_a_corner_and_an_edge_one_point_per_cell_cuts() {
    use surfrecon_distfield::features::cell_of;
    use surfrecon_distfield::format::{read_udf, write_udf};
    let (mut udf, _) = fandisk_minus_cylinder_field(4);
    // One point per cell, as sculpting keeps without further points.
    udf.cell_points.clear();
    let spec = udf.spec;
    let h = spec.spacing;
    let (one, _) = udf.extract();
    let before = cap_error(&one, h);
    let corner = DVec3::new(2.878, 15.0, -1.874);
    let concave = DVec3::new(2.85126, 15.0326, -1.84753);
    let first = udf.feature_points();
    // Each cell keeps its own point first (the edge's, the rim's).
    for (at, point) in [(DVec3::new(2.9, 15.0, -1.85), corner), (concave, concave)] {
        let cell = cell_of(&spec, at).unwrap();
        let own = first[&cell];
        assert!(own.distance(point) > h / 3.0, "{own} beside {point}");
        udf.cell_points.insert(cell as u32, vec![point]);
    }
    let (both, _) = udf.extract();
    assert_closed_manifold(&both, 2);
    let after = cap_error(&both, h);
    eprintln!("cap off the surface: one point per cell {before} h, further points {after} h");
    // (one point per cell: 0.2225 h; further points: 0.098 h)
    assert!(before > 0.2 && after < 0.15, "{before} h -> {after} h");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.udf");
    written_as_version_2(&udf, &both, &path);
    // Cut anywhere in its further points (or their count), it is refused.
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.udf");
    for less in [1, 8, 28, 29, 36, 56] {
        std::fs::write(&cut, &bytes[..bytes.len() - less]).unwrap();
        let message = read_udf(&cut).unwrap_err().to_string();
        assert!(message.contains("cut.udf"), "{less}: {message}");
    }
    // Without further points the file stays version 1.
    udf.cell_points.clear();
    write_udf(&path, &udf).unwrap();
    assert_eq!(&std::fs::read(&path).unwrap()[..8], b"SRUDF\0\0\x01");
}

/// Two cubes overlapping, written as one mesh: closed, but faces of each
/// cross the other. Their union is a box.
fn overlapping_cubes(angles: [f64; 3]) -> (TriMesh, TriMesh) {
    let mut both = cuboid(DVec3::splat(-0.5), DVec3::splat(0.5));
    both.append(&cuboid(
        DVec3::new(-0.1, -0.5, -0.5),
        DVec3::new(0.9, 0.5, 0.5),
    ));
    let union = cuboid(DVec3::splat(-0.5), DVec3::new(0.9, 0.5, 0.5));
    (rotate(&both, angles), rotate(&union, angles))
}

/// A self-intersecting closed mesh: the unified field signs it by winding
/// number and gives one closed surface near the union (documented robust
/// result); the offset field, whose search would pull samples onto the
/// internal faces (dents 4.5 h deep before it refused), gives one clear
/// error.
#[test]
fn a_self_intersecting_mesh_gives_the_union_or_a_clear_error() {
    use surfrecon_distfield::offset::{build_odf, OdfOptions};
    let (shape, union) = overlapping_cubes([0.3, 0.2, 0.5]);
    let size = GridSize::Resolution(24);
    let (udf, _) = udf_of(&shape, size);
    let h = udf.spec.spacing;
    let (mesh, _) = udf.extract();
    assert_closed_manifold(&mesh, 2);
    let exact = MeshQuery::new(&union).unwrap();
    let (max, mean) = two_way_error(&union, &exact, &mesh, 9);
    let regular = marching_cubes(&regular_field(&shape, size), 0.0);
    let (regular_max, regular_mean) = two_way_error(&union, &exact, &regular, 9);
    eprintln!(
        "udf {} / {} h, regular {} / {} h",
        max / h,
        mean / h,
        regular_max / h,
        regular_mean / h
    );
    // The crossing curve of the two cubes is no edge of the mesh, so the
    // unified field rounds it, by about a cell as the regular field does.
    assert!(max < 1.2 * h, "udf max {} h", max / h);
    assert!(
        mean < 0.25 * regular_mean,
        "udf mean {mean}, regular {regular_mean}"
    );
    let err = build_odf(
        &shape,
        &OdfOptions {
            size,
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("intersects itself"), "{err}");
}

/// Parallel work does not change results: fields built, sculpted and
/// extracted on one thread and on four are identical.
#[test]
fn results_do_not_depend_on_the_number_of_threads() {
    use surfrecon_distfield::sculpt::{sculpt_odf, sculpt_udf, Operation, Tool};
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let shape = rotated_cube();
            let size = GridSize::Resolution(16);
            let (mut udf, _) = udf_of(&shape, size);
            let (mut odf, _) = odf_of(&shape, size);
            let tool = Tool::Sphere {
                centre: shape.vertices[0],
                radius: 0.3,
            };
            let sculpted = sculpt_udf(&mut udf, Operation::Subtract, &tool, 0.1).unwrap();
            sculpt_odf(&mut odf, Operation::Subtract, &tool).unwrap();
            let meshes = (udf.extract().0, odf.extract().0);
            (udf, odf, meshes, sculpted.kept)
        })
    };
    let (one, four) = (run(1), run(4));
    assert!(one.3 > 0, "the sphere makes a new edge");
    assert!(one.0 == four.0, "unified fields differ");
    assert!(one.1 == four.1, "offset fields differ");
    assert!(one.2 == four.2, "extracted meshes differ");
}
