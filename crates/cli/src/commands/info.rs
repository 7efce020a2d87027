//! `surfrecon info IN`: what a geometry file holds — counts, bounds,
//! normals, and the mean nearest-neighbour spacing of its points.

use crate::context::Context;
use serde_json::json;
use std::path::PathBuf;
use surfrecon_geom::io::{self, Format};
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, Geometry};

/// Points whose nearest neighbour is measured; larger inputs are
/// subsampled (seeded, so the figure is reproducible).
const SPACING_SAMPLE: usize = 20_000;
const SAMPLE_SEED: u64 = 0x5eed_1e55;

#[derive(clap::Args)]
pub struct Args {
    /// Geometry file (.ply, .obj, .off, .stl, .xyz).
    pub input: PathBuf,
    /// Input format, overriding the extension (ply, obj, off, stl, xyz).
    #[arg(long, value_name = "FMT")]
    pub from: Option<Format>,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    let format = match args.from {
        Some(f) => f,
        None => Format::from_path(&args.input)?,
    };
    let spinner = ctx.spinner(&format!("reading {}", args.input.display()));
    let g = io::read_as(&args.input, format)?;
    spinner.set_message("measuring spacing");
    let spacing = mean_spacing(&g.points.positions);
    spinner.finish_and_clear();
    let report = Report::of(&g, spacing);
    if ctx.json {
        let mut value = report.json();
        value["file"] = json!(args.input);
        value["format"] = json!(format.name());
        value["seconds"] = json!(ctx.elapsed());
        ctx.emit_json(&value);
    } else if !ctx.quiet {
        println!("{}  ({format})", args.input.display());
        print!("{}", report.text());
    }
    Ok(())
}

/// Mean distance from a point to its nearest other point, over all points
/// or a seeded sample of [`SPACING_SAMPLE`] of them. `None` below 2 points.
fn mean_spacing(points: &[DVec3]) -> Option<Spacing> {
    if points.len() < 2 {
        return None;
    }
    let tree = KdTree::new(points);
    let sample = sample_indices(points.len(), SPACING_SAMPLE, SAMPLE_SEED);
    // knn(q, 2): the first hit is the point itself (or a duplicate at 0).
    let total: f64 = sample
        .iter()
        .map(|&i| tree.knn(points[i], 2).get(1).map_or(0.0, |n| n.distance))
        .sum();
    Some(Spacing {
        mean: total / sample.len() as f64,
        sampled: sample.len(),
    })
}

struct Spacing {
    mean: f64,
    sampled: usize,
}

/// `min(n, k)` distinct indices below `n`: all of them if `n <= k`, else a
/// seeded partial Fisher-Yates shuffle (SplitMix64), sorted.
fn sample_indices(n: usize, k: usize, seed: u64) -> Vec<usize> {
    let mut all: Vec<usize> = (0..n).collect();
    if n <= k {
        return all;
    }
    let mut state = seed;
    for i in 0..k {
        let j = i + (splitmix64(&mut state) % (n - i) as u64) as usize;
        all.swap(i, j);
    }
    all.truncate(k);
    all.sort_unstable();
    all
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

struct Report {
    points: usize,
    triangles: usize,
    polylines: usize,
    segments: usize,
    normals: bool,
    scalars: bool,
    min: Option<DVec3>,
    max: Option<DVec3>,
    diagonal: f64,
    spacing: Option<Spacing>,
}

impl Report {
    fn of(g: &Geometry, spacing: Option<Spacing>) -> Report {
        let bounds = g.bounds();
        let (min, max) = if bounds.is_empty() {
            (None, None)
        } else {
            (Some(bounds.min), Some(bounds.max))
        };
        Report {
            points: g.points.len(),
            triangles: g.triangles.len(),
            polylines: g.lines.len(),
            segments: g.to_polylines().segments().count(),
            normals: g.points.normals.is_some(),
            scalars: g.points.scalars.is_some(),
            min,
            max,
            diagonal: if bounds.is_empty() {
                0.0
            } else {
                bounds.diagonal()
            },
            spacing,
        }
    }

    fn json(&self) -> serde_json::Value {
        json!({
            "points": self.points,
            "triangles": self.triangles,
            "polylines": self.polylines,
            "segments": self.segments,
            "has_normals": self.normals,
            "has_scalars": self.scalars,
            "bounds": {
                "min": self.min.map(|p| p.to_array()),
                "max": self.max.map(|p| p.to_array()),
            },
            "diagonal": self.diagonal,
            "mean_spacing": self.spacing.as_ref().map(|s| s.mean),
            "spacing_sample": self.spacing.as_ref().map_or(0, |s| s.sampled),
        })
    }

    fn text(&self) -> String {
        let yes_no = |b: bool| if b { "yes" } else { "no" };
        let vec = |p: Option<DVec3>| {
            p.map_or("-".into(), |p| format!("{:.6} {:.6} {:.6}", p.x, p.y, p.z))
        };
        let spacing = match &self.spacing {
            Some(s) if s.sampled < self.points => {
                format!("{:.6} (over {} sampled points)", s.mean, s.sampled)
            }
            Some(s) => format!("{:.6}", s.mean),
            None => "-".into(),
        };
        format!(
            "  points        {}\n  triangles     {}\n  polylines     {} ({} segments)\n  \
             normals       {}\n  scalars       {}\n  bounds min    {}\n  bounds max    {}\n  \
             diagonal      {:.6}\n  mean spacing  {}\n",
            self.points,
            self.triangles,
            self.polylines,
            self.segments,
            yes_no(self.normals),
            yes_no(self.scalars),
            vec(self.min),
            vec(self.max),
            self.diagonal,
            spacing
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_is_distinct_sorted_and_seeded() {
        let a = sample_indices(1000, 100, 7);
        assert_eq!(a.len(), 100);
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(a, sample_indices(1000, 100, 7));
        assert_ne!(a, sample_indices(1000, 100, 8));
        assert_eq!(sample_indices(5, 100, 7), vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn spacing_of_a_regular_grid_is_its_step() {
        let points: Vec<DVec3> = (0..30)
            .flat_map(|i| (0..30).map(move |j| DVec3::new(i as f64 * 0.5, j as f64 * 0.5, 1.0)))
            .collect();
        let s = mean_spacing(&points).unwrap();
        assert!((s.mean - 0.5).abs() < 1e-12, "{}", s.mean);
        assert!(mean_spacing(&points[..1]).is_none());
    }
}
