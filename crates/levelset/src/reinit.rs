//! Reinitialization: make φ a signed distance function again in a narrow
//! band around its zero set, without moving the zero set.
//!
//! 1. Nodes next to a sign change get their distance to the interface,
//!    located by linear interpolation along each grid edge that crosses it
//!    (d = 1/√Σ 1/dₐ², exact for a planar interface).
//! 2. The band grows from them layer by layer (breadth first); each new
//!    node takes the upwind Godunov solution of |∇φ| = 1 from nodes of the
//!    previous layers. Growth stops at `half_width`.
//!
//! Work is proportional to the band size (surface area × width), never the
//! grid volume; each layer is computed in parallel from earlier layers only,
//! so the result is independent of the thread count.

use crate::band::{has_sign_change, inside, is_inner, NarrowBand};
use rayon::prelude::*;
use surfrecon_grid::sweep::fast_sweep;
use surfrecon_grid::Field;

/// Recompute φ as signed distance in the band and rebuild the band list.
pub fn reinitialize<const D: usize>(band: &mut NarrowBand<D>) {
    let spec = band.phi.spec;
    let h = spec.spacing;
    let strides = spec.strides();
    let w = band.half_width;
    // Mark the old band so interface nodes just outside it can be found.
    let old_mark = next_epoch(band, 1);
    for &l in &band.active {
        band.marks[l as usize] = old_mark;
    }
    let interface = interface_nodes(band, old_mark, &strides);

    let max_layers = (w / h).ceil() as u32 + 2;
    let base = next_epoch(band, max_layers + 1);
    let phi = &band.phi.values;
    let first: Vec<f64> = interface
        .par_iter()
        .map(|&l| interface_distance(phi, l as usize, &strides, h))
        .collect();
    let mut accepted = Vec::with_capacity(band.active.len() + interface.len());
    let mut frontier = Vec::with_capacity(interface.len());
    for (&l, &v) in interface.iter().zip(&first) {
        band.phi.values[l as usize] = v;
        band.marks[l as usize] = base;
        accepted.push(l);
        frontier.push(l);
    }
    for layer in 1..max_layers {
        let candidates = next_layer(band, &frontier, base, base + layer, &strides);
        let phi = &band.phi.values;
        let marks = &band.marks;
        let first: Vec<f64> = candidates
            .par_iter()
            .map(|&l| godunov_from_layers(phi, marks, l as usize, &strides, h, base, base + layer))
            .collect();
        // A second (Jacobi) pass lets nodes of this layer lean on each other,
        // which the first pass could not: values only decrease towards the
        // true distance, and the order of nodes does not matter.
        let mut values = first.clone();
        for (&l, &v) in candidates.iter().zip(&first) {
            let old = &mut band.phi.values[l as usize];
            *old = if inside(*old) { -v } else { v };
        }
        let phi = &band.phi.values;
        values.par_iter_mut().zip(&candidates).for_each(|(v, &l)| {
            let again =
                godunov_from_layers(phi, marks, l as usize, &strides, h, base, base + layer + 1);
            *v = v.min(again);
        });
        frontier.clear();
        for (&l, &v) in candidates.iter().zip(&values) {
            let s = if inside(band.phi.values[l as usize]) {
                -1.0
            } else {
                1.0
            };
            if v < w {
                band.phi.values[l as usize] = s * v;
                accepted.push(l);
                frontier.push(l);
            } else {
                band.phi.values[l as usize] = s * w;
            }
        }
        if frontier.is_empty() {
            break;
        }
    }
    // Old band nodes no longer reached keep their side, clamped.
    let top = base + max_layers;
    for &l in &band.active {
        let m = band.marks[l as usize];
        if !(base..top).contains(&m) {
            let v = &mut band.phi.values[l as usize];
            *v = if inside(*v) { -w } else { w };
        }
    }
    accepted.par_sort_unstable();
    band.active = accepted;
}

/// φ as a signed distance on the whole grid: the band values are kept and
/// the rest is filled by fast sweeping from them (sign from the side each
/// node is on). Costs O(grid); only for writing the field out.
pub fn signed_distance_everywhere<const D: usize>(band: &NarrowBand<D>) -> Field<D> {
    let spec = band.phi.spec;
    let mut frozen = vec![false; spec.node_count()];
    let mut unsigned = Field::filled(spec, f64::INFINITY);
    for &l in &band.active {
        frozen[l as usize] = true;
        unsigned.values[l as usize] = band.phi.values[l as usize].abs();
    }
    if band.active.is_empty() {
        return band.phi.clone();
    }
    fast_sweep(&mut unsigned, &frozen);
    for (u, &v) in unsigned.values.iter_mut().zip(&band.phi.values) {
        if inside(v) {
            *u = -*u;
        }
    }
    unsigned
}

/// Reserve `span` fresh stamp values and return the first; resets the
/// marks when the counter would overflow.
fn next_epoch<const D: usize>(band: &mut NarrowBand<D>, span: u32) -> u32 {
    if band.epoch.checked_add(span + 1).is_none() {
        band.marks.iter_mut().for_each(|m| *m = 0);
        band.epoch = 0;
    }
    let first = band.epoch + 1;
    band.epoch += span + 1;
    first
}

/// Band nodes with a sign change to a neighbour, plus such neighbours that
/// lie outside the band (the zero set may have reached the band's edge).
fn interface_nodes<const D: usize>(
    band: &mut NarrowBand<D>,
    old_mark: u32,
    strides: &[usize; D],
) -> Vec<u32> {
    let spec = band.phi.spec;
    let phi = &band.phi.values;
    let mut nodes: Vec<u32> = band
        .active
        .par_iter()
        .copied()
        .filter(|&l| has_sign_change(phi, l as usize, strides))
        .collect();
    let mut extra = Vec::new();
    for &l in &nodes {
        let l = l as usize;
        let s = inside(phi[l]);
        for &st in strides {
            for n in [l - st, l + st] {
                if band.marks[n] != old_mark && inside(phi[n]) != s && is_inner(&spec, n) {
                    band.marks[n] = old_mark;
                    extra.push(n as u32);
                }
            }
        }
    }
    nodes.extend(extra);
    nodes
}

/// Signed distance from node `l` to the interpolated zero set through the
/// grid edges at `l` that cross it.
fn interface_distance<const D: usize>(phi: &[f64], l: usize, strides: &[usize; D], h: f64) -> f64 {
    let v = phi[l];
    let s = inside(v);
    let mut inv_sq = 0.0;
    for &st in strides {
        let mut da = f64::INFINITY;
        for n in [l - st, l + st] {
            let vn = phi[n];
            if inside(vn) != s {
                let theta = v / (v - vn);
                da = da.min(theta.clamp(0.0, 1.0) * h);
            }
        }
        if da.is_finite() {
            inv_sq += 1.0 / (da * da).max(1e-300);
        }
    }
    let dist = if inv_sq > 0.0 { 1.0 / inv_sq.sqrt() } else { h };
    // Keep the side: a node exactly on the zero set is "inside" (φ ≤ 0).
    let dist = dist.max(1e-9 * h);
    if s {
        -dist
    } else {
        dist
    }
}

/// Unvisited inner neighbours of `frontier`, stamped `stamp`; nodes with a
/// stamp in `base..=stamp` were already visited by this reinitialization.
fn next_layer<const D: usize>(
    band: &mut NarrowBand<D>,
    frontier: &[u32],
    base: u32,
    stamp: u32,
    strides: &[usize; D],
) -> Vec<u32> {
    let spec = band.phi.spec;
    let mut out = Vec::new();
    for &l in frontier {
        let l = l as usize;
        for &st in strides {
            for n in [l - st, l + st] {
                if (base..=stamp).contains(&band.marks[n]) || !is_inner(&spec, n) {
                    continue;
                }
                band.marks[n] = stamp;
                out.push(n as u32);
            }
        }
    }
    out
}

/// Upwind Godunov solution of |∇u| = 1 at `l` from the neighbours stamped
/// in `base..current` (earlier layers), using their absolute values.
fn godunov_from_layers<const D: usize>(
    phi: &[f64],
    marks: &[u32],
    l: usize,
    strides: &[usize; D],
    h: f64,
    base: u32,
    current: u32,
) -> f64 {
    let known = |n: usize| (base..current).contains(&marks[n]);
    let mut u = [f64::INFINITY; D];
    for (a, &st) in strides.iter().enumerate() {
        for n in [l - st, l + st] {
            if known(n) {
                u[a] = u[a].min(phi[n].abs());
            }
        }
    }
    surfrecon_grid::sweep::godunov_update(&mut u, h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_grid::GridSpec;

    fn circle_band(scale: f64) -> (NarrowBand<2>, GridSpec<2>) {
        let spec = GridSpec::<2> {
            origin: [-1.0, -1.0],
            spacing: 0.05,
            dims: [41, 41],
        };
        let r = 0.6;
        let values = (0..spec.node_count())
            .map(|l| {
                let [x, y] = spec.position(spec.unlinear(l));
                scale * ((x * x + y * y).sqrt() - r)
            })
            .collect();
        let band = NarrowBand::from_field(Field { spec, values }, 4.0 * spec.spacing);
        (band, spec)
    }

    #[test]
    fn distorted_circle_becomes_signed_distance() {
        // φ = 3(r − R): same zero set, wrong slope.
        let (mut band, spec) = circle_band(3.0);
        reinitialize(&mut band);
        assert!(band.len() > 100);
        for &l in &band.active {
            let [x, y] = spec.position(spec.unlinear(l as usize));
            let exact = (x * x + y * y).sqrt() - 0.6;
            let got = band.phi.values[l as usize];
            assert!((got - exact).abs() < 0.3 * spec.spacing, "{got} vs {exact}");
            assert!(got.abs() < band.half_width);
        }
    }
}
