//! `surfrecon tetrahedralize` end to end: the VTK file parses, its counts
//! and volume match the JSON summary and the input's convex hull.

mod common;
use common::{json_of, path_str, surfrecon};

use std::path::Path;

/// A 4×4×4 lattice (hull volume 27, massively cospherical) written as
/// XYZ, with the first 10 points repeated (duplicates to merge).
fn write_lattice(path: &Path) -> usize {
    let mut lines = Vec::new();
    for x in 0..4 {
        for y in 0..4 {
            for z in 0..4 {
                lines.push(format!("{x} {y} {z}"));
            }
        }
    }
    let copies: Vec<String> = lines[..10].to_vec();
    lines.extend(copies);
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
    lines.len()
}

/// The parts of a binary legacy VTK unstructured grid.
struct Grid {
    points: Vec<[f64; 3]>,
    cells: Vec<Vec<i32>>,
    types: Vec<i32>,
}

fn parse_vtk(bytes: &[u8]) -> Grid {
    let mut at = 0;
    let mut line = || {
        let end = at + bytes[at..].iter().position(|&b| b == b'\n').unwrap();
        let text = String::from_utf8(bytes[at..end].to_vec()).unwrap();
        at = end + 1;
        text
    };
    assert_eq!(line(), "# vtk DataFile Version 3.0");
    line();
    assert_eq!(line(), "BINARY");
    assert_eq!(line(), "DATASET UNSTRUCTURED_GRID");
    let header = line();
    let n: usize = header
        .strip_prefix("POINTS ")
        .unwrap()
        .strip_suffix(" double")
        .unwrap()
        .parse()
        .unwrap();
    let f64_at = |i: usize| f64::from_be_bytes(bytes[i..i + 8].try_into().unwrap());
    let i32_at = |i: usize| i32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
    let start = at;
    let points = (0..n)
        .map(|k| [0, 1, 2].map(|c| f64_at(start + 24 * k + 8 * c)))
        .collect();
    let mut at = start + 24 * n + 1;
    let mut line = || {
        let end = at + bytes[at..].iter().position(|&b| b == b'\n').unwrap();
        let text = String::from_utf8(bytes[at..end].to_vec()).unwrap();
        at = end + 1;
        (text, at)
    };
    let (cells_header, start) = line();
    let parts: Vec<usize> = cells_header
        .split(' ')
        .skip(1)
        .map(|s| s.parse().unwrap())
        .collect();
    let m = parts[0];
    assert_eq!(parts[1], 5 * m);
    let cells: Vec<Vec<i32>> = (0..m)
        .map(|k| (0..5).map(|c| i32_at(start + 20 * k + 4 * c)).collect())
        .collect();
    let rest = &bytes[start + 20 * m + 1..];
    let types_header = format!("CELL_TYPES {m}\n");
    assert!(rest.starts_with(types_header.as_bytes()));
    let types = (0..m)
        .map(|k| i32_at(start + 20 * m + 1 + types_header.len() + 4 * k))
        .collect();
    assert_eq!(rest.len(), types_header.len() + 4 * m + 1);
    Grid {
        points,
        cells,
        types,
    }
}

fn det_volume(grid: &Grid, cell: &[i32]) -> f64 {
    let p = |i: usize| glam::DVec3::from_array(grid.points[cell[i] as usize]);
    let (a, b, c, d) = (p(1), p(2), p(3), p(4));
    (b - a).cross(c - a).dot(d - a) / 6.0
}

#[test]
fn tetrahedralize_writes_a_valid_vtk_grid() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("lattice.xyz");
    let count = write_lattice(&input);
    let output = dir.path().join("lattice.vtk");
    let v = json_of(&surfrecon(&[
        "tetrahedralize",
        path_str(&input),
        "-o",
        path_str(&output),
        "--json",
    ]));
    assert_eq!(v["points"], count);
    assert_eq!(v["vertices"], 64);
    assert_eq!(v["duplicates_merged"], 10);
    assert_eq!(v["volume"].as_f64().unwrap(), 27.0);
    assert!(v["seconds"].as_f64().unwrap() >= 0.0);

    let grid = parse_vtk(&std::fs::read(&output).unwrap());
    assert_eq!(grid.points.len(), count);
    assert_eq!(grid.cells.len(), v["tetrahedra"].as_u64().unwrap() as usize);
    assert!(grid.types.iter().all(|&t| t == 10));
    let mut total = 0.0;
    for cell in &grid.cells {
        assert_eq!(cell[0], 4);
        assert!(cell[1..].iter().all(|&i| (i as usize) < count));
        let volume = det_volume(&grid, cell);
        assert!(volume > 0.0, "{cell:?} is not positively oriented");
        total += volume;
    }
    assert!((total - 27.0).abs() < 1e-12, "{total}");
}

#[test]
fn tetrahedralize_rejects_flat_input_and_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("flat.xyz");
    std::fs::write(&input, "0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 3 0\n").unwrap();
    let output = dir.path().join("flat.vtk");
    let out = surfrecon(&["tetrahedralize", path_str(&input), "-o", path_str(&output)]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("flat.xyz") && err.contains("coplanar"),
        "{err}"
    );
    assert!(!output.exists());

    let out = surfrecon(&["tetrahedralize", path_str(&input), "-o", "grid.ply"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains(".vtk"));
}
