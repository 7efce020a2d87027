//! Every real file in the shared data directory parses with the counts its
//! README lists. Skipped with a note when the directory is absent.

use crate::io::read;
use std::path::PathBuf;

/// (path under the data directory, vertices, triangles, has normals).
/// Face counts are the README's; `cube.off` has 6 quads, so 12 triangles.
const FILES: &[(&str, usize, usize, bool)] = &[
    (
        "stanford_bunny/reconstruction/bun_zipper.ply",
        35_947,
        69_451,
        false,
    ),
    (
        "stanford_bunny/reconstruction/bun_zipper_res2.ply",
        8_171,
        16_301,
        false,
    ),
    (
        "stanford_bunny/reconstruction/bun_zipper_res3.ply",
        1_889,
        3_851,
        false,
    ),
    (
        "stanford_bunny/reconstruction/bun_zipper_res4.ply",
        453,
        948,
        false,
    ),
    (
        "stanford_bunny/reconstruction/bun_zipper_binary_le.ply",
        35_947,
        69_451,
        false,
    ),
    ("stanford_bunny/scans/bun000.ply", 40_256, 0, false),
    ("stanford_bunny/scans/bun045.ply", 40_097, 0, false),
    ("stanford_bunny/scans/bun090.ply", 30_379, 0, false),
    ("stanford_bunny/scans/bun180.ply", 40_251, 0, false),
    ("stanford_bunny/scans/bun270.ply", 31_701, 0, false),
    ("stanford_bunny/scans/bun315.ply", 35_336, 0, false),
    ("stanford_bunny/scans/chin.ply", 37_738, 0, false),
    ("stanford_bunny/scans/ear_back.ply", 32_193, 0, false),
    ("stanford_bunny/scans/top2.ply", 38_298, 0, false),
    ("stanford_bunny/scans/top3.ply", 36_023, 0, false),
    ("fandisk/fandisk.off", 7_229, 14_454, false),
    ("fandisk/fandisk_cgal.off", 6_475, 12_946, false),
    ("small/vipss/torus_gt.obj", 4_096, 8_192, false),
    ("small/vipss/torus_wires.xyz", 991, 0, false),
    ("small/vipss/torus_crosscut.xyz", 1_000, 0, false),
    ("small/vipss/torus_parallelcut.xyz", 499, 0, false),
    ("small/vipss/torus_halfsamplel500_r25.xyz", 241, 0, false),
    ("small/vipss/torus_multisample_n25.xyz", 25, 0, false),
    ("small/vipss/torus_multisample_n50.xyz", 50, 0, false),
    ("small/vipss/kitten_gt.obj", 14_472, 28_944, false),
    ("small/vipss/kitten_500.xyz", 500, 0, false),
    ("small/vipss/kitten_500_noisy_h001.xyz", 500, 0, false),
    ("small/vipss/kitten_500_noisy_h004.xyz", 500, 0, false),
    ("small/vipss/spring_wireframe.xyz", 999, 0, false),
    ("small/libigl/sphere.obj", 382, 760, false),
    ("small/libigl/cube.off", 8, 12, false),
    ("small/libigl/TinyTorus.obj", 24, 48, false),
    ("small/cgal/oni.ply", 1_435, 0, true),
    ("small/cgal/kitten.xyz", 5_210, 0, true),
    ("small/cgal/sphere_1k.xyz", 1_050, 0, true),
    ("small/pcl/colored_cloud.ply", 1_000, 0, true),
];

fn data_dir() -> Option<PathBuf> {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let candidates = [
        std::env::var_os("SURFRECON_DATA").map(PathBuf::from),
        Some(manifest.join("../../../shared/data")),
        Some(PathBuf::from("/work/shared/data")),
    ];
    candidates
        .into_iter()
        .flatten()
        .find(|d| d.join("README.md").is_file())
}

#[test]
fn every_shared_data_file_reads_with_its_counts() {
    let Some(dir) = data_dir() else {
        eprintln!("note: shared data directory not found; real-file test skipped");
        return;
    };
    for &(name, vertices, triangles, normals) in FILES {
        let g = read(dir.join(name)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(g.points.len(), vertices, "{name}");
        assert_eq!(g.triangles.len(), triangles, "{name}");
        assert_eq!(g.points.normals.is_some(), normals, "{name}");
        assert!(g.points.positions.iter().all(|p| p.is_finite()), "{name}");
    }
}

#[test]
fn bunny_ascii_and_binary_copies_agree() {
    let Some(dir) = data_dir() else {
        eprintln!("note: shared data directory not found; test skipped");
        return;
    };
    let base = dir.join("stanford_bunny/reconstruction");
    let ascii = read(base.join("bun_zipper.ply")).unwrap();
    let binary = read(base.join("bun_zipper_binary_le.ply")).unwrap();
    assert!(ascii.triangles == binary.triangles, "same faces");
    // The binary copy stores 32-bit floats; the ascii one decimal text.
    let single = |g: &crate::Geometry| {
        g.points
            .positions
            .iter()
            .map(|p| p.as_vec3())
            .collect::<Vec<_>>()
    };
    let (a, b) = (single(&ascii), single(&binary));
    let differ = a.iter().zip(&b).filter(|(p, q)| p != q).count();
    assert!(
        a.len() == b.len() && differ == 0,
        "{differ} vertices differ"
    );
    assert_eq!(
        ascii.points.scalars.as_ref().map(Vec::len),
        Some(35_947),
        "confidence kept"
    );
}
