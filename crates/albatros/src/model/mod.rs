//! The architecture model (SYSTEM.md 6): per-unit counters, and later the timing model
//! and the analytic model of P3.

pub mod stats;
