//! Criterion benchmarks of the renderer (filled in below).
#![allow(missing_docs)]
fn main() {}
