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

use crate::band::{inside, join, NarrowBand, BORDER};
use rayon::prelude::*;
use surfrecon_grid::sweep::fast_sweep;
use surfrecon_grid::Field;

/// Recompute φ as signed distance in the band and rebuild the band list;
/// blocks left without band nodes become tiles again.
pub fn reinitialize<const D: usize>(band: &mut NarrowBand<D>) {
    let h = band.spec().spacing;
    let w = band.half_width;
    // Mark the old band so interface nodes just outside it can be found.
    let old_mark = next_epoch(band, 1);
    for &k in &band.active {
        band.marks[k as usize] = old_mark;
    }
    let interface = interface_nodes(band, old_mark);

    let max_layers = (w / h).ceil() as u32 + 2;
    let base = next_epoch(band, max_layers + 1);
    let b = &*band;
    let first: Vec<f64> = interface
        .par_iter()
        .map(|&k| interface_distance(b, k, h))
        .collect();
    let mut accepted = Vec::with_capacity(band.active.len() + interface.len());
    let mut frontier = Vec::with_capacity(interface.len());
    for (&k, &v) in interface.iter().zip(&first) {
        band.set(k, v);
        band.marks[k as usize] = base;
        accepted.push(k);
        frontier.push(k);
    }
    for layer in 1..max_layers {
        let candidates = next_layer(band, &frontier, base, base + layer);
        let b = &*band;
        // Each node's first value with its side, so the serial loops
        // below only write φ (reading it there, in layer order, missed the
        // cache at every node).
        let first: Vec<(f64, bool)> = candidates
            .par_iter()
            .map(|&k| {
                let v = godunov_from_layers(b, k, h, base, base + layer);
                (v, inside(b.value(k)))
            })
            .collect();
        let signed = |(v, was_inside): (f64, bool)| if was_inside { -v } else { v };
        for (&k, &f) in candidates.iter().zip(&first) {
            band.set(k, signed(f));
        }
        // A second (Jacobi) pass lets nodes of this layer lean on each other,
        // which the first pass could not: values only decrease towards the
        // true distance, and the order of nodes does not matter.
        let b = &*band;
        let values: Vec<f64> = (first.par_iter().zip(&candidates))
            .map(|(&(v, _), &k)| v.min(godunov_from_layers(b, k, h, base, base + layer + 1)))
            .collect();
        frontier.clear();
        for ((&k, &v), &f) in candidates.iter().zip(&values).zip(&first) {
            // The side of the value set above.
            let s = if inside(signed(f)) { -1.0 } else { 1.0 };
            if v < w {
                band.set(k, s * v);
                accepted.push(k);
                frontier.push(k);
            } else {
                band.set(k, s * w);
            }
        }
        if frontier.is_empty() {
            break;
        }
    }
    // Old band nodes no longer reached keep their side, clamped.
    let top = base + max_layers;
    for i in 0..band.active.len() {
        let k = band.active[i];
        if !(base..top).contains(&band.marks[k as usize]) {
            let v = band.value(k);
            band.set(k, if inside(v) { -w } else { w });
        }
    }
    // The last stamp reserved names the new band.
    for &k in &accepted {
        band.marks[k as usize] = top;
    }
    band.set_band(top);
}

/// φ as a signed distance on the whole (dense) grid: the band values are
/// kept and the rest is filled by fast sweeping from them (sign from the
/// side each node is on). Costs O(grid); only for writing the field out.
pub fn signed_distance_everywhere<const D: usize>(band: &NarrowBand<D>) -> Field<D> {
    let phi = band.phi.to_dense();
    if band.active.is_empty() {
        return phi;
    }
    let spec = phi.spec;
    let mut frozen = vec![false; spec.node_count()];
    let mut unsigned = Field::filled(spec, f64::INFINITY);
    for &k in &band.active {
        let l = spec.linear(band.node(k));
        frozen[l] = true;
        unsigned.values[l] = band.value(k).abs();
    }
    fast_sweep(&mut unsigned, &frozen);
    for (u, &v) in unsigned.values.iter_mut().zip(&phi.values) {
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

/// The neighbour of inner node `key` along `axis` as a key, allocating its
/// block if it is a tile; `None` within the border.
fn neighbour_key<const D: usize>(
    band: &mut NarrowBand<D>,
    key: u32,
    axis: usize,
    forward: bool,
) -> Option<u32> {
    let mut idx = band.node(key);
    idx[axis] = if forward {
        idx[axis] + 1
    } else {
        idx[axis].checked_sub(1)?
    };
    // `key` is inner, so only this axis can reach the border.
    if idx[axis] < BORDER || idx[axis] + BORDER >= band.spec().dims[axis] {
        return None;
    }
    if let (Some(n), _) = band.neighbour(key, band.block_values(key), axis, forward) {
        return Some(n);
    }
    band.allocate(idx);
    let (b, l) = band.phi.locate(idx)?;
    Some(join::<D>(b, l))
}

/// Band nodes with a sign change to a neighbour, plus such neighbours that
/// lie outside the band (the zero set may have reached the band's edge).
fn interface_nodes<const D: usize>(band: &mut NarrowBand<D>, old_mark: u32) -> Vec<u32> {
    let b = &*band;
    let mut nodes: Vec<u32> = band
        .active
        .par_iter()
        .copied()
        .filter(|&k| b.has_sign_change(k))
        .collect();
    let mut extra = Vec::new();
    for &k in &nodes {
        let s = inside(band.value(k));
        for a in 0..D {
            for f in [false, true] {
                if inside(band.value_at(k, a, f)) == s {
                    continue;
                }
                if let Some(n) = neighbour_key(band, k, a, f) {
                    if band.marks[n as usize] != old_mark {
                        band.marks[n as usize] = old_mark;
                        extra.push(n);
                    }
                }
            }
        }
    }
    nodes.extend(extra);
    nodes
}

/// Signed distance from node `key` to the interpolated zero set through
/// the grid edges at the node that cross it.
fn interface_distance<const D: usize>(band: &NarrowBand<D>, key: u32, h: f64) -> f64 {
    let values = band.block_values(key);
    let v = band.value(key);
    let s = inside(v);
    let mut inv_sq = 0.0;
    for a in 0..D {
        let mut da = f64::INFINITY;
        for forward in [false, true] {
            let vn = band.neighbour(key, values, a, forward).1;
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
/// The neighbours are found in parallel; stamping (and allocating the
/// blocks of tiles reached) follows in frontier order, so the result does
/// not depend on the thread count.
fn next_layer<const D: usize>(
    band: &mut NarrowBand<D>,
    frontier: &[u32],
    base: u32,
    stamp: u32,
) -> Vec<u32> {
    let b = &*band;
    let visited = |n: u32| (base..=stamp).contains(&b.marks[n as usize]);
    // Per frontier node, one slot per axis and direction: a fixed-size
    // table filled in parallel, no list grown per node or per thread.
    // (Keys hold 3 bits per axis below the block index.)
    debug_assert!(
        band.block_count() + 1 < 1 << (32 - 3 * D),
        "keys below the markers"
    );
    let mut found = vec![NOTHING; 2 * D * frontier.len()];
    found
        .par_chunks_mut(2 * D)
        .zip(frontier)
        .for_each(|(slots, &k)| {
            let values = b.block_values(k);
            for (j, slot) in slots.iter_mut().enumerate() {
                let (a, forward) = (j / 2, j % 2 == 1);
                *slot = match b.neighbour(k, values, a, forward).0 {
                    Some(n) if !visited(n) && inner_step(b, k, a, forward) => n,
                    Some(_) => NOTHING,
                    None => TILE,
                };
            }
        });
    let mut out = Vec::with_capacity(frontier.len());
    for (j, &f) in found.iter().enumerate() {
        let n = match f {
            NOTHING => continue,
            TILE => {
                let (k, a, forward) = (frontier[j / (2 * D)], j % (2 * D) / 2, j % 2 == 1);
                match neighbour_key(band, k, a, forward) {
                    Some(n) => n,
                    None => continue,
                }
            }
            n => n,
        };
        if (base..=stamp).contains(&band.marks[n as usize]) {
            continue;
        }
        band.marks[n as usize] = stamp;
        out.push(n);
    }
    out
}

/// Entries of [`next_layer`]'s table besides keys: no new neighbour, and
/// a step into a tile (whose block is allocated when stamped).
const NOTHING: u32 = u32::MAX;
const TILE: u32 = u32::MAX - 1;

/// Whether the neighbour of inner node `key` along `axis` is inner too
/// (only that axis can reach the border).
fn inner_step<const D: usize>(band: &NarrowBand<D>, key: u32, axis: usize, forward: bool) -> bool {
    let i = band.node(key)[axis];
    let n = if forward { i + 1 } else { i - 1 };
    n >= BORDER && n + BORDER < band.spec().dims[axis]
}

/// Upwind Godunov solution of |∇u| = 1 at `key` from the neighbours
/// stamped in `base..current` (earlier layers), using their absolute values.
fn godunov_from_layers<const D: usize>(
    band: &NarrowBand<D>,
    key: u32,
    h: f64,
    base: u32,
    current: u32,
) -> f64 {
    let values = band.block_values(key);
    let mut u = [f64::INFINITY; D];
    for (a, ua) in u.iter_mut().enumerate() {
        for forward in [false, true] {
            if let (Some(n), v) = band.neighbour(key, values, a, forward) {
                if (base..current).contains(&band.marks[n as usize]) {
                    *ua = ua.min(v.abs());
                }
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
        let band = NarrowBand::from_field(Field { spec, values }, 4.0 * spec.spacing).unwrap();
        (band, spec)
    }

    #[test]
    fn distorted_circle_becomes_signed_distance() {
        // φ = 3(r − R): same zero set, wrong slope.
        let (mut band, spec) = circle_band(3.0);
        reinitialize(&mut band);
        assert!(band.len() > 100);
        for &k in &band.active {
            let [x, y] = spec.position(band.node(k));
            let exact = (x * x + y * y).sqrt() - 0.6;
            let got = band.value(k);
            assert!((got - exact).abs() < 0.3 * spec.spacing, "{got} vs {exact}");
            assert!(got.abs() < band.half_width);
        }
    }
}
