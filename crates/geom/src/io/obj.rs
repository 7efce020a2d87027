//! Wavefront OBJ: `v`, `vn`, `f` (every `v`, `v/vt`, `v//vn`, `v/vt/vn`
//! form, negative indices relative to the current end), `l` polylines.
//! Polygons are fan-triangulated. Comments, `vt`, `o`, `g`, `s`, `usemtl`,
//! `mtllib` and other statements are ignored.
//!
//! Own reader rather than tobj: we need `l` lines, per-line error positions
//! and the vertex-normal mapping below, and the format is small.
//!
//! Normals: OBJ indexes normals separately from positions; they become
//! per-vertex normals only when every vertex is always used with the same
//! normal (or, without faces naming normals, when there is one `vn` per `v`).
//! Otherwise they are dropped.

use super::text::{parse_f64, parse_i64, show, strip_comment, tokens, write_f64s, Lines};
use super::{fan_triangulate, Src};
use crate::{GeomError, Geometry, PointCloud};
use glam::DVec3;
use std::io::Write;

const NO_NORMAL: u32 = u32::MAX;

/// What has been read so far.
#[derive(Default)]
struct ObjData {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    lines: Vec<Vec<u32>>,
    /// Normal index used with each vertex so far (`NO_NORMAL` if none).
    normal_of: Vec<u32>,
    /// (vertex, normal) pairs of corners naming a vertex not yet read.
    deferred_normals: Vec<(usize, usize)>,
    /// Some vertex was used with two different normals.
    normals_conflict: bool,
    /// Largest positive index that pointed past the vertices read so far,
    /// with its line: legal if the vertex comes later (checked at the end).
    forward_vertex: Option<(usize, usize)>,
    forward_normal: Option<(usize, usize)>,
}

pub(crate) fn read(bytes: &[u8], src: &Src) -> Result<Geometry, GeomError> {
    let mut data = ObjData::default();
    let mut corners = Vec::new();
    for (number, line) in Lines::new(bytes, 1) {
        let mut words = tokens(strip_comment(line));
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            b"v" => data.positions.push(read_vec3(words, src, number, "v")?),
            b"vn" => data.normals.push(read_vec3(words, src, number, "vn")?),
            b"f" => {
                read_corners(words, &mut data, &mut corners, src, number)?;
                fan_triangulate(&corners, &mut data.triangles);
            }
            b"l" => {
                read_corners(words, &mut data, &mut corners, src, number)?;
                if corners.len() >= 2 {
                    data.lines.push(corners.clone());
                }
            }
            _ => {} // vt, o, g, s, usemtl, mtllib, p, ...
        }
    }
    finish(data, src)
}

/// Three finite numbers (extra values such as `w` or colours are ignored).
fn read_vec3<'a>(
    mut words: impl Iterator<Item = &'a [u8]>,
    src: &Src,
    number: usize,
    what: &str,
) -> Result<DVec3, GeomError> {
    let mut xyz = [0.0; 3];
    for c in &mut xyz {
        let token = words
            .next()
            .ok_or_else(|| src.line(number, format!("'{what}' needs 3 numbers")))?;
        *c = parse_f64(token)
            .ok_or_else(|| src.line(number, format!("{} is not a number", show(token))))?;
        if !c.is_finite() {
            return Err(src.line(number, format!("non-finite value {}", show(token))));
        }
    }
    Ok(DVec3::from_array(xyz))
}

/// The vertex indices (0-based) of an `f` or `l` statement.
fn read_corners<'a>(
    words: impl Iterator<Item = &'a [u8]>,
    data: &mut ObjData,
    corners: &mut Vec<u32>,
    src: &Src,
    number: usize,
) -> Result<(), GeomError> {
    corners.clear();
    for word in words {
        let mut parts = word.split(|&b| b == b'/');
        let v = parts.next().unwrap_or_default();
        let _texture = parts.next();
        let vn = parts.next().filter(|p| !p.is_empty());
        let vi = resolve(v, data.positions.len(), src, number, "vertex")?;
        note_forward(&mut data.forward_vertex, vi, data.positions.len(), number);
        if let Some(vn) = vn {
            let ni = resolve(vn, data.normals.len(), src, number, "normal")?;
            note_forward(&mut data.forward_normal, ni, data.normals.len(), number);
            data.note_normal(vi, ni);
        }
        corners.push(vi as u32);
    }
    Ok(())
}

/// A 1-based (or negative, relative) OBJ index as 0-based.
fn resolve(
    token: &[u8],
    len: usize,
    src: &Src,
    number: usize,
    what: &str,
) -> Result<usize, GeomError> {
    let i = parse_i64(token)
        .ok_or_else(|| src.line(number, format!("{} is not a {what} index", show(token))))?;
    let resolved = match i {
        1.. => Some(i as u64 - 1),
        0 => None,
        _ => (len as u64).checked_sub(i.unsigned_abs()),
    };
    match resolved {
        Some(r) if r < u32::MAX as u64 => Ok(r as usize),
        _ => Err(src.line(
            number,
            format!(
                "{what} index {i} out of range ({len} {} so far)",
                plural(what)
            ),
        )),
    }
}

fn plural(what: &str) -> &str {
    match what {
        "vertex" => "vertices",
        _ => "normals",
    }
}

fn note_forward(slot: &mut Option<(usize, usize)>, index: usize, len: usize, number: usize) {
    if index >= len && slot.is_none_or(|(i, _)| index > i) {
        *slot = Some((index, number));
    }
}

impl ObjData {
    fn note_normal(&mut self, vertex: usize, normal: usize) {
        if vertex >= self.positions.len() {
            // Forward reference: grow the table only once the vertex exists
            // (a bogus huge index must not allocate).
            self.deferred_normals.push((vertex, normal));
            return;
        }
        if self.normal_of.len() <= vertex {
            self.normal_of.resize(self.positions.len(), NO_NORMAL);
        }
        let slot = &mut self.normal_of[vertex];
        if *slot == NO_NORMAL {
            *slot = normal as u32;
        } else if *slot != normal as u32 {
            self.normals_conflict = true;
        }
    }

    /// Per-vertex normals, if the file's normals map onto vertices.
    fn vertex_normals(&self) -> Option<Vec<DVec3>> {
        let n = self.positions.len();
        if self.normals.is_empty() || self.normals_conflict {
            return None;
        }
        // `vn` k belongs to `v` k (as we write them, and as point clouds do).
        let aligned = self.normals.len() == n
            && (self.normal_of.iter().enumerate()).all(|(v, &i)| i == NO_NORMAL || i as usize == v);
        if aligned {
            return Some(self.normals.clone());
        }
        if self.normal_of.len() < n {
            return None;
        }
        self.normal_of[..n]
            .iter()
            .map(|&i| self.normals.get(i as usize).copied())
            .collect()
    }
}

fn finish(mut data: ObjData, src: &Src) -> Result<Geometry, GeomError> {
    let forward = [
        (data.forward_vertex, data.positions.len(), "vertex"),
        (data.forward_normal, data.normals.len(), "normal"),
    ];
    for (worst, len, what) in forward {
        if let Some((index, number)) = worst.filter(|&(i, _)| i >= len) {
            return Err(src.line(
                number,
                format!(
                    "{what} index {} out of range (file has {len} {})",
                    index + 1,
                    plural(what)
                ),
            ));
        }
    }
    if data.positions.is_empty() {
        return Err(src.file("no vertices ('v' lines)"));
    }
    for (vertex, normal) in std::mem::take(&mut data.deferred_normals) {
        data.note_normal(vertex, normal); // every vertex exists by now
    }
    let normals = data.vertex_normals();
    Ok(Geometry {
        points: PointCloud {
            positions: data.positions,
            normals,
            scalars: None,
        },
        triangles: data.triangles,
        lines: data.lines,
    })
}

pub(crate) fn write(w: &mut dyn Write, geom: &Geometry) -> std::io::Result<()> {
    writeln!(w, "# written by surfrecon")?;
    let pts = &geom.points;
    for p in &pts.positions {
        w.write_all(b"v ")?;
        write_f64s(w, &p.to_array())?;
        w.write_all(b"\n")?;
    }
    if let Some(normals) = &pts.normals {
        for n in normals {
            w.write_all(b"vn ")?;
            write_f64s(w, &n.to_array())?;
            w.write_all(b"\n")?;
        }
    }
    let with_normals = pts.normals.is_some();
    for t in &geom.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        if with_normals {
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
        } else {
            writeln!(w, "f {a} {b} {c}")?;
        }
    }
    for line in &geom.lines {
        w.write_all(b"l")?;
        for i in line {
            write!(w, " {}", i + 1)?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}
