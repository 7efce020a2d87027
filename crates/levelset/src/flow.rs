//! Weighted minimal surface flow and the shared time stepping driver.
//!
//! Gradient flow of E(Γ) = (∫_Γ d^p ds)^(1/p), p ≥ 1:
//! φ_t = F · d^(p−1) · [∇d·∇φ + (1/p) d |∇φ| κ], F = (∫ d^p δ(φ)|∇φ| dx)^(1/p−1).
//! For p = 1 this is φ_t = ∇d·∇φ + d|∇φ|κ. The first term is upwinded (as
//! in convection), the curvature term uses central differences. d and ∇d
//! are taken at each node's closest point on the zero set and extended
//! along the normals (see `NodeSpeed`). Each node steps with its own
//! stable Δt ≤ h / (F d^(p−1) Σ|∂ₐd|) (advection) and
//! Δt ≤ h² / (2·dim·F d^p / p) (the curvature term is a diffusion with
//! coefficient F d^p/p): local time stepping, which leaves the steady
//! state unchanged and reaches it without waiting for the slowest node
//! (the surface spanning a wide hole, where d is large).
//!
//! [`evolve`] runs either motion on the narrow band: steps, reinitializes
//! before the zero set can leave the band, and stops when the zero set near
//! the data has stopped moving (mean displacement per step below a
//! tolerance) or after a maximum number of steps. With `keep_topology`, no
//! step changes the surface's topology.

use crate::anchors::{DataCells, TangentSides};
use crate::band::{det_sum, inside, par_filter_map, BandDistance, NarrowBand, Stencil};
#[cfg(doc)]
use crate::convection::advection_term;
use crate::convection::upwind_advection;
use crate::reinit::reinitialize;
use rayon::prelude::*;
use surfrecon_geom::progress::{Hook, Progress};
use surfrecon_geom::DVec3;
use surfrecon_grid::sparse::WINDOW;
use surfrecon_grid::topology::Neighbourhood;
use surfrecon_grid::GridSpec;

/// Which law moves the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Motion {
    /// φ_t = ∇d·∇φ.
    Convection,
    /// Gradient flow of (∫ d^p ds)^(1/p).
    MinimalSurface { p: f64 },
}

/// Time stepping controls shared by convection and minimal surface flow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvolveParams {
    /// Upper bound on time steps.
    pub max_steps: usize,
    /// Converged when the mean displacement per step of the zero set near
    /// the data falls below this fraction of the largest possible (the
    /// CFL fraction of a cell; for convection: of its speed scale).
    pub tolerance: f64,
    /// Fraction of the stable time step used.
    pub cfl: f64,
    /// Never change the surface's topology: a node changes side only if it
    /// is a simple point ([`crate::topology`]), so no handle opens or
    /// closes and no component splits off, merges or vanishes.
    pub keep_topology: bool,
}

impl Default for EvolveParams {
    fn default() -> Self {
        EvolveParams {
            max_steps: 200,
            tolerance: 0.02,
            cfl: 0.5,
            keep_topology: false,
        }
    }
}

/// What an evolution did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EvolveStats {
    pub steps: usize,
    pub reinitializations: usize,
    /// Whether the convergence test stopped it (rather than the step cap).
    pub converged: bool,
    /// Last measured mean zero-set speed, relative to the speed scale.
    pub last_change: f64,
    /// ∫ d^p δ(φ)|∇φ| at the end (the weighted area).
    pub energy: f64,
    /// Largest band size seen.
    pub max_band: usize,
    /// Whether the progress hook cancelled it.
    pub cancelled: bool,
}

/// Run `motion` on `band` until convergence or `params.max_steps`; ends
/// with a reinitialized band. `anchors` keep the surface on the data
/// ([`crate::anchors`]). `hook` hears of every measurement interval and
/// may cancel there (`stats.cancelled`).
pub fn evolve<const D: usize>(
    band: &mut NarrowBand<D>,
    d: &mut BandDistance<D>,
    motion: Motion,
    params: &EvolveParams,
    anchors: &Anchors<D>,
    hook: Hook,
) -> EvolveStats {
    let mut stats = EvolveStats::default();
    if band.is_empty() {
        return stats;
    }
    d.cover(band);
    let h = band.spec().spacing;
    let p = match motion {
        Motion::Convection => 1.0,
        Motion::MinimalSurface { p } => p,
    };
    // The zero set moves at most cfl·h per step; reinitialize before it can
    // come within a cell of the band's edge.
    let interval = (((band.half_width / h) - 1.0) / params.cfl.max(0.05) + 1e-9)
        .floor()
        .max(1.0) as usize;
    // An even number of steps between measurements: explicit steps near
    // the stability limit leave a period-two jitter of the zero set at the
    // data, which must not count as motion.
    let interval = if interval >= 2 {
        interval & !1
    } else {
        interval
    };
    let mut snapshot = zero_set_snapshot(band, d);
    // The flow's zero set from one interval earlier, with its step count.
    let mut earlier: Option<(Snapshot<D>, usize)> = None;
    stats.max_band = band.len();
    let guard = Guard {
        topology: params
            .keep_topology
            .then(|| Neighbourhood::new(&cube_strides::<D>())),
        anchors,
    };
    let stage = match motion {
        Motion::Convection => "convection",
        Motion::MinimalSurface { .. } => "flow",
    };
    while stats.steps < params.max_steps {
        let at = Progress {
            stage,
            done: stats.steps,
            total: params.max_steps,
        };
        if hook(at).is_break() {
            stats.cancelled = true;
            break;
        }
        // Only p ≠ 1 needs the energy while stepping (the factor F); the
        // report's energy is taken at the end.
        let factor = if p == 1.0 {
            1.0
        } else {
            stats.energy = weighted_area(band, d, p);
            global_factor(stats.energy, p)
        };
        let coef = Coefficients { motion, p, factor };
        let n = interval.min(params.max_steps - stats.steps);
        let change = match motion {
            Motion::Convection => {
                let (stable, speed_scale) = stable_step(band, d, &coef);
                let dt = stable * params.cfl;
                // Fixed until the reinitialization below changes the band.
                let grads = distance_gradients(band, d);
                for _ in 0..n {
                    convection_step(band, &grads, dt, &guard);
                }
                reinitialize(band);
                d.cover(band);
                // Mean zero-set speed relative to the motion's own speed
                // scale: small time steps do not fake convergence.
                zero_set_change(band, &snapshot) * h / (n as f64 * dt * speed_scale)
            }
            Motion::MinimalSurface { .. } => {
                for _ in 0..n {
                    // Speeds are recomputed every step: speeds frozen over
                    // several steps overshoot where the zero set crosses
                    // the data.
                    interface_step(band, d, &coef, params.cfl, &guard);
                }
                reinitialize(band);
                d.cover(band);
                // Every node moves at most `cfl` cells per step: the mean
                // displacement per step as a share of that, measured over
                // the last two intervals. Near the data the explicit
                // scheme leaves the zero set jittering in place by a small
                // fraction of a cell; over a longer span that jitter
                // averages out while a real drift adds up.
                let (base, span) = match earlier.take() {
                    Some((old, steps)) => (old, steps + n),
                    None => (snapshot.clone(), n),
                };
                earlier = Some((snapshot.clone(), n));
                zero_set_change(band, &base) / (span as f64 * params.cfl)
            }
        };
        stats.steps += n;
        stats.reinitializations += 1;
        stats.max_band = stats.max_band.max(band.len());
        stats.last_change = change;
        snapshot = zero_set_snapshot(band, d);
        if change < params.tolerance {
            stats.converged = true;
            break;
        }
    }
    stats.energy = weighted_area(band, d, p);
    stats
}

/// Per-node coefficients of the two terms.
struct Coefficients {
    motion: Motion,
    p: f64,
    factor: f64,
}

impl Coefficients {
    /// (advection coefficient, curvature coefficient) at distance `dist`.
    #[inline]
    fn at(&self, dist: f64) -> (f64, f64) {
        match self.motion {
            Motion::Convection => (1.0, 0.0),
            Motion::MinimalSurface { .. } if self.p == 1.0 => (1.0, dist),
            Motion::MinimalSurface { .. } => {
                let w = self.factor * dist.max(0.0).powf(self.p - 1.0);
                (w, w * dist / self.p)
            }
        }
    }
}

/// F = E^(1/p − 1); 1 for p = 1, and 1 for an empty surface.
fn global_factor(energy: f64, p: f64) -> f64 {
    if p == 1.0 || energy <= 0.0 || !energy.is_finite() {
        1.0
    } else {
        energy.powf(1.0 / p - 1.0)
    }
}

/// One explicit Euler step of convection on the band nodes, with ∇d per
/// band node from [`distance_gradients`]: d is fixed, so each step reads
/// only φ.
fn convection_step<const D: usize>(
    band: &mut NarrowBand<D>,
    grads: &[[f64; D]],
    dt: f64,
    guard: &Guard<D>,
) {
    let h = band.spec().spacing;
    let rates = band.map_active(false, None, |s| {
        dt * upwind_advection(s.phi, s.at, s.strides, &grads[s.index], h)
    });
    apply(band, rates, guard);
}

/// ∇d (per cell, central differences, as [`advection_term`] takes it) at
/// every band node, in band order.
fn distance_gradients<const D: usize>(band: &NarrowBand<D>, d: &BandDistance<D>) -> Vec<[f64; D]> {
    band.map_active_from([0.0; D], false, Some(d.grid()), |s| {
        s.strides.map(|st| (s.d[s.at + st] - s.d[s.at - st]) * 0.5)
    })
}

/// What keeps the evolving surface on the data ([`crate::anchors`]); the
/// default holds nothing.
pub struct Anchors<'a, const D: usize> {
    pub cells: Option<&'a DataCells<D>>,
    /// 3D only.
    pub sides: Option<&'a TangentSides<'a>>,
}

impl<const D: usize> Default for Anchors<'_, D> {
    fn default() -> Self {
        Anchors {
            cells: None,
            sides: None,
        }
    }
}

/// What may stop a node from changing side.
struct Guard<'a, const D: usize> {
    /// The simple point test (topology kept).
    topology: Option<Neighbourhood>,
    anchors: &'a Anchors<'a, D>,
}

impl<const D: usize> Guard<'_, D> {
    fn is_active(&self) -> bool {
        self.topology.is_some() || self.anchors.cells.is_some() || self.anchors.sides.is_some()
    }

    /// Whether the tangent planes let each node of `moves` move to its
    /// side (true: inside). The test reads only the node's position,
    /// nothing the evolution changes, so a step's crossings are all tested
    /// at once (and answers repeat, see [`TangentSides::allows_all`]).
    fn sides_allow(&self, spec: &GridSpec<D>, moves: &[([usize; D], bool)]) -> Vec<bool> {
        let Some(sides) = self.anchors.sides else {
            return vec![true; moves.len()];
        };
        let queries: Vec<(DVec3, bool)> = (moves.iter())
            .map(|&(node, to_inside)| {
                let p = spec.position(node);
                let p = DVec3::from_array(std::array::from_fn(|a| if a < D { p[a] } else { 0.0 }));
                (p, to_inside)
            })
            .collect();
        sides.allows_all(&queries)
    }

    /// Whether the data cells and the topology let `node` change side now
    /// (they read the sides of its neighbours, which earlier crossings of
    /// the same step may have changed).
    fn grid_allows(&self, band: &NarrowBand<D>, node: [usize; D], to_inside: bool) -> bool {
        let side = |idx: [usize; D]| inside(band.phi.get(idx));
        if let Some(cells) = self.anchors.cells {
            if !cells.allows(node, to_inside, side) {
                return false;
            }
        }
        // The neighbourhood is numbered in the node's own 3^D cube (see
        // `cube_strides`): no divisions by the grid's dimensions per
        // neighbour.
        let centre = (3usize.pow(D as u32) - 1) / 2;
        self.topology.as_ref().is_none_or(|cube| {
            cube.is_simple(centre, |n| {
                side(std::array::from_fn(|a| {
                    node[a] + n / 3usize.pow(a as u32) % 3 - 1
                }))
            })
        })
    }
}

/// Adds `updates` (one per band node) to φ. A node that would change side
/// does so only if `guard` allows it at that moment; such nodes are
/// visited in band order so the result is deterministic.
fn apply<const D: usize>(band: &mut NarrowBand<D>, updates: Vec<f64>, guard: &Guard<D>) {
    let guarded = guard.is_active();
    let crossings = band.add_active(&updates, |old, new| guarded && inside(new) != inside(old));
    let moves: Vec<([usize; D], bool)> = (crossings.iter())
        .map(|&(k, new)| (band.node(k), inside(new)))
        .collect();
    let sides = guard.sides_allow(band.spec(), &moves);
    for (&(k, new), sides_allow) in crossings.iter().zip(sides) {
        if sides_allow && guard.grid_allows(band, band.node(k), inside(new)) {
            band.set(k, new);
        }
    }
}

/// Strides of a 3^D cube, axis 0 fastest: the simple point test's
/// neighbourhood numbered around its centre, (3^D − 1) / 2.
fn cube_strides<const D: usize>() -> [usize; D] {
    std::array::from_fn(|a| 3usize.pow(a as u32))
}

/// Speed of one band node for the minimal surface flow, taken at the zero
/// set and extended along the normals: the weight d and the direction ∇d
/// found at the node's closest point on the zero set (x − φ n), not at the
/// node itself. Nodes next to the surface sit up to a cell off the data,
/// where d is a cell larger than on the surface; taking d there would
/// overweight the curvature term and shrink the surface by O(h²κ) and eat
/// thin features.
struct NodeSpeed<const D: usize> {
    /// Advection and curvature coefficients.
    advection: f64,
    curvature: f64,
    /// ∇d at the closest point, per cell.
    grad: [f64; D],
    /// The node's own stable time step (before the CFL fraction): local
    /// time steps reach the steady state, which they do not change,
    /// without the whole surface waiting for its slowest node.
    dt: f64,
}

fn node_speed<const D: usize>(
    s: &Stencil<D>,
    d: &BandDistance<D>,
    coef: &Coefficients,
    h: f64,
) -> NodeSpeed<D> {
    let (dist, grad) = at_interface(s, d, h);
    let (advection, curvature) = coef.at(dist);
    let rate: f64 = grad.iter().map(|g| g.abs()).sum::<f64>() * advection / h;
    let mut dt = h;
    if rate > 0.0 {
        dt = dt.min(h / rate);
    }
    if curvature > 0.0 {
        dt = dt.min(h * h / (2.0 * D as f64 * curvature));
    }
    NodeSpeed {
        advection,
        curvature,
        grad,
        dt,
    }
}

/// One explicit step of the minimal surface flow, each band node with its
/// extended speed (computed from the same φ, in the same pass).
fn interface_step<const D: usize>(
    band: &mut NarrowBand<D>,
    d: &BandDistance<D>,
    coef: &Coefficients,
    cfl: f64,
    guard: &Guard<D>,
) {
    let h = band.spec().spacing;
    let updates = band.map_active(true, Some(d.grid()), |s| {
        let sp = node_speed(s, d, coef, h);
        let mut rate = sp.advection * upwind_advection(s.phi, s.at, s.strides, &sp.grad, h);
        if sp.curvature != 0.0 {
            rate += sp.curvature * curvature_term(s.phi, s.at, s.strides, h);
        }
        cfl * sp.dt * rate
    });
    apply(band, updates, guard);
}

/// d and its gradient (per cell) at the point of the zero set closest to
/// the node, x − φ ∇φ/|∇φ|, by multilinear interpolation; the node's own
/// values where φ has no usable gradient (or, which the distance's
/// coverage of the band's neighbour blocks rules out for sane bands, where
/// that point's cell lies outside the computed distance).
fn at_interface<const D: usize>(s: &Stencil<D>, d: &BandDistance<D>, h: f64) -> (f64, [f64; D]) {
    let (at, st) = (s.at, s.strides);
    let own = || {
        let grad = std::array::from_fn(|a| (s.d[at + st[a]] - s.d[at - st[a]]) * 0.5);
        (s.d[at], grad)
    };
    let g: [f64; D] = std::array::from_fn(|a| (s.phi[at + st[a]] - s.phi[at - st[a]]) * 0.5);
    let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm.is_nan() || norm <= 1e-6 * h {
        return own();
    }
    let dims = d.grid().spec().dims;
    let shift = s.phi[at] / norm;
    let mut base = [0usize; D];
    let mut t = [0.0; D];
    for a in 0..D {
        let x = (s.node[a] as f64 - shift * g[a]).clamp(0.0, (dims[a] - 1) as f64);
        let i = (x.floor() as usize).min(dims[a] - 2);
        base[a] = i;
        t[a] = x - i as f64;
    }
    match cell_corners(s, d, base) {
        Some(values) => multilinear_with_gradient(&values, t),
        None => own(),
    }
}

/// d at the 2^D corners of the cell whose lowest corner is node `base`
/// (corner c is high along axis a when bit a of c is set): from the
/// block's window when the cell lies in the block or across one face of
/// it, else (the closest point may lie a few cells away) from the
/// distance's blocks; `None` if a corner's block has no distance.
fn cell_corners<const D: usize>(
    s: &Stencil<D>,
    d: &BandDistance<D>,
    base: [usize; D],
) -> Option<[f64; 8]> {
    debug_assert!(D <= 3, "cells of at most 8 corners");
    let mut values = [0.0; 8];
    let (mut w0, mut layers, mut in_window) = (0, 0, true);
    for ((&b, &corner), &stride) in base.iter().zip(&s.corner).zip(s.strides) {
        match (b + 1).checked_sub(corner) {
            Some(c) if c + 1 < WINDOW => {
                w0 += c * stride;
                layers += usize::from(c == 0) + usize::from(c + 2 == WINDOW);
            }
            _ => in_window = false,
        }
    }
    for (c, v) in values.iter_mut().enumerate().take(1 << D) {
        *v = if in_window && layers <= 1 {
            let w = (0..D).fold(w0, |w, a| w + (c >> a & 1) * s.strides[a]);
            s.d[w]
        } else {
            d.get(std::array::from_fn(|a| base[a] + (c >> a & 1)))?
        };
    }
    Some(values)
}

/// Value and gradient (per cell) of the multilinear interpolant of a
/// cell's corner values (ordered as in [`cell_corners`]) at offsets `t`.
fn multilinear_with_gradient<const D: usize>(values: &[f64; 8], t: [f64; D]) -> (f64, [f64; D]) {
    let mut value = 0.0;
    let mut grad = [0.0; D];
    for (corner, &v) in values.iter().enumerate().take(1 << D) {
        let mut w = 1.0;
        // Weight of this corner without axis a's factor, per axis.
        let mut partial = [1.0; D];
        for (a, &ta) in t.iter().enumerate() {
            let wa = if corner >> a & 1 == 1 { ta } else { 1.0 - ta };
            w *= wa;
            for (b, p) in partial.iter_mut().enumerate() {
                if b != a {
                    *p *= wa;
                }
            }
        }
        value += w * v;
        for a in 0..D {
            let sign = if corner >> a & 1 == 1 { 1.0 } else { -1.0 };
            grad[a] += sign * partial[a] * v;
        }
    }
    (value, grad)
}

/// |∇φ|κ at node `l` by central differences:
/// (Δφ |∇φ|² − ∇φᵀ H ∇φ) / |∇φ|², the Laplacian where ∇φ vanishes.
#[inline]
pub fn curvature_term<const D: usize>(phi: &[f64], l: usize, strides: &[usize; D], h: f64) -> f64 {
    let mut g = [0.0; D];
    let mut hess = [[0.0; D]; D];
    let c = phi[l];
    for a in 0..D {
        let (lo, hi) = (phi[l - strides[a]], phi[l + strides[a]]);
        g[a] = (hi - lo) * 0.5;
        hess[a][a] = hi - 2.0 * c + lo;
        for b in 0..a {
            let (sa, sb) = (strides[a], strides[b]);
            let m =
                (phi[l + sa + sb] - phi[l + sa - sb] - phi[l - sa + sb] + phi[l - sa - sb]) * 0.25;
            hess[a][b] = m;
            hess[b][a] = m;
        }
    }
    let g2: f64 = g.iter().map(|x| x * x).sum();
    let lap: f64 = (0..D).map(|a| hess[a][a]).sum();
    if g2 < 1e-12 {
        return lap / (h * h);
    }
    let mut ghg = 0.0;
    for a in 0..D {
        for b in 0..D {
            ghg += g[a] * hess[a][b] * g[b];
        }
    }
    (lap * g2 - ghg) / (g2 * h * h)
}

/// Largest stable Δt (before the CFL fraction) from the nodes near the
/// zero set, whose updates matter (farther band nodes are recomputed by the
/// next reinitialization anyway), and the mean advection coefficient there
/// (the motion's speed scale).
fn stable_step<const D: usize>(
    band: &NarrowBand<D>,
    d: &BandDistance<D>,
    coef: &Coefficients,
) -> (f64, f64) {
    let h = band.spec().spacing;
    let near = 2.5 * h;
    let per_node = band.map_active(false, Some(d.grid()), |s| {
        if s.phi[s.at].abs() >= near {
            return None;
        }
        let (a, c) = coef.at(s.d[s.at]);
        let grad_l1: f64 = s
            .strides
            .iter()
            .map(|&st| (s.d[s.at + st] - s.d[s.at - st]).abs() * 0.5 / h)
            .sum();
        Some((a * grad_l1, c, a))
    });
    let per_node = par_filter_map(&per_node, (0.0, 0.0, 0.0), |x| *x);
    // Maxima are the same in any order (f64::max skips NaN).
    let max_adv = per_node.par_iter().map(|x| x.0).reduce(|| 0.0, f64::max);
    let max_diff = per_node.par_iter().map(|x| x.1).reduce(|| 0.0, f64::max);
    let mean_adv = det_sum(&per_node, |x| x.2) / per_node.len().max(1) as f64;
    let mut dt = h;
    if max_adv > 0.0 {
        dt = dt.min(h / max_adv);
    }
    if max_diff > 0.0 {
        dt = dt.min(h * h / (2.0 * D as f64 * max_diff));
    }
    let scale = if mean_adv > 0.0 { mean_adv } else { 1.0 };
    (dt, scale)
}

/// ∫ d^p δ(φ)|∇φ| dx with a cosine-smoothed δ of half-width 1.5h. `d`
/// must cover the band ([`BandDistance::cover`]).
pub fn weighted_area<const D: usize>(band: &NarrowBand<D>, d: &BandDistance<D>, p: f64) -> f64 {
    let h = band.spec().spacing;
    let eps = 1.5 * h;
    let cell = h.powi(D as i32);
    let terms = band.map_active(false, Some(d.grid()), |s| {
        let v = s.phi[s.at];
        if v.abs() >= eps {
            return 0.0;
        }
        let delta = (1.0 + (std::f64::consts::PI * v / eps).cos()) / (2.0 * eps);
        let g2: f64 = s
            .strides
            .iter()
            .map(|&st| ((s.phi[s.at + st] - s.phi[s.at - st]) * 0.5 / h).powi(2))
            .sum();
        s.d[s.at].max(0.0).powf(p) * delta * g2.sqrt() * cell
    });
    det_sum(&terms, |&x| x)
}

/// Nodes next to the zero set and their φ at one moment.
type Snapshot<const D: usize> = Vec<([usize; D], f64)>;

/// Nodes farther than this many cells from the data do not count for
/// convergence.
const SUPPORTED_CELLS: f64 = 2.0;

/// φ at the nodes next to the zero set (|φ| ≤ h) that are near the data,
/// by node index (keys change when reinitialization releases blocks).
/// Convergence is judged there: where the surface spans a hole in the
/// data, nothing holds it, and the flow keeps reshaping it long after the
/// surface on the data has settled.
fn zero_set_snapshot<const D: usize>(band: &NarrowBand<D>, d: &BandDistance<D>) -> Snapshot<D> {
    let h = band.spec().spacing;
    let supported = |n: [usize; D]| d.get(n).is_some_and(|v| v <= SUPPORTED_CELLS * h);
    let next_to_zero = |k: u32| Some((band.node(k), band.value(k))).filter(|&(_, v)| v.abs() <= h);
    let placeholder = ([0; D], 0.0);
    let near: Snapshot<D> = par_filter_map(&band.active, placeholder, |&k| {
        next_to_zero(k).filter(|&(n, _)| supported(n))
    });
    if near.is_empty() {
        // No data near the surface at all (e.g. a single point): judge
        // the whole zero set.
        return par_filter_map(&band.active, placeholder, |&k| next_to_zero(k));
    }
    near
}

/// Mean displacement of the zero set since `snapshot`, in cells: the mean
/// change of φ at the nodes that were next to it, each capped at one cell.
fn zero_set_change<const D: usize>(band: &NarrowBand<D>, snapshot: &[([usize; D], f64)]) -> f64 {
    if snapshot.is_empty() {
        return 0.0;
    }
    let h = band.spec().spacing;
    let total = det_sum(snapshot, |&(n, old)| {
        ((band.phi.get(n) - old).abs() / h).min(1.0)
    });
    total / snapshot.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_grid::{Field, GridSpec};

    fn sphere_field(spec: GridSpec<3>, r: f64) -> Field<3> {
        let values = (0..spec.node_count())
            .map(|l| {
                let p = spec.position(spec.unlinear(l));
                (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - r
            })
            .collect();
        Field { spec, values }
    }

    #[test]
    fn curvature_of_a_sphere_is_two_over_r() {
        let spec = GridSpec::<3> {
            origin: [-1.0; 3],
            spacing: 0.05,
            dims: [41; 3],
        };
        let f = sphere_field(spec, 0.6);
        let strides = spec.strides();
        // A node at radius ≈ 0.6 on the x axis.
        let l = spec.linear([32, 20, 20]);
        let k = curvature_term(&f.values, l, &strides, spec.spacing);
        assert!((k - 2.0 / 0.6).abs() < 0.1, "κ = {k}");
    }

    #[test]
    fn weighted_area_of_sphere_with_unit_weight() {
        let spec = GridSpec::<3> {
            origin: [-1.0; 3],
            spacing: 0.04,
            dims: [51; 3],
        };
        let mut band = NarrowBand::from_field(sphere_field(spec, 0.6), 0.16).unwrap();
        crate::reinit::reinitialize(&mut band);
        let mut ones = BandDistance::dense(std::sync::Arc::new(Field::filled(spec, 1.0))).unwrap();
        ones.cover(&band);
        let area = weighted_area(&band, &ones, 1.0);
        let exact = 4.0 * std::f64::consts::PI * 0.36;
        assert!((area - exact).abs() / exact < 0.03, "{area} vs {exact}");
    }
}
