//! Position-control stack (being built).
