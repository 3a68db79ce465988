//! A scanner simulator: synthetic buildings with exact ground truth, scanned by static or mobile
//! scanners. Used by tests, benchmarks and `asbuilt simulate`.
