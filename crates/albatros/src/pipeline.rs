//! The machine's three stages as a pipeline, with its two double-buffered
//! memories between them: the GP sets up frame `n + 2` in one half of the frame
//! memory (FB) while the matrix of VPs renders frame `n + 1` from the other half
//! (P1, SYSTEM.md 1), into one half of their video memories, while the other half,
//! frame `n`, is read out (SYSTEM.md 4.4); then both pairs of halves swap.
//!
//! Here all three run on the matrix's threads ([`Matrix::step`]): with one thread a
//! step costs what the three cost one after the other; with more, the VPs render
//! frame `n + 1` on every thread (their shares are even), and as each thread's VP is
//! done it takes the GP's tasks for frame `n + 2` and the readout's bands of frame
//! `n`, which the other threads join as their VPs finish. The GP's serial parts,
//! the readout and the VPs' uneven ends thus overlap instead of leaving cores idle
//! (measured in BENCHMARKS.md, sessions 5 and 16). A frame is shown two steps after
//! it is set up (the hardware's latency of two frame periods), and its image is byte
//! for byte the one the stages give run one after another.

use crate::db::{Eye, Screen};
use crate::frame::FrameList;
use crate::gp::{self, Database, GpConfig, GpCounters, GpMemory};
use crate::matrix::Matrix;
use crate::vp::vb::Image;

/// The GP and the matrix of VPs with the two halves of FB between them (the
/// VPs' video memories hold the two halves of the VB: [`Matrix::step`]).
pub struct Pipeline<'a> {
    db: &'a Database,
    screen: Screen,
    gp_config: GpConfig,
    gp_memory: GpMemory,
    gp_counters: GpCounters,
    matrix: Matrix,
    /// The half being read by the VPs (frame `n`), as the several GPs' stretches
    /// ([`gp::frame_stretches_into`]: the VPs walk them in order, no join).
    shown: Vec<FrameList>,
    /// The half being filled by the GP (frame `n + 1`).
    next: Vec<FrameList>,
    /// Whether `shown` holds a frame (not before the first step).
    primed: bool,
}

impl<'a> Pipeline<'a> {
    /// A pipeline of the database's GP (with `gp_config`; its `threads` should be
    /// the matrix's, so that the several GPs run on the matrix's threads) and
    /// `matrix`, for `screen`.
    pub fn new(db: &'a Database, screen: Screen, gp_config: GpConfig, matrix: Matrix) -> Self {
        Self {
            db,
            screen,
            gp_config,
            gp_memory: GpMemory::default(),
            gp_counters: GpCounters::default(),
            matrix,
            shown: Vec::new(),
            next: Vec::new(),
            primed: false,
        }
    }

    /// One frame period: the GP sets up the frame seen from `eye` while the VPs
    /// render the frame set up by the previous step and the VB reads out into
    /// `image` the frame they rendered at the previous step. Returns whether
    /// `image` now holds a frame (not on the first two steps, before the first
    /// frame has been set up and rendered).
    pub fn step(&mut self, eye: &Eye, image: &mut Image) -> bool {
        let Self { db, screen, gp_config, gp_memory, gp_counters, matrix, shown, next, primed } = self;
        let set_up = || gp::frame_stretches_into(db, eye, *screen, gp_config, gp_counters, gp_memory, next);
        let ((), read) = matrix.step(primed.then_some(&shown[..]), image, set_up);
        std::mem::swap(shown, next);
        *primed = true;
        read
    }

    /// A frame period with no new frame set up: the frames still in the pipeline
    /// move on by one stage. Returns whether `image` now holds a frame: the frame
    /// before the last at the first call after the last step, the last one at the
    /// second, and none after that.
    pub fn finish(&mut self, image: &mut Image) -> bool {
        let frame = self.primed.then_some(&self.shown[..]);
        self.primed = false;
        self.matrix.step(frame, image, || ()).1
    }

    /// The GP's counters of the last frame it set up.
    pub fn gp_counters(&self) -> &GpCounters {
        &self.gp_counters
    }

    /// The matrix.
    pub fn matrix(&self) -> &Matrix {
        &self.matrix
    }
}
