//! surfrecon-svm: implicit surfaces from oriented points by multi-scale
//! support-vector regression, and dense warp fields between two shapes.
//!
//! f(x) = b + Σ β_i k(|x − c_i| / s) with the compactly supported Wu kernel
//! ([`kernel`]) approximates the signed distance near the surface (negative
//! inside). Entry points:
//! - [`multiscale::fit`] fits an [`model::SvmModel`] to points + normals
//!   (training set in [`training`], ε-insensitive or squared-loss solve in
//!   [`regression`]; the noise level it adapts to in [`noise`]);
//! - [`selection::select_parameters`] picks the regularization by validation;
//! - [`model::SvmModel`] evaluates f, ∇f and curvature, drops fine levels,
//!   saves and loads models;
//! - [`hermite::HermiteFit`] interpolates sparse samples with normals
//!   (curve networks) by a global triharmonic Hermite fit;
//! - [`curve_network::reconstruct_from_curves`] spans a curve network
//!   with a Hermite fit of the normals the curves imply, and joins the
//!   pieces the curves do not keep apart ([`joining`]);
//! - [`mesh::mesh_model`] extracts the zero set of either by
//!   surface-following marching cubes;
//! - [`warp::fit_warp`] computes a dense deformation field between two
//!   fitted shapes (morphing).

pub mod bridges;
pub mod cells;
pub mod curve_network;
pub mod error;
pub mod hermite;
pub mod joining;
pub mod kernel;
pub mod mesh;
pub mod model;
pub mod multiscale;
pub mod noise;
pub mod regression;
pub mod selection;
pub mod training;
pub mod warp;

pub use error::SvmError;
pub use model::SvmModel;
pub use multiscale::{fit, fit_with, FitOptions, FitReport};
pub use regression::Loss;
