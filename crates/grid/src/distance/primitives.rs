//! Distances from a point to segments and triangles, and nearest points.

#[inline(always)]
pub(super) fn sub<const D: usize>(a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|k| a[k] - b[k])
}

#[inline(always)]
pub(super) fn dot<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    (0..D).map(|k| a[k] * b[k]).sum()
}

#[inline(always)]
pub(super) fn dist2<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    let d = sub(a, b);
    dot(&d, &d)
}

/// Squared distance from `p` to the segment `a..b` (a point when a = b).
#[inline]
pub fn segment_dist2<const D: usize>(p: &[f64; D], a: &[f64; D], b: &[f64; D]) -> f64 {
    dist2(p, &segment_closest(p, a, b))
}

/// The point of segment `a..b` nearest to `p`.
#[inline]
pub fn segment_closest<const D: usize>(p: &[f64; D], a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    let ab = sub(b, a);
    let len2 = dot(&ab, &ab);
    let t = if len2 > 0.0 {
        (dot(&sub(p, a), &ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    std::array::from_fn(|k| a[k] + t * ab[k])
}

/// Squared distance from `p` to the triangle `a, b, c` (any dimension).
#[inline]
pub fn triangle_dist2<const D: usize>(
    p: &[f64; D],
    a: &[f64; D],
    b: &[f64; D],
    c: &[f64; D],
) -> f64 {
    dist2(p, &triangle_closest(p, a, b, c))
}

/// The point of triangle `a, b, c` nearest to `p`, in any dimension:
/// classify `p` against the Voronoi regions of the corners, edges and face
/// using dot products only; degenerate triangles fall back to their edges.
#[inline]
pub fn triangle_closest<const D: usize>(
    p: &[f64; D],
    a: &[f64; D],
    b: &[f64; D],
    c: &[f64; D],
) -> [f64; D] {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let (d1, d2) = (dot(&ab, &ap), dot(&ac, &ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(&ab, &bp), dot(&ac, &bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(&ab, &cp), dot(&ac, &cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return segment_closest(p, a, b);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return segment_closest(p, a, c);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 >= d3 && d5 >= d6 {
        return segment_closest(p, b, c);
    }
    let sum = va + vb + vc;
    if sum.is_nan() || sum <= 0.0 {
        let edges = [
            segment_closest(p, a, b),
            segment_closest(p, a, c),
            segment_closest(p, b, c),
        ];
        return edges
            .into_iter()
            .min_by(|x, y| dist2(p, x).total_cmp(&dist2(p, y)))
            .unwrap_or(*a);
    }
    let (v, w) = (vb / sum, vc / sum);
    std::array::from_fn(|k| a[k] + v * ab[k] + w * ac[k])
}
