//! Fandisk at the paper's resolution: regular field vs unified field,
//! error in grid units both ways (exact point-to-triangle distances),
//! construction and extraction time, stored counts.
//!
//! cargo bench -p surfrecon-distfield --bench fandisk [-- PATH.off [CELLS]]

use std::time::Instant;
use surfrecon_distfield::grid_for;
use surfrecon_distfield::offset::{build_odf, OdfOptions};
use surfrecon_distfield::query::{deviation, lattice_points, MeshQuery};
use surfrecon_distfield::unified::{build_udf, UdfOptions};
use surfrecon_geom::{io, TriMesh};
use surfrecon_grid::{marching::marching_cubes, sdf::signed_distance, GridSize};

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let path = args
        .first()
        .cloned()
        .unwrap_or_else(|| "../../../shared/data/fandisk/fandisk.off".into());
    let cells: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(64);
    let mesh = io::read(std::path::Path::new(&path))
        .expect("read the mesh")
        .to_mesh();
    let exact = MeshQuery::new(&mesh).expect("index the mesh");
    let size = GridSize::Resolution(cells);
    println!(
        "{path}: {} triangles, {cells} cells on the long axis",
        mesh.triangles.len()
    );
    println!("| field | construct s | extract s | max error h | mean error h | stored |");
    println!("|---|---|---|---|---|---|");

    let t = Instant::now();
    let spec = grid_for(&mesh, size, 2).unwrap();
    let field = signed_distance(&mesh, &spec, None).unwrap();
    let construct = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let regular = marching_cubes(&field, 0.0);
    row(
        "regular",
        construct,
        t.elapsed().as_secs_f64(),
        &regular,
        &mesh,
        &exact,
        spec.spacing,
        String::new(),
    );

    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    // ONLY=udf skips the slow offset field while iterating.
    let only_udf = std::env::var("ONLY").is_ok_and(|k| k == "udf");
    let mut odf_options = OdfOptions {
        size,
        ..Default::default()
    };
    odf_options.weights.spring = env("ODF_SPRING", odf_options.weights.spring);
    odf_options.weights.ortho = env("ODF_ORTHO", odf_options.weights.ortho);
    odf_options.iterations = env("ODF_ITERATIONS", odf_options.iterations as f64) as usize;
    let thresholds: Vec<f64> = match std::env::var("THRESHOLDS") {
        Ok(list) => list.split(',').filter_map(|t| t.parse().ok()).collect(),
        Err(_) if only_udf => vec![0.1],
        Err(_) => vec![0.1, 0.2, 0.3],
    };
    if !only_udf {
        let (odf, report) = build_odf(&mesh, &odf_options).unwrap();
        let t = Instant::now();
        let (out, _) = odf.extract();
        let stored = format!(
        "{} samples moved ({} aligned with features, {} smoothed, {} repair moves at {} places) of {} candidates; feature energy {:.1} -> {:.1}",
        report.moved,
        report.aligned,
        report.smoothed,
        report.repaired,
        report.repair_places,
        report.candidates,
        report.energy_before,
        report.energy_after
    );
        row(
            "ODF",
            report.seconds,
            t.elapsed().as_secs_f64(),
            &out,
            &mesh,
            &exact,
            odf.spec.spacing,
            stored,
        );
    }

    for &threshold in &thresholds {
        let options = UdfOptions {
            size,
            threshold,
            feature_angle_deg: env("FEATURE_ANGLE", 30.0),
            ..Default::default()
        };
        let (udf, report) = build_udf(&mesh, &options).unwrap();
        let t = Instant::now();
        let (out, extract) = udf.extract();
        let stored = format!(
            "{} directed, {} feature points ({} beside an edge; {} fanned, {} merged into a neighbour's fan, {} flips), {} moved samples, {} cells re-picked, {} repaired; {} boundary / {} feature cells",
            report.directed, report.feature_points, report.sharp_cells, extract.fans, extract.merged, extract.flips, report.positions, report.repicked, report.repaired, report.boundary_cells, report.feature_cells
        );
        let name = format!("UDF {threshold}");
        row(
            &name,
            report.seconds,
            t.elapsed().as_secs_f64(),
            &out,
            &mesh,
            &exact,
            udf.spec.spacing,
            stored,
        );
    }
    println!("| paper (65³, 2.5 GHz Pentium 4): regular / ODF / UDF 0.1 | 11.8 / 57.8 / 12.5 | 1.32 / 1.44 / 1.53 | 0.97 / 0.14 / 0.12 | 0.006 / 0.0022 / 0.0018 | UDF: 8,933 directed, 1,354 feature cells, 15,406 boundary cells |");
}

#[allow(clippy::too_many_arguments)]
fn row(
    name: &str,
    construct: f64,
    extract: f64,
    out: &TriMesh,
    mesh: &TriMesh,
    exact: &MeshQuery,
    h: f64,
    stored: String,
) {
    if let Some(dir) = std::env::var_os("DUMP") {
        let path = std::path::Path::new(&dir).join(format!(
            "fandisk_{}.ply",
            name.to_lowercase().replace(' ', "_")
        ));
        io::write(&path, &surfrecon_geom::Geometry::from_mesh(out.clone()))
            .expect("write the mesh");
    }
    let back = MeshQuery::new(out).expect("index the output");
    // PER_TRIANGLE=N measures about N points per triangle (default 16).
    let per_triangle = std::env::var("PER_TRIANGLE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(16);
    let there = deviation(out, exact, per_triangle);
    let back_dev = deviation(mesh, &back, per_triangle);
    let max = there.max.max(back_dev.max) / h;
    let mean = 0.5 * (there.mean + back_dev.mean) / h;
    println!("| {name} | {construct:.3} | {extract:.3} | {max:.3} | {mean:.4} | {stored} |");
    if let Some(worst) = std::env::var_os("WORST") {
        println!(
            "  worst output->mesh {:.3} h at {:?}; mesh->output {:.3} h at {:?}",
            there.max / h,
            there.worst,
            back_dev.max / h,
            back_dev.worst
        );
        let places: usize = worst.to_str().and_then(|s| s.parse().ok()).unwrap_or(1);
        if places > 1 {
            let mut all = worst_places(out, exact, h);
            all.extend(worst_places(mesh, &back, h));
            all.sort_by(|a, b| b.0.total_cmp(&a.0));
            let mut kept: Vec<(f64, surfrecon_geom::DVec3)> = Vec::new();
            for (d, p) in all {
                if kept.len() >= places {
                    break;
                }
                if kept.iter().all(|k| k.1.distance(p) > 1.5 * h) {
                    kept.push((d, p));
                }
            }
            for (d, p) in kept {
                println!("    {d:.3} h at ({:.3}, {:.3}, {:.3})", p.x, p.y, p.z);
            }
        }
    }
}

/// Distances (in h) above 0.1 h from the vertices and 16 points per
/// triangle of `from` to `to`, with where they are.
fn worst_places(from: &TriMesh, to: &MeshQuery, h: f64) -> Vec<(f64, surfrecon_geom::DVec3)> {
    let mut out = Vec::new();
    for t in 0..from.triangles.len() {
        for p in lattice_points(from.corners(t), 4) {
            let d = to.signed_distance(p).abs() / h;
            if d > 0.1 {
                out.push((d, p));
            }
        }
    }
    for &p in &from.vertices {
        let d = to.signed_distance(p).abs() / h;
        if d > 0.1 {
            out.push((d, p));
        }
    }
    out
}
