//! # Albatros
//!
//! A software image generator for visual simulation built as the «Альбатрос» visual
//! systems of the 1990s were built in hardware, and a model of that machine.
//!
//! One frame flows through the units of the papers (see `ARCHITECTURE.md`):
//!
//! ```text
//! db (scene database, BSP) -> gp (geometric processor) -> frame::FrameList
//!     -> vp (video processor: gq cell processors, spp, cc) -> vb (video buffer) -> image
//! ```

pub mod db;
pub mod frame;
pub mod gp;
mod hint;
pub mod isa;
pub mod matrix;
pub mod model;
pub mod peer;
pub mod pipeline;
pub mod vp;
