//! k-NN and normal-estimation benchmark on 1M points sampled on a torus:
//! k-d tree build, 16-NN queries (one thread and all threads), normal
//! estimation and orientation. Run:
//! `cargo bench -p surfrecon-geom --bench spatial` (set SPATIAL_POINTS to
//! change the size). Prints figures and ratios to the reference figures of
//! issue 2 (build 0.3 s, 16-NN 5.5 us per query on 1M points).

use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;
use surfrecon_geom::normals::{estimate_normals, estimate_oriented_normals, orient_normals};
use surfrecon_geom::shapes::{sample_surface, torus};
use surfrecon_geom::spatial::KdTree;

const REFERENCE_BUILD_S: f64 = 0.3;
const REFERENCE_KNN_US: f64 = 5.5;
const K: usize = 16;

/// Seconds taken by `f`, with its result.
fn timed<T>(f: impl FnOnce() -> T) -> (f64, T) {
    let start = Instant::now();
    let out = f();
    (start.elapsed().as_secs_f64(), out)
}

/// Best of `runs` timings (less noise from other work on the machine).
fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    (0..runs)
        .map(|_| timed(|| black_box(f())).0)
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let n: usize = std::env::var("SPATIAL_POINTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let threads = rayon::current_num_threads();
    println!("spatial benchmark: {n} points on a torus, k = {K}, {threads} rayon threads");
    let mesh = torus(2.0, 0.6, 512, 256);
    let cloud = sample_surface(&mesh, n, 42);
    let points = cloud.positions;

    let build = best_of(3, || KdTree::new(&points));
    println!(
        "kd-tree build         {build:8.3} s      ({:.2}x the 0.3 s reference)",
        build / REFERENCE_BUILD_S
    );

    let tree = KdTree::new(&points);
    let queries = &points[..n.min(200_000)];
    let single = best_of(2, || {
        queries.iter().map(|&q| tree.knn(q, K).len()).sum::<usize>()
    });
    let single_us = single / queries.len() as f64 * 1e6;
    println!(
        "16-NN, 1 thread       {single_us:8.3} us/query ({:.2}x the 5.5 us reference)",
        single_us / REFERENCE_KNN_US
    );
    let parallel = best_of(2, || {
        points
            .par_iter()
            .map(|&q| tree.knn(q, K).len())
            .sum::<usize>()
    });
    let parallel_us = parallel / n as f64 * 1e6;
    println!(
        "16-NN, all threads    {parallel_us:8.3} us/point ({:.2}x speed-up over 1 thread)",
        single_us / parallel_us
    );

    let (estimate, mut normals) = timed(|| estimate_normals(&points, K));
    println!(
        "estimate_normals      {estimate:8.3} s      ({:.2} us/point)",
        estimate / n as f64 * 1e6
    );
    let (orient, ()) = timed(|| orient_normals(&points, &mut normals, K));
    println!(
        "orient_normals        {orient:8.3} s      ({:.2} us/point)",
        orient / n as f64 * 1e6
    );
    let (combined, oriented) = timed(|| estimate_oriented_normals(&points, K));
    println!(
        "estimate_oriented     {combined:8.3} s      (one shared k-NN pass; {:.2}x the two calls)",
        combined / (estimate + orient)
    );
    let truth = cloud.normals.unwrap();
    for (name, found) in [("separate", &normals), ("combined", &oriented)] {
        let outward = found
            .iter()
            .zip(&truth)
            .filter(|(a, b)| a.dot(**b) > 0.0)
            .count();
        println!(
            "outward ({name})     {:8.3} %",
            100.0 * outward as f64 / n as f64
        );
    }
}
