//! Benchmarks (placeholder until the methods exist).
fn main() {}
