//! surfrecon-levelset: level-set surface reconstruction from points, curves
//! and surface patches, in 2D and 3D by one generic code path (Zhao, Osher,
//! Fedkiw: "Fast surface reconstruction using the level set method").
//!
//! Pipeline ([`reconstruct::reconstruct_field`], [`reconstruct::reconstruct_3d`],
//! [`reconstruct::reconstruct_2d`]): point [`cleaning`] (outliers, noise) →
//! unsigned distance d to the data on a padded grid → initial surface by an
//! outer distance contour and the fast [`tagging`] algorithm, which keeps
//! the contour's topology and drops inside components without data →
//! [`convection`] φ_t = ∇d·∇φ → weighted minimal surface [`flow`] → a last
//! convection that settles the zero set on the data → marching cubes
//! (squares in 2D) → in 3D, [`refine`]: vertices snapped onto the data's
//! local fit, gap patches of scans faired. Every evolution stops by its
//! convergence test; none changes the topology (simple point test). Evolution runs on a narrow
//! band ([`band`]) kept a signed distance by [`reinit`]; large grids are
//! solved coarse-to-fine ([`multires`]).

pub mod anchors;
pub mod band;
mod centre;
pub mod cleaning;
pub mod convection;
pub mod error;
pub mod flow;
mod holes;
pub mod multires;
mod nesting;
pub mod reach;
pub mod reconstruct;
pub mod refine;
pub mod reinit;
pub mod rim_fit;
pub mod slices;
pub mod tagging;

pub use band::NarrowBand;
pub use error::{LevelsetError, Result};
pub use reconstruct::{
    reconstruct_2d, reconstruct_2d_with, reconstruct_3d, reconstruct_3d_with, reconstruct_field,
    reconstruct_field_with, Input, ReconstructParams, Reconstruction2, Reconstruction3, Report,
};
