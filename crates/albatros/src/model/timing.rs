//! The hardware timing model (SYSTEM.md 6): a configuration of the video processor
//! (numbers of GQ, SPP, CC and VB units, cycles per operation, clock) that turns one
//! frame's [`Counters`] into a time per pipeline stage, the frame time, the
//! bottleneck and the load of every stage, so that P1 fig. 4's experiment can be
//! rerun.
//!
//! # The model
//! The VP is a pipeline of stages with FIFOs between them (P1 fig. 1): GQ 0 .. GQ
//! G-1, SPP, CC, VB. Each stage's time is the sum over the frame of its operations
//! times their cycles ([`Cycles`]):
//! - **GQ of level `k`** (splits cells of level `k` into level `k+1`), after P3 eq.
//!   (5), `t_i = t_e [4 w_{i-1} + w_i k_p/k_e]`, a term for the cells coming in and
//!   one for the cells going out. P1's GQ tests a parent's four children at once
//!   (eq. 2 works on 4-bit codes), so the first term is `gq_cell` per parent cell
//!   (`tested[k+1] / 4`: the mask word's read and write, eq. 2's combination) plus
//!   `gq_edge_test` per ROM look-up (`edge_tests[k+1]`, one per active edge of a
//!   parent: the edges arrive one after another); the second is `gq_cell_out` per
//!   child handed on (IN or CR, not masked). A polygon whose descent starts at level
//!   `k` costs one `gq_cell` there (its start cell is checked against the masks
//!   above). Each GQ works through its cells one at a time (P1: "from level 0 to 6
//!   the branches of the tree are traversed sequentially").
//! - **SPP**: per fragment (4 x 4 cell) `spp_fragment`, plus `spp_edge` per active
//!   edge, the 16 pixels in parallel on 16 SPPs (P1: "at the last level 16 cells of
//!   pixel size in parallel"); with fewer SPPs a fragment takes `ceil(16 / spp)`
//!   passes.
//! - **CC**: `cc_pixel` per coloured pixel; the channels work in parallel, so with
//!   P1's 4 channels the stage takes as long as its busiest channel (the counters
//!   keep the pixels of each). With another number of channels the pixels are taken
//!   as spread evenly.
//! - **VB**: `vb_write` per first write, `vb_read_modify_write` per later fragment,
//!   spread evenly over the modules (each VM module sits behind one CC channel, whose
//!   loads the counters show to be even within about 1%). The background's fill is
//!   not counted: the VB clears through the first-write flags, and the background
//!   takes what is left at readout of the other half of the double buffer.
//!
//! The frame time is that of the slowest stage, `T = max_i t_i` (P3 eq. (9): a
//! pipeline's throughput is its slowest stage's, the FIFOs absorbing the per-polygon
//! variation); the bottleneck is that stage; the load of stage `i` is `t_i / T`, and
//! the mean load is P3 eq. (10), `R_p = sum_i t_i / (n T)` over the `n` stages of the
//! hardware (idle GQs included: they are in the machine). `sequential_ms`, the sum of
//! the stages (P3 eq. (6)), is what one processor doing every stage in turn would
//! take.
//!
//! # Levels and GQs
//! A screen of root level `L` has levels `0..L-1` to split; the hardware has `G` GQs.
//! With `L = G` (P1: 512 x 512, `L = G = 7`) GQ `g` splits level `g`. Otherwise the
//! last levels map one to one onto the last GQs, since the work grows toward the
//! bottom of the tree: level `k` goes to GQ `k - (L - G)`; with `L > G` the top
//! `L - G + 1` levels all go to GQ 0, which traverses them as a stack (P3's mixed
//! "stack - pipeline" architecture); with `L < G` the first `G - L` GQs only pass the
//! root on and have no work.
//!
//! # Where the numbers come from
//! The unit counts (7 GQ, 16 SPP, 4 CC, 4 VB) and the 20 ms half-frame are P1's; one
//! pixel per cycle in a CC is P2's. The rest are assumptions, calibrated on P1 fig.
//! 4's ROMBM (22 rhombi over a 512 x 512 screen): with all mask levels the model's
//! ROMBM is bound by the 4 CC channels and 4 VB modules filling the screen, 65,536
//! pixels per channel at one per cycle, and P1's "a little over 12 ms" for it gives
//! the clock, 5.5 MHz (12.0 ms). With the last level's mask only, every rhombus is
//! split down to the last GQ, and P1's "over 25 ms" needs at least 1.3 cycles per
//! parent cell there: `gq_cell = 2`, the mask word's read and write, is the smallest
//! whole number (36 ms). One cycle per ROM look-up, per cell handed on, per SPP
//! table look-up and per VB write, two per SPP mask word and per VB
//! read-modify-write, are the plain guesses of a synchronous design.
//! `hw/albatros-base.toml` is the default file and says the same per key;
//! `docs/architecture-model.md` has the numbers.

use std::ops::Range;

use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::stats::{Counters, MAX_LEVELS, PIXELS_PER_CELL};

/// The default hardware file (P1's base variant), as shipped in `hw/albatros-base.toml`.
pub const BASE_TOML: &str = include_str!("../../../../hw/albatros-base.toml");

/// P1's base variant: cell processors (one per level of a 512 x 512 screen).
pub const P1_GQ: u32 = 7;
/// P1's base variant: subpixel processors, one per pixel of a 4 x 4 cell.
pub const P1_SPP: u32 = 16;
/// P1's base variant: colour computer channels.
pub const P1_CC: u32 = 4;
/// P1's base variant: video memory modules.
pub const P1_VB: u32 = 4;
/// P1: the half-frame, the time budget of one image, ms.
pub const P1_HALF_FRAME_MS: f64 = 20.0;
/// Assumed clock, MHz (P1 gives none; see the module docs).
pub const BASE_CLOCK_MHZ: f64 = 5.5;

/// Most SPPs a configuration may have: one per pixel of a 4 x 4 cell.
pub const MAX_SPP: u32 = PIXELS_PER_CELL as u32;
/// Most CC channels or VB modules a configuration may have (a sanity bound).
pub const MAX_CHANNELS: u32 = 64;
/// Children of a split cell.
const CHILDREN: u64 = 4;
/// Number of stages besides the GQs: SPP, CC, VB.
const NON_GQ_STAGES: usize = 3;
/// Cycles per millisecond at 1 MHz.
const CYCLES_PER_MS_PER_MHZ: f64 = 1000.0;

/// How many units of each kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Units {
    /// Cell processors (GQ), one pipeline stage each.
    pub gq: u32,
    /// Subpixel processors (SPP), working on one fragment's pixels in parallel.
    pub spp: u32,
    /// Colour computer channels (CC).
    pub cc: u32,
    /// Video memory modules (VB).
    pub vb: u32,
}

/// Cycles per operation (fractions allowed: an average cost).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Cycles {
    /// GQ: per parent cell split (its four children tested at once: mask word read
    /// and write, P1 eq. 2).
    pub gq_cell: f64,
    /// GQ: per cell-edge test, one ROM look-up per active edge of a parent cell.
    pub gq_edge_test: f64,
    /// GQ: per child cell handed on to the next stage (IN or CR, not masked).
    pub gq_cell_out: f64,
    /// SPP: per fragment (the subpixel mask word's read and write).
    pub spp_fragment: f64,
    /// SPP: per edge look-up of a fragment (all its pixels in parallel).
    pub spp_edge: f64,
    /// CC: per coloured pixel.
    pub cc_pixel: f64,
    /// VB: per first write of a pixel.
    pub vb_write: f64,
    /// VB: per read-modify-write (a pixel's later fragments).
    pub vb_read_modify_write: f64,
}

/// A hardware configuration of the video processor.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HwConfig {
    /// A name for reports.
    pub name: String,
    /// Clock, MHz.
    pub clock_mhz: f64,
    /// The time budget of one image, ms (P1: the 20 ms half-frame).
    pub half_frame_ms: f64,
    /// Unit counts.
    pub units: Units,
    /// Cycles per operation.
    pub cycles: Cycles,
}

impl Default for HwConfig {
    /// P1's base variant, the same as [`BASE_TOML`].
    fn default() -> Self {
        Self {
            name: "P1 base variant".into(),
            clock_mhz: BASE_CLOCK_MHZ,
            half_frame_ms: P1_HALF_FRAME_MS,
            units: Units { gq: P1_GQ, spp: P1_SPP, cc: P1_CC, vb: P1_VB },
            cycles: Cycles {
                gq_cell: 2.0,
                gq_edge_test: 1.0,
                gq_cell_out: 1.0,
                spp_fragment: 2.0,
                spp_edge: 1.0,
                cc_pixel: 1.0,
                vb_write: 1.0,
                vb_read_modify_write: 2.0,
            },
        }
    }
}

/// Why a hardware file was refused. Lines and columns are 1-based; `key` is the
/// dotted path of the key (`units.gq`, `cycles.spp_edge`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HwError {
    /// Not valid TOML, an unknown key, or a value of the wrong type.
    #[error("line {line}, column {column}: {}{message}", key.as_ref().map(|k| format!("{k}: ")).unwrap_or_default())]
    Syntax {
        /// The key at the error, when one could be found.
        key: Option<String>,
        /// Line.
        line: usize,
        /// Column.
        column: usize,
        /// What the TOML reader said.
        message: String,
    },
    /// A value of the right type that is out of range.
    #[error("line {line}, column {column}: {key} = {value}: {reason}")]
    Invalid {
        /// The key.
        key: String,
        /// The value as read.
        value: String,
        /// Line.
        line: usize,
        /// Column.
        column: usize,
        /// What is wrong.
        reason: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHw {
    name: Option<String>,
    clock_mhz: Option<Spanned<f64>>,
    half_frame_ms: Option<Spanned<f64>>,
    units: Option<RawUnits>,
    cycles: Option<RawCycles>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawUnits {
    gq: Option<Spanned<u32>>,
    spp: Option<Spanned<u32>>,
    cc: Option<Spanned<u32>>,
    vb: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCycles {
    gq_cell: Option<Spanned<f64>>,
    gq_edge_test: Option<Spanned<f64>>,
    gq_cell_out: Option<Spanned<f64>>,
    spp_fragment: Option<Spanned<f64>>,
    spp_edge: Option<Spanned<f64>>,
    cc_pixel: Option<Spanned<f64>>,
    vb_write: Option<Spanned<f64>>,
    vb_read_modify_write: Option<Spanned<f64>>,
}

/// 1-based line and column (in characters) of byte `offset` of `text`.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The dotted key whose line holds byte `offset`: the text before `=` on that line,
/// prefixed with the last `[table]` header above it.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    let start = text.get(..offset)?.rfind('\n').map_or(0, |i| i + 1);
    let line = text[start..].lines().next().unwrap_or("");
    let (key, _) = line.split_once('=')?;
    let key = key.trim().trim_matches('"');
    if key.is_empty() || key.starts_with('#') || key.starts_with('[') {
        return None;
    }
    let table = text[..start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && !l.starts_with("[["))
        .map(|l| l.trim_start_matches('[').split(']').next().unwrap_or("").trim().to_string());
    Some(match table {
        Some(t) if !t.is_empty() => format!("{t}.{key}"),
        _ => key.to_string(),
    })
}

/// Checks a range: the value is kept if `ok`, else an [`HwError::Invalid`] naming
/// `key` at the value's place.
fn check<T: Copy + std::fmt::Display>(
    text: &str,
    key: &str,
    raw: Option<Spanned<T>>,
    default: T,
    ok: impl Fn(T) -> bool,
    reason: &str,
) -> Result<T, HwError> {
    let Some(v) = raw else { return Ok(default) };
    let span: Range<usize> = v.span();
    let value = *v.get_ref();
    if ok(value) {
        return Ok(value);
    }
    let (line, column) = line_column(text, span.start);
    Err(HwError::Invalid { key: key.into(), value: value.to_string(), line, column, reason: reason.into() })
}

impl HwConfig {
    /// Reads a hardware configuration from TOML text (the keys of
    /// `hw/albatros-base.toml`; missing keys take its values).
    pub fn from_toml(text: &str) -> Result<Self, HwError> {
        let raw: RawHw = toml::from_str(text).map_err(|e| {
            let offset = e.span().map_or(0, |s| s.start);
            let (line, column) = line_column(text, offset);
            let key = e.span().and_then(|s| key_at(text, s.start));
            HwError::Syntax { key, line, column, message: e.message().trim().to_string() }
        })?;
        let base = Self::default();
        let count = |key: &str, raw: Option<Spanned<u32>>, default: u32, max: u32| {
            check(text, key, raw, default, |v| (1..=max).contains(&v), &format!("must be a whole number in 1..={max}"))
        };
        let cycles = |key: &str, raw: Option<Spanned<f64>>, default: f64| {
            check(text, key, raw, default, |v: f64| v.is_finite() && v >= 0.0, "must be a finite number of cycles >= 0")
        };
        let positive = |key: &str, raw: Option<Spanned<f64>>, default: f64| {
            check(text, key, raw, default, |v: f64| v.is_finite() && v > 0.0, "must be a finite number > 0")
        };
        let (u, c) = (base.units, base.cycles);
        let units = match raw.units {
            None => u,
            Some(r) => Units {
                gq: count("units.gq", r.gq, u.gq, MAX_LEVELS as u32)?,
                spp: count("units.spp", r.spp, u.spp, MAX_SPP)?,
                cc: count("units.cc", r.cc, u.cc, MAX_CHANNELS)?,
                vb: count("units.vb", r.vb, u.vb, MAX_CHANNELS)?,
            },
        };
        let cycles = match raw.cycles {
            None => c,
            Some(r) => Cycles {
                gq_cell: cycles("cycles.gq_cell", r.gq_cell, c.gq_cell)?,
                gq_edge_test: cycles("cycles.gq_edge_test", r.gq_edge_test, c.gq_edge_test)?,
                gq_cell_out: cycles("cycles.gq_cell_out", r.gq_cell_out, c.gq_cell_out)?,
                spp_fragment: cycles("cycles.spp_fragment", r.spp_fragment, c.spp_fragment)?,
                spp_edge: cycles("cycles.spp_edge", r.spp_edge, c.spp_edge)?,
                cc_pixel: cycles("cycles.cc_pixel", r.cc_pixel, c.cc_pixel)?,
                vb_write: cycles("cycles.vb_write", r.vb_write, c.vb_write)?,
                vb_read_modify_write: cycles(
                    "cycles.vb_read_modify_write",
                    r.vb_read_modify_write,
                    c.vb_read_modify_write,
                )?,
            },
        };
        Ok(Self {
            name: raw.name.unwrap_or(base.name),
            clock_mhz: positive("clock_mhz", raw.clock_mhz, base.clock_mhz)?,
            half_frame_ms: positive("half_frame_ms", raw.half_frame_ms, base.half_frame_ms)?,
            units,
            cycles,
        })
    }

    /// The levels each GQ splits on a screen of root level `root_level` (index =
    /// GQ); see the module docs.
    pub fn gq_levels(&self, root_level: u32) -> Vec<Vec<u32>> {
        let g = self.units.gq;
        let mut out = vec![Vec::new(); g as usize];
        for k in 0..root_level {
            let gq = (k + g).saturating_sub(root_level);
            out[gq as usize].push(k);
        }
        out
    }

    /// Converts cycles to milliseconds at this clock.
    pub fn ms(&self, cycles: f64) -> f64 {
        cycles / (self.clock_mhz * CYCLES_PER_MS_PER_MHZ)
    }
}

/// Which kind of unit a stage is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    /// A cell processor.
    Gq,
    /// The subpixel processors.
    Spp,
    /// The colour computers.
    Cc,
    /// The video buffer.
    Vb,
}

/// One pipeline stage's estimated time for a frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageTime {
    /// `GQ0` .. `GQ{G-1}`, `SPP`, `CC`, `VB`.
    pub name: String,
    /// The kind of unit.
    pub unit: Unit,
    /// For a GQ, the levels whose cells it splits (empty: idle); empty otherwise.
    pub levels: Vec<u32>,
    /// Cycles.
    pub cycles: f64,
    /// Milliseconds at the configuration's clock.
    pub ms: f64,
    /// Load: this stage's time over the slowest stage's (1 for the bottleneck).
    pub load: f64,
}

/// The estimated time of one frame on a hardware configuration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Timing {
    /// Every stage in pipeline order.
    pub stages: Vec<StageTime>,
    /// The frame time: the slowest stage's (P3 eq. 9), ms.
    pub frame_ms: f64,
    /// The slowest stage's name (the first, on a tie).
    pub bottleneck: String,
    /// The pipeline's mean load `R_p` (P3 eq. 10): mean stage time over the slowest.
    pub mean_load: f64,
    /// The sum of all stages' times, ms: one processor doing each stage in turn.
    pub sequential_ms: f64,
    /// The configuration's time budget, ms.
    pub half_frame_ms: f64,
    /// Whether the frame time is within the budget.
    pub fits_half_frame: bool,
}

impl Timing {
    /// Estimates the frame time of a frame whose counters are `c` on hardware `hw`.
    pub fn estimate(hw: &HwConfig, c: &Counters) -> Self {
        let cy = &hw.cycles;
        let level = |k: u32| c.levels.get(k as usize).copied().unwrap_or_default();
        let l = c.root_level;
        let mut stages = Vec::with_capacity(hw.units.gq as usize + NON_GQ_STAGES);
        for (g, levels) in hw.gq_levels(l).into_iter().enumerate() {
            let mut cycles = 0.0;
            for &k in &levels {
                let children = level(k + 1);
                // Parents: the cells split (a quarter of the children tested), plus the
                // polygons entering at this level (the start cell's mask check); those
                // entering at the last level pass the last GQ.
                let mut starts = level(k).starts;
                if k + 1 == l {
                    starts += level(l).starts;
                }
                let parents = children.tested / CHILDREN + starts;
                cycles += cy.gq_cell * parents as f64
                    + cy.gq_edge_test * children.edge_tests as f64
                    + cy.gq_cell_out * (children.inside + children.crossed) as f64;
            }
            stages.push((format!("GQ{g}"), Unit::Gq, levels, cycles));
        }
        let s = &c.spp;
        let passes = PIXELS_PER_CELL.div_ceil(u64::from(hw.units.spp)) as f64;
        let edges_per_pixel = s.edge_lookups as f64 / PIXELS_PER_CELL as f64;
        let spp = passes * (cy.spp_fragment * s.fragments as f64 + cy.spp_edge * edges_per_pixel);
        stages.push(("SPP".into(), Unit::Spp, Vec::new(), spp));
        let channels = &c.color.pixels_per_channel;
        let cc_pixels = if hw.units.cc as usize == channels.len() {
            channels.iter().copied().max().unwrap_or(0)
        } else {
            channels.iter().sum::<u64>().div_ceil(u64::from(hw.units.cc))
        };
        stages.push(("CC".into(), Unit::Cc, Vec::new(), cy.cc_pixel * cc_pixels as f64));
        let vb = (cy.vb_write * c.color.first_writes as f64
            + cy.vb_read_modify_write * c.color.read_modify_writes as f64)
            / f64::from(hw.units.vb);
        stages.push(("VB".into(), Unit::Vb, Vec::new(), vb));

        let (mut max, mut bottleneck) = (0.0f64, 0usize);
        for (i, st) in stages.iter().enumerate() {
            if st.3 > max {
                (max, bottleneck) = (st.3, i);
            }
        }
        let sum: f64 = stages.iter().map(|s| s.3).sum();
        let load = |t: f64| if max > 0.0 { t / max } else { 0.0 };
        let mean_load = load(sum / stages.len() as f64);
        let frame_ms = hw.ms(max);
        Timing {
            bottleneck: stages[bottleneck].0.clone(),
            stages: stages
                .into_iter()
                .map(|(name, unit, levels, cycles)| StageTime {
                    name,
                    unit,
                    levels,
                    cycles,
                    ms: hw.ms(cycles),
                    load: load(cycles),
                })
                .collect(),
            frame_ms,
            mean_load,
            sequential_ms: hw.ms(sum),
            half_frame_ms: hw.half_frame_ms,
            fits_half_frame: frame_ms <= hw.half_frame_ms,
        }
    }

    /// The stage named `name`, if there is one.
    pub fn stage(&self, name: &str) -> Option<&StageTime> {
        self.stages.iter().find(|s| s.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_map_onto_the_last_gqs() {
        let hw = HwConfig::default();
        let seven: Vec<Vec<u32>> = (0..7).map(|k| vec![k]).collect();
        assert_eq!(hw.gq_levels(7), seven);
        // A 1024 root (L = 8) on 7 GQs: levels 0 and 1 both on GQ 0.
        assert_eq!(hw.gq_levels(8)[0], vec![0, 1]);
        assert_eq!(hw.gq_levels(8)[6], vec![7]);
        // A 128 root (L = 5): GQs 0 and 1 idle.
        let five = hw.gq_levels(5);
        assert!(five[0].is_empty() && five[1].is_empty());
        assert_eq!(five[2], vec![0]);
        assert_eq!(five[6], vec![4]);
    }

    #[test]
    fn key_and_place_of_an_offset() {
        let text = "a = 1\n[units]\ngq = \"x\"\n";
        let at = text.find("\"x\"").unwrap();
        assert_eq!(line_column(text, at), (3, 6));
        assert_eq!(key_at(text, at).as_deref(), Some("units.gq"));
        assert_eq!(key_at(text, 0).as_deref(), Some("a"));
    }
}
