//! `surfrecon distance`: a distance field from any geometry file: unsigned
//! distance to its points, polylines and triangles (2D or 3D), or the signed
//! distance of a closed triangle mesh.

use crate::context::Context;
use anyhow::{bail, Context as _};
use std::path::PathBuf;
use std::time::Instant;
use surfrecon_geom::{io, Geometry};
use surfrecon_grid::distance::{unsigned_distance_with, DataSet, DistanceOptions};
use surfrecon_grid::field_io::write_field;
use surfrecon_grid::sdf::{check_closed, signed_distance};
use surfrecon_grid::{Field, GridSize, GridSpec};

/// Cells along the longest axis when neither --resolution nor --spacing is given.
const DEFAULT_RESOLUTION: usize = 128;

#[derive(clap::Args)]
pub struct Args {
    /// Geometry file (.ply, .obj, .off, .stl, .xyz): points, polylines and
    /// triangles all count as data.
    pub input: PathBuf,
    /// Output field (.nrrd or .vtk).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Cells along the longest axis of the data bounds [default: 128].
    #[arg(long, conflicts_with = "spacing")]
    pub resolution: Option<usize>,
    /// Grid spacing (distance between nodes), instead of --resolution.
    #[arg(long)]
    pub spacing: Option<f64>,
    /// Empty cells added around the data bounds on every side.
    #[arg(long, default_value_t = 4)]
    pub padding: usize,
    /// Signed distance (negative inside) of a closed triangle mesh.
    #[arg(long)]
    pub signed: bool,
    /// With --signed: accept a mesh with holes or non-manifold edges; the
    /// sign then follows the generalized winding number (inside where the
    /// surface wraps a point more than halfway).
    #[arg(long, requires = "signed")]
    pub allow_open: bool,
    /// Only compute distances within this distance of the data (same units
    /// as the data); nodes farther away store the band value (±band when
    /// signed). Much faster than the full field.
    #[arg(long)]
    pub band: Option<f64>,
    /// Compute a 2D field in the xy plane (z is ignored). Chosen
    /// automatically when every z is 0 and there are no triangles.
    #[arg(long = "2d", conflicts_with = "three_d")]
    pub two_d: bool,
    /// Compute a 3D field even when every z is 0.
    #[arg(long = "3d")]
    pub three_d: bool,
    /// Which field: `regular` (a distance per grid node, .nrrd/.vtk),
    /// `odf` (offset field: samples moved onto sharp edges and corners,
    /// .odf) or `udf` (unified field: regular distances plus exact
    /// crossings and feature points only where needed, .udf). odf and udf
    /// keep the sharp features of a closed mesh.
    #[arg(long, value_enum, default_value_t = Kind::Regular)]
    pub kind: Kind,
    /// odf/udf: angle in degrees between face normals above which a mesh
    /// edge counts as sharp.
    #[arg(long, default_value_t = surfrecon_distfield::features::DEFAULT_FEATURE_ANGLE_DEG)]
    pub feature_angle: f64,
    /// udf: store exact crossings where interpolating the distances
    /// misplaces them by more than this many grid spacings.
    #[arg(long, default_value_t = surfrecon_distfield::unified::DEFAULT_THRESHOLD)]
    pub threshold: f64,
    /// odf: weight of the fidelity energy (distance to the features and
    /// the surface).
    #[arg(long, default_value_t = 1.0)]
    pub lambda_distance: f64,
    /// odf: weight of the spring energy (grid edges near their length).
    #[arg(long, default_value_t = 0.1)]
    pub lambda_spring: f64,
    /// odf: weight of the orthogonality energy (grid edges perpendicular).
    #[arg(long, default_value_t = 0.1)]
    pub lambda_ortho: f64,
    /// odf: rounds of the sample search; the step halves every round.
    #[arg(long, default_value_t = surfrecon_distfield::offset::DEFAULT_ITERATIONS)]
    pub iterations: usize,
}

/// The kinds of field `distance` computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    Regular,
    Odf,
    Udf,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    let size = grid_size(&args)?;
    if args.kind != Kind::Regular {
        return super::feature_field::run(&args, size, ctx);
    }
    if let Some(w) = args.band {
        if !(w.is_finite() && w > 0.0) {
            bail!("--band must be a positive distance, not {w}");
        }
    }
    let t_read = Instant::now();
    let geometry = io::read(&args.input)?;
    let read_secs = t_read.elapsed().as_secs_f64();
    let flat = geometry.points.positions.iter().all(|p| p.z == 0.0);
    let two_d = args.two_d || (flat && !args.three_d && !geometry.is_mesh() && !args.signed);
    if two_d && args.signed {
        bail!("--signed needs a closed triangle mesh in 3D; it does not apply to 2D data");
    }
    if flat && two_d && !args.two_d {
        ctx.say("all z are 0: computing a 2D field (use --3d for a 3D one)");
    }
    let t_compute = Instant::now();
    let spinner = ctx.spinner("computing distances");
    let summary = if two_d {
        let field = unsigned_field::<2>(&geometry, size, &args)?;
        spinner.finish_and_clear();
        write(&args, &field, ctx, t_compute, read_secs)?
    } else if args.signed {
        let field = signed_field(&geometry, size, &args)?;
        spinner.finish_and_clear();
        write(&args, &field, ctx, t_compute, read_secs)?
    } else {
        let field = unsigned_field::<3>(&geometry, size, &args)?;
        spinner.finish_and_clear();
        write(&args, &field, ctx, t_compute, read_secs)?
    };
    ctx.emit_json(&summary);
    Ok(())
}

pub(super) fn grid_size(args: &Args) -> anyhow::Result<GridSize> {
    match (args.resolution, args.spacing) {
        (_, Some(h)) if !(h.is_finite() && h > 0.0) => {
            bail!("--spacing must be a positive number, not {h}")
        }
        (_, Some(h)) => Ok(GridSize::Spacing(h)),
        (Some(0), None) => bail!("--resolution must be at least 1"),
        (Some(n), None) => Ok(GridSize::Resolution(n)),
        (None, None) => Ok(GridSize::Resolution(DEFAULT_RESOLUTION)),
    }
}

/// The grid over the data's bounds, named after the input on failure.
fn grid_over<const D: usize>(
    data: &DataSet<D>,
    size: GridSize,
    args: &Args,
) -> anyhow::Result<GridSpec<D>> {
    let Some((lo, hi)) = data.bounds() else {
        bail!(
            "{} holds no points, lines or triangles",
            args.input.display()
        );
    };
    GridSpec::from_bounds(lo, hi, size, args.padding)
        .with_context(|| format!("cannot place a grid over {}", args.input.display()))
}

fn unsigned_field<const D: usize>(
    geometry: &Geometry,
    size: GridSize,
    args: &Args,
) -> anyhow::Result<Field<D>> {
    let data = DataSet::<D>::from_geometry(geometry)
        .with_context(|| format!("bad geometry in {}", args.input.display()))?;
    let spec = grid_over(&data, size, args)?;
    let options = match args.band {
        Some(w) => DistanceOptions {
            band_cells: w / spec.spacing,
            propagate: false,
        },
        None => DistanceOptions::default(),
    };
    let mut field = unsigned_distance_with(&data, &spec, &options)
        .with_context(|| format!("distance to {}", args.input.display()))?
        .field;
    if let Some(w) = args.band {
        field.values.iter_mut().for_each(|v| *v = v.min(w));
    }
    Ok(field)
}

fn signed_field(geometry: &Geometry, size: GridSize, args: &Args) -> anyhow::Result<Field<3>> {
    if !geometry.is_mesh() {
        bail!(
            "--signed needs a closed triangle mesh, but {} has no triangles",
            args.input.display()
        );
    }
    let mesh = geometry.to_mesh();
    if !args.allow_open {
        check_closed(&mesh).with_context(|| {
            format!(
                "cannot sign {} (--allow-open signs it by winding number anyway)",
                args.input.display()
            )
        })?;
    }
    let data = DataSet::<3>::from_mesh(&mesh)
        .with_context(|| format!("bad mesh in {}", args.input.display()))?;
    let spec = grid_over(&data, size, args)?;
    signed_distance(&mesh, &spec, args.band)
        .with_context(|| format!("signed distance of {}", args.input.display()))
}

/// Write the field, report, and return the JSON summary.
fn write<const D: usize>(
    args: &Args,
    field: &Field<D>,
    ctx: &Context,
    t_compute: Instant,
    read_secs: f64,
) -> anyhow::Result<serde_json::Value> {
    let compute_secs = t_compute.elapsed().as_secs_f64();
    let t_write = Instant::now();
    write_field(&args.output, field)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    let write_secs = t_write.elapsed().as_secs_f64();
    let spec = &field.spec;
    let (min, max) = field
        .values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    ctx.say(format!(
        "{} {}D distance on a {} grid (spacing {:.6}), values {min:.6} to {max:.6}",
        if args.signed { "signed" } else { "unsigned" },
        D,
        spec.dims_string(),
        spec.spacing
    ));
    ctx.say_wrote(&args.output, Some(format!("compute {compute_secs:.2} s")));
    Ok(serde_json::json!({
        "command": "distance",
        "input": args.input,
        "output": args.output,
        "dimension": D,
        "signed": args.signed,
        "band": args.band,
        "dims": spec.dims.to_vec(),
        "spacing": spec.spacing,
        "origin": spec.origin.to_vec(),
        "min": min,
        "max": max,
        "seconds": {
            "read": read_secs,
            "compute": compute_secs,
            "write": write_secs,
            "total": ctx.elapsed(),
        },
    }))
}
