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
use surfrecon_geom::spatial::{CellGrid, KdTree};

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

    radius_queries(&points, &tree, build);

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

/// Fixed-radius queries (radius chosen for about 16 neighbours): k-d tree
/// against the uniform cell grid (cell size = radius), one thread.
fn radius_queries(points: &[surfrecon_geom::DVec3], tree: &KdTree, tree_build: f64) {
    let area = 4.0 * std::f64::consts::PI.powi(2) * 2.0 * 0.6;
    let radius = (16.0 * area / (std::f64::consts::PI * points.len() as f64)).sqrt();
    let grid_build = best_of(3, || CellGrid::new(points, radius));
    println!(
        "cell grid build       {grid_build:8.3} s      ({:.2}x faster than the kd-tree build)",
        tree_build / grid_build
    );
    let grid = CellGrid::new(points, radius);
    let queries = &points[..points.len().min(200_000)];
    let count =
        |f: &dyn Fn(surfrecon_geom::DVec3) -> usize| queries.iter().map(|&q| f(q)).sum::<usize>();
    let found = count(&|q| tree.within(q, radius).len());
    let tree_time = best_of(2, || count(&|q| tree.within(q, radius).len()));
    let grid_time = best_of(2, || {
        count(&|q| {
            let mut n = 0;
            grid.for_each_within(q, radius, |_| n += 1);
            n
        })
    });
    let per = |t: f64| t / queries.len() as f64 * 1e6;
    println!(
        "radius {radius:.4}: kd-tree {:.3} us/query, cell grid {:.3} us/query ({:.2}x), {:.1} neighbours on average",
        per(tree_time),
        per(grid_time),
        tree_time / grid_time,
        found as f64 / queries.len() as f64
    );
}
