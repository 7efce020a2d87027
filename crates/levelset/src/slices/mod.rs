//! Parallel contour slices (MRI, CT or serial sections): points and curves
//! that lie on a few parallel planes.
//!
//! Between two slices the data say nothing, and the weighted minimal
//! surface spans the gap with a membrane that sags towards the data and is
//! piecewise flat. For such stacks the surface is instead interpolated
//! between the slices' own shapes ("shape-based interpolation"): each
//! slice's contours are reconstructed as closed curves by the 2D level-set
//! method, each gives a signed distance in its plane, and the 3D field
//! blends the two slices around every point linearly along the stacking
//! axis. A cross-section thus morphs from one contour into the next. Past
//! the end slices the field closes the surface within half a slice gap.

mod joins;

pub(crate) use joins::join_lost_parts;

use crate::reconstruct::{reconstruct_field, Input, ReconstructParams};
use crate::Result;
use rayon::prelude::*;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::DVec3;
use surfrecon_grid::{Field, GridSpec};

/// Most slices a stack may have (more are a dense scan, not a stack).
const MAX_SLICES: usize = 512;
/// Fewest points on a slice.
const MIN_SLICE_POINTS: usize = 8;
/// Cells along the longest axis of the stack by default.
const DEFAULT_RESOLUTION: usize = 128;
/// The outer contour of a slice's 2D reconstruction lies this share of its
/// widest contour gap out, so that it bridges the gap with room to spare.
const GAP_BRIDGE: f64 = 0.6;
/// Least half-width, in cells, of the band around the data that separates
/// the regions whose nesting is counted; it widens to bridge the contours'
/// gaps (as the outer contour does), else every region would leak to the
/// exterior through them. Where an annulus is thinner than the band, its
/// two contours merge into one and its hole cannot be told (points
/// without polylines or normals say no more).
const NESTING_BAND: f64 = 2.0;
/// Points sharing a plane agree to this share of the data's extent.
const PLANE_TOLERANCE: f64 = 1e-9;

/// Points grouped by the plane (perpendicular to `axis`) they lie on.
#[derive(Clone, Debug)]
pub struct SliceStack {
    /// Coordinate axis the planes are perpendicular to.
    pub axis: usize,
    /// Plane positions along `axis`, ascending.
    pub levels: Vec<f64>,
    /// The data of each plane (points and segments), in the plane's
    /// coordinates: the two other axes in order, z = 0. Normals, if the
    /// input has them, are in the same order of axes, with the component
    /// along `axis` as z.
    pub slices: Vec<Input>,
}

impl SliceStack {
    /// The in-plane axes, in order.
    pub fn plane_axes(&self) -> [usize; 2] {
        plane_axes(self.axis)
    }

    /// Median distance between consecutive planes.
    pub fn gap(&self) -> f64 {
        let mut gaps: Vec<f64> = self.levels.windows(2).map(|w| w[1] - w[0]).collect();
        gaps.sort_by(f64::total_cmp);
        gaps[gaps.len() / 2]
    }
}

/// The stack `input` forms, if its points and curves lie on at least two
/// planes perpendicular to one coordinate axis (and the other two axes do
/// not look the same, as voxel centres would). Triangles make no stack.
pub fn detect_slices(input: &Input) -> Option<SliceStack> {
    if !input.triangles.is_empty() {
        return None;
    }
    let vertices: Vec<DVec3> = input
        .points
        .iter()
        .chain(input.segments.iter().flatten())
        .copied()
        .collect();
    if vertices.len() < 2 * MIN_SLICE_POINTS {
        return None;
    }
    let groups: Vec<Option<Vec<f64>>> = (0..3).map(|a| planes(&vertices, a)).collect();
    let sliced: Vec<usize> = (0..3).filter(|&a| groups[a].is_some()).collect();
    let &[axis] = sliced.as_slice() else {
        return None;
    };
    let levels = groups[axis].clone()?;
    let tolerance = plane_tolerance(&vertices, axis);
    let plane_of = |p: &DVec3| levels.partition_point(|&l| l < p[axis] - tolerance);
    let [u, v] = plane_axes(axis);
    let flat = |p: &DVec3| DVec3::new(p[u], p[v], 0.0);
    let mut slices: Vec<Input> = vec![Input::default(); levels.len()];
    let oriented = input.is_oriented();
    for (i, p) in input.points.iter().enumerate() {
        let slice = &mut slices[plane_of(p)];
        slice.points.push(flat(p));
        if oriented {
            let n = input.normals[i];
            slice.normals.push(DVec3::new(n[u], n[v], n[axis]));
        }
    }
    for [a, b] in &input.segments {
        let k = plane_of(a);
        if plane_of(b) != k {
            return None;
        }
        slices[k].segments.push([flat(a), flat(b)]);
    }
    Some(SliceStack {
        axis,
        levels,
        slices,
    })
}

/// The two axes other than `axis`, in order.
fn plane_axes(axis: usize) -> [usize; 2] {
    match axis {
        0 => [1, 2],
        1 => [0, 2],
        _ => [0, 1],
    }
}

fn plane_tolerance(points: &[DVec3], axis: usize) -> f64 {
    let (lo, hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[axis]), hi.max(p[axis]))
        });
    PLANE_TOLERANCE * (hi - lo).max(f64::MIN_POSITIVE)
}

/// Positions of the planes perpendicular to `axis` that hold all
/// `points`, if they are a plausible stack.
fn planes(points: &[DVec3], axis: usize) -> Option<Vec<f64>> {
    let mut values: Vec<f64> = points.iter().map(|p| p[axis]).collect();
    values.sort_by(f64::total_cmp);
    let tolerance = plane_tolerance(points, axis);
    let mut planes: Vec<(f64, usize)> = Vec::new();
    for &x in &values {
        if let Some((level, count)) = planes.last_mut() {
            if x - *level <= tolerance {
                *count += 1;
                continue;
            }
        }
        if planes.len() == MAX_SLICES {
            return None;
        }
        planes.push((x, 1));
    }
    let plausible = planes.len() >= 2
        && planes.len() * 4 * MIN_SLICE_POINTS <= points.len()
        && planes.iter().all(|(_, count)| *count >= MIN_SLICE_POINTS);
    plausible.then(|| planes.into_iter().map(|(level, _)| level).collect())
}

/// The field φ (negative inside) interpolated between the slices' 2D
/// reconstructions on a 3D grid; `params` are used for each slice's 2D
/// level-set run. The spacing comes from `params.resolution` (cells along
/// the longest axis), else [`DEFAULT_RESOLUTION`].
pub fn interpolate_slices(stack: &SliceStack, params: &ReconstructParams) -> Result<Field<3>> {
    let cells = params.resolution.unwrap_or(DEFAULT_RESOLUTION).max(1);
    let gap = stack.gap();
    let (lo, hi) = plane_bounds(&stack.slices);
    let across = stack.levels[stack.levels.len() - 1] - stack.levels[0];
    let spacing = (hi - lo).max_element().max(across) / cells as f64;
    let spec = stack_grid(stack, (lo, hi), spacing, gap)?;
    // The field, its pieces' labels ([`join_lost_parts`]), and each
    // slice's section over the plane.
    spec.check_memory(8 + 4 + 8 * stack.levels.len() / spec.dims[stack.axis].max(1))?;
    let [u, v] = stack.plane_axes();
    let plane = GridSpec::<2> {
        origin: [spec.origin[u], spec.origin[v]],
        spacing,
        dims: [spec.dims[u], spec.dims[v]],
    };
    let sections: Vec<Section> = stack
        .slices
        .iter()
        .map(|slice| Section::new(slice, &plane, params, gap))
        .collect::<Result<_>>()?;
    let values = (0..spec.node_count())
        .into_par_iter()
        .map(|l| {
            let idx = spec.unlinear(l);
            let at = plane.linear([idx[u], idx[v]]);
            let s = spec.origin[stack.axis] + idx[stack.axis] as f64 * spacing;
            blend(&stack.levels, &sections, gap, at, s)
        })
        .collect();
    let mut field = Field { spec, values };
    fill_cavities(&mut field);
    Ok(field)
}

/// Make inside every outside node the grid's border cannot reach (face
/// neighbours): a hole carved in the middle slices but not in the end
/// ones (where an annulus is too thin to tell) would otherwise be a
/// cavity, a second surface hidden inside the first.
fn fill_cavities(field: &mut Field<3>) {
    let spec = field.spec;
    let outside = |v: f64| v >= 0.0;
    let mut reached = vec![false; spec.node_count()];
    let mut queue: std::collections::VecDeque<usize> = (0..spec.node_count())
        .filter(|&l| {
            let idx = spec.unlinear(l);
            (0..3).any(|a| idx[a] == 0 || idx[a] + 1 == spec.dims[a]) && outside(field.values[l])
        })
        .collect();
    for &l in &queue {
        reached[l] = true;
    }
    let strides = spec.strides();
    while let Some(l) = queue.pop_front() {
        let idx = spec.unlinear(l);
        for m in spec.axis_neighbours(l, &idx, &strides) {
            if !reached[m] && outside(field.values[m]) {
                reached[m] = true;
                queue.push_back(m);
            }
        }
    }
    for (v, reached) in field.values.iter_mut().zip(reached) {
        if outside(*v) && !reached {
            *v = -v.max(f64::MIN_POSITIVE);
        }
    }
}

/// One slice's contribution to the field: its 2D signed distance over
/// the plane, and where the data have normals, the slope of the 3D field
/// along the stacking axis (in units of the 2D distance), which turns the
/// linear blend into a cubic one that leaves each slice at the surface's
/// own tilt.
struct Section {
    values: Vec<f64>,
    slopes: Option<Vec<f64>>,
    /// The deepest inside value (the largest -φ), at least 0.
    depth: f64,
}

impl Section {
    fn new(
        slice: &Input,
        plane: &GridSpec<2>,
        params: &ReconstructParams,
        gap: f64,
    ) -> Result<Self> {
        let values = section(slice, plane, params)?;
        let depth = values.iter().fold(0.0f64, |m, &x| m.max(-x));
        let slopes = slice.is_oriented().then(|| axial_slopes(slice, plane, gap));
        Ok(Self {
            values,
            slopes,
            depth,
        })
    }

    fn slope(&self, at: usize) -> Option<f64> {
        self.slopes.as_ref().map(|m| m[at])
    }
}

/// Steepest slope taken from a normal: beyond it the surface is nearly
/// parallel to the slice and the ratio says more about noise than shape.
const MAX_SLOPE: f64 = 3.0;

/// Distance from the data, in slice gaps, at which a node's slope has
/// faded to 0: so far off, the 2D distance no longer measures the distance
/// to the same piece of surface. Not nearer: where the surface is tilted,
/// its cross sections move far across the plane between slices (a tube's
/// top, 3 gaps in a gap), and a slope faded there flattened the cubic back
/// to the linear blend (harness slices rows: sphere CD -43%, bunny -13%).
const SLOPE_FADE_GAPS: f64 = 8.0;

/// At each plane node, the slope ∂φ/∂s the nearest point's normal gives
/// (its axial over its in-plane component), fading to 0 at
/// [`SLOPE_FADE_GAPS`] from the data.
fn axial_slopes(slice: &Input, plane: &GridSpec<2>, gap: f64) -> Vec<f64> {
    let tree = KdTree::new(&slice.points);
    (0..plane.node_count())
        .into_par_iter()
        .map(|l| {
            let p = plane.position(plane.unlinear(l));
            let Some(near) = tree.nearest(DVec3::new(p[0], p[1], 0.0)) else {
                return 0.0;
            };
            let n = slice.normals[near.index];
            let across = n.x.hypot(n.y);
            let slope = if across * MAX_SLOPE > n.z.abs() {
                n.z / across
            } else {
                MAX_SLOPE.copysign(n.z)
            };
            slope * (1.0 - near.distance / (SLOPE_FADE_GAPS * gap)).max(0.0)
        })
        .collect()
}

/// φ at plane node `at` and stacking coordinate `s`: cubic Hermite between
/// the two slices around `s` (linear where they have no slopes); past an
/// end slice, its cap ([`cap`]).
fn blend(levels: &[f64], sections: &[Section], gap: f64, at: usize, s: f64) -> f64 {
    let last = levels.len() - 1;
    if s <= levels[0] {
        return cap(&sections[0], gap, at, levels[0] - s, -1.0);
    }
    if s >= levels[last] {
        return cap(&sections[last], gap, at, s - levels[last], 1.0);
    }
    let k = levels.partition_point(|&l| l <= s) - 1;
    let width = levels[k + 1] - levels[k];
    let t = (s - levels[k]) / width;
    let (a, b) = (&sections[k], &sections[k + 1]);
    let (va, vb) = (a.values[at], b.values[at]);
    let linear = (1.0 - t) * va + t * vb;
    // Without normals nothing tells the tilt: a cubic with zero slopes
    // would stand the surface upright at every slice (waves between them).
    let (Some(ma), Some(mb)) = (a.slope(at), b.slope(at)) else {
        return linear;
    };
    let (t2, t3) = (t * t, t * t * t);
    let cubic = va * (2.0 * t3 - 3.0 * t2 + 1.0)
        + vb * (3.0 * t2 - 2.0 * t3)
        + width * ma * (t3 - 2.0 * t2 + t)
        + width * mb * (t3 - t2);
    // The slices decide the side; the slopes only move the surface where
    // they disagree. (The slopes of the nearest points, which may lie on
    // another part, otherwise carved pits and joined nearby parts by
    // handles: the sliced bunny had genus 3.)
    // Except where both slopes lead the surface towards the node from
    // both slices: a tilted part whose sections do not overlap from one
    // slice to the next (an ear, a cone) is crossed outside both.
    let joins_a_tilted_part = va >= 0.0 && ma < 0.0 && mb > 0.0;
    if (va < 0.0) == (vb < 0.0) && (cubic < 0.0) != (va < 0.0) && !joins_a_tilted_part {
        linear
    } else {
        cubic
    }
}

/// φ at plane node `at`, `beyond` past an end slice (`outward`: +1 past
/// the last, -1 before the first). The cap rises over the slice's section
/// to at most half a gap above its deepest point (less over a section
/// thinner than a gap). A node `d` deep in the section lies under the cap
/// up to the height `h(d/D)` of a profile that leaves the contour at the
/// surface's tilt (the node's slope; straight, as a cone, without normals)
/// and arrives level at the apex: a rounded dome as over a sphere's or a
/// tube's end rather than a cone inside it (harness sphere slices: the
/// caps were 5‰ of the diagonal inside, the slices between 0.2‰). φ scales
/// the height left to the cap so that it equals the section on the slice.
fn cap(section: &Section, gap: f64, at: usize, beyond: f64, outward: f64) -> f64 {
    let v = section.values[at];
    let depth = section.depth.max(f64::MIN_POSITIVE);
    let apex = 0.5 * gap * (depth / gap).min(1.0);
    // The rise over depth `depth` along the contour's tangent, kept where
    // the profile stays monotone (at most 3 apexes); a tilt away from the
    // cap (the surface widening past the slice) starts it at that steepest.
    let tangent = section.slope(at).map(|m| {
        if m * outward > 0.0 {
            (depth / (m * outward)).min(3.0 * apex)
        } else {
            3.0 * apex
        }
    });
    let height = |u: f64| match tangent {
        Some(t) => apex * u * u * (3.0 - 2.0 * u) + t * u * (1.0 - u) * (1.0 - u),
        None => apex * u,
    };
    if v < 0.0 {
        let u = (-v / depth).min(1.0);
        v + beyond * -v / height(u)
    } else {
        // Outside the section, or on its contour: the profile's slope there.
        let rise = tangent.unwrap_or(apex).max(f64::MIN_POSITIVE);
        v + beyond * depth / rise
    }
}

/// The grid over the stack: the slices' extent in the plane (`lo..hi`,
/// plane coordinates), half a gap beyond the end slices along the axis,
/// and a margin of cells around.
fn stack_grid(
    stack: &SliceStack,
    (lo, hi): (DVec3, DVec3),
    spacing: f64,
    gap: f64,
) -> Result<GridSpec<3>> {
    let [u, v] = stack.plane_axes();
    let mut min = [0.0; 3];
    let mut max = [0.0; 3];
    (min[u], min[v], max[u], max[v]) = (lo.x, lo.y, hi.x, hi.y);
    min[stack.axis] = stack.levels[0] - 0.5 * gap;
    max[stack.axis] = stack.levels[stack.levels.len() - 1] + 0.5 * gap;
    Ok(GridSpec::<3>::from_bounds(
        min,
        max,
        surfrecon_grid::GridSize::Spacing(spacing),
        3,
    )?)
}

/// The widest gap along the contours formed by `points` (in a plane): a
/// gap shows as a point whose nearest neighbour on the far side (away from
/// its nearest neighbour) is far. A slice through an open scan has open
/// contours, and the outer distance contour of the 2D reconstruction must
/// bridge their gaps, or the inside leaks out.
pub fn widest_gap(points: &[DVec3]) -> f64 {
    let tree = KdTree::new(points);
    points
        .par_iter()
        .filter_map(|&p| far_side_gap(&tree, points, p))
        .reduce(|| 0.0, f64::max)
}

/// Distance from `p` to the nearest point on the far side of it from its
/// nearest neighbour (coincident points aside); at the edge of a gap that
/// point lies across the gap, beyond many neighbours on the near side, so
/// the search widens until it finds one. `None` at the end of an open
/// curve.
fn far_side_gap(tree: &KdTree, points: &[DVec3], p: DVec3) -> Option<f64> {
    let mut k = 12;
    loop {
        let near = tree.knn(p, k);
        let mut others = near.iter().filter(|n| n.distance > 0.0);
        if let Some(first) = others.next() {
            let towards = points[first.index] - p;
            if let Some(n) = others.find(|n| (points[n.index] - p).dot(towards) < 0.0) {
                return Some(n.distance);
            }
        }
        if near.len() < k {
            return None;
        }
        k *= 4;
    }
}

/// Bounds of the slices' points and segment ends (plane coordinates).
fn plane_bounds(slices: &[Input]) -> (DVec3, DVec3) {
    slices
        .iter()
        .flat_map(vertices)
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        })
}

/// The points and segment ends of a slice.
fn vertices(input: &Input) -> impl Iterator<Item = DVec3> + '_ {
    input
        .points
        .iter()
        .chain(input.segments.iter().flatten())
        .copied()
}

/// The points of a slice and points along its segments, at most `step`
/// apart: what the gaps are measured on.
fn samples(input: &Input, step: f64) -> Vec<DVec3> {
    let mut samples = input.points.clone();
    for [a, b] in &input.segments {
        let n = (a.distance(*b) / step).ceil().max(1.0) as usize;
        samples.extend((0..=n).map(|i| a.lerp(*b, i as f64 / n as f64)));
    }
    samples
}

/// One slice's signed distance at the nodes of `plane`: to its oriented
/// points' contours where it has normals (and no polylines), else to its
/// data reconstructed as closed curves by the 2D level-set method, with
/// the holes that inner contours enclose carved out by the nesting rule.
fn section(slice: &Input, plane: &GridSpec<2>, params: &ReconstructParams) -> Result<Vec<f64>> {
    let samples = samples(slice, 0.5 * plane.spacing);
    let bridge = GAP_BRIDGE * widest_gap(&samples);
    let band = bridge.max(NESTING_BAND * plane.spacing);
    if slice.is_oriented() && slice.segments.is_empty() {
        return Ok(crate::nesting::oriented_section(
            plane,
            &slice.points,
            &slice.normals,
            band,
        ));
    }
    let mut values = level_set_section(slice, plane, params, bridge)?;
    crate::nesting::apply_nesting(&mut values, plane, &samples, band);
    Ok(values)
}

/// The 2D level-set reconstruction of a slice's data, whose outer contour
/// lies `bridge` out, resampled on `plane` (beyond its own grid, growing
/// with the distance to it).
fn level_set_section(
    slice: &Input,
    plane: &GridSpec<2>,
    params: &ReconstructParams,
    bridge: f64,
) -> Result<Vec<f64>> {
    let (lo, hi) = plane_bounds(std::slice::from_ref(slice));
    let extent = (hi - lo).max_element();
    let slice_params = ReconstructParams {
        resolution: Some(((extent / plane.spacing).ceil() as usize).max(8)),
        epsilon: (bridge > 3.0 * plane.spacing).then_some(bridge),
        full_field: true,
        levels: None,
        clean: false,
        ..params.clone()
    };
    let (band, field, _) = reconstruct_field::<2>(slice, &slice_params)?;
    // `full_field` asks for the dense signed distance.
    let field = field.unwrap_or_else(|| band.to_dense());
    Ok((0..plane.node_count())
        .into_par_iter()
        .map(|l| {
            let p = plane.position(plane.unlinear(l));
            let inside: [f64; 2] = std::array::from_fn(|a| {
                let last =
                    field.spec.origin[a] + (field.spec.dims[a] - 1) as f64 * field.spec.spacing;
                p[a].clamp(field.spec.origin[a], last)
            });
            let outside = ((p[0] - inside[0]).powi(2) + (p[1] - inside[1]).powi(2)).sqrt();
            crate::multires::interpolate(&field, inside) + outside
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::TriMesh;

    fn sphere_slices(count: usize, per_slice: usize) -> Vec<DVec3> {
        let mut points = Vec::new();
        for k in 0..count {
            let z = -1.0 + (k as f64 + 0.5) * 2.0 / count as f64;
            let r = (1.0 - z * z).sqrt();
            for i in 0..per_slice {
                let t = i as f64 / per_slice as f64 * std::f64::consts::TAU;
                points.push(DVec3::new(r * t.cos(), r * t.sin(), z));
            }
        }
        points
    }

    /// The stack `input` forms, its blended field and that field's zero set.
    fn blended(input: &Input) -> (SliceStack, Field<3>, TriMesh) {
        let stack = detect_slices(input).expect("a stack");
        let mut field = interpolate_slices(&stack, &ReconstructParams::default()).unwrap();
        join_lost_parts(&mut field, &stack);
        let mesh = surfrecon_grid::marching::marching_cubes(&field, 0.0);
        (stack, field, mesh)
    }

    #[test]
    fn stacks_are_detected_and_other_data_are_not() {
        let stack = detect_slices(&Input::from_points(sphere_slices(10, 100))).expect("a stack");
        assert_eq!((stack.axis, stack.levels.len()), (2, 10));
        assert!(stack.slices.iter().all(|s| s.points.len() == 100));
        assert!((stack.gap() - 0.2).abs() < 1e-12);
        // A scan (points everywhere on the sphere) is no stack.
        let scan = surfrecon_geom::shapes::sample_surface(
            &surfrecon_geom::shapes::icosphere(DVec3::ZERO, 1.0, 4),
            4000,
            3,
        );
        assert!(detect_slices(&Input::from_points(scan.positions)).is_none());
        // Voxel centres lie on few planes along every axis: no stack either.
        let voxels: Vec<DVec3> = (0..1000)
            .map(|i| DVec3::new((i % 10) as f64, (i / 10 % 10) as f64, (i / 100) as f64))
            .collect();
        assert!(detect_slices(&Input::from_points(voxels)).is_none());
    }

    /// The contours of `sphere_slices` as closed polylines.
    fn contour_curves(count: usize, per_slice: usize) -> Input {
        let points = sphere_slices(count, per_slice);
        let segments = points
            .chunks(per_slice)
            .flat_map(|ring| (0..ring.len()).map(move |i| [ring[i], ring[(i + 1) % ring.len()]]))
            .collect();
        Input {
            segments,
            ..Default::default()
        }
    }

    #[test]
    fn the_widest_gap_along_a_contour_is_found() {
        // 400 points on a unit circle with one arc of 0.5 rad left out,
        // each point twice (as where polylines join).
        let points: Vec<DVec3> = (0..400)
            .map(|i| 0.5 + i as f64 / 400.0 * (std::f64::consts::TAU - 0.5))
            .flat_map(|t| [DVec3::new(t.cos(), t.sin(), 0.0); 2])
            .collect();
        let chord = 2.0 * (0.25f64).sin();
        let step = (std::f64::consts::TAU - 0.5) / 400.0;
        assert!(
            (widest_gap(&points) - chord).abs() < step,
            "{}",
            widest_gap(&points)
        );
    }

    #[test]
    fn curves_on_planes_form_a_stack_and_curves_across_them_do_not() {
        let mut curves = contour_curves(8, 40);
        let stack = detect_slices(&curves).expect("a stack");
        assert_eq!(stack.levels.len(), 8);
        assert!(stack.slices.iter().all(|s| s.segments.len() == 40));
        curves
            .segments
            .push([DVec3::new(0.0, 0.0, -0.875), DVec3::new(0.0, 0.0, -0.625)]);
        assert!(detect_slices(&curves).is_none());
    }

    #[test]
    fn sliced_spheres_are_interpolated_between_their_contours() {
        check_sliced_sphere(&Input::from_points(sphere_slices(12, 300)));
        check_sliced_sphere(&contour_curves(12, 60));
    }

    fn check_sliced_sphere(input: &Input) {
        let (stack, field, mesh) = blended(input);
        let topology = surfrecon_geom::metrics::topology(&mesh);
        assert!(topology.watertight && topology.edge_manifold);
        assert_eq!((topology.components, topology.euler), (1, 2));
        // Between the slices the radius is interpolated linearly: within
        // the chord sag of the sphere's profile, away from the poles.
        let h = field.spec.spacing;
        let worst = mesh
            .vertices
            .iter()
            .filter(|v| v.z.abs() <= 0.75)
            .map(|v| (v.length() - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.03 && worst < 2.0 * h, "worst {worst}, h {h}");
        // The caps close within half a gap beyond the end slices.
        let top = mesh.vertices.iter().map(|v| v.z).fold(f64::MIN, f64::max);
        let last = stack.levels[stack.levels.len() - 1];
        assert!(
            top > last && top <= last + 0.5 * stack.gap() + h,
            "top {top}"
        );
    }

    #[test]
    fn oriented_slices_close_a_sphere_with_round_caps() {
        // Ten slices, the end ones half a gap (0.1) below the poles: a cone
        // from the end contour to the pole lay up to 0.025 inside.
        let points = sphere_slices(10, 300);
        let mut input = Input::from_points(points.clone());
        input.normals = points;
        let (_, _, mesh) = blended(&input);
        let off = |v: &DVec3| (v.length() - 1.0).abs();
        let cap = |v: &&DVec3| v.z.abs() > 0.9;
        let worst_cap = mesh
            .vertices
            .iter()
            .filter(cap)
            .map(off)
            .fold(0.0, f64::max);
        let worst = mesh.vertices.iter().map(off).fold(0.0, f64::max);
        assert!(
            worst_cap < 0.01 && worst < 0.01,
            "cap {worst_cap}, all {worst}"
        );
    }

    #[test]
    fn a_tilted_rod_whose_sections_do_not_overlap_stays_one_piece() {
        // Radius 0.05, 60° from the stacking axis: each section (an
        // ellipse 0.2 wide) lies 0.35 beside the previous one.
        let (r, tilt) = (0.05, 60f64.to_radians());
        let axis = DVec3::new(tilt.sin(), 0.0, tilt.cos());
        let mut input = Input::default();
        for k in 0..6 {
            let z = 0.2 * k as f64;
            for i in 0..120 {
                let t = i as f64 / 120.0 * std::f64::consts::TAU;
                let p = DVec3::new(z * tilt.tan() + r / tilt.cos() * t.cos(), r * t.sin(), z);
                input.points.push(p);
                input.normals.push((p - p.dot(axis) * axis).normalize());
            }
        }
        let (_, _, mesh) = blended(&input);
        let topology = surfrecon_geom::metrics::topology(&mesh);
        assert!(topology.watertight && topology.edge_manifold);
        assert_eq!((topology.components, topology.euler), (1, 2));
        // Between the end slices the tube follows the rod.
        let off = |v: &DVec3| ((*v - v.dot(axis) * axis).length() - r).abs();
        let between = |v: &&DVec3| v.z > 0.05 && v.z < 0.95;
        let worst = mesh
            .vertices
            .iter()
            .filter(between)
            .map(off)
            .fold(0.0, f64::max);
        assert!(worst < 0.035, "worst {worst}");
    }

    #[test]
    fn slices_without_normals_interpolate_a_cone_linearly() {
        // A frustum, radius 1 at z = 0 down to 0.4 at z = 2, on 6 slices.
        let radius = |z: f64| 1.0 - 0.3 * z;
        let mut points = Vec::new();
        for k in 0..6 {
            let z = k as f64 * 0.4;
            for i in 0..300 {
                let t = i as f64 / 300.0 * std::f64::consts::TAU;
                points.push(DVec3::new(radius(z) * t.cos(), radius(z) * t.sin(), z));
            }
        }
        let (_, field, mesh) = blended(&Input::from_points(points));
        // Nothing tells a tilt but the slices: the side wall is straight
        // between them (zero slopes at the slices bulged it by up to 0.011).
        let worst = mesh
            .vertices
            .iter()
            .filter(|v| v.z > 0.05 && v.z < 1.95)
            .map(|v| (v.x.hypot(v.y) - radius(v.z)).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.004, "worst {worst}, h {}", field.spec.spacing);
    }

    /// Points on `count` slices (perpendicular to z) of the torus with
    /// major radius 1 and minor radius `r`, with outward normals, unevenly
    /// spaced along the contours (as a scanner's would be).
    fn sliced_torus(count: usize, r: f64) -> Input {
        let mut input = Input::default();
        for k in 0..count {
            let z = r * (-1.0 + (k as f64 + 0.5) * 2.0 / count as f64);
            let w = (r * r - z * z).sqrt();
            for (radius, side) in [(1.0 + w, 1.0), (1.0 - w, -1.0)] {
                for i in 0..200 {
                    let t =
                        (i as f64 + 0.4 * (i as f64 * 2.39).sin()) / 200.0 * std::f64::consts::TAU;
                    let (c, s) = (t.cos(), t.sin());
                    input.points.push(DVec3::new(radius * c, radius * s, z));
                    let tube = DVec3::new(side * w * c, side * w * s, z) / r;
                    input.normals.push(tube.normalize());
                }
            }
        }
        input
    }

    #[test]
    fn normals_keep_the_hole_of_a_sliced_torus_and_its_tilt() {
        let r = 0.35;
        let input = sliced_torus(10, r);
        let (_, _, mesh) = blended(&input);
        let topology = surfrecon_geom::metrics::topology(&mesh);
        assert!(topology.watertight && topology.edge_manifold);
        // The end slices' annuli are thinner than the band that separates
        // regions; without normals the hole was filled there (genus 0).
        assert_eq!((topology.components, topology.euler), (1, 0));
        // The tube between the slices follows its tilt: its distance to the
        // true torus stays well within the gap between slices (0.07).
        let off = |p: &DVec3| ((p.x.hypot(p.y) - 1.0).hypot(p.z) - r).abs();
        let worst = mesh.vertices.iter().map(off).fold(0.0, f64::max);
        let mean = mesh.vertices.iter().map(off).sum::<f64>() / mesh.vertices.len() as f64;
        // Its caps are rounded too (as a cone, the mean was 0.0024).
        assert!(worst < 0.02 && mean < 0.0015, "worst {worst}, mean {mean}");
    }
}
