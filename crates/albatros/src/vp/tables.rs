//! The video processor's ROM tables: the cell processors' CI/CRI table (P1, eq. 1-2)
//! and the subpixel processors' subpixel-set table (P1, "the SPP table").
//!
//! Both are built here from their definitions, once, and exported by `albatros tables`
//! as `$readmemh` hex files a hardware designer can load.
//!
//! # GQ table ([`GqRom`], 256 x 8 bits)
//! Address (8 bits): `[7] TG (1 = vertical) | [6] LR | [5:4] b1 | [3:2] bm | [1:0] b2`,
//! where `b = clamp(floor((V - cell origin) / (cell side / 2)), -1, 2) + 1` are the
//! high bits of V1, (V1+V2)/2 and V2: the integer part of V in half-cell units,
//! saturated. For a vertical edge V1/V2 are taken on the cell's top/bottom border and
//! the origin is the cell's left border; for a horizontal edge on the left/right
//! border, origin the top.
//! Data (8 bits): `[7:4] CRI | [3:0] CI`, one bit per child: bit 0 top-left, 1
//! top-right, 2 bottom-left, 3 bottom-right.
//!
//! A child is IN for an edge when the whole (half-open) child lies on the polygon's
//! side of the line, OUT when it lies wholly on the other side (touching the child's
//! far border counts as outside), else crossed. These decisions are *sound* for the
//! subpixel table below: IN implies every pixel of the child gets all 16 subpixels for
//! this edge, OUT implies none. So whichever level decides, the image is the same.
//!
//! # SPP table ([`SppTable`], 2 x 2 x 25 x 25 x 16 bits)
//! Address: `((TG * 2 + LR) * 25 + q1 + 8) * 25 + q2 + 8`, with `q = round(8 (V -
//! pixel origin))` the edge's V at the pixel's two borders in eighths of a pixel (half
//! a subpixel), saturated to `-8..=16` (which never changes the answer since
//! `|q2 - q1| <= 8`).
//! Data: the 16-bit set of subpixels on the polygon's side, bit `4 sy + sx` for the
//! subpixel in column `sx`, row `sy` (row-major from the top-left).
//!
//! The line a table entry stands for passes through `q1/8` and `q2/8`. Two builds:
//! - [`SppMode::Area`] (the papers' choice, default): the set has `round(16 A)`
//!   subpixels (ties to even), `A` the exact area of the pixel on the polygon's side,
//!   chosen nearest-first by the signed distance of their centres from the line (ties by
//!   a 4x4 Bayer order, which spreads partial rows so that corners AND well);
//! - [`SppMode::Sample`]: the subpixels whose centres lie strictly on the polygon's
//!   side (point sampling), for comparison with a plain 4x4-sample reference.
//!
//! In both, LR = 1 is by construction the complement of LR = 0, so the two polygons
//! that share an edge split every pixel's subpixels exactly, and horizontal entries
//! are the transposes of vertical ones.

use std::sync::OnceLock;

use super::edge::Tg;

/// Subpixels per pixel side.
pub const SUBPIXEL_SIDE: usize = 4;
/// Subpixels per pixel.
pub const SUBPIXELS: u32 = 16;
/// The V precision at the SPP: eighths of a pixel, half a subpixel (P1).
pub const SPP_V_BITS: u32 = 3;
/// Smallest table index `q` (saturated below).
pub const SPP_Q_MIN: i32 = -8;
/// Largest table index `q` (saturated above).
pub const SPP_Q_MAX: i32 = 16;
/// Number of distinct `q`.
pub const SPP_Q_COUNT: usize = (SPP_Q_MAX - SPP_Q_MIN + 1) as usize;

/// A 4x4 Bayer ordered-dither matrix: the tie-break order of subpixels.
const BAYER4: [u8; 16] = [0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5];

/// Which SPP table to build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SppMode {
    /// Area-faithful sets (count = round(16 x area)).
    #[default]
    Area,
    /// Point sampling of the table's line at the 16 subpixel centres.
    Sample,
    /// Not a table: point sampling of the exact edge line at the 16 subpixel centres
    /// (integer edge functions). A modern choice beside the papers': watertight at
    /// shared vertices too, at the price of 4x4-grid area accuracy.
    Exact,
}

/// The GQ ROM: CI/CRI codes of the four children for one edge.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GqRom(pub [u8; 256]);

impl GqRom {
    /// The ROM, built once.
    pub fn get() -> &'static GqRom {
        static ROM: OnceLock<GqRom> = OnceLock::new();
        ROM.get_or_init(GqRom::build)
    }

    /// Builds the table from its definition (see the module docs).
    pub fn build() -> Self {
        let mut rom = [0u8; 256];
        for (addr, entry) in rom.iter_mut().enumerate() {
            let tg = if addr >> 7 & 1 == 1 { Tg::Vertical } else { Tg::Horizontal };
            let lr = addr >> 6 & 1 == 1;
            let b = [(addr >> 4 & 3) as i32 - 1, (addr >> 2 & 3) as i32 - 1, (addr & 3) as i32 - 1];
            let (mut ci, mut cri) = (0u8, 0u8);
            for child in 0..4i32 {
                let (col, row) = (child & 1, child >> 1);
                // The child's stretch of the line: (first border, middle) or (middle,
                // second border), and the child's position across V.
                let (along, across) = match tg {
                    Tg::Vertical => (row, col),
                    Tg::Horizontal => (col, row),
                };
                let (ba, bb) = if along == 0 { (b[0], b[1]) } else { (b[1], b[2]) };
                let (lo, hi) = (ba.min(bb), ba.max(bb));
                // The line lies wholly before the child (V < child's near border) or
                // wholly at/after its far border.
                let before = hi < across;
                let after = lo > across;
                // LR: the polygon is on the greater-V side.
                let (inside, outside) = if lr { (before, after) } else { (after, before) };
                if inside {
                    ci |= 1 << child;
                }
                if !outside {
                    cri |= 1 << child;
                }
            }
            *entry = cri << 4 | ci;
        }
        Self(rom)
    }

    /// The address for an edge with high bits `b1`, `bm`, `b2` (each already
    /// saturated to `-1..=2`).
    #[inline]
    pub fn address(tg: Tg, lr: bool, b1: i32, bm: i32, b2: i32) -> usize {
        (tg as usize) << 7
            | (lr as usize) << 6
            | ((b1 + 1) as usize) << 4
            | ((bm + 1) as usize) << 2
            | (b2 + 1) as usize
    }

    /// `(CI, CRI)` at `address`.
    #[inline]
    pub fn lookup(&self, address: usize) -> (u8, u8) {
        let e = self.0[address];
        (e & 0xF, e >> 4)
    }

    /// `$readmemh` text: one two-digit hex byte per line, address order.
    pub fn to_hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}\n")).collect()
    }
}

/// The SPP table: subpixel sets for one edge in one pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SppTable {
    /// Which build.
    pub mode: SppMode,
    /// Entries, see the module docs for the address layout.
    pub sets: Vec<u16>,
}

impl SppTable {
    /// The table for `mode`, built once.
    pub fn get(mode: SppMode) -> &'static SppTable {
        static AREA: OnceLock<SppTable> = OnceLock::new();
        static SAMPLE: OnceLock<SppTable> = OnceLock::new();
        match mode {
            SppMode::Area => AREA.get_or_init(|| SppTable::build(mode)),
            // The exact mode has no table; it shares the sample table's definition.
            SppMode::Sample | SppMode::Exact => SAMPLE.get_or_init(|| SppTable::build(SppMode::Sample)),
        }
    }

    /// The address of `(tg, lr, q1, q2)`; `q` saturated to `SPP_Q_MIN..=SPP_Q_MAX`.
    #[inline]
    pub fn address(tg: Tg, lr: bool, q1: i32, q2: i32) -> usize {
        let q1 = (q1.clamp(SPP_Q_MIN, SPP_Q_MAX) - SPP_Q_MIN) as usize;
        let q2 = (q2.clamp(SPP_Q_MIN, SPP_Q_MAX) - SPP_Q_MIN) as usize;
        (((tg as usize) * 2 + lr as usize) * SPP_Q_COUNT + q1) * SPP_Q_COUNT + q2
    }

    /// The subpixel set at an address.
    #[inline]
    pub fn lookup(&self, address: usize) -> u16 {
        self.sets[address]
    }

    /// The part of the table for one `(TG, LR)`: `SPP_Q_COUNT * SPP_Q_COUNT` sets.
    #[inline]
    pub fn half(&self, tg: Tg, lr: bool) -> &[u16; SPP_Q_COUNT * SPP_Q_COUNT] {
        let start = Self::address(tg, lr, SPP_Q_MIN, SPP_Q_MIN);
        self.sets[start..start + SPP_Q_COUNT * SPP_Q_COUNT].try_into().expect("the table has four parts")
    }

    /// The set for `(q1, q2)` in one part of the table ([`SppTable::half`]).
    #[inline]
    pub fn lookup_in(part: &[u16; SPP_Q_COUNT * SPP_Q_COUNT], q1: i32, q2: i32) -> u16 {
        let q1 = (q1.clamp(SPP_Q_MIN, SPP_Q_MAX) - SPP_Q_MIN) as usize;
        let q2 = (q2.clamp(SPP_Q_MIN, SPP_Q_MAX) - SPP_Q_MIN) as usize;
        part[q1 * SPP_Q_COUNT + q2]
    }

    /// Builds the table from its definition.
    pub fn build(mode: SppMode) -> Self {
        let n = SPP_Q_COUNT;
        let mut sets = vec![0u16; 4 * n * n];
        for q1 in SPP_Q_MIN..=SPP_Q_MAX {
            for q2 in SPP_Q_MIN..=SPP_Q_MAX {
                let v = vertical_greater_side(mode, q1, q2);
                let h = transpose(v);
                sets[Self::address(Tg::Vertical, true, q1, q2)] = v;
                sets[Self::address(Tg::Vertical, false, q1, q2)] = !v;
                sets[Self::address(Tg::Horizontal, true, q1, q2)] = h;
                sets[Self::address(Tg::Horizontal, false, q1, q2)] = !h;
            }
        }
        Self { mode, sets }
    }

    /// `$readmemh` text: one four-digit hex word per line, address order.
    pub fn to_hex(&self) -> String {
        self.sets.iter().map(|b| format!("{b:04x}\n")).collect()
    }
}

/// Smallest `q` of a pixel line relative to a cell's first pixel that the row table
/// tells apart: below it the cell's four pixels read the table's saturated entries.
pub const ROW_Q_MIN: i32 = SPP_Q_MIN;
/// Largest such `q`: the last pixel of the row is `8 * 3` eighths further on.
pub const ROW_Q_MAX: i32 = SPP_Q_MAX + (((SUBPIXEL_SIDE - 1) as i32) << SPP_V_BITS);
/// Number of distinct row `q`.
pub const ROW_Q_COUNT: usize = (ROW_Q_MAX - ROW_Q_MIN + 1) as usize;
/// Entries of one part of the row table.
pub const ROW_ENTRIES: usize = ROW_Q_COUNT * ROW_Q_COUNT;
/// Words of one part as stored: [`ROW_ENTRIES`] padded with zeros to a power of
/// two, so that an index masked to 12 bits needs no bounds check (the SPP's SIMD
/// indices; the padding is never read, and the words read stay where they were).
pub const ROW_PART_WORDS: usize = ROW_ENTRIES.next_power_of_two();

/// The SPP table read a row at a time: one edge's subpixel sets for the four pixels
/// of a cell's pixel line across its V lines, by one look-up instead of four.
///
/// A vertical edge's pixel `across` of a cell row reads the [`SppTable`] at `(q1 - 8
/// across, q2 - 8 across)`, with `q1`, `q2` its V on the row's two borders relative
/// to the cell's left border, in eighths of a pixel (likewise a horizontal edge's
/// pixels of a cell column). The four sets are therefore a function of `(q1, q2)`,
/// and of `(clamp(q1, -8, 40), clamp(q2, -8, 40))`: the table saturates each `q` to
/// `-8..=16`, and below -8 (above 40) every pixel's `q - 8 across` is below -8 (above
/// 16) whether or not `q` is clamped first.
///
/// Layout: two parts, `[TG]` (0 horizontal, 1 vertical), of [`ROW_ENTRIES`] words
/// (stored padded to [`ROW_PART_WORDS`]) at
/// `(q1 + 8) * 49 + (q2 + 8)` ([`Self::line`] of each `q`); word bits `[16 j + 15 ..
/// 16 j]` hold the set of pixel `across = j` for `LR = 1`. `LR = 0` is the complement
/// (the table's two halves are complements by construction), so the word XOR all
/// ones. Both `q` clamped alike rather than `q1` and `q2 - q1` (the earlier layout,
/// 57 x 17 words): a look-up is then one clamp per pixel line and a multiply-add,
/// and the words an edge reads (`|q2 - q1| <= 8`) still span about 9 KiB.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SppRowTable {
    /// Which build of the SPP table.
    pub mode: SppMode,
    /// An array rather than a `Vec`: the SPP's AVX2 step reads both parts for every
    /// fragment, and the `Vec`'s length check cost it some 4 instructions.
    parts: Box<[[u64; ROW_PART_WORDS]; 2]>,
}

impl SppRowTable {
    /// The row table of `mode`'s SPP table, built once.
    pub fn get(mode: SppMode) -> &'static SppRowTable {
        static AREA: OnceLock<SppRowTable> = OnceLock::new();
        static SAMPLE: OnceLock<SppRowTable> = OnceLock::new();
        match mode {
            SppMode::Area => AREA.get_or_init(|| SppRowTable::build(SppTable::get(mode))),
            SppMode::Sample | SppMode::Exact => {
                SAMPLE.get_or_init(|| SppRowTable::build(SppTable::get(SppMode::Sample)))
            }
        }
    }

    /// Builds the row table from the SPP table's `LR = 1` halves.
    pub fn build(table: &SppTable) -> Self {
        let parts = [Tg::Horizontal, Tg::Vertical]
            .iter()
            .map(|&tg| {
                let half = table.half(tg, true);
                debug_assert!(half.iter().zip(table.half(tg, false)).all(|(&t, &f)| t == !f));
                let mut part = [0u64; ROW_PART_WORDS];
                for q1 in ROW_Q_MIN..=ROW_Q_MAX {
                    for q2 in ROW_Q_MIN..=ROW_Q_MAX {
                        let mut word = 0u64;
                        for across in 0..SUBPIXEL_SIDE as i32 {
                            let shift = across << SPP_V_BITS;
                            let set = SppTable::lookup_in(half, q1 - shift, q2 - shift);
                            word |= u64::from(set) << (16 * across);
                        }
                        part[Self::index(q1, q2)] = word;
                    }
                }
                part
            })
            .collect::<Vec<_>>()
            .into_boxed_slice()
            .try_into()
            .expect("two parts");
        Self { mode: table.mode, parts }
    }

    /// The part of one TG (`LR = 1`).
    #[inline]
    pub fn part(&self, tg: Tg) -> &[u64; ROW_PART_WORDS] {
        &self.parts[tg as usize]
    }

    /// A pixel line's `q`, saturated, as a row or column number of a part
    /// (`0..ROW_Q_COUNT`).
    #[inline(always)]
    pub fn line(q: i32) -> usize {
        (q.clamp(ROW_Q_MIN, ROW_Q_MAX) - ROW_Q_MIN) as usize
    }

    /// The index of `(q1, q2)` in a part, whatever `q1` and `q2` are.
    #[inline(always)]
    pub fn index(q1: i32, q2: i32) -> usize {
        Self::line(q1) * ROW_Q_COUNT + Self::line(q2)
    }
}

/// Transposes a 4x4 subpixel set (swaps sx and sy).
pub fn transpose(set: u16) -> u16 {
    let mut out = 0u16;
    for sy in 0..SUBPIXEL_SIDE {
        for sx in 0..SUBPIXEL_SIDE {
            if set >> (sy * SUBPIXEL_SIDE + sx) & 1 == 1 {
                out |= 1 << (sx * SUBPIXEL_SIDE + sy);
            }
        }
    }
    out
}

/// The area of the unit pixel where `x > X(y)`, X the line through `(x1, 0)` and
/// `(x2, 1)`: the integral over y of the clamped `1 - X(y)`, exact (piecewise linear,
/// integrated over its breakpoints).
pub fn area_right_of(x1: f64, x2: f64) -> f64 {
    let f = |y: f64| (1.0 - (x1 + (x2 - x1) * y)).clamp(0.0, 1.0);
    // Breakpoints where X(y) crosses 0 or 1.
    let mut ys = vec![0.0, 1.0];
    if x2 != x1 {
        for target in [0.0, 1.0] {
            let y = (target - x1) / (x2 - x1);
            if y > 0.0 && y < 1.0 {
                ys.push(y);
            }
        }
    }
    ys.sort_by(f64::total_cmp);
    ys.windows(2).map(|w| (w[1] - w[0]) * (f(w[0]) + f(w[1])) * 0.5).sum()
}

/// The set for a vertical edge with the polygon on the right (greater x), through
/// `(q1/8, 0)` and `(q2/8, 1)` in pixel units.
fn vertical_greater_side(mode: SppMode, q1: i32, q2: i32) -> u16 {
    let scale = f64::from(1u32 << SPP_V_BITS);
    let (x1, x2) = (f64::from(q1) / scale, f64::from(q2) / scale);
    // Signed distance (scaled by the line's length) of subpixel centres, > 0 inside.
    let dist = |k: usize| {
        let sx = (k % SUBPIXEL_SIDE) as f64 + 0.5;
        let sy = (k / SUBPIXEL_SIDE) as f64 + 0.5;
        let (px, py) = (sx / SUBPIXEL_SIDE as f64, sy / SUBPIXEL_SIDE as f64);
        px - (x1 + (x2 - x1) * py)
    };
    match mode {
        SppMode::Sample | SppMode::Exact => (0..16).filter(|&k| dist(k) > 0.0).fold(0u16, |s, k| s | 1 << k),
        SppMode::Area => {
            let area = area_right_of(x1, x2);
            let count = round_half_even(area * f64::from(SUBPIXELS)) as usize;
            let mut order: Vec<usize> = (0..16).collect();
            order.sort_by(|&a, &b| dist(b).total_cmp(&dist(a)).then(BAYER4[a].cmp(&BAYER4[b])));
            order[..count].iter().fold(0u16, |s, &k| s | 1 << k)
        }
    }
}

fn round_half_even(v: f64) -> f64 {
    let r = v.round();
    if (v - v.trunc()).abs() == 0.5 && r % 2.0 != 0.0 {
        r - v.signum()
    } else {
        r
    }
}

/// The README written beside the hex files by `albatros tables`.
pub const TABLES_README: &str = "\
Albatros video processor ROM tables, $readmemh format (one hex word per line, address order).

gq_rom.hex     256 x 8 bits. The cell processors' (GQ) CI/CRI table.
               address = TG<<7 | LR<<6 | b1<<4 | bm<<2 | b2
                 TG = 1 vertical edge (V are X at the cell's top/bottom), 0 horizontal (V are Y at left/right)
                 LR = 1 the polygon lies on the side of greater V
                 b1, bm, b2 = clamp(floor((V - cell origin) / (side/2)), -1, 2) + 1 for V1, (V1+V2)/2, V2
               data = CRI<<4 | CI, one bit per child: 0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right
spp_area.hex   2500 x 16 bits. Subpixel processors' (SPP) table, area-faithful build (P1).
spp_sample.hex 2500 x 16 bits. The same, point-sample build.
               address = ((TG*2 + LR)*25 + q1+8)*25 + q2+8
                 q = round(8 * (V - pixel origin)), saturated to -8..16 (eighths of a pixel)
               data = subpixel set, bit 4*sy+sx for subpixel column sx, row sy from the pixel's top-left
tac_fog.hex    4098 x 32 bits. The texture address computers' (TAC, P2) fog ROM: f32 bit patterns.
               address k: exp(-k/256) for k < 4096, then 0 (f = exp(-Z/Z0) is read at 256 Z/Z0,
               interpolated linearly between k and k+1)
tac_log2.hex   257 x 32 bits. The TAC's log2 ROM for the level of detail: f32 bit patterns.
               address k: log2(1 + k/256), k = the top 8 mantissa bits of the f32 footprint;
               log2(x) = exponent + the entry, interpolated linearly with the next 15 bits
";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_of_simple_lines() {
        assert_eq!(area_right_of(0.0, 0.0), 1.0);
        assert_eq!(area_right_of(1.0, 1.0), 0.0);
        assert!((area_right_of(0.5, 0.5) - 0.5).abs() < 1e-12);
        assert!((area_right_of(0.0, 1.0) - 0.5).abs() < 1e-12);
        assert!((area_right_of(-1.0, 0.0) - 1.0).abs() < 1e-12);
        assert!((area_right_of(0.5, 1.5) - 0.125).abs() < 1e-12);
    }

    #[test]
    fn round_half_even_ties() {
        assert_eq!(round_half_even(2.5), 2.0);
        assert_eq!(round_half_even(3.5), 4.0);
        assert_eq!(round_half_even(3.4), 3.0);
        assert_eq!(round_half_even(13.5), 14.0);
    }

    /// Every row word is the four look-ups of its pixels, for both LR, far beyond
    /// the saturation on both sides and for any pair of `q` (not only those of a
    /// line no steeper than 45 degrees).
    #[test]
    fn row_table_is_four_lookups() {
        for mode in [SppMode::Area, SppMode::Sample] {
            let (table, rows) = (SppTable::get(mode), SppRowTable::get(mode));
            for tg in [Tg::Horizontal, Tg::Vertical] {
                for q1 in -90..=120 {
                    for q2 in -90..=120 {
                        let word = rows.part(tg)[SppRowTable::index(q1, q2)];
                        for (lr, flip) in [(true, 0), (false, u64::MAX)] {
                            let word = word ^ flip;
                            for across in 0..4 {
                                let shift = across << SPP_V_BITS;
                                let want = SppTable::lookup_in(table.half(tg, lr), q1 - shift, q2 - shift);
                                assert_eq!(
                                    (word >> (16 * across)) as u16,
                                    want,
                                    "{mode:?} {tg:?} lr {lr} q1 {q1} q2 {q2}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn transpose_is_an_involution() {
        for s in [0u16, 1, 0x8000, 0x1234, 0xFFFF, 0x00F0] {
            assert_eq!(transpose(transpose(s)), s);
        }
        assert_eq!(transpose(0x000F), 0x1111);
    }
}
