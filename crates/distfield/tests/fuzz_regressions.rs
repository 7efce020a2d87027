//! Inputs found by `fuzz/run.sh` (targets `odf`, `udf`), replayed: each must
//! be a clear error, not a field the writer then stores differently.

use std::path::Path;
use surfrecon_distfield::format::{read_odf, read_udf};
use surfrecon_distfield::offset::{build_odf, OdfOptions};
use surfrecon_distfield::unified::{build_udf, UdfOptions};
use surfrecon_geom::metrics::topology;
use surfrecon_geom::shapes::{cuboid, icosphere};
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::GridSize;

fn stored(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn nan_sample_positions_are_refused() {
    // Found by the fuzzer: a moved sample (.odf) or a position extra (.udf)
    // with a NaN coordinate passed the "inside its cell" check (the NaN was
    // skipped by max_element) and came back from a round trip unequal.
    let dir = tempfile::tempdir().unwrap();
    let odf = stored(
        dir.path(),
        "nan.odf",
        include_bytes!("data/fuzz-odf-nan-position.odf"),
    );
    let message = read_odf(&odf).unwrap_err().to_string();
    assert!(
        message.contains("outside its cell") && message.contains("NaN"),
        "{message}"
    );
    let udf = stored(
        dir.path(),
        "nan.udf",
        include_bytes!("data/fuzz-udf-nan-position.udf"),
    );
    let message = read_udf(&udf).unwrap_err().to_string();
    assert!(
        message.contains("outside its cell") && message.contains("NaN"),
        "{message}"
    );
}

/// The structured fuzzer's mesh (target `feature_field`): an icosahedron
/// flattened to x = 0, scaled by (0, 250, 250) and moved to x = y = -4e19,
/// where its y coordinates vanish (an ulp there is 8192): a needle along
/// z, closed and of no volume, centred at (`x`, `x`, 0).
fn needle(x: f64) -> TriMesh {
    let (a, b) = (212.66270208801, 131.4327780297834);
    let zs = [0.0, 0.0, 0.0, 0.0, a, a, -a, -a, -b, b, -b, b];
    let mesh = icosphere(DVec3::ZERO, 1.0, 0);
    TriMesh {
        vertices: zs.iter().map(|&z| DVec3::new(x, x, z)).collect(),
        ..mesh
    }
}

/// At resolution 4 with padding 1 the udf's grid had spacing 106 at 4e19:
/// its nodes in x and y all had one position, lying on the needle, and
/// the extracted surface had 16 boundary edges. Such a grid is now
/// refused; near the origin the same needle gives no surface (it has no
/// inside), and a solid box a closed one, for every padding.
#[test]
fn udf_grids_finer_than_the_coordinates_precision_are_refused() {
    let options = |padding| UdfOptions {
        size: GridSize::Resolution(4),
        padding,
        threshold: 0.0,
        feature_angle_deg: 0.0,
    };
    let e = build_udf(&needle(-4e19), &options(1))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("too fine for coordinates as large as 4.000e19"),
        "{e}"
    );
    for padding in 1..=3 {
        let (field, _) = build_udf(&needle(5.0), &options(padding)).unwrap();
        let (surface, _) = field.extract();
        assert!(surface.triangles.is_empty(), "padding {padding}");
        let solid = cuboid(DVec3::new(-3.0, -1.0, -2.0), DVec3::new(1.0, 2.0, 5.0));
        let (field, _) = build_udf(&solid, &options(padding)).unwrap();
        let t = topology(&field.extract().0);
        assert!(
            t.watertight && t.edge_manifold && t.vertex_manifold,
            "padding {padding}: {t:?}"
        );
    }
}

/// Found by the `feature_field` target: an icosphere 5e-151 wide (every
/// edge a feature, resolution 7) took 72 s instead of milliseconds, its
/// squared distances and cell volumes being subnormal numbers. Meshes
/// that small are refused, as `reconstruct` refuses such data; the same
/// sphere at unit size is built.
#[test]
fn meshes_too_small_for_f64_are_refused() {
    let options = UdfOptions {
        size: GridSize::Resolution(7),
        padding: 0,
        threshold: 0.0,
        feature_angle_deg: 0.0,
    };
    let tiny = icosphere(DVec3::ZERO, 2.5e-151, 1);
    let e = build_udf(&tiny, &options).unwrap_err().to_string();
    assert!(e.contains("the mesh spans only 5e-151"), "{e}");
    assert!(e.contains("rescale it"), "{e}");
    let odf = OdfOptions {
        size: GridSize::Resolution(7),
        ..OdfOptions::default()
    };
    let e = build_odf(&tiny, &odf).unwrap_err().to_string();
    assert!(e.contains("the mesh spans only 5e-151"), "{e}");
    assert!(build_udf(&icosphere(DVec3::ZERO, 2.5, 1), &options).is_ok());
    let huge = icosphere(DVec3::splat(3e100), 1.0, 1);
    let e = build_udf(&huge, &options).unwrap_err().to_string();
    assert!(e.contains("reaches coordinate 3"), "{e}");
}
