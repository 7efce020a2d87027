//! Nested contours in a plane: which regions they enclose are inside,
//! by the nesting rule, or by the points' normals where they have them.
//!
//! A slice through a torus has two concentric contours; the disk inside
//! the inner one is a hole, but the level set, which tags the exterior
//! from the grid's border, cannot reach it and fills it. Contour stacks
//! follow the nesting rule instead: a region enclosed by an odd number of
//! contours is inside, by an even number outside. The regions are the
//! connected parts of the plane farther than a band from the data; the
//! band's connected parts are the contours; a region's depth is the number
//! of contours crossed from the border. Regions the reconstruction got
//! wrong are carved out (or filled) with the distance to the data, whose
//! zero lies on the contour between them.

use rayon::prelude::*;
use std::collections::{BTreeSet, VecDeque};
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::DVec3;
use surfrecon_grid::GridSpec;

const UNSET: usize = usize::MAX;

/// Re-sign the regions of the 2D field `values` (negative inside, on
/// `plane`) that contradict the nesting of the contours through `samples`
/// (plane coordinates, z = 0); `band` is the half-width around the data
/// that separates regions. Returns how many regions changed side.
pub(crate) fn apply_nesting(
    values: &mut [f64],
    plane: &GridSpec<2>,
    samples: &[DVec3],
    band: f64,
) -> usize {
    if samples.is_empty() {
        return 0;
    }
    let tree = KdTree::new(samples);
    let distance: Vec<f64> = (0..plane.node_count())
        .into_par_iter()
        .map(|l| {
            let p = plane.position(plane.unlinear(l));
            tree.nearest(DVec3::new(p[0], p[1], 0.0))
                .map_or(f64::INFINITY, |n| n.distance)
        })
        .collect();
    let free: Vec<bool> = distance.iter().map(|&d| d > band).collect();
    let (region, regions) = label(plane, |l| free[l], false);
    let (ring, rings) = label(plane, |l| !free[l], true);
    let depth = region_depths(plane, &free, &region, regions, &ring, rings);
    let mut negative = vec![(0usize, 0usize); regions];
    for (l, &r) in region.iter().enumerate() {
        if r != UNSET {
            negative[r].0 += (values[l] < 0.0) as usize;
            negative[r].1 += 1;
        }
    }
    // Regions the border reaches (depth 0) are the level set's own
    // exterior; only enclosed ones are checked.
    let wrong: Vec<bool> = (0..regions)
        .map(|r| {
            depth[r] != UNSET
                && depth[r] > 0
                && (depth[r] % 2 == 1) != (2 * negative[r].0 > negative[r].1)
        })
        .collect();
    if !wrong.contains(&true) {
        return 0;
    }
    let owner = nearest_region(plane, &region);
    for (l, v) in values.iter_mut().enumerate() {
        let r = owner[l];
        if r != UNSET && wrong[r] {
            *v = if depth[r] % 2 == 1 {
                v.min(-distance[l])
            } else {
                v.max(distance[l])
            };
        }
    }
    wrong.iter().filter(|&&w| w).count()
}

/// Points whose tangent lines give a node near the contours its value.
const TANGENT_NEIGHBOURS: usize = 4;

/// The signed distance (negative inside, at the nodes of `plane`) to the
/// contours sampled by `points` (plane coordinates) with outward
/// `normals` (in-plane components in x and y). Within `band` of the
/// points a node takes the mean signed distance to the tangent lines of
/// its nearest points, which is 0 on the contour between samples; where
/// those lines disagree on its side (off a sharp corner), or farther out,
/// the distance to the points with the side that the points' winding
/// number gives (for a region farther than `band`, once, at its node
/// farthest from them). Normals tell a thin annulus from a disk, where
/// the nesting rule, once the band merges its two contours, cannot.
pub(crate) fn oriented_section(
    plane: &GridSpec<2>,
    points: &[DVec3],
    normals: &[DVec3],
    band: f64,
) -> Vec<f64> {
    let tree = KdTree::new(points);
    let outward: Vec<DVec3> = normals
        .iter()
        .map(|n| DVec3::new(n.x, n.y, 0.0).normalize_or_zero())
        .collect();
    let winding = ContourWinding::new(points, &outward, &tree);
    let at = |l: usize| {
        let p = plane.position(plane.unlinear(l));
        DVec3::new(p[0], p[1], 0.0)
    };
    let signed = |l: usize, distance: f64| {
        if winding.at(at(l)) > 0.5 {
            -distance
        } else {
            distance
        }
    };
    // Per node: the distance to the points, and the tangent-line value
    // where their lines agree (NaN where they do not or it is far).
    let near: Vec<(f64, f64)> = (0..plane.node_count())
        .into_par_iter()
        .map(|l| {
            let q = at(l);
            let found = tree.knn(q, TANGENT_NEIGHBOURS);
            let distance = found.first().map_or(f64::INFINITY, |n| n.distance);
            let sides: Vec<f64> = found
                .iter()
                .map(|n| (q - points[n.index]).dot(outward[n.index]))
                .collect();
            let agreed = sides.iter().all(|&x| x > 0.0) || sides.iter().all(|&x| x < 0.0);
            let value = if distance > band {
                f64::NAN
            } else if agreed {
                sides.iter().sum::<f64>() / sides.len() as f64
            } else {
                signed(l, distance)
            };
            (distance, value)
        })
        .collect();
    let (region, regions) = label(plane, |l| near[l].0 > band, false);
    let mut deepest = vec![(f64::NEG_INFINITY, 0usize); regions];
    for (l, &r) in region.iter().enumerate() {
        if r != UNSET && near[l].0 > deepest[r].0 {
            deepest[r] = (near[l].0, l);
        }
    }
    let region_sign: Vec<f64> = deepest.par_iter().map(|&(_, l)| signed(l, 1.0)).collect();
    near.iter()
        .zip(&region)
        .map(|(&(distance, value), &r)| {
            if r == UNSET {
                value
            } else {
                region_sign[r] * distance
            }
        })
        .collect()
}

/// Oriented contour points as short segments along their tangents (each
/// as long as the mean distance to its two nearest neighbours): their
/// winding number is about 1 inside the contours they sample, 0 outside.
struct ContourWinding {
    segments: Vec<(DVec3, DVec3)>,
}

impl ContourWinding {
    fn new(points: &[DVec3], outward: &[DVec3], tree: &KdTree) -> Self {
        let segments = points
            .par_iter()
            .zip(outward)
            .filter(|(_, n)| **n != DVec3::ZERO)
            .map(|(&p, n)| {
                let near = tree.knn(p, 3);
                let length = near.iter().skip(1).map(|m| m.distance).sum::<f64>() / 2.0;
                // Counter-clockwise around the inside when `n` points out.
                let half = 0.5 * length * DVec3::new(-n.y, n.x, 0.0);
                (p - half, p + half)
            })
            .collect();
        Self { segments }
    }

    fn at(&self, q: DVec3) -> f64 {
        let turned: f64 = self
            .segments
            .iter()
            .map(|&(a, b)| {
                let (a, b) = (a - q, b - q);
                (a.x * b.y - a.y * b.x).atan2(a.x * b.x + a.y * b.y)
            })
            .sum();
        turned / std::f64::consts::TAU
    }
}

/// Axis neighbours (and with `diagonal`, the diagonal ones too) of node `l`.
fn neighbours(plane: &GridSpec<2>, l: usize, diagonal: bool) -> impl Iterator<Item = usize> + '_ {
    let [i, j] = plane.unlinear(l).map(|x| x as i64);
    let [nx, ny] = plane.dims.map(|x| x as i64);
    (-1i64..=1)
        .flat_map(move |dj| (-1i64..=1).map(move |di| (di, dj)))
        .filter(move |&(di, dj)| (di, dj) != (0, 0) && (diagonal || di == 0 || dj == 0))
        .filter_map(move |(di, dj)| {
            let (a, b) = (i + di, j + dj);
            (a >= 0 && b >= 0 && a < nx && b < ny).then(|| plane.linear([a as usize, b as usize]))
        })
}

/// Connected components of the nodes where `member` holds (axis or, with
/// `diagonal`, full neighbourhoods): per node its component or UNSET.
fn label(
    plane: &GridSpec<2>,
    member: impl Fn(usize) -> bool,
    diagonal: bool,
) -> (Vec<usize>, usize) {
    let n = plane.node_count();
    let mut id = vec![UNSET; n];
    let mut count = 0;
    for start in 0..n {
        if id[start] != UNSET || !member(start) {
            continue;
        }
        id[start] = count;
        let mut queue = VecDeque::from([start]);
        while let Some(l) = queue.pop_front() {
            for m in neighbours(plane, l, diagonal) {
                if id[m] == UNSET && member(m) {
                    id[m] = count;
                    queue.push_back(m);
                }
            }
        }
        count += 1;
    }
    (id, count)
}

/// Contours crossed from the grid's border to each region (UNSET where
/// no path leads).
fn region_depths(
    plane: &GridSpec<2>,
    free: &[bool],
    region: &[usize],
    regions: usize,
    ring: &[usize],
    rings: usize,
) -> Vec<usize> {
    let mut ring_regions: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); rings];
    let mut region_rings: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); regions];
    let mut depth = vec![UNSET; regions];
    let mut queue = VecDeque::new();
    for l in (0..free.len()).filter(|&l| free[l]) {
        let r = region[l];
        let [i, j] = plane.unlinear(l);
        let on_border = i == 0 || j == 0 || i + 1 == plane.dims[0] || j + 1 == plane.dims[1];
        if on_border && depth[r] == UNSET {
            depth[r] = 0;
            queue.push_back(r);
        }
        for m in neighbours(plane, l, false).filter(|&m| !free[m]) {
            ring_regions[ring[m]].insert(r);
            region_rings[r].insert(ring[m]);
        }
    }
    while let Some(r) = queue.pop_front() {
        for &k in &region_rings[r] {
            for &s in &ring_regions[k] {
                if depth[s] == UNSET {
                    depth[s] = depth[r] + 1;
                    queue.push_back(s);
                }
            }
        }
    }
    depth
}

/// For every node, the region of the nearest region node (grid steps,
/// breadth first from all regions at once); region nodes own themselves.
fn nearest_region(plane: &GridSpec<2>, region: &[usize]) -> Vec<usize> {
    let mut owner = region.to_vec();
    let mut queue: VecDeque<usize> = (0..region.len()).filter(|&l| region[l] != UNSET).collect();
    while let Some(l) = queue.pop_front() {
        for m in neighbours(plane, l, false) {
            if owner[m] == UNSET {
                owner[m] = owner[l];
                queue.push_back(m);
            }
        }
    }
    owner
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(r: f64, n: usize) -> impl Iterator<Item = DVec3> {
        (0..n).map(move |i| {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            DVec3::new(r * t.cos(), r * t.sin(), 0.0)
        })
    }

    #[test]
    fn the_disk_inside_an_annulus_is_carved_out_and_an_island_in_it_filled() {
        let plane = GridSpec::<2> {
            origin: [-1.5, -1.5],
            spacing: 0.02,
            dims: [151, 151],
        };
        // Three nested circles: annulus 0.6..1.2 inside, island r < 0.3.
        let samples: Vec<DVec3> = circle(1.2, 600)
            .chain(circle(0.6, 300))
            .chain(circle(0.3, 150))
            .collect();
        // A "filled disk" field, as the level set gives: inside r < 1.2.
        let mut values: Vec<f64> = (0..plane.node_count())
            .map(|l| {
                let p = plane.position(plane.unlinear(l));
                p[0].hypot(p[1]) - 1.2
            })
            .collect();
        let changed = apply_nesting(&mut values, &plane, &samples, 0.05);
        assert_eq!(changed, 1, "only the hole was wrong");
        let at = |x: f64, y: f64| {
            values[plane.linear([
                ((x + 1.5) / 0.02).round() as usize,
                ((y + 1.5) / 0.02).round() as usize,
            ])]
        };
        assert!(at(0.9, 0.0) < 0.0, "the annulus stays inside");
        assert!(
            at(0.45, 0.0) > 0.0 && at(0.0, 0.5) > 0.0,
            "the hole is outside"
        );
        assert!(at(0.0, 0.0) < 0.0, "the island inside the hole is inside");
        assert!(at(1.4, 0.0) > 0.0);
        // The new boundary sits on the inner circle.
        let crossing = (0..40)
            .map(|k| 0.5 + k as f64 * 0.005)
            .find(|&x| at(x, 0.0) < 0.0)
            .unwrap();
        assert!((crossing - 0.6).abs() < 0.03, "{crossing}");
    }
}
