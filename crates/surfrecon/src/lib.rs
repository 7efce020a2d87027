//! surfrecon: surface reconstruction from points, curves and triangle
//! patches through one call, whatever the method.
//!
//! ```no_run
//! let input = surfrecon::io::read("data/bunny/bunny.ply")?;
//! let output = surfrecon::reconstruct(&input, &surfrecon::Options::default())?;
//! surfrecon::io::write("bunny_surface.ply", &surfrecon::Geometry::from_mesh(output.mesh))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`reconstruct`] takes the data ([`Input`]: points with optional normals,
//! polylines, triangles — what a file holds) and [`Options`] (the
//! [`Method`] with its own options, each with the command line's defaults)
//! and returns one [`Output`]: the mesh (or 2D curves), the field when
//! asked for, and a typed [`Report`] that serializes to the keys
//! `surfrecon reconstruct --json` prints. [`reconstruct_with`] also takes a
//! progress-and-cancel [`Hook`]. Crossing curve networks are detected and
//! spanned by a Hermite fit whatever the method, as the command line does.
//!
//! The method crates (surfrecon-levelset, -svm, -convection, -distfield)
//! stay available for finer control; this crate re-exports what a user
//! needs so that it is the only dependency to add.

mod convection;
mod curves;
mod error;
mod levelset;
pub mod morph;
mod options;
mod report;
mod stack;
mod svm;

pub use curves::detect as detect_curve_network;
pub use error::{Error, ErrorKind, Result};
pub use levelset::is_planar;
pub use morph::{morph, Morph, MorphOptions};
pub use options::*;
pub use report::*;
pub use svm::DEFAULT_RESOLUTION as SVM_DEFAULT_RESOLUTION;

pub use surfrecon_geom::progress::{no_progress, ControlFlow, Hook, Progress};
pub use surfrecon_geom::{io, Aabb, DVec3, Geometry, PointCloud, Polylines, TriMesh};
pub use surfrecon_grid::{field_io, shell, Field, Field2, Field3, GridSpec};
/// The geometry, grid and distance-field crates, for what the facade does
/// not wrap (metrics, fields, sharp-feature fields).
pub use {surfrecon_distfield as distfield, surfrecon_geom as geom, surfrecon_grid as grid};

/// The method crates, for finer control than [`Options`] gives.
pub mod methods {
    pub use surfrecon_convection as convection;
    pub use surfrecon_levelset as levelset;
    pub use surfrecon_svm as svm;
}

/// The data to reconstruct from: points (with optional normals),
/// polylines and triangles over them, as [`io::read`] returns them.
pub type Input = Geometry;
/// A triangle mesh (vertices and indexed triangles).
pub type Mesh = TriMesh;

/// The result of [`reconstruct`].
#[derive(Clone, Debug)]
pub struct Output {
    /// The closed surface (empty for 2D data, see `curves`).
    pub mesh: Mesh,
    /// 2D data: the closed curves in the xy plane.
    pub curves: Option<Polylines>,
    /// The level set's field, when [`LevelSetOptions::field`] asks for it.
    pub field: Option<OutputField>,
    pub report: Report,
}

impl Output {
    /// The mesh, or the curves for 2D data, as a [`Geometry`] to write.
    pub fn into_geometry(self) -> Geometry {
        match self.curves {
            Some(curves) => Geometry::from_polylines(curves),
            None => Geometry::from_mesh(self.mesh),
        }
    }
}

/// A field on a 2D or a 3D grid.
#[derive(Clone, Debug)]
pub enum OutputField {
    Two(Field2),
    Three(Field3),
}

/// Reconstruct a surface (or, for planar data with the level set, closed
/// curves) from `input`.
pub fn reconstruct(input: &Input, options: &Options) -> Result<Output> {
    reconstruct_with(input, options, &no_progress)
}

/// [`reconstruct`] reporting its stages and iterations to `hook`: between
/// stages, at every measurement interval of the level-set evolutions and
/// every SVM level. When the hook returns `ControlFlow::Break`, the run
/// stops there and returns an error of kind [`ErrorKind::Cancelled`].
pub fn reconstruct_with(input: &Input, options: &Options, hook: Hook) -> Result<Output> {
    check(hook, "start")?;
    check_scale(input)?;
    let network = options
        .curve_network
        .then(|| curves::detect(input))
        .flatten();
    let (resolution, fit) = (options.resolution, options.data_fit);
    let output = match (&network, &options.method) {
        (Some(network), _) => curves::run(input, network, options, fit),
        (None, Method::LevelSet(o)) => levelset::run(input, o, resolution, fit, hook),
        (None, Method::Svm(o)) => svm::run(input, o, resolution, fit, hook),
        (None, Method::Convection(o)) => convection::run(input, o, fit, hook),
    }?;
    let method = match network {
        Some(_) => "curve-network",
        None => options.method.name(),
    };
    require_surface(&output, method)?;
    check(hook, "done")?;
    Ok(output)
}

/// Largest coordinate magnitude, and smallest non-zero data extent, the
/// methods support: squared distances, kernel values and products of
/// coordinates must stay inside the f64 range (near 1e300 a k-d tree
/// search compared NaN distances and panicked).
const MAX_COORDINATE: f64 = 1e100;
const MIN_EXTENT: f64 = 1e-100;

/// Refuse data too large or too small in magnitude for the methods.
fn check_scale(input: &Input) -> Result<()> {
    let positions = &input.points.positions;
    if positions.is_empty() || positions.iter().any(|p| !p.is_finite()) {
        return Ok(()); // each method names these errors itself
    }
    let largest = positions
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0, f64::max);
    // The largest side (a diagonal of tiny sides would underflow to 0).
    let extent = input.bounds().size().max_element();
    let message = if largest > MAX_COORDINATE {
        format!("the data reach coordinate {largest:e}; at most {MAX_COORDINATE:e} is supported: rescale the data")
    } else if extent > 0.0 && extent < MIN_EXTENT {
        format!(
            "the data span only {extent:e}; at least {MIN_EXTENT:e} is supported: rescale the data"
        )
    } else {
        return Ok(());
    };
    Err(Error::new(ErrorKind::InvalidInput, message))
}

/// An empty result is an error rather than a file without faces: the
/// method found nothing to close (zero-volume data such as a flat or
/// collinear set, data too sparse for the grid, or a loaded SVM model
/// whose surface does not pass near the data).
fn require_surface(output: &Output, method: &str) -> Result<()> {
    let empty = match &output.curves {
        Some(curves) => curves.lines.is_empty(),
        None => output.mesh.triangles.is_empty(),
    };
    if empty {
        return Err(Error::new(
            ErrorKind::Failed,
            format!(
                "the {method} reconstruction found no surface (flat, collinear or too sparse data for the grid, or a model that does not fit the data)"
            ),
        ));
    }
    Ok(())
}

/// The input's points, or an invalid-input error ("the input has no
/// points to `purpose`").
pub(crate) fn require_points<'a>(input: &'a Geometry, purpose: &str) -> Result<&'a PointCloud> {
    if input.points.positions.is_empty() {
        return Err(error::Error::new(
            error::ErrorKind::InvalidInput,
            format!("the input has no points to {purpose}"),
        ));
    }
    Ok(&input.points)
}

/// Cancelled if `hook` says so at the start of `stage`.
pub(crate) fn check(hook: Hook, stage: &'static str) -> Result<()> {
    match hook(Progress::stage(stage)) {
        ControlFlow::Continue(()) => Ok(()),
        ControlFlow::Break(()) => Err(Error::cancelled()),
    }
}

/// How closely `mesh` reaches every input datum (points, curve and patch
/// vertices).
pub(crate) fn data_fit_report(mesh: &Mesh, input: &Input) -> DataFitReport {
    match surfrecon_geom::data_fit::data_fit(mesh, &input.points.positions) {
        Ok(fit) => DataFitReport::Fit(fit),
        Err(e) => DataFitReport::Error {
            error: e.to_string(),
        },
    }
}
