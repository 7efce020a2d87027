//! `surfrecon tetrahedralize IN -o OUT.vtk`: the exact Delaunay
//! tetrahedralization of the input points, written as a legacy VTK
//! unstructured grid (binary) for ParaView and other VTK readers.

use crate::context::Context;
use anyhow::{bail, Context as _};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;
use surfrecon_delaunay::Triangulation;
use surfrecon_geom::io::{self, Format};
use surfrecon_geom::DVec3;

/// VTK's cell type for a linear tetrahedron.
const VTK_TETRA: i32 = 10;

#[derive(clap::Args)]
pub struct Args {
    /// Input points (any geometry file; a mesh's vertices are used).
    pub input: PathBuf,
    /// Output legacy VTK file (`.vtk`).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Input format, overriding the extension (ply, obj, off, stl, xyz).
    #[arg(long, value_name = "FMT")]
    pub from: Option<Format>,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    let is_vtk = args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vtk"));
    if !is_vtk {
        bail!(
            "{}: the tetrahedralization is written as legacy VTK; use a .vtk output",
            args.output.display()
        );
    }
    let format = match args.from {
        Some(f) => f,
        None => Format::from_path(&args.input)?,
    };
    let geometry = io::read_as(&args.input, format)?;
    let points = &geometry.points.positions;
    ctx.detail(format!(
        "read {} points from {}",
        points.len(),
        args.input.display()
    ));

    let spinner = ctx.spinner("tetrahedralizing");
    let start = Instant::now();
    let tri = Triangulation::bulk_load(points)
        .with_context(|| format!("{}: cannot tetrahedralize", args.input.display()))?;
    let delaunay_seconds = start.elapsed().as_secs_f64();
    spinner.set_message("writing");
    let cells = tetrahedra_in_input_order(&tri);
    if cells.len().saturating_mul(5) > i32::MAX as usize {
        bail!(
            "{} tetrahedra are too many for a legacy VTK file",
            cells.len()
        );
    }
    io::write_atomic(&args.output, |w| write_vtk(w, points, &cells))?;
    spinner.finish_and_clear();

    let volume = tri.volume();
    ctx.say_wrote(
        &args.output,
        Some(format!(
            "{} tetrahedra on {} points, {} duplicates merged, volume {volume:.6}",
            cells.len(),
            tri.num_vertices(),
            tri.merged_duplicates()
        )),
    );
    ctx.emit_json(&json!({
        "command": "tetrahedralize",
        "input": args.input,
        "output": args.output,
        "points": points.len(),
        "vertices": tri.num_vertices(),
        "duplicates_merged": tri.merged_duplicates(),
        "tetrahedra": cells.len(),
        "hull_facets": tri.num_hull_facets(),
        "volume": volume,
        "delaunay_seconds": delaunay_seconds,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

/// Finite tetrahedra with vertices as input point indices, so the file's
/// points are the input's, in its order.
fn tetrahedra_in_input_order(tri: &Triangulation) -> Vec<[u32; 4]> {
    tri.finite_tets()
        .map(|t| {
            tri.tet_vertices(t).map(|v| {
                tri.input_of_vertex(v)
                    .expect("bulk_load vertices have an input index") as u32
            })
        })
        .collect()
}

/// Binary legacy VTK (big-endian). Tetrahedra are positively oriented in
/// VTK's sense: the fourth point is on the side the right-hand normal of
/// the first three points to.
fn write_vtk(w: &mut dyn Write, points: &[DVec3], cells: &[[u32; 4]]) -> std::io::Result<()> {
    writeln!(w, "# vtk DataFile Version 3.0")?;
    writeln!(w, "surfrecon Delaunay tetrahedralization")?;
    writeln!(w, "BINARY")?;
    writeln!(w, "DATASET UNSTRUCTURED_GRID")?;
    writeln!(w, "POINTS {} double", points.len())?;
    for p in points {
        for x in p.to_array() {
            w.write_all(&x.to_be_bytes())?;
        }
    }
    writeln!(w)?;
    writeln!(w, "CELLS {} {}", cells.len(), cells.len() * 5)?;
    for cell in cells {
        w.write_all(&4i32.to_be_bytes())?;
        for &v in cell {
            w.write_all(&(v as i32).to_be_bytes())?;
        }
    }
    writeln!(w)?;
    writeln!(w, "CELL_TYPES {}", cells.len())?;
    for _ in cells {
        w.write_all(&VTK_TETRA.to_be_bytes())?;
    }
    writeln!(w)
}
