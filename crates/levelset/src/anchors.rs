//! Data anchors: once the zero set crosses a grid cell that holds data,
//! it keeps crossing it.
//!
//! Convection and the minimal surface flow are driven by the unsigned
//! distance d. Where a part of the shape is thin next to the sampling gap
//! (a spike, a fin, a tail), a node inside it is often closer to a sample
//! on the far side than to one on its own side, so the evolution pulls the
//! two sides together and the part erodes from its tip until it is gone:
//! data that the initial surface reached are left behind. [`DataCells`]
//! forbids exactly that: a node may change side only if every cell around
//! it that holds a datum still has nodes on both sides afterwards. The zero
//! set then passes within one cell of every datum it has reached, and thin
//! parts are kept as long as the grid holds one row of nodes inside them.
//!
//! [`TangentSides`] keeps the evolution from pulling a node across to the
//! wrong side of the data in the first place: near the points, a node may
//! only move to the side that the tangent plane of its nearest point puts
//! it on (normals fitted to the neighbours, oriented by the current
//! surface). Inside a thin part every node lies behind the tangent plane of
//! whichever face is nearest, so the part stays solid.

use crate::band::NarrowBand;
use crate::holes::AREA_NEIGHBOURS;
use crate::multires::interpolate_with;
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use std::sync::Mutex;
use surfrecon_geom::normals::{estimate_normals, estimate_normals_and_spacing};
use surfrecon_geom::spatial::{KdTree, Neighbour};
use surfrecon_geom::DVec3;
use surfrecon_grid::GridSpec;

/// The cells of a grid that hold at least one datum, each named by the
/// linear index of its lowest corner node. Sorted, without repeats.
#[derive(Clone, Debug)]
pub struct DataCells<const D: usize> {
    spec: GridSpec<D>,
    cells: Vec<usize>,
}

impl<const D: usize> DataCells<D> {
    /// The cells of `spec` that hold a vertex of `vertices` (first `D`
    /// coordinates; vertices outside the grid are ignored).
    pub fn new(spec: GridSpec<D>, vertices: impl Iterator<Item = DVec3>) -> Self {
        let mut cells: Vec<usize> = vertices
            .filter_map(|v| cell_of(&spec, std::array::from_fn(|a| v[a])))
            .map(|c| spec.linear(c))
            .collect();
        cells.sort_unstable();
        cells.dedup();
        DataCells { spec, cells }
    }

    /// Number of cells holding data.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// True when no datum lies in the grid.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// Whether `node` may move to side `to_inside`, given the side of every
    /// node (`inside`): false if some data cell at its corner would then
    /// have all its corners on that side.
    pub fn allows(
        &self,
        node: [usize; D],
        to_inside: bool,
        inside: impl Fn([usize; D]) -> bool,
    ) -> bool {
        (0..1usize << D).all(|corner| {
            let Some(cell) = self.cell_at_corner(node, corner) else {
                return true;
            };
            if self.cells.binary_search(&self.spec.linear(cell)).is_err() {
                return true;
            }
            // Some other corner must stay on the side the node leaves.
            (0..1usize << D).any(|other| {
                let idx: [usize; D] = std::array::from_fn(|a| cell[a] + (other >> a & 1));
                idx != node && inside(idx) != to_inside
            })
        })
    }

    /// The cell that has `node` as its corner number `corner` (bit a set:
    /// the node is the cell's upper corner along axis a), if in the grid.
    fn cell_at_corner(&self, node: [usize; D], corner: usize) -> Option<[usize; D]> {
        let mut cell = [0; D];
        for a in 0..D {
            let upper = corner >> a & 1;
            if node[a] < upper || node[a] - upper + 1 >= self.spec.dims[a] {
                return None;
            }
            cell[a] = node[a] - upper;
        }
        Some(cell)
    }
}

/// Neighbours of the plane fit that gives each point's normal.
const NORMAL_NEIGHBOURS: usize = 12;

/// A normal counts as oriented by the surface only if the surface's
/// gradient at the point is at least this close to it (cosine): at the tip
/// of a part thinner than a cell the gradient says nothing.
const MIN_ORIENTATION_COSINE: f64 = 0.5;

/// The points' tangent planes (12-neighbour plane fits) and a search tree
/// over the points: computed once, shared by every level's
/// [`TangentSides`].
pub struct PointPlanes {
    points: Vec<DVec3>,
    /// Unit normals of the plane fits (unoriented).
    planes: Vec<DVec3>,
    /// Each point's mean distance to its nearest others, which sets its
    /// share of the area ([`crate::holes::tangent_disks`]); from the plane
    /// fits' neighbour search, or empty (then searched when needed).
    spacing: Vec<f64>,
    tree: KdTree,
}

impl PointPlanes {
    /// `None` without points or in 2D (a plane fit there gives the plane's
    /// normal).
    pub fn new(points: &[DVec3], dim: usize) -> Option<Self> {
        if dim != 3 || points.is_empty() {
            return None;
        }
        // One neighbour search gives the planes and the spacing, the same
        // values bit for bit as two searches (with a full row of neighbours).
        let (planes, spacing) = if points.len() > NORMAL_NEIGHBOURS {
            estimate_normals_and_spacing(points, NORMAL_NEIGHBOURS, AREA_NEIGHBOURS)
        } else {
            (estimate_normals(points, NORMAL_NEIGHBOURS), Vec::new())
        };
        Some(PointPlanes {
            points: points.to_vec(),
            planes,
            spacing,
            tree: KdTree::new(points),
        })
    }

    /// One small triangle per point in its tangent plane, of its share of
    /// the area (see [`crate::holes::tangent_disks`]).
    pub fn surfels(&self) -> Vec<[DVec3; 3]> {
        self.disks(&self.planes)
    }

    /// The points' tangent disks in the planes of `normals`.
    fn disks(&self, normals: &[DVec3]) -> Vec<[DVec3; 3]> {
        if self.spacing.len() == self.points.len() {
            crate::holes::disks_of_spacing(&self.points, normals, &self.spacing)
        } else {
            crate::holes::tangent_disks(&self.points, normals, &self.tree)
        }
    }

    /// The points with the corners of their tangent disks (see
    /// [`crate::holes::tangent_disks`]) added for the points where
    /// `with_disk` holds (up to four times as many), in the planes of the
    /// given unit `normals` (one per point). Each corner keeps its point's
    /// fitted plane (the fits anchor thin parts better than the given
    /// normals: spikes CD 0.164 against 0.185‰).
    pub fn densified(&self, normals: &[DVec3], with_disk: &[bool]) -> Self {
        let corners = self.disks(normals);
        let points: Vec<DVec3> = self
            .points
            .iter()
            .copied()
            .chain(kept(&corners, with_disk).flatten())
            .collect();
        let tree = KdTree::new(&points);
        PointPlanes {
            points,
            planes: with_corners(&self.planes, with_disk),
            spacing: Vec::new(),
            tree,
        }
    }

    /// Whether each point's given unit normal agrees with those of at least
    /// [`AGREEING_NEIGHBOURS`] of its [`AGREEMENT_NEIGHBOURS`] nearest
    /// points (cosine ≥ [`AGREEMENT_COSINE`]). On a sampled surface nearly
    /// every point's does, beside a sharp edge with those of its own face;
    /// a stray point's normal says nothing of the surface it lies near.
    pub fn normals_agree(&self, normals: &[DVec3]) -> Vec<bool> {
        self.points
            .par_iter()
            .zip(normals)
            .map(|(&p, &n)| {
                let near = self.tree.knn(p, AGREEMENT_NEIGHBOURS + 1);
                let agreeing = near
                    .iter()
                    .filter(|x| normals[x.index].dot(n) >= AGREEMENT_COSINE)
                    .count();
                // The point itself is among its nearest.
                agreeing > AGREEING_NEIGHBOURS
            })
            .collect()
    }

    /// The points the planes were fitted to.
    pub fn points(&self) -> &[DVec3] {
        &self.points
    }
}

/// Per-point values followed by each repeated for the three disk corners
/// of the points where `with_disk` holds, in the order
/// [`PointPlanes::densified`] adds them.
pub(crate) fn with_corners(values: &[DVec3], with_disk: &[bool]) -> Vec<DVec3> {
    let repeated = values.iter().map(|&v| [v; 3]).collect::<Vec<_>>();
    values
        .iter()
        .copied()
        .chain(kept(&repeated, with_disk).flatten())
        .collect()
}

/// The items where `with_disk` holds.
fn kept<'a, T: Copy>(items: &'a [T], with_disk: &'a [bool]) -> impl Iterator<Item = T> + 'a {
    items
        .iter()
        .zip(with_disk)
        .filter(|(_, &k)| k)
        .map(|(&t, _)| t)
}

/// Neighbours whose given normals a point's is compared with, and how many
/// must agree, within about 26°, for its disk to be trusted
/// ([`PointPlanes::normals_agree`]): a random normal agrees with a given
/// one with probability 0.05, so with 3 of 8 about 0.6% of the time.
const AGREEMENT_NEIGHBOURS: usize = 8;
const AGREEING_NEIGHBOURS: usize = 3;
const AGREEMENT_COSINE: f64 = 0.9;

/// Oriented tangent planes of the points, for the side test.
pub struct TangentSides<'a> {
    fits: &'a PointPlanes,
    /// +1 / −1 where a plane's normal / its opposite points outward, 0
    /// where it is unknown.
    orientation: Vec<f64>,
    h: f64,
    /// Nodes farther than this from every point are not tested, nor
    /// nodes farther than `beside` from the nearest point's normal line.
    reach: f64,
    beside: f64,
    /// Answers of [`TangentSides::allows`] given so far, by the node's
    /// position and side: the flow's zero set jitters by a node at the
    /// data, and the same nodes ask again every step.
    answers: Mutex<FxHashMap<([u64; 3], bool), bool>>,
}

impl<'a> TangentSides<'a> {
    /// The planes of `fits`, oriented along the gradient of the current
    /// level set `band` (outward, φ negative inside).
    pub fn new<const D: usize>(
        fits: &'a PointPlanes,
        band: &NarrowBand<D>,
        reach: f64,
        beside: f64,
    ) -> Self {
        let spec = *band.spec();
        let h = spec.spacing;
        let phi =
            |p: DVec3| interpolate_with(&spec, |i| band.phi.get(i), std::array::from_fn(|a| p[a]));
        let orientation: Vec<f64> = fits
            .planes
            .par_iter()
            .zip(&fits.points)
            .map(|(&n, &p)| {
                let grad = DVec3::from_array(std::array::from_fn(|a| {
                    let step =
                        DVec3::from_array(std::array::from_fn(|b| if a == b { h } else { 0.0 }));
                    phi(p + step) - phi(p - step)
                }));
                let cos = grad.dot(n) / grad.length();
                if cos.abs() >= MIN_ORIENTATION_COSINE {
                    cos.signum()
                } else {
                    0.0
                }
            })
            .collect();
        TangentSides {
            fits,
            orientation,
            h,
            reach,
            beside,
            answers: Mutex::new(FxHashMap::default()),
        }
    }

    /// [`TangentSides::allows`] for every `(position, to_inside)` query,
    /// the answers not given before computed in parallel (the test reads
    /// only the position and fixed data, so a kept answer is the answer).
    pub fn allows_all(&self, queries: &[(DVec3, bool)]) -> Vec<bool> {
        let key = |&(p, to_inside): &(DVec3, bool)| (p.to_array().map(f64::to_bits), to_inside);
        let mut answers = self.answers.lock().unwrap_or_else(|e| e.into_inner());
        let known: Vec<Option<bool>> = queries
            .iter()
            .map(|q| answers.get(&key(q)).copied())
            .collect();
        let all: Vec<bool> = (queries.par_iter().zip(&known))
            .map(|(&(p, to_inside), known)| known.unwrap_or_else(|| self.allows(p, to_inside)))
            .collect();
        for ((q, known), &answer) in queries.iter().zip(&known).zip(&all) {
            if known.is_none() {
                answers.insert(key(q), answer);
            }
        }
        all
    }

    /// Whether a node at `position` may move to side `to_inside`: always
    /// beyond the reach or where the nearest point's normal is unknown;
    /// otherwise only to the side of that point's tangent plane it lies on.
    pub fn allows(&self, position: DVec3, to_inside: bool) -> bool {
        let Some(near) = self.fits.tree.nearest(position) else {
            return true;
        };
        if near.distance > self.reach {
            return true;
        }
        if !to_inside && self.between_faces(position, near.index) {
            return false;
        }
        let plane = self.fits.planes[near.index];
        let v = position - self.fits.points[near.index];
        let offset = v.dot(plane) * self.orientation[near.index];
        // Beside the data (over a hole, past a rim) the tangent plane says
        // nothing about sides.
        if (v - v.dot(plane) * plane).length() > self.beside || self.orientation[near.index] == 0.0
        {
            return true;
        }
        if to_inside {
            offset <= 0.0
        } else {
            offset >= 0.0
        }
    }

    /// Whether points within a cell of `position` lie on both sides of it
    /// across the plane of its nearest point `nearest`: the node is inside
    /// a part thinner than two cells, where the faces' orientations cannot
    /// be told apart and the part must keep its row of inside nodes.
    fn between_faces(&self, position: DVec3, nearest: usize) -> bool {
        let plane = self.fits.planes[nearest];
        let (mut below, mut above) = (false, false);
        // The nearest SANDWICH_NEIGHBOURS within a cell: when no more lie
        // within it, they are all the points within it (found much faster
        // than the nearest 16, which reach far beyond the cell). The
        // radius is padded so that the same distance test decides both.
        let mut near: Vec<Neighbour> = self.fits.tree.within(position, self.h * (1.0 + 1e-9));
        near.retain(|q| q.distance <= self.h);
        if near.len() > SANDWICH_NEIGHBOURS {
            near = self.fits.tree.knn(position, SANDWICH_NEIGHBOURS);
            near.retain(|q| q.distance <= self.h);
        }
        for q in near {
            let s = (self.fits.points[q.index] - position).dot(plane);
            below |= s < -SANDWICH_MARGIN * self.h;
            above |= s > SANDWICH_MARGIN * self.h;
        }
        below && above
    }
}

/// Points near a node checked for lying on both sides of it.
const SANDWICH_NEIGHBOURS: usize = 16;

/// Points count as on one side of a node only beyond this share of a cell
/// from its plane (noise and curvature in a flat neighbourhood stay below).
const SANDWICH_MARGIN: f64 = 0.1;

/// The cell holding world position `p` (lowest corner node), if in the grid.
fn cell_of<const D: usize>(spec: &GridSpec<D>, p: [f64; D]) -> Option<[usize; D]> {
    let g = spec.to_grid(p);
    let mut cell = [0; D];
    for a in 0..D {
        if !(g[a] >= 0.0 && g[a] <= (spec.dims[a] - 1) as f64) {
            return None;
        }
        cell[a] = (g[a].floor() as usize).min(spec.dims[a] - 2);
    }
    Some(cell)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> GridSpec<2> {
        GridSpec {
            origin: [0.0, 0.0],
            spacing: 1.0,
            dims: [5, 4],
        }
    }

    #[test]
    fn cells_are_found_and_deduplicated() {
        let pts = [
            DVec3::new(1.5, 2.5, 0.0),
            DVec3::new(1.2, 2.9, 0.0),
            DVec3::new(4.0, 3.0, 0.0),  // upper grid corner: last cell
            DVec3::new(-0.1, 1.0, 0.0), // outside
        ];
        let cells = DataCells::new(spec(), pts.into_iter());
        assert_eq!(cells.len(), 2);
        assert_eq!(
            cells.cells,
            vec![spec().linear([1, 2]), spec().linear([3, 2])]
        );
    }

    #[test]
    fn last_crossing_of_a_data_cell_is_kept() {
        let cells = DataCells::new(spec(), std::iter::once(DVec3::new(1.5, 1.5, 0.0)));
        // Cell (1,1) has corners (1,1), (2,1), (1,2), (2,2); only (2,2) inside.
        let inside = |i: [usize; 2]| i == [2, 2];
        assert!(!cells.allows([2, 2], false, inside), "last inside corner");
        assert!(cells.allows([1, 1], true, inside), "a second inside corner");
        // A node of no data cell may do anything.
        assert!(cells.allows([4, 0], false, inside));
        // All four inside: the cell is not crossed yet, so any corner may
        // leave; with three inside, the fourth may not join them.
        let all = |i: [usize; 2]| (1..=2).contains(&i[0]) && (1..=2).contains(&i[1]);
        assert!(cells.allows([1, 1], false, all));
        let three = |i: [usize; 2]| all(i) && i != [1, 1];
        assert!(
            !cells.allows([1, 1], true, three),
            "would close the crossing"
        );
    }
}
