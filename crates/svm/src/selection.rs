//! Parameter selection by validation, as the paper does: fit on part of the
//! points, measure the error on the held-out rest, keep the best value.
//!
//! Too small a C (strong regularization) gives a smooth function that misses
//! the data; too large a C over-fits and generalizes worse. The validation
//! error is the mean absolute deviation of f from the signed distance at the
//! held-out surface points (target 0) and at consistent off-surface points
//! along their normals (target ±y).

use crate::error::{Result, SvmError};
use crate::multiscale::{fit, FitOptions};
use crate::training::SurfaceSamples;
use crate::SvmModel;
use glam::DVec3;

/// One tried parameter pair and its validation error (relative to the
/// diagonal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trial {
    pub c: f64,
    pub epsilon: f64,
    pub error: f64,
}

/// The chosen parameters and every trial.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    pub c: f64,
    pub epsilon: f64,
    pub trials: Vec<Trial>,
}

/// How the validation is set up.
#[derive(Clone, Debug)]
pub struct SelectionOptions {
    pub c_values: Vec<f64>,
    pub epsilon_values: Vec<f64>,
    /// Every `holdout`-th point (in a fixed scrambled order) is held out.
    pub holdout: usize,
    /// Fit on at most this many points (a strided subset) to keep the
    /// search fast on large scans; the relative parameters transfer.
    pub max_points: usize,
}

impl Default for SelectionOptions {
    fn default() -> Self {
        SelectionOptions {
            c_values: vec![0.125, 0.25, 0.5, 1.0, 2.0, 4.0],
            epsilon_values: vec![5e-4],
            holdout: 5,
            max_points: 20_000,
        }
    }
}

/// Try every (C, ε) pair of `sel` with the other settings of `base`; return
/// the pair with the smallest validation error.
pub fn select_parameters(
    points: &[DVec3],
    normals: &[DVec3],
    base: &FitOptions,
    sel: &SelectionOptions,
) -> Result<Selection> {
    if sel.c_values.is_empty() || sel.epsilon_values.is_empty() || sel.holdout < 2 {
        return Err(SvmError::InvalidParameter {
            name: "selection",
            message: "needs at least one C, one ε and a hold-out period of 2 or more".into(),
        });
    }
    let (train, valid) = split(points.len(), sel.holdout, sel.max_points);
    let pick = |idx: &[usize], v: &[DVec3]| idx.iter().map(|&i| v[i]).collect::<Vec<_>>();
    let (tp, tn) = (pick(&train, points), pick(&train, normals));
    let validation = SurfaceSamples::new(&pick(&valid, points), &pick(&valid, normals))?;
    let reference = SurfaceSamples::new(points, normals)?;
    let mut trials = Vec::new();
    for &epsilon in &sel.epsilon_values {
        for &c in &sel.c_values {
            let opts = FitOptions {
                c,
                epsilon,
                ..*base
            };
            let (model, _) = fit(&tp, &tn, &opts)?;
            let error = validation_error(&model, &validation, &reference) / reference.diameter;
            trials.push(Trial { c, epsilon, error });
        }
    }
    let best = *trials
        .iter()
        .min_by(|a, b| a.error.total_cmp(&b.error))
        .expect("at least one trial");
    Ok(Selection {
        c: best.c,
        epsilon: best.epsilon,
        trials,
    })
}

/// Indices of the training and the validation points: a fixed scramble
/// (multiplicative hash) so held-out points are spread over the surface.
fn split(n: usize, holdout: usize, max_points: usize) -> (Vec<usize>, Vec<usize>) {
    let stride = (n / max_points.max(1)).max(1);
    let (mut train, mut valid) = (Vec::new(), Vec::new());
    for i in (0..n).step_by(stride) {
        let scrambled = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32;
        if scrambled.is_multiple_of(holdout as u64) {
            valid.push(i);
        } else {
            train.push(i);
        }
    }
    (train, valid)
}

/// Mean |f − target| over the held-out points and their off-surface points
/// at 1% of the diagonal (consistency-checked against all samples).
fn validation_error(model: &SvmModel, valid: &SurfaceSamples, all: &SurfaceSamples) -> f64 {
    let y = 0.01 * all.diameter;
    let reps: Vec<usize> = (0..valid.points.len()).collect();
    let off = valid.off_surface(&reps, y);
    let consistent: Vec<_> = off
        .into_iter()
        .filter(|t| {
            all.tree
                .nearest(t.position)
                .is_none_or(|n| n.distance >= 0.9 * y)
        })
        .collect();
    let on: f64 = model.values(&valid.points).iter().map(|v| v.abs()).sum();
    let positions: Vec<DVec3> = consistent.iter().map(|t| t.position).collect();
    let off_err: f64 = model
        .values(&positions)
        .iter()
        .zip(&consistent)
        .map(|(v, t)| (v - t.target).abs())
        .sum();
    (on + off_err) / (valid.points.len() + consistent.len()) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::shapes::{sample_surface, torus};

    #[test]
    fn split_holds_out_about_one_in_holdout_and_covers_all() {
        let (t, v) = split(10_000, 5, 100_000);
        assert_eq!(t.len() + v.len(), 10_000);
        assert!((1800..2200).contains(&v.len()), "{}", v.len());
        let (t, v) = split(10_000, 5, 1000);
        assert!(t.len() + v.len() <= 1000);
    }

    #[test]
    fn validation_prefers_a_reasonable_c_over_extremes() {
        let pc = sample_surface(&torus(1.0, 0.35, 96, 48), 3000, 5);
        let sel = SelectionOptions {
            c_values: vec![0.002, 1.0],
            ..Default::default()
        };
        let s = select_parameters(
            &pc.positions,
            pc.normals.as_ref().unwrap(),
            &FitOptions::default(),
            &sel,
        )
        .unwrap();
        // C = 0.002·width cannot move f far from the offset b: large error.
        assert_eq!(s.c, 1.0, "{:?}", s.trials);
        assert!(
            s.trials[0].error > 5.0 * s.trials[1].error,
            "{:?}",
            s.trials
        );
    }
}
