//! Per-unit counters of one frame (SYSTEM.md 6): what every unit of the machine did.
//!
//! The video processor fills a [`Counters`] when asked to (`VpConfig::stats`); with
//! counting off the counting code is compiled out of the hot loops (a `const` generic
//! parameter). **Invariant: counters never change rendering.**

use serde::Serialize;

/// The most GQ levels a frame can have (root level 0 to level 11 for an 8192 root).
pub const MAX_LEVELS: usize = 12;

/// Counters of one GQ level: about the cells *of* that level (children produced by the
/// GQ of the level above).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LevelCounters {
    /// Cells tested against the polygon's edges (4 per parent cell processed).
    pub tested: u64,
    /// Cells wholly inside the polygon.
    pub inside: u64,
    /// Cells wholly outside (dropped).
    pub outside: u64,
    /// Cells crossed by an edge.
    pub crossed: u64,
    /// Cells inside or crossed that the level's mask memory dropped.
    pub masked: u64,
    /// Edge tests (ROM look-ups): one per active edge per parent cell.
    pub edge_tests: u64,
    /// Polygons dropped whole at this level because their starting cell was masked.
    pub polygons_masked: u64,
    /// Descents that started at a cell of this level (the polygon's bounding cell).
    pub starts: u64,
}

/// Counters of the subpixel processors (SPP).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SppCounters {
    /// 4x4 cells (fragments) that reached the SPPs.
    pub fragments: u64,
    /// Edge look-ups in the SPP table (one per active edge per pixel).
    pub edge_lookups: u64,
    /// Pixels of those cells on the screen (16 per fragment, fewer at the border).
    pub pixels_touched: u64,
    /// Pixels that received a non-empty visible subpixel set.
    pub pixels_visible: u64,
    /// Subpixels newly set in the subpixel mask memory.
    pub subpixels_set: u64,
}

/// Counters of the colour computers (CC) and the video buffer (VB).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ColorCounters {
    /// Pixels coloured, per CC channel (P1: four channels).
    pub pixels_per_channel: [u64; 4],
    /// Textured pixels (trilinear look-ups).
    pub textured: u64,
    /// VB first writes (the pixel's first fragment).
    pub first_writes: u64,
    /// VB read-modify-writes.
    pub read_modify_writes: u64,
}

/// All counters of one frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Counters {
    /// Polygons in the frame list.
    pub polygons: u64,
    /// Root level `L` of the frame (levels `0..=L`).
    pub root_level: u32,
    /// Per GQ level, index = level.
    pub levels: Vec<LevelCounters>,
    /// The subpixel processors.
    pub spp: SppCounters,
    /// Colour and video buffer.
    pub color: ColorCounters,
}

impl Counters {
    /// Empty counters for a frame of root level `root_level`.
    pub fn new(root_level: u32) -> Self {
        Self { root_level, levels: vec![LevelCounters::default(); root_level as usize + 1], ..Self::default() }
    }

    /// Adds another frame's (or another VP's) counters into these.
    pub fn add(&mut self, o: &Counters) {
        self.polygons += o.polygons;
        if self.levels.len() < o.levels.len() {
            self.levels.resize(o.levels.len(), LevelCounters::default());
        }
        for (a, b) in self.levels.iter_mut().zip(&o.levels) {
            a.tested += b.tested;
            a.inside += b.inside;
            a.outside += b.outside;
            a.crossed += b.crossed;
            a.masked += b.masked;
            a.edge_tests += b.edge_tests;
            a.polygons_masked += b.polygons_masked;
            a.starts += b.starts;
        }
        let (s, t) = (&mut self.spp, &o.spp);
        s.fragments += t.fragments;
        s.edge_lookups += t.edge_lookups;
        s.pixels_touched += t.pixels_touched;
        s.pixels_visible += t.pixels_visible;
        s.subpixels_set += t.subpixels_set;
        let (c, d) = (&mut self.color, &o.color);
        for (a, b) in c.pixels_per_channel.iter_mut().zip(d.pixels_per_channel) {
            *a += b;
        }
        c.textured += d.textured;
        c.first_writes += d.first_writes;
        c.read_modify_writes += d.read_modify_writes;
    }

    /// Cells tested over all levels.
    pub fn cells_tested(&self) -> u64 {
        self.levels.iter().map(|l| l.tested).sum()
    }
}
