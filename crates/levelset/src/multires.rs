//! Multiresolution: the dense distance, the tagging and a first evolution
//! run on a coarser grid (1/2^dim of the nodes per level). That evolution
//! erodes parts thinner than its cells, so the tagged inside is put back
//! around the points it left outside ([`restore_near_missed`]); φ is then
//! interpolated to each finer grid, grown to the points still missed
//! ([`grow_to_points`]), and evolved on the finest.

use crate::band::{inside, is_inner, NarrowBand};
use crate::error::Result;
use crate::reinit::reinitialize;
use crate::tagging::{fast_tag_with, Tag, TagStore};
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::DVec3;
use surfrecon_grid::sparse::{BlockGrid, BLOCK};
use surfrecon_grid::spec::for_each_in_box;
use surfrecon_grid::{Field, GridSpec};

/// Grids larger than this (nodes along the longest axis) get a coarse level.
pub const COARSEN_ABOVE: usize = 160;

/// Number of levels for a fine grid: one more per halving needed to bring
/// the longest axis to at most [`COARSEN_ABOVE`] nodes, at most 3.
pub fn auto_levels<const D: usize>(dims: &[usize; D]) -> usize {
    let mut longest = dims.iter().copied().max().unwrap_or(1);
    let mut levels = 1;
    while longest > COARSEN_ABOVE && levels < 3 {
        longest = longest.div_ceil(2);
        levels += 1;
    }
    levels
}

/// The grid with `factor` times the spacing over the same region (same
/// origin, covering at least the fine grid).
pub fn coarsen<const D: usize>(fine: &GridSpec<D>, factor: usize) -> GridSpec<D> {
    GridSpec {
        origin: fine.origin,
        spacing: fine.spacing * factor as f64,
        dims: std::array::from_fn(|a| ((fine.dims[a] - 1).div_ceil(factor) + 1).max(2)),
    }
}

/// Multilinear interpolation of `coarse` at the nodes of `fine` (positions
/// outside the coarse grid take the nearest boundary value).
pub fn upsample<const D: usize>(coarse: &Field<D>, fine: GridSpec<D>) -> Field<D> {
    let values = (0..fine.node_count())
        .into_par_iter()
        .map(|l| interpolate(coarse, fine.position(fine.unlinear(l))))
        .collect();
    Field { spec: fine, values }
}

/// Multilinear interpolation of `field` at world position `p`.
pub fn interpolate<const D: usize>(field: &Field<D>, p: [f64; D]) -> f64 {
    interpolate_with(&field.spec, |idx| field.get(idx), p)
}

/// Multilinear interpolation at world position `p` of the values `get`
/// returns for the nodes of `spec` (positions outside the grid take the
/// nearest boundary value).
pub fn interpolate_with<const D: usize>(
    spec: &GridSpec<D>,
    get: impl Fn([usize; D]) -> f64,
    p: [f64; D],
) -> f64 {
    let g = spec.to_grid(p);
    let mut base = [0usize; D];
    let mut t = [0.0; D];
    for a in 0..D {
        let x = g[a].clamp(0.0, (spec.dims[a] - 1) as f64);
        let i = (x.floor() as usize).min(spec.dims[a] - 2);
        base[a] = i;
        t[a] = x - i as f64;
    }
    let mut sum = 0.0;
    for corner in 0..1usize << D {
        let mut w = 1.0;
        let mut idx = base;
        for a in 0..D {
            if corner >> a & 1 == 1 {
                w *= t[a];
                idx[a] += 1;
            } else {
                w *= 1.0 - t[a];
            }
        }
        sum += w * get(idx);
    }
    sum
}

/// The band of the next finer grid `fine`: φ of `coarse` interpolated on
/// the fine blocks under the coarse blocks (and one coarse node around
/// them), clamped to ±`half_width` and set outside at the border, as a
/// dense upsampling would give there; every other fine block is a tile on
/// the side the coarse φ gives it. Reinitialize before evolving.
pub fn upsample_band<const D: usize>(
    coarse: &NarrowBand<D>,
    fine: GridSpec<D>,
    half_width: f64,
) -> Result<NarrowBand<D>> {
    let mut grid = BlockGrid::new(fine, half_width)?;
    let cspec = *coarse.spec();
    let at = |idx: [usize; D]| interpolate_with(&cspec, |c| coarse.phi.get(c), fine.position(idx));
    let dims = grid.block_dims();
    let coords: Vec<[usize; D]> = (0..dims.iter().product::<usize>())
        .map(|mut b| {
            std::array::from_fn(|a| {
                let c = b % dims[a];
                b /= dims[a];
                c
            })
        })
        .collect();
    let sides: Vec<bool> = coords
        .par_iter()
        .map(|c| inside(at(c.map(|x| x * BLOCK))))
        .collect();
    for (c, &s) in coords.iter().zip(&sides) {
        grid.set_tile_inside(*c, s);
    }
    // A coarse block spans coarse nodes 8c..8c+7, fine nodes 16c..16c+14;
    // with one coarse node around it, fine blocks 2c − 1 ..= 2c + 2.
    for blk in coarse.phi.blocks() {
        let lo = blk.coord.map(|c| (2 * c).saturating_sub(1));
        let hi: [usize; D] = std::array::from_fn(|a| (2 * blk.coord[a] + 2).min(dims[a] - 1));
        let count: usize = (0..D).map(|a| hi[a] - lo[a] + 1).product();
        for mut k in 0..count {
            let c: [usize; D] = std::array::from_fn(|a| {
                let n = hi[a] - lo[a] + 1;
                let x = lo[a] + k % n;
                k /= n;
                x
            });
            grid.allocate(c.map(|x| x * BLOCK));
        }
    }
    grid.blocks_mut().par_iter_mut().for_each(|blk| {
        for local in 0..blk.values.len() {
            let idx = blk.node(local);
            if (0..D).all(|a| idx[a] < fine.dims[a]) {
                blk.values[local] = if is_inner(&fine, idx) {
                    at(idx).clamp(-half_width, half_width)
                } else {
                    half_width
                };
            }
        }
    });
    Ok(NarrowBand::from_grid(grid, half_width))
}

/// Points farther outside the surface than this many cells count as
/// missed ([`grow_to_points`]): a coarser level's zero set is within a
/// coarse cell (two fine cells) of what it reached.
pub const MISSED_CELLS: f64 = 2.0;

/// Grow the surface of `band` to the points it left outside: every point
/// whose φ exceeds [`MISSED_CELLS`] cells gets the ball of `radius` around
/// it added to the inside (φ = min(φ, |x − p| − radius)). A coarse level
/// cuts parts thinner than its cells (the tip of a spike, a fin); their
/// points run in a chain from the body, so balls wider than half the
/// sampling gap join them to it, and the evolution shrinks the tube onto
/// the data. Returns the band (reinitialized) and the number of points.
pub fn grow_to_points<const D: usize>(
    band: NarrowBand<D>,
    points: &[DVec3],
    radius: f64,
) -> (NarrowBand<D>, usize) {
    let spec = *band.spec();
    let beyond = MISSED_CELLS * spec.spacing;
    lower_around_points_outside(band, points, beyond, radius, |idx, p| {
        let x = spec.position(idx);
        (0..D).map(|a| (x[a] - p[a]).powi(2)).sum::<f64>().sqrt() - radius
    })
}

/// Put back, near the points an evolution left outside (φ above
/// `cells` cells at the point), the inside of `before` (the surface the
/// evolution started from, on the same grid): within `radius` of each such
/// point φ becomes min(φ, φ_before). Returns the band and the count.
pub fn restore_near_missed<const D: usize>(
    band: NarrowBand<D>,
    before: &NarrowBand<D>,
    points: &[DVec3],
    cells: f64,
    radius: f64,
) -> (NarrowBand<D>, usize) {
    let beyond = cells * band.spec().spacing;
    lower_around_points_outside(band, points, beyond, radius, |idx, _| before.phi.get(idx))
}

/// Around every point where φ exceeds `beyond`, lowers φ at the inner nodes
/// within `radius` to `value(node, point)` where that is lower,
/// then reinitializes. Returns the band and the count of such points.
fn lower_around_points_outside<const D: usize>(
    band: NarrowBand<D>,
    points: &[DVec3],
    beyond: f64,
    radius: f64,
    value: impl Fn([usize; D], [f64; D]) -> f64,
) -> (NarrowBand<D>, usize) {
    let spec = *band.spec();
    let half_width = band.half_width;
    let missed = points_outside(&band, points, beyond);
    if missed.is_empty() {
        return (band, 0);
    }
    let mut grid = band.phi;
    for p in &missed {
        let Some((lo, hi)) = spec.node_box((*p, *p), radius) else {
            continue;
        };
        for_each_in_box(lo, hi, |&idx| {
            let v = value(idx, *p);
            if v < grid.get(idx) && is_inner(&spec, idx) {
                grid.set(idx, v.clamp(-half_width, half_width));
            }
        });
    }
    let mut band = NarrowBand::from_grid(grid, half_width);
    reinitialize(&mut band);
    (band, missed.len())
}

/// The points where φ (interpolated) exceeds `beyond`.
fn points_outside<const D: usize>(
    band: &NarrowBand<D>,
    points: &[DVec3],
    beyond: f64,
) -> Vec<[f64; D]> {
    points_where(band, points, |phi| phi > beyond)
}

/// The points where φ (interpolated) satisfies `keep`.
fn points_where<const D: usize>(
    band: &NarrowBand<D>,
    points: &[DVec3],
    keep: impl Fn(f64) -> bool + Sync,
) -> Vec<[f64; D]> {
    let spec = *band.spec();
    points
        .par_iter()
        .map(|p| -> [f64; D] { std::array::from_fn(|a| p[a]) })
        .filter(|&p| keep(interpolate_with(&spec, |i| band.phi.get(i), p)))
        .collect()
}

/// Points deeper inside the inherited surface than this many cells count
/// as buried ([`reopen_near_buried`]): like [`MISSED_CELLS`] outside, a
/// coarser zero set is within two fine cells of what it reached.
pub const BURIED_CELLS: f64 = 2.0;

/// Re-open the concavities a coarser level filled in (a narrow wedge
/// between a fin and the body: the coarse tagging stops a coarse cell
/// short of its apex and the fine convection stalls on its bisector, where
/// d has no slope across). Around every point more than [`BURIED_CELLS`]
/// cells inside the surface, the fast tagging runs again on this level's
/// grid, within `radius` of such points, from the outside next to them,
/// on the exact distance to the points (the interpolated coarse distance
/// is off by up to a fine cell, enough to block the walk into a wedge):
/// it turns inside nodes outside only downhill in d and down to d = one
/// cell, so it stops at the data and cannot cross a gap between samples
/// (nor, with `keep_topology`, change the topology). The opened nodes get
/// φ = d; φ elsewhere is kept. Returns the band (reinitialized) and the
/// number of buried points.
pub fn reopen_near_buried<const D: usize>(
    band: NarrowBand<D>,
    points: &[DVec3],
    radius: f64,
    keep_topology: bool,
) -> (NarrowBand<D>, usize) {
    let spec = *band.spec();
    let h = spec.spacing;
    let buried = points_where(&band, points, |phi| phi < -BURIED_CELLS * h);
    if buried.is_empty() {
        return (band, 0);
    }
    let phi_at = |n: usize| band.phi.get(spec.unlinear(n));
    let region = nodes_near(&spec, &buried, radius, |idx| {
        is_inner(&spec, idx) && inside(band.phi.get(idx))
    });
    let distance = distances_to_points(&spec, &region, points);
    let mut tags = LocalTags {
        tags: region.iter().map(|&n| (n, Tag::Interior)).collect(),
        other: |n: usize| {
            if inside(phi_at(n)) {
                Tag::Boundary
            } else {
                Tag::Exterior
            }
        },
    };
    let strides = spec.strides();
    let front: Vec<u32> = region
        .iter()
        .copied()
        .filter(|&n| {
            strides
                .iter()
                .any(|&s| tags.tag(n - s) == Tag::Exterior || tags.tag(n + s) == Tag::Exterior)
        })
        .map(|n| n as u32)
        .collect();
    for &n in &front {
        tags.set_tag(n as usize, Tag::Temporary);
    }
    // The walk reads d only at region nodes.
    let dist = |n: usize| distance.get(&n).copied().unwrap_or(0.0);
    fast_tag_with(&strides, dist, &mut tags, &front, h, keep_topology);
    let opened: Vec<(usize, f64)> = region
        .iter()
        .filter(|&&n| tags.tag(n) == Tag::Exterior)
        .map(|&n| (n, dist(n)))
        .collect();
    if opened.is_empty() {
        return (band, buried.len());
    }
    let half_width = band.half_width;
    let mut grid = band.phi;
    for (n, dn) in opened {
        grid.set(spec.unlinear(n), dn.clamp(0.5 * h, half_width));
    }
    let mut band = NarrowBand::from_grid(grid, half_width);
    reinitialize(&mut band);
    (band, buried.len())
}

/// Distance from each node of `nodes` (linear indices) to the nearest of
/// `points`.
fn distances_to_points<const D: usize>(
    spec: &GridSpec<D>,
    nodes: &[usize],
    points: &[DVec3],
) -> FxHashMap<usize, f64> {
    let tree = KdTree::new(points);
    nodes
        .par_iter()
        .map(|&n| {
            let x = spec.position(spec.unlinear(n));
            let c = |a: usize| if a < D { x[a] } else { 0.0 };
            let q = DVec3::new(c(0), c(1), c(2));
            (n, tree.nearest(q).map_or(f64::INFINITY, |nb| nb.distance))
        })
        .collect()
}

/// Linear indices (sorted) of the nodes within `radius` of any of
/// `centres` that satisfy `keep`. Balls around neighbouring points overlap
/// many times over (45k buried points at 8 cells: 10⁸ visits), so each
/// ball is marked row by row (a run of bits per row along axis 0) in one
/// bit per grid node, in parallel over the centres, and the marks are read
/// back in order, `keep` tested once per marked node: no hashing and no
/// sort.
fn nodes_near<const D: usize>(
    spec: &GridSpec<D>,
    centres: &[[f64; D]],
    radius: f64,
    keep: impl Fn([usize; D]) -> bool + Sync,
) -> Vec<usize> {
    let words: Vec<AtomicU64> = (0..spec.node_count().div_ceil(64))
        .map(|_| AtomicU64::new(0))
        .collect();
    centres.par_iter().for_each(|p| {
        let Some((lo, hi)) = spec.node_box((*p, *p), radius) else {
            return;
        };
        let in_ball = |idx: [usize; D]| {
            let x = spec.position(idx);
            let r2: f64 = (0..D).map(|a| (x[a] - p[a]).powi(2)).sum();
            r2 <= radius * radius
        };
        let mut row_lo = lo;
        row_lo[0] = hi[0];
        for_each_in_box(row_lo, hi, |&row| {
            if let Some((a, b)) = ball_row(spec, p, radius, lo[0], hi[0], row, in_ball) {
                let start = spec.linear(row.map_first(a));
                set_bits(&words, start, start + (b - a));
            }
        });
    });
    words
        .par_iter()
        .enumerate()
        .flat_map_iter(|(w, word)| {
            let mut bits = word.load(Ordering::Relaxed);
            std::iter::from_fn(move || {
                (bits != 0).then(|| {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    w * 64 + b
                })
            })
        })
        .filter(|&l| keep(spec.unlinear(l)))
        .collect()
}

/// Node `idx` with its axis-0 index replaced.
trait MapFirst {
    fn map_first(self, first: usize) -> Self;
}

impl<const D: usize> MapFirst for [usize; D] {
    fn map_first(mut self, first: usize) -> Self {
        self[0] = first;
        self
    }
}

/// The first and last axis-0 index in `lo..=hi` of the row through `row`
/// (its other indices) whose nodes `in_ball` holds, or `None`. Along a row
/// the test grows with the distance from the centre's axis-0 coordinate,
/// so its nodes form one run; the run's ends are estimated from the
/// radius and then settled by `in_ball` itself, so the run is exactly
/// the nodes `in_ball` holds.
fn ball_row<const D: usize>(
    spec: &GridSpec<D>,
    centre: &[f64; D],
    radius: f64,
    lo: usize,
    hi: usize,
    row: [usize; D],
    in_ball: impl Fn([usize; D]) -> bool,
) -> Option<(usize, usize)> {
    let x = spec.position(row);
    let across: f64 = (1..D).map(|a| (x[a] - centre[a]).powi(2)).sum();
    let g = (centre[0] - spec.origin[0]) / spec.spacing;
    let reach = (radius * radius - across).max(0.0).sqrt() / spec.spacing;
    let at = |i: usize| in_ball(row.map_first(i));
    let nearest = (g.round().max(0.0) as usize).clamp(lo, hi);
    let (mut a, mut b) = (
        ((g - reach).ceil().max(0.0) as usize).clamp(lo, hi),
        ((g + reach).floor().max(0.0) as usize).clamp(lo, hi),
    );
    // The run, if any, holds the node nearest the centre or one beside it.
    a = a.min(nearest.saturating_sub(1).max(lo));
    b = b.max((nearest + 1).min(hi));
    while a > lo && at(a - 1) {
        a -= 1;
    }
    while b < hi && at(b + 1) {
        b += 1;
    }
    while a <= b && !at(a) {
        a += 1;
    }
    while b >= a && !at(b) {
        if b == 0 {
            return None;
        }
        b -= 1;
    }
    (a <= b).then_some((a, b))
}

/// Set bits `first..=last` of `words`.
fn set_bits(words: &[AtomicU64], first: usize, last: usize) {
    let (first_word, last_word) = (first / 64, last / 64);
    for (w, word) in words[first_word..=last_word].iter().enumerate() {
        let w = first_word + w;
        let from = if w == first_word { first % 64 } else { 0 };
        let to = if w == last_word { last % 64 } else { 63 };
        let mask = (u64::MAX >> (63 - to)) & (u64::MAX << from);
        word.fetch_or(mask, Ordering::Relaxed);
    }
}

/// Tags of a region's nodes; every other node keeps the side `other`
/// gives it, frozen (inside nodes there are final boundary nodes).
struct LocalTags<F> {
    tags: FxHashMap<usize, Tag>,
    other: F,
}

impl<F: Fn(usize) -> Tag> TagStore for LocalTags<F> {
    fn tag(&self, n: usize) -> Tag {
        self.tags
            .get(&n)
            .copied()
            .unwrap_or_else(|| (self.other)(n))
    }
    fn set_tag(&mut self, n: usize, t: Tag) {
        self.tags.insert(n, t);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nodes_near_match_a_node_by_node_search() {
        let spec = GridSpec::<3> {
            origin: [-0.37, 0.11, -1.3],
            spacing: 0.05,
            dims: [70, 67, 65],
        };
        // Centres anywhere, on nodes, and near the grid's faces (balls cut
        // off by the border).
        let mut centres: Vec<[f64; 3]> = (0..200)
            .map(|i| {
                let t = i as f64;
                let c = |f: f64, a: usize| {
                    spec.origin[a] + (f * t).sin().abs() * spec.spacing * spec.dims[a] as f64
                };
                [c(1.3, 0), c(0.7, 1), c(2.9, 2)]
            })
            .collect();
        centres.push(spec.position([10, 20, 30]));
        centres.push(spec.position([0, 0, 0]));
        centres.push(spec.position([69, 66, 64]));
        let keep = |idx: [usize; 3]| !(idx[0] + 2 * idx[1] + idx[2]).is_multiple_of(3);
        for radius in [0.0, 0.03, 0.05, 0.1234, 0.4] {
            // Node by node over each ball's box of nodes.
            let mut expected = std::collections::BTreeSet::new();
            for p in &centres {
                let Some((lo, hi)) = spec.node_box((*p, *p), radius) else {
                    continue;
                };
                for_each_in_box(lo, hi, |&idx| {
                    let x = spec.position(idx);
                    let r2: f64 = (0..3).map(|a| (x[a] - p[a]).powi(2)).sum();
                    if r2 <= radius * radius && keep(idx) {
                        expected.insert(spec.linear(idx));
                    }
                });
            }
            let expected: Vec<usize> = expected.into_iter().collect();
            assert!(radius < 0.1 || expected.len() > 1000);
            assert_eq!(
                nodes_near(&spec, &centres, radius, keep),
                expected,
                "radius {radius}"
            );
        }
    }

    #[test]
    fn linear_functions_upsample_exactly() {
        let fine = GridSpec::<3> {
            origin: [0.5, -1.0, 2.0],
            spacing: 0.1,
            dims: [21, 17, 10],
        };
        let coarse = coarsen(&fine, 2);
        assert!(coarse
            .max_corner()
            .iter()
            .zip(fine.max_corner())
            .all(|(c, f)| *c >= f - 1e-12));
        let f = |p: [f64; 3]| 2.0 * p[0] - p[1] + 0.5 * p[2] + 1.0;
        let cf = Field {
            spec: coarse,
            values: (0..coarse.node_count())
                .map(|l| f(coarse.position(coarse.unlinear(l))))
                .collect(),
        };
        let up = upsample(&cf, fine);
        for l in 0..fine.node_count() {
            let want = f(fine.position(fine.unlinear(l)));
            assert!((up.values[l] - want).abs() < 1e-9);
        }
    }

    #[test]
    fn sparse_upsampling_equals_dense_upsampling() {
        let coarse_spec = GridSpec::<3> {
            origin: [-1.0; 3],
            spacing: 0.1,
            dims: [21, 19, 23],
        };
        let fine = GridSpec::<3> {
            origin: [-1.0; 3],
            spacing: 0.05,
            dims: [41, 37, 45],
        };
        let sphere = |spec: GridSpec<3>| Field {
            spec,
            values: (0..spec.node_count())
                .map(|l| {
                    let p = spec.position(spec.unlinear(l));
                    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.55
                })
                .collect(),
        };
        let coarse = NarrowBand::from_field(sphere(coarse_spec), 0.3).unwrap();
        let sparse = upsample_band(&coarse, fine, 0.15).unwrap();
        let dense = NarrowBand::from_field(upsample(&coarse.phi.to_dense(), fine), 0.15).unwrap();
        assert!(sparse.block_count() < dense.phi.block_dims().iter().product::<usize>());
        assert_eq!(sparse.phi.to_dense(), dense.phi.to_dense());
        let nodes = |b: &NarrowBand<3>| -> Vec<[usize; 3]> {
            let mut v: Vec<_> = b.active.iter().map(|&k| b.node(k)).collect();
            v.sort_unstable();
            v
        };
        assert_eq!(nodes(&sparse), nodes(&dense));
    }

    #[test]
    fn levels_grow_with_grid_size() {
        assert_eq!(auto_levels(&[100, 80, 60]), 1);
        assert_eq!(auto_levels(&[300, 212, 136]), 2);
        assert_eq!(auto_levels(&[1000, 10]), 3);
    }

    /// A sphere of radius `r` as a band on a small grid.
    fn sphere_band(r: f64) -> NarrowBand<3> {
        let spec = GridSpec::<3> {
            origin: [-1.0; 3],
            spacing: 0.05,
            dims: [41; 3],
        };
        let field = Field {
            spec,
            values: (0..spec.node_count())
                .map(|l| DVec3::from_array(spec.position(spec.unlinear(l))).length() - r)
                .collect(),
        };
        NarrowBand::from_field(field, 0.5).unwrap()
    }

    #[test]
    fn the_inside_before_comes_back_only_around_missed_points() {
        // Evolution shrank a sphere of radius 0.7 to 0.5; one point on the
        // old surface is now missed, one on the new surface is not.
        let (before, after) = (sphere_band(0.7), sphere_band(0.5));
        let missed = DVec3::new(0.7, 0.0, 0.0);
        let reached = DVec3::new(0.0, 0.5, 0.0);
        let (band, count) = restore_near_missed(after, &before, &[missed, reached], 0.5, 0.2);
        assert_eq!(count, 1);
        let phi = |p: DVec3| interpolate_with(band.spec(), |i| band.phi.get(i), p.to_array());
        // Near the missed point the surface is back at 0.7 ...
        assert!(phi(DVec3::new(0.65, 0.0, 0.0)) < 0.0);
        assert!(phi(missed).abs() < 0.05, "{}", phi(missed));
        // ... elsewhere it stays at 0.5.
        assert!(phi(DVec3::new(-0.6, 0.0, 0.0)) > 0.05);
        assert!(phi(DVec3::new(0.0, 0.0, 0.6)) > 0.05);
    }
}
