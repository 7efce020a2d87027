//! PNG previews: a small software rasterizer for meshes, point clouds and
//! polylines.
//!
//! [`render`] draws a [`Geometry`] into an [`Image`] as seen from a camera at
//! [`RenderOptions::azimuth_deg`] / [`RenderOptions::elevation_deg`] around
//! the scene, zoomed so the geometry fills the frame. Meshes are shaded
//! (smooth or flat, both sides lit, back faces tinted so the inside of an
//! open surface reads as such) with an optional wireframe; point clouds are
//! drawn as round splats sized from the point spacing, shaded by their
//! normals (estimated when the file has none, unless turned off: then as
//! rounded dots) and darkened with depth; polylines as strokes that fade
//! with depth. Supersampling smooths the edges. [`write_png`] and
//! [`read_png`] store and load images.
//!
//! The work is split into horizontal bands drawn in parallel; every band
//! draws its primitives in input order, so the picture is the same for any
//! number of threads.

mod camera;
mod png_file;
mod raster;
mod scene;
mod shade;
#[cfg(test)]
mod tests;

use crate::{GeomError, Geometry};

pub use png_file::{read_png, write_png};

/// Largest accepted image side in pixels.
pub const MAX_SIDE: u32 = 16384;
/// Largest accepted image area in pixels (about 8192 × 8192).
pub const MAX_PIXELS: u64 = 1 << 26;
/// Supersampling is lowered for big images so the sample buffers stay
/// within this many samples.
const MAX_SAMPLES: u64 = 1 << 25;

/// Which world axis points up on screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum UpAxis {
    /// +y up, front towards +z (scanned models such as the Stanford bunny).
    #[default]
    Y,
    /// +z up, front towards −y (CAD models, terrain).
    Z,
}

/// How the 3D scene is flattened onto the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Projection {
    /// A camera with a narrow field of view: natural-looking depth.
    #[default]
    Perspective,
    /// Parallel projection: sizes do not shrink with distance.
    Orthographic,
}

/// How mesh normals are chosen for lighting.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Shading {
    /// Interpolated vertex normals (the file's, else area-weighted averages
    /// of the face normals).
    #[default]
    Smooth,
    /// One normal per triangle: facets show.
    Flat,
}

/// Everything that decides what a preview looks like.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
    /// Camera direction around the up axis, degrees; 0 looks at the front.
    pub azimuth_deg: f64,
    /// Camera height above the horizontal plane, degrees in [−90, 90].
    pub elevation_deg: f64,
    pub up: UpAxis,
    pub projection: Projection,
    pub shading: Shading,
    /// Draw mesh edges over the shaded surface.
    pub wireframe: bool,
    /// Samples per pixel along each axis (1 = no antialiasing, at most 4).
    pub supersample: u32,
    /// Point clouds without normals: estimate normals from neighbours for
    /// shading (true), or draw rounded dots darkened with depth (false,
    /// faster for huge clouds).
    pub estimate_point_normals: bool,
    /// Splat diameter in pixels; `None` sizes splats from the point spacing.
    pub point_size: Option<f64>,
    /// Width of wireframe edges in pixels (polylines are drawn 1.5× wider).
    pub line_width: f64,
    /// sRGB colours.
    pub background: [u8; 3],
    pub surface_color: [u8; 3],
    /// Colour of the back side of faces (seen through holes of open meshes).
    pub back_color: [u8; 3],
    pub wire_color: [u8; 3],
    pub point_color: [u8; 3],
    pub line_color: [u8; 3],
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 800,
            height: 600,
            azimuth_deg: 35.0,
            elevation_deg: 25.0,
            up: UpAxis::Y,
            projection: Projection::Perspective,
            shading: Shading::Smooth,
            wireframe: false,
            supersample: 3,
            estimate_point_normals: true,
            point_size: None,
            line_width: 1.0,
            background: [250, 250, 248],
            surface_color: [178, 192, 212],
            back_color: [214, 170, 138],
            wire_color: [38, 42, 54],
            point_color: [96, 146, 204],
            line_color: [40, 72, 150],
        }
    }
}

impl RenderOptions {
    /// Refuse sizes and angles that cannot make a picture.
    fn validate(&self) -> Result<(), GeomError> {
        let invalid = |msg: String| Err(GeomError::InvalidInput(msg));
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return invalid(format!("image size {w}x{h} is empty"));
        }
        if w > MAX_SIDE || h > MAX_SIDE || w as u64 * h as u64 > MAX_PIXELS {
            return invalid(format!(
                "image size {w}x{h} is too large (at most {MAX_SIDE} pixels per side and {} megapixels)",
                MAX_PIXELS >> 20
            ));
        }
        if !self.azimuth_deg.is_finite() || !(-90.0..=90.0).contains(&self.elevation_deg) {
            return invalid(format!(
                "view azimuth {} / elevation {} degrees: azimuth must be finite, elevation within [-90, 90]",
                self.azimuth_deg, self.elevation_deg
            ));
        }
        if !(1..=4).contains(&self.supersample) {
            return invalid(format!("supersample {} must be 1 to 4", self.supersample));
        }
        if let Some(size) = self.point_size {
            if !(size > 0.0 && size <= 1000.0) {
                return invalid(format!("point size {size} must be in (0, 1000] pixels"));
            }
        }
        if !(self.line_width > 0.0 && self.line_width <= 100.0) {
            return invalid(format!(
                "line width {} must be in (0, 100] pixels",
                self.line_width
            ));
        }
        Ok(())
    }

    /// The supersampling factor actually used: lowered for huge images.
    fn samples_per_side(&self) -> usize {
        let pixels = self.width as u64 * self.height as u64;
        let mut s = self.supersample as u64;
        while s > 1 && pixels * s * s > MAX_SAMPLES {
            s -= 1;
        }
        s as usize
    }
}

/// An RGB8 picture, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// `3 * width * height` bytes: red, green, blue per pixel.
    pub pixels: Vec<u8>,
}

impl Image {
    /// An image filled with one colour.
    pub fn filled(width: u32, height: u32, colour: [u8; 3]) -> Image {
        Image {
            width,
            height,
            pixels: colour.repeat(width as usize * height as usize),
        }
    }

    /// The colour at column `x`, row `y` (panics outside the image, like
    /// slice indexing).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the image"
        );
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
    }
}

/// Draw `geometry` as described by `options`. Triangles make a shaded
/// surface, lines make strokes; a geometry with neither is drawn as a point
/// cloud. Errors (never panics) on empty geometry, out-of-range indices,
/// non-finite coordinates and unusable options.
pub fn render(geometry: &Geometry, options: &RenderOptions) -> Result<Image, GeomError> {
    options.validate()?;
    let scene = scene::Scene::new(geometry, options)?;
    let ss = options.samples_per_side();
    let frame = scene.draw(ss);
    Ok(Image {
        width: options.width,
        height: options.height,
        pixels: frame.downsample(ss),
    })
}
