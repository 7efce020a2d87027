//! Geometry file formats: PLY (ascii, binary little/big endian), OBJ, OFF,
//! STL (ascii, binary) and XYZ.
//!
//! Entry points: [`read`] / [`read_as`] / [`read_bytes`] return a
//! [`Geometry`]; [`write`] / [`write_as`] / [`to_bytes`] store one;
//! [`write_atomic`] is the temp-file-and-rename writer every output of
//! surfrecon goes through (also NRRD, VTK and PNG from other crates), so a
//! failed run never leaves a half-written file. The [`Format`] comes from the
//! file extension unless given explicitly.
//!
//! All parsers are our own: they read the whole file into memory and never
//! panic; malformed input is a [`GeomError::Parse`] naming the file, the line
//! (text) or byte offset (binary) and the problem. Counts from headers are
//! checked against the bytes actually present before anything is allocated
//! from them.

mod obj;
mod off;
mod ply;
mod stl;
mod text;
mod xyz;

#[cfg(test)]
mod tests;

use crate::{GeomError, Geometry, Location};
use std::fmt;
use std::io::Write;
use std::path::Path;
use std::str::FromStr;

/// A geometry file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    Ply,
    Obj,
    Off,
    Stl,
    Xyz,
}

impl Format {
    /// Every supported format.
    pub const ALL: [Format; 5] = [
        Format::Ply,
        Format::Obj,
        Format::Off,
        Format::Stl,
        Format::Xyz,
    ];

    /// The format named by a file extension (case-insensitive, no dot).
    pub fn from_extension(ext: &str) -> Option<Format> {
        match ext.to_ascii_lowercase().as_str() {
            "ply" => Some(Format::Ply),
            "obj" => Some(Format::Obj),
            "off" => Some(Format::Off),
            "stl" => Some(Format::Stl),
            "xyz" => Some(Format::Xyz),
            _ => None,
        }
    }

    /// The format of `path` by its extension.
    pub fn from_path(path: impl AsRef<Path>) -> Result<Format, GeomError> {
        let path = path.as_ref();
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().into_owned())
            .unwrap_or_default();
        Format::from_extension(&ext).ok_or_else(|| GeomError::UnknownFormat {
            path: path.to_path_buf(),
            format: ext,
        })
    }

    /// Lower-case name, also the usual extension.
    pub fn name(self) -> &'static str {
        match self {
            Format::Ply => "ply",
            Format::Obj => "obj",
            Format::Off => "off",
            Format::Stl => "stl",
            Format::Xyz => "xyz",
        }
    }

    /// Whether files of this format can hold triangles.
    pub fn stores_triangles(self) -> bool {
        !matches!(self, Format::Xyz)
    }

    /// Whether files of this format can hold polylines (only OBJ `l`).
    pub fn stores_lines(self) -> bool {
        matches!(self, Format::Obj)
    }

    /// Whether files of this format can hold per-vertex normals.
    pub fn stores_normals(self) -> bool {
        !matches!(self, Format::Stl)
    }

    /// Whether files of this format can hold one scalar per vertex.
    pub fn stores_scalars(self) -> bool {
        matches!(self, Format::Ply | Format::Xyz)
    }

    /// Whether vertices that no triangle uses survive (STL keeps only
    /// triangle corners, merged by position).
    pub fn stores_points(self) -> bool {
        !matches!(self, Format::Stl)
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> Result<Format, String> {
        Format::from_extension(s.trim_start_matches('.'))
            .ok_or_else(|| format!("unknown format {s:?} (supported: ply, obj, off, stl, xyz)"))
    }
}

/// Text or binary layout for formats that have both (PLY, STL).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Encoding {
    Ascii,
    #[default]
    BinaryLittleEndian,
    /// PLY only; binary STL is always little-endian.
    BinaryBigEndian,
}

/// How to write a file. The default is binary little-endian PLY/STL.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteOptions {
    pub encoding: Encoding,
}

impl WriteOptions {
    /// Text output for PLY and STL.
    pub fn ascii() -> Self {
        WriteOptions {
            encoding: Encoding::Ascii,
        }
    }
}

/// Read a geometry file, format chosen by its extension.
pub fn read(path: impl AsRef<Path>) -> Result<Geometry, GeomError> {
    let path = path.as_ref();
    read_as(path, Format::from_path(path)?)
}

/// Read a geometry file in the given format, whatever its extension.
pub fn read_as(path: impl AsRef<Path>, format: Format) -> Result<Geometry, GeomError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| GeomError::Io {
        path: path.to_path_buf(),
        error: source,
    })?;
    read_bytes(&bytes, format, path)
}

/// Parse file contents held in memory; `name` is used in error messages.
pub fn read_bytes(
    bytes: &[u8],
    format: Format,
    name: impl AsRef<Path>,
) -> Result<Geometry, GeomError> {
    let src = Src {
        path: name.as_ref(),
    };
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(src.file("empty file"));
    }
    match format {
        Format::Ply => ply::read(bytes, &src),
        Format::Obj => obj::read(bytes, &src),
        Format::Off => off::read(bytes, &src),
        Format::Stl => stl::read(bytes, &src),
        Format::Xyz => xyz::read(bytes, &src),
    }
}

/// Write `geom` to `path` in the format of its extension (binary PLY/STL).
pub fn write(path: impl AsRef<Path>, geom: &Geometry) -> Result<(), GeomError> {
    let path = path.as_ref();
    write_as(
        path,
        geom,
        Format::from_path(path)?,
        WriteOptions::default(),
    )
}

/// Write `geom` to `path` in `format`, atomically. Parts the format cannot
/// hold (see [`Format::stores_lines`] etc.) are left out; STL without
/// triangles is an error.
pub fn write_as(
    path: impl AsRef<Path>,
    geom: &Geometry,
    format: Format,
    options: WriteOptions,
) -> Result<(), GeomError> {
    check_writable(geom, format)?;
    write_atomic(path, |w| encode(w, geom, format, options))
}

/// The bytes of `geom` stored in `format` (what [`write_as`] would write).
pub fn to_bytes(
    geom: &Geometry,
    format: Format,
    options: WriteOptions,
) -> Result<Vec<u8>, GeomError> {
    check_writable(geom, format)?;
    let mut out = Vec::new();
    encode(&mut out, geom, format, options).map_err(|source| GeomError::Io {
        path: "<memory>".into(),
        error: source,
    })?;
    Ok(out)
}

fn encode(
    w: &mut dyn Write,
    geom: &Geometry,
    format: Format,
    options: WriteOptions,
) -> std::io::Result<()> {
    match format {
        Format::Ply => ply::write(w, geom, options.encoding),
        Format::Obj => obj::write(w, geom),
        Format::Off => off::write(w, geom),
        Format::Stl => stl::write(w, geom, options.encoding),
        Format::Xyz => xyz::write(w, geom),
    }
}

/// Write a file through `fill`: the bytes go to a temporary file in the same
/// directory (buffered), which replaces `path` only when `fill` and the flush
/// succeed. On any failure the temporary file is removed and `path` is left
/// as it was.
pub fn write_atomic<F>(path: impl AsRef<Path>, fill: F) -> Result<(), GeomError>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let path = path.as_ref();
    let io_err = |source| GeomError::Io {
        path: path.to_path_buf(),
        error: source,
    };
    // Same directory as the target, so the final rename cannot cross
    // file systems.
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".surfrecon-").suffix(".tmp");
    // Temporary files are private (0600); an output file should get the
    // usual permissions (0644 less the umask), like any newly created file.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let tmp = builder.tempfile_in(dir).map_err(io_err)?;
    let mut buffered = std::io::BufWriter::with_capacity(1 << 20, tmp);
    fill(&mut buffered).map_err(io_err)?;
    let tmp = buffered.into_inner().map_err(|e| io_err(e.into_error()))?;
    tmp.persist(path).map_err(|e| io_err(e.error))?;
    Ok(())
}

/// Refuse geometry that would make an unreadable or inconsistent file.
fn check_writable(geom: &Geometry, format: Format) -> Result<(), GeomError> {
    let invalid = |msg: String| Err(GeomError::InvalidInput(msg));
    let pts = &geom.points;
    let n = pts.positions.len();
    if n > u32::MAX as usize {
        return invalid(format!("{n} vertices exceed the 32-bit index limit"));
    }
    if let Some(i) = pts.positions.iter().position(|p| !p.is_finite()) {
        return invalid(format!("vertex {i} has a non-finite coordinate"));
    }
    if let Some(normals) = &pts.normals {
        if normals.len() != n {
            return invalid(format!("{} normals for {n} vertices", normals.len()));
        }
        if let Some(i) = normals.iter().position(|p| !p.is_finite()) {
            return invalid(format!("normal {i} has a non-finite component"));
        }
    }
    if let Some(scalars) = &pts.scalars {
        if scalars.len() != n {
            return invalid(format!("{} scalars for {n} vertices", scalars.len()));
        }
        if let Some(i) = scalars.iter().position(|s| !s.is_finite()) {
            return invalid(format!("scalar {i} is not finite"));
        }
    }
    let out_of_range = |i: &u32| *i as usize >= n;
    if let Some(t) = geom
        .triangles
        .iter()
        .position(|t| t.iter().any(out_of_range))
    {
        return invalid(format!("triangle {t} has a vertex index >= {n}"));
    }
    if let Some(l) = geom.lines.iter().position(|l| l.iter().any(out_of_range)) {
        return invalid(format!("polyline {l} has a vertex index >= {n}"));
    }
    if format == Format::Stl && geom.triangles.is_empty() {
        return invalid("STL stores triangles only, and this geometry has none".into());
    }
    Ok(())
}

/// The file being parsed, for error messages.
pub(crate) struct Src<'a> {
    pub path: &'a Path,
}

impl Src<'_> {
    fn err(&self, location: Location, message: impl Into<String>) -> GeomError {
        GeomError::Parse {
            path: self.path.to_path_buf(),
            location,
            message: message.into(),
        }
    }

    /// A problem on a 1-based line of a text file.
    pub fn line(&self, line: usize, message: impl Into<String>) -> GeomError {
        self.err(Location::Line(line), message)
    }

    /// A problem at a byte offset of a binary file.
    pub fn byte(&self, offset: usize, message: impl Into<String>) -> GeomError {
        self.err(Location::Byte(offset as u64), message)
    }

    /// A problem with the file as a whole.
    pub fn file(&self, message: impl Into<String>) -> GeomError {
        self.err(Location::File, message)
    }
}

/// Split polygon `corners` into a triangle fan around its first corner;
/// polygons with fewer than three corners add nothing.
pub(crate) fn fan_triangulate(corners: &[u32], out: &mut Vec<[u32; 3]>) {
    if let Some((&first, rest)) = corners.split_first() {
        out.extend(rest.windows(2).map(|w| [first, w[0], w[1]]));
    }
}
