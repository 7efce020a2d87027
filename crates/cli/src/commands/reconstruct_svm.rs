//! TODO(helper svm): the `--method svm` part of `surfrecon reconstruct`.
