//! Feature points from a cell's surface crossings alone.
//!
//! Where the normals at a cell's crossings disagree sharply, an edge or a
//! corner of the surface runs through or just beside the cell, whether or
//! not a mesh feature edge lies inside it (a ridge passing just outside a
//! cell leaves crossings on both of its faces, and marching cubes then
//! cuts under it). The point that best fits the tangent planes at the
//! crossings (the QEF minimizer of dual contouring and extended marching
//! cubes) lies on that edge or corner.

use surfrecon_geom::DVec3;
use surfrecon_grid::GridSpec;

/// A surface point and its unit normal.
pub type Tangent = (DVec3, DVec3);

/// Eigenvalues below this share of the largest count as zero in the QEF:
/// the directions the planes leave free (along an edge; all but one on a
/// flat face) take the crossings' mean instead.
const QEF_TRUNCATION: f64 = 0.1;

/// Whether some two normals differ by more than the angle whose cosine is
/// `cos_limit`.
pub fn is_sharp(tangents: &[Tangent], cos_limit: f64) -> bool {
    tangents
        .iter()
        .enumerate()
        .any(|(i, a)| tangents[i + 1..].iter().any(|b| a.1.dot(b.1) < cos_limit))
}

/// The point nearest, in the least-squares sense, to all tangent planes;
/// along directions they do not fix, the nearest such point to their mean.
pub fn qef_minimizer(tangents: &[Tangent]) -> Option<DVec3> {
    if tangents.is_empty() {
        return None;
    }
    let mass = tangents.iter().map(|t| t.0).sum::<DVec3>() / tangents.len() as f64;
    // Minimize |A x - b|² around the mass point: x = mass + A⁺ r.
    let mut ata = [[0.0; 3]; 3];
    let mut atr = DVec3::ZERO;
    for &(p, n) in tangents {
        let r = n.dot(p - mass);
        for i in 0..3 {
            for j in 0..3 {
                ata[i][j] += n[i] * n[j];
            }
        }
        atr += n * r;
    }
    let (values, vectors) = symmetric_eigen(ata);
    let largest = values.iter().fold(0.0f64, |m, &v| m.max(v));
    if largest <= 0.0 {
        return Some(mass);
    }
    let mut x = mass;
    for k in 0..3 {
        if values[k] > QEF_TRUNCATION * largest {
            x += vectors[k] * (vectors[k].dot(atr) / values[k]);
        }
    }
    x.is_finite().then_some(x)
}

/// Eigenvalues and unit eigenvectors of a symmetric 3×3 matrix (cyclic
/// Jacobi rotations).
fn symmetric_eigen(mut a: [[f64; 3]; 3]) -> ([f64; 3], [DVec3; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..32 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let scale = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2);
        if off <= 1e-30 * scale.max(f64::MIN_POSITIVE) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A ← Jᵀ A J with J the rotation in the (p, q) plane.
            for row in a.iter_mut() {
                let (rp, rq) = (row[p], row[q]);
                row[p] = c * rp - s * rq;
                row[q] = s * rp + c * rq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
            a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let vectors = std::array::from_fn(|k| DVec3::new(v[0][k], v[1][k], v[2][k]));
    ([a[0][0], a[1][1], a[2][2]], vectors)
}

/// `p` limited to `cell`'s box grown by `margin` on every side, and kept
/// 1e-7 spacings off the box's own faces, so that [`owner_cell`] decides
/// unambiguously which cell it belongs to.
pub fn clamp_near(spec: &GridSpec<3>, cell: usize, p: DVec3, margin: f64) -> DVec3 {
    let lo = DVec3::from_array(spec.position(spec.unlinear(cell)));
    let hi = lo + DVec3::splat(spec.spacing);
    let e = 1e-7 * spec.spacing;
    DVec3::from_array(std::array::from_fn(|a| {
        let x = p[a].clamp(lo[a] - margin, hi[a] + margin);
        if x < lo[a] {
            x.min(lo[a] - e)
        } else if x > hi[a] {
            x.max(hi[a] + e)
        } else {
            x.clamp(lo[a] + e, hi[a] - e)
        }
    }))
}

/// The cell a feature point stored at sample `node` belongs to: of the
/// cells around the sample, the one whose box lies nearest the point (the
/// one containing it, when one does). A point may lie a little outside
/// its cell, beyond the faces away from the sample that stores it.
pub fn owner_cell(spec: &GridSpec<3>, node: usize, p: DVec3) -> Option<usize> {
    crate::offset::cells_around(spec, node)
        .map(|c| {
            let lo = DVec3::from_array(spec.position(spec.unlinear(c)));
            let hi = lo + DVec3::splat(spec.spacing);
            let outside = (lo - p).max(p - hi).max(DVec3::ZERO);
            (outside.length_squared(), c)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        .map(|(_, c)| c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_qef_finds_a_ridge_and_a_corner() {
        // Two faces of the box x ≤ 1, y ≤ 2: the ridge is the line
        // x = 1, y = 2; the crossings' mean has z = 0.5.
        let ridge = [
            (DVec3::new(1.0, 1.5, 0.0), DVec3::X),
            (DVec3::new(1.0, 1.2, 1.0), DVec3::X),
            (DVec3::new(0.4, 2.0, 0.2), DVec3::Y),
            (DVec3::new(0.7, 2.0, 0.8), DVec3::Y),
        ];
        let p = qef_minimizer(&ridge).unwrap();
        assert!(p.distance(DVec3::new(1.0, 2.0, 0.5)) < 1e-12, "{p}");
        assert!(is_sharp(&ridge, 30f64.to_radians().cos()));
        let mut corner = ridge.to_vec();
        corner.push((DVec3::new(0.3, 0.3, 3.0), DVec3::Z));
        let p = qef_minimizer(&corner).unwrap();
        assert!(p.distance(DVec3::new(1.0, 2.0, 3.0)) < 1e-12, "{p}");
        // A flat face: no feature, the point stays on the plane.
        let flat = [
            (DVec3::new(0.0, 0.0, 1.0), DVec3::Z),
            (DVec3::new(1.0, 0.0, 1.0), DVec3::Z),
        ];
        assert!(!is_sharp(&flat, 0.9));
        assert!((qef_minimizer(&flat).unwrap().z - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_point_just_outside_a_cell_belongs_to_it_from_the_far_corner() {
        let spec = GridSpec::<3> {
            origin: [0.0; 3],
            spacing: 1.0,
            dims: [5, 5, 5],
        };
        let cell = spec.linear([1, 1, 1]);
        let p = clamp_near(&spec, cell, DVec3::new(2.9, 1.5, 1.0), 0.5);
        assert_eq!(p, DVec3::new(2.5, 1.5, 1.0 + 1e-7));
        // Stored at the cell's corner on the low x side it belongs to the cell.
        assert_eq!(owner_cell(&spec, spec.linear([1, 1, 1]), p), Some(cell));
        assert_eq!(owner_cell(&spec, spec.linear([1, 2, 2]), p), Some(cell));
        // From the high x side it would belong to the neighbour.
        assert_ne!(owner_cell(&spec, spec.linear([2, 1, 1]), p), Some(cell));
    }
}
