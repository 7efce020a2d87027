//! The reconstruction runs on data moved near the origin, and its results
//! are moved back.
//!
//! Grid nodes sit at `origin + spacing * index`. Far from the origin the
//! spacing can fall below the precision of the coordinates: a single
//! point at 1e30 gets a grid of spacing 0.25 (one ulp there is 1.4e14),
//! so every node had the same position, every distance was 0 and the 2D
//! level set came out as an open curve. Relative to the data's centre the
//! nodes are distinct whatever the data's position; only the final
//! coordinates are rounded, once, when moved back.

use crate::reconstruct::{Input, Reconstruction2, Reconstruction3};
use std::borrow::Cow;
use surfrecon_geom::DVec3;
use surfrecon_grid::sparse::BlockGrid;
use surfrecon_grid::Field;

/// Where to put the origin for data whose first `D` coordinates span the
/// box `lo..hi`: the box's centre rounded to a multiple of the power of
/// two `q` ≥ 4 × the box's largest side (a single point: the point), on
/// the axes where the centre lies at least 2 `q` from 0. Data within
/// about 8 times their size of the origin stay where they are (zero
/// offset: results unchanged). Moving is exact: every coordinate lies
/// within a factor 2 of the offset it is moved by (Sterbenz).
pub(crate) fn offset<const D: usize>(lo: [f64; D], hi: [f64; D]) -> DVec3 {
    if lo.iter().chain(&hi).any(|c| !c.is_finite()) {
        return DVec3::ZERO;
    }
    let extent = (0..D).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    let mut by = DVec3::ZERO;
    if extent == 0.0 {
        (0..D.min(3)).for_each(|a| by[a] = lo[a]);
        return by;
    }
    let q = 2f64.powi((4.0 * extent).log2().ceil() as i32);
    if !q.is_normal() {
        return DVec3::ZERO;
    }
    for a in 0..D.min(3) {
        let k = ((0.5 * lo[a] + 0.5 * hi[a]) / q).round();
        if k.abs() >= 2.0 {
            by[a] = k * q;
        }
    }
    by
}

/// `input` moved by `-by` (borrowed unchanged when `by` is zero).
pub(crate) fn moved(input: &Input, by: DVec3) -> Cow<'_, Input> {
    if by == DVec3::ZERO {
        return Cow::Borrowed(input);
    }
    let m = |v: &DVec3| *v - by;
    Cow::Owned(Input {
        points: input.points.iter().map(m).collect(),
        normals: input.normals.clone(),
        segments: input.segments.iter().map(|s| s.each_ref().map(m)).collect(),
        triangles: input
            .triangles
            .iter()
            .map(|t| t.each_ref().map(m))
            .collect(),
    })
}

/// The first `D` coordinates of `by`.
fn head<const D: usize>(by: DVec3) -> [f64; D] {
    std::array::from_fn(|a| if a < 3 { by[a] } else { 0.0 })
}

/// φ (and the dense field, if any) moved by `by`.
pub(crate) fn move_fields<const D: usize>(
    phi: &mut BlockGrid<D>,
    field: Option<&mut Field<D>>,
    by: DVec3,
) {
    phi.translate(head(by));
    if let Some(f) = field {
        let by = head::<D>(by);
        (0..D).for_each(|a| f.spec.origin[a] += by[a]);
    }
}

impl Reconstruction3 {
    /// Every position moved by `by`.
    pub(crate) fn moved_by(mut self, by: DVec3) -> Self {
        self.mesh.vertices.iter_mut().for_each(|v| *v += by);
        move_fields(&mut self.phi, self.field.as_mut(), by);
        self
    }
}

impl Reconstruction2 {
    /// Every position moved by `by` (x and y; the curves stay at z = 0).
    pub(crate) fn moved_by(mut self, by: DVec3) -> Self {
        let in_plane = DVec3::new(by.x, by.y, 0.0);
        self.curves.vertices.iter_mut().for_each(|v| *v += in_plane);
        move_fields(&mut self.phi, self.field.as_mut(), by);
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rounding error of `a - b` (Knuth's two-sum).
    fn rounding_of_difference(a: f64, b: f64) -> f64 {
        let s = a - b;
        let bb = s - a;
        (a - (s - bb)) + (-b - bb)
    }

    #[test]
    fn data_near_the_origin_stay_and_far_data_move_exactly() {
        assert_eq!(offset([0.0, 0.0], [1.0, 1.0]), DVec3::ZERO);
        assert_eq!(offset([-3.0; 3], [-1.0; 3]), DVec3::ZERO);
        assert_eq!(offset([0.0; 3], [0.0; 3]), DVec3::ZERO);
        // Far away: a multiple of a power of two near the centre.
        let by = offset([1e6, 2e6, -5.0], [1e6 + 1.0, 2e6 + 1.0, -4.0]);
        assert_eq!(by, DVec3::new(1e6, 2e6, 0.0));
        // A single point: the point itself, which moves to 0.
        let p = [-7.500000000000001e29, -3.75e30];
        assert_eq!(offset(p, p), DVec3::new(p[0], p[1], 0.0));
        // Moving changes no coordinate: exact differences.
        let mut x = 0.37f64;
        for _ in 0..2000 {
            x = (x * 7919.0 + 0.123).fract();
            let (c, side) = (10f64.powf(60.0 * x - 20.0), 10f64.powf(20.0 * x - 10.0));
            let (lo, hi) = ([c, -c * 0.5], [c + side, -c * 0.5 + side * x]);
            let by = offset(lo, hi);
            for (v, by) in [(lo[0], by.x), (hi[0], by.x), (lo[0] + side * x, by.x)]
                .into_iter()
                .chain([(lo[1], by.y), (hi[1], by.y)])
            {
                assert_eq!(rounding_of_difference(v, by), 0.0, "{v} - {by}");
            }
        }
    }
}
