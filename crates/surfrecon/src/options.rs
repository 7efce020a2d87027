//! What to run: the method with its own options, and what every method
//! shares. Every `Default` is the command line's default.

use std::path::PathBuf;

/// Options of [`crate::reconstruct`].
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The method, with its options.
    pub method: Method,
    /// Grid cells along the longest axis of the data [default: per method:
    /// level set and curve networks from the sampling density, SVM 200].
    pub resolution: Option<usize>,
    /// Span crossing curves (polylines, or points along curves) with a
    /// Hermite fit of the normals the crossings imply, whatever `method`
    /// says, when the data are such a network (as `surfrecon reconstruct`
    /// does unless `--no-curve-network`).
    pub curve_network: bool,
    /// On the curve-network path, join pieces of the surface that the
    /// curves do not keep apart (sections of one object give one solid;
    /// `surfrecon reconstruct` does unless `--keep-pieces`).
    pub join_pieces: bool,
    /// Measure how closely the surface reaches every datum (a pass over the
    /// data) into the report's `data_fit`.
    pub data_fit: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::LevelSet(LevelSetOptions::default()),
            resolution: None,
            curve_network: true,
            join_pieces: true,
            data_fit: false,
        }
    }
}

impl Options {
    /// Default options for `method`.
    pub fn with_method(method: Method) -> Self {
        Options {
            method,
            ..Options::default()
        }
    }
}

/// Reconstruction method.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Level-set method (Zhao, Osher, Fedkiw): distance, tagging,
    /// convection, minimal surface flow; no normals needed; points, curves
    /// and patches; closed curves for planar data.
    LevelSet(LevelSetOptions),
    /// Multi-scale SVM implicit surface fitted to oriented points
    /// (normals given or estimated).
    Svm(SvmOptions),
    /// Geometric convection through the Delaunay tetrahedralization: a
    /// mesh interpolating the points.
    Convection(ConvectionOptions),
}

impl Method {
    /// The name `--method` takes.
    pub fn name(&self) -> &'static str {
        match self {
            Method::LevelSet(_) => "levelset",
            Method::Svm(_) => "svm",
            Method::Convection(_) => "convection",
        }
    }
}

/// Which field a level-set run hands back besides the surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FieldOutput {
    /// None (the run keeps φ on its narrow band only).
    #[default]
    None,
    /// φ dense, exact on the narrow band and clamped beyond (enough for a
    /// thin shell).
    Band,
    /// The signed distance on the whole grid.
    Full,
}

/// Options of [`Method::LevelSet`] (`surfrecon reconstruct` flags).
#[derive(Clone, Debug, PartialEq)]
pub struct LevelSetOptions {
    /// Offset of the initial outer distance contour, in data units
    /// [default: from the sampling density].
    pub epsilon: Option<f64>,
    /// Exponent of the weighted area energy (∫ d^p ds)^(1/p), p ≥ 1.
    pub p: f64,
    /// Maximum minimal surface flow steps per resolution level.
    pub steps: usize,
    /// Narrow band half-width in cells.
    pub band: f64,
    /// Resolution levels, coarse to fine [default: automatic].
    pub levels: Option<usize>,
    /// Treat everything outside the data's bounding box as exterior.
    pub bounding_box: bool,
    /// Let tagging and evolution change the topology.
    pub free_topology: bool,
    /// Remove outliers and smooth noise first.
    pub cleaning: bool,
    /// Snap the surface onto the points and fair patches over gaps.
    pub refine: bool,
    /// Interpolate stacks of parallel contour slices between their 2D
    /// reconstructions.
    pub slices: bool,
    /// Reconstruct closed curves in the xy plane (also chosen when every z
    /// is equal).
    pub two_d: bool,
    /// The field to hand back in [`crate::Output::field`].
    pub field: FieldOutput,
}

impl Default for LevelSetOptions {
    fn default() -> Self {
        let p = surfrecon_levelset::ReconstructParams::default();
        LevelSetOptions {
            epsilon: None,
            p: p.p,
            steps: p.steps,
            band: p.band,
            levels: None,
            bounding_box: false,
            free_topology: false,
            cleaning: true,
            refine: true,
            slices: true,
            two_d: false,
            field: FieldOutput::None,
        }
    }
}

/// Residual penalty of the SVM fit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Loss {
    /// ε-insensitive (robust to outliers; the paper's choice).
    #[default]
    Epsilon,
    /// Squared loss (least squares).
    Squared,
}

/// The SVM's box constraint C.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SvmC {
    /// C relative to each level's local residual.
    Fixed(f64),
    /// C and ε chosen by validation on held-out points.
    Auto,
}

/// Options of [`Method::Svm`] (`--svm-*` flags).
#[derive(Clone, Debug, PartialEq)]
pub struct SvmOptions {
    pub c: SvmC,
    /// Width of the ε-insensitive tube relative to the bounding-box diagonal.
    pub epsilon: f64,
    /// Fitting accuracy relative to the diagonal.
    pub accuracy: f64,
    pub loss: Loss,
    /// Leave out the K finest levels when meshing.
    pub drop_levels: usize,
    /// Also save the fitted model (binary .svm format) here.
    pub model_out: Option<PathBuf>,
    /// Mesh a model saved earlier instead of fitting.
    pub model_in: Option<PathBuf>,
    /// Neighbours used to estimate normals when the input has none.
    pub normal_k: usize,
    /// Remove outliers and smooth noise first, as the level set does.
    pub cleaning: bool,
}

impl Default for SvmOptions {
    fn default() -> Self {
        SvmOptions {
            c: SvmC::Fixed(1.0),
            epsilon: surfrecon_svm::FitOptions::default().epsilon,
            accuracy: surfrecon_svm::FitOptions::default().accuracy,
            loss: Loss::Epsilon,
            drop_levels: 0,
            model_out: None,
            model_in: None,
            normal_k: 12,
            cleaning: true,
        }
    }
}

/// Options of [`Method::Convection`].
#[derive(Clone, Debug, PartialEq)]
pub struct ConvectionOptions {
    /// Decimation radius as a fraction of the diagonal (0: keep every point).
    pub rho: f64,
    /// Decimation, geometric criterion (cosine).
    pub rho_geom: f64,
    /// Decimation, topological-disk criterion (cosine; 1: off).
    pub rho_topo: f64,
    /// Decimate in the order a convection front reaches the points (the
    /// paper's on-the-fly scheme) instead of input order.
    pub decimate_on_the_fly: bool,
    /// Close boundary loops of at most this many edges (0: leave open).
    pub fill_holes: usize,
    /// Open pockets with normals after the Gabriel convection.
    pub pockets: bool,
    /// Put thin parts swept by the convection back inside.
    pub thin_parts: bool,
    /// Neighbours used to estimate normals when the input has none.
    pub normal_k: usize,
    /// The paper's brush: a decimation radius varying around a centre.
    pub brush: Option<surfrecon_convection::decimate::Brush>,
    /// Triangle-quality refinement after the decimation: largest
    /// circumradius-to-shortest-edge ratio (0: off).
    pub refine_alpha: f64,
    /// ... and smallest ratio of the vertex radii in a triangle (0: off).
    pub refine_gamma: f64,
    /// Leave holes in the sampling open (reported as boundary edges; the
    /// default) instead of covering them with faces far larger than the
    /// spacing (false: the output closed wherever the convection closes it).
    pub open_holes: bool,
    /// Flip edges where that lowers the surface's bending (across Delaunay
    /// tetrahedra, vertices unchanged).
    pub edge_flips: bool,
    /// Split edges where the smooth surface bends away from them (new
    /// vertices after the input points; not across sharp edges, not with
    /// decimation, not on noisy input).
    pub split_curved_edges: bool,
}

impl Default for ConvectionOptions {
    fn default() -> Self {
        let p = surfrecon_convection::Params::default();
        ConvectionOptions {
            rho: 0.0,
            rho_geom: 0.9,
            rho_topo: 0.95,
            decimate_on_the_fly: p.decimate_on_the_fly,
            fill_holes: 24,
            pockets: true,
            thin_parts: true,
            normal_k: p.normal_k,
            brush: None,
            refine_alpha: p.refine_alpha,
            refine_gamma: p.refine_gamma,
            open_holes: p.open_holes.is_some(),
            edge_flips: p.edge_flips,
            split_curved_edges: p.split_curved_edges,
        }
    }
}
