//! Exact power-of-two rescaling of data and grids whose coordinates are so
//! large or so small that squared distances (and the winding number's
//! triple products) would leave the f64 range: around 1e150 a squared
//! distance overflows, around 1e-160 it underflows. Multiplying by a power
//! of two changes no bit of any result that stays in range, so rescaled
//! runs give the same distances as unscaled ones wherever those were right.

use super::DataSet;
use crate::GridSpec;

/// Largest coordinates between 2^-RANGE and 2^RANGE are used as they are
/// (cubes of differences stay far inside the f64 range).
const RANGE: i32 = 100;

/// The power of two that brings the largest coordinate of `data` and
/// `spec` near 1, when that coordinate lies outside 2^±[`RANGE`].
pub(crate) fn unit_scale<const D: usize>(data: &DataSet<D>, spec: &GridSpec<D>) -> Option<f64> {
    let mut largest = spec.spacing.abs();
    for v in spec.origin.iter().chain(&spec.max_corner()) {
        largest = largest.max(v.abs());
    }
    for i in 0..data.len() {
        let (lo, hi) = data.datum_bounds(i);
        for v in lo.iter().chain(&hi) {
            largest = largest.max(v.abs());
        }
    }
    if largest == 0.0 || !largest.is_finite() {
        return None;
    }
    let exponent = largest.log2().floor() as i32;
    (exponent.abs() > RANGE).then(|| 2f64.powi(-exponent.clamp(-1000, 1000)))
}

impl<const D: usize> DataSet<D> {
    /// Every coordinate times `s` (exact for a power of two).
    pub fn scaled(&self, s: f64) -> Self {
        let scale = |p: &[f64; D]| p.map(|c| c * s);
        DataSet {
            points: self.points.iter().map(scale).collect(),
            segments: self
                .segments
                .iter()
                .map(|g| g.each_ref().map(scale))
                .collect(),
            triangles: self
                .triangles
                .iter()
                .map(|t| t.each_ref().map(scale))
                .collect(),
        }
    }
}

impl<const D: usize> GridSpec<D> {
    /// The same grid with origin and spacing times `s`.
    pub(crate) fn scaled(&self, s: f64) -> Self {
        GridSpec {
            origin: self.origin.map(|c| c * s),
            spacing: self.spacing * s,
            dims: self.dims,
        }
    }
}
