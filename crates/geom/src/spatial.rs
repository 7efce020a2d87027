//! Spatial indexes shared by every method.
//!
//! - [`KdTree`]: k-nearest and radius queries; a thin wrapper over kiddo's
//!   immutable k-d tree (measured fastest here for both building and querying
//!   large scans).
//! - [`CellGrid`]: a uniform grid for many fixed-radius queries; on 1M
//!   surface points it builds about 3x faster than the k-d tree and answers
//!   radius queries about 1.4x faster when the cell size is the radius.

use glam::DVec3;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use std::num::NonZero;

type Tree = ImmutableKdTree<f64, u32, 3, 32>;

/// Immutable k-d tree over a fixed point set; query results index into it.
pub struct KdTree {
    tree: Tree,
    len: usize,
}

/// One query result: index into the indexed points and the distance to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neighbour {
    /// Position of the point in the slice the index was built from.
    pub index: usize,
    /// Euclidean distance from the query.
    pub distance: f64,
}

impl KdTree {
    /// Index `points` (which may contain duplicates; at most `u32::MAX`).
    pub fn new(points: &[DVec3]) -> Self {
        let coords: Vec<[f64; 3]> = points.iter().map(|p| p.to_array()).collect();
        KdTree {
            tree: Tree::new_from_slice(&coords),
            len: points.len(),
        }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no point is indexed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest indexed point, or `None` for an empty tree.
    pub fn nearest(&self, q: DVec3) -> Option<Neighbour> {
        if self.len == 0 {
            return None;
        }
        let n = self.tree.nearest_one::<SquaredEuclidean>(&q.to_array());
        Some(Neighbour {
            index: n.item as usize,
            distance: n.distance.sqrt(),
        })
    }

    /// The `k` nearest points, closest first (fewer if the tree is smaller).
    pub fn knn(&self, q: DVec3, k: usize) -> Vec<Neighbour> {
        let k = k.min(self.len);
        let Some(k) = NonZero::new(k) else {
            return Vec::new();
        };
        self.tree
            .nearest_n::<SquaredEuclidean>(&q.to_array(), k)
            .into_iter()
            .map(|n| Neighbour {
                index: n.item as usize,
                distance: n.distance.sqrt(),
            })
            .collect()
    }

    /// All points within distance `r` of `q`, in no particular order.
    pub fn within(&self, q: DVec3, r: f64) -> Vec<Neighbour> {
        self.tree
            .within_unsorted::<SquaredEuclidean>(&q.to_array(), r * r)
            .into_iter()
            .map(|n| Neighbour {
                index: n.item as usize,
                distance: n.distance.sqrt(),
            })
            .collect()
    }
}

/// Uniform grid of cubic cells with the points stored in cell order: for
/// many fixed-radius queries ([`CellGrid::within`]) it builds several times
/// faster than a k-d tree and answers about as fast when the radius is close
/// to the cell size (see the `spatial` benchmark). Results are exact for any
/// radius; the cell size only affects speed.
pub struct CellGrid {
    origin: DVec3,
    cell: f64,
    dims: [usize; 3],
    /// Points of cell c are `sorted[starts[c]..starts[c + 1]]`.
    starts: Vec<u32>,
    sorted: Vec<DVec3>,
    /// Input index of each entry of `sorted`.
    indices: Vec<u32>,
}

/// Cells per point allowed before the cell size is enlarged (keeps memory
/// proportional to the points for a too-small `cell_size`).
const MAX_CELLS_PER_POINT: usize = 8;

impl CellGrid {
    /// Index `points` (finite, at most `u32::MAX`) in cells of about
    /// `cell_size` (a good choice is the query radius). A non-positive or
    /// non-finite size, or one that would need more than 8 cells per point
    /// (+ 4096), is enlarged: queries stay exact.
    pub fn new(points: &[DVec3], cell_size: f64) -> Self {
        let bounds = crate::Aabb::from_points(points);
        let extent = if bounds.is_empty() {
            DVec3::ZERO
        } else {
            bounds.size()
        };
        let budget = (MAX_CELLS_PER_POINT * points.len() + 4096) as f64;
        let mut cell = if cell_size > 0.0 && cell_size.is_finite() {
            cell_size
        } else {
            f64::INFINITY
        };
        // Smallest cell with at most `budget` cells (a cube root bound).
        let volume_cell = ((extent.x + extent.y + extent.z) / budget.cbrt()).max(f64::MIN_POSITIVE);
        if ((extent / cell).floor() + DVec3::ONE).element_product() > budget {
            cell = cell.max(volume_cell);
        }
        if !cell.is_finite() {
            cell = extent.max_element().max(1.0);
        }
        let dims = ((extent / cell).floor() + DVec3::ONE)
            .to_array()
            .map(|d| (d as usize).max(1));
        let origin = if bounds.is_empty() {
            DVec3::ZERO
        } else {
            bounds.min
        };
        let mut grid = CellGrid {
            origin,
            cell,
            dims,
            starts: Vec::new(),
            sorted: Vec::new(),
            indices: Vec::new(),
        };
        grid.fill(points);
        grid
    }

    /// Counting sort of the points into their cells.
    fn fill(&mut self, points: &[DVec3]) {
        let cells = self.dims.iter().product::<usize>();
        let ids: Vec<u32> = points.iter().map(|&p| self.cell_of(p) as u32).collect();
        let mut starts = vec![0u32; cells + 1];
        for &c in &ids {
            starts[c as usize + 1] += 1;
        }
        for c in 0..cells {
            starts[c + 1] += starts[c];
        }
        let mut fill = starts[..cells].to_vec();
        self.sorted = vec![DVec3::ZERO; points.len()];
        self.indices = vec![0; points.len()];
        for (i, (&c, &p)) in ids.iter().zip(points).enumerate() {
            let slot = fill[c as usize] as usize;
            self.sorted[slot] = p;
            self.indices[slot] = i as u32;
            fill[c as usize] += 1;
        }
        self.starts = starts;
    }

    /// Cell coordinate of `x` along `axis`, clamped into the grid.
    fn coord(&self, x: f64, axis: usize) -> usize {
        let c = ((x - self.origin[axis]) / self.cell).floor();
        // `as` maps NaN to 0 and saturates; the clamp keeps it in range.
        (c.max(0.0) as usize).min(self.dims[axis] - 1)
    }

    fn cell_of(&self, p: DVec3) -> usize {
        let [x, y, z] = [0, 1, 2].map(|a| self.coord(p[a], a));
        (z * self.dims[1] + y) * self.dims[0] + x
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.sorted.len()
    }

    /// Whether no point is indexed.
    pub fn is_empty(&self) -> bool {
        self.sorted.is_empty()
    }

    /// Calls `visit` for every point within distance `r` of `q`, in cell
    /// order (no allocation).
    pub fn for_each_within(&self, q: DVec3, r: f64, mut visit: impl FnMut(Neighbour)) {
        if self.sorted.is_empty() || r.is_nan() || r < 0.0 {
            return;
        }
        let lo = [0, 1, 2].map(|a| self.coord(q[a] - r, a));
        let hi = [0, 1, 2].map(|a| self.coord(q[a] + r, a));
        let r2 = r * r;
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                let row = (z * self.dims[1] + y) * self.dims[0];
                // Cells x0..=x1 of one row are contiguous in `sorted`.
                let start = self.starts[row + lo[0]] as usize;
                let end = self.starts[row + hi[0] + 1] as usize;
                for slot in start..end {
                    let d2 = self.sorted[slot].distance_squared(q);
                    if d2 <= r2 {
                        visit(Neighbour {
                            index: self.indices[slot] as usize,
                            distance: d2.sqrt(),
                        });
                    }
                }
            }
        }
    }

    /// All points within distance `r` of `q`, in no particular order.
    pub fn within(&self, q: DVec3, r: f64) -> Vec<Neighbour> {
        let mut out = Vec::new();
        self.for_each_within(q, r, |n| out.push(n));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_points(n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()))
            .collect()
    }

    #[test]
    fn knn_and_radius_match_brute_force() {
        let pts = random_points(2000, 1);
        let tree = KdTree::new(&pts);
        for q in random_points(50, 2) {
            let mut brute: Vec<(f64, usize)> = pts
                .iter()
                .enumerate()
                .map(|(i, p)| (p.distance(q), i))
                .collect();
            brute.sort_by(|a, b| a.0.total_cmp(&b.0));
            let knn = tree.knn(q, 8);
            for (n, b) in knn.iter().zip(&brute) {
                assert!((n.distance - b.0).abs() < 1e-12);
            }
            assert_eq!(tree.nearest(q).unwrap().distance, brute[0].0);
            let r = 0.1;
            let mut within: Vec<usize> = tree.within(q, r).iter().map(|n| n.index).collect();
            within.sort();
            let mut expect: Vec<usize> = brute.iter().filter(|b| b.0 <= r).map(|b| b.1).collect();
            expect.sort();
            assert_eq!(within, expect);
        }
    }

    #[test]
    fn empty_tree_answers_nothing() {
        let tree = KdTree::new(&[]);
        assert!(tree.nearest(DVec3::ZERO).is_none());
        assert!(tree.knn(DVec3::ZERO, 3).is_empty());
    }

    #[test]
    fn cell_grid_radius_queries_match_brute_force() {
        let pts = random_points(3000, 3);
        for cell in [0.05, 0.2, 1e-9, 0.0, f64::NAN, 10.0] {
            let grid = CellGrid::new(&pts, cell);
            assert_eq!(grid.len(), pts.len());
            assert!(
                grid.dims.iter().product::<usize>() <= 8 * 3000 + 4096 + 1,
                "{cell}"
            );
            for q in random_points(40, 4) {
                let q = 1.4 * q - DVec3::splat(0.2); // some outside the bounds
                for r in [0.0, 0.03, 0.1, 0.5, 3.0] {
                    let mut got: Vec<(usize, f64)> = grid
                        .within(q, r)
                        .iter()
                        .map(|n| (n.index, n.distance))
                        .collect();
                    got.sort_by_key(|g| g.0);
                    let expect: Vec<(usize, f64)> = pts
                        .iter()
                        .enumerate()
                        .filter(|(_, p)| p.distance(q) <= r)
                        .map(|(i, p)| (i, p.distance(q)))
                        .collect();
                    assert_eq!(got.len(), expect.len(), "cell {cell} r {r}");
                    for (g, e) in got.iter().zip(&expect) {
                        assert_eq!(g.0, e.0);
                        assert!((g.1 - e.1).abs() < 1e-12);
                    }
                }
            }
        }
    }

    #[test]
    fn cell_grid_handles_empty_and_flat_input() {
        let empty = CellGrid::new(&[], 0.1);
        assert!(empty.is_empty() && empty.within(DVec3::ZERO, 1.0).is_empty());
        let same = vec![DVec3::ONE; 5];
        let grid = CellGrid::new(&same, 0.1);
        assert_eq!(grid.within(DVec3::ONE, 0.0).len(), 5);
        assert!(grid.within(DVec3::ONE, f64::NAN).is_empty());
        assert!(grid.within(DVec3::ONE, -1.0).is_empty());
        let line: Vec<DVec3> = (0..100).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect();
        let grid = CellGrid::new(&line, 1e-6);
        assert_eq!(grid.within(DVec3::new(50.2, 0.0, 0.0), 1.5).len(), 3);
    }
}
