//! XYZ: one point per line, `x y [z [nx ny nz]] [s]`.
//!
//! Accepted column counts: 2 (planar, z = 0), 3 (position), 4 (position and
//! a scalar), 6 (position and normal), 7 (position, normal, scalar). Every
//! data line must have the count of the first. Separators are whitespace,
//! commas or semicolons; blank lines and `#` comments are skipped.

use super::text::{is_blank, line_chunks, parse_f64, show, strip_comment, write_f64s, Lines};
use super::Src;
use crate::{GeomError, Geometry, PointCloud};
use glam::DVec3;
use rayon::prelude::*;
use std::io::Write;

/// Column layout fixed by the first data line.
#[derive(Clone, Copy)]
struct Layout {
    columns: usize,
    has_z: bool,
    has_normal: bool,
    has_scalar: bool,
}

impl Layout {
    fn for_columns(columns: usize) -> Option<Layout> {
        let (has_z, has_normal, has_scalar) = match columns {
            2 => (false, false, false),
            3 => (true, false, false),
            4 => (true, false, true),
            6 => (true, true, false),
            7 => (true, true, true),
            _ => return None,
        };
        Some(Layout {
            columns,
            has_z,
            has_normal,
            has_scalar,
        })
    }
}

/// Bytes per piece parsed in parallel: big enough to amortise the
/// hand-off, small enough to balance the cores.
const CHUNK_BYTES: usize = 1 << 20;

pub(crate) fn read(bytes: &[u8], src: &Src) -> Result<Geometry, GeomError> {
    let first = first_layout(bytes, src)?;
    // Lines are independent: parse pieces in parallel, then join them in
    // file order; the first error in file order is the one reported.
    let parts: Vec<Result<Columns, GeomError>> = line_chunks(bytes, 1, CHUNK_BYTES)
        .into_par_iter()
        .map(|(number, chunk)| parse_chunk(chunk, number, first, src))
        .collect();
    let mut all = Columns::default();
    for part in parts {
        all.append(part?);
    }
    let lay = first.0;
    Ok(Geometry::from_points(PointCloud {
        positions: all.positions,
        normals: lay.has_normal.then_some(all.normals),
        scalars: lay.has_scalar.then_some(all.scalars),
    }))
}

/// The layout of the first data line, and that line's number.
fn first_layout(bytes: &[u8], src: &Src) -> Result<(Layout, usize), GeomError> {
    let mut row = [0.0f64; 7];
    for (number, line) in Lines::new(bytes, 1) {
        let line = strip_comment(line);
        if is_blank(line) {
            continue;
        }
        let count = parse_row(line, &mut row, src, number)?;
        let lay = Layout::for_columns(count).ok_or_else(|| {
            src.line(
                number,
                format!("{count} numbers on a line; expected 2, 3, 4, 6 or 7"),
            )
        })?;
        return Ok((lay, number));
    }
    Err(src.file("no points (only blank lines or comments)"))
}

/// Points read from part of a file.
#[derive(Default)]
struct Columns {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    scalars: Vec<f64>,
}

impl Columns {
    fn append(&mut self, mut other: Columns) {
        self.positions.append(&mut other.positions);
        self.normals.append(&mut other.normals);
        self.scalars.append(&mut other.scalars);
    }
}

/// Parse whole lines `chunk`, whose first line is `first_number`; every
/// data line must match the layout of the file's first data line.
fn parse_chunk(
    chunk: &[u8],
    first_number: usize,
    (lay, first): (Layout, usize),
    src: &Src,
) -> Result<Columns, GeomError> {
    let mut out = Columns {
        positions: Vec::with_capacity(chunk.len() / 32),
        ..Default::default()
    };
    let mut row = [0.0f64; 7];
    for (number, line) in Lines::new(chunk, first_number) {
        let line = strip_comment(line);
        if is_blank(line) {
            continue;
        }
        let count = parse_row(line, &mut row, src, number)?;
        if count != lay.columns {
            return Err(src.line(
                number,
                format!(
                    "{count} numbers, but line {first} has {} (every line needs the same columns)",
                    lay.columns
                ),
            ));
        }
        push_row(&row, lay, &mut out);
    }
    Ok(out)
}

/// Parse up to 7 numbers into `row`; returns how many the line holds.
fn parse_row(
    line: &[u8],
    row: &mut [f64; 7],
    src: &Src,
    number: usize,
) -> Result<usize, GeomError> {
    let fields = line
        .split(|&b| b.is_ascii_whitespace() || b == b',' || b == b';')
        .filter(|t| !t.is_empty());
    let mut count = 0;
    for token in fields {
        let v = parse_f64(token)
            .ok_or_else(|| src.line(number, format!("{} is not a number", show(token))))?;
        if !v.is_finite() {
            return Err(src.line(number, format!("non-finite value {}", show(token))));
        }
        if count < row.len() {
            row[count] = v;
        }
        count += 1;
    }
    Ok(count)
}

fn push_row(row: &[f64; 7], lay: Layout, out: &mut Columns) {
    let z = if lay.has_z { row[2] } else { 0.0 };
    out.positions.push(DVec3::new(row[0], row[1], z));
    if lay.has_normal {
        out.normals.push(DVec3::new(row[3], row[4], row[5]));
    }
    if lay.has_scalar {
        out.scalars.push(row[lay.columns - 1]);
    }
}

pub(crate) fn write(w: &mut dyn Write, geom: &Geometry) -> std::io::Result<()> {
    let pts = &geom.points;
    for (i, p) in pts.positions.iter().enumerate() {
        write_f64s(w, &p.to_array())?;
        if let Some(n) = &pts.normals {
            w.write_all(b" ")?;
            write_f64s(w, &n[i].to_array())?;
        }
        if let Some(s) = &pts.scalars {
            w.write_all(b" ")?;
            write_f64s(w, &[s[i]])?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}
