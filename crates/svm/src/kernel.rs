//! The Wu function: a compactly supported, C² radial kernel, and the sparse
//! kernel matrix it induces over a set of centres.
//!
//! The paper writes k(r) = (1 − r)₊⁴ (4 + 16r + 12r² + 3r³) with r = |x − c|/s,
//! so k(0) = 4. We divide by 4 so that k(0) = 1: a coefficient then equals
//! the function value its kernel adds at its own centre, which makes the box
//! constraint C (a bound on the coefficients) read in distance units. This
//! only rescales the paper's coefficients and C by 4.

use crate::cells::CellIndex;
use glam::DVec3;
use rayon::prelude::*;

/// k(r) for r = distance / width; zero for r ≥ 1, k(0) = 1.
#[inline]
pub fn wu(r: f64) -> f64 {
    if r >= 1.0 {
        return 0.0;
    }
    let t = 1.0 - r;
    let t2 = t * t;
    t2 * t2 * (4.0 + r * (16.0 + r * (12.0 + 3.0 * r))) * 0.25
}

/// k'(r) / r, finite at r = 0 (k'(r) = −7/4 · r (1 − r)³ (8 + 9r + 3r²)).
#[inline]
pub fn wu_slope_over_r(r: f64) -> f64 {
    if r >= 1.0 {
        return 0.0;
    }
    let t = 1.0 - r;
    -1.75 * t * t * t * (8.0 + r * (9.0 + 3.0 * r))
}

/// d/dr of [`wu_slope_over_r`]: 105/4 · (1 − r)² (1 + r)².
#[inline]
pub fn wu_slope_over_r_derivative(r: f64) -> f64 {
    if r >= 1.0 {
        return 0.0;
    }
    let a = (1.0 - r) * (1.0 + r);
    26.25 * a * a
}

/// Value of a kernel of width `s` centred at `c`, evaluated at `x`.
#[inline]
pub fn kernel_value(x: DVec3, c: DVec3, s: f64) -> f64 {
    wu(x.distance(c) / s)
}

/// Gradient with respect to `x` of the kernel of width `s` centred at `c`.
#[inline]
pub fn kernel_gradient(x: DVec3, c: DVec3, s: f64) -> DVec3 {
    let d = x - c;
    let r = d.length() / s;
    d * (wu_slope_over_r(r) / (s * s))
}

/// Hessian with respect to `x` (rows) of the kernel of width `s` at `c`:
/// H = [g(r) I + r g'(r) û ûᵀ] / s², g = k'(r)/r, û = (x − c)/|x − c|.
pub fn kernel_hessian(x: DVec3, c: DVec3, s: f64) -> [DVec3; 3] {
    let d = x - c;
    let len = d.length();
    let r = len / s;
    if r >= 1.0 {
        return [DVec3::ZERO; 3];
    }
    let g = wu_slope_over_r(r) / (s * s);
    // r g'(r) û ûᵀ = g'(r) d dᵀ / (len s): finite as len → 0.
    let w = if len > 0.0 {
        wu_slope_over_r_derivative(r) / (len * s * s * s)
    } else {
        0.0
    };
    [
        DVec3::new(g, 0.0, 0.0) + d * (w * d.x),
        DVec3::new(0.0, g, 0.0) + d * (w * d.y),
        DVec3::new(0.0, 0.0, g) + d * (w * d.z),
    ]
}

/// Sparse symmetric kernel matrix K_ij = k(|x_i − x_j| / s) in compressed
/// rows; row i lists every j within the support, including i itself.
#[derive(Clone, Debug, Default)]
pub struct KernelMatrix {
    /// Row i occupies `cols[row_start[i]..row_start[i + 1]]`.
    pub row_start: Vec<usize>,
    pub cols: Vec<u32>,
    pub values: Vec<f64>,
    /// K_ii (always k(0) = 1 for distinct-free rows, kept for clarity).
    pub diagonal: Vec<f64>,
}

impl KernelMatrix {
    /// Build the matrix over `centres` for width `s`; rows are found with a
    /// fixed-radius cell index and built in parallel (the result does not
    /// depend on the thread count: each row is sorted by column).
    pub fn build(centres: &[DVec3], s: f64) -> KernelMatrix {
        let index = CellIndex::new(centres, s);
        let inv = 1.0 / s;
        let rows: Vec<Vec<(u32, f64)>> = centres
            .par_iter()
            .map(|&c| {
                let mut row: Vec<(u32, f64)> = Vec::new();
                index.for_each_candidate(c, |slot| {
                    let j = index.order[slot];
                    let v = wu(centres[j as usize].distance(c) * inv);
                    if v > 0.0 {
                        row.push((j, v));
                    }
                });
                row.sort_unstable_by_key(|&(j, _)| j);
                row
            })
            .collect();
        Self::from_rows(rows)
    }

    fn from_rows(rows: Vec<Vec<(u32, f64)>>) -> KernelMatrix {
        let total = rows.iter().map(Vec::len).sum();
        let mut m = KernelMatrix {
            row_start: Vec::with_capacity(rows.len() + 1),
            cols: Vec::with_capacity(total),
            values: Vec::with_capacity(total),
            diagonal: Vec::with_capacity(rows.len()),
        };
        m.row_start.push(0);
        for (i, row) in rows.into_iter().enumerate() {
            let mut diag = 0.0;
            for (j, v) in row {
                if j as usize == i {
                    diag = v;
                }
                m.cols.push(j);
                m.values.push(v);
            }
            m.diagonal.push(diag);
            m.row_start.push(m.cols.len());
        }
        m
    }

    pub fn rows(&self) -> usize {
        self.diagonal.len()
    }

    pub fn nonzeros(&self) -> usize {
        self.cols.len()
    }

    /// Row i as (columns, values).
    #[inline]
    pub fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.row_start[i]..self.row_start[i + 1];
        (&self.cols[r.clone()], &self.values[r])
    }

    /// K · x.
    pub fn multiply(&self, x: &[f64]) -> Vec<f64> {
        (0..self.rows())
            .into_par_iter()
            .map(|i| {
                let (cols, vals) = self.row(i);
                cols.iter()
                    .zip(vals)
                    .map(|(&j, &v)| v * x[j as usize])
                    .sum()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wu_matches_the_paper_up_to_a_factor_four() {
        for i in 0..=20 {
            let r = i as f64 / 20.0;
            let paper = (1.0 - r).powi(4) * (4.0 + 16.0 * r + 12.0 * r * r + 3.0 * r.powi(3));
            assert!((4.0 * wu(r) - paper).abs() < 1e-12);
        }
        assert_eq!(wu(1.0), 0.0);
        assert_eq!(wu(1.5), 0.0);
        assert_eq!(wu(0.0), 1.0);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let h = 1e-6;
        for i in 1..20 {
            let r = i as f64 / 20.0;
            let fd = (wu(r + h) - wu(r - h)) / (2.0 * h);
            assert!((fd - r * wu_slope_over_r(r)).abs() < 1e-7, "r={r}");
            let g = |r: f64| wu_slope_over_r(r);
            let fd2 = (g(r + h) - g(r - h)) / (2.0 * h);
            assert!((fd2 - wu_slope_over_r_derivative(r)).abs() < 1e-6);
        }
        let c = DVec3::new(0.1, -0.2, 0.3);
        let x = DVec3::new(0.35, 0.05, 0.1);
        let s = 0.7;
        let grad = kernel_gradient(x, c, s);
        let hess = kernel_hessian(x, c, s);
        for a in 0..3 {
            let e = DVec3::AXES[a] * h;
            let fd = (kernel_value(x + e, c, s) - kernel_value(x - e, c, s)) / (2.0 * h);
            assert!((fd - grad[a]).abs() < 1e-7);
            let fdg = (kernel_gradient(x + e, c, s) - kernel_gradient(x - e, c, s)) / (2.0 * h);
            assert!((fdg - hess[a]).length() < 1e-6);
        }
    }

    #[test]
    fn kernel_matrix_matches_brute_force_and_is_symmetric() {
        let pts: Vec<DVec3> = (0..300)
            .map(|i| {
                let t = i as f64;
                DVec3::new((t * 0.37).sin(), (t * 0.71).cos(), (t * 0.13).sin())
            })
            .collect();
        let s = 0.4;
        let k = KernelMatrix::build(&pts, s);
        for i in 0..pts.len() {
            let (cols, vals) = k.row(i);
            let mut dense = vec![0.0; pts.len()];
            for (&j, &v) in cols.iter().zip(vals) {
                dense[j as usize] = v;
            }
            for j in 0..pts.len() {
                assert!((dense[j] - kernel_value(pts[i], pts[j], s)).abs() < 1e-12);
            }
            assert_eq!(k.diagonal[i], 1.0);
        }
    }
}
