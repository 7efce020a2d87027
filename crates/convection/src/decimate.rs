//! Decimation of the input points by the paper's two criteria, before the
//! triangulation (the paper decimates on the fly as points join the
//! surface; here the region growing is the same but runs over the input in
//! its given order).
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
}

/// Which points to keep (one flag per point). `normals` are unit vectors,
/// one per point.
pub fn decimate(points: &[DVec3], normals: &[DVec3], settings: &Decimation) -> Vec<bool> {
    let tree = KdTree::new(points);
    let mut keep = vec![true; points.len()];
    let mut decided = vec![false; points.len()];
    for p in 0..points.len() {
        if decided[p] {
            continue;
        }
        decided[p] = true;
        let mut near = tree.within(points[p], settings.radius);
        near.sort_by(|a, b| {
            a.distance
                .total_cmp(&b.distance)
                .then(a.index.cmp(&b.index))
        });
        for q in near.into_iter().map(|n| n.index).filter(|&q| q != p) {
            if decided[q] && keep[q] {
                // Another kept point: the disk reaches no further this way.
                continue;
            }
            if !removable(points, normals, p, q, settings) {
                break;
            }
            keep[q] = false;
            decided[q] = true;
        }
    }
    keep
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
}
