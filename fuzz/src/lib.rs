//! Shared check of the fuzz targets: parsing arbitrary bytes never panics,
//! and whatever parses can be written and read back unchanged.

use surfrecon_geom::io::{read_bytes, to_bytes, Encoding, Format, WriteOptions};

/// Parse `data` as `format`; on success, write the geometry in every
/// encoding of that format and require the same geometry back.
pub fn check(data: &[u8], format: Format) {
    let Ok(geometry) = read_bytes(data, format, "fuzz-input") else {
        return;
    };
    if format == Format::Stl && geometry.triangles.is_empty() {
        return; // an empty solid parses, but STL output needs triangles
    }
    let encodings: &[Encoding] = match format {
        Format::Ply => &[
            Encoding::Ascii,
            Encoding::BinaryLittleEndian,
            Encoding::BinaryBigEndian,
        ],
        // Binary STL rounds to 32-bit floats; the ascii form is exact.
        // Text-only formats ignore the encoding.
        _ => &[Encoding::Ascii],
    };
    for &encoding in encodings {
        let bytes = to_bytes(&geometry, format, WriteOptions { encoding })
            .unwrap_or_else(|e| panic!("parsed geometry not writable as {format}: {e}"));
        if bytes.is_empty() {
            continue; // e.g. an OBJ/XYZ of nothing: reading "" is an error by design
        }
        let again = read_bytes(&bytes, format, "fuzz-rewrite")
            .unwrap_or_else(|e| panic!("written {format} not readable: {e}"));
        assert_eq!(
            again, geometry,
            "{format} {encoding:?} round trip changed the geometry"
        );
    }
}
