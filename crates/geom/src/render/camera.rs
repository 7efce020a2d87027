//! Camera placement: a viewing direction from azimuth and elevation around
//! the scene's up axis, and a projection whose zoom and offset are fitted so
//! that the drawn geometry fills the frame with a small margin.

use super::{Projection, RenderOptions, UpAxis};
use glam::DVec3;

/// Fraction of the frame left free on each side.
const MARGIN: f64 = 0.06;
/// Vertical field of view of the perspective camera, in degrees. Narrow, so
/// shapes look natural rather than wide-angle distorted.
const FIELD_OF_VIEW_DEG: f64 = 28.0;

/// A vertex on screen: `x`, `y` in samples (y grows downwards), `depth`
/// along the viewing axis in scene units (always positive), and `inv_w`, the weight that
/// makes attribute interpolation perspective-correct (1/depth for a
/// perspective camera, 1 for an orthographic one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ScreenPoint {
    pub x: f64,
    pub y: f64,
    pub depth: f64,
    pub inv_w: f64,
}

/// An orthonormal view frame plus the fitted projection. The camera works
/// in scene units: world coordinates moved to the centre of the drawn
/// geometry and divided by its bounding radius, so depths stay near 1 for
/// any input scale (they go into an `f32` depth buffer).
#[derive(Clone, Debug)]
pub(crate) struct Camera {
    /// Screen right, screen up and the direction from the scene to the eye.
    pub right: DVec3,
    pub up: DVec3,
    pub back: DVec3,
    /// World centre and 1 / world radius of the scene.
    center: DVec3,
    inv_radius: f64,
    /// Eye position in scene units.
    eye: DVec3,
    perspective: bool,
    /// Samples per unit of image-plane coordinate.
    focal: f64,
    /// Sample position of the image-plane origin.
    cx: f64,
    cy: f64,
}

/// World axes (right, up, front) of a scene with the given up axis. Right
/// handed: right × up = front.
fn world_axes(up: UpAxis) -> (DVec3, DVec3, DVec3) {
    match up {
        UpAxis::Y => (DVec3::X, DVec3::Y, DVec3::Z),
        UpAxis::Z => (DVec3::X, DVec3::Z, DVec3::NEG_Y),
    }
}

/// View frame (right, up, back) for azimuth/elevation in degrees. Azimuth 0
/// and elevation 0 look at the front of the scene; positive azimuth swings
/// the eye towards the scene's right, positive elevation raises it. Written
/// in closed form so that it stays well defined straight above or below.
fn view_frame(azimuth_deg: f64, elevation_deg: f64, up_axis: UpAxis) -> (DVec3, DVec3, DVec3) {
    let (r, u, f) = world_axes(up_axis);
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    let (se, ce) = elevation_deg.to_radians().sin_cos();
    let horizontal = sa * r + ca * f;
    let back = ce * horizontal + se * u;
    let right = ca * r - sa * f;
    let up = back.cross(right);
    (right, up, back)
}

impl Camera {
    /// A camera looking at the points selected by `used` from the options'
    /// direction, zoomed and shifted so their projection is centred in a
    /// `width` × `height` sample frame.
    pub fn fit(
        points: &[DVec3],
        used: &[bool],
        options: &RenderOptions,
        width: f64,
        height: f64,
    ) -> Camera {
        let (right, up, back) = view_frame(options.azimuth_deg, options.elevation_deg, options.up);
        let (center, radius) = bounding_sphere(points, used);
        let perspective = options.projection == Projection::Perspective;
        let distance = if perspective {
            1.0 / (0.5 * FIELD_OF_VIEW_DEG.to_radians()).sin()
        } else {
            2.0
        };
        let mut camera = Camera {
            right,
            up,
            back,
            center,
            inv_radius: 1.0 / radius,
            eye: back * distance,
            perspective,
            focal: 1.0,
            cx: 0.0,
            cy: 0.0,
        };
        let plane_radius = if perspective { 1.0 / distance } else { 1.0 };
        camera.fit_plane(points, used, plane_radius, width, height);
        camera
    }

    /// A world point in scene units.
    fn to_scene(&self, p: DVec3) -> DVec3 {
        (p - self.center) * self.inv_radius
    }

    /// A world length in scene units.
    pub fn scene_length(&self, world: f64) -> f64 {
        world * self.inv_radius
    }

    /// Image-plane coordinates (u right, v up) and depth of a world point.
    fn plane(&self, p: DVec3) -> (f64, f64, f64) {
        let rel = self.to_scene(p) - self.eye;
        let depth = -rel.dot(self.back);
        let (u, v) = (rel.dot(self.right), rel.dot(self.up));
        if self.perspective {
            (u / depth, v / depth, depth)
        } else {
            (u, v, depth)
        }
    }

    /// Choose zoom and offset from the extent of the projected points;
    /// `plane_radius` (the bounding sphere on the image plane) is the fallback
    /// when the extent is nil in both directions (a single point).
    fn fit_plane(
        &mut self,
        points: &[DVec3],
        used: &[bool],
        plane_radius: f64,
        width: f64,
        height: f64,
    ) {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (p, _) in points.iter().zip(used).filter(|(_, &u)| u) {
            let (u, v, _) = self.plane(*p);
            lo = [lo[0].min(u), lo[1].min(v)];
            hi = [hi[0].max(u), hi[1].max(v)];
        }
        let usable = [width * (1.0 - 2.0 * MARGIN), height * (1.0 - 2.0 * MARGIN)];
        let tiny = 1e-9 * plane_radius;
        let focal = (0..2)
            .filter(|&a| hi[a] - lo[a] > tiny)
            .map(|a| usable[a] / (hi[a] - lo[a]))
            .fold(f64::INFINITY, f64::min);
        self.focal = if focal.is_finite() {
            focal
        } else {
            usable[0].min(usable[1]) / (2.0 * plane_radius)
        };
        self.cx = 0.5 * width - self.focal * 0.5 * (lo[0] + hi[0]);
        self.cy = 0.5 * height + self.focal * 0.5 * (lo[1] + hi[1]);
    }

    /// Where a world point lands on screen.
    pub fn project(&self, p: DVec3) -> ScreenPoint {
        let (u, v, depth) = self.plane(p);
        ScreenPoint {
            x: self.cx + self.focal * u,
            y: self.cy - self.focal * v,
            depth,
            inv_w: if self.perspective { 1.0 / depth } else { 1.0 },
        }
    }

    /// Unit direction from `p` towards the eye (the viewing direction for an
    /// orthographic camera).
    pub fn towards_eye(&self, p: DVec3) -> DVec3 {
        if self.perspective {
            (self.eye - self.to_scene(p)).normalize_or(self.back)
        } else {
            self.back
        }
    }

    /// Samples per scene unit for something at `depth`: converts sizes
    /// (point spacing) to screen sizes.
    pub fn samples_per_unit(&self, depth: f64) -> f64 {
        if self.perspective {
            self.focal / depth
        } else {
            self.focal
        }
    }
}

/// Centre and radius of the box around the used points (radius 1 when the
/// points coincide, so the camera still has a distance).
fn bounding_sphere(points: &[DVec3], used: &[bool]) -> (DVec3, f64) {
    let bounds =
        crate::Aabb::from_points(points.iter().zip(used).filter(|(_, &u)| u).map(|(p, _)| p));
    let radius = 0.5 * scaled_length(bounds.size());
    let radius = if radius > 0.0 && radius.is_finite() {
        radius
    } else {
        1.0
    };
    (bounds.center(), radius)
}

/// Length of `v` without the underflow or overflow of squaring tiny or
/// huge components.
pub(crate) fn scaled_length(v: DVec3) -> f64 {
    let largest = v.abs().max_element();
    if largest > 0.0 && largest.is_finite() {
        largest * (v / largest).length()
    } else {
        largest
    }
}

/// `v` normalised at any scale (zero for a zero or non-finite vector).
pub(crate) fn scaled_unit(v: DVec3) -> DVec3 {
    let largest = v.abs().max_element();
    if largest > 0.0 && largest.is_finite() {
        (v / largest).normalize_or_zero()
    } else {
        DVec3::ZERO
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_frame_is_orthonormal_and_right_handed() {
        for up in [UpAxis::Y, UpAxis::Z] {
            for (az, el) in [(0.0, 0.0), (35.0, 25.0), (-120.0, 90.0), (200.0, -90.0)] {
                let (r, u, b) = view_frame(az, el, up);
                for v in [r, u, b] {
                    assert!((v.length() - 1.0).abs() < 1e-12);
                }
                assert!(r.dot(u).abs() < 1e-12 && r.dot(b).abs() < 1e-12 && u.dot(b).abs() < 1e-12);
                assert!((r.cross(u) - b).length() < 1e-12);
            }
        }
        // Front view of a y-up scene: looking down -z with x to the right.
        let (r, u, b) = view_frame(0.0, 0.0, UpAxis::Y);
        assert!((r - DVec3::X).length() < 1e-12);
        assert!((u - DVec3::Y).length() < 1e-12);
        assert!((b - DVec3::Z).length() < 1e-12);
        // Elevation 90 looks straight down the up axis.
        let (_, _, b) = view_frame(10.0, 90.0, UpAxis::Z);
        assert!((b - DVec3::Z).length() < 1e-12);
    }

    #[test]
    fn fitted_points_are_centred_inside_the_margin() {
        let points: Vec<DVec3> = (0..50)
            .map(|i| {
                let t = i as f64 * 0.37;
                DVec3::new(3.0 * t.cos(), 1.0 + t.sin(), 0.5 * (2.0 * t).sin())
            })
            .collect();
        let used = vec![true; points.len()];
        for projection in [Projection::Perspective, Projection::Orthographic] {
            let options = RenderOptions {
                projection,
                ..Default::default()
            };
            let cam = Camera::fit(&points, &used, &options, 800.0, 600.0);
            let screen: Vec<ScreenPoint> = points.iter().map(|p| cam.project(*p)).collect();
            let (x0, x1) = screen
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), s| (a.min(s.x), b.max(s.x)));
            let (y0, y1) = screen
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), s| (a.min(s.y), b.max(s.y)));
            assert!(x0 >= 800.0 * MARGIN - 1e-6 && x1 <= 800.0 * (1.0 - MARGIN) + 1e-6);
            assert!(y0 >= 600.0 * MARGIN - 1e-6 && y1 <= 600.0 * (1.0 - MARGIN) + 1e-6);
            assert!(
                ((x0 + x1) / 2.0 - 400.0).abs() < 1e-6 && ((y0 + y1) / 2.0 - 300.0).abs() < 1e-6
            );
            // One of the two directions is filled exactly.
            let fill_x = (x1 - x0) / (800.0 * (1.0 - 2.0 * MARGIN));
            let fill_y = (y1 - y0) / (600.0 * (1.0 - 2.0 * MARGIN));
            assert!((fill_x.max(fill_y) - 1.0).abs() < 1e-9);
            assert!(screen.iter().all(|s| s.depth > 0.0));
        }
    }

    #[test]
    fn a_single_point_lands_in_the_middle() {
        let points = [DVec3::new(5.0, -2.0, 7.0)];
        let cam = Camera::fit(&points, &[true], &RenderOptions::default(), 640.0, 480.0);
        let s = cam.project(points[0]);
        assert!((s.x - 320.0).abs() < 1e-9 && (s.y - 240.0).abs() < 1e-9);
        assert!(s.depth > 0.0 && cam.samples_per_unit(s.depth).is_finite());
    }
}
