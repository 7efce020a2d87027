//! PLY, ascii and binary (little- and big-endian).
//!
//! Reads the `vertex` element (x, y, optional z, optional nx/ny/nz, one
//! optional scalar named `confidence`, `intensity`, `quality`, `scalar`,
//! `value` or `scalar_*`; any numeric types) and the `face` element
//! (`vertex_indices` or `vertex_index` list, any count/index types, polygons
//! fan-triangulated). Other properties and elements are skipped.
//!
//! Our own parser rather than a crate: ply-rs-bw through its typed hooks
//! was measured at 0.08 s for a 1M-point file with normals (its generic
//! path 20x slower), and we need byte/line error positions and count checks
//! before allocating anyway. The vertex block of a binary file with
//! fixed-size rows is decoded row by row in parallel, the property type and
//! byte order dispatched once per block (about 0.04 s of CPU for that file,
//! see `benches/io.rs`); everything else goes through one general row
//! reader shared by ascii and binary, so both report errors the same way
//! (line for ascii, byte offset for binary).

use super::text::{is_blank, parse_f64, parse_i64, show, tokens, write_f64s, Lines};
use super::{fan_triangulate, Encoding, Src};
use crate::{GeomError, Geometry, PointCloud};
use glam::DVec3;
use rayon::prelude::*;
use std::io::Write;

/// Names accepted for the one per-vertex scalar, in order of preference.
const SCALAR_NAMES: [&str; 5] = ["confidence", "intensity", "quality", "scalar", "value"];

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decode a value from the start of `b`; `None` if `b` is too short.
    fn decode(self, b: &[u8], big: bool) -> Option<f64> {
        Some(match self {
            Scalar::I8 => *b.first()? as i8 as f64,
            Scalar::U8 => *b.first()? as f64,
            Scalar::I16 => pick(i16::from_le_bytes, i16::from_be_bytes, b, big)? as f64,
            Scalar::U16 => pick(u16::from_le_bytes, u16::from_be_bytes, b, big)? as f64,
            Scalar::I32 => pick(i32::from_le_bytes, i32::from_be_bytes, b, big)? as f64,
            Scalar::U32 => pick(u32::from_le_bytes, u32::from_be_bytes, b, big)? as f64,
            Scalar::F32 => pick(f32::from_le_bytes, f32::from_be_bytes, b, big)? as f64,
            Scalar::F64 => pick(f64::from_le_bytes, f64::from_be_bytes, b, big)?,
        })
    }
}

/// Apply the little- or big-endian decoder to the first `N` bytes of `b`.
#[inline(always)]
fn pick<const N: usize, T>(
    le: fn([u8; N]) -> T,
    be: fn([u8; N]) -> T,
    b: &[u8],
    big: bool,
) -> Option<T> {
    let bytes: [u8; N] = b.get(..N)?.try_into().ok()?;
    Some(if big { be(bytes) } else { le(bytes) })
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
    /// Header line that declared it.
    line: usize,
}

impl Element {
    /// Bytes per row when every property is a scalar.
    fn fixed_row_size(&self) -> Option<usize> {
        self.props
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => Some(s.size()),
                Kind::List { .. } => None,
            })
            .sum()
    }

    /// Fewest bytes one binary row can take (lists empty).
    fn min_row_size(&self) -> usize {
        self.props
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => s.size(),
                Kind::List { count, .. } => count.size(),
            })
            .sum()
    }

    fn find(&self, name: &str) -> Option<usize> {
        self.props.iter().position(|p| p.name == name)
    }
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the body.
    body: usize,
    /// Line number of the first body line (ascii).
    body_line: usize,
}

pub(crate) fn read(bytes: &[u8], src: &Src) -> Result<Geometry, GeomError> {
    let header = parse_header(bytes, src)?;
    let vertex = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| src.file("no 'vertex' element in the header"))?;
    let layout = VertexLayout::new(&header.elements[vertex], src)?;
    let mut body = Body::new(&header, bytes, src);
    let mut out = Geometry::default();
    for (index, el) in header.elements.iter().enumerate() {
        if index == vertex {
            out.points = body.vertices(el, &layout)?;
        } else if el.name == "face" {
            let nverts = header.elements[vertex].count;
            out.triangles = body.faces(el, nverts)?;
        } else {
            body.skip(el)?;
        }
    }
    body.finish()?;
    Ok(out)
}

fn parse_header(bytes: &[u8], src: &Src) -> Result<Header, GeomError> {
    let mut lines = Lines::new(bytes, 1);
    match lines.next() {
        Some((_, l)) if l.trim_ascii() == b"ply" => {}
        _ => return Err(src.line(1, "not a PLY file (first line is not 'ply')")),
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some((number, line)) = lines.next() else {
            return Err(src.file("header has no 'end_header' line"));
        };
        let mut words = tokens(line);
        match words.next() {
            Some(b"end_header") => break,
            Some(b"comment") | Some(b"obj_info") | None => {}
            Some(b"format") => encoding = Some(parse_format(words, src, number)?),
            Some(b"element") => elements.push(parse_element(words, src, number)?),
            Some(b"property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| src.line(number, "property before any element"))?;
                el.props.push(parse_property(words, src, number)?);
            }
            Some(other) => {
                return Err(src.line(number, format!("unknown header keyword {}", show(other))))
            }
        }
    }
    let encoding = encoding.ok_or_else(|| src.file("header has no 'format' line"))?;
    check_unique(&elements, src)?;
    Ok(Header {
        encoding,
        elements,
        body: bytes.len() - lines.rest().len(),
        body_line: lines.number() + 1,
    })
}

fn parse_format<'a>(
    mut words: impl Iterator<Item = &'a [u8]>,
    src: &Src,
    number: usize,
) -> Result<Encoding, GeomError> {
    match words.next() {
        Some(b"ascii") => Ok(Encoding::Ascii),
        Some(b"binary_little_endian") => Ok(Encoding::BinaryLittleEndian),
        Some(b"binary_big_endian") => Ok(Encoding::BinaryBigEndian),
        Some(w) => Err(src.line(number, format!("unknown PLY format {}", show(w)))),
        None => Err(src.line(number, "format line names no format")),
    }
}

fn parse_element<'a>(
    mut words: impl Iterator<Item = &'a [u8]>,
    src: &Src,
    number: usize,
) -> Result<Element, GeomError> {
    let (Some(name), Some(count)) = (words.next(), words.next()) else {
        return Err(src.line(number, "element line needs a name and a count"));
    };
    let count = parse_i64(count)
        .and_then(|c| usize::try_from(c).ok())
        .ok_or_else(|| src.line(number, format!("bad element count {}", show(count))))?;
    Ok(Element {
        name: String::from_utf8_lossy(name).into_owned(),
        count,
        props: Vec::new(),
        line: number,
    })
}

fn parse_property<'a>(
    mut words: impl Iterator<Item = &'a [u8]>,
    src: &Src,
    number: usize,
) -> Result<Property, GeomError> {
    let scalar = |w: Option<&[u8]>| {
        let w = w.ok_or_else(|| src.line(number, "incomplete property line"))?;
        Scalar::from_name(w)
            .ok_or_else(|| src.line(number, format!("unknown property type {}", show(w))))
    };
    let first = words.next();
    let kind = if first == Some(b"list".as_slice()) {
        let count = scalar(words.next())?;
        let item = scalar(words.next())?;
        if !count.is_integer() {
            return Err(src.line(number, "list count type must be an integer type"));
        }
        Kind::List { count, item }
    } else {
        Kind::Scalar(scalar(first)?)
    };
    let name = words
        .next()
        .ok_or_else(|| src.line(number, "property has no name"))?;
    Ok(Property {
        name: String::from_utf8_lossy(name).into_owned(),
        kind,
    })
}

fn check_unique(elements: &[Element], src: &Src) -> Result<(), GeomError> {
    for name in ["vertex", "face"] {
        let mut same = elements.iter().filter(|e| e.name == name);
        if let (Some(_), Some(second)) = (same.next(), same.next()) {
            return Err(src.line(second.line, format!("second '{name}' element")));
        }
    }
    Ok(())
}

/// Where the wanted values sit among the vertex properties.
struct VertexLayout {
    xyz: [Option<usize>; 3],
    normal: Option<[usize; 3]>,
    scalar: Option<usize>,
}

impl VertexLayout {
    fn new(el: &Element, src: &Src) -> Result<VertexLayout, GeomError> {
        let scalar_prop = |name: &str| {
            el.find(name)
                .filter(|&i| matches!(el.props[i].kind, Kind::Scalar(_)))
        };
        let xyz = [scalar_prop("x"), scalar_prop("y"), scalar_prop("z")];
        if xyz[0].is_none() || xyz[1].is_none() {
            return Err(src.line(
                el.line,
                "vertex element needs scalar 'x' and 'y' properties",
            ));
        }
        let normal = match [scalar_prop("nx"), scalar_prop("ny"), scalar_prop("nz")] {
            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
            _ => None,
        };
        let scalar = SCALAR_NAMES
            .iter()
            .find_map(|n| scalar_prop(n))
            .or_else(|| {
                (0..el.props.len()).find(|&i| {
                    el.props[i].name.starts_with("scalar_")
                        && matches!(el.props[i].kind, Kind::Scalar(_))
                })
            });
        if el.count > u32::MAX as usize {
            return Err(src.line(el.line, "more vertices than 32-bit indices can address"));
        }
        Ok(VertexLayout {
            xyz,
            normal,
            scalar,
        })
    }

    /// Which output slot property `p` feeds: 0-2 position, 3-5 normal,
    /// 6 scalar.
    fn slots(&self, nprops: usize) -> Vec<Option<usize>> {
        let mut slots = vec![None; nprops];
        for (axis, p) in self.xyz.iter().enumerate() {
            if let Some(p) = p {
                slots[*p] = Some(axis);
            }
        }
        if let Some(n) = self.normal {
            for (axis, p) in n.iter().enumerate() {
                slots[*p] = Some(3 + axis);
            }
        }
        if let Some(s) = self.scalar {
            slots[s] = Some(6);
        }
        slots
    }
}

/// The vertex data being filled.
struct VertexData {
    positions: Vec<DVec3>,
    normals: Option<Vec<DVec3>>,
    scalars: Option<Vec<f64>>,
}

impl VertexData {
    fn zeroed(count: usize, layout: &VertexLayout) -> VertexData {
        VertexData {
            positions: vec![DVec3::ZERO; count],
            normals: layout.normal.map(|_| vec![DVec3::ZERO; count]),
            scalars: layout.scalar.map(|_| vec![0.0; count]),
        }
    }

    /// Store value `v` of output slot `slot` (see [`VertexLayout::slots`]).
    fn set(&mut self, row: usize, slot: usize, v: f64) {
        match (slot, &mut self.normals, &mut self.scalars) {
            (0..=2, _, _) => self.positions[row][slot] = v,
            (3..=5, Some(n), _) => n[row][slot - 3] = v,
            (6, _, Some(s)) => s[row] = v,
            _ => {}
        }
    }

    fn row_is_finite(&self, row: usize) -> bool {
        self.positions[row].is_finite()
            && self.normals.as_ref().is_none_or(|n| n[row].is_finite())
            && self.scalars.as_ref().is_none_or(|s| s[row].is_finite())
    }

    fn into_cloud(self) -> PointCloud {
        PointCloud {
            positions: self.positions,
            normals: self.normals,
            scalars: self.scalars,
        }
    }
}

/// Byte offset (within a row) and type of one fixed-size property.
#[derive(Clone, Copy)]
struct Field {
    offset: usize,
    ty: Scalar,
}

/// Below this many rows, decoding in parallel costs more than it saves.
const PARALLEL_ROWS: usize = 1 << 14;

/// Decode one vector per fixed-size row from three fields (a missing field
/// reads as 0). Rows are independent, so they are decoded in parallel; the
/// type and byte order are dispatched once, so the common all-float and
/// all-double cases compile to a tight loop.
fn decode_vec3s(
    block: &[u8],
    row_size: usize,
    fields: [Option<Field>; 3],
    big: bool,
) -> Vec<DVec3> {
    let same_type = match fields {
        [Some(a), Some(b), Some(c)] if a.ty == b.ty && b.ty == c.ty => Some(a.ty),
        _ => None,
    };
    let offsets = fields.map(|f| f.map_or(0, |f| f.offset));
    match (same_type, big) {
        (Some(Scalar::F32), false) => {
            vec3s::<4>(block, row_size, offsets, |b| f32::from_le_bytes(b) as f64)
        }
        (Some(Scalar::F32), true) => {
            vec3s::<4>(block, row_size, offsets, |b| f32::from_be_bytes(b) as f64)
        }
        (Some(Scalar::F64), false) => vec3s::<8>(block, row_size, offsets, f64::from_le_bytes),
        (Some(Scalar::F64), true) => vec3s::<8>(block, row_size, offsets, f64::from_be_bytes),
        _ => rows(block, row_size)
            .map(|row| {
                DVec3::from_array(fields.map(|f| f.map_or(0.0, |f| field_value(row, f, big))))
            })
            .collect(),
    }
}

fn vec3s<const N: usize>(
    block: &[u8],
    row_size: usize,
    offsets: [usize; 3],
    decode: impl Fn([u8; N]) -> f64 + Sync,
) -> Vec<DVec3> {
    // Never NaN in practice: offsets lie inside the row by construction.
    let get = |row: &[u8], at: usize| {
        row.get(at..at + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .map_or(f64::NAN, &decode)
    };
    rows(block, row_size)
        .map(|row| {
            DVec3::new(
                get(row, offsets[0]),
                get(row, offsets[1]),
                get(row, offsets[2]),
            )
        })
        .collect()
}

/// One value per fixed-size row.
fn decode_scalars(block: &[u8], row_size: usize, field: Field, big: bool) -> Vec<f64> {
    rows(block, row_size)
        .map(|row| field_value(row, field, big))
        .collect()
}

fn field_value(row: &[u8], field: Field, big: bool) -> f64 {
    row.get(field.offset..)
        .and_then(|b| field.ty.decode(b, big))
        .unwrap_or(f64::NAN)
}

/// The rows of a fixed-size block as an ordered parallel iterator.
fn rows(block: &[u8], row_size: usize) -> impl IndexedParallelIterator<Item = &[u8]> {
    block.par_chunks_exact(row_size).with_min_len(PARALLEL_ROWS)
}

/// Reading position in the body: the next line (ascii) or byte (binary).
struct Body<'a, 's> {
    src: &'s Src<'s>,
    bytes: &'a [u8],
    encoding: Encoding,
    /// Binary: offset of the next unread byte.
    pos: usize,
    /// Ascii: the remaining lines.
    lines: Lines<'a>,
    /// Ascii: tokens of the current row and the next one to read.
    tokens: Vec<&'a [u8]>,
    next_token: usize,
    /// Where the current row starts (line number or byte offset).
    row_at: usize,
}

impl<'a, 's> Body<'a, 's> {
    fn new(header: &Header, bytes: &'a [u8], src: &'s Src<'s>) -> Self {
        let rest = bytes.get(header.body..).unwrap_or_default();
        Body {
            src,
            bytes,
            encoding: header.encoding,
            pos: header.body,
            lines: Lines::new(rest, header.body_line),
            tokens: Vec::new(),
            next_token: 0,
            row_at: 0,
        }
    }

    fn ascii(&self) -> bool {
        self.encoding == Encoding::Ascii
    }

    fn big(&self) -> bool {
        self.encoding == Encoding::BinaryBigEndian
    }

    /// An error at the current row.
    fn row_error(&self, msg: impl Into<String>) -> GeomError {
        if self.ascii() {
            self.src.line(self.row_at, msg)
        } else {
            self.src.byte(self.row_at, msg)
        }
    }

    /// An error at the current reading position.
    fn here_error(&self, msg: impl Into<String>) -> GeomError {
        if self.ascii() {
            self.src.line(self.lines.number() + 1, msg)
        } else {
            self.src.byte(self.pos, msg)
        }
    }

    /// Refuse counts the rest of the file cannot hold, before allocating.
    fn check_fits(&self, el: &Element) -> Result<(), GeomError> {
        let (per_row, available) = if self.ascii() {
            // A row is at least one character and a line end.
            (2, self.lines.rest().len() + 1)
        } else {
            (el.min_row_size(), self.bytes.len().saturating_sub(self.pos))
        };
        if el.count.saturating_mul(per_row) > available {
            return Err(self.here_error(format!(
                "header declares {} '{}' rows, more than the remaining {available} bytes can hold \
                 (truncated file or wrong count)",
                el.count, el.name
            )));
        }
        Ok(())
    }

    fn begin_row(&mut self, el: &Element, row: usize) -> Result<(), GeomError> {
        if !self.ascii() {
            self.row_at = self.pos;
            return Ok(());
        }
        let (number, line) = loop {
            match self.lines.next() {
                Some((_, l)) if is_blank(l) => continue,
                Some(found) => break found,
                None => {
                    return Err(self.src.file(format!(
                        "file ends after {row} of {} '{}' rows (truncated file or wrong count)",
                        el.count, el.name
                    )))
                }
            }
        };
        self.row_at = number;
        self.tokens.clear();
        self.tokens.extend(tokens(line));
        self.next_token = 0;
        Ok(())
    }

    fn end_row(&mut self, el: &Element) -> Result<(), GeomError> {
        if self.ascii() && self.next_token < self.tokens.len() {
            return Err(self.row_error(format!(
                "{} values on a '{}' row, more than its properties declare",
                self.tokens.len(),
                el.name
            )));
        }
        Ok(())
    }

    /// The next value of the current row.
    fn value(&mut self, ty: Scalar, el: &Element) -> Result<f64, GeomError> {
        if self.ascii() {
            let token =
                self.tokens.get(self.next_token).copied().ok_or_else(|| {
                    self.row_error(format!("too few values on a '{}' row", el.name))
                })?;
            self.next_token += 1;
            return parse_f64(token)
                .ok_or_else(|| self.row_error(format!("{} is not a number", show(token))));
        }
        let v = self
            .bytes
            .get(self.pos..)
            .and_then(|b| ty.decode(b, self.big()))
            .ok_or_else(|| {
                self.here_error(format!("file ends inside a '{}' row (truncated)", el.name))
            })?;
        self.pos += ty.size();
        Ok(v)
    }

    /// The length of a list property.
    fn list_len(&mut self, ty: Scalar, el: &Element) -> Result<usize, GeomError> {
        let v = self.value(ty, el)?;
        if v < 0.0 || v.fract() != 0.0 {
            return Err(self.row_error(format!("invalid list length {v} in '{}'", el.name)));
        }
        Ok(v as usize)
    }

    fn vertices(&mut self, el: &Element, layout: &VertexLayout) -> Result<PointCloud, GeomError> {
        self.check_fits(el)?;
        if let (false, Some(row_size)) = (self.ascii(), el.fixed_row_size()) {
            return self.vertex_block(el, row_size, layout);
        }
        let mut data = VertexData::zeroed(el.count, layout);
        self.vertex_rows(el, &layout.slots(el.props.len()), &mut data)?;
        Ok(data.into_cloud())
    }

    /// General path: row by row, checking each row.
    fn vertex_rows(
        &mut self,
        el: &Element,
        slots: &[Option<usize>],
        data: &mut VertexData,
    ) -> Result<(), GeomError> {
        for row in 0..el.count {
            self.begin_row(el, row)?;
            for (prop, slot) in el.props.iter().zip(slots) {
                match prop.kind {
                    Kind::Scalar(ty) => {
                        let v = self.value(ty, el)?;
                        if let Some(slot) = slot {
                            data.set(row, *slot, v);
                        }
                    }
                    Kind::List { count, item } => self.skip_list(count, item, el)?,
                }
            }
            self.end_row(el)?;
            if !data.row_is_finite(row) {
                return Err(self.row_error(format!(
                    "vertex {row} has a non-finite coordinate, normal or scalar"
                )));
            }
        }
        Ok(())
    }

    /// Fast path: fixed-size binary rows decoded field by field.
    fn vertex_block(
        &mut self,
        el: &Element,
        row_size: usize,
        layout: &VertexLayout,
    ) -> Result<PointCloud, GeomError> {
        // No overflow: check_fits bounded count * row_size by the file size.
        let len = el.count * row_size;
        let block = self.bytes.get(self.pos..self.pos + len).ok_or_else(|| {
            self.here_error(format!("file ends inside the '{}' element", el.name))
        })?;
        let mut fields = Vec::with_capacity(el.props.len());
        let mut offset = 0;
        for prop in &el.props {
            let Kind::Scalar(ty) = prop.kind else {
                continue;
            };
            fields.push(Field { offset, ty });
            offset += ty.size();
        }
        let field = |p: Option<usize>| p.and_then(|i| fields.get(i).copied());
        let big = self.big();
        let cloud = PointCloud {
            positions: decode_vec3s(block, row_size, layout.xyz.map(field), big),
            normals: layout
                .normal
                .map(|n| decode_vec3s(block, row_size, n.map(|i| field(Some(i))), big)),
            scalars: field(layout.scalar).map(|f| decode_scalars(block, row_size, f, big)),
        };
        let bad_normal = |n: &Vec<DVec3>| n.iter().position(|p| !p.is_finite());
        let bad = [
            cloud.positions.iter().position(|p| !p.is_finite()),
            cloud.normals.as_ref().and_then(bad_normal),
            cloud
                .scalars
                .as_ref()
                .and_then(|s| s.iter().position(|x| !x.is_finite())),
        ];
        if let Some(row) = bad.into_iter().flatten().min() {
            return Err(self.src.byte(
                self.pos + row * row_size,
                format!("vertex {row} has a non-finite coordinate, normal or scalar"),
            ));
        }
        self.pos += len;
        Ok(cloud)
    }

    fn skip_list(&mut self, count: Scalar, item: Scalar, el: &Element) -> Result<(), GeomError> {
        let n = self.list_len(count, el)?;
        if !self.ascii() {
            // Skip the items at once; a huge n must not loop.
            let len = n.saturating_mul(item.size());
            if len > self.bytes.len().saturating_sub(self.pos) {
                return Err(
                    self.here_error(format!("file ends inside a '{}' list (truncated)", el.name))
                );
            }
            self.pos += len;
            return Ok(());
        }
        for _ in 0..n {
            self.value(item, el)?;
        }
        Ok(())
    }

    fn faces(&mut self, el: &Element, nverts: usize) -> Result<Vec<[u32; 3]>, GeomError> {
        let list = ["vertex_indices", "vertex_index"]
            .iter()
            .find_map(|n| el.find(n))
            .filter(|&i| matches!(el.props[i].kind, Kind::List { .. }))
            .ok_or_else(|| {
                self.src
                    .line(el.line, "face element has no 'vertex_indices' list")
            })?;
        self.check_fits(el)?;
        let mut triangles = Vec::with_capacity(el.count.min(1 << 24));
        let mut corners = Vec::new();
        for row in 0..el.count {
            self.begin_row(el, row)?;
            for (p, prop) in el.props.iter().enumerate() {
                match prop.kind {
                    Kind::List { count, item } if p == list => {
                        self.face_corners(count, item, el, row, nverts, &mut corners)?
                    }
                    Kind::List { count, item } => self.skip_list(count, item, el)?,
                    Kind::Scalar(ty) => {
                        self.value(ty, el)?;
                    }
                }
            }
            self.end_row(el)?;
            fan_triangulate(&corners, &mut triangles);
        }
        Ok(triangles)
    }

    fn face_corners(
        &mut self,
        count: Scalar,
        item: Scalar,
        el: &Element,
        row: usize,
        nverts: usize,
        corners: &mut Vec<u32>,
    ) -> Result<(), GeomError> {
        let n = self.list_len(count, el)?;
        corners.clear();
        for _ in 0..n {
            let v = self.value(item, el)?;
            if !(v >= 0.0 && v < nverts as f64 && v.fract() == 0.0) {
                return Err(self.row_error(format!(
                    "face {row}: vertex index {v} out of range (file has {nverts} vertices)"
                )));
            }
            corners.push(v as u32);
        }
        Ok(())
    }

    fn skip(&mut self, el: &Element) -> Result<(), GeomError> {
        self.check_fits(el)?;
        if let (false, Some(row_size)) = (self.ascii(), el.fixed_row_size()) {
            self.pos += el.count * row_size; // fits: checked above
            return Ok(());
        }
        for row in 0..el.count {
            self.begin_row(el, row)?;
            for prop in &el.props {
                match prop.kind {
                    Kind::Scalar(ty) => {
                        self.value(ty, el)?;
                    }
                    Kind::List { count, item } => self.skip_list(count, item, el)?,
                }
            }
            self.end_row(el)?;
        }
        Ok(())
    }

    /// Anything after the last element means the header counts are wrong.
    fn finish(&mut self) -> Result<(), GeomError> {
        if self.ascii() {
            if let Some((number, _)) = self.lines.by_ref().find(|(_, l)| !is_blank(l)) {
                return Err(self.src.line(
                    number,
                    "extra data after the last element (header counts too small?)",
                ));
            }
        } else if self.pos < self.bytes.len() {
            let extra = self.bytes.len() - self.pos;
            return Err(self.here_error(format!(
                "{extra} bytes of extra data after the last element (header counts too small?)"
            )));
        }
        Ok(())
    }
}

pub(crate) fn write(w: &mut dyn Write, geom: &Geometry, encoding: Encoding) -> std::io::Result<()> {
    write_header(w, geom, encoding)?;
    let pts = &geom.points;
    for (i, p) in pts.positions.iter().enumerate() {
        let mut row = [0.0; 7];
        let mut len = 0;
        let mut push = |v: f64| {
            row[len] = v;
            len += 1;
        };
        p.to_array().into_iter().for_each(&mut push);
        if let Some(n) = &pts.normals {
            n[i].to_array().into_iter().for_each(&mut push);
        }
        if let Some(s) = &pts.scalars {
            push(s[i]);
        }
        write_vertex(w, &row[..len], encoding)?;
    }
    for t in &geom.triangles {
        write_face(w, t, encoding)?;
    }
    Ok(())
}

fn write_header(w: &mut dyn Write, geom: &Geometry, encoding: Encoding) -> std::io::Result<()> {
    let format = match encoding {
        Encoding::Ascii => "ascii",
        Encoding::BinaryLittleEndian => "binary_little_endian",
        Encoding::BinaryBigEndian => "binary_big_endian",
    };
    let pts = &geom.points;
    writeln!(w, "ply\nformat {format} 1.0\ncomment written by surfrecon")?;
    writeln!(w, "element vertex {}", pts.positions.len())?;
    // Doubles: positions must survive a round trip exactly.
    writeln!(w, "property double x\nproperty double y\nproperty double z")?;
    if pts.normals.is_some() {
        writeln!(
            w,
            "property double nx\nproperty double ny\nproperty double nz"
        )?;
    }
    if pts.scalars.is_some() {
        writeln!(w, "property double quality")?;
    }
    if !geom.triangles.is_empty() {
        writeln!(w, "element face {}", geom.triangles.len())?;
        writeln!(w, "property list uchar uint vertex_indices")?;
    }
    writeln!(w, "end_header")
}

fn write_vertex(w: &mut dyn Write, values: &[f64], encoding: Encoding) -> std::io::Result<()> {
    match encoding {
        Encoding::Ascii => {
            write_f64s(w, values)?;
            w.write_all(b"\n")
        }
        Encoding::BinaryLittleEndian => values
            .iter()
            .try_for_each(|v| w.write_all(&v.to_le_bytes())),
        Encoding::BinaryBigEndian => values
            .iter()
            .try_for_each(|v| w.write_all(&v.to_be_bytes())),
    }
}

fn write_face(w: &mut dyn Write, t: &[u32; 3], encoding: Encoding) -> std::io::Result<()> {
    match encoding {
        Encoding::Ascii => writeln!(w, "3 {} {} {}", t[0], t[1], t[2]),
        Encoding::BinaryLittleEndian => {
            w.write_all(&[3])?;
            t.iter().try_for_each(|i| w.write_all(&i.to_le_bytes()))
        }
        Encoding::BinaryBigEndian => {
            w.write_all(&[3])?;
            t.iter().try_for_each(|i| w.write_all(&i.to_be_bytes()))
        }
    }
}
