//! The `.odf` and `.udf` files: compact, exact, little-endian binary.
//!
//! Both start with the same header:
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic: `SRODF\0\0\x01` or `SRUDF\0\0\x01` (format version 1) |
//! | 3 × 4 | samples along x, y, z (u32) |
//! | 3 × 8 | origin: position of sample (0, 0, 0) (f64) |
//! | 8 | spacing h (f64) |
//! | n × 8 | signed distance per sample, x fastest, then y, then z (f64) |
//!
//! `.odf` then stores only the samples that moved off their grid nodes:
//! a count m (u64) and m records of (sample index u32, position 3 × f64),
//! in increasing index order; every other sample sits on its node.
//!
//! `.udf` then stores a 2-bit tag per sample, four to a byte, sample i in
//! bits 2(i mod 4) of byte i/4: 0 = distance only, 1 = directed distances,
//! 2 = a feature point, 3 = the sample's moved position. Then, for each
//! tagged sample in index order, three f64: the distances along +x, +y, +z
//! to the surface (+∞ where that edge has none stored; towards a moved
//! sample off the surface, d/h is the crossing's fraction of the edge to
//! its position), the feature point, or the position. Untagged samples (almost all) cost nothing beyond
//! their distance and 2 bits. A cell crossed by two feature lines may own
//! two feature points (two of its samples tagged 2; the higher index is
//! its first, see [`UnifiedField::second_points`]): no change of layout.

use crate::offset::{node_position, OffsetField};
use crate::unified::{Extra, UnifiedField};
use crate::DistFieldError;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;
use surfrecon_geom::DVec3;
use surfrecon_grid::GridSpec;

const ODF_MAGIC: &[u8; 8] = b"SRODF\0\0\x01";
const UDF_MAGIC: &[u8; 8] = b"SRUDF\0\0\x01";
/// Version 2 of the `.udf`: version 1 followed by the cells' further points.
const UDF2_MAGIC: &[u8; 8] = b"SRUDF\0\0\x02";
/// Bytes per record of a cell's further point (u32 cell, 3 × f64).
const CELL_POINT_BYTES: usize = 4 + 24;
/// How far (in spacings) a cell's further point may lie outside its cell:
/// as far as a feature point from its cell (half a cell, see
/// [`crate::sharp::owner_cell`]).
const CELL_POINT_REACH: f64 = 0.5;
const HEADER_BYTES: usize = 8 + 12 + 24 + 8;

/// Which of the two field kinds a file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldKind {
    Offset,
    Unified,
}

/// The kind a file's magic bytes announce, or else its extension (so that
/// a damaged .udf is read, and refused, as one), if it is one of ours.
pub fn sniff(path: &Path) -> Result<Option<FieldKind>, DistFieldError> {
    let mut magic = [0u8; 8];
    let mut f = std::fs::File::open(path).map_err(|error| io_error(path, error))?;
    Ok(match std::io::Read::read_exact(&mut f, &mut magic) {
        Ok(()) if &magic == ODF_MAGIC => Some(FieldKind::Offset),
        Ok(()) if &magic == UDF_MAGIC || &magic == UDF2_MAGIC => Some(FieldKind::Unified),
        _ => match extension(path).as_str() {
            "odf" => Some(FieldKind::Offset),
            "udf" => Some(FieldKind::Unified),
            _ => None,
        },
    })
}

/// Error unless `path` names a field file of a kind we read.
pub fn check_field_extension(path: &Path) -> Result<(), DistFieldError> {
    match extension(path).as_str() {
        "nrrd" | "vtk" | "odf" | "udf" => Ok(()),
        ext => Err(DistFieldError::BadFile {
            path: path.to_path_buf(),
            message: format!("unknown field format {ext:?} (supported: nrrd, vtk, odf, udf)"),
        }),
    }
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

pub fn write_odf(path: &Path, field: &OffsetField) -> Result<(), DistFieldError> {
    write_file(path, |w| {
        write_header(w, ODF_MAGIC, &field.spec, &field.values)?;
        w.write_all(&(field.moved.len() as u64).to_le_bytes())?;
        for (&i, p) in &field.moved {
            w.write_all(&i.to_le_bytes())?;
            write_vec(w, *p)?;
        }
        Ok(())
    })
}

pub fn write_udf(path: &Path, field: &UnifiedField) -> Result<(), DistFieldError> {
    write_file(path, |w| {
        let more = !field.cell_points.is_empty();
        let magic = if more { UDF2_MAGIC } else { UDF_MAGIC };
        write_header(w, magic, &field.spec, &field.values)?;
        let mut tags = vec![0u8; field.values.len().div_ceil(4)];
        for (&i, e) in &field.extras {
            let i = i as usize;
            tags[i / 4] |= tag_of(e) << (2 * (i % 4));
        }
        w.write_all(&tags)?;
        for e in field.extras.values() {
            let v = match *e {
                Extra::Directed(d) => DVec3::from_array(d),
                Extra::FeaturePoint(p) | Extra::Position(p) => p,
            };
            write_vec(w, v)?;
        }
        if more {
            let count: usize = field.cell_points.values().map(Vec::len).sum();
            w.write_all(&(count as u64).to_le_bytes())?;
            for (&cell, points) in &field.cell_points {
                for &p in points {
                    w.write_all(&cell.to_le_bytes())?;
                    write_vec(w, p)?;
                }
            }
        }
        Ok(())
    })
}

pub fn read_odf(path: &Path) -> Result<OffsetField, DistFieldError> {
    let bytes = std::fs::read(path).map_err(|error| io_error(path, error))?;
    let mut r = Reader {
        bytes: &bytes,
        at: 0,
        path,
    };
    let (spec, values) = r.header(ODF_MAGIC, "offset distance field (.odf)")?;
    let m = r.u64("the count of moved samples")? as usize;
    if m > values.len() || r.remaining() != m * 28 {
        return Err(r.bad(format!(
            "{m} moved samples announced but {} bytes follow (28 per sample expected)",
            r.remaining()
        )));
    }
    let mut moved = BTreeMap::new();
    let mut last = None;
    for _ in 0..m {
        let i = r.u32("a sample index")?;
        let p = r.vec("a sample position")?;
        if (i as usize) >= values.len() || last.is_some_and(|l| i <= l) {
            return Err(r.bad(format!(
                "moved sample index {i} is out of range or out of order"
            )));
        }
        check_in_cell(&r, &spec, i as usize, p)?;
        moved.insert(i, p);
        last = Some(i);
    }
    Ok(OffsetField {
        spec,
        values,
        moved,
    })
}

pub fn read_udf(path: &Path) -> Result<UnifiedField, DistFieldError> {
    let bytes = std::fs::read(path).map_err(|error| io_error(path, error))?;
    let mut r = Reader {
        bytes: &bytes,
        at: 0,
        path,
    };
    let version2 = bytes.get(..8) == Some(UDF2_MAGIC.as_slice());
    let magic = if version2 { UDF2_MAGIC } else { UDF_MAGIC };
    let (spec, values) = r.header(magic, "unified distance field (.udf)")?;
    let n = values.len();
    let tags = r.take(n.div_ceil(4), "the sample tags")?.to_vec();
    let tag = |i: usize| (tags[i / 4] >> (2 * (i % 4))) & 3;
    let tagged: Vec<usize> = (0..n).filter(|&i| tag(i) != 0).collect();
    let tail = if version2 {
        // The count of further points (8 bytes) must follow at least.
        let at = r.at + tagged.len() * 24;
        let count = bytes
            .get(at..at + 8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")));
        match count {
            Some(m) if m <= n as u64 => 8 + m as usize * CELL_POINT_BYTES,
            Some(m) => return Err(r.bad(format!("{m} further cell points for {n} samples"))),
            None => 8,
        }
    } else {
        0
    };
    if r.remaining() != tagged.len() * 24 + tail {
        return Err(r.bad(format!(
            "{} tagged samples need {} bytes of extra data{} but {} follow",
            tagged.len(),
            tagged.len() * 24,
            if version2 {
                format!(" and the further cell points {tail}")
            } else {
                String::new()
            },
            r.remaining()
        )));
    }
    let mut extras = BTreeMap::new();
    for i in tagged {
        let v = r.vec("extra sample data")?;
        let extra = match tag(i) {
            1 => {
                if v.to_array()
                    .iter()
                    .any(|&d| !(d >= 0.0 && d <= spec.spacing || d == f64::INFINITY))
                {
                    return Err(r.bad(format!(
                        "sample {i}: directed distances {v} must lie within one spacing"
                    )));
                }
                Extra::Directed(v.to_array())
            }
            2 => Extra::FeaturePoint(check_finite(&r, i, v)?),
            _ => {
                check_in_cell(&r, &spec, i, v)?;
                Extra::Position(v)
            }
        };
        extras.insert(i as u32, extra);
    }
    let cell_points = if version2 {
        read_cell_points(&mut r, &spec)?
    } else {
        BTreeMap::new()
    };
    Ok(UnifiedField {
        spec,
        values,
        extras,
        cell_points,
    })
}

/// The further points of cells that end a version 2 `.udf`: each in a
/// cell of the grid (not on its last layer of samples), finite, within
/// [`CELL_POINT_REACH`] of the cell, by increasing cell index.
fn read_cell_points(
    r: &mut Reader,
    spec: &GridSpec<3>,
) -> Result<BTreeMap<u32, Vec<DVec3>>, DistFieldError> {
    let m = r.u64("the count of further cell points")?;
    let mut out: BTreeMap<u32, Vec<DVec3>> = BTreeMap::new();
    let mut last = None;
    for _ in 0..m {
        let cell = r.u32("a cell index")?;
        let p = r.vec("a cell's further point")?;
        let samples: usize = spec.dims.iter().product();
        let idx = spec.unlinear((cell as usize).min(samples - 1));
        let is_cell = (cell as usize) < samples && (0..3).all(|a| idx[a] + 1 < spec.dims[a]);
        if !is_cell || last.is_some_and(|l| cell < l) {
            return Err(r.bad(format!(
                "further point of cell {cell}: not a cell of the grid, or out of order"
            )));
        }
        let lo = DVec3::from_array(spec.position(idx));
        let reach = CELL_POINT_REACH * spec.spacing;
        let outside = (lo - p).max(p - lo - DVec3::splat(spec.spacing));
        if !(p.is_finite() && outside.max_element() <= reach) {
            return Err(r.bad(format!(
                "further point {p} of cell {idx:?} lies outside the cell"
            )));
        }
        out.entry(cell).or_default().push(p);
        last = Some(cell);
    }
    Ok(out)
}

fn tag_of(e: &Extra) -> u8 {
    match e {
        Extra::Directed(_) => 1,
        Extra::FeaturePoint(_) => 2,
        Extra::Position(_) => 3,
    }
}

fn write_file(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), DistFieldError> {
    surfrecon_geom::io::write_atomic(path, fill).map_err(|e| match e {
        surfrecon_geom::GeomError::Io { path, error } => DistFieldError::Io { path, error },
        other => DistFieldError::BadFile {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    })
}

fn write_header(
    w: &mut dyn Write,
    magic: &[u8; 8],
    spec: &GridSpec<3>,
    values: &[f64],
) -> std::io::Result<()> {
    w.write_all(magic)?;
    for d in spec.dims {
        w.write_all(&(d as u32).to_le_bytes())?;
    }
    write_vec(w, DVec3::from_array(spec.origin))?;
    w.write_all(&spec.spacing.to_le_bytes())?;
    for v in values {
        w.write_all(&v.to_le_bytes())?;
    }
    Ok(())
}

fn write_vec(w: &mut dyn Write, v: DVec3) -> std::io::Result<()> {
    for x in v.to_array() {
        w.write_all(&x.to_le_bytes())?;
    }
    Ok(())
}

fn io_error(path: &Path, error: std::io::Error) -> DistFieldError {
    DistFieldError::Io {
        path: path.to_path_buf(),
        error,
    }
}

fn check_finite(r: &Reader, i: usize, p: DVec3) -> Result<DVec3, DistFieldError> {
    if p.is_finite() {
        Ok(p)
    } else {
        Err(r.bad(format!("sample {i}: non-finite point {p}")))
    }
}

/// A moved sample must stay within half a spacing of its node.
fn check_in_cell(r: &Reader, spec: &GridSpec<3>, i: usize, p: DVec3) -> Result<(), DistFieldError> {
    // `max_element` skips NaN components, so finiteness is checked on `p`.
    let off = (p - node_position(spec, i)).abs().max_element();
    if p.is_finite() && off <= 0.5 * spec.spacing {
        Ok(())
    } else {
        Err(r.bad(format!("sample {i} is placed at {p}, outside its cell")))
    }
}

/// A cursor over a field file's bytes that names what it is reading
/// when the file ends early.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl Reader<'_> {
    fn bad(&self, message: String) -> DistFieldError {
        DistFieldError::BadFile {
            path: self.path.to_path_buf(),
            message,
        }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], DistFieldError> {
        if self.remaining() < n {
            return Err(self.bad(format!(
                "truncated: {what} needs {n} bytes at offset {} but only {} remain",
                self.at,
                self.remaining()
            )));
        }
        self.at += n;
        Ok(&self.bytes[self.at - n..self.at])
    }

    fn u32(&mut self, what: &str) -> Result<u32, DistFieldError> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4 bytes"),
        ))
    }

    fn u64(&mut self, what: &str) -> Result<u64, DistFieldError> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }

    fn f64(&mut self, what: &str) -> Result<f64, DistFieldError> {
        Ok(f64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }

    fn vec(&mut self, what: &str) -> Result<DVec3, DistFieldError> {
        Ok(DVec3::new(
            self.f64(what)?,
            self.f64(what)?,
            self.f64(what)?,
        ))
    }

    fn header(
        &mut self,
        magic: &[u8; 8],
        kind: &str,
    ) -> Result<(GridSpec<3>, Vec<f64>), DistFieldError> {
        if self.bytes.len() < 8 {
            return Err(self.bad(format!(
                "truncated: {} bytes, shorter than the 8-byte magic of a {kind} file",
                self.bytes.len()
            )));
        }
        if &self.bytes[..8] != magic {
            return Err(self.bad(format!("not a surfrecon {kind} file (wrong magic bytes)")));
        }
        self.at = 8;
        let dims = [
            self.u32("the grid size")?,
            self.u32("the grid size")?,
            self.u32("the grid size")?,
        ]
        .map(|d| d as usize);
        let origin = self.vec("the grid origin")?.to_array();
        let spacing = self.f64("the grid spacing")?;
        if dims.iter().any(|&d| d < 2)
            || !(spacing.is_finite() && spacing > 0.0)
            || origin.iter().any(|o| !o.is_finite())
        {
            return Err(self.bad(format!(
                "bad grid: {dims:?} samples, spacing {spacing}, origin {origin:?}"
            )));
        }
        let n = dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
        let n = match n {
            Some(n) if n.checked_mul(8).is_some_and(|b| b <= self.remaining()) => n,
            _ => {
                return Err(self.bad(format!(
                    "truncated: a {}×{}×{} grid needs more than the {} bytes after the {HEADER_BYTES}-byte header",
                    dims[0],
                    dims[1],
                    dims[2],
                    self.remaining()
                )))
            }
        };
        let raw = self.take(n * 8, "the distances")?;
        let values: Vec<f64> = raw
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(self.bad(format!("sample {i} has a non-finite distance")));
        }
        Ok((
            GridSpec {
                origin,
                spacing,
                dims,
            },
            values,
        ))
    }
}

/// A distance field file of any of the three kinds.
#[derive(Debug, Clone, PartialEq)]
pub enum AnyField {
    /// A regular grid (.nrrd or .vtk), 3D.
    Regular(surfrecon_grid::Field3),
    Offset(OffsetField),
    Unified(UnifiedField),
}

impl AnyField {
    /// Read a field, telling the kinds apart by their contents (.odf and
    /// .udf by magic bytes, anything else as a regular field file).
    pub fn read(path: &Path) -> Result<Self, DistFieldError> {
        match sniff(path)? {
            Some(FieldKind::Offset) => Ok(AnyField::Offset(read_odf(path)?)),
            Some(FieldKind::Unified) => Ok(AnyField::Unified(read_udf(path)?)),
            None => {
                check_field_extension(path)?;
                match surfrecon_grid::field_io::read_field(path)? {
                    surfrecon_grid::field_io::AnyField::D3(f) => Ok(AnyField::Regular(f)),
                    surfrecon_grid::field_io::AnyField::D2(_) => Err(DistFieldError::BadFile {
                        path: path.to_path_buf(),
                        message:
                            "a 2D field has no surface to sculpt or compare; a 3D field is needed"
                                .into(),
                    }),
                }
            }
        }
    }

    /// Write in the file's own kind; `.odf`/`.udf` kinds must be written
    /// to files with those extensions, regular ones to .nrrd or .vtk.
    pub fn write(&self, path: &Path) -> Result<(), DistFieldError> {
        let ext = extension(path);
        let expected = match self {
            AnyField::Regular(_) => "nrrd or .vtk",
            AnyField::Offset(_) => "odf",
            AnyField::Unified(_) => "udf",
        };
        let fits = match self {
            AnyField::Regular(_) => ext == "nrrd" || ext == "vtk",
            AnyField::Offset(_) => ext == "odf",
            AnyField::Unified(_) => ext == "udf",
        };
        if !fits {
            return Err(DistFieldError::BadFile {
                path: path.to_path_buf(),
                message: format!("this field is written as .{expected}, not .{ext}"),
            });
        }
        match self {
            AnyField::Regular(f) => Ok(surfrecon_grid::field_io::write_field(path, f)?),
            AnyField::Offset(f) => write_odf(path, f),
            AnyField::Unified(f) => write_udf(path, f),
        }
    }

    /// The zero set as a closed mesh.
    pub fn surface(&self) -> surfrecon_geom::TriMesh {
        match self {
            AnyField::Regular(f) => surfrecon_grid::marching::marching_cubes(f, 0.0),
            AnyField::Offset(f) => f.extract().0,
            AnyField::Unified(f) => f.extract().0,
        }
    }

    pub fn spec(&self) -> &GridSpec<3> {
        match self {
            AnyField::Regular(f) => &f.spec,
            AnyField::Offset(f) => &f.spec,
            AnyField::Unified(f) => &f.spec,
        }
    }

    /// Combine with a tool (see [`crate::sculpt`]).
    pub fn sculpt(
        &mut self,
        operation: crate::sculpt::Operation,
        tool: &crate::sculpt::Tool,
    ) -> Result<crate::sculpt::SculptReport, DistFieldError> {
        use crate::sculpt::{sculpt_odf, sculpt_regular, sculpt_udf};
        match self {
            AnyField::Regular(f) => Ok(sculpt_regular(f, operation, tool)),
            AnyField::Offset(f) => sculpt_odf(f, operation, tool),
            AnyField::Unified(f) => {
                sculpt_udf(f, operation, tool, crate::unified::DEFAULT_THRESHOLD)
            }
        }
    }
}
