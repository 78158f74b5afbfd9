//! `softnc reproduce`: the papers' experiments, one module per experiment.

pub mod p000;
pub mod p001;
pub mod p001_audit;
pub mod p002_filter;
pub mod p002_learning;
pub mod p003;
pub mod p004;
