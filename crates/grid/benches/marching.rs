//! Marching cubes, sparse extraction and thin-shell benchmark (plain
//! binary, run with `cargo bench -p surfrecon-grid --bench marching`).
//!
//! 1. Dense marching cubes of a 512³ smooth union of spheres: time,
//!    triangles/s. The field is also written to `$TMPDIR` as raw f64 so
//!    `benches/skimage_mc.py` can time scikit-image on the very same data;
//!    set `SKIMAGE_PYTHON=/path/to/python` (with numpy + scikit-image) to
//!    have the bench run it and print the ratio.
//! 2. Sparse: the same field kept as a 3h narrow band in a BlockGrid
//!    (memory, extraction time), and a 1024³ narrow band (memory).
//! 3. Thin shell of a 256³ field: size ratio, rebuild time, rebuild error.
//!
//! Sizes can be reduced with `MARCHING_BENCH_N` (default 512).

use rayon::prelude::*;
use std::time::Instant;
use surfrecon_geom::DVec3;
use surfrecon_grid::marching::marching_cubes;
use surfrecon_grid::shell::Shell;
use surfrecon_grid::sparse::{marching_cubes_sparse, Block, BlockGrid, BLOCK};
use surfrecon_grid::{Field3, GridSpec};

/// Centres and radii of the spheres in the unit cube.
const SPHERES: [([f64; 3], f64); 6] = [
    ([0.35, 0.40, 0.45], 0.22),
    ([0.62, 0.45, 0.50], 0.20),
    ([0.50, 0.68, 0.40], 0.16),
    ([0.45, 0.35, 0.70], 0.14),
    ([0.70, 0.70, 0.68], 0.12),
    ([0.25, 0.70, 0.30], 0.10),
];

/// Smooth union (polynomial smooth minimum) of sphere distances.
fn blobs(p: DVec3) -> f64 {
    let k = 0.05;
    SPHERES.iter().fold(f64::INFINITY, |acc, &(c, r)| {
        let d = (p - DVec3::from_array(c)).length() - r;
        if acc.is_infinite() {
            return d;
        }
        let h = (0.5 + 0.5 * (d - acc) / k).clamp(0.0, 1.0);
        d * (1.0 - h) + acc * h - k * h * (1.0 - h)
    })
}

/// An exact signed distance: a sphere and a torus apart from each other
/// (their plain minimum is exact inside and outside).
fn sphere_and_torus(p: DVec3) -> f64 {
    let sphere = (p - DVec3::new(0.28, 0.5, 0.5)).length() - 0.17;
    let q = p - DVec3::new(0.72, 0.5, 0.5);
    let ring = (q.x * q.x + q.y * q.y).sqrt() - 0.14;
    let torus = (ring * ring + q.z * q.z).sqrt() - 0.06;
    sphere.min(torus)
}

fn unit_spec(n: usize) -> GridSpec<3> {
    GridSpec {
        origin: [0.0; 3],
        spacing: 1.0 / (n - 1) as f64,
        dims: [n; 3],
    }
}

fn sample(spec: GridSpec<3>, f: impl Fn(DVec3) -> f64 + Sync) -> Field3 {
    let values = (0..spec.node_count())
        .into_par_iter()
        .map(|l| f(DVec3::from_array(spec.position(spec.unlinear(l)))))
        .collect();
    Field3 { spec, values }
}

/// Best of `runs` timings of `f`, with its last result.
fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("runs > 0"))
}

fn main() {
    let n: usize = std::env::var("MARCHING_BENCH_N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(512);
    println!("threads: {}", rayon::current_num_threads());
    let field = sample(unit_spec(n), blobs);
    let dense_secs = dense(&field, n);
    sparse(&field, dense_secs);
    narrow_band_1024();
    drop(field);
    thin_shell(n.min(256));
}

fn dense(field: &Field3, n: usize) -> f64 {
    marching_cubes(&sample(unit_spec(8), blobs), 0.0); // builds the case table
    let (secs, mesh) = best_of(3, || marching_cubes(field, 0.0));
    let cells = ((n - 1) as f64).powi(3);
    println!(
        "dense marching cubes {n}^3: {:.3} s, {} triangles, {} vertices, {:.1} M triangles/s, {:.0} M cells/s",
        secs,
        mesh.triangles.len(),
        mesh.vertices.len(),
        mesh.triangles.len() as f64 / secs / 1e6,
        cells / secs / 1e6
    );
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let (secs1, _) = one.install(|| best_of(1, || marching_cubes(field, 0.0)));
    println!(
        "  1 thread: {secs1:.3} s (parallel speed-up {:.2}x)",
        secs1 / secs
    );
    compare_skimage(field, n, secs, mesh.triangles.len());
    secs
}

/// Write the field for `skimage_mc.py`; run it when SKIMAGE_PYTHON is set.
fn compare_skimage(field: &Field3, n: usize, ours: f64, triangles: usize) {
    let path = std::env::temp_dir().join(format!("surfrecon_mc_{n}.f64"));
    let bytes: Vec<u8> = field.values.iter().flat_map(|v| v.to_le_bytes()).collect();
    if let Err(e) = std::fs::write(&path, bytes) {
        println!("  cannot write {}: {e}", path.display());
        return;
    }
    let Ok(python) = std::env::var("SKIMAGE_PYTHON") else {
        println!(
            "  field written to {}; set SKIMAGE_PYTHON to compare with scikit-image",
            path.display()
        );
        return;
    };
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/skimage_mc.py");
    let out = std::process::Command::new(python)
        .args([script, path.to_str().unwrap_or_default(), &n.to_string()])
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout);
            print!("  scikit-image: {text}");
            let secs = text
                .split_whitespace()
                .find_map(|w| w.strip_prefix("seconds="))
                .and_then(|s| s.parse::<f64>().ok());
            if let Some(s) = secs {
                println!(
                    "  ratio scikit-image / surfrecon: {:.2}x (ours {triangles} triangles)",
                    s / ours
                );
            }
        }
        Ok(o) => println!(
            "  scikit-image failed: {}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => println!("  cannot run python: {e}"),
    }
    let _ = std::fs::remove_file(&path);
}

fn sparse(field: &Field3, dense_secs: f64) {
    let band = 3.0 * field.spec.spacing;
    let t = Instant::now();
    let grid = BlockGrid::from_dense_band(field, band).expect("valid grid");
    let build = t.elapsed().as_secs_f64();
    let (secs, mesh) = best_of(3, || marching_cubes_sparse(&grid, 0.0));
    let dense_mb = field.values.len() as f64 * 8.0 / 1e6;
    println!(
        "sparse 3h band: {} blocks, {:.1} MB vs {:.0} MB dense ({:.1}%), built in {:.2} s; extraction {:.3} s ({:.1}x faster than dense), {} triangles",
        grid.blocks().len(),
        grid.memory_bytes() as f64 / 1e6,
        dense_mb,
        100.0 * grid.memory_bytes() as f64 / 1e6 / dense_mb,
        build,
        secs,
        dense_secs / secs,
        mesh.triangles.len()
    );
}

/// A sphere of radius 400 h in a 1024³ grid, band of 3 h, blocks filled
/// directly from the analytic distance.
fn narrow_band_1024() {
    let n = 1024;
    let spec = unit_spec(n);
    let h = spec.spacing;
    let (c, r, band) = (DVec3::splat(0.5), 400.0 * h, 3.0 * h);
    let t = Instant::now();
    let mut grid = BlockGrid::new(spec, band).expect("valid grid");
    let bd = grid.block_dims();
    let reach = band + (BLOCK as f64) * h; // block half-diagonal < 8h
    for bz in 0..bd[2] {
        for by in 0..bd[1] {
            for bx in 0..bd[0] {
                let centre = DVec3::new(bx as f64 + 0.5, by as f64 + 0.5, bz as f64 + 0.5)
                    * (BLOCK as f64 * h);
                if ((centre - c).length() - r).abs() < reach {
                    grid.allocate([bx * BLOCK, by * BLOCK, bz * BLOCK]);
                }
            }
        }
    }
    grid.blocks_mut()
        .par_iter_mut()
        .for_each(|b: &mut Block<3>| {
            for l in 0..Block::<3>::LEN {
                let p = DVec3::from_array(spec.position(b.node(l)));
                b.values[l] = ((p - c).length() - r).clamp(-band, band);
            }
        });
    grid.fill_tile_signs();
    let build = t.elapsed().as_secs_f64();
    let (secs, mesh) = best_of(1, || marching_cubes_sparse(&grid, 0.0));
    println!(
        "sparse 1024^3 sphere (r = 400 h, 3h band): {} blocks, {:.0} MB (dense f64 would be {:.0} MB), built in {:.2} s; extraction {:.2} s, {} triangles",
        grid.blocks().len(),
        grid.memory_bytes() as f64 / 1e6,
        (n as f64).powi(3) * 8.0 / 1e6,
        build,
        secs,
        mesh.triangles.len()
    );
}

fn thin_shell(n: usize) {
    let field = sample(unit_spec(n), sphere_and_torus);
    let h = field.spec.spacing;
    let t = Instant::now();
    let shell = Shell::from_field(&field);
    let build = t.elapsed().as_secs_f64();
    let (rebuild, back) = best_of(1, || shell.rebuild().expect("valid shell"));
    let nrrd_bytes = 8 * field.values.len() + 250;
    let max_err = |within: f64| {
        field
            .values
            .iter()
            .zip(&back.values)
            .filter(|(a, _)| a.abs() <= within * h)
            .map(|(a, b)| (a - b).abs() / h)
            .fold(0.0, f64::max)
    };
    let signs_ok = field
        .values
        .iter()
        .zip(&back.values)
        .all(|(a, b)| (*a < 0.0) == (*b < 0.0));
    println!(
        "thin shell {n}^3: {} shell nodes, {:.2} MB vs {:.1} MB NRRD ({:.0}x smaller), built in {:.3} s, rebuilt in {:.2} s; signs identical: {signs_ok}; max error (h) within 1h / 3h / all: {:.3} / {:.3} / {:.3}",
        shell.indices.len(),
        shell.encoded_len() as f64 / 1e6,
        nrrd_bytes as f64 / 1e6,
        nrrd_bytes as f64 / shell.encoded_len() as f64,
        build,
        rebuild,
        max_err(1.0),
        max_err(3.0),
        max_err(f64::INFINITY)
    );
}
