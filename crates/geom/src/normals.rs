//! TODO(helper): normals
