//! Reconstruction estimators (work in progress).
