//! The oriented Gabriel test of a Delaunay facet.
//!
//! An oriented facet `abc` with Delaunay tetrahedron `abcs` behind it meets
//! the oriented Gabriel property when the half of its diametral ball (the
//! smallest ball whose sphere passes through `a`, `b`, `c`; centre in the
//! facet's plane) on the side of `s` holds no point. The spheres through
//! `a`, `b`, `c` form a pencil: on the side of `s`, the empty circumball of
//! `abcs` either contains that half-ball (then it is empty) or is contained
//! in it (then `s` itself is inside). So the property fails exactly when
//! `s` lies strictly inside the diametral ball, and no search for points is
//! needed.
//!
//! This is a geometric decision, evaluated in floating point (degree-6
//! polynomial, relative to `a`): the pseudo-surface stays a consistent
//! complex of exact Delaunay facets whatever it answers, so a near-tie
//! decided either way changes which facet is kept, never the topology's
//! validity. Points exactly on the sphere count as outside (no opening).

use surfrecon_geom::DVec3;

/// Whether `s` is strictly inside the diametral ball of triangle `abc`
/// (which must not be degenerate; Delaunay facets never are).
pub fn in_diametral_ball(a: DVec3, b: DVec3, c: DVec3, s: DVec3) -> bool {
    let (u, v, w) = (b - a, c - a, s - a);
    let n = u.cross(v);
    // 2|n|² (m − a) for the facet's circumcentre m; compare |w − (m − a)|²
    // with |m − a|², both scaled by |n|² to stay polynomial.
    let twice_centre = u.length_squared() * v.cross(n) + v.length_squared() * n.cross(u);
    w.length_squared() * n.length_squared() < w.dot(twice_centre)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn right_triangle_ball_is_its_hypotenuse_ball() {
        let (a, b, c) = (
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        );
        // Centre (1, 1, 0), radius √2.
        let centre = DVec3::new(1.0, 1.0, 0.0);
        assert!(in_diametral_ball(
            a,
            b,
            c,
            centre + DVec3::new(0.0, 0.0, 1.4)
        ));
        assert!(!in_diametral_ball(
            a,
            b,
            c,
            centre + DVec3::new(0.0, 0.0, 1.42)
        ));
        assert!(in_diametral_ball(
            a,
            b,
            c,
            centre + DVec3::new(0.3, -0.2, -1.3)
        ));
        assert!(!in_diametral_ball(a, b, c, DVec3::new(3.0, 3.0, 0.1)));
    }

    #[test]
    fn matches_the_centre_distance_on_random_cases() {
        let mut x = 0x9e3779b97f4a7c15_u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let mut p = || DVec3::new(next(), next(), next());
            let (a, b, c, s) = (p(), p(), p(), p());
            let (u, v) = (b - a, c - a);
            let n = u.cross(v);
            let m = a
                + (u.length_squared() * v.cross(n) + v.length_squared() * n.cross(u))
                    / (2.0 * n.length_squared());
            let (r2, d2) = ((a - m).length_squared(), (s - m).length_squared());
            if (r2 - d2).abs() > 1e-9 * r2 {
                assert_eq!(in_diametral_ball(a, b, c, s), d2 < r2);
            }
        }
    }
}
