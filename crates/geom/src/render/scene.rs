//! From a checked [`Geometry`] to drawing layers on screen: shaded surface,
//! wireframe and polyline strokes, point splats, each binned into bands.

use super::camera::{scaled_length, scaled_unit, Camera, ScreenPoint};
use super::raster::{bin_by_rows, Band, Frame};
use super::shade::{linear, mix, Lighting};
use super::{RenderOptions, Shading};
use crate::normals::estimate_normals;
use crate::spatial::KdTree;
use crate::{GeomError, Geometry};
use glam::DVec3;
use rayon::prelude::*;
use std::borrow::Cow;

/// Depth slack that lets wireframe edges win against the faces they bound,
/// as a fraction of the scene radius.
const WIRE_DEPTH_SLACK: f64 = 0.006;
/// How much farther geometry fades (strokes) or darkens (splats).
const DEPTH_CUE: f64 = 0.45;
/// Largest automatic splat radius, as a fraction of the shorter image side.
const MAX_SPLAT_FRACTION: f64 = 0.02;
/// Points sampled to estimate the typical spacing of a cloud.
const SPACING_SAMPLES: usize = 2000;
/// Spacing (in scene units, radius 1) assumed when all points coincide.
const FALLBACK_SPACING: f64 = 0.01;
/// Neighbours of the plane fit that estimates missing point normals.
const NORMAL_NEIGHBOURS: usize = 12;
/// Which nearest distinct neighbour measures the spacing.
const SPACING_NEIGHBOURS: usize = 4;

/// A geometry that passed the checks, with the vertices it draws.
pub(crate) struct Scene<'a> {
    geometry: &'a Geometry,
    options: &'a RenderOptions,
    /// Vertices referenced by what is drawn (all of them for a point cloud).
    used: Vec<bool>,
}

impl<'a> Scene<'a> {
    /// Check `geometry` can be drawn: vertices present, indices in range,
    /// drawn coordinates finite.
    pub fn new(geometry: &'a Geometry, options: &'a RenderOptions) -> Result<Scene<'a>, GeomError> {
        let invalid = |msg: String| Err(GeomError::InvalidInput(msg));
        let n = geometry.points.positions.len();
        if n == 0 {
            return invalid("nothing to render: the geometry has no vertices".into());
        }
        if let Some(normals) = &geometry.points.normals {
            if normals.len() != n {
                return invalid(format!("{} normals for {n} vertices", normals.len()));
            }
        }
        let used = used_vertices(geometry)?;
        let positions = &geometry.points.positions;
        if let Some(i) = (0..n).find(|&i| used[i] && !positions[i].is_finite()) {
            return invalid(format!("vertex {i} has a non-finite coordinate"));
        }
        if !used.contains(&true) {
            return invalid("nothing to render: no line has a vertex".into());
        }
        let extent = crate::Aabb::from_points(
            positions
                .iter()
                .zip(&used)
                .filter(|(_, &u)| u)
                .map(|(p, _)| p),
        );
        if !scaled_length(extent.size()).is_finite() {
            return invalid(
                "coordinates are too large to draw (the bounding box overflows)".into(),
            );
        }
        Ok(Scene {
            geometry,
            options,
            used,
        })
    }

    /// Draw into a frame `ss` times the image size along each axis.
    pub fn draw(&self, ss: usize) -> Frame {
        let o = self.options;
        let (w, h) = (o.width as usize * ss, o.height as usize * ss);
        let positions = &self.geometry.points.positions;
        let camera = Camera::fit(positions, &self.used, o, w as f64, h as f64);
        let screen: Vec<ScreenPoint> = positions.par_iter().map(|p| camera.project(*p)).collect();
        let view = View {
            camera: &camera,
            screen: &screen,
            lighting: Lighting::new(&camera),
            depth_range: self.depth_range(&screen),
            ss: ss as f64,
        };
        let mut frame = Frame::new(w, h, o.background);
        let bands = frame.band_count();
        let surface = Surface::build(self, &view, bands);
        let strokes = Strokes::build(self, &view, bands);
        let splats = Splats::build(self, &view, bands);
        frame.draw_bands(|i, band| {
            surface.draw(i, band, &view);
            splats.draw(i, band, &view);
            strokes.draw(i, band, &view);
        });
        frame
    }

    /// Nearest and farthest depth of the drawn vertices.
    fn depth_range(&self, screen: &[ScreenPoint]) -> (f64, f64) {
        screen
            .iter()
            .zip(&self.used)
            .filter(|(_, &u)| u)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (s, _)| {
                (lo.min(s.depth), hi.max(s.depth))
            })
    }

    fn is_point_cloud(&self) -> bool {
        self.geometry.triangles.is_empty() && self.geometry.lines.is_empty()
    }
}

/// Which vertices the triangles and lines use (all for a point cloud);
/// errors on an index out of range.
fn used_vertices(geometry: &Geometry) -> Result<Vec<bool>, GeomError> {
    let n = geometry.points.positions.len();
    if geometry.triangles.is_empty() && geometry.lines.is_empty() {
        return Ok(vec![true; n]);
    }
    let mut used = vec![false; n];
    let mut mark = |what: &str, item: usize, i: u32| {
        let slot = used.get_mut(i as usize).ok_or_else(|| {
            GeomError::InvalidInput(format!(
                "{what} {item} refers to vertex {i}, but there are only {n} vertices"
            ))
        })?;
        *slot = true;
        Ok::<(), GeomError>(())
    };
    for (t, tri) in geometry.triangles.iter().enumerate() {
        tri.iter().try_for_each(|&i| mark("triangle", t, i))?;
    }
    for (l, line) in geometry.lines.iter().enumerate() {
        line.iter().try_for_each(|&i| mark("line", l, i))?;
    }
    Ok(used)
}

/// What every layer needs to know about the view.
struct View<'c> {
    camera: &'c Camera,
    screen: &'c [ScreenPoint],
    lighting: Lighting,
    /// Nearest and farthest drawn depth, for depth cueing.
    depth_range: (f64, f64),
    /// Samples per pixel along an axis.
    ss: f64,
}

impl View<'_> {
    /// 0 at the nearest drawn depth, 1 at the farthest.
    fn depth_fraction(&self, depth: f64) -> f64 {
        let (lo, hi) = self.depth_range;
        if hi > lo {
            ((depth - lo) / (hi - lo)).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

/// Per-triangle lighting facts.
#[derive(Clone, Copy)]
struct Face {
    /// Unit face normal turned towards the viewer.
    normal: DVec3,
    /// Whether the triangle's winding faces the viewer.
    front: bool,
}

/// The shaded triangles.
struct Surface<'a> {
    triangles: &'a [[u32; 3]],
    faces: Vec<Face>,
    /// Vertex normals for smooth shading.
    vertex_normals: Option<Vec<DVec3>>,
    front_base: [f64; 3],
    back_base: [f64; 3],
    bins: Vec<Vec<u32>>,
}

impl<'a> Surface<'a> {
    fn build(scene: &Scene<'a>, view: &View, bands: usize) -> Surface<'a> {
        let g = scene.geometry;
        let triangles = &g.triangles[..];
        let faces = triangles
            .par_iter()
            .map(|t| face_facts(t.map(|i| g.points.positions[i as usize]), view.camera))
            .collect();
        let vertex_normals = match scene.options.shading {
            Shading::Flat => None,
            Shading::Smooth => Some(smooth_normals(g, view.camera)),
        };
        let extents = triangles.iter().map(|t| {
            let ys = t.map(|i| view.screen[i as usize].y);
            (ys[0].min(ys[1]).min(ys[2]), ys[0].max(ys[1]).max(ys[2]))
        });
        Surface {
            triangles,
            faces,
            vertex_normals,
            front_base: linear(scene.options.surface_color),
            back_base: linear(scene.options.back_color),
            bins: bin_by_rows(extents, bands),
        }
    }

    fn draw(&self, band_index: usize, band: &mut Band, view: &View) {
        for &t in &self.bins[band_index] {
            let tri = self.triangles[t as usize];
            let face = self.faces[t as usize];
            let base = if face.front {
                self.front_base
            } else {
                self.back_base
            };
            let corners = tri.map(|i| view.screen[i as usize]);
            match &self.vertex_normals {
                None => band.fill_triangle(&corners, |_| view.lighting.shade(face.normal, base)),
                Some(vn) => {
                    // Vertex normals turned to the viewer's side of the face,
                    // so files whose normals disagree with the winding still
                    // shade correctly.
                    let n = tri.map(|i| {
                        let n = vn[i as usize];
                        if n.dot(face.normal) < 0.0 {
                            -n
                        } else {
                            n
                        }
                    });
                    band.fill_triangle(&corners, |w| {
                        let blended = (w[0] * n[0] + w[1] * n[1] + w[2] * n[2]).normalize_or_zero();
                        let normal = if blended == DVec3::ZERO {
                            face.normal
                        } else {
                            blended
                        };
                        view.lighting.shade(normal, base)
                    });
                }
            }
        }
    }
}

/// Face normal towards the viewer and whether the winding faces the viewer.
fn face_facts(corners: [DVec3; 3], camera: &Camera) -> Face {
    let [a, b, c] = corners;
    // Unit edges first: same direction, no overflow or underflow at
    // extreme coordinate scales.
    let n = scaled_unit(scaled_unit(b - a).cross(scaled_unit(c - a)));
    let to_eye = camera.towards_eye((a + b + c) / 3.0);
    let front = n.dot(to_eye) >= 0.0;
    Face {
        normal: if front { n } else { -n },
        front,
    }
}

/// The file's vertex normals when present and usable, else area-weighted
/// averages of the adjacent face normals (accumulated in triangle order so
/// the result is reproducible).
fn smooth_normals(g: &Geometry, camera: &Camera) -> Vec<DVec3> {
    if let Some(normals) = &g.points.normals {
        if normals
            .iter()
            .all(|n| n.is_finite() && n.length_squared() > 0.0)
        {
            return normals.iter().map(|n| n.normalize()).collect();
        }
    }
    let p = &g.points.positions;
    let mut sum = vec![DVec3::ZERO; p.len()];
    for t in &g.triangles {
        let [a, b, c] = t.map(|i| p[i as usize]);
        // Length = twice the area, in scene units so it cannot underflow.
        let scale = camera.scene_length(1.0);
        let weighted = ((b - a) * scale).cross((c - a) * scale);
        t.iter().for_each(|&i| sum[i as usize] += weighted);
    }
    sum.par_iter_mut().for_each(|n| *n = n.normalize_or_zero());
    sum
}

/// Straight strokes: wireframe edges and polyline segments.
struct Strokes {
    /// Vertex pairs, colour, half width in samples, depth slack.
    segments: Vec<([u32; 2], [u8; 3], f64, f64)>,
    bins: Vec<Vec<u32>>,
}

impl Strokes {
    fn build(scene: &Scene, view: &View, bands: usize) -> Strokes {
        let o = scene.options;
        let g = scene.geometry;
        let slack = WIRE_DEPTH_SLACK; // the scene radius is 1
        let mut segments = Vec::new();
        if o.wireframe {
            let half = 0.5 * o.line_width * view.ss;
            segments.extend(
                unique_edges(&g.triangles)
                    .into_iter()
                    .map(|e| (e, o.wire_color, half, slack)),
            );
        }
        let half = 0.75 * o.line_width * view.ss;
        for line in &g.lines {
            for pair in line.windows(2) {
                let depth = 0.5
                    * (view.screen[pair[0] as usize].depth + view.screen[pair[1] as usize].depth);
                let colour = mix(
                    o.line_color,
                    o.background,
                    DEPTH_CUE * view.depth_fraction(depth),
                );
                segments.push(([pair[0], pair[1]], colour, half, slack));
            }
        }
        let extents = segments.iter().map(|&([a, b], _, half, _)| {
            let (ya, yb) = (view.screen[a as usize].y, view.screen[b as usize].y);
            (ya.min(yb) - half, ya.max(yb) + half)
        });
        let bins = bin_by_rows(extents, bands);
        Strokes { segments, bins }
    }

    fn draw(&self, band_index: usize, band: &mut Band, view: &View) {
        for &s in &self.bins[band_index] {
            let ([a, b], colour, half, slack) = self.segments[s as usize];
            band.stroke(
                &view.screen[a as usize],
                &view.screen[b as usize],
                half,
                slack,
                colour,
            );
        }
    }
}

/// Every triangle edge once, as (smaller, larger) vertex index.
fn unique_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.par_sort_unstable();
    edges.dedup();
    edges
}

/// Round splats for a point cloud.
struct Splats<'a> {
    positions: &'a [DVec3],
    /// The file's normals, or estimated ones, or none (depth shading).
    normals: Option<Cow<'a, [DVec3]>>,
    /// Splat radius in samples, per point (0 for points not drawn).
    radius: Vec<f64>,
    base: [f64; 3],
    bins: Vec<Vec<u32>>,
}

impl<'a> Splats<'a> {
    fn build(scene: &Scene<'a>, view: &View, bands: usize) -> Splats<'a> {
        let g = scene.geometry;
        let positions = &g.points.positions[..];
        let radius = if scene.is_point_cloud() {
            splat_radii(positions, scene.options, view)
        } else {
            Vec::new()
        };
        let extents = radius
            .iter()
            .zip(view.screen)
            .map(|(&r, s)| (s.y - r, s.y + r));
        let normals = match &g.points.normals {
            Some(n) => Some(Cow::Borrowed(&n[..])),
            None if scene.is_point_cloud() && scene.options.estimate_point_normals => {
                Some(Cow::Owned(estimate_normals(positions, NORMAL_NEIGHBOURS)))
            }
            None => None,
        };
        Splats {
            positions,
            normals,
            bins: bin_by_rows(extents, bands),
            radius,
            base: linear(scene.options.point_color),
        }
    }

    fn draw(&self, band_index: usize, band: &mut Band, view: &View) {
        let cam = view.camera;
        for &i in &self.bins[band_index] {
            let i = i as usize;
            let centre = view.screen[i];
            let r = self.radius[i];
            // Size of the splat in the scene, so it can bulge towards the
            // viewer like a small ball and overlapping splats blend smoothly.
            let scene_r = r / cam.samples_per_unit(centre.depth);
            let dim = 1.0 - DEPTH_CUE * view.depth_fraction(centre.depth);
            let base = self.base.map(|c| c * dim);
            let normal = self.normals.as_ref().map(|n| {
                let n = n[i].normalize_or_zero();
                if n.dot(cam.towards_eye(self.positions[i])) < 0.0 {
                    -n
                } else {
                    n
                }
            });
            // With a normal the colour is the same over the whole splat:
            // shade once instead of per sample.
            let flat_colour = normal.map(|n| view.lighting.shade(n, base));
            band.splat(
                &centre,
                r,
                |ox, oy| centre.depth - (1.0 - ox * ox - oy * oy).max(0.0).sqrt() * scene_r,
                |ox, oy| {
                    // Without normals: a gently rounded disk, so each splat
                    // reads as a dot without darkening into a grid pattern.
                    flat_colour.unwrap_or_else(|| {
                        let n = (0.5 * (ox * cam.right + oy * cam.up) + cam.back).normalize();
                        view.lighting.shade(n, base)
                    })
                },
            );
        }
    }
}

/// Splat radius in samples for every point: from the option, or from the
/// typical point spacing, bounded so sparse clouds still look like points.
fn splat_radii(positions: &[DVec3], options: &RenderOptions, view: &View) -> Vec<f64> {
    let ss = view.ss;
    if let Some(size) = options.point_size {
        return vec![0.5 * size * ss; positions.len()];
    }
    let min_r = 0.6 * ss;
    let max_r = (MAX_SPLAT_FRACTION * options.width.min(options.height) as f64 * ss).max(min_r);
    let spacing =
        typical_spacing(positions).map_or(FALLBACK_SPACING, |s| view.camera.scene_length(s));
    // A little over half the spacing so neighbouring splats overlap.
    let scene_r = 0.6 * spacing;
    view.screen
        .par_iter()
        .map(|s| (scene_r * view.camera.samples_per_unit(s.depth)).clamp(min_r, max_r))
        .collect()
}

/// Median distance from a point to its fourth nearest distinct neighbour
/// (or the farthest of fewer), over an evenly strided sample of the cloud;
/// `None` when all points coincide. The fourth rather than the first, so
/// scans with dense rows but sparser columns get splats that close the gaps.
fn typical_spacing(positions: &[DVec3]) -> Option<f64> {
    if positions.len() < 2 {
        return None;
    }
    let tree = KdTree::new(positions);
    let step = (positions.len() / SPACING_SAMPLES).max(1);
    let mut gaps: Vec<f64> = (0..positions.len())
        .step_by(step)
        .collect::<Vec<_>>()
        .par_iter()
        .filter_map(|&i| {
            let distinct: Vec<f64> = tree
                .knn(positions[i], SPACING_NEIGHBOURS + 4)
                .into_iter()
                .map(|n| n.distance)
                .filter(|&d| d > 0.0)
                .take(SPACING_NEIGHBOURS)
                .collect();
            distinct.last().copied()
        })
        .collect();
    if gaps.is_empty() {
        return None;
    }
    let mid = gaps.len() / 2;
    gaps.select_nth_unstable_by(mid, f64::total_cmp);
    Some(gaps[mid])
}
