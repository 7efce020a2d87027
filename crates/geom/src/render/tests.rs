use super::camera::Camera;
use super::*;
use crate::shapes::{cuboid, icosphere, sample_surface};
use crate::{DVec3, PointCloud, Polylines};

fn small() -> RenderOptions {
    RenderOptions {
        width: 160,
        height: 120,
        ..Default::default()
    }
}

/// Pixels that differ from the background.
fn object_pixels(img: &Image, background: [u8; 3]) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for y in 0..img.height {
        for x in 0..img.width {
            if img.pixel(x, y) != background {
                out.push((x, y));
            }
        }
    }
    out
}

fn luminance(c: [u8; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Checks shared by every picture of a whole object: something is drawn,
/// it is centred, it stays inside the frame with the margin, corners are
/// background.
fn assert_framed(img: &Image, background: [u8; 3]) {
    let (w, h) = (img.width, img.height);
    for (x, y) in [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1)] {
        assert_eq!(img.pixel(x, y), background, "corner ({x}, {y})");
    }
    let px = object_pixels(img, background);
    assert!(
        px.len() as f64 > 0.1 * (w * h) as f64,
        "only {} object pixels",
        px.len()
    );
    let (x0, x1) = (
        px.iter().map(|p| p.0).min().unwrap(),
        px.iter().map(|p| p.0).max().unwrap(),
    );
    let (y0, y1) = (
        px.iter().map(|p| p.1).min().unwrap(),
        px.iter().map(|p| p.1).max().unwrap(),
    );
    // 6% margin on each side, give or take an antialiased pixel.
    assert!(x0 >= w / 25 && x1 <= w - 1 - w / 25, "x range {x0}..{x1}");
    assert!(y0 >= h / 25 && y1 <= h - 1 - h / 25, "y range {y0}..{y1}");
    let (cx, cy) = ((x0 + x1) as f64 / 2.0, (y0 + y1) as f64 / 2.0);
    assert!(
        (cx - w as f64 / 2.0).abs() <= 2.0 && (cy - h as f64 / 2.0).abs() <= 2.0,
        "centre ({cx}, {cy})"
    );
    // The object touches the margin in at least one direction (fit to frame).
    let fill =
        ((x1 - x0 + 1) as f64 / (0.88 * w as f64)).max((y1 - y0 + 1) as f64 / (0.88 * h as f64));
    assert!((fill - 1.0).abs() < 0.05, "fill {fill}");
}

#[test]
fn icosphere_is_shaded_centred_and_framed() {
    let options = small();
    let mesh = icosphere(DVec3::new(3.0, -1.0, 2.0), 0.5, 3);
    let img = render(&Geometry::from_mesh(mesh), &options).unwrap();
    assert_eq!(
        (img.width, img.height, img.pixels.len()),
        (160, 120, 160 * 120 * 3)
    );
    assert_framed(&img, options.background);
    // Lit from the upper left: the upper-left of the ball is brighter.
    let lum = |x, y| luminance(img.pixel(x, y));
    assert!(
        lum(70, 50) > lum(90, 70) + 10.0,
        "{} vs {}",
        lum(70, 50),
        lum(90, 70)
    );
}

#[test]
fn orthographic_sphere_covers_a_disk_of_the_fitted_size() {
    let options = RenderOptions {
        width: 200,
        height: 100,
        projection: Projection::Orthographic,
        ..Default::default()
    };
    let img = render(
        &Geometry::from_mesh(icosphere(DVec3::ZERO, 1.0, 4)),
        &options,
    )
    .unwrap();
    // The disk spans the usable height: 88 pixels across.
    let coverage: f64 = (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let c = img.pixel(x, y);
            let bg = options.background;
            // Fractional coverage from the antialiased edge: distance to the
            // background colour relative to a fully covered pixel is not
            // known, so count partly covered pixels as half.
            if c == bg {
                0.0
            } else if (0..3).all(|i| (c[i] as i32 - bg[i] as i32).abs() < 40) {
                0.5
            } else {
                1.0
            }
        })
        .sum();
    let disk = std::f64::consts::PI * 44.0 * 44.0;
    assert!(
        (coverage - disk).abs() / disk < 0.04,
        "{coverage} vs {disk}"
    );
}

#[test]
fn wireframe_cube_has_dark_visible_edges_and_hides_back_edges() {
    let cube = Geometry::from_mesh(cuboid(DVec3::splat(-1.0), DVec3::splat(1.0)));
    let plain_options = small();
    let wire_options = RenderOptions {
        wireframe: true,
        ..small()
    };
    let plain = render(&cube, &plain_options).unwrap();
    let wired = render(&cube, &wire_options).unwrap();
    let darkened = |x: u32, y: u32| luminance(plain.pixel(x, y)) - luminance(wired.pixel(x, y));
    let edge_pixels = (0..120)
        .flat_map(|y| (0..160).map(move |x| (x, y)))
        .filter(|&(x, y)| darkened(x, y) > 60.0 && luminance(wired.pixel(x, y)) < 90.0)
        .count();
    // Nine visible edges of about 50 pixels each, at least a pixel wide.
    assert!(edge_pixels > 300, "{edge_pixels} dark edge pixels");
    assert_framed(&wired, wire_options.background);

    // Where corners land on screen (same camera as the renderer).
    let ss = wire_options.samples_per_side() as f64;
    let used = vec![true; 8];
    let cam = Camera::fit(
        &cube.points.positions,
        &used,
        &wire_options,
        160.0 * ss,
        120.0 * ss,
    );
    let darkening_near = |p: DVec3| {
        let s = cam.project(p);
        let (x, y) = ((s.x / ss) as i64, (s.y / ss) as i64);
        (-2..=2)
            .flat_map(|dy| (-2..=2).map(move |dx| ((x + dx) as u32, (y + dy) as u32)))
            .map(|(x, y)| darkened(x, y))
            .fold(f64::NEG_INFINITY, f64::max)
    };
    // The corner nearest the eye (35° azimuth, 25° elevation) shows its
    // three edges; the hidden far corner and its edges stay covered.
    assert!(darkening_near(DVec3::ONE) > 60.0);
    assert!(darkening_near(DVec3::splat(-1.0)) < 1.0);
}

#[test]
fn point_clouds_render_with_and_without_normals() {
    let options = small();
    let sphere = icosphere(DVec3::ZERO, 1.0, 3);
    let with_normals = sample_surface(&sphere, 4000, 7);
    let without = PointCloud::new(with_normals.positions.clone());
    for cloud in [with_normals, without] {
        let img = render(&Geometry::from_points(cloud), &options).unwrap();
        assert_framed(&img, options.background);
    }
    // A single point and coincident points still draw a visible dot.
    for cloud in [vec![DVec3::ONE], vec![DVec3::ONE; 3]] {
        let img = render(&Geometry::from_points(PointCloud::new(cloud)), &options).unwrap();
        assert_ne!(img.pixel(80, 60), options.background);
        assert_eq!(img.pixel(5, 5), options.background);
    }
}

#[test]
fn splat_size_option_changes_coverage() {
    let cloud = sample_surface(&icosphere(DVec3::ZERO, 1.0, 2), 300, 3);
    let geometry = Geometry::from_points(cloud);
    let count = |size| {
        let options = RenderOptions {
            point_size: Some(size),
            ..small()
        };
        object_pixels(&render(&geometry, &options).unwrap(), options.background).len()
    };
    assert!(count(6.0) > 2 * count(2.0));
}

#[test]
fn polylines_are_drawn_as_strokes() {
    let n = 64;
    let circle = Polylines {
        vertices: (0..n)
            .map(|i| {
                let a = i as f64 / n as f64 * std::f64::consts::TAU;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect(),
        lines: vec![(0..n as u32).chain([0]).collect()],
    };
    let options = RenderOptions {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        ..small()
    };
    let img = render(&Geometry::from_polylines(circle), &options).unwrap();
    // Viewed head-on: a ring; the middle stays empty.
    assert_eq!(img.pixel(80, 60), options.background);
    let ring = object_pixels(&img, options.background);
    let radius = 0.44 * 120.0;
    for &(x, y) in &ring {
        let r = ((x as f64 + 0.5 - 80.0).powi(2) + (y as f64 + 0.5 - 60.0).powi(2)).sqrt();
        assert!((r - radius).abs() < 3.0, "pixel ({x}, {y}) at radius {r}");
    }
    assert!(ring.len() as f64 > 2.0 * std::f64::consts::PI * radius);
}

#[test]
fn back_faces_get_the_back_colour() {
    let triangle = crate::TriMesh {
        vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
        triangles: vec![[0, 1, 2]],
        normals: None,
    };
    let geometry = Geometry::from_mesh(triangle);
    let at = |azimuth_deg| {
        let options = RenderOptions {
            azimuth_deg,
            elevation_deg: 0.0,
            ..small()
        };
        let img = render(&geometry, &options).unwrap();
        let px = object_pixels(&img, options.background);
        let (x, y) = px[px.len() / 2];
        img.pixel(x, y)
    };
    let front = at(10.0); // counter-clockwise seen from +z: front
    let back = at(170.0);
    assert!(front[2] > front[0], "front {front:?}");
    assert!(back[0] > back[2], "back {back:?}");
}

#[test]
fn picture_does_not_depend_on_thread_count() {
    let mesh = icosphere(DVec3::ZERO, 1.0, 3);
    let mut geometry = Geometry::from_mesh(mesh);
    geometry.lines = vec![vec![0, 5, 9, 40]];
    let options = RenderOptions {
        wireframe: true,
        ..small()
    };
    let in_pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render(&geometry, &options).unwrap())
    };
    assert_eq!(in_pool(1), in_pool(3));
}

#[test]
fn png_round_trip_keeps_every_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("view.png");
    let img = render(
        &Geometry::from_mesh(icosphere(DVec3::ZERO, 1.0, 2)),
        &small(),
    )
    .unwrap();
    write_png(&path, &img).unwrap();
    assert_eq!(read_png(&path).unwrap(), img);
    // Overwriting works and leaves no temporary files behind.
    write_png(&path, &Image::filled(3, 2, [1, 2, 3])).unwrap();
    assert_eq!(read_png(&path).unwrap(), Image::filled(3, 2, [1, 2, 3]));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn png_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bogus = dir.path().join("bogus.png");
    std::fs::write(&bogus, b"not a png at all").unwrap();
    let err = read_png(&bogus).unwrap_err().to_string();
    assert!(err.contains("bogus.png") && err.contains("PNG"), "{err}");
    let missing = dir.path().join("missing.png");
    assert!(read_png(&missing)
        .unwrap_err()
        .to_string()
        .contains("missing.png"));
    let nowhere = dir.path().join("no-such-dir").join("out.png");
    let err = write_png(&nowhere, &Image::filled(2, 2, [0; 3])).unwrap_err();
    assert!(err.to_string().contains("out.png"), "{err}");
    let broken = Image {
        width: 4,
        height: 4,
        pixels: vec![0; 5],
    };
    assert!(write_png(dir.path().join("b.png"), &broken).is_err());
    assert!(!dir.path().join("b.png").exists());
}

#[test]
fn unusable_input_is_a_clear_error() {
    let sphere = Geometry::from_mesh(icosphere(DVec3::ZERO, 1.0, 1));
    let message = |g: &Geometry, o: &RenderOptions| render(g, o).unwrap_err().to_string();
    assert!(message(&Geometry::default(), &small()).contains("no vertices"));
    let huge = RenderOptions {
        width: 20000,
        ..small()
    };
    assert!(message(&sphere, &huge).contains("too large"));
    let wide = RenderOptions {
        width: 16000,
        height: 16000,
        ..small()
    };
    assert!(message(&sphere, &wide).contains("too large"));
    let empty = RenderOptions {
        height: 0,
        ..small()
    };
    assert!(message(&sphere, &empty).contains("empty"));
    let steep = RenderOptions {
        elevation_deg: 95.0,
        ..small()
    };
    assert!(message(&sphere, &steep).contains("elevation"));
    let nan_view = RenderOptions {
        azimuth_deg: f64::NAN,
        ..small()
    };
    assert!(message(&sphere, &nan_view).contains("azimuth"));

    let mut bad_index = sphere.clone();
    bad_index.triangles[3][1] = 10_000;
    assert!(message(&bad_index, &small()).contains("triangle 3 refers to vertex 10000"));
    let mut bad_line = sphere.clone();
    bad_line.lines = vec![vec![0, 99_999]];
    assert!(message(&bad_line, &small()).contains("line 0"));
    let mut nan = sphere.clone();
    nan.points.positions[2].y = f64::NAN;
    assert!(message(&nan, &small()).contains("vertex 2"));
    let mut short_normals = sphere;
    short_normals.points.normals = Some(vec![DVec3::X]);
    assert!(message(&short_normals, &small()).contains("normals"));
}

#[test]
fn extreme_scales_draw_or_fail_cleanly() {
    let options = small();
    // Far apart but representable: drawn as three dots.
    let far = vec![DVec3::splat(1e300), DVec3::splat(-1e300), DVec3::ZERO];
    let img = render(&Geometry::from_points(PointCloud::new(far)), &options).unwrap();
    assert!(object_pixels(&img, options.background).len() > 30);
    // A box wider than the largest f64 cannot be framed.
    let overflow = vec![DVec3::splat(f64::MAX), DVec3::splat(-f64::MAX)];
    match render(&Geometry::from_points(PointCloud::new(overflow)), &options) {
        Err(e) => assert!(e.to_string().contains("too large"), "{e}"),
        Ok(_) => panic!("an overflowing bounding box was accepted"),
    }
    // A tiny but proper shape still fills the frame.
    let tiny = icosphere(DVec3::splat(1e-200), 1e-200, 2);
    assert_framed(
        &render(&Geometry::from_mesh(tiny), &options).unwrap(),
        options.background,
    );
}

#[test]
fn huge_images_lower_supersampling_instead_of_failing() {
    let options = RenderOptions {
        width: 8192,
        height: 8192,
        ..Default::default()
    };
    assert_eq!(options.samples_per_side(), 1);
    assert_eq!(small().samples_per_side(), 3);
}
