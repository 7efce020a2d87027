//! STL, ascii and binary. Facets become an indexed mesh: corners with
//! identical coordinates are merged into one vertex (in order of first use).
//! Facet normals are not kept (they are implied by the winding).
//!
//! Binary or ascii: a file whose size is exactly `84 + 50 n` for the count
//! `n` stored at byte 80 is binary, unless it starts with `solid` and is
//! plain text throughout (an ascii file that happens to have that size).
//! Otherwise a file starting with `solid` is ascii; anything else is binary
//! with a size that does not match its count, which is an error.
//! Own reader rather than stl_io: this detection, byte/line error positions
//! and exact-coordinate merging into our mesh type are most of the work.

use super::text::{parse_f64, show, write_f64s, Lines};
use super::{Encoding, Src};
use crate::{GeomError, Geometry, PointCloud};
use glam::DVec3;
use std::collections::HashMap;
use std::io::Write;

const HEADER: usize = 80;
const FACET: usize = 50;

pub(crate) fn read(bytes: &[u8], src: &Src) -> Result<Geometry, GeomError> {
    let starts_solid = bytes.trim_ascii_start().starts_with(b"solid");
    if let Some(n) = binary_count(bytes) {
        if bytes.len() == HEADER + 4 + n.saturating_mul(FACET) && !(starts_solid && is_text(bytes))
        {
            return read_binary(bytes, n, src);
        }
    }
    if starts_solid {
        return read_ascii(bytes, src);
    }
    match binary_count(bytes) {
        None => Err(src.file(format!(
            "{} bytes: too short for binary STL and no 'solid' header",
            bytes.len()
        ))),
        Some(n) => Err(src.byte(
            HEADER,
            format!(
                "binary STL header declares {n} triangles ({} bytes) but the file has {} bytes",
                (HEADER as u64 + 4) + n as u64 * FACET as u64,
                bytes.len()
            ),
        )),
    }
}

fn binary_count(bytes: &[u8]) -> Option<usize> {
    let raw: [u8; 4] = bytes.get(HEADER..HEADER + 4)?.try_into().ok()?;
    Some(u32::from_le_bytes(raw) as usize)
}

fn is_text(bytes: &[u8]) -> bool {
    bytes
        .iter()
        .all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace())
}

/// Merges corners with bit-identical coordinates into shared vertices.
#[derive(Default)]
struct Welder {
    index: HashMap<[u64; 3], u32>,
    vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

impl Welder {
    fn with_capacity(triangles: usize) -> Self {
        Welder {
            index: HashMap::with_capacity(triangles / 2),
            vertices: Vec::with_capacity(triangles / 2),
            triangles: Vec::with_capacity(triangles),
        }
    }

    fn vertex(&mut self, p: DVec3) -> u32 {
        // +0.0 and -0.0 are the same point.
        let key = (p + DVec3::ZERO).to_array().map(f64::to_bits);
        *self.index.entry(key).or_insert_with(|| {
            self.vertices.push(p);
            (self.vertices.len() - 1) as u32
        })
    }

    fn triangle(&mut self, corners: [DVec3; 3]) {
        let t = corners.map(|c| self.vertex(c));
        self.triangles.push(t);
    }

    fn finish(self) -> Geometry {
        Geometry {
            points: PointCloud::new(self.vertices),
            triangles: self.triangles,
            lines: Vec::new(),
        }
    }
}

fn read_binary(bytes: &[u8], n: usize, src: &Src) -> Result<Geometry, GeomError> {
    let body = bytes.get(HEADER + 4..).unwrap_or_default();
    let mut welder = Welder::with_capacity(n);
    for (t, facet) in body.chunks_exact(FACET).enumerate() {
        let at = HEADER + 4 + t * FACET;
        let mut corners = [DVec3::ZERO; 3];
        for (c, corner) in corners.iter_mut().enumerate() {
            // Skip the 12-byte facet normal; then three 12-byte corners.
            let start = 12 + 12 * c;
            let mut xyz = [0.0; 3];
            for (k, v) in xyz.iter_mut().enumerate() {
                let raw: [u8; 4] = facet[start + 4 * k..start + 4 * k + 4]
                    .try_into()
                    .unwrap_or_default();
                *v = f32::from_le_bytes(raw) as f64;
            }
            *corner = DVec3::from_array(xyz);
            if !corner.is_finite() {
                return Err(src.byte(at + start, format!("triangle {t} has a non-finite corner")));
            }
        }
        welder.triangle(corners);
    }
    Ok(welder.finish())
}

/// Token reader over the lines of an ascii STL.
struct Tokens<'a> {
    lines: Lines<'a>,
    current: Vec<&'a [u8]>,
    next: usize,
    line: usize,
}

impl<'a> Tokens<'a> {
    fn next(&mut self) -> Option<&'a [u8]> {
        while self.next >= self.current.len() {
            let (number, line) = self.lines.next()?;
            self.current = super::text::tokens(line).collect();
            self.next = 0;
            self.line = number;
        }
        self.next += 1;
        Some(self.current[self.next - 1])
    }

    /// Drop what is left of the current line (e.g. a solid's name).
    fn skip_line(&mut self) {
        self.next = self.current.len();
    }

    fn expect(&mut self, word: &str, src: &Src) -> Result<(), GeomError> {
        match self.next() {
            Some(w) if w.eq_ignore_ascii_case(word.as_bytes()) => Ok(()),
            Some(w) => Err(src.line(self.line, format!("expected '{word}', found {}", show(w)))),
            None => Err(src.file(format!("file ends where '{word}' was expected (truncated)"))),
        }
    }

    fn number(&mut self, src: &Src) -> Result<f64, GeomError> {
        let token = self
            .next()
            .ok_or_else(|| src.file("file ends inside a facet (truncated)"))?;
        let v = parse_f64(token)
            .ok_or_else(|| src.line(self.line, format!("{} is not a number", show(token))))?;
        if !v.is_finite() {
            return Err(src.line(self.line, format!("non-finite value {}", show(token))));
        }
        Ok(v)
    }

    fn point(&mut self, src: &Src) -> Result<DVec3, GeomError> {
        Ok(DVec3::new(
            self.number(src)?,
            self.number(src)?,
            self.number(src)?,
        ))
    }
}

fn read_ascii(bytes: &[u8], src: &Src) -> Result<Geometry, GeomError> {
    let mut tokens = Tokens {
        lines: Lines::new(bytes, 1),
        current: Vec::new(),
        next: 0,
        line: 0,
    };
    let mut welder = Welder::default();
    let mut loop_corners = Vec::new();
    // Several solids may follow each other.
    while let Some(word) = tokens.next() {
        if !word.eq_ignore_ascii_case(b"solid") {
            return Err(src.line(
                tokens.line,
                format!("expected 'solid', found {}", show(word)),
            ));
        }
        tokens.skip_line();
        loop {
            match tokens.next() {
                Some(w) if w.eq_ignore_ascii_case(b"facet") => {
                    read_facet(&mut tokens, &mut loop_corners, src)?;
                    fan(&loop_corners, &mut welder);
                }
                Some(w) if w.eq_ignore_ascii_case(b"endsolid") => {
                    tokens.skip_line();
                    break;
                }
                Some(w) => {
                    let msg = format!("expected 'facet' or 'endsolid', found {}", show(w));
                    return Err(src.line(tokens.line, msg));
                }
                None => return Err(src.file("file ends without 'endsolid' (truncated)")),
            }
        }
    }
    Ok(welder.finish())
}

/// One `facet normal .. outer loop vertex.. endloop endfacet`; the loop's
/// corners go to `corners` (usually three).
fn read_facet(tokens: &mut Tokens, corners: &mut Vec<DVec3>, src: &Src) -> Result<(), GeomError> {
    tokens.expect("normal", src)?;
    tokens.point(src)?;
    tokens.expect("outer", src)?;
    tokens.expect("loop", src)?;
    corners.clear();
    loop {
        match tokens.next() {
            Some(w) if w.eq_ignore_ascii_case(b"vertex") => corners.push(tokens.point(src)?),
            Some(w) if w.eq_ignore_ascii_case(b"endloop") => break,
            Some(w) => {
                let msg = format!("expected 'vertex' or 'endloop', found {}", show(w));
                return Err(src.line(tokens.line, msg));
            }
            None => return Err(src.file("file ends inside a facet (truncated)")),
        }
    }
    if corners.len() < 3 {
        return Err(src.line(
            tokens.line,
            format!("facet with {} vertices", corners.len()),
        ));
    }
    tokens.expect("endfacet", src)
}

fn fan(corners: &[DVec3], welder: &mut Welder) {
    for w in corners[1..].windows(2) {
        welder.triangle([corners[0], w[0], w[1]]);
    }
}

pub(crate) fn write(w: &mut dyn Write, geom: &Geometry, encoding: Encoding) -> std::io::Result<()> {
    match encoding {
        Encoding::Ascii => write_ascii(w, geom),
        // Binary STL is little-endian by definition.
        _ => write_binary(w, geom),
    }
}

fn facet_normal(c: [DVec3; 3]) -> DVec3 {
    (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero()
}

fn corners(geom: &Geometry, t: &[u32; 3]) -> [DVec3; 3] {
    t.map(|i| geom.points.positions[i as usize])
}

fn write_ascii(w: &mut dyn Write, geom: &Geometry) -> std::io::Result<()> {
    writeln!(w, "solid surfrecon")?;
    for t in &geom.triangles {
        let c = corners(geom, t);
        w.write_all(b"facet normal ")?;
        write_f64s(w, &facet_normal(c).to_array())?;
        w.write_all(b"\nouter loop\n")?;
        for p in c {
            w.write_all(b"vertex ")?;
            write_f64s(w, &p.to_array())?;
            w.write_all(b"\n")?;
        }
        w.write_all(b"endloop\nendfacet\n")?;
    }
    writeln!(w, "endsolid surfrecon")
}

fn write_binary(w: &mut dyn Write, geom: &Geometry) -> std::io::Result<()> {
    // Must not start with "solid", or readers may take it for ascii.
    let mut header = [b' '; HEADER];
    let text = b"binary STL written by surfrecon";
    header[..text.len()].copy_from_slice(text);
    w.write_all(&header)?;
    let count = u32::try_from(geom.triangles.len())
        .map_err(|_| std::io::Error::other("too many triangles for binary STL"))?;
    w.write_all(&count.to_le_bytes())?;
    for t in &geom.triangles {
        let c = corners(geom, t);
        let mut facet = [0u8; FACET];
        let values = std::iter::once(facet_normal(c)).chain(c);
        for (slot, v) in facet
            .chunks_exact_mut(4)
            .zip(values.flat_map(|p| p.to_array()))
        {
            let single = v as f32;
            if !single.is_finite() {
                return Err(std::io::Error::other(format!(
                    "coordinate {v} does not fit binary STL's 32-bit floats"
                )));
            }
            slot.copy_from_slice(&single.to_le_bytes());
        }
        w.write_all(&facet)?;
    }
    Ok(())
}
