//! One module per subcommand, each with `Args` and `run`.

pub mod convert;
pub mod distance;
pub mod eval;
pub mod extract;
pub mod feature_field;
pub mod info;
pub mod morph;
pub mod normals;
pub mod reconstruct;
pub mod reconstruct_convection;
pub mod reconstruct_svm;
pub mod render;
pub mod sculpt;
pub mod shell;
pub mod tetrahedralize;
pub mod unshell;
