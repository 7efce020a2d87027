//! Convection φ_t = ∇d·∇φ: the surface moves along −∇d towards its closest
//! data, with normal speed at most 1, so Δt = O(h) is stable. Upwind
//! differences (the side the information comes from) keep it monotone; their
//! numerical viscosity resolves ties at points equidistant from two data.
//! Its equilibrium is close to a polyhedron with vertices on the data.

use crate::band::{BandDistance, NarrowBand};
use crate::flow::{evolve, EvolveParams, EvolveStats, Motion};

/// Upwind ∇d·∇φ at node `l`: per axis, the one-sided difference of φ on the
/// side the velocity −∇d comes from, times the central difference of d.
#[inline]
pub fn advection_term<const D: usize>(
    phi: &[f64],
    d: &[f64],
    l: usize,
    strides: &[usize; D],
    h: f64,
) -> f64 {
    let grad = strides.map(|s| (d[l + s] - d[l - s]) * 0.5);
    upwind_advection(phi, l, strides, &grad, h)
}

/// ∇d·∇φ for a given ∇d (per cell), φ differenced on the upwind side of
/// the velocity −∇d: a velocity v > 0 (∂d < 0) takes the backward
/// difference.
#[inline]
pub fn upwind_advection<const D: usize>(
    phi: &[f64],
    l: usize,
    strides: &[usize; D],
    grad: &[f64; D],
    h: f64,
) -> f64 {
    let mut sum = 0.0;
    for (&s, &g) in strides.iter().zip(grad) {
        let dphi = if g < 0.0 {
            phi[l] - phi[l - s]
        } else {
            phi[l + s] - phi[l]
        };
        sum += g * dphi;
    }
    sum / (h * h)
}

/// Run convection until the zero set stops moving (or `params.max_steps`).
pub fn convect<const D: usize>(
    band: &mut NarrowBand<D>,
    d: &mut BandDistance<D>,
    params: &EvolveParams,
) -> EvolveStats {
    evolve(
        band,
        d,
        Motion::Convection,
        params,
        &Default::default(),
        &surfrecon_geom::progress::no_progress,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reinit::reinitialize;
    use surfrecon_grid::{Field, GridSpec};

    #[test]
    fn circle_shrinks_onto_smaller_circle_of_data() {
        // Data: dense points on a circle of radius 0.5; start: circle of
        // radius 0.9 (what a large ε contour would give).
        let spec = GridSpec::<2> {
            origin: [-1.2, -1.2],
            spacing: 0.03,
            dims: [81, 81],
        };
        let pts: Vec<[f64; 2]> = (0..200)
            .map(|i| {
                let t = i as f64 / 200.0 * std::f64::consts::TAU;
                [0.5 * t.cos(), 0.5 * t.sin()]
            })
            .collect();
        let pos = |l: usize| spec.position(spec.unlinear(l));
        let d = Field {
            spec,
            values: (0..spec.node_count())
                .map(|l| {
                    let [x, y] = pos(l);
                    pts.iter()
                        .map(|p| ((x - p[0]).powi(2) + (y - p[1]).powi(2)).sqrt())
                        .fold(f64::INFINITY, f64::min)
                })
                .collect(),
        };
        let start = Field {
            spec,
            values: (0..spec.node_count())
                .map(|l| {
                    let [x, y] = pos(l);
                    (x * x + y * y).sqrt() - 0.9
                })
                .collect(),
        };
        let mut band = NarrowBand::from_field(start, 3.0 * spec.spacing).unwrap();
        reinitialize(&mut band);
        let mut d = BandDistance::dense(std::sync::Arc::new(d)).unwrap();
        let stats = convect(&mut band, &mut d, &EvolveParams::default());
        assert!(stats.steps > 10);
        for &k in &band.active {
            let v = band.value(k);
            if v.abs() < 0.5 * spec.spacing {
                let [x, y] = spec.position(band.node(k));
                let r = (x * x + y * y).sqrt();
                assert!((r - 0.5).abs() < 1.5 * spec.spacing, "zero set at r = {r}");
            }
        }
    }
}
