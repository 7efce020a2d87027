//! Robust estimate of the sampling noise: the typical distance by which
//! samples scatter off a smooth surface.
//!
//! Around a sample, its k nearest neighbours are written as heights over
//! the tangent plane of the sample's normal and fitted by a quadric
//! h(u, v) = a + bu + cv + du² + euv + fv². The quadric absorbs the
//! surface's curvature and any tilt of the normal; what is left is noise
//! plus detail finer than the neighbourhood (the bumps of a scanned
//! surface). The two are told apart by fitting at two neighbourhood sizes:
//! noise leaves about the same residual at both, unresolved detail grows
//! like r³ with the neighbourhood radius r (so like k^{3/2}). Reading detail
//! as noise would raise ε and the fitting accuracy of a clean, detailed
//! scan and leave the surface a tube's width off its data. The median over
//! a spread-out subset ignores outliers and sharp features.

use glam::DVec3;
use rayon::prelude::*;
use surfrecon_geom::linalg::HeightField;
use surfrecon_geom::normals::plane_normal;
use surfrecon_geom::spatial::KdTree;

/// Neighbours of the wide quadric fit: enough that the six coefficients
/// cannot follow the noise.
const NEIGHBOURS: usize = 32;
/// Neighbours of the narrow fit (the nearest of the wide fit's).
const NARROW_NEIGHBOURS: usize = 12;
/// Growth of the residual from the narrow to the wide fit for pure noise
/// (measured 1.1–1.3 on isotropic noise of 0.25–1% of the diagonal: the
/// nearest neighbours are picked partly by their noise, which the narrow fit
/// sees less of).
const NOISE_GROWTH: f64 = 1.25;

/// Samples the median runs over at most (evenly strided).
const MAX_PROBES: usize = 4000;

/// Estimated noise standard deviation (absolute units) of `points`, given
/// rough unit `normals`; 0 when no neighbourhood could be fitted (e.g. all
/// samples lie on curves, where the quadric is not determined).
pub fn estimate_noise(points: &[DVec3], normals: &[DVec3], tree: &KdTree) -> f64 {
    residual_medians(points, Some(normals), tree)
        .map_or(0.0, |(wide, narrow)| noise_without_detail(wide, narrow))
}

/// [`estimate_noise`] of points without normals: each probed
/// neighbourhood's plane fit gives its own.
pub fn estimate_noise_unoriented(points: &[DVec3], tree: &KdTree) -> f64 {
    residual_medians(points, None, tree)
        .map_or(0.0, |(wide, narrow)| noise_without_detail(wide, narrow))
}

/// Median RMS residuals of the wide and the narrow quadric fits over a
/// spread-out subset of the samples; None when no neighbourhood fits.
fn residual_medians(
    points: &[DVec3],
    normals: Option<&[DVec3]>,
    tree: &KdTree,
) -> Option<(f64, f64)> {
    let k = NEIGHBOURS.min(points.len());
    let stride = (points.len() / MAX_PROBES).max(1);
    let (mut wide, mut narrow): (Vec<f64>, Vec<f64>) = (0..points.len())
        .into_par_iter()
        .step_by(stride)
        .filter_map(|i| {
            let neighbours: Vec<DVec3> = tree
                .knn(points[i], k)
                .into_iter()
                .map(|n| points[n.index])
                .collect();
            let narrow = &neighbours[..NARROW_NEIGHBOURS.min(neighbours.len())];
            let normal = normals.map_or_else(|| plane_normal(&neighbours), |n| n[i]);
            Some((
                quadric_residual_rms(points[i], normal, &neighbours)?,
                quadric_residual_rms(points[i], normal, narrow)?,
            ))
        })
        .unzip();
    (!wide.is_empty()).then(|| (median(&mut wide), median(&mut narrow)))
}

/// The noise part of the wide fit's residual `wide`, given the narrow fit's
/// `narrow`: with wide² = σ² + d², narrow² = (σ/g)² + (d/D)², g the noise's
/// growth and D = (k_wide/k_narrow)^{3/2} the detail's, solve for σ.
fn noise_without_detail(wide: f64, narrow: f64) -> f64 {
    let detail_growth = (NEIGHBOURS as f64 / NARROW_NEIGHBOURS as f64).powi(3);
    let noise_growth = NOISE_GROWTH * NOISE_GROWTH;
    let sigma_squared =
        (detail_growth * narrow * narrow - wide * wide) / (detail_growth / noise_growth - 1.0);
    sigma_squared.max(0.0).sqrt().min(wide)
}

fn median(values: &mut [f64]) -> f64 {
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
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
    fn without_normals_the_planes_of_the_neighbourhoods_do() {
        for sigma in [0.005, 0.02] {
            let (p, _) = noisy_sphere(sigma);
            let estimate = estimate_noise_unoriented(&p, &KdTree::new(&p));
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
    fn detail_finer_than_the_neighbourhood_is_not_noise() {
        // A sphere with bumps a few samples wide: the wide fit cannot follow
        // them, the narrow one nearly can.
        let (p, n) = noisy_sphere(0.0);
        let bumpy: Vec<DVec3> = p
            .iter()
            .map(|&q| {
                q * (1.0 + 0.004 * (20.0 * q.x).sin() * (20.0 * q.y).sin() * (20.0 * q.z).sin())
            })
            .collect();
        let tree = KdTree::new(&bumpy);
        let estimate = estimate_noise(&bumpy, &n, &tree);
        let (wide, _) = residual_medians(&bumpy, Some(&n), &tree).unwrap();
        assert!(wide > 5e-4, "the bumps must show in the wide fit: {wide}");
        assert!(
            estimate < 0.3 * wide,
            "estimate {estimate}, wide residual {wide}"
        );
    }

    #[test]
    fn samples_on_a_line_give_zero_not_nan() {
        let p: Vec<DVec3> = (0..100).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect();
        let n = vec![DVec3::Z; 100];
        assert_eq!(estimate_noise(&p, &n, &KdTree::new(&p)), 0.0);
    }
}
