//! A fitted implicit function f(x) = b + Σ_levels Σ_i β_i k(|x − c_i| / s_level):
//! evaluation of f, its gradient and curvature, and a binary file format.
//!
//! f approximates the signed distance near the surface, negative inside and
//! positive outside; far from all centres f = b > 0 (outside).
//!
//! # File format (`.svm`, all numbers little-endian)
//! ```text
//! offset  size  field
//! 0       8     magic "SRSVMMDL"
//! 8       4     version (u32) = 1
//! 12      8     b, the constant offset (f64)
//! 20      4     number of levels L (u32)
//! then L times:
//!         8     kernel width s (f64, > 0)
//!         8     number of centres n (u64)
//!         n*32  n records: centre x, y, z, coefficient β (4 × f64)
//! ```
//! Levels are stored coarsest first; the file ends right after the last
//! level. Every number must be finite.

use crate::cells::CellIndex;
use crate::error::{Result, SvmError};
use crate::kernel::{kernel_gradient, kernel_hessian, wu};
use glam::DVec3;
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;

const MAGIC: &[u8; 8] = b"SRSVMMDL";
const VERSION: u32 = 1;

/// Kernels of one width: centres and their coefficients, with an index.
/// Centres are kept sorted by index cell (so each cell is contiguous in
/// memory); the order carries no meaning.
pub struct Level {
    pub width: f64,
    inverse_width: f64,
    pub centres: Vec<DVec3>,
    pub coefficients: Vec<f64>,
    index: CellIndex,
}

impl Level {
    /// A level of kernels of width `width` (> 0) at `centres`.
    pub fn new(width: f64, centres: Vec<DVec3>, coefficients: Vec<f64>) -> Level {
        debug_assert_eq!(centres.len(), coefficients.len());
        let unsorted = CellIndex::new(&centres, width);
        let centres: Vec<DVec3> = unsorted
            .order
            .iter()
            .map(|&i| centres[i as usize])
            .collect();
        let coefficients = unsorted
            .order
            .iter()
            .map(|&i| coefficients[i as usize])
            .collect();
        // Re-index the sorted copy: its order is the identity.
        let index = CellIndex::new(&centres, width);
        debug_assert!(index
            .order
            .iter()
            .enumerate()
            .all(|(i, &o)| o as usize == i));
        Level {
            width,
            inverse_width: 1.0 / width,
            centres,
            coefficients,
            index,
        }
    }

    /// Call `f(centre, coefficient)` for each centre whose support holds `x`.
    #[inline]
    fn for_each_near(&self, x: DVec3, mut f: impl FnMut(DVec3, f64)) {
        let s2 = self.width * self.width;
        self.index.for_each_candidate(x, |i| {
            let c = self.centres[i];
            if c.distance_squared(x) < s2 {
                f(c, self.coefficients[i]);
            }
        });
    }

    /// This level's contribution Σ β_i k(|x − c_i| / s).
    pub fn value(&self, x: DVec3) -> f64 {
        let inv = 1.0 / self.width;
        let mut sum = 0.0;
        self.for_each_near(x, |c, b| sum += b * wu(c.distance(x) * inv));
        sum
    }

    /// Gradient of this level's contribution.
    pub fn gradient(&self, x: DVec3) -> DVec3 {
        let mut g = DVec3::ZERO;
        self.for_each_near(x, |c, b| g += b * kernel_gradient(x, c, self.width));
        g
    }

    fn hessian(&self, x: DVec3) -> [DVec3; 3] {
        let mut h = [DVec3::ZERO; 3];
        self.for_each_near(x, |c, b| {
            let k = kernel_hessian(x, c, self.width);
            for a in 0..3 {
                h[a] += b * k[a];
            }
        });
        h
    }
}

impl Clone for Level {
    fn clone(&self) -> Self {
        Level::new(self.width, self.centres.clone(), self.coefficients.clone())
    }
}

impl std::fmt::Debug for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Level")
            .field("width", &self.width)
            .field("centres", &self.centres.len())
            .finish()
    }
}

/// Mean and Gaussian curvature of the level set of f through a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Curvature {
    /// κ = ∇·(∇f/|∇f|): the sum of the principal curvatures, positive on a
    /// sphere (2/R) since f grows outward.
    pub mean: f64,
    /// Product of the principal curvatures (1/R² on a sphere).
    pub gaussian: f64,
}

/// A fitted multi-scale implicit function (coarsest level first).
#[derive(Clone, Debug)]
pub struct SvmModel {
    pub offset: f64,
    pub levels: Vec<Level>,
}

impl SvmModel {
    /// Total number of kernel centres over all levels.
    pub fn centre_count(&self) -> usize {
        self.levels.iter().map(|l| l.centres.len()).sum()
    }

    /// f(x).
    pub fn value(&self, x: DVec3) -> f64 {
        self.offset + self.levels.iter().map(|l| l.value(x)).sum::<f64>()
    }

    /// ∇f(x).
    pub fn gradient(&self, x: DVec3) -> DVec3 {
        self.levels.iter().map(|l| l.gradient(x)).sum()
    }

    /// Hessian of f at x, as rows.
    pub fn hessian(&self, x: DVec3) -> [DVec3; 3] {
        let mut h = [DVec3::ZERO; 3];
        for l in &self.levels {
            let lh = l.hessian(x);
            for a in 0..3 {
                h[a] += lh[a];
            }
        }
        h
    }

    /// Curvature of the level set through `x`; `None` where ∇f = 0.
    pub fn curvature(&self, x: DVec3) -> Option<Curvature> {
        let g = self.gradient(x);
        let len = g.length();
        if len.is_nan() || len <= 0.0 {
            return None;
        }
        let h = self.hessian(x);
        let trace = h[0].x + h[1].y + h[2].z;
        let hg = DVec3::new(h[0].dot(g), h[1].dot(g), h[2].dot(g));
        let mean = (len * len * trace - g.dot(hg)) / (len * len * len);
        // Gaussian curvature: gᵀ adj(H) g / |g|⁴, adj(H) the adjugate.
        let adj = adjugate(h);
        let ag = DVec3::new(adj[0].dot(g), adj[1].dot(g), adj[2].dot(g));
        let gaussian = g.dot(ag) / (len * len * len * len);
        Some(Curvature { mean, gaussian })
    }

    /// f at many points, in parallel (results independent of thread count).
    ///
    /// Points are grouped into small cubes; per cube and level the centres
    /// that can reach the cube are gathered once, and each point then only
    /// scans that short list. Much faster than [`SvmModel::value`] per point
    /// when points are dense (grid nodes, training points); agrees with it
    /// up to rounding.
    pub fn values(&self, points: &[DVec3]) -> Vec<f64> {
        let groups = group_by_cube(points, self.brick_size(points));
        self.values_grouped(points, &groups)
    }

    /// Like [`SvmModel::values`] with the caller's grouping: each group
    /// should be spatially compact (e.g. the nodes of one grid block); every
    /// index of `points` must appear in exactly one group.
    pub fn values_grouped(&self, points: &[DVec3], groups: &[Vec<u32>]) -> Vec<f64> {
        self.batched(points, groups, self.offset, |sum, x, c, b, l| {
            *sum += b * wu(c.distance(x) * l.inverse_width)
        })
    }

    /// ∇f at many points (batched like [`SvmModel::values`]).
    pub fn gradients(&self, points: &[DVec3]) -> Vec<DVec3> {
        let groups = group_by_cube(points, self.brick_size(points));
        self.batched(points, &groups, DVec3::ZERO, |g, x, c, b, l| {
            *g += b * kernel_gradient(x, c, l.width)
        })
    }

    /// Sum `add(acc, x, centre, coefficient, level)` over every centre whose
    /// support holds x, for all points, gathering centres once per group.
    fn batched<T, F>(&self, points: &[DVec3], groups: &[Vec<u32>], zero: T, add: F) -> Vec<T>
    where
        T: Copy + Send + Sync,
        F: Fn(&mut T, DVec3, DVec3, f64, &Level) + Sync,
    {
        let parts: Vec<Vec<T>> = groups
            .par_iter()
            .map(|g| self.batch_of_group(points, g, zero, &add))
            .collect();
        let mut out = vec![zero; points.len()];
        for (g, vals) in groups.iter().zip(parts) {
            for (&i, v) in g.iter().zip(vals) {
                out[i as usize] = v;
            }
        }
        out
    }

    fn batch_of_group<T: Copy, F>(
        &self,
        points: &[DVec3],
        group: &[u32],
        zero: T,
        add: &F,
    ) -> Vec<T>
    where
        F: Fn(&mut T, DVec3, DVec3, f64, &Level),
    {
        if group.is_empty() {
            return Vec::new();
        }
        let centre = group.iter().map(|&i| points[i as usize]).sum::<DVec3>() / group.len() as f64;
        let radius = group
            .iter()
            .map(|&i| points[i as usize].distance(centre))
            .fold(0.0, f64::max);
        let mut acc = vec![zero; group.len()];
        let mut near: Vec<(DVec3, f64)> = Vec::new();
        for l in &self.levels {
            near.clear();
            let reach = l.width + radius;
            l.index.for_each_candidate_within(centre, reach, |i| {
                if l.centres[i].distance_squared(centre) < reach * reach {
                    near.push((l.centres[i], l.coefficients[i]));
                }
            });
            let s2 = l.width * l.width;
            for (a, &i) in acc.iter_mut().zip(group) {
                let x = points[i as usize];
                for &(c, b) in &near {
                    if c.distance_squared(x) < s2 {
                        add(a, x, c, b, l);
                    }
                }
            }
        }
        acc
    }

    /// Cube side for batched evaluation: about the finest kernel width,
    /// but at least the side holding ~16 points of a uniform spread.
    fn brick_size(&self, points: &[DVec3]) -> f64 {
        let finest = self.levels.last().map_or(1.0, |l| l.width);
        let bounds = surfrecon_geom::Aabb::from_points(points);
        let volume = bounds
            .size()
            .max(DVec3::splat(finest * 1e-3))
            .element_product();
        let crowded = (16.0 * volume / points.len().max(1) as f64).cbrt();
        finest.max(crowded.min(finest * 4.0))
    }

    /// The model without its `k` finest levels: a smoother function with
    /// the same offset (at least the coarsest level is always kept).
    pub fn without_finest(&self, k: usize) -> SvmModel {
        let keep = self
            .levels
            .len()
            .saturating_sub(k)
            .max(1.min(self.levels.len()));
        SvmModel {
            offset: self.offset,
            levels: self.levels[..keep].to_vec(),
        }
    }

    /// The same function moved by `by`: f'(x) = f(x − by).
    pub fn translated(&self, by: DVec3) -> SvmModel {
        let level = |l: &Level| {
            let centres = l.centres.iter().map(|&c| c + by).collect();
            Level::new(l.width, centres, l.coefficients.clone())
        };
        SvmModel {
            offset: self.offset,
            levels: self.levels.iter().map(level).collect(),
        }
    }

    /// Write the model in the format documented at the top of this module.
    pub fn write_to(&self, w: &mut dyn Write) -> std::io::Result<()> {
        w.write_all(MAGIC)?;
        w.write_all(&VERSION.to_le_bytes())?;
        w.write_all(&self.offset.to_le_bytes())?;
        w.write_all(&(self.levels.len() as u32).to_le_bytes())?;
        for l in &self.levels {
            w.write_all(&l.width.to_le_bytes())?;
            w.write_all(&(l.centres.len() as u64).to_le_bytes())?;
            let mut buf = Vec::with_capacity(l.centres.len() * 32);
            for (c, b) in l.centres.iter().zip(&l.coefficients) {
                for v in [c.x, c.y, c.z, *b] {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
            }
            w.write_all(&buf)?;
        }
        Ok(())
    }

    /// Save to `path` atomically (temporary file in the same directory,
    /// then rename), so a failed save leaves no partial model.
    pub fn save(&self, path: &Path) -> Result<()> {
        surfrecon_geom::io::write_atomic(path, |w| self.write_to(w))?;
        Ok(())
    }

    /// Load a model saved by [`SvmModel::save`]; malformed files give
    /// [`SvmError::Format`] naming the byte offset of the problem.
    pub fn load(path: &Path) -> Result<SvmModel> {
        let bytes = std::fs::read(path).map_err(|error| SvmError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        Self::from_bytes(&bytes).map_err(|(byte, message)| SvmError::Format {
            path: path.to_path_buf(),
            byte,
            message,
        })
    }

    /// Parse the binary format; errors are (byte offset, message).
    pub fn from_bytes(bytes: &[u8]) -> std::result::Result<SvmModel, (u64, String)> {
        let mut r = ByteReader { bytes, pos: 0 };
        let magic = r.take(8, "magic")?;
        if magic != MAGIC {
            return Err((0, "not a surfrecon SVM model (bad magic)".into()));
        }
        let version = r.u32("version")?;
        if version != VERSION {
            return Err((
                8,
                format!("unsupported version {version} (expected {VERSION})"),
            ));
        }
        let offset = r.finite("offset b")?;
        let level_count = r.u32("level count")?;
        let mut levels = Vec::new();
        for li in 0..level_count {
            levels.push(read_level(&mut r, li)?);
        }
        if r.pos != bytes.len() {
            return Err((r.pos as u64, "trailing bytes after the last level".into()));
        }
        Ok(SvmModel { offset, levels })
    }
}

fn read_level(r: &mut ByteReader, li: u32) -> std::result::Result<Level, (u64, String)> {
    let at = r.pos as u64;
    let width = r.finite("kernel width")?;
    if width <= 0.0 {
        return Err((
            at,
            format!("level {li}: kernel width {width} is not positive"),
        ));
    }
    let at = r.pos as u64;
    let n = r.u64("centre count")?;
    let remaining = (r.bytes.len() - r.pos) as u64;
    if n.checked_mul(32).is_none_or(|b| b > remaining) {
        return Err((
            at,
            format!("level {li}: {n} centres need more bytes than the file has left ({remaining})"),
        ));
    }
    let mut centres = Vec::with_capacity(n as usize);
    let mut coefficients = Vec::with_capacity(n as usize);
    for _ in 0..n {
        let x = r.finite("centre x")?;
        let y = r.finite("centre y")?;
        let z = r.finite("centre z")?;
        centres.push(DVec3::new(x, y, z));
        coefficients.push(r.finite("coefficient")?);
    }
    // Centres the cell index cannot hold would silently drop out of the level.
    if !CellIndex::can_hold(&centres, width) {
        return Err((
            at,
            format!(
                "level {li}: its {n} centres spread over more than 2^20 kernel widths ({width})"
            ),
        ));
    }
    Ok(Level::new(width, centres, coefficients))
}

struct ByteReader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl ByteReader<'_> {
    fn take(&mut self, n: usize, what: &str) -> std::result::Result<&[u8], (u64, String)> {
        if self.bytes.len() - self.pos < n {
            return Err((
                self.pos as u64,
                format!("file ends inside the {what} (truncated)"),
            ));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn u32(&mut self, what: &str) -> std::result::Result<u32, (u64, String)> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes(b.try_into().expect("4 bytes")))
    }

    fn u64(&mut self, what: &str) -> std::result::Result<u64, (u64, String)> {
        let b = self.take(8, what)?;
        Ok(u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }

    fn finite(&mut self, what: &str) -> std::result::Result<f64, (u64, String)> {
        let at = self.pos as u64;
        let b = self.take(8, what)?;
        let v = f64::from_le_bytes(b.try_into().expect("8 bytes"));
        if v.is_finite() {
            Ok(v)
        } else {
            Err((at, format!("{what} is not a finite number ({v})")))
        }
    }
}

/// Indices of `points` grouped by cube of side `side`, groups in key order.
fn group_by_cube(points: &[DVec3], side: f64) -> Vec<Vec<u32>> {
    let origin = points.iter().copied().fold(DVec3::INFINITY, DVec3::min);
    let mut keyed: Vec<([i64; 3], u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let c = ((*p - origin) / side).floor();
            ([c.z as i64, c.y as i64, c.x as i64], i as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| run.iter().map(|&(_, i)| i).collect())
        .collect()
}

/// Adjugate (transposed cofactor matrix) of a symmetric 3×3 matrix in rows.
fn adjugate(m: [DVec3; 3]) -> [DVec3; 3] {
    let [a, b, c] = m;
    // For rows a, b, c the adjugate's columns are b×c, c×a, a×b.
    let (c0, c1, c2) = (b.cross(c), c.cross(a), a.cross(b));
    [
        DVec3::new(c0.x, c1.x, c2.x),
        DVec3::new(c0.y, c1.y, c2.y),
        DVec3::new(c0.z, c1.z, c2.z),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_model() -> SvmModel {
        let mut levels = Vec::new();
        for (li, s) in [1.0, 0.5, 0.25].into_iter().enumerate() {
            let centres: Vec<DVec3> = (0..20)
                .map(|i| {
                    let t = (i + 7 * li) as f64;
                    DVec3::new((t * 0.3).sin(), (t * 0.5).cos(), (t * 0.7).sin()) * 0.5
                })
                .collect();
            let coefficients = (0..20).map(|i| ((i * 13 % 7) as f64 - 3.0) * 0.1).collect();
            levels.push(Level::new(s, centres, coefficients));
        }
        SvmModel {
            offset: 0.5,
            levels,
        }
    }

    #[test]
    fn value_matches_brute_force_and_gradient_matches_differences() {
        let m = sample_model();
        let x = DVec3::new(0.1, 0.2, -0.05);
        let mut brute = m.offset;
        for l in &m.levels {
            for (c, b) in l.centres.iter().zip(&l.coefficients) {
                brute += b * wu(x.distance(*c) / l.width);
            }
        }
        assert!((m.value(x) - brute).abs() < 1e-12);
        let many: Vec<DVec3> = (0..500)
            .map(|i| {
                DVec3::new(
                    (i as f64 * 0.1).sin(),
                    (i as f64 * 0.2).cos(),
                    0.01 * i as f64 - 2.0,
                )
            })
            .collect();
        for ((p, v), g) in many.iter().zip(m.values(&many)).zip(m.gradients(&many)) {
            assert!((m.value(*p) - v).abs() < 1e-12);
            assert!((m.gradient(*p) - g).length() < 1e-12);
        }
        let h = 1e-6;
        let g = m.gradient(x);
        let hess = m.hessian(x);
        for a in 0..3 {
            let e = DVec3::AXES[a] * h;
            let fd = (m.value(x + e) - m.value(x - e)) / (2.0 * h);
            assert!((fd - g[a]).abs() < 1e-7);
            let fdg = (m.gradient(x + e) - m.gradient(x - e)) / (2.0 * h);
            assert!((fdg - hess[a]).length() < 1e-6);
        }
    }

    #[test]
    fn save_load_round_trip_and_malformed_files() {
        let m = sample_model();
        let mut bytes = Vec::new();
        m.write_to(&mut bytes).unwrap();
        let back = SvmModel::from_bytes(&bytes).unwrap();
        assert_eq!(back.offset, m.offset);
        assert_eq!(back.levels.len(), 3);
        for (a, b) in back.levels.iter().zip(&m.levels) {
            assert_eq!(a.width, b.width);
            assert_eq!(a.centres, b.centres);
            assert_eq!(a.coefficients, b.coefficients);
        }
        let x = DVec3::new(0.3, -0.1, 0.2);
        assert_eq!(back.value(x), m.value(x));

        let err = |b: &[u8]| SvmModel::from_bytes(b).unwrap_err();
        assert_eq!(err(b"NOTAMODEL___________").0, 0);
        assert!(err(&bytes[..bytes.len() - 5]).1.contains("more bytes"));
        assert!(err(&bytes[..10]).1.contains("truncated"));
        let mut extra = bytes.clone();
        extra.push(0);
        assert!(err(&extra).1.contains("trailing"));
        let mut nan = bytes.clone();
        nan[12..20].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_eq!(err(&nan).0, 12);
        let mut huge = bytes.clone();
        huge[32..40].copy_from_slice(&u64::MAX.to_le_bytes());
        assert_eq!(err(&huge).0, 32);
        let mut neg = bytes.clone();
        neg[24..32].copy_from_slice(&(-1.0f64).to_le_bytes());
        assert!(err(&neg).1.contains("not positive"));
    }

    #[test]
    fn a_translated_model_is_the_same_function_moved() {
        let m = sample_model();
        let by = DVec3::new(1e6, -2.5, 1024.0);
        let moved = m.translated(by);
        for i in 0..200 {
            let x = DVec3::new(i as f64 * 0.013 - 1.3, (i % 7) as f64 * 0.1, -0.2);
            let (a, b) = (m.value(x), moved.value(x + by));
            // Moving x by 1e6 rounds it by about 1e-10.
            assert!((a - b).abs() < 1e-6, "{a} against {b} at {x}");
        }
    }

    #[test]
    fn dropping_levels_keeps_the_coarsest() {
        let m = sample_model();
        assert_eq!(m.without_finest(1).levels.len(), 2);
        assert_eq!(m.without_finest(10).levels.len(), 1);
    }

    #[test]
    fn curvature_of_a_radial_function_is_that_of_a_sphere() {
        // One wide kernel: level sets are spheres around its centre; with a
        // negative coefficient f grows outward.
        let m = SvmModel {
            offset: 0.0,
            levels: vec![Level::new(4.0, vec![DVec3::ZERO], vec![-1.0])],
        };
        let x = DVec3::new(0.6, 0.0, 0.8);
        let c = m.curvature(x).unwrap();
        assert!((c.mean - 2.0).abs() < 1e-9, "{c:?}");
        assert!((c.gaussian - 1.0).abs() < 1e-9, "{c:?}");
    }
}
