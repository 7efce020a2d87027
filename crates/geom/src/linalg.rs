//! Small dense linear systems, such as the normal equations of the local
//! least-squares fits of points to a plane or quadric.

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

#[cfg(test)]
mod tests {
    use super::*;

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
