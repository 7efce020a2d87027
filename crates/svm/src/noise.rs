//! Robust estimate of the sampling noise: the typical distance by which
//! samples scatter off a smooth surface.
//!
//! Around a sample, its k nearest neighbours are written as heights over
//! the tangent plane of the sample's normal and fitted by a quadric
//! h(u, v) = a + bu + cv + du² + euv + fv². The quadric absorbs the
//! surface's curvature and any tilt of the normal, so the RMS of what is
//! left is the noise (clean samples leave only third-order terms). The
//! median over a spread-out subset ignores outliers and sharp features.

use glam::DVec3;
use rayon::prelude::*;
use surfrecon_geom::linalg::HeightField;
use surfrecon_geom::spatial::KdTree;

/// Neighbours per local quadric fit: enough that the six coefficients
/// cannot follow the noise, few enough that the neighbourhood stays small.
const NEIGHBOURS: usize = 32;

/// Samples the median runs over at most (evenly strided).
const MAX_PROBES: usize = 4000;

/// Estimated noise standard deviation (absolute units) of `points`, given
/// rough unit `normals`; 0 when no neighbourhood could be fitted (e.g. all
/// samples lie on curves, where the quadric is not determined).
pub fn estimate_noise(points: &[DVec3], normals: &[DVec3], tree: &KdTree) -> f64 {
    let k = NEIGHBOURS.min(points.len());
    let stride = (points.len() / MAX_PROBES).max(1);
    let mut rms: Vec<f64> = (0..points.len())
        .into_par_iter()
        .step_by(stride)
        .filter_map(|i| {
            let neighbours: Vec<DVec3> = tree
                .knn(points[i], k)
                .into_iter()
                .map(|n| points[n.index])
                .collect();
            quadric_residual_rms(points[i], normals[i], &neighbours)
        })
        .collect();
    if rms.is_empty() {
        return 0.0;
    }
    let mid = rms.len() / 2;
    *rms.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// RMS residual (with the 6 fitted degrees of freedom taken out) of the
/// least-squares quadric height field through `neighbours` in the frame of
/// `origin` and `normal`; None when the fit is not determined.
fn quadric_residual_rms(origin: DVec3, normal: DVec3, neighbours: &[DVec3]) -> Option<f64> {
    const TERMS: usize = 6;
    if neighbours.len() <= TERMS + 2 {
        return None;
    }
    let (u_axis, v_axis) = normal.any_orthonormal_pair();
    let local = |p: &DVec3| {
        let d = *p - origin;
        ([d.dot(u_axis), d.dot(v_axis)], d.dot(normal))
    };
    // Scale u, v to unit size so the normal equations are well conditioned.
    let scale = neighbours
        .iter()
        .map(|p| local(p).0.map(f64::abs).into_iter().fold(0.0, f64::max))
        .fold(0.0, f64::max);
    if scale <= 0.0 || !scale.is_finite() {
        return None;
    }
    let samples: Vec<([f64; 2], f64)> = neighbours
        .iter()
        .map(|p| {
            let (uv, h) = local(p);
            (uv.map(|c| c / scale), h)
        })
        .collect();
    // None: the neighbours do not spread over a surface patch.
    let fit = HeightField::fit(&samples, true, 1e-9)?;
    Some((fit.squared_residual(&samples) / (samples.len() - TERMS) as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use surfrecon_geom::shapes::{icosphere, sample_surface};

    /// A standard normal deviate (Box–Muller).
    fn gaussian(rng: &mut impl Rng) -> f64 {
        let u: f64 = rng.random::<f64>().max(1e-300);
        let v: f64 = rng.random();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    fn noisy_sphere(sigma: f64) -> (Vec<DVec3>, Vec<DVec3>) {
        let pc = sample_surface(&icosphere(DVec3::ZERO, 1.0, 5), 8000, 3);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let points = pc
            .positions
            .iter()
            .map(|p| {
                *p + DVec3::new(gaussian(&mut rng), gaussian(&mut rng), gaussian(&mut rng)) * sigma
            })
            .collect();
        (points, pc.normals.unwrap())
    }

    #[test]
    fn estimates_the_noise_of_a_noisy_sphere_within_a_third() {
        for sigma in [0.005, 0.02] {
            let (p, n) = noisy_sphere(sigma);
            let estimate = estimate_noise(&p, &n, &KdTree::new(&p));
            assert!(
                (estimate / sigma - 1.0).abs() < 0.35,
                "sigma {sigma}: estimate {estimate}"
            );
        }
    }

    #[test]
    fn clean_curved_samples_have_almost_no_noise() {
        let (p, n) = noisy_sphere(0.0);
        let estimate = estimate_noise(&p, &n, &KdTree::new(&p));
        assert!(estimate < 1e-4, "estimate {estimate}");
    }

    #[test]
    fn samples_on_a_line_give_zero_not_nan() {
        let p: Vec<DVec3> = (0..100).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect();
        let n = vec![DVec3::Z; 100];
        assert_eq!(estimate_noise(&p, &n, &KdTree::new(&p)), 0.0);
    }
}
