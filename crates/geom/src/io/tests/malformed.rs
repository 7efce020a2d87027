//! Malformed input: a parse error naming the position and the problem.

use super::*;
use Location::{Byte, File, Line};

#[track_caller]
fn expect(bytes: &[u8], format: Format, location: Location, needle: &str) {
    let (at, message) = parse_error(bytes, format);
    assert_eq!(at, location, "{message}");
    assert!(message.contains(needle), "{message:?} lacks {needle:?}");
}

#[test]
fn empty_files_are_errors_in_every_format() {
    for format in Format::ALL {
        expect(b"", format, File, "empty");
        expect(b" \n\n ", format, File, "empty");
    }
}

const PLY_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                        property float y\nproperty float z\nelement face 1\n\
                        property list uchar int vertex_indices\nend_header\n";

fn ply(body: &str) -> Vec<u8> {
    format!("{PLY_HEAD}{body}").into_bytes()
}

#[test]
fn ply_ascii_errors() {
    let ok = parse_ok(&ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"), Format::Ply);
    assert_eq!(ok.triangles, vec![[0, 1, 2]]);
    expect(
        &ply("0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"),
        Format::Ply,
        Line(11),
        "not a number",
    );
    expect(
        &ply("0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n"),
        Format::Ply,
        Line(11),
        "non-finite",
    );
    expect(
        &ply("0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n"),
        Format::Ply,
        Line(11),
        "non-finite",
    );
    expect(
        &ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
        Format::Ply,
        Line(13),
        "out of range",
    );
    expect(
        &ply("0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n"),
        Format::Ply,
        Line(13),
        "out of range",
    );
    expect(
        &ply("0 0 0\n1 0 0\n"),
        Format::Ply,
        File,
        "after 2 of 3 'vertex' rows",
    );
    expect(
        &ply("0 0 0\n1 0\n0 1 0\n3 0 1 2\n"),
        Format::Ply,
        Line(11),
        "too few values",
    );
    expect(
        &ply("0 0 0\n1 0 0 7\n0 1 0\n3 0 1 2\n"),
        Format::Ply,
        Line(11),
        "more than",
    );
    expect(
        &ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n"),
        Format::Ply,
        Line(14),
        "extra data",
    );
    expect(
        &ply("0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n"),
        Format::Ply,
        Line(13),
        "too few values",
    );
}

#[test]
fn ply_header_errors() {
    expect(
        b"plx\nformat ascii 1.0\n",
        Format::Ply,
        Line(1),
        "not a PLY file",
    );
    expect(
        b"ply\nformat ascii 1.0\nelement vertex 1\n",
        Format::Ply,
        File,
        "end_header",
    );
    expect(
        b"ply\nformat zip 1.0\nend_header\n",
        Format::Ply,
        Line(2),
        "unknown PLY format",
    );
    expect(
        b"ply\nelement vertex 1\nproperty float x\nend_header\n",
        Format::Ply,
        File,
        "format",
    );
    expect(
        b"ply\nformat ascii 1.0\nproperty float x\n",
        Format::Ply,
        Line(3),
        "before any element",
    );
    let bad_count = b"ply\nformat ascii 1.0\nelement vertex many\nend_header\n";
    expect(bad_count, Format::Ply, Line(3), "bad element count");
    let bad_type = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n";
    expect(bad_type, Format::Ply, Line(4), "unknown property type");
    let no_y = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n";
    expect(no_y, Format::Ply, Line(3), "'x' and 'y'");
    let no_vertex = b"ply\nformat ascii 1.0\nelement face 0\nend_header\n";
    expect(no_vertex, Format::Ply, File, "no 'vertex' element");
}

#[test]
fn ply_absurd_counts_are_refused_without_allocating() {
    for format in ["ascii", "binary_little_endian"] {
        let text = format!(
            "ply\nformat {format} 1.0\nelement vertex 4000000000\n\
             property double x\nproperty double y\nend_header\n0 0\n"
        );
        let (_, message) = parse_error(text.as_bytes(), Format::Ply);
        assert!(message.contains("more than the remaining"), "{message}");
    }
}

/// A binary PLY of `n` float vertices and one face, little-endian.
fn binary_ply(n: usize, face: [i32; 3]) -> (Vec<u8>, usize) {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
         property float y\nproperty float z\nelement face 1\n\
         property list uchar int vertex_indices\nend_header\n"
    )
    .into_bytes();
    let body = bytes.len();
    for i in 0..n * 3 {
        bytes.extend_from_slice(&(i as f32).to_le_bytes());
    }
    bytes.push(3);
    for i in face {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    (bytes, body)
}

#[test]
fn ply_binary_errors_name_byte_offsets() {
    let (ok, body) = binary_ply(3, [0, 1, 2]);
    let g = parse_ok(&ok, Format::Ply);
    assert_eq!(g.points.positions[2], DVec3::new(6.0, 7.0, 8.0));
    // Truncated inside the face list: the missing index is at body + 36 + 1 + 8.
    expect(
        &ok[..ok.len() - 2],
        Format::Ply,
        Byte((body + 45) as u64),
        "truncated",
    );
    // Too short for the declared vertices.
    expect(
        &ok[..body + 20],
        Format::Ply,
        Byte(body as u64),
        "more than the remaining",
    );
    let (bad, _) = binary_ply(3, [0, 3, 2]);
    expect(&bad, Format::Ply, Byte((body + 36) as u64), "out of range");
    let mut nan = ok.clone();
    nan[body + 16..body + 20].copy_from_slice(&f32::NAN.to_le_bytes());
    expect(
        &nan,
        Format::Ply,
        Byte((body + 12) as u64),
        "vertex 1 has a non-finite",
    );
    let mut extra = ok.clone();
    extra.extend_from_slice(&[0, 0, 0]);
    expect(
        &extra,
        Format::Ply,
        Byte(ok.len() as u64),
        "3 bytes of extra data",
    );
}

#[test]
fn ply_reads_any_scalar_types_and_skips_other_elements() {
    let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty short x\n\
        property uchar red\nproperty int y\nproperty double z\nproperty float intensity\n\
        element range_grid 3\nproperty list uchar int vertex_indices\n\
        element face 1\nproperty uint flags\nproperty list ushort uint vertex_index\nend_header\n"
        .to_vec();
    for (x, y) in [(-3i16, 70000i32), (5, -2)] {
        bytes.extend_from_slice(&x.to_be_bytes());
        bytes.push(255);
        bytes.extend_from_slice(&y.to_be_bytes());
        bytes.extend_from_slice(&0.5f64.to_be_bytes());
        bytes.extend_from_slice(&2.25f32.to_be_bytes());
    }
    // range_grid rows: one empty list, one with one index, one empty.
    bytes.extend_from_slice(&[0, 1, 0, 0, 0, 1, 0]);
    bytes.extend_from_slice(&7u32.to_be_bytes());
    bytes.extend_from_slice(&4u16.to_be_bytes());
    for i in [0u32, 1, 0, 1] {
        bytes.extend_from_slice(&i.to_be_bytes());
    }
    let g = parse_ok(&bytes, Format::Ply);
    assert_eq!(
        g.points.positions,
        vec![DVec3::new(-3.0, 70000.0, 0.5), DVec3::new(5.0, -2.0, 0.5)]
    );
    assert_eq!(g.points.scalars, Some(vec![2.25, 2.25]));
    assert_eq!(
        g.triangles,
        vec![[0, 1, 0], [0, 0, 1]],
        "quad fan-triangulated"
    );
}

#[test]
fn obj_errors() {
    let ok = parse_ok(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", Format::Obj);
    assert_eq!(ok.triangles.len(), 1);
    expect(b"v 0 0 0\nv 1 x 0\n", Format::Obj, Line(2), "not a number");
    expect(b"v 0 0 0\nv 1 NaN 0\n", Format::Obj, Line(2), "non-finite");
    expect(b"v 0 0\n", Format::Obj, Line(1), "needs 3 numbers");
    expect(b"v 0 0 0\nf 1 1 0\n", Format::Obj, Line(2), "out of range");
    expect(
        b"v 0 0 0\nf -1 -2 -1\n",
        Format::Obj,
        Line(2),
        "out of range",
    );
    expect(
        b"v 0 0 0\nf 1 2 1\nv 1 1 1\nf 1 2 3\n",
        Format::Obj,
        Line(4),
        "index 3 out of range",
    );
    expect(
        b"v 0 0 0\nf 1 a 1\n",
        Format::Obj,
        Line(2),
        "not a vertex index",
    );
    expect(
        b"v 0 0 0\nvn 0 0 1\nf 1//2 1//1 1//1\n",
        Format::Obj,
        Line(3),
        "normal index 2",
    );
    expect(b"# nothing\ng group\n", Format::Obj, File, "no vertices");
}

#[test]
fn obj_reads_every_face_form_and_relative_indices() {
    let text = b"# comment\no thing\nmtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
        vt 0 0\nvn 0 0 1\nusemtl m\ns off\ng side\nf 1/1 2/1 3/1\nf -4//1 -2//1 -1//1\n\
        f 1/1/1 2/1/1 3/1/1 4/1/1\nl 1 2 3 4 1\nl 4/1 2/1\n";
    let g = parse_ok(text, Format::Obj);
    assert_eq!(
        g.triangles,
        vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3]]
    );
    assert_eq!(g.lines, vec![vec![0, 1, 2, 3, 0], vec![3, 1]]);
    assert_eq!(
        g.points.normals,
        Some(vec![DVec3::Z; 4]),
        "all vertices share vn 1"
    );
    // Two normals for one vertex: normals dropped, geometry kept.
    let text =
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 -1\nf 1//1 2//1 3//1\nf 1//2 3//2 2//2\n";
    let g = parse_ok(text, Format::Obj);
    assert_eq!(g.points.normals, None);
    assert_eq!(g.triangles.len(), 2);
}

#[test]
fn off_errors() {
    let cube =
        b"OFF\n# comment\n4 1 0\n0 0 0\n1 0 0\n1 1 0 # corner\n0 1 0\n\n4 0 1 2 3 0.5 0.5 0.5\n";
    let g = parse_ok(cube, Format::Off);
    assert_eq!(g.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    let first_line = parse_ok(b"OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", Format::Off);
    assert_eq!(first_line.triangles.len(), 1);
    let noff = parse_ok(b"NOFF\n1 0 0\n0 0 0 0 0 1\n", Format::Off);
    assert_eq!(noff.points.normals, Some(vec![DVec3::Z]));
    expect(
        b"OFF\n3 1 0\n0 0 0\n1 0 0\n",
        Format::Off,
        File,
        "after 2 of 3 vertices",
    );
    expect(
        b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n",
        Format::Off,
        File,
        "after 0 of 1 faces",
    );
    expect(
        b"OFF\n3 1 0\n0 0 0\n1 q 0\n0 1 0\n3 0 1 2\n",
        Format::Off,
        Line(4),
        "not a number",
    );
    expect(
        b"OFF\n3 1 0\n0 0 0\n1 -inf 0\n0 1 0\n3 0 1 2\n",
        Format::Off,
        Line(4),
        "non-finite",
    );
    expect(
        b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
        Format::Off,
        Line(6),
        "out of range",
    );
    expect(
        b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n",
        Format::Off,
        Line(6),
        "fewer indices",
    );
    expect(
        b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n",
        Format::Off,
        Line(7),
        "extra data",
    );
    expect(b"OFF\n3\n", Format::Off, Line(2), "missing face count");
    expect(
        b"4OFF\n1 0 0\n0 0 0 0\n",
        Format::Off,
        Line(1),
        "not supported",
    );
    expect(b"OFF BINARY\n", Format::Off, Line(1), "binary OFF");
    expect(
        b"OFF\n999999999999 1 0\n0 0 0\n",
        Format::Off,
        File,
        "more than the file",
    );
}

#[test]
fn stl_errors() {
    expect(b"hello", Format::Stl, File, "too short for binary STL");
    let mut binary = vec![b' '; 80];
    binary.extend_from_slice(&2u32.to_le_bytes());
    binary.extend_from_slice(&[0u8; 50]);
    expect(&binary, Format::Stl, Byte(80), "declares 2 triangles");
    let mut nan = binary.clone();
    nan[80..84].copy_from_slice(&1u32.to_le_bytes());
    nan[84 + 28..84 + 32].copy_from_slice(&f32::INFINITY.to_le_bytes());
    expect(&nan, Format::Stl, Byte(84 + 24), "non-finite");
    let facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
    let ok = format!("solid a b\n{facet}{facet}endsolid a b\n");
    let g = parse_ok(ok.as_bytes(), Format::Stl);
    assert_eq!(
        (g.points.len(), g.triangles.len()),
        (3, 2),
        "corners merged"
    );
    let truncated = format!("solid a\n{facet}");
    expect(
        truncated.as_bytes(),
        Format::Stl,
        File,
        "without 'endsolid'",
    );
    let bad = ok.replace("vertex 1 0 0", "vertex 1 O 0");
    expect(bad.as_bytes(), Format::Stl, Line(5), "not a number");
    let bad = ok.replace("outer loop", "outer lop");
    expect(bad.as_bytes(), Format::Stl, Line(3), "expected 'loop'");
    let two = ok.replace("vertex 0 1 0\n", "");
    expect(
        two.as_bytes(),
        Format::Stl,
        Line(6),
        "facet with 2 vertices",
    );
}

#[test]
fn stl_binary_with_solid_header_is_binary() {
    let mut bytes = b"solid but binary".to_vec();
    bytes.resize(80, 0);
    bytes.extend_from_slice(&1u32.to_le_bytes());
    for v in [
        0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0,
    ] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes.extend_from_slice(&[0, 0]);
    let g = parse_ok(&bytes, Format::Stl);
    assert_eq!(g.triangles, vec![[0, 1, 2]]);
    assert_eq!(g.points.positions[2], DVec3::Y);
}

#[test]
fn xyz_errors() {
    let g = parse_ok(b"# header\n1 2\n\n3,4\n5;6 # comment\n", Format::Xyz);
    assert_eq!(g.points.positions[2], DVec3::new(5.0, 6.0, 0.0));
    expect(b"1 2 3\n4 five 6\n", Format::Xyz, Line(2), "not a number");
    expect(b"1 2 3\n4 nan 6\n", Format::Xyz, Line(2), "non-finite");
    expect(
        b"1 2 3\n4 5 6 7 8 9\n",
        Format::Xyz,
        Line(2),
        "line 1 has 3",
    );
    expect(
        b"\n1 2 3 4 5\n",
        Format::Xyz,
        Line(2),
        "expected 2, 3, 4, 6 or 7",
    );
    expect(b"# only a comment\n", Format::Xyz, File, "no points");
}

#[test]
fn obj_forward_references_resolve_at_the_end() {
    let g = parse_ok(
        b"vn 0 0 1\nf 1//1 2//1 3//1\nv 0 0 0\nv 1 0 0\nv 0 1 0\n",
        Format::Obj,
    );
    assert_eq!(g.triangles, vec![[0, 1, 2]]);
    assert_eq!(g.points.normals, Some(vec![DVec3::Z; 3]));
    // A huge forward index is an error, not a huge allocation.
    let (_, message) = parse_error(
        b"v 0 0 0\nvn 0 0 1\nf 1//1 4000000000//1 1//1\n",
        Format::Obj,
    );
    assert!(message.contains("out of range"), "{message}");
}

#[test]
fn line_chunks_cover_the_file_with_correct_line_numbers() {
    let text = b"a\nbb\n\nccc\nd\neeee\nf";
    for target in 1..text.len() + 2 {
        let chunks = crate::io::text::line_chunks(text, 1, target);
        let joined: Vec<u8> = chunks.iter().flat_map(|(_, c)| c.iter().copied()).collect();
        assert_eq!(joined, text.to_vec(), "target {target}");
        for (number, chunk) in &chunks {
            let offset = chunk.as_ptr() as usize - text.as_ptr() as usize;
            let expected = 1 + text[..offset].iter().filter(|&&b| b == b'\n').count();
            assert_eq!(*number, expected, "target {target}");
        }
    }
}

#[test]
fn xyz_errors_far_into_a_big_file_name_the_right_line() {
    let mut text = String::from("# big file\n");
    for i in 0..200_000 {
        text.push_str(&format!("{i}.5 {} -{i}.25 0 0 1\n", i * 2));
    }
    let g = parse_ok(text.as_bytes(), Format::Xyz);
    assert_eq!(g.points.len(), 200_000);
    assert_eq!(
        g.points.positions[199_999],
        DVec3::new(199_999.5, 399_998.0, -199_999.25)
    );
    // Line 150,002 holds point 150,000.
    let bad = text.replace("150000.5 300000", "150000.5 3OOOOO");
    expect(bad.as_bytes(), Format::Xyz, Line(150_002), "not a number");
    let short = text.replace(
        "180000.5 360000 -180000.25 0 0 1",
        "180000.5 360000 -180000.25",
    );
    expect(short.as_bytes(), Format::Xyz, Line(180_002), "line 2 has 6");
}

#[test]
fn ply_vertex_rows_with_lists_take_the_general_path() {
    let head = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex 2\nproperty double x\n\
             property list uchar float tags\nproperty double y\nproperty double z\n\
             property double nx\nproperty double ny\nproperty double nz\nend_header\n"
        )
    };
    let ascii = format!("{}1 2 0.5 0.25 2 3 0 0 1\n4 0 5 6 0 1 0\n", head("ascii"));
    let mut binary = head("binary_little_endian").into_bytes();
    for (x, tags, y, z, n) in [
        (1.0, &[0.5f32, 0.25][..], 2.0, 3.0, [0.0, 0.0, 1.0]),
        (4.0, &[], 5.0, 6.0, [0.0, 1.0, 0.0]),
    ] {
        binary.extend_from_slice(&f64::to_le_bytes(x));
        binary.push(tags.len() as u8);
        tags.iter()
            .for_each(|t| binary.extend_from_slice(&t.to_le_bytes()));
        for v in [y, z].into_iter().chain(n) {
            let v: f64 = v;
            binary.extend_from_slice(&v.to_le_bytes());
        }
    }
    for bytes in [ascii.into_bytes(), binary] {
        let g = parse_ok(&bytes, Format::Ply);
        assert_eq!(
            g.points.positions,
            vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(4.0, 5.0, 6.0)]
        );
        assert_eq!(g.points.normals, Some(vec![DVec3::Z, DVec3::Y]));
    }
}

/// A NaN or infinite scalar (a scanner's quality) is refused when read,
/// in binary as in ascii: the writer refuses it, so every file the reader
/// accepts can be written back.
#[test]
fn ply_non_finite_scalars_are_refused_in_every_encoding() {
    let head = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
             property float z\nproperty float quality\nend_header\n"
        )
    };
    let mut binary = head("binary_little_endian").into_bytes();
    let body = binary.len();
    for v in [[0.0f32, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, f32::NAN]] {
        v.iter().for_each(|x| binary.extend(x.to_le_bytes()));
    }
    expect(
        &binary,
        Format::Ply,
        Byte((body + 16) as u64),
        "vertex 1 has a non-finite",
    );
    let ascii = format!("{}0 0 0 1\n1 0 0 inf\n", head("ascii"));
    let (_, message) = parse_error(ascii.as_bytes(), Format::Ply);
    assert!(message.contains("non-finite"), "{message}");
}
