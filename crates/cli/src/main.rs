//! ringsync CLI
fn main() {}
