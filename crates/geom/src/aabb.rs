//! Axis-aligned bounding boxes.

use glam::DVec3;

/// Axis-aligned box. Invariant: `min <= max` componentwise unless empty
/// (an empty box has `min = +inf`, `max = -inf`, so `grow` works from it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// Smallest box containing all `points` (EMPTY for none).
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a DVec3>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.grow(*p))
    }

    pub fn grow(self, p: DVec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    pub fn size(&self) -> DVec3 {
        self.max - self.min
    }

    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    pub fn diagonal(&self) -> f64 {
        self.size().length()
    }

    /// The box grown by `margin` on every side.
    pub fn padded(&self, margin: f64) -> Aabb {
        Aabb {
            min: self.min - DVec3::splat(margin),
            max: self.max + DVec3::splat(margin),
        }
    }

    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// Whether the closed boxes share a point (touching counts).
    pub fn overlaps(&self, o: &Aabb) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }
}

/// Where to put the origin for data whose first `D` coordinates span the
/// box `lo..hi`, so that computations relative to it keep the data's
/// precision however far from 0 the data lie: the box's centre rounded to a multiple of the power of
/// two `q` ≥ 4 × the box's largest side (a single point: the point), on
/// the axes where the centre lies at least 2 `q` from 0. Data within
/// about 8 times their size of the origin stay where they are (zero
/// offset: results unchanged). Moving is exact: every coordinate lies
/// within a factor 2 of the offset it is moved by (Sterbenz).
pub fn offset_to_origin<const D: usize>(lo: [f64; D], hi: [f64; D]) -> DVec3 {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_of_points() {
        let pts = [DVec3::new(1.0, -2.0, 3.0), DVec3::new(-1.0, 4.0, 0.0)];
        let b = Aabb::from_points(&pts);
        assert_eq!(b.min, DVec3::new(-1.0, -2.0, 0.0));
        assert_eq!(b.max, DVec3::new(1.0, 4.0, 3.0));
        assert!(Aabb::EMPTY.is_empty());
        assert!(!b.is_empty());
        assert!(b.contains(DVec3::ZERO));
    }

    /// The rounding error of `a - b` (Knuth's two-sum).
    fn rounding_of_difference(a: f64, b: f64) -> f64 {
        let s = a - b;
        let bb = s - a;
        (a - (s - bb)) + (-b - bb)
    }

    #[test]
    fn data_near_the_origin_stay_and_far_data_move_exactly() {
        assert_eq!(offset_to_origin([0.0, 0.0], [1.0, 1.0]), DVec3::ZERO);
        assert_eq!(offset_to_origin([-3.0; 3], [-1.0; 3]), DVec3::ZERO);
        assert_eq!(offset_to_origin([0.0; 3], [0.0; 3]), DVec3::ZERO);
        // Far away: a multiple of a power of two near the centre.
        let by = offset_to_origin([1e6, 2e6, -5.0], [1e6 + 1.0, 2e6 + 1.0, -4.0]);
        assert_eq!(by, DVec3::new(1e6, 2e6, 0.0));
        // A single point: the point itself, which moves to 0.
        let p = [-7.500000000000001e29, -3.75e30];
        assert_eq!(offset_to_origin(p, p), DVec3::new(p[0], p[1], 0.0));
        // Moving changes no coordinate: exact differences.
        let mut x = 0.37f64;
        for _ in 0..2000 {
            x = (x * 7919.0 + 0.123).fract();
            let (c, side) = (10f64.powf(60.0 * x - 20.0), 10f64.powf(20.0 * x - 10.0));
            let (lo, hi) = ([c, -c * 0.5], [c + side, -c * 0.5 + side * x]);
            let by = offset_to_origin(lo, hi);
            for (v, by) in [(lo[0], by.x), (hi[0], by.x), (lo[0] + side * x, by.x)]
                .into_iter()
                .chain([(lo[1], by.y), (hi[1], by.y)])
            {
                assert_eq!(rounding_of_difference(v, by), 0.0, "{v} - {by}");
            }
        }
    }
}
