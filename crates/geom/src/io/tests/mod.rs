//! Tests of the file formats: round trips, malformed input, robustness
//! against every truncation and byte flip, real data files, atomic writes.

mod atomic;
mod data;
mod malformed;
mod robustness;
mod roundtrip;

use super::{read_bytes, to_bytes, Format, WriteOptions};
use crate::{shapes, GeomError, Geometry, Location};
use glam::DVec3;

/// A sphere mesh with unit normals and one scalar per vertex; coordinates
/// are irrational, so text formats must print every digit to round-trip.
fn sample_mesh() -> Geometry {
    let mesh = shapes::icosphere(DVec3::new(0.1, -2.0, 3.5), 1.3, 2);
    let mut g = Geometry::from_mesh(mesh);
    let c = DVec3::new(0.1, -2.0, 3.5);
    g.points.normals = Some(
        g.points
            .positions
            .iter()
            .map(|p| (*p - c).normalize())
            .collect(),
    );
    g.points.scalars = Some((0..g.points.len()).map(|i| i as f64 * 0.37 - 5.0).collect());
    g
}

/// Parse `text` as `format`, expecting a parse error; returns its location
/// and message.
#[track_caller]
fn parse_error(bytes: &[u8], format: Format) -> (Location, String) {
    match read_bytes(bytes, format, "test.input") {
        Err(GeomError::Parse {
            location,
            message,
            path,
        }) => {
            assert_eq!(path.to_str(), Some("test.input"));
            (location, message)
        }
        Ok(g) => panic!("expected a parse error, got {} points", g.points.len()),
        Err(e) => panic!("expected a parse error, got {e}"),
    }
}

/// Parse, expecting success.
#[track_caller]
fn parse_ok(bytes: &[u8], format: Format) -> Geometry {
    read_bytes(bytes, format, "test.input").unwrap_or_else(|e| panic!("{e}"))
}

/// Bytes of `g` in `format`.
fn encode(g: &Geometry, format: Format, options: WriteOptions) -> Vec<u8> {
    to_bytes(g, format, options).expect("encodable")
}
