//! Thin-shell storage of a signed distance field: keep only the nodes with
//! a sign change to an axis neighbour (the two node layers that enclose the
//! zero level set), rebuild the full field from them.
//!
//! File format (`.shell`, all numbers little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `SRSHELL\0` |
//! | 4 | format version, `u32` = 1 |
//! | 4 | dimension D, `u32` (2 or 3) |
//! | 8·D | node counts per axis, `u64` |
//! | 8·D | origin, `f64` |
//! | 8 | spacing, `f64` |
//! | 8 | shell node count n, `u64` |
//! | varies | n linear node indices (axis 0 fastest), ascending, each stored as the difference to the previous one (the first as itself) in unsigned LEB128 (7 bits per byte, high bit = more bytes follow) |
//! | 8·n | the n node values, `f64` |
//!
//! Values stay `f64`: the shell nodes then come back bit-exact (well inside
//! the 1e-6 h the format promises, for any field scale), and the values
//! still dominate the size only modestly, as neighbouring shell nodes have
//! index gaps of one or two bytes.
//!
//! Rebuild ([`Shell::rebuild`]): |φ| by fast sweeping from the shell values
//! (frozen), then the signs by tagging: a node with no sign change to any
//! neighbour has the sign of all its neighbours, so signs spread from the
//! shell nodes along each row, then breadth first over the rows without
//! a shell node. This marks the region outside the shell exterior
//! (positive) as a flood fill from the grid boundary would, and is also
//! right when the surface touches the grid boundary or encloses several
//! separate regions. A grid without any shell node comes back positive.

use crate::sweep::fast_sweep;
use crate::{Field, GridError, GridSpec};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::io::Write;
use std::path::Path;

const MAGIC: &[u8; 8] = b"SRSHELL\0";
const VERSION: u32 = 1;

/// The shell nodes of a field: ascending linear indices and their values.
#[derive(Clone, Debug, PartialEq)]
pub struct Shell<const D: usize> {
    pub spec: GridSpec<D>,
    pub indices: Vec<u64>,
    pub values: Vec<f64>,
}

/// A shell of either dimension, as read from a file.
#[derive(Clone, Debug, PartialEq)]
pub enum AnyShell {
    D2(Shell<2>),
    D3(Shell<3>),
}

/// Whether `v` is on the negative (inside) side. Zero counts as outside.
#[inline]
fn negative(v: f64) -> bool {
    v < 0.0
}

/// Signs of one row: each run of nodes off the shell takes the sign of
/// the shell node before it, or else after it. Returns whether the row
/// has a shell node (else it is left as it was).
fn fill_row(inside: &mut [bool], is_shell: &[bool]) -> bool {
    let Some(first) = is_shell.iter().position(|&s| s) else {
        return false;
    };
    let mut sign = inside[first];
    inside[..first].fill(sign);
    for (inside, &shell) in inside[first..].iter_mut().zip(&is_shell[first..]) {
        if shell {
            sign = *inside;
        } else {
            *inside = sign;
        }
    }
    true
}

/// Whether node `l` has a sign change to an axis neighbour.
fn on_shell<const D: usize>(field: &Field<D>, l: usize, strides: &[usize; D]) -> bool {
    let idx = field.spec.unlinear(l);
    let s = negative(field.values[l]);
    let changes = field
        .spec
        .axis_neighbours(l, &idx, strides)
        .any(|m| negative(field.values[m]) != s);
    changes
}

impl<const D: usize> Shell<D> {
    /// The shell of a signed distance field (zero level set).
    pub fn from_field(field: &Field<D>) -> Self {
        use rayon::prelude::*;
        let strides = field.spec.strides();
        let indices: Vec<u64> = (0..field.values.len())
            .into_par_iter()
            .filter(|&l| on_shell(field, l, &strides))
            .map(|l| l as u64)
            .collect();
        let values = indices.iter().map(|&l| field.values[l as usize]).collect();
        Shell {
            spec: field.spec,
            indices,
            values,
        }
    }

    /// Rebuild the full signed distance field (see the module docs).
    pub fn rebuild(&self) -> Result<Field<D>, GridError> {
        self.check()?;
        let n = self.spec.node_count();
        let mut field = Field::filled(self.spec, f64::INFINITY);
        let mut frozen = vec![false; n];
        for (&l, &v) in self.indices.iter().zip(&self.values) {
            field.values[l as usize] = v.abs();
            frozen[l as usize] = true;
        }
        fast_sweep(&mut field, &frozen);
        let inside = self.tag_inside(&frozen);
        for ((v, &neg), &fixed) in field.values.iter_mut().zip(&inside).zip(&frozen) {
            if neg && !fixed {
                *v = -*v;
            }
        }
        for (&l, &v) in self.indices.iter().zip(&self.values) {
            field.values[l as usize] = v;
        }
        Ok(field)
    }

    /// Per node: whether it is inside. A node off the shell has the sign
    /// of all its neighbours, so along a row (axis 0) each run of such
    /// nodes takes the sign of a shell node at either end, in parallel
    /// over rows; rows without a shell node are uniform and take the
    /// sign of a neighbouring row, breadth first over rows.
    fn tag_inside(&self, is_shell: &[bool]) -> Vec<bool> {
        let row_len = self.spec.dims[0];
        let mut inside = vec![false; self.spec.node_count()];
        for (&l, &v) in self.indices.iter().zip(&self.values) {
            inside[l as usize] = negative(v);
        }
        let mut known: Vec<bool> = inside
            .par_chunks_mut(row_len)
            .zip(is_shell.par_chunks(row_len))
            .map(|(inside, is_shell)| fill_row(inside, is_shell))
            .collect();
        let mut queue: VecDeque<usize> = (0..known.len()).filter(|&r| known[r]).collect();
        let rows = GridSpec {
            dims: std::array::from_fn(|a| if a == 0 { 1 } else { self.spec.dims[a] }),
            ..self.spec
        };
        let row_strides = rows.strides();
        while let Some(r) = queue.pop_front() {
            let idx = rows.unlinear(r);
            for m in rows.axis_neighbours(r, &idx, &row_strides) {
                if !known[m] {
                    known[m] = true;
                    let sign = inside[r * row_len];
                    inside[m * row_len..][..row_len].fill(sign);
                    queue.push_back(m);
                }
            }
        }
        inside
    }

    /// Consistency of indices and values (files may be corrupt).
    fn check(&self) -> Result<(), GridError> {
        let n = self.spec.node_count() as u64;
        let invalid = |m: String| Err(GridError::Invalid(format!("shell: {m}")));
        if self.indices.len() != self.values.len() {
            return invalid(format!(
                "{} indices for {} values",
                self.indices.len(),
                self.values.len()
            ));
        }
        if let Some(w) = self.indices.windows(2).find(|w| w[1] <= w[0]) {
            return invalid(format!("indices not ascending ({} then {})", w[0], w[1]));
        }
        if let Some(&l) = self.indices.last().filter(|&&l| l >= n) {
            return invalid(format!("index {l} beyond the {n} grid nodes"));
        }
        if let Some(i) = self.values.iter().position(|v| !v.is_finite()) {
            return invalid(format!("value {i} is not finite"));
        }
        Ok(())
    }

    /// Size in bytes of the encoded shell.
    pub fn encoded_len(&self) -> usize {
        let mut prev = 0;
        let index_bytes: usize = self
            .indices
            .iter()
            .map(|&l| {
                let bits = 64 - (l - prev).leading_zeros() as usize;
                prev = l;
                bits.div_ceil(7).max(1)
            })
            .sum();
        8 + 4 + 4 + 16 * D + 8 + 8 + index_bytes + 8 * self.values.len()
    }

    /// The file bytes (see the module docs for the layout).
    pub fn encode(&self, w: &mut dyn Write) -> std::io::Result<()> {
        w.write_all(MAGIC)?;
        w.write_all(&VERSION.to_le_bytes())?;
        w.write_all(&(D as u32).to_le_bytes())?;
        for n in self.spec.dims {
            w.write_all(&(n as u64).to_le_bytes())?;
        }
        for o in self.spec.origin {
            w.write_all(&o.to_le_bytes())?;
        }
        w.write_all(&self.spec.spacing.to_le_bytes())?;
        w.write_all(&(self.indices.len() as u64).to_le_bytes())?;
        let mut buf = Vec::with_capacity(self.indices.len() * 2);
        let mut prev = 0;
        for &l in &self.indices {
            write_varint(&mut buf, l - prev);
            prev = l;
        }
        w.write_all(&buf)?;
        buf.clear();
        buf.extend(self.values.iter().flat_map(|v| v.to_le_bytes()));
        w.write_all(&buf)
    }
}

fn write_varint(out: &mut Vec<u8>, mut x: u64) {
    while x >= 0x80 {
        out.push((x as u8 & 0x7f) | 0x80);
        x >>= 7;
    }
    out.push(x as u8);
}

/// Write `shell` to `path` (atomically: a failed write leaves no file).
pub fn write_shell<const D: usize>(
    path: impl AsRef<Path>,
    shell: &Shell<D>,
) -> Result<(), GridError> {
    if D != 2 && D != 3 {
        return Err(GridError::Invalid(format!("shells are 2D or 3D, not {D}D")));
    }
    shell.check()?;
    surfrecon_geom::io::write_atomic(path, |w| shell.encode(w))?;
    Ok(())
}

/// Read a shell file.
pub fn read_shell(path: impl AsRef<Path>) -> Result<AnyShell, GridError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| GridError::FieldIo {
        path: path.to_path_buf(),
        error: source,
    })?;
    let fail = |at: usize, message: String| GridError::FieldFile {
        path: path.to_path_buf(),
        message: format!("byte {at}: {message}"),
    };
    decode(&bytes).map_err(|(at, m)| fail(at, m))
}

/// A little-endian reader over the file bytes that reports positions.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

type DecodeResult<T> = Result<T, (usize, String)>;

impl Reader<'_> {
    fn take(&mut self, n: usize, what: &str) -> DecodeResult<&[u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| (self.pos, format!("file truncated in {what}")))?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> DecodeResult<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn u64(&mut self, what: &str) -> DecodeResult<u64> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn f64(&mut self, what: &str) -> DecodeResult<f64> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn varint(&mut self) -> DecodeResult<u64> {
        let start = self.pos;
        let mut x = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.take(1, "node indices")?[0];
            x |= ((b & 0x7f) as u64) << shift;
            if b & 0x80 == 0 {
                return Ok(x);
            }
        }
        Err((start, "node index varint longer than 10 bytes".into()))
    }
}

fn decode(bytes: &[u8]) -> DecodeResult<AnyShell> {
    let mut r = Reader { bytes, pos: 0 };
    if r.take(8, "magic")? != MAGIC {
        return Err((0, "not a surfrecon shell file (bad magic)".into()));
    }
    let version = r.u32("version")?;
    if version != VERSION {
        return Err((
            8,
            format!("shell format version {version} not supported (expected {VERSION})"),
        ));
    }
    match r.u32("dimension")? {
        2 => Ok(AnyShell::D2(decode_body::<2>(&mut r)?)),
        3 => Ok(AnyShell::D3(decode_body::<3>(&mut r)?)),
        d => Err((12, format!("dimension {d} not supported (2 or 3)"))),
    }
}

fn decode_body<const D: usize>(r: &mut Reader) -> DecodeResult<Shell<D>> {
    let spec = decode_spec::<D>(r)?;
    let nodes = spec
        .dims
        .iter()
        .try_fold(1u64, |c, &n| c.checked_mul(n as u64));
    let nodes = nodes.ok_or((r.pos, "grid size overflows".to_string()))?;
    let count_at = r.pos;
    let count = r.u64("node count")?;
    // Each node takes at least 9 bytes (index + value): a corrupt count
    // must not make us reserve absurd amounts of memory.
    if count > nodes || count > (r.bytes.len() - r.pos) as u64 / 9 {
        return Err((
            count_at,
            format!("{count} shell nodes cannot fit (grid has {nodes}, file is too short)"),
        ));
    }
    let indices = decode_indices(r, count as usize, nodes)?;
    let values = decode_values(r, count as usize)?;
    if r.pos != r.bytes.len() {
        return Err((
            r.pos,
            format!(
                "{} unexpected bytes after the values",
                r.bytes.len() - r.pos
            ),
        ));
    }
    Ok(Shell {
        spec,
        indices,
        values,
    })
}

fn decode_spec<const D: usize>(r: &mut Reader) -> DecodeResult<GridSpec<D>> {
    let mut dims = [0usize; D];
    for n in dims.iter_mut() {
        let at = r.pos;
        *n = r.u64("dims")? as usize;
        if *n < 2 {
            return Err((at, format!("axis with {n} nodes (need >= 2)")));
        }
    }
    let mut origin = [0.0; D];
    for o in origin.iter_mut() {
        *o = r.f64("origin")?;
    }
    let at = r.pos;
    let spacing = r.f64("spacing")?;
    if !(spacing > 0.0 && spacing.is_finite()) || origin.iter().any(|o| !o.is_finite()) {
        return Err((
            at,
            format!("unusable spacing {spacing} or origin {origin:?}"),
        ));
    }
    Ok(GridSpec {
        origin,
        spacing,
        dims,
    })
}

/// `count` ascending node indices below `nodes`, delta-encoded.
fn decode_indices(r: &mut Reader, count: usize, nodes: u64) -> DecodeResult<Vec<u64>> {
    let mut indices = Vec::with_capacity(count);
    let mut prev = 0u64;
    for i in 0..count {
        let at = r.pos;
        let delta = r.varint()?;
        let l = prev
            .checked_add(delta)
            .filter(|&l| l < nodes && (i == 0 || delta > 0));
        let l = l.ok_or((
            at,
            format!("node index {i} is out of order or beyond the grid"),
        ))?;
        indices.push(l);
        prev = l;
    }
    Ok(indices)
}

fn decode_values(r: &mut Reader, count: usize) -> DecodeResult<Vec<f64>> {
    let mut values = Vec::with_capacity(count);
    for i in 0..count {
        let at = r.pos;
        let v = r.f64("values")?;
        if !v.is_finite() {
            return Err((at, format!("value {i} is not finite")));
        }
        values.push(v);
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::marching::tests::{cube_spec, sample3};
    use surfrecon_geom::DVec3;

    fn torus(p: DVec3) -> f64 {
        let q = (p.x * p.x + p.y * p.y).sqrt() - 0.55;
        (q * q + p.z * p.z).sqrt() - 0.25
    }

    /// Rebuild through a file; shell nodes must come back exactly, every
    /// sign must match; returns the largest error within `near` of the
    /// surface, in units of h.
    fn check_rebuild<const D: usize>(field: &Field<D>, near: f64) -> f64 {
        let shell = Shell::from_field(field);
        assert!(!shell.indices.is_empty());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.shell");
        write_shell(&path, &shell).unwrap();
        assert_eq!(
            std::fs::metadata(&path).unwrap().len() as usize,
            shell.encoded_len()
        );
        let back = match (read_shell(&path).unwrap(), D) {
            (AnyShell::D3(s), 3) => s.rebuild().unwrap().values,
            (AnyShell::D2(s), 2) => s.rebuild().unwrap().values,
            _ => panic!("wrong dimension"),
        };
        let h = field.spec.spacing;
        for &l in &shell.indices {
            assert_eq!(
                back[l as usize].to_bits(),
                field.values[l as usize].to_bits()
            );
        }
        let mut worst = 0.0f64;
        for (a, b) in field.values.iter().zip(&back) {
            assert_eq!(negative(*a), negative(*b), "sign differs: {a} vs {b}");
            if a.abs() <= near * h {
                worst = worst.max((a - b).abs() / h);
            }
        }
        worst
    }

    #[test]
    fn sphere_and_torus_rebuild_with_exact_shell_and_signs() {
        let spec = cube_spec(40, -1.0, 1.0);
        let c = DVec3::new(0.02, -0.01, 0.03);
        let sphere = sample3(spec, |p| (p - c).length() - 0.6);
        let shell_err = check_rebuild(&sphere, 1.0);
        assert!(
            shell_err < 0.1,
            "sphere error within 1 h of the surface: {shell_err} h"
        );
        check_rebuild(&sample3(spec, torus), 1.0);
        // Shell much smaller than the field.
        let shell = Shell::from_field(&sphere);
        assert!(shell.encoded_len() * 10 < spec.node_count() * 8);
    }

    /// A field that is itself a fast-sweeping solution from its shell (as
    /// the level-set pipeline produces) comes back within 1e-6 h everywhere.
    #[test]
    fn swept_fields_round_trip_everywhere() {
        let spec = cube_spec(36, -1.0, 1.0);
        let analytic = sample3(spec, torus);
        let swept = Shell::from_field(&analytic).rebuild().unwrap();
        let worst = check_rebuild(&swept, f64::INFINITY);
        assert!(worst < 1e-6, "swept field rebuilt with error {worst} h");
    }

    #[test]
    fn shell_nodes_are_exactly_the_sign_change_nodes() {
        let spec = GridSpec::<2> {
            origin: [-1.0; 2],
            spacing: 0.1,
            dims: [21, 21],
        };
        let values = (0..spec.node_count())
            .map(|l| {
                let p = spec.position(spec.unlinear(l));
                p[0].hypot(p[1]) - 0.55
            })
            .collect();
        let field = Field { spec, values };
        let shell = Shell::from_field(&field);
        for l in 0..spec.node_count() {
            let idx = spec.unlinear(l);
            let s = negative(field.values[l]);
            let change = (0..2).any(|a| {
                [-1isize, 1].iter().any(|&d| {
                    let mut n = idx;
                    match idx[a].checked_add_signed(d) {
                        Some(x) if x < 21 => n[a] = x,
                        _ => return false,
                    }
                    negative(field.get(n)) != s
                })
            });
            assert_eq!(change, shell.indices.contains(&(l as u64)));
        }
        check_rebuild(&field, 1.0);
    }

    #[test]
    fn surface_touching_the_boundary_keeps_its_signs() {
        // A half space: the inside reaches the grid boundary, where a flood
        // fill from the boundary would wrongly call it outside.
        let spec = cube_spec(12, -1.0, 1.0);
        check_rebuild(&sample3(spec, |p| p.x - 0.13), 1.0);
    }

    #[test]
    fn rows_without_shell_nodes_take_their_neighbours_sign() {
        // Rows along x that never meet the surface: on both sides of a
        // plane across z, and inside and around a cylinder along x.
        let spec = cube_spec(12, -1.0, 1.0);
        check_rebuild(&sample3(spec, |p| p.z - 0.13), 1.0);
        check_rebuild(&sample3(spec, |p| p.y.hypot(p.z) - 0.55), 1.0);
    }

    #[test]
    fn corrupt_files_are_errors() {
        let spec = cube_spec(10, -1.0, 1.0);
        let shell = Shell::from_field(&sample3(spec, |p| p.length() - 0.5));
        let mut good = Vec::new();
        shell.encode(&mut good).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.shell");
        let msg = |bytes: &[u8]| {
            std::fs::write(&p, bytes).unwrap();
            read_shell(&p).unwrap_err().to_string()
        };
        assert!(msg(&good[..good.len() - 1]).contains("truncated"));
        assert!(msg(b"SRSHELX\0rest").contains("magic"));
        let mut v = good.clone();
        v[8] = 9;
        assert!(msg(&v).contains("version 9"));
        let mut extra = good.clone();
        extra.push(0);
        assert!(msg(&extra).contains("unexpected bytes"));
        // A first index beyond the grid (varint of 10^6 for a 1000-node grid).
        let header_len = 8 + 4 + 4 + 24 + 24 + 8 + 8;
        let mut big = good[..header_len].to_vec();
        big[header_len - 8..].copy_from_slice(&1u64.to_le_bytes());
        write_varint(&mut big, 1_000_000);
        big.extend(0.5f64.to_le_bytes());
        assert!(msg(&big).contains("beyond the grid"));
        assert!(msg(&big).contains("c.shell"));
    }
}
