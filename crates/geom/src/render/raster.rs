//! The rasterizer: a colour + depth sample buffer cut into horizontal bands
//! that are drawn in parallel. Each band draws every primitive overlapping
//! it in input order, so the picture does not depend on the thread count.

use super::camera::ScreenPoint;
use rayon::prelude::*;

/// Sample rows per band: small enough to balance work across threads, large
/// enough that binning stays cheap.
pub(crate) const BAND_ROWS: usize = 16;

/// The part of the sample buffer one thread draws into: rows
/// `y0 .. y0 + rows` of a `width`-sample-wide frame.
pub(crate) struct Band<'a> {
    y0: usize,
    rows: usize,
    width: usize,
    colour: &'a mut [[u8; 3]],
    depth: &'a mut [f32],
}

/// Interpolated depth and weights for perspective-correct interpolation of
/// the attributes of a triangle's corners.
fn perspective_weights(v: &[ScreenPoint; 3], bary: [f64; 3]) -> (f64, [f64; 3]) {
    let w = [0, 1, 2].map(|i| bary[i] * v[i].inv_w);
    let sum = w[0] + w[1] + w[2];
    let w = w.map(|x| x / sum);
    let depth = w[0] * v[0].depth + w[1] * v[1].depth + w[2] * v[2].depth;
    (depth, w)
}

/// The sample rows `lo ..= hi` (in frame coordinates, clamped to the band)
/// whose centres may lie between `y_min` and `y_max`.
fn row_range(y0: usize, rows: usize, y_min: f64, y_max: f64) -> std::ops::Range<usize> {
    let first = (y_min - 0.5).ceil().max(y0 as f64);
    let end = ((y_max - 0.5).floor() + 1.0).min((y0 + rows) as f64);
    if first < end {
        first as usize..end as usize
    } else {
        0..0 // also for NaN bounds
    }
}

/// Sample columns whose centres lie in `[x_min, x_max]`, clamped to the frame.
fn column_range(width: usize, x_min: f64, x_max: f64) -> std::ops::Range<usize> {
    let first = (x_min - 0.5).ceil().max(0.0);
    let end = ((x_max - 0.5).floor() + 1.0).min(width as f64);
    if first < end {
        first as usize..end as usize
    } else {
        0..0 // also for NaN bounds
    }
}

impl Band<'_> {
    /// Write `colour` at sample (x, y) if `depth` passes the depth test
    /// (`slack` lets lines lying on a surface win against it).
    fn plot(
        &mut self,
        x: usize,
        y: usize,
        depth: f64,
        slack: f64,
        colour: impl FnOnce() -> [u8; 3],
    ) {
        let i = (y - self.y0) * self.width + x;
        if depth < self.depth[i] as f64 + slack {
            if slack == 0.0 {
                self.depth[i] = depth as f32;
            }
            self.colour[i] = colour();
        }
    }

    /// Fill a triangle. `shade` gets the perspective-correct weights of the
    /// three corners at each covered sample.
    pub fn fill_triangle(&mut self, v: &[ScreenPoint; 3], shade: impl Fn([f64; 3]) -> [u8; 3]) {
        let Some(edges) = EdgeFunctions::new(v) else {
            return; // degenerate on screen: seen edge-on, covers nothing
        };
        let (y_min, y_max) = (
            v[0].y.min(v[1].y).min(v[2].y),
            v[0].y.max(v[1].y).max(v[2].y),
        );
        for y in row_range(self.y0, self.rows, y_min, y_max) {
            let py = y as f64 + 0.5;
            let (x_lo, x_hi) = edges.row_span(py);
            for x in column_range(self.width, x_lo, x_hi) {
                let bary = edges.barycentric(x as f64 + 0.5, py);
                // The span is exact up to rounding; recheck at its ends.
                if bary.iter().all(|&b| b >= 0.0) {
                    let (depth, weights) = perspective_weights(v, bary);
                    self.plot(x, y, depth, 0.0, || shade(weights));
                }
            }
        }
    }

    /// Draw a segment as a round-capped stroke `half_width` samples wide.
    /// Samples pass the depth test with `slack` extra depth, so a stroke lying
    /// on a surface shows while strokes behind it stay hidden.
    pub fn stroke(
        &mut self,
        a: &ScreenPoint,
        b: &ScreenPoint,
        half_width: f64,
        slack: f64,
        colour: [u8; 3],
    ) {
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let len2 = dx * dx + dy * dy;
        let r = half_width;
        let (y_min, y_max) = (a.y.min(b.y) - r, a.y.max(b.y) + r);
        let (x_lo, x_hi) = (a.x.min(b.x) - r, a.x.max(b.x) + r);
        for y in row_range(self.y0, self.rows, y_min, y_max) {
            let py = y as f64 + 0.5;
            let (lo, hi) = stroke_row_span(a, dx, dy, len2, r, py);
            for x in column_range(self.width, lo.max(x_lo), hi.min(x_hi)) {
                let px = x as f64 + 0.5;
                let t = if len2 > 0.0 {
                    (((px - a.x) * dx + (py - a.y) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (ex, ey) = (a.x + t * dx - px, a.y + t * dy - py);
                if ex * ex + ey * ey <= r * r {
                    let q = (1.0 - t) * a.inv_w + t * b.inv_w;
                    let depth = ((1.0 - t) * a.inv_w * a.depth + t * b.inv_w * b.depth) / q;
                    self.plot(x, y, depth, slack, || colour);
                }
            }
        }
    }

    /// Draw a round splat of `radius` samples centred at `c`. `depth` and
    /// `colour` get the offset from the centre in units of the radius (x
    /// right, y up); the colour is only computed where the depth test passes.
    pub fn splat(
        &mut self,
        c: &ScreenPoint,
        radius: f64,
        depth: impl Fn(f64, f64) -> f64,
        colour: impl Fn(f64, f64) -> [u8; 3],
    ) {
        for y in row_range(self.y0, self.rows, c.y - radius, c.y + radius) {
            let oy = (c.y - (y as f64 + 0.5)) / radius;
            for x in column_range(self.width, c.x - radius, c.x + radius) {
                let ox = (x as f64 + 0.5 - c.x) / radius;
                if ox * ox + oy * oy <= 1.0 {
                    self.plot(x, y, depth(ox, oy), 0.0, || colour(ox, oy));
                }
            }
        }
    }
}

/// Barycentric coordinates of a screen triangle as three functions linear
/// in x and y, normalised by the area so that inside means all >= 0.
struct EdgeFunctions {
    /// Per corner: value = a * x + b * y + c.
    coefficients: [[f64; 3]; 3],
}

impl EdgeFunctions {
    /// `None` for a triangle of (nearly) no area on screen.
    fn new(v: &[ScreenPoint; 3]) -> Option<EdgeFunctions> {
        // Corner i's weight is the edge function of the opposite edge.
        let edge = |p: &ScreenPoint, q: &ScreenPoint| {
            let (a, b) = (-(q.y - p.y), q.x - p.x);
            [a, b, -(a * p.x + b * p.y)]
        };
        let raw = [edge(&v[1], &v[2]), edge(&v[2], &v[0]), edge(&v[0], &v[1])];
        let [a, b, c] = raw[0];
        let area = a * v[0].x + b * v[0].y + c;
        if area.is_nan() || area.abs() <= 1e-12 {
            return None;
        }
        Some(EdgeFunctions {
            coefficients: raw.map(|e| e.map(|k| k / area)),
        })
    }

    fn barycentric(&self, x: f64, y: f64) -> [f64; 3] {
        self.coefficients.map(|[a, b, c]| a * x + b * y + c)
    }

    /// The x interval of row `y` where every weight is >= 0.
    fn row_span(&self, y: f64) -> (f64, f64) {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for [a, b, c] in self.coefficients {
            let rest = b * y + c; // weight = a * x + rest >= 0
            if a > 0.0 {
                lo = lo.max(-rest / a);
            } else if a < 0.0 {
                hi = hi.min(-rest / a);
            } else if rest < 0.0 {
                return (1.0, 0.0); // empty
            }
        }
        // Widen by a hair so samples exactly on an edge are not lost to
        // rounding; the barycentric test decides.
        (lo - 1e-9, hi + 1e-9)
    }
}

/// The x interval of row `py` within distance `r` of the infinite line
/// through `a` with direction (dx, dy); unbounded for a point or a line
/// parallel to the rows (the caller clamps to the stroke's box).
fn stroke_row_span(a: &ScreenPoint, dx: f64, dy: f64, len2: f64, r: f64, py: f64) -> (f64, f64) {
    if dy.abs() < 1e-9 || len2 == 0.0 {
        return (f64::NEG_INFINITY, f64::INFINITY);
    }
    // Points (x, py) with |cross((x - a.x, py - a.y), (dx, dy))| / len <= r.
    let len = len2.sqrt();
    let x_at = a.x + (py - a.y) * dx / dy;
    let reach = r * len / dy.abs();
    (x_at - reach, x_at + reach)
}

/// Colour and depth samples of the whole frame.
pub(crate) struct Frame {
    pub width: usize,
    pub height: usize,
    pub colour: Vec<[u8; 3]>,
    depth: Vec<f32>,
}

impl Frame {
    pub fn new(width: usize, height: usize, background: [u8; 3]) -> Frame {
        Frame {
            width,
            height,
            colour: vec![background; width * height],
            depth: vec![f32::INFINITY; width * height],
        }
    }

    pub fn band_count(&self) -> usize {
        self.height.div_ceil(BAND_ROWS)
    }

    /// Run `draw(band_index, band)` for every band, in parallel.
    pub fn draw_bands(&mut self, draw: impl Fn(usize, &mut Band) + Sync) {
        let width = self.width;
        let chunk = BAND_ROWS * width;
        self.colour
            .par_chunks_mut(chunk)
            .zip(self.depth.par_chunks_mut(chunk))
            .enumerate()
            .for_each(|(i, (colour, depth))| {
                let mut band = Band {
                    y0: i * BAND_ROWS,
                    rows: colour.len() / width,
                    width,
                    colour,
                    depth,
                };
                draw(i, &mut band);
            });
    }

    /// Average `factor` × `factor` blocks of samples into pixels (RGB8).
    pub fn downsample(&self, factor: usize) -> Vec<u8> {
        let (w, h) = (self.width / factor, self.height / factor);
        let n = (factor * factor) as u32;
        let mut pixels = vec![0u8; w * h * 3];
        pixels
            .par_chunks_mut(w * 3)
            .enumerate()
            .for_each(|(y, row)| {
                for x in 0..w {
                    let mut sum = [0u32; 3];
                    for sy in 0..factor {
                        let start = (y * factor + sy) * self.width + x * factor;
                        for s in &self.colour[start..start + factor] {
                            (0..3).for_each(|c| sum[c] += s[c] as u32);
                        }
                    }
                    (0..3).for_each(|c| row[x * 3 + c] = ((sum[c] + n / 2) / n) as u8);
                }
            });
        pixels
    }
}

/// Assign primitives to the bands their vertical extent `[y_min, y_max]`
/// (in samples) overlaps; each band's list keeps input order.
pub(crate) fn bin_by_rows(
    extents: impl Iterator<Item = (f64, f64)>,
    bands: usize,
) -> Vec<Vec<u32>> {
    let mut bins = vec![Vec::new(); bands];
    let last = bands as f64 - 1.0;
    for (i, (y_min, y_max)) in extents.enumerate() {
        if y_min.is_nan() || y_max.is_nan() || y_min > y_max || bands == 0 {
            continue;
        }
        let first = ((y_min - 0.5) / BAND_ROWS as f64).floor().clamp(0.0, last) as usize;
        let end = ((y_max + 0.5) / BAND_ROWS as f64).floor().clamp(0.0, last) as usize;
        for bin in &mut bins[first..=end] {
            bin.push(i as u32);
        }
    }
    bins
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sp(x: f64, y: f64, depth: f64) -> ScreenPoint {
        ScreenPoint {
            x,
            y,
            depth,
            inv_w: 1.0,
        }
    }

    fn draw_all(frame: &mut Frame, draw: impl Fn(&mut Band) + Sync) {
        frame.draw_bands(|_, band| draw(band));
    }

    #[test]
    fn triangle_covers_its_area_and_respects_depth() {
        let mut frame = Frame::new(100, 100, [0; 3]);
        let big = [sp(0.0, 0.0, 2.0), sp(100.0, 0.0, 2.0), sp(0.0, 100.0, 2.0)];
        // Counter-clockwise on screen: winding must not matter.
        let near = [
            sp(10.0, 10.0, 1.0),
            sp(10.0, 50.0, 1.0),
            sp(50.0, 10.0, 1.0),
        ];
        let far = [
            sp(0.0, 0.0, 3.0),
            sp(0.0, 100.0, 3.0),
            sp(100.0, 100.0, 3.0),
        ];
        draw_all(&mut frame, |b| {
            b.fill_triangle(&big, |_| [255, 0, 0]);
            b.fill_triangle(&near, |_| [0, 255, 0]);
            b.fill_triangle(&far, |_| [0, 0, 255]);
        });
        let count = |c: [u8; 3]| frame.colour.iter().filter(|&&s| s == c).count() as f64;
        let (red, green, blue) = (count([255, 0, 0]), count([0, 255, 0]), count([0, 0, 255]));
        assert!((green - 800.0).abs() < 60.0, "green {green}");
        assert!((red + green - 5000.0).abs() < 150.0, "red {red}");
        // The far triangle shows only where the big one does not cover it.
        assert!((blue - 2500.0).abs() < 100.0, "blue {blue}");
    }

    #[test]
    fn stroke_matches_capsule_area_and_hides_behind_surfaces() {
        let mut frame = Frame::new(200, 100, [0; 3]);
        let (a, b) = (sp(20.0, 30.0, 1.0), sp(170.0, 70.0, 1.0));
        draw_all(&mut frame, |band| band.stroke(&a, &b, 4.0, 0.0, [255; 3]));
        let lit = frame.colour.iter().filter(|s| s[0] == 255).count() as f64;
        let len = ((150.0f64).powi(2) + 40.0f64.powi(2)).sqrt();
        let capsule = len * 8.0 + std::f64::consts::PI * 16.0;
        assert!((lit - capsule).abs() / capsule < 0.03, "{lit} vs {capsule}");

        let mut frame = Frame::new(200, 100, [0; 3]);
        let wall = [sp(0.0, 0.0, 0.5), sp(400.0, 0.0, 0.5), sp(0.0, 200.0, 0.5)];
        draw_all(&mut frame, |band| {
            band.fill_triangle(&wall, |_| [9; 3]);
            band.stroke(&a, &b, 4.0, 0.01, [255; 3]);
        });
        assert!(frame.colour.iter().all(|s| s[0] != 255));
    }

    #[test]
    fn splat_is_a_disk() {
        let mut frame = Frame::new(64, 64, [0; 3]);
        let c = sp(30.3, 33.7, 1.0);
        draw_all(&mut frame, |band| {
            band.splat(&c, 10.0, |_, _| 1.0, |_, _| [255; 3])
        });
        let lit = frame.colour.iter().filter(|s| s[0] == 255).count() as f64;
        let disk = std::f64::consts::PI * 100.0;
        assert!((lit - disk).abs() / disk < 0.04, "{lit} vs {disk}");
    }

    #[test]
    fn downsample_averages_blocks() {
        let mut frame = Frame::new(4, 2, [0; 3]);
        frame.colour[0] = [200, 100, 0];
        frame.colour[1] = [100, 100, 0];
        frame.colour[4] = [100, 0, 4];
        let pixels = frame.downsample(2);
        assert_eq!(pixels, vec![100, 50, 1, 0, 0, 0]);
    }

    #[test]
    fn bins_cover_overlapping_bands_in_order() {
        let bins = bin_by_rows(
            [(0.0, 5.0), (10.0, 40.0), (f64::NAN, 1.0), (60.0, 63.0)].into_iter(),
            4,
        );
        assert_eq!(bins[0], vec![0, 1]);
        assert_eq!(bins[1], vec![1]);
        assert_eq!(bins[2], vec![1]);
        assert_eq!(bins[3], vec![3]);
    }
}
