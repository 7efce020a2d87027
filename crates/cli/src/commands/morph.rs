//! `surfrecon morph`: fit SVM implicit surfaces to two shapes, compute a
//! dense warp field between them (feature pairs + distance preservation),
//! apply it to the source mesh (and any `--carry` meshes), and write the
//! intermediate meshes by linear interpolation.

use crate::context::Context;
use anyhow::Context as _;
use serde_json::json;
use std::path::{Path, PathBuf};
use surfrecon::morph::{fit_shape, oriented_points, warp_samples};
use surfrecon::{io, DVec3, Geometry, MorphOptions, TriMesh};
use surfrecon_svm::warp::{fit_warp, WarpField};

/// Each frame is a file; more than this is a mistake, not an animation.
const MAX_FRAMES: usize = 10_000;

#[derive(clap::Args)]
pub struct Args {
    /// Source mesh (its vertices are warped).
    pub source: PathBuf,
    /// Target shape: a mesh, or points with normals.
    pub target: PathBuf,
    /// Feature correspondences: one pair per line, "x1 y1 z1 x2 y2 z2"
    /// (source point, target point); '#' starts a comment.
    #[arg(long, value_name = "PAIRS.txt")]
    pub pairs: Option<PathBuf>,
    /// Output prefix: writes PREFIX_000.ply ... PREFIX_<K-1>.ply.
    #[arg(short, long, value_name = "PREFIX")]
    pub output: PathBuf,
    /// Number of meshes written, from the source (0%) to the warped source (100%).
    #[arg(long, default_value_t = 5)]
    pub frames: usize,
    /// Extra meshes carried along by the warp (written as PREFIX_carry<i>_<k>.ply).
    #[arg(long, value_name = "EXTRA.obj")]
    pub carry: Vec<PathBuf>,
    /// Weight of the correspondence term.
    #[arg(long, default_value_t = 100.0)]
    pub c_corr: f64,
    /// Weight of the distance-preserving term.
    #[arg(long, default_value_t = 1.0)]
    pub c_dist: f64,
    /// Warp levels, from kernels half the diameter wide, halving.
    #[arg(long, default_value_t = 4)]
    pub warp_levels: usize,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    if !(2..=MAX_FRAMES).contains(&args.frames) {
        anyhow::bail!(
            "--frames must be between 2 (the source and the result) and {MAX_FRAMES} (one file each), not {}",
            args.frames
        );
    }
    let opts = MorphOptions {
        c_corr: args.c_corr,
        c_dist: args.c_dist,
        warp_levels: args.warp_levels,
    }
    .warp_options();
    opts.validate().context("invalid warp options")?;
    let source = read_mesh(&args.source)?;
    let target = io::read(&args.target)?;
    let carried: Vec<TriMesh> = args
        .carry
        .iter()
        .map(|p| read_mesh(p))
        .collect::<anyhow::Result<_>>()?;
    let pairs = match &args.pairs {
        Some(p) => read_pairs(p)?,
        None => Vec::new(),
    };
    let source_points = oriented_points(&Geometry::from_mesh(source.clone()));
    let target_points = oriented_points(&target);
    let spinner = ctx.spinner("fitting both shapes");
    let (f1, r1) =
        fit_shape(&source_points).with_context(|| format!("fitting {}", args.source.display()))?;
    let (f2, _) =
        fit_shape(&target_points).with_context(|| format!("fitting {}", args.target.display()))?;
    spinner.finish_and_clear();
    let samples = warp_samples(&source_points, r1.diameter);
    let spinner = ctx.spinner("fitting the warp field");
    let (warp, reports) =
        fit_warp(&f1, &f2, &samples, &pairs, r1.diameter, &opts).context("warp fit failed")?;
    spinner.finish_and_clear();
    let mut written = write_frames(&source, &warp, &args.output, "", args.frames)?;
    for (i, m) in carried.iter().enumerate() {
        written.extend(write_frames(
            m,
            &warp,
            &args.output,
            &format!("_carry{i}"),
            args.frames,
        )?);
    }
    let last = reports.last();
    ctx.say(format!(
        "morph: {} frames written; correspondence rms {:.3e}, mean |f1 - f2(warped)| {:.3e}",
        args.frames,
        last.map_or(0.0, |r| r.correspondence_rms),
        last.map_or(0.0, |r| r.distance_mean)
    ));
    ctx.emit_json(&json!({
        "command": "morph",
        "frames": written.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "pairs": pairs.len(),
        "samples": samples.len(),
        "levels": reports.iter().map(|r| json!({
            "width": r.width, "centres": r.centres,
            "correspondence_rms": r.correspondence_rms, "distance_mean": r.distance_mean,
        })).collect::<Vec<_>>(),
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

fn read_mesh(path: &Path) -> anyhow::Result<TriMesh> {
    let g = io::read(path)?;
    if !g.is_mesh() {
        anyhow::bail!("{}: has no triangles; morph warps a mesh", path.display());
    }
    Ok(g.to_mesh())
}

/// Parse "x1 y1 z1 x2 y2 z2" lines; errors name the file and line.
fn read_pairs(path: &Path) -> anyhow::Result<Vec<(DVec3, DVec3)>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut pairs = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let content = line.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let nums: Vec<f64> = content
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .map(|s| s.parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()
            .filter(|v: &Vec<f64>| v.len() == 6 && v.iter().all(|x| x.is_finite()))
            .with_context(|| {
                format!(
                    "{}: line {}: expected six numbers \"x1 y1 z1 x2 y2 z2\", got {content:?}",
                    path.display(),
                    i + 1
                )
            })?;
        pairs.push((
            DVec3::new(nums[0], nums[1], nums[2]),
            DVec3::new(nums[3], nums[4], nums[5]),
        ));
    }
    Ok(pairs)
}

/// Write `frames` copies of `mesh` moved by k/(frames−1) of the warp.
fn write_frames(
    mesh: &TriMesh,
    warp: &WarpField,
    prefix: &Path,
    tag: &str,
    frames: usize,
) -> anyhow::Result<Vec<PathBuf>> {
    let t = warp.displacements(&mesh.vertices);
    let mut written = Vec::new();
    for k in 0..frames {
        let a = k as f64 / (frames - 1) as f64;
        let frame = TriMesh {
            vertices: mesh
                .vertices
                .iter()
                .zip(&t)
                .map(|(v, d)| *v + *d * a)
                .collect(),
            triangles: mesh.triangles.clone(),
            normals: None,
        };
        let path = PathBuf::from(format!("{}{tag}_{k:03}.ply", prefix.display()));
        io::write(&path, &Geometry::from_mesh(frame))
            .with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}
