//! Inputs found by the structured fuzz targets (`fuzz/`, `recon_*`),
//! replayed through the facade.

use surfrecon::geom::shapes::icosphere;
use surfrecon::{DVec3, ErrorKind, Geometry, Loss, Method, Options, SvmC, SvmOptions};

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
    let e = surfrecon::reconstruct(&flat_icosahedron(), &options).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Failed);
    assert!(
        e.to_string()
            .contains("svm reconstruction found no surface"),
        "{e}"
    );
}
