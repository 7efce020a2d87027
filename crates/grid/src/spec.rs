//! Regular grids in any dimension: node layout and per-node fields.

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
        for a in 0..D {
            idx[a] = l % self.dims[a];
            l /= self.dims[a];
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
}
