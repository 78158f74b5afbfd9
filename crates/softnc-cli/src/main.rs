//! `softnc`: operator client and offline tools.
fn main() {}
