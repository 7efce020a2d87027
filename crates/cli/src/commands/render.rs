//! `surfrecon render`: draw a mesh, point cloud or polylines to a PNG.

use crate::context::Context;
use anyhow::Context as _;
use std::path::PathBuf;
use surfrecon_geom::io;
use surfrecon_geom::render::{self, Projection, RenderOptions, Shading, UpAxis};

#[derive(clap::Args)]
pub struct Args {
    /// Geometry file to draw (ply, obj, off, stl, xyz).
    pub input: PathBuf,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Camera azimuth and elevation in degrees, e.g. `35,25`; `0,0` looks
    /// at the front, `0,90` from above.
    #[arg(long, value_name = "AZ,EL", default_value = "35,25", value_parser = parse_view, allow_hyphen_values = true)]
    pub view: (f64, f64),
    /// Image size: `WxH`, or `N` for a square.
    #[arg(long, value_name = "WxH", default_value = "800x600", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Draw mesh edges over the surface.
    #[arg(long)]
    pub wireframe: bool,
    /// Flat shading: one normal per triangle.
    #[arg(long)]
    pub flat: bool,
    /// Orthographic (parallel) projection instead of perspective.
    #[arg(long)]
    pub ortho: bool,
    /// Which axis of the data points up on screen.
    #[arg(long, value_enum, default_value = "y")]
    pub up: Up,
    /// Point clouds without normals: skip normal estimation and shade the
    /// points by depth only (faster for millions of points).
    #[arg(long)]
    pub depth_shading: bool,
    /// Splat diameter in pixels for point clouds (default: from the point
    /// spacing).
    #[arg(long, value_name = "PX")]
    pub point_size: Option<f64>,
}

/// The `--up` choices.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum Up {
    Y,
    Z,
}

/// `AZ,EL` in degrees.
fn parse_view(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("expected AZ,EL in degrees (e.g. 35,25), got {s:?}");
    let (az, el) = s.split_once(',').ok_or_else(bad)?;
    let az: f64 = az.trim().parse().map_err(|_| bad())?;
    let el: f64 = el.trim().parse().map_err(|_| bad())?;
    if !az.is_finite() || !(-90.0..=90.0).contains(&el) {
        return Err(format!(
            "azimuth must be finite and elevation within [-90, 90], got {s:?}"
        ));
    }
    Ok((az, el))
}

/// `WxH` or `N` (square), each side 1 to the renderer's maximum.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected WxH or N in pixels (e.g. 800x600), got {s:?}");
    let side = |t: &str| -> Result<u32, String> {
        let v: u32 = t.trim().parse().map_err(|_| bad())?;
        if v == 0 || v > render::MAX_SIDE {
            return Err(format!(
                "image side {v} must be 1 to {} pixels",
                render::MAX_SIDE
            ));
        }
        Ok(v)
    };
    match s.split_once(['x', 'X']) {
        Some((w, h)) => Ok((side(w)?, side(h)?)),
        None => side(s).map(|n| (n, n)),
    }
}

/// "1 point", "2 points".
fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

impl Args {
    fn options(&self) -> RenderOptions {
        RenderOptions {
            width: self.size.0,
            height: self.size.1,
            azimuth_deg: self.view.0,
            elevation_deg: self.view.1,
            up: match self.up {
                Up::Y => UpAxis::Y,
                Up::Z => UpAxis::Z,
            },
            projection: if self.ortho {
                Projection::Orthographic
            } else {
                Projection::Perspective
            },
            shading: if self.flat {
                Shading::Flat
            } else {
                Shading::Smooth
            },
            wireframe: self.wireframe,
            point_size: self.point_size,
            estimate_point_normals: !self.depth_shading,
            ..RenderOptions::default()
        }
    }
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    let spinner = ctx.spinner("reading");
    let geometry = io::read(&args.input).context("reading the input")?;
    spinner.set_message("rendering");
    let options = args.options();
    let image = render::render(&geometry, &options)
        .with_context(|| format!("rendering {}", args.input.display()))?;
    render::write_png(&args.output, &image).context("writing the picture")?;
    spinner.finish_and_clear();
    let what = if geometry.is_mesh() {
        count(geometry.triangles.len(), "triangle")
    } else if !geometry.lines.is_empty() {
        count(geometry.lines.len(), "polyline")
    } else {
        count(geometry.points.len(), "point")
    };
    ctx.say(format!(
        "wrote {} ({}x{}, {what}) in {:.2} s",
        args.output.display(),
        image.width,
        image.height,
        ctx.elapsed()
    ));
    ctx.emit_json(&serde_json::json!({
        "command": "render",
        "input": args.input.display().to_string(),
        "output": args.output.display().to_string(),
        "width": image.width,
        "height": image.height,
        "vertices": geometry.points.len(),
        "triangles": geometry.triangles.len(),
        "lines": geometry.lines.len(),
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_and_sizes_parse() {
        assert_eq!(parse_view("35,25"), Ok((35.0, 25.0)));
        assert_eq!(parse_view("-120, -10.5"), Ok((-120.0, -10.5)));
        assert!(parse_view("35").is_err());
        assert!(parse_view("a,b").is_err());
        assert!(parse_view("0,91").is_err());
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert_eq!(parse_size("300"), Ok((300, 300)));
        assert!(parse_size("0x10").is_err());
        assert!(parse_size("99999x10").unwrap_err().contains("16384"));
        assert!(parse_size("big").is_err());
    }
}
