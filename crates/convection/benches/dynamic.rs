//! Dynamic correction benchmark: a [`DynamicSurface`] over points near a
//! sphere, then points inserted and removed one at a time, each a local
//! update; against rebuilding from scratch (triangulation and convection).
//! Run: `cargo bench -p surfrecon-convection --bench dynamic`
//! (`DYNAMIC_POINTS` sets the size, default 20,000; 1,000 edits).

use rand::{Rng, SeedableRng};
use std::time::Instant;
use surfrecon_convection::DynamicSurface;
use surfrecon_geom::DVec3;

fn sphere_points(n: usize, rng: &mut impl Rng) -> Vec<DVec3> {
    (0..n)
        .map(|_| {
            let d = DVec3::new(
                rng.random::<f64>() - 0.5,
                rng.random::<f64>() - 0.5,
                rng.random::<f64>() - 0.5,
            );
            // 1% radial jitter: no four points cospherical.
            d.normalize_or(DVec3::X) * (1.0 + 0.01 * rng.random::<f64>())
        })
        .collect()
}

fn main() {
    let n: usize = std::env::var("DYNAMIC_POINTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_000);
    const EDITS: usize = 1000;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let points = sphere_points(n, &mut rng);
    let extra = sphere_points(EDITS, &mut rng);
    println!(
        "dynamic benchmark: {n} points near a sphere, {EDITS} insertions then {EDITS} removals"
    );

    let start = Instant::now();
    let mut surface = DynamicSurface::new(&points).expect("sphere points triangulate");
    let build_s = start.elapsed().as_secs_f64();
    let facets = surface.facets().len();

    let (mut swept, mut replaced) = (0, 0);
    let start = Instant::now();
    let mut added = Vec::with_capacity(EDITS);
    for &p in &extra {
        added.push(surface.insert(p).expect("insert"));
        swept += surface.last_update().swept;
        replaced += surface.last_update().replaced;
    }
    let insert_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    for v in added {
        surface.remove(v).expect("remove");
        swept += surface.last_update().swept;
        replaced += surface.last_update().replaced;
    }
    let remove_s = start.elapsed().as_secs_f64();
    assert_eq!(surface.facets().len(), facets, "back to the start");
    let tets = surface.triangulation().num_tets();
    println!("  from scratch: {build_s:.3} s ({tets} tetrahedra, {facets} surface facets)");
    println!(
        "  insert: {:.1} µs per point, remove: {:.1} µs per point ({:.0}× and {:.0}× faster than from scratch)",
        insert_s / EDITS as f64 * 1e6,
        remove_s / EDITS as f64 * 1e6,
        build_s / (insert_s / EDITS as f64),
        build_s / (remove_s / EDITS as f64),
    );
    println!(
        "  per edit: {:.1} tetrahedra replaced, {:.1} re-swept",
        replaced as f64 / (2 * EDITS) as f64,
        swept as f64 / (2 * EDITS) as f64
    );
}
