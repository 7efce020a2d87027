//! Hermite implicit fit for sparse data such as curve networks: the
//! smoothest f (triharmonic kernel r³, a linear polynomial) with f = 0 at
//! every sample and ∇f = n where the sample has a normal.
//!
//! f(x) = Σ_j a_j φ(x − x_j) − Σ_j b_j·∇φ(x − x_j) + c + g·x, φ(v) = |v|³.
//! The kernel is global, so the zero set spans the gaps between curves
//! instead of shrinking onto them; unit normals make f approximate the
//! signed distance near the samples (negative inside). The interpolation
//! system is dense and symmetric: O(n²) memory and O(n³) time in the
//! sample count, so callers thin the samples first ([`MAX_SAMPLES`]).

use crate::error::{Result, SvmError};
use crate::mesh::Implicit;
use faer::linalg::solvers::Solve;
use faer::Mat;
use glam::DVec3;
use rayon::prelude::*;

/// The largest sample count [`HermiteFit::fit`] accepts: the system of
/// 4 unknowns per sample then holds ~8,000² entries (0.5 GB) and solves in
/// seconds.
pub const MAX_SAMPLES: usize = 2000;

/// One interpolation constraint: f(position) = 0, and ∇f = normal (unit,
/// outward) when given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HermiteSample {
    pub position: DVec3,
    pub normal: Option<DVec3>,
}

/// A fitted Hermite interpolant (see the module docs).
#[derive(Clone, Debug)]
pub struct HermiteFit {
    centres: Vec<DVec3>,
    /// Value coefficients a_j.
    value_weights: Vec<f64>,
    /// Gradient coefficients b_j (zero where the sample had no normal).
    gradient_weights: Vec<DVec3>,
    constant: f64,
    linear: DVec3,
    /// Data were moved by −`shift` and scaled by `scale` before fitting
    /// (conditioning); f is returned in data units.
    shift: DVec3,
    scale: f64,
}

impl HermiteFit {
    /// Fits the interpolant. `smoothing` ≥ 0 (in units of the normalized
    /// data, ~1e-4 is mild) lets the gradient constraints give way where
    /// normals disagree with each other; 0 interpolates them exactly.
    pub fn fit(samples: &[HermiteSample], smoothing: f64) -> Result<Self> {
        validate(samples, smoothing)?;
        let (shift, scale) = normalization(samples);
        let centres: Vec<DVec3> = samples
            .iter()
            .map(|s| (s.position - shift) * scale)
            .collect();
        let layout = Layout::new(samples);
        let matrix = assemble(&centres, &layout, smoothing);
        let rhs = Mat::from_fn(layout.size, 1, |row, _| {
            layout.right_hand_side(samples, row)
        });
        let solution = matrix.partial_piv_lu().solve(&rhs);
        let x = |row: usize| solution[(row, 0)];
        if (0..layout.size).any(|r| !x(r).is_finite()) {
            return Err(SvmError::InvalidInput(
                "the curve samples give a singular Hermite system (coincident samples with different normals?)"
                    .into(),
            ));
        }
        let gradient_weights = (0..samples.len())
            .map(|j| {
                layout.gradient_row[j].map_or(DVec3::ZERO, |r| DVec3::new(x(r), x(r + 1), x(r + 2)))
            })
            .collect();
        let p = layout.polynomial_row;
        Ok(HermiteFit {
            value_weights: (0..samples.len()).map(x).collect(),
            gradient_weights,
            constant: x(p),
            linear: DVec3::new(x(p + 1), x(p + 2), x(p + 3)),
            centres,
            shift,
            scale,
        })
    }

    /// f at `x`, in data units (≈ signed distance near the samples).
    pub fn value(&self, x: DVec3) -> f64 {
        let y = (x - self.shift) * self.scale;
        let f = self
            .terms(y)
            .fold(self.constant + self.linear.dot(y), |f, (v, r, a, b)| {
                f + r * (a * r * r - 3.0 * b.dot(v))
            });
        f / self.scale
    }

    /// ∇f at `x`.
    pub fn gradient(&self, x: DVec3) -> DVec3 {
        let y = (x - self.shift) * self.scale;
        // ∇φ = 3 r v, Hessian H = 3 (r I + v vᵀ / r) (0 at v = 0).
        self.terms(y).fold(self.linear, |g, (v, r, a, b)| {
            let hessian_b = if r > 0.0 {
                3.0 * (r * b + v * (v.dot(b) / r))
            } else {
                DVec3::ZERO
            };
            g + 3.0 * a * r * v - hessian_b
        })
    }

    /// Per centre, at normalized `y`: (y − centre, its length, a_j, b_j).
    fn terms(&self, y: DVec3) -> impl Iterator<Item = (DVec3, f64, f64, DVec3)> + '_ {
        self.centres
            .iter()
            .zip(&self.value_weights)
            .zip(&self.gradient_weights)
            .map(move |((c, a), b)| {
                let v = y - *c;
                (v, v.length(), *a, *b)
            })
    }

    /// Number of samples (kernel centres).
    pub fn sample_count(&self) -> usize {
        self.centres.len()
    }
}

impl Implicit for HermiteFit {
    fn values_grouped(&self, points: &[DVec3], _groups: &[Vec<u32>]) -> Vec<f64> {
        points.par_iter().map(|&p| self.value(p)).collect()
    }

    fn gradients(&self, points: &[DVec3]) -> Vec<DVec3> {
        points.par_iter().map(|&p| self.gradient(p)).collect()
    }
}

fn validate(samples: &[HermiteSample], smoothing: f64) -> Result<()> {
    if samples.len() < 4 {
        return Err(SvmError::InvalidInput(format!(
            "a Hermite fit needs at least 4 samples, got {}",
            samples.len()
        )));
    }
    if samples.len() > MAX_SAMPLES {
        return Err(SvmError::InvalidInput(format!(
            "a Hermite fit takes at most {MAX_SAMPLES} samples (dense system), got {}; thin the samples first",
            samples.len()
        )));
    }
    if !samples.iter().any(|s| s.normal.is_some()) {
        return Err(SvmError::InvalidInput(
            "a Hermite fit needs a normal at one sample at least (otherwise f = 0 fits)".into(),
        ));
    }
    let finite = |v: DVec3| v.is_finite();
    if let Some(i) = samples
        .iter()
        .position(|s| !finite(s.position) || s.normal.is_some_and(|n| !finite(n)))
    {
        return Err(SvmError::InvalidInput(format!("sample {i} is not finite")));
    }
    if !(smoothing.is_finite() && smoothing >= 0.0) {
        return Err(SvmError::InvalidParameter {
            name: "smoothing",
            message: format!("must be a finite number ≥ 0, got {smoothing}"),
        });
    }
    Ok(())
}

/// Centre and scale that map the samples into a box of unit diagonal.
fn normalization(samples: &[HermiteSample]) -> (DVec3, f64) {
    let (lo, hi) = samples.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), s| (lo.min(s.position), hi.max(s.position)),
    );
    let diagonal = (hi - lo).length();
    let scale = if diagonal > 0.0 { 1.0 / diagonal } else { 1.0 };
    (0.5 * (lo + hi), scale)
}

/// Where each unknown sits in the system: a_j at row j, then b_j (three
/// rows) for samples with normals, then the 4 polynomial coefficients.
struct Layout {
    gradient_row: Vec<Option<usize>>,
    polynomial_row: usize,
    size: usize,
}

impl Layout {
    fn new(samples: &[HermiteSample]) -> Self {
        let mut next = samples.len();
        let gradient_row = samples
            .iter()
            .map(|s| {
                s.normal.map(|_| {
                    next += 3;
                    next - 3
                })
            })
            .collect();
        Layout {
            gradient_row,
            polynomial_row: next,
            size: next + 4,
        }
    }

    /// What row `row` asks of f: 0 for values and side conditions, the
    /// normal's component for gradient rows.
    fn right_hand_side(&self, samples: &[HermiteSample], row: usize) -> f64 {
        if row < samples.len() || row >= self.polynomial_row {
            return 0.0;
        }
        let (j, axis) = self
            .gradient_row
            .iter()
            .enumerate()
            .find_map(|(j, r)| {
                r.filter(|&r| (r..r + 3).contains(&row))
                    .map(|r| (j, row - r))
            })
            .expect("every gradient row belongs to a sample");
        let n = samples[j]
            .normal
            .expect("gradient rows have normals")
            .normalize_or_zero();
        n[axis]
    }
}

/// The symmetric interpolation matrix [[K, P], [Pᵀ, 0]] (see the module
/// docs for the basis; rows of K are value and gradient constraints).
fn assemble(centres: &[DVec3], layout: &Layout, smoothing: f64) -> Mat<f64> {
    let mut m = Mat::<f64>::zeros(layout.size, layout.size);
    let n = centres.len();
    for i in 0..n {
        let gi = layout.gradient_row[i];
        for j in 0..n {
            let v = centres[i] - centres[j];
            let r = v.length();
            let grad = 3.0 * r * v;
            m[(i, j)] = r * r * r;
            if let Some(gj) = layout.gradient_row[j] {
                for k in 0..3 {
                    m[(i, gj + k)] = -grad[k];
                }
            }
            let Some(gi) = gi else { continue };
            for l in 0..3 {
                m[(gi + l, j)] = grad[l];
            }
            if let Some(gj) = layout.gradient_row[j] {
                for l in 0..3 {
                    for k in 0..3 {
                        let outer = if r > 0.0 { v[l] * v[k] / r } else { 0.0 };
                        let identity = if l == k { r } else { 0.0 };
                        m[(gi + l, gj + k)] = -3.0 * (identity + outer);
                    }
                }
            }
        }
        if let Some(gi) = gi {
            for l in 0..3 {
                m[(gi + l, gi + l)] += smoothing;
            }
        }
    }
    let p = layout.polynomial_row;
    for (i, c) in centres.iter().enumerate() {
        let row = [1.0, c.x, c.y, c.z];
        for (k, value) in row.into_iter().enumerate() {
            m[(i, p + k)] = value;
            m[(p + k, i)] = value;
        }
        if let Some(gi) = layout.gradient_row[i] {
            for l in 0..3 {
                m[(gi + l, p + 1 + l)] = 1.0;
                m[(p + 1 + l, gi + l)] = 1.0;
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere_samples(n: usize, radius: f64) -> Vec<HermiteSample> {
        // Points on a Fibonacci sphere with their radial normals.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let a = golden * i as f64;
                let d = DVec3::new(r * a.cos(), r * a.sin(), z);
                HermiteSample {
                    position: 2.0 * DVec3::ONE + radius * d,
                    normal: Some(d),
                }
            })
            .collect()
    }

    #[test]
    fn interpolates_values_and_normals() {
        let samples = sphere_samples(60, 1.5);
        let fit = HermiteFit::fit(&samples, 0.0).unwrap();
        for s in &samples {
            assert!(
                fit.value(s.position).abs() < 1e-8,
                "{}",
                fit.value(s.position)
            );
            let g = fit.gradient(s.position);
            assert!(g.distance(s.normal.unwrap()) < 1e-6, "{g}");
        }
    }

    #[test]
    fn sparse_sphere_samples_give_the_sphere() {
        let samples = sphere_samples(40, 1.0);
        let fit = HermiteFit::fit(&samples, 0.0).unwrap();
        let centre = 2.0 * DVec3::ONE;
        assert!(fit.value(centre) < -0.5, "inside: {}", fit.value(centre));
        // Between the samples f stays near the signed distance.
        for (i, d) in sphere_samples(500, 1.0).iter().enumerate() {
            let dir = d.normal.unwrap();
            for t in [-0.2, 0.0, 0.2] {
                let f = fit.value(centre + (1.0 + t) * dir);
                assert!((f - t).abs() < 0.03, "sample {i} offset {t}: f = {f}");
            }
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let fit = HermiteFit::fit(&sphere_samples(30, 1.0), 1e-4).unwrap();
        let x = DVec3::new(2.3, 1.6, 2.9);
        let h = 1e-6;
        let fd = DVec3::new(
            fit.value(x + h * DVec3::X) - fit.value(x - h * DVec3::X),
            fit.value(x + h * DVec3::Y) - fit.value(x - h * DVec3::Y),
            fit.value(x + h * DVec3::Z) - fit.value(x - h * DVec3::Z),
        ) / (2.0 * h);
        assert!(
            fit.gradient(x).distance(fd) < 1e-5,
            "{} vs {fd}",
            fit.gradient(x)
        );
    }

    #[test]
    fn bad_samples_are_refused() {
        let mut s = sphere_samples(10, 1.0);
        assert!(HermiteFit::fit(&s[..3], 0.0).is_err());
        s[4].position.x = f64::NAN;
        assert!(HermiteFit::fit(&s, 0.0).is_err());
        let no_normals: Vec<HermiteSample> = sphere_samples(10, 1.0)
            .into_iter()
            .map(|s| HermiteSample { normal: None, ..s })
            .collect();
        assert!(HermiteFit::fit(&no_normals, 0.0).is_err());
        assert!(HermiteFit::fit(&sphere_samples(10, 1.0), -1.0).is_err());
    }
}
