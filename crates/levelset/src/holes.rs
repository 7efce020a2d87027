//! Holes in the data must not let the outside in.
//!
//! Tagging floods the exterior from the grid's border through every node
//! farther than ε from the data. Where a scan misses a patch wider than 2ε
//! the flood runs in through it, the inside is tagged outside and the
//! walls collapse. Points with oriented normals tell inside from outside
//! without a closed contour: each stands for a small disk of the surface
//! (its share of the area, in its tangent plane), and the generalized
//! winding number of those disks exceeds 1/2 inside. It integrates over
//! all points, so scattered normals of noisy data average out. Nodes the
//! plain flood reached that it puts inside, beyond ε and within a reach of
//! the data, are sealed (given distance 0 in the field the flood reads);
//! the evolution still follows the data everywhere.

use crate::reconstruct::Input;
use rayon::prelude::*;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::sdf::WindingTree;
use surfrecon_grid::Field;

/// Neighbours whose mean distance sets a point's share of the area.
pub(crate) const AREA_NEIGHBOURS: usize = 6;

/// Share of the sampled candidates that must be inside for the flood to
/// count as got in (and the full field to be computed).
const FLOODED_SHARE: f64 = 0.02;
/// Every this many candidates are sampled for that test.
const SAMPLE_STRIDE: usize = 32;

/// The distance field for tagging, when the flood got in: `d` with the
/// nodes that `exterior` (the plain tagging) put outside, farther than
/// `epsilon` but within `reach` of the data, set to 0 where the oriented
/// points' winding number exceeds `inside_above` (1/2: inside; lower
/// also seals the mouth of a hole out to where the winding number falls
/// off, while the outside of a closed part stays near 0); and how many
/// were sealed.
/// `None` when a sample of those nodes finds (almost) none inside, so data
/// the flood did not enter cost one cheap test. `input.normals` must hold
/// one unit normal per point.
pub(crate) fn seal_with_normals<const D: usize>(
    d: &Field<D>,
    exterior: impl Fn(usize) -> bool + Sync,
    input: &Input,
    epsilon: f64,
    reach: f64,
    inside_above: f64,
) -> Option<(Field<D>, usize)> {
    if D != 3 {
        return None;
    }
    let candidates: Vec<usize> = (0..d.values.len())
        .filter(|&l| d.values[l] > epsilon && d.values[l] <= reach && exterior(l))
        .collect();
    if candidates.is_empty() {
        return None;
    }
    let tree = WindingTree::of_mesh(&oriented_disks(input));
    let spec = d.spec;
    let inside = |l: usize| {
        let p = spec.position(spec.unlinear(l));
        let x = DVec3::from_array(std::array::from_fn(|a| if a < D { p[a] } else { 0.0 }));
        tree.winding_number(x) > inside_above
    };
    let sampled: Vec<usize> = candidates.iter().step_by(SAMPLE_STRIDE).copied().collect();
    let found = sampled.par_iter().filter(|&&l| inside(l)).count();
    if (found as f64) < FLOODED_SHARE * sampled.len() as f64 {
        return None;
    }
    let sealed: Vec<usize> = candidates.into_par_iter().filter(|&l| inside(l)).collect();
    let mut field = d.clone();
    for &l in &sealed {
        field.values[l] = 0.0;
    }
    Some((field, sealed.len()))
}

/// One small triangle per point, in its tangent plane, facing along its
/// normal, with the point's share of the surface area.
fn oriented_disks(input: &Input) -> TriMesh {
    let tree = KdTree::new(&input.points);
    let corners = tangent_disks(&input.points, &input.normals, &tree);
    TriMesh {
        vertices: corners.iter().flatten().copied().collect(),
        triangles: (0..corners.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect(),
        normals: None,
    }
}

/// Per point a triangle in the plane through it with the given unit
/// normal, counter-clockwise about the normal, of area spacing² (the mean
/// distance to its nearest neighbours in `tree`, built over `points`): the
/// point's share of the surface it samples.
pub(crate) fn tangent_disks(points: &[DVec3], normals: &[DVec3], tree: &KdTree) -> Vec<[DVec3; 3]> {
    let spacing: Vec<f64> = points
        .par_iter()
        .map(|&p| {
            let near = tree.knn(p, AREA_NEIGHBOURS + 1);
            near.iter().map(|x| x.distance).sum::<f64>() / AREA_NEIGHBOURS as f64
        })
        .collect();
    disks_of_spacing(points, normals, &spacing)
}

/// [`tangent_disks`] with each point's spacing given (its mean distance to
/// its [`AREA_NEIGHBOURS`] nearest other points).
pub(crate) fn disks_of_spacing(
    points: &[DVec3],
    normals: &[DVec3],
    spacing: &[f64],
) -> Vec<[DVec3; 3]> {
    (points.par_iter().zip(normals).zip(spacing))
        .map(|((&p, &n), &spacing)| {
            // Equilateral triangle of area spacing²: circumradius r with
            // (3√3/4) r² = spacing².
            let r = spacing * (4.0 / (3.0 * 3f64.sqrt())).sqrt();
            let u = n.any_orthonormal_vector();
            let v = n.cross(u);
            std::array::from_fn(|k| {
                let t = k as f64 * std::f64::consts::TAU / 3.0;
                p + (u * t.cos() + v * t.sin()) * r
            })
        })
        .collect()
}
