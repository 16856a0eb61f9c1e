//! cvtrace: Embree FFI and its safe wrapper live here (work in progress).
