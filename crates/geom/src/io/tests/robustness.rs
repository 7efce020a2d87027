//! No input makes a parser panic: every prefix and many single-byte changes
//! of valid files in every format and encoding parse to `Ok` or `Err`.

use super::*;
use crate::io::Encoding;

fn small_inputs() -> Vec<(Format, Vec<u8>)> {
    let mut g = Geometry::from_mesh(shapes::cuboid(DVec3::ZERO, DVec3::new(1.0, 2.0, 0.5)));
    g.points.normals = Some(
        g.points
            .positions
            .iter()
            .map(|p| p.normalize_or_zero())
            .collect(),
    );
    g.points.scalars = Some((0..g.points.len()).map(|i| i as f64).collect());
    let mut with_lines = g.clone();
    with_lines.lines = vec![vec![0, 1, 2], vec![3, 4]];
    let mut inputs = vec![(
        Format::Obj,
        encode(&with_lines, Format::Obj, WriteOptions::default()),
    )];
    for encoding in [
        Encoding::Ascii,
        Encoding::BinaryLittleEndian,
        Encoding::BinaryBigEndian,
    ] {
        inputs.push((
            Format::Ply,
            encode(&g, Format::Ply, WriteOptions { encoding }),
        ));
    }
    for encoding in [Encoding::Ascii, Encoding::BinaryLittleEndian] {
        inputs.push((
            Format::Stl,
            encode(&g, Format::Stl, WriteOptions { encoding }),
        ));
    }
    for format in [Format::Off, Format::Xyz] {
        inputs.push((format, encode(&g, format, WriteOptions::default())));
    }
    inputs
}

#[test]
fn every_prefix_parses_without_panic() {
    for (format, bytes) in small_inputs() {
        assert!(read_bytes(&bytes, format, "full").is_ok(), "{format}");
        for end in 0..bytes.len() {
            let _ = read_bytes(&bytes[..end], format, "prefix");
        }
    }
}

#[test]
fn single_byte_changes_parse_without_panic() {
    const REPLACEMENTS: [u8; 8] = [0, 0xff, b'9', b' ', b'\n', b'-', b'e', 0x80];
    for (format, bytes) in small_inputs() {
        let mut changed = bytes.clone();
        for i in 0..bytes.len() {
            for r in REPLACEMENTS {
                changed[i] = r;
                let _ = read_bytes(&changed, format, "changed");
            }
            changed[i] = bytes[i];
        }
    }
}

#[test]
fn truncated_binary_files_are_errors() {
    for (format, bytes) in small_inputs() {
        if format == Format::Ply && !bytes.starts_with(b"ply\nformat ascii") {
            for end in [bytes.len() - 1, bytes.len() - 13, bytes.len() / 2] {
                assert!(read_bytes(&bytes[..end], format, "t").is_err(), "{end}");
            }
        }
    }
}
