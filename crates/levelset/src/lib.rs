//! surfrecon-levelset: TODO(helper)
