//! What a reconstruction reports, per method, as typed structs that
//! serialize to the keys `surfrecon reconstruct --json` prints (the
//! command adds "command", "input" and "output").

use serde::Serialize;
use surfrecon_geom::data_fit::DataFit;
pub use surfrecon_svm::curve_network::CurveFitReport;
pub use surfrecon_svm::joining::{GapReport, JoinReport};
pub use surfrecon_svm::multiscale::LevelReport;

/// The report of one [`crate::reconstruct`] run.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum Report {
    LevelSet(Box<LevelSetReport>),
    Svm(Box<SvmReport>),
    Convection(Box<ConvectionReport>),
    CurveNetwork(Box<CurveNetworkReport>),
}

impl Report {
    /// The method's name as the command line prints it.
    pub fn method(&self) -> &'static str {
        match self {
            Report::LevelSet(_) => "levelset",
            Report::Svm(_) => "svm",
            Report::Convection(_) => "convection",
            Report::CurveNetwork(_) => "curve-network",
        }
    }

    /// How closely the surface reaches the data (when asked for).
    pub fn data_fit(&self) -> Option<&DataFitReport> {
        match self {
            Report::LevelSet(r) => r.data_fit.as_ref(),
            Report::Svm(r) => r.data_fit.as_ref(),
            Report::Convection(r) => r.data_fit.as_ref(),
            Report::CurveNetwork(r) => r.data_fit.as_ref(),
        }
    }
}

/// Sizes of the result: a surface (triangles) or 2D curves.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
pub struct OutputCounts {
    pub vertices: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub triangles: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curves: Option<usize>,
}

impl OutputCounts {
    pub fn mesh(mesh: &surfrecon_geom::TriMesh) -> Self {
        OutputCounts {
            vertices: mesh.vertices.len(),
            triangles: Some(mesh.triangles.len()),
            curves: None,
        }
    }
}

/// The data fit, or why it could not be measured.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum DataFitReport {
    Fit(DataFit),
    Error { error: String },
}

/// `--method levelset`.
#[derive(Clone, Debug, Serialize)]
pub struct LevelSetReport {
    pub method: &'static str,
    pub dimension: usize,
    pub data: DataCounts,
    pub grid: GridReport,
    pub cleaning: CleaningReport,
    pub epsilon: f64,
    pub surfels: usize,
    pub densified: usize,
    pub tagging: TaggingReport,
    pub band_nodes: usize,
    pub band: BandReport,
    pub convection: Vec<EvolveReport>,
    pub flow: Vec<EvolveReport>,
    pub settle: Vec<EvolveReport>,
    pub refine: RefineReport,
    pub slices: Option<SlicesReport>,
    pub timings: Vec<StageTime>,
    pub seconds_total: f64,
    pub output_counts: OutputCounts,
    pub data_fit: Option<DataFitReport>,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct DataCounts {
    pub points: usize,
    pub segments: usize,
    pub triangles: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct GridReport {
    pub dims: Vec<usize>,
    pub spacing: f64,
    pub nodes: usize,
    pub levels: usize,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct CleaningReport {
    pub outliers_removed: usize,
    pub projected: usize,
    pub rms_shift: f64,
}

impl From<&surfrecon_levelset::cleaning::CleaningStats> for CleaningReport {
    fn from(stats: &surfrecon_levelset::cleaning::CleaningStats) -> Self {
        CleaningReport {
            outliers_removed: stats.outliers,
            projected: stats.projected,
            rms_shift: stats.rms_shift,
        }
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct TaggingReport {
    pub heap_pops: usize,
    pub inside_nodes: usize,
    pub removed_components: usize,
    pub grown_to_points: usize,
    pub restored_near_points: usize,
    pub reopened_near_points: usize,
    pub sealed_by_normals: usize,
    /// Lone nodes given their neighbours' side before extraction.
    pub lone_nodes: usize,
    /// Pieces of a stack of slices joined to the body.
    pub joined_parts: usize,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct BandReport {
    pub nodes: usize,
    pub blocks: usize,
    pub block_nodes: usize,
}

/// One evolution (convection, flow or settling) on one level.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct EvolveReport {
    pub steps: usize,
    pub converged: bool,
    /// "convergence" or "step cap".
    pub stopped_by: &'static str,
    pub last_change: f64,
    pub energy: f64,
    pub max_band: usize,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct RefineReport {
    pub snapped: usize,
    pub snapped_to_planes: usize,
    /// Of those, onto the line where two faces' planes meet (sharp edges).
    pub snapped_to_edges: usize,
    pub faired: usize,
    pub max_fairing_shift: f64,
    /// Faired vertices moved onto the quadric the rim's data continue.
    pub fitted_to_rim: usize,
    /// Exact data beyond half a cell the surface was pulled onto (cone
    /// tips, wedge apexes).
    pub reached_far_points: usize,
    /// Moved vertices put back where their faces crossed others.
    pub uncrossed: usize,
}

/// A stack of parallel contour slices, across `axis` (0 = x).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SlicesReport {
    pub axis: usize,
    pub count: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: String,
    pub seconds: f64,
}

/// `--method svm`.
#[derive(Clone, Debug, Serialize)]
pub struct SvmReport {
    pub method: &'static str,
    pub svm: SvmSummary,
    pub output_counts: OutputCounts,
    pub data_fit: Option<DataFitReport>,
    /// Neighbours normals were estimated from, when the input had none.
    #[serde(skip)]
    pub normals_estimated: Option<usize>,
}

#[derive(Clone, Debug, Serialize)]
pub struct SvmSummary {
    pub method: &'static str,
    pub fit: SvmFit,
    /// For contour slices: whether the surface fitted with the stack's
    /// added samples was kept (`None`: the input is no contour stack).
    pub contour_stack: Option<ContourStack>,
    pub centres: usize,
    pub levels_used: usize,
    /// Wall time besides meshing: preparing the points and fitting (both
    /// fits, with and without a contour stack's samples).
    pub fit_seconds: f64,
    /// Wall time meshing and refining (both meshes for a contour stack).
    pub mesh_seconds: f64,
    pub mesh: SvmMeshReport,
}

/// What became of the surface fitted with a contour stack's added samples
/// (mid-gap, end-cap and interpolated samples, guesses beside the
/// contours).
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ContourStack {
    /// Kept: no more pieces and no more handles than without the samples.
    Used,
    /// Kept without the end caps: with them the surface had more pieces
    /// or handles, without them not.
    UsedWithoutCaps,
    /// Kept without the end caps and the level set's interpolated
    /// samples: with those the surface had more pieces or handles.
    UsedWithoutInterpolation,
    /// The surface fitted to the contours alone kept: the samples added pieces.
    DroppedMorePieces,
    /// The surface fitted to the contours alone kept: the samples added handles.
    DroppedMoreHandles,
}

/// A fitted model, or one loaded from a file.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum SvmFit {
    Loaded { loaded: String },
    Fitted(Box<SvmFitReport>),
}

#[derive(Clone, Debug, Serialize)]
pub struct SvmFitReport {
    pub c: f64,
    pub epsilon: f64,
    pub accuracy: f64,
    pub loss: String,
    /// Validation trials when C was chosen automatically.
    pub selection: Option<Vec<SvmTrial>>,
    pub seconds: f64,
    pub diameter: f64,
    pub spacing: f64,
    pub noise_estimate: f64,
    pub isolated_samples: usize,
    /// Sample normals the fit turned round (they pointed against the
    /// coarser levels' surface beside them).
    pub normals_flipped: usize,
    pub epsilon_used: f64,
    pub accuracy_used: f64,
    pub min_width: f64,
    pub levels: Vec<LevelReport>,
    /// What cleaning did to the points before the fit (`None`: used as
    /// given: cleaning off, or the points are not noisy).
    pub cleaning: Option<CleaningReport>,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct SvmTrial {
    pub c: f64,
    pub epsilon: f64,
    pub validation_error: f64,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct SvmMeshReport {
    pub grid_dims: [usize; 3],
    pub spacing: f64,
    pub cells_visited: usize,
    pub nodes_evaluated: usize,
    /// Closed pieces under three cells dropped from the mesh.
    pub specks_removed: usize,
    /// Pieces of the fitted function's inside joined where they are
    /// thinner than a mesh cell (a thin tip the grid would cut into crumbs).
    pub thin_joins: usize,
    /// Mesh grid nodes set inside so that samples on parts thinner than a
    /// cell (a fin's rim, a cone's tip) are reached.
    pub thin_samples_reached: usize,
    /// Mesh grid nodes set inside to close pinholes the fitted function
    /// leaves through a sheet (barely open across it, a node or few wide).
    pub pinholes_filled: usize,
    /// Vertices moved onto the points' local fit (points used as measured).
    pub snapped: usize,
    /// Of the others, beside sharp edges, onto the nearest point's plane.
    pub snapped_to_planes: usize,
    /// Of those, onto the line where two faces' planes meet.
    pub snapped_to_edges: usize,
    /// Points farther than half a cell from the surface pulled onto: thin
    /// parts' tips the fit ends short of, and surface it misses.
    pub reached_far_points: usize,
    /// Snapped vertices put back where their faces crossed others.
    pub uncrossed: usize,
    pub vertices: usize,
    pub triangles: usize,
}

/// `--method convection`.
#[derive(Clone, Debug, Serialize)]
pub struct ConvectionReport {
    pub method: &'static str,
    pub convection: surfrecon_convection::Report,
    /// The input was found noisy, so no edges were flipped or split and
    /// the decimation ran in input order, not on the fly (tested only when
    /// flips, splits or the decimation on the fly are on).
    pub noisy_input: bool,
    /// The input is a stack of parallel contour slices, so no hole in the
    /// sampling was opened (the gaps between slices are no scanner's
    /// blind spots; tested only when holes are opened).
    pub sliced_input: bool,
    pub output_counts: OutputCounts,
    pub data_fit: Option<DataFitReport>,
}

/// A crossing curve network (chosen automatically).
#[derive(Clone, Debug, Serialize)]
pub struct CurveNetworkReport {
    pub method: &'static str,
    pub path: &'static str,
    pub curve_network: CurveFitReport,
    pub seconds_total: f64,
    pub output_counts: OutputCounts,
    pub data_fit: Option<DataFitReport>,
}
