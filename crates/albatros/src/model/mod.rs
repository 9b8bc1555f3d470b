//! The architecture model (SYSTEM.md 6): per-unit counters ([`stats`]), the hardware
//! timing model that turns them into stage times, the frame time and the bottleneck
//! ([`timing`]), and P1 fig. 4's mask-level experiment with the `albatros stats`
//! report ([`experiment`]). Later: the analytic model of P3.

pub mod experiment;
pub mod stats;
pub mod timing;
