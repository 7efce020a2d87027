//! `surfrecon shell`: store a signed distance field as a compact thin shell
//! (only the nodes next to the zero level set).

use crate::context::Context;
use anyhow::Context as _;
use std::path::{Path, PathBuf};
use surfrecon_grid::field_io::{read_field, AnyField};
use surfrecon_grid::shell::{write_shell, Shell};

#[derive(clap::Args)]
pub struct Args {
    /// Signed distance field (.nrrd or .vtk, 2D or 3D; negative inside).
    pub input: PathBuf,
    /// Output shell file (e.g. `field.shell`).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    let field = read_field(&args.input)?;
    let (nodes, shell_nodes, written) = match &field {
        AnyField::D2(f) => store(&Shell::from_field(f), &args.output)?,
        AnyField::D3(f) => store(&Shell::from_field(f), &args.output)?,
    };
    let shell_bytes = file_size(&args.output)?;
    let field_bytes = file_size(&args.input)?;
    let dense_bytes = 8 * nodes as u64;
    let ratio = field_bytes as f64 / shell_bytes as f64;
    ctx.say(format!(
        "{shell_nodes} of {nodes} nodes on the shell; {} is {shell_bytes} bytes, {ratio:.1}x smaller than {} ({field_bytes} bytes)",
        args.output.display(),
        args.input.display(),
    ));
    debug_assert_eq!(written, shell_bytes as usize);
    ctx.emit_json(&serde_json::json!({
        "command": "shell",
        "input": args.input,
        "output": args.output,
        "nodes": nodes,
        "shell_nodes": shell_nodes,
        "field_bytes": field_bytes,
        "shell_bytes": shell_bytes,
        "size_ratio": ratio,
        "raw_f64_ratio": dense_bytes as f64 / shell_bytes as f64,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

/// Write the shell; returns (grid nodes, shell nodes, bytes written).
fn store<const D: usize>(shell: &Shell<D>, path: &Path) -> anyhow::Result<(usize, usize, usize)> {
    if shell.indices.is_empty() {
        anyhow::bail!(
            "the field has no sign change, so its shell is empty: is it a signed distance field?"
        );
    }
    write_shell(path, shell).with_context(|| format!("cannot write {}", path.display()))?;
    Ok((
        shell.spec.node_count(),
        shell.indices.len(),
        shell.encoded_len(),
    ))
}

fn file_size(path: &Path) -> anyhow::Result<u64> {
    Ok(std::fs::metadata(path)
        .with_context(|| format!("cannot stat {}", path.display()))?
        .len())
}
