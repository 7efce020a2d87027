//! How well a surface reaches the data it was built from: the exact
//! distance from every datum (point, curve vertex, patch vertex) to the
//! mesh, summarized relative to the data's bounding-box diagonal. A
//! reconstruction that drops a thin part shows it here even when the
//! Chamfer distance to a reference barely moves.

use crate::metrics::TriangleBvh;
use crate::{Aabb, GeomError, TriMesh};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// Distances from the data to a mesh. Distances are fractions of
/// `diagonal`; shares are fractions of `points`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DataFit {
    pub points: usize,
    /// Bounding-box diagonal of the data (data units).
    pub diagonal: f64,
    pub mean: f64,
    pub max: f64,
    pub within_0_25pct: f64,
    pub within_0_5pct: f64,
    pub within_1pct: f64,
    /// The datum farthest from the mesh.
    pub farthest: [f64; 3],
}

/// Largest coordinate magnitude measured.
const MAX_COORDINATE: f64 = 1e100;

/// Exact distances from `data` to the triangles of `mesh` (parallel; the
/// result does not depend on the thread count).
pub fn data_fit(mesh: &TriMesh, data: &[DVec3]) -> Result<DataFit, GeomError> {
    if data.is_empty() {
        return Err(GeomError::InvalidInput("data fit: no data points".into()));
    }
    if let Some(i) = data.iter().position(|p| !p.is_finite()) {
        return Err(GeomError::InvalidInput(format!(
            "data fit: data point {i} is not finite"
        )));
    }
    // Distances between points past 1e100 square out of the f64 range (the
    // fuzzer found a NaN mean at 1e299).
    let huge = |p: &DVec3| p.abs().max_element() > MAX_COORDINATE;
    if data.iter().any(huge) || mesh.vertices.iter().any(huge) {
        return Err(GeomError::InvalidInput(format!(
            "data fit: coordinates beyond {MAX_COORDINATE:e} are not supported; rescale the data and the mesh"
        )));
    }
    let bvh = TriangleBvh::new(mesh);
    let distances: Vec<f64> = data
        .par_iter()
        .map(|&p| bvh.closest(p).map(|c| c.distance))
        .collect::<Option<_>>()
        .ok_or_else(|| GeomError::InvalidInput("data fit: the mesh has no triangles".into()))?;
    let diagonal = Aabb::from_points(data).diagonal();
    let scale = if diagonal > 0.0 { 1.0 / diagonal } else { 1.0 };
    let (far, max) =
        distances.iter().enumerate().fold(
            (0, 0.0),
            |(i, m), (j, &d)| if d > m { (j, d) } else { (i, m) },
        );
    let share = |t: f64| {
        distances.iter().filter(|&&d| d <= t * diagonal).count() as f64 / data.len() as f64
    };
    Ok(DataFit {
        points: data.len(),
        diagonal,
        mean: distances.iter().sum::<f64>() / data.len() as f64 * scale,
        max: max * scale,
        within_0_25pct: share(0.0025),
        within_0_5pct: share(0.005),
        within_1pct: share(0.01),
        farthest: data[far].to_array(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::closest_point_on_triangle;
    use crate::shapes::icosphere;

    /// Fuzz input (target `eval`): one datum near 2.5e154 against a mesh
    /// near 4e299 gave a NaN mean; now an error.
    #[test]
    fn huge_coordinates_are_refused() {
        let mut mesh = icosphere(DVec3::ZERO, 1.0, 0);
        mesh.vertices.iter_mut().for_each(|v| *v *= 4e299);
        let datum = DVec3::new(-2.500000000000001e154, -2.4999750000000008e154, -4.0004e154);
        let e = data_fit(&mesh, &[datum]).unwrap_err();
        assert!(e.to_string().contains("rescale"), "{e}");
    }

    #[test]
    fn distances_match_brute_force() {
        let mesh = icosphere(DVec3::ZERO, 1.0, 2);
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
        };
        let data: Vec<DVec3> = (0..300)
            .map(|_| DVec3::new(next(), next(), next()))
            .collect();
        let fit = data_fit(&mesh, &data).unwrap();
        let brute: Vec<f64> = data
            .iter()
            .map(|&p| {
                (0..mesh.triangles.len())
                    .map(|t| closest_point_on_triangle(p, mesh.corners(t)).distance(p))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let diagonal = Aabb::from_points(&data).diagonal();
        let mean = brute.iter().sum::<f64>() / brute.len() as f64 / diagonal;
        let max = brute.iter().copied().fold(0.0, f64::max) / diagonal;
        assert!((fit.mean - mean).abs() < 1e-12 && (fit.max - max).abs() < 1e-12);
        let within = brute.iter().filter(|&&d| d <= 0.01 * diagonal).count() as f64 / 300.0;
        assert_eq!(fit.within_1pct, within);
    }

    #[test]
    fn points_off_a_sphere_by_known_amounts() {
        let mesh = icosphere(DVec3::ZERO, 1.0, 5);
        // Vertices of the mesh are on it; one point 0.1 outside, on a vertex ray.
        let mut data: Vec<DVec3> = mesh.vertices.iter().step_by(7).copied().collect();
        let off = 1.1 * mesh.vertices[0];
        data.push(off);
        let fit = data_fit(&mesh, &data).unwrap();
        assert!((fit.max * fit.diagonal - 0.1).abs() < 1e-9, "{fit:?}");
        assert_eq!(fit.farthest, off.to_array());
        assert_eq!(
            fit.within_0_25pct,
            (data.len() - 1) as f64 / data.len() as f64
        );
    }

    #[test]
    fn empty_or_non_finite_input_is_refused() {
        let mesh = icosphere(DVec3::ZERO, 1.0, 1);
        assert!(data_fit(&mesh, &[]).is_err());
        assert!(data_fit(&mesh, &[DVec3::new(f64::NAN, 0.0, 0.0)]).is_err());
        assert!(data_fit(&TriMesh::default(), &[DVec3::ONE]).is_err());
    }
}
