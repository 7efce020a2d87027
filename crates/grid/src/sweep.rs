//! Fast sweeping for the Eikonal equation |∇u| = 1 on a regular grid.
//!
//! Gauss–Seidel iteration over the grid in the 2^D alternating orders (each
//! axis forwards or backwards), with the first-order Godunov upwind update:
//! at a node, take per axis the smaller of the two neighbour values, sort
//! these minima, and solve the discrete equation with one, then two, then
//! three terms until the solution no longer exceeds the next minimum. The
//! characteristics of every direction are followed by one of the orders, so
//! a few rounds of 2^D sweeps reach the fixed point (Zhao 2005).
//!
//! Used where only values are known (rebuilding a field from a thin shell,
//! reinitializing a level set). From data, [`crate::distance`] propagates
//! the closest datum instead, which is far more accurate (test
//! `godunov_sweeping_from_the_band_is_less_accurate`).

use crate::{Field, GridSpec};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Upper bound on full rounds (of 2^D sweeps each); the iteration normally
/// stops much earlier.
const MAX_ROUNDS: usize = 64;

/// A full round whose largest change is below this many grid spacings
/// ends the iteration. Later rounds only move values by amounts of this
/// order along long, nearly diagonal characteristics (the exact fixed point
/// can take ten times as many sweeps), far below the O(h) error of the
/// first-order scheme itself.
pub const SWEEP_TOLERANCE: f64 = 1e-9;

/// Solve |∇u| = 1 for nonnegative `u` given the values at `frozen` nodes.
///
/// Non-frozen nodes should start at `f64::INFINITY` (or at any upper bound
/// of their distance: values only ever decrease). Frozen nodes are never
/// changed. Iterates sweeps until one sweep changes no value (a fixed
/// point of the update), a full round of 2^D sweeps changes no value by
/// more than [`SWEEP_TOLERANCE`] grid spacings, or a bounded number of
/// rounds has run; returns the number of sweeps done. Only nodes beside
/// a change are evaluated again ("locking"), and large 3D grids are swept
/// by rayon's number of threads in a pipeline over planes; the values are
/// those of plain sequential Gauss–Seidel, bit for bit, whatever the
/// thread count.
///
/// # Panics
/// When `frozen.len()` differs from the node count (a programming error).
pub fn fast_sweep<const D: usize>(field: &mut Field<D>, frozen: &[bool]) -> usize {
    assert_eq!(
        frozen.len(),
        field.values.len(),
        "fast_sweep: one frozen flag per node"
    );
    let spec = field.spec;
    let mut unlocked = initially_unlocked(&spec, &field.values, frozen);
    let grid = SweepGrid {
        spec,
        values: field.values.as_mut_ptr(),
        unlocked: unlocked.as_mut_ptr(),
        frozen,
    };
    let threads = pipeline_threads(&spec);
    let mut sweeps = 0;
    for round in 0..MAX_ROUNDS {
        let mut largest_change = 0.0f64;
        for order in 0..1usize << D {
            sweeps += 1;
            let (change, changed) = grid.sweep(order, threads);
            largest_change = largest_change.max(change);
            // One complete sweep without change: every node satisfies its
            // update with the current values, so further sweeps are no-ops.
            if !changed && (round > 0 || order > 0) {
                return sweeps;
            }
        }
        if largest_change <= SWEEP_TOLERANCE * spec.spacing {
            return sweeps;
        }
    }
    sweeps
}

/// Threads for the pipelined sweeps: rayon's count, but one for small or
/// 2D grids (a 2D plane is a single line, so threads could not overlap).
fn pipeline_threads<const D: usize>(spec: &GridSpec<D>) -> usize {
    if D < 3 || spec.node_count() < 1 << 16 {
        return 1;
    }
    rayon::current_num_threads().clamp(1, spec.dims[D - 1])
}

/// A field being swept, shared by the threads of a pipelined sweep.
///
/// Invariant of [`SweepGrid::sweep`]: the planes along the last axis are
/// dealt round-robin to the threads, and a thread starts line `j` of a
/// plane only once the plane before has finished its line `j`. A node's
/// update reads its axis neighbours: in the plane before, already updated
/// in this sweep; in the plane after, not yet touched. Every node is thus
/// updated exactly as in sequential Gauss–Seidel order, whatever the
/// thread count, and no memory location is accessed by two threads
/// without a release/acquire on a plane's progress in between.
struct SweepGrid<'a, const D: usize> {
    spec: GridSpec<D>,
    values: *mut f64,
    unlocked: *mut bool,
    frozen: &'a [bool],
}

// SAFETY: see the invariant above.
unsafe impl<const D: usize> Sync for SweepGrid<'_, D> {}

impl<const D: usize> SweepGrid<'_, D> {
    /// One sweep in `order` (bit `a` set: axis `a` backwards), on
    /// `threads` threads; the largest decrease and whether any value
    /// changed.
    fn sweep(&self, order: usize, threads: usize) -> (f64, bool) {
        let planes = self.spec.dims[D - 1];
        let progress: Vec<AtomicUsize> = (0..planes).map(|_| AtomicUsize::new(0)).collect();
        let run = |first: usize| {
            let mut result = (0.0f64, false);
            for k in (first..planes).step_by(threads) {
                let previous = k.checked_sub(1).map(|p| &progress[p]);
                let (change, changed) = self.sweep_plane(order, k, previous, &progress[k]);
                result = (result.0.max(change), result.1 || changed);
            }
            result
        };
        if threads == 1 {
            return run(0);
        }
        std::thread::scope(|scope| {
            let workers: Vec<_> = (1..threads).map(|t| scope.spawn(move || run(t))).collect();
            workers
                .into_iter()
                .map(|w| w.join().expect("a sweep thread panicked"))
                .fold(run(0), |a, b| (a.0.max(b.0), a.1 || b.1))
        })
    }

    /// The `k`-th plane of the sweep, line by line, each after the same
    /// line of the plane before (`previous`); counts its lines done in
    /// `done`.
    fn sweep_plane(
        &self,
        order: usize,
        k: usize,
        previous: Option<&AtomicUsize>,
        done: &AtomicUsize,
    ) -> (f64, bool) {
        let dims = self.spec.dims;
        let strides = self.spec.strides();
        let along = |a: usize, i: usize| {
            if order >> a & 1 == 1 {
                dims[a] - 1 - i
            } else {
                i
            }
        };
        let lines: usize = dims[1..D - 1].iter().product();
        let mut idx = [0; D];
        idx[D - 1] = along(D - 1, k);
        let (mut largest_change, mut changed) = (0.0f64, false);
        for j in 0..lines {
            if let Some(previous) = previous {
                wait_until_above(previous, j);
            }
            let mut rest = j;
            for a in 1..D - 1 {
                idx[a] = along(a, rest % dims[a]);
                rest /= dims[a];
            }
            let row: usize = (1..D).map(|a| idx[a] * strides[a]).sum();
            for i in 0..dims[0] {
                idx[0] = along(0, i);
                // SAFETY: the invariant of `SweepGrid`.
                let change = unsafe { self.update(row + idx[0], &idx, &strides) };
                largest_change = largest_change.max(change);
                changed |= change > 0.0;
            }
            done.store(j + 1, Ordering::Release);
        }
        (largest_change, changed)
    }

    /// Evaluate node `l` at `idx` if unlocked; returns the decrease of its
    /// value (0 when none).
    ///
    /// # Safety
    /// No other thread touches `l` or its axis neighbours meanwhile.
    #[inline(always)]
    unsafe fn update(&self, l: usize, idx: &[usize; D], strides: &[usize; D]) -> f64 {
        if !*self.unlocked.add(l) {
            return 0.0;
        }
        *self.unlocked.add(l) = false;
        let dims = &self.spec.dims;
        let minima = &mut [f64::INFINITY; D];
        for a in 0..D {
            if idx[a] > 0 {
                minima[a] = *self.values.add(l - strides[a]);
            }
            if idx[a] + 1 < dims[a] {
                minima[a] = minima[a].min(*self.values.add(l + strides[a]));
            }
        }
        let u = godunov_update(minima, self.spec.spacing);
        let old = *self.values.add(l);
        if u >= old {
            return 0.0;
        }
        *self.values.add(l) = u;
        unlock_neighbours(&self.spec, strides, l, idx, self.frozen, self.unlocked);
        old - u
    }
}

/// Spin, then yield, until `progress` exceeds `line`.
fn wait_until_above(progress: &AtomicUsize, line: usize) {
    let mut spins = 0u32;
    while progress.load(Ordering::Acquire) <= line {
        if spins < 1 << 10 {
            std::hint::spin_loop();
            spins += 1;
        } else {
            std::thread::yield_now();
        }
    }
}

/// "Locking" (Bak, McLaughlin & Renzi 2010): a node is evaluated only
/// when a neighbour changed since its last evaluation. The update depends
/// on the neighbours alone, so skipping the others changes no value, and
/// late sweeps, which move few nodes, cost little more than a scan.
/// Initially: the free nodes beside a finite value.
fn initially_unlocked<const D: usize>(
    spec: &GridSpec<D>,
    values: &[f64],
    frozen: &[bool],
) -> Vec<bool> {
    let strides = spec.strides();
    let mut unlocked = vec![false; values.len()];
    let flags = unlocked.as_mut_ptr();
    for_each_node_ordered(&spec.dims, 0, |l, idx| {
        if values[l].is_finite() {
            // SAFETY: one flag per node, owned here.
            unsafe { unlock_neighbours(spec, &strides, l, idx, frozen, flags) };
        }
    });
    unlocked
}

/// Unlock the free axis neighbours of node `l` at `idx`.
///
/// # Safety
/// `unlocked` holds one flag per node, and no other thread touches these
/// neighbours' flags meanwhile.
#[inline(always)]
unsafe fn unlock_neighbours<const D: usize>(
    spec: &GridSpec<D>,
    strides: &[usize; D],
    l: usize,
    idx: &[usize; D],
    frozen: &[bool],
    unlocked: *mut bool,
) {
    for m in spec.axis_neighbours(l, idx, strides) {
        if !frozen[m] {
            *unlocked.add(m) = true;
        }
    }
}

/// Godunov upwind solution of |∇u| = 1 at a node whose per-axis neighbour
/// minima are `minima` (reordered in place). Returns `INFINITY` when no
/// neighbour has a value.
#[inline(always)]
pub fn godunov_update<const D: usize>(minima: &mut [f64; D], h: f64) -> f64 {
    sort_small(minima);
    let mut u = minima[0] + h;
    let (mut sum, mut sum_sq) = (minima[0], minima[0] * minima[0]);
    for (m, &next) in minima.iter().enumerate().skip(1) {
        if u <= next {
            break;
        }
        // Solve sum_k (u - a_k)^2 = h^2 over the m + 1 smallest minima.
        sum += next;
        sum_sq += next * next;
        let count = (m + 1) as f64;
        let disc = sum * sum - count * (sum_sq - h * h);
        u = (sum + disc.max(0.0).sqrt()) / count;
    }
    u
}

/// Insertion sort for the 2 or 3 per-axis minima (NaN-free by construction).
#[inline(always)]
fn sort_small<const D: usize>(v: &mut [f64; D]) {
    for i in 1..D {
        let mut j = i;
        while j > 0 && v[j - 1] > v[j] {
            v.swap(j - 1, j);
            j -= 1;
        }
    }
}

/// Visit every node of a grid of `dims` in sweep order `order`: bit `a` of
/// `order` set means axis `a` runs backwards. Calls `visit(linear, index)`;
/// axis 0 is the innermost loop, so memory is walked with stride 1.
#[inline(always)]
pub fn for_each_node_ordered<const D: usize>(
    dims: &[usize; D],
    order: usize,
    mut visit: impl FnMut(usize, &[usize; D]),
) {
    if dims.contains(&0) {
        return;
    }
    let backwards: [bool; D] = std::array::from_fn(|a| order >> a & 1 == 1);
    let start = |a: usize| if backwards[a] { dims[a] - 1 } else { 0 };
    let mut idx: [usize; D] = std::array::from_fn(start);
    let mut strides = [1usize; D];
    for a in 1..D {
        strides[a] = strides[a - 1] * dims[a - 1];
    }
    loop {
        let row: usize = (1..D).map(|a| idx[a] * strides[a]).sum();
        for step in 0..dims[0] {
            idx[0] = if backwards[0] {
                dims[0] - 1 - step
            } else {
                step
            };
            visit(row + idx[0], &idx);
        }
        // Odometer over the outer axes.
        let mut a = 1;
        loop {
            if a == D {
                return;
            }
            let at_end = if backwards[a] {
                idx[a] == 0
            } else {
                idx[a] + 1 == dims[a]
            };
            if !at_end {
                idx[a] = if backwards[a] { idx[a] - 1 } else { idx[a] + 1 };
                break;
            }
            idx[a] = start(a);
            a += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridSpec;

    fn spec<const D: usize>(n: usize, h: f64) -> GridSpec<D> {
        GridSpec {
            origin: [0.0; D],
            spacing: h,
            dims: [n; D],
        }
    }

    #[test]
    fn every_order_visits_every_node_once() {
        let dims = [3, 4, 5];
        for order in 0..8 {
            let mut seen = vec![0; 60];
            let mut first = None;
            for_each_node_ordered(&dims, order, |l, idx| {
                seen[l] += 1;
                first.get_or_insert(*idx);
                let g = GridSpec::<3> {
                    origin: [0.0; 3],
                    spacing: 1.0,
                    dims,
                };
                assert_eq!(g.linear(*idx), l);
            });
            assert!(seen.iter().all(|&c| c == 1));
            let f = first.unwrap();
            for a in 0..3 {
                let back = order >> a & 1 == 1;
                assert_eq!(f[a], if back { dims[a] - 1 } else { 0 });
            }
        }
    }

    #[test]
    fn plane_source_gives_exact_distance() {
        // A frozen column x = 0: the distance |x| is reproduced exactly.
        let g = spec::<2>(20, 0.1);
        let mut f = Field::filled(g, f64::INFINITY);
        let mut frozen = vec![false; g.node_count()];
        for j in 0..20 {
            let l = g.linear([0, j]);
            f.values[l] = 0.0;
            frozen[l] = true;
        }
        fast_sweep(&mut f, &frozen);
        for l in 0..g.node_count() {
            let x = g.position(g.unlinear(l))[0];
            assert!((f.values[l] - x).abs() < 1e-12);
        }
    }

    fn point_source_error<const D: usize>(n: usize) -> (f64, usize) {
        let h = 1.0 / (n - 1) as f64;
        let g = spec::<D>(n, h);
        let centre = [0.5; D];
        let dist = |l: usize| -> f64 {
            let p = g.position(g.unlinear(l));
            (0..D)
                .map(|a| (p[a] - centre[a]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let mut f = Field::filled(g, f64::INFINITY);
        let mut frozen = vec![false; g.node_count()];
        for (l, fixed) in frozen.iter_mut().enumerate() {
            if dist(l) <= 2.0 * h {
                f.values[l] = dist(l);
                *fixed = true;
            }
        }
        let sweeps = fast_sweep(&mut f, &frozen);
        let err = (0..g.node_count())
            .map(|l| (f.values[l] - dist(l)).abs())
            .fold(0.0, f64::max);
        (err, sweeps)
    }

    #[test]
    fn point_source_converges_at_first_order() {
        let (e2a, s2) = point_source_error::<2>(33);
        let (e2b, _) = point_source_error::<2>(65);
        assert!(e2a < 0.05 && e2b < 0.7 * e2a, "2D errors {e2a} {e2b}");
        assert!(s2 <= 3 * 4, "2D sweeps {s2}");
        let (e3a, s3) = point_source_error::<3>(17);
        let (e3b, _) = point_source_error::<3>(33);
        assert!(e3a < 0.08 && e3b < 0.8 * e3a, "3D errors {e3a} {e3b}");
        assert!(s3 <= 3 * 8, "3D sweeps {s3}");
    }

    /// Smaller of the two neighbour values of node `l` along one axis.
    #[inline(always)]
    fn axis_min(values: &[f64], l: usize, i: usize, n: usize, stride: usize) -> f64 {
        let lo = if i > 0 {
            values[l - stride]
        } else {
            f64::INFINITY
        };
        let hi = if i + 1 < n {
            values[l + stride]
        } else {
            f64::INFINITY
        };
        lo.min(hi)
    }

    /// Plain Gauss–Seidel with every node evaluated in every sweep and the
    /// same stopping rule, to check that locking changes nothing.
    fn sweep_every_node<const D: usize>(field: &mut Field<D>, frozen: &[bool]) -> usize {
        let (spec, h) = (field.spec, field.spec.spacing);
        let strides = spec.strides();
        let mut sweeps = 0;
        for round in 0..MAX_ROUNDS {
            let mut largest_change = 0.0f64;
            for order in 0..1usize << D {
                sweeps += 1;
                let mut changed = false;
                for_each_node_ordered(&spec.dims, order, |l, idx| {
                    let mut minima: [f64; D] = std::array::from_fn(|a| {
                        axis_min(&field.values, l, idx[a], spec.dims[a], strides[a])
                    });
                    let u = godunov_update(&mut minima, h);
                    if !frozen[l] && u < field.values[l] {
                        largest_change = largest_change.max(field.values[l] - u);
                        field.values[l] = u;
                        changed = true;
                    }
                });
                if !changed && (round > 0 || order > 0) {
                    return sweeps;
                }
            }
            if largest_change <= SWEEP_TOLERANCE * h {
                return sweeps;
            }
        }
        sweeps
    }

    #[test]
    fn same_values_as_plain_gauss_seidel_for_any_thread_count() {
        // Sources and a finite upper bound somewhere: curved fronts that
        // need several rounds, on a grid big enough to be pipelined.
        let g = spec::<3>(48, 0.02);
        let mut f = Field::filled(g, f64::INFINITY);
        let mut frozen = vec![false; g.node_count()];
        for (idx, v) in [([5, 7, 9], 0.0), ([30, 33, 20], 0.01), ([20, 2, 45], 0.02)] {
            f.values[g.linear(idx)] = v;
            frozen[g.linear(idx)] = true;
        }
        f.values[g.linear([47, 47, 0])] = 0.3;
        let mut plain = f.clone();
        let plain_sweeps = sweep_every_node(&mut plain, &frozen);
        assert!(
            plain_sweeps > 2 * 8,
            "{plain_sweeps} sweeps: too easy a test"
        );
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut swept = f.clone();
            let sweeps = pool.install(|| {
                assert_eq!(pipeline_threads(&g), threads);
                fast_sweep(&mut swept, &frozen)
            });
            assert_eq!(sweeps, plain_sweeps, "{threads} threads");
            assert!(swept == plain, "{threads} threads: values differ");
        }
    }

    #[test]
    fn godunov_update_matches_hand_solutions() {
        let h = 1.0;
        assert_eq!(godunov_update(&mut [0.0, f64::INFINITY], h), 1.0);
        // Two equal minima: u = a + h / sqrt(2).
        let u = godunov_update(&mut [2.0, 2.0], h);
        assert!((u - (2.0 + 0.5f64.sqrt())).abs() < 1e-14);
        // Far-apart minima keep the one-sided solution.
        assert_eq!(godunov_update(&mut [5.0, 1.0, 9.0], h), 2.0);
        let u = godunov_update(&mut [0.0; 3], h);
        assert!((u - 1.0 / 3f64.sqrt()).abs() < 1e-14);
        assert_eq!(godunov_update(&mut [f64::INFINITY; 3], h), f64::INFINITY);
    }
}
