//! Regular grids in any dimension: node layout and per-node fields.
//!
//! Grids are placed over data bounds with [`GridSpec::from_bounds`] (sized by
//! a resolution or a spacing, with padding) and checked against the
//! machine's memory with [`GridSpec::check_memory`] before anything large is
//! allocated.

use crate::GridError;

/// How to size a grid placed over data bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GridSize {
    /// Number of cells along the longest axis of the bounds.
    Resolution(usize),
    /// Distance between neighbouring nodes.
    Spacing(f64),
}

/// Grids with more nodes than this are refused outright as absurd, whatever
/// the machine (2^40 nodes would be 8 TB of `f64`).
const MAX_NODES: usize = 1 << 40;

/// Share of the available memory a grid may claim: the rest of the process
/// (data, meshes, temporary buffers) needs room too.
const MEMORY_SHARE: f64 = 0.8;

/// Geometry of a regular grid of `dims` nodes in `D` dimensions.
///
/// Invariants: `spacing > 0`, every `dims[a] >= 2`. Node `idx` sits at
/// `origin + spacing * idx`; linear index has axis 0 fastest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec<const D: usize> {
    pub origin: [f64; D],
    pub spacing: f64,
    pub dims: [usize; D],
}

impl<const D: usize> GridSpec<D> {
    /// The range of node indices within `radius` of the box `lo..hi`,
    /// clamped to the grid; `None` when it misses the grid.
    pub fn node_box(
        &self,
        (lo, hi): ([f64; D], [f64; D]),
        radius: f64,
    ) -> Option<([usize; D], [usize; D])> {
        let mut first = [0usize; D];
        let mut last = [0usize; D];
        for a in 0..D {
            let top = (self.dims[a] - 1) as f64;
            let f = ((lo[a] - radius - self.origin[a]) / self.spacing).ceil();
            let l = ((hi[a] + radius - self.origin[a]) / self.spacing).floor();
            if f > top || l < 0.0 || f > l {
                return None;
            }
            first[a] = f.max(0.0) as usize;
            last[a] = l.min(top) as usize;
        }
        Some((first, last))
    }

    pub fn node_count(&self) -> usize {
        self.dims.iter().product()
    }

    /// Linear index of the node at `idx` (axis 0 fastest).
    #[inline]
    pub fn linear(&self, idx: [usize; D]) -> usize {
        let mut l = 0;
        for a in (0..D).rev() {
            l = l * self.dims[a] + idx[a];
        }
        l
    }

    /// Node index of linear index `l`.
    #[inline]
    pub fn unlinear(&self, mut l: usize) -> [usize; D] {
        let mut idx = [0; D];
        for (i, &n) in idx.iter_mut().zip(&self.dims) {
            *i = l % n;
            l /= n;
        }
        idx
    }

    /// Distance between linear indices of neighbours along each axis.
    pub fn strides(&self) -> [usize; D] {
        let mut s = [1; D];
        for a in 1..D {
            s[a] = s[a - 1] * self.dims[a - 1];
        }
        s
    }

    /// Linear indices of the axis neighbours of node `idx` (linear index
    /// `l`) that lie in the grid; `strides` as from [`Self::strides`].
    #[inline(always)]
    pub fn axis_neighbours<'a>(
        &'a self,
        l: usize,
        idx: &'a [usize; D],
        strides: &'a [usize; D],
    ) -> impl Iterator<Item = usize> + 'a {
        (0..D).flat_map(move |a| {
            let below = (idx[a] > 0).then(|| l - strides[a]);
            let above = (idx[a] + 1 < self.dims[a]).then(|| l + strides[a]);
            below.into_iter().chain(above)
        })
    }

    /// Position of node `idx`.
    #[inline]
    pub fn position(&self, idx: [usize; D]) -> [f64; D] {
        std::array::from_fn(|a| self.origin[a] + self.spacing * idx[a] as f64)
    }

    /// Continuous grid coordinates of a position (node units).
    #[inline]
    pub fn to_grid(&self, p: [f64; D]) -> [f64; D] {
        std::array::from_fn(|a| (p[a] - self.origin[a]) / self.spacing)
    }

    /// Far corner of the grid.
    pub fn max_corner(&self) -> [f64; D] {
        std::array::from_fn(|a| self.origin[a] + self.spacing * (self.dims[a] - 1) as f64)
    }

    /// A grid covering the box `min..max` plus `padding_cells` cells on every
    /// side, sized by `size`. The data box is centred in the grid (the
    /// rounding slack is split evenly). Refuses NaN or infinite bounds,
    /// `max < min`, non-positive sizes, a zero-extent box sized by
    /// resolution, absurd node counts (overflow, more than 2^40 nodes), and
    /// a spacing too fine for the coordinates' precision (below 2^-40 of
    /// the largest coordinate: see `check_precision`).
    pub fn from_bounds(
        min: [f64; D],
        max: [f64; D],
        size: GridSize,
        padding_cells: usize,
    ) -> Result<Self, GridError> {
        validate_bounds(&min, &max)?;
        let extent: [f64; D] = std::array::from_fn(|a| max[a] - min[a]);
        let spacing = spacing_for(&extent, size)?;
        let mut dims = [0usize; D];
        for a in 0..D {
            let cells = (extent[a] / spacing * (1.0 - 1e-12)).ceil();
            let nodes = cells + 1.0 + 2.0 * padding_cells as f64;
            if nodes.is_nan() || nodes > MAX_NODES as f64 {
                return Err(too_many_nodes());
            }
            dims[a] = (nodes as usize).max(2);
        }
        checked_node_count(&dims)?;
        let origin = std::array::from_fn(|a| {
            let slack = (dims[a] - 1) as f64 * spacing - extent[a];
            min[a] - 0.5 * slack
        });
        let spec = GridSpec {
            origin,
            spacing,
            dims,
        };
        check_precision(&spec)?;
        Ok(spec)
    }

    /// Bytes a grid with `bytes_per_node` bytes per node would take.
    pub fn memory_estimate(&self, bytes_per_node: usize) -> f64 {
        self.dims.iter().map(|&d| d as f64).product::<f64>() * bytes_per_node as f64
    }

    /// Refuse (with [`GridError::TooLarge`]) a grid that would need more than
    /// 80% of the machine's available memory (MemAvailable in
    /// /proc/meminfo, else MemTotal; unchecked when neither is readable).
    /// The error names the estimate, the memory the machine has, and a
    /// resolution that would fit.
    pub fn check_memory(&self, bytes_per_node: usize) -> Result<(), GridError> {
        match available_memory() {
            Some(have) => self.check_memory_against(bytes_per_node, have),
            None => Ok(()),
        }
    }

    /// [`GridSpec::check_memory`] against a given amount of memory (bytes).
    pub fn check_memory_against(&self, bytes_per_node: usize, have: f64) -> Result<(), GridError> {
        let need = self.memory_estimate(bytes_per_node);
        if need <= MEMORY_SHARE * have {
            return Ok(());
        }
        let shrink = (MEMORY_SHARE * have / need).powf(1.0 / D as f64);
        let longest_cells = self.dims.iter().max().map_or(1, |&d| d - 1);
        let fits = ((longest_cells as f64 * shrink).floor() as usize).max(1);
        Err(GridError::TooLarge {
            dims: self.dims_string(),
            need_mb: need / 1e6,
            have_mb: have / 1e6,
            suggestion: format!("--resolution {fits} or less"),
        })
    }

    /// Dimensions as `"300x212x136"`.
    pub fn dims_string(&self) -> String {
        let parts: Vec<String> = self.dims.iter().map(|d| d.to_string()).collect();
        parts.join("x")
    }
}

fn validate_bounds<const D: usize>(min: &[f64; D], max: &[f64; D]) -> Result<(), GridError> {
    for a in 0..D {
        if !min[a].is_finite() || !max[a].is_finite() {
            return Err(GridError::Invalid(format!(
                "bounds must be finite numbers, got min {min:?}, max {max:?} (empty or non-finite data?)"
            )));
        }
        if max[a] < min[a] {
            return Err(GridError::Invalid(format!(
                "bounds have max < min on axis {a}: min {min:?}, max {max:?}"
            )));
        }
    }
    Ok(())
}

fn spacing_for<const D: usize>(extent: &[f64; D], size: GridSize) -> Result<f64, GridError> {
    match size {
        GridSize::Spacing(h) if h.is_finite() && h > 0.0 => Ok(h),
        GridSize::Spacing(h) => Err(GridError::Invalid(format!(
            "spacing must be a positive number, got {h}"
        ))),
        GridSize::Resolution(0) => Err(GridError::Invalid(
            "resolution must be at least 1 cell".into(),
        )),
        GridSize::Resolution(n) if n > MAX_NODES => Err(too_many_nodes()),
        GridSize::Resolution(n) => {
            let longest = extent.iter().cloned().fold(0.0, f64::max);
            if longest > 0.0 {
                Ok(longest / n as f64)
            } else {
                Err(GridError::Invalid(
                    "the data occupy a single point, so a resolution gives no spacing; give a spacing instead".into(),
                ))
            }
        }
    }
}

/// Refuse a grid whose spacing is below 2^-40 of its largest coordinate:
/// f64 places a node `origin + spacing * i` only to an ulp of its
/// coordinates, so such a cell spans fewer than 2^12 ulps, and far below
/// it nodes merge (a mesh near 4e19 on a grid of spacing 106 had all its
/// nodes in x and y at one position, an ulp there being 8192, and the
/// surface extracted from it came out open).
fn check_precision<const D: usize>(spec: &GridSpec<D>) -> Result<(), GridError> {
    let largest = spec
        .origin
        .iter()
        .chain(&spec.max_corner())
        .fold(0.0f64, |m, c| m.max(c.abs()));
    if spec.spacing >= largest * MIN_RELATIVE_SPACING {
        return Ok(());
    }
    let ulp = 2f64.powi(largest.log2().floor() as i32 - 52);
    Err(GridError::Invalid(format!(
        "spacing {:.3e} is too fine for coordinates as large as {largest:.3e}, where f64 \
         places points only {ulp:.3e} apart; move the data near the origin or use a coarser grid",
        spec.spacing
    )))
}

/// See [`check_precision`].
const MIN_RELATIVE_SPACING: f64 = 1.0 / (1u64 << 40) as f64;

fn checked_node_count(dims: &[usize]) -> Result<usize, GridError> {
    dims.iter()
        .try_fold(1usize, |n, &d| n.checked_mul(d))
        .filter(|&n| n <= MAX_NODES)
        .ok_or_else(too_many_nodes)
}

fn too_many_nodes() -> GridError {
    GridError::Invalid(format!(
        "grid would have more than {MAX_NODES} nodes; use a coarser resolution or a larger spacing"
    ))
}

/// Bytes of memory available to a new allocation: MemAvailable from
/// /proc/meminfo, falling back to MemTotal; `None` off Linux.
pub fn available_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let field = |name: &str| -> Option<f64> {
        let line = text.lines().find(|l| l.starts_with(name))?;
        let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb * 1024.0)
    };
    field("MemAvailable:").or_else(|| field("MemTotal:"))
}

/// One `f64` per node of a grid. Invariant: `values.len() == spec.node_count()`.
#[derive(Clone, Debug, PartialEq)]
pub struct Field<const D: usize> {
    pub spec: GridSpec<D>,
    pub values: Vec<f64>,
}

pub type Field2 = Field<2>;
pub type Field3 = Field<3>;

impl<const D: usize> Field<D> {
    /// A field holding `value` at every node.
    pub fn filled(spec: GridSpec<D>, value: f64) -> Self {
        Field {
            values: vec![value; spec.node_count()],
            spec,
        }
    }

    #[inline]
    pub fn get(&self, idx: [usize; D]) -> f64 {
        self.values[self.spec.linear(idx)]
    }

    #[inline]
    pub fn set(&mut self, idx: [usize; D], v: f64) {
        let l = self.spec.linear(idx);
        self.values[l] = v;
    }
}

/// Visit every index of the box `first..=last` (axis 0 fastest).
#[inline(always)]
pub fn for_each_in_box<const D: usize>(
    first: [usize; D],
    last: [usize; D],
    mut visit: impl FnMut(&[usize; D]),
) {
    let mut idx = first;
    loop {
        visit(&idx);
        let mut a = 0;
        loop {
            if a == D {
                return;
            }
            if idx[a] < last[a] {
                idx[a] += 1;
                break;
            }
            idx[a] = first[a];
            a += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_index_round_trips() {
        let g = GridSpec::<3> {
            origin: [0.0; 3],
            spacing: 0.5,
            dims: [4, 5, 6],
        };
        for l in 0..g.node_count() {
            assert_eq!(g.linear(g.unlinear(l)), l);
        }
        assert_eq!(g.strides(), [1, 4, 20]);
        assert_eq!(g.position([1, 2, 3]), [0.5, 1.0, 1.5]);
        assert_eq!(g.max_corner(), [1.5, 2.0, 2.5]);
    }

    #[test]
    fn from_bounds_refuses_spacings_below_the_coordinates_precision() {
        // The fuzzer's udf grid: spacing 106 at 4e19 (an ulp is 8192).
        let e = GridSpec::<3>::from_bounds(
            [-4e19, -4e19, -212.66],
            [-4e19, -4e19, 212.66],
            GridSize::Resolution(4),
            1,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("too fine for coordinates as large as 4.000e19")
                && e.contains("8.192e3 apart"),
            "{e}"
        );
        // At 1e6, a cell of 1e-6 spans 8590 ulps: kept; 1e-7 is refused.
        let (lo, hi) = ([1e6, 0.0], [1e6 + 1e-5, 1e-5]);
        assert!(GridSpec::<2>::from_bounds(lo, hi, GridSize::Resolution(10), 1).is_ok());
        assert!(GridSpec::<2>::from_bounds(lo, hi, GridSize::Resolution(100), 1).is_err());
        // Near the origin any spacing is fine.
        let tiny = GridSpec::<2>::from_bounds([0.0; 2], [1e-200; 2], GridSize::Resolution(8), 1);
        assert!(tiny.is_ok());
    }

    #[test]
    fn from_bounds_by_resolution_covers_and_centres_the_data() {
        let g = GridSpec::<3>::from_bounds(
            [0.0, 0.0, 0.0],
            [2.0, 1.0, 0.5],
            GridSize::Resolution(20),
            2,
        )
        .unwrap();
        assert!((g.spacing - 0.1).abs() < 1e-15);
        assert_eq!(g.dims, [25, 15, 10]);
        let hi = g.max_corner();
        for a in 0..3 {
            let lo_gap = [0.0, 0.0, 0.0][a] - g.origin[a];
            let hi_gap = hi[a] - [2.0, 1.0, 0.5][a];
            assert!(lo_gap >= 2.0 * g.spacing - 1e-12);
            assert!((lo_gap - hi_gap).abs() < 1e-12, "centred on axis {a}");
        }
    }

    #[test]
    fn from_bounds_by_spacing_and_degenerate_axes() {
        let g =
            GridSpec::<2>::from_bounds([1.0, 5.0], [2.05, 5.0], GridSize::Spacing(0.5), 0).unwrap();
        assert_eq!(g.spacing, 0.5);
        assert_eq!(g.dims, [4, 2]);
        assert!(g.origin[0] <= 1.0 && g.max_corner()[0] >= 2.05);
        assert!(g.origin[1] <= 5.0 && g.max_corner()[1] >= 5.0);
    }

    #[test]
    fn from_bounds_refuses_bad_input() {
        let bad = [
            GridSpec::<3>::from_bounds([f64::NAN; 3], [1.0; 3], GridSize::Resolution(8), 0),
            GridSpec::<3>::from_bounds([1.0; 3], [0.0; 3], GridSize::Resolution(8), 0),
            GridSpec::<3>::from_bounds([0.0; 3], [1.0; 3], GridSize::Resolution(0), 0),
            GridSpec::<3>::from_bounds([0.0; 3], [1.0; 3], GridSize::Spacing(-1.0), 0),
            GridSpec::<3>::from_bounds([0.0; 3], [1.0; 3], GridSize::Spacing(f64::NAN), 0),
            GridSpec::<3>::from_bounds([0.0; 3], [0.0; 3], GridSize::Resolution(8), 1),
            GridSpec::<3>::from_bounds([0.0; 3], [1.0; 3], GridSize::Spacing(1e-300), 0),
            GridSpec::<3>::from_bounds([0.0; 3], [1.0; 3], GridSize::Resolution(usize::MAX), 0),
        ];
        for r in bad {
            assert!(matches!(r, Err(GridError::Invalid(_))), "{r:?}");
        }
        let point = GridSpec::<3>::from_bounds([1.0; 3], [1.0; 3], GridSize::Spacing(0.1), 1);
        assert_eq!(point.unwrap().dims, [3, 3, 3]);
    }

    #[test]
    fn memory_check_refuses_with_a_fitting_suggestion() {
        let g =
            GridSpec::<3>::from_bounds([0.0; 3], [1.0; 3], GridSize::Resolution(1000), 0).unwrap();
        assert!(g.check_memory_against(8, 1e12).is_ok());
        let err = g.check_memory_against(8, 1e9).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("1001x1001x1001"), "{msg}");
        assert!(msg.contains("8024 MB") && msg.contains("1000 MB"), "{msg}");
        let GridError::TooLarge { suggestion, .. } = err else {
            panic!("wrong variant");
        };
        let n: usize = suggestion
            .split_whitespace()
            .nth(1)
            .unwrap()
            .parse()
            .unwrap();
        let smaller =
            GridSpec::<3>::from_bounds([0.0; 3], [1.0; 3], GridSize::Resolution(n), 0).unwrap();
        assert!(smaller.check_memory_against(8, 1e9).is_ok());
        assert!(n > 400, "suggestion {n} should not be needlessly small");
    }
}
