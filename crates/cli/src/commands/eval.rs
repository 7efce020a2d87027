//! `surfrecon eval MESH --reference REF`: score a reconstruction against a
//! reference surface (distances, F-scores, normal consistency, topology).

use crate::context::Context;
use anyhow::{bail, Context as _};
use std::path::{Path, PathBuf};
use surfrecon_geom::io;
use surfrecon_geom::metrics::{self, EvalOptions, EvalReport, Surface};

#[derive(clap::Args)]
pub struct Args {
    /// The reconstruction to score: a mesh (or a point set).
    pub input: PathBuf,
    /// The reference surface: a mesh (or a point set).
    #[arg(short, long)]
    pub reference: PathBuf,
    /// Points sampled uniformly from each mesh (point sets are used whole).
    #[arg(long, default_value_t = 100_000)]
    pub samples: usize,
    /// Seed of the sampling (same seed, same scores).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    if args.samples == 0 {
        bail!("--samples must be at least 1");
    }
    let candidate = read_surface(&args.input)?;
    let reference = read_surface(&args.reference)?;
    let spinner = ctx.spinner("measuring distances");
    let options = EvalOptions {
        samples: args.samples,
        seed: args.seed,
    };
    let report = metrics::evaluate(&candidate, &reference, &options).with_context(|| {
        format!(
            "cannot compare {} with {}",
            args.input.display(),
            args.reference.display()
        )
    })?;
    spinner.finish_and_clear();
    if ctx.json {
        ctx.emit_json(&serde_json::to_value(&report)?);
    } else if !ctx.quiet {
        print!("{}", table(&args, &report));
    }
    ctx.detail(format!("done in {:.2} s", ctx.elapsed()));
    Ok(())
}

fn read_surface(path: &Path) -> anyhow::Result<Surface> {
    let geometry = io::read(path)?;
    Ok(Surface::from(geometry))
}

fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

/// The human-readable report: one metric per line, name then value.
fn table(args: &Args, r: &EvalReport) -> String {
    let mut rows: Vec<(String, String)> = vec![
        ("candidate".into(), args.input.display().to_string()),
        ("reference".into(), args.reference.display().to_string()),
        (
            "samples".into(),
            format!(
                "{} candidate, {} reference",
                r.sample_counts.0, r.sample_counts.1
            ),
        ),
        ("reference diagonal".into(), format!("{:.6e}", r.diagonal)),
        ("chamfer L1".into(), format!("{:.6e}", r.chamfer_l1)),
        (
            "chamfer L2 (squared)".into(),
            format!("{:.6e}", r.chamfer_l2),
        ),
        ("hausdorff".into(), format!("{:.6e}", r.hausdorff)),
        (
            "F-score @0.5%".into(),
            format!(
                "{:.4} (threshold {:.3e})",
                r.fscore_0_5pct,
                0.005 * r.diagonal
            ),
        ),
        (
            "F-score @1%".into(),
            format!("{:.4} (threshold {:.3e})", r.fscore_1pct, 0.01 * r.diagonal),
        ),
        (
            "normal consistency".into(),
            r.normal_consistency
                .map_or("n/a (a point set without normals)".into(), |n| {
                    format!("{n:.4}")
                }),
        ),
        ("vertices".into(), r.vertices.to_string()),
        ("faces".into(), r.faces.to_string()),
    ];
    if let Some(t) = &r.topology {
        rows.extend([
            (
                "watertight".into(),
                format!(
                    "{} ({} boundary edges)",
                    yes_no(t.watertight),
                    t.boundary_edges
                ),
            ),
            (
                "edge-manifold".into(),
                format!(
                    "{} ({} edges in 3+ faces)",
                    yes_no(t.edge_manifold),
                    t.nonmanifold_edges
                ),
            ),
            (
                "vertex-manifold".into(),
                format!(
                    "{} ({} vertices with several fans)",
                    yes_no(t.vertex_manifold),
                    t.nonmanifold_vertices
                ),
            ),
            ("components".into(), t.components.to_string()),
            (
                "euler (V-E+F)".into(),
                format!(
                    "{} (V = {} used vertices, E = {})",
                    t.euler, t.referenced_vertices, t.edges
                ),
            ),
        ]);
    } else {
        rows.push(("topology".into(), "n/a (candidate is a point set)".into()));
    }
    let width = rows.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
    rows.iter()
        .map(|(k, v)| format!("{k:<width$}  {v}\n"))
        .collect()
}
