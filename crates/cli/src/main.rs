//! `surfrecon`: reconstruct surfaces from scattered data and work with
//! distance fields. A thin layer over the surfrecon crates: one subcommand
//! per user task, each in `commands/`.

mod commands;
mod context;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use context::Context;

#[derive(Parser)]
#[command(
    name = "surfrecon",
    version,
    about = "Surface reconstruction from points, curves and patches; distance fields"
)]
struct Cli {
    /// Print nothing but errors.
    #[arg(long, global = true)]
    quiet: bool,
    /// Print a machine-readable JSON summary on stdout.
    #[arg(long, global = true)]
    json: bool,
    /// More detail on stderr (repeat for more).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Convert between geometry formats (by extension).
    Convert(commands::convert::Args),
    /// Print counts, bounds, normals and spacing of a geometry file.
    Info(commands::info::Args),
    /// Estimate and consistently orient point normals.
    Normals(commands::normals::Args),
    /// Score a reconstruction against a reference surface.
    Eval(commands::eval::Args),
    /// Draw a mesh or point cloud to a PNG.
    Render(commands::render::Args),
    /// Compute a distance field (unsigned, signed for a closed mesh, or
    /// keeping its sharp features: --kind odf|udf).
    Distance(commands::distance::Args),
    /// Extract an isosurface mesh (or 2D curves) from a field.
    Extract(commands::extract::Args),
    /// Carve, add or intersect shapes on a distance field (CSG), keeping
    /// the new sharp edges in offset and unified fields.
    Sculpt(commands::sculpt::Args),
    /// Store a field as a compact thin shell.
    Shell(commands::shell::Args),
    /// Rebuild a full signed distance field from a thin shell.
    Unshell(commands::unshell::Args),
    /// Reconstruct a closed surface from points, curves and patches.
    Reconstruct(commands::reconstruct::Args),
    /// Morph one shape into another with an SVM warp field.
    Morph(commands::morph::Args),
    /// Exact 3D Delaunay tetrahedralization of points, as a VTK grid.
    Tetrahedralize(commands::tetrahedralize::Args),
}

fn main() {
    // Sculpting steps apply in command-line order, which only the raw
    // matches record.
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let ctx = Context::new(cli.quiet, cli.json, cli.verbose);
    let result = match cli.command {
        Command::Convert(a) => commands::convert::run(a, &ctx),
        Command::Info(a) => commands::info::run(a, &ctx),
        Command::Normals(a) => commands::normals::run(a, &ctx),
        Command::Eval(a) => commands::eval::run(a, &ctx),
        Command::Render(a) => commands::render::run(a, &ctx),
        Command::Distance(a) => commands::distance::run(a, &ctx),
        Command::Extract(a) => commands::extract::run(a, &ctx),
        Command::Sculpt(a) => {
            let sub = matches
                .subcommand_matches("sculpt")
                .expect("parsed as sculpt");
            commands::sculpt::run(a, sub, &ctx)
        }
        Command::Shell(a) => commands::shell::run(a, &ctx),
        Command::Unshell(a) => commands::unshell::run(a, &ctx),
        Command::Reconstruct(a) => commands::reconstruct::run(a, &ctx),
        Command::Morph(a) => commands::morph::run(a, &ctx),
        Command::Tetrahedralize(a) => commands::tetrahedralize::run(a, &ctx),
    };
    if let Err(e) = result {
        // One clear line: the chain of causes joined, no backtrace.
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
