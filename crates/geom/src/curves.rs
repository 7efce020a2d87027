//! Curve networks: curves as first-class data, and the surface normal a
//! network of curves on a surface implies.
//!
//! - [`curves_from_polylines`]: OBJ `l` polylines as [`Curve`]s (pieces that
//!   meet end to end and continue smoothly are joined).
//! - [`chain_points`]: detects point sets that lie along curves and chains
//!   them into [`Curve`]s (points near crossings, where the neighbourhood is
//!   not a line, are bridged and put back where they fit).
//! - [`CurveNetwork::new`]: finds the crossings of the curves and gives
//!   curve vertices the normal of the surface the curves lie on: at a
//!   crossing the two tangents fix it (their cross product); along a curve
//!   it stays perpendicular to the tangent and turns linearly (in a
//!   rotation-minimizing frame) from one crossing to the next; it is
//!   trusted only as far as the curve runs straight from a crossing
//!   ([`MAX_TURN`]): where the curve bends, the surface may turn in ways
//!   the curve does not tell. Signs are made consistent over the network by a maximum spanning
//!   tree of the crossing graph, then outward by the extreme vertices.
//!   Curves that cross nothing get no normal.
//! - [`CurveNetwork::samples`]: evenly spaced oriented samples for an
//!   implicit fit.

use crate::normals::symmetric_eigen3;
use crate::spatial::KdTree;
use crate::Polylines;
use glam::DVec3;
use std::f64::consts::PI;

/// One curve: its vertices in order; a closed curve joins its last vertex
/// back to its first (which is not repeated).
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    pub points: Vec<DVec3>,
    pub closed: bool,
}

impl Curve {
    /// A closed circle of `n` vertices: centre + radius (cos t u + sin t v)
    /// for unit, orthogonal `u`, `v` (test and example networks).
    pub fn circle(center: DVec3, u: DVec3, v: DVec3, radius: f64, n: usize) -> Self {
        let points = (0..n)
            .map(|i| {
                let t = 2.0 * PI * i as f64 / n as f64;
                center + radius * (t.cos() * u + t.sin() * v)
            })
            .collect();
        Curve {
            points,
            closed: true,
        }
    }

    /// Number of segments.
    pub fn segment_count(&self) -> usize {
        match (self.closed, self.points.len()) {
            (_, 0 | 1) => 0,
            (true, n) => n,
            (false, n) => n - 1,
        }
    }

    /// Segment `i` as its two end points.
    pub fn segment(&self, i: usize) -> (DVec3, DVec3) {
        let n = self.points.len();
        (self.points[i], self.points[(i + 1) % n])
    }

    /// Arc length at each vertex, plus the total length last.
    pub fn arc_lengths(&self) -> Vec<f64> {
        let mut s = vec![0.0];
        for i in 0..self.segment_count() {
            let (a, b) = self.segment(i);
            s.push(s[i] + a.distance(b));
        }
        s
    }

    pub fn length(&self) -> f64 {
        *self.arc_lengths().last().unwrap_or(&0.0)
    }

    /// Unit tangent at each vertex (central differences; one-sided at the
    /// ends of an open curve).
    pub fn tangents(&self) -> Vec<DVec3> {
        let n = self.points.len();
        (0..n)
            .map(|i| {
                let (prev, next) = if self.closed {
                    ((i + n - 1) % n, (i + 1) % n)
                } else {
                    (i.saturating_sub(1), (i + 1).min(n - 1))
                };
                (self.points[next] - self.points[prev]).normalize_or_zero()
            })
            .collect()
    }
}

/// Where two curves cross, and the surface normal there (unit, signed
/// after orientation).
#[derive(Clone, Debug, PartialEq)]
pub struct Crossing {
    pub position: DVec3,
    pub normal: DVec3,
    /// The two curves (index, arc length along it).
    pub on: [(usize, f64); 2],
}

/// Curves with their crossings and a normal at every vertex of every curve
/// that crosses another.
#[derive(Clone, Debug)]
pub struct CurveNetwork {
    pub curves: Vec<Curve>,
    pub crossings: Vec<Crossing>,
    /// Per curve, per vertex: the implied unit surface normal (outward), or
    /// `None` on curves without a crossing.
    pub normals: Vec<Vec<Option<DVec3>>>,
    /// Per curve, per vertex: how far (radians) the curve's tangent has
    /// turned since the nearest crossing; the implied normal is only as
    /// good as this is small (see [`MAX_TURN`]). Infinite on curves
    /// without a crossing.
    pub turns: Vec<Vec<f64>>,
    /// Per curve, per vertex: on planar curves that cross another, the
    /// in-plane part of the normal (see [`InPlaneNormal`]).
    pub in_plane: Vec<Vec<Option<InPlaneNormal>>>,
    /// Median segment length.
    pub spacing: f64,
}

/// On a planar curve (a section), the surface normal is n = s·m + t·p with
/// m the unit normal of the curve within its plane and p the plane's
/// normal: m is exact at every vertex, only the share s = n·m ∈ [0, 1]
/// (the surface's tilt out of the plane) has to be interpolated between
/// crossings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InPlaneNormal {
    /// m, pointing out of the surface (the side the crossings' normals say).
    pub direction: DVec3,
    /// s, interpolated in arc length between crossings.
    pub share: f64,
}

/// A point on a curve, with what the network says about the surface there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveSample {
    pub position: DVec3,
    /// The implied normal, where the curve has turned little since a crossing.
    pub normal: Option<DVec3>,
    pub in_plane: Option<InPlaneNormal>,
}

/// Curves cross where they pass closer than this share of the spacing.
const CROSSING_TOLERANCE: f64 = 0.75;
/// Tangents at a crossing make at least this angle (sine).
const CROSSING_MIN_SINE: f64 = 0.3;
/// Two crossings of the same pair of curves are one if closer than this many spacings.
const CROSSING_MERGE: f64 = 4.0;

impl CurveNetwork {
    /// Crossings, normals and their orientation for `curves`.
    pub fn new(curves: Vec<Curve>) -> Self {
        let curves: Vec<Curve> = curves.into_iter().filter(|c| c.points.len() >= 2).collect();
        let spacing = median_segment(&curves);
        let mut crossings = find_crossings(&curves, spacing);
        let frames: Vec<Frames> = curves.iter().map(Frames::new).collect();
        let signs = orient_crossings(&curves, &frames, &crossings);
        for (c, s) in crossings.iter_mut().zip(&signs) {
            c.normal *= *s;
        }
        let (mut normals, turns): (Vec<_>, Vec<_>) = curves
            .iter()
            .zip(&frames)
            .enumerate()
            .map(|(k, (c, f))| interpolate_normals(k, c, f, &crossings))
            .unzip();
        make_outward(&curves, &mut normals, &mut crossings);
        let on = crossings_by_curve(&curves, &crossings);
        let in_plane = curves
            .iter()
            .zip(&frames)
            .zip(&on)
            .map(|((c, f), list)| in_plane_normals(c, f, list, &crossings, spacing))
            .collect();
        CurveNetwork {
            curves,
            crossings,
            normals,
            turns,
            in_plane,
            spacing,
        }
    }

    /// Total vertex count.
    pub fn vertex_count(&self) -> usize {
        self.curves.iter().map(|c| c.points.len()).sum()
    }

    /// Curves that cross at least one other.
    pub fn crossed_curves(&self) -> usize {
        self.normals
            .iter()
            .filter(|n| n.iter().any(Option::is_some))
            .count()
    }

    /// The network's connected components: per curve, the index of its
    /// group of curves linked through crossings (0..). Curves of one
    /// component lie on one connected surface; nothing in the curves ties
    /// two components together.
    pub fn components(&self) -> Vec<usize> {
        curve_groups(self.curves.len(), &self.crossings)
    }

    /// The distinct planes of the planar curves (sections): a plane that
    /// cuts a solid shows all of it in its section.
    pub fn section_planes(&self) -> Vec<Plane> {
        let mut planes: Vec<Plane> = Vec::new();
        for c in &self.curves {
            if let Some(p) = Plane::of(c, self.spacing) {
                if !planes
                    .iter()
                    .any(|q| Plane::same(Some(*q), Some(p), self.spacing))
                {
                    planes.push(p);
                }
            }
        }
        planes
    }

    /// The median arc length between neighbouring crossings along a curve:
    /// the size of a typical cell of the network, the scale below which
    /// the curves cannot show what the surface does. 0 without crossings.
    pub fn cell_size(&self) -> f64 {
        let mut arcs = Vec::new();
        for (c, list) in self
            .curves
            .iter()
            .zip(crossings_by_curve(&self.curves, &self.crossings))
        {
            arcs.extend(list.windows(2).map(|w| w[1].0 - w[0].0));
            if c.closed && list.len() >= 2 {
                arcs.push(list[0].0 + c.length() - list[list.len() - 1].0);
            }
        }
        arcs.retain(|a| *a > 0.0);
        if arcs.is_empty() {
            return 0.0;
        }
        arcs.sort_by(f64::total_cmp);
        arcs[arcs.len() / 2]
    }

    /// Samples every `step` of arc length (and at every crossing, which
    /// come first, in the order of [`CurveNetwork::crossings`]), with the
    /// normal where the curve has one and has turned at most `max_turn`
    /// since the nearest crossing, and the in-plane normal where the curve
    /// has one. Samples closer than half a step to an earlier one are left
    /// out (the fit needs distinct points); the positions do not depend on
    /// `max_turn`.
    pub fn samples(&self, step: f64, max_turn: f64) -> Vec<CurveSample> {
        let mut out: Vec<CurveSample> = self
            .crossings
            .iter()
            .map(|c| CurveSample {
                position: c.position,
                normal: Some(c.normal),
                in_plane: None,
            })
            .collect();
        let mut candidates = Vec::new();
        for (k, c) in self.curves.iter().enumerate() {
            let trusted: Vec<Option<DVec3>> = self.normals[k]
                .iter()
                .zip(&self.turns[k])
                .map(|(n, &t)| n.filter(|_| t <= max_turn))
                .collect();
            resample(c, &trusted, &self.in_plane[k], step, &mut candidates);
        }
        let mut accepted = SpacedSet::new(0.5 * step);
        for s in &out {
            accepted.insert(s.position);
        }
        for s in candidates {
            if accepted.insert(s.position) {
                out.push(s);
            }
        }
        out
    }
}

/// Points kept at least `min_distance` apart (uniform hash grid).
struct SpacedSet {
    cell: f64,
    cells: std::collections::HashMap<[i64; 3], Vec<DVec3>>,
}

impl SpacedSet {
    fn new(min_distance: f64) -> Self {
        SpacedSet {
            cell: min_distance.max(f64::MIN_POSITIVE),
            cells: Default::default(),
        }
    }

    fn key(&self, p: DVec3) -> [i64; 3] {
        (p / self.cell).floor().as_i64vec3().to_array()
    }

    /// Inserts `p` unless a kept point is within the distance; true if inserted.
    fn insert(&mut self, p: DVec3) -> bool {
        let k = self.key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let q = [k[0] + dx, k[1] + dy, k[2] + dz];
                    if let Some(v) = self.cells.get(&q) {
                        if v.iter().any(|o| o.distance(p) < self.cell) {
                            return false;
                        }
                    }
                }
            }
        }
        self.cells.entry(k).or_default().push(p);
        true
    }
}

fn median_segment(curves: &[Curve]) -> f64 {
    let mut lengths: Vec<f64> = curves
        .iter()
        .flat_map(|c| (0..c.segment_count()).map(move |i| c.segment(i)))
        .map(|(a, b)| a.distance(b))
        .filter(|l| *l > 0.0)
        .collect();
    if lengths.is_empty() {
        return 0.0;
    }
    lengths.sort_by(f64::total_cmp);
    lengths[lengths.len() / 2]
}

/// Samples every `step` along `c`, normals and in-plane normals
/// interpolated between vertices (`None` where a vertex has none).
fn resample(
    c: &Curve,
    normals: &[Option<DVec3>],
    in_plane: &[Option<InPlaneNormal>],
    step: f64,
    out: &mut Vec<CurveSample>,
) {
    let s = c.arc_lengths();
    let total = *s.last().unwrap_or(&0.0);
    let count = ((total / step).round() as usize).max(1);
    let count = if c.closed { count } else { count + 1 };
    let spacing = if c.closed {
        total / count as f64
    } else {
        total / (count - 1).max(1) as f64
    };
    let mut seg = 0;
    for k in 0..count {
        let at = k as f64 * spacing;
        while seg + 1 < c.segment_count() && s[seg + 1] < at {
            seg += 1;
        }
        let len = s[seg + 1] - s[seg];
        let t = if len > 0.0 {
            ((at - s[seg]) / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = c.segment(seg);
        let j = (seg + 1) % c.points.len();
        let normal = match (normals[seg], normals[j]) {
            (Some(na), Some(nb)) => Some(na.lerp(nb, t).normalize_or(na)),
            _ => None,
        };
        let in_plane = match (in_plane[seg], in_plane[j]) {
            (Some(ma), Some(mb)) => Some(InPlaneNormal {
                direction: ma
                    .direction
                    .lerp(mb.direction, t)
                    .normalize_or(ma.direction),
                share: ma.share + t * (mb.share - ma.share),
            }),
            _ => None,
        };
        out.push(CurveSample {
            position: a.lerp(b, t),
            normal,
            in_plane,
        });
    }
}

/// The in-plane normals of a planar curve with crossings `list` (arc
/// length, crossing index; sorted): m = tangent × plane normal, signed by
/// the crossings' normals; the share n·m at the crossings, linear in arc
/// length between them. `None` everywhere on other curves.
fn in_plane_normals(
    c: &Curve,
    f: &Frames,
    list: &[(f64, usize)],
    crossings: &[Crossing],
    spacing: f64,
) -> Vec<Option<InPlaneNormal>> {
    let plane = Plane::of(c, spacing);
    let (Some(plane), false) = (plane, list.is_empty()) else {
        return vec![None; c.points.len()];
    };
    let m: Vec<DVec3> = f
        .tangent
        .iter()
        .map(|t| t.cross(plane.normal).normalize_or_zero())
        .collect();
    let at_crossing = |&(s, i): &(f64, usize)| crossings[i].normal.dot(m[f.vertex_at(s)]);
    let sign = if list.iter().map(at_crossing).sum::<f64>() < 0.0 {
        -1.0
    } else {
        1.0
    };
    let mut keys: Vec<(f64, f64)> = list
        .iter()
        .map(|x| (x.0, (sign * at_crossing(x)).max(0.0)))
        .collect();
    let length = *f.arc.last().unwrap_or(&0.0);
    if c.closed {
        keys.push((keys[0].0 + length, keys[0].1));
    }
    (0..c.points.len())
        .map(|i| {
            let mut s = f.arc[i];
            if c.closed && s < keys[0].0 {
                s += length;
            }
            Some(InPlaneNormal {
                direction: sign * m[i],
                share: piecewise_linear(&keys, s),
            })
        })
        .collect()
}

/// Rotation-minimizing frames along a curve: `normal[i]` ⟂ `tangent[i]`,
/// transported by projection from vertex to vertex; `holonomy` is the
/// angle the frame has turned (about the first tangent) after one loop of a
/// closed curve.
struct Frames {
    tangent: Vec<DVec3>,
    normal: Vec<DVec3>,
    arc: Vec<f64>,
    holonomy: f64,
}

impl Frames {
    fn new(c: &Curve) -> Self {
        let tangent = c.tangents();
        let mut normal = Vec::with_capacity(tangent.len());
        let mut n = tangent[0].any_orthonormal_vector();
        for t in &tangent {
            n = transport(n, *t);
            normal.push(n);
        }
        let holonomy = if c.closed {
            let back = transport(n, tangent[0]);
            angle_in_frame(back, tangent[0], normal[0])
        } else {
            0.0
        };
        Frames {
            tangent,
            normal,
            arc: c.arc_lengths(),
            holonomy,
        }
    }

    /// Angle of `v` about the tangent at vertex `i`, from the frame normal.
    fn angle(&self, i: usize, v: DVec3) -> f64 {
        angle_in_frame(v, self.tangent[i], self.normal[i])
    }

    /// Vector at angle `a` in the frame of vertex `i`.
    fn direction(&self, i: usize, a: f64) -> DVec3 {
        let b = self.tangent[i].cross(self.normal[i]);
        self.normal[i] * a.cos() + b * a.sin()
    }

    /// The vertex nearest to arc length `s`.
    fn vertex_at(&self, s: f64) -> usize {
        let n = self.tangent.len();
        let i = self.arc.partition_point(|&x| x < s).min(self.arc.len() - 1);
        let i = if i > 0 && (s - self.arc[i - 1]) < (self.arc[i] - s) {
            i - 1
        } else {
            i
        };
        i % n
    }
}

/// `n` made perpendicular to `t` with as little turning as possible.
fn transport(n: DVec3, t: DVec3) -> DVec3 {
    let p = n - n.dot(t) * t;
    if p.length_squared() > 1e-20 {
        p.normalize()
    } else {
        t.any_orthonormal_vector()
    }
}

fn angle_in_frame(v: DVec3, t: DVec3, n: DVec3) -> f64 {
    let b = t.cross(n);
    v.dot(b).atan2(v.dot(n))
}

/// Angle `a` shifted by whole turns to lie within half a turn of `near`.
fn unwrap_near(a: f64, near: f64) -> f64 {
    a - 2.0 * PI * ((a - near) / (2.0 * PI)).round()
}

/// Crossings of each curve, sorted by arc length: (arc, crossing index).
fn crossings_by_curve(curves: &[Curve], crossings: &[Crossing]) -> Vec<Vec<(f64, usize)>> {
    let mut on: Vec<Vec<(f64, usize)>> = vec![Vec::new(); curves.len()];
    for (k, c) in crossings.iter().enumerate() {
        for (curve, s) in c.on {
            on[curve].push((s, k));
        }
    }
    for v in &mut on {
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    on
}

/// Sign (+1 or -1) per crossing so that the normal turns by less than a
/// quarter turn between neighbouring crossings along the curves, where it
/// can: relations between consecutive crossings on each curve, kept by a
/// maximum spanning forest (Kruskal with a parity union-find).
fn orient_crossings(curves: &[Curve], frames: &[Frames], crossings: &[Crossing]) -> Vec<f64> {
    let on = crossings_by_curve(curves, crossings);
    // (weight, a, b, same sign?)
    let mut relations: Vec<(f64, usize, usize, bool)> = Vec::new();
    for (k, list) in on.iter().enumerate() {
        let f = &frames[k];
        let angle = |&(s, idx): &(f64, usize)| f.angle(f.vertex_at(s), crossings[idx].normal);
        for w in list.windows(2) {
            let d = angle(&w[1]) - angle(&w[0]);
            relations.push((d.cos().abs(), w[0].1, w[1].1, d.cos() >= 0.0));
        }
        if curves[k].closed && list.len() >= 2 {
            let (first, last) = (&list[0], &list[list.len() - 1]);
            let d = angle(first) - f.holonomy - angle(last);
            relations.push((d.cos().abs(), last.1, first.1, d.cos() >= 0.0));
        }
    }
    relations.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut uf = ParityUnionFind::new(crossings.len());
    for (_, a, b, same) in relations {
        uf.union(a, b, !same);
    }
    (0..crossings.len())
        .map(|k| if uf.find(k).1 { -1.0 } else { 1.0 })
        .collect()
}

/// Union-find where each element carries a parity relative to its root.
struct ParityUnionFind {
    parent: Vec<usize>,
    parity: Vec<bool>,
}

impl ParityUnionFind {
    fn new(n: usize) -> Self {
        ParityUnionFind {
            parent: (0..n).collect(),
            parity: vec![false; n],
        }
    }

    /// Root and parity relative to it.
    fn find(&mut self, x: usize) -> (usize, bool) {
        let p = self.parent[x];
        if p == x {
            return (x, false);
        }
        let (root, pp) = self.find(p);
        self.parent[x] = root;
        self.parity[x] ^= pp;
        (root, self.parity[x])
    }

    /// Joins the sets of `a` and `b` with parity(a) ^ parity(b) = `differ`,
    /// unless they are joined already.
    fn union(&mut self, a: usize, b: usize, differ: bool) {
        let (ra, pa) = self.find(a);
        let (rb, pb) = self.find(b);
        if ra != rb {
            self.parent[rb] = ra;
            self.parity[rb] = pa ^ pb ^ differ;
        }
    }
}

/// Normal at every vertex of curve `k`: the angle in the transported frame
/// turns linearly in arc length between consecutive crossings (and stays
/// constant past the end crossings of an open curve); with the turning of
/// the tangent from the nearest crossing.
fn interpolate_normals(
    k: usize,
    c: &Curve,
    f: &Frames,
    crossings: &[Crossing],
) -> (Vec<Option<DVec3>>, Vec<f64>) {
    let mut keys: Vec<(f64, f64)> = Vec::new();
    let mut list: Vec<(f64, usize)> = crossings
        .iter()
        .enumerate()
        .flat_map(|(i, x)| x.on.iter().filter(|o| o.0 == k).map(move |o| (o.1, i)))
        .collect();
    list.sort_by(|a, b| a.0.total_cmp(&b.0));
    for &(s, i) in &list {
        let a = f.angle(f.vertex_at(s), crossings[i].normal);
        let a = keys.last().map_or(a, |&(_, prev)| unwrap_near(a, prev));
        keys.push((s, a));
    }
    if keys.is_empty() {
        return (
            vec![None; c.points.len()],
            vec![f64::INFINITY; c.points.len()],
        );
    }
    let length = *f.arc.last().unwrap_or(&0.0);
    if c.closed {
        let (s0, a0) = keys[0];
        let last = keys[keys.len() - 1].1;
        keys.push((s0 + length, unwrap_near(a0 - f.holonomy, last)));
    }
    let turning = Turning::new(c, f);
    let anchors: Vec<usize> = list.iter().map(|&(s, _)| f.vertex_at(s)).collect();
    (0..c.points.len())
        .map(|i| {
            let mut s = f.arc[i];
            if c.closed && s < keys[0].0 {
                s += length;
            }
            let turn = anchors
                .iter()
                .map(|&a| turning.between(i, a))
                .fold(f64::INFINITY, f64::min);
            (Some(f.direction(i, piecewise_linear(&keys, s))), turn)
        })
        .unzip()
}

/// How far a normal is carried from a crossing: while the curve's tangent
/// has turned less than this (radians). Where a curve bends, the surface
/// normal turns too, in ways a curve alone does not tell (cross-sections
/// of a torus); straight stretches (sections of planar faces) carry it far.
/// Measured: 0.03 keeps torus cross-sections at CD-L1 1.7‰ (0.1: 2.8‰)
/// while fandisk sections need some carrying (0: 26‰, 0.03: 2.0‰).
pub const MAX_TURN: f64 = 0.03;

/// Cumulative turning of a curve's tangent, vertex by vertex.
struct Turning {
    at: Vec<f64>,
    /// Total turning of a closed curve (back to its first vertex).
    loop_total: Option<f64>,
}

impl Turning {
    fn new(c: &Curve, f: &Frames) -> Self {
        let angle = |a: DVec3, b: DVec3| a.dot(b).clamp(-1.0, 1.0).acos();
        let mut at = vec![0.0];
        for w in f.tangent.windows(2) {
            at.push(at[at.len() - 1] + angle(w[0], w[1]));
        }
        let loop_total = c
            .closed
            .then(|| at[at.len() - 1] + angle(f.tangent[f.tangent.len() - 1], f.tangent[0]));
        Turning { at, loop_total }
    }

    /// Turning between vertices `i` and `j` (the shorter way round a loop).
    fn between(&self, i: usize, j: usize) -> f64 {
        let d = (self.at[i] - self.at[j]).abs();
        self.loop_total.map_or(d, |t| d.min(t - d))
    }
}

/// Linear interpolation in sorted `(x, y)` keys, constant beyond the ends.
fn piecewise_linear(keys: &[(f64, f64)], x: f64) -> f64 {
    let j = keys.partition_point(|k| k.0 <= x);
    if j == 0 {
        return keys[0].1;
    }
    if j == keys.len() {
        return keys[j - 1].1;
    }
    let ((x0, y0), (x1, y1)) = (keys[j - 1], keys[j]);
    let t = if x1 > x0 { (x - x0) / (x1 - x0) } else { 0.0 };
    y0 + t * (y1 - y0)
}

/// Flips every connected group of crossed curves whose normals point
/// inward: at the network's extreme vertices in 26 directions the outward
/// normal has a positive component along the direction.
fn make_outward(curves: &[Curve], normals: &mut [Vec<Option<DVec3>>], crossings: &mut [Crossing]) {
    let groups = curve_groups(curves.len(), crossings);
    let group_count = groups.iter().copied().max().map_or(0, |g| g + 1);
    let mut vote = vec![0.0; group_count];
    for d in directions26() {
        let mut best = vec![(f64::NEG_INFINITY, None); group_count];
        for (k, c) in curves.iter().enumerate() {
            for (p, n) in c.points.iter().zip(&normals[k]) {
                if let Some(n) = n {
                    let h = p.dot(d);
                    if h > best[groups[k]].0 {
                        best[groups[k]] = (h, Some(n.dot(d)));
                    }
                }
            }
        }
        for (g, (_, v)) in best.iter().enumerate() {
            vote[g] += v.unwrap_or(0.0);
        }
    }
    for (k, n) in normals.iter_mut().enumerate() {
        if vote[groups[k]] < 0.0 {
            n.iter_mut().flatten().for_each(|v| *v = -*v);
        }
    }
    for c in crossings {
        if vote[groups[c.on[0].0]] < 0.0 {
            c.normal = -c.normal;
        }
    }
}

/// Group index per curve: curves joined through crossings share one.
fn curve_groups(curve_count: usize, crossings: &[Crossing]) -> Vec<usize> {
    let mut uf = ParityUnionFind::new(curve_count);
    for c in crossings {
        uf.union(c.on[0].0, c.on[1].0, false);
    }
    let mut ids = std::collections::HashMap::new();
    (0..curve_count)
        .map(|k| {
            let r = uf.find(k).0;
            let next = ids.len();
            *ids.entry(r).or_insert(next)
        })
        .collect()
}

fn directions26() -> impl Iterator<Item = DVec3> {
    (-1..=1)
        .flat_map(|x| (-1..=1).flat_map(move |y| (-1..=1).map(move |z| (x, y, z))))
        .filter(|&d| d != (0, 0, 0))
        .map(|(x, y, z)| DVec3::new(x as f64, y as f64, z as f64).normalize())
}

/// Closest points of segments `a0a1` and `b0b1`: parameters (s, t) in [0, 1].
fn segment_closest(a0: DVec3, a1: DVec3, b0: DVec3, b1: DVec3) -> (f64, f64) {
    let (u, v, w) = (a1 - a0, b1 - b0, a0 - b0);
    let (a, b, c, d, e) = (u.dot(u), u.dot(v), v.dot(v), u.dot(w), v.dot(w));
    let den = a * c - b * b;
    let mut s = if den > 1e-300 {
        ((b * e - c * d) / den).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = if c > 0.0 { (b * s + e) / c } else { 0.0 };
    if !(0.0..=1.0).contains(&t) {
        t = t.clamp(0.0, 1.0);
        s = if a > 0.0 {
            ((b * t - d) / a).clamp(0.0, 1.0)
        } else {
            0.0
        };
    }
    (s, t)
}

/// Places where two curves (or two far-apart parts of one) pass within
/// [`CROSSING_TOLERANCE`] spacings at a clear angle; one crossing per pair
/// of curves and place, the closest approach.
/// The plane a curve lies in: the points p with normal·p = offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal.
    pub normal: DVec3,
    pub offset: f64,
}

impl Plane {
    /// Signed distance of `p` from the plane.
    pub fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }

    /// The curve's plane, if every vertex is within a quarter spacing of it.
    fn of(c: &Curve, spacing: f64) -> Option<Self> {
        if c.points.len() < 3 {
            return None;
        }
        let normal = crate::normals::plane_normal(&c.points).try_normalize()?;
        let centre = c.points.iter().sum::<DVec3>() / c.points.len() as f64;
        let flat = c
            .points
            .iter()
            .all(|p| (*p - centre).dot(normal).abs() <= 0.25 * spacing);
        flat.then(|| Plane {
            normal,
            offset: normal.dot(centre),
        })
    }

    fn same(a: Option<Self>, b: Option<Self>, spacing: f64) -> bool {
        let (Some(a), Some(b)) = (a, b) else {
            return false;
        };
        let cos = a.normal.dot(b.normal);
        cos.abs() > 0.999 && (a.offset - cos.signum() * b.offset).abs() < spacing
    }
}

fn find_crossings(curves: &[Curve], spacing: f64) -> Vec<Crossing> {
    if spacing <= 0.0 {
        return Vec::new();
    }
    let arcs: Vec<Vec<f64>> = curves.iter().map(Curve::arc_lengths).collect();
    let mut segs: Vec<(usize, usize)> = Vec::new();
    let mut mids = Vec::new();
    let mut longest = 0.0f64;
    for (k, c) in curves.iter().enumerate() {
        for i in 0..c.segment_count() {
            let (a, b) = c.segment(i);
            segs.push((k, i));
            mids.push(0.5 * (a + b));
            longest = longest.max(a.distance(b));
        }
    }
    let tree = KdTree::new(&mids);
    let tol = CROSSING_TOLERANCE * spacing;
    let planes: Vec<Option<Plane>> = curves.iter().map(|c| Plane::of(c, spacing)).collect();
    // (distance, crossing)
    let mut found: Vec<(f64, Crossing)> = Vec::new();
    for (si, &(ka, ia)) in segs.iter().enumerate() {
        let (a0, a1) = curves[ka].segment(ia);
        for nb in tree.within(mids[si], longest + tol) {
            let (kb, ib) = segs[nb.index];
            if (kb, ib) <= (ka, ia) {
                continue;
            }
            // Two curves in one plane (contours of one slice, a planar
            // curve with itself) meet without fixing a surface normal:
            // their tangents only give the plane's.
            if Plane::same(planes[ka], planes[kb], spacing) {
                continue;
            }
            let (b0, b1) = curves[kb].segment(ib);
            let (s, t) = segment_closest(a0, a1, b0, b1);
            let (pa, pb) = (a0.lerp(a1, s), b0.lerp(b1, t));
            let dist = pa.distance(pb);
            let (ta, tb) = ((a1 - a0).normalize_or_zero(), (b1 - b0).normalize_or_zero());
            let normal = ta.cross(tb);
            if dist > tol || normal.length() < CROSSING_MIN_SINE {
                continue;
            }
            let arc_a = arcs[ka][ia] + s * a0.distance(a1);
            let arc_b = arcs[kb][ib] + t * b0.distance(b1);
            if ka == kb && arc_gap(&curves[ka], &arcs[ka], arc_a, arc_b) < 10.0 * spacing {
                continue;
            }
            found.push((
                dist,
                Crossing {
                    position: 0.5 * (pa + pb),
                    normal: normal.normalize(),
                    on: [(ka, arc_a), (kb, arc_b)],
                },
            ));
        }
    }
    found.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut kept: Vec<Crossing> = Vec::new();
    for (_, c) in found {
        let duplicate = kept.iter().any(|k| {
            k.on[0].0 == c.on[0].0
                && k.on[1].0 == c.on[1].0
                && k.position.distance(c.position) < CROSSING_MERGE * spacing
        });
        if !duplicate {
            kept.push(c);
        }
    }
    kept
}

/// Distance along curve `c` between arc lengths `a` and `b` (the shorter
/// way round on a closed curve).
fn arc_gap(c: &Curve, arcs: &[f64], a: f64, b: f64) -> f64 {
    let d = (a - b).abs();
    if c.closed {
        d.min(arcs.last().unwrap_or(&0.0) - d)
    } else {
        d
    }
}

/// Polylines as curves: a line whose ends are the same vertex (or the same
/// position) is closed; lines that meet end to end where no third line
/// ends, and continue without a sharp turn, are joined first.
pub fn curves_from_polylines(p: &Polylines) -> Vec<Curve> {
    let mut pieces: Vec<Vec<DVec3>> = p
        .lines
        .iter()
        .map(|l| {
            l.iter()
                .filter_map(|&i| p.vertices.get(i as usize).copied())
                .collect::<Vec<_>>()
        })
        .filter(|v| v.len() >= 2)
        .collect();
    join_pieces(&mut pieces);
    pieces.into_iter().map(curve_from_chain).collect()
}

/// A chain of positions as a curve: closed when its ends coincide.
fn curve_from_chain(mut v: Vec<DVec3>) -> Curve {
    let closed = v.len() > 3 && v[0] == v[v.len() - 1];
    if closed {
        v.pop();
    }
    Curve { points: v, closed }
}

/// Joins pieces end to end where exactly two piece ends share a position
/// and the turn there is less than 60°.
fn join_pieces(pieces: &mut Vec<Vec<DVec3>>) {
    loop {
        let mut ends: std::collections::HashMap<[u64; 3], Vec<(usize, bool)>> = Default::default();
        for (i, p) in pieces.iter().enumerate() {
            if p[0] == p[p.len() - 1] {
                continue;
            }
            ends.entry(key(p[0])).or_default().push((i, false));
            ends.entry(key(p[p.len() - 1])).or_default().push((i, true));
        }
        let joint = ends.values().find(|v| {
            v.len() == 2 && v[0].0 != v[1].0 && {
                let da = end_direction(&pieces[v[0].0], v[0].1);
                let db = end_direction(&pieces[v[1].0], v[1].1);
                da.dot(db) < -0.5
            }
        });
        let Some(j) = joint.cloned() else {
            return;
        };
        let (mut a, b) = (pieces[j[0].0].clone(), pieces[j[1].0].clone());
        if !j[0].1 {
            a.reverse();
        }
        let mut b = b;
        if j[1].1 {
            b.reverse();
        }
        a.extend_from_slice(&b[1..]);
        let (lo, hi) = (j[0].0.min(j[1].0), j[0].0.max(j[1].0));
        pieces.swap_remove(hi);
        pieces[lo] = a;
    }
}

fn key(p: DVec3) -> [u64; 3] {
    p.to_array().map(f64::to_bits)
}

/// Direction leaving piece `p` at its end (`last`) or start.
fn end_direction(p: &[DVec3], last: bool) -> DVec3 {
    let n = p.len();
    if last {
        (p[n - 1] - p[n - 2]).normalize_or_zero()
    } else {
        (p[0] - p[1]).normalize_or_zero()
    }
}

/// A point is on a clean stretch of curve when its neighbours (within this
/// many local spacings) spread along one line: second PCA eigenvalue below
/// [`LINE_RATIO`] of the first.
const LINE_RADIUS: f64 = 2.5;
const LINE_RATIO: f64 = 0.04;
/// Share of points that must be on clean stretches for a point set to be
/// read as curves.
const MIN_CURVE_SHARE: f64 = 0.6;
/// Points looked at before the whole set is.
const PRECHECK: usize = 2000;
/// Chains with fewer points are dropped.
const MIN_CHAIN: usize = 5;
/// A trace steps to points within this many spacings ahead...
const STEP_REACH: f64 = 3.0;
/// ...and within this angle (cosine) of its current direction.
const STEP_COS: f64 = 0.75;
/// A trace that runs onto this many points of other chains in a row is
/// retracing a curve already found, not crossing it.
const RETRACE: usize = 4;
/// A trace that comes back within this many steps of its start has closed.
const CLOSE_WITHIN: usize = 3;

/// Chains a point set that lies along curves into curves, or `None` when
/// the points do not look like curves (e.g. they sample a surface).
///
/// Each chain is traced from a point on a clean stretch (its neighbourhood
/// is a line), in both directions, always stepping to the point that best
/// continues the chain's current direction. Following the direction rather
/// than the nearest point carries a trace straight through crossings,
/// where the nearest points may belong to the other curve; points at a
/// crossing may be used by both curves.
pub fn chain_points(points: &[DVec3]) -> Option<Vec<Curve>> {
    if points.len() < 4 * MIN_CHAIN {
        return None;
    }
    let tree = KdTree::new(points);
    let spacing_at = |i: usize| tree.knn(points[i], 3).get(2).map_or(0.0, |n| n.distance);
    // A surface scan fails the line test on a subset already (so a scan of
    // millions of points costs little here).
    let stride = (points.len() / PRECHECK).max(1);
    let probe: Vec<usize> = (0..points.len()).step_by(stride).collect();
    let s = median(&probe.iter().map(|&i| spacing_at(i)).collect::<Vec<_>>());
    if s <= 0.0 {
        return None;
    }
    let tangent =
        |i: usize, sp: f64| line_direction(&tree, points, points[i], LINE_RADIUS * sp.max(0.5 * s));
    let lines = probe
        .iter()
        .filter(|&&i| tangent(i, spacing_at(i)).is_some())
        .count();
    if (lines as f64) < MIN_CURVE_SHARE * probe.len() as f64 {
        return None;
    }
    let tangents: Vec<Option<DVec3>> = (0..points.len())
        .map(|i| tangent(i, spacing_at(i)))
        .collect();
    let clean = tangents.iter().filter(|t| t.is_some()).count();
    if (clean as f64) < MIN_CURVE_SHARE * points.len() as f64 {
        return None;
    }
    let tracer = Tracer {
        points,
        tree: &tree,
        reach: STEP_REACH * s,
    };
    let mut owner = vec![usize::MAX; points.len()];
    let mut curves = Vec::new();
    for (start, t) in tangents.iter().enumerate() {
        let Some(t) = *t else { continue };
        if owner[start] != usize::MAX {
            continue;
        }
        let (chain, closed) = tracer.trace(start, t, &owner);
        if chain.len() < MIN_CHAIN {
            owner[start] = usize::MAX - 1;
            continue;
        }
        for i in tracer.covered(&chain, closed, 0.5 * s) {
            if owner[i] == usize::MAX {
                owner[i] = curves.len();
            }
        }
        curves.push(Curve {
            points: chain.iter().map(|&i| points[i]).collect(),
            closed,
        });
    }
    let chained = owner.iter().filter(|&&o| o < curves.len()).count();
    if curves.is_empty() || (chained as f64) < 0.8 * points.len() as f64 {
        return None;
    }
    Some(curves)
}

/// Traces chains through a point set.
struct Tracer<'a> {
    points: &'a [DVec3],
    tree: &'a KdTree,
    reach: f64,
}

impl Tracer<'_> {
    /// The chain through `start` (tangent `t`): traced forward, then
    /// backward. Either trace that comes back to `start` is the curve: the
    /// other may have turned off at a shallow crossing.
    fn trace(&self, start: usize, t: DVec3, owner: &[usize]) -> (Vec<usize>, bool) {
        let (ahead, closed) = self.follow(start, t, owner);
        if closed {
            return (ahead, true);
        }
        let (mut behind, closed) = self.follow(start, -t, owner);
        behind.reverse();
        if closed {
            return (behind, true);
        }
        behind.pop();
        behind.extend(ahead);
        (behind, false)
    }

    /// The chain's points and the points it stepped over (within
    /// `tolerance` of one of its segments).
    fn covered(&self, chain: &[usize], closed: bool, tolerance: f64) -> Vec<usize> {
        let n = chain.len();
        let segments = if closed { n } else { n - 1 };
        let mut out = chain.to_vec();
        for k in 0..segments {
            let (a, b) = (self.points[chain[k]], self.points[chain[(k + 1) % n]]);
            let mid = 0.5 * (a + b);
            for q in self.tree.within(mid, 0.5 * a.distance(b) + tolerance) {
                if distance_to_segment(self.points[q.index], a, b) < tolerance {
                    out.push(q.index);
                }
            }
        }
        out
    }

    /// Steps from `start` along `t` until no point continues the chain,
    /// the chain closes (true), or it runs along another chain.
    fn follow(&self, start: usize, t: DVec3, owner: &[usize]) -> (Vec<usize>, bool) {
        let mut chain = vec![start];
        let mut on_chain: std::collections::HashSet<usize> = [start].into();
        let mut direction = t;
        let mut foreign = 0;
        while let Some(next) = self.step(&chain, direction) {
            if self.closes(&chain, next) {
                return (chain, true);
            }
            if !on_chain.insert(next) {
                break;
            }
            foreign = if owner[next] < usize::MAX - 1 {
                foreign + 1
            } else {
                0
            };
            chain.push(next);
            if foreign >= RETRACE {
                chain.truncate(chain.len() - foreign);
                break;
            }
            direction = self.direction(&chain).unwrap_or(direction);
        }
        (chain, false)
    }

    /// Whether stepping to `next` closes the chain: the step lands on or
    /// passes one of its first points (steps may skip points).
    fn closes(&self, chain: &[usize], next: usize) -> bool {
        if chain.len() <= 4 * CLOSE_WITHIN {
            return false;
        }
        let (here, there) = (self.points[chain[chain.len() - 1]], self.points[next]);
        chain[..CLOSE_WITHIN].iter().any(|&i| {
            let p = self.points[i];
            i == next || (p - here).dot(there - p) >= 0.0 && p.distance(here) < self.reach
        })
    }

    /// The point that best continues `chain` along `direction`: within
    /// reach and the angle, the one with the smallest distance weighted by
    /// its turn.
    fn step(&self, chain: &[usize], direction: DVec3) -> Option<usize> {
        let here = self.points[*chain.last()?];
        let recent = &chain[chain.len().saturating_sub(3)..];
        self.tree
            .within(here, self.reach)
            .into_iter()
            .filter(|n| n.distance > 0.0 && !recent.contains(&n.index))
            .filter_map(|n| {
                let cos = (self.points[n.index] - here).dot(direction) / n.distance;
                (cos >= STEP_COS).then(|| (n.distance * (2.0 - cos).powi(4), n.index))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, i)| i)
    }

    /// Current direction of a chain: from a few points back to its end,
    /// turned on by half the turn seen over that stretch (the chord lags
    /// the tangent on a bend).
    fn direction(&self, chain: &[usize]) -> Option<DVec3> {
        let n = chain.len();
        if n < 3 {
            let d = self.points[chain[n - 1]] - self.points[chain[0]];
            return d.try_normalize();
        }
        let back = 4.min(n - 1);
        let (a, m, b) = (
            self.points[chain[n - 1 - back]],
            self.points[chain[n - 1 - back / 2]],
            self.points[chain[n - 1]],
        );
        let (first, second) = ((m - a).try_normalize()?, (b - m).try_normalize()?);
        (second * 1.5 - first * 0.5).try_normalize()
    }
}

fn distance_to_segment(q: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t = ((q - a).dot(ab) / ab.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    q.distance(a + t * ab)
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// The direction of the line the points within `r` of `p` spread along, if
/// they do (principal axis; second eigenvalue small against the first).
fn line_direction(tree: &KdTree, points: &[DVec3], p: DVec3, r: f64) -> Option<DVec3> {
    let nb = tree.within(p, r);
    if nb.len() < 3 {
        return None;
    }
    let c = nb.iter().map(|n| points[n.index]).sum::<DVec3>() / nb.len() as f64;
    let mut m = [[0.0; 3]; 3];
    for n in &nb {
        let d = points[n.index] - c;
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += d[i] * d[j];
            }
        }
    }
    let (values, vectors) = symmetric_eigen3(m);
    (values[1] < LINE_RATIO * values[2]).then_some(vectors[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three orthogonal great circles of the unit sphere.
    fn great_circles(n: usize) -> Vec<Curve> {
        let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
        vec![
            Curve::circle(DVec3::ZERO, x, y, 1.0, n),
            Curve::circle(DVec3::ZERO, y, z, 1.0, n),
            Curve::circle(DVec3::ZERO, z, x, 1.0, n),
        ]
    }

    #[test]
    fn sphere_circles_give_radial_outward_normals() {
        let net = CurveNetwork::new(great_circles(200));
        assert_eq!(net.crossings.len(), 6);
        for (c, normals) in net.curves.iter().zip(&net.normals) {
            for (p, n) in c.points.iter().zip(normals) {
                let n = n.expect("every circle crosses another");
                assert!(n.dot(p.normalize()) > 0.999, "{p} {n}");
            }
        }
        // Circles bend everywhere: trusted normals only at the crossings.
        let trusted = net.samples(net.spacing, MAX_TURN);
        let given = trusted.iter().filter(|s| s.normal.is_some()).count();
        assert!((6..60).contains(&given), "{given} trusted normals");
        // Great circles are sections through the centre: the normal lies in
        // each circle's plane, so m is the radial direction and n·m = 1.
        for s in &trusted[6..] {
            let m = s.in_plane.expect("every circle is planar and crossed");
            assert!(m.direction.dot(s.position.normalize()) > 0.999, "{m:?}");
            assert!((m.share - 1.0).abs() < 1e-3, "{m:?}");
        }
        for x in &net.crossings {
            assert!(x.normal.dot(x.position.normalize()) > 0.999);
        }
    }

    #[test]
    fn torus_meridians_and_equators_give_the_torus_normal() {
        // Torus R = 1, r = 0.3 around z: four meridians, outer and inner equator.
        let (big, small) = (1.0, 0.3);
        let mut curves = vec![
            Curve::circle(DVec3::ZERO, DVec3::X, DVec3::Y, big + small, 300),
            Curve::circle(DVec3::ZERO, DVec3::X, DVec3::Y, big - small, 200),
        ];
        for k in 0..4 {
            let a = PI * 0.5 * k as f64 + 0.3;
            let radial = DVec3::new(a.cos(), a.sin(), 0.0);
            curves.push(Curve::circle(big * radial, radial, DVec3::Z, small, 80));
        }
        let net = CurveNetwork::new(curves);
        assert_eq!(net.crossings.len(), 8);
        for (c, normals) in net.curves.iter().zip(&net.normals) {
            for (p, n) in c.points.iter().zip(normals) {
                let ring = big * DVec3::new(p.x, p.y, 0.0).normalize();
                let truth = (*p - ring).normalize();
                assert!(n.unwrap().dot(truth) > 0.99, "{p} {n:?}");
            }
        }
    }

    #[test]
    fn sampled_crossing_circles_chain_into_curves() {
        let curves = great_circles(150);
        let points: Vec<DVec3> = curves.iter().flat_map(|c| c.points.clone()).collect();
        let chained = chain_points(&points).expect("points along curves");
        assert_eq!(
            chained.len(),
            3,
            "{:?}",
            chained.iter().map(|c| c.points.len()).collect::<Vec<_>>()
        );
        for c in &chained {
            assert!(c.closed);
            // Each chain stays on one great circle: its points span a plane
            // through the centre.
            let n = crate::normals::plane_normal(&c.points);
            let off = c.points.iter().map(|p| p.dot(n).abs()).fold(0.0, f64::max);
            assert!(off < 0.05, "off-plane {off}");
            assert!(c.points.len() >= 140);
        }
    }

    #[test]
    fn curves_crossing_within_one_plane_fix_no_normal() {
        let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
        // Two overlapping circles in the plane z = 0.3: no crossing.
        let flat = CurveNetwork::new(vec![
            Curve::circle(DVec3::new(-0.3, 0.0, 0.3), x, y, 0.5, 120),
            Curve::circle(DVec3::new(0.3, 0.0, 0.3), x, y, 0.5, 120),
        ]);
        assert!(flat.crossings.is_empty());
        assert_eq!(flat.crossed_curves(), 0);
        // The first with a circle in the plane y = 0 through its point
        // (0.2, 0, 0.3): one crossing, normal ±z.
        let across = CurveNetwork::new(vec![
            Curve::circle(DVec3::new(-0.3, 0.0, 0.3), x, y, 0.5, 120),
            Curve::circle(DVec3::new(0.2, 0.0, 0.8), x, z, 0.5, 120),
        ]);
        assert_eq!(across.crossings.len(), 1);
        assert!(across.crossings[0].normal.dot(z).abs() > 0.99);
    }

    #[test]
    fn surface_samples_are_not_curves() {
        let sphere = crate::shapes::icosphere(DVec3::ZERO, 1.0, 3);
        let points = crate::shapes::sample_surface(&sphere, 2000, 1).positions;
        assert!(chain_points(&points).is_none());
    }

    #[test]
    fn polylines_meeting_end_to_end_are_joined() {
        let c = Curve::circle(DVec3::ZERO, DVec3::X, DVec3::Y, 1.0, 40);
        let vertices = c.points.clone();
        // Two halves sharing vertices 0 and 20.
        let first: Vec<u32> = (0..=20).collect();
        let second: Vec<u32> = (20..40).chain([0]).collect();
        let p = Polylines {
            vertices,
            lines: vec![first, second],
        };
        let curves = curves_from_polylines(&p);
        assert_eq!(curves.len(), 1);
        assert!(curves[0].closed);
        assert_eq!(curves[0].points.len(), 40);
    }
}
