//! `surfrecon normals IN -o OUT`: estimate point normals by local plane fits
//! and orient them consistently outward.

use crate::context::Context;
use anyhow::{bail, Context as _};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;
use surfrecon_geom::{io, normals};

#[derive(clap::Args)]
pub struct Args {
    /// Input points (any geometry file; a mesh's vertices are used).
    pub input: PathBuf,
    /// Output file; PLY, OBJ and XYZ store the normals.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Neighbours per point for the plane fit and the orientation graph
    /// (at least 3).
    #[arg(short, default_value_t = 16)]
    pub k: usize,
    /// Keep the arbitrary signs of the plane fit (no orientation).
    #[arg(long)]
    pub no_orient: bool,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    if args.k < 3 {
        bail!(
            "-k must be at least 3 (a plane needs 3 points), got {}",
            args.k
        );
    }
    let mut geometry = io::read(&args.input)?;
    let points = &geometry.points.positions;
    if points.is_empty() {
        bail!(
            "{}: no points to estimate normals for",
            args.input.display()
        );
    }
    ctx.detail(format!(
        "read {} points from {}",
        points.len(),
        args.input.display()
    ));

    let spinner = ctx.spinner("estimating normals");
    let start = Instant::now();
    let found = if args.no_orient {
        normals::estimate_normals(points, args.k)
    } else {
        normals::estimate_oriented_normals(points, args.k)
    };
    let normals_seconds = start.elapsed().as_secs_f64();
    spinner.finish_and_clear();

    let count = points.len();
    geometry.points.normals = Some(found);
    io::write(&args.output, &geometry)
        .with_context(|| format!("cannot write {}", args.output.display()))?;

    ctx.say(format!(
        "{} normals for {count} points (k = {}) written to {}",
        if args.no_orient {
            "unoriented"
        } else {
            "oriented"
        },
        args.k,
        args.output.display()
    ));
    ctx.emit_json(&json!({
        "input": args.input,
        "output": args.output,
        "points": count,
        "k": args.k,
        "oriented": !args.no_orient,
        "normals_seconds": normals_seconds,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}
