//! Simulated servo backend (being built).
