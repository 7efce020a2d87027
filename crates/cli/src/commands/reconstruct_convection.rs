//! The `--method convection` flags of `surfrecon reconstruct` (geometric
//! convection over the exact Delaunay tetrahedralization of the points):
//! `reconstruct.rs` flattens [`ConvectionArgs`] into its arguments and
//! hands [`ConvectionArgs::options`] to the facade.

/// Convection-specific flags of `surfrecon reconstruct --method convection`.
#[derive(clap::Args, Clone, Debug)]
pub struct ConvectionArgs {
    /// Decimation: the largest radius of the ball over which a kept point
    /// removes its neighbours, as a fraction of the bounding-box diagonal
    /// (0: keep every point).
    #[arg(long, default_value_t = 0.0)]
    pub rho: f64,
    /// Decimation, geometric criterion: a neighbour is removed only while
    /// |n_i · n(p)| exceeds this cosine (the paper's ρ, 0.9 to 0.98).
    #[arg(long = "rho-geom", default_value_t = 0.9)]
    pub rho_geom: f64,
    /// Decimation, topological-disk criterion ρ′: ... and while
    /// |n(p) · (p − p_i)/|p − p_i|| stays below this cosine (1: off).
    #[arg(long = "rho-topo", default_value_t = 0.95)]
    pub rho_topo: f64,
    /// Close boundary loops of at most this many edges left where the
    /// surface pinched (0: leave them open and report them).
    #[arg(long = "fill-holes", default_value_t = 24, value_name = "EDGES")]
    pub fill_holes: usize,
    /// Stop at the Gabriel convection: do not open pockets with normals.
    #[arg(long)]
    pub no_pockets: bool,
    /// Never put thin parts back inside (spike tips and thin fins swept by
    /// the convection stay cut off).
    #[arg(long)]
    pub no_thin_parts: bool,
    /// Neighbours used to estimate normals (pocket test) when the input has none.
    #[arg(long = "convection-normal-k", default_value_t = 12)]
    pub normal_k: usize,
}

impl ConvectionArgs {
    /// The facade's options for these flags.
    pub fn options(&self) -> surfrecon::ConvectionOptions {
        surfrecon::ConvectionOptions {
            rho: self.rho,
            rho_geom: self.rho_geom,
            rho_topo: self.rho_topo,
            fill_holes: self.fill_holes,
            pockets: !self.no_pockets,
            thin_parts: !self.no_thin_parts,
            normal_k: self.normal_k,
        }
    }
}
