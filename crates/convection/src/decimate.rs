//! Decimation of the input points by the paper's two criteria, before the
//! triangulation, in input order ([`crate::front`] decimates on the fly, as
//! the paper does, in the order a convection front reaches the points;
//! both grow the same disks, [`remove_around`]).
//!
//! Each point not yet removed is kept and grows a ball over its nearest
//! neighbours, closest first, up to a radius. A neighbour `q` is removed
//! while both hold (`p` the kept point, `n` unit normals, signs ignored):
//! - geometric: `|n(q) · n(p)| > ρ`: the surface barely turns;
//! - topological disk: `|n(p) · (q − p)/|q − p|| < ρ′`: `q` lies along the
//!   tangent plane, not across a thin part or another sheet.
//!
//! The growth stops at the first neighbour failing either, so the removed
//! points form a disk around `p` on its own side of the surface.
//!
//! A [`Brush`] varies the ball radius around a centre (the paper's
//! interactive refinement, §4.3); [`redecimate_region`] decides again only
//! the points inside a brush, for a local update of a reconstruction.

use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::DVec3;

/// Settings of [`decimate`].
#[derive(Clone, Copy, Debug)]
pub struct Decimation {
    /// Largest radius of a decimation ball (absolute length).
    pub radius: f64,
    /// The geometric criterion's cosine ρ (the paper uses 0.9 to 0.98).
    pub geometric: f64,
    /// The topological-disk criterion's cosine ρ′ (paper: 0.95; 1: off).
    pub topological: f64,
    /// A local change of the radius.
    pub brush: Option<Brush>,
}

impl Decimation {
    /// The largest ball radius anywhere (the brush's centre may exceed
    /// `radius`).
    pub fn largest_radius(&self) -> f64 {
        match &self.brush {
            Some(b) => self.radius.max(b.rho_centre),
            None => self.radius,
        }
    }

    /// The decimation ball radius around `p`.
    pub fn radius_at(&self, p: DVec3) -> f64 {
        match &self.brush {
            Some(b) => b.radius_at(p, self.radius),
            None => self.radius,
        }
    }
}

/// The paper's brush: the decimation radius becomes
/// `ρ_loc(p) = ρ + (ρ_c − ρ)/rⁿ · (rⁿ − |p − c|ⁿ)` within distance `r` of
/// the centre `c` (`ρ_c` at the centre, back to `ρ` at distance `r`,
/// smoothly for `n ≥ 2`). `ρ_c > ρ` coarsens, `ρ_c < ρ` refines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Brush {
    pub centre: DVec3,
    /// Reach `r` (absolute length).
    pub radius: f64,
    /// `ρ_c`, the radius at the centre (absolute length).
    pub rho_centre: f64,
    /// `n`, at least 2.
    pub exponent: i32,
}

impl Brush {
    /// `ρ_loc(p)` for the radius `rho` outside the brush.
    pub fn radius_at(&self, p: DVec3, rho: f64) -> f64 {
        let d = p.distance(self.centre);
        if d >= self.radius {
            return rho;
        }
        let rn = self.radius.powi(self.exponent);
        rho + (self.rho_centre - rho) / rn * (rn - d.powi(self.exponent))
    }
}

/// Which points to keep (one flag per point). `normals` are unit vectors,
/// one per point.
pub fn decimate(points: &[DVec3], normals: &[DVec3], settings: &Decimation) -> Vec<bool> {
    let tree = KdTree::new(points);
    let mut keep = vec![true; points.len()];
    let mut decided = vec![false; points.len()];
    grow_disks(&tree, points, normals, settings, &mut keep, &mut decided);
    keep
}

/// Decide again the points within the brush's reach (`settings.brush`,
/// which must be set), given the decision `keep` for all: points outside
/// keep theirs, and kept ones there still stop the disks grown inside.
pub fn redecimate_region(
    points: &[DVec3],
    normals: &[DVec3],
    keep: &[bool],
    settings: &Decimation,
) -> Vec<bool> {
    let Some(brush) = settings.brush else {
        return keep.to_vec();
    };
    let inside = |i: usize| points[i].distance(brush.centre) < brush.radius;
    let mut keep = keep.to_vec();
    let mut decided: Vec<bool> = (0..points.len()).map(|i| !inside(i)).collect();
    for i in (0..points.len()).filter(|&i| inside(i)) {
        keep[i] = true;
    }
    let tree = KdTree::new(points);
    grow_disks(&tree, points, normals, settings, &mut keep, &mut decided);
    keep
}

/// Every undecided point, in input order, is kept and removes its
/// undecided neighbours by the two criteria.
pub(crate) fn grow_disks(
    tree: &KdTree,
    points: &[DVec3],
    normals: &[DVec3],
    settings: &Decimation,
    keep: &mut [bool],
    decided: &mut [bool],
) {
    for p in 0..points.len() {
        if decided[p] {
            continue;
        }
        decided[p] = true;
        remove_around(tree, points, normals, settings, p, keep, decided, |_| {});
    }
}

/// The kept point `p` grows its disk: undecided neighbours within the
/// radius, closest first, are removed until one fails a criterion;
/// `on_remove` hears of each.
#[allow(clippy::too_many_arguments)]
pub(crate) fn remove_around(
    tree: &KdTree,
    points: &[DVec3],
    normals: &[DVec3],
    settings: &Decimation,
    p: usize,
    keep: &mut [bool],
    decided: &mut [bool],
    on_remove: impl FnMut(usize),
) {
    let order = disk_order(tree, points, settings, p);
    grow_disk(
        points, normals, settings, p, &order, keep, decided, on_remove,
    );
}

/// The points within `p`'s decimation radius, closest first (ties by
/// index), `p` left out: the order its disk grows in. It depends on the
/// points only, so it may be found ahead of time (the front finds them in
/// parallel for the points its next steps reach).
pub(crate) fn disk_order(
    tree: &KdTree,
    points: &[DVec3],
    settings: &Decimation,
    p: usize,
) -> Vec<usize> {
    let mut near = tree.within(points[p], settings.radius_at(points[p]));
    near.sort_by(|a, b| {
        a.distance
            .total_cmp(&b.distance)
            .then(a.index.cmp(&b.index))
    });
    near.into_iter()
        .map(|n| n.index)
        .filter(|&q| q != p)
        .collect()
}

/// [`remove_around`] with `p`'s [`disk_order`] given.
#[allow(clippy::too_many_arguments)]
pub(crate) fn grow_disk(
    points: &[DVec3],
    normals: &[DVec3],
    settings: &Decimation,
    p: usize,
    order: &[usize],
    keep: &mut [bool],
    decided: &mut [bool],
    mut on_remove: impl FnMut(usize),
) {
    for &q in order {
        if decided[q] && keep[q] {
            // Another kept point: the disk reaches no further this way.
            continue;
        }
        if !removable(points, normals, p, q, settings) {
            break;
        }
        if !decided[q] {
            on_remove(q);
        }
        keep[q] = false;
        decided[q] = true;
    }
}

fn removable(points: &[DVec3], normals: &[DVec3], p: usize, q: usize, s: &Decimation) -> bool {
    let n = normals[p];
    if normals[q].dot(n).abs() <= s.geometric {
        return false;
    }
    let along = (points[q] - points[p]).normalize_or_zero();
    s.topological >= 1.0 || along == DVec3::ZERO || n.dot(along).abs() < s.topological
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat grid with spacing 1 and normals +z.
    fn grid(n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
        let points: Vec<DVec3> = (0..n * n)
            .map(|i| DVec3::new((i % n) as f64, (i / n) as f64, 0.0))
            .collect();
        let normals = vec![DVec3::Z; points.len()];
        (points, normals)
    }

    #[test]
    fn removed_points_lie_within_the_radius_of_a_kept_point() {
        let (points, normals) = grid(20);
        let settings = Decimation {
            radius: 2.5,
            geometric: 0.9,
            topological: 0.95,
            brush: None,
        };
        let keep = decimate(&points, &normals, &settings);
        let kept: Vec<DVec3> = (0..points.len())
            .filter(|&i| keep[i])
            .map(|i| points[i])
            .collect();
        assert!(kept.len() < points.len() / 4, "{} kept", kept.len());
        for (i, p) in points.iter().enumerate().filter(|(i, _)| !keep[*i]) {
            let nearest = kept.iter().map(|k| k.distance(*p)).fold(f64::MAX, f64::min);
            assert!(nearest <= settings.radius, "point {i} at {nearest}");
        }
    }

    /// A disk's order: every other point within the radius, closest
    /// first, ties (a grid has many) by index.
    #[test]
    fn disk_order_is_the_points_within_the_radius_closest_first() {
        let (points, _) = grid(12);
        let tree = KdTree::new(&points);
        let settings = Decimation {
            radius: 2.3,
            geometric: 0.9,
            topological: 0.95,
            brush: None,
        };
        for p in [0, 17, 77, 143] {
            let mut expected: Vec<(f64, usize)> = (0..points.len())
                .filter(|&q| q != p && points[q].distance(points[p]) <= settings.radius)
                .map(|q| (points[q].distance(points[p]), q))
                .collect();
            expected.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let expected: Vec<usize> = expected.into_iter().map(|(_, q)| q).collect();
            assert_eq!(disk_order(&tree, &points, &settings, p), expected);
        }
    }

    #[test]
    fn opposite_sheet_is_not_decimated_across() {
        // Two parallel grids 0.5 apart: the second lies along the normal of
        // the first, so the topological-disk criterion keeps it whole.
        let (mut points, mut normals) = grid(10);
        let n = points.len();
        let upper: Vec<DVec3> = points
            .iter()
            .map(|&p| p + DVec3::new(0.0, 0.0, 0.5))
            .collect();
        points.extend(upper);
        normals.extend(vec![-DVec3::Z; n]);
        let settings = Decimation {
            radius: 0.6,
            geometric: 0.9,
            topological: 0.95,
            brush: None,
        };
        let keep = decimate(&points, &normals, &settings);
        assert!(keep[n..].iter().all(|&k| k), "the upper sheet lost points");
        let off = Decimation {
            topological: 1.0,
            ..settings
        };
        let keep = decimate(&points, &normals, &off);
        assert!(keep[n..].iter().any(|&k| !k), "without ρ′ it is decimated");
    }

    #[test]
    fn brush_radius_goes_from_the_centre_value_to_rho() {
        let b = Brush {
            centre: DVec3::ZERO,
            radius: 2.0,
            rho_centre: 0.1,
            exponent: 2,
        };
        assert!((b.radius_at(DVec3::ZERO, 0.5) - 0.1).abs() < 1e-12);
        assert_eq!(b.radius_at(DVec3::new(2.0, 0.0, 0.0), 0.5), 0.5);
        assert_eq!(b.radius_at(DVec3::new(0.0, 3.0, 0.0), 0.5), 0.5);
        // 0.5 + (0.1 − 0.5)/4 · (4 − 1) = 0.2 at distance 1.
        assert!((b.radius_at(DVec3::new(0.0, 0.0, 1.0), 0.5) - 0.2).abs() < 1e-12);
        let mut last = 0.0;
        for k in 0..=20 {
            let r = b.radius_at(DVec3::new(k as f64 * 0.1, 0.0, 0.0), 0.5);
            assert!(r >= last, "monotone from the centre out");
            last = r;
        }
    }
}
