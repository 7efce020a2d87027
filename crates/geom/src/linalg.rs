//! Small dense linear systems, such as the normal equations of the local
//! least-squares fits of points to a plane or quadric, and that fit itself
//! ([`HeightField`]).

/// Solves the leading `n`×`n` block of `a x = b` (`n ≤ N`; entries beyond
/// it are ignored and come back as 0) by Gaussian elimination with partial
/// pivoting. `None` when the system is (nearly) singular: a pivot is NaN
/// or at most `relative_pivot` times the largest diagonal magnitude.
pub fn solve<const N: usize>(
    mut a: [[f64; N]; N],
    mut b: [f64; N],
    n: usize,
    relative_pivot: f64,
) -> Option<[f64; N]> {
    let n = n.min(N);
    let scale = (0..n).map(|i| a[i][i].abs()).fold(0.0, f64::max);
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        let magnitude = a[pivot][col].abs();
        if magnitude.is_nan() || magnitude <= relative_pivot * scale {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = a[col];
        for r in col + 1..n {
            let f = a[r][col] / pivot_row[col];
            for (x, p) in a[r][col..n].iter_mut().zip(&pivot_row[col..n]) {
                *x -= f * p;
            }
            b[r] -= f * b[col];
        }
    }
    let mut x = [0.0; N];
    for r in (0..n).rev() {
        let rest: f64 = (r + 1..n).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - rest) / a[r][r];
    }
    Some(x)
}

/// A least-squares quadratic height field over a local frame: over a
/// plane (`h = c0 + c1 u + c2 v + c3 u² + c4 uv + c5 v²`) for surfaces in
/// 3D, over a line (`h = c0 + c1 u + c2 u²`) for curves in 2D. The
/// quadratic terms follow the curvature, so what is left is noise.
#[derive(Clone, Copy, Debug)]
pub struct HeightField {
    coefficients: [f64; 6],
    terms: usize,
}

impl HeightField {
    /// Fit to `(uv, h)` samples (`uv[1]` unused over a line). Keep `uv`
    /// near unit size so the normal equations are well conditioned. `None`
    /// when the samples do not determine the fit (too few, or all on a
    /// line across a plane): a pivot of the normal equations is at most
    /// `relative_pivot` times their largest diagonal entry (see [`solve`]).
    pub fn fit(samples: &[([f64; 2], f64)], over_plane: bool, relative_pivot: f64) -> Option<Self> {
        let terms = if over_plane { 6 } else { 3 };
        let mut ata = [[0.0; 6]; 6];
        let mut atb = [0.0; 6];
        for (uv, h) in samples {
            let row = Self::basis(*uv, over_plane);
            for r in 0..terms {
                atb[r] += row[r] * h;
                for c in 0..terms {
                    ata[r][c] += row[r] * row[c];
                }
            }
        }
        let coefficients = solve(ata, atb, terms, relative_pivot)?;
        Some(HeightField {
            coefficients,
            terms,
        })
    }

    /// Number of fitted coefficients (6 over a plane, 3 over a line).
    pub fn terms(&self) -> usize {
        self.terms
    }

    /// The fitted height at `uv`.
    pub fn at(&self, uv: [f64; 2]) -> f64 {
        Self::basis(uv, self.terms == 6)
            .iter()
            .zip(&self.coefficients)
            .map(|(b, c)| b * c)
            .sum()
    }

    /// Sum of squared differences between the samples and the field.
    pub fn squared_residual(&self, samples: &[([f64; 2], f64)]) -> f64 {
        samples
            .iter()
            .map(|(uv, h)| (h - self.at(*uv)).powi(2))
            .sum()
    }

    fn basis([u, v]: [f64; 2], over_plane: bool) -> [f64; 6] {
        if over_plane {
            [1.0, u, v, u * u, u * v, v * v]
        } else {
            [1.0, u, u * u, 0.0, 0.0, 0.0]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn height_fields_reproduce_quadratics_and_refuse_lines() {
        let quadric = |[u, v]: [f64; 2]| 0.5 - u + 2.0 * v + 0.3 * u * u - u * v + 0.7 * v * v;
        let samples: Vec<([f64; 2], f64)> = (0..25)
            .map(|i| {
                let uv = [(i % 5) as f64 / 2.0 - 1.0, (i / 5) as f64 / 2.0 - 1.0];
                (uv, quadric(uv))
            })
            .collect();
        let fit = HeightField::fit(&samples, true, 1e-9).unwrap();
        assert_eq!(fit.terms(), 6);
        assert!((fit.at([0.3, -0.2]) - quadric([0.3, -0.2])).abs() < 1e-12);
        assert!(fit.squared_residual(&samples) < 1e-20);
        // Samples along one line do not determine a field over a plane,
        // but do over that line.
        let line: Vec<([f64; 2], f64)> = samples
            .iter()
            .filter(|(uv, _)| uv[1] == 0.0)
            .copied()
            .collect();
        assert!(HeightField::fit(&line, true, 1e-9).is_none());
        let parabola = HeightField::fit(&line, false, 1e-9).unwrap();
        assert!((parabola.at([0.25, 0.0]) - quadric([0.25, 0.0])).abs() < 1e-12);
    }

    #[test]
    fn solves_a_system_needing_pivoting() {
        // Zero on the first diagonal entry: only row exchange solves it.
        let a = [[0.0, 2.0, 1.0], [1.0, 1.0, 0.0], [2.0, 0.0, 3.0]];
        let x_true = [1.0, -2.0, 0.5];
        let b: [f64; 3] = std::array::from_fn(|r| (0..3).map(|c| a[r][c] * x_true[c]).sum());
        let x = solve(a, b, 3, 1e-12).unwrap();
        for (got, want) in x.iter().zip(&x_true) {
            assert!((got - want).abs() < 1e-12);
        }
    }

    #[test]
    fn leading_block_only_and_singular_systems_refused() {
        let mut a = [[0.0; 4]; 4];
        a[0][0] = 2.0;
        a[1][1] = 4.0;
        a[3][3] = f64::NAN; // outside the block: ignored
        let x = solve(a, [2.0, 8.0, 0.0, 7.0], 2, 1e-9).unwrap();
        assert_eq!(x, [1.0, 2.0, 0.0, 0.0]);
        let singular = [[1.0, 2.0], [2.0, 4.0]];
        assert!(solve(singular, [1.0, 2.0], 2, 1e-9).is_none());
        assert!(solve([[f64::NAN]], [1.0], 1, 1e-9).is_none());
    }
}
