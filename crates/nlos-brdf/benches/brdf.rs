//! Throughput of value+gradient evaluation (placeholder, filled in below).
fn main() {}
