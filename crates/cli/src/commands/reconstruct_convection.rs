//! The `--method convection` flags of `surfrecon reconstruct` (geometric
//! convection over the exact Delaunay tetrahedralization of the points):
//! `reconstruct.rs` flattens [`ConvectionArgs`] into its arguments and
//! hands [`ConvectionArgs::options`] to the facade.

use surfrecon_convection::decimate::Brush;

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
    /// The paper's brush: within distance R of (X,Y,Z) (the points' units)
    /// the decimation radius goes from RHO_C at the centre (fraction of the
    /// diagonal, like --rho) back to --rho at distance R, as
    /// ρ + (ρ_c − ρ)/R²·(R² − d²). RHO_C below --rho keeps more detail there.
    #[arg(long, value_name = "X,Y,Z,R,RHO_C", value_parser = parse_brush, allow_hyphen_values = true)]
    pub brush: Option<Box<Brush>>,
    /// Triangle-quality refinement after the decimation (an error without --rho):
    /// removed points are put back where a surface triangle's
    /// circumradius-to-shortest-edge ratio reaches A (the paper's α; an
    /// equilateral triangle has 0.577; 0: off).
    #[arg(long = "refine-alpha", default_value_t = 0.0, value_name = "A")]
    pub refine_alpha: f64,
    /// ... or where the smallest of a triangle's vertex spacings is below
    /// G times the largest (the paper's density γ, 0 to 1; 0: off).
    #[arg(long = "refine-gamma", default_value_t = 0.0, value_name = "G")]
    pub refine_gamma: f64,
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
    /// Cover the holes in the sampling instead of leaving them open. By
    /// default patches of faces far longer than their vertices' sample
    /// spacing (several longer than 3.5 spacings, no sample inside) are
    /// removed and reported as boundary edges, as where a scanner saw
    /// nothing; with this flag the output stays closed wherever the
    /// convection closes it.
    #[arg(long)]
    pub cover_holes: bool,
    /// Accepted for old scripts: leaving sampling holes open is now the
    /// default.
    #[arg(long, hide = true, conflicts_with = "cover_holes")]
    pub open_holes: bool,
    /// Decimate (--rho) on the fly, in the order a convection front from
    /// the convex hull reaches the points (the paper's scheme: the points
    /// met first, tips and extremes, are kept; closer fit at the same
    /// --rho, several times slower) instead of in input order.
    #[arg(long)]
    pub on_the_fly: bool,
    /// Keep the convection's own triangles: do not flip edges where that
    /// lowers the surface's bending (the flips remove bevels across sharp
    /// edges; the vertices are the input points either way).
    #[arg(long)]
    pub no_edge_flips: bool,
    /// Keep the input points as the only vertices: do not split edges
    /// where the smooth surface bends away from them (by default such
    /// edges get a vertex on a cubic curve from the vertex normals, after
    /// the input points; never across sharp edges, with --rho or on noisy
    /// input).
    #[arg(long)]
    pub no_curved_splits: bool,
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
            decimate_on_the_fly: self.on_the_fly,
            fill_holes: self.fill_holes,
            pockets: !self.no_pockets,
            thin_parts: !self.no_thin_parts,
            normal_k: self.normal_k,
            brush: self.brush.as_deref().copied(),
            refine_alpha: self.refine_alpha,
            refine_gamma: self.refine_gamma,
            open_holes: !self.cover_holes,
            edge_flips: !self.no_edge_flips,
            split_curved_edges: !self.no_curved_splits,
        }
    }
}

/// `X,Y,Z,R,RHO_C`: five numbers; R above 0, RHO_C from 0 to 1.
fn parse_brush(s: &str) -> Result<Box<Brush>, String> {
    let bad = || format!("expected X,Y,Z,R,RHO_C (five numbers, e.g. 0,0,1,0.3,0.001), got {s:?}");
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    let [x, y, z, r, rho_c] = v[..] else {
        return Err(bad());
    };
    if !(x.is_finite() && y.is_finite() && z.is_finite() && r.is_finite() && r > 0.0) {
        return Err(format!(
            "brush centre must be finite and R above 0, got {s:?}"
        ));
    }
    if !(0.0..1.0).contains(&rho_c) {
        return Err(format!(
            "brush RHO_C must be from 0 to 1 (fraction of the diagonal), got {s:?}"
        ));
    }
    // Boxed: the reconstruct arguments stay small next to other commands'.
    Ok(Box::new(Brush {
        centre: surfrecon_geom::DVec3::new(x, y, z),
        radius: r,
        rho_centre: rho_c,
        exponent: 2,
    }))
}
