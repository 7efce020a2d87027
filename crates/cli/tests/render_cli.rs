//! End-to-end tests of `surfrecon render`: real files in, decoded PNGs out.

mod common;
use common::{path_str, surfrecon};

use surfrecon_geom::render::read_png;
use surfrecon_geom::shapes::{cuboid, icosphere, sample_surface};
use surfrecon_geom::{io, DVec3, Geometry, PointCloud};

const BACKGROUND: [u8; 3] = [250, 250, 248];

#[test]
fn renders_a_wireframe_cube_to_a_png_of_the_requested_size() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cube.off");
    io::write(
        &input,
        &Geometry::from_mesh(cuboid(DVec3::ZERO, DVec3::ONE)),
    )
    .unwrap();
    let output = dir.path().join("view.png");
    let run = surfrecon(&[
        "render",
        path_str(&input),
        "-o",
        path_str(&output),
        "--size",
        "120x90",
        "--view",
        "30,20",
        "--wireframe",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let img = read_png(&output).unwrap();
    assert_eq!((img.width, img.height), (120, 90));
    assert_eq!(img.pixel(0, 0), BACKGROUND);
    assert_eq!(img.pixel(119, 89), BACKGROUND);
    assert_ne!(img.pixel(60, 45), BACKGROUND);
    // Wireframe edges: some pixels are much darker than any shaded face.
    let darkest = (0..90)
        .flat_map(|y| (0..120).map(move |x| (x, y)))
        .map(|(x, y)| img.pixel(x, y).iter().map(|&c| c as u32).sum::<u32>())
        .min()
        .unwrap();
    assert!(darkest < 200, "darkest pixel sum {darkest}");
}

#[test]
fn point_cloud_with_json_summary_and_square_size() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ball.xyz");
    let cloud = sample_surface(&icosphere(DVec3::ZERO, 1.0, 2), 500, 1);
    io::write(
        &input,
        &Geometry::from_points(PointCloud::new(cloud.positions)),
    )
    .unwrap();
    let output = dir.path().join("points.png");
    let run = surfrecon(&[
        "--json",
        "render",
        path_str(&input),
        "-o",
        path_str(&output),
        "--size",
        "64",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).expect("one JSON object");
    assert_eq!(summary["width"], 64);
    assert_eq!(summary["height"], 64);
    assert_eq!(summary["vertices"], 500);
    let img = read_png(&output).unwrap();
    assert_eq!((img.width, img.height), (64, 64));
    // The ball fills most of the frame; splats of random samples leave a
    // few gaps, so count rather than probe one pixel.
    let drawn = (0..64)
        .flat_map(|y| (0..64).map(move |x| (x, y)))
        .filter(|&(x, y)| img.pixel(x, y) != BACKGROUND)
        .count();
    assert!(drawn > 64 * 64 / 2, "{drawn} pixels drawn");
    assert_eq!(img.pixel(0, 0), BACKGROUND);
}

#[test]
fn failures_print_one_line_and_leave_no_picture() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("never.png");
    let missing = dir.path().join("missing.ply");
    let run = surfrecon(&["render", path_str(&missing), "-o", path_str(&output)]);
    assert_eq!(run.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.starts_with("error:") && stderr.contains("missing.ply"),
        "{stderr}"
    );
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");

    let input = dir.path().join("cube.obj");
    io::write(
        &input,
        &Geometry::from_mesh(cuboid(DVec3::ZERO, DVec3::ONE)),
    )
    .unwrap();
    for bad in [
        ["--size", "0x10"],
        ["--size", "99999"],
        ["--view", "10,100"],
        ["--view", "north"],
    ] {
        let run = surfrecon(&[
            "render",
            path_str(&input),
            "-o",
            path_str(&output),
            bad[0],
            bad[1],
        ]);
        assert!(!run.status.success(), "{bad:?} was accepted");
    }
    assert!(!output.exists());
}

#[test]
fn negative_view_angles_are_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ball.obj");
    io::write(&input, &Geometry::from_mesh(icosphere(DVec3::ZERO, 1.0, 1))).unwrap();
    let output = dir.path().join("below.png");
    let run = surfrecon(&[
        "render",
        path_str(&input),
        "-o",
        path_str(&output),
        "--view",
        "-40,-30",
        "--size",
        "40x30",
        "--up",
        "z",
        "--flat",
        "--ortho",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(read_png(&output).unwrap().width, 40);
}
