//! Preview rendering speed: meshes, wireframes and point clouds at the
//! default 800x600 (3x3 supersampled), and the gain from threads.
//!
//! Run: `cargo bench -p surfrecon-geom --bench render`

use std::time::Instant;
use surfrecon_geom::render::{render, RenderOptions};
use surfrecon_geom::shapes::{icosphere, sample_surface, torus};
use surfrecon_geom::{DVec3, Geometry, PointCloud};

/// Median wall time of `runs` calls, in seconds.
fn median_seconds(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[runs / 2]
}

fn time_render(geometry: &Geometry, options: &RenderOptions, threads: usize, runs: usize) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        median_seconds(runs, || {
            render(geometry, options).expect("render");
        })
    })
}

fn report(name: &str, geometry: &Geometry, options: &RenderOptions, runs: usize) -> f64 {
    let threads = rayon::current_num_threads();
    let one = time_render(geometry, options, 1, runs);
    let all = time_render(geometry, options, threads, runs);
    println!(
        "{name:<44} {:>8.1} ms  (1 thread {:>8.1} ms, {threads} threads speed-up {:.2}x)",
        all * 1e3,
        one * 1e3,
        one / all
    );
    all
}

fn main() {
    let options = RenderOptions::default();
    let wire = RenderOptions {
        wireframe: true,
        ..RenderOptions::default()
    };
    println!("render 800x600, 3x3 supersampling; median of 5 runs (3 for 1M points, 1 with normal estimation)");

    let sphere = Geometry::from_mesh(icosphere(DVec3::ZERO, 1.0, 7));
    let shaded = report("icosphere 327,680 triangles, smooth", &sphere, &options, 5);
    let wired = report("icosphere 327,680 triangles, wireframe", &sphere, &wire, 5);
    println!("  wireframe / shaded time ratio {:.2}", wired / shaded);

    let bunny_path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/stanford_bunny/reconstruction/bun_zipper.ply"
    );
    match surfrecon_geom::io::read(bunny_path) {
        Ok(bunny) => {
            report("bunny 69,451 triangles, smooth", &bunny, &options, 5);
        }
        Err(e) => println!("bunny skipped: {e}"),
    }

    let ring = torus(2.0, 0.7, 64, 32);
    let with_normals = sample_surface(&ring, 1_000_000, 1);
    let bare = Geometry::from_points(PointCloud::new(with_normals.positions.clone()));
    let with_normals = Geometry::from_points(with_normals);
    report("1M points with normals", &with_normals, &options, 3);
    let depth_only = RenderOptions {
        estimate_point_normals: false,
        ..RenderOptions::default()
    };
    report(
        "1M points, no normals, depth shading",
        &bare,
        &depth_only,
        3,
    );
    report(
        "1M points, no normals, estimated normals",
        &bare,
        &options,
        1,
    );
}
