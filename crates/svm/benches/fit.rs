//! Fit benchmark at the paper's scales: a 178k-point scan (the paper's head:
//! 34.9 s, 30,162 centres on a Pentium 4 2.2 GHz) and a 400k-point
//! dragon-sized one (405k points: 319 s, 284,003 centres). Points are drawn
//! densely from the Stanford bunny mesh (with its face normals).
//!
//! Run: cargo bench -p surfrecon-svm --bench fit [-- MESH.ply]

use std::time::Instant;
use surfrecon_geom::shapes::sample_surface;
use surfrecon_geom::{io, TriMesh};
use surfrecon_svm::mesh::{mesh_model, MeshOptions};
use surfrecon_svm::{fit, FitOptions};

/// The shared data folder sits beside the repository.
const DEFAULT_MESH: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/data/stanford_bunny/reconstruction/bun_zipper.ply"
);

/// CPU seconds (user + system) of this process so far, from /proc.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    // Fields 14 and 15 of stat (utime, stime) are 11 and 12 after the ')'.
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .unwrap_or_default()
        .split_whitespace()
        .next()
        .unwrap_or("?")
        .to_string()
}

fn main() {
    let path = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .unwrap_or_else(|| DEFAULT_MESH.to_string());
    let mesh: TriMesh = match io::read(&path) {
        Ok(g) => g.to_mesh(),
        Err(e) => {
            eprintln!("cannot read {path}: {e}");
            return;
        }
    };
    println!(
        "mesh {path}: {} triangles; {} threads",
        mesh.triangles.len(),
        rayon::current_num_threads()
    );
    let cases = [
        ("head-sized", 178_000usize, 34.9, 30_162usize, 3.0),
        ("dragon-sized", 400_000, 319.0, 284_003, 15.0),
    ];
    for (name, n, paper_s, paper_centres, target_s) in cases {
        let pc = sample_surface(&mesh, n, 11);
        let normals = pc.normals.as_ref().expect("sampled normals");
        let load = load_average();
        let (t, cpu) = (Instant::now(), cpu_seconds());
        let (model, report) = fit(&pc.positions, normals, &FitOptions::default()).expect("fit");
        let secs = t.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - cpu;
        println!(
            "  (load average before: {load}; CPU time {cpu:.2} s over {} threads)",
            rayon::current_num_threads()
        );
        println!(
            "{name}: {n} points, fit {secs:.2} s (target < {target_s} s; paper {paper_s} s, ratio {:.1}x), \
             {} centres (paper {paper_centres}), {} levels",
            paper_s / secs,
            model.centre_count(),
            model.levels.len()
        );
        for (i, l) in report.levels.iter().enumerate() {
            println!(
                "  level {i}: width {:.5} candidates {} base {} centres {} sweeps {} {:.2} s",
                l.width, l.candidates, l.base_points, l.centres, l.sweeps, l.seconds
            );
        }
        let (t, cpu) = (Instant::now(), cpu_seconds());
        let opts = MeshOptions {
            resolution: 256,
            ..Default::default()
        };
        let (m, r) = mesh_model(&model, &pc.positions, pc.bounds(), &opts).expect("mesh");
        println!(
            "  mesh at 256: {:.2} s (CPU {:.2} s), {} nodes evaluated, {} triangles",
            t.elapsed().as_secs_f64(),
            cpu_seconds() - cpu,
            r.nodes_evaluated,
            m.triangles.len()
        );
    }
}
