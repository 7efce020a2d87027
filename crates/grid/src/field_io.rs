//! Field files other tools open: NRRD (3D Slicer, ITK, teem) and legacy VTK
//! structured points (ParaView, VisIt), chosen by extension (`.nrrd`,
//! `.vtk`), in 2D and 3D.
//!
//! Written: NRRD `type: double`, `encoding: raw`, `endian: little`, with
//! `space directions`/`space origin`; VTK `BINARY` big-endian doubles
//! (`DIMENSIONS nx ny 1` in 2D). Read: NRRD float/double in raw, ascii or
//! gzip encoding, either endianness, axis-aligned uniform spacing (from
//! `space directions` or `spacings`); VTK ASCII or BINARY, float or double.
//! Anything else, truncated data, size mismatches and NaN values are
//! reported as [`GridError::FieldFile`] naming the file and the problem.

use crate::{Field, Field2, Field3, GridError, GridSpec};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// A field of either dimension, as read from a file.
#[derive(Clone, Debug, PartialEq)]
pub enum AnyField {
    D2(Field2),
    D3(Field3),
}

impl AnyField {
    /// 2 or 3.
    pub fn dimension(&self) -> usize {
        match self {
            AnyField::D2(_) => 2,
            AnyField::D3(_) => 3,
        }
    }

    /// Node counts along each axis.
    pub fn dims(&self) -> Vec<usize> {
        match self {
            AnyField::D2(f) => f.spec.dims.to_vec(),
            AnyField::D3(f) => f.spec.dims.to_vec(),
        }
    }

    /// Node spacing.
    pub fn spacing(&self) -> f64 {
        match self {
            AnyField::D2(f) => f.spec.spacing,
            AnyField::D3(f) => f.spec.spacing,
        }
    }

    /// The node values.
    pub fn values(&self) -> &[f64] {
        match self {
            AnyField::D2(f) => &f.values,
            AnyField::D3(f) => &f.values,
        }
    }
}

/// The file formats of this module.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldFormat {
    Nrrd,
    Vtk,
}

impl FieldFormat {
    /// Format from a path's extension.
    pub fn from_path(path: &Path) -> Result<Self, GridError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        match ext.as_str() {
            "nrrd" => Ok(FieldFormat::Nrrd),
            "vtk" => Ok(FieldFormat::Vtk),
            _ => Err(file_error(
                path,
                format!("unknown field format {ext:?} (supported: nrrd, vtk)"),
            )),
        }
    }
}

fn file_error(path: &Path, message: impl Into<String>) -> GridError {
    GridError::FieldFile {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Write `field` (2D or 3D) to `path` in the format of its extension,
/// atomically (a failed write leaves no partial file).
pub fn write_field<const D: usize>(
    path: impl AsRef<Path>,
    field: &Field<D>,
) -> Result<(), GridError> {
    let path = path.as_ref();
    let format = FieldFormat::from_path(path)?;
    check_writable(path, field)?;
    surfrecon_geom::io::write_atomic(path, |w| match format {
        FieldFormat::Nrrd => write_nrrd(w, field),
        FieldFormat::Vtk => write_vtk(w, field),
    })?;
    Ok(())
}

fn check_writable<const D: usize>(path: &Path, field: &Field<D>) -> Result<(), GridError> {
    let problem = if D != 2 && D != 3 {
        Some(format!("only 2D and 3D fields can be stored, not {D}D"))
    } else if field.values.len() != field.spec.node_count() {
        Some(format!(
            "field has {} values for {} nodes",
            field.values.len(),
            field.spec.node_count()
        ))
    } else if !(field.spec.spacing > 0.0 && field.spec.spacing.is_finite()) {
        Some(format!("spacing {} is not positive", field.spec.spacing))
    } else {
        field
            .values
            .iter()
            .position(|v| v.is_nan())
            .map(|i| format!("value {i} is NaN"))
    };
    match problem {
        Some(p) => Err(file_error(path, format!("cannot write field: {p}"))),
        None => Ok(()),
    }
}

fn join<T: std::fmt::Display>(items: impl IntoIterator<Item = T>, sep: &str) -> String {
    items
        .into_iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(sep)
}

fn write_nrrd<const D: usize>(w: &mut dyn Write, field: &Field<D>) -> std::io::Result<()> {
    let spec = &field.spec;
    let directions = (0..D).map(|a| {
        let v: Vec<f64> = (0..D)
            .map(|b| if a == b { spec.spacing } else { 0.0 })
            .collect();
        format!("({})", join(v, ","))
    });
    writeln!(w, "NRRD0004")?;
    writeln!(w, "# written by surfrecon")?;
    writeln!(w, "type: double")?;
    writeln!(w, "dimension: {D}")?;
    writeln!(w, "space dimension: {D}")?;
    writeln!(w, "sizes: {}", join(spec.dims, " "))?;
    writeln!(w, "space directions: {}", join(directions, " "))?;
    writeln!(w, "space origin: ({})", join(spec.origin, ","))?;
    writeln!(w, "kinds: {}", join((0..D).map(|_| "domain"), " "))?;
    writeln!(w, "endian: little")?;
    writeln!(w, "encoding: raw")?;
    writeln!(w)?;
    write_values(w, &field.values, f64::to_le_bytes)
}

fn write_values(
    w: &mut dyn Write,
    values: &[f64],
    encode: fn(f64) -> [u8; 8],
) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(8 * 4096);
    for chunk in values.chunks(4096) {
        buf.clear();
        buf.extend(chunk.iter().flat_map(|&v| encode(v)));
        w.write_all(&buf)?;
    }
    Ok(())
}

fn write_vtk<const D: usize>(w: &mut dyn Write, field: &Field<D>) -> std::io::Result<()> {
    let spec = &field.spec;
    let pad = |xs: Vec<String>, fill: &str| {
        let mut xs = xs;
        xs.resize(3, fill.to_string());
        xs.join(" ")
    };
    writeln!(w, "# vtk DataFile Version 3.0")?;
    writeln!(w, "surfrecon field")?;
    writeln!(w, "BINARY")?;
    writeln!(w, "DATASET STRUCTURED_POINTS")?;
    writeln!(
        w,
        "DIMENSIONS {}",
        pad(spec.dims.map(|n| n.to_string()).to_vec(), "1")
    )?;
    writeln!(
        w,
        "ORIGIN {}",
        pad(spec.origin.map(|x| x.to_string()).to_vec(), "0")
    )?;
    writeln!(w, "SPACING {0} {0} {0}", spec.spacing)?;
    writeln!(w, "POINT_DATA {}", spec.node_count())?;
    writeln!(w, "SCALARS values double 1")?;
    writeln!(w, "LOOKUP_TABLE default")?;
    write_values(w, &field.values, f64::to_be_bytes)?;
    writeln!(w)
}

/// Read a 2D or 3D field from a `.nrrd` or `.vtk` file.
pub fn read_field(path: impl AsRef<Path>) -> Result<AnyField, GridError> {
    let path = path.as_ref();
    let format = FieldFormat::from_path(path)?;
    let bytes = std::fs::read(path).map_err(|source| GridError::FieldIo {
        path: path.to_path_buf(),
        error: source,
    })?;
    let src = Source {
        path: path.to_path_buf(),
    };
    let raw = match format {
        FieldFormat::Nrrd => parse_nrrd(&bytes, &src)?,
        FieldFormat::Vtk => parse_vtk(&bytes, &src)?,
    };
    raw.into_field(&src)
}

/// Names the file in parse errors.
struct Source {
    path: PathBuf,
}

impl Source {
    fn err(&self, message: impl Into<String>) -> GridError {
        file_error(&self.path, message)
    }
    fn line_err(&self, line: usize, message: impl std::fmt::Display) -> GridError {
        self.err(format!("line {line}: {message}"))
    }
}

/// What every format yields before it becomes a field.
struct RawField {
    dims: Vec<usize>,
    origin: Vec<f64>,
    spacing: f64,
    values: Vec<f64>,
}

impl RawField {
    fn into_field(self, src: &Source) -> Result<AnyField, GridError> {
        let RawField {
            dims,
            origin,
            spacing,
            values,
        } = self;
        if let Some(i) = values.iter().position(|v| v.is_nan()) {
            return Err(src.err(format!("value {i} is NaN")));
        }
        if !(spacing > 0.0 && spacing.is_finite()) || origin.iter().any(|o| !o.is_finite()) {
            return Err(src.err(format!(
                "spacing {spacing} or origin {origin:?} is not usable"
            )));
        }
        Ok(match dims.len() {
            2 => AnyField::D2(Field {
                spec: GridSpec {
                    origin: [origin[0], origin[1]],
                    spacing,
                    dims: [dims[0], dims[1]],
                },
                values,
            }),
            _ => AnyField::D3(Field {
                spec: GridSpec {
                    origin: [origin[0], origin[1], origin[2]],
                    spacing,
                    dims: [dims[0], dims[1], dims[2]],
                },
                values,
            }),
        })
    }
}

/// Header lines of a text header, with 1-based numbers, and the byte
/// offset where the data starts: after the line `is_last` accepts, or
/// (NRRD) after the first empty line when `stop_at_empty`.
/// Numbered header lines and where the data starts (if the header ended).
type Header<'a> = (Vec<(usize, &'a str)>, Option<usize>);

fn header_lines<'a>(
    bytes: &'a [u8],
    src: &Source,
    stop_at_empty: bool,
    mut is_last: impl FnMut(&str) -> bool,
) -> Result<Header<'a>, GridError> {
    let mut lines = Vec::new();
    let mut pos = 0;
    while pos < bytes.len() {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |e| pos + e);
        let number = lines.len() + 1;
        let text = std::str::from_utf8(&bytes[pos..end])
            .map_err(|_| src.line_err(number, "header is not text"))?
            .trim_end_matches('\r');
        pos = (end + 1).min(bytes.len());
        if stop_at_empty && text.is_empty() && !lines.is_empty() {
            return Ok((lines, Some(pos)));
        }
        let last = is_last(text);
        lines.push((number, text));
        if last {
            return Ok((lines, Some(pos)));
        }
        if number > 1000 {
            break;
        }
    }
    // No end found: the caller checks the lines first, for a precise error.
    Ok((lines, None))
}

fn header_end(start: Option<usize>, src: &Source) -> Result<usize, GridError> {
    start.ok_or_else(|| src.err("header does not end (no empty line or data section found)"))
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Scalar {
    F32,
    F64,
}

impl Scalar {
    fn size(self) -> usize {
        match self {
            Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Encoding {
    Raw,
    Ascii,
    Gzip,
}

/// Decode `count` binary values starting at byte `start`.
fn decode_binary(
    data: &[u8],
    start: usize,
    count: usize,
    scalar: Scalar,
    little: bool,
    src: &Source,
) -> Result<Vec<f64>, GridError> {
    let need = count
        .checked_mul(scalar.size())
        .ok_or_else(|| src.err("data size overflows"))?;
    let have = data.len().saturating_sub(start);
    if have < need {
        return Err(src.err(format!(
            "byte {start}: data truncated: {have} bytes for {count} values of {} bytes",
            scalar.size()
        )));
    }
    let body = &data[start..start + need];
    Ok(match (scalar, little) {
        (Scalar::F64, true) => body
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect(),
        (Scalar::F64, false) => body
            .chunks_exact(8)
            .map(|c| f64::from_be_bytes(c.try_into().unwrap()))
            .collect(),
        (Scalar::F32, true) => body
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64)
            .collect(),
        (Scalar::F32, false) => body
            .chunks_exact(4)
            .map(|c| f32::from_be_bytes(c.try_into().unwrap()) as f64)
            .collect(),
    })
}

/// Decode `count` whitespace-separated numbers from text starting at `start`.
fn decode_ascii(
    data: &[u8],
    start: usize,
    count: usize,
    src: &Source,
) -> Result<Vec<f64>, GridError> {
    let text = std::str::from_utf8(&data[start.min(data.len())..])
        .map_err(|_| src.err(format!("byte {start}: ASCII data is not text")))?;
    // Each value takes at least two bytes (a digit and a separator): a
    // header declaring more values than the text can hold must not reserve
    // memory for them before the count check below refuses the file.
    let mut values = Vec::with_capacity(count.min(text.len() / 2 + 1));
    for token in text.split_ascii_whitespace() {
        if values.len() == count {
            return Err(src.err(format!("more than the {count} expected values")));
        }
        let v: f64 = token
            .parse()
            .map_err(|_| src.err(format!("value {}: {token:?} is not a number", values.len())))?;
        values.push(v);
    }
    if values.len() < count {
        return Err(src.err(format!(
            "data truncated: {} values, expected {count}",
            values.len()
        )));
    }
    Ok(values)
}

/// Parsed NRRD header fields.
#[derive(Default)]
struct NrrdHeader {
    scalar: Option<Scalar>,
    dimension: Option<usize>,
    sizes: Option<Vec<usize>>,
    directions: Option<Vec<Vec<f64>>>,
    spacings: Option<Vec<f64>>,
    origin: Option<Vec<f64>>,
    encoding: Option<Encoding>,
    little: Option<bool>,
}

fn parse_nrrd(bytes: &[u8], src: &Source) -> Result<RawField, GridError> {
    if !bytes.starts_with(b"NRRD000") {
        return Err(src.err("not a NRRD file (it must start with NRRD000x)"));
    }
    let (lines, data_start) = header_lines(bytes, src, true, |_| false)?;
    let mut h = NrrdHeader::default();
    for &(n, line) in lines.iter().skip(1) {
        if line.starts_with('#') || line.contains(":=") {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(src.line_err(n, format!("expected `field: value`, found {line:?}")));
        };
        nrrd_field(&mut h, key.trim(), value.trim()).map_err(|m| src.line_err(n, m))?;
    }
    let data_start = header_end(data_start, src)?;
    let raw = nrrd_geometry(&h).map_err(|m| src.err(m))?;
    let count = grid_points(&raw.dims, "sizes", src)?;
    let scalar = h
        .scalar
        .ok_or_else(|| src.err("header has no `type` field"))?;
    let values = match h
        .encoding
        .ok_or_else(|| src.err("header has no `encoding` field"))?
    {
        Encoding::Ascii => decode_ascii(bytes, data_start, count, src)?,
        Encoding::Raw => decode_binary(
            bytes,
            data_start,
            count,
            scalar,
            nrrd_little(&h, scalar, src)?,
            src,
        )?,
        Encoding::Gzip => {
            // Inflate no more than the values need (plus one byte, so the
            // size check still sees too much data): a small gzip stream can
            // expand a thousandfold.
            let limit = (count as u64)
                .saturating_mul(scalar.size() as u64)
                .saturating_add(1);
            let mut inflated = Vec::new();
            flate2::read::MultiGzDecoder::new(&bytes[data_start..])
                .take(limit)
                .read_to_end(&mut inflated)
                .map_err(|e| {
                    src.err(format!(
                        "byte {data_start}: gzip data cannot be decompressed: {e}"
                    ))
                })?;
            decode_binary(
                &inflated,
                0,
                count,
                scalar,
                nrrd_little(&h, scalar, src)?,
                src,
            )?
        }
    };
    Ok(RawField { values, ..raw })
}

/// Node count of a grid with `dims` nodes per axis; an error (naming the
/// header field `what`) when the product overflows.
fn grid_points(dims: &[usize], what: &str, src: &Source) -> Result<usize, GridError> {
    dims.iter()
        .try_fold(1usize, |c, &n| c.checked_mul(n))
        .ok_or_else(|| src.err(format!("{what} {dims:?} overflow the grid size")))
}

fn nrrd_little(h: &NrrdHeader, scalar: Scalar, src: &Source) -> Result<bool, GridError> {
    match h.little {
        Some(l) => Ok(l),
        None if scalar.size() == 1 => Ok(true),
        None => Err(src.err("header has no `endian` field (required for binary data)")),
    }
}

fn parse_numbers<T: std::str::FromStr>(s: &str, what: &str) -> Result<Vec<T>, String> {
    s.split_whitespace()
        .map(|t| {
            t.parse()
                .map_err(|_| format!("{what}: {t:?} is not a number"))
        })
        .collect()
}

/// A vector like `(1,0,0)`.
fn parse_vector(s: &str) -> Result<Vec<f64>, String> {
    let inner = s
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or_else(|| format!("expected a vector like (1,0,0), found {s:?}"))?;
    inner
        .split(',')
        .map(|t| {
            t.trim()
                .parse()
                .map_err(|_| format!("{t:?} is not a number"))
        })
        .collect()
}

fn nrrd_field(h: &mut NrrdHeader, key: &str, value: &str) -> Result<(), String> {
    match key.to_ascii_lowercase().as_str() {
        "type" => {
            h.scalar = Some(match value {
                "double" | "float64" => Scalar::F64,
                "float" | "float32" => Scalar::F32,
                other => return Err(format!("type {other:?} not supported (float or double)")),
            })
        }
        "dimension" => {
            h.dimension = Some(
                value
                    .parse()
                    .map_err(|_| format!("bad dimension {value:?}"))?,
            )
        }
        "sizes" => h.sizes = Some(parse_numbers(value, "sizes")?),
        "spacings" => h.spacings = Some(parse_numbers(value, "spacings")?),
        "space directions" => {
            h.directions = Some(
                value
                    .split_whitespace()
                    .map(parse_vector)
                    .collect::<Result<_, _>>()?,
            )
        }
        "space origin" => h.origin = Some(parse_vector(value)?),
        "encoding" => {
            h.encoding = Some(match value {
                "raw" => Encoding::Raw,
                "ascii" | "text" | "txt" => Encoding::Ascii,
                "gzip" | "gz" => Encoding::Gzip,
                other => {
                    return Err(format!(
                        "encoding {other:?} not supported (raw, ascii or gzip)"
                    ))
                }
            })
        }
        "endian" => {
            h.little = Some(match value {
                "little" => true,
                "big" => false,
                other => return Err(format!("unknown endian {other:?}")),
            })
        }
        "data file" | "datafile" => return Err("detached data files are not supported".into()),
        "byte skip" | "byteskip" | "line skip" | "lineskip" if value != "0" => {
            return Err(format!("{key} is not supported"))
        }
        _ => {}
    }
    Ok(())
}

/// Dimensions, origin and spacing from the header.
fn nrrd_geometry(h: &NrrdHeader) -> Result<RawField, String> {
    let d = h.dimension.ok_or("header has no `dimension` field")?;
    if d != 2 && d != 3 {
        return Err(format!("dimension {d} not supported (2 or 3)"));
    }
    let dims = h.sizes.clone().ok_or("header has no `sizes` field")?;
    if dims.len() != d || dims.iter().any(|&n| n < 2) {
        return Err(format!("sizes {dims:?} must be {d} numbers >= 2"));
    }
    let spacing_per_axis: Vec<f64> = match (&h.directions, &h.spacings) {
        (Some(dirs), _) => {
            if dirs.len() != d {
                return Err(format!("{} space directions for dimension {d}", dirs.len()));
            }
            let mut s = Vec::new();
            for (a, v) in dirs.iter().enumerate() {
                if v.iter().enumerate().any(|(b, &x)| b != a && x != 0.0) || v.len() <= a {
                    return Err(format!("space direction {v:?} is not axis-aligned (rotated grids are not supported)"));
                }
                s.push(v[a]);
            }
            s
        }
        (None, Some(sp)) if sp.len() == d => sp.clone(),
        (None, Some(sp)) => return Err(format!("{} spacings for dimension {d}", sp.len())),
        (None, None) => vec![1.0; d],
    };
    let spacing = uniform_spacing(&spacing_per_axis)?;
    let mut origin = h.origin.clone().unwrap_or_else(|| vec![0.0; d]);
    if origin.len() < d || origin[d..].iter().any(|&x| x != 0.0) {
        return Err(format!(
            "space origin {origin:?} does not match dimension {d}"
        ));
    }
    origin.truncate(d);
    Ok(RawField {
        dims,
        origin,
        spacing,
        values: Vec::new(),
    })
}

/// The one spacing of a grid whose axes all have (nearly) the same spacing.
fn uniform_spacing(per_axis: &[f64]) -> Result<f64, String> {
    let h = per_axis[0];
    if !(h > 0.0 && h.is_finite()) {
        return Err(format!("spacing {h} is not positive"));
    }
    if per_axis.iter().any(|&s| ((s - h) / h).abs() > 1e-9) {
        return Err(format!(
            "spacings {per_axis:?} differ between axes (only uniform grids are supported)"
        ));
    }
    Ok(h)
}

/// Parsed VTK structured-points header fields.
#[derive(Default)]
struct VtkHeader {
    binary: bool,
    dims: Option<Vec<usize>>,
    origin: Option<Vec<f64>>,
    spacing: Option<Vec<f64>>,
    points: Option<usize>,
    scalar: Option<Scalar>,
}

fn parse_vtk(bytes: &[u8], src: &Source) -> Result<RawField, GridError> {
    if !bytes.starts_with(b"# vtk DataFile") {
        return Err(src.err("not a legacy VTK file (it must start with `# vtk DataFile`)"));
    }
    let mut saw_scalars = false;
    // The data follows the LOOKUP_TABLE line that comes after SCALARS.
    let (lines, data_start) = header_lines(bytes, src, false, |l| {
        let upper = l.trim().to_ascii_uppercase();
        saw_scalars |= upper.starts_with("SCALARS");
        saw_scalars && upper.starts_with("LOOKUP_TABLE")
    })?;
    let mut h = VtkHeader::default();
    for &(n, line) in &lines {
        if n <= 2 {
            continue; // version line and title
        }
        vtk_line(&mut h, line).map_err(|m| src.line_err(n, m))?;
    }
    let data_start = header_end(data_start, src)?;
    if !saw_scalars {
        return Err(
            src.err("no `SCALARS` point data found (only scalar structured points are supported)")
        );
    }
    let raw = vtk_geometry(&h).map_err(|m| src.err(m))?;
    let count = grid_points(&raw.dims, "DIMENSIONS", src)?;
    if h.points != Some(count) {
        return Err(src.err(format!(
            "POINT_DATA {:?} does not match {count} grid points",
            h.points
        )));
    }
    let scalar = h
        .scalar
        .ok_or_else(|| src.err("SCALARS line has no type"))?;
    let values = if h.binary {
        decode_binary(bytes, data_start, count, scalar, false, src)?
    } else {
        decode_ascii(bytes, data_start, count, src)?
    };
    Ok(RawField { values, ..raw })
}

fn vtk_line(h: &mut VtkHeader, line: &str) -> Result<(), String> {
    let mut words = line.split_whitespace();
    let Some(key) = words.next() else {
        return Ok(());
    };
    let rest: Vec<&str> = words.collect();
    let rest_str = rest.join(" ");
    match key.to_ascii_uppercase().as_str() {
        "ASCII" => h.binary = false,
        "BINARY" => h.binary = true,
        "DATASET"
            if rest.first().map(|s| s.to_ascii_uppercase()) != Some("STRUCTURED_POINTS".into()) =>
        {
            return Err(format!(
                "dataset {rest_str:?} not supported (STRUCTURED_POINTS only)"
            ))
        }
        "DATASET" => {}
        "DIMENSIONS" => h.dims = Some(parse_numbers(&rest_str, "DIMENSIONS")?),
        "ORIGIN" => h.origin = Some(parse_numbers(&rest_str, "ORIGIN")?),
        "SPACING" | "ASPECT_RATIO" => h.spacing = Some(parse_numbers(&rest_str, "SPACING")?),
        "POINT_DATA" => {
            h.points = Some(
                rest_str
                    .parse()
                    .map_err(|_| format!("bad POINT_DATA {rest_str:?}"))?,
            )
        }
        "SCALARS" => {
            h.scalar = Some(match rest.get(1).copied() {
                Some("double") => Scalar::F64,
                Some("float") => Scalar::F32,
                other => {
                    return Err(format!(
                        "SCALARS type {other:?} not supported (float or double)"
                    ))
                }
            });
            if rest.get(2).is_some_and(|&c| c != "1") {
                return Err("SCALARS with more than one component are not supported".into());
            }
        }
        "LOOKUP_TABLE" => {}
        "CELL_DATA" | "FIELD" | "VECTORS" | "NORMALS" => {
            return Err(format!("{key} before the point scalars is not supported"))
        }
        other => return Err(format!("unexpected keyword {other:?}")),
    }
    Ok(())
}

fn vtk_geometry(h: &VtkHeader) -> Result<RawField, String> {
    let dims = h.dims.clone().ok_or("no DIMENSIONS line")?;
    if dims.len() != 3 || dims.contains(&0) {
        return Err(format!(
            "DIMENSIONS {dims:?} must be three positive numbers"
        ));
    }
    let origin = h.origin.clone().unwrap_or_else(|| vec![0.0; 3]);
    let spacing = h.spacing.clone().unwrap_or_else(|| vec![1.0; 3]);
    if origin.len() != 3 || spacing.len() != 3 {
        return Err("ORIGIN and SPACING need three numbers".into());
    }
    let d = if dims[2] == 1 { 2 } else { 3 };
    if dims[..d].iter().any(|&n| n < 2) {
        return Err(format!(
            "DIMENSIONS {dims:?}: need at least 2 nodes along x and y"
        ));
    }
    Ok(RawField {
        dims: dims[..d].to_vec(),
        origin: origin[..d].to_vec(),
        spacing: uniform_spacing(&spacing[..d])?,
        values: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn field3() -> Field3 {
        let spec = GridSpec {
            origin: [-1.5, 0.25, 3.0],
            spacing: 0.125,
            dims: [5, 4, 3],
        };
        let values = (0..spec.node_count())
            .map(|l| (l as f64).sin() * 1e3 + 1e-9)
            .collect();
        Field { spec, values }
    }

    fn field2() -> Field2 {
        let spec = GridSpec {
            origin: [2.0, -7.5],
            spacing: 0.3,
            dims: [6, 3],
        };
        let values = (0..18).map(|l| l as f64 / 7.0 - 1.0).collect();
        Field { spec, values }
    }

    #[test]
    fn round_trips_in_both_formats_and_dimensions() {
        let dir = tempfile::tempdir().unwrap();
        for ext in ["nrrd", "vtk"] {
            let p3 = dir.path().join(format!("f3.{ext}"));
            write_field(&p3, &field3()).unwrap();
            assert_eq!(read_field(&p3).unwrap(), AnyField::D3(field3()));
            let p2 = dir.path().join(format!("f2.{}", ext.to_uppercase()));
            write_field(&p2, &field2()).unwrap();
            assert_eq!(read_field(&p2).unwrap(), AnyField::D2(field2()));
        }
    }

    fn write_bytes(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    fn nrrd_header(extra: &str) -> String {
        format!("NRRD0005\n# c\ndimension: 2\nsizes: 2 2\nspacings: 0.5 0.5\nkinds: domain domain\n{extra}\n\n")
    }

    /// A gzip stream of `values` (f64, little endian) then `zeros` zero bytes.
    fn gzip_values(values: &[f64], zeros: usize) -> flate2::write::GzEncoder<Vec<u8>> {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        for v in values {
            enc.write_all(&v.to_le_bytes()).unwrap();
        }
        let block = vec![0u8; 1 << 20];
        let mut left = zeros;
        while left > 0 {
            let n = left.min(block.len());
            enc.write_all(&block[..n]).unwrap();
            left -= n;
        }
        enc
    }

    #[test]
    fn reads_nrrd_variants() {
        let dir = tempfile::tempdir().unwrap();
        let expect = [1.0, -2.0, 3.5, 4.25];
        let check = |p: &Path| match read_field(p).unwrap() {
            AnyField::D2(f) => {
                assert_eq!(f.values, expect);
                assert_eq!(f.spec.spacing, 0.5);
                assert_eq!(f.spec.origin, [0.0, 0.0]);
            }
            other => panic!("expected 2D, got {other:?}"),
        };
        let mut be_float = nrrd_header("type: float\nencoding: raw\nendian: big").into_bytes();
        be_float.extend(expect.iter().flat_map(|&v| (v as f32).to_be_bytes()));
        check(&write_bytes(&dir, "be.nrrd", &be_float));
        let ascii = nrrd_header("type: double\nencoding: ascii") + "1 -2\n3.5 4.25\n";
        check(&write_bytes(&dir, "ascii.nrrd", ascii.as_bytes()));
        let mut gz = nrrd_header("type: double\nencoding: gzip\nendian: little").into_bytes();
        gz.extend(gzip_values(&expect, 0).finish().unwrap());
        check(&write_bytes(&dir, "gz.nrrd", &gz));
    }

    #[test]
    fn reads_ascii_float_vtk() {
        let dir = tempfile::tempdir().unwrap();
        let text = "# vtk DataFile Version 2.0\n\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n\
                    ASPECT_RATIO 2 2 2\nORIGIN 1 2 3\nPOINT_DATA 8\nSCALARS d float\nLOOKUP_TABLE default\n\
                    0 1 2 3\n4 5 6 7\n";
        match read_field(write_bytes(&dir, "a.vtk", text.as_bytes())).unwrap() {
            AnyField::D3(f) => {
                assert_eq!(f.values, (0..8).map(f64::from).collect::<Vec<_>>());
                assert_eq!((f.spec.origin, f.spec.spacing), ([1.0, 2.0, 3.0], 2.0));
            }
            other => panic!("expected 3D, got {other:?}"),
        }
    }

    /// The error for `bytes` stored as `name` mentions the file and `needle`.
    fn assert_fails(name: &str, bytes: &[u8], needle: &str) {
        let dir = tempfile::tempdir().unwrap();
        let msg = read_field(write_bytes(&dir, name, bytes))
            .unwrap_err()
            .to_string();
        assert!(msg.contains(name) && msg.contains(needle), "{name}: {msg}");
    }

    #[test]
    fn malformed_files_are_clear_errors() {
        let good = {
            let dir = tempfile::tempdir().unwrap();
            let p = dir.path().join("g.nrrd");
            write_field(&p, &field2()).unwrap();
            std::fs::read(p).unwrap()
        };
        assert_fails("t.nrrd", &good[..good.len() - 3], "truncated");
        assert_fails("m.nrrd", b"NRRX0004\n", "not a NRRD");
        assert_fails(
            "s.nrrd",
            nrrd_header("type: short\nencoding: raw").as_bytes(),
            "short",
        );
        assert_fails(
            "e.nrrd",
            nrrd_header("type: double\nencoding: bzip2").as_bytes(),
            "bzip2",
        );
        assert_fails("l.nrrd", b"NRRD0004\ntype: double\nnonsense\n\n", "line 3");
        assert_fails(
            "r.nrrd",
            b"NRRD0004\ntype: double\ndimension: 2\nsizes: 2 2\nspace directions: (1,1) (0,1)\nencoding: ascii\n\n1 2 3 4\n",
            "axis-aligned",
        );
        assert_fails("u.nrrd", b"NRRD0004\ntype: double\ndimension: 2\nsizes: 2 2\nspacings: 1 2\nencoding: ascii\n\n1 2 3 4\n", "differ");
        assert_fails(
            "n.nrrd",
            (nrrd_header("type: double\nencoding: ascii") + "1 nan 2 3").as_bytes(),
            "NaN",
        );
        assert_fails(
            "f.nrrd",
            (nrrd_header("type: double\nencoding: ascii") + "1 2 3").as_bytes(),
            "truncated",
        );
        assert_fails(
            "x.nrrd",
            (nrrd_header("type: double\nencoding: ascii") + "1 2 3 4 5").as_bytes(),
            "more than",
        );
        let mut gz = nrrd_header("type: double\nencoding: gzip\nendian: little").into_bytes();
        gz.extend(b"not gzip at all");
        assert_fails("g.nrrd", &gz, "gzip");
        let vtk = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 1\nPOINT_DATA 5\nSCALARS v double 1\nLOOKUP_TABLE default\n1 2 3 4\n";
        assert_fails("p.vtk", vtk.as_bytes(), "POINT_DATA");
        assert_fails(
            "d.vtk",
            b"# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\n",
            "POLYDATA",
        );
        assert_fails("q.vtk", b"hello", "legacy VTK");
        // Dimensions whose product passes 2^64 (wrapped to 0 before).
        let huge = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 4294967296 4294967296 4294967296\nPOINT_DATA 3375\nSCALARS v double 1\nLOOKUP_TABLE default\n1 2 3\n";
        assert_fails("o.vtk", huge.as_bytes(), "overflow");
        assert_fails("z.vtk", b"# vtk DataFile Version 3.0\nt\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 1\nPOINT_DATA 4\nSCALARS v double\nLOOKUP_TABLE default\n\x00\x01", "truncated");
        assert_fails("k.raw", b"", "unknown field format");
        // NRRD sizes whose product passes 2^64 (a panic with overflow checks).
        let huge = nrrd_header("").replace("sizes: 2 2", "sizes: 4294967296 4294967296")
            + "type: double\nencoding: ascii\n\n1 2 3\n";
        let huge = huge.replace("\n\n\ntype", "\ntype");
        assert_fails("o.nrrd", huge.as_bytes(), "overflow");
    }

    #[test]
    fn gzip_data_is_inflated_only_as_far_as_the_header_needs() {
        // A 2x2 double field whose gzip stream goes on with 64 MiB of zeros
        // and lacks its trailer. The reader stops after the 32 bytes it
        // needs (+1), so it never inflates the zeros nor reaches the cut
        // trailer; an unbounded read would inflate it all and then fail.
        let expect: [f64; 4] = [1.0, -2.0, 3.5, 4.25];
        let mut gz = nrrd_header("type: double\nencoding: gzip\nendian: little").into_bytes();
        let stream = gzip_values(&expect, 64 << 20).finish().unwrap();
        gz.extend(&stream[..stream.len() - 8]);
        assert!(gz.len() < 200_000, "{} bytes", gz.len());
        let dir = tempfile::tempdir().unwrap();
        match read_field(write_bytes(&dir, "bomb.nrrd", &gz)).unwrap() {
            AnyField::D2(f) => assert_eq!(f.values, expect),
            other => panic!("expected 2D, got {other:?}"),
        }
    }

    #[test]
    fn missing_file_and_unwritable_target_fail_cleanly() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("none.nrrd");
        assert!(matches!(
            read_field(&missing),
            Err(GridError::FieldIo { .. })
        ));
        let target = dir.path().join("no/such/dir/f.vtk");
        assert!(write_field(&target, &field3()).is_err());
        assert!(!target.exists());
        let mut bad = field2();
        bad.values[3] = f64::NAN;
        let p = dir.path().join("nan.nrrd");
        assert!(write_field(&p, &bad)
            .unwrap_err()
            .to_string()
            .contains("NaN"));
        assert!(!p.exists());
    }
}
