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

    /// Cells of level `k` that a GQ split (the cells the GQ of level `k` took as
    /// parents): the IN and CR children that level `k-1` handed on, plus the
    /// descents that started at level `k` and were not dropped whole. Zero for the
    /// last level, whose cells go to the SPPs instead.
    pub fn cells_split(&self, k: u32) -> u64 {
        if k >= self.root_level {
            return 0;
        }
        self.cells_entering(k)
    }

    /// Cells of level `k` that went on from it (to the GQ of level `k` or, at the last
    /// level, to the SPPs): IN and CR children plus unmasked starts.
    pub fn cells_entering(&self, k: u32) -> u64 {
        self.levels.get(k as usize).map_or(0, |l| (l.inside + l.crossed + l.starts).saturating_sub(l.polygons_masked))
    }

    /// Pixels covered by at least one polygon: every such pixel gets exactly one VB
    /// first write from a polygon (the background's writes are not counted).
    pub fn covered_pixels(&self) -> u64 {
        self.color.first_writes
    }

    /// Figures derived from the counters (ratios are 0 where the denominator is).
    pub fn derived(&self) -> Derived {
        let covered = self.covered_pixels();
        let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
        let masked: u64 = self.levels.iter().map(|l| l.masked).sum();
        let candidates: u64 = self.levels.iter().map(|l| l.inside + l.crossed + l.masked).sum();
        Derived {
            covered_pixels: covered,
            cells_tested: self.cells_tested(),
            cells_masked: masked,
            polygons_masked: self.levels.iter().map(|l| l.polygons_masked).sum(),
            masked_share_of_candidates: ratio(masked, candidates),
            masked_share_per_level: self
                .levels
                .iter()
                .map(|l| ratio(l.masked, l.inside + l.crossed + l.masked))
                .collect(),
            visible_fragments_per_covered_pixel: ratio(self.spp.pixels_visible, covered),
            spp_pixels_per_covered_pixel: ratio(self.spp.pixels_touched, covered),
            visible_area_pixels: self.spp.subpixels_set as f64 / SUBPIXELS_PER_PIXEL as f64,
        }
    }

    /// The identities that hold between the counters of one frame by construction of
    /// the GQ, SPP, CC and VB; each broken one is described in the result (empty:
    /// all hold). They are (with `L` the root level, `split(k)` =
    /// [`Self::cells_split`]):
    /// 1. every tested cell is exactly one of IN, CR, OUT, masked:
    ///    `tested[k] = inside[k] + crossed[k] + outside[k] + masked[k]`;
    /// 2. nothing tests the root: `tested[0] = 0`, and no edge test is counted there;
    /// 3. the children of split cells: `tested[k+1] = 4 split(k)` for `k < L`;
    /// 4. the fragments the SPPs got are the level-`L` cells that went on:
    ///    `fragments = inside[L] + crossed[L] + starts[L] - polygons_masked[L]`;
    /// 5. the SPPs look every active edge up in 16 pixels: `edge_lookups` is a
    ///    multiple of 16;
    /// 6. `pixels_visible <= pixels_touched <= 16 fragments`, and a pixel with visible
    ///    area has 1 to 16 newly set subpixels: `pixels_visible <= subpixels_set <=
    ///    16 pixels_visible`;
    /// 7. every visible pixel is coloured by exactly one CC channel:
    ///    `sum(pixels_per_channel) = pixels_visible`;
    /// 8. every visible pixel is one VB write: `first_writes + read_modify_writes =
    ///    pixels_visible`, and no pixel has more than 16 subpixels:
    ///    `subpixels_set <= 16 first_writes`;
    /// 9. polygons dropped whole are among those that started at that level.
    pub fn violations(&self) -> Vec<String> {
        let mut out = Vec::new();
        let l = self.root_level as usize;
        let mut check = |ok: bool, what: String| {
            if !ok {
                out.push(what);
            }
        };
        check(self.levels.len() == l + 1, format!("{} levels for root level {l}", self.levels.len()));
        for (k, c) in self.levels.iter().enumerate() {
            check(
                c.tested == c.inside + c.crossed + c.outside + c.masked,
                format!(
                    "level {k}: tested {} != IN {} + CR {} + OUT {} + masked {}",
                    c.tested, c.inside, c.crossed, c.outside, c.masked
                ),
            );
            check(
                c.polygons_masked <= c.starts,
                format!("level {k}: {} polygons dropped of {} started", c.polygons_masked, c.starts),
            );
        }
        if let Some(root) = self.levels.first() {
            check(root.tested == 0 && root.edge_tests == 0, format!("level 0: {} cells tested", root.tested));
        }
        for k in 0..l {
            let children = self.levels[k + 1].tested;
            let split = self.cells_split(k as u32);
            check(
                children == 4 * split,
                format!("level {}: tested {children} != 4 x {split} split at level {k}", k + 1),
            );
        }
        let s = &self.spp;
        let entering = self.cells_entering(self.root_level);
        check(
            s.fragments == entering,
            format!("SPP fragments {} != {entering} level-{l} cells handed on", s.fragments),
        );
        check(
            s.edge_lookups.is_multiple_of(PIXELS_PER_CELL),
            format!("SPP edge look-ups {} not a multiple of 16", s.edge_lookups),
        );
        check(
            s.pixels_visible <= s.pixels_touched && s.pixels_touched <= PIXELS_PER_CELL * s.fragments,
            format!(
                "SPP pixels visible {} / touched {} / fragments {}",
                s.pixels_visible, s.pixels_touched, s.fragments
            ),
        );
        check(
            s.pixels_visible <= s.subpixels_set && s.subpixels_set <= SUBPIXELS_PER_PIXEL * s.pixels_visible,
            format!("SPP subpixels set {} for {} visible pixels", s.subpixels_set, s.pixels_visible),
        );
        let c = &self.color;
        let coloured: u64 = c.pixels_per_channel.iter().sum();
        check(coloured == s.pixels_visible, format!("CC coloured {coloured} != SPP visible {}", s.pixels_visible));
        check(
            c.first_writes + c.read_modify_writes == s.pixels_visible,
            format!("VB writes {} + {} != SPP visible {}", c.first_writes, c.read_modify_writes, s.pixels_visible),
        );
        check(
            s.subpixels_set <= SUBPIXELS_PER_PIXEL * c.first_writes,
            format!("{} subpixels set in {} covered pixels", s.subpixels_set, c.first_writes),
        );
        out
    }
}

/// The pixels of a CC channel within a 4 x 4 cell, bit `4 y + x` (P1: the visible
/// pixels are dealt to four channels by their place in each 2 x 2 quad, channel
/// `(x & 1) + 2 (y & 1)`, as `vp::cc::channel` does).
pub const CHANNEL_PIXELS: [u16; 4] = [0x0505, 0x0A0A, 0x5050, 0xA0A0];

/// Bit `i` set where pixel `i` (`4 y + x`) of a cell has a non-empty subpixel set.
#[inline]
pub fn visible_pixels(sets: &[u16; 16]) -> u16 {
    let mut mask = 0u16;
    for (i, &set) in sets.iter().enumerate() {
        mask |= u16::from(set != 0) << i;
    }
    mask
}

impl Counters {
    /// Counts one cell's coloured pixels at once (`visible`: a bit per pixel, see
    /// [`visible_pixels`]): per CC channel, and as textured if `textured`. The same
    /// totals as counting pixel by pixel, with a few popcounts per cell instead of an
    /// indexed add per pixel.
    #[inline]
    pub fn count_cc_cell(&mut self, visible: u16, textured: bool) {
        let c = &mut self.color;
        for (n, bits) in c.pixels_per_channel.iter_mut().zip(CHANNEL_PIXELS) {
            *n += u64::from((visible & bits).count_ones());
        }
        if textured {
            c.textured += u64::from(visible.count_ones());
        }
    }

    /// Counts one SPP fragment: its visible subpixel sets and the number of its
    /// pixels on the screen.
    #[inline]
    pub fn count_spp_fragment(&mut self, sets: &[u16; 16], on_screen: u32) {
        self.count_spp_pixels(visible_pixels(sets).count_ones(), on_screen);
        self.spp.subpixels_set += u64::from(sets.iter().map(|v| v.count_ones()).sum::<u32>());
    }

    /// The per-fragment part of [`Self::count_spp_fragment`], from the count of pixels
    /// with a visible subpixel the SPPs already have (the subpixels set are counted
    /// once per frame: `VideoProcessor::run`).
    #[inline]
    pub fn count_spp_pixels(&mut self, pixels_visible: u32, on_screen: u32) {
        let s = &mut self.spp;
        s.fragments += 1;
        s.pixels_touched += u64::from(on_screen);
        s.pixels_visible += u64::from(pixels_visible);
    }
}

/// Pixels of a last-level (4 x 4) cell: one SPP each.
pub const PIXELS_PER_CELL: u64 = 16;
/// Subpixels of a pixel (4 x 4).
pub const SUBPIXELS_PER_PIXEL: u64 = 16;

/// Figures derived from one frame's [`Counters`] (see [`Counters::derived`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Derived {
    /// Pixels covered by at least one polygon (VB first writes).
    pub covered_pixels: u64,
    /// Cells tested over all levels.
    pub cells_tested: u64,
    /// Cells dropped by a mask memory, over all levels.
    pub cells_masked: u64,
    /// Polygons dropped whole, over all levels.
    pub polygons_masked: u64,
    /// Of the cells found IN or CR (the candidates), the share a mask dropped.
    pub masked_share_of_candidates: f64,
    /// The same per level (index = level).
    pub masked_share_per_level: Vec<f64>,
    /// Visible fragment pixels per covered pixel: how many fragments the VB blends
    /// into a covered pixel on average (1 where every pixel is one polygon's).
    pub visible_fragments_per_covered_pixel: f64,
    /// Pixels of the cells that reached the SPPs per covered pixel: the depth of work
    /// the SPPs see, which the masks reduce.
    pub spp_pixels_per_covered_pixel: f64,
    /// The visible areas of all fragments summed, in pixels: the screen area covered
    /// by polygons.
    pub visible_area_pixels: f64,
}
