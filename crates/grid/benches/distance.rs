//! Distance-field benchmarks: unsigned distance from ~440k points on the
//! paper's Dragon grid (300x212x136), and mesh -> signed distance of a
//! ~100k-triangle mesh at 256^3 (dense and narrow band).
//! Run: cargo bench -p surfrecon-grid --bench distance

use std::time::Instant;
use surfrecon_geom::{shapes, DVec3};
use surfrecon_grid::distance::{unsigned_distance, DataSet};
use surfrecon_grid::GridSpec;

fn main() {
    println!("threads: {}", rayon::current_num_threads());
    unsigned_from_points();
}

/// Best of `runs` wall-clock times (seconds) of `f`, and its last result.
fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("at least one run"))
}

fn unsigned_from_points() {
    // A torus squashed to the Dragon's box proportions (300:212:136).
    let torus = shapes::torus(2.0, 0.5, 512, 128);
    let cloud = shapes::sample_surface(&torus, 437_645, 11);
    let scale = DVec3::new(1.0, 0.7067, 2.267);
    let points: Vec<[f64; 3]> = cloud
        .positions
        .iter()
        .map(|p| (*p * scale).to_array())
        .collect();
    let data = DataSet::<3> {
        points,
        ..Default::default()
    };
    let (lo, hi) = data.bounds().expect("points");
    let dims = [300, 212, 136];
    let spacing = (0..3)
        .map(|a| (hi[a] - lo[a]) / (dims[a] - 5) as f64)
        .fold(0.0, f64::max);
    let origin = std::array::from_fn(|a| lo[a] - 2.0 * spacing);
    let spec = GridSpec::<3> {
        origin,
        spacing,
        dims,
    };
    let (secs, df) = best_of(3, || unsigned_distance(&data, &spec).expect("distance"));
    let nodes = spec.node_count() as f64;
    let paper_secs = 4.0 * 60.0;
    println!(
        "unsigned distance, {} points, grid {}: {:.3} s ({:.1} M nodes/s); \
         target < 1 s: {}; paper's whole initial stage ~{} s on a 600 MHz PIII: {:.0}x",
        data.len(),
        spec.dims_string(),
        secs,
        nodes / secs / 1e6,
        if secs < 1.0 { "met" } else { "MISSED" },
        paper_secs,
        paper_secs / secs
    );
    let reached = df.closest.iter().filter(|&&c| c != u32::MAX).count();
    assert_eq!(reached, spec.node_count());
}
