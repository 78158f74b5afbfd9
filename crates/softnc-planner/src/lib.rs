//! Lookahead motion planner (being built).
