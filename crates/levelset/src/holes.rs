//! Holes in the data must not let the outside in.
//!
//! Tagging floods the exterior from the grid's border through every node
//! farther than ε from the data. Where a scan misses a patch wider than 2ε
//! the flood runs in through it, the inside is tagged outside and the
//! walls collapse. Points with oriented normals tell inside from outside
//! without a closed contour: each stands for a small disk of the surface
//! (its share of the area, in its tangent plane), and the generalized
//! winding number of those disks exceeds 1/2 inside. It integrates over
//! all points, so scattered normals of noisy data average out. Nodes it
//! puts inside, beyond ε and within a reach of the data, are sealed (given
//! distance 0 in the field the flood reads); the evolution still follows
//! the data everywhere.

use crate::reconstruct::Input;
use rayon::prelude::*;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::{Field, GridSpec};

/// Neighbours whose mean distance sets a point's share of the area.
const AREA_NEIGHBOURS: usize = 6;

/// The distance field for tagging: `d` with the nodes farther than
/// `epsilon` but within `reach` of the data that the oriented points'
/// winding number puts inside set to 0, and how many were sealed. Only in
/// 3D; `input.normals` must hold one unit normal per point.
pub(crate) fn seal_with_normals<const D: usize>(
    d: &Field<D>,
    input: &Input,
    epsilon: f64,
    reach: f64,
) -> Option<(Field<D>, usize)> {
    if D != 3 {
        return None;
    }
    let spec = GridSpec::<3> {
        origin: std::array::from_fn(|a| d.spec.origin[a]),
        spacing: d.spec.spacing,
        dims: std::array::from_fn(|a| d.spec.dims[a]),
    };
    let disks = oriented_disks(input);
    let signed =
        surfrecon_grid::sdf::signed_distance(&disks, &spec, Some(reach.max(spec.spacing))).ok()?;
    let mut field = d.clone();
    let mut count = 0;
    for (v, s) in field.values.iter_mut().zip(&signed.values) {
        if *v > epsilon && *v <= reach && *s < 0.0 {
            *v = 0.0;
            count += 1;
        }
    }
    Some((field, count))
}

/// One small triangle per point, in its tangent plane, facing along its
/// normal, with the point's share of the surface area (from the mean
/// distance to its nearest neighbours).
fn oriented_disks(input: &Input) -> TriMesh {
    let tree = KdTree::new(&input.points);
    let corners: Vec<[DVec3; 3]> = input
        .points
        .par_iter()
        .zip(&input.normals)
        .map(|(&p, &n)| {
            let near = tree.knn(p, AREA_NEIGHBOURS + 1);
            let spacing = near.iter().map(|x| x.distance).sum::<f64>() / AREA_NEIGHBOURS as f64;
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
        .collect();
    TriMesh {
        vertices: corners.iter().flatten().copied().collect(),
        triangles: (0..corners.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect(),
        normals: None,
    }
}
