//! Geometric processor (GP, SYSTEM.md 3).

pub mod clip;
