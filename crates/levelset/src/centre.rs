//! The reconstruction runs on data moved near the origin, and its results
//! are moved back.
//!
//! Grid nodes sit at `origin + spacing * index`. Far from the origin the
//! spacing can fall below the precision of the coordinates: a single
//! point at 1e30 gets a grid of spacing 0.25 (one ulp there is 1.4e14),
//! so every node had the same position, every distance was 0 and the 2D
//! level set came out as an open curve. Relative to the data's centre the
//! nodes are distinct whatever the data's position; only the final
//! coordinates are rounded, once, when moved back.

use crate::reconstruct::{Input, Reconstruction2, Reconstruction3};
use std::borrow::Cow;
use surfrecon_geom::DVec3;
use surfrecon_grid::sparse::BlockGrid;
use surfrecon_grid::Field;

pub(crate) use surfrecon_geom::aabb::offset_to_origin as offset;

/// `input` moved by `-by` (borrowed unchanged when `by` is zero).
pub(crate) fn moved(input: &Input, by: DVec3) -> Cow<'_, Input> {
    if by == DVec3::ZERO {
        return Cow::Borrowed(input);
    }
    let m = |v: &DVec3| *v - by;
    Cow::Owned(Input {
        points: input.points.iter().map(m).collect(),
        normals: input.normals.clone(),
        segments: input.segments.iter().map(|s| s.each_ref().map(m)).collect(),
        triangles: input
            .triangles
            .iter()
            .map(|t| t.each_ref().map(m))
            .collect(),
    })
}

/// The first `D` coordinates of `by`.
fn head<const D: usize>(by: DVec3) -> [f64; D] {
    std::array::from_fn(|a| if a < 3 { by[a] } else { 0.0 })
}

/// φ (and the dense field, if any) moved by `by`.
pub(crate) fn move_fields<const D: usize>(
    phi: &mut BlockGrid<D>,
    field: Option<&mut Field<D>>,
    by: DVec3,
) {
    phi.translate(head(by));
    if let Some(f) = field {
        let by = head::<D>(by);
        (0..D).for_each(|a| f.spec.origin[a] += by[a]);
    }
}

impl Reconstruction3 {
    /// Every position moved by `by`.
    pub(crate) fn moved_by(mut self, by: DVec3) -> Self {
        self.mesh.vertices.iter_mut().for_each(|v| *v += by);
        move_fields(&mut self.phi, self.field.as_mut(), by);
        self
    }
}

impl Reconstruction2 {
    /// Every position moved by `by` (x and y; the curves stay at z = 0).
    pub(crate) fn moved_by(mut self, by: DVec3) -> Self {
        let in_plane = DVec3::new(by.x, by.y, 0.0);
        self.curves.vertices.iter_mut().for_each(|v| *v += in_plane);
        move_fields(&mut self.phi, self.field.as_mut(), by);
        self
    }
}
