//! Offset distance field (ODF): one sample per grid node, each free to
//! float within its own cell (the box of half a spacing around its node),
//! so that samples can sit on the corners and edges a regular grid cuts.
//!
//! Samples start on their nodes with the regular signed distances. The
//! samples around cells crossed by sharp features then move to minimize
//!   E = λ_d E_dist + λ_s Σ_edges (1 − |g_i − g_j| / h)² + λ_o Σ (ê_i · ê_j)²
//! where E_dist sums, over each feature element (corner, bend, edge piece)
//! in a cell, the squared distance to the nearest vertex marching cubes
//! puts in that cell (in units of h²), the spring term keeps grid edges
//! near their rest length h and the orthogonality term keeps the edges at
//! a sample (and at its neighbours) perpendicular. The search is the
//! paper's: per sample try ±x, ±y, ±z steps (plus a jump onto a feature
//! point in reach), take the best legal move, halve the step each round.
//! A move is legal when the sample stays in its box and every cell around
//! it stays convex. Samples of the same index parity share no cell and no
//! energy term, so each parity class moves in parallel and the result
//! does not depend on the thread count.

use crate::extract::{corner_nodes, extract, ExtractReport, SampledField};
use crate::features::{cells_with_features, CellFeatures, Features};
use crate::query::MeshQuery;
use crate::unified::BAND_CELLS;
use crate::{check_mesh, grid_for, DistFieldError};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::time::Instant;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::marching::tables::EDGE_CORNERS;
use surfrecon_grid::marching::crossing_fraction;
use surfrecon_grid::sdf::signed_distance;
use surfrecon_grid::{GridSize, GridSpec};

/// The weights of the three energy terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    pub distance: f64,
    pub spring: f64,
    pub ortho: f64,
}

impl Default for Weights {
    fn default() -> Self {
        Self { distance: 1.0, spring: 0.1, ortho: 0.1 }
    }
}

/// How to build an offset field.
#[derive(Debug, Clone, Copy)]
pub struct OdfOptions {
    pub size: GridSize,
    pub padding: usize,
    pub feature_angle_deg: f64,
    pub weights: Weights,
    /// Rounds of the search; the step halves every round from h/4.
    pub iterations: usize,
}

impl Default for OdfOptions {
    fn default() -> Self {
        Self {
            size: GridSize::Resolution(64),
            padding: 2,
            feature_angle_deg: crate::features::DEFAULT_FEATURE_ANGLE_DEG,
            weights: Weights::default(),
            iterations: 8,
        }
    }
}

/// An offset distance field.
#[derive(Debug, Clone, PartialEq)]
pub struct OffsetField {
    pub spec: GridSpec<3>,
    /// Signed distance at each sample's position (negative inside).
    pub values: Vec<f64>,
    /// Positions of the samples that moved off their nodes.
    pub moved: BTreeMap<u32, DVec3>,
}

/// What building an offset field did.
#[derive(Debug, Clone, Copy, Default)]
pub struct OdfReport {
    pub samples: usize,
    pub feature_cells: usize,
    /// Samples the search considered.
    pub candidates: usize,
    pub moved: usize,
    /// Samples moved by Laplacian smoothing away from the surface.
    pub smoothed: usize,
    /// Total energy of the feature cells before and after.
    pub energy_before: f64,
    pub energy_after: f64,
    pub seconds: f64,
}

/// Build the offset field of a closed, outward-oriented mesh.
pub fn build_odf(mesh: &TriMesh, options: &OdfOptions) -> Result<(OffsetField, OdfReport), DistFieldError> {
    let start = Instant::now();
    check_mesh(mesh)?;
    let w = options.weights;
    if ![w.distance, w.spring, w.ortho].iter().all(|x| x.is_finite() && *x >= 0.0) {
        return Err(DistFieldError::InvalidOption(format!("energy weights must be finite and at least 0: {w:?}")));
    }
    let spec = grid_for(mesh, options.size, options.padding)?;
    let values = signed_distance(mesh, &spec, Some(BAND_CELLS * spec.spacing))?.values;
    let query = MeshQuery::new(mesh)?;
    let features = Features::detect(mesh, options.feature_angle_deg);
    let cells = cells_with_features(mesh, &features, &spec, |_| true);
    let mut field = OffsetField { spec, values, moved: BTreeMap::new() };
    let search = Search { spec: &spec, query: &query, cells: &cells, weights: w };
    let candidates = search.candidates();
    let mut report = OdfReport {
        samples: field.values.len(),
        feature_cells: cells.len(),
        candidates: candidates.len(),
        energy_before: search.total_energy(&field),
        ..Default::default()
    };
    let mut step = 0.25 * field.spec.spacing;
    for _ in 0..options.iterations {
        search.round(&mut field, &candidates, step);
        step *= 0.5;
    }
    report.smoothed = search.smooth_away_from_surface(&mut field);
    report.moved = field.moved.len();
    report.energy_after = search.total_energy(&field);
    report.seconds = start.elapsed().as_secs_f64();
    Ok((field, report))
}

impl OffsetField {
    /// Where sample `node` sits.
    pub fn position_of(&self, node: usize) -> DVec3 {
        self.moved
            .get(&(node as u32))
            .copied()
            .unwrap_or_else(|| node_position(&self.spec, node))
    }

    /// The surface: marching cubes on the offset grid.
    pub fn extract(&self) -> (TriMesh, ExtractReport) {
        extract(self, &BTreeMap::new())
    }
}

impl SampledField for OffsetField {
    fn spec(&self) -> &GridSpec<3> {
        &self.spec
    }
    fn value(&self, node: usize) -> f64 {
        self.values[node]
    }
    fn position(&self, node: usize) -> DVec3 {
        self.position_of(node)
    }
}

pub(crate) fn node_position(spec: &GridSpec<3>, node: usize) -> DVec3 {
    DVec3::from_array(spec.position(spec.unlinear(node)))
}

/// Smallest triple product of a cell corner's edges, in h³, for a cell to
/// count as convex (regular cells have 1).
const MIN_CORNER_VOLUME: f64 = 0.1;
/// Energy of a feature element whose cell has no crossing yet, plus its
/// squared distance (h²) to the nearest sample, which draws a sample onto
/// it until the surface crosses the cell.
const UNREACHED: f64 = 1.0;

/// The energy minimization over a field's samples.
pub(crate) struct Search<'a> {
    pub spec: &'a GridSpec<3>,
    pub query: &'a MeshQuery,
    pub cells: &'a BTreeMap<usize, CellFeatures>,
    pub weights: Weights,
}

/// Read and write access to samples that may move.
pub(crate) trait Movable: Sync {
    fn value(&self, node: usize) -> f64;
    fn position(&self, node: usize) -> DVec3;
    fn set(&mut self, node: usize, position: DVec3, value: f64);
}

impl Movable for OffsetField {
    fn value(&self, node: usize) -> f64 {
        self.values[node]
    }
    fn position(&self, node: usize) -> DVec3 {
        self.position_of(node)
    }
    fn set(&mut self, node: usize, position: DVec3, value: f64) {
        self.values[node] = value;
        if position == node_position(&self.spec, node) {
            self.moved.remove(&(node as u32));
        } else {
            self.moved.insert(node as u32, position);
        }
    }
}

impl Search<'_> {
    /// The samples at the corners of feature cells, sorted.
    pub fn candidates(&self) -> Vec<usize> {
        let set: BTreeSet<usize> = self.cells.keys().flat_map(|&c| corner_nodes(self.spec, c)).collect();
        set.into_iter().filter(|&n| self.interior(n)).collect()
    }

    /// Samples not on the grid's outer layer (those have incomplete cells).
    fn interior(&self, node: usize) -> bool {
        let idx = self.spec.unlinear(node);
        (0..3).all(|a| idx[a] > 0 && idx[a] + 1 < self.spec.dims[a])
    }

    /// One round over the candidates, parity class by parity class.
    pub fn round(&self, field: &mut impl Movable, candidates: &[usize], step: f64) {
        for class in 0..8 {
            let moves: Vec<(usize, DVec3, f64)> = candidates
                .par_iter()
                .filter(|&&n| parity(self.spec, n) == class)
                .filter_map(|&n| self.best_move(&*field, n, step))
                .collect();
            for (n, p, v) in moves {
                field.set(n, p, v);
            }
        }
    }

    /// The best legal move of sample `node` that lowers its energy.
    fn best_move(&self, field: &impl Movable, node: usize, step: f64) -> Option<(usize, DVec3, f64)> {
        let here = field.position(node);
        let current = self.local_energy(field, node, here, field.value(node));
        let mut tries: Vec<DVec3> = (0..6)
            .map(|k| {
                let mut d = DVec3::ZERO;
                d[k / 2] = if k % 2 == 0 { step } else { -step };
                here + d
            })
            .collect();
        tries.extend(self.feature_points_near(node));
        let home = node_position(self.spec, node);
        let reach = 0.5 * self.spec.spacing * (1.0 - 1e-9);
        tries
            .into_iter()
            .filter(|p| (*p - home).abs().max_element() <= reach)
            .filter(|&p| self.stays_convex(field, node, p))
            .map(|p| {
                let v = self.query.signed_distance(p);
                (p, v, self.local_energy(field, node, p, v))
            })
            .filter(|&(_, _, e)| e < current - 1e-12)
            .min_by(|a, b| a.2.total_cmp(&b.2))
            .map(|(p, v, _)| (node, p, v))
    }

    /// Corners and bends in the cells around `node`.
    fn feature_points_near(&self, node: usize) -> Vec<DVec3> {
        self.cells_around(node)
            .filter_map(|c| self.cells.get(&c))
            .flat_map(|f| f.corners.iter().chain(&f.bends).copied())
            .collect()
    }

    /// The (up to eight) cells that have `node` as a corner.
    fn cells_around(&self, node: usize) -> impl Iterator<Item = usize> + '_ {
        let idx = self.spec.unlinear(node);
        (0..8).filter_map(move |c: usize| {
            let mut cell = idx;
            for a in 0..3 {
                if (c >> a) & 1 == 1 {
                    cell[a] = cell[a].checked_sub(1)?;
                }
                if cell[a] + 1 >= self.spec.dims[a] {
                    return None;
                }
            }
            Some(self.spec.linear(cell))
        })
    }

    /// Energy terms that change when `node` moves to `p` with value `v`.
    fn local_energy(&self, field: &impl Movable, node: usize, p: DVec3, v: f64) -> f64 {
        let at = |n: usize| if n == node { (p, v) } else { (field.position(n), field.value(n)) };
        let h = self.spec.spacing;
        let distance: f64 = self.cells_around(node).map(|c| self.cell_energy(c, &at)).sum();
        let neighbours = self.neighbours(node);
        let spring: f64 = neighbours
            .iter()
            .flatten()
            .map(|&n| (1.0 - at(n).0.distance(p) / h).powi(2))
            .sum();
        let mut ortho = 0.0;
        // Perpendicular edge pairs at the sample, then at each neighbour
        // the edge back to the sample against the neighbour's other edges.
        let edge = |from: usize, to: usize| (at(to).0 - at(from).0).normalize_or_zero();
        for a in 0..6 {
            for b in (a + 1)..6 {
                if a / 2 != b / 2 {
                    if let (Some(na), Some(nb)) = (neighbours[a], neighbours[b]) {
                        ortho += edge(node, na).dot(edge(node, nb)).powi(2);
                    }
                }
            }
        }
        for (a, n) in neighbours.iter().enumerate() {
            let Some(n) = *n else { continue };
            let back = edge(n, node);
            for (b, m) in self.neighbours(n).iter().enumerate() {
                if let Some(m) = *m {
                    if b / 2 != a / 2 {
                        ortho += back.dot(edge(n, m)).powi(2);
                    }
                }
            }
        }
        self.weights.distance * distance + self.weights.spring * spring + self.weights.ortho * ortho
    }

    /// The six axis neighbours (−x, +x, −y, +y, −z, +z), where they exist.
    fn neighbours(&self, node: usize) -> [Option<usize>; 6] {
        let idx = self.spec.unlinear(node);
        let strides = self.spec.strides();
        std::array::from_fn(|k| {
            let a = k / 2;
            if k % 2 == 0 {
                (idx[a] > 0).then(|| node - strides[a])
            } else {
                (idx[a] + 1 < self.spec.dims[a]).then(|| node + strides[a])
            }
        })
    }

    /// E_dist of one cell, in h²: per feature element, the squared
    /// distance to the nearest crossing of the cell.
    fn cell_energy(&self, cell: usize, at: &impl Fn(usize) -> (DVec3, f64)) -> f64 {
        let Some(features) = self.cells.get(&cell) else {
            return 0.0;
        };
        let corners = corner_nodes(self.spec, cell).map(at);
        let crossings: Vec<DVec3> = EDGE_CORNERS
            .iter()
            .filter_map(|&[a, b]| {
                let ((pa, va), (pb, vb)) = (corners[a as usize], corners[b as usize]);
                ((va >= 0.0) != (vb >= 0.0)).then(|| pa.lerp(pb, crossing_fraction(va, vb, 0.0)))
            })
            .collect();
        let h2 = self.spec.spacing * self.spec.spacing;
        let nearest = |d2: &dyn Fn(DVec3) -> f64| -> f64 {
            if crossings.is_empty() {
                UNREACHED + corners.iter().map(|&(p, _)| d2(p)).fold(f64::INFINITY, f64::min) / h2
            } else {
                crossings.iter().map(|&x| d2(x)).fold(f64::INFINITY, f64::min) / h2
            }
        };
        let points = features.corners.iter().chain(&features.bends);
        let e_points: f64 = points.map(|&f| nearest(&|x| x.distance_squared(f))).sum();
        let e_pieces: f64 = features
            .pieces
            .iter()
            .map(|&[a, b]| nearest(&|x| x.distance_squared(crate::features::closest_on_segment(x, a, b))))
            .sum();
        e_points + e_pieces
    }

    /// Whether every cell around `node` stays convex with `node` at `p`.
    fn stays_convex(&self, field: &impl Movable, node: usize, p: DVec3) -> bool {
        let h3 = self.spec.spacing.powi(3);
        self.cells_around(node).all(|cell| {
            let pos = corner_nodes(self.spec, cell).map(|n| if n == node { p } else { field.position(n) });
            (0..8).all(|c: usize| {
                let e = [1, 2, 4].map(|bit| pos[c ^ bit] - pos[c]);
                let sign = if c.count_ones() % 2 == 0 { 1.0 } else { -1.0 };
                sign * e[0].cross(e[1]).dot(e[2]) > MIN_CORNER_VOLUME * h3
            })
        })
    }

    /// Total E_dist over the feature cells.
    pub fn total_energy(&self, field: &impl Movable) -> f64 {
        let at = |n: usize| (field.position(n), field.value(n));
        self.cells.keys().map(|&c| self.cell_energy(c, &at)).sum()
    }

    /// Laplacian smoothing of the samples next to moved ones whose cells
    /// the surface does not cross: each goes to the mean of its cells'
    /// centres (kept in its box and legal). Returns how many moved.
    pub fn smooth_away_from_surface(&self, field: &mut OffsetField) -> usize {
        let moved: Vec<usize> = field.moved.keys().map(|&n| n as usize).collect();
        let mut ring: BTreeSet<usize> = BTreeSet::new();
        for n in moved {
            ring.extend(self.neighbours(n).into_iter().flatten().filter(|&m| self.interior(m)));
        }
        let crossing = |f: &OffsetField, cell: usize| {
            let inside = corner_nodes(self.spec, cell).map(|c| f.values[c] < 0.0);
            inside.iter().any(|&s| s) && inside.iter().any(|&s| !s)
        };
        let mut count = 0;
        for n in ring {
            if field.moved.contains_key(&(n as u32)) || self.cells_around(n).any(|c| crossing(field, c)) {
                continue;
            }
            let centres: Vec<DVec3> = self
                .cells_around(n)
                .map(|c| corner_nodes(self.spec, c).map(|m| field.position_of(m)).iter().sum::<DVec3>() / 8.0)
                .collect();
            let home = node_position(self.spec, n);
            let reach = DVec3::splat(0.5 * self.spec.spacing * (1.0 - 1e-9));
            let target = (centres.iter().sum::<DVec3>() / centres.len() as f64).clamp(home - reach, home + reach);
            if target != home && self.stays_convex(&*field, n, target) {
                let v = self.query.signed_distance(target);
                if (v >= 0.0) == (field.values[n] >= 0.0) {
                    field.set(n, target, v);
                    count += 1;
                }
            }
        }
        count
    }
}

/// Parity class (0..8) of a node's index: nodes of one class share no cell.
fn parity(spec: &GridSpec<3>, node: usize) -> usize {
    let idx = spec.unlinear(node);
    (idx[0] & 1) | (idx[1] & 1) << 1 | (idx[2] & 1) << 2
}
