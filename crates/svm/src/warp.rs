//! Dense warp fields between two fitted shapes (the paper's Section 4).
//!
//! Each coordinate of the displacement is a kernel expansion,
//! t(x) = Σ_j w_j k(|x − c_j| / s) with w_j ∈ R³, fitted by minimizing
//!   ½ λ Σ|w_j|² + (C_corr / 2P) Σ_i |x_i + t(x_i) − z_i|²
//!             + (C_dist / 2N) Σ_s (f1(x_s) − f2(x_s + t(x_s)))²
//! over P feature-point pairs (x_i → z_i) and N sample points x_s on and
//! near the source surface (the integral of the paper, discretized). The
//! last term keeps signed distances: surface points go to the target
//! surface, off-surface points keep their distance. Solved by Gauss–Newton
//! (linearizing f2 along its gradient) with conjugate gradients on the
//! normal equations, level by level from wide to narrow kernels; each level
//! adds to the displacement of the coarser ones.

use crate::cells::CellIndex;
use crate::error::{require_non_negative, require_positive, Result, SvmError};
use crate::kernel::wu;
use crate::model::SvmModel;
use crate::training::box_representatives;
use glam::DVec3;
use rayon::prelude::*;

/// Parameters of the warp fit.
#[derive(Clone, Copy, Debug)]
pub struct WarpOptions {
    /// Widest kernel, relative to the diameter; each level halves it.
    pub coarsest: f64,
    pub levels: usize,
    /// Kernel centres: one sample per box of side cell_ratio · width.
    pub cell_ratio: f64,
    pub c_corr: f64,
    pub c_dist: f64,
    /// λ relative to the mean diagonal of the normal equations.
    pub ridge: f64,
    pub gauss_newton_steps: usize,
    pub cg_iterations: usize,
}

/// More levels than this make kernels narrower than any sampling reaches
/// (the 16th is 2^-16 of the diameter wide) and only cost time.
pub const MAX_WARP_LEVELS: usize = 16;

impl WarpOptions {
    /// Error unless every parameter lies in its range.
    pub fn validate(&self) -> Result<()> {
        require_positive("coarsest", self.coarsest)?;
        require_positive("cell_ratio", self.cell_ratio)?;
        require_non_negative("c_corr", self.c_corr)?;
        require_non_negative("c_dist", self.c_dist)?;
        require_non_negative("ridge", self.ridge)?;
        if !(1..=MAX_WARP_LEVELS).contains(&self.levels) {
            return Err(SvmError::InvalidParameter {
                name: "levels",
                message: format!(
                    "must be between 1 and {MAX_WARP_LEVELS}, got {}",
                    self.levels
                ),
            });
        }
        Ok(())
    }
}

impl Default for WarpOptions {
    fn default() -> Self {
        WarpOptions {
            coarsest: 0.5,
            levels: 4,
            cell_ratio: 0.5,
            c_corr: 100.0,
            c_dist: 1.0,
            ridge: 1e-6,
            gauss_newton_steps: 6,
            cg_iterations: 60,
        }
    }
}

/// Kernels of one width with vector coefficients.
pub struct WarpLevel {
    pub width: f64,
    pub centres: Vec<DVec3>,
    pub coefficients: Vec<DVec3>,
    index: CellIndex,
}

impl WarpLevel {
    fn displacement(&self, x: DVec3) -> DVec3 {
        let mut t = DVec3::ZERO;
        let s2 = self.width * self.width;
        self.index.for_each_candidate(x, |slot| {
            let j = self.index.order[slot] as usize;
            let d2 = self.centres[j].distance_squared(x);
            if d2 < s2 {
                t += self.coefficients[j] * wu(d2.sqrt() / self.width);
            }
        });
        t
    }
}

/// A fitted displacement field t: x ↦ x + t(x) maps source to target.
pub struct WarpField {
    pub levels: Vec<WarpLevel>,
}

impl WarpField {
    pub fn displacement(&self, x: DVec3) -> DVec3 {
        self.levels.iter().map(|l| l.displacement(x)).sum()
    }

    /// t at many points, in parallel.
    pub fn displacements(&self, points: &[DVec3]) -> Vec<DVec3> {
        points.par_iter().map(|&p| self.displacement(p)).collect()
    }
}

/// How the fit went, per level: the root-mean-square correspondence error
/// and the mean |f1(x) − f2(x + t(x))| over the samples at the end.
#[derive(Clone, Debug, PartialEq)]
pub struct WarpLevelReport {
    pub width: f64,
    pub centres: usize,
    pub correspondence_rms: f64,
    pub distance_mean: f64,
}

/// Fit the warp from the shape of `source` to that of `target`.
/// `samples`: points on and around the source surface; `pairs`: feature
/// correspondences (source point, target point); `diameter`: the length
/// the kernel widths refer to.
pub fn fit_warp(
    source: &SvmModel,
    target: &SvmModel,
    samples: &[DVec3],
    pairs: &[(DVec3, DVec3)],
    diameter: f64,
    opts: &WarpOptions,
) -> Result<(WarpField, Vec<WarpLevelReport>)> {
    require_positive("diameter", diameter)?;
    opts.validate()?;
    if samples.is_empty() && pairs.is_empty() {
        return Err(SvmError::InvalidInput(
            "a warp needs sample points or correspondences".into(),
        ));
    }
    if samples
        .iter()
        .chain(pairs.iter().flat_map(|p| [&p.0, &p.1]))
        .any(|p| !p.is_finite())
    {
        return Err(SvmError::InvalidInput(
            "non-finite sample or correspondence".into(),
        ));
    }
    let problem = Problem {
        source_values: source.values(samples),
        samples: samples.to_vec(),
        pairs: pairs.to_vec(),
        target,
        opts: *opts,
    };
    let mut field = WarpField { levels: Vec::new() };
    let mut reports = Vec::new();
    let mut width = opts.coarsest * diameter;
    for _ in 0..opts.levels {
        let (level, report) = problem.fit_level(&field, width);
        field.levels.push(level);
        reports.push(report);
        width /= 2.0;
    }
    Ok((field, reports))
}

struct Problem<'a> {
    samples: Vec<DVec3>,
    source_values: Vec<f64>,
    pairs: Vec<(DVec3, DVec3)>,
    target: &'a SvmModel,
    opts: WarpOptions,
}

/// Sparse kernel rows of evaluation points against one level's centres.
type Rows = Vec<Vec<(u32, f64)>>;

fn kernel_rows(points: &[DVec3], centres: &[DVec3], width: f64) -> Rows {
    let index = CellIndex::new(centres, width);
    points
        .par_iter()
        .map(|&p| {
            let mut row = Vec::new();
            index.for_each_candidate(p, |slot| {
                let j = index.order[slot];
                let v = wu(centres[j as usize].distance(p) / width);
                if v > 0.0 {
                    row.push((j, v));
                }
            });
            row.sort_unstable_by_key(|e| e.0);
            row
        })
        .collect()
}

fn apply(rows: &Rows, w: &[DVec3]) -> Vec<DVec3> {
    rows.par_iter()
        .map(|r| r.iter().map(|&(j, k)| w[j as usize] * k).sum())
        .collect()
}

impl Problem<'_> {
    fn centres(&self, width: f64) -> Vec<DVec3> {
        let mut centres: Vec<DVec3> = if self.samples.is_empty() {
            Vec::new()
        } else {
            let origin = self
                .samples
                .iter()
                .copied()
                .fold(DVec3::INFINITY, DVec3::min);
            box_representatives(&self.samples, origin, self.opts.cell_ratio * width)
                .into_iter()
                .map(|(i, _)| self.samples[i])
                .collect()
        };
        // A centre at every feature point lets narrow levels pin it exactly.
        centres.extend(self.pairs.iter().map(|p| p.0));
        centres
    }

    fn fit_level(&self, field: &WarpField, width: f64) -> (WarpLevel, WarpLevelReport) {
        let centres = self.centres(width);
        let corr_points: Vec<DVec3> = self.pairs.iter().map(|p| p.0).collect();
        let sample_rows = kernel_rows(&self.samples, &centres, width);
        let corr_rows = kernel_rows(&corr_points, &centres, width);
        let base_samples: Vec<DVec3> = field
            .displacements(&self.samples)
            .iter()
            .zip(&self.samples)
            .map(|(t, x)| *x + *t)
            .collect();
        let base_corr: Vec<DVec3> = field
            .displacements(&corr_points)
            .iter()
            .zip(&corr_points)
            .map(|(t, x)| *x + *t)
            .collect();
        let weights = (
            self.opts.c_corr / self.pairs.len().max(1) as f64,
            self.opts.c_dist / self.samples.len().max(1) as f64,
        );
        let mut w = vec![DVec3::ZERO; centres.len()];
        for _ in 0..self.opts.gauss_newton_steps {
            let moved_s = add(&base_samples, &apply(&sample_rows, &w));
            let moved_c = add(&base_corr, &apply(&corr_rows, &w));
            let f2 = self.target.values(&moved_s);
            let g2 = self.target.gradients(&moved_s);
            let sys = Normal {
                sample_rows: &sample_rows,
                corr_rows: &corr_rows,
                gradients: &g2,
                weights,
                n: centres.len(),
                lambda: 0.0,
            };
            let lambda = self.opts.ridge * sys.mean_diagonal().max(1e-300);
            let sys = Normal { lambda, ..sys };
            let r_corr: Vec<DVec3> = moved_c
                .iter()
                .zip(&self.pairs)
                .map(|(m, p)| *m - p.1)
                .collect();
            let r_dist: Vec<f64> = f2
                .iter()
                .zip(&self.source_values)
                .map(|(a, b)| a - b)
                .collect();
            let mut rhs = sys.transpose_apply(&r_corr, &r_dist);
            for (r, wj) in rhs.iter_mut().zip(&w) {
                *r = -(*r + *wj * lambda);
            }
            let step = conjugate_gradient(&sys, &rhs, self.opts.cg_iterations);
            for (wj, s) in w.iter_mut().zip(step) {
                *wj += s;
            }
        }
        let moved_s = add(&base_samples, &apply(&sample_rows, &w));
        let moved_c = add(&base_corr, &apply(&corr_rows, &w));
        let report = WarpLevelReport {
            width,
            centres: centres.len(),
            correspondence_rms: rms(moved_c
                .iter()
                .zip(&self.pairs)
                .map(|(m, p)| m.distance(p.1))),
            distance_mean: mean(
                self.target
                    .values(&moved_s)
                    .iter()
                    .zip(&self.source_values)
                    .map(|(a, b)| (a - b).abs()),
            ),
        };
        let index = CellIndex::new(&centres, width);
        (
            WarpLevel {
                width,
                centres,
                coefficients: w,
                index,
            },
            report,
        )
    }
}

fn add(a: &[DVec3], b: &[DVec3]) -> Vec<DVec3> {
    a.iter().zip(b).map(|(x, y)| *x + *y).collect()
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

/// The Gauss–Newton normal equations (JᵀWJ + λI) δ = b, matrix-free.
struct Normal<'a> {
    sample_rows: &'a Rows,
    corr_rows: &'a Rows,
    /// ∇f2 at the moved samples: the linearization of the distance term.
    gradients: &'a [DVec3],
    /// (correspondence, distance) weights.
    weights: (f64, f64),
    n: usize,
    lambda: f64,
}

impl Normal<'_> {
    /// Jᵀ W r for correspondence residuals (vectors) and distance residuals.
    fn transpose_apply(&self, r_corr: &[DVec3], r_dist: &[f64]) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; self.n];
        for (row, r) in self.corr_rows.iter().zip(r_corr) {
            for &(j, k) in row {
                out[j as usize] += *r * (k * self.weights.0);
            }
        }
        for ((row, r), g) in self.sample_rows.iter().zip(r_dist).zip(self.gradients) {
            for &(j, k) in row {
                out[j as usize] += *g * (k * r * self.weights.1);
            }
        }
        out
    }

    fn apply(&self, d: &[DVec3]) -> Vec<DVec3> {
        let jc = apply(self.corr_rows, d);
        let js: Vec<f64> = self
            .sample_rows
            .par_iter()
            .zip(self.gradients)
            .map(|(row, g)| row.iter().map(|&(j, k)| k * g.dot(d[j as usize])).sum())
            .collect();
        let mut out = self.transpose_apply(&jc, &js);
        for (o, x) in out.iter_mut().zip(d) {
            *o += *x * self.lambda;
        }
        out
    }

    /// Mean over centres of the diagonal of JᵀWJ (per coordinate).
    fn mean_diagonal(&self) -> f64 {
        let mut diag = vec![0.0; self.n];
        for row in self.corr_rows {
            for &(j, k) in row {
                diag[j as usize] += k * k * self.weights.0;
            }
        }
        for (row, g) in self.sample_rows.iter().zip(self.gradients) {
            for &(j, k) in row {
                diag[j as usize] += k * k * g.length_squared() / 3.0 * self.weights.1;
            }
        }
        mean(diag.into_iter())
    }
}

fn dot(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(*y)).sum()
}

/// Conjugate gradients from zero for the symmetric positive definite system.
fn conjugate_gradient(sys: &Normal, b: &[DVec3], iterations: usize) -> Vec<DVec3> {
    let mut x = vec![DVec3::ZERO; b.len()];
    let mut r = b.to_vec();
    let mut p = r.clone();
    let mut rr = dot(&r, &r);
    let stop = rr * 1e-20;
    for _ in 0..iterations {
        if rr <= stop || rr == 0.0 {
            break;
        }
        let ap = sys.apply(&p);
        let pap = dot(&p, &ap);
        if pap.is_nan() || pap <= 0.0 {
            break;
        }
        let alpha = rr / pap;
        for i in 0..x.len() {
            x[i] += p[i] * alpha;
            r[i] -= ap[i] * alpha;
        }
        let rr_new = dot(&r, &r);
        let beta = rr_new / rr;
        for i in 0..p.len() {
            p[i] = r[i] + p[i] * beta;
        }
        rr = rr_new;
    }
    x
}
