//! Morphing (`surfrecon morph`): SVM implicit surfaces fitted to two
//! shapes, and a dense warp field between them (feature pairs + distance
//! preservation) that moves the source mesh onto the target.

use crate::error::{Classify, Error, ErrorKind, Result};
use crate::{check, Geometry, Hook, Mesh};
use serde::Serialize;
use surfrecon_geom::normals::{estimate_normals, orient_normals};
use surfrecon_geom::shapes::sample_surface;
use surfrecon_geom::{DVec3, PointCloud};
use surfrecon_svm::warp::{fit_warp, WarpField, WarpOptions};
use surfrecon_svm::{FitOptions, FitReport, SvmError, SvmModel};

/// Options of [`morph`] (the `surfrecon morph` flags).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MorphOptions {
    /// Weight of the feature correspondences.
    pub c_corr: f64,
    /// Weight of distance preservation.
    pub c_dist: f64,
    /// Levels of the warp field.
    pub warp_levels: usize,
}

impl Default for MorphOptions {
    fn default() -> Self {
        MorphOptions {
            c_corr: 100.0,
            c_dist: 1.0,
            warp_levels: 4,
        }
    }
}

impl MorphOptions {
    pub fn warp_options(&self) -> WarpOptions {
        WarpOptions {
            c_corr: self.c_corr,
            c_dist: self.c_dist,
            levels: self.warp_levels,
            ..Default::default()
        }
    }
}

/// A fitted warp and what its levels did.
pub struct Morph {
    pub warp: WarpField,
    pub report: MorphReport,
}

/// The keys `surfrecon morph --json` prints about the warp.
#[derive(Clone, Debug, Serialize)]
pub struct MorphReport {
    pub pairs: usize,
    pub samples: usize,
    pub levels: Vec<WarpLevel>,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct WarpLevel {
    pub width: f64,
    pub centres: usize,
    pub correspondence_rms: f64,
    pub distance_mean: f64,
}

/// Warp `source` onto the shape of `target` (a mesh or oriented points);
/// `pairs` are feature correspondences (source point, target point). The
/// displacement of any point is [`WarpField::displacements`]; frame t ∈
/// [0, 1] of the morph is `v + t·d`.
pub fn morph(
    source: &Mesh,
    target: &Geometry,
    pairs: &[(DVec3, DVec3)],
    options: &MorphOptions,
    hook: Hook,
) -> Result<Morph> {
    if source.triangles.is_empty() {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "the source has no triangles; morph warps a mesh",
        ));
    }
    let warp_options = options.warp_options();
    warp_options
        .validate()
        .map_err(|e| e.within("invalid morph options"))?;
    let source_points = oriented_points(&Geometry::from_mesh(source.clone()));
    let target_points = oriented_points(target);
    check(hook, "fit source")?;
    let (f1, r1) = fit_shape(&source_points).map_err(|e| e.within("fitting the source"))?;
    check(hook, "fit target")?;
    let (f2, _) = fit_shape(&target_points).map_err(|e| e.within("fitting the target"))?;
    let samples = warp_samples(&source_points, r1.diameter);
    check(hook, "warp")?;
    let (warp, reports) = fit_warp(&f1, &f2, &samples, pairs, r1.diameter, &warp_options)
        .map_err(|e| e.within("warp fit failed"))?;
    let levels = reports.iter().map(|r| WarpLevel {
        width: r.width,
        centres: r.centres,
        correspondence_rms: r.correspondence_rms,
        distance_mean: r.distance_mean,
    });
    let report = MorphReport {
        pairs: pairs.len(),
        samples: samples.len(),
        levels: levels.collect(),
    };
    Ok(Morph { warp, report })
}

/// Oriented samples of a shape: points drawn from a mesh (5,000 to 50,000,
/// with the faces' normals), else the points with their normals, estimated
/// and oriented when missing.
pub fn oriented_points(g: &Geometry) -> PointCloud {
    if g.is_mesh() {
        let mesh = g.to_mesh();
        let n = mesh.vertices.len().clamp(5_000, 50_000);
        let pc = sample_surface(&mesh, n, 1);
        if !pc.is_empty() {
            return pc;
        }
    }
    let mut pc = g.points.clone();
    if pc.normals.is_none() {
        let mut normals = estimate_normals(&pc.positions, 12);
        orient_normals(&pc.positions, &mut normals, 12);
        pc.normals = Some(normals);
    }
    pc
}

/// The SVM implicit surface of oriented points, default options.
pub fn fit_shape(pc: &PointCloud) -> Result<(SvmModel, FitReport), SvmError> {
    let normals = pc.normals.as_deref().unwrap_or_default();
    surfrecon_svm::fit(&pc.positions, normals, &FitOptions::default())
}

/// Warp samples: up to ~4,000 of the points, each also moved 2% of the
/// diameter out and in along its normal.
pub fn warp_samples(pc: &PointCloud, diameter: f64) -> Vec<DVec3> {
    let stride = (pc.len() / 4000).max(1);
    let normals = pc.normals.as_deref().unwrap_or_default();
    let mut out = Vec::new();
    for (p, n) in pc.positions.iter().zip(normals).step_by(stride) {
        for t in [-0.02, 0.0, 0.02] {
            out.push(*p + *n * (t * diameter));
        }
    }
    out
}
