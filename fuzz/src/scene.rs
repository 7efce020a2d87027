//! Small structured inputs for the algorithm targets, decoded from the
//! fuzzer's bytes with `arbitrary`: point sets in degenerate layouts
//! (coincident, collinear, coplanar, flat, a few points), curves over them,
//! triangle soups and closed meshes, at any scale from 1e-300 to 1e300 and
//! far from the origin. Every coordinate is finite (as the file readers
//! guarantee); sizes stay small so that one run takes milliseconds.

use arbitrary::{Result, Unstructured};
use surfrecon_geom::shapes::{cuboid, icosphere};
use surfrecon_geom::{DVec3, Geometry, PointCloud, TriMesh};

/// How the points of a set are laid out (before scaling and moving).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// Anywhere on the lattice.
    Free,
    /// A few distinct points, each repeated.
    Coincident,
    /// On one line.
    Collinear,
    /// On one tilted plane.
    Coplanar,
    /// In the plane z = 0 (2D data for the level set and distances).
    Flat,
    /// On a sphere (well-behaved data with a known inside).
    Sphere,
    /// On the surface of a cube (sharp edges, many coplanar points).
    CubeSurface,
}

const LAYOUTS: [Layout; 7] = [
    Layout::Free,
    Layout::Coincident,
    Layout::Collinear,
    Layout::Coplanar,
    Layout::Flat,
    Layout::Sphere,
    Layout::CubeSurface,
];

/// Powers of ten the unit-sized layouts are scaled by: mostly 1, then
/// small and huge magnitudes up to the ends of the f64 range.
const SCALE_EXPONENTS: [i32; 14] = [0, 0, 0, 0, -3, 3, -8, 8, -30, 30, -150, 150, -300, 300];
/// Powers of ten of the translation (none, or far from the origin
/// relative to the size, where coordinates lose their low bits).
const OFFSET_EXPONENTS: [Option<i32>; 6] = [None, None, Some(0), Some(4), Some(9), Some(16)];

/// A coordinate on a coarse lattice (multiples of 1/4 in [-4, 4]) so that
/// equal, aligned and coplanar values are common.
fn coordinate(u: &mut Unstructured) -> Result<f64> {
    Ok(f64::from(u.int_in_range(-16i8..=16)?) / 4.0)
}

fn lattice_point(u: &mut Unstructured) -> Result<DVec3> {
    Ok(DVec3::new(coordinate(u)?, coordinate(u)?, coordinate(u)?))
}

/// Between 1 and `max` points laid out by an arbitrary [`Layout`], unit-sized.
pub fn layout_points(u: &mut Unstructured, max: usize) -> Result<(Layout, Vec<DVec3>)> {
    let layout = *u.choose(&LAYOUTS)?;
    let n = u.int_in_range(1..=max.max(1))?;
    let mut points = Vec::with_capacity(n);
    match layout {
        Layout::Free => {
            for _ in 0..n {
                points.push(lattice_point(u)?);
            }
        }
        Layout::Coincident => {
            let distinct: Vec<DVec3> = (0..u.int_in_range(1..=3)?)
                .map(|_| lattice_point(u))
                .collect::<Result<_>>()?;
            for i in 0..n {
                points.push(distinct[i % distinct.len()]);
            }
        }
        Layout::Collinear => {
            let (a, d) = (lattice_point(u)?, lattice_point(u)?);
            for _ in 0..n {
                points.push(a + coordinate(u)? * d);
            }
        }
        Layout::Coplanar => {
            let (a, e1, e2) = (lattice_point(u)?, lattice_point(u)?, lattice_point(u)?);
            for _ in 0..n {
                points.push(a + coordinate(u)? * e1 + coordinate(u)? * e2);
            }
        }
        Layout::Flat => {
            for _ in 0..n {
                points.push(DVec3::new(coordinate(u)?, coordinate(u)?, 0.0));
            }
        }
        Layout::Sphere => {
            for _ in 0..n {
                let d = lattice_point(u)?;
                points.push(if d == DVec3::ZERO {
                    DVec3::X
                } else {
                    d.normalize()
                });
            }
        }
        Layout::CubeSurface => {
            for _ in 0..n {
                let mut p = lattice_point(u)? / 4.0;
                let axis = u.int_in_range(0..=2)?;
                p[axis] = if u.arbitrary()? { 1.0 } else { -1.0 };
                points.push(p);
            }
        }
    }
    Ok((layout, points))
}

/// Scale and move `points` by arbitrary powers of ten. Returns false (and
/// leaves them unusable) when a coordinate overflowed.
pub fn place(u: &mut Unstructured, points: &mut [DVec3]) -> Result<bool> {
    let scale = 10f64.powi(*u.choose(&SCALE_EXPONENTS)?);
    let offset = match *u.choose(&OFFSET_EXPONENTS)? {
        Some(e) => lattice_point(u)? * 10f64.powi(e) * scale,
        None => DVec3::ZERO,
    };
    for p in points.iter_mut() {
        *p = *p * scale + offset;
    }
    Ok(points.iter().all(|p| p.is_finite()))
}

/// Normals for `points`: none, outward from their centroid (zero at the
/// centroid), lattice vectors (zero included), or outward ones with
/// arbitrary signs.
pub fn normals(u: &mut Unstructured, points: &[DVec3]) -> Result<Option<Vec<DVec3>>> {
    let centre = points.iter().copied().sum::<DVec3>() / points.len().max(1) as f64;
    let outward = |p: DVec3| (p - centre).normalize_or_zero();
    Ok(match u.int_in_range(0..=3)? {
        0 => None,
        1 => Some(points.iter().map(|&p| outward(p)).collect()),
        2 => Some(
            points
                .iter()
                .map(|_| lattice_point(u))
                .collect::<Result<_>>()?,
        ),
        _ => Some(
            points
                .iter()
                .map(|&p| {
                    Ok(if u.arbitrary()? {
                        -outward(p)
                    } else {
                        outward(p)
                    })
                })
                .collect::<Result<_>>()?,
        ),
    })
}

/// Up to four polylines over `n` vertices (runs of neighbouring indices or
/// arbitrary ones, closed or not; repeated indices allowed).
pub fn polylines(u: &mut Unstructured, n: usize) -> Result<Vec<Vec<u32>>> {
    let mut lines = Vec::new();
    if n == 0 {
        return Ok(lines);
    }
    for _ in 0..u.int_in_range(0..=4)? {
        let len = u.int_in_range(2..=12)?;
        let mut line: Vec<u32> = if u.arbitrary()? {
            let start = u.int_in_range(0..=n - 1)?;
            (0..len).map(|i| ((start + i) % n) as u32).collect()
        } else {
            (0..len)
                .map(|_| Ok(u.int_in_range(0..=n - 1)? as u32))
                .collect::<Result<_>>()?
        };
        if u.arbitrary()? {
            line.push(line[0]);
        }
        lines.push(line);
    }
    Ok(lines)
}

/// Up to 16 triangles over `n` vertices (any indices: degenerate,
/// duplicated, non-manifold and inconsistently oriented faces occur).
pub fn triangle_soup(u: &mut Unstructured, n: usize) -> Result<Vec<[u32; 3]>> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let index = |u: &mut Unstructured| -> Result<u32> { Ok(u.int_in_range(0..=n - 1)? as u32) };
    (0..u.int_in_range(1..=16)?)
        .map(|_| Ok([index(u)?, index(u)?, index(u)?]))
        .collect()
}

/// A closed mesh: an icosahedron (subdivided or not) or a cube, stretched
/// per axis (possibly flat), with a few vertices moved, then placed.
/// Returns the mesh and whether it is still convex (nothing moved).
pub fn closed_mesh(u: &mut Unstructured) -> Result<Option<(TriMesh, bool)>> {
    let mut mesh = match u.int_in_range(0..=2)? {
        0 => icosphere(DVec3::ZERO, 1.0, 0),
        1 => icosphere(DVec3::ZERO, 1.0, 1),
        _ => cuboid(DVec3::splat(-1.0), DVec3::ONE),
    };
    // Stretch per axis by 1/4..4, or 0 (flattened: a closed mesh of no volume).
    let stretch = DVec3::new(
        f64::from(u.int_in_range(0u8..=16)?) / 4.0,
        f64::from(u.int_in_range(1u8..=16)?) / 4.0,
        f64::from(u.int_in_range(1u8..=16)?) / 4.0,
    );
    let mut convex = stretch.x > 0.0;
    for v in &mut mesh.vertices {
        *v *= stretch;
    }
    for _ in 0..u.int_in_range(0..=3)? {
        let i = u.int_in_range(0..=mesh.vertices.len() - 1)?;
        mesh.vertices[i] = lattice_point(u)?;
        convex = false;
    }
    Ok(place(u, &mut mesh.vertices)?.then_some((mesh, convex)))
}

/// A whole input as a file gives it: points (with or without normals),
/// optionally polylines and triangles over them, or a closed mesh.
/// At most `max_points` points. None when placing overflowed.
pub fn geometry(u: &mut Unstructured, max_points: usize) -> Result<Option<Geometry>> {
    if u.ratio(1, 5)? {
        return Ok(closed_mesh(u)?.map(|(mesh, _)| Geometry::from_mesh(mesh)));
    }
    let (_, mut points) = layout_points(u, max_points)?;
    if !place(u, &mut points)? {
        return Ok(None);
    }
    let normals = normals(u, &points)?;
    let n = points.len();
    let mut geometry = Geometry::from_points(PointCloud {
        positions: points,
        normals,
        scalars: None,
    });
    match u.int_in_range(0..=3)? {
        0 => geometry.lines = polylines(u, n)?,
        1 => geometry.triangles = triangle_soup(u, n)?,
        _ => {}
    }
    Ok(Some(geometry))
}

/// One of `values`, or (one time in eight) an arbitrary f64 (NaN, infinite,
/// negative, subnormal...).
pub fn pick_f64(u: &mut Unstructured, values: &[f64]) -> Result<f64> {
    if u.ratio(1, 8)? {
        return u.arbitrary();
    }
    Ok(*u.choose(values)?)
}
