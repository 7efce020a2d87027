//! Delaunay tetrahedralization benchmark: `bulk_load` of uniform random
//! points in the unit cube on one core (the construction is sequential).
//! Run: `cargo bench -p surfrecon-delaunay --bench delaunay`
//! (`DELAUNAY_POINTS` sets the size, default 1,000,000). Prints seconds,
//! points and tetrahedra per second, and the ratio to the 2 s goal and to
//! TetGen's 10.2 s measured here (issue 17). On a shared machine the
//! thread's CPU time per run (from `/proc/thread-self/stat`, Linux only) is
//! printed too: it moves less with the other processes' load than wall time.

use rand::{Rng, SeedableRng};
use std::time::Instant;
use surfrecon_delaunay::{brio_order, DVec3, Triangulation};

const GOAL_S: f64 = 2.0;
const TETGEN_S: f64 = 10.2;

fn main() {
    let n: usize = std::env::var("DELAUNAY_POINTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(42);
    let points: Vec<DVec3> = (0..n)
        .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()))
        .collect();
    println!("delaunay benchmark: {n} uniform random points in the unit cube, one thread");

    let start = Instant::now();
    let order = brio_order(&points);
    let order_s = start.elapsed().as_secs_f64();
    std::hint::black_box(order);

    let mut best = f64::INFINITY;
    let mut tets = 0;
    let mut cpu = Vec::new();
    for _ in 0..3 {
        let cpu_start = thread_cpu_seconds();
        let start = Instant::now();
        let tri = Triangulation::bulk_load(&points).expect("random points triangulate");
        best = best.min(start.elapsed().as_secs_f64());
        tets = tri.num_tets();
        if let (Some(a), Some(b)) = (cpu_start, thread_cpu_seconds()) {
            cpu.push(format!("{:.2}", b - a));
        }
    }
    println!("  BRIO + Hilbert order alone: {order_s:.3} s");
    println!(
        "  bulk_load: {best:.3} s (best of 3), {tets} tetrahedra ({:.2} per point)",
        tets as f64 / n as f64
    );
    if !cpu.is_empty() {
        println!("  CPU time per run (user + system): {} s", cpu.join(", "));
    }
    println!(
        "  {:.2} M points/s, {:.2} M tetrahedra/s",
        n as f64 / best / 1e6,
        tets as f64 / best / 1e6
    );
    if n == 1_000_000 {
        println!(
            "  vs goal {GOAL_S} s: {:.2}x; vs TetGen {TETGEN_S} s: {:.1}x faster",
            best / GOAL_S,
            TETGEN_S / best
        );
    }
}

/// This thread's user + system CPU time, in clock ticks of 10 ms (Linux).
fn thread_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are
    // fields 14 and 15 of the whole line.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}
