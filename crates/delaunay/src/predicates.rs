//! Exact orientation and in-sphere predicates on `DVec3`, with a symbolic
//! perturbation that decides every cospherical case.
//!
//! Convention (right-handed, the same as VTK's tetra): `orient3d(a, b, c, d)`
//! is positive when `d` lies on the side of the plane `abc` that
//! `(b − a) × (c − a)` points to, i.e. `det[b − a, c − a, d − a] > 0`; its
//! value is six times the signed volume of the tetrahedron. The `robust`
//! crate uses the opposite handedness, so the wrappers swap `b` and `c`.

use glam::DVec3;
use robust::Coord3D;

#[inline(always)]
fn coord(p: DVec3) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// Unit roundoff of f64 (half an ulp of 1).
const EPS: f64 = f64::EPSILON / 2.0;
/// Relative error bound of the floating-point orientation determinant
/// below, in units of its permanent (Shewchuk 1997, first stage).
const ORIENT_BOUND: f64 = (7.0 + 56.0 * EPS) * EPS;
/// The same for the in-sphere determinant.
const INSPHERE_BOUND: f64 = (16.0 + 224.0 * EPS) * EPS;

/// Exact sign (adaptive precision) of `det[b − a, c − a, d − a]`; the value
/// is that determinant up to rounding when it is far from zero.
///
/// The plain floating-point determinant decides when it exceeds its error
/// bound (almost always); otherwise the adaptive `robust` predicate does.
#[inline(always)]
pub fn orient3d(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    orient3d_filtered(a, b, c, d, f64::INFINITY)
}

/// [`orient3d`] that first compares the determinant with `static_bound`,
/// an error bound valid for all points in a box ([`StaticFilter`]), and
/// computes the permanent only when that does not decide.
#[inline(always)]
pub(crate) fn orient3d_filtered(a: DVec3, b: DVec3, c: DVec3, d: DVec3, static_bound: f64) -> f64 {
    let (u, v, w) = (b - a, c - a, d - a);
    let (uv_z, vu_z) = (u.x * v.y, v.x * u.y);
    let (vw_z, wv_z) = (v.x * w.y, w.x * v.y);
    let (wu_z, uw_z) = (w.x * u.y, u.x * w.y);
    let det = w.z * (uv_z - vu_z) + u.z * (vw_z - wv_z) + v.z * (wu_z - uw_z);
    if det.abs() > static_bound {
        return det;
    }
    let permanent = w.z.abs() * (uv_z.abs() + vu_z.abs())
        + u.z.abs() * (vw_z.abs() + wv_z.abs())
        + v.z.abs() * (wu_z.abs() + uw_z.abs());
    if det.abs() > ORIENT_BOUND * permanent {
        return det;
    }
    robust::orient3d(coord(a), coord(c), coord(b), coord(d))
}

/// Exact in-sphere test for a positively oriented tetrahedron `abcd`:
/// positive when `e` is strictly inside its circumsphere, negative when
/// strictly outside, zero when the five points are cospherical.
///
/// Filtered like [`orient3d`]: the lifted 4×4 determinant of the
/// differences to `e`, expanded by 2×2 minors of the x, y columns, decides
/// when it exceeds the error bound of its permanent.
#[inline(always)]
pub fn insphere(a: DVec3, b: DVec3, c: DVec3, d: DVec3, e: DVec3) -> f64 {
    let (det, permanent) = insphere_terms(a, b, c, d, e);
    if det.abs() > INSPHERE_BOUND * permanent {
        return det;
    }
    robust::insphere(coord(a), coord(c), coord(b), coord(d), coord(e))
}

/// The in-sphere determinant if the static bound (see [`StaticFilter`])
/// decides its sign, else `None`: the caller then runs the exact test
/// ([`insphere_sos`]) out of line, from vertex ids rather than points (an
/// out-of-line call taking the points made the compiler keep copies of
/// them on the stack for every test).
#[inline(always)]
pub(crate) fn insphere_static(
    a: DVec3,
    b: DVec3,
    c: DVec3,
    d: DVec3,
    e: DVec3,
    static_bound: f64,
) -> Option<f64> {
    let det = insphere_det(a, b, c, d, e);
    (det.abs() > static_bound).then_some(det)
}

/// The in-sphere determinant (rows p, q, r, s of the differences to `e`)
/// and its permanent, the plain way.
#[inline(always)]
fn insphere_terms(a: DVec3, b: DVec3, c: DVec3, d: DVec3, e: DVec3) -> (f64, f64) {
    // Shewchuk's positive order is (a, c, b, d): rows p, q, r, s.
    let (p, q, r, s) = (a - e, c - e, b - e, d - e);
    let (pq, qp) = (p.x * q.y, q.x * p.y);
    let (qr, rq) = (q.x * r.y, r.x * q.y);
    let (rs, sr) = (r.x * s.y, s.x * r.y);
    let (sp, ps) = (s.x * p.y, p.x * s.y);
    let (pr, rp) = (p.x * r.y, r.x * p.y);
    let (qs, sq) = (q.x * s.y, s.x * q.y);
    let (m_pq, m_qr, m_rs, m_sp, m_pr, m_qs) =
        (pq - qp, qr - rq, rs - sr, sp - ps, pr - rp, qs - sq);
    // 3×3 minors (x, y, z) of the row triples, then the lifted expansion.
    let pqr = p.z * m_qr - q.z * m_pr + r.z * m_pq;
    let qrs = q.z * m_rs - r.z * m_qs + s.z * m_qr;
    let rsp = r.z * m_sp + s.z * m_pr + p.z * m_rs;
    let spq = s.z * m_pq + p.z * m_qs + q.z * m_sp;
    let (lp, lq, lr, ls) = (
        p.length_squared(),
        q.length_squared(),
        r.length_squared(),
        s.length_squared(),
    );
    let det = (ls * pqr - lr * spq) + (lq * rsp - lp * qrs);
    let (zp, zq, zr, zs) = (p.z.abs(), q.z.abs(), r.z.abs(), s.z.abs());
    let (a_pq, a_qr, a_rs, a_sp) = (
        pq.abs() + qp.abs(),
        qr.abs() + rq.abs(),
        rs.abs() + sr.abs(),
        sp.abs() + ps.abs(),
    );
    let (a_pr, a_qs) = (pr.abs() + rp.abs(), qs.abs() + sq.abs());
    let permanent = (a_rs * zq + a_qs * zr + a_qr * zs) * lp
        + (a_sp * zr + a_pr * zs + a_rs * zp) * lq
        + (a_pq * zs + a_qs * zp + a_sp * zq) * lr
        + (a_qr * zp + a_pr * zq + a_pq * zr) * ls;
    (det, permanent)
}

/// The in-sphere determinant of [`insphere_terms`], the same
/// operations in the same order (so the same value, bit for bit), two at a
/// time in SSE2 registers (the x86-64 baseline): rows p, q in one register
/// and r, s in another, per coordinate. Written out because the compiler's
/// own pairing of the scalar code spent more instructions shuffling than
/// computing: the in-sphere tests were a third of the build's
/// instructions.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn insphere_det(a: DVec3, b: DVec3, c: DVec3, d: DVec3, e: DVec3) -> f64 {
    use std::arch::x86_64::{
        __m128d, _mm_add_pd, _mm_cvtsd_f64, _mm_mul_pd, _mm_set1_pd, _mm_set_pd, _mm_shuffle_pd,
        _mm_sub_pd, _mm_unpackhi_pd, _mm_unpacklo_pd, _mm_xor_pd,
    };
    // SAFETY: SSE2 is part of the x86_64 baseline, always available; the
    // intrinsics only compute on registers.
    unsafe {
        let (add, sub, mul) = (_mm_add_pd, _mm_sub_pd, _mm_mul_pd);
        let (lo, hi) = (_mm_unpacklo_pd, _mm_unpackhi_pd);
        // Lanes (first, second) = (_mm_set_pd(second, first)).
        let pair = |first: f64, second: f64| _mm_set_pd(second, first);
        // (u[1], w[0]): the pair shifted by one row.
        let shifted = |u: __m128d, w: __m128d| _mm_shuffle_pd::<1>(u, w);
        // Negates the first lane (exactly).
        let negate_first = |u: __m128d| _mm_xor_pd(u, pair(-0.0, 0.0));
        // Rows p = a − e, q = c − e (register "a") and r = b − e, s = d − e ("b").
        let (ex, ey, ez) = (_mm_set1_pd(e.x), _mm_set1_pd(e.y), _mm_set1_pd(e.z));
        let (xa, xb) = (sub(pair(a.x, c.x), ex), sub(pair(b.x, d.x), ex));
        let (ya, yb) = (sub(pair(a.y, c.y), ey), sub(pair(b.y, d.y), ey));
        let (za, zb) = (sub(pair(a.z, c.z), ez), sub(pair(b.z, d.z), ez));
        // 2×2 minors of the x, y columns: (pq, qr), (rs, sp), (pr, qs).
        let m1 = sub(mul(xa, shifted(ya, yb)), mul(shifted(xa, xb), ya));
        let m2 = sub(mul(xb, shifted(yb, ya)), mul(shifted(xb, xa), yb));
        let m3 = sub(mul(xa, yb), mul(xb, ya));
        // 3×3 minors (pqr, rsp) and (qrs, spq).
        let v1 = add(
            add(
                mul(lo(za, zb), hi(m1, m2)),
                mul(negate_first(hi(za, zb)), lo(m3, m3)),
            ),
            mul(lo(zb, za), lo(m1, m2)),
        );
        let v2 = add(
            add(
                mul(hi(za, zb), lo(m2, m1)),
                mul(negate_first(lo(zb, za)), hi(m3, m3)),
            ),
            mul(hi(zb, za), hi(m1, m2)),
        );
        // Lifts (lp, lq) and (lr, ls), then the lifted expansion.
        let la = add(add(mul(xa, xa), mul(ya, ya)), mul(za, za));
        let lb = add(add(mul(xb, xb), mul(yb, yb)), mul(zb, zb));
        let terms = sub(mul(hi(lb, la), v1), mul(lo(lb, la), shifted(v2, v2)));
        _mm_cvtsd_f64(terms) + _mm_cvtsd_f64(hi(terms, terms))
    }
}

/// The in-sphere determinant of [`insphere_terms`].
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn insphere_det(a: DVec3, b: DVec3, c: DVec3, d: DVec3, e: DVec3) -> f64 {
    let (p, q, r, s) = (a - e, c - e, b - e, d - e);
    let minor = |u: DVec3, w: DVec3| u.x * w.y - w.x * u.y;
    let (m_pq, m_qr, m_rs) = (minor(p, q), minor(q, r), minor(r, s));
    let (m_sp, m_pr, m_qs) = (minor(s, p), minor(p, r), minor(q, s));
    let pqr = p.z * m_qr - q.z * m_pr + r.z * m_pq;
    let qrs = q.z * m_rs - r.z * m_qs + s.z * m_qr;
    let rsp = r.z * m_sp + s.z * m_pr + p.z * m_rs;
    let spq = s.z * m_pq + p.z * m_qs + q.z * m_sp;
    let (lp, lq) = (p.length_squared(), q.length_squared());
    let (lr, ls) = (r.length_squared(), s.length_squared());
    (ls * pqr - lr * spq) + (lq * rsp - lp * qrs)
}

/// Error bounds of the floating-point stage of [`orient3d`] and
/// [`insphere`] that hold for all points in one axis-aligned box: every
/// coordinate difference is at most the box's extent on its axis, which
/// bounds the permanents the per-test bounds are computed from. A test
/// whose determinant exceeds the static bound skips computing its own
/// permanent (about a third of the in-sphere test's arithmetic); one that
/// does not falls back to the per-test bound, so the static one only has
/// to be valid, not tight: on points spread through the box (uniform
/// random points) it decides nearly all tests, on points much denser
/// than the box (a fine scan) few, at the cost of one comparison.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StaticFilter {
    pub orient: f64,
    pub insphere: f64,
}

impl StaticFilter {
    /// Bounds for all points `p` with `lo <= p <= hi`.
    pub(crate) fn for_box(lo: DVec3, hi: DVec3) -> StaticFilter {
        // Rounding is monotone, so every rounded difference of two
        // coordinates in the box is at most the rounded extent; the margin
        // covers the products below rounding differently from the tests'.
        let extent = hi - lo;
        let volume = extent.x * extent.y * extent.z;
        let margin = 1.0 + 1e-9;
        // orient3d's permanent: three terms |z| (|x y| + |x y|).
        let orient = ORIENT_BOUND * 6.0 * volume * margin;
        // insphere's: four lifts times three terms |z| (|x y| + |x y|).
        let insphere = INSPHERE_BOUND * 24.0 * volume * extent.length_squared() * margin;
        // A bound near underflow (or overflowed, or NaN) is not trusted:
        // infinity makes the static stage never decide.
        let usable = |b: f64| {
            if b.is_finite() && b > 1e-250 {
                b
            } else {
                f64::INFINITY
            }
        };
        StaticFilter {
            orient: usable(orient),
            insphere: usable(insphere),
        }
    }
}

/// In-sphere test that never ties: `true` when `e` is inside the
/// circumsphere of the positively oriented tetrahedron `abcd`, with
/// cospherical cases decided by a symbolic perturbation of the points'
/// lifted coordinate (Simulation of Simplicity). `ids` are the vertex ids of
/// `a, b, c, d, e`; a larger id gets a larger perturbation. Because the
/// decision depends only on the point set and the ids, every tetrahedron
/// sees the same perturbed point set and the triangulation stays consistent.
#[inline]
pub fn insphere_sos(pts: [DVec3; 5], ids: [u32; 5]) -> bool {
    let [a, b, c, d, e] = pts;
    let exact = insphere(a, b, c, d, e);
    if exact != 0.0 {
        return exact > 0.0;
    }
    perturbed_sign(pts, ids) > 0.0
}

/// Sign of the perturbed lifted determinant when its exact value is zero.
///
/// In Shewchuk's row order (a, c, b, d, e) the in-sphere value is the 5×5
/// determinant with rows `[x, y, z, |p|², 1]`. Adding ε^k to the lifted
/// coordinate of the point of k-th largest id adds ε^k times that row's
/// cofactor, `±orient` of the other four points, alternating in sign with
/// the row. The first non-zero cofactor in decreasing id order decides.
/// The cofactor of `e` is ∓orient(abcd) ≠ 0, so a tie remains only if all
/// five points are coplanar (returned as 0).
#[cold]
fn perturbed_sign(pts: [DVec3; 5], ids: [u32; 5]) -> f64 {
    // Shewchuk's positive order swaps b and c.
    let rows = [pts[0], pts[2], pts[1], pts[3], pts[4]];
    let row_ids = [ids[0], ids[2], ids[1], ids[3], ids[4]];
    let mut order = [0usize, 1, 2, 3, 4];
    order.sort_unstable_by_key(|&r| std::cmp::Reverse(row_ids[r]));
    for r in order {
        let mut others = [DVec3::ZERO; 4];
        let mut k = 0;
        for (j, &p) in rows.iter().enumerate() {
            if j != r {
                others[k] = p;
                k += 1;
            }
        }
        let minor = robust::orient3d(
            coord(others[0]),
            coord(others[1]),
            coord(others[2]),
            coord(others[3]),
        );
        if minor != 0.0 {
            // Cofactor sign (−1)^(row + lift column) with 0-based rows and
            // the lift in column 3: negative for even rows.
            return if r % 2 == 0 { -minor } else { minor };
        }
    }
    0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers in [0, 1) from a fixed seed (a 64-bit LCG's high
    /// bits): the same inputs on every run.
    fn uniform_stream(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn cube_corner(i: u32) -> DVec3 {
        DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)
    }

    #[test]
    fn orient3d_is_right_handed_six_volumes() {
        let o = orient3d(DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z);
        assert_eq!(o, 1.0);
        assert_eq!(orient3d(DVec3::ZERO, DVec3::Y, DVec3::X, DVec3::Z), -1.0);
        assert_eq!(
            orient3d(DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::X + DVec3::Y),
            0.0
        );
    }

    /// The filtered predicates agree in sign with the adaptive ones, on
    /// random and on nearly degenerate inputs.
    #[test]
    fn filters_agree_with_robust() {
        let mut random = uniform_stream(12345);
        let mut point = || DVec3::new(random(), random(), random());
        for k in 0..200_000 {
            let (a, b, c, mut d, mut e) = (point(), point(), point(), point(), point());
            if k % 2 == 1 {
                // Nearly coplanar / cospherical: stress the fallback.
                d = a + (b - a) * 0.3 + (c - a) * 0.6 + DVec3::splat(1e-17 * (k % 7) as f64);
                e = a.lerp(b, 0.5) + DVec3::Z * 1e-16 * (k % 5) as f64;
            }
            let o = robust::orient3d(coord(a), coord(c), coord(b), coord(d));
            assert_eq!(
                orient3d(a, b, c, d).signum() * (o != 0.0) as i32 as f64,
                o.signum() * (o != 0.0) as i32 as f64
            );
            assert_eq!(orient3d(a, b, c, d) == 0.0, o == 0.0);
            let s = robust::insphere(coord(a), coord(c), coord(b), coord(d), coord(e));
            let f = insphere(a, b, c, d, e);
            assert_eq!(f == 0.0, s == 0.0);
            assert!(f == 0.0 || f.signum() == s.signum(), "{k}: {f} vs {s}");
        }
    }

    /// With a static bound for the points' box, the filtered predicates
    /// give the same signs as without, on random and nearly degenerate
    /// points at several scales and offsets (where the static bound is
    /// loose or tight), and the static stage decides most random tests.
    #[test]
    fn static_filter_keeps_signs() {
        let mut random = uniform_stream(4242);
        for (scale, offset) in [(1.0, 0.0), (1e-3, 0.5), (1e4, -3e4), (1e-9, 1.0)] {
            let lo = DVec3::splat(offset);
            let hi = lo + DVec3::splat(scale);
            let filter = StaticFilter::for_box(lo, hi);
            let mut decided = 0;
            for k in 0..50_000 {
                let mut point = || lo + DVec3::new(random(), random(), random()) * scale;
                let (a, b, c, mut d, mut e) = (point(), point(), point(), point(), point());
                if k % 2 == 1 {
                    // Nearly coplanar and nearly cospherical.
                    d = (a + (b - a) * 0.3 + (c - a) * 0.6).clamp(lo, hi);
                    e = a.lerp(b, 0.5);
                }
                let o = orient3d(a, b, c, d);
                assert_eq!(
                    orient3d_filtered(a, b, c, d, filter.orient).signum(),
                    o.signum()
                );
                assert_eq!(
                    orient3d_filtered(a, b, c, d, filter.orient) == 0.0,
                    o == 0.0
                );
                let i = insphere(a, b, c, d, e);
                if let Some(f) = insphere_static(a, b, c, d, e, filter.insphere) {
                    assert_eq!(f.signum(), i.signum(), "{k}");
                }
                decided += usize::from(k % 2 == 0 && i.abs() > filter.insphere);
            }
            // A box the points fill: the static stage decides nearly all.
            assert!(decided > 24_000, "{scale}: {decided}");
        }
        // A box too small or too large for trustworthy bounds disables them.
        assert_eq!(
            StaticFilter::for_box(DVec3::ZERO, DVec3::splat(1e-60)).insphere,
            f64::INFINITY
        );
        assert_eq!(
            StaticFilter::for_box(DVec3::splat(-1e300), DVec3::splat(1e300)).orient,
            f64::INFINITY
        );
    }

    /// The paired determinant is the plain one bit for bit, so the
    /// filter's error bound holds for it and the build's decisions are
    /// unchanged, on random points, nearly degenerate ones, and points at
    /// several scales.
    #[test]
    fn paired_insphere_determinant_is_the_plain_one() {
        let mut random = uniform_stream(777);
        for k in 0..100_000 {
            let scale = [1.0, 1e-7, 3e5][k % 3];
            let mut point = || DVec3::new(random(), random(), random()) * scale;
            let (a, b, c, d, mut e) = (point(), point(), point(), point(), point());
            if k % 2 == 1 {
                e = a.lerp(b, 0.5);
            }
            let plain = insphere_terms(a, b, c, d, e).0;
            assert_eq!(
                insphere_det(a, b, c, d, e).to_bits(),
                plain.to_bits(),
                "{k}"
            );
        }
    }

    #[test]
    fn insphere_signs() {
        let (a, b, c, d) = (DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z);
        assert!(insphere(a, b, c, d, DVec3::splat(0.25)) > 0.0);
        assert!(insphere(a, b, c, d, DVec3::splat(2.0)) < 0.0);
        assert_eq!(insphere(a, b, c, d, DVec3::ONE), 0.0);
    }

    /// The perturbed determinant is a function of the point set: swapping two
    /// rows flips it. Checked on cospherical cube corners, where only the
    /// perturbation decides.
    #[test]
    fn perturbation_is_alternating() {
        let ids = [0u32, 3, 5, 6, 7];
        let pts = ids.map(cube_corner);
        let base = perturbed_sign(pts, ids);
        assert_ne!(base, 0.0);
        for i in 0..5 {
            for j in (i + 1)..5 {
                let (mut p, mut q) = (pts, ids);
                p.swap(i, j);
                q.swap(i, j);
                assert_eq!(
                    perturbed_sign(p, q).signum(),
                    -base.signum(),
                    "swap {i} {j}"
                );
            }
        }
    }

    /// The eight cube corners split into one of the cube's triangulations:
    /// of the two tetrahedra sharing a face, at most one may contain the
    /// other's apex in its perturbed sphere.
    #[test]
    fn perturbation_decides_consistently_across_a_face() {
        let ids: Vec<u32> = (0..8).collect();
        for a in 0..8u32 {
            for b in 0..8 {
                for c in 0..8 {
                    for d in 0..8 {
                        for e in 0..8 {
                            let v = [a, b, c, d, e];
                            let distinct = (0..5).all(|i| (0..i).all(|j| v[i] != v[j]));
                            if !distinct {
                                continue;
                            }
                            let [pa, pb, pc, pd, pe] = v.map(cube_corner);
                            if orient3d(pa, pb, pc, pd) <= 0.0 || orient3d(pb, pa, pc, pe) <= 0.0 {
                                continue;
                            }
                            let idx = v.map(|i| ids[i as usize]);
                            // abcd and bace share the face abc, apexes d and e.
                            let e_in = insphere_sos([pa, pb, pc, pd, pe], idx);
                            let d_in = insphere_sos(
                                [pb, pa, pc, pe, pd],
                                [idx[1], idx[0], idx[2], idx[4], idx[3]],
                            );
                            assert_eq!(e_in, d_in, "{v:?}");
                        }
                    }
                }
            }
        }
    }
}
