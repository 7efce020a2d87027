//! Support-vector regression with a fixed offset, solved by coordinate
//! descent over a sparse kernel matrix.
//!
//! With the offset folded into the targets t_i = y_i − b, the ε-insensitive
//! dual in β = α − α* is
//!   minimize ½ βᵀKβ − Σ β_i t_i + ε Σ |β_i|   subject to |β_i| ≤ C.
//! One coordinate at a time, with g = Σ_{j≠i} K_ij β_j − t_i, the exact
//! minimizer is the soft threshold β_i = −sign(g) max(|g| − ε, 0) / K_ii,
//! clipped to [−C, C]. The squared-loss option (kernel ridge regression,
//! ½ βᵀ(K + I/C)β − βᵀt, unconstrained) uses β_i = −g / (K_ii + 1/C).

use crate::kernel::KernelMatrix;

/// Which penalty the fit puts on residuals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Loss {
    /// The paper's loss: residuals under ε are free, larger ones cost
    /// linearly, so single outliers have bounded influence (|β| ≤ C).
    #[default]
    EpsilonInsensitive,
    /// Least squares with ridge 1/C: for comparison, not robust to outliers.
    Squared,
}

/// Parameters of one regression solve.
#[derive(Clone, Copy, Debug)]
pub struct RegressionParams {
    pub loss: Loss,
    /// Box constraint (ε-insensitive) or inverse ridge (squared loss).
    pub c: f64,
    /// Width of the insensitive tube (ignored by the squared loss).
    pub epsilon: f64,
    /// Stop when no sweep changes any K_ii β_i by more than this.
    pub tolerance: f64,
    pub max_sweeps: usize,
}

/// Coefficients and how the solve went.
#[derive(Clone, Debug)]
pub struct RegressionResult {
    pub coefficients: Vec<f64>,
    pub sweeps: usize,
    /// Largest change of a K_ii β_i in the last sweep.
    pub last_change: f64,
}

/// Minimize the dual for `targets` (already offset-corrected) over `k`,
/// starting from β = 0. Sweeps are Gauss–Seidel in row order, so the
/// result is deterministic; callers order rows spatially for locality.
pub fn solve(k: &KernelMatrix, targets: &[f64], params: &RegressionParams) -> RegressionResult {
    solve_weighted(k, targets, params, &vec![1.0; k.rows()])
}

/// [`solve`] with a weight per point: point i gets C_i = C · w_i (a sample
/// weight on its loss term; w_i > 0).
pub fn solve_weighted(
    k: &KernelMatrix,
    targets: &[f64],
    params: &RegressionParams,
    weights: &[f64],
) -> RegressionResult {
    let n = k.rows();
    let mut beta = vec![0.0; n];
    let mut sweeps = 0;
    let mut last_change = 0.0;
    while sweeps < params.max_sweeps {
        sweeps += 1;
        last_change = sweep(k, targets, params, weights, &mut beta);
        if last_change <= params.tolerance {
            break;
        }
    }
    RegressionResult {
        coefficients: beta,
        sweeps,
        last_change,
    }
}

/// One pass over all coordinates; returns the largest change of K_ii β_i.
fn sweep(
    k: &KernelMatrix,
    targets: &[f64],
    p: &RegressionParams,
    weights: &[f64],
    beta: &mut [f64],
) -> f64 {
    let mut max_change: f64 = 0.0;
    for i in 0..beta.len() {
        let (cols, vals) = k.row(i);
        let kii = k.diagonal[i];
        if kii <= 0.0 {
            continue;
        }
        let mut g = -targets[i];
        for (&j, &v) in cols.iter().zip(vals) {
            g += v * beta[j as usize];
        }
        g -= kii * beta[i];
        let new = update(g, kii, p, p.c * weights[i]);
        max_change = max_change.max(((new - beta[i]) * kii).abs());
        beta[i] = new;
    }
    max_change
}

/// The exact one-coordinate minimizer given g = Σ_{j≠i} K_ij β_j − t_i
/// and this point's C.
#[inline]
fn update(g: f64, kii: f64, p: &RegressionParams, c: f64) -> f64 {
    match p.loss {
        Loss::EpsilonInsensitive => {
            let shrunk = (g.abs() - p.epsilon).max(0.0) / kii;
            (-g.signum() * shrunk).clamp(-c, c)
        }
        Loss::Squared => -g / (kii + 1.0 / c),
    }
}

/// The dual objective ½βᵀKβ − βᵀt + ε|β|₁ (ε-insensitive) or
/// ½βᵀ(K + I/C)β − βᵀt (squared); used by tests to check optimality.
pub fn objective(k: &KernelMatrix, targets: &[f64], p: &RegressionParams, beta: &[f64]) -> f64 {
    let kb = k.multiply(beta);
    let quad: f64 = beta.iter().zip(&kb).map(|(b, kb)| 0.5 * b * kb).sum();
    let lin: f64 = beta.iter().zip(targets).map(|(b, t)| b * t).sum();
    match p.loss {
        Loss::EpsilonInsensitive => {
            quad - lin + p.epsilon * beta.iter().map(|b| b.abs()).sum::<f64>()
        }
        Loss::Squared => quad - lin + 0.5 / p.c * beta.iter().map(|b| b * b).sum::<f64>(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    fn problem(n: usize, seed: u64) -> (Vec<DVec3>, Vec<f64>) {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let pts: Vec<DVec3> = (0..n)
            .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let t = pts.iter().map(|p| (3.0 * p.x).sin() + p.y * p.z).collect();
        (pts, t)
    }

    fn params(loss: Loss, c: f64, epsilon: f64) -> RegressionParams {
        RegressionParams {
            loss,
            c,
            epsilon,
            tolerance: 1e-12,
            max_sweeps: 5000,
        }
    }

    /// No single-coordinate move (nor a small random move) lowers the
    /// objective: the solve reached the constrained minimum.
    #[test]
    fn epsilon_insensitive_solution_is_optimal_and_feasible() {
        let (pts, t) = problem(200, 3);
        let k = KernelMatrix::build(&pts, 0.35);
        let p = params(Loss::EpsilonInsensitive, 0.8, 0.05);
        let r = solve(&k, &t, &p);
        assert!(
            r.last_change <= 1e-12,
            "did not converge: {}",
            r.last_change
        );
        assert!(r.coefficients.iter().all(|b| b.abs() <= 0.8 + 1e-15));
        let best = objective(&k, &t, &p, &r.coefficients);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        for _ in 0..200 {
            let mut b = r.coefficients.clone();
            let i = rng.random_range(0..b.len());
            b[i] = (b[i] + rng.random_range(-0.05..0.05)).clamp(-0.8, 0.8);
            assert!(objective(&k, &t, &p, &b) >= best - 1e-10);
        }
        // KKT: fitted values within ε of the targets where |β| < C and β ≠ 0
        // means exactly on the tube boundary.
        let f = k.multiply(&r.coefficients);
        for i in 0..t.len() {
            let b = r.coefficients[i];
            if b == 0.0 {
                assert!((f[i] - t[i]).abs() <= 0.05 + 1e-8);
            } else if b.abs() < 0.8 - 1e-9 {
                assert!(((f[i] - t[i]).abs() - 0.05).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn squared_loss_solves_the_ridge_system() {
        let (pts, t) = problem(150, 4);
        let k = KernelMatrix::build(&pts, 0.3);
        let c = 10.0;
        let r = solve(&k, &t, &params(Loss::Squared, c, 0.0));
        let kb = k.multiply(&r.coefficients);
        for i in 0..t.len() {
            let resid = kb[i] + r.coefficients[i] / c - t[i];
            assert!(resid.abs() < 1e-9, "row {i}: {resid}");
        }
    }

    #[test]
    fn box_constraint_bounds_an_outlier() {
        // One far target among zeros: its coefficient saturates at C.
        let pts: Vec<DVec3> = (0..10)
            .map(|i| DVec3::new(i as f64 * 0.1, 0.0, 0.0))
            .collect();
        let mut t = vec![0.0; 10];
        t[5] = 100.0;
        let k = KernelMatrix::build(&pts, 0.25);
        let r = solve(&k, &t, &params(Loss::EpsilonInsensitive, 0.5, 0.01));
        assert!((r.coefficients[5] - 0.5).abs() < 1e-12);
        let f = k.multiply(&r.coefficients);
        assert!(f.iter().all(|v| v.abs() <= 1.0));
    }
}
