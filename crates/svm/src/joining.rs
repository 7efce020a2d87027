//! Joining the pieces of a curve-network surface that the curves do not
//! keep apart.
//!
//! Curves that cross are on one connected surface, but two groups of
//! curves that cross nothing of each other (a network's components) say
//! nothing about how their surfaces meet: the Hermite fit may span each
//! with a piece of its own, as the bunny's rear ear, whose tip is cut by
//! sections that miss the rest, floats above the head. Sections of one
//! object should give one solid, so two pieces are joined when
//! - they hold curves of one network component (the curves say they are
//!   one surface), or
//! - their gap is narrower than a cell of the network (the curves are too
//!   sparse to show it) and no section plane passes through it (a plane
//!   through the gap would show the neck as a section of its own, and it
//!   does not).
//!
//! The join asks the fit, not the mesh, for a neck: along the shortest
//! segment between the pieces, from the deepest point of one (on the
//! segment's line) to the deepest point of the other, f is asked to be
//! minus the depth, interpolated between the two ends; the smoothest
//! interpolant then grows a neck that tapers from one piece's thickness to
//! the other's and leaves every curve on the surface.

use crate::hermite::{Gradient, HermiteSample};
use glam::DVec3;
use std::collections::BTreeSet;
use surfrecon_geom::curves::CurveNetwork;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{Aabb, TriMesh};

/// More pieces than this are left as they are: the fit has failed in a
/// way a few necks do not mend.
const MAX_PIECES: usize = 12;

/// A bridge point closer to a curve sample than this share of its depth
/// is left out: f = 0 there and minus the depth so near would ask for a
/// gradient far steeper than a distance's.
const MIN_CLEARANCE: f64 = 0.5;

/// One gap between two pieces, as decided (serializes into the
/// `curve_network.joining.gaps` of `surfrecon reconstruct --json`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct GapReport {
    /// Distance between the two pieces (closest mesh vertices).
    pub gap: f64,
    /// Asked-for depth of the neck at its two ends (the pieces' depth
    /// there); zero when not bridged.
    pub depths: [f64; 2],
    /// Why the gap was bridged or left.
    pub reason: &'static str,
    /// Whether a neck was asked for (see [`JoinReport::not_kept`]).
    pub bridged: bool,
}

/// What joining did (the `curve_network.joining` keys of `--json`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct JoinReport {
    /// Pieces of the first fit.
    pub pieces_before: usize,
    /// Pieces that the final surface joined to another.
    pub pieces_joined: usize,
    /// Pieces left apart in the final surface (beyond the first).
    pub pieces_left_apart: usize,
    /// The network's typical cell (median arc between neighbouring
    /// crossings): gaps up to this wide may be bridged.
    pub network_cell: f64,
    pub gaps: Vec<GapReport>,
    /// Why the necks asked for were not kept, if they were not (the
    /// surface is then the first fit's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_kept: Option<String>,
}

/// The necks to ask of the fit.
#[derive(Debug, Default)]
pub(crate) struct Plan {
    pub samples: Vec<HermiteSample>,
    pub gaps: Vec<GapReport>,
    pub network_cell: f64,
}

/// Plans the necks between the pieces of `mesh` (the zero set of `f`)
/// that the network does not keep apart; `cell` is the mesh's cell size,
/// `curve_samples` the fit's samples.
pub(crate) fn plan(
    network: &CurveNetwork,
    mesh: &TriMesh,
    f: &dyn Fn(DVec3) -> f64,
    cell: f64,
    curve_samples: &[DVec3],
) -> Plan {
    let cell_size = network.cell_size();
    let mut plan = Plan {
        network_cell: cell_size,
        ..Default::default()
    };
    let pieces = Pieces::of(mesh);
    if pieces.vertices.len() < 2 || pieces.vertices.len() > MAX_PIECES {
        return plan;
    }
    let components = pieces.components(network, mesh, 2.0 * cell);
    let planes = network.section_planes();
    let sample_tree = KdTree::new(curve_samples);
    let mut groups: Vec<usize> = (0..pieces.vertices.len()).collect();
    for (gap, i, j, a, b) in pieces.closest_pairs() {
        let (gi, gj) = (groups[i], groups[j]);
        if gi == gj {
            continue;
        }
        let reason = if !components[i].is_disjoint(&components[j]) {
            Ok("one network component: the curves say the pieces are one surface")
        } else if gap > cell_size {
            Err("the gap is wider than a cell of the network")
        } else if planes
            .iter()
            .any(|p| passes_through_gap(p, a, b, network.spacing))
        {
            Err("a section plane passes through the gap and shows no neck")
        } else {
            Ok("one object: the curves show nothing in the gap")
        };
        let report = match reason {
            Ok(reason) => {
                let reach = [pieces.bounds[i].diagonal(), pieces.bounds[j].diagonal()];
                let (neck, depths) = neck(f, a, b, cell, reach, &sample_tree);
                plan.samples.extend(neck);
                groups
                    .iter_mut()
                    .filter(|g| **g == gj)
                    .for_each(|g| *g = gi);
                GapReport {
                    gap,
                    depths,
                    reason,
                    bridged: true,
                }
            }
            Err(reason) => GapReport {
                gap,
                depths: [0.0; 2],
                reason,
                bridged: false,
            },
        };
        plan.gaps.push(report);
    }
    plan
}

/// The connected pieces of a mesh: their vertices and bounds.
struct Pieces {
    labels: Vec<usize>,
    vertices: Vec<Vec<DVec3>>,
    bounds: Vec<Aabb>,
}

impl Pieces {
    fn of(mesh: &TriMesh) -> Self {
        let (labels, count) = mesh.piece_labels();
        let mut vertices = vec![Vec::new(); count];
        for (v, &l) in mesh.vertices.iter().zip(&labels) {
            vertices[l].push(*v);
        }
        // Marching cubes leaves no vertex outside a triangle, but a mesh
        // may: such vertices are no piece.
        let mut used = vec![false; count];
        for t in &mesh.triangles {
            used[labels[t[0] as usize]] = true;
        }
        let mut renumber = vec![usize::MAX; count];
        let mut kept = Vec::new();
        for (l, v) in vertices.into_iter().enumerate() {
            if used[l] {
                renumber[l] = kept.len();
                kept.push(v);
            }
        }
        Pieces {
            labels: labels.iter().map(|&l| renumber[l]).collect(),
            bounds: kept
                .iter()
                .map(|v| Aabb::from_points(v.as_slice()))
                .collect(),
            vertices: kept,
        }
    }

    /// Per piece, the network components of the curves it holds (curve
    /// vertices within `near` of one of its vertices).
    fn components(
        &self,
        network: &CurveNetwork,
        mesh: &TriMesh,
        near: f64,
    ) -> Vec<BTreeSet<usize>> {
        let tree = KdTree::new(&mesh.vertices);
        let component = network.components();
        let mut held = vec![BTreeSet::new(); self.vertices.len()];
        for (curve, c) in network.curves.iter().enumerate() {
            for p in &c.points {
                if let Some(n) = tree.nearest(*p).filter(|n| n.distance <= near) {
                    let piece = self.labels[n.index];
                    if piece != usize::MAX {
                        held[piece].insert(component[curve]);
                    }
                }
            }
        }
        held
    }

    /// Every pair of pieces with its gap and closest vertices, nearest
    /// first: (gap, i, j, on i, on j).
    fn closest_pairs(&self) -> Vec<(f64, usize, usize, DVec3, DVec3)> {
        let trees: Vec<KdTree> = self.vertices.iter().map(|v| KdTree::new(v)).collect();
        let mut pairs = Vec::new();
        for i in 0..self.vertices.len() {
            for j in i + 1..self.vertices.len() {
                // Query the smaller piece against the larger one's tree.
                let (q, t) = if self.vertices[i].len() <= self.vertices[j].len() {
                    (i, j)
                } else {
                    (j, i)
                };
                let closest = self.vertices[q]
                    .iter()
                    .filter_map(|p| trees[t].nearest(*p).map(|n| (n.distance, *p, n.index)))
                    .min_by(|x, y| x.0.total_cmp(&y.0));
                if let Some((gap, p, k)) = closest {
                    let other = self.vertices[t][k];
                    let (a, b) = if q == i { (p, other) } else { (other, p) };
                    pairs.push((gap, i, j, a, b));
                }
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
        pairs
    }
}

/// Whether `plane` meets the open segment from `a` to `b` (shortened by
/// `tolerance` at each end: the ends lie on the pieces, which sections
/// may cut right there).
fn passes_through_gap(
    plane: &surfrecon_geom::curves::Plane,
    a: DVec3,
    b: DVec3,
    tolerance: f64,
) -> bool {
    let length = a.distance(b);
    if length <= 2.0 * tolerance {
        return false;
    }
    let u = (b - a) / length;
    let (p, q) = (
        plane.distance(a + tolerance * u),
        plane.distance(b - tolerance * u),
    );
    p * q <= 0.0 || p.abs().min(q.abs()) <= tolerance
}

/// The neck's samples between the pieces whose closest points are `a` and
/// `b`, and its depth at each end.
fn neck(
    f: &dyn Fn(DVec3) -> f64,
    a: DVec3,
    b: DVec3,
    step: f64,
    reach: [f64; 2],
    curve_samples: &KdTree,
) -> (Vec<HermiteSample>, [f64; 2]) {
    let axis = (b - a).normalize_or_zero();
    let (start, depth_a) = deepest_along(f, a, -axis, step, reach[0]);
    let (end, depth_b) = deepest_along(f, b, axis, step, reach[1]);
    let spacing = depth_a.min(depth_b).max(step);
    let count = (start.distance(end) / spacing).ceil().max(1.0) as usize;
    let samples = (0..=count)
        .map(|k| {
            let t = k as f64 / count as f64;
            (start.lerp(end, t), depth_a + t * (depth_b - depth_a))
        })
        .filter(|(p, depth)| {
            curve_samples
                .nearest(*p)
                .is_none_or(|n| n.distance >= MIN_CLEARANCE * depth)
        })
        .map(|(position, depth)| HermiteSample {
            position,
            value: -depth,
            gradient: Gradient::Free,
        })
        .collect();
    (samples, [depth_a, depth_b])
}

/// From `start` on a piece's surface, into the piece along `direction`:
/// the first point where f stops falling, and its depth −f (f ≈ the
/// signed distance). At least one `step` deep.
fn deepest_along(
    f: &dyn Fn(DVec3) -> f64,
    start: DVec3,
    direction: DVec3,
    step: f64,
    reach: f64,
) -> (DVec3, f64) {
    let mut best = (start, f(start));
    let steps = (reach / step).ceil() as usize;
    for k in 1..=steps {
        let p = start + (k as f64 * step) * direction;
        let v = f(p);
        if v < best.1 {
            best = (p, v);
        } else if v > best.1 + 0.5 * step {
            break;
        }
    }
    (best.0, (-best.1).max(step))
}
