//! Write then read gives back what the format can hold, exactly.

use super::*;
use crate::io::Encoding;
use crate::PointCloud;

/// What survives a trip through `format` (STL handled separately).
fn storable(g: &Geometry, format: Format) -> Geometry {
    let mut out = g.clone();
    if !format.stores_lines() {
        out.lines.clear();
    }
    if !format.stores_triangles() {
        out.triangles.clear();
    }
    if !format.stores_normals() {
        out.points.normals = None;
    }
    if !format.stores_scalars() {
        out.points.scalars = None;
    }
    out
}

fn round_trip(g: &Geometry, format: Format, options: WriteOptions) -> Geometry {
    parse_ok(&encode(g, format, options), format)
}

const ENCODINGS: [Encoding; 3] = [
    Encoding::Ascii,
    Encoding::BinaryLittleEndian,
    Encoding::BinaryBigEndian,
];

#[test]
fn ply_round_trips_in_every_encoding() {
    let g = sample_mesh();
    for encoding in ENCODINGS {
        let back = round_trip(&g, Format::Ply, WriteOptions { encoding });
        assert_eq!(back, g, "{encoding:?}");
    }
}

#[test]
fn ply_round_trips_point_clouds_without_extras() {
    let mut g = sample_mesh();
    g.triangles.clear();
    g.points.normals = None;
    g.points.scalars = None;
    for encoding in ENCODINGS {
        assert_eq!(round_trip(&g, Format::Ply, WriteOptions { encoding }), g);
    }
}

#[test]
fn text_formats_round_trip_exactly() {
    let g = sample_mesh();
    for format in [Format::Obj, Format::Off, Format::Xyz] {
        let back = round_trip(&g, format, WriteOptions::default());
        assert_eq!(back, storable(&g, format), "{format}");
    }
}

#[test]
fn extreme_values_round_trip_through_text() {
    let values = [
        1e-300,
        -2.5e300,
        0.1,
        -0.0,
        123456789.12345679,
        5e-324,
        1e16,
        9.999e15,
    ];
    let positions = values
        .chunks(2)
        .map(|c| DVec3::new(c[0], c[1], 1.0 / 3.0))
        .collect();
    let g = Geometry::from_points(PointCloud::new(positions));
    for format in [Format::Obj, Format::Off, Format::Xyz] {
        assert_eq!(
            round_trip(&g, format, WriteOptions::default()),
            g,
            "{format}"
        );
    }
    let back = round_trip(&g, Format::Ply, WriteOptions::ascii());
    assert_eq!(back, g);
}

#[test]
fn obj_round_trips_polylines_with_and_without_triangles() {
    let mut g = sample_mesh();
    g.points.scalars = None;
    g.lines = vec![vec![0, 1, 2, 0], vec![5, 9]];
    assert_eq!(round_trip(&g, Format::Obj, WriteOptions::default()), g);
    g.triangles.clear();
    g.points.normals = None;
    assert_eq!(round_trip(&g, Format::Obj, WriteOptions::default()), g);
}

#[test]
fn xyz_round_trips_every_column_layout() {
    let base = sample_mesh();
    for (normals, scalars) in [(false, false), (true, false), (false, true), (true, true)] {
        let mut g = Geometry::from_points(base.points.clone());
        if !normals {
            g.points.normals = None;
        }
        if !scalars {
            g.points.scalars = None;
        }
        assert_eq!(round_trip(&g, Format::Xyz, WriteOptions::default()), g);
    }
}

/// STL keeps triangle corners only (binary: as 32-bit floats), merged by
/// position in order of first use.
#[test]
fn stl_round_trips_triangle_corners() {
    let g = sample_mesh();
    for encoding in [Encoding::Ascii, Encoding::BinaryLittleEndian] {
        let back = round_trip(&g, Format::Stl, WriteOptions { encoding });
        assert_eq!(back.triangles.len(), g.triangles.len());
        assert_eq!(back.points.len(), g.points.len(), "shared corners merged");
        assert!(back.points.normals.is_none() && back.lines.is_empty());
        let round = |p: DVec3| match encoding {
            Encoding::Ascii => p,
            _ => p.as_vec3().as_dvec3(),
        };
        for t in 0..g.triangles.len() {
            let want = g.to_mesh().corners(t).map(round);
            assert_eq!(back.to_mesh().corners(t), want);
        }
    }
}

#[test]
fn stl_without_triangles_is_refused() {
    let g = Geometry::from_points(PointCloud::new(vec![DVec3::ONE]));
    let err = to_bytes(&g, Format::Stl, WriteOptions::default()).unwrap_err();
    assert!(err.to_string().contains("triangles"), "{err}");
}

#[test]
fn invalid_geometry_is_refused_before_writing() {
    let mut g = sample_mesh();
    g.triangles.push([0, 1, 10_000]);
    assert!(matches!(
        to_bytes(&g, Format::Ply, WriteOptions::default()),
        Err(GeomError::InvalidInput(_))
    ));
    let mut g = sample_mesh();
    g.points.positions[3].y = f64::NAN;
    assert!(matches!(
        to_bytes(&g, Format::Obj, WriteOptions::default()),
        Err(GeomError::InvalidInput(_))
    ));
}

#[test]
fn format_comes_from_the_extension() {
    assert_eq!(Format::from_path("a/b.PLY").unwrap(), Format::Ply);
    assert_eq!(Format::from_path("x.Obj").unwrap(), Format::Obj);
    assert_eq!("stl".parse::<Format>().unwrap(), Format::Stl);
    assert!(matches!(
        Format::from_path("scan.pcd"),
        Err(GeomError::UnknownFormat { .. })
    ));
    assert!(Format::from_path("noextension").is_err());
    for f in Format::ALL {
        assert_eq!(Format::from_extension(f.name()), Some(f));
    }
}
