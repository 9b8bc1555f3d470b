//! P1 fig. 4's experiment and the `albatros stats` report: a frame rendered with
//! counting on under one or several mask modes, each run's counters turned into
//! derived figures and an estimated time on a hardware configuration
//! ([`super::timing`]), plus the scene's depth complexity from a coverage probe.
//!
//! Input: a frame list (from the GP), its texture maps, the modes, a [`HwConfig`].
//! Output: a [`Report`], whose JSON form is the `albatros stats --json` schema
//! ([`SCHEMA`], documented in `docs/architecture-model.md` and pinned by a test).
//! Invariant: the probe and the runs only read the frame; every run renders the same
//! image (masks change work, never the image), so the visible counters agree across
//! runs.

use std::sync::Arc;

use serde::Serialize;

use super::stats::{Counters, Derived};
use super::timing::{HwConfig, Timing};
use crate::frame::FrameList;
use crate::gp::GpCounters;
use crate::vp::gq::{CellProcessors, GqPolygon, MaskLevels};
use crate::vp::spp::SubpixelProcessors;
use crate::vp::tables::SppMode;
use crate::vp::texture::TextureMaps;
use crate::vp::{VideoProcessor, VpConfig};

/// The name and version of the report's JSON schema. Bump the number when a key is
/// renamed or removed; adding keys keeps it.
pub const SCHEMA: &str = "albatros-stats/1";

/// P1 fig. 4's modes, named I..IV, for a screen of root level `root_level`.
pub fn p1_modes(root_level: u32) -> [(&'static str, MaskLevels); 4] {
    [
        ("I", MaskLevels::mode_i(root_level)),
        ("II", MaskLevels::mode_ii(root_level)),
        ("III", MaskLevels::mode_iii(root_level)),
        ("IV", MaskLevels::mode_iv(root_level)),
    ]
}

/// The levels `1..=root_level` whose mask memory is in use.
pub fn mask_level_list(masks: MaskLevels, root_level: u32) -> Vec<u32> {
    (1..=root_level).filter(|&k| masks.has(k)).collect()
}

/// The share of `base` that `value` lacks: `1 - value / base` (0 for an empty base).
fn removed_share(value: u64, base: u64) -> f64 {
    if base == 0 {
        0.0
    } else {
        1.0 - value as f64 / base as f64
    }
}

/// What the masks of a run removed, against the same frame with no GQ masks.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Removed {
    /// Share of the cell tests (all levels) removed.
    pub cells_tested_share: f64,
    /// Share of the fragments (4 x 4 cells reaching the SPPs) removed.
    pub fragments_share: f64,
}

/// One mask mode's run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModeRun {
    /// The mode's name (`I`..`IV`, or as given).
    pub mode: String,
    /// The levels whose mask memory was in use.
    pub mask_levels: Vec<u32>,
    /// The counters of the frame.
    pub counters: Counters,
    /// Figures derived from them.
    pub derived: Derived,
    /// What the masks removed, against no masks.
    pub removed_by_masks: Removed,
    /// The estimated time on the hardware.
    pub timing: Timing,
}

/// The frame with no GQ mask memory: the work the masks start from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NoMasks {
    /// Cells tested over all levels.
    pub cells_tested: u64,
    /// Fragments reaching the SPPs.
    pub fragments: u64,
    /// Pixels of those fragments.
    pub pixels_touched: u64,
    /// The estimated frame time, ms.
    pub frame_ms: f64,
}

/// The report of `albatros stats` (its JSON form is the documented schema).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// [`SCHEMA`].
    pub schema: &'static str,
    /// The scene's name.
    pub scene: String,
    /// Screen width, pixels.
    pub width: u32,
    /// Screen height, pixels.
    pub height: u32,
    /// Root level `L`.
    pub root_level: u32,
    /// Polygons in the frame list.
    pub polygons: u64,
    /// The hardware configuration the times are for.
    pub hw: HwConfig,
    /// The geometric processor's counters, when the caller had them.
    pub gp: Option<GpCounters>,
    /// Pixels covered by at least one polygon.
    pub covered_pixels: u64,
    /// Pixels of every polygon's own coverage (no masks) summed over polygons.
    pub polygon_pixels: u64,
    /// Depth complexity: `polygon_pixels / covered_pixels`, the mean number of
    /// polygons over a covered pixel (the work a machine without masks would see).
    pub depth_complexity: f64,
    /// The frame with no GQ masks.
    pub no_masks: NoMasks,
    /// The runs, in the order asked.
    pub runs: Vec<ModeRun>,
}

/// A frame under study: renders it with counting on and probes its coverage.
#[derive(Clone, Debug)]
pub struct Experiment<'a> {
    /// The frame list.
    pub frame: &'a FrameList,
    /// Its texture maps (empty: textured faces keep their colour, which changes no
    /// counter but `textured`).
    pub textures: Arc<TextureMaps>,
    /// The SPP table.
    pub spp: SppMode,
    /// Greene's hierarchical coverage in the mask memories.
    pub hierarchical: bool,
}

impl<'a> Experiment<'a> {
    /// An experiment on `frame` with no textures and P1's area-faithful SPP table.
    pub fn new(frame: &'a FrameList) -> Self {
        Self { frame, textures: Arc::default(), spp: SppMode::Area, hierarchical: false }
    }

    /// The root level of the frame's screen.
    pub fn root_level(&self) -> u32 {
        CellProcessors::root_level_for(self.frame.width, self.frame.height)
    }

    /// A video processor for the frame with counting on.
    pub fn video_processor(&self, masks: MaskLevels) -> VideoProcessor {
        let config =
            VpConfig { masks, spp: self.spp, stats: true, hierarchical: self.hierarchical, ..VpConfig::default() };
        let mut vp = VideoProcessor::new(self.frame.width, self.frame.height, config);
        vp.set_textures(Arc::clone(&self.textures));
        vp
    }

    /// Renders the frame under `masks` and returns its counters.
    pub fn counters(&self, masks: MaskLevels) -> Counters {
        let mut vp = self.video_processor(masks);
        vp.render_frame(self.frame);
        vp.counters
    }

    /// Pixels of every polygon's own coverage summed over polygons: for each
    /// polygon alone (no masks), the on-screen pixels where its fragment code (the
    /// SPP's subpixel sets before masking and thinning) is not empty.
    pub fn polygon_pixels(&self) -> u64 {
        let (w, h) = (self.frame.width, self.frame.height);
        let mut gq = CellProcessors::new(w, h, MaskLevels::NONE);
        let spp = SubpixelProcessors::new(w, h, self.spp);
        let mut scratch = Counters::new(gq.root_level);
        let mut total = 0u64;
        for poly in &self.frame.polygons {
            let edges = self.frame.edges_of(poly);
            let bbox = crate::vp::bbox(self.frame.vertices_of(poly), w, h);
            if bbox[0] >= bbox[1] || bbox[2] >= bbox[3] {
                continue;
            }
            let gp = GqPolygon { edges, opaque: false, bbox };
            let mut counters = Counters::new(gq.root_level);
            gq.descend::<false>(&gp, &mut counters, &mut |frag| {
                let code = spp.fragment_code::<false>(&frag, edges, &mut scratch);
                for (i, &set) in code.iter().enumerate() {
                    let (x, y) = (frag.px + (i as u32 & 3), frag.py + (i as u32 >> 2));
                    if set != 0 && x < w && y < h {
                        total += 1;
                    }
                }
            });
        }
        total
    }

    /// One run: counters under `masks`, derived figures, time on `hw`, and what the
    /// masks removed against `no_masks` (the counters with no GQ masks).
    pub fn run(&self, mode: &str, masks: MaskLevels, hw: &HwConfig, no_masks: &Counters) -> ModeRun {
        let counters = self.counters(masks);
        ModeRun {
            mode: mode.to_string(),
            mask_levels: mask_level_list(masks, counters.root_level),
            derived: counters.derived(),
            removed_by_masks: Removed {
                cells_tested_share: removed_share(counters.cells_tested(), no_masks.cells_tested()),
                fragments_share: removed_share(counters.spp.fragments, no_masks.spp.fragments),
            },
            timing: Timing::estimate(hw, &counters),
            counters,
        }
    }

    /// The full report: the frame with no masks, the coverage probe, and one run per
    /// `(name, masks)` in `modes`.
    pub fn report(&self, scene: &str, gp: Option<GpCounters>, modes: &[(String, MaskLevels)], hw: &HwConfig) -> Report {
        let base = self.counters(MaskLevels::NONE);
        let polygon_pixels = self.polygon_pixels();
        let covered = base.covered_pixels();
        let runs = modes.iter().map(|(name, masks)| self.run(name, *masks, hw, &base)).collect();
        Report {
            schema: SCHEMA,
            scene: scene.to_string(),
            width: self.frame.width,
            height: self.frame.height,
            root_level: base.root_level,
            polygons: self.frame.polygons.len() as u64,
            hw: hw.clone(),
            gp,
            covered_pixels: covered,
            polygon_pixels,
            depth_complexity: if covered == 0 { 0.0 } else { polygon_pixels as f64 / covered as f64 },
            no_masks: NoMasks {
                cells_tested: base.cells_tested(),
                fragments: base.spp.fragments,
                pixels_touched: base.spp.pixels_touched,
                frame_ms: Timing::estimate(hw, &base).frame_ms,
            },
            runs,
        }
    }
}
