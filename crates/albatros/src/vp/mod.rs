//! Video processor (VP, P1): turns a frame list into an antialiased image.
//!
//! ```text
//! frame list ─► BP ─► GQ level 0 ► … ► GQ level L-1 ─► 16 SPP ─► 4 CC ─► VB ─► F2 ─► gamma
//!               (edges)  cell processors + mask memories   subpixels  colour  accumulate
//! ```
//!
//! Polygons are processed strictly in the frame list's front-to-back order; each
//! subpixel belongs to the first polygon that covers it, the background takes what is
//! left. **Invariants**: the image does not depend on which mask levels are in use
//! ([`gq::MaskLevels`]) nor on whether counters are collected; the same frame list
//! gives the same bytes every time.

pub mod cc;
pub mod edge;
pub mod gq;
pub mod spp;
pub mod tables;
pub mod tac;
pub mod texture;
pub mod vb;

use std::sync::Arc;

use crate::frame::{FrameList, FramePolygon};
use crate::model::stats::Counters;
use cc::ColorComputers;
use edge::EdgeCode;
use gq::{CellProcessors, GqPolygon, MaskLevels};
use spp::SubpixelProcessors;
use tables::SppMode;
use texture::TextureMaps;
use vb::{Image, Readout, VbMode, VideoBuffer};

/// How the VP is configured for a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VpConfig {
    /// Mask memory levels in use.
    pub masks: MaskLevels,
    /// Which SPP table.
    pub spp: SppMode,
    /// Greene's hierarchical coverage: a cell whose subpixels are all covered is
    /// marked in the last level's mask memory, and a parent whose four children are
    /// marked is marked too (P1 marks only cells one polygon covers wholly). On by
    /// default for rendering; `model::experiment` uses P1's rule.
    pub hierarchical: bool,
    /// Collect per-unit counters.
    pub stats: bool,
    /// Readout options.
    pub readout: Readout,
    /// How the video buffer stores colours (default: P1's 8-bit log codes).
    pub vb: VbMode,
}

impl Default for VpConfig {
    fn default() -> Self {
        Self {
            masks: MaskLevels::ALL,
            spp: SppMode::Area,
            // Measured to win (BENCHMARKS.md: raster -16% on default, -22% on
            // terrain at 1920x1080) and never changes the image: on by default. The
            // architecture model runs P1's rule unless asked.
            hierarchical: true,
            stats: false,
            readout: Readout::default(),
            vb: VbMode::default(),
        }
    }
}

/// One video processor with its memories, sized for a screen.
#[derive(Clone, Debug)]
pub struct VideoProcessor {
    /// The configuration.
    pub config: VpConfig,
    /// The cell processors with their mask memories.
    pub gq: CellProcessors,
    /// The subpixel processors with the subpixel mask memory.
    pub spp: SubpixelProcessors,
    /// The video buffer.
    pub vb: VideoBuffer,
    /// Counters of the last frame (when `config.stats`).
    pub counters: Counters,
    /// The texture map memory (none at first: textured faces keep their colour).
    pub textures: Arc<TextureMaps>,
    /// The work of the last frame per column of last-level cells, in the units of
    /// [`work`] (a strip matrix evens out its VPs' work with it): what the VP did
    /// there, not what it took in time, so the same frame list gives the same tallies.
    pub column_work: Vec<u32>,
}

/// The weights of [`VideoProcessor::column_work`]: rough estimates of the work the VP
/// does for a cell, one unit about 120 instructions on the machine of session 5
/// (BENCHMARKS.md): a cell crossed by edges (its share of the GQ's splits and the
/// SPP's look-ups, ~1000), a cell wholly inside a polygon (the mask walk and the SPP's
/// step, ~250), a cell with visible pixels (the CC's ~740 and the VB's ~465), a column
/// of cells' background pass. Only their proportions matter: the strip matrix turns
/// each strip's tallies into its VP's measured time.
pub mod work {
    /// A cell with active edges.
    pub const EDGE_CELL: u32 = 8;
    /// A cell wholly inside a polygon, with no active edge.
    pub const INSIDE_CELL: u32 = 2;
    /// A cell with visible pixels, to the colour units and the VB.
    pub const VISIBLE_CELL: u32 = 10;
    /// A column of last-level cells' background pass, whatever is drawn.
    pub const BACKGROUND_COLUMN: u64 = 60;
}

impl VideoProcessor {
    /// A VP for a `width` x `height` screen.
    pub fn new(width: u32, height: u32, config: VpConfig) -> Self {
        let mut gq = CellProcessors::new(width, height, config.masks);
        gq.hierarchical = config.hierarchical;
        let counters = Counters::new(gq.root_level);
        Self {
            config,
            spp: SubpixelProcessors::new(width, height, config.spp),
            vb: VideoBuffer::new(width, height, config.vb),
            gq,
            counters,
            textures: Arc::default(),
            column_work: vec![0; width.div_ceil(spp::CELL_SIDE) as usize],
        }
    }

    /// Loads the texture map memory (the maps of the scene, indexed like
    /// `Scene::textures`).
    pub fn set_textures(&mut self, maps: impl Into<Arc<TextureMaps>>) {
        self.textures = maps.into();
    }

    /// Renders a frame list into the video buffer (every pixel of the VP's share is
    /// written afresh; nothing of the previous frame remains).
    pub fn render_frame(&mut self, frame: &FrameList) {
        self.render_stretches(std::slice::from_ref(frame));
    }

    /// [`Self::render_frame`] of a frame given as stretches
    /// ([`crate::gp::frame_stretches_into`]): the lists' polygons in order, one list
    /// after another, with the first list's header; the same image as their join.
    pub fn render_stretches(&mut self, stretches: &[FrameList]) {
        for l in stretches {
            assert_eq!((l.width, l.height), (self.vb.width, self.vb.height), "frame list for another screen size");
        }
        // One list (one GP) takes a copy with no per-fragment check of the stretch
        // (+1 % of colour + VB instructions on default and terrain with it).
        match (self.config.stats, stretches.len() > 1) {
            (true, true) => self.render_inner::<true, true>(stretches),
            (true, false) => self.render_inner::<true, false>(stretches),
            (false, true) => self.render_inner::<false, true>(stretches),
            (false, false) => self.render_inner::<false, false>(stretches),
        }
    }

    /// Renders and reads out an image.
    pub fn render(&mut self, frame: &FrameList) -> Image {
        self.render_frame(frame);
        self.vb.read_out(&self.config.readout)
    }

    /// `STRETCHES`: whether `stretches` may hold more than one list.
    fn render_inner<const STATS: bool, const STRETCHES: bool>(&mut self, stretches: &[FrameList]) {
        let frame = &stretches[0];
        // No clearing of the VB: every pixel of this VP's share gets a first write
        // each frame (the background is the last fragment of every pixel and takes
        // what is left, so each pixel's mask goes from empty to full), and the first
        // write replaces what the pixel held. Pixels outside the share are never
        // read out of this VP.
        let vb = &mut self.vb;
        // The background's colour encoded once for the frame, and whether F1 runs
        // inside the colour computers, found once.
        let background = vb.prepare_flat(frame.background);
        let fused = vb.fused_f1();
        let textures = &*self.textures;
        let mut sink = Colouring::<STATS, STRETCHES> {
            cc: ColorComputers::new(frame, textures),
            colors: cc::CellColors::default(),
            inner: Counters::new(self.gq.root_level),
            vb,
            background,
            fused,
            textures,
            stretches,
            stretch: 0,
            fifo: [spp::Visible::default(); FIFO_CELLS],
            queued: 0,
            kind: Kind::None,
            fresh: true,
            runs: [Run { start: 0, kind: Kind::None }; FIFO_CELLS],
            run_count: 0,
        };
        Self::run::<STATS>(
            &mut self.gq,
            &mut self.spp,
            &mut self.counters,
            &mut self.column_work,
            stretches,
            &mut sink,
        );
        // The fragments still queued (a frame with no background fragment after
        // them: a screen covered wholly).
        sink.flush();
        if STATS {
            self.counters.add(&sink.inner);
        }
    }

    /// The raster stages alone (BP, GQ, SPP with their mask memories), the colour
    /// units and the video buffer left out: for timing the stages apart. With no
    /// background pass, the SPPs' mask memory is left as the polygons set it:
    /// [`Self::restore_masks`] puts it back before the next render, which would
    /// otherwise copy it back itself and be timed with that copy.
    pub fn raster(&mut self, frame: &FrameList) -> u64 {
        let mut visible = 0u64;
        let mut count = EachCell::new(|_, vis: &spp::Visible| visible += u64::from(vis.any()));
        Self::run::<false>(
            &mut self.gq,
            &mut self.spp,
            &mut self.counters,
            &mut self.column_work,
            std::slice::from_ref(frame),
            &mut count,
        );
        visible
    }

    /// Puts the SPPs' mask memory back in its cleared state, as a render's
    /// background pass leaves it, after [`Self::raster`] (a 4 MB copy at 1920 x
    /// 1080 that the next render would otherwise make in its own time: the bench's
    /// one-thread frame counted it until session 21).
    pub fn restore_masks(&mut self) {
        self.spp.restore();
    }

    /// Which polygon owns every subpixel: `u32::MAX` for the background, else the
    /// polygon's index in the frame list. Row-major pixels, 16 subpixels each
    /// (`4 sy + sx`). The same pipeline as [`Self::render`], with the colour units
    /// replaced by a recorder.
    pub fn ownership(&mut self, frame: &FrameList) -> Vec<u32> {
        let (w, h) = (frame.width as usize, frame.height as usize);
        let mut owner = vec![u32::MAX; w * h * 16];
        let mut counters = Counters::new(self.gq.root_level);
        Self::run::<false>(
            &mut self.gq,
            &mut self.spp,
            &mut counters,
            &mut self.column_work,
            std::slice::from_ref(frame),
            &mut EachCell::new(|poly, vis: &spp::Visible| {
                let Some((_, p)) = poly else { return };
                for (i, &set) in vis.sets.iter().enumerate() {
                    let (x, y) = (vis.px as usize + (i & 3), vis.py as usize + (i >> 2));
                    for sub in 0..16 {
                        if set >> sub & 1 == 1 {
                            owner[(y * w + x) * 16 + sub] = p as u32;
                        }
                    }
                }
            }),
        );
        owner
    }

    /// The fragment codes of one polygon alone (no masks, no transparency): the
    /// subpixels it covers, per 4x4 cell `(px, py, sets)`.
    pub fn coverage(&mut self, frame: &FrameList, index: usize) -> Vec<(u32, u32, [u16; 16])> {
        let poly = &frame.polygons[index];
        let edges = frame.edges_of(poly);
        let bbox = bbox(frame.vertices_of(poly), frame.width, frame.height);
        let mut out = Vec::new();
        if bbox[0] >= bbox[1] || bbox[2] >= bbox[3] {
            return out;
        }
        let saved = self.gq.masks;
        self.gq.masks = MaskLevels::NONE;
        self.gq.clear();
        let mut counters = Counters::new(self.gq.root_level);
        let mut scratch = Counters::new(self.gq.root_level);
        let spp = &self.spp;
        let gp = GqPolygon { edges, opaque: false, bbox };
        self.gq.descend::<false>(&gp, &mut counters, &mut |frag| {
            let code = spp.fragment_code::<false>(&frag, edges, &mut scratch);
            // Pixels off the screen are not the polygon's.
            let mut sets = code;
            for (i, s) in sets.iter_mut().enumerate() {
                if frag.px + (i as u32 & 3) >= frame.width || frag.py + (i as u32 >> 2) >= frame.height {
                    *s = 0;
                }
            }
            out.push((frag.px, frag.py, sets));
        });
        self.gq.masks = saved;
        out
    }

    /// The VP's pipeline over a frame: BP, GQ descent, SPP; every visible fragment
    /// goes to `sink` ([`Sink::cell`], after [`Sink::polygon`] named its polygon
    /// by its stretch and index there; [`Sink::background`]'s last). The frame is
    /// `stretches`, their polygons one list after another (with one list, the
    /// index is the polygon's in the frame list).
    fn run<const STATS: bool>(
        gq: &mut CellProcessors,
        spp: &mut SubpixelProcessors,
        counters: &mut Counters,
        work: &mut [u32],
        stretches: &[FrameList],
        sink: &mut impl Sink,
    ) {
        gq.clear();
        spp.clear();
        work.fill(0);
        let share = spp.share;
        *counters = Counters::new(gq.root_level);
        if STATS {
            counters.polygons = stretches.iter().map(|l| l.polygons.len() as u64).sum();
        }
        // A second counter set for the SPP stage (the GQ holds the first).
        let mut inner = Counters::new(gq.root_level);
        let hierarchical = gq.hierarchical;
        let skip_marked = gq.hidden_boxes && gq.marks_last();
        // The last-level cells a polygon covers wholly, in Z order.
        let mut covered_cells: Vec<usize> = Vec::new();
        // The last box of a polygon ahead whose memory was asked for ([`Sink::ahead`]);
        // none yet: a box no other box is near.
        let mut asked = NOWHERE;
        for (s, frame) in stretches.iter().enumerate() {
            // (A list whose polygons were pushed past `FrameList::push_polygon` would
            // have its polygons passed over for want of boxes.)
            assert_eq!(
                frame.boxes.len(),
                frame.polygons.len(),
                "the frame list's boxes are not in step with its polygons"
            );
            let box_of = |i: usize| frame.boxes.get(i).map(|b| b.bounds());
            // The boxes of the polygons from the current one to the one ahead,
            // each found once, at `i % BOXES`.
            let mut boxes = [[0u32; 4]; BOXES];
            for (k, b) in boxes.iter_mut().enumerate().take(POLYGONS_AHEAD) {
                *b = box_of(k).unwrap_or_default();
            }
            // Whether each of those polygons was found hidden at the look-ahead (by
            // the marks then: see below).
            let mut hidden = [false; BOXES];
            for (i, poly) in frame.polygons.iter().enumerate() {
                if let Some(later) = box_of(i + POLYGONS_AHEAD) {
                    boxes[(i + POLYGONS_AHEAD) % BOXES] = later;
                    // A small box all of whose last-level cells are marked already
                    // (with counting off, [`gq::CellProcessors::box_marked`]): the
                    // polygon has nothing visible, and is passed over here, its
                    // memories not asked for, with no set-up, no start and no test of
                    // its box by the SPPs. Marks are only ever added, so it is hidden
                    // when its turn comes too, and its descent would mark no cell
                    // under Greene's rule (a cell in its box has all its last-level
                    // cells marked, so is marked itself); otherwise the marks it leaves
                    // out change later polygons' work, never their subpixels, as with
                    // [`gq::FragmentSink::box_hidden`]'s pass
                    // (`passing_hidden_boxes_over_is_the_descent` turns both off).
                    // `many` 960 x 540: 373 k of its 1,000 k triangles, the 155 k the
                    // start's `covered` dropped among them, where the SPPs' box test
                    // found 311 k (93 k left to it).
                    let marked = !STATS && skip_marked && gq.box_marked(later);
                    hidden[(i + POLYGONS_AHEAD) % BOXES] = marked;
                    if !STATS && !marked && share.meets_columns(later[0], later[1]) {
                        // The SPP's masks and the polygon's edges, for every polygon:
                        // a neighbour's box shares only some of their lines, and the
                        // first read of each cell's mask in a frame, and of each edge
                        // by the GQ's start, waited on memory (terrain, where the
                        // triangles follow one another across the ground: the SPP's
                        // mask load ~30 % of its copy's samples, the start's edge
                        // read ~8 % of the descent's; session 18).
                        spp.prefetch_box(later);
                        // (A triangle's three 32-byte codes span two or three lines:
                        // every line from the first byte, and the last byte's.)
                        let edges = frame.edges_of(&frame.polygons[i + POLYGONS_AHEAD]);
                        let (first, bytes) = (edges.as_ptr().cast::<u8>(), std::mem::size_of_val(edges));
                        for offset in (0..bytes).step_by(crate::hint::LINE) {
                            crate::hint::prefetch(first.wrapping_add(offset));
                        }
                        crate::hint::prefetch(first.wrapping_add(bytes.saturating_sub(1)));
                        // The VB's words only when not next to the last box asked for:
                        // a neighbour's memory is in the caches already (`many`'s
                        // triangles lie anywhere).
                        if !near(later, asked) {
                            sink.ahead(later);
                            asked = later;
                        }
                    }
                }
                if hidden[i % BOXES] {
                    continue;
                }
                let index = (s, i);
                let edges = frame.edges_of(poly);
                let bbox = boxes[i % BOXES];
                if bbox[0] >= bbox[1] || bbox[2] >= bbox[3] {
                    continue;
                }
                if !STATS && !share.meets_columns(bbox[0], bbox[1]) {
                    // Every subpixel of the polygon lies in its box: a polygon whose
                    // box misses this VP's strip has nothing here (its start cells
                    // would all read pre-masked). With counting on, it is counted as
                    // the machine does.
                    continue;
                }
                let opaque = poly.transparency == 0;
                let gp = GqPolygon { edges, opaque, bbox };
                sink.polygon(index);
                let spp_poly = spp.polygon(bbox, poly.transparency);
                let mut fragments = Fragments::<'_, _, STATS> {
                    spp: &mut *spp,
                    edges,
                    spp_poly: &spp_poly,
                    inner: &mut inner,
                    covered_cells: &mut covered_cells,
                    work: &mut *work,
                    sink: &mut *sink,
                    hierarchical,
                    opaque,
                    fill_ahead: bbox[1] - bbox[0] > FILL_AHEAD_BOX || bbox[3] - bbox[2] > FILL_AHEAD_BOX,
                };
                if STATS {
                    gq.descend_to::<STATS>(&gp, counters, &mut fragments);
                } else {
                    gq.descend_filling_to(&gp, counters, &mut fragments);
                }
                // Cells this polygon finished covering are marked for the next ones.
                gq.mark_covered_cells(&mut covered_cells);
            }
        }
        // The background: the last fragment of every pixel, over the cells of this
        // VP's share (the others are pre-masked whole: no subpixel of theirs is open).
        // Cells the last GQ level marks covered (all their subpixels taken: the
        // marks are sound) get nothing, and only have their masks put back, a run of
        // them at once; the marks are read a row of an 8 x 8 block at a time.
        let (mut background_subpixels, mut background_firsts) = (0u64, 0u64);
        let marks = gq.memory(gq.root_level);
        for (cy, runs) in share_cells(&spp.share, spp.stride, spp.rows) {
            for run in runs {
                let mut cx = run.start;
                while cx < run.end {
                    // This row of the cell's 8 x 8 block, from `cx` on to the run's end.
                    let end = ((cx | BLOCK_MASK) + 1).min(run.end);
                    let covered = u32::from(marks.block_row(cx, cy)) >> (cx & BLOCK_MASK);
                    let n = end - cx;
                    if covered & ((1 << n) - 1) == (1 << n) - 1 {
                        spp.background_covered(cy, cx..end);
                        cx = end;
                        continue;
                    }
                    for (i, x) in (cx..end).enumerate() {
                        if covered >> i & 1 == 1 {
                            spp.background_covered(cy, x..x + 1);
                            continue;
                        }
                        let vis = spp.background(x, cy);
                        if STATS {
                            background_subpixels += vis.sets.iter().map(|s| u64::from(s.count_ones())).sum::<u64>();
                            background_firsts += u64::from(vis.first.count_ones());
                        }
                        if vis.any() {
                            sink.background(&vis);
                        }
                    }
                    cx = end;
                }
            }
        }
        // Every cell of the share is back in its cleared state.
        spp.background_done();
        if STATS {
            // Counted once per frame instead of per fragment, exactly: every open
            // subpixel is set once, by a polygon or else by the background; every open
            // pixel has one first write, by a polygon or else by the background; every
            // other visible polygon pixel is a read-modify-write of the VB.
            let open = spp.open_pixels();
            inner.spp.subpixels_set += 16 * open - background_subpixels;
            let firsts = open - background_firsts;
            inner.color.first_writes += firsts;
            inner.color.read_modify_writes += inner.spp.pixels_visible - firsts;
            counters.add(&inner);
        }
    }
}

/// [`VideoProcessor::run`]'s work on the fragments of one polygon, handed to the
/// GQ's descent as a [`gq::FragmentSink`] whose method the descent inlines: the
/// SPPs' look-ups, Greene's covered cells, the work per column and the sink. (As a
/// closure it stayed out of line, called once a fragment: its saved registers, the
/// fragment built on the stack and its captures read back cost ~20 instructions a
/// call, ~109 k calls a frame on `default`.)
struct Fragments<'r, S, const STATS: bool> {
    spp: &'r mut SubpixelProcessors,
    edges: &'r [EdgeCode],
    spp_poly: &'r spp::SppPolygon,
    /// The SPP stage's counters.
    inner: &'r mut Counters,
    /// The last-level cells the polygon covers wholly, in Z order.
    covered_cells: &'r mut Vec<usize>,
    /// [`VideoProcessor::column_work`].
    work: &'r mut [u32],
    sink: &'r mut S,
    /// Greene's hierarchical coverage ([`VpConfig::hierarchical`]).
    hierarchical: bool,
    opaque: bool,
    /// The polygon's box is larger than [`FILL_AHEAD_BOX`]: its fill asks for the
    /// memories ahead.
    fill_ahead: bool,
}

impl<S: Sink, const STATS: bool> gq::FragmentSink for Fragments<'_, S, STATS> {
    #[inline(always)]
    fn box_hidden(&mut self) -> bool {
        !STATS && self.spp.box_hidden(self.spp_poly)
    }

    #[inline(always)]
    fn fragment(&mut self, frag: gq::Fragment<'_>) {
        if !STATS && frag.active.is_empty() {
            // With counting off, cells no edge crosses (wholly inside, up to
            // four siblings at once) need no look-ups, and an opaque
            // polygon's are marked covered by the GQ
            // ([`CellProcessors::descend_filling`]).
            if self.fill_ahead && (frag.px | frag.py) & 8 == 0 {
                // The memories under the cell of level L - 2 next in Z order, where
                // a large polygon's fill goes next (a hint), asked for at the
                // first cell of level L - 1 of each.
                let (x, y) = unmorton(gq::morton(frag.px / 16, frag.py / 16) + 1);
                let ahead = [x * 16, x * 16 + 16, y * 16, y * 16 + 16];
                self.spp.prefetch_box(ahead);
                self.sink.ahead(ahead);
            }
            let mut cells = frag.cells;
            while cells != 0 {
                let c = cells.trailing_zeros();
                cells &= cells - 1;
                let (px, py) = (frag.px + spp::CELL_SIDE * (c & 1), frag.py + spp::CELL_SIDE * (c >> 1));
                // The SPPs' result written where the sink keeps it ([`Sink::slot`]).
                let vis = self.sink.slot();
                let any = self.spp.inside_to(px, py, self.spp_poly, vis);
                if self.hierarchical && !self.opaque && vis.covered {
                    self.covered_cells.push(gq::morton(px / spp::CELL_SIDE, py / spp::CELL_SIDE));
                }
                let column = &mut self.work[(px / spp::CELL_SIDE) as usize];
                *column += work::INSIDE_CELL;
                if any {
                    *column += work::VISIBLE_CELL;
                    self.sink.cell();
                }
            }
            return;
        }
        let vis = self.sink.slot();
        let any = self.spp.process_to::<STATS>(&frag, self.edges, self.spp_poly, self.inner, vis);
        if self.hierarchical && vis.covered {
            self.covered_cells.push(gq::morton(frag.px / spp::CELL_SIDE, frag.py / spp::CELL_SIDE));
        }
        let column = &mut self.work[(frag.px / spp::CELL_SIDE) as usize];
        *column += work::EDGE_CELL;
        if any {
            *column += work::VISIBLE_CELL;
            self.sink.cell();
        }
    }
}

/// Where [`VideoProcessor::run`] hands the visible fragments: the colour units and
/// the VB when rendering ([`Colouring`]), a recorder or a count otherwise
/// ([`EachCell`]).
trait Sink {
    /// The cells that come next, up to the next call, are of polygon `index` (its
    /// stretch and its index there). Once per polygon, before its descent: what
    /// depends on the polygon alone is settled here, not per cell.
    fn polygon(&mut self, index: (usize, usize));
    /// Where the SPPs write their next fragment (of the last polygon named): the
    /// sink's own memory, so that a visible fragment is kept with no copy.
    fn slot(&mut self) -> &mut spp::Visible;
    /// The fragment just written into [`Self::slot`] is visible.
    fn cell(&mut self);
    /// A visible fragment of the background (after every polygon).
    fn background(&mut self, vis: &spp::Visible);
    /// A polygon [`POLYGONS_AHEAD`] later has the box `bbox` on this VP's share:
    /// a hint to fetch its memory (no result may depend on it).
    #[inline(always)]
    fn ahead(&mut self, bbox: [u32; 4]) {
        let _ = bbox;
    }
}

/// The widest or highest box (pixels) whose fill does not ask for the memories
/// ahead (the next cell of level L - 2 in Z order, at the first cell of level L - 1
/// of each: one cell of level L - 1 ahead in Z order, or two, or eight, was no
/// better on `rhombus` and `default`, and asking at every cell cost ~100
/// instructions a cell): the look-ahead asks for a box of up to
/// [`spp::PREFETCH_BOX_CELLS`] cells a side before the polygon starts (terrain's
/// inside cells, ~9 M instructions of asking, had their memory already).
const FILL_AHEAD_BOX: u32 = spp::PREFETCH_BOX_CELLS * spp::CELL_SIDE;

/// The cell `(x, y)` of Z-order index `z` ([`gq::morton`]'s inverse).
#[inline(always)]
fn unmorton(z: usize) -> (u32, u32) {
    #[inline(always)]
    fn compact(v: u64) -> u32 {
        let v = v & 0x5555_5555_5555_5555;
        let v = (v | v >> 1) & 0x3333_3333_3333_3333;
        let v = (v | v >> 2) & 0x0F0F_0F0F_0F0F_0F0F;
        let v = (v | v >> 4) & 0x00FF_00FF_00FF_00FF;
        let v = (v | v >> 8) & 0x0000_FFFF_0000_FFFF;
        ((v | v >> 16) & 0xFFFF_FFFF) as u32
    }
    (compact(z as u64), compact((z as u64) >> 1))
}

/// How many polygons ahead of the one being rendered the VP asks for the video
/// memory under the next ones ([`Sink::ahead`]).
const POLYGONS_AHEAD: usize = 2;

/// The ring of boxes the loop keeps (a power of two above [`POLYGONS_AHEAD`]).
const BOXES: usize = 4;

/// Pixels around a box within which [`near`] finds another box.
const NEAR_PIXELS: u32 = 16;

/// A box [`near`] no box on a screen is near (past any screen's side).
const NOWHERE: [u32; 4] = [u32::MAX; 4];

/// Whether box `b` lies within [`NEAR_PIXELS`] of box `a` (`[x0, x1, y0, y1]`):
/// the look-ahead then leaves its memory to the caches.
#[inline(always)]
fn near(b: [u32; 4], a: [u32; 4]) -> bool {
    let grown = |v: u32| v.saturating_add(NEAR_PIXELS);
    grown(b[0]) >= a[0] && b[1] <= grown(a[1]) && grown(b[2]) >= a[2] && b[3] <= grown(a[3])
}

/// A [`Sink`] from a function of the polygon (`None`: the background) and the
/// fragment.
struct EachCell<F> {
    index: Option<(usize, usize)>,
    /// [`Sink::slot`].
    vis: spp::Visible,
    each: F,
}

impl<F: FnMut(Option<(usize, usize)>, &spp::Visible)> EachCell<F> {
    fn new(each: F) -> Self {
        Self { index: None, vis: spp::Visible::default(), each }
    }
}

impl<F: FnMut(Option<(usize, usize)>, &spp::Visible)> Sink for EachCell<F> {
    fn polygon(&mut self, index: (usize, usize)) {
        self.index = Some(index);
    }

    #[inline(always)]
    fn slot(&mut self) -> &mut spp::Visible {
        &mut self.vis
    }

    fn cell(&mut self) {
        (self.each)(self.index, &self.vis);
    }

    fn background(&mut self, vis: &spp::Visible) {
        (self.each)(None, vis);
    }
}

/// What [`Colouring`] does with the cells of a polygon ([`Run`]).
#[derive(Clone, Copy)]
enum Kind<'a> {
    /// No polygon named yet.
    None,
    /// Not yet known whether the polygon has one colour (found at its first
    /// visible cell: most polygons have none).
    Unknown(&'a FramePolygon),
    /// A polygon of one colour, encoded for the VB once: to the VB as the
    /// background goes, with no work per pixel in the CC.
    Flat(vb::FlatColor),
    /// Coloured by the CC pixel by pixel.
    Shaded(&'a FramePolygon),
}

/// The [`Sink`] of [`VideoProcessor::render_inner`]: the colour computers and the
/// VB. (What depends on the polygon alone, its stretch's colour computers, the
/// polygon's record and whether it has one colour, is settled once per polygon:
/// as a closure called per cell with the polygon's index, it took some 60
/// instructions a cell.)
struct Colouring<'a, 'v, const STATS: bool, const STRETCHES: bool> {
    cc: ColorComputers<'a>,
    colors: cc::CellColors,
    inner: Counters,
    vb: &'v mut VideoBuffer,
    /// The background's colour, encoded once for the frame.
    background: vb::FlatColor,
    /// Whether F1 runs inside the colour computers, found once.
    fused: Option<vb::FusedF1>,
    textures: &'a TextureMaps,
    stretches: &'a [FrameList],
    /// The stretch of `cc`.
    stretch: usize,
    /// The visible fragments the colour computers have yet to take, in order:
    /// `fifo[..queued]`. The SPPs write the next fragment at `fifo[queued]`
    /// ([`Sink::slot`]), kept there if visible: no copy a cell.
    fifo: [spp::Visible; FIFO_CELLS],
    queued: usize,
    /// What colours the cells of the polygon named last (found at its first
    /// visible cell).
    kind: Kind<'a>,
    /// Whether the polygon named last has no cell in the queue yet: its next
    /// visible cell begins a run.
    fresh: bool,
    /// The polygons of the queued fragments, in order, `runs[..run_count]`: run `k`
    /// holds the fragments from its `start` to the next run's (the last run's to
    /// `queued`), at least one (so there are at most `FIFO_CELLS`). Begun at a
    /// polygon's first visible cell, not when it is named: most of `many`'s
    /// polygons have one or two visible cells, hidden ones none.
    runs: [Run<'a>; FIFO_CELLS],
    run_count: usize,
}

/// How many visible fragments wait between the SPPs and the colour computers
/// before the colour computers take them all ([`Colouring::flush`]); a power of two.
///
/// The machine's stages are a pipeline with queues between them. Here the queue lets
/// each stage run a batch of cells in turn, its code and tables hot in the caches:
/// shading each cell as the SPPs hand it on, the GQ and SPP ran ~45 % slower inside
/// the rendering pass than alone (terrain, perf samples against instructions;
/// session 19). The order of the cells is kept, so the VB's sums are the same.
const FIFO_CELLS: usize = 64;

const _: () = assert!(FIFO_CELLS.is_power_of_two());

/// Queued fragments of one polygon in [`Colouring::fifo`], from `start` on, and what
/// colours them.
#[derive(Clone, Copy)]
struct Run<'a> {
    start: usize,
    kind: Kind<'a>,
}

impl<const STATS: bool, const STRETCHES: bool> Colouring<'_, '_, STATS, STRETCHES> {
    /// The colour computers and the VB take every fragment waiting, in order.
    #[inline(never)]
    fn flush(&mut self) {
        let count = self.run_count;
        let end = |runs: &[Run], k: usize| if k + 1 < count { runs[k + 1].start } else { self.queued };
        let mut k = 0;
        while k < count {
            let cells = &self.fifo[self.runs[k].start..end(&self.runs, k)];
            match self.runs[k].kind {
                Kind::Shaded(poly) => self.cc.shade_accumulate::<STATS>(
                    poly,
                    cells,
                    &mut self.colors,
                    &mut self.inner,
                    self.vb,
                    self.fused,
                ),
                Kind::Flat(_) => {
                    // This run and the one-colour runs after it, in one call (`many`:
                    // ~1.4 cells a run).
                    let flats = self.runs[k..count].iter().take_while(|r| matches!(r.kind, Kind::Flat(_))).count();
                    let (fifo, runs) = (&self.fifo, &self.runs);
                    self.vb.accumulate_prepared_runs((k..k + flats).map(|j| match runs[j].kind {
                        Kind::Flat(flat) => (&fifo[runs[j].start..end(runs, j)], flat),
                        _ => unreachable!("a run counted as one colour"),
                    }));
                    k += flats;
                    continue;
                }
                Kind::None | Kind::Unknown(_) => unreachable!("a cell queued before its polygon"),
            }
            k += 1;
        }
        self.queued = 0;
        self.run_count = 0;
        // The next cells of the polygon named last begin a run again.
        self.fresh = true;
    }

    /// The first queued cell of the polygon named last (or the first since a
    /// flush) begins its run, with whether it has one colour found at its first
    /// (most polygons have none).
    #[inline(always)]
    fn begin_run(&mut self) {
        self.fresh = false;
        if let Kind::Unknown(poly) = self.kind {
            self.kind = match self.cc.flat_color(poly) {
                Some(color) => Kind::Flat(self.vb.prepare_flat(color)),
                None => Kind::Shaded(poly),
            };
        }
        self.runs[self.run_count & (FIFO_CELLS - 1)] = Run { start: self.queued, kind: self.kind };
        self.run_count += 1;
    }
}

impl<const STATS: bool, const STRETCHES: bool> Sink for Colouring<'_, '_, STATS, STRETCHES> {
    #[inline]
    fn polygon(&mut self, (s, p): (usize, usize)) {
        // With one list, `s` is 0.
        let s = if STRETCHES { s } else { 0 };
        if STRETCHES && s != self.stretch {
            // The colour computers' registers, loaded again at each stretch (its
            // own texture set-ups), after the last stretch's cells.
            self.flush();
            self.stretch = s;
            self.cc = ColorComputers::new(&self.stretches[s], self.textures);
        }
        let poly = &self.stretches[s].polygons[p];
        // (Not when counting: the counters count the CC's pixels as the machine
        // colours them.)
        self.kind = if STATS { Kind::Shaded(poly) } else { Kind::Unknown(poly) };
        self.fresh = true;
    }

    #[inline(always)]
    fn ahead(&mut self, bbox: [u32; 4]) {
        self.vb.prefetch_box(bbox);
    }

    #[inline(always)]
    fn slot(&mut self) -> &mut spp::Visible {
        &mut self.fifo[self.queued & (FIFO_CELLS - 1)]
    }

    #[inline(always)]
    fn cell(&mut self) {
        // The VB's writes are counted once per frame (`run`).
        if self.fresh {
            self.begin_run();
        }
        self.queued += 1;
        if self.queued == FIFO_CELLS {
            self.flush();
        }
    }

    #[inline]
    fn background(&mut self, vis: &spp::Visible) {
        // (After every polygon's cells: the background is each pixel's last.)
        if self.queued != 0 {
            self.flush();
        }
        self.vb.accumulate_prepared(vis, &self.background);
    }
}

/// The last cell of an 8 x 8 block of last-level cells, as a mask of a column: the
/// blocks the background pass reads the GQ's marks by ([`gq::MaskMemory::block_row`]).
const BLOCK_MASK: usize = 7;

/// The last-level cells of a share of a `stride x rows`-cell screen, row by row:
/// `(cy, runs of columns cx)`. With whole-cell tiles, only the rows and runs of
/// columns of the share's tiles; with a pixel interleave (tiles under a cell), every
/// cell.
fn share_cells(
    share: &gq::Share,
    stride: usize,
    rows: usize,
) -> impl Iterator<Item = (usize, impl Iterator<Item = std::ops::Range<usize>>)> {
    let whole_cells = share.tile >= spp::CELL_SIDE && share.p * share.q > 1;
    // Cells per tile side, and the share's first tile column and row.
    let (side, p, q) = if whole_cells {
        ((share.tile / spp::CELL_SIDE) as usize, share.p as usize, share.q as usize)
    } else {
        (stride.max(rows).max(1), 1, 1)
    };
    let (i, j) = if whole_cells { (share.i as usize, share.j as usize) } else { (0, 0) };
    // A strip's cell columns (whole cells: its borders are multiples of a cell).
    let (s0, s1) = share.strip;
    let (s0, s1) = ((s0 / spp::CELL_SIDE) as usize, s1.div_ceil(spp::CELL_SIDE).min(stride as u32) as usize);
    (0..rows).filter(move |&cy| (cy / side) % q == j).map(move |cy| {
        let runs = (i * side..stride)
            .step_by(side * p)
            .map(move |x0| x0.max(s0)..(x0 + side).min(stride).min(s1))
            .filter(|run| !run.is_empty());
        (cy, runs)
    })
}

/// The pixel bounding box `[x0, x1) x [y0, y1)` of a polygon, inside the screen.
///
/// With SSE4.1 (the build's x86-64-v2 target has it), [`bbox_sse41`]: the same
/// numbers in two lanes and four, about 20 instructions a polygon rather than 55
/// (`many`'s VP loop spent ~55 a triangle here, more than half of its own cost).
#[inline]
pub fn bbox(verts: &[crate::frame::ScreenVertex], width: u32, height: u32) -> [u32; 4] {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    if width.max(height) <= BBOX_SSE41_MAX {
        // SAFETY: `bbox_sse41` needs SSE4.1, which the build enables for every
        // function (this branch is compiled only then).
        #[allow(unsafe_code, reason = "a function compiled for SSE4.1 in a build that requires it")]
        return unsafe { bbox_sse41(verts, width, height) };
    }
    bbox_plain(verts, width, height)
}

/// The largest screen side [`bbox_sse41`] takes: its bounds are exact as `f32`.
const BBOX_SSE41_MAX: u32 = 1 << f32::MANTISSA_DIGITS;

/// [`bbox`] by its definition, one coordinate at a time.
pub fn bbox_plain(verts: &[crate::frame::ScreenVertex], width: u32, height: u32) -> [u32; 4] {
    let (mut x0, mut x1, mut y0, mut y1) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
    // Comparisons rather than `f32::min` and `max`: the same values (a NaN
    // coordinate is passed over either way), one `minss` or `maxss` each rather than
    // three instructions (~3 % of `many`'s VP went to this box).
    for v in verts {
        x0 = if v.x < x0 { v.x } else { x0 };
        x1 = if v.x > x1 { v.x } else { x1 };
        y0 = if v.y < y0 { v.y } else { y0 };
        y1 = if v.y > y1 { v.y } else { y1 };
    }
    // A subpixel set may reach one pixel beyond the exact box (rounding to half a
    // subpixel), so widen by one pixel each way.
    let lo = |v: f32, max: u32| ((v.floor() - 1.0).max(0.0) as u32).min(max);
    let hi = |v: f32, max: u32| ((v.ceil() + 1.0).max(0.0) as u32).min(max);
    [lo(x0, width), hi(x1, width), lo(y0, height), hi(y1, height)]
}

/// [`bbox_plain`] in SSE4.1, bit for bit: the least and greatest `(x, y)` in two
/// lanes (`minps`/`maxps` with the vertex first pass a NaN over, as the
/// comparisons do), then the four bounds side by side: floor or ceil, minus or plus
/// one, `max` with 0 (a NaN gives 0, as `f32::max` does), `min` with the screen's
/// side (exact as `f32` up to [`BBOX_SSE41_MAX`], and the bounds are whole numbers,
/// so the truncating conversion gives what the saturating cast and `min` give).
#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
#[target_feature(enable = "sse4.1")]
#[inline]
fn bbox_sse41(verts: &[crate::frame::ScreenVertex], width: u32, height: u32) -> [u32; 4] {
    use std::arch::x86_64::*;
    let (mut lo, mut hi) = (_mm_set1_ps(f32::MAX), _mm_set1_ps(f32::MIN));
    for v in verts {
        let p = _mm_setr_ps(v.x, v.y, 0.0, 0.0);
        lo = _mm_min_ps(p, lo);
        hi = _mm_max_ps(p, hi);
    }
    // Lanes x0, y0, x1, y1.
    let bounds = box_bounds_sse41(_mm_movelh_ps(lo, hi), width, height);
    let mut out = [0u32; 4];
    // SAFETY: `out` is 16 bytes, which the store writes.
    #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
    unsafe {
        _mm_storeu_si128(out.as_mut_ptr().cast(), bounds)
    };
    out
}

/// [`bbox_sse41`]'s bounds from the least and greatest `x, y` of a polygon's
/// vertices (lanes `x0, y0, x1, y1`): floor or ceil, minus or plus one, `max` with
/// 0, `min` with the screen's side, truncated to whole numbers, in lanes `x0, x1,
/// y0, y1`. Also the GP's set-up's, on a triangle's lanes
/// (`gp::setup::triangle_vertices_avx2`), so that its boxes are the VP's.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[inline]
pub(crate) fn box_bounds_sse41(v: std::arch::x86_64::__m128, width: u32, height: u32) -> std::arch::x86_64::__m128i {
    use std::arch::x86_64::*;
    let one = _mm_set1_ps(1.0);
    let widened = _mm_blend_ps::<0b1100>(_mm_sub_ps(_mm_floor_ps(v), one), _mm_add_ps(_mm_ceil_ps(v), one));
    let (w, h) = (width as f32, height as f32);
    let clamped = _mm_min_ps(_mm_max_ps(widened, _mm_setzero_ps()), _mm_setr_ps(w, h, w, h));
    // To x0, x1, y0, y1.
    _mm_shuffle_epi32::<0b11_01_10_00>(_mm_cvttps_epi32(clamped))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The filling descent's pass over a polygon whose box is covered already
    /// ([`gq::FragmentSink::box_hidden`], [`spp::SubpixelProcessors::box_hidden`]) is
    /// the descent: the same visible cells (polygon, pixel, sets, first writes,
    /// covered) in the same order, with and without Greene's rule, under several mask
    /// levels, on `many` (tiny triangles, most of them hidden) at two sizes and on
    /// `default`; under Greene's rule with the last level in use, the same GQ marks
    /// too. And it passes polygons over: the work tallied per column drops.
    #[test]
    fn passing_hidden_boxes_over_is_the_descent() {
        use gq::{CellProcessors, MaskLevels};
        for (name, width, height) in [("many", 240, 135), ("many", 480, 270), ("default", 320, 240)] {
            let mut scene = crate::db::builtin::scene(name).unwrap();
            scene.screen = crate::db::Screen { width, height };
            let db = crate::gp::Database::new(scene);
            let (frame, _) = crate::gp::frame_of_scene(&db, &crate::gp::GpConfig::default());
            let l = CellProcessors::root_level_for(width, height);
            for masks in [MaskLevels::mode_iv(l), MaskLevels::NONE, MaskLevels::mode_ii(l), MaskLevels::range(1, l - 1)]
            {
                for hierarchical in [true, false] {
                    let run = |hidden_boxes: bool| {
                        let mut vp =
                            VideoProcessor::new(width, height, VpConfig { masks, hierarchical, ..VpConfig::default() });
                        vp.gq.hidden_boxes = hidden_boxes;
                        let mut cells = Vec::new();
                        VideoProcessor::run::<false>(
                            &mut vp.gq,
                            &mut vp.spp,
                            &mut vp.counters,
                            &mut vp.column_work,
                            std::slice::from_ref(&frame),
                            &mut EachCell::new(|poly, vis: &spp::Visible| cells.push((poly, *vis))),
                        );
                        let marks: Vec<Vec<bool>> = (0..=l)
                            .map(|k| {
                                let m = vp.gq.memory(k);
                                (0..1usize << k).flat_map(|y| (0..1usize << k).map(move |x| m.get(x, y))).collect()
                            })
                            .collect();
                        let work: u64 = vp.column_work.iter().map(|&w| u64::from(w)).sum();
                        (cells, marks, work, vp.spp.small_route_avx2())
                    };
                    let (cells, marks, work, tested) = run(true);
                    let (plain_cells, plain_marks, plain_work, _) = run(false);
                    let what = format!("{name} {width} x {height}, masks {masks:?}, hierarchical {hierarchical}");
                    assert_eq!(cells.len(), plain_cells.len(), "{what}: visible cells");
                    assert!(cells == plain_cells, "{what}: visible cells differ");
                    if hierarchical && masks.has(l) {
                        assert!(marks == plain_marks, "{what}: marks differ");
                    }
                    assert!(work <= plain_work, "{what}: work {work} against {plain_work}");
                    // (Only the AVX2 route's small polygons are tested whole: on a
                    // processor without AVX2, or with the AVX-512 copies asked for,
                    // [`crate::isa`], none is passed over.)
                    if name == "many" && tested {
                        assert!(work < plain_work, "{what}: no polygon passed over");
                    }
                }
            }
        }
    }

    /// The look-ahead's test of a box against the last one asked for ([`near`]):
    /// within [`NEAR_PIXELS`] on every side, and never near [`NOWHERE`].
    #[test]
    fn the_look_ahead_skips_neighbours_only() {
        let a = [100, 110, 50, 58];
        // The same box, one overlapping it and one a few pixels off: near.
        assert!(near(a, a));
        assert!(near([104, 114, 54, 62], a));
        assert!(near([110 + NEAR_PIXELS - 8, 110 + NEAR_PIXELS, 58, 60], a));
        // Past the margin on any side, or nothing asked yet: not near.
        assert!(!near([111 + NEAR_PIXELS, 120 + NEAR_PIXELS, 50, 58], a));
        assert!(!near([60, 70, 50, 58], a));
        assert!(!near([100, 110, 59 + NEAR_PIXELS, 70 + NEAR_PIXELS], a));
        assert!(!near([100, 110, 10, 20], a));
        assert!(!near(a, NOWHERE));
        assert!(!near([0, 16, 0, 16], NOWHERE));
        // The largest boxes do not overflow.
        assert!(near(NOWHERE, NOWHERE));
    }

    /// [`bbox`] (by whichever copy the build runs) is [`bbox_plain`]: random
    /// polygons on and off the screen, and coordinates that are NaN, infinite,
    /// negative zero, huge, or halfway between pixels.
    #[test]
    fn bbox_is_bbox_plain() {
        use crate::frame::ScreenVertex;
        let special =
            [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0, 0.0, 1e30, -1e30, 0.5, 1919.5, 3e9, 16777217.0];
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for k in 0..200_000 {
            let n = (next() % 9) as usize;
            let mut coordinate = || {
                let r = next();
                if r % 7 == 0 {
                    special[(r >> 8) as usize % special.len()]
                } else {
                    ((r >> 16) % 5_000_000) as f32 / 1000.0 - 1000.0
                }
            };
            let verts: Vec<ScreenVertex> =
                (0..n).map(|_| ScreenVertex { x: coordinate(), y: coordinate(), inv_w: 1.0 }).collect();
            let (w, h) = [(1920, 1080), (1, 1), (333, 217), (4000, 3000)][k % 4];
            assert_eq!(bbox(&verts, w, h), bbox_plain(&verts, w, h), "{verts:?} on {w} x {h}");
        }
    }

    /// The background's cells of a share are the cells whose first pixel the share
    /// owns (every cell with a pixel interleave), each once, row by row.
    #[test]
    fn share_cells_are_the_cells_of_the_share() {
        let (stride, rows) = (37, 23);
        for (tile, p, q) in [(4, 1, 1), (1, 2, 2), (2, 3, 1), (4, 2, 1), (16, 2, 2), (64, 3, 2), (8, 1, 3), (256, 2, 2)]
        {
            for j in 0..q {
                for i in 0..p {
                    let share = gq::Share::interleaved(tile, p, q, i, j);
                    let got: Vec<(usize, usize)> = share_cells(&share, stride, rows)
                        .flat_map(|(cy, runs)| runs.flatten().map(move |cx| (cx, cy)))
                        .collect();
                    let want: Vec<(usize, usize)> = (0..rows)
                        .flat_map(|cy| (0..stride).map(move |cx| (cx, cy)))
                        .filter(|&(cx, cy)| tile < 4 || share.owns_pixel(4 * cx as u32, 4 * cy as u32))
                        .collect();
                    assert_eq!(got, want, "tile {tile}, {p} x {q}, VP ({i}, {j})");
                }
            }
        }
    }
}
