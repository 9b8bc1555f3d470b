//! Subpixel processors (SPP, P1 fig. 5): sixteen of them, one per pixel of a 4 x 4
//! cell, each pixel split into 4 x 4 subpixels.
//!
//! Input: a level-L cell from the last GQ with the edges that cross it. For every
//! pixel and edge the SPP forms the edge's V at the pixel's two borders relative to
//! the pixel, rounds them to half a subpixel, and looks the 16-bit subpixel set up in
//! the [`SppTable`](super::tables::SppTable); the AND over edges is the fragment's code. Against the subpixel
//! mask memory (256 bits per cell, `[u16; 16]`):
//! `visible = fragment & thin(t) & !mask; mask |= visible; area = popcount / 16`,
//! and the first-write flag marks pixels that had no subpixel covered before.
//!
//! Transparency (P2 fig. 3): a face of code `t` keeps only a dither-thinned subset of
//! density `1 - t/64` of its subpixels ([`thinning`]), so faces behind fill the rest.
//!
//! What the SPPs take of a polygon (its thinning pattern, its box as the AVX2
//! clip's lanes, the step its fragments go to) is made once before its descent
//! ([`SppPolygon`]), not per fragment. A small polygon's fragments first ask whether
//! the box's pixels in the cell are all covered already, before any edge is looked
//! up ([`Route::Avx2Small`]).
//!
//! On the AVX2 step's critical path (perf, session 16): values just stored narrowly
//! and loaded wide miss the store forwarding, so the step takes the fragment's pixel
//! by value, not the two `u32` of [`Fragment`] as one 8-byte load, and its cold
//! vertex copies keep their words in arrays of their own
//! ([`SubpixelProcessors::process_avx2`], [`words_through_memory`]).
//!
//! Bit layout of a pixel's set: bit `4 sy + sx`, subpixel column `sx`, row `sy` from
//! the pixel's top-left. A cell's 16 pixels are indexed `4 y + x` likewise.

use super::edge::{EdgeCode, ExactLine, Tg, EDGE_FRAC_BITS, EXACT32_END_LIMIT, SNAP_ONE};
#[cfg(target_arch = "x86_64")]
use super::gq::{ActiveEdge, ONE_CELL};
use super::gq::{Fragment, Share};
use super::tables::{SppMode, SppRowTable, ROW_PART_WORDS, ROW_Q_COUNT, ROW_Q_MAX, ROW_Q_MIN, SPP_V_BITS};
#[cfg(test)]
use super::tables::{SppTable, SPP_Q_COUNT, SPP_Q_MAX, SPP_Q_MIN};
use crate::model::stats::Counters;

/// Pixels per cell side at the last level.
pub const CELL_SIDE: u32 = 4;
/// A full pixel: all 16 subpixels.
pub const FULL: u16 = 0xFFFF;

/// The pixels of the 4 x 4 cell at pixel `(px, py)` inside the box `[x0, x1) x
/// [y0, y1)` (`bbox`, as [`super::bbox`] gives it): bit `4 y + x`.
///
/// The BP's box as a window on the SPPs' codes: no subpixel outside a polygon's
/// box (its vertices' box widened by a pixel each way) is the polygon's. Without
/// it, beyond a sliver's acute tip the row tables' sets of the two edges can AND to
/// a few subpixels more than a pixel past the box (where the two edges' rounded
/// positions are within a step of `q` on a pixel line but not on the same table
/// entry), in cells only a descent from the polygon's bounding cell reaches: the
/// image then depended on where the bounding cell's borders happened to lie, and
/// descents could not start at the cells of the polygon's size
/// ([`super::gq::CellProcessors::descend_filling`]). Two comparisons per border in
/// hardware; here a test skips the clip for cells wholly inside the box (the AVX2
/// step clips every fragment with no branch: [`box_outside_at_avx2`]).
#[inline]
pub fn box_pixels(px: u32, py: u32, bbox: [u32; 4]) -> u16 {
    let [x0, x1, y0, y1] = bbox;
    if px >= x0 && px + CELL_SIDE <= x1 && py >= y0 && py + CELL_SIDE <= y1 {
        return ALL_PIXELS;
    }
    // The cell's pixels `lo..hi` (each in 0..=4) along one axis inside `[a, b)`, as
    // bits of `unit` each (1 for columns, 4 for rows: a row is 4 bits of the code).
    let span = |p: u32, a: u32, b: u32, unit: u32| {
        let (lo, hi) = (a.saturating_sub(p).min(CELL_SIDE) * unit, b.saturating_sub(p).min(CELL_SIDE) * unit);
        ((1u32 << hi) - 1) & !((1u32 << lo) - 1)
    };
    // The columns repeated in every row, ANDed with the rows' nibbles.
    ((span(px, x0, x1, 1) * 0x1111) & span(py, y0, y1, 4)) as u16
}

/// The visible part of a polygon in one cell, handed to the colour computers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Visible {
    /// Left pixel of the cell.
    pub px: u32,
    /// Top pixel of the cell.
    pub py: u32,
    /// Visible subpixel set per pixel (`4 y + x`).
    pub sets: [u16; 16],
    /// Bit per pixel: first write (the pixel had nothing covered before).
    pub first: u16,
    /// The cell is now wholly covered (all 256 subpixels of its mask memory set).
    pub covered: bool,
}

impl Visible {
    /// Whether any subpixel is visible. An OR over the 16 sets rather than a search
    /// that stops at the first: no branch per pixel, and it vectorises (the VP asks
    /// this of every fragment, most of them wholly visible or wholly hidden).
    #[inline]
    pub fn any(&self) -> bool {
        self.sets.iter().fold(0, |a, &s| a | s) != 0
    }
}

/// The 16 SPPs and the subpixel mask memory.
#[derive(Clone, Debug)]
pub struct SubpixelProcessors {
    /// Which subpixel rule.
    pub mode: SppMode,
    /// Use the exact rule in the pixels at an edge's endpoints (table modes).
    pub vertex_exact: bool,
    /// The part of the screen this VP renders (set before `clear`).
    pub share: Share,
    row_table: &'static SppRowTable,
    /// Cells per row.
    pub stride: usize,
    /// Cell rows.
    pub rows: usize,
    width: u32,
    height: u32,
    /// Subpixel mask memory, a `[u16; 16]` (256 bits) per 4x4 cell.
    masks: Vec<Words16>,
    /// The mask memory as a frame starts (pre-masked pixels set), for `share`.
    cleared: Vec<Words16>,
    cleared_share: Option<Share>,
    /// The mask memory holds the cleared state (the background pass of the last
    /// frame put it back cell by cell), so the next [`Self::clear`] has nothing to do.
    clean: bool,
    /// Pixels of the share on the screen (not pre-masked): each gets exactly one
    /// first write per frame.
    open_pixels: u64,
    /// The thinning patterns ([`thinning`]) of the 64 transparency codes: an array,
    /// so that a code masked to 6 bits needs no bounds check.
    thin: Box<[Words16; 64]>,
    /// The processor has what [`Self::table_code_avx2`] is compiled for
    /// ([`has_avx2`]), and the AVX-512 copy was not asked for ([`crate::isa`]: with
    /// it, the plain route, whose vertex pixels [`vertex_words`] takes in AVX-512):
    /// detected once here, a check per fragment cost some 20 instructions of the
    /// fragment's dispatch. Private, so only the detection sets it.
    avx2: bool,
    /// The [`Route`] of a polygon larger than [`SMALL_BOX`] and of a small one: the
    /// AVX2 ones when `avx2` and a table mode. Private, set with `avx2`; a look-up
    /// with no branch for [`Self::polygon`].
    routes: [Route; 2],
}

/// What the SPPs take of a polygon, made once before its descent
/// ([`SubpixelProcessors::polygon`]) rather than for each of its fragments: its
/// thinning pattern (the AVX2 step ANDs it from here, not indexing the patterns by
/// the code) and its box as the AVX2 clip's lanes ([`BoxLanes`]).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct SppPolygon {
    thin: Words16,
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code, reason = "read by the AVX2 step"))]
    lanes: BoxLanes,
    /// The box (pixels, [`super::bbox`]).
    bbox: [u32; 4],
    /// The transparency code.
    t: u8,
    /// Which step [`SubpixelProcessors::process`] takes the polygon's fragments to.
    route: Route,
}

/// How [`SubpixelProcessors::process`] takes a polygon's fragments, chosen once a
/// polygon ([`SubpixelProcessors::polygon`]): one test of it a fragment rather than
/// of the processor's features and the SPP mode, and then of the polygon's size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code, reason = "the AVX2 routes"))]
enum Route {
    /// [`SubpixelProcessors::process_plain`]: no AVX2, [`SppMode::Exact`], or the
    /// AVX-512 copies asked for ([`crate::isa`]).
    Plain,
    /// [`SubpixelProcessors::process_avx2`].
    Avx2,
    /// [`SubpixelProcessors::process_avx2`] of a polygon whose box is at most
    /// [`SMALL_BOX`] pixels each way: first asking whether the box's pixels in the
    /// cell are all covered already ([`SubpixelProcessors::hidden_avx2`]).
    Avx2Small,
}

/// The widest and highest box (pixels) of a polygon whose fragments are tested for
/// being hidden before their edges are looked up ([`Route::Avx2Small`]): `many`'s
/// triangles (a pixel or two each, their boxes widened by a pixel each way) are
/// mostly hidden at subpixel level in cells not wholly covered, where the test saves
/// the edges' look-ups and vertex pixels (`many` 960 x 540: `process_avx2` 819.6 →
/// 731.1 M instructions with the test); a large polygon's fragments meet the box
/// only at its border and are rarely hidden there (a cell wholly covered never
/// reaches the SPPs), so they skip the test (on default 1 740 of 89 440 fragments
/// take it, 17 of them hidden). 16 rather than 8 since session 15: `many` at
/// 1920 x 1080, where its triangles' boxes are twice as wide, `process_avx2` 741.4
/// → 695.2 M, default unchanged, terrain −0.2 M. (The test for every polygon took
/// default's `process_avx2` 27.47 → 26.07 M but made the raster stage slower on the
/// wall: the mask's load then comes before every fragment's edge work.)
const SMALL_BOX: u32 = 16;

/// Sixteen words of a cell, a pixel's each (a cell's subpixel mask, a thinning
/// pattern), aligned to 32 bytes: the AVX2 step reads and writes them as one
/// register, where an access the compiler cannot prove aligned it splits in two (its
/// tuning for x86-64 in general): 3 instructions a fragment more.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
struct Words16([u16; 16]);

/// Rounds a pixel-relative V (in [`super::edge::EdgeCoord`] units) to eighths of a
/// pixel: `round(8 V)`, halves up.
#[inline]
fn round_q(v: i64) -> i32 {
    const SHIFT: u32 = EDGE_FRAC_BITS - SPP_V_BITS;
    ((v + (1 << (SHIFT - 1))) >> SHIFT) as i32
}

/// The row-table indices ([`SppRowTable::index`]) of an edge's four pixel lines in a
/// cell, from V1 (relative to the cell) and the slope: line `k` reads `(q_k, q_k+1)`,
/// `q_k = round_q(V1 + k slope)`.
#[inline(always)]
fn line_indices_portable(v1: i64, slope: i64) -> [usize; 4] {
    let mut line = [0usize; 5];
    for (k, l) in line.iter_mut().enumerate() {
        *l = SppRowTable::line(round_q(v1 + slope * k as i64));
    }
    std::array::from_fn(|k| line[k] * ROW_Q_COUNT + line[k + 1])
}

/// [`line_indices_portable`] in SSE2 (x86-64's baseline: the detection is a constant), the same
/// numbers (tested): the five sums in 64-bit lanes and shifted logically (the low 32
/// bits of a logical and an arithmetic shift by 29 agree, and `round_q` keeps those);
/// packed to 16 bits with signed saturation, which the clamp to `ROW_Q_MIN..=ROW_Q_MAX`
/// then cannot tell from the 32-bit value; the index `line_k * 49 + line_k+1` in 16-bit
/// lanes (at most 2400). About 30 instructions against 48 for the five roundings,
/// clamps and products in general registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn line_indices_sse2(v1: i64, slope: i64) -> [usize; 4] {
    let packed = std::arch::x86_64::_mm_cvtsi128_si64(line_index_lanes_sse2(v1, slope)) as u64;
    std::array::from_fn(|k| (packed >> (16 * k)) as usize & (ROW_PART_WORDS - 1))
}

/// [`line_indices_sse2`]'s indices as they are made, in the low four 16-bit lanes of
/// a register: each at most `(ROW_Q_COUNT - 1) (ROW_Q_COUNT + 1)`, below
/// `ROW_ENTRIES` (the clamp's), for the AVX2 fragment code to read one at a time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn line_index_lanes_sse2(v1: i64, slope: i64) -> std::arch::x86_64::__m128i {
    use std::arch::x86_64::{
        _mm_add_epi16, _mm_max_epi16, _mm_min_epi16, _mm_mullo_epi16, _mm_packs_epi32, _mm_set1_epi16, _mm_srli_si128,
        _mm_sub_epi16,
    };
    // `round_q` of V on lines 0..4, then with line 4's to eight i16.
    let (q0123, l45) = shifted_lines_sse2::<{ 1 << (SHIFT_Q - 1) }>(v1, slope);
    let q = _mm_packs_epi32(q0123, l45);
    let q = _mm_min_epi16(_mm_max_epi16(q, _mm_set1_epi16(ROW_Q_MIN as i16)), _mm_set1_epi16(ROW_Q_MAX as i16));
    let line = _mm_sub_epi16(q, _mm_set1_epi16(ROW_Q_MIN as i16));
    _mm_add_epi16(_mm_mullo_epi16(line, _mm_set1_epi16(ROW_Q_COUNT as i16)), _mm_srli_si128::<2>(line))
}

/// [`line_index_lanes_sse2`] for the AVX2 fragment code (SSE4.1; the same indices,
/// tested): the clamp's lower bound folded into the rounding's constant, so that the
/// shifted sums are `line = q - ROW_Q_MIN` (`ROW_Q_MIN 2^SHIFT` is a whole number of
/// steps, so the floor moves by exactly `ROW_Q_MIN`), packed to 16 bits with unsigned
/// saturation (a negative `line`, `q` below `ROW_Q_MIN`, becomes 0) and clamped above
/// by one unsigned min: 2 instructions an edge fewer than the signed pack, two
/// clamps and the subtraction. The indices are not masked: each is at most
/// `(ROW_Q_COUNT - 1) (ROW_Q_COUNT + 1)`, below `ROW_ENTRIES`, and the caller reads
/// them unchecked.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[inline]
fn line_index_lanes_sse41(v1: i64, slope: i64) -> std::arch::x86_64::__m128i {
    use std::arch::x86_64::{
        _mm_add_epi16, _mm_min_epu16, _mm_mullo_epi16, _mm_packus_epi32, _mm_set1_epi16, _mm_srli_si128,
    };
    // Half a step up (the rounding), then `-ROW_Q_MIN` steps (the clamp's origin).
    const BIAS: i64 = (1 << (SHIFT_Q - 1)) - ((ROW_Q_MIN as i64) << SHIFT_Q);
    let (q0123, l45) = shifted_lines_sse2::<BIAS>(v1, slope);
    let line = _mm_min_epu16(_mm_packus_epi32(q0123, l45), _mm_set1_epi16((ROW_Q_COUNT - 1) as i16));
    _mm_add_epi16(_mm_mullo_epi16(line, _mm_set1_epi16(ROW_Q_COUNT as i16)), _mm_srli_si128::<2>(line))
}

/// The shift from an edge's V to the SPP's `q` (eighths of a pixel).
const SHIFT_Q: i32 = (EDGE_FRAC_BITS - SPP_V_BITS) as i32;

/// `(V_k + BIAS) >> SHIFT_Q` of an edge's lines `k` = 0..4 (V on line 0 `v1`, the
/// slope `slope` a line), shifted logically in 64-bit lanes (the low 32 bits of a
/// logical and an arithmetic shift agree): lines 0..3's low halves as four i32 in
/// the first register, line 4's (and 5's) 64-bit lanes in the second, for a pack.
/// The common part of [`line_index_lanes_sse2`] and [`line_index_lanes_sse41`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn shifted_lines_sse2<const BIAS: i64>(
    v1: i64,
    slope: i64,
) -> (std::arch::x86_64::__m128i, std::arch::x86_64::__m128i) {
    use std::arch::x86_64::{
        _mm_add_epi64, _mm_and_si128, _mm_castps_si128, _mm_castsi128_ps, _mm_set1_epi64x, _mm_set_epi64x,
        _mm_shuffle_ps, _mm_srli_epi64,
    };
    // Lines 0, 1 | 2, 3 | 4, (5): each 64-bit lane's low half. Made from the
    // broadcasts of `v1` and `slope` (the slope loaded once, the second lane's by a
    // mask, which the compiler makes a byte shift) rather than from the sums in
    // general registers moved across: about an instruction an edge fewer as
    // compiled (the same numbers: wrapping sums in any order).
    let slopes = _mm_set1_epi64x(slope);
    let step = _mm_add_epi64(slopes, slopes);
    let firsts = _mm_add_epi64(_mm_and_si128(slopes, _mm_set_epi64x(-1, 0)), _mm_set1_epi64x(BIAS));
    let l01 = _mm_add_epi64(_mm_set1_epi64x(v1), firsts);
    let l23 = _mm_add_epi64(l01, step);
    let l45 = _mm_add_epi64(l23, step);
    let (l01, l23, l45) =
        (_mm_srli_epi64::<SHIFT_Q>(l01), _mm_srli_epi64::<SHIFT_Q>(l23), _mm_srli_epi64::<SHIFT_Q>(l45));
    const LOW_HALVES: i32 = 0b10_00_10_00;
    let q0123 = _mm_castps_si128(_mm_shuffle_ps::<LOW_HALVES>(_mm_castsi128_ps(l01), _mm_castsi128_ps(l23)));
    (q0123, l45)
}

// What the unchecked reads of `line_index_lanes_sse41`'s indices rest on.
const _: () = assert!((ROW_Q_COUNT - 1) * (ROW_Q_COUNT + 1) < ROW_PART_WORDS);

/// The body of [`vertex_words_avx2`] as an immediately called closure, for
/// [`SubpixelProcessors::table_code_avx2`] to expand in its own code: a closure takes
/// the target features of the function it is written in, where `#[inline(always)]`
/// is refused on a `#[target_feature]` function and `#[inline]` left a call (on
/// `many` two calls a fragment, each some 40 instructions of passing the words,
/// saving and reloading registers and checking again what the caller knew). It takes
/// and gives the edge's four words in a register (`$words`, a `__m256i`): given and
/// taken as `[u64; 4]`, the compiler stored the words as two 16-byte halves and the
/// caller read them back as one 32-byte load, which no store forwarded (6 % of
/// `process_avx2`'s time on default). `$taken` (a constant) says the caller has found
/// that the edge and cell are not for the cold copies ([`vertex_words_cold`]): the
/// body's own test of them then folds.
#[cfg(target_arch = "x86_64")]
macro_rules! vertex_words_avx2_body {
    ($e:expr, $px:expr, $py:expr, $vertical:expr, $words:expr, $offsets:expr, $full:expr, $taken:expr) => {{
        let body = |e: &EdgeCode,
                    px: u32,
                    py: u32,
                    vertical: bool,
                    w: std::arch::x86_64::__m256i,
                    offsets: std::arch::x86_64::__m128i,
                    full: [u16; 2]| {
            // (`$taken`, a constant: the caller found the edge and cell not for the
            // cold copies, [`vertex_words_cold`], and this test folds.)
            if !$taken && (!e.exact32() || (px | py) >= CELL_LIMIT_32) {
                return words_through_memory(w, |words| vertex_words_far(e, px, py, vertical, words));
            }
            use std::arch::x86_64::{
                _mm256_add_epi32, _mm256_blendv_epi8, _mm256_castsi256_si128, _mm256_cmpgt_epi32,
                _mm256_extracti128_si256, _mm256_load_si256, _mm256_mullo_epi32, _mm256_packs_epi32,
                _mm256_set1_epi16, _mm256_set1_epi32, _mm256_setr_epi32, _mm256_slli_epi32, _mm256_store_si256,
                _mm256_sub_epi32, _mm_movemask_epi8, _mm_packs_epi16,
            };
            const ONE: i32 = SNAP_ONE;
            const HALF_SUB: i32 = SNAP_ONE / 8;
            const SUB: i32 = SNAP_ONE / 4;
            // No exact sets for pixels whose subpixels are all covered already (`full`,
            // in the words' order: entry 1 pixel `4 y + x` for a vertical edge, entry 0
            // `4 x + y`): nothing of theirs is visible whatever their code.
            let near = vertex_near_avx2(offsets, vertical) & !full[usize::from(vertical)];
            if near == 0 {
                return w;
            }
            // The 32-bit numbers below hold for `|a|, |b| < VERTEX_COEFFICIENT_LIMIT`
            // (every edge shorter than 8192 pixels each way: the code's `vertex32`,
            // found once an edge); a longer one goes to `vertex_words_wide`.
            if !e.vertex32() {
                return words_through_memory(w, |words| vertex_words_wide(e, px, py, vertical, words));
            }
            debug_assert_eq!(e.exact().a >= 0, on_line_greater(&e.exact()));
            // -E at each pixel's first centre, less the threshold (`E >= threshold` is
            // the greater side, as in `vertex_words_sse41`), lanes of words 0 and 1 in one
            // register, of words 2 and 3 in the other, in wrapping 32-bit arithmetic: the
            // value of a vertex pixel is exact ([`VERTEX_COEFFICIENT_LIMIT`]), the others'
            // lanes are not read. About 25 instructions fewer a call than `E` at the cell
            // in 64 bits and the check that its lanes fit 32 bits.
            let (a, b, c) = e.exact_i32();
            let threshold = i32::from(a < 0);
            // `px, py < CELL_LIMIT_32`: `px ONE + HALF_SUB < 2^31`.
            let (x0, y0) = (px as i32 * ONE + HALF_SUB, py as i32 * ONE + HALF_SUB);
            let e_cell =
                a.wrapping_mul(x0).wrapping_add(b.wrapping_mul(y0)).wrapping_add(c).wrapping_sub(threshold);
            // `a` and `b` broadcast once for both the steps to each pixel's first centre
            // and the offsets of its centres. The steps, `a ONE` and `b ONE` times each
            // lane's pixel column and row (in the order of the edge's words), as two
            // products by a pair of [`VERTEX_STEPS`] for each register: the same
            // numbers modulo `2^32` as the sums of `a ONE` and `b ONE` they replace
            // (chosen by TG, a mask and a sum) and the products of `a SUB` and `b SUB`
            // broadcast apart: 53 instructions for a vertex cell's set-up against 65
            // (session 26; terrain's `process_avx2` 113.3 → 109.1 M, `many` 480 x 270
            // 605.7 → 578.6 M).
            let (a_lanes, b_lanes) = (_mm256_set1_epi32(a), _mm256_set1_epi32(b));
            let [a01, b01, a23, b23] = &VERTEX_STEPS.0[usize::from(vertical)];
            // SAFETY: each of the entry's rows is 32 bytes aligned to 32 (an aligned
            // array of 32-byte rows), the 4 x 32 bytes the aligned loads read.
            #[allow(unsafe_code, reason = "aligned loads of arrays of a register's size")]
            let (a01, b01, a23, b23) = unsafe {
                (
                    _mm256_load_si256(a01.as_ptr().cast()),
                    _mm256_load_si256(b01.as_ptr().cast()),
                    _mm256_load_si256(a23.as_ptr().cast()),
                    _mm256_load_si256(b23.as_ptr().cast()),
                )
            };
            let minus_e = _mm256_set1_epi32(e_cell.wrapping_neg());
            let t01 = _mm256_sub_epi32(
                minus_e,
                _mm256_add_epi32(_mm256_mullo_epi32(a_lanes, a01), _mm256_mullo_epi32(b_lanes, b01)),
            );
            let t23 = _mm256_sub_epi32(
                minus_e,
                _mm256_add_epi32(_mm256_mullo_epi32(a_lanes, a23), _mm256_mullo_epi32(b_lanes, b23)),
            );
            // Aligned (as the words and masks below): the compiler splits an unaligned
            // 32-byte access in two.
            let mut t = Aligned32([0i32; 16]);
            // SAFETY: `t` is 16 `i32` aligned to 32 bytes, the 2 x 32 bytes the aligned
            // stores write.
            #[allow(unsafe_code, reason = "aligned stores into an array of two registers' size")]
            unsafe {
                _mm256_store_si256(t.0.as_mut_ptr().cast(), t01);
                _mm256_store_si256(t.0.as_mut_ptr().add(8).cast(), t23);
            }
            // The offsets of a pixel's 16 centres from its first (fit: `ExactLine32`; the
            // same numbers as the SSE2 path's rows), subpixels 0-3 and 8-11 in one register
            // and 4-7 and 12-15 in the other: each pack then keeps the subpixels' order.
            const _: () = assert!(SUB == 1 << 6);
            let step_y = _mm256_slli_epi32::<6>(b_lanes);
            // Rows 1 and 3 are rows 0 and 2 a step further (an addition, not a product).
            let (sub_2, sub_3) = (2 * SUB, 3 * SUB);
            let columns = _mm256_mullo_epi32(a_lanes, _mm256_setr_epi32(0, SUB, sub_2, sub_3, 0, SUB, sub_2, sub_3));
            let rows_02 = _mm256_mullo_epi32(b_lanes, _mm256_setr_epi32(0, 0, 0, 0, sub_2, sub_2, sub_2, sub_2));
            let offsets_02 = _mm256_add_epi32(columns, rows_02);
            let offsets_13 = _mm256_add_epi32(offsets_02, step_y);
            // Per vertex pixel: its centres off the greater side, `offset < -E0`.
            // The words in a register, each vertex pixel's set blended into its lane (in a
            // register: sets stored as `u16` and read back as one load would miss the
            // store-to-load forwarding).
            let mut w = w;
            // `greater = !less`; LR = 0 keeps the other side.
            let flip: u16 = if e.lr() { 0 } else { u16::MAX };
            // In 32 bits: `blsr` then sets the flag the loop tests (as `u16` the
            // compiler tested the word again).
            let mut left = u32::from(near);
            while left != 0 {
                let lane = left.trailing_zeros() as usize & 15;
                left &= left - 1;
                let value = _mm256_set1_epi32(t.0[lane]);
                let (less_02, less_13) = (_mm256_cmpgt_epi32(value, offsets_02), _mm256_cmpgt_epi32(value, offsets_13));
                let both = _mm256_packs_epi32(less_02, less_13);
                let bytes = _mm_packs_epi16(_mm256_castsi256_si128(both), _mm256_extracti128_si256::<1>(both));
                let set = !(_mm_movemask_epi8(bytes) as u16) ^ flip;
                // SAFETY: `LANE_MASKS.0[lane]` is 16 `u16`, 32 bytes aligned to 32 (an
                // aligned array of 32-byte rows), a register's size.
                #[allow(unsafe_code, reason = "an aligned load of an array of a register's size")]
                let chosen = unsafe { _mm256_load_si256(LANE_MASKS.0[lane].as_ptr().cast()) };
                w = _mm256_blendv_epi8(w, _mm256_set1_epi16(set as i16), chosen);
            }
            w
        };
        body($e, $px, $py, $vertical, $words, $offsets, $full)
    }};
}

/// [`vertex_words_avx2_body`] takes edges with `|a|, |b|` below this (snapped units:
/// edges shorter than 8192 pixels each way) in wrapping 32-bit arithmetic. A vertex
/// pixel holds an endpoint within [`VERTEX_MARGIN`] of its square, so its first
/// subpixel centre lies within `ONE + MARGIN - ONE / 8 = 352` snapped units of the
/// endpoint in x and in y; the line passes through the endpoint (`E = 0` there: the
/// line through the snapped endpoints, [`ExactLine`]), so `|E|` at that centre is at
/// most `352 (|a| + |b|) < 352 * 2^22 < 2^31`, and a sum that wrapped on the way
/// (`E` at the cell's first pixel, the steps) ends exact. The 16 subpixel offsets
/// (`3 * 64 (|a| + |b|)`) fit as they do for [`ExactLine32`].
pub(crate) const VERTEX_COEFFICIENT_LIMIT: i64 = 1 << 21;
const _: () = assert!(352 * 2 * VERTEX_COEFFICIENT_LIMIT + 1 < 1 << 31);
const _: () = assert!(SNAP_ONE + VERTEX_MARGIN - SNAP_ONE / 8 == 352);

/// [`vertex_words_sse41`] for [`vertex_words_avx2_body`]'s edges beyond its 32-bit
/// numbers ([`VERTEX_COEFFICIENT_LIMIT`]; none on a screen the model supports, nor in
/// `many`, default or terrain): out of line and cold, as [`vertex_words_far`], its
/// words through [`words_through_memory`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[cold]
#[inline(never)]
fn vertex_words_wide(e: &EdgeCode, px: u32, py: u32, vertical: bool, words: [u64; 4]) -> [u64; 4] {
    // `vertex_words_sse41` (not `vertex_words`, whose AVX2 path would come back here)
    // takes every edge of `exact32` in a cell below `CELL_LIMIT_32`, as the caller's.
    vertex_words_sse41(e, px, py, vertical, words)
}

/// `f` of the four words of register `w`, back in a register: the cold vertex paths'
/// way to their array-based copies, written at their call sites in
/// [`vertex_words_avx2_body`]. The call's arrays are its own: when the cold functions
/// took and gave the register (`__m256i` goes by memory between functions), the
/// caller's words were the call's result in memory on every path, so each edge of
/// [`SubpixelProcessors::process_avx2`] stored its words and loaded them back before
/// its rows and columns (some 6 % of the function's samples on default, at the load).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn words_through_memory(
    w: std::arch::x86_64::__m256i,
    f: impl FnOnce([u64; 4]) -> [u64; 4],
) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::__m256i;
    // SAFETY: `__m256i` and `[u64; 4]` are both 32 bytes of integers, any bits valid.
    #[allow(unsafe_code, reason = "a register's bits as the array of its words and back")]
    unsafe {
        std::mem::transmute::<[u64; 4], __m256i>(f(std::mem::transmute::<__m256i, [u64; 4]>(w)))
    }
}

/// [`vertex_words`] for [`vertex_words_avx2_body`]'s edges and cells beyond its 32-bit
/// numbers (rare: none on `many`, default or terrain), its words through
/// [`words_through_memory`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[cold]
#[inline(never)]
fn vertex_words_far(e: &EdgeCode, px: u32, py: u32, vertical: bool, words: [u64; 4]) -> [u64; 4] {
    vertex_words(e, px, py, vertical, words)
}

/// Whether [`vertex_words_avx2_body`] would hand the edge `e` at the cell at pixel
/// `(px, py)` to a cold copy ([`vertex_words_far`], [`vertex_words_wide`]): the AVX2
/// fragment code asks first and takes such an edge to [`vertex_words_far`] (the same
/// words by [`vertex_words`]), so that the body's own cold calls fold there.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn vertex_words_cold(e: &EdgeCode, px: u32, py: u32) -> bool {
    // `vertex32` implies `exact32`.
    !e.vertex32() || (px | py) >= CELL_LIMIT_32
}

/// The AVX2 fragment code before the clip to the box ([`SubpixelProcessors::edge_code`]),
/// as an immediately called closure (the way of [`vertex_words_avx2_body`]) for
/// [`SubpixelProcessors::table_code_avx2`] and [`SubpixelProcessors::process_avx2`] to
/// expand in their own code: the code of [`SubpixelProcessors::table_code`] with the
/// pixel rows and columns held in two registers, a register each per edge's four
/// words, ANDed into one of them with no branch (`rows &= w | across`, `columns &=
/// w | !across`, `across` all ones for a horizontal edge). In general registers, the
/// words ANDed into the array an edge's TG chose through a pointer: the compiler kept
/// both arrays in memory, and their 8-byte stores were read back as 16-byte loads for
/// the transpose, which no store forwarded (on Zen 3 some 12 % of the function's
/// time stood on that one load). The columns are transposed by a byte shuffle and a
/// dword permute ([`transpose_words`] in registers), and the code is `rows &
/// columns`, bit `16 (4 y + x)` the pixel `(x, y)`'s set. `$vertex_exact` is a
/// constant (the SPPs' [`SubpixelProcessors::vertex_exact`] chosen by the caller), so
/// the loop has no test of it per edge; the row-table indices come from
/// [`line_index_lanes_sse41`], read with no mask or bounds check.
#[cfg(target_arch = "x86_64")]
macro_rules! table_code_avx2_body {
    ($spp:expr, $px:expr, $py:expr, $active:expr, $edges:expr, $vertex_exact:expr, $full:expr) => {{
        let body = |spp: &SubpixelProcessors,
                    px: u32,
                    py: u32,
                    active: &[ActiveEdge],
                    edges: &[EdgeCode],
                    full: [u16; 2]|
         -> std::arch::x86_64::__m256i {
            use std::arch::x86_64::{
                _mm256_and_si256, _mm256_load_si256, _mm256_or_si256, _mm256_permutevar8x32_epi32, _mm256_set1_epi64x,
                _mm256_set_epi64x, _mm256_setr_epi32, _mm256_setr_epi8, _mm256_shuffle_epi8, _mm256_xor_si256,
                _mm_extract_epi16,
            };
            let ones = _mm256_set1_epi64x(-1);
            let (mut rows, mut columns) = (ones, ones);
            // Both parts looked up once a fragment rather than once an edge.
            let (part_v, part_h) = (spp.row_table.part(Tg::Vertical), spp.row_table.part(Tg::Horizontal));
            for a in active {
                let e = &edges[a.edge as usize];
                let vertical = e.tg() == Tg::Vertical;
                let index = line_index_lanes_sse41(a.v1.0, e.slope.0);
                let part = if vertical { part_v } else { part_h };
                // The edge's sets, a word per pixel line along it (LR = 0: complements).
                // Four loads rather than a gather (`vpgatherqq`): as fast on Zen 3 in
                // time, though counted as one instruction.
                // SAFETY: `line_index_lanes_sse41`'s indices are below `ROW_ENTRIES`
                // (its clamp), within a part's `ROW_PART_WORDS`.
                #[allow(unsafe_code, reason = "indices clamped in SIMD, which the compiler cannot see")]
                let word = |k: usize| unsafe { *part.get_unchecked(k) } as i64;
                let read = _mm256_set_epi64x(
                    word(_mm_extract_epi16::<3>(index) as usize),
                    word(_mm_extract_epi16::<2>(index) as usize),
                    word(_mm_extract_epi16::<1>(index) as usize),
                    word(_mm_extract_epi16::<0>(index) as usize),
                );
                // The flip by LR, and `rows &= w | keep_rows`, `columns &= w |
                // keep_columns` (a vertical edge keeps the columns, a horizontal one
                // the rows): three registers of one entry.
                let [flip, keep_rows, keep_columns, _] = &TG_LR_WORDS.0[e.tg_lr()];
                // SAFETY: each of the entry's rows is 32 bytes aligned to 32 (an
                // aligned array of 32-byte rows), the 3 x 32 bytes the aligned loads
                // read.
                #[allow(unsafe_code, reason = "aligned loads of arrays of a register's size")]
                let (flip, keep_rows, keep_columns) = unsafe {
                    (
                        _mm256_load_si256(flip.as_ptr().cast()),
                        _mm256_load_si256(keep_rows.as_ptr().cast()),
                        _mm256_load_si256(keep_columns.as_ptr().cast()),
                    )
                };
                let mut w = _mm256_xor_si256(read, flip);
                // The pixels of this cell near an endpoint of the edge, where the exact
                // rule replaces the table. The endpoints' offsets from the cell serve
                // both the test and the vertex pixels.
                if $vertex_exact {
                    let offsets = end_offsets_sse2(&e.ends, px, py);
                    if near_end_cell_at_sse41(&e.ends, px, py, offsets) {
                        if vertex_words_cold(e, px, py) {
                            // The cold copy's words ANDed in on their own path: merged
                            // with the others into `w`, the words of every edge went
                            // through the call's result in memory ([`words_through_memory`]).
                            let w = words_through_memory(w, |words| vertex_words_far(e, px, py, vertical, words));
                            rows = _mm256_and_si256(rows, _mm256_or_si256(w, keep_rows));
                            columns = _mm256_and_si256(columns, _mm256_or_si256(w, keep_columns));
                            continue;
                        }
                        w = vertex_words_avx2_body!(e, px, py, vertical, w, offsets, full, true);
                    }
                }
                rows = _mm256_and_si256(rows, _mm256_or_si256(w, keep_rows));
                columns = _mm256_and_si256(columns, _mm256_or_si256(w, keep_columns));
            }
            // Columns to rows: set `(x, y)` from 16-bit lane `4 x + y` to `4 y + x`. In
            // each 128-bit half (columns `x` and `x + 1`) the shuffle puts lane `4 x + y`
            // at `2 y + x`, so dword `y` of a half is row `y`'s two sets there; the
            // permute takes row `y`'s dwords `y` and `4 + y` of the two halves in turn.
            const B: [i8; 16] = [0, 1, 8, 9, 2, 3, 10, 11, 4, 5, 12, 13, 6, 7, 14, 15];
            let by_row = _mm256_setr_epi8(
                B[0], B[1], B[2], B[3], B[4], B[5], B[6], B[7], B[8], B[9], B[10], B[11], B[12], B[13], B[14], B[15],
                B[0], B[1], B[2], B[3], B[4], B[5], B[6], B[7], B[8], B[9], B[10], B[11], B[12], B[13], B[14], B[15],
            );
            let halves = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
            let columns = _mm256_permutevar8x32_epi32(_mm256_shuffle_epi8(columns, by_row), halves);
            _mm256_and_si256(rows, columns)
        };
        body($spp, $px, $py, $active, $edges, $full)
    }};
}

/// The pixels of `pixels` (bit `4 y + x`) as 16-bit lanes of all ones, the others 0:
/// the reference for [`box_outside_at_avx2`]'s test.
#[cfg(all(test, target_arch = "x86_64"))]
#[target_feature(enable = "avx2")]
#[inline]
fn pixel_lanes_avx2(pixels: u16) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::{_mm256_and_si256, _mm256_cmpeq_epi16, _mm256_set1_epi16, _mm256_setr_epi16};
    #[allow(clippy::cast_possible_wrap, reason = "bit 15 as an i16")]
    let bits = _mm256_setr_epi16(
        1,
        1 << 1,
        1 << 2,
        1 << 3,
        1 << 4,
        1 << 5,
        1 << 6,
        1 << 7,
        1 << 8,
        1 << 9,
        1 << 10,
        1 << 11,
        1 << 12,
        1 << 13,
        1 << 14,
        (1u16 << 15) as i16,
    );
    _mm256_cmpeq_epi16(_mm256_and_si256(_mm256_set1_epi16(pixels as i16), bits), bits)
}

/// A polygon's box as [`box_outside_at_avx2`] reads it, made once a polygon
/// ([`SppPolygon`]): lanes 0-3 for the cell's pixel columns, 4-7 for its rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
struct BoxLanes {
    /// The box's first column (row) less the lane's pixel in the cell, `x0 - i`
    /// (wrapping): `px - (x0 - i)` is pixel `px + i`'s distance from the border.
    start: [i32; 8],
    /// The box's width (height), `x1 -sat x0`.
    width: [i32; 8],
}

impl BoxLanes {
    /// The lanes of box `bbox`: in SSE2 on x86-64 (its baseline), some 10
    /// instructions a polygon fewer than the compiler's lanes one by one (`many` has
    /// a million polygons); [`Self::new_plain`] elsewhere.
    #[inline]
    fn new(bbox: [u32; 4]) -> Self {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `new_sse2` only needs SSE2, which every x86-64 processor has.
        #[allow(unsafe_code, reason = "a function compiled for SSE2, x86-64's baseline")]
        unsafe {
            Self::new_sse2(bbox)
        }
        #[cfg(not(target_arch = "x86_64"))]
        Self::new_plain(bbox)
    }

    /// [`Self::new`] by its definition.
    #[cfg_attr(target_arch = "x86_64", allow(dead_code, reason = "the definition, for the tests"))]
    fn new_plain(bbox: [u32; 4]) -> Self {
        let [x0, x1, y0, y1] = bbox;
        let lane = |i: usize| if i < 4 { (x0, x1) } else { (y0, y1) };
        BoxLanes {
            start: std::array::from_fn(|i| lane(i).0.wrapping_sub(i as u32 & 3) as i32),
            width: std::array::from_fn(|i| lane(i).1.saturating_sub(lane(i).0) as i32),
        }
    }

    /// [`Self::new_plain`] in SSE2 (tested): each start a broadcast less `0, 1, 2,
    /// 3`, the widths broadcast, stored as four aligned 16-byte halves.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    #[inline]
    fn new_sse2(bbox: [u32; 4]) -> Self {
        use std::arch::x86_64::{
            __m128i, _mm_loadu_si128, _mm_set1_epi32, _mm_setr_epi32, _mm_shuffle_epi32, _mm_store_si128, _mm_sub_epi32,
        };
        let [x0, x1, y0, y1] = bbox;
        // SAFETY: `bbox` is 4 `u32`, the 16 bytes the unaligned load reads.
        #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
        let b = unsafe { _mm_loadu_si128(bbox.as_ptr().cast()) };
        let lanes = _mm_setr_epi32(0, 1, 2, 3);
        let (x0s, y0s) = (_mm_shuffle_epi32::<0b00_00_00_00>(b), _mm_shuffle_epi32::<0b10_10_10_10>(b));
        let (width, height) = (x1.saturating_sub(x0) as i32, y1.saturating_sub(y0) as i32);
        let mut out = BoxLanes { start: [0; 8], width: [0; 8] };
        let halves: [(&mut [i32], __m128i); 4] = {
            let (start, width_lanes) = (&mut out.start, &mut out.width);
            let (s0, s1) = start.split_at_mut(4);
            let (w0, w1) = width_lanes.split_at_mut(4);
            [
                (s0, _mm_sub_epi32(x0s, lanes)),
                (s1, _mm_sub_epi32(y0s, lanes)),
                (w0, _mm_set1_epi32(width)),
                (w1, _mm_set1_epi32(height)),
            ]
        };
        for (half, v) in halves {
            // SAFETY: each half is 4 `i32` at a multiple of 16 bytes in `BoxLanes`
            // (aligned to 32), the 16 bytes the aligned store writes.
            #[allow(unsafe_code, reason = "aligned stores into halves of a register's size")]
            unsafe {
                _mm_store_si128(half.as_mut_ptr().cast(), v);
            }
        }
        out
    }
}

/// The complement of [`box_pixels`] of the cell at pixel `(px, py)`, as 16-bit lanes
/// of all ones (the pixels outside the box) or 0, with no branch: 55 % of default's
/// fragments with edges meet a border of their polygon's box, so `box_pixels`' test
/// for a cell wholly inside went either way (and its clip cost some 45 instructions
/// where it applied). Lanes 0-3 of the 32-bit registers are the cell's pixel columns,
/// 4-7 its rows; pixel `p + i` of an axis lies in `[a, b)` when `p + i - a < b -sat a`
/// as unsigned numbers (for `p + i < a` the difference wraps to at least `2^32 - a`,
/// more than any `b - a`; a reversed box has no width), so a lane is outside when
/// `max(p + i - a, width) == p + i - a`; the caller clips by `andnot`. (`box_pixels`'
/// `span`, its saturating differences, took 4 instructions more.) The columns'
/// lanes packed to 16 bits and repeated make lane `4 y + x` column `x`'s; the rows'
/// lanes, each widened to two 16-bit lanes by the dword permute, row `y`'s; a pixel
/// is outside when its column or its row is. `px + 3` and `py + 3` must not wrap (a
/// pixel of a screen; so does `box_pixels`' `px + CELL_SIDE`). The box's part, each
/// border less the lane's pixel and the width, is made once a polygon ([`BoxLanes`]):
/// some 12 instructions a fragment fewer than making it for every fragment.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn box_outside_at_avx2(px: u32, py: u32, lanes: &BoxLanes) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::{
        _mm256_cmpeq_epi32, _mm256_load_si256, _mm256_max_epu32, _mm256_or_si256, _mm256_packs_epi32,
        _mm256_permute4x64_epi64, _mm256_permutevar8x32_epi32, _mm256_setr_epi32, _mm256_sub_epi32,
    };
    let (px, py) = (px as i32, py as i32);
    // SAFETY: `start` and `width` are 8 `i32` aligned to 32 bytes (`BoxLanes` is
    // aligned to 32 and `start` 32 bytes long), the 32 bytes each aligned load reads.
    #[allow(unsafe_code, reason = "aligned loads of arrays of a register's size")]
    let (start, width) =
        unsafe { (_mm256_load_si256(lanes.start.as_ptr().cast()), _mm256_load_si256(lanes.width.as_ptr().cast())) };
    let from_start = _mm256_sub_epi32(_mm256_setr_epi32(px, px, px, px, py, py, py, py), start);
    let outside = _mm256_cmpeq_epi32(_mm256_max_epu32(from_start, width), from_start);
    // Quadwords 0, 1, 0, 1: the low half's columns (packed twice) in both halves.
    const LOW_HALF_TWICE: i32 = 0b01_00_01_00;
    let columns = _mm256_permute4x64_epi64::<LOW_HALF_TWICE>(_mm256_packs_epi32(outside, outside));
    let rows = _mm256_permutevar8x32_epi32(outside, _mm256_setr_epi32(4, 4, 5, 5, 6, 6, 7, 7));
    _mm256_or_si256(columns, rows)
}

/// The pixels (bit `4 y + x`) whose 16-bit lane is all ones, the lanes all ones or
/// 0: the signed pack keeps -1 and 0, one byte a lane, and the byte mask reads them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn lane_bits_avx2(lanes: std::arch::x86_64::__m256i) -> u16 {
    use std::arch::x86_64::{_mm256_castsi256_si128, _mm256_extracti128_si256, _mm_movemask_epi8, _mm_packs_epi16};
    _mm_movemask_epi8(_mm_packs_epi16(_mm256_castsi256_si128(lanes), _mm256_extracti128_si256::<1>(lanes))) as u16
}

/// Which of each cell column's four pixel columns (bit `x`) and each cell row's four
/// pixel rows (bit `y`) lie on the screen and in an SPP set's share
/// ([`SubpixelProcessors::owned_lines`]).
struct OwnedLines {
    columns: Vec<u8>,
    rows: Vec<u8>,
}

impl OwnedLines {
    /// Cell `(cx, cy)` as a frame starts: its pixels off the screen or outside the
    /// share pre-masked (all 16 subpixels set).
    fn cleared_cell(&self, cx: usize, cy: usize) -> Words16 {
        let (columns, rows) = (self.columns[cx], self.rows[cy]);
        Words16(std::array::from_fn(|i| if columns >> (i & 3) & rows >> (i >> 2) & 1 != 0 { 0 } else { FULL }))
    }

    /// The open pixels (on the screen and in the share): open columns times open rows.
    fn open_pixels(&self) -> u64 {
        let count = |lines: &[u8]| lines.iter().map(|b| u64::from(b.count_ones())).sum::<u64>();
        count(&self.columns) * count(&self.rows)
    }
}

impl SubpixelProcessors {
    /// SPPs for a screen, with the given table.
    pub fn new(width: u32, height: u32, mode: SppMode) -> Self {
        let stride = width.div_ceil(CELL_SIDE) as usize;
        let rows = height.div_ceil(CELL_SIDE) as usize;
        let mut s = Self {
            mode,
            vertex_exact: mode == SppMode::Area,
            share: Share::WHOLE,
            row_table: SppRowTable::get(mode),
            stride,
            rows,
            width,
            height,
            masks: vec![Words16([0; 16]); stride * rows],
            cleared: Vec::new(),
            open_pixels: 0,
            cleared_share: None,
            clean: false,
            thin: Box::new(std::array::from_fn(|t| Words16(thinning(t as u8)))),
            avx2: has_avx2() && !(crate::isa::avx512_copies() && has_avx512()),
            routes: [Route::Plain; 2],
        };
        if s.avx2 && mode != SppMode::Exact {
            s.routes = [Route::Avx2, Route::Avx2Small];
        }
        s.clear();
        s
    }

    /// Whether small polygons take the AVX2 route ([`Route::Avx2Small`]), the one
    /// whose boxes [`Self::box_hidden`] tests.
    #[cfg(test)]
    pub(crate) fn small_route_avx2(&self) -> bool {
        self.routes[1] == Route::Avx2Small
    }

    /// Clears the mask memory for a new frame; pixels off the screen, and pixels
    /// outside this VP's share of the screen, are pre-masked. After a frame whose
    /// background pass visited every cell of the share ([`Self::background`],
    /// [`Self::background_done`]) the memory is already clear and nothing is copied
    /// (4 MiB a frame at 1920 x 1080, per VP of a matrix).
    pub fn clear(&mut self) {
        match self.cleared_share {
            Some(old) if old == self.share => {}
            Some(old) if Share { strip: self.share.strip, ..old } == self.share => {
                // Only the strip moved (a strip matrix evening out its VPs' work):
                // the cell columns whose pixels changed hands are made again.
                let (a, b) = (old.strip, self.share.strip);
                let inside = |strip: (u32, u32), x: u32| x >= strip.0 && x < strip.1;
                let changed: Vec<usize> = (0..self.stride)
                    .filter(|&cx| {
                        (cx as u32 * CELL_SIDE..(cx as u32 + 1) * CELL_SIDE).any(|x| inside(a, x) != inside(b, x))
                    })
                    .collect();
                let lines = self.owned_lines();
                for cy in 0..self.rows {
                    for &cx in &changed {
                        let c = cy * self.stride + cx;
                        let cell = lines.cleared_cell(cx, cy);
                        self.cleared[c] = cell;
                        if self.clean {
                            // The rest of the memory is in its cleared state already.
                            self.masks[c] = cell;
                        }
                    }
                }
                self.open_pixels = lines.open_pixels();
                self.cleared_share = Some(self.share);
            }
            _ => {
                let lines = self.owned_lines();
                self.cleared = (0..self.rows * self.stride)
                    .map(|c| lines.cleared_cell(c % self.stride, c / self.stride))
                    .collect();
                self.open_pixels = lines.open_pixels();
                self.cleared_share = Some(self.share);
                self.clean = false;
            }
        }
        if !self.clean {
            self.masks.copy_from_slice(&self.cleared);
        }
        // From here on the frame changes the memory.
        self.clean = false;
    }

    /// The share's pixel columns and rows on the screen, cell by cell
    /// ([`OwnedLines`]): a pixel is open as a frame starts when both its column and
    /// its row are (a share is a product of columns and rows, [`Share::owns_pixel`]).
    /// Found once per column and row rather than per pixel: the cleared memory of a
    /// 1920 x 1080 screen is 2 M pixels, and a strip matrix remakes a few of its
    /// cell columns every frame.
    fn owned_lines(&self) -> OwnedLines {
        let side = CELL_SIDE as usize;
        let bits = |n: usize, owns: &dyn Fn(u32) -> bool| -> Vec<u8> {
            (0..n).map(|c| (0..side).fold(0u8, |b, k| b | u8::from(owns((c * side + k) as u32)) << k)).collect()
        };
        OwnedLines {
            columns: bits(self.stride, &|x| x < self.width && self.share.owns_column(x)),
            rows: bits(self.rows, &|y| y < self.height && self.share.owns_row(y)),
        }
    }

    /// Says that [`Self::background`] has visited every cell of the share since
    /// the last [`Self::clear`]: the memory is back in its cleared state (the cells
    /// outside the share never leave it: their pixels are all pre-masked).
    pub fn background_done(&mut self) {
        self.clean = true;
    }

    /// Puts the memory back in its cleared state after a pass with no background
    /// ([`super::VideoProcessor::raster`]): the copy [`Self::clear`] would make at
    /// the next frame's start, made now (nothing when the memory is clean already,
    /// or when the share has moved since, which `clear` handles whole).
    pub fn restore(&mut self) {
        if !self.clean && self.cleared_share == Some(self.share) {
            self.masks.copy_from_slice(&self.cleared);
            self.clean = true;
        }
    }

    /// Pixels of this SPP set's share on the screen (valid after [`Self::clear`]):
    /// each has 16 open subpixels and gets exactly one first write per frame.
    pub fn open_pixels(&self) -> u64 {
        self.open_pixels
    }

    /// The SPPs' set-up for a polygon with box `bbox` (as [`super::bbox`] gives it, the
    /// box of its fragments: [`Fragment::bbox`]) and transparency code `t`, for
    /// [`Self::process`] and [`Self::inside_to`] of its fragments.
    #[inline]
    pub fn polygon(&self, bbox: [u32; 4], t: u8) -> SppPolygon {
        let [x0, x1, y0, y1] = bbox;
        let small = x1.saturating_sub(x0).max(y1.saturating_sub(y0)) <= SMALL_BOX;
        let route = self.routes[usize::from(small)];
        SppPolygon { thin: self.thin[usize::from(t & 63)], lanes: BoxLanes::new(bbox), bbox, t, route }
    }

    /// The mask memory word of the cell at `(cx, cy)`.
    #[inline]
    pub fn mask(&self, cx: usize, cy: usize) -> &[u16; 16] {
        &self.masks[cy * self.stride + cx].0
    }

    /// The fragment's code: per pixel, the AND over the crossing edges of their
    /// subpixel sets (no masking), clipped to the polygon's box ([`box_pixels`]).
    /// Only the dispatch is inlined: the copies it calls
    /// are kept out of line (inlined into the counting variant of the VP's loop, the
    /// code made that loop's code larger and the counters' cost several times their
    /// work), and a call of the AVX2 copy from an out-of-line dispatch cost some 36
    /// instructions a fragment.
    #[inline]
    pub fn fragment_code<const STATS: bool>(
        &self,
        frag: &Fragment,
        edges: &[EdgeCode],
        counters: &mut Counters,
    ) -> [u16; 16] {
        let mut code = self.edge_code::<STATS>(frag, edges, counters);
        let window = box_pixels(frag.px, frag.py, frag.bbox);
        if window != ALL_PIXELS {
            // Branch-free, so that it vectorises: each pixel's set ANDed with all ones
            // or none.
            for (pixel, c) in code.iter_mut().enumerate() {
                *c &= 0u16.wrapping_sub(window >> pixel & 1);
            }
        }
        code
    }

    /// [`Self::fragment_code`] before the clip to the box: the AND over the edges.
    #[inline(always)]
    fn edge_code<const STATS: bool>(&self, frag: &Fragment, edges: &[EdgeCode], counters: &mut Counters) -> [u16; 16] {
        if self.mode == SppMode::Exact {
            return self.fragment_code_exact::<STATS>(frag, edges, counters);
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `table_code_avx2` only needs the features `has_avx2` found the
            // processor to have when `self` was made (`avx2` is set nowhere else).
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return self.table_code_avx2::<STATS>(frag, edges, counters);
            }
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("sse2") {
            // SAFETY: `table_code_sse2` only needs SSE2, which the processor was just
            // found to have (on x86-64 it always has: the check is a constant).
            #[allow(unsafe_code, reason = "a function compiled for SSE2, after detection")]
            unsafe {
                return self.table_code_sse2::<STATS>(frag, edges, counters);
            }
        }
        self.table_code::<STATS>(frag, edges, counters, line_indices_portable, near_end_cell, vertex_words)
    }

    /// [`Self::table_code`] with the row-table indices in SSE2 ([`line_indices_sse2`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    #[inline(never)]
    fn table_code_sse2<const STATS: bool>(
        &self,
        frag: &Fragment,
        edges: &[EdgeCode],
        counters: &mut Counters,
    ) -> [u16; 16] {
        self.table_code::<STATS>(
            frag,
            edges,
            counters,
            |v1, slope| line_indices_sse2(v1, slope),
            |ends, px, py| near_end_cell_sse2(ends, px, py),
            vertex_words,
        )
    }

    /// [`Self::table_code_sse2`] compiled for AVX2, its rows and columns in registers
    /// ([`table_code_avx2_body`]), with the exact rule's vertex pixels by
    /// [`vertex_words_avx2`]'s body expanded in place ([`vertex_words_avx2_body`]),
    /// where [`vertex_words`] detects the processor's features at every call and calls
    /// it (some 48 instructions a call with its passing of the words, against about 190
    /// for the AVX2 work itself; a direct call still cost about 40). The features are
    /// detected once, by [`SubpixelProcessors::new`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1")]
    #[inline(never)]
    fn table_code_avx2<const STATS: bool>(
        &self,
        frag: &Fragment,
        edges: &[EdgeCode],
        counters: &mut Counters,
    ) -> [u16; 16] {
        use std::arch::x86_64::_mm256_store_si256;
        let code = if self.vertex_exact {
            table_code_avx2_body!(self, frag.px, frag.py, frag.active, edges, true, [0; 2])
        } else {
            table_code_avx2_body!(self, frag.px, frag.py, frag.active, edges, false, [0; 2])
        };
        let mut out = Aligned32([0u16; 16]);
        // SAFETY: `out` is 32 bytes aligned to 32, a register's size.
        #[allow(unsafe_code, reason = "an aligned store into an array of a register's size")]
        unsafe {
            _mm256_store_si256(out.0.as_mut_ptr().cast(), code);
        }
        if STATS {
            counters.spp.edge_lookups += 16 * frag.active.len() as u64;
        }
        out.0
    }

    /// The table modes' fragment code, with `line_indices` giving an edge's four
    /// row-table indices ([`line_indices_portable`] or a copy of it in SIMD),
    /// `near_end` telling whether an edge's end is near the cell ([`near_end_cell`]
    /// or its copy) and `vertex_words` putting the exact rule's sets at the vertex
    /// pixels ([`vertex_words`] or its copy for AVX2).
    #[inline(always)]
    fn table_code<const STATS: bool>(
        &self,
        frag: &Fragment,
        edges: &[EdgeCode],
        counters: &mut Counters,
        line_indices: impl Fn(i64, i64) -> [usize; 4],
        near_end: impl Fn(&[(i32, i32); 2], u32, u32) -> bool,
        vertex_words: impl Fn(&EdgeCode, u32, u32, bool, [u64; 4]) -> [u64; 4],
    ) -> [u16; 16] {
        // The code as pixel rows (word `y`, bits `16 x ..` the pixel `(x, y)`) from the
        // vertical edges, and as pixel columns (word `x`, bits `16 y ..`) from the
        // horizontal ones: an edge's row-table words AND in whole.
        let mut rows = [u64::MAX; 4];
        let mut columns = [u64::MAX; 4];
        for a in frag.active {
            let e = &edges[a.edge as usize];
            let vertical = e.tg() == Tg::Vertical;
            // q on the five pixel lines of the cell (rows for a vertical edge, columns
            // for a horizontal one), relative to the cell's first pixel column (row),
            // as V1 is; the next pixel across is 8 eighths further, so its q is 8
            // less. V is exact (additions of the slope), so five roundings serve 16
            // pixels.
            let index = line_indices(a.v1.0, e.slope.0);
            // The edge's sets, a word per pixel line along it (LR = 0: complements).
            let part = self.row_table.part(e.tg());
            let flip = if e.lr() { 0 } else { u64::MAX };
            let mut words = [0u64; 4];
            for (w, i) in words.iter_mut().zip(index) {
                *w = part[i] ^ flip;
            }
            // The pixels of this cell near an endpoint of the edge, where the exact
            // rule replaces the table (about one edge in seven on default: out of line).
            if self.vertex_exact && near_end(&e.ends, frag.px, frag.py) {
                words = vertex_words(e, frag.px, frag.py, vertical, words);
            }
            let code = if vertical { &mut rows } else { &mut columns };
            for (c, w) in code.iter_mut().zip(words) {
                *c &= w;
            }
        }
        let columns = transpose_words(columns);
        let mut code = [0u16; 16];
        for (pixel, c) in code.iter_mut().enumerate() {
            let shift = 16 * (pixel & 3);
            *c = ((rows[pixel >> 2] & columns[pixel >> 2]) >> shift) as u16;
        }
        if STATS {
            counters.spp.edge_lookups += 16 * frag.active.len() as u64;
        }
        code
    }

    /// [`SppMode::Exact`]: the sign of each crossing edge's exact line at the 16
    /// subpixel centres of every pixel.
    fn fragment_code_exact<const STATS: bool>(
        &self,
        frag: &Fragment,
        edges: &[EdgeCode],
        counters: &mut Counters,
    ) -> [u16; 16] {
        let mut code = [FULL; 16];
        for a in frag.active {
            let e = &edges[a.edge as usize];
            for (pixel, c) in code.iter_mut().enumerate() {
                *c &= exact_set(&e.exact(), e.lr(), frag.px + (pixel as u32 & 3), frag.py + (pixel as u32 >> 2));
            }
        }
        if STATS {
            counters.spp.edge_lookups += 16 * frag.active.len() as u64;
        }
        code
    }

    /// Processes one fragment of polygon `poly` ([`Self::polygon`]; the fragment's
    /// box is the polygon's): returns the visible subpixels and updates the mask
    /// memory. Only the dispatch is inlined: with AVX2 (and a table mode) the whole
    /// step is [`Self::process_avx2`], one call a fragment from the VP's loop;
    /// otherwise [`Self::process_plain`].
    #[inline]
    pub fn process<const STATS: bool>(
        &mut self,
        frag: &Fragment,
        edges: &[EdgeCode],
        poly: &SppPolygon,
        counters: &mut Counters,
    ) -> Visible {
        let mut vis = Visible::default();
        self.process_to::<STATS>(frag, edges, poly, counters, &mut vis);
        vis
    }

    /// [`Self::process`] with the result written into `out`: the VP's queue of
    /// visible fragments, where the SPPs' result stays when visible (returned, it
    /// was written on the stack and copied into the queue, its reads then straddling
    /// the copy's stores: terrain ~15 instructions a cell; session 20). Returns
    /// whether any subpixel is visible ([`Visible::any`] of `out`), found in a
    /// register: read back from `out`, the sets' 16-byte loads waited on the
    /// 32-byte store that had just written them (no store forwarding). Always
    /// inlined: a dispatch, which as `#[inline]` stayed out of line once it returned
    /// the answer (terrain +8.8 M instructions, a call a fragment).
    #[inline(always)]
    pub fn process_to<const STATS: bool>(
        &mut self,
        frag: &Fragment,
        edges: &[EdgeCode],
        poly: &SppPolygon,
        counters: &mut Counters,
        out: &mut Visible,
    ) -> bool {
        debug_assert_eq!(frag.bbox, poly.bbox, "a fragment of another polygon");
        // The usual route tested first, on its own: a compare and a branch.
        #[cfg(target_arch = "x86_64")]
        if poly.route == Route::Avx2 {
            // SAFETY: `process_avx2` only needs the features `has_avx2` found the
            // processor to have: `polygon` chooses an AVX2 route only for an SPP set
            // whose `avx2` says so (its `routes` are set from the detection in `new`,
            // nowhere else).
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return self.process_avx2::<STATS, false>(frag.px, frag.py, frag.active, edges, poly, counters, out);
            }
        }
        // A small polygon's fragments (counting off) in their own copy, which first
        // asks whether they are hidden ([`Self::hidden_avx2`]): the route chosen here,
        // not tested in the copy's entry, leaves the other copy's registers as they were.
        #[cfg(target_arch = "x86_64")]
        if poly.route == Route::Avx2Small {
            // SAFETY: as above.
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return if STATS {
                    self.process_avx2::<STATS, false>(frag.px, frag.py, frag.active, edges, poly, counters, out)
                } else {
                    self.process_avx2::<STATS, true>(frag.px, frag.py, frag.active, edges, poly, counters, out)
                };
            }
        }
        *out = self.process_plain::<STATS>(frag, edges, poly.t, counters);
        out.any()
    }

    /// [`Self::process`] by its definition: the fragment code ([`Self::fragment_code`]),
    /// then the mask memory step ([`Self::apply`]).
    #[inline(never)]
    fn process_plain<const STATS: bool>(
        &mut self,
        frag: &Fragment,
        edges: &[EdgeCode],
        t: u8,
        counters: &mut Counters,
    ) -> Visible {
        let code = self.fragment_code::<STATS>(frag, edges, counters);
        let (vis, pixels) = self.apply::<STATS>(frag.px, frag.py, &code, t);
        if STATS {
            let on_screen = (self.width - frag.px).min(CELL_SIDE) * (self.height - frag.py).min(CELL_SIDE);
            counters.count_spp_pixels(pixels.count_ones(), on_screen);
        }
        vis
    }

    /// [`Self::process_plain`] of a table mode in AVX2, the same visible sets, mask
    /// memory and counts (tested): the code in a register ([`table_code_avx2_body`]),
    /// clipped to the box with no branch ([`box_outside_at_avx2`] of the polygon's
    /// lanes), ANDed with the polygon's thinning pattern, and the mask step on it
    /// ([`Self::apply_avx2`]). Through memory, the code (stored as 16 `u16`, the box
    /// clip's stores of odd sizes, read back as 16-byte loads) missed the store
    /// forwarding: some 20 % of `process`'s time stood on one load; and the call
    /// chain `process` → `table_code_avx2` was two calls a fragment. A cell beyond
    /// [`CELL_LIMIT_32`] (none on a screen the model supports) goes to
    /// [`Self::process_plain`], checked once a fragment rather than at every edge's
    /// near-end test and vertex pixels. With `PRETEST` (a small polygon's fragments,
    /// counting off: [`Route::Avx2Small`]) a fragment whose box pixels are all
    /// covered already returns before its edges ([`Self::hidden_avx2`]). The
    /// fragment's pixel `(px, py)` and its edges `active` come by value: given the
    /// [`Fragment`], the step read its `px` and `py`, stored by the descent as two
    /// 4-byte fields, as one 8-byte load, which no store forwarded (6.7 % of the
    /// function's samples on default, session 16).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1")]
    #[inline(never)]
    #[allow(clippy::too_many_arguments, reason = "the fragment's values by value, and where its result goes")]
    fn process_avx2<const STATS: bool, const PRETEST: bool>(
        &mut self,
        px: u32,
        py: u32,
        active: &[ActiveEdge],
        edges: &[EdgeCode],
        poly: &SppPolygon,
        counters: &mut Counters,
        out: &mut Visible,
    ) -> bool {
        use std::arch::x86_64::_mm256_andnot_si256;
        if (px | py) >= CELL_LIMIT_32 {
            // Beyond the 32-bit vertex paths (no screen the model supports): checked
            // once here, the checks of every edge's near end and vertex pixels fold.
            let frag = Fragment { px, py, active, cells: ONE_CELL, bbox: poly.bbox };
            *out = self.process_plain::<STATS>(&frag, edges, poly.t, counters);
            return out.any();
        }
        // The pixels full already, in the two orders of an edge's words (none without
        // the pre-test: the vertex pixels' test of them folds).
        let full = if PRETEST {
            match self.hidden_avx2(px, py, &poly.lanes) {
                Err(covered) => {
                    *out = Visible { px, py, sets: [0; 16], first: 0, covered };
                    return false;
                }
                Ok(full) => full,
            }
        } else {
            [0; 2]
        };
        // Two copies of the edge loop: with and without the vertex pixels (a test an
        // edge less).
        let code = if self.vertex_exact {
            table_code_avx2_body!(&*self, px, py, active, edges, true, full)
        } else {
            table_code_avx2_body!(&*self, px, py, active, edges, false, full)
        };
        let code = _mm256_andnot_si256(box_outside_at_avx2(px, py, &poly.lanes), code);
        let (any, pixels) = self.apply_avx2::<STATS>(px, py, code, &poly.thin, out);
        if STATS {
            counters.spp.edge_lookups += 16 * active.len() as u64;
            let on_screen = (self.width - px).min(CELL_SIDE) * (self.height - py).min(CELL_SIDE);
            counters.count_spp_pixels(pixels.count_ones(), on_screen);
        }
        any
    }

    /// The fragment at pixel `(px, py)` of a polygon with box lanes `lanes` when
    /// every pixel of the box in the cell is covered already (all 16 subpixels set in
    /// the mask memory), `Err` of whether the whole cell is: whatever its code
    /// (clipped to the box), nothing is visible, there is no first write and the mask
    /// stays as it is, so [`Self::process_avx2`] returns that without looking up an
    /// edge. Otherwise `Ok` of the cell's full pixels, bit `4 x + y` (entry 0: the
    /// order of a horizontal edge's words) and `4 y + x` (entry 1: a vertical
    /// edge's), which take no exact sets at vertex pixels: their code does not
    /// matter (`many` 960 x 540: ~35 % of the vertex pixels, ~22 M instructions).
    /// Only in the copy of a small polygon's fragments (`PRETEST`, [`Route`]):
    /// tested in the one copy for every fragment, the mask and the box's lanes were
    /// kept for the mask step after the edge loop, which uses every `ymm` register,
    /// and its words were spilled every edge (`spp-covered-box-early-out.patch` in the
    /// session 10 notes; default +0.8 M, terrain +6.6 M instructions); the mask and
    /// the lanes are made again after the edges.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn hidden_avx2(&self, px: u32, py: u32, lanes: &BoxLanes) -> Result<[u16; 2], bool> {
        use std::arch::x86_64::{
            __m256i, _mm256_castsi256_si128, _mm256_cmpeq_epi16, _mm256_extracti128_si256, _mm256_load_si256,
            _mm256_or_si256, _mm256_set1_epi16, _mm256_testc_si256, _mm_movemask_epi8, _mm_packs_epi16, _mm_setr_epi8,
            _mm_shuffle_epi8,
        };
        let cell = (py / CELL_SIDE) as usize * self.stride + (px / CELL_SIDE) as usize;
        let mask_ptr: *const __m256i = self.masks[cell].0.as_ptr().cast();
        // SAFETY: a cell's mask is 16 `u16` aligned to 32 bytes ([`Words16`]), the 32
        // bytes the aligned load reads.
        #[allow(unsafe_code, reason = "an aligned load of an array of a register's size")]
        let mask = unsafe { _mm256_load_si256(mask_ptr) };
        let ones = _mm256_set1_epi16(-1);
        // Every pixel outside the box or full: `!(mask | outside) & ones` is zero.
        if _mm256_testc_si256(_mm256_or_si256(mask, box_outside_at_avx2(px, py, lanes)), ones) != 0 {
            return Err(_mm256_testc_si256(mask, ones) != 0);
        }
        // A byte per pixel (`4 y + x`), all ones where the pixel is full; then the
        // same in the order `4 x + y` (byte `4 x + y` from byte `4 y + x`).
        let full = _mm256_cmpeq_epi16(mask, ones);
        let bytes = _mm_packs_epi16(_mm256_castsi256_si128(full), _mm256_extracti128_si256::<1>(full));
        let by_column = _mm_shuffle_epi8(bytes, _mm_setr_epi8(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15));
        Ok([_mm_movemask_epi8(by_column) as u16, _mm_movemask_epi8(bytes) as u16])
    }

    /// Whether every pixel of a small polygon's box is covered already (all 16
    /// subpixels set in the mask memory), with counting off: then none of its
    /// fragments can have a visible subpixel (no subpixel outside its box is the
    /// polygon's, [`box_pixels`]), none makes a first write or changes the mask, and
    /// the VP passes the polygon over before its descent, where each of its fragments
    /// would have been found hidden one by one ([`Self::hidden_avx2`]). Only for the
    /// polygons of [`Route::Avx2Small`] (`false` for the others): a large box is
    /// rarely all covered, and a wholly covered cell never reaches the SPPs.
    #[inline(always)]
    pub fn box_hidden(&self, poly: &SppPolygon) -> bool {
        #[cfg(target_arch = "x86_64")]
        if poly.route == Route::Avx2Small {
            // SAFETY: `box_hidden_avx2` only needs the features `has_avx2` found the
            // processor to have: `polygon` chooses an AVX2 route only for an SPP set
            // whose `avx2` says so.
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return self.box_hidden_avx2(poly);
            }
        }
        let _ = poly;
        false
    }

    /// [`Self::box_hidden`] in AVX2: cell by cell, row by row, the cell's mask with
    /// the pixels outside the box set against all ones; the first cell with a box
    /// pixel not full ends it (most polygons not hidden meet one in their first
    /// cell). Only the box's first and last cell column and row have pixels outside
    /// it, and those pixels depend on the box's borders alone: their lanes
    /// ([`BORDER_LANES`]) are read once a polygon, and a cell inside the box is its
    /// mask alone (`box_outside_at_avx2`'s lanes for every cell, and the loops over
    /// inclusive ranges, cost some 40 instructions a cell: `many` 960 x 540, 128.4 M
    /// for 2.7 M cells).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    fn box_hidden_avx2(&self, poly: &SppPolygon) -> bool {
        use std::arch::x86_64::{
            __m256i, _mm256_load_si256, _mm256_or_si256, _mm256_set1_epi16, _mm256_setzero_si256, _mm256_testc_si256,
        };
        let [x0, x1, y0, y1] = poly.bbox;
        // An empty box (the box of a polygon with no finite vertex, say) is left to
        // the descent, as before: no `x1 - 1` below zero.
        if x1 <= x0 || y1 <= y0 {
            return false;
        }
        let (c0, c1) = ((x0 / CELL_SIDE) as usize, ((x1 - 1) / CELL_SIDE) as usize);
        let (r0, r1) = ((y0 / CELL_SIDE) as usize, ((y1 - 1) / CELL_SIDE) as usize);
        let lanes = |table: &[Words16; 4], k: u32| {
            // SAFETY: a table entry is 16 `u16` aligned to 32 bytes ([`Words16`]), the
            // 32 bytes the aligned load reads.
            #[allow(unsafe_code, reason = "an aligned load of an array of a register's size")]
            unsafe {
                _mm256_load_si256(table[(k % CELL_SIDE) as usize].0.as_ptr().cast())
            }
        };
        // The lanes outside the box in its first and last cell column (row); in one
        // column (row) both.
        let (left, right) = (lanes(&BORDER_LANES.0[0], x0), lanes(&BORDER_LANES.0[1], x1 - 1));
        let (top, bottom) = (lanes(&BORDER_LANES.0[2], y0), lanes(&BORDER_LANES.0[3], y1 - 1));
        let ones = _mm256_set1_epi16(-1);
        // The box's cells lie on the screen: the last one's index bounds them all.
        let (first, last_row) = (r0 * self.stride, r1 * self.stride);
        assert!(last_row + c1 < self.masks.len(), "a box off the screen");
        let masks = self.masks.as_ptr();
        let (mut row, mut outside_row) = (first, top);
        loop {
            if row == last_row {
                outside_row = _mm256_or_si256(outside_row, bottom);
            }
            let (mut c, mut outside) = (c0, _mm256_or_si256(outside_row, left));
            loop {
                if c == c1 {
                    outside = _mm256_or_si256(outside, right);
                }
                // SAFETY: cell `row + c` is one of the box's cells, whose last one's
                // index is below the memory's length (asserted above); a cell's mask
                // is 16 `u16` aligned to 32 bytes ([`Words16`]), the 32 bytes the
                // aligned load reads.
                #[allow(unsafe_code, reason = "an aligned load of a cell the assert above bounds")]
                let mask = unsafe { _mm256_load_si256(masks.add(row + c).cast::<__m256i>()) };
                // A box pixel not full: `!(mask | outside) & ones` is not zero (the
                // test of `hidden_avx2`).
                if _mm256_testc_si256(_mm256_or_si256(mask, outside), ones) == 0 {
                    return false;
                }
                if c == c1 {
                    break;
                }
                c += 1;
                outside = outside_row;
            }
            if row == last_row {
                return true;
            }
            row += self.stride;
            outside_row = _mm256_setzero_si256();
        }
    }

    /// [`Self::process_to`] of a fragment that no edge crosses (a cell wholly inside
    /// its polygon: every pixel's code is [`FULL`]), with counting off: no look-ups,
    /// and the same visible sets and mask memory (tested against `process`), written
    /// into `out`; returns whether any subpixel is visible. Only the dispatch is
    /// inlined, to [`Self::inside_avx2`] or [`Self::inside_plain`].
    #[inline(always)]
    pub fn inside_to(&mut self, px: u32, py: u32, poly: &SppPolygon, out: &mut Visible) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `inside_avx2` only needs the features `has_avx2` found the
            // processor to have when `self` was made (`avx2` is set nowhere else).
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return self.inside_avx2(px, py, &poly.thin, out);
            }
        }
        *out = self.inside_plain(px, py, poly.t);
        out.any()
    }

    /// [`Self::inside_to`] by its definition: [`Self::apply`] of an all-ones code.
    #[inline(never)]
    fn inside_plain(&mut self, px: u32, py: u32, t: u8) -> Visible {
        self.apply::<false>(px, py, &[FULL; 16], t).0
    }

    /// [`Self::inside_plain`] in AVX2 ([`Self::apply_avx2`]; tested).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    fn inside_avx2(&mut self, px: u32, py: u32, thin: &Words16, out: &mut Visible) -> bool {
        self.apply_avx2::<false>(px, py, std::arch::x86_64::_mm256_set1_epi16(-1), thin, out).0
    }

    /// [`Self::apply`] in AVX2 with the code in a register and the thinning pattern
    /// `thin` (the polygon's, [`SppPolygon`]): the cell's 16 pixels are one
    /// register's lanes, the first writes and the pixels with a visible subpixel a
    /// compare with zero and a pack each ([`lane_bits_avx2`]), the cover one `vptest`.
    /// The visible fragment is written into `out`; returns whether any subpixel is
    /// visible (one `vptest`) and, when counting, the pixels with a visible subpixel.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn apply_avx2<const STATS: bool>(
        &mut self,
        px: u32,
        py: u32,
        code: std::arch::x86_64::__m256i,
        thin: &Words16,
        out: &mut Visible,
    ) -> (bool, u16) {
        use std::arch::x86_64::{
            __m256i, _mm256_and_si256, _mm256_andnot_si256, _mm256_cmpeq_epi16, _mm256_load_si256, _mm256_or_si256,
            _mm256_set1_epi16, _mm256_setzero_si256, _mm256_store_si256, _mm256_storeu_si256, _mm256_testc_si256,
            _mm256_testz_si256,
        };
        let thin: *const __m256i = thin.0.as_ptr().cast();
        let cell = (py / CELL_SIDE) as usize * self.stride + (px / CELL_SIDE) as usize;
        let mask_ptr: *mut __m256i = self.masks[cell].0.as_mut_ptr().cast();
        // SAFETY: a pattern and a cell's mask are 16 `u16` aligned to 32 bytes
        // ([`Words16`]), the 32 bytes each aligned load reads (and the store writes back).
        #[allow(unsafe_code, reason = "aligned loads of arrays of a register's size")]
        let (thin, mask) = unsafe { (_mm256_load_si256(thin), _mm256_load_si256(mask_ptr)) };
        let visible = _mm256_andnot_si256(mask, _mm256_and_si256(code, thin));
        let now = _mm256_or_si256(mask, visible);
        // SAFETY: as the load of `mask` above.
        #[allow(unsafe_code, reason = "an aligned store into an array of a register's size")]
        unsafe {
            _mm256_store_si256(mask_ptr, now);
        }
        let zero = _mm256_setzero_si256();
        let none = _mm256_cmpeq_epi16(visible, zero);
        // First writes: pixels empty before with a visible subpixel now.
        let first = lane_bits_avx2(_mm256_andnot_si256(none, _mm256_cmpeq_epi16(mask, zero)));
        // Covered: `!now & ones` is zero.
        let covered = _mm256_testc_si256(now, _mm256_set1_epi16(-1)) != 0;
        let pixels = if STATS { !lane_bits_avx2(none) } else { 0 };
        // SAFETY: `out.sets` is 16 `u16`, the 32 bytes the unaligned store writes.
        #[allow(unsafe_code, reason = "an unaligned store into an array of a register's size")]
        unsafe {
            _mm256_storeu_si256(out.sets.as_mut_ptr().cast(), visible);
        }
        (out.px, out.py, out.first, out.covered) = (px, py, first, covered);
        (_mm256_testz_si256(visible, visible) == 0, pixels)
    }

    /// The mask memory step of [`Self::process`] for the cell at pixel `(px, py)`
    /// with fragment code `code` and transparency `t`: the visible sets, and (when
    /// counting) the pixels with a visible subpixel, bit `4 y + x`.
    #[inline(always)]
    fn apply<const STATS: bool>(&mut self, px: u32, py: u32, code: &[u16; 16], t: u8) -> (Visible, u16) {
        // The pattern and the cell's mask in locals, the mask written back whole:
        // with no store into the memories between the loads, the loop vectorises
        // (otherwise the mask's stores might alias the pattern: 130 instructions a
        // cell rather than about 30).
        let thin = self.thin[usize::from(t & 63)].0;
        let cell = (py / CELL_SIDE) as usize * self.stride + (px / CELL_SIDE) as usize;
        let mask = self.masks[cell].0;
        let mut now = [0u16; 16];
        let mut sets = [0u16; 16];
        // Counting only: pixels with a visible subpixel. (The subpixels set are
        // counted once per frame from the background's share: `VideoProcessor::run`.)
        let mut pixels = 0u16;
        for i in 0..16 {
            let m = mask[i];
            let visible = code[i] & thin[i] & !m;
            now[i] = m | visible;
            sets[i] = visible;
            if STATS {
                pixels |= u16::from(visible != 0) << i;
            }
        }
        self.masks[cell] = Words16(now);
        // First writes (pixels empty before with a visible subpixel now) and cover
        // (every word full) by byte masks: some 10 instructions fewer a fragment than
        // the compiler's reductions of the loop's bits.
        let first = word_bits(&mask, 0) & !word_bits(&sets, 0);
        let covered = word_bits(&now, FULL) == ALL_PIXELS;
        (Visible { px, py, sets, first, covered }, pixels)
    }

    /// The background's fragment in cell `(cx, cy)`: every subpixel still uncovered.
    /// The background is the last fragment of the cell's pixels this frame, so the
    /// cell's mask is put back in its cleared state for the next frame (rather than
    /// set full).
    ///
    /// The first writes (the pixels with nothing covered) by [`word_bits`]: the
    /// compiler's byte mask of the loop's bits came out in the wrong order and was
    /// put right bit group by bit group, some 14 instructions a cell more.
    #[inline]
    pub fn background(&mut self, cx: usize, cy: usize) -> Visible {
        let cell = cy * self.stride + cx;
        let mask = self.masks[cell].0;
        let first = word_bits(&mask, 0);
        let mut sets = [0u16; 16];
        for (s, m) in sets.iter_mut().zip(mask) {
            *s = !m;
        }
        self.masks[cell] = self.cleared[cell];
        Visible { px: cx as u32 * CELL_SIDE, py: cy as u32 * CELL_SIDE, sets, first, covered: true }
    }

    /// [`Self::background`] of the cells `columns` of row `cy` whose subpixels are all
    /// covered already (the GQ's last mask level says so): the background gets no
    /// subpixel there, so only their masks go back to the cleared state, in one copy.
    #[inline]
    pub fn background_covered(&mut self, cy: usize, columns: std::ops::Range<usize>) {
        let row = cy * self.stride;
        let cells = row + columns.start..row + columns.end;
        debug_assert!(self.masks[cells.clone()].iter().all(|m| m.0 == [FULL; 16]));
        self.masks[cells.clone()].copy_from_slice(&self.cleared[cells]);
    }
}

/// The pixels (bit `4 y + x`) whose word is `value`: in SSE2 on x86-64 (two compares,
/// a pack and a byte mask, against some ten instructions for the compiler's
/// reduction of the loop).
#[inline(always)]
fn word_bits(words: &[u16; 16], value: u16) -> u16 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("sse2") {
        // SAFETY: `word_bits_sse2` only needs SSE2, which the processor was just found
        // to have (on x86-64 always: the check is a constant).
        #[allow(unsafe_code, reason = "a function compiled for SSE2, after detection")]
        unsafe {
            return word_bits_sse2(words, value);
        }
    }
    word_bits_portable(words, value)
}

/// [`word_bits`] as its definition.
fn word_bits_portable(words: &[u16; 16], value: u16) -> u16 {
    (0..16).fold(0, |bits, i| bits | u16::from(words[i] == value) << i)
}

/// [`word_bits`] in SSE2 (x86-64's baseline).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn word_bits_sse2(words: &[u16; 16], value: u16) -> u16 {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi16, _mm_loadu_si128, _mm_movemask_epi8, _mm_packs_epi16, _mm_set1_epi16,
    };
    let w = words.as_ptr().cast::<__m128i>();
    // SAFETY: `words` is 16 `u16`, the 2 x 16 bytes the loads read.
    #[allow(unsafe_code, reason = "unaligned loads of an array of two registers' size")]
    let (lo, hi) = unsafe { (_mm_loadu_si128(w), _mm_loadu_si128(w.add(1))) };
    let v = _mm_set1_epi16(value as i16);
    // Equal words are all ones, -1 as i16: the signed pack keeps them -1, others 0.
    _mm_movemask_epi8(_mm_packs_epi16(_mm_cmpeq_epi16(lo, v), _mm_cmpeq_epi16(hi, v))) as u16
}

/// Every pixel of a cell, bit `4 y + x`.
const ALL_PIXELS: u16 = 0xFFFF;

/// How far (snapped units) beyond a pixel an edge's endpoint may lie for the pixel
/// to count as a vertex pixel of that edge: half a pixel.
const VERTEX_MARGIN: i32 = SNAP_ONE / 2;

/// Whether one of the edge's endpoints lies in pixel `(x, y)` or within
/// [`VERTEX_MARGIN`] of it (the rule [`vertex_pixels`] applies to a whole cell).
#[cfg(test)]
fn near_end(ends: &[(i32, i32); 2], x: u32, y: u32) -> bool {
    let (x0, y0) = (x as i32 * SNAP_ONE - VERTEX_MARGIN, y as i32 * SNAP_ONE - VERTEX_MARGIN);
    let (x1, y1) = ((x as i32 + 1) * SNAP_ONE + VERTEX_MARGIN, (y as i32 + 1) * SNAP_ONE + VERTEX_MARGIN);
    ends.iter().any(|&(ex, ey)| ex >= x0 && ex <= x1 && ey >= y0 && ey <= y1)
}

/// The vertex pixels of an edge in the 4x4 cell at pixel `(px, py)`: bit `4 y + x`
/// set when one of the edge's endpoints lies in that pixel or within
/// [`VERTEX_MARGIN`] of it. Per endpoint the pixels form a rectangle: the columns
/// whose widened span holds its x times the rows whose widened span holds its y.
#[inline]
fn vertex_pixels(ends: &[(i32, i32); 2], px: u32, py: u32) -> u16 {
    const ONE: i64 = SNAP_ONE as i64;
    const MARGIN: i64 = VERTEX_MARGIN as i64;
    // The pixels `d` (0..4) of the cell's row or column from pixel `p` whose widened
    // span `(p + d) ONE - MARGIN ..= (p + d + 1) ONE + MARGIN` holds the coordinate
    // `c`: with `t = c - (p ONE - MARGIN)`, `t - ONE - 2 MARGIN <= d ONE <= t`, the
    // `d` from `ceil((t - ONE - 2 MARGIN) / ONE)` to `floor(t / ONE)`, as bits.
    let span = |c: i32, p: u32| -> u16 {
        let t = i64::from(c) - (i64::from(p) * ONE - MARGIN);
        let last = (t.div_euclid(ONE) + 1).clamp(0, 4);
        let first = (-(ONE + 2 * MARGIN - t).div_euclid(ONE)).clamp(0, 4);
        ((1u16 << last) - 1) & (0xF << first)
    };
    let mut pixels = 0u16;
    for &(ex, ey) in ends {
        let (cols, rows) = (span(ex, px), span(ey, py));
        // Row bit `y` to nibble `y`, times the four column bits.
        let spread = (rows & 1) | (rows & 2) << 3 | (rows & 4) << 6 | (rows & 8) << 9;
        pixels |= spread * cols;
    }
    pixels
}

/// [`vertex_pixels`], in SSE4.1 when the processor has it and the numbers are small
/// enough for 32-bit lanes ([`vertex_pixels_sse41`]).
#[inline(always)]
fn vertex_pixels_fast(ends: &[(i32, i32); 2], px: u32, py: u32) -> u16 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("sse4.1") && VertexWindow::fits(ends, px, py) {
        // SAFETY: `vertex_pixels_sse41` only needs SSE4.1 (and the SSSE3 it implies),
        // which the processor was just found to have.
        #[allow(unsafe_code, reason = "a function compiled for SSE4.1, after detection")]
        unsafe {
            return vertex_pixels_sse41(ends, px, py);
        }
    }
    vertex_pixels(ends, px, py)
}

/// The rule of [`vertex_pixels`] as a window of bits: with `t` a coordinate less the
/// cell's first widened border (`p ONE - MARGIN`) and `f = floor(t / ONE)`, the
/// pixels `d` holding it are `f - 1` and `f`, and also `f - 2` when `t` is a multiple
/// of `ONE` (the widened spans are `2 ONE` long: `ONE + 2 MARGIN`). As bits of the
/// cell's four, `(w << (f - 2)) & 0xF` with `w = 0b110` or `0b111`; `f + 1` clamped to
/// `0..=7` loses nothing (below, the window lies before pixel 0; above, after pixel 3),
/// so the bits are a 16-entry table of `(clamped f + 1) + 8 exact`.
struct VertexWindow;

impl VertexWindow {
    /// The table: entry `g + 8 e` is `((0b110 | e) << (g + 1)) >> 4 & 0xF`.
    const TABLE: [u8; 16] = {
        let mut t = [0u8; 16];
        let mut i = 0;
        while i < 16 {
            let (g, exact) = (i & 7, i >> 3);
            t[i] = (((0b110 | exact) << (g + 1)) >> 4 & 0xF) as u8;
            i += 1;
        }
        t
    };

    /// Whether every `t` of the line's endpoints in the cell at `(px, py)` fits in 32
    /// bits: coordinates and cell borders below `2^30` in size (screens are at most
    /// `2^13` pixels, `2^21` snapped units).
    #[inline(always)]
    fn fits(ends: &[(i32, i32); 2], px: u32, py: u32) -> bool {
        const LIMIT: u32 = 1 << 30;
        let small = |c: i32| c.unsigned_abs() < LIMIT;
        (px | py) < LIMIT / SNAP_ONE as u32
            && small(ends[0].0)
            && small(ends[0].1)
            && small(ends[1].0)
            && small(ends[1].1)
    }
}

/// [`vertex_pixels`] for both endpoints' four coordinates at once ([`VertexWindow`]):
/// a subtract, a shift, a compare, a clamp and one `pshufb` of the window table, about
/// 25 instructions against some 120. Needs [`VertexWindow::fits`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
fn vertex_pixels_sse41(ends: &[(i32, i32); 2], px: u32, py: u32) -> u16 {
    vertex_spread(vertex_windows_sse41(ends, px, py), false)
}

/// The vertex pixels from the endpoints' windows ([`vertex_windows_sse41`]): bit
/// `4 y + x` (`transposed`: bit `4 x + y`) for the pixel `(x, y)` of the cell.
#[inline(always)]
fn vertex_spread([first, second]: [u64; 2], transposed: bool) -> u16 {
    // Row bit `y` to nibble `y` (bit `4 y`), times the four column bits (transposed:
    // the other way round).
    let spread = |rows: u64| (rows * 0x249) & 0x1111;
    let (x0, y0, x1, y1) = (first & 0xF, first >> 32, second & 0xF, second >> 32);
    let pixels = if transposed { (spread(x0) * y0) | (spread(x1) * y1) } else { (spread(y0) * x0) | (spread(y1) * x1) };
    pixels as u16
}

/// The windows of [`vertex_pixels_sse41`]: per endpoint a word with the cell's
/// columns holding its x in bits 0..4 and the rows holding its y in bits 32..36.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[inline]
fn vertex_windows_sse41(ends: &[(i32, i32); 2], px: u32, py: u32) -> [u64; 2] {
    use std::arch::x86_64::{
        _mm_add_epi32, _mm_and_si128, _mm_cmpeq_epi32, _mm_cvtsi128_si64, _mm_extract_epi64, _mm_max_epi32,
        _mm_min_epi32, _mm_or_si128, _mm_set1_epi32, _mm_set_epi32, _mm_set_epi8, _mm_setzero_si128, _mm_shuffle_epi8,
        _mm_srai_epi32, _mm_sub_epi32,
    };
    const ONE_BITS: i32 = SNAP_ONE.trailing_zeros() as i32;
    let (x0, y0) = (px as i32 * SNAP_ONE - VERTEX_MARGIN, py as i32 * SNAP_ONE - VERTEX_MARGIN);
    let ends = _mm_set_epi32(ends[1].1, ends[1].0, ends[0].1, ends[0].0);
    let t = _mm_sub_epi32(ends, _mm_set_epi32(y0, x0, y0, x0));
    let exact = _mm_cmpeq_epi32(_mm_and_si128(t, _mm_set1_epi32(SNAP_ONE - 1)), _mm_setzero_si128());
    let g = _mm_add_epi32(_mm_srai_epi32::<ONE_BITS>(t), _mm_set1_epi32(1));
    let g = _mm_min_epi32(_mm_max_epi32(g, _mm_setzero_si128()), _mm_set1_epi32(7));
    let index = _mm_or_si128(g, _mm_and_si128(exact, _mm_set1_epi32(8)));
    const T: [u8; 16] = VertexWindow::TABLE;
    let table = _mm_set_epi8(
        T[15] as i8,
        T[14] as i8,
        T[13] as i8,
        T[12] as i8,
        T[11] as i8,
        T[10] as i8,
        T[9] as i8,
        T[8] as i8,
        T[7] as i8,
        T[6] as i8,
        T[5] as i8,
        T[4] as i8,
        T[3] as i8,
        T[2] as i8,
        T[1] as i8,
        T[0] as i8,
    );
    // Bytes 0, 4, 8, 12: the bits of x0, y0, x1, y1; the others index entry 0 (zero).
    let bits = _mm_shuffle_epi8(table, index);
    [_mm_cvtsi128_si64(bits) as u64, _mm_extract_epi64::<1>(bits) as u64]
}

/// One edge's subpixel sets for the 16 pixels of a cell (`4 y + x`), from the table
/// part of its `(TG, LR)` and its `q` on the cell's five pixel lines: the pixel
/// `along` the edge's V lines and `across` them reads `(q[along] - 8 across,
/// q[along + 1] - 8 across)`. `VERTICAL`: along is `y`, across is `x`; else the other
/// way round.
#[cfg(test)]
fn edge_sets<const VERTICAL: bool>(table: &[u16; SPP_Q_COUNT * SPP_Q_COUNT], q: &[i32; 5]) -> [u16; 16] {
    // The saturated q of line `k` for the pixels `across`, as a table row / column
    // index (the saturation of [`SppTable::lookup_in`]).
    let mut idx = [[0usize; 4]; 5];
    for (k, row) in idx.iter_mut().enumerate() {
        for (across, i) in row.iter_mut().enumerate() {
            let v = q[k] - ((across as i32) << SPP_V_BITS);
            *i = (v.clamp(SPP_Q_MIN, SPP_Q_MAX) - SPP_Q_MIN) as usize;
        }
    }
    let mut sets = [0u16; 16];
    for along in 0..4 {
        for across in 0..4 {
            let pixel = if VERTICAL { along * 4 + across } else { across * 4 + along };
            sets[pixel] = table[idx[along][across] * SPP_Q_COUNT + idx[along + 1][across]];
        }
    }
    sets
}

/// Transposes a cell's code held as four words of four 16-bit sets: word `i`, bits
/// `16 j ..` to word `j`, bits `16 i ..` (columns to rows).
#[inline]
fn transpose_words(w: [u64; 4]) -> [u64; 4] {
    const EVEN: u64 = 0x0000_FFFF_0000_FFFF;
    const LOW: u64 = 0x0000_0000_FFFF_FFFF;
    // Pairs of words: 2 x 2 blocks of sets swapped across the diagonal first.
    let t0 = (w[0] & EVEN) | (w[1] & EVEN) << 16;
    let t1 = (w[0] >> 16 & EVEN) | (w[1] & !EVEN);
    let t2 = (w[2] & EVEN) | (w[3] & EVEN) << 16;
    let t3 = (w[2] >> 16 & EVEN) | (w[3] & !EVEN);
    [(t0 & LOW) | t2 << 32, (t1 & LOW) | t3 << 32, t0 >> 32 | (t2 & !LOW), t1 >> 32 | (t3 & !LOW)]
}

/// Puts the exact sets ([`exact_set`]) of one edge into its words at the vertex
/// pixels `near` (bit `4 y + x` of the cell at pixel `(px, py)`). The words run along
/// the edge: for a vertical edge word `y`, bits `16 x ..`; for a horizontal one word
/// `x`, bits `16 y ..`.
#[inline]
fn exact_into(line: &ExactLine, lr: bool, px: u32, py: u32, near: u16, vertical: bool, words: &mut [u64; 4]) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("sse2") && ExactLine32::fits(line) {
        // SAFETY: `exact_into_sse2` only needs SSE2, which the processor was just found
        // to have (on x86-64 it always has: the check is a constant).
        #[allow(unsafe_code, reason = "a function compiled for SSE2, after detection")]
        unsafe {
            return exact_into_sse2(line, lr, i64::from(!on_line_greater(line)), px, py, near, vertical, words);
        }
    }
    let mut near = near;
    while near != 0 {
        let pixel = near.trailing_zeros();
        near &= near - 1;
        let set = exact_set(line, lr, px + (pixel & 3), py + (pixel >> 2));
        put_set(words, pixel, vertical, set);
    }
}

/// Puts `set` as pixel `pixel`'s (`4 y + x`) in an edge's words (see [`exact_into`]).
#[inline(always)]
fn put_set(words: &mut [u64; 4], pixel: u32, vertical: bool, set: u16) {
    let (x, y) = (pixel & 3, pixel >> 2);
    let (word, lane) = if vertical { (y, x) } else { (x, y) };
    let shift = 16 * lane;
    let w = &mut words[word as usize];
    *w = (*w & !(0xFFFF << shift)) | u64::from(set) << shift;
}

/// An exact line's 16 subpixel centres relative to a pixel's first one, in 32 bits:
/// the centre `(sx, sy)` is `E0 + sx A + sy B` with `A = a SNAP_ONE / 4`, `B = b SNAP_ONE
/// / 4` and `E0` the function at the first centre. On any screen the numbers support
/// (`|a|, |b| <= 8192 * 256`) the 16 offsets `sx A + sy B` lie within `6 * 64 * 2^22
/// < 2^31`; so the sign of `E0 + offset` is `offset >= -E0`, a compare of 32-bit
/// lanes once `-E0` is saturated to 32 bits (an offset never reaches the saturated
/// values, so the compare's answer is that of the 64-bit sum).
struct ExactLine32;

impl ExactLine32 {
    /// Whether the line's offsets fit in 32 bits (`|a|, |b| < 2^22`).
    #[inline]
    fn fits(line: &ExactLine) -> bool {
        const LIMIT: u64 = 1 << 22;
        line.a.unsigned_abs() < LIMIT && line.b.unsigned_abs() < LIMIT
    }
}

/// [`exact_into`] with the 16 centres of a pixel as four SSE2 compares of 32-bit lanes
/// ([`ExactLine32`]) and their signs as one byte mask: the same sets as [`exact_set`]
/// (tested), in about a fifth of its instructions.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[allow(clippy::too_many_arguments, reason = "one edge's numbers and the cell's, all in registers")]
#[inline]
fn exact_into_sse2(
    line: &ExactLine,
    lr: bool,
    threshold: i64,
    px: u32,
    py: u32,
    near: u16,
    vertical: bool,
    words: &mut [u64; 4],
) {
    use std::arch::x86_64::{
        _mm_add_epi32, _mm_cmpgt_epi32, _mm_movemask_epi8, _mm_packs_epi16, _mm_packs_epi32, _mm_set1_epi32,
        _mm_set_epi32,
    };
    const HALF_SUB: i64 = (SNAP_ONE / 8) as i64;
    const SUB: i64 = (SNAP_ONE / 4) as i64;
    // The offsets of the centres from the first, row by row (fit: `ExactLine32`).
    let (step_x, step_y) = ((line.a * SUB) as i32, (line.b * SUB) as i32);
    let row0 = _mm_set_epi32(3 * step_x, 2 * step_x, step_x, 0);
    let down = _mm_set1_epi32(step_y);
    let row1 = _mm_add_epi32(row0, down);
    let row2 = _mm_add_epi32(row1, down);
    let row3 = _mm_add_epi32(row2, down);
    // As `exact_set`: the greater side is `E >= 0` where a centre on the line belongs
    // to it, else `E >= 1` (`threshold`, 0 or 1, from `on_line_greater`).
    let flip = if lr { 0 } else { 0xFFFF };
    // E at the first centre of the cell's first pixel; a pixel further is `SNAP_ONE a`
    // (`SNAP_ONE b`) more. (Every term is below 2^48: no overflow.)
    let x0 = i64::from(px) * i64::from(SNAP_ONE) + HALF_SUB;
    let y0 = i64::from(py) * i64::from(SNAP_ONE) + HALF_SUB;
    let e_cell = line.a * x0 + line.b * y0 + line.c - threshold;
    let (pixel_x, pixel_y) = (line.a * i64::from(SNAP_ONE), line.b * i64::from(SNAP_ONE));
    let mut near = near;
    while near != 0 {
        let pixel = near.trailing_zeros();
        near &= near - 1;
        let e0 = e_cell + pixel_x * i64::from(pixel & 3) + pixel_y * i64::from(pixel >> 2);
        // A centre is off the greater side when its offset is below -E0.
        let t = _mm_set1_epi32((-e0).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32);
        let (l0, l1) = (_mm_cmpgt_epi32(t, row0), _mm_cmpgt_epi32(t, row1));
        let (l2, l3) = (_mm_cmpgt_epi32(t, row2), _mm_cmpgt_epi32(t, row3));
        let less = _mm_movemask_epi8(_mm_packs_epi16(_mm_packs_epi32(l0, l1), _mm_packs_epi32(l2, l3))) as u16;
        // `greater = !less`; LR = 0 keeps the other side.
        put_set(words, pixel, vertical, !less ^ flip);
    }
}

/// Whether one of the edge's endpoints lies within [`VERTEX_MARGIN`] of the square of
/// `side` pixels at pixel `(px, py)`: whether any pixel there is one of the edge's
/// vertex pixels ([`vertex_pixels`]), for a cell of any level (the GQ's
/// [`band_closed`](super::gq) leaves those to the SPPs). Per coordinate
/// `x0 <= e <= x0 + span` as one unsigned compare of `e - x0` (in `i64`: no wrap),
/// both endpoints without a branch.
#[inline(always)]
pub fn ends_near(ends: &[(i32, i32); 2], px: u32, py: u32, side: u32) -> bool {
    let span = (i64::from(side) * i64::from(SNAP_ONE) + 2 * i64::from(VERTEX_MARGIN)) as u64;
    let x0 = i64::from(px) * i64::from(SNAP_ONE) - i64::from(VERTEX_MARGIN);
    let y0 = i64::from(py) * i64::from(SNAP_ONE) - i64::from(VERTEX_MARGIN);
    let within = |(ex, ey): (i32, i32)| ((i64::from(ex) - x0) as u64 <= span) & ((i64::from(ey) - y0) as u64 <= span);
    within(ends[0]) | within(ends[1])
}

/// [`ends_near`] of the 4x4 cell at pixel `(px, py)`: whether the cell has a vertex
/// pixel of the edge.
#[inline(always)]
fn near_end_cell(ends: &[(i32, i32); 2], px: u32, py: u32) -> bool {
    ends_near(ends, px, py, CELL_SIDE)
}

/// [`near_end_cell`] out of line, for [`near_end_cell_sse2`]'s cells beyond its 32-bit
/// numbers (none on a screen the model supports): inlined, its constants were made
/// for every fragment of the AVX2 fragment code, some 10 instructions each.
#[cold]
#[inline(never)]
fn near_end_cell_far(ends: &[(i32, i32); 2], px: u32, py: u32) -> bool {
    near_end_cell(ends, px, py)
}

/// [`near_end_cell`] in SSE2, the four coordinates at once: each `e - x0`, biased by
/// `2^31` so that a signed compare asks the unsigned `<= SPAN`. In 32 bits the
/// differences wrap, but with the cell below [`CELL_LIMIT_32`] (`x0 < 2^30`) a true
/// difference lies in `(-2^31 - 2^30, 2^31)`, so it wraps into `0..=SPAN` only when
/// it is there: about 10 instructions an edge against some 20 (tested).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn near_end_cell_sse2(ends: &[(i32, i32); 2], px: u32, py: u32) -> bool {
    use std::arch::x86_64::{
        _mm_castsi128_ps, _mm_cmpgt_epi32, _mm_movemask_ps, _mm_set1_epi32, _mm_set_epi32, _mm_sub_epi32,
    };
    if (px | py) >= CELL_LIMIT_32 {
        return near_end_cell_far(ends, px, py);
    }
    const SPAN: i32 = CELL_SIDE as i32 * SNAP_ONE + 2 * VERTEX_MARGIN;
    let (x0, y0) = (px as i32 * SNAP_ONE - VERTEX_MARGIN, py as i32 * SNAP_ONE - VERTEX_MARGIN);
    let base = _mm_set_epi32(y0 ^ i32::MIN, x0 ^ i32::MIN, y0 ^ i32::MIN, x0 ^ i32::MIN);
    let [(ax, ay), (bx, by)] = *ends;
    let biased = _mm_sub_epi32(_mm_set_epi32(by, bx, ay, ax), base);
    let within = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(_mm_set1_epi32((SPAN + 1) ^ i32::MIN), biased)));
    // Both coordinates of one endpoint: bits 0 and 1, or 2 and 3.
    within & (within >> 1) & 0b101 != 0
}

/// An edge's words (see [`exact_into`]) with the exact sets at its vertex pixels in
/// the cell at pixel `(px, py)`. Out of line: most edges have no endpoint near the
/// cell, and inlined its set-up was hoisted into every fragment's.
#[inline(never)]
fn vertex_words(e: &EdgeCode, px: u32, py: u32, vertical: bool, words: [u64; 4]) -> [u64; 4] {
    #[cfg(target_arch = "x86_64")]
    if e.exact32() && (px | py) < CELL_LIMIT_32 {
        if has_avx512() {
            // SAFETY: `vertex_words_avx512` only needs the features `has_avx512`
            // just found the processor to have.
            #[allow(unsafe_code, reason = "a function compiled for AVX-512, after detection")]
            unsafe {
                return vertex_words_avx512(e, px, py, vertical, words);
            }
        }
        if has_avx2() {
            // SAFETY: `vertex_words_avx2` only needs the features `has_avx2` just
            // found the processor to have.
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return vertex_words_avx2(e, px, py, vertical, words);
            }
        }
        if std::is_x86_feature_detected!("sse4.1") {
            // SAFETY: `vertex_words_sse41` only needs SSE4.1 (and the SSE2 it
            // implies), which the processor was just found to have.
            #[allow(unsafe_code, reason = "a function compiled for SSE4.1, after detection")]
            unsafe {
                return vertex_words_sse41(e, px, py, vertical, words);
            }
        }
    }
    let mut words = words;
    let vertex = vertex_pixels_fast(&e.ends, px, py);
    if vertex != 0 {
        exact_into(&e.exact(), e.lr(), px, py, vertex, vertical, &mut words);
    }
    words
}

/// Cells at pixels below this (in both coordinates) take the 32-bit vertex paths
/// ([`VertexWindow::fits`]): their borders in snapped units are below `2^30`.
const CELL_LIMIT_32: u32 = EXACT32_END_LIMIT / SNAP_ONE as u32;

/// [`vertex_words`] for an edge whose exact line fits 32-bit lanes
/// ([`EdgeCode::exact32`], checked once per edge by the GP, and the cell's pixel below
/// [`CELL_LIMIT_32`]): the vertex pixels in SSE4.1 ([`vertex_pixels_sse41`]) and their
/// sets in SSE2 ([`exact_into_sse2`]), with no check of the line's numbers per cell.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
fn vertex_words_sse41(e: &EdgeCode, px: u32, py: u32, vertical: bool, words: [u64; 4]) -> [u64; 4] {
    let mut words = words;
    let vertex = vertex_pixels_sse41(&e.ends, px, py);
    if vertex != 0 {
        // An edge's line is oriented with `a > 0` (vertical) or `b > 0` (horizontal),
        // so `a == 0` only with `b > 0`: the centres on the line are on the greater
        // side exactly when `a >= 0` (the rule of `exact_set`).
        debug_assert_eq!(e.exact().a >= 0, on_line_greater(&e.exact()));
        let threshold = i64::from(e.exact().a < 0);
        exact_into_sse2(&e.exact(), e.lr(), threshold, px, py, vertex, vertical, &mut words);
    }
    words
}

/// Whether the processor has what [`vertex_words_avx512`] is compiled for.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn has_avx512() -> bool {
    std::is_x86_feature_detected!("avx512f")
        && std::is_x86_feature_detected!("avx512bw")
        && std::is_x86_feature_detected!("avx512vl")
        && std::is_x86_feature_detected!("avx512dq")
        && std::is_x86_feature_detected!("bmi1")
}

/// Whether the processor has what [`vertex_words_avx2`] and
/// [`SubpixelProcessors::table_code_avx2`] are compiled for.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn has_avx2() -> bool {
    std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("bmi1")
}

/// [`has_avx2`] elsewhere than on x86-64: never.
#[cfg(not(target_arch = "x86_64"))]
fn has_avx2() -> bool {
    false
}

/// [`has_avx512`] elsewhere than on x86-64: never.
#[cfg(not(target_arch = "x86_64"))]
fn has_avx512() -> bool {
    false
}

/// What the AVX-512 copy of the vertex pixels ([`vertex_words_avx512`]) starts
/// from: the vertex pixels and the exact line's value at the cell.
#[cfg(target_arch = "x86_64")]
struct VertexStart {
    /// The vertex pixels, lane `4 w + l` of the words (word `w`, bits `16 l ..`): the
    /// pixel `(l, w)` of a vertical edge's cell and `(w, l)` of a horizontal one's.
    near: u16,
    /// `E - threshold` at the first subpixel centre of the cell's pixel (0, 0): the
    /// greater side is `E >= threshold` (as in [`vertex_words_sse41`]).
    e_cell: i64,
    /// `E`'s change from a lane to the next, and from a word to the next.
    per_lane: i64,
    per_word: i64,
}

/// [`VertexStart`] of `line` in the cell at `(px, py)`, or `None` when no pixel of
/// the cell is a vertex pixel.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[inline]
fn vertex_start(line: &ExactLine, px: u32, py: u32, vertical: bool) -> Option<VertexStart> {
    vertex_start_at(line, px, py, vertical, vertex_spread(vertex_windows_sse41(&line.ends, px, py), !vertical))
}

/// [`vertex_start`] with the vertex pixels `near` found (in the words' order).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn vertex_start_at(line: &ExactLine, px: u32, py: u32, vertical: bool, near: u16) -> Option<VertexStart> {
    const ONE: i64 = SNAP_ONE as i64;
    const HALF_SUB: i64 = (SNAP_ONE / 8) as i64;
    if near == 0 {
        return None;
    }
    debug_assert_eq!(line.a >= 0, on_line_greater(line));
    let threshold = i64::from(line.a < 0);
    let e_cell =
        line.a * (i64::from(px) * ONE + HALF_SUB) + line.b * (i64::from(py) * ONE + HALF_SUB) + line.c - threshold;
    let (pixel_x, pixel_y) = (line.a * ONE, line.b * ONE);
    let (per_lane, per_word) = if vertical { (pixel_x, pixel_y) } else { (pixel_y, pixel_x) };
    Some(VertexStart { near, e_cell, per_lane, per_word })
}

/// The endpoints' coordinates less the cell's first widened border, `x0 = px ONE -
/// MARGIN` and `y0` alike, as 32-bit lanes `ax, ay, bx, by` (wrapping): what
/// [`near_end_cell_at_sse41`] and [`vertex_near_avx2`] compare, made once an edge.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn end_offsets_sse2(ends: &[(i32, i32); 2], px: u32, py: u32) -> std::arch::x86_64::__m128i {
    use std::arch::x86_64::{_mm_set_epi32, _mm_sub_epi32};
    // Wrapping: far cells (beyond `CELL_LIMIT_32`) take other paths, which do not
    // read these lanes.
    let p = |p: u32| (p as i32).wrapping_mul(SNAP_ONE).wrapping_sub(VERTEX_MARGIN);
    let (x0, y0) = (p(px), p(py));
    let [(ax, ay), (bx, by)] = *ends;
    _mm_sub_epi32(_mm_set_epi32(by, bx, ay, ax), _mm_set_epi32(y0, x0, y0, x0))
}

/// [`near_end_cell`] from the endpoints' offsets `t` ([`end_offsets_sse2`]; tested):
/// within `0..=SPAN` of the widened cell as one unsigned compare (`min(t, SPAN) ==
/// t`, the reasoning of [`near_end_cell_sse2`]), both coordinates of an endpoint as
/// one 64-bit lane of all ones, tested by `ptest`: 7 instructions against 13 for
/// [`near_end_cell_sse2`]'s biased compare and byte mask. Cells beyond the 32-bit
/// numbers go to [`near_end_cell_far`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[inline]
fn near_end_cell_at_sse41(ends: &[(i32, i32); 2], px: u32, py: u32, t: std::arch::x86_64::__m128i) -> bool {
    use std::arch::x86_64::{_mm_cmpeq_epi32, _mm_cmpeq_epi64, _mm_min_epu32, _mm_set1_epi32, _mm_testz_si128};
    if (px | py) >= CELL_LIMIT_32 {
        return near_end_cell_far(ends, px, py);
    }
    const SPAN: i32 = CELL_SIDE as i32 * SNAP_ONE + 2 * VERTEX_MARGIN;
    let within = _mm_cmpeq_epi32(_mm_min_epu32(t, _mm_set1_epi32(SPAN)), t);
    let both = _mm_cmpeq_epi64(within, _mm_set1_epi32(-1));
    _mm_testz_si128(both, both) == 0
}

/// The vertex pixels of [`vertex_start`] in AVX2 (tested), for cells and endpoints
/// within [`VertexWindow::fits`]: with `t` a coordinate less the cell's first widened
/// border, pixel `d` holds it when `0 <= t - d ONE <= ONE + 2 MARGIN`, one unsigned
/// compare of the difference. It takes the endpoints' offsets `t`
/// ([`end_offsets_sse2`]), made once for the test of [`near_end_cell_at_sse41`] too,
/// packed to 16 bits with signed saturation: a value in range (below `4 ONE + 2
/// MARGIN`) is kept, and a saturated or far one stays out of range (its 16-bit
/// difference, wrapped or not, is above `ONE + 2 MARGIN` as an unsigned number),
/// so both endpoints' x and y, four `d` each, are one register of 16-bit lanes, and
/// one byte mask gives each endpoint's lane bits (low nibble) and word bits (high
/// nibble) in a byte: about 14 instructions against some 20 for two registers of
/// 32-bit lanes. Each endpoint's lanes hold its x then its y (no swap by the TG),
/// and its eight bits are turned into pixels by [`NEAR_PIXELS`]: some 16
/// instructions fewer a call than the swap and the products that spread the bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1")]
#[inline]
fn vertex_near_avx2(t: std::arch::x86_64::__m128i, vertical: bool) -> u16 {
    use std::arch::x86_64::{
        _mm256_broadcastq_epi64, _mm256_castsi256_si128, _mm256_cmpeq_epi16, _mm256_extracti128_si256,
        _mm256_min_epu16, _mm256_set1_epi16, _mm256_set1_epi64x, _mm256_setr_epi8, _mm256_shuffle_epi8,
        _mm256_sub_epi16, _mm_movemask_epi8, _mm_packs_epi16, _mm_packs_epi32,
    };
    const ONE: i16 = SNAP_ONE as i16;
    const SPAN: i16 = (SNAP_ONE + 2 * VERTEX_MARGIN) as i16;
    // `ax ay bx by` as 16-bit lanes 0-3, the quadword in both halves.
    let t = _mm256_broadcastq_epi64(_mm_packs_epi32(t, t));
    // Lanes 0-3 the first endpoint's x, 4-7 its y; 8-15 the second's.
    let spread = _mm256_setr_epi8(
        0, 1, 0, 1, 0, 1, 0, 1, 2, 3, 2, 3, 2, 3, 2, 3, 4, 5, 4, 5, 4, 5, 4, 5, 6, 7, 6, 7, 6, 7, 6, 7,
    );
    // Each group of four lanes `0, ONE, 2 ONE, 3 ONE`: the pixel columns' (rows')
    // left (top) borders.
    const STEPS: i64 = (ONE as i64) << 16 | (2 * ONE as i64) << 32 | (3 * ONE as i64) << 48;
    let steps = _mm256_set1_epi64x(STEPS);
    let d = _mm256_sub_epi16(_mm256_shuffle_epi8(t, spread), steps);
    let within = _mm256_cmpeq_epi16(_mm256_min_epu16(d, _mm256_set1_epi16(SPAN)), d);
    let bits =
        _mm_movemask_epi8(_mm_packs_epi16(_mm256_castsi256_si128(within), _mm256_extracti128_si256::<1>(within)));
    let pixels = &NEAR_PIXELS[usize::from(vertical)];
    pixels[bits as usize & (NEAR_BITS - 1)] | pixels[bits as usize >> 8 & (NEAR_BITS - 1)]
}

/// The values of an endpoint's eight within-bits in [`vertex_near_avx2`].
#[cfg(target_arch = "x86_64")]
const NEAR_BITS: usize = 1 << 8;

/// [`vertex_near_avx2`]'s pixels of one endpoint from its within-bits `m` (bit `x`:
/// pixel column `x` holds the endpoint's x; bit `4 + y`: row `y` its y): the pixels
/// `(x, y)` of both, in the words' order ([`VertexStart::near`]), bit `4 x + y` for a
/// horizontal edge (entry 0, its words pixel columns), `4 y + x` for a vertical one.
#[cfg(target_arch = "x86_64")]
static NEAR_PIXELS: [[u16; NEAR_BITS]; 2] = {
    let mut table = [[0u16; NEAR_BITS]; 2];
    let mut m = 0;
    while m < NEAR_BITS {
        let mut x = 0;
        while x < 4 {
            let mut y = 0;
            while y < 4 {
                if m >> x & 1 == 1 && m >> (4 + y) & 1 == 1 {
                    table[0][m] |= 1 << (4 * x + y);
                    table[1][m] |= 1 << (4 * y + x);
                }
                y += 1;
            }
            x += 1;
        }
        m += 1;
    }
    table
};

/// [`vertex_words_sse41`] in AVX2 for processors without AVX-512 (Zen 3): the same
/// sets (tested), about 200 instructions a call against 256 for the SSE4.1 path
/// with its detection, at terrain's 3.6 vertex pixels a call. As in [`vertex_words_avx512`], the vertex pixels come
/// in the words' order (by [`vertex_near_avx2`]) and -E at the first centre of all 16 pixels is made at once
/// (two registers of 32-bit lanes in wrapping arithmetic, exact at the vertex pixels
/// for an edge within [`VERTEX_COEFFICIENT_LIMIT`]: a longer one goes to
/// [`vertex_words_wide`]); per vertex
/// pixel one broadcast of its value, two 8-lane compares against the 16 centres'
/// offsets ([`ExactLine32`]) and two packs give its set, blended into its lane of
/// the words (held in a register) under a mask read from a table.
/// Against the SSE4.1 path it saves each pixel's products and clamp and its put
/// into the words (some 46 instructions a vertex pixel there, about 15 here), for a
/// longer set-up (about 150). The sets are not stored as `u16` and read back as one
/// load: that load missed the store-to-load forwarding, and in time the copy was no
/// faster than the SSE4.1 path's.
///
/// Called directly from [`SubpixelProcessors::table_code_avx2`], so it takes every
/// edge and cell: those the 32-bit paths do not take ([`EdgeCode::exact32`],
/// [`CELL_LIMIT_32`]) go on to [`vertex_words`]. This function (for [`vertex_words`]
/// and the tests) is out of line, as `vertex_words`; `table_code_avx2` expands its
/// body ([`vertex_words_avx2_body`]) inside its loop (on `many` 77 M instructions
/// fewer at 960 x 540, terrain 6).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1")]
#[inline(never)]
fn vertex_words_avx2(e: &EdgeCode, px: u32, py: u32, vertical: bool, words: [u64; 4]) -> [u64; 4] {
    use std::arch::x86_64::{_mm256_load_si256, _mm256_store_si256};
    let words = Aligned32(words);
    // SAFETY: `words` is 32 bytes aligned to 32, a register's size.
    #[allow(unsafe_code, reason = "an aligned load of an array of a register's size")]
    let w = unsafe { _mm256_load_si256(words.0.as_ptr().cast()) };
    let w = vertex_words_avx2_body!(e, px, py, vertical, w, end_offsets_sse2(&e.ends, px, py), [0; 2], false);
    let mut out = Aligned32([0u64; 4]);
    // SAFETY: `out` is 32 bytes aligned to 32, a register's size.
    #[allow(unsafe_code, reason = "an aligned store into an array of a register's size")]
    unsafe {
        _mm256_store_si256(out.0.as_mut_ptr().cast(), w);
    }
    out.0
}

/// [`vertex_words_avx2_body`]'s factors of `a` and `b` for the steps from a vertex
/// cell's first subpixel centre to each pixel's first, lanes of words 0 and 1 (`a01`,
/// `b01`) and of words 2 and 3 (`a23`, `b23`), entry 1 for a vertical edge (word `y`
/// a pixel row, lane `x` in it: `ONE x` and `ONE y`), entry 0 for a horizontal one
/// (word `x` a pixel column, lane `y`: the same with the roles swapped).
#[cfg(target_arch = "x86_64")]
static VERTEX_STEPS: Aligned32<[[[i32; 8]; 4]; 2]> = {
    const ONE: i32 = SNAP_ONE;
    // Lane `i` of words `2 k` and `2 k + 1`: `ONE (i & 3)` along the word, `ONE (2 k +
    // i / 4)` across the words.
    const ALONG: [i32; 8] = [0, ONE, 2 * ONE, 3 * ONE, 0, ONE, 2 * ONE, 3 * ONE];
    const ACROSS_01: [i32; 8] = [0, 0, 0, 0, ONE, ONE, ONE, ONE];
    const ACROSS_23: [i32; 8] = [2 * ONE, 2 * ONE, 2 * ONE, 2 * ONE, 3 * ONE, 3 * ONE, 3 * ONE, 3 * ONE];
    // `[a01, b01, a23, b23]`: a horizontal edge's `a` (x) steps across its words, a
    // vertical one's along them.
    Aligned32([[ACROSS_01, ALONG, ACROSS_23, ALONG], [ALONG, ACROSS_01, ALONG, ACROSS_23]])
};

/// [`table_code_avx2_body`]'s words for an edge's TG and LR, entry
/// [`EdgeCode::tg_lr`] (`TG + 2 LR`, TG 1 for [`Tg::Vertical`]): the flip of its
/// words by its LR (all ones for LR = 0, the complements; none for LR = 1), then the
/// words that keep the rows and the columns (a horizontal edge's words AND into the
/// columns only, a vertical one's into the rows: `rows &= w | keep_rows`), then a
/// fourth register's padding (entries of 128 bytes: the index is a shift). One index
/// for the three loads: it had been two tables, by LR and by TG, each index made from
/// the flags on its own (a shift and a mask each). Loads where the masks had been made
/// from the flags (a broadcast and a compare, two `andn`: 5 instructions an edge
/// more).
#[cfg(target_arch = "x86_64")]
static TG_LR_WORDS: Aligned32<[[[u64; 4]; 4]; 4]> = {
    const ALL: [u64; 4] = [u64::MAX; 4];
    const NONE: [u64; 4] = [0; 4];
    // `[flip, keep_rows, keep_columns, padding]`.
    Aligned32([
        [ALL, ALL, NONE, NONE],  // horizontal, LR = 0
        [ALL, NONE, ALL, NONE],  // vertical, LR = 0
        [NONE, ALL, NONE, NONE], // horizontal, LR = 1
        [NONE, NONE, ALL, NONE], // vertical, LR = 1
    ])
};

/// [`vertex_words_avx2`]'s blend masks: entry `i` selects the 16-bit lane `i`.
#[cfg(target_arch = "x86_64")]
static LANE_MASKS: Aligned32<[[u16; 16]; 16]> = {
    let mut m = [[0u16; 16]; 16];
    let mut i = 0;
    while i < 16 {
        m[i][i] = u16::MAX;
        i += 1;
    }
    Aligned32(m)
};

/// [`SubpixelProcessors::box_hidden_avx2`]'s pixels outside a box in its border
/// cells, all ones in 16-bit lane `4 y + x`: `[0][k]` the columns `x < k` (a box
/// whose first column is `k` in its cell), `[1][k]` the columns `x > k` (its last
/// column `k`), `[2][k]` the rows `y < k`, `[3][k]` the rows `y > k`.
#[cfg(target_arch = "x86_64")]
static BORDER_LANES: Aligned32<[[Words16; 4]; 4]> = {
    let mut t = [[Words16([0; 16]); 4]; 4];
    let mut k = 0;
    while k < 4 {
        let mut lane = 0;
        while lane < 16 {
            let (x, y) = (lane % 4, lane / 4);
            let outside = [x < k, x > k, y < k, y > k];
            let mut side = 0;
            while side < 4 {
                if outside[side] {
                    t[side][k].0[lane] = FULL;
                }
                side += 1;
            }
            lane += 1;
        }
        k += 1;
    }
    Aligned32(t)
};

/// A value aligned to 32 bytes, for the AVX2 copies' aligned loads and stores of a
/// whole register: an unaligned one the compiler splits into two halves (its tuning
/// for x86-64 in general), an instruction more each.
#[cfg(target_arch = "x86_64")]
#[repr(C, align(32))]
struct Aligned32<T>(T);

/// [`vertex_words_sse41`] in AVX-512: the same sets (tested), in about half its
/// instructions. The vertex pixels come in the words' order (bit `4 word + lane`),
/// so no put per pixel: -E at the first centre of all 16 pixels at once (64-bit
/// lanes, narrowed to 32 bits with signed saturation, which is the SSE2 path's
/// clamp), then per vertex pixel one 16-lane compare of its value against the 16
/// centres' offsets ([`ExactLine32`]) gives its set; the sets go into the words
/// by one masked blend.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq,bmi1")]
fn vertex_words_avx512(e: &EdgeCode, px: u32, py: u32, vertical: bool, words: [u64; 4]) -> [u64; 4] {
    use std::arch::x86_64::{
        _mm256_extract_epi64, _mm256_mask_blend_epi16, _mm256_mask_broadcastw_epi16, _mm256_set1_epi16,
        _mm256_set_epi64x, _mm256_setzero_si256, _mm256_xor_si256, _mm512_add_epi32, _mm512_add_epi64,
        _mm512_castsi256_si512, _mm512_cmpgt_epi32_mask, _mm512_cvtsepi64_epi32, _mm512_inserti64x4,
        _mm512_maskz_set1_epi64, _mm512_mullo_epi32, _mm512_mullo_epi64, _mm512_permutexvar_epi32, _mm512_set1_epi32,
        _mm512_set1_epi64, _mm512_set_epi32, _mm512_set_epi64, _mm_cvtsi32_si128,
    };
    const SUB: i64 = (SNAP_ONE / 4) as i64;
    let line = &e.exact();
    let Some(VertexStart { near, e_cell, per_lane, per_word }) = vertex_start(line, px, py, vertical) else {
        return words;
    };
    // -E at each pixel's first centre (every term below 2^48: no overflow), lanes of
    // words 0 and 1, then 2 and 3, saturated to 32 bits.
    let lanes = _mm512_mullo_epi64(_mm512_set1_epi64(-per_lane), _mm512_set_epi64(3, 2, 1, 0, 3, 2, 1, 0));
    const SECOND_WORD: u8 = 0xF0;
    let t01 = _mm512_add_epi64(
        _mm512_add_epi64(_mm512_set1_epi64(-e_cell), lanes),
        _mm512_maskz_set1_epi64(SECOND_WORD, -per_word),
    );
    let t23 = _mm512_add_epi64(t01, _mm512_set1_epi64(-2 * per_word));
    let t = _mm512_inserti64x4::<1>(_mm512_castsi256_si512(_mm512_cvtsepi64_epi32(t01)), _mm512_cvtsepi64_epi32(t23));
    // The offsets of a pixel's 16 centres from its first, subpixel `4 sy + sx` in lane
    // `4 sy + sx` (fit: `ExactLine32`; the same numbers as the SSE2 path's rows).
    let (step_x, step_y) = ((line.a * SUB) as i32, (line.b * SUB) as i32);
    let offsets = _mm512_add_epi32(
        _mm512_mullo_epi32(_mm512_set1_epi32(step_x), _mm512_set_epi32(3, 2, 1, 0, 3, 2, 1, 0, 3, 2, 1, 0, 3, 2, 1, 0)),
        _mm512_mullo_epi32(_mm512_set1_epi32(step_y), _mm512_set_epi32(3, 3, 3, 3, 2, 2, 2, 2, 1, 1, 1, 1, 0, 0, 0, 0)),
    );
    // Per vertex pixel: its centres off the greater side, `offset < -E0`.
    let mut less = _mm256_setzero_si256();
    let mut left = near;
    while left != 0 {
        let lane = left.trailing_zeros();
        let bit = left & left.wrapping_neg();
        left &= left - 1;
        let t_lane = _mm512_permutexvar_epi32(_mm512_set1_epi32(lane as i32), t);
        // Through a general register: as a `set1` of the mask LLVM builds the
        // broadcast from the mask's bits one word at a time.
        let set = _mm_cvtsi32_si128(i32::from(_mm512_cmpgt_epi32_mask(t_lane, offsets)));
        less = _mm256_mask_broadcastw_epi16(less, bit, set);
    }
    // `greater = !less`; LR = 0 keeps the other side.
    let sets = _mm256_xor_si256(less, _mm256_set1_epi16(if e.lr() { -1 } else { 0 }));
    let w = _mm256_set_epi64x(words[3] as i64, words[2] as i64, words[1] as i64, words[0] as i64);
    let w = _mm256_mask_blend_epi16(near, w, sets);
    [
        _mm256_extract_epi64::<0>(w) as u64,
        _mm256_extract_epi64::<1>(w) as u64,
        _mm256_extract_epi64::<2>(w) as u64,
        _mm256_extract_epi64::<3>(w) as u64,
    ]
}

/// Whether a point on the exact line lies on its greater side (the perturbation of
/// [`ExactLine::greater_side`]).
#[inline(always)]
fn on_line_greater(line: &ExactLine) -> bool {
    line.a > 0 || (line.a == 0 && line.b > 0)
}

/// The subpixels of pixel `(x, y)` on the polygon's side of an exact line: the
/// sign of the line's edge function at the 16 subpixel centres
/// ([`ExactLine::greater_side`] at each), the function stepped from centre to centre
/// by additions.
#[inline]
fn exact_set(line: &ExactLine, lr: bool, x: u32, y: u32) -> u16 {
    // Subpixel centres at (2k + 1)/8 pixel, in snapped units.
    const HALF_SUB: i64 = (SNAP_ONE / 8) as i64;
    const SUB: i64 = (SNAP_ONE / 4) as i64;
    let x0 = i64::from(x) * i64::from(SNAP_ONE) + HALF_SUB;
    let y0 = i64::from(y) * i64::from(SNAP_ONE) + HALF_SUB;
    // A centre on the line: the one perturbation of `greater_side` decides, so the
    // greater side is `E >= 0` when it holds there and `E >= 1` otherwise.
    let threshold = i64::from(!on_line_greater(line));
    let (step_x, step_y) = (line.a * SUB, line.b * SUB);
    // E at the row's centres, less the threshold: a centre is on the greater side
    // when this is not negative. Steps by additions, four centres of a row at once.
    let steps = [0, step_x, step_x + step_x, step_x + step_x + step_x];
    let mut row = line.a * x0 + line.b * y0 + line.c - threshold;
    let mut e = [0i64; 16];
    for sy in 0..4 {
        for (sx, &dx) in steps.iter().enumerate() {
            e[4 * sy + sx] = row + dx;
        }
        row += step_y;
    }
    // The sign bits of the 16 values: the centres off the greater side.
    let mut less = 0u16;
    for (i, &v) in e.iter().enumerate() {
        less |= ((v as u64 >> 63) as u16) << i;
    }
    let greater = !less;
    if lr {
        greater
    } else {
        !greater
    }
}

/// A 16 x 16 Bayer threshold matrix over the 256 subpixels of a cell.
fn bayer16(x: u32, y: u32) -> u32 {
    let mut v = 0;
    for bit in 0..4 {
        let xb = x >> bit & 1;
        let yb = y >> bit & 1;
        v |= ((xb ^ yb) << 1 | yb) << (2 * (3 - bit));
    }
    v
}

/// The thinning pattern for transparency code `t`: a subpixel is kept when its Bayer
/// threshold is at least `4 t`, so exactly `256 - 4 t` of the cell's 256 subpixels
/// (density `1 - t/64`) are kept, spread evenly.
pub fn thinning(t: u8) -> [u16; 16] {
    let mut out = [0u16; 16];
    for (pixel, set) in out.iter_mut().enumerate() {
        let (px, py) = (pixel as u32 & 3, pixel as u32 >> 2);
        for sub in 0..16u32 {
            let (sx, sy) = (px * 4 + (sub & 3), py * 4 + (sub >> 2));
            if bayer16(sx, sy) >= 4 * u32::from(t) {
                *set |= 1 << sub;
            }
        }
    }
    out
}

/// The SPP's side of the VP's look-ahead ([`super::Sink::ahead`]).
impl SubpixelProcessors {
    /// Asks the caches for the last level's mask memory under a small box of pixels
    /// (`[x0, x1, y0, y1]`, ends excluded, as [`super::bbox`] gives it) ahead of the
    /// polygon that will read it: a hint only, no result changes. A small polygon's
    /// cells lie anywhere on the screen, and the first read of a cell's mask
    /// ([`Self::hidden_avx2`] and the mask step) waited on memory: on `many`, three
    /// fifths of `process_avx2`'s samples sat on that load. Boxes of more than
    /// [`PREFETCH_BOX_CELLS`] cells a side are left to the processor's own
    /// prefetcher.
    #[inline]
    pub fn prefetch_box(&self, [x0, x1, y0, y1]: [u32; 4]) {
        if x1 <= x0 || y1 <= y0 {
            return;
        }
        let (cx0, cx1) = (x0 / CELL_SIDE, (x1 - 1) / CELL_SIDE);
        let (cy0, cy1) = (y0 / CELL_SIDE, (y1 - 1) / CELL_SIDE);
        if cx1 - cx0 >= PREFETCH_BOX_CELLS || cy1 - cy0 >= PREFETCH_BOX_CELLS {
            return;
        }
        use crate::hint::LINE;
        let base = self.masks.as_ptr().cast::<u8>();
        let size = std::mem::size_of::<Words16>();
        for cy in cy0 as usize..=cy1 as usize {
            let row = cy * self.stride;
            // Each line of the row's run of cells (a cell is half a line).
            let (first, last) = ((row + cx0 as usize) * size, (row + cx1 as usize) * size);
            let mut at = first & !(LINE - 1);
            while at <= last {
                crate::hint::prefetch(base.wrapping_add(at));
                at += LINE;
            }
        }
    }
}

/// The most cells a side of a box [`SubpixelProcessors::prefetch_box`] asks for.
/// 12 rather than 5 since session 18: on terrain a quarter of the polygons' boxes
/// span 5 to 12 cells, and their fragments (the SPP's copy without the pre-test)
/// waited on the mask's load (its samples there 31 → 13 % of the copy's).
pub const PREFETCH_BOX_CELLS: u32 = 12;

#[cfg(test)]
mod tests {
    use super::*;

    /// The SPPs' window on a polygon's box ([`box_pixels`]) is
    /// the cell's pixels inside the box, pixel by pixel: boxes around, across and
    /// inside a cell, empty and not, near the screen's origin and far from it.
    #[test]
    fn box_pixels_are_the_pixels_in_the_box() {
        for (px, py) in [(0u32, 0u32), (4, 8), (1000, 516)] {
            for x0 in px.saturating_sub(2)..px + 7 {
                for x1 in x0..px + 8 {
                    for (y0, y1) in [(0, u32::MAX), (py + 1, py + 3), (py, py + 4), (py + 3, py + 9), (py + 5, py + 9)]
                    {
                        let bbox = [x0, x1, y0, y1];
                        let want = (0..16).fold(0u16, |w, i| {
                            let (x, y) = (px + (i & 3), py + (i >> 2));
                            w | u16::from(x >= x0 && x < x1 && y >= y0 && y < y1) << i
                        });
                        assert_eq!(box_pixels(px, py, bbox), want, "cell ({px}, {py}), box {bbox:?}");
                    }
                }
            }
        }
        assert_eq!(box_pixels(8, 4, super::super::gq::NO_BOX), 0xFFFF);
    }

    /// The mask memory as a frame starts pre-masks exactly the pixels off the screen
    /// or outside the share, pixel by pixel ([`Share::owns_pixel`]): for interleaved
    /// shares and strips of a screen whose sides are not whole cells, made whole
    /// and remade after a strip moves.
    #[test]
    fn cleared_memory_pre_masks_the_pixels_outside_the_share() {
        let (width, height) = (70, 37);
        let check = |spp: &SubpixelProcessors| {
            for cy in 0..spp.rows {
                for cx in 0..spp.stride {
                    let want: [u16; 16] = std::array::from_fn(|i| {
                        let (x, y) = ((cx * 4 + (i & 3)) as u32, (cy * 4 + (i >> 2)) as u32);
                        if x < width && y < height && spp.share.owns_pixel(x, y) {
                            0
                        } else {
                            FULL
                        }
                    });
                    assert_eq!(*spp.mask(cx, cy), want, "share {:?}, cell ({cx}, {cy})", spp.share);
                }
            }
            let open = (0..width).flat_map(|x| (0..height).map(move |y| (x, y)));
            let open = open.filter(|&(x, y)| spp.share.owns_pixel(x, y)).count() as u64;
            assert_eq!(spp.open_pixels(), open, "share {:?}", spp.share);
        };
        for share in [Share::WHOLE, Share::interleaved(8, 3, 2, 1, 1), Share::interleaved(16, 2, 3, 0, 2)] {
            let mut spp = SubpixelProcessors::new(width, height, SppMode::Area);
            spp.share = share;
            spp.clear();
            check(&spp);
        }
        let mut spp = SubpixelProcessors::new(width, height, SppMode::Area);
        for strip in [(0, 32), (16, 48), (48, 80), (0, 80), (32, 64), (8, 16)] {
            spp.share = Share::strip(8, strip.0, strip.1);
            spp.clear();
            check(&spp);
        }
    }

    /// [`box_outside_at_avx2`] of [`BoxLanes::new`] is the complement of [`pixel_lanes_avx2`] of
    /// [`box_pixels`], lane by lane: boxes around,
    /// across and inside cells, empty, reversed and unbounded, near the origin and near
    /// the end of `u32`.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn box_outside_lanes_are_box_pixels() {
        if !has_avx2() {
            return;
        }
        let mut next = xorshift(0x5EED_B0C5_0000_0011);
        // The last cells before `box_pixels`' `px + CELL_SIDE` would overflow.
        let far = u32::MAX - CELL_SIDE;
        for k in 0..200_000 {
            let (px, py) = match k % 4 {
                0 => (4 * next(8) as u32, 4 * next(8) as u32),
                1 => (far - 4 * next(4) as u32, 4 * next(300) as u32),
                _ => (4 * next(500) as u32, 4 * next(300) as u32),
            };
            let mut side = |p: u32| -> [u32; 2] {
                match next(6) {
                    0 => [0, u32::MAX],
                    1 => [next(1 << 20) as u32, next(1 << 20) as u32],
                    2 => [u32::MAX - next(8) as u32, u32::MAX - next(8) as u32],
                    _ => {
                        let lo = (i64::from(p) + next(13) - 6).clamp(0, i64::from(u32::MAX)) as u32;
                        [lo, lo.saturating_add(next(12) as u32)]
                    }
                }
            };
            let ([x0, x1], [y0, y1]) = (side(px), side(py));
            let bbox = [x0, x1, y0, y1];
            // SAFETY: both functions only need AVX2, which `has_avx2` found.
            #[allow(unsafe_code, reason = "functions compiled for AVX2, after detection")]
            let (got, want) = unsafe {
                let mut got = [0u16; 16];
                let mut want = [0u16; 16];
                std::arch::x86_64::_mm256_storeu_si256(
                    got.as_mut_ptr().cast(),
                    box_outside_at_avx2(px, py, &BoxLanes::new(bbox)),
                );
                std::arch::x86_64::_mm256_storeu_si256(
                    want.as_mut_ptr().cast(),
                    pixel_lanes_avx2(box_pixels(px, py, bbox)),
                );
                (got, want)
            };
            assert_eq!(got, want.map(|w| !w), "case {k}: cell ({px}, {py}), box {bbox:?}");
        }
    }

    /// [`BoxLanes::new`] (SSE2 on x86-64) is [`BoxLanes::new_plain`]: boxes near
    /// the origin, reversed, empty and unbounded.
    #[test]
    fn box_lanes_are_the_plain_ones() {
        let mut next = xorshift(0x5EED_B0C5_0000_0022);
        for k in 0..20_000 {
            let mut v = || match next(4) {
                0 => next(4) as u32,
                1 => u32::MAX - next(4) as u32,
                _ => next(1 << 32) as u32,
            };
            let bbox = [v(), v(), v(), v()];
            assert_eq!(BoxLanes::new(bbox), BoxLanes::new_plain(bbox), "case {k}: box {bbox:?}");
        }
    }

    /// Marsaglia's xorshift64: `next(n)` is a deterministic number in `0..n`.
    /// Up to `n` random edges (fewer where two points coincide) of a screen of
    /// `root_side` pixels, each with an end in or around the 4 x 4 cell at `(px, py)`
    /// and the other there too or anywhere on the screen, and their active entries
    /// at the cell.
    fn edges_around_cell(
        next: &mut impl FnMut(i64) -> i64,
        px: u32,
        py: u32,
        root_side: u32,
        n: usize,
    ) -> (Vec<super::super::edge::EdgeCode>, Vec<super::super::gq::ActiveEdge>) {
        use super::super::edge::{EdgeCode, ScreenFx};
        use super::super::gq::ActiveEdge;
        let one = i64::from(SNAP_ONE);
        let span = i64::from(root_side) * one;
        let mut point = |near: bool| {
            let (x, y) = if near {
                (i64::from(px) * one + next(12 * one) - 4 * one, i64::from(py) * one + next(12 * one) - 4 * one)
            } else {
                (next(span + 1), next(span + 1))
            };
            (ScreenFx(x.clamp(0, span) as i32), ScreenFx(y.clamp(0, span) as i32))
        };
        let edges: Vec<EdgeCode> =
            (0..n).filter_map(|i| EdgeCode::new(point(i % 2 == 0), point(true), i % 3 == 0, root_side)).collect();
        let active = edges
            .iter()
            .enumerate()
            .map(|(i, e)| ActiveEdge::at_cell(i as u32, e, i64::from(px), i64::from(py), 4))
            .collect();
        (edges, active)
    }

    fn xorshift(mut state: u64) -> impl FnMut(i64) -> i64 {
        move |n| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as i64
        }
    }

    #[test]
    fn bayer16_is_a_permutation() {
        let mut seen = [false; 256];
        for y in 0..16 {
            for x in 0..16 {
                seen[bayer16(x, y) as usize] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn thinning_has_the_code_density() {
        for t in 0..64u8 {
            let kept: u32 = thinning(t).iter().map(|s| s.count_ones()).sum();
            assert_eq!(kept, 256 - 4 * u32::from(t), "t = {t}");
        }
        assert_eq!(thinning(0), [FULL; 16]);
    }

    #[test]
    fn exact_set_is_greater_side_at_the_sixteen_centres() {
        // Lines through random snapped points, some through subpixel centres (ties).
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        for k in 0..20_000 {
            let (x, y) = (next(64) as u32, next(64) as u32);
            let centre = |c: u32, s: i64| i64::from(c) * i64::from(SNAP_ONE) + (2 * s + 1) * i64::from(SNAP_ONE) / 8;
            let p = if k % 3 == 0 {
                (centre(x, next(4)), centre(y, next(4)))
            } else {
                (next(64 * i64::from(SNAP_ONE)), next(64 * i64::from(SNAP_ONE)))
            };
            let (a, b) = match k % 7 {
                0 => (0, next(2000) + 1),
                1 => (next(2000) + 1, 0),
                _ => (next(4001) - 2000, next(4001) - 2000),
            };
            let line = ExactLine { a, b, c: -(a * p.0 + b * p.1), ends: [(0, 0); 2] };
            for lr in [false, true] {
                let set = exact_set(&line, lr, x, y);
                for sub in 0..16 {
                    let greater = line.greater_side(centre(x, sub & 3), centre(y, sub >> 2));
                    assert_eq!(set >> sub & 1 == 1, greater == lr, "line {line:?}, pixel ({x}, {y}), subpixel {sub}");
                }
            }
        }
    }

    #[test]
    fn vertex_pixels_are_the_pixels_near_an_end() {
        let mut next = {
            let mut next = xorshift(0x2545_F491_4F6C_DD1D);
            move |n: i32| next(i64::from(n)) as i32
        };
        for _ in 0..20_000 {
            let (px, py) = (4 * next(16) as u32, 4 * next(16) as u32);
            let mut end = || (next(70 * SNAP_ONE) - 3 * SNAP_ONE, next(70 * SNAP_ONE) - 3 * SNAP_ONE);
            let mut ends = [end(), end()];
            // Endpoints on and around the margins of the cell's pixels.
            if next(2) == 0 {
                let d = |v: i32| v - v.rem_euclid(SNAP_ONE / 2);
                ends[0] = (d(ends[0].0) + next(3) - 1, d(ends[0].1) + next(3) - 1);
            }
            let line = ExactLine { a: 1, b: 0, c: 0, ends };
            let pixels = vertex_pixels(&line.ends, px, py);
            assert_eq!(vertex_pixels_fast(&line.ends, px, py), pixels, "ends {ends:?}, cell ({px}, {py})");
            for pixel in 0..16u32 {
                let near = near_end(&line.ends, px + (pixel & 3), py + (pixel >> 2));
                assert_eq!(pixels >> pixel & 1 == 1, near, "ends {ends:?}, cell ({px}, {py}), pixel {pixel}");
            }
            assert_eq!(pixels != 0, near_end_cell(&line.ends, px, py), "ends {ends:?}, cell ({px}, {py})");
            #[cfg(target_arch = "x86_64")]
            {
                // SAFETY: x86-64 always has SSE2.
                #[allow(unsafe_code, reason = "a function compiled for SSE2, on x86-64")]
                let got = unsafe { near_end_cell_sse2(&line.ends, px, py) };
                assert_eq!(got, pixels != 0, "SSE2: ends {ends:?}, cell ({px}, {py})");
            }
        }
    }

    /// [`vertex_pixels_fast`] (the SSE4.1 window) is [`vertex_pixels`] on screens up
    /// to 8192 pixels, endpoints on pixel borders, their margins and anywhere, and
    /// coordinates too large for its 32-bit lanes (the portable path then).
    #[test]
    fn vertex_pixels_fast_is_vertex_pixels() {
        let mut next = xorshift(0x0EDD_1E5E_A5E5_F00D);
        let one = i64::from(SNAP_ONE);
        for k in 0..200_000 {
            let (px, py) = (4 * next(2048) as u32, 4 * next(2048) as u32);
            let mut coordinate = |p: u32| -> i32 {
                let near = i64::from(p) * one + next(8 * one) - 2 * one;
                match k % 6 {
                    0 => (near - near.rem_euclid(one / 2) + next(3) - 1) as i32,
                    1 => next(1 << 32) as i32 ^ (next(2) << 31) as i32,
                    2 => (next(2 * 8192 * one) - 8192 * one) as i32,
                    _ => near as i32,
                }
            };
            let ends = [(coordinate(px), coordinate(py)), (coordinate(px), coordinate(py))];
            let line = ExactLine { a: 1, b: 0, c: 0, ends };
            assert_eq!(
                vertex_pixels_fast(&line.ends, px, py),
                vertex_pixels(&line.ends, px, py),
                "{ends:?} ({px}, {py})"
            );
        }
    }

    /// [`vertex_near_avx2`] is the window table's vertex pixels ([`vertex_start`]) in
    /// the words' order, and [`vertex_pixels`] (transposed for a horizontal edge):
    /// endpoints in, around and far from the cell, on the widened borders and one unit
    /// either side, anywhere in the 32-bit paths' range.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn vertex_near_avx2_is_vertex_pixels() {
        if !has_avx2() {
            return;
        }
        let mut next = xorshift(0x0A11_2E4D_5EED_0B0E);
        let one = i64::from(SNAP_ONE);
        let limit = i64::from(EXACT32_END_LIMIT);
        let transpose = |p: u16| (0..16).fold(0u16, |t, i| t | (p >> i & 1) << (4 * (i & 3) + (i >> 2)));
        for k in 0..200_000 {
            let (px, py) = match k % 4 {
                0 => (4 * next(i64::from(CELL_LIMIT_32) / 4) as u32, 4 * next(i64::from(CELL_LIMIT_32) / 4) as u32),
                _ => (4 * next(2048) as u32, 4 * next(2048) as u32),
            };
            let mut coordinate = |p: u32| -> i32 {
                let near = i64::from(p) * one + next(8 * one) - 2 * one;
                let v = match k % 5 {
                    0 => near - near.rem_euclid(one / 2) + next(3) - 1,
                    1 => next(2 * limit - 2) - limit + 1,
                    _ => near,
                };
                v.clamp(-limit + 1, limit - 1) as i32
            };
            let ends = [(coordinate(px), coordinate(py)), (coordinate(px), coordinate(py))];
            let line = ExactLine { a: 1, b: 0, c: 0, ends };
            assert!(VertexWindow::fits(&line.ends, px, py));
            let plain = vertex_pixels(&line.ends, px, py);
            for vertical in [false, true] {
                // SAFETY: the processor has what `has_avx2` asks (and the SSE4.1 it implies).
                #[allow(unsafe_code, reason = "functions compiled for AVX2 and SSE4.1, after detection")]
                let (got, table) = unsafe {
                    (
                        vertex_near_avx2(end_offsets_sse2(&line.ends, px, py), vertical),
                        vertex_start(&line, px, py, vertical).map_or(0, |s| s.near),
                    )
                };
                assert_eq!(got, table, "{ends:?} ({px}, {py}) vertical {vertical}");
                assert_eq!(got, if vertical { plain } else { transpose(plain) }, "{ends:?} ({px}, {py})");
            }
        }
    }

    /// [`near_end_cell_sse2`] is [`near_end_cell`]: cells up to and beyond
    /// [`CELL_LIMIT_32`], endpoints in, around and far from them, at the ends of the
    /// `i32` range (where the 32-bit differences wrap).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn near_end_cell_sse2_is_near_end_cell() {
        let mut next = xorshift(0x0DD5_EE2E_11D5_0A11);
        let one = i64::from(SNAP_ONE);
        for k in 0..400_000 {
            let cell = |next: &mut dyn FnMut(i64) -> i64| match k % 3 {
                0 => 4 * next(2048) as u32,
                1 => (i64::from(CELL_LIMIT_32) - 4 * next(64)) as u32,
                _ => 4 * next(1 << 28) as u32,
            };
            let (px, py) = (cell(&mut next), cell(&mut next));
            let mut coordinate = |p: u32| -> i32 {
                let near = i64::from(p) * one + next(8 * one) - 2 * one;
                let v = match k % 7 {
                    0 => near - near.rem_euclid(one / 2) + next(3) - 1,
                    1 => next(1 << 32) ^ (next(2) << 31),
                    2 => [i64::from(i32::MIN), i64::from(i32::MAX)][next(2) as usize] + next(2000) - 1000,
                    3 => near + (next(3) - 1) * (1 << 32),
                    _ => near,
                };
                v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
            };
            let ends = [(coordinate(px), coordinate(py)), (coordinate(px), coordinate(py))];
            let line = ExactLine { a: 1, b: 0, c: 0, ends };
            // SAFETY: x86-64 always has SSE2.
            #[allow(unsafe_code, reason = "a function compiled for SSE2, on x86-64")]
            let got = unsafe { near_end_cell_sse2(&line.ends, px, py) };
            assert_eq!(got, near_end_cell(&line.ends, px, py), "{ends:?} ({px}, {py})");
            if std::is_x86_feature_detected!("sse4.1") {
                // SAFETY: the processor was just found to have SSE4.1 (and SSE2).
                #[allow(unsafe_code, reason = "functions compiled for SSE4.1, after detection")]
                let got = unsafe { near_end_cell_at_sse41(&line.ends, px, py, end_offsets_sse2(&line.ends, px, py)) };
                assert_eq!(got, near_end_cell(&line.ends, px, py), "{ends:?} ({px}, {py}), offsets");
            }
        }
    }

    #[test]
    fn edge_sets_are_the_sixteen_lookups() {
        let table = SppTable::get(SppMode::Area);
        for (tg, vertical) in [(Tg::Vertical, true), (Tg::Horizontal, false)] {
            for lr in [false, true] {
                let part = table.half(tg, lr);
                for q0 in -40..40 {
                    for dq in -12..12 {
                        let q: [i32; 5] = std::array::from_fn(|k| q0 + dq * k as i32 / 2);
                        let sets = if vertical { edge_sets::<true>(part, &q) } else { edge_sets::<false>(part, &q) };
                        for along in 0..4 {
                            for across in 0..4 {
                                let pixel = if vertical { along * 4 + across } else { across * 4 + along };
                                let shift = (across as i32) << SPP_V_BITS;
                                let want = SppTable::lookup_in(part, q[along] - shift, q[along + 1] - shift);
                                assert_eq!(sets[pixel], want, "q {q:?}, pixel {pixel}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// [`SubpixelProcessors::fragment_code`] as it was defined before the row table:
    /// per edge the 16 look-ups of [`edge_sets`], then [`exact_set`] at its vertex
    /// pixels, ANDed pixel by pixel.
    fn fragment_code_plain(spp: &SubpixelProcessors, frag: &Fragment, edges: &[EdgeCode]) -> [u16; 16] {
        let table = SppTable::get(spp.mode);
        let mut code = [FULL; 16];
        for a in frag.active {
            let e = &edges[a.edge as usize];
            let vertex = if spp.vertex_exact { vertex_pixels(&e.ends, frag.px, frag.py) } else { 0 };
            // V1 relative to the cell's first pixel column (row), as the GQ gives it.
            let q: [i32; 5] = std::array::from_fn(|k| round_q(a.v1.0 + e.slope.0 * k as i64));
            let part = table.half(e.tg(), e.lr());
            let mut sets = match e.tg() {
                Tg::Vertical => edge_sets::<true>(part, &q),
                Tg::Horizontal => edge_sets::<false>(part, &q),
            };
            for (pixel, set) in sets.iter_mut().enumerate() {
                if vertex >> pixel & 1 == 1 {
                    *set = exact_set(&e.exact(), e.lr(), frag.px + (pixel as u32 & 3), frag.py + (pixel as u32 >> 2));
                }
            }
            for (c, s) in code.iter_mut().zip(sets) {
                *c &= s;
            }
        }
        code
    }

    /// The fragment codes by row table, 32-bit exact sets and transposed columns are
    /// those of the plain definition: random edges through and around random cells,
    /// endpoints in and near the cell (vertex pixels), long and steep lines, lines on
    /// subpixel centres, every mode, screens from 64 to 8192 pixels.
    #[test]
    fn fragment_code_is_the_plain_definition() {
        use super::super::edge::{EdgeCode, ScreenFx};
        use super::super::gq::ActiveEdge;
        let mut next = xorshift(0x0DDB_1A5E_5BAD_5EED);
        let mut checked = [0usize; 2];
        for k in 0..60_000 {
            let level = (k % 12) as u32;
            let root_side = 4u32 << level;
            let mode = [SppMode::Area, SppMode::Sample, SppMode::Area][k % 3];
            // The fragment code reads no memory of the screen: a one-cell screen.
            let mut spp = SubpixelProcessors::new(CELL_SIDE, CELL_SIDE, mode);
            spp.vertex_exact = k % 3 != 1;
            let cells = i64::from(root_side / CELL_SIDE);
            let (px, py) = (4 * next(cells) as u32, 4 * next(cells) as u32);
            let one = i64::from(SNAP_ONE);
            let span = i64::from(root_side) * one;
            // A point near the cell (often in it), or anywhere on the screen; sometimes
            // on a subpixel centre or a pixel corner.
            let point = |next: &mut dyn FnMut(i64) -> i64, near: bool| -> (ScreenFx, ScreenFx) {
                let (x, y) = if near {
                    let r = [2, 8, 40][next(3) as usize] * one;
                    (i64::from(px) * one + next(2 * r) - r / 2, i64::from(py) * one + next(2 * r) - r / 2)
                } else {
                    (next(span + 1), next(span + 1))
                };
                let mut snap = |v: i64| match next(4) {
                    0 => v - v.rem_euclid(one / 4) + one / 8,
                    1 => v - v.rem_euclid(one),
                    _ => v,
                };
                let (x, y) = (snap(x), snap(y));
                (ScreenFx(x.clamp(0, span) as i32), ScreenFx(y.clamp(0, span) as i32))
            };
            let n = 1 + next(4) as usize;
            let mut edges = Vec::new();
            while edges.len() < n {
                let (na, nb) = (next(3) != 0, next(2) == 0);
                let (a, b) = (point(&mut next, na), point(&mut next, nb));
                if let Some(e) = EdgeCode::new(a, b, next(2) == 0, root_side) {
                    edges.push(e);
                }
            }
            let active: Vec<ActiveEdge> = edges
                .iter()
                .enumerate()
                .map(|(i, e)| ActiveEdge::at_cell(i as u32, e, i64::from(px), i64::from(py), 4))
                .collect();
            let frag =
                Fragment { px, py, active: &active, cells: super::super::gq::ONE_CELL, bbox: super::super::gq::NO_BOX };
            let want = fragment_code_plain(&spp, &frag, &edges);
            let got = spp.fragment_code::<false>(&frag, &edges, &mut Counters::new(level));
            assert_eq!(got, want, "case {k}: mode {mode:?}, cell ({px}, {py}), edges {edges:?}");
            checked[usize::from(want.iter().any(|&c| c != 0 && c != FULL))] += 1;
        }
        // A third of the cases or more cut some pixel: not all empty or full cells.
        assert!(checked[1] > checked[0] / 2, "{checked:?}");
    }

    /// The exact sets at vertex pixels in 32-bit lanes are [`exact_set`]: lines of
    /// every slope up to the largest coefficients that fit, far from the pixel (the
    /// saturated compare) and through its subpixel centres (ties).
    #[test]
    fn exact_sets_in_32_bits_are_exact_set() {
        let mut next = xorshift(0x005E_ED0F_E1A5_7E57);
        let one = i64::from(SNAP_ONE);
        for k in 0..40_000 {
            let limit = [2_000, 1 << 16, (1 << 22) - 1][k % 3];
            let (a, b) = match k % 5 {
                0 => (0, next(limit) + 1),
                1 => (next(limit) + 1, 0),
                _ => (next(2 * limit + 1) - limit, next(2 * limit + 1) - limit),
            };
            let (px, py) = (4 * next(2048) as u32, 4 * next(2048) as u32);
            // Through a point near the cell, on a centre or anywhere; or far away.
            let p = match k % 4 {
                0 => (
                    i64::from(px) * one + (2 * next(16) + 1) * one / 8,
                    i64::from(py) * one + (2 * next(16) + 1) * one / 8,
                ),
                1 => (i64::from(px) * one + next(4 * one), i64::from(py) * one + next(4 * one)),
                2 => (i64::from(px) * one + next(64 * one) - 32 * one, i64::from(py) * one + next(64 * one) - 32 * one),
                _ => (next(8192 * one), next(8192 * one)),
            };
            let line = ExactLine { a, b, c: -(a * p.0 + b * p.1), ends: [(0, 0); 2] };
            assert!(ExactLine32::fits(&line));
            let near = next(1 << 16) as u16;
            for vertical in [false, true] {
                for lr in [false, true] {
                    let mut words = [0x0123_4567_89AB_CDEF_u64, 0, u64::MAX, 0x5555_AAAA_0F0F_F0F0];
                    let mut want = words;
                    exact_into(&line, lr, px, py, near, vertical, &mut words);
                    for pixel in 0..16 {
                        if near >> pixel & 1 == 1 {
                            let set = exact_set(&line, lr, px + (pixel & 3), py + (pixel >> 2));
                            put_set(&mut want, pixel, vertical, set);
                        }
                    }
                    assert_eq!(words, want, "line {line:?}, cell ({px}, {py}), near {near:#06x}");
                }
            }
        }
    }

    /// [`vertex_words`] (the 32-bit path an edge's `exact32` flag opens, and the checked
    /// one) puts [`exact_set`] at the [`vertex_pixels`] of the plain definition: edges
    /// with endpoints in and around the cell, long ones (`exact32` false beyond `2^22`
    /// snapped units) and lines through subpixel centres; and an edge's line has
    /// `a >= 0` exactly when its points on the line are on the greater side.
    #[test]
    fn vertex_words_are_the_plain_sets() {
        use super::super::edge::ScreenFx;
        let mut next = xorshift(0x0BAD_CAFE_F00D_1234);
        let one = i64::from(SNAP_ONE);
        let (mut long, mut wide, mut sse41, mut avx2, mut avx512) = (0, 0, 0, 0, 0);
        for k in 0..100_000 {
            let (px, py) = (4 * next(2048) as u32, 4 * next(2048) as u32);
            let mut point = |near: bool| {
                let (x, y) = if near {
                    (i64::from(px) * one + next(8 * one) - 2 * one, i64::from(py) * one + next(8 * one) - 2 * one)
                } else {
                    let far = [8192 * one, 1 << 23, 1 << 26][next(3) as usize];
                    (next(2 * far) - far / 2, next(2 * far) - far / 2)
                };
                let snap = |v: i64| if k % 4 == 0 { v - v.rem_euclid(one / 4) + one / 8 } else { v };
                (ScreenFx(snap(x) as i32), ScreenFx(snap(y) as i32))
            };
            let (a, b) = (point(true), point(k % 3 == 0));
            let Some(e) = EdgeCode::new(a, b, k % 2 == 0, 8192) else { continue };
            assert_eq!(e.exact().a >= 0, on_line_greater(&e.exact()), "{e:?}");
            long += usize::from(!e.exact32());
            // The 32-bit edges that the AVX2 path hands to `vertex_words_wide`.
            let coefficients = e.exact().a.unsigned_abs().max(e.exact().b.unsigned_abs());
            wide += usize::from(
                e.exact32() && coefficients >= VERTEX_COEFFICIENT_LIMIT as u64 && vertex_pixels(&e.ends, px, py) != 0,
            );
            let words: [u64; 4] = std::array::from_fn(|_| next(i64::MAX) as u64 ^ (next(2) as u64) << 63);
            for vertical in [false, true] {
                let mut want = words;
                let vertex = vertex_pixels(&e.ends, px, py);
                for pixel in 0..16 {
                    if vertex >> pixel & 1 == 1 {
                        let set = exact_set(&e.exact(), e.lr(), px + (pixel & 3), py + (pixel >> 2));
                        put_set(&mut want, pixel, vertical, set);
                    }
                }
                assert_eq!(vertex_words(&e, px, py, vertical, words), want, "{e:?} ({px}, {py})");
                #[cfg(target_arch = "x86_64")]
                if e.exact32() {
                    // Each SIMD path the processor has, whichever `vertex_words` takes.
                    if std::is_x86_feature_detected!("sse4.1") {
                        // SAFETY: the processor has SSE4.1.
                        #[allow(unsafe_code, reason = "a function compiled for SSE4.1, after detection")]
                        let got = unsafe { vertex_words_sse41(&e, px, py, vertical, words) };
                        assert_eq!(got, want, "SSE4.1: {e:?} ({px}, {py})");
                        sse41 += 1;
                    }
                    if has_avx2() {
                        // SAFETY: the processor has what `has_avx2` asks.
                        #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
                        let got = unsafe { vertex_words_avx2(&e, px, py, vertical, words) };
                        assert_eq!(got, want, "AVX2: {e:?} ({px}, {py})");
                        avx2 += 1;
                    }
                    if has_avx512() {
                        // SAFETY: the processor has what `has_avx512` asks.
                        #[allow(unsafe_code, reason = "a function compiled for AVX-512, after detection")]
                        let got = unsafe { vertex_words_avx512(&e, px, py, vertical, words) };
                        assert_eq!(got, want, "AVX-512: {e:?} ({px}, {py})");
                        avx512 += 1;
                    }
                }
                let checked = e.without_exact32();
                assert_eq!(vertex_words(&checked, px, py, vertical, words), want, "{e:?} ({px}, {py})");
            }
        }
        assert!(long > 1000, "{long}");
        assert!(wide > 1000, "{wide}");
        eprintln!("vertex_words: {wide} wide, {sse41} cases in SSE4.1, {avx2} in AVX2, {avx512} in AVX-512");
    }

    /// The SSE2 row-table indices are the portable ones: V and slopes of every size
    /// (far beyond the row table's saturation, and up to the sums' 64-bit range),
    /// on and around the rounding's halves, negative and positive.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn line_indices_sse2_are_the_portable_ones() {
        let mut next = xorshift(0x0051_DECA_5E0F_1DE5);
        let half = 1i64 << (EDGE_FRAC_BITS - SPP_V_BITS - 1);
        for k in 0..200_000 {
            let scale = [1i64 << 20, 1 << 30, 1 << 33, 1 << 36, 1 << 44, 1 << 58][k % 6];
            let mut v1 = next(2 * scale) - scale;
            let slope = match k % 5 {
                0 => 0,
                1 => next(1 << 33) - (1 << 32),
                2 => (next(17) - 8) * half,
                _ => next(2 * scale / 8) - scale / 8,
            };
            if k % 3 == 0 {
                // On a rounding half, or one unit either side.
                v1 = (v1 / (2 * half)) * 2 * half + half + next(3) - 1;
            }
            // SAFETY: x86-64 always has SSE2.
            #[allow(unsafe_code, reason = "a function compiled for SSE2, on x86-64")]
            let got = unsafe { line_indices_sse2(v1, slope) };
            let want = line_indices_portable(v1, slope);
            assert_eq!(got, want, "v1 {v1}, slope {slope}");
            if std::is_x86_feature_detected!("sse4.1") {
                // SAFETY: the processor was just found to have SSE4.1.
                #[allow(unsafe_code, reason = "a function compiled for SSE4.1, after detection")]
                let lanes = unsafe { std::arch::x86_64::_mm_cvtsi128_si64(line_index_lanes_sse41(v1, slope)) } as u64;
                let got: [usize; 4] = std::array::from_fn(|k| (lanes >> (16 * k)) as u16 as usize);
                assert_eq!(got, want, "SSE4.1: v1 {v1}, slope {slope}");
            }
        }
    }

    /// [`SubpixelProcessors::background`] by its definition: every subpixel the mask
    /// leaves open, first writes where the pixel had nothing, and the cell's mask back
    /// in its cleared state; masks empty, full, pre-masked and anything.
    #[test]
    fn background_is_its_definition() {
        let mut next = xorshift(0xBAC6_0000_D5EE_0007);
        let (w, h) = (23, 14);
        let mut spp = SubpixelProcessors::new(w, h, SppMode::Area);
        for k in 0..5_000 {
            let (cx, cy) = (next(6) as usize, next(4) as usize);
            let cell = cy * spp.stride + cx;
            let mask: [u16; 16] = std::array::from_fn(|_| match next(4) {
                0 => 0,
                1 => FULL,
                _ => next(1 << 16) as u16,
            });
            spp.masks[cell].0 = [[0; 16], [FULL; 16], mask][(next(6) as usize).min(2)];
            let before = spp.masks[cell].0;
            let vis = spp.background(cx, cy);
            let first = (0..16).fold(0u16, |f, i| f | u16::from(before[i] == 0) << i);
            let want = Visible { px: 4 * cx as u32, py: 4 * cy as u32, sets: before.map(|m| !m), first, covered: true };
            assert_eq!(vis, want, "case {k}");
            assert_eq!(spp.masks[cell], spp.cleared[cell], "case {k}");
        }
    }

    /// The table fact the GQ's closed bands rest on ([`band_closed`](super::super::gq)),
    /// over every pair of row-table entries of both builds and both TGs: where the
    /// LR = 1 edge's `q` is greater than the LR = 0 edge's on both lines of a pixel
    /// row, or both saturate alike at the row table's bounds, the LR = 1 edge's
    /// greater-side word lies within the other's, so the band's AND is empty.
    /// Entries whose two lines differ by more than `STEP` are left out: no edge reads
    /// them (|slope| is at most a pixel a pixel, plus the root values' rounding, so `q`
    /// moves by at most 9 from a line to the next); the fact fails only beyond 16.
    #[test]
    fn greater_lines_nest_greater_sides() {
        const STEP: i32 = 16;
        let ordered = |l: i32, u: i32| l > u || (l == u && (l == ROW_Q_MIN || l == ROW_Q_MAX));
        for mode in [SppMode::Area, SppMode::Sample] {
            let part_of = SppRowTable::get(mode);
            for tg in [Tg::Vertical, Tg::Horizontal] {
                let part = part_of.part(tg);
                for l1 in ROW_Q_MIN..=ROW_Q_MAX {
                    for l2 in (l1 - STEP).max(ROW_Q_MIN)..=(l1 + STEP).min(ROW_Q_MAX) {
                        let lower = part[SppRowTable::index(l1, l2)];
                        for u1 in ROW_Q_MIN..=l1 {
                            for u2 in (u1 - STEP).max(ROW_Q_MIN)..=(u1 + STEP).min(l2) {
                                if ordered(l1, u1) && ordered(l2, u2) {
                                    let upper = part[SppRowTable::index(u1, u2)];
                                    assert_eq!(lower & !upper, 0, "{mode:?} {tg:?}: ({l1}, {l2}) over ({u1}, {u2})");
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// [`ends_near`] of a 4x4 cell is [`near_end_cell`], and of any cell it is whether
    /// [`vertex_pixels`] finds a vertex pixel in one of its 4x4 cells.
    #[test]
    fn ends_near_is_a_vertex_pixel_in_the_cell() {
        use super::super::edge::{EdgeCode, ScreenFx};
        let mut next = xorshift(0xE4D5_4EA4_0F7E_11CE);
        for k in 0..20_000 {
            let side = 4u32 << (k % 4);
            let (px, py) = (side * next(8) as u32, side * next(8) as u32);
            let one = i64::from(SNAP_ONE);
            let mut point = || {
                let r = i64::from(side) * one;
                let mut c = |p: u32| (i64::from(p) * one + next(3 * r) - r).clamp(0, 40 * r);
                (ScreenFx(c(px) as i32), ScreenFx(c(py) as i32))
            };
            let (a, b) = (point(), point());
            let Some(e) = EdgeCode::new(a, b, true, 4096) else { continue };
            let cells = side / CELL_SIDE;
            let any = (0..cells * cells).any(|i| {
                let (x, y) = (px + CELL_SIDE * (i % cells), py + CELL_SIDE * (i / cells));
                vertex_pixels(&e.ends, x, y) != 0
            });
            assert_eq!(ends_near(&e.ends, px, py, side), any, "side {side}, cell ({px}, {py}), {:?}", e.exact().ends);
            if side == CELL_SIDE {
                assert_eq!(ends_near(&e.ends, px, py, side), near_end_cell(&e.ends, px, py));
            }
        }
    }

    /// The portable fragment code (the path of processors without SSE2) is the one
    /// [`SubpixelProcessors::fragment_code`] gives, over the cases of
    /// `fragment_code_is_the_plain_definition` (which checks the latter against the
    /// plain definition).
    #[test]
    fn portable_fragment_code_is_fragment_code() {
        let mut next = xorshift(0x7AB1_E5C0_DE5A_11CE);
        for k in 0..20_000 {
            let root_side = 4u32 << (k % 12);
            let mode = [SppMode::Area, SppMode::Sample][k % 2];
            let mut spp = SubpixelProcessors::new(CELL_SIDE, CELL_SIDE, mode);
            spp.vertex_exact = k % 3 != 1;
            let cells = i64::from(root_side / CELL_SIDE);
            let (px, py) = (4 * next(cells) as u32, 4 * next(cells) as u32);
            let (edges, active) = edges_around_cell(&mut next, px, py, root_side, 4);
            let frag =
                Fragment { px, py, active: &active, cells: super::super::gq::ONE_CELL, bbox: super::super::gq::NO_BOX };
            let mut counters = Counters::new(3);
            let want = spp.fragment_code::<false>(&frag, &edges, &mut counters);
            let got = spp.table_code::<false>(
                &frag,
                &edges,
                &mut counters,
                line_indices_portable,
                near_end_cell,
                vertex_words,
            );
            assert_eq!(got, want, "case {k}");
        }
    }

    /// [`SubpixelProcessors::process`] (on a processor with AVX2, its AVX2 copy) is
    /// [`SubpixelProcessors::process_plain`]: the same visible sets, first writes,
    /// cover, mask memory and counts, over random edges through and around random
    /// cells (vertex pixels, steep and long lines), boxes that clip the cell or not,
    /// masks empty, full or anything, every transparency code, both table modes,
    /// cells at a screen's ragged right and bottom borders, counting on and off.
    /// Most boxes are small ([`SMALL_BOX`]), so with counting off the AVX2 step first
    /// asks whether the fragment is hidden ([`SubpixelProcessors::hidden_avx2`]; a
    /// test that says so wrongly fails here).
    #[test]
    fn process_is_process_plain() {
        use super::super::gq::NO_BOX;
        let mut next = xorshift(0x0F0F_5EED_A5A5_1234);
        // Per level (screens up to 1024 pixels) and mode, two SPP sets fed alike.
        let mut sets: Vec<Option<(SubpixelProcessors, SubpixelProcessors)>> = (0..18).map(|_| None).collect();
        for k in 0..30_000 {
            let level = (k / 2 % 9) as u32;
            let root_side = 4u32 << level;
            let mode = [SppMode::Area, SppMode::Sample][k % 2];
            let (a, b) = sets[k % 18].get_or_insert_with(|| {
                let (w, h) = (root_side - 1, (root_side - 3).max(1));
                (SubpixelProcessors::new(w, h, mode), SubpixelProcessors::new(w, h, mode))
            });
            let vertex_exact = k % 5 != 1;
            (a.vertex_exact, b.vertex_exact) = (vertex_exact, vertex_exact);
            let cells = i64::from(root_side / CELL_SIDE);
            let (px, py) = (4 * next(cells) as u32, 4 * next(cells) as u32);
            let n = next(5) as usize;
            let (edges, active) = edges_around_cell(&mut next, px, py, root_side, n);
            let bbox = if next(3) == 0 {
                NO_BOX
            } else {
                let mut side = |p: u32| {
                    let lo = (i64::from(p) + next(9) - 6).max(0) as u32;
                    [lo, lo + next(10) as u32]
                };
                let ([x0, x1], [y0, y1]) = (side(px), side(py));
                [x0, x1, y0, y1]
            };
            let frag = Fragment { px, py, active: &active, cells: super::super::gq::ONE_CELL, bbox };
            let cell = (py / CELL_SIDE) as usize * a.stride + (px / CELL_SIDE) as usize;
            let mask: [u16; 16] = std::array::from_fn(|_| match next(5) {
                0 => 0,
                1 => FULL,
                _ => next(1 << 16) as u16,
            });
            let mask = [[0; 16], [FULL; 16], mask][(next(8) as usize).min(2)];
            (a.masks[cell].0, b.masks[cell].0) = (mask, mask);
            let t = if k % 3 == 0 { 0 } else { next(64) as u8 };
            let (mut ca, mut cb) = (Counters::new(level), Counters::new(level));
            let poly = a.polygon(bbox, t);
            let (got, want) = if k % 4 == 0 {
                (a.process::<true>(&frag, &edges, &poly, &mut ca), b.process_plain::<true>(&frag, &edges, t, &mut cb))
            } else {
                // Written over a slot's old contents, as the VP's queue hands it; the
                // answer is whether anything is visible.
                let mut out = Visible { px: 7, py: 9, sets: [0xA5A5; 16], first: 5, covered: true };
                let any = a.process_to::<false>(&frag, &edges, &poly, &mut ca, &mut out);
                assert_eq!(any, out.any(), "case {k}: process_to's answer");
                (out, b.process_plain::<false>(&frag, &edges, t, &mut cb))
            };
            assert_eq!(got, want, "case {k}: mode {mode:?}, cell ({px}, {py}), box {bbox:?}, edges {edges:?}");
            assert_eq!(a.masks[cell], b.masks[cell], "case {k}");
            assert_eq!(ca, cb, "case {k}");
        }
    }

    /// [`SubpixelProcessors::box_hidden`] is its definition: every pixel of the box
    /// has all 16 subpixels set in the mask memory (for a small polygon with the
    /// AVX2 route; `false` otherwise), over random masks (mostly full pixels) and
    /// boxes of 1 to 20 pixels each way anywhere on the screen, at its ragged edges
    /// too.
    #[test]
    fn box_hidden_is_its_definition() {
        let mut next = xorshift(0x0B0C_5EED_4B1D_0001);
        let (w, h) = (61, 43);
        let mut a = SubpixelProcessors::new(w, h, SppMode::Area);
        let (mut hidden, mut shown) = (0, 0);
        for k in 0..40_000 {
            if k % 50 == 0 {
                let full = next(8) as u32;
                for m in &mut a.masks {
                    m.0 = std::array::from_fn(|_| if (next(8) as u32) <= full { FULL } else { next(1 << 16) as u16 });
                }
            }
            let (x0, y0) = (next(i64::from(w)) as u32, next(i64::from(h)) as u32);
            let (x1, y1) = ((x0 + 1 + next(20) as u32).min(w), (y0 + 1 + next(20) as u32).min(h));
            let bbox = [x0, x1, y0, y1];
            let poly = a.polygon(bbox, 0);
            let want = poly.route == Route::Avx2Small
                && (y0..y1).all(|y| {
                    (x0..x1).all(|x| {
                        a.masks[(y / CELL_SIDE) as usize * a.stride + (x / CELL_SIDE) as usize].0
                            [(4 * (y % CELL_SIDE) + x % CELL_SIDE) as usize]
                            == FULL
                    })
                });
            assert_eq!(a.box_hidden(&poly), want, "case {k}: box {bbox:?}");
            if want {
                hidden += 1;
            } else {
                shown += 1;
            }
        }
        assert!(!a.avx2 || (hidden > 1000 && shown > 1000), "{hidden} hidden, {shown} not");
        // Empty boxes (at the screen's corners too) are never hidden and do not panic,
        // every mask full.
        for m in &mut a.masks {
            m.0 = [FULL; 16];
        }
        for bbox in [[0, 0, 0, 0], [w, 0, h, 0], [5, 5, 3, 9], [5, 9, 3, 3], [w, w, h, h]] {
            let poly = a.polygon(bbox, 0);
            assert!(!a.box_hidden(&poly), "empty box {bbox:?}");
        }
    }

    /// [`word_bits`] (SSE2 on x86-64) is [`word_bits_portable`].
    #[test]
    fn word_bits_are_the_portable_ones() {
        let mut next = xorshift(0x0BE2_F1CE_5EED_0003);
        for k in 0..20_000 {
            let words: [u16; 16] = std::array::from_fn(|_| match next(4) {
                0 => 0,
                1 => FULL,
                _ => next(1 << 16) as u16,
            });
            let value = [0, FULL, words[0], 0x8000][k % 4];
            assert_eq!(word_bits(&words, value), word_bits_portable(&words, value), "case {k}");
        }
    }

    /// [`SubpixelProcessors::inside_to`] is [`SubpixelProcessors::process`] of a
    /// fragment with no active edge: the same visible sets, first writes, cover and
    /// mask memory, over random masks (empty, full, pre-masked pixels, anything),
    /// every transparency code, cells at the screen's ragged edges.
    #[test]
    fn inside_is_process_with_no_edge() {
        let mut next = xorshift(0x1357_9BDF_2468_ACE0);
        let (w, h) = (23, 14);
        let mut a = SubpixelProcessors::new(w, h, SppMode::Area);
        for k in 0..20_000 {
            let (cx, cy) = (next(6) as u32, next(4) as u32);
            let cell = cy as usize * a.stride + cx as usize;
            let mask: [u16; 16] = std::array::from_fn(|_| match next(5) {
                0 => 0,
                1 => FULL,
                _ => next(1 << 16) as u16,
            });
            a.masks[cell].0 = if k % 7 == 0 { [0; 16] } else { mask };
            let mut b = a.clone();
            let t = if k % 3 == 0 { 0 } else { next(64) as u8 };
            let frag = Fragment {
                px: 4 * cx,
                py: 4 * cy,
                active: &[],
                cells: super::super::gq::ONE_CELL,
                bbox: super::super::gq::NO_BOX,
            };
            let poly = a.polygon(super::super::gq::NO_BOX, t);
            let want = a.process::<false>(&frag, &[], &poly, &mut Counters::new(3));
            let mut got = Visible { px: 1, py: 2, sets: [0x5A5A; 16], first: 3, covered: true };
            let any = b.inside_to(4 * cx, 4 * cy, &poly, &mut got);
            assert_eq!(got, want, "case {k}");
            assert_eq!(any, want.any(), "case {k}");
            assert_eq!(b.masks[cell], a.masks[cell], "case {k}");
        }
    }

    #[test]
    fn transpose_words_swaps_rows_and_columns() {
        let mut next = xorshift(0xC0FF_EE00_D15E_A5E5);
        for _ in 0..1000 {
            let w: [u64; 4] = std::array::from_fn(|_| next(i64::MAX) as u64 ^ (next(i64::MAX) as u64) << 1);
            let t = transpose_words(w);
            for (i, &row) in w.iter().enumerate() {
                for (j, &column) in t.iter().enumerate() {
                    assert_eq!((column >> (16 * i)) as u16, (row >> (16 * j)) as u16);
                }
            }
            assert_eq!(transpose_words(t), w);
        }
    }

    #[test]
    fn round_q_rounds_half_up() {
        let px = |f: f64| (f * (1u64 << EDGE_FRAC_BITS) as f64) as i64;
        assert_eq!(round_q(px(0.0)), 0);
        assert_eq!(round_q(px(1.0 / 16.0)), 1);
        assert_eq!(round_q(px(1.0 / 16.0) - 1), 0);
        assert_eq!(round_q(px(-1.0 / 16.0)), 0);
        assert_eq!(round_q(px(1.0)), 8);
    }
}
