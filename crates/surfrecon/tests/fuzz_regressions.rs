//! Inputs found by the structured fuzz targets (`fuzz/`, `recon_*`),
//! replayed through the facade.

use surfrecon::geom::shapes::icosphere;
use surfrecon::{DVec3, ErrorKind, Geometry, Loss, Method, Options, SvmC, SvmOptions};

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
