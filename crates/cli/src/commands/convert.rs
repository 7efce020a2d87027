//! `surfrecon convert IN OUT`: read any supported geometry file and write it
//! in another format (chosen by extension unless `--from`/`--to` are given).

use crate::context::Context;
use anyhow::Context as _;
use serde_json::json;
use std::path::PathBuf;
use surfrecon_geom::io::{self, Encoding, Format, WriteOptions};
use surfrecon_geom::Geometry;

#[derive(clap::Args)]
pub struct Args {
    /// Input geometry file (.ply, .obj, .off, .stl, .xyz).
    pub input: PathBuf,
    /// Output file; its extension picks the format unless --to is given.
    pub output: PathBuf,
    /// Input format, overriding the input's extension (ply, obj, off, stl, xyz).
    #[arg(long, value_name = "FMT")]
    pub from: Option<Format>,
    /// Output format, overriding the output's extension.
    #[arg(long, value_name = "FMT")]
    pub to: Option<Format>,
    /// Write PLY or STL as text (default: binary little-endian).
    #[arg(long, conflicts_with = "big_endian")]
    pub ascii: bool,
    /// Write binary PLY big-endian.
    #[arg(long)]
    pub big_endian: bool,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    let from = match args.from {
        Some(f) => f,
        None => Format::from_path(&args.input)?,
    };
    let to = match args.to {
        Some(f) => f,
        None => Format::from_path(&args.output)?,
    };
    let spinner = ctx.spinner(&format!("reading {}", args.input.display()));
    let geometry = io::read_as(&args.input, from)?;
    spinner.finish_and_clear();
    let read_seconds = ctx.elapsed();

    let options = WriteOptions {
        encoding: encoding(&args),
    };
    let spinner = ctx.spinner(&format!("writing {}", args.output.display()));
    io::write_as(&args.output, &geometry, to, options)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    spinner.finish_and_clear();
    let dropped = dropped_parts(&geometry, to);
    for part in &dropped {
        ctx.say(format!("note: {to} files cannot store {part}; left out"));
    }

    let summary = Summary::of(&geometry);
    ctx.say(format!(
        "{} -> {}: {} points, {} triangles, {} polylines{} ({:.2} s)",
        args.input.display(),
        args.output.display(),
        summary.points,
        summary.triangles,
        summary.polylines,
        if summary.normals {
            ", with normals"
        } else {
            ""
        },
        ctx.elapsed()
    ));
    ctx.emit_json(&json!({
        "input": args.input,
        "output": args.output,
        "from": from.name(),
        "to": to.name(),
        "points": summary.points,
        "triangles": summary.triangles,
        "polylines": summary.polylines,
        "normals": summary.normals,
        "dropped": dropped,
        "read_seconds": read_seconds,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

fn encoding(args: &Args) -> Encoding {
    if args.ascii {
        Encoding::Ascii
    } else if args.big_endian {
        Encoding::BinaryBigEndian
    } else {
        Encoding::BinaryLittleEndian
    }
}

/// Parts of `g` that files of format `to` cannot hold.
fn dropped_parts(g: &Geometry, to: Format) -> Vec<&'static str> {
    let pts = &g.points;
    let referenced = || {
        let mut used = vec![false; pts.len()];
        for &i in g.triangles.iter().flatten() {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
        used.iter().all(|&u| u)
    };
    [
        (!g.lines.is_empty() && !to.stores_lines(), "polylines"),
        (
            !g.triangles.is_empty() && !to.stores_triangles(),
            "triangles",
        ),
        (pts.normals.is_some() && !to.stores_normals(), "normals"),
        (
            pts.scalars.is_some() && !to.stores_scalars(),
            "per-point scalars",
        ),
        (
            !to.stores_points() && !referenced(),
            "points outside triangles",
        ),
    ]
    .into_iter()
    .filter_map(|(lost, part)| lost.then_some(part))
    .collect()
}

struct Summary {
    points: usize,
    triangles: usize,
    polylines: usize,
    normals: bool,
}

impl Summary {
    fn of(g: &Geometry) -> Summary {
        Summary {
            points: g.points.len(),
            triangles: g.triangles.len(),
            polylines: g.lines.len(),
            normals: g.points.normals.is_some(),
        }
    }
}
