//! Sharp features of a mesh and the grid cells they pass through.
//!
//! A feature edge is a mesh edge whose two faces' normals differ by more
//! than the feature angle (so a flat or gently curved surface has none); a
//! corner is a vertex where more than two feature edges meet. Distance
//! fields keep these by storing points on them per cell ([`crate::unified`])
//! or by moving samples onto them ([`crate::offset`]).

use std::collections::{BTreeMap, HashMap};
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::GridSpec;

/// Default angle between face normals above which an edge is sharp.
pub const DEFAULT_FEATURE_ANGLE_DEG: f64 = 30.0;

/// The sharp edges and corners of a closed mesh.
#[derive(Debug, Clone, Default)]
pub struct Features {
    /// Feature edges as vertex pairs, lower index first, sorted.
    pub edges: Vec<[u32; 2]>,
    /// Vertices where more than two feature edges meet, sorted.
    pub corners: Vec<u32>,
}

impl Features {
    /// Edges of `mesh` whose faces' normals differ by more than
    /// `angle_deg`, and the corners where more than two of them meet.
    pub fn detect(mesh: &TriMesh, angle_deg: f64) -> Self {
        let cos_limit = angle_deg.to_radians().cos();
        let normals: Vec<DVec3> = (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect();
        let mut faces: HashMap<[u32; 2], Vec<usize>> = HashMap::new();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                faces.entry([a.min(b), a.max(b)]).or_default().push(t);
            }
        }
        let mut edges: Vec<[u32; 2]> = faces
            .into_iter()
            .filter(|(_, f)| f.len() == 2 && normals[f[0]].dot(normals[f[1]]) < cos_limit)
            .map(|(e, _)| e)
            .collect();
        edges.sort_unstable();
        let mut degree: BTreeMap<u32, usize> = BTreeMap::new();
        for e in &edges {
            for &v in e {
                *degree.entry(v).or_default() += 1;
            }
        }
        let corners = degree
            .into_iter()
            .filter(|&(_, d)| d > 2)
            .map(|(v, _)| v)
            .collect();
        Self { edges, corners }
    }
}

/// What the features leave in one grid cell.
#[derive(Debug, Clone, Default)]
pub struct CellFeatures {
    /// Corners inside the cell.
    pub corners: Vec<DVec3>,
    /// Corners in a cell next to this one that the surface enters
    /// without changing any sample's sign (so no patch of their own
    /// reaches them), within half a cell of this one.
    pub near_corners: Vec<DVec3>,
    /// Feature-line vertices (bends) inside the cell that are not corners.
    pub bends: Vec<DVec3>,
    /// Pieces of feature edges clipped to the cell.
    pub pieces: Vec<[DVec3; 2]>,
}

impl CellFeatures {
    /// Points that could stand for the features of this cell, best first:
    /// its corners, then its bends, then points along its feature edge
    /// pieces, nearest first to the projection of `centroid` (the mean of
    /// the cell's surface crossings: Ju et al.'s mass point, whose
    /// projection minimizes the crossings' quadric along a straight edge).
    pub fn candidates(&self, centroid: DVec3) -> Vec<DVec3> {
        let mut along: Vec<(f64, DVec3)> = Vec::new();
        for &[a, b] in &self.pieces {
            let best = closest_on_segment(centroid, a, b);
            along.push((0.0, best));
            for k in 0..=PIECE_SAMPLES {
                let p = a.lerp(b, k as f64 / PIECE_SAMPLES as f64);
                along.push((p.distance(best), p));
            }
        }
        along.sort_by(|x, y| x.0.total_cmp(&y.0));
        self.corners
            .iter()
            .chain(&self.bends)
            .copied()
            .chain(along.into_iter().map(|(_, p)| p))
            .collect()
    }
}

impl CellFeatures {
    /// How many separate feature lines cross the cell: chains of pieces
    /// joined end to end.
    pub fn lines(&self) -> usize {
        let n = self.pieces.len();
        let mut chain: Vec<usize> = (0..n).collect();
        fn root(chain: &mut [usize], mut i: usize) -> usize {
            while chain[i] != i {
                chain[i] = chain[chain[i]];
                i = chain[i];
            }
            i
        }
        for i in 0..n {
            for j in i + 1..n {
                let [a, b] = self.pieces[i];
                let [c, d] = self.pieces[j];
                if a == c || a == d || b == c || b == d {
                    let (ri, rj) = (root(&mut chain, i), root(&mut chain, j));
                    chain[ri] = rj;
                }
            }
        }
        (0..n).filter(|&i| root(&mut chain, i) == i).count()
    }

    /// Points on the cell's features: its corners and bends, and points
    /// along each piece of feature edge, ends included.
    pub fn probes(&self) -> Vec<DVec3> {
        let along = self.pieces.iter().flat_map(|&[a, b]| {
            (0..=PROBES_PER_PIECE).map(move |k| a.lerp(b, k as f64 / PROBES_PER_PIECE as f64))
        });
        self.corners
            .iter()
            .chain(&self.bends)
            .copied()
            .chain(along)
            .collect()
    }
}

/// Intervals along a feature edge piece at which [`CellFeatures::probes`]
/// samples it.
const PROBES_PER_PIECE: usize = 4;

/// Points tried along each feature edge piece (besides the projection of
/// the crossings' mean) when looking for a feature point that fans well.
const PIECE_SAMPLES: usize = 8;

/// The features of `mesh` binned into the cells of `spec` (keyed by the
/// linear index of each cell's lowest node). A corner or bend on a cell
/// face belongs to several cells; it goes to the first for which
/// `has_surface` holds (the surface must cross a cell for it to be kept).
pub fn cells_with_features(
    mesh: &TriMesh,
    features: &Features,
    spec: &GridSpec<3>,
    has_surface: impl Fn(usize) -> bool,
) -> BTreeMap<usize, CellFeatures> {
    let mut cells: BTreeMap<usize, CellFeatures> = BTreeMap::new();
    let corner_set: std::collections::HashSet<u32> = features.corners.iter().copied().collect();
    let mut bends: Vec<u32> = features.edges.iter().flatten().copied().collect();
    bends.sort_unstable();
    bends.dedup();
    for v in bends {
        let p = mesh.vertices[v as usize];
        if let Some(cell) = cells_containing(spec, p)
            .into_iter()
            .find(|&c| has_surface(c))
        {
            let entry = cells.entry(cell).or_default();
            if corner_set.contains(&v) {
                entry.corners.push(p);
            } else {
                entry.bends.push(p);
            }
        } else if corner_set.contains(&v) {
            for cell in cells_near(spec, p, 0.5 * spec.spacing) {
                if has_surface(cell) {
                    cells.entry(cell).or_default().near_corners.push(p);
                }
            }
        }
    }
    for &[a, b] in &features.edges {
        let (a, b) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
        for (cell, piece) in clip_to_cells(spec, a, b) {
            cells.entry(cell).or_default().pieces.push(piece);
        }
    }
    cells
}

/// The cells whose closed boxes contain `p` (one, or up to eight when it
/// lies on cell faces), in index order.
fn cells_containing(spec: &GridSpec<3>, p: DVec3) -> Vec<usize> {
    let g = spec.to_grid(p.to_array());
    let options: [Vec<usize>; 3] = std::array::from_fn(|a| {
        let f = g[a].floor();
        let mut out = Vec::new();
        for i in [f - 1.0, f] {
            let on_face = i == f || (i == f - 1.0 && g[a] == f);
            if on_face && i >= 0.0 && (i as usize) + 1 < spec.dims[a] {
                out.push(i as usize);
            }
        }
        out
    });
    let mut cells = Vec::new();
    for &k in &options[2] {
        for &j in &options[1] {
            for &i in &options[0] {
                cells.push(spec.linear([i, j, k]));
            }
        }
    }
    cells
}

/// The cells whose boxes lie within `reach` of `p` (in every axis).
fn cells_near(spec: &GridSpec<3>, p: DVec3, reach: f64) -> Vec<usize> {
    let lo = spec.to_grid((p - DVec3::splat(reach)).to_array());
    let hi = spec.to_grid((p + DVec3::splat(reach)).to_array());
    let range = |a: usize| {
        let first = lo[a].floor().max(0.0) as usize;
        let last = (hi[a].floor().max(0.0) as usize).min(spec.dims[a].saturating_sub(2));
        first..=last
    };
    let mut out = Vec::new();
    for k in range(2) {
        for j in range(1) {
            for i in range(0) {
                out.push(spec.linear([i, j, k]));
            }
        }
    }
    out
}

/// `p` moved just inside cell `cell` (by 1e-7 of a spacing at most), so
/// that [`cell_of`] finds that cell even for points on its faces.
pub fn nudge_into(spec: &GridSpec<3>, cell: usize, p: DVec3) -> DVec3 {
    let lo = DVec3::from_array(spec.position(spec.unlinear(cell)));
    let margin = 1e-7 * spec.spacing;
    p.clamp(lo + margin, lo + DVec3::splat(spec.spacing - margin))
}

/// The cell (lowest node's linear index) containing `p`, if any.
pub fn cell_of(spec: &GridSpec<3>, p: DVec3) -> Option<usize> {
    let g = spec.to_grid(p.to_array());
    let mut idx = [0usize; 3];
    for a in 0..3 {
        let i = g[a].floor();
        if !(i >= 0.0 && (i as usize) + 1 < spec.dims[a]) {
            return None;
        }
        idx[a] = i as usize;
    }
    Some(spec.linear(idx))
}

/// `points` binned by the cell containing them; in cells holding more
/// than `keep_up_to`, at most one per `1/per_spacing`-th of a cell along
/// each axis (the first one met). A mesh much finer than the grid would
/// otherwise give each error measurement thousands of points (fandisk at
/// 8 or 16 cells), so the repairs' cost follows the grid, not the mesh.
pub(crate) fn thinned_by_cell(
    spec: &GridSpec<3>,
    points: impl Iterator<Item = DVec3> + Clone,
    per_spacing: f64,
    keep_up_to: usize,
) -> HashMap<usize, Vec<DVec3>> {
    let mut count: HashMap<usize, usize> = HashMap::new();
    for c in points.clone().filter_map(|p| cell_of(spec, p)) {
        *count.entry(c).or_default() += 1;
    }
    let mut by_cell: HashMap<usize, Vec<DVec3>> = HashMap::new();
    let mut taken = std::collections::HashSet::new();
    let origin = DVec3::from_array(spec.origin);
    for p in points {
        let Some(c) = cell_of(spec, p) else { continue };
        let sub = ((p - origin) * (per_spacing / spec.spacing))
            .floor()
            .as_i64vec3();
        if count[&c] <= keep_up_to || taken.insert(sub) {
            by_cell.entry(c).or_default().push(p);
        }
    }
    by_cell
}

/// The pieces of segment `a`-`b` inside each cell it crosses.
pub(crate) fn clip_to_cells(spec: &GridSpec<3>, a: DVec3, b: DVec3) -> Vec<(usize, [DVec3; 2])> {
    let (ga, gb) = (spec.to_grid(a.to_array()), spec.to_grid(b.to_array()));
    let lo: [usize; 3] = std::array::from_fn(|k| ga[k].min(gb[k]).floor().max(0.0) as usize);
    let hi: [usize; 3] = std::array::from_fn(|k| {
        (ga[k].max(gb[k]).floor().max(0.0) as usize).min(spec.dims[k].saturating_sub(2))
    });
    let mut out = Vec::new();
    for k in lo[2]..=hi[2] {
        for j in lo[1]..=hi[1] {
            for i in lo[0]..=hi[0] {
                let cell_lo = DVec3::from_array(spec.position([i, j, k]));
                let cell_hi = cell_lo + DVec3::splat(spec.spacing);
                if let Some((t0, t1)) = clip_segment(a, b, cell_lo, cell_hi) {
                    if t1 > t0 {
                        out.push((spec.linear([i, j, k]), [a.lerp(b, t0), a.lerp(b, t1)]));
                    }
                }
            }
        }
    }
    out
}

/// Parameter range of segment `a`-`b` inside the box (Liang–Barsky).
fn clip_segment(a: DVec3, b: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..3 {
        if d[k] == 0.0 {
            if a[k] < lo[k] || a[k] > hi[k] {
                return None;
            }
            continue;
        }
        let (mut s0, mut s1) = ((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]);
        if s0 > s1 {
            std::mem::swap(&mut s0, &mut s1);
        }
        t0 = t0.max(s0);
        t1 = t1.min(s1);
        if t0 > t1 {
            return None;
        }
    }
    Some((t0, t1))
}

pub(crate) fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let d = b - a;
    let len2 = d.length_squared();
    if len2 == 0.0 {
        return a;
    }
    a + d * ((p - a).dot(d) / len2).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::shapes::icosphere;

    fn cube() -> TriMesh {
        let v: Vec<DVec3> = (0..8)
            .map(|c| DVec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64))
            .collect();
        // Two outward triangles per face.
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q: &[u32; 4]| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriMesh {
            vertices: v,
            triangles,
            normals: None,
        }
    }

    #[test]
    fn a_cube_has_twelve_sharp_edges_and_eight_corners() {
        let f = Features::detect(&cube(), 30.0);
        assert_eq!(f.edges.len(), 12);
        assert_eq!(f.corners, (0..8).collect::<Vec<u32>>());
    }

    #[test]
    fn a_fine_sphere_has_none() {
        let f = Features::detect(&icosphere(DVec3::ZERO, 1.0, 3), 30.0);
        assert!(f.edges.is_empty() && f.corners.is_empty());
    }

    #[test]
    fn an_edge_is_split_exactly_among_the_cells_it_crosses() {
        let spec = GridSpec::<3> {
            origin: [0.0; 3],
            spacing: 0.25,
            dims: [9, 9, 9],
        };
        let (a, b) = (DVec3::new(0.1, 0.3, 0.6), DVec3::new(1.9, 1.2, 0.65));
        let pieces = clip_to_cells(&spec, a, b);
        let total: f64 = pieces.iter().map(|(_, [p, q])| p.distance(*q)).sum();
        assert!((total - a.distance(b)).abs() < 1e-12, "{total}");
        for (cell, [p, q]) in pieces {
            let mid = (p + q) * 0.5;
            assert_eq!(cell_of(&spec, mid), Some(cell));
        }
        // A point on an edge between four cells belongs to all four.
        let p = DVec3::new(0.5, 0.75, 0.6);
        let cells = cells_containing(&spec, p);
        assert_eq!(cells.len(), 4);
        for c in cells {
            assert_eq!(cell_of(&spec, nudge_into(&spec, c, p)), Some(c));
        }
    }
}
