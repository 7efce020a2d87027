//! `surfrecon unshell`: rebuild the full signed distance field from a thin
//! shell (fast sweeping for the distances, tagging for the signs).

use crate::context::Context;
use anyhow::Context as _;
use std::path::PathBuf;
use std::time::Instant;
use surfrecon_grid::field_io::write_field;
use surfrecon_grid::shell::{read_shell, AnyShell};

#[derive(clap::Args)]
pub struct Args {
    /// Shell file written by `surfrecon shell`.
    pub input: PathBuf,
    /// Output field (.nrrd or .vtk).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    surfrecon_grid::field_io::FieldFormat::from_path(&args.output)?;
    let shell = read_shell(&args.input)?;
    let spinner = ctx.spinner("rebuilding the distance field");
    let start = Instant::now();
    let rebuilt = match &shell {
        AnyShell::D2(s) => s.rebuild().map(|f| (f.spec.dims.to_vec(), Field::D2(f))),
        AnyShell::D3(s) => s.rebuild().map(|f| (f.spec.dims.to_vec(), Field::D3(f))),
    };
    let (dims, field) =
        rebuilt.with_context(|| format!("cannot rebuild {}", args.input.display()))?;
    let rebuild_seconds = start.elapsed().as_secs_f64();
    spinner.finish_and_clear();
    match &field {
        Field::D2(f) => write_field(&args.output, f),
        Field::D3(f) => write_field(&args.output, f),
    }
    .with_context(|| format!("cannot write {}", args.output.display()))?;
    ctx.say(format!(
        "rebuilt a {} field in {rebuild_seconds:.2} s; wrote {}",
        dims.iter()
            .map(|n| n.to_string())
            .collect::<Vec<_>>()
            .join("x"),
        args.output.display()
    ));
    ctx.emit_json(&serde_json::json!({
        "command": "unshell",
        "input": args.input,
        "output": args.output,
        "dims": dims,
        "rebuild_seconds": rebuild_seconds,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

enum Field {
    D2(surfrecon_grid::Field2),
    D3(surfrecon_grid::Field3),
}
