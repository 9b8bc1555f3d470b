//! P1's double-buffered frame memory (FB) as a pipeline: the GP sets up frame `n + 1`
//! in one half of FB while the matrix of VPs renders frame `n` from the other half
//! (P1, SYSTEM.md 2), then the halves swap.
//!
//! Here both run on the matrix's threads ([`Matrix::render_beside`]): with one
//! thread a step costs what the GP and the VPs cost one after the other; with more,
//! the VPs render frame `n` on every thread (their shares are even), then the GP's
//! tasks for frame `n + 1` and the readout's bands of frame `n` run together, the
//! threads taking whichever is waiting, so the GP's serial parts and the readout
//! overlap instead of leaving cores idle (measured in BENCHMARKS.md, session 5). A
//! frame is shown one step after it is set up (the hardware's latency of one frame
//! period), and its image is byte for byte the one the stages give run one after
//! another.

use crate::db::{Eye, Screen};
use crate::frame::FrameList;
use crate::gp::{self, Database, GpConfig, GpCounters, GpMemory};
use crate::matrix::Matrix;
use crate::vp::vb::Image;

/// The GP and the matrix of VPs with the two halves of FB between them.
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
    /// render the frame set up by the previous step and read it out into `image`.
    /// Returns whether `image` now holds a frame (not on the first step, when there
    /// was none to render yet).
    pub fn step(&mut self, eye: &Eye, image: &mut Image) -> bool {
        let Self { db, screen, gp_config, gp_memory, gp_counters, matrix, shown, next, primed } = self;
        let set_up = || gp::frame_stretches_into(db, eye, *screen, gp_config, gp_counters, gp_memory, next);
        let rendered = *primed;
        if rendered {
            matrix.render_beside(shown, image, set_up);
        } else {
            matrix.install(set_up);
        }
        std::mem::swap(shown, next);
        *primed = true;
        rendered
    }

    /// Renders the last frame set up (with no new one beside it) into `image`;
    /// returns whether there was one.
    pub fn finish(&mut self, image: &mut Image) -> bool {
        if !self.primed {
            return false;
        }
        self.matrix.render_beside(&self.shown, image, || ());
        self.primed = false;
        true
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
