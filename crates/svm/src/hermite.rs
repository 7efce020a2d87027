//! Hermite implicit fit for sparse data such as curve networks: the
//! smoothest f (triharmonic kernel r³, a linear polynomial) with f = 0 at
//! every surface sample (or the value asked for, inside or outside) and
//! ∇f = n where the sample has a normal.
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
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// The largest sample count [`HermiteFit::fit`] accepts: the system of
/// 4 unknowns per sample then holds ~8,000² entries (0.5 GB) and solves in
/// seconds.
pub const MAX_SAMPLES: usize = 2000;

/// One interpolation constraint: f(position) = value, and what is known
/// of ∇f there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HermiteSample {
    pub position: DVec3,
    /// 0 on the surface; negative inside (≈ minus the depth), positive
    /// outside.
    pub value: f64,
    pub gradient: Gradient,
}

impl HermiteSample {
    /// A sample on the surface (f = 0).
    pub fn on_surface(position: DVec3, gradient: Gradient) -> Self {
        HermiteSample {
            position,
            value: 0.0,
            gradient,
        }
    }
}

/// What a sample says about ∇f.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gradient {
    /// Nothing: the smoothest interpolant decides.
    Free,
    /// ∇f = the unit outward normal (normalized if it is not unit).
    Normal(DVec3),
    /// ∇f·direction = value (direction unit): one component only, e.g. the
    /// in-plane part of the normal on a planar section.
    Component { direction: DVec3, value: f64 },
}

impl Gradient {
    /// The derivative constraints: (unit direction, value) pairs.
    fn rows(self) -> impl Iterator<Item = (DVec3, f64)> {
        let (rows, count) = match self {
            Gradient::Free => ([(DVec3::ZERO, 0.0); 3], 0),
            Gradient::Normal(n) => {
                let n = n.normalize_or_zero();
                ([(DVec3::X, n.x), (DVec3::Y, n.y), (DVec3::Z, n.z)], 3)
            }
            Gradient::Component { direction, value } => {
                let d = direction.normalize_or_zero();
                ([(d, value), (DVec3::ZERO, 0.0), (DVec3::ZERO, 0.0)], 1)
            }
        };
        rows.into_iter().take(count)
    }

    fn is_finite(self) -> bool {
        match self {
            Gradient::Free => true,
            Gradient::Normal(n) => n.is_finite(),
            Gradient::Component { direction, value } => direction.is_finite() && value.is_finite(),
        }
    }
}

/// A fitted Hermite interpolant (see the module docs).
#[derive(Clone, Debug)]
pub struct HermiteFit {
    centres: Vec<DVec3>,
    /// Value coefficients a_j.
    value_weights: Vec<f64>,
    /// Gradient coefficients b_j: the sum of each derivative row's
    /// coefficient times its direction (zero at free samples).
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
        let layout = Layout::new(samples, scale);
        let matrix = assemble(&centres, &layout, smoothing);
        let rhs = Mat::from_fn(layout.size, 1, |row, _| layout.right_hand_side(row));
        let solution = matrix.partial_piv_lu().solve(&rhs);
        let x = |row: usize| solution[(row, 0)];
        if (0..layout.size).any(|r| !x(r).is_finite()) {
            return Err(SvmError::InvalidInput(
                "the curve samples give a singular Hermite system (coincident samples with different normals?)"
                    .into(),
            ));
        }
        let mut gradient_weights = vec![DVec3::ZERO; samples.len()];
        for (k, row) in layout.derivatives.iter().enumerate() {
            gradient_weights[row.sample] += row.direction * x(samples.len() + k);
        }
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
        self.terms(y).fold(self.linear, |g, (v, r, a, b)| {
            g + 3.0 * a * r * v - hessian(v, r) * b
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

/// The Hessian of φ = |v|³: 3 (r I + v vᵀ / r), 0 at v = 0.
fn hessian(v: DVec3, r: f64) -> DMat3 {
    if r > 0.0 {
        3.0 * (DMat3::from_diagonal(DVec3::splat(r))
            + DMat3::from_cols(v * v.x, v * v.y, v * v.z) / r)
    } else {
        DMat3::ZERO
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
    if !samples
        .iter()
        .any(|s| s.value != 0.0 || s.gradient.rows().any(|(_, value)| value != 0.0))
    {
        return Err(SvmError::InvalidInput(
            "a Hermite fit needs a nonzero gradient or value at one sample at least (otherwise f = 0 fits)"
                .into(),
        ));
    }
    if let Some(i) = samples
        .iter()
        .position(|s| !s.position.is_finite() || !s.value.is_finite() || !s.gradient.is_finite())
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

/// One derivative constraint: ∇f(sample)·direction = target.
struct DerivativeRow {
    sample: usize,
    direction: DVec3,
    target: f64,
}

/// Where each unknown sits in the system: a_j at row j, then one row per
/// derivative constraint, then the 4 polynomial coefficients.
struct Layout {
    values: usize,
    /// f asked for at each sample (normalized units).
    value_targets: Vec<f64>,
    derivatives: Vec<DerivativeRow>,
    polynomial_row: usize,
    size: usize,
}

impl Layout {
    /// `scale`: the normalization's, which values (not unit gradients)
    /// scale with.
    fn new(samples: &[HermiteSample], scale: f64) -> Self {
        let derivatives: Vec<DerivativeRow> = samples
            .iter()
            .enumerate()
            .flat_map(|(sample, s)| {
                s.gradient
                    .rows()
                    .map(move |(direction, target)| DerivativeRow {
                        sample,
                        direction,
                        target,
                    })
            })
            .collect();
        let polynomial_row = samples.len() + derivatives.len();
        Layout {
            values: samples.len(),
            value_targets: samples.iter().map(|s| s.value * scale).collect(),
            derivatives,
            polynomial_row,
            size: polynomial_row + 4,
        }
    }

    /// What row `row` asks of f: the sample's value for value rows, the
    /// target for derivative rows, 0 for the side conditions.
    fn right_hand_side(&self, row: usize) -> f64 {
        match row.checked_sub(self.values) {
            None => self.value_targets[row],
            Some(k) if k < self.derivatives.len() => self.derivatives[k].target,
            _ => 0.0,
        }
    }
}

/// The symmetric interpolation matrix [[K, P], [Pᵀ, 0]] (see the module
/// docs for the basis; rows of K are value and derivative constraints).
fn assemble(centres: &[DVec3], layout: &Layout, smoothing: f64) -> Mat<f64> {
    let mut m = Mat::<f64>::zeros(layout.size, layout.size);
    let n = layout.values;
    let rows = &layout.derivatives;
    for i in 0..n {
        for j in 0..n {
            let r = centres[i].distance(centres[j]);
            m[(i, j)] = r * r * r;
        }
        for (k, d) in rows.iter().enumerate() {
            let v = centres[i] - centres[d.sample];
            let slope = -3.0 * v.length() * v.dot(d.direction);
            m[(i, n + k)] = slope;
            m[(n + k, i)] = slope;
        }
    }
    for (k, dk) in rows.iter().enumerate() {
        for (l, dl) in rows.iter().enumerate() {
            let v = centres[dk.sample] - centres[dl.sample];
            m[(n + k, n + l)] = -dk.direction.dot(hessian(v, v.length()) * dl.direction);
        }
        m[(n + k, n + k)] += smoothing;
    }
    let p = layout.polynomial_row;
    for (i, c) in centres.iter().enumerate() {
        for (k, value) in [1.0, c.x, c.y, c.z].into_iter().enumerate() {
            m[(i, p + k)] = value;
            m[(p + k, i)] = value;
        }
    }
    for (k, d) in rows.iter().enumerate() {
        for (l, value) in d.direction.to_array().into_iter().enumerate() {
            m[(n + k, p + 1 + l)] = value;
            m[(p + 1 + l, n + k)] = value;
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
                HermiteSample::on_surface(2.0 * DVec3::ONE + radius * d, Gradient::Normal(d))
            })
            .collect()
    }

    fn normal(s: &HermiteSample) -> DVec3 {
        match s.gradient {
            Gradient::Normal(n) => n,
            _ => panic!("sphere samples have normals"),
        }
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
            assert!(g.distance(normal(s)) < 1e-6, "{g}");
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
            let dir = normal(d);
            for t in [-0.2, 0.0, 0.2] {
                let f = fit.value(centre + (1.0 + t) * dir);
                assert!((f - t).abs() < 0.03, "sample {i} offset {t}: f = {f}");
            }
        }
    }

    #[test]
    fn in_plane_components_alone_give_the_sphere() {
        // Only the part of the normal within horizontal planes, as sections
        // by z-planes give it (samples near the poles carry little).
        let samples: Vec<HermiteSample> = sphere_samples(80, 1.0)
            .iter()
            .map(|s| {
                let n = normal(s);
                let m = DVec3::new(n.x, n.y, 0.0).normalize();
                HermiteSample::on_surface(
                    s.position,
                    Gradient::Component {
                        direction: m,
                        value: n.dot(m),
                    },
                )
            })
            .collect();
        let fit = HermiteFit::fit(&samples, 0.0).unwrap();
        for s in &samples {
            let Gradient::Component { direction, value } = s.gradient else {
                unreachable!()
            };
            assert!(fit.value(s.position).abs() < 1e-8);
            assert!((fit.gradient(s.position).dot(direction) - value).abs() < 1e-6);
        }
        let centre = 2.0 * DVec3::ONE;
        for d in sphere_samples(300, 1.0) {
            let f = fit.value(centre + 1.1 * normal(&d));
            assert!((f - 0.1).abs() < 0.03, "f = {f} at 0.1 outside");
        }
    }

    #[test]
    fn interior_values_are_interpolated_in_data_units() {
        // The sphere of radius 1.5 plus its centre asked to lie 1.5 deep:
        // f keeps the signed distance there, in the data's units.
        let mut samples = sphere_samples(40, 1.5);
        let centre = 2.0 * DVec3::ONE;
        samples.push(HermiteSample {
            position: centre,
            value: -1.5,
            gradient: Gradient::Free,
        });
        let fit = HermiteFit::fit(&samples, 0.0).unwrap();
        assert!(
            (fit.value(centre) + 1.5).abs() < 1e-8,
            "{}",
            fit.value(centre)
        );
        for s in &samples[..40] {
            assert!(fit.value(s.position).abs() < 1e-8);
        }
        // Halfway in, f lies between the surface's and the centre's (the
        // smoothest interpolant, not exactly the distance).
        let halfway = fit.value(centre + 0.75 * DVec3::X);
        assert!(
            (-1.0..-0.6).contains(&halfway),
            "f = {halfway} at depth 0.75"
        );
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
            .map(|s| HermiteSample {
                gradient: Gradient::Free,
                ..s
            })
            .collect();
        assert!(HermiteFit::fit(&no_normals, 0.0).is_err());
        assert!(HermiteFit::fit(&sphere_samples(10, 1.0), -1.0).is_err());
    }
}
