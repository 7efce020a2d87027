//! OFF (Object File Format), ascii.
//!
//! Header keyword `OFF` with optional prefixes `ST`, `C`, `N` (texture
//! coordinates, colours, normals: only normals are kept), or no keyword at
//! all; the counts `vertices faces [edges]` may follow on the same line.
//! One vertex per line (`x y z [nx ny nz] [colour] [st]`), one face per line
//! (`k i1 .. ik [colour]`), polygons fan-triangulated. `#` comments and blank
//! lines are skipped. 4D/nD and binary OFF are refused with a clear error.

use super::text::{is_blank, parse_f64, parse_i64, show, strip_comment, tokens, write_f64s, Lines};
use super::{fan_triangulate, Src};
use crate::{GeomError, Geometry, PointCloud};
use glam::DVec3;
use std::io::Write;

/// Data lines (comments stripped, blank lines dropped) with their numbers.
struct DataLines<'a> {
    lines: Lines<'a>,
}

impl<'a> Iterator for DataLines<'a> {
    type Item = (usize, &'a [u8]);
    fn next(&mut self) -> Option<Self::Item> {
        self.lines
            .by_ref()
            .map(|(n, l)| (n, strip_comment(l)))
            .find(|(_, l)| !is_blank(l))
    }
}

struct Counts {
    vertices: usize,
    faces: usize,
    has_normals: bool,
}

pub(crate) fn read(bytes: &[u8], src: &Src) -> Result<Geometry, GeomError> {
    let mut lines = DataLines {
        lines: Lines::new(bytes, 1),
    };
    let counts = read_header(&mut lines, src)?;
    // Each vertex or face line takes at least two bytes.
    if counts.vertices.saturating_add(counts.faces) > bytes.len() / 2 + 1 {
        return Err(src.file(format!(
            "header declares {} vertices and {} faces, more than the file's {} bytes can hold",
            counts.vertices,
            counts.faces,
            bytes.len()
        )));
    }
    let (positions, normals) = read_vertices(&mut lines, &counts, src)?;
    let triangles = read_faces(&mut lines, &counts, src)?;
    if let Some((number, _)) = lines.next() {
        return Err(src.line(
            number,
            "extra data after the last face (header counts too small?)",
        ));
    }
    Ok(Geometry {
        points: PointCloud {
            positions,
            normals,
            scalars: None,
        },
        triangles,
        lines: Vec::new(),
    })
}

fn read_header(lines: &mut DataLines, src: &Src) -> Result<Counts, GeomError> {
    let (number, first) = lines
        .next()
        .ok_or_else(|| src.file("no OFF header (only comments)"))?;
    let mut words: Vec<&[u8]> = tokens(first).collect();
    let mut has_normals = false;
    if let Some(keyword) = words.first().copied().filter(|w| w.ends_with(b"OFF")) {
        has_normals = parse_keyword(keyword, src, number)?;
        words.remove(0);
        if words
            .first()
            .is_some_and(|w| w.eq_ignore_ascii_case(b"BINARY"))
        {
            return Err(src.line(number, "binary OFF is not supported"));
        }
    }
    let mut count_line = number;
    if words.is_empty() {
        let (n, line) = lines
            .next()
            .ok_or_else(|| src.file("file ends before the vertex and face counts"))?;
        words = tokens(line).collect();
        count_line = n;
    }
    let count = |i: usize, what: &str| {
        let token = words
            .get(i)
            .ok_or_else(|| src.line(count_line, format!("missing {what} count")))?;
        parse_i64(token)
            .and_then(|c| usize::try_from(c).ok())
            .ok_or_else(|| src.line(count_line, format!("bad {what} count {}", show(token))))
    };
    Ok(Counts {
        vertices: count(0, "vertex")?,
        faces: count(1, "face")?,
        has_normals,
    })
}

/// Whether the keyword (`[ST][C][N]OFF`) announces normals.
fn parse_keyword(keyword: &[u8], src: &Src, number: usize) -> Result<bool, GeomError> {
    let prefix = &keyword[..keyword.len() - 3];
    if prefix.contains(&b'4') || prefix.contains(&b'n') {
        return Err(src.line(
            number,
            format!("{} (4D or nD OFF) is not supported", show(keyword)),
        ));
    }
    if !prefix.iter().all(|c| b"STCN".contains(c)) {
        return Err(src.line(number, format!("unknown OFF header {}", show(keyword))));
    }
    Ok(prefix.contains(&b'N'))
}

type Vertices = (Vec<DVec3>, Option<Vec<DVec3>>);

fn read_vertices(lines: &mut DataLines, counts: &Counts, src: &Src) -> Result<Vertices, GeomError> {
    let mut positions = Vec::with_capacity(counts.vertices);
    let mut normals = Vec::with_capacity(if counts.has_normals {
        counts.vertices
    } else {
        0
    });
    let needed = if counts.has_normals { 6 } else { 3 };
    let mut values = [0.0; 6];
    for i in 0..counts.vertices {
        let (number, line) = lines.next().ok_or_else(|| {
            src.file(format!(
                "file ends after {i} of {} vertices",
                counts.vertices
            ))
        })?;
        let mut words = tokens(line);
        for v in &mut values[..needed] {
            let token = words
                .next()
                .ok_or_else(|| src.line(number, format!("vertex line needs {needed} numbers")))?;
            *v = parse_f64(token)
                .ok_or_else(|| src.line(number, format!("{} is not a number", show(token))))?;
            if !v.is_finite() {
                return Err(src.line(number, format!("non-finite value {}", show(token))));
            }
        }
        positions.push(DVec3::new(values[0], values[1], values[2]));
        if counts.has_normals {
            normals.push(DVec3::new(values[3], values[4], values[5]));
        }
    }
    Ok((positions, counts.has_normals.then_some(normals)))
}

fn read_faces(
    lines: &mut DataLines,
    counts: &Counts,
    src: &Src,
) -> Result<Vec<[u32; 3]>, GeomError> {
    let nverts = counts.vertices;
    if nverts > u32::MAX as usize {
        return Err(src.file("more vertices than 32-bit indices can address"));
    }
    let mut triangles = Vec::with_capacity(counts.faces);
    let mut corners = Vec::new();
    for f in 0..counts.faces {
        let (number, line) = lines
            .next()
            .ok_or_else(|| src.file(format!("file ends after {f} of {} faces", counts.faces)))?;
        let mut words = tokens(line);
        let bad =
            |token: &[u8], what: &str| src.line(number, format!("bad {what} {}", show(token)));
        let k = words.next().unwrap_or_default();
        let k = parse_i64(k)
            .and_then(|c| usize::try_from(c).ok())
            .ok_or_else(|| bad(k, "face size"))?;
        corners.clear();
        for _ in 0..k {
            let token = words.next().ok_or_else(|| {
                src.line(number, format!("face of {k} corners lists fewer indices"))
            })?;
            let i = parse_i64(token).ok_or_else(|| bad(token, "vertex index"))?;
            if i < 0 || i as u64 >= nverts as u64 {
                return Err(src.line(
                    number,
                    format!("vertex index {i} out of range (file has {nverts} vertices)"),
                ));
            }
            corners.push(i as u32);
        }
        fan_triangulate(&corners, &mut triangles);
    }
    Ok(triangles)
}

pub(crate) fn write(w: &mut dyn Write, geom: &Geometry) -> std::io::Result<()> {
    let pts = &geom.points;
    let keyword = if pts.normals.is_some() { "NOFF" } else { "OFF" };
    writeln!(
        w,
        "{keyword}\n{} {} 0",
        pts.positions.len(),
        geom.triangles.len()
    )?;
    for (i, p) in pts.positions.iter().enumerate() {
        write_f64s(w, &p.to_array())?;
        if let Some(n) = &pts.normals {
            w.write_all(b" ")?;
            write_f64s(w, &n[i].to_array())?;
        }
        w.write_all(b"\n")?;
    }
    for [a, b, c] in &geom.triangles {
        writeln!(w, "3 {a} {b} {c}")?;
    }
    Ok(())
}
