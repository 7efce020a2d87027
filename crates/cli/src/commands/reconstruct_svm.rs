//! The `--method svm` flags of `surfrecon reconstruct` (a multi-scale SVM
//! implicit surface fitted to oriented points, meshed by surface-following
//! marching cubes): `reconstruct.rs` flattens [`SvmArgs`] into its
//! arguments and hands [`SvmArgs::options`] to the facade.

use crate::context::Context;
use std::path::PathBuf;
use surfrecon_svm::FitOptions;

/// Residual penalty of the SVM fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LossArg {
    /// ε-insensitive (robust to outliers; the paper's choice).
    Epsilon,
    /// Squared loss (least squares; for comparison).
    Squared,
}

/// SVM-specific flags of `surfrecon reconstruct --method svm`.
#[derive(clap::Args, Clone, Debug)]
pub struct SvmArgs {
    /// Box constraint C relative to each level's local residual, or "auto"
    /// to choose C and ε by validation on held-out points.
    #[arg(long = "svm-c", default_value = "1", value_parser = parse_c)]
    pub svm_c: CSetting,
    /// Width of the ε-insensitive tube, relative to the bounding-box
    /// diagonal; raised to the estimated noise level of the input.
    #[arg(long = "svm-epsilon", default_value_t = FitOptions::default().epsilon)]
    pub svm_epsilon: f64,
    /// Fitting accuracy relative to the diagonal: refinement stops when all
    /// proposed base points are fitted within it; raised to twice the
    /// estimated noise level of the input.
    #[arg(long = "svm-accuracy", default_value_t = FitOptions::default().accuracy)]
    pub svm_accuracy: f64,
    /// Residual penalty.
    #[arg(long, value_enum, default_value_t = LossArg::Epsilon)]
    pub loss: LossArg,
    /// Leave out the K finest levels when meshing (smoother, no re-fit).
    #[arg(long = "drop-levels", default_value_t = 0, value_name = "K")]
    pub drop_levels: usize,
    /// Also save the fitted model (binary .svm format) to this file.
    #[arg(long = "model-out", value_name = "M.svm")]
    pub model_out: Option<PathBuf>,
    /// Mesh a model saved earlier instead of fitting (the input points
    /// still seed the surface-following meshing).
    #[arg(long = "model-in", value_name = "M.svm")]
    pub model_in: Option<PathBuf>,
    /// Neighbours used to estimate normals when the input has none.
    #[arg(long = "svm-normal-k", default_value_t = 12)]
    pub svm_normal_k: usize,
}

/// A fixed C or selection by validation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CSetting {
    Fixed(f64),
    Auto,
}

fn parse_c(s: &str) -> Result<CSetting, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(CSetting::Auto);
    }
    match s.parse::<f64>() {
        Ok(c) if c.is_finite() && c > 0.0 => Ok(CSetting::Fixed(c)),
        _ => Err(format!("expected a positive number or \"auto\", got {s:?}")),
    }
}

impl SvmArgs {
    /// The facade's options for these flags.
    pub fn options(&self) -> surfrecon::SvmOptions {
        surfrecon::SvmOptions {
            c: match self.svm_c {
                CSetting::Fixed(c) => surfrecon::SvmC::Fixed(c),
                CSetting::Auto => surfrecon::SvmC::Auto,
            },
            epsilon: self.svm_epsilon,
            accuracy: self.svm_accuracy,
            loss: match self.loss {
                LossArg::Epsilon => surfrecon::Loss::Epsilon,
                LossArg::Squared => surfrecon::Loss::Squared,
            },
            drop_levels: self.drop_levels,
            model_out: self.model_out.clone(),
            model_in: self.model_in.clone(),
            normal_k: self.svm_normal_k,
            ..Default::default()
        }
    }
}

/// What the fit did, on stderr (the facade reports, the command speaks).
pub fn say_fit(args: &SvmArgs, report: &surfrecon::SvmReport, ctx: &Context) {
    if let Some(k) = report.normals_estimated {
        ctx.say(format!(
            "svm: no normals in the input; estimating them from {k} neighbours"
        ));
    }
    let svm = &report.svm;
    match &svm.fit {
        surfrecon::SvmFit::Loaded { loaded } => {
            ctx.detail(format!("loaded model {loaded} ({} centres)", svm.centres));
        }
        surfrecon::SvmFit::Fitted(fit) => {
            if fit.selection.is_some() {
                ctx.say(format!(
                    "svm: C = {}, ε = {} chosen by validation",
                    fit.c, fit.epsilon
                ));
            }
            for (i, l) in fit.levels.iter().enumerate() {
                ctx.detail(format!(
                    "level {i}: width {:.4}, {} candidates, {} base points, {} centres, {} sweeps, {:.2} s",
                    l.width, l.candidates, l.base_points, l.centres, l.sweeps, l.seconds
                ));
            }
            if let Some(path) = &args.model_out {
                ctx.detail(format!("model saved to {}", path.display()));
            }
        }
    }
    match svm.contour_stack {
        Some(surfrecon::ContourStack::Used) => {
            ctx.detail("contour stack: fitted with samples between and past the slices")
        }
        Some(surfrecon::ContourStack::UsedWithoutCaps) => ctx.say(
            "svm: contour stack: fitted with samples between the slices; caps past the end slices dropped (they added pieces or handles)",
        ),
        Some(surfrecon::ContourStack::UsedWithoutInterpolation) => ctx.say(
            "svm: contour stack: fitted with Hermite samples between the slices; caps and interpolated samples dropped (they added pieces or handles)",
        ),
        Some(surfrecon::ContourStack::DroppedMorePieces) => ctx.say(
            "svm: contour stack: samples between and past the slices dropped (they added pieces)",
        ),
        Some(surfrecon::ContourStack::DroppedMoreHandles) => ctx.say(
            "svm: contour stack: samples between and past the slices dropped (they added handles)",
        ),
        None => {}
    }
    if args.drop_levels > 0 {
        ctx.detail(format!(
            "leaving out the {} finest level(s)",
            args.drop_levels
        ));
    }
    ctx.say(format!(
        "svm: {} kernel centres in {} levels; mesh {} vertices, {} triangles",
        svm.centres, svm.levels_used, svm.mesh.vertices, svm.mesh.triangles
    ));
}
