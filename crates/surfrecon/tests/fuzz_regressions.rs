//! Inputs found by the structured fuzz targets (`fuzz/`, `recon_*`),
//! replayed through the facade.

use surfrecon::geom::shapes::icosphere;
use surfrecon::{
    DVec3, ErrorKind, FieldOutput, Geometry, LevelSetOptions, Loss, Method, Options, PointCloud,
    SvmC, SvmOptions,
};

/// The error of a run that must fail (without printing a whole mesh
/// when it does not).
fn error_of(input: &Geometry, options: &Options) -> surfrecon::Error {
    match surfrecon::reconstruct(input, options) {
        Ok(_) => panic!("reconstruct succeeded"),
        Err(e) => e,
    }
}

/// The fuzzer's input: the 12 vertices of an icosahedron (with its
/// normals) flattened into the plane x = 0 and shrunk to a quarter.
fn flat_icosahedron() -> Geometry {
    let mut mesh = icosphere(DVec3::ZERO, 1.0, 0);
    for v in &mut mesh.vertices {
        *v *= DVec3::new(0.0, 0.25, 0.25);
    }
    Geometry::from_mesh(mesh)
}

/// The SVM fitted to flat data has no zero crossing near it, and
/// `reconstruct` returned Ok with an empty mesh (the command line then
/// wrote a file without faces and said "reconstructed a surface with 0
/// vertices"). Now an error that says so.
#[test]
fn svm_on_flat_data_is_an_error_not_an_empty_surface() {
    let options = Options {
        method: Method::Svm(SvmOptions {
            c: SvmC::Fixed(0.1),
            epsilon: 0.0,
            accuracy: 0.01,
            loss: Loss::Squared,
            drop_levels: 3,
            normal_k: 11,
            ..SvmOptions::default()
        }),
        resolution: Some(15),
        curve_network: false,
        join_pieces: true,
        data_fit: false,
    };
    let e = error_of(&flat_icosahedron(), &options);
    assert_eq!(e.kind, ErrorKind::Failed);
    assert!(
        e.to_string()
            .contains("svm reconstruction found no surface"),
        "{e}"
    );
}

/// Coordinates near 1e300: a k-d tree search of the SVM's training set
/// compared NaN squared distances and panicked (kiddo's `unwrap` of
/// `partial_cmp`). Such data are now refused up front, whatever the
/// method, with a message that says what to do.
#[test]
fn coordinates_near_the_f64_limit_are_refused() {
    let mut mesh = icosphere(DVec3::ZERO, 1.0, 1);
    for v in &mut mesh.vertices {
        *v *= DVec3::new(0.0, 3.25, 3.75);
    }
    mesh.vertices[28] = DVec3::new(-1.0, -3.75, -2.5);
    for v in &mut mesh.vertices {
        *v *= 1e300;
    }
    let input = Geometry::from_mesh(mesh);
    let svm = Method::Svm(SvmOptions {
        loss: Loss::Squared,
        normal_k: 0,
        ..SvmOptions::default()
    });
    for method in [
        svm,
        Method::LevelSet(Default::default()),
        Method::Convection(Default::default()),
    ] {
        let options = Options {
            method,
            resolution: Some(0),
            curve_network: false,
            join_pieces: true,
            data_fit: false,
        };
        let e = error_of(&input, &options);
        assert_eq!(e.kind, ErrorKind::InvalidInput);
        assert!(e.to_string().contains("rescale the data"), "{e}");
    }
    // Data spanning less than 1e-100 are refused the same way.
    let mut tiny = flat_icosahedron();
    tiny.points
        .positions
        .iter_mut()
        .for_each(|p| *p = *p * 1e-200 + DVec3::X);
    let e = error_of(&tiny, &Options::default());
    assert!(e.to_string().contains("the data span only"), "{e}");
}

/// The fuzzer's input (`recon_svm`, a 30-minute run): three points a few
/// units apart at coordinates near 2e16 (an ulp there is 4), each eight
/// times; SVM, C chosen, ε 0, cleaning off. The fit ran for half a minute
/// (libFuzzer called it a hang) before the mesh grid was refused as finer
/// than f64 resolves there. The SVM now runs on the data moved near the
/// origin: the same surface as there, moved; the finding's resolution 0
/// is then refused as such.
#[test]
fn svm_on_three_points_near_2e16_is_the_surface_near_the_origin_moved() {
    let three = [
        DVec3::new(-7500000000000003.0, -2.0000000000000004e16, -1.5e16),
        DVec3::new(-7500000000000002.0, -2e16, -1.5000000000000004e16),
        DVec3::new(
            -7500000000000004.0,
            -2.0000000000000004e16,
            -1.5000000000000002e16,
        ),
    ];
    let shift = DVec3::new(-7.5e15, -2e16, -1.5e16);
    let near_origin: Vec<DVec3> = three.repeat(8).iter().map(|&p| p - shift).collect();
    let svm = Method::Svm(SvmOptions {
        c: SvmC::Auto,
        epsilon: 0.0,
        accuracy: 0.0002,
        loss: Loss::Epsilon,
        drop_levels: 0,
        normal_k: 0,
        cleaning: false,
        ..SvmOptions::default()
    });
    compare_moved(&near_origin, shift, 16, &svm);
    let far = Geometry::from_points(PointCloud::new(three.repeat(8)));
    let options = Options {
        method: svm,
        resolution: Some(0),
        curve_network: false,
        join_pieces: false,
        data_fit: false,
    };
    let e = error_of(&far, &options);
    assert_eq!(e.kind, ErrorKind::InvalidInput);
    assert!(format!("{e:?}").contains("resolution"), "{e:?}");
}

/// The fuzzer's input: one point near 1e30 (with six degenerate
/// triangles on it), ε = 0.1, resolution 4. Planar, so the 2D level set
/// ran on a grid of spacing 0.25 whose nodes all had the same position
/// (an ulp there is 1.4e14): every distance was 0 and the curve came out
/// open. The level set now runs relative to the data's centre.
#[test]
fn a_single_point_near_1e30_gives_a_closed_curve_around_it() {
    let p = DVec3::new(-7.500000000000001e29, -3.75e30, -3.0000000000000003e30);
    let input = Geometry {
        points: PointCloud::new(vec![p]),
        triangles: vec![[0, 0, 0]; 6],
        lines: vec![],
    };
    let options = Options {
        method: Method::LevelSet(LevelSetOptions {
            epsilon: Some(0.1),
            p: 1.0,
            steps: 24,
            band: 2.0,
            levels: None,
            bounding_box: false,
            free_topology: false,
            cleaning: true,
            refine: false,
            slices: false,
            two_d: false,
            field: FieldOutput::None,
        }),
        resolution: Some(4),
        curve_network: false,
        join_pieces: true,
        data_fit: false,
    };
    let out = surfrecon::reconstruct(&input, &options).unwrap();
    let curves = out.curves.expect("planar data: curves");
    assert!(!curves.lines.is_empty());
    for line in &curves.lines {
        assert!(
            line.len() > 3 && line.first() == line.last(),
            "open curve {line:?}"
        );
    }
    // Around the point: within ε plus a few cells, and the rounding of
    // coordinates near 1e30.
    let reach = 0.1 + 3.0 * 0.25 + 4.0 * f64::EPSILON * 3.75e30;
    for v in &curves.vertices {
        let d = (v.truncate() - p.truncate()).length();
        assert!(d <= reach, "vertex {v} is {d:e} from the point");
    }
}

/// A reconstruction far from the origin is the one at the origin, moved:
/// with the grid spacing below an ulp of the coordinates (2D at 2^49 +
/// 2^48, 3D at 2^52), the nodes used to collapse.
#[test]
fn reconstructions_far_from_the_origin_are_moved_copies() {
    // 2D: a circle of radius 8, coordinates multiples of 1/8 (exact at
    // the shift, where an ulp is 1/8); spacing 1/16.
    let circle: Vec<DVec3> = (0..64)
        .map(|k| {
            let t = k as f64 / 64.0 * std::f64::consts::TAU;
            (DVec3::new(t.cos(), t.sin(), 0.0) * 64.0).round() / 8.0
        })
        .collect();
    let shift = DVec3::new(2f64.powi(49) + 2f64.powi(48), -(2f64.powi(49)), 0.0);
    compare_moved(&circle, shift, 256, &level_set());
    // 3D: a sphere of radius 16, integer coordinates (an ulp at 2^52 is
    // 1); spacing 0.8.
    let sphere: Vec<DVec3> = icosphere(DVec3::ZERO, 16.0, 2)
        .vertices
        .iter()
        .map(|v| v.round())
        .collect();
    let shift = DVec3::new(2f64.powi(52), 0.0, -(2f64.powi(52)));
    compare_moved(&sphere, shift, 40, &level_set());
    // The SVM too (it fitted for half a minute on eight points a few units
    // apart near 2e16, then refused the mesh grid as too fine).
    compare_moved(&sphere, shift, 40, &Method::Svm(SvmOptions::default()));
}

fn level_set() -> Method {
    Method::LevelSet(LevelSetOptions {
        refine: false,
        ..LevelSetOptions::default()
    })
}

/// Reconstruct `points` and `points + shift` with `method` at
/// `resolution`: same curves or triangles, vertices within the rounding
/// of the shifted coordinates.
fn compare_moved(points: &[DVec3], shift: DVec3, resolution: usize, method: &Method) {
    let options = Options {
        method: method.clone(),
        resolution: Some(resolution),
        curve_network: false,
        join_pieces: true,
        data_fit: false,
    };
    let run = |by: DVec3| {
        let moved = points.iter().map(|&p| p + by).collect();
        surfrecon::reconstruct(&Geometry::from_points(PointCloud::new(moved)), &options).unwrap()
    };
    let (home, far) = (run(DVec3::ZERO), run(shift));
    for p in points {
        assert_eq!(*p + shift - shift, *p, "the test's points move exactly");
    }
    let ulp = shift.abs().max_element() * f64::EPSILON;
    let (a, b) = match (home.curves, far.curves) {
        (Some(a), Some(b)) => {
            assert_eq!(a.lines, b.lines, "the same curves");
            (a.vertices, b.vertices)
        }
        _ => {
            assert_eq!(
                home.mesh.triangles, far.mesh.triangles,
                "the same triangles"
            );
            (home.mesh.vertices, far.mesh.vertices)
        }
    };
    assert!(!a.is_empty() && a.len() == b.len());
    for (u, v) in a.iter().zip(&b) {
        let d = (*v - shift - *u).abs().max_element();
        assert!(d <= ulp, "{v} against {u} moved: {d}");
    }
}
