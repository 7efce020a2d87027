//! `surfrecon eval MESH --reference REF --data DATA`: score a reconstruction
//! against a reference surface (distances, F-scores, normal consistency,
//! topology) and/or against the data it was built from (how closely every
//! datum is reached).

use crate::context::Context;
use anyhow::{bail, Context as _};
use std::path::{Path, PathBuf};
use surfrecon_geom::data_fit::{self, DataFit};
use surfrecon_geom::metrics::{self, EvalOptions, EvalReport, Surface};
use surfrecon_geom::{intersections, io};

#[derive(clap::Args)]
pub struct Args {
    /// The reconstruction to score: a mesh (or a point set).
    pub input: PathBuf,
    /// The reference surface: a mesh (or a point set).
    #[arg(short, long, required_unless_present_any = ["data", "self_intersections"])]
    pub reference: Option<PathBuf>,
    /// The data the reconstruction was built from (any geometry file: its
    /// points, curve and patch vertices): reports the distance from every
    /// datum to the mesh.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Points sampled uniformly from each mesh (point sets are used whole).
    #[arg(long, default_value_t = 100_000)]
    pub samples: usize,
    /// Seed of the sampling (same seed, same scores).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also count the pairs of the mesh's faces that cross or touch away
    /// from the corners and edge they share (exact test).
    #[arg(long)]
    pub self_intersections: bool,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    if args.samples == 0 {
        bail!("--samples must be at least 1");
    }
    let candidate = read_surface(&args.input)?;
    let spinner = ctx.spinner("measuring distances");
    let report = match &args.reference {
        Some(reference) => Some(score_against(&args, &candidate, reference)?),
        None => None,
    };
    let fit = match &args.data {
        Some(data) => Some(fit_to_data(&args.input, &candidate, data)?),
        None => None,
    };
    let crossing = match args.self_intersections {
        true => Some(count_self_intersections(&args.input, &candidate)?),
        false => None,
    };
    spinner.finish_and_clear();
    if ctx.json {
        let mut value = match &report {
            Some(r) => serde_json::to_value(r)?,
            None => serde_json::json!({}),
        };
        if let Some(fit) = &fit {
            value["data_fit"] = serde_json::to_value(fit)?;
        }
        if let Some(n) = crossing {
            value["self_intersecting_pairs"] = n.into();
        }
        ctx.emit_json(&value);
    } else if !ctx.quiet {
        if let (Some(r), Some(reference)) = (&report, &args.reference) {
            print!("{}", table(&args.input, reference, r));
        }
        if let Some(fit) = &fit {
            print!("{}", data_fit_table(fit));
        }
        if let Some(n) = crossing {
            print!(
                "{}",
                aligned(&[("self-intersecting face pairs".into(), n.to_string())])
            );
        }
    }
    ctx.detail(format!("done in {:.2} s", ctx.elapsed()));
    Ok(())
}

fn score_against(args: &Args, candidate: &Surface, reference: &Path) -> anyhow::Result<EvalReport> {
    let options = EvalOptions {
        samples: args.samples,
        seed: args.seed,
    };
    metrics::evaluate(candidate, &read_surface(reference)?, &options).with_context(|| {
        format!(
            "cannot compare {} with {}",
            args.input.display(),
            reference.display()
        )
    })
}

fn fit_to_data(input: &Path, candidate: &Surface, data: &Path) -> anyhow::Result<DataFit> {
    let Surface::Mesh(mesh) = candidate else {
        bail!(
            "--data needs a mesh to measure against; {} holds no triangles",
            input.display()
        );
    };
    let geometry = io::read(data)?;
    data_fit::data_fit(mesh, &geometry.points.positions).with_context(|| {
        format!(
            "cannot measure {} against {}",
            data.display(),
            input.display()
        )
    })
}

fn count_self_intersections(input: &Path, candidate: &Surface) -> anyhow::Result<usize> {
    let Surface::Mesh(mesh) = candidate else {
        bail!(
            "--self-intersections needs a mesh; {} holds no triangles",
            input.display()
        );
    };
    Ok(intersections::self_intersections(mesh).len())
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
fn table(input: &Path, reference: &Path, r: &EvalReport) -> String {
    let mut rows: Vec<(String, String)> = vec![
        ("candidate".into(), input.display().to_string()),
        ("reference".into(), reference.display().to_string()),
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
    aligned(&rows)
}

/// The data-fit block: distances in % of the data's diagonal.
fn data_fit_table(f: &DataFit) -> String {
    let pct = |x: f64| format!("{:.2}%", 100.0 * x);
    let rows: Vec<(String, String)> = vec![
        ("data points".into(), f.points.to_string()),
        ("data diagonal".into(), format!("{:.6e}", f.diagonal)),
        (
            "data: mean distance".into(),
            format!("{:.4}% of the diagonal", 100.0 * f.mean),
        ),
        (
            "data: max distance".into(),
            format!("{:.4}% of the diagonal at {:?}", 100.0 * f.max, f.farthest),
        ),
        ("data within 0.25%".into(), pct(f.within_0_25pct)),
        ("data within 0.5%".into(), pct(f.within_0_5pct)),
        ("data within 1%".into(), pct(f.within_1pct)),
    ];
    aligned(&rows)
}

fn aligned(rows: &[(String, String)]) -> String {
    let width = rows.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
    rows.iter()
        .map(|(k, v)| format!("{k:<width$}  {v}\n"))
        .collect()
}
