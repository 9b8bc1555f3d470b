//! Albatros integration tests: one binary, a module per area (links once).

mod canonical;
mod clip;
mod golden;
mod gp;
mod load;
mod model;
mod peer;
mod pipeline;
mod texture;
mod vb;
mod vp;
