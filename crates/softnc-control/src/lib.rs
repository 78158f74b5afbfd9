//! Position-control stack (being built).
pub mod zero_lag_fir;
