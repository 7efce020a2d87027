//! surfrecon-svm: TODO(helper)
