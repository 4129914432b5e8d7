//! `ickon`: the launcher.
fn main() {}
