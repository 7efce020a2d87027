//! Contour stacks for the SVM. Its kernels are as wide as the spacing
//! along a contour, four to twenty times less than the gap between
//! slices: alone, the fit sags between slices and ends flat at the last
//! ones. The fit is given, besides the contours, samples of the surface
//! the contours' own normals describe: between two slices the middle of
//! a Hermite curve from each contour point to the point its tilt leads
//! to on the next slice, and past each end slice a dome that leaves the contour at
//! its tilt and closes over its section. Where a part changes shape
//! between two slices (an ear leaning across them) no contour point has a
//! partner: there the fit is also given samples of the level set's
//! shape-based interpolation between the slices' own 2D shapes.

use surfrecon_geom::fairing::area_weighted_normals;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, PointCloud};
use surfrecon_levelset::reconstruct::{reconstruct_3d, ReconstructParams};
use surfrecon_levelset::slices::{detect_slices, SliceStack};
use surfrecon_levelset::Input;

/// Steepest tilt (axial over in-plane normal component) followed: beyond
/// it the surface is nearly parallel to the slice and the ratio says more
/// about noise than shape (the level set's interpolation uses the same).
const MAX_TILT: f64 = 3.0;
/// A contour point and the one its tilt leads to on the next slice are
/// joined only if, carried half way at their tilts, they land within this
/// share of the gap of each other (else the surface changes shape between
/// the slices: a part begins or ends, and the fit is left to bridge it).
const MATCH_TOLERANCE: f64 = 0.25;
/// ... and their in-plane normals agree to this cosine.
const MATCH_COSINE: f64 = 0.7;
/// A cap closes at most this many gaps past its end slice (a stack sampled
/// at a regular spacing ends within one gap; on average half way).
const CAP_HEIGHT: f64 = 0.5;
/// Samples nearer than this many contour spacings to one kept before are
/// dropped (the arcs of a cap meet over its middle).
const THINNING: f64 = 0.7;
/// Most half-spacing steps inward from a contour point to the middle of
/// its section.
const MAX_MARCH: usize = 2000;
/// Most samples on one cap profile.
const MAX_STEPS: usize = 12;
/// Interpolated samples nearer a slice than this share of the gap are
/// left out: there the contours speak.
const OFF_SLICE: f64 = 0.15;
/// Interpolated samples are thinned to this share of the gap apart.
const INTERPOLATED_SPACING: f64 = 0.3;
/// An interpolated sample is added only where no Hermite sample lies
/// within this share of the gap: the Hermite curves follow round sections
/// more closely (harness tori: CD 1.525 / 1.475‰ with them, 1.58 / 1.62‰
/// with the interpolation alone) and the interpolation follows parts that
/// change shape (bunny: 3.95 → 3.09‰ with both).
const HERMITE_COVER: f64 = 0.5;

/// Whether the domes past the end slices are among the samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum EndCaps {
    Added,
    Left,
}

/// Whether the samples of the level set's interpolation are among them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Interpolated {
    Added,
    Left,
}

/// The samples a stack of oriented contour slices adds to its contours.
pub(crate) struct StackSamples {
    stack: SliceStack,
    /// Of the level set's interpolation between the slices, in the
    /// input's coordinates.
    interpolated: Vec<Sample>,
}

impl StackSamples {
    /// The stack `points` form if they are oriented contour slices; `None`
    /// otherwise (every other input is fitted exactly as before).
    pub(crate) fn of(points: &PointCloud) -> Option<Self> {
        let input = Input {
            points: points.positions.clone(),
            normals: points.normals.clone()?,
            ..Default::default()
        };
        let stack = detect_slices(&input)?;
        if stack.slices.iter().any(|s| !s.is_oriented()) {
            return None;
        }
        let interpolated = interpolated_samples(&input, &stack);
        Some(StackSamples {
            stack,
            interpolated,
        })
    }

    /// `points` with the Hermite samples between (and, with `caps`, past)
    /// the slices and, as `interpolated` says, the interpolation's where
    /// those leave gaps.
    pub(crate) fn joined(
        &self,
        points: &PointCloud,
        caps: EndCaps,
        interpolated: Interpolated,
    ) -> PointCloud {
        let stack = &self.stack;
        let hermite: Vec<Sample> = (stack_samples(stack, caps).into_iter())
            .map(|(p, n)| (unflat(stack, p), unflat(stack, n).normalize_or_zero()))
            .filter(|(p, n)| *n != DVec3::ZERO && p.is_finite())
            .collect();
        let tree = KdTree::new(&hermite.iter().map(|s| s.0).collect::<Vec<_>>());
        let cover = HERMITE_COVER * stack.gap();
        let uncovered = |p: DVec3| tree.nearest(p).is_none_or(|n| n.distance > cover);
        let gaps_filled = (self.interpolated.iter())
            .filter(|_| interpolated == Interpolated::Added)
            .filter(|(p, _)| uncovered(*p));
        let mut joined = points.clone();
        for &(p, n) in hermite.iter().chain(gaps_filled) {
            joined.positions.push(p);
            if let Some(normals) = &mut joined.normals {
                normals.push(n);
            }
        }
        // Per-point values of the contours have no counterpart on the samples.
        joined.scalars = None;
        joined
    }
}

/// Samples of the surface the level set interpolates between the slices'
/// 2D reconstructions ([`surfrecon_levelset::slices`]), away from the
/// slices, thinned; none if it fails.
fn interpolated_samples(input: &Input, stack: &SliceStack) -> Vec<Sample> {
    let Ok(interpolation) = reconstruct_3d(input, &ReconstructParams::default()) else {
        return Vec::new();
    };
    let mesh = interpolation.mesh;
    let normals = area_weighted_normals(&mesh.vertices, &mesh.triangles);
    let gap = stack.gap();
    let off_slices = |p: &DVec3| {
        let along = p[stack.axis];
        (stack.levels.iter()).all(|&level| (along - level).abs() > OFF_SLICE * gap)
    };
    let samples = (mesh.vertices.into_iter().zip(normals))
        .filter(|(p, n)| off_slices(p) && *n != DVec3::ZERO)
        .collect();
    thinned(samples, INTERPOLATED_SPACING * gap)
}

/// Mid-gap samples between each two neighbouring slices and (with `caps`)
/// caps past the two end ones, thinned, in plane coordinates.
fn stack_samples(stack: &SliceStack, caps: EndCaps) -> Vec<Sample> {
    let slices: Vec<Slice> = (stack.slices.iter().zip(&stack.levels))
        .map(|(s, &level)| Slice::new(s, level))
        .collect();
    let mut samples = Vec::new();
    for pair in slices.windows(2) {
        mid_gap_samples(&pair[0], &pair[1], &mut samples);
    }
    let cap_height = CAP_HEIGHT * stack.gap();
    if let (EndCaps::Added, Some(first), Some(last)) = (caps, slices.first(), slices.last()) {
        end_cap_samples(first, -1.0, cap_height, &mut samples);
        end_cap_samples(last, 1.0, cap_height, &mut samples);
    }
    let finest_spacing = slices
        .iter()
        .map(|s| s.spacing)
        .fold(f64::INFINITY, f64::min);
    thinned(samples, THINNING * finest_spacing)
}

/// A sample: position and normal; the Hermite ones in the plane's
/// coordinates (the axis as z, the level added) until [`unflat`], the
/// interpolated ones in the input's.
type Sample = (DVec3, DVec3);

/// `p` in plane coordinates (the stacking axis as z) back in the input's.
fn unflat(stack: &SliceStack, p: DVec3) -> DVec3 {
    let [u, v] = stack.plane_axes();
    let mut out = DVec3::ZERO;
    out[u] = p.x;
    out[v] = p.y;
    out[stack.axis] = p.z;
    out
}

/// One slice's contour points with what the samples need of them.
struct Slice<'a> {
    level: f64,
    points: &'a [DVec3],
    tree: KdTree,
    /// Unit outward direction in the plane of each point's normal.
    outward: Vec<DVec3>,
    /// Axial over in-plane component of each normal: the surface moves
    /// inward by this much per unit along the axis.
    tilt: Vec<f64>,
    /// Median distance between neighbouring contour points.
    spacing: f64,
}

impl<'a> Slice<'a> {
    fn new(slice: &'a Input, level: f64) -> Self {
        let tree = KdTree::new(&slice.points);
        let (outward, tilt) = slice.normals.iter().map(|&n| split_normal(n)).unzip();
        let mut spacings: Vec<f64> = (slice.points.iter())
            .filter_map(|&p| tree.knn(p, 2).get(1).map(|n| n.distance))
            .collect();
        spacings.sort_by(f64::total_cmp);
        let spacing = spacings.get(spacings.len() / 2).copied().unwrap_or(0.0);
        Self {
            level,
            points: &slice.points,
            tree,
            outward,
            tilt,
            spacing,
        }
    }

    /// Where the surface through point `i` meets the plane `ds` along the
    /// axis, following its tilt.
    fn led_to(&self, i: usize, ds: f64) -> DVec3 {
        self.points[i] - ds * self.tilt[i] * self.outward[i]
    }
}

/// A normal's unit in-plane direction and tilt (axial over in-plane
/// component, clamped to [`MAX_TILT`]).
fn split_normal(n: DVec3) -> (DVec3, f64) {
    let flat = DVec3::new(n.x, n.y, 0.0);
    let across = flat.length();
    if across * MAX_TILT <= n.z.abs() {
        let outward = if across > 0.0 {
            flat / across
        } else {
            DVec3::X
        };
        return (outward, MAX_TILT.copysign(n.z));
    }
    (flat / across, n.z / across)
}

/// The point of `b` that contour point `i` of `a` leads to (following its
/// tilt across the gap), if the two agree where the surface crosses the
/// middle of the gap: each point's tilt carried half way lands near the
/// other's. (Carried the whole gap, a tangent overshoots on a curved
/// section four times as far: the lower half of the harness's spikes
/// ball, sliced 0.31 apart, got no mid-gap sample at all.)
fn partner(a: &Slice, i: usize, b: &Slice) -> Option<usize> {
    let gap = b.level - a.level;
    let tolerance = MATCH_TOLERANCE * gap.abs();
    let j = b.tree.nearest(a.led_to(i, gap))?.index;
    let meet = a.led_to(i, 0.5 * gap).distance(b.led_to(j, -0.5 * gap));
    let agree = a.outward[i].dot(b.outward[j]) >= MATCH_COSINE;
    (agree && meet <= tolerance).then_some(j)
}

/// Samples of the Hermite curves joining contour points of `a` to their
/// partners on `b`, one mid-gap per curve. (Samples at the contours'
/// spacing along the axis, up to 12 a curve, held the fit so tightly
/// to the curves that contours where a part ends, with no partners,
/// were left behind: harness fandisk slices with a contour point 9.0%
/// of the diagonal off, bunny 2.8% and genus 2, against 0.3% and genus
/// 1 with one sample.)
fn mid_gap_samples(a: &Slice, b: &Slice, out: &mut Vec<Sample>) {
    for i in 0..a.points.len() {
        if let Some(j) = partner(a, i, b) {
            out.push(hermite(a, i, b, j, 0.5));
        }
    }
}

/// Number of steps of about `spacing` over `length`, 2 to [`MAX_STEPS`].
fn steps_over(length: f64, spacing: f64) -> usize {
    if spacing <= 0.0 {
        return 2;
    }
    ((length / spacing).ceil() as usize).clamp(2, MAX_STEPS)
}

/// The point at `t` (0 at `a`'s point `i`, 1 at `b`'s point `j`) of the
/// cubic that leaves each at its tilt, with the normal of the surface
/// there.
fn hermite(a: &Slice, i: usize, b: &Slice, j: usize, t: f64) -> Sample {
    let gap = b.level - a.level;
    let (p, q) = (a.points[i], b.points[j]);
    // In-plane motion per unit along the axis, times the gap.
    let (mp, mq) = (
        -gap * a.tilt[i] * a.outward[i],
        -gap * b.tilt[j] * b.outward[j],
    );
    let (t2, t3) = (t * t, t * t * t);
    let at = p * (2.0 * t3 - 3.0 * t2 + 1.0)
        + mp * (t3 - 2.0 * t2 + t)
        + q * (3.0 * t2 - 2.0 * t3)
        + mq * (t3 - t2);
    let along = p * (6.0 * t2 - 6.0 * t)
        + mp * (3.0 * t2 - 4.0 * t + 1.0)
        + q * (6.0 * t - 6.0 * t2)
        + mq * (3.0 * t2 - 2.0 * t);
    let outward = (a.outward[i] * (1.0 - t) + b.outward[j] * t).normalize_or_zero();
    let tilt = -along.dot(outward) / gap;
    let position = DVec3::new(at.x, at.y, a.level + t * gap);
    (position, outward + DVec3::Z * tilt)
}

/// Samples of a dome past slice `end` (`side` +1 above it, −1 below):
/// from each of its contour points a circular arc that leaves it at its
/// tilt and ends level over the middle of its section, squashed to close
/// within `max_height`. A sphere's or a round tube's end is closed
/// exactly. (Caps also where a part ends between two slices, closed from
/// the contour points without a partner on the next slice, gave the
/// harness's bunny, sphere and tori 12-36 pieces: a part that only
/// narrows or merges looks the same from one slice.)
fn end_cap_samples(end: &Slice, side: f64, max_height: f64, out: &mut Vec<Sample>) {
    for i in 0..end.points.len() {
        let Some(radius) = half_width(end, i) else {
            continue;
        };
        // Elevation of the normal towards the cap's side; a surface that
        // still widens there is closed as if it stood upright.
        let elevation = (side * end.tilt[i]).atan().max(0.0);
        let (sin_e, cos_e) = elevation.sin_cos();
        let arc_radius = radius / cos_e;
        let height = arc_radius * (1.0 - sin_e);
        let squash = if height > max_height {
            max_height / height
        } else {
            1.0
        };
        let sweep = std::f64::consts::FRAC_PI_2 - elevation;
        let steps = steps_over(arc_radius * sweep, end.spacing);
        let p = end.points[i];
        let outward = end.outward[i];
        for k in 1..=steps {
            let angle = elevation + sweep * k as f64 / steps as f64;
            let (sin_a, cos_a) = angle.sin_cos();
            let inward = arc_radius * (cos_e - cos_a);
            let up = squash * arc_radius * (sin_a - sin_e);
            let position = p - inward * outward + DVec3::Z * (end.level + side * up);
            let normal = outward * (squash * cos_a) + DVec3::Z * (side * sin_a);
            out.push((position, normal));
        }
    }
}

/// Distance inward from contour point `i` to the middle of its section:
/// along its inward direction, where the distance to the contours peaks.
/// (A shrinking disc that must touch the point is thrown off by the
/// slightest error in its normal: a circle's came out 0.09–0.43 for 0.44.)
fn half_width(slice: &Slice, i: usize) -> Option<f64> {
    let p = slice.points[i];
    let inward = -slice.outward[i];
    let step = 0.5 * slice.spacing;
    if step.is_nan() || step <= 0.0 {
        return None;
    }
    let mut best = (0.0, 0.0); // (depth, distance along)
    for k in 1..=MAX_MARCH {
        let along = k as f64 * step;
        let depth = slice.tree.nearest(p + along * inward)?.distance;
        if depth > best.0 {
            best = (depth, along);
        } else if depth < best.0 - 2.0 * step {
            // A ridge much shallower than it is far lies outside.
            return (best.0 >= 0.5 * best.1).then_some(best.1);
        }
    }
    // No ridge: the ray left the section (through a gap, or from a
    // point whose normal lies nearly along the axis).
    None
}

/// `samples` without those nearer than `radius` to one kept before.
fn thinned(samples: Vec<Sample>, radius: f64) -> Vec<Sample> {
    if radius.is_nan() || radius <= 0.0 {
        return samples;
    }
    let cell = |p: DVec3| {
        let c = (p / radius).floor();
        [c.x as i64, c.y as i64, c.z as i64]
    };
    let mut grid: std::collections::HashMap<[i64; 3], Vec<DVec3>> = Default::default();
    let mut kept = Vec::with_capacity(samples.len());
    for (p, n) in samples {
        let c = cell(p);
        let crowded = (-1..=1).any(|x| {
            (-1..=1).any(|y| {
                (-1..=1).any(|z| {
                    grid.get(&[c[0] + x, c[1] + y, c[2] + z])
                        .is_some_and(|v| v.iter().any(|q| q.distance(p) < radius))
                })
            })
        });
        if !crowded {
            grid.entry(c).or_default().push(p);
            kept.push((p, n));
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `count` points of the unit sphere's section at height `z`, with
    /// the sphere's normals, in plane coordinates (as `detect_slices`
    /// gives them).
    fn sphere_section(z: f64, count: usize) -> Input {
        let r = (1.0 - z * z).sqrt();
        let points: Vec<DVec3> = (0..count)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / count as f64;
                DVec3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect();
        Input {
            normals: points.clone(),
            points: points.iter().map(|p| DVec3::new(p.x, p.y, 0.0)).collect(),
            ..Default::default()
        }
    }

    #[test]
    fn sections_of_a_curved_surface_sliced_far_apart_are_joined_on_it() {
        // A unit ball's lower half sliced 0.3 apart (the harness's spikes
        // ball: 0.31): the sections' tilts, carried the whole gap, miss
        // the next section by more than a third of the gap.
        let (za, zb) = (-0.75, -0.45);
        let (a, b) = (sphere_section(za, 200), sphere_section(zb, 240));
        let (a, b) = (Slice::new(&a, za), Slice::new(&b, zb));
        let mut samples = Vec::new();
        mid_gap_samples(&a, &b, &mut samples);
        assert!(
            samples.len() * 10 >= a.points.len() * 9,
            "{} of {} contour points joined",
            samples.len(),
            a.points.len()
        );
        for (p, n) in &samples {
            assert!((p.length() - 1.0).abs() < 0.01, "sample {p} off the sphere");
            assert!(n.normalize().dot(p.normalize()) > 0.99, "normal {n} at {p}");
        }
    }
}
