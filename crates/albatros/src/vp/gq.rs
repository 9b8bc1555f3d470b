//! Cell processors (GQ, P1 "клеточные процессоры"): the recursive split of the screen
//! into cells, one GQ per level, with a mask memory (MM) on every level.
//!
//! # Design rules of this hot module
//! - A cell of level `k` has side `4 * 2^(L-k)` pixels; level 0 is the root covering
//!   the screen, level `L` cells are 4 x 4 pixels and go to the SPPs.
//! - For each active (crossing) edge the GQ forms `(V1 + V2) / 2` by one addition and a
//!   shift, finds the edge's CI/CRI codes (those of the [`GqRom`](super::tables::GqRom) with the high bits
//!   of V1, (V1+V2)/2, V2, read by comparisons and a small table: `child_codes`), and
//!   combines them by P1 eq. (2): `CRI = !M & AND CRI_i`, `CI = !M & AND CI_i`, `CR = CRI & !CI`,
//!   `M |= CI`.
//! - Children's V1, V2 are the parent's V1 and the midpoint, or the midpoint and V2,
//!   less half a cell for the children further along V: no multiplication below the
//!   starting cell. Values are kept relative to the cell ([`ActiveEdge`]).
//! - Values are exact (see [`super::edge`]), so the decisions at a cell do not depend on
//!   where the descent started; decisions are sound for the SPP table, so the level at
//!   which an edge is decided, and whether a mask dropped a cell early, never changes
//!   which subpixels a polygon gets. **Masks change work, never the image.**
//! - With counting off, a cell beyond a polygon's sharp vertex, where its two edges'
//!   lines have crossed by a step of the SPP's rounding, is dropped although each
//!   edge alone crosses it ([`band_closed`]): its codes would all be empty.
//! - No allocation per polygon or per cell: active-edge lists live in per-level scratch
//!   vectors owned by the [`CellProcessors`]; one pass over a cell's edges fills its
//!   four children's lists, each edge written at the end of all four and the ends of
//!   those it crosses moved past it ([`write_children`]: no branch per child, which
//!   the predictors could not learn; session 16, timed on the wall, not counted).
//! - The cell's Z-order index goes down the descent (a child is `4 z + c`): the mask
//!   memories are read and written without interleaving bits per cell.
//! - The last-level cells go to a [`FragmentSink`]; the VP's loop implements it with a
//!   method the descent inlines, not a closure called per fragment.

use super::edge::{EdgeCode, EdgeCoord, Tg, EDGE_FRAC_BITS};
use super::spp::ends_near;
#[cfg(test)]
use super::tables::GqRom;
use super::tables::SPP_V_BITS;
use crate::model::stats::Counters;

/// An edge active in a cell: which edge of the polygon, its TG and LR, and its V at
/// the cell's first and second border (top/bottom for a vertical edge, left/right for
/// a horizontal), relative to the cell's first border across V (its left border for
/// a vertical edge, its top for a horizontal one): the GQ's comparisons then need no
/// cell origin, and a child's values are its parent's less half a cell or not.
///
/// In C layout, V1 and V2 first (one SSE2 register), the index and kind after them
/// (one word): [`write_children`] writes a child's copy as those two stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct ActiveEdge {
    /// V1: V at the cell's first border, relative to the cell.
    pub v1: EdgeCoord,
    /// V2: V at the cell's second border, relative to the cell.
    pub v2: EdgeCoord,
    /// Index into the polygon's edge list.
    pub edge: u32,
    /// TG and LR as the high bits of an address of [`CHILD_CODES`]: bit
    /// [`KIND_VERTICAL`] for TG = [`Tg::Vertical`], bit [`KIND_LR`] for LR (the polygon
    /// lies on the side of greater V), bit [`KIND_DOWN`] for `V1 > V2`. One word, so that a child's copy moves the
    /// edge's index and kind together.
    kind: u32,
}

// The layout [`write_children`]'s stores rest on.
const _: () = assert!(std::mem::offset_of!(ActiveEdge, v1) == 0);
const _: () = assert!(std::mem::offset_of!(ActiveEdge, v2) == 8);
const _: () = assert!(std::mem::offset_of!(ActiveEdge, edge) == 16);
const _: () = assert!(std::mem::offset_of!(ActiveEdge, kind) == 20);
const _: () = assert!(std::mem::size_of::<ActiveEdge>() == 24);

/// [`ActiveEdge`]'s kind bit for TG = [`Tg::Vertical`].
const KIND_VERTICAL: u32 = 1 << 8;
/// [`ActiveEdge`]'s kind bit for LR.
const KIND_LR: u32 = 1 << 9;
/// [`ActiveEdge`]'s kind bit for V decreasing along the edge's direction of travel
/// (`V1 > V2`). The sign of `V2 - V1` is the slope's, in every cell of the descent (a
/// child's V1 and V2 are its parent's V1 and midpoint, or midpoint and V2, less the
/// same amount; the midpoint lies between them), so it is found once, at the
/// starting cell, and [`child_codes`] need not order V1, the midpoint and V2 (when
/// they are equal, either order serves).
const KIND_DOWN: u32 = 1 << 10;

impl ActiveEdge {
    /// An entry of the scratch lists before it is written.
    const EMPTY: Self = Self { edge: 0, kind: 0, v1: EdgeCoord(0), v2: EdgeCoord(0) };

    /// Edge `edge` (`e` itself) in the cell of side `side` pixels at pixel `(x0, y0)`.
    #[inline]
    pub fn at_cell(edge: u32, e: &EdgeCode, x0: i64, y0: i64, side: i64) -> Self {
        let (t0, origin) = match e.tg() {
            Tg::Vertical => (y0, x0),
            Tg::Horizontal => (x0, y0),
        };
        let origin = EdgeCoord::pixels(origin).0;
        let (v1, v2) = (e.v_at(t0).0 - origin, e.v_at(t0 + side).0 - origin);
        Self {
            edge,
            kind: if e.tg() == Tg::Vertical { KIND_VERTICAL } else { 0 }
                | if e.lr() { KIND_LR } else { 0 }
                | if v1 > v2 { KIND_DOWN } else { 0 },
            v1: EdgeCoord(v1),
            v2: EdgeCoord(v2),
        }
    }

    /// Whether the edge's TG is [`Tg::Vertical`].
    #[inline]
    pub fn vertical(&self) -> bool {
        self.kind & KIND_VERTICAL != 0
    }

    /// The edge's LR: the polygon lies on the side of greater V.
    #[inline]
    pub fn lr(&self) -> bool {
        self.kind & KIND_LR != 0
    }
}

/// Which levels' mask memories are in use: bit `k` for level `k` (levels `1..=L`).
///
/// P1 fig. 4 compares four modes, named here relative to the root level `L` (P1 has
/// `L = 7`): I only level L, II levels L-1..L, III levels L-2..L, IV levels 1..L.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MaskLevels(pub u32);

impl MaskLevels {
    /// No GQ mask memory (only the subpixel mask memory, which is always on).
    pub const NONE: Self = Self(0);
    /// Every level 1..=MAX.
    pub const ALL: Self = Self(!1);

    /// P1's mode I: only the last level.
    pub fn mode_i(root_level: u32) -> Self {
        Self::range(root_level, root_level)
    }
    /// P1's mode II: the last two levels.
    pub fn mode_ii(root_level: u32) -> Self {
        Self::range(root_level.saturating_sub(1).max(1), root_level)
    }
    /// P1's mode III: the last three levels.
    pub fn mode_iii(root_level: u32) -> Self {
        Self::range(root_level.saturating_sub(2).max(1), root_level)
    }
    /// P1's mode IV: levels 1 to L.
    pub fn mode_iv(root_level: u32) -> Self {
        Self::range(1, root_level)
    }
    /// Levels `lo..=hi` (level 0, the root, has no mask).
    pub fn range(lo: u32, hi: u32) -> Self {
        let mut bits = 0u32;
        for k in lo.max(1)..=hi.min(31) {
            bits |= 1 << k;
        }
        Self(bits)
    }
    /// Whether level `k` masks.
    #[inline]
    pub fn has(self, k: u32) -> bool {
        k < 32 && self.0 >> k & 1 == 1
    }
}

/// One level's mask memory: a bit per cell, "wholly covered by polygons already drawn".
///
/// Bit layout: the cells of level `k` form a `2^k x 2^k` square (the root cell's
/// children, grandchildren, ...), stored in Z order (Morton order): cell `(x, y)` is
/// bit `z(x, y)` of the `u64` words, `z` interleaving the bits of `x` (even bit
/// positions) and `y` (odd ones) ([`morton`]). The four children of a cell `z` are
/// then bits `4 z .. 4 z + 3` of the next level, child `c = dx + 2 dy` at `4 z + c`:
/// one nibble, never split across words, read and written at once (P1's GQ reads the
/// four children's mask bits together), and a cell's parent is `z >> 2`.
///
/// Cells of the square wholly off the screen are set when the memory is cleared, so
/// they always read as covered (pre-masked), and so are the cells that hold no pixel
/// of the VP's share of a matrix ([`Share`], [`MaskMemory::pre_mask`]).
#[derive(Clone, Debug, Default)]
pub struct MaskMemory {
    /// Cells per row that touch the screen.
    pub stride: usize,
    /// Rows of cells that touch the screen.
    pub rows: usize,
    bits: Vec<u64>,
    /// The words as a frame starts: the pre-masked cells set.
    cleared: Vec<u64>,
    /// The words with only the cells off the screen set.
    off_screen: Vec<u64>,
}

/// The Z-order (Morton) index of cell `(x, y)`: the bits of `x` at the even
/// positions, those of `y` at the odd ones (`x, y < 2^16`). A byte at a time from
/// [`SPREAD_BYTE`] (~16 instructions rather than ~30 by shifts and masks: the VP
/// loop finds the Z-order index of each last-level cell a polygon covers wholly).
#[inline]
pub fn morton(x: u32, y: u32) -> usize {
    /// The 16 low bits of `v` spread to the even bit positions.
    #[inline(always)]
    fn spread(v: u32) -> u64 {
        u64::from(SPREAD_BYTE[(v & 0xFF) as usize]) | u64::from(SPREAD_BYTE[(v >> 8 & 0xFF) as usize]) << 16
    }
    (spread(x) | spread(y) << 1) as usize
}

/// [`morton`] by its definition, bit by bit (for [`SPREAD_BYTE`] and tests).
const fn morton_plain(x: u32, y: u32) -> usize {
    let mut z = 0;
    let mut i = 0;
    while i < 16 {
        z |= ((x as usize >> i) & 1) << (2 * i) | ((y as usize >> i) & 1) << (2 * i + 1);
        i += 1;
    }
    z
}

/// The bits of a byte spread to the even bit positions of 16: [`morton`]'s table.
const SPREAD_BYTE: [u16; 256] = {
    let mut table = [0u16; 256];
    let mut v = 0;
    while v < 256 {
        table[v] = morton_plain(v as u32, 0) as u16;
        v += 1;
    }
    table
};

impl MaskMemory {
    /// The memory of level `level` (a `2^level` square of cells) for a screen of
    /// `stride x rows` cells: every cell off the screen pre-masked.
    fn new(level: u32, stride: usize, rows: usize) -> Self {
        let side = 1usize << level;
        let words = (side * side).div_ceil(64);
        let mut m = Self { stride, rows, bits: vec![0; words], cleared: Vec::new(), off_screen: Vec::new() };
        for cy in 0..side {
            for cx in 0..side {
                if cx >= stride || cy >= rows {
                    m.set(cx, cy);
                }
            }
        }
        m.cleared = m.bits.clone();
        m.off_screen = m.bits.clone();
        m
    }

    /// Whether cell `(cx, cy)` (inside the level's square) is covered; cells wholly
    /// off the screen are.
    #[inline]
    pub fn get(&self, cx: usize, cy: usize) -> bool {
        self.get_z(morton(cx as u32, cy as u32))
    }

    /// Whether the cell of Z-order index `z` is covered.
    #[inline]
    fn get_z(&self, z: usize) -> bool {
        self.bits[z >> 6] >> (z & 63) & 1 == 1
    }

    #[inline]
    fn set(&mut self, cx: usize, cy: usize) {
        self.set_z(morton(cx as u32, cy as u32));
    }

    #[inline]
    fn set_z(&mut self, z: usize) {
        self.bits[z >> 6] |= 1 << (z & 63);
    }

    /// Whether the cells `(cx & !7) + i` of row `cy`, `i` in `0..8`, are covered: bit
    /// `i`. The 8 x 8 cells of an aligned block are one word in Z order (cell `(i, j)`
    /// of the block at bit `morton(i, j)`), so a row of the block is the bits at
    /// `morton(i, 0) = 0, 1, 4, 5, 16, 17, 20, 21` above `morton(0, j)`, gathered by
    /// four shifts. (Levels of fewer than 64 cells have one word, the cells beyond the
    /// square reading 0.)
    #[inline]
    pub fn block_row(&self, cx: usize, cy: usize) -> u8 {
        let word = self.bits[morton((cx >> 3) as u32, (cy >> 3) as u32)];
        let t = word >> morton(0, (cy & 7) as u32);
        (t & 0x3 | t >> 2 & 0xC | t >> 12 & 0x30 | t >> 14 & 0xC0) as u8
    }

    /// The mask bits of the aligned 8 x 8 block of cells of Z-order index `bz` (its
    /// cells' Z-order indices `bz << 6 | p`, at bit `p`). (Levels of fewer than 64
    /// cells have one word, `bz` 0, the cells beyond the square reading 0.)
    #[inline]
    fn word(&self, bz: usize) -> u64 {
        self.bits[bz]
    }

    /// The mask bits of the four children of the parent cell `z` (of the level
    /// above), child `c` at bit `c`.
    #[inline]
    fn children(&self, z: usize) -> u8 {
        let first = 4 * z;
        (self.bits[first >> 6] >> (first & 63)) as u8 & 0xF
    }

    /// Sets the children `nibble` (bit `c` for child `c`) of the parent cell `z`.
    #[inline]
    fn set_children(&mut self, z: usize, nibble: u8) {
        let first = 4 * z;
        self.bits[first >> 6] |= u64::from(nibble & 0xF) << (first & 63);
    }

    /// Sets every cell of the square that holds no pixel of a share: cell `(cx, cy)`
    /// when `!columns(cx) || !rows(cy)` (a share is a product of columns and rows,
    /// [`Share::owns_pixel`]). An aligned 8 x 8 block at a time: its word is the or of
    /// its unheld columns' cells and its unheld rows' ([`Z_COLUMNS`], [`Z_ROWS`]), the
    /// columns' words found once per block column (in `scratch`, kept from call to
    /// call). (A level of fewer than 64 cells, one word, cell by cell: the bits
    /// beyond its square must read 0.)
    fn pre_mask(
        &mut self,
        level: u32,
        columns: impl Fn(u32) -> bool,
        rows: impl Fn(u32) -> bool,
        scratch: &mut Vec<u64>,
    ) {
        let side = 1u32 << level;
        if side < BLOCK_SIDE {
            for cy in 0..side {
                for cx in 0..side {
                    if !columns(cx) || !rows(cy) {
                        self.set(cx as usize, cy as usize);
                    }
                }
            }
            return;
        }
        // The cells of the block's unheld lines (`line` of the 8 in it), as a word.
        let unheld = |held: &dyn Fn(u32) -> bool, first: u32, lines: &[u64; 64]| {
            (0..BLOCK_SIDE).filter(|&i| !held(first + i)).fold(0, |w, i| w | lines[(i | i << 3) as usize])
        };
        let blocks = side / BLOCK_SIDE;
        scratch.clear();
        scratch.extend((0..blocks).map(|bx| unheld(&columns, bx * BLOCK_SIDE, &Z_COLUMNS)));
        for by in 0..blocks {
            let row_word = unheld(&rows, by * BLOCK_SIDE, &Z_ROWS);
            for (bx, &column_word) in (0..blocks).zip(scratch.iter()) {
                self.bits[morton(bx, by)] |= column_word | row_word;
            }
        }
    }

    /// Back to the state a frame starts from.
    fn clear(&mut self) {
        self.bits.copy_from_slice(&self.cleared);
    }

    /// Makes the present bits the state a frame starts from.
    fn keep_as_cleared(&mut self) {
        self.cleared.copy_from_slice(&self.bits);
    }

    /// Forgets every pre-mask but the off-screen cells': the state after [`Self::new`]
    /// (copied, not made again: a strip matrix's shares change from frame to frame).
    fn reset_cleared(&mut self) {
        self.bits.copy_from_slice(&self.off_screen);
        self.cleared.copy_from_slice(&self.off_screen);
    }
}

/// The share of the screen one VP of a `p x q` matrix renders (P3): the square tiles
/// of `tile` pixels (a power of two) at tile column `tx` and row `ty` with
/// `tx % p == i` and `ty % q == j`. `tile = 1` is P3's interleave by single pixels
/// (every VP works on the whole screen, on a sparse raster); `tile = 4 * 2^m` is an
/// interleave by whole cells of level `L - m`. Everything outside the share is
/// pre-masked, like the area off the screen: a cell that holds no pixel of the share
/// reads as covered on every level, so a VP never spends a cell on it (with tiles
/// under a cell, the SPPs keep to the share: [`super::spp`]).
///
/// A share may also be cut to a strip of pixel columns `strip.0 .. strip.1`
/// (multiples of the tile side): a matrix of VPs side by side in vertical strips,
/// each a contiguous part of the screen, whose widths [`crate::matrix::Matrix`]
/// moves from frame to frame to even out the VPs' work (a modern choice beside P3's
/// fixed interleave: see ARCHITECTURE.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Share {
    /// Tile side in pixels (a power of two).
    pub tile: u32,
    /// Matrix columns.
    pub p: u32,
    /// Matrix rows.
    pub q: u32,
    /// This VP's column.
    pub i: u32,
    /// This VP's row.
    pub j: u32,
    /// The pixel columns `strip.0 .. strip.1` the share is cut to
    /// ([`Share::ALL_COLUMNS`]: not cut).
    pub strip: (u32, u32),
}

impl Share {
    /// The whole screen (a 1 x 1 matrix).
    pub const WHOLE: Share = Share { tile: 4, p: 1, q: 1, i: 0, j: 0, strip: Self::ALL_COLUMNS };
    /// [`Share::strip`] of a share not cut to a strip.
    pub const ALL_COLUMNS: (u32, u32) = (0, u32::MAX);

    /// VP `(i, j)` of a `p x q` matrix interleaved by tiles of `tile` pixels (P3).
    pub fn interleaved(tile: u32, p: u32, q: u32, i: u32, j: u32) -> Self {
        Share { tile, p, q, i, j, strip: Self::ALL_COLUMNS }
    }

    /// The strip of pixel columns `x0 .. x1` (multiples of `tile`, a power of two of
    /// at least a cell) of a matrix of VPs side by side in strips.
    pub fn strip(tile: u32, x0: u32, x1: u32) -> Self {
        Share { tile, p: 1, q: 1, i: 0, j: 0, strip: (x0, x1) }
    }

    /// Whether the share is the whole screen (nothing pre-masked but the area off
    /// the screen).
    pub fn is_whole(&self) -> bool {
        self.p * self.q == 1 && self.strip == Self::ALL_COLUMNS
    }

    /// Whether pixel `(x, y)` is this VP's: its column's and its row's
    /// ([`Self::owns_column`], [`Self::owns_row`]; a share is a product of the two).
    #[inline]
    pub fn owns_pixel(&self, x: u32, y: u32) -> bool {
        self.owns_column(x) && self.owns_row(y)
    }

    /// Whether the share holds pixels of column `x`: its tile column is the VP's
    /// and it lies in the strip.
    #[inline]
    pub fn owns_column(&self, x: u32) -> bool {
        (x / self.tile) % self.p == self.i && x >= self.strip.0 && x < self.strip.1
    }

    /// Whether the share holds pixels of row `y`: its tile row is the VP's.
    #[inline]
    pub fn owns_row(&self, y: u32) -> bool {
        (y / self.tile) % self.q == self.j
    }

    /// Whether the share's strip holds any pixel of columns `x0 .. x1`.
    #[inline]
    pub fn meets_columns(&self, x0: u32, x1: u32) -> bool {
        x0 < self.strip.1 && x1 > self.strip.0
    }

    /// Whether the share holds pixels of any of columns `x0 .. x1`
    /// ([`Self::owns_column`] of one of them): the columns in the strip span tile
    /// columns `t0 ..= t1`, and one of those is the VP's when the first of the VP's
    /// from `t0` on, `(i - t0) mod p` further, is no further than `t1`.
    pub fn holds_columns(&self, x0: u32, x1: u32) -> bool {
        let (x0, x1) = (x0.max(self.strip.0), x1.min(self.strip.1));
        x0 < x1 && Self::holds_tiles(x0 / self.tile, (x1 - 1) / self.tile, self.p, self.i)
    }

    /// Whether the share holds pixels of any of rows `y0 .. y1` ([`Self::owns_row`]
    /// of one of them), as [`Self::holds_columns`] (rows are not cut).
    pub fn holds_rows(&self, y0: u32, y1: u32) -> bool {
        y0 < y1 && Self::holds_tiles(y0 / self.tile, (y1 - 1) / self.tile, self.q, self.j)
    }

    /// Whether one of tile lines `t0 ..= t1` is `k`'s of `n` interleaved.
    fn holds_tiles(t0: u32, t1: u32, n: u32, k: u32) -> bool {
        (k + n - t0 % n) % n <= t1 - t0
    }
}

/// A cell: level and position (cell indices at that level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cell {
    /// Level, 0 = root.
    pub level: u32,
    /// Column at that level.
    pub x: u32,
    /// Row at that level.
    pub y: u32,
}

/// What a GQ decided about a cell, as recorded for pictures (see
/// [`CellProcessors::recorder`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CellKind {
    /// Wholly inside the polygon (IN): marked in the mask, still descended.
    Inside,
    /// Crossed by an edge (CR): descended with the edges that cross it.
    Crossed,
    /// Wholly outside the polygon (OUT): dropped.
    Outside,
    /// Inside or crossed, but the level's mask memory said "covered": dropped.
    Masked,
    /// The polygon's starting (bounding) cell lay in a covered cell: the whole polygon
    /// was dropped there.
    PolygonMasked,
    /// The polygon's starting (bounding) cell, where its descent begins (recorded
    /// before the cells of that descent).
    Start,
}

/// One recorded GQ decision: the cell and what was decided.
pub type CellRecord = (Cell, CellKind);

/// The GQ pipeline: one cell processor and one mask memory per level.
#[derive(Clone, Debug)]
pub struct CellProcessors {
    /// Root level `L`: the root's side is `4 * 2^L` pixels.
    pub root_level: u32,
    /// Screen size.
    pub width: u32,
    /// Screen size.
    pub height: u32,
    /// Levels whose mask memory is in use.
    pub masks: MaskLevels,
    /// The part of the screen this VP renders.
    pub share: Share,
    /// Greene's hierarchical coverage ([`CellProcessors::mark_covered`]).
    pub hierarchical: bool,
    /// When `Some`, every cell the GQs test during a descent *with counting on*
    /// (`STATS`) is appended, in processing order, with its [`CellKind`]; polygons
    /// dropped whole add their starting cell. For the `render --cells` picture.
    /// Recording lives in the counting instantiation only, so with counting off it is
    /// compiled out; with counting on and `None` it costs one branch per split cell.
    pub recorder: Option<Vec<CellRecord>>,
    memories: Vec<MaskMemory>,
    /// The share the memories' cleared states were made for.
    cleared_share: Share,
    /// [`MaskMemory::pre_mask`]'s words of block columns (scratch).
    pre_mask_columns: Vec<u64>,
    /// Active-edge lists, four per level, each `stride` entries long, all in one
    /// vector: level `k`'s block of four at `4 k stride`, child `c`'s list at `c stride`
    /// in it. A cell's children's lists are on the level below, filled in one pass
    /// over the cell's edges, written by index; the starting cell's list is the first
    /// of its level. A cell has at most as many active edges
    /// as its polygon, so `stride` only grows with a polygon of more edges than any
    /// before (the GP's clipper bounds none).
    lists: Vec<ActiveEdge>,
    /// [`Self::start_at_size`]'s edges of the start's first cell, set up for
    /// [`derive_start_list`] (scratch, `stride` entries).
    start_edges: Vec<StartEdge>,
    /// Entries per list (see `lists`).
    stride: usize,
    /// Per level, the cells an opaque polygon covers wholly inside, queued by
    /// [`Self::descend_filling`] under Greene's rule for [`Self::mark_covered_cells`]
    /// (Z-order indices).
    inside: Vec<Vec<usize>>,
    /// Bit `k`: `inside[k]` is not empty.
    queued: u32,
    /// Whether [`Self::descend_filling`] finds a small polygon's last-level cells at
    /// once ([`Self::last_cells`]); off, it splits level by level (for tests).
    at_once: bool,
    /// Whether [`Self::descend_filling`] passes over a polygon whose box its sink
    /// finds hidden ([`FragmentSink::box_hidden`]); off for the VP's tests.
    pub(super) hidden_boxes: bool,
}

/// A level-L cell handed to the SPPs, with the edges that cross it; or, from
/// [`CellProcessors::descend_filling`] only, up to four level-L cells wholly inside
/// the polygon, siblings in a cell of level L - 1 (`cells`).
pub struct Fragment<'a> {
    /// Left pixel of the 4x4 cell (of the 8x8 parent when `cells` is not [`ONE_CELL`]).
    pub px: u32,
    /// Top pixel.
    pub py: u32,
    /// Edges crossing the cell, with V at its borders relative to the cell's left
    /// pixel column (vertical edges) or top pixel row (horizontal ones).
    pub active: &'a [ActiveEdge],
    /// The cells: bit `c = dx + 2 dy` for the cell at pixel `(px + 4 dx, py + 4 dy)`.
    /// [`ONE_CELL`] (the cell at `(px, py)`) for every fragment with active edges and
    /// every fragment of [`CellProcessors::descend`]; a fragment of several cells
    /// (siblings wholly inside, no active edge) saves the sink a call per cell.
    pub cells: u8,
    /// The polygon's box, `[x0, x1) x [y0, y1)` in pixels ([`GqPolygon::bbox`]): the
    /// SPPs clip the code to it ([`super::spp::box_pixels`]).
    pub bbox: [u32; 4],
}

impl Fragment<'_> {
    /// The fragment of last-level child `c` (`dx + 2 dy`) of cell `cell` of level
    /// L - 1, wholly inside its polygon of box `bbox`: no edge, in the descent's order
    /// (the split's and [`LastCells`]' one cell at a time).
    #[inline(always)]
    fn inside_child(cell: Cell, c: u32, bbox: [u32; 4]) -> Self {
        Fragment { px: cell.x * 8, py: cell.y * 8, active: &[], cells: 1 << c, bbox }
    }
}

/// A [`Fragment::bbox`] that clips nothing: for fragments with no edge (cells wholly
/// inside their polygon, so inside its box) and for tests.
pub const NO_BOX: [u32; 4] = [0, u32::MAX, 0, u32::MAX];

/// [`Fragment::cells`] of a fragment of the one cell at its `(px, py)`.
pub const ONE_CELL: u8 = 1;

/// Where a descent hands its fragments ([`CellProcessors::descend_to`],
/// [`CellProcessors::descend_filling_to`]). The VP's loop implements it with an
/// `#[inline(always)]` method, so that the descent's splits take in its work per
/// fragment rather than calling a closure (~20 instructions of the call's saved
/// registers and the fragment's copy on the stack each, in two of every three
/// last-level cells on `default`); [`CellProcessors::descend`] and
/// [`CellProcessors::descend_filling`] take any `FnMut(Fragment)`.
pub trait FragmentSink {
    /// One fragment of the polygon being descended.
    fn fragment(&mut self, frag: Fragment<'_>);

    /// Whether no fragment of the polygon can have a visible subpixel: every pixel
    /// of its box is covered already (the VP's sink asks the SPPs' mask memory,
    /// [`super::spp::SubpixelProcessors::box_hidden`]). Asked once a polygon by the
    /// filling descent ([`CellProcessors::descend_filling`]), which then passes the
    /// polygon over. `false` unless the sink knows better.
    #[inline(always)]
    fn box_hidden(&mut self) -> bool {
        false
    }
}

/// A closure as a [`FragmentSink`].
struct EachFragment<F>(F);

impl<F: FnMut(Fragment<'_>)> FragmentSink for EachFragment<F> {
    #[inline]
    fn fragment(&mut self, frag: Fragment<'_>) {
        (self.0)(frag);
    }
}

/// The polygon the GQs are working on.
pub struct GqPolygon<'a> {
    /// Its edges.
    pub edges: &'a [EdgeCode],
    /// Whether it is opaque (only opaque polygons mark mask memories).
    pub opaque: bool,
    /// Bounding box in pixels, `[x0, x1) x [y0, y1)`, inside the screen.
    pub bbox: [u32; 4],
}

impl CellProcessors {
    /// The root level for a screen: the smallest `L` with `4 * 2^L >= max(w, h)`.
    pub fn root_level_for(width: u32, height: u32) -> u32 {
        let side = width.max(height).max(4);
        let mut l = 0;
        while (4u32 << l) < side {
            l += 1;
        }
        l
    }

    /// GQs for a screen, with the given mask levels.
    pub fn new(width: u32, height: u32, masks: MaskLevels) -> Self {
        let root_level = Self::root_level_for(width, height);
        let memories = (0..=root_level)
            .map(|k| {
                let side = 4u32 << (root_level - k);
                MaskMemory::new(k, width.div_ceil(side) as usize, height.div_ceil(side) as usize)
            })
            .collect();
        Self {
            root_level,
            width,
            height,
            masks,
            share: Share::WHOLE,
            hierarchical: false,
            recorder: None,
            memories,
            cleared_share: Share::WHOLE,
            pre_mask_columns: Vec::new(),
            lists: Vec::new(),
            start_edges: Vec::new(),
            stride: 0,
            inside: vec![Vec::new(); root_level as usize + 1],
            queued: 0,
            at_once: true,
            hidden_boxes: true,
        }
    }

    /// Clears every mask memory for a new frame: the cells off the screen, and those
    /// of other VPs of a matrix at the share's tile level, are pre-masked.
    pub fn clear(&mut self) {
        if self.cleared_share != self.share {
            self.pre_mask_share();
        }
        for m in &mut self.memories {
            m.clear();
        }
    }

    /// Makes the memories' cleared states for `self.share`: on every level, each
    /// cell that holds no pixel of the share is set, as the cells off the screen are.
    /// A cell wholly outside has its descendants wholly outside, so the marks stay
    /// closed downward ([`Self::covered`] reads one level), and a start cell or a
    /// child outside the share is dropped where the descent meets it, not split down
    /// to the tile level. (Tiles under a cell, P3's pixel interleave: every cell holds
    /// pixels of the share, nothing is set; the SPPs keep to it.) A strip matrix's
    /// shares change from frame to frame: a block of cells at a time,
    /// [`MaskMemory::pre_mask`].
    fn pre_mask_share(&mut self) {
        for m in &mut self.memories {
            m.reset_cleared();
        }
        let share = self.share;
        if !share.is_whole() && share.tile >= CELL_SIDE {
            for level in 0..=self.root_level {
                let side = self.side(level);
                let m = &mut self.memories[level as usize];
                let columns = |cx: u32| share.holds_columns(cx * side, (cx + 1) * side);
                let rows = |cy: u32| share.holds_rows(cy * side, (cy + 1) * side);
                m.pre_mask(level, columns, rows, &mut self.pre_mask_columns);
                m.keep_as_cleared();
            }
        }
        self.cleared_share = share;
    }

    /// Greene's hierarchical coverage: the last-level cell `(cx, cy)` is now wholly
    /// covered (all its subpixels): mark it, and every ancestor whose four children
    /// are then all marked, as far up as the levels in use reach. Sound: a covered
    /// cell hides everything behind it, so dropping it early changes no subpixel.
    pub fn mark_covered(&mut self, cx: u32, cy: u32) {
        let mut z = morton(cx, cy);
        let mut k = self.root_level;
        while k >= 1 && self.masks.has(k) {
            let m = &mut self.memories[k as usize];
            m.set_z(z);
            // The four siblings are the nibble of the parent `z >> 2`.
            if m.children(z >> 2) != 0xF {
                break;
            }
            z >>= 2;
            k -= 1;
        }
    }

    /// [`Self::mark_covered`] of many last-level cells at once, given by their
    /// Z-order indices ([`morton`]; `cells` is used as scratch and left empty): level
    /// by level, all the cells of a level marked, then each parent checked once. The
    /// same marks as marking the cells one by one, in any order: a parent is marked
    /// when its four children are, and whichever child came last saw them all. It
    /// saves the walks up: a polygon covering a large area marks its cells IN on every
    /// level as it descends (P1's rule), so a walk from each of its last-level cells
    /// would climb through those marks again and again (7 levels on average on
    /// `rombm`, against 1.33 parents per cell here). Cells in ascending Z order (the
    /// descent's own order) have their parents' repeats side by side, checked once.
    ///
    /// The cells [`Self::descend_filling`] queued on their own levels join the cells
    /// climbing through those levels (their subtrees are marked already).
    #[inline]
    pub fn mark_covered_cells(&mut self, cells: &mut Vec<usize>) {
        // Most polygons cover no cell wholly (all of `many`'s but a few): no call.
        if !cells.is_empty() || self.queued != 0 {
            self.mark_queued_cells(cells);
        }
    }

    /// [`Self::mark_covered_cells`]' work, out of line.
    #[inline(never)]
    fn mark_queued_cells(&mut self, cells: &mut Vec<usize>) {
        let mut k = self.root_level;
        // Levels `k` and above with queued cells: `queued & below(k)`.
        let below = |k: u32| (2u32 << k).wrapping_sub(1);
        while k >= 1 && self.masks.has(k) && (!cells.is_empty() || self.queued & below(k) != 0) {
            cells.append(&mut self.inside[k as usize]);
            if cells.is_empty() {
                k -= 1;
                continue;
            }
            let m = &mut self.memories[k as usize];
            for &z in cells.iter() {
                m.set_z(z);
            }
            let (mut kept, mut last) = (0, usize::MAX);
            for i in 0..cells.len() {
                let parent = cells[i] >> 2;
                if parent != last && m.children(parent) == 0xF {
                    cells[kept] = parent;
                    kept += 1;
                }
                last = parent;
            }
            cells.truncate(kept);
            k -= 1;
        }
        cells.clear();
        // Queued on levels the climb does not reach (a level out of use below them):
        // P1's marks in their subtrees are all they get, as when climbing cell by cell.
        while self.queued != 0 {
            let k = self.queued.trailing_zeros();
            self.queued &= self.queued - 1;
            self.inside[k as usize].clear();
        }
    }

    /// Whether every last-level cell that the pixel box `bbox` (`[x0, x1, y0, y1]`,
    /// ends excluded) meets is marked covered, for a box of at most [`MARKED_BOX`]
    /// pixels each way (`false` for a larger or an empty box); with the last level in
    /// use ([`Self::marks_last`]). Then no polygon inside the box can have a visible
    /// subpixel: a last-level cell is marked only when every subpixel of its mask is
    /// set (Greene's rule; P1's IN of an opaque polygon, which takes every open
    /// subpixel), or when it holds no pixel of this VP (off the screen, or outside
    /// the share, whose masks are full). The box's cells lie in at most 2 x 2 aligned
    /// blocks of 8 x 8 cells, each block's marks one word in Z order: the first
    /// block's word is found by [`morton`], its neighbours' by a carry through the
    /// other coordinate's bits, and each word is tested against the box's cells in
    /// it (`Z_COLUMNS & Z_ROWS`, as [`StartBlocks::block`] makes them). Not through
    /// [`StartBlocks`] itself, whose blocks would give the same words: with its
    /// order of blocks and a [`morton`] per block, `many` 480 x 270 raster 1637.2 →
    /// 1655.9 M instructions (this runs for every polygon at the look-ahead).
    #[inline(always)]
    pub fn box_marked(&self, [x0, x1, y0, y1]: [u32; 4]) -> bool {
        debug_assert!(self.marks_last());
        // Empty or larger than `MARKED_BOX` either way: one unsigned compare each.
        if x1.wrapping_sub(x0).wrapping_sub(1) >= MARKED_BOX || y1.wrapping_sub(y0).wrapping_sub(1) >= MARKED_BOX {
            return false;
        }
        let (cx0, cx1, cy0, cy1) = (x0 / CELL_SIDE, (x1 - 1) / CELL_SIDE, y0 / CELL_SIDE, (y1 - 1) / CELL_SIDE);
        // The box's columns (rows) in the first block and in the next one (none when
        // it ends in the first).
        let (two_x, two_y) = ((cx0 ^ cx1) >= BLOCK_SIDE, (cy0 ^ cy1) >= BLOCK_SIDE);
        let (a, b) = (cx0 % BLOCK_SIDE, cx1 % BLOCK_SIDE);
        let (c, d) = (cy0 % BLOCK_SIDE, cy1 % BLOCK_SIDE);
        let columns = Z_COLUMNS[(a | if two_x { 7 } else { b } << 3) as usize];
        let rows = Z_ROWS[(c | if two_y { 7 } else { d } << 3) as usize];
        let bits = &self.memories[self.root_level as usize].bits;
        let bz = morton(cx0 / BLOCK_SIDE, cy0 / BLOCK_SIDE);
        let cells = columns & rows;
        if bits[bz] & cells != cells {
            return false;
        }
        // The next block right (below): its Z-order index has one more in the
        // column's (row's) bits, the even (odd) ones.
        const EVEN: usize = 0x5555_5555_5555_5555_u64 as usize;
        const ODD: usize = !EVEN;
        let right = ((bz | ODD) + 1) & EVEN | bz & ODD;
        let below = ((bz | EVEN) + 2) & ODD | bz & EVEN;
        let (next_columns, next_rows) = (Z_COLUMNS[(b << 3) as usize], Z_ROWS[(d << 3) as usize]);
        if two_x {
            let cells = next_columns & rows;
            if bits[right] & cells != cells {
                return false;
            }
        }
        if two_y {
            let cells = columns & next_rows;
            if bits[below] & cells != cells {
                return false;
            }
            if two_x {
                let corner = ((below | ODD) + 1) & EVEN | below & ODD;
                let cells = next_columns & next_rows;
                return bits[corner] & cells == cells;
            }
        }
        true
    }

    /// Whether the last level's mask memory is in use ([`Self::box_marked`]).
    #[inline]
    pub fn marks_last(&self) -> bool {
        self.masks.has(self.root_level)
    }

    /// The mask memory of level `k` (for pictures and tests).
    pub fn memory(&self, k: u32) -> &MaskMemory {
        &self.memories[k as usize]
    }

    /// Side in pixels of a cell of level `k`.
    #[inline]
    pub fn side(&self, k: u32) -> u32 {
        4 << (self.root_level - k)
    }

    /// The smallest cell that holds the bounding box.
    pub fn bounding_cell(&self, bbox: [u32; 4]) -> Cell {
        let [x0, x1, y0, y1] = bbox;
        let (x1, y1) = (x1.max(x0 + 1) - 1, y1.max(y0 + 1) - 1);
        // The cell side must reach the highest differing bit of the pixel addresses.
        let diff = (x0 ^ x1) | (y0 ^ y1) | 3;
        let bits = 32 - diff.leading_zeros(); // side = 2^bits pixels
        let level = (self.root_level + 2).saturating_sub(bits);
        let shift = self.root_level + 2 - level;
        Cell { level, x: x0 >> shift, y: y0 >> shift }
    }

    /// Runs the descent of one polygon from its bounding cell, calling `spp` for every
    /// level-L cell that is inside or crossed and not masked. `STATS` selects counting.
    pub fn descend<const STATS: bool>(
        &mut self,
        poly: &GqPolygon,
        counters: &mut Counters,
        spp: &mut impl FnMut(Fragment),
    ) {
        self.descend_inner::<STATS, false>(poly, counters, &mut EachFragment(spp));
    }

    /// [`Self::descend`] into a [`FragmentSink`].
    pub fn descend_to<const STATS: bool>(
        &mut self,
        poly: &GqPolygon,
        counters: &mut Counters,
        sink: &mut impl FragmentSink,
    ) {
        self.descend_inner::<STATS, false>(poly, counters, sink);
    }

    /// [`Self::descend`] with counting off, with two shortcuts for the cells wholly
    /// inside the polygon (IN for every edge, so no edge crosses them and their
    /// fragments come with no active edge): their subtrees are walked with the mask
    /// memories alone (the same marks and the same last-level cells as the descent),
    /// and under Greene's rule (`hierarchical`) an opaque polygon's inside cells are
    /// queued for [`Self::mark_covered_cells`] on their own level. Every last-level
    /// cell under them ends wholly covered (an opaque polygon takes every open
    /// subpixel of a cell with no edge), so the caller need not report those cells
    /// one by one: it reports only fragments with active edges, and those of
    /// transparent polygons. The counters are not touched (counting runs the
    /// machine's every step: [`Self::descend`]).
    pub fn descend_filling(&mut self, poly: &GqPolygon, counters: &mut Counters, spp: &mut impl FnMut(Fragment)) {
        self.descend_inner::<false, true>(poly, counters, &mut EachFragment(spp));
    }

    /// [`Self::descend_filling`] into a [`FragmentSink`].
    pub fn descend_filling_to(&mut self, poly: &GqPolygon, counters: &mut Counters, sink: &mut impl FragmentSink) {
        self.descend_inner::<false, true>(poly, counters, sink);
    }

    fn descend_inner<const STATS: bool, const FILL: bool>(
        &mut self,
        poly: &GqPolygon,
        counters: &mut Counters,
        spp: &mut impl FragmentSink,
    ) {
        let start = self.bounding_cell(poly.bbox);
        if STATS {
            counters.levels[start.level as usize].starts += 1;
        }
        // A polygon whose starting cell lies in a covered cell of any masking level
        // is dropped whole.
        let start_z = morton(start.x, start.y);
        if self.covered(start_z, start.level, 1) {
            if STATS {
                counters.levels[start.level as usize].polygons_masked += 1;
                if let Some(rec) = &mut self.recorder {
                    rec.push((start, CellKind::PolygonMasked));
                }
            }
            return;
        }
        if STATS {
            if let Some(rec) = &mut self.recorder {
                rec.push((start, CellKind::Start));
            }
        }
        // Every pixel of the box covered already (with counting off): its every
        // fragment would be hidden, leave the masks as they are, make no first write
        // and mark nothing, so the polygon is passed over whole. Its descent would
        // mark no GQ cell either: a cell wholly inside it lies inside its box, so all
        // its subpixels are set, and such a cell is marked covered already, as its
        // last fragment found it covered (under Greene's rule); and without the rule
        // the marks it leaves out change later polygons' work, never their subpixels
        // (they stay sound and closed downward). `many` 960 x 540: 466 k of its
        // 1,000 k triangles, 155 k of them dropped by the test above; since session
        // 27 the VP passes over 373 k of them (all of those 155 k) before their start,
        // by the last level's marks under their box ([`Self::box_marked`]), and 93 k
        // come here.
        if FILL && self.hidden_boxes && spp.box_hidden() {
            return;
        }
        let n = poly.edges.len();
        if n > self.stride {
            self.stride = n.next_power_of_two();
            self.lists.resize(4 * self.stride * (self.root_level as usize + 1), ActiveEdge::EMPTY);
            self.start_edges.resize(self.stride, StartEdge::EMPTY);
        }
        if FILL && self.at_once && n <= AT_ONCE_EDGES && self.root_level >= 1 {
            // A box within 4 x 4 cells of level L - 1 (8 pixels): its last-level cells
            // at once ([`Self::last_cells`]), from the bounding cell when that is of
            // level L - 1, else from the start at the polygon's size.
            let [x0, x1, y0, y1] = poly.bbox;
            let (cx0, cy0) = (x0 >> 3, y0 >> 3);
            let (columns, rows) = (((x1 - 1) >> 3) - cx0, ((y1 - 1) >> 3) - cy0);
            if start.level + 1 == self.root_level {
                self.last_cells_of(start, start_z, poly, spp);
                return;
            }
            if start.level + 1 < self.root_level && columns < WINDOW_SPAN && rows < WINDOW_SPAN {
                self.last_cells(cx0, cy0, columns, rows, start.level + 1, poly, spp);
                return;
            }
        }
        if FILL && self.start_at_size(start, poly, counters, spp) {
            return;
        }
        let side = i64::from(self.side(start.level));
        let (x0, y0) = (i64::from(start.x) * side, i64::from(start.y) * side);
        let first = 4 * self.stride * start.level as usize;
        let list = &mut self.lists[first..first + n];
        for (i, (a, e)) in list.iter_mut().zip(poly.edges).enumerate() {
            *a = ActiveEdge::at_cell(i as u32, e, x0, y0, side);
        }
        if start.level == self.root_level {
            spp.fragment(Fragment {
                px: start.x * 4,
                py: start.y * 4,
                active: &self.lists[first..first + n],
                cells: ONE_CELL,
                bbox: poly.bbox,
            });
            return;
        }
        let half = 1i64 << (EDGE_FRAC_BITS + (self.root_level + 1 - start.level));
        self.split::<STATS, FILL>(start, start_z, first, n, half, poly, counters, spp);
    }

    /// Whether the cell of Z-order index `z` on level `level`, or its ancestor on a
    /// level `from..=level` in use, is marked covered.
    ///
    /// The marks are closed downward over the levels in use: a cell marked on a level
    /// in use has every descendant on the deeper levels in use marked too (a cell is
    /// marked IN on the way down and its subtree filled below it, [`Self::fill`];
    /// Greene's rule marks a parent only when its four children are marked; the cells
    /// off the screen, and those outside a matrix VP's share, are pre-masked on every
    /// level, [`Self::pre_mask_share`]; tested by `marks_are_closed_downward` and
    /// `share_pre_masks_are_exact_and_closed_downward`). So the cell's ancestor on the deepest
    /// level in use decides alone: one read where the walk up the levels took one per
    /// level for every polygon not hidden (most of `many`'s triangles are hidden at
    /// subpixel level, below the marks).
    #[inline(always)]
    fn covered(&self, z: usize, level: u32, from: u32) -> bool {
        let levels = self.masks.0 & ((2u32 << level) - 1) & !((1u32 << from) - 1);
        if levels == 0 {
            return false;
        }
        // The ancestor on level `k`: two Z-order bits per level up.
        let k = 31 - levels.leading_zeros();
        self.memories[k as usize].get_z(z >> (2 * (level - k)))
    }

    /// Whether the marks are closed downward over the levels in use (see
    /// [`Self::covered`]): every marked cell of a level in use has every descendant
    /// marked on each deeper level in use.
    #[cfg(test)]
    fn marks_closed_downward(&self) -> bool {
        let in_use: Vec<u32> = (1..=self.root_level).filter(|&k| self.masks.has(k)).collect();
        for (i, &k) in in_use.iter().enumerate() {
            let m = &self.memories[k as usize];
            let side = 1usize << k;
            for z in (0..side * side).filter(|&z| m.get_z(z)) {
                for &deeper in &in_use[i + 1..] {
                    let shift = 2 * (deeper - k) as usize;
                    let d = &self.memories[deeper as usize];
                    if !(z << shift..(z + 1) << shift).all(|z| d.get_z(z)) {
                        return false;
                    }
                }
            }
        }
        true
    }

    /// The level of a box's size (`bbox`, not empty): the deepest level at most L - 1
    /// whose cells it spans fewer than [`MAX_START_SPAN`] of each way. Not deeper
    /// than L - 1 (8 pixel cells), whose split hands the SPPs only the edges crossing
    /// each last-level cell.
    fn size_level(&self, bbox: [u32; 4]) -> u32 {
        let [x0, x1, y0, y1] = bbox;
        let (x1, y1) = (x1 - 1, y1 - 1);
        // Cells of `2^shift` pixels; most boxes (`terrain`'s and `many`'s) fit L - 1's.
        if (x1 >> 3) - (x0 >> 3) < MAX_START_SPAN && (y1 >> 3) - (y0 >> 3) < MAX_START_SPAN {
            return (self.root_level + 2).saturating_sub(3);
        }
        let mut shift = 4;
        while (x1 >> shift) - (x0 >> shift) >= MAX_START_SPAN || (y1 >> shift) - (y0 >> shift) >= MAX_START_SPAN {
            shift += 1;
        }
        (self.root_level + 2).saturating_sub(shift)
    }

    /// The filling descent's start at the cells of the polygon's size: the cells (up
    /// to [`MAX_START_SPAN`] each way) of the deepest level above the last whose
    /// cells the box (`poly.bbox`) spans fewer than that many of each way, when that
    /// level lies below the bounding cell `start` (else returns `false`, and the
    /// descent starts at `start`). A polygon whose box straddles a border of a large
    /// cell (a tenth of `many`'s triangles start at levels 0-2, 3-9 levels above
    /// their size) is otherwise split level by level down through cells it barely
    /// touches; and a start cell's edges cost less than a split of its parent: they
    /// come from the block's first cell's by additions ([`derive_start_list`]), and
    /// a cell OUT for an edge is dropped there, as its parent's split would drop it.
    /// Up to eight cells each way (64) measured best once the cells came in Z order
    /// with no sort ([`StartBlocks`]; session 13: raster default / terrain / city
    /// 100.4 / 324.7 / 50.5 M with four, 96.5 / 323.2 / 49.4 with six, 94.8 / 323.8 /
    /// 49.1 with eight; session 12, with a sort: two 110.0 / 349.3, four 103.0 /
    /// 336.0, six 100.6 / 340.3).
    ///
    /// The same subpixels as the descent from `start`: every cell the box meets lies
    /// in these cells, the SPPs clip each code to the box
    /// ([`super::spp::box_pixels`]), and a cell's descent depends only on its active
    /// edges (here the polygon's every edge: one that crosses no ancestor codes its
    /// children all IN or all OUT, as at the ancestor, and only crossing edges go on
    /// to the children's lists) and on the mask memories, read here for the levels
    /// between, as the splits would. Cells the box does not meet are not descended:
    /// their codes clip to nothing. The cells go in Z order, as the descent visits
    /// them, and a cell wholly inside is marked and filled as its parent's split
    /// would. A cell of a level above wholly inside the polygon (possible when the
    /// box spans three or four cells) is marked only on its children's level and
    /// below (under Greene's rule the climb marks it too): the marks stay sound and
    /// closed downward, so they change later polygons' work, never their subpixels.
    #[inline(always)]
    fn start_at_size(
        &mut self,
        start: Cell,
        poly: &GqPolygon,
        counters: &mut Counters,
        spp: &mut impl FragmentSink,
    ) -> bool {
        if start.level + 1 >= self.root_level {
            return false;
        }
        let level = self.size_level(poly.bbox);
        if level < start.level + 1 {
            return false;
        }
        let [bx0, bx1, by0, by1] = poly.bbox;
        let (bx1, by1) = (bx1 - 1, by1 - 1);
        let shift = self.root_level + 2 - level;
        let (cx0, cy0) = (bx0 >> shift, by0 >> shift);
        let (columns, rows) = ((bx1 >> shift) - cx0, (by1 >> shift) - cy0);
        let side = i64::from(self.side(level));
        let half = 1i64 << (EDGE_FRAC_BITS + (self.root_level + 1 - level));
        let first = 4 * self.stride * level as usize;
        let n = poly.edges.len();
        // The block's first cell's edges: every cell's are derived from them into
        // the level's first list ([`derive_start_list`]).
        let (x0, y0) = (i64::from(cx0) * side, i64::from(cy0) * side);
        for (i, (s, e)) in self.start_edges[..n].iter_mut().zip(poly.edges).enumerate() {
            *s = StartEdge::new(ActiveEdge::at_cell(i as u32, e, x0, y0, side), 2 * half);
        }
        // With the start level in use, the level's own mark decides
        // ([`Self::covered`]): an aligned 8 x 8 block's marks are one word, read once
        // for its cells. A start cell's descent marks only itself on its level (and
        // cells below it), so the word read before serves the others.
        let one_read = self.masks.has(level);
        let blocks = StartBlocks::new(cx0, cy0, columns, rows);
        for i in 0..blocks.count {
            let (bz, bx, by, cells) = blocks.block(i);
            let mut open = cells;
            if one_read {
                open &= !self.memories[level as usize].word(bz);
            }
            for (z, dx, dy) in blocks.cells(bz, bx, by, open) {
                let cell = Cell { level, x: cx0 + dx, y: cy0 + dy };
                if !one_read && self.covered(z, level, start.level + 1) {
                    continue;
                }
                let Some(len) = derive_start_list(&self.start_edges[..n], &mut self.lists[first..first + n], dx, dy)
                else {
                    // OUT for an edge: its parent's split would drop it, and its own split
                    // finds every child OUT (no mark, no cell).
                    continue;
                };
                if len == 0 {
                    self.start_inside(cell, z, poly.opaque, spp);
                    continue;
                }
                self.split::<false, true>(cell, z, first, len, half, poly, counters, spp);
            }
        }
        true
    }

    /// The filling descent of a small polygon from the cells of level L - 1 (8
    /// pixels) `cx0 ..= cx0 + columns` by `cy0 ..= cy0 + rows` (fewer than
    /// [`WINDOW_SPAN`] each way), their last-level cells found at once: each edge
    /// coded for the 8 x 8 last-level cells of the 4 x 4 cells of level L - 1 from
    /// `(cx0, cy0)` in one step ([`LastCells`]), not by a split of each cell of
    /// level L - 1 edge by edge (the start's list of each cell, `child_codes`, the
    /// children's lists written for every edge). The same fragments in the same
    /// order, and the same marks and queued cells, as the descent: here for the
    /// start at the polygon's size ([`Self::start_at_size`]: the cells in Z order by
    /// [`StartBlocks`], each cell's mark read from level `from` on, a cell wholly
    /// inside marked and filled, the others split as [`Self::last_split`] splits);
    /// for the descent from a bounding cell of level L - 1 see
    /// [`Self::last_cells_of`]. A split's decisions are each child's alone: an edge
    /// codes a child IN when its line lies at or before the child's near border on
    /// the polygon's side, OUT when at or beyond its far one
    /// (the tests' `edge_code`), by the V of the child's own stretch, which is the edge's V at
    /// the child's borders (exact, [`super::edge`]); so a cell of level L - 1 is OUT
    /// for an edge (dropped by the start) when its four children are, IN when they
    /// are, and the split's child lists hold, in order, the edges that cross the
    /// child. Tested against the descent level by level
    /// (`last_cells_are_the_descent`).
    #[expect(clippy::too_many_arguments, reason = "the start's cells, passed in registers")]
    #[inline(always)]
    fn last_cells(
        &mut self,
        cx0: u32,
        cy0: u32,
        columns: u32,
        rows: u32,
        from: u32,
        poly: &GqPolygon,
        spp: &mut impl FragmentSink,
    ) {
        let last = self.root_level;
        let level = last - 1;
        let n = poly.edges.len();
        let codes = LastCells::new(poly.edges, cx0 * 8, cy0 * 8, columns, rows, poly.bbox);
        let list = 4 * self.stride * last as usize;
        // With the level in use, its own mark decides ([`Self::covered`]): an aligned
        // 8 x 8 block's marks are one word, read once for its cells.
        let one_read = self.masks.has(level);
        let blocks = StartBlocks::new(cx0, cy0, columns, rows);
        for i in 0..blocks.count {
            let (bz, bx, by, cells) = blocks.block(i);
            let mut open = cells;
            if one_read {
                open &= !self.memories[level as usize].word(bz);
            }
            for (z, dx, dy) in blocks.cells(bz, bx, by, open) {
                let cell = Cell { level, x: cx0 + dx, y: cy0 + dy };
                // The cell's children in the window's words: bits `b`, `b + 1`, `b + 8`
                // and `b + 9`.
                let b = 2 * dx + 16 * dy;
                let (outside, inside) = (children_bits(codes.outside, b), children_bits(codes.inside, b));
                if !one_read && self.covered(z, level, from) {
                    continue;
                }
                if inside == 0xF {
                    // Wholly inside: as the start at the polygon's size does.
                    self.start_inside(cell, z, poly.opaque, spp);
                    continue;
                }
                if outside == 0xF {
                    // Every child OUT (or beyond the box): the split would mark none
                    // (`ci` empty) and hand none on, so its mask memory is neither
                    // read nor written (session 27: `many` 480 x 270 raster 1649.8 →
                    // 1641.5 M instructions).
                    continue;
                }
                // The split of `cell` ([`Self::split_step`], its children last-level;
                // the children the box does not meet are OUT in `codes`, where the split
                // takes them as masked: the same marks and cells).
                let m = u32::from(self.memories[last as usize].children(z));
                if m == 0xF {
                    continue;
                }
                // (A child the box does not meet is OUT, so not IN: the split's mask.)
                let cri = !m & !outside & 0xF;
                let ci = cri & inside;
                if poly.opaque && self.masks.has(last) {
                    self.memories[last as usize].set_children(z, ci as u8);
                }
                let mut todo = cri;
                while todo != 0 {
                    let c = todo.trailing_zeros();
                    todo &= todo - 1;
                    if ci >> c & 1 == 1 {
                        if self.hierarchical && poly.opaque {
                            self.inside[last as usize].push(4 * z + c as usize);
                            self.queued |= 1 << last;
                        }
                        spp.fragment(Fragment::inside_child(cell, c, poly.bbox));
                        continue;
                    }
                    let len = codes.list(b + (c & 1) + 8 * (c >> 1), &mut self.lists[list..list + n]);
                    spp.fragment(Fragment {
                        px: (cell.x * 2 + (c & 1)) * 4,
                        py: (cell.y * 2 + (c >> 1)) * 4,
                        active: &self.lists[list..list + len],
                        cells: ONE_CELL,
                        bbox: poly.bbox,
                    });
                }
            }
        }
    }

    /// [`Self::last_cells`] for the descent from the bounding cell `cell` of level
    /// L - 1 (Z-order index `z`), whose marks the caller has read: the window is
    /// that one cell, split ([`Self::last_split`]) with no walk over
    /// [`StartBlocks`] (its block's Z-order index, word and cell), which a polygon
    /// within one cell of 8 pixels does not need (session 26, with the window's box
    /// by tables, [`window_box`]: `many` 480 x 270 raster 1733.1 → 1710.3 M
    /// instructions, terrain 272.0 → 270.9 M). [`Self::last_cells`] keeps its own
    /// copy of the split: through [`Self::last_split`] there, the compiler loaded
    /// the sink's state for each cell rather than for each block (terrain's raster
    /// +2.3 M).
    #[inline(always)]
    fn last_cells_of(&mut self, cell: Cell, z: usize, poly: &GqPolygon, spp: &mut impl FragmentSink) {
        let codes = LastCells::new(poly.edges, cell.x * 8, cell.y * 8, 0, 0, poly.bbox);
        self.last_split(&codes, cell, z, 0, poly, spp);
    }

    /// The split ([`Self::split_step`]) of the window's cell `cell` of level L - 1
    /// (Z-order index `z`, its children at bits `b`, `b + 1`, `b + 8`, `b + 9` of
    /// `codes`): its children are last-level, those the box does not meet OUT in
    /// `codes`, where the split takes them as masked (the same marks and cells).
    #[inline(always)]
    fn last_split(
        &mut self,
        codes: &LastCells,
        cell: Cell,
        z: usize,
        b: u32,
        poly: &GqPolygon,
        spp: &mut impl FragmentSink,
    ) {
        let last = self.root_level;
        let n = poly.edges.len();
        let list = 4 * self.stride * last as usize;
        let m = u32::from(self.memories[last as usize].children(z));
        if m == 0xF {
            return;
        }
        let (outside, inside) = (children_bits(codes.outside, b), children_bits(codes.inside, b));
        // (A child the box does not meet is OUT, so not IN: the split's mask.)
        let cri = !m & !outside & 0xF;
        let ci = cri & inside;
        if poly.opaque && self.masks.has(last) {
            self.memories[last as usize].set_children(z, ci as u8);
        }
        let mut todo = cri;
        while todo != 0 {
            let c = todo.trailing_zeros();
            todo &= todo - 1;
            if ci >> c & 1 == 1 {
                if self.hierarchical && poly.opaque {
                    self.inside[last as usize].push(4 * z + c as usize);
                    self.queued |= 1 << last;
                }
                spp.fragment(Fragment::inside_child(cell, c, poly.bbox));
                continue;
            }
            let len = codes.list(b + (c & 1) + 8 * (c >> 1), &mut self.lists[list..list + n]);
            spp.fragment(Fragment {
                px: (cell.x * 2 + (c & 1)) * 4,
                py: (cell.y * 2 + (c >> 1)) * 4,
                active: &self.lists[list..list + len],
                cells: ONE_CELL,
                bbox: poly.bbox,
            });
        }
    }

    /// One GQ step: splits `cell` (Z-order index `z`, its `len` active edges at `list`
    /// in its level's lists, `half` its half side in [`EdgeCoord`] units) into four
    /// children and descends into those inside or crossed.
    #[expect(clippy::too_many_arguments, reason = "the descent's state, passed in registers")]
    fn split<const STATS: bool, const FILL: bool>(
        &mut self,
        cell: Cell,
        z: usize,
        list: usize,
        len: usize,
        half: i64,
        poly: &GqPolygon,
        counters: &mut Counters,
        spp: &mut impl FragmentSink,
    ) {
        self.split_step::<STATS, FILL, false>(cell, z, list, len, half, poly, counters, spp);
    }

    /// [`Self::split`]'s body; with `LAST` for a cell of level L - 1 only (its
    /// children go to the SPPs). A cell of level L - 2 splits its children of level
    /// L - 1 by the `LAST` copy inlined, not by a call: most splits are of level
    /// L - 1 cells (terrain's and many's small polygons start at L - 2 or L - 1), and
    /// a call of the recursive split costs its saved registers and arguments.
    #[expect(clippy::too_many_arguments, reason = "the descent's state, passed in registers")]
    #[inline(always)]
    fn split_step<const STATS: bool, const FILL: bool, const LAST: bool>(
        &mut self,
        cell: Cell,
        z: usize,
        list: usize,
        len: usize,
        half: i64,
        poly: &GqPolygon,
        counters: &mut Counters,
        spp: &mut impl FragmentSink,
    ) {
        let k = cell.level as usize;
        let child_level = cell.level + 1;

        // Edge codes: CI_i, CRI_i per edge, ANDed (P1 eq. 2); each edge goes on the
        // lists of the children it crosses, with the V of the child's stretch.
        // The mask memory of the children's level, read first: a masked child needs
        // no list (and with counting off, four masked children no edge codes).
        // Bits are only ever set on levels in use; cells wholly off the screen always
        // read as covered (pre-masked), whatever the mode.
        let mut m = self.memories[child_level as usize].children(z);
        if FILL {
            // Children the polygon's box does not meet, as if masked: their codes
            // clip to nothing ([`super::spp::box_pixels`]), and none is IN (a cell
            // wholly inside the polygon lies in its box), so the marks are the same.
            m |= !children_in_box(cell, self.root_level + 1 - cell.level, poly.bbox) & 0xF;
        }
        if !STATS && m == 0xF {
            return;
        }
        let stride = self.stride;
        // The children's block of lists, after the cell's own.
        let block = 4 * stride * (k + 1);
        let (lo, hi) = self.lists.split_at_mut(block);
        let active = &lo[list..list + len];
        let children = &mut hi[..4 * stride];
        // Where the children's lists end; child `c`'s starts at `c * stride`.
        let mut ends = [0, stride, 2 * stride, 3 * stride];
        // CI in bits 0-3, CRI in bits 4-7, ANDed over the edges.
        let mut codes_all = 0xFFu32;
        let open = u32::from(!m & 0xF);
        let thresholds = ChildThresholds::new(half);
        for (i, a) in active.iter().enumerate() {
            let code = child_codes(a.v1.0, a.v2.0, &thresholds, a.kind);
            codes_all &= code.codes;
            if !STATS && codes_all >> 4 & open == 0 {
                // Every open child is OUT: no child to descend into, none IN.
                break;
            }
            // Before this edge at most the `i` edges before it went on a list, and
            // `len <= stride`: `ends[c] < (c + 1) stride`, in child `c`'s list.
            debug_assert!(i < stride && ends.iter().enumerate().all(|(c, &end)| end <= c * stride + i));
            // SAFETY: `ends[c] < (c + 1) stride` (above: each edge moves an end by at
            // most one, and a cell's list holds at most its polygon's edges, at most
            // `stride`), and `children` is the four lists, `4 stride` entries.
            #[allow(unsafe_code, reason = "the child lists' writes, bounded by the lists' length")]
            unsafe {
                write_children(children, &mut ends, a, code.vm, half, code.codes >> 8 & open)
            };
        }
        let (ci_all, cri_all) = (codes_all as u8 & 0xF, (codes_all >> 4) as u8 & 0xF);
        let mem_on = self.masks.has(child_level);
        let cri = !m & cri_all & 0xF;
        let ci = !m & ci_all & 0xF;
        if STATS {
            let lc = &mut counters.levels[child_level as usize];
            lc.tested += 4;
            lc.edge_tests += active.len() as u64;
            lc.inside += u64::from(ci.count_ones());
            lc.crossed += u64::from((cri & !ci).count_ones());
            lc.outside += u64::from((!cri_all & 0xF).count_ones());
            lc.masked += u64::from((m & cri_all).count_ones());
            if let Some(rec) = &mut self.recorder {
                record_children(rec, cell, cri_all, m, ci);
            }
        }
        if poly.opaque && mem_on {
            self.memories[child_level as usize].set_children(z, ci);
        }
        let mut todo = cri;
        while todo != 0 {
            let c = todo.trailing_zeros();
            todo &= todo - 1;
            let child_cell = Cell { level: child_level, x: cell.x * 2 + (c & 1), y: cell.y * 2 + (c >> 1) };
            if FILL && ci >> c & 1 == 1 {
                // Wholly inside: no edge to carry further down.
                if self.hierarchical && poly.opaque {
                    self.inside[child_level as usize].push(4 * z + c as usize);
                    self.queued |= 1 << child_level;
                }
                if LAST || child_level == self.root_level {
                    // In the descent's order, cell by cell (this cell of the parent).
                    spp.fragment(Fragment::inside_child(cell, c, poly.bbox));
                } else {
                    self.fill(child_cell, 4 * z + c as usize, poly.opaque, spp);
                }
                continue;
            }
            let (start, end) = (c as usize * stride, ends[c as usize]);
            // Only cells of two edges can close ([`band_closed`]): their length first,
            // before the list is sliced. Not a last-level cell: closed, it is one
            // fragment whose code comes out empty, and the test of every such cell of
            // two edges cost more than the fragments it saved (terrain, a frame: ~3,900
            // of ~140,000 such cells closed; raster 296.5 → 293.5 M instructions, the
            // rendering VP's 453.7 → 452.1 M; default 87.4 → 86.1 M and 188.4 → 187.3 M).
            if FILL
                && !(LAST || child_level == self.root_level)
                && end - start == 2
                && band_closed(&self.lists[block + start..block + end], poly.edges, child_cell, self.side(child_level))
            {
                continue;
            }
            if LAST || child_level == self.root_level {
                spp.fragment(Fragment {
                    px: child_cell.x * 4,
                    py: child_cell.y * 4,
                    active: &self.lists[block + start..block + end],
                    cells: ONE_CELL,
                    bbox: poly.bbox,
                });
            } else if child_level + 1 == self.root_level {
                self.split_step::<STATS, FILL, true>(
                    child_cell,
                    4 * z + c as usize,
                    block + start,
                    end - start,
                    half >> 1,
                    poly,
                    counters,
                    spp,
                );
            } else {
                self.split::<STATS, FILL>(
                    child_cell,
                    4 * z + c as usize,
                    block + start,
                    end - start,
                    half >> 1,
                    poly,
                    counters,
                    spp,
                );
            }
        }
    }

    /// A start's cell (Z-order index `z`) wholly inside the polygon, as
    /// [`Self::split_step`] takes a child wholly inside: marked (opaque, its level in
    /// use), queued for the hierarchical marks, and filled ([`Self::fill`]).
    #[inline(always)]
    fn start_inside(&mut self, cell: Cell, z: usize, opaque: bool, spp: &mut impl FragmentSink) {
        let level = cell.level;
        if opaque && self.masks.has(level) {
            self.memories[level as usize].set_z(z);
        }
        if self.hierarchical && opaque {
            self.inside[level as usize].push(z);
            self.queued |= 1 << level;
        }
        self.fill(cell, z, opaque, spp);
    }

    /// [`Self::split`] of a cell wholly inside the polygon (Z-order index `z`): its
    /// children are all IN, so only the mask memory decides (the marks and the cells
    /// of `split` with no active edge), down to the last level's cells, which go to
    /// `spp` with no active edge, the open children of a cell of level L - 1 in one
    /// fragment.
    fn fill(&mut self, cell: Cell, z: usize, opaque: bool, spp: &mut impl FragmentSink) {
        let child_level = cell.level + 1;
        let todo = !self.memories[child_level as usize].children(z) & 0xF;
        if opaque && self.masks.has(child_level) {
            self.memories[child_level as usize].set_children(z, todo);
        }
        if child_level == self.root_level {
            if todo != 0 {
                spp.fragment(Fragment { px: cell.x * 8, py: cell.y * 8, active: &[], cells: todo, bbox: NO_BOX });
            }
            return;
        }
        let mut rest = todo;
        while rest != 0 {
            let c = rest.trailing_zeros();
            rest &= rest - 1;
            let (x, y) = (cell.x * 2 + (c & 1), cell.y * 2 + (c >> 1));
            self.fill(Cell { level: child_level, x, y }, 4 * z + c as usize, opaque, spp);
        }
    }
}

/// Writes edge `a` (of a cell of half side `half`, its midpoint V `vm`) at the end
/// of each of the cell's four children's lists in `children` (child `c`'s at
/// `ends[c]`, which must lie below `(c + 1) stride`, `stride` a quarter of
/// `children`), and moves the ends of the lists of the children it crosses
/// (`crossed`, bit `c = dx + 2 dy`) past it: a list past its end is never read. No
/// branch per child, where the loop over the crossed children (1 to 3, as the edge's
/// line runs) ended or went on by data no predictor learns, and the ends stay in
/// registers (indexed by the child, each end's load waited on the last edge's store
/// of it). A child's stretch is the first half along V's lines `(V1, Vm)` or the
/// second `(Vm, V2)`, its V origin the cell's or half a cell further across them:
/// child 0 takes the first half unshifted and child 3 the second shifted, whatever
/// the TG; children 1 and 2 the second half unshifted and the first shifted
/// (horizontal TG: `c & 1` along) or the other way round (vertical: `c >> 1` along).
/// In SSE2 on x86-64: V1 and V2 in one register, the TG's swap of children 1 and 2
/// by a mask, each copy two stores; elsewhere by its definition (tested against each
/// other).
///
/// # Safety
///
/// `ends[c] < (c + 1) * (children.len() / 4)` for every child `c`: the stores are
/// not bounds-checked.
#[allow(unsafe_code, reason = "the child lists' writes, bounded by the caller")]
#[inline(always)]
unsafe fn write_children(
    children: &mut [ActiveEdge],
    ends: &mut [usize; 4],
    a: &ActiveEdge,
    vm: i64,
    half: i64,
    crossed: u32,
) {
    debug_assert!(ends.iter().enumerate().all(|(c, &end)| end < (c + 1) * (children.len() / 4)));
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let tail = u64::from(a.edge) | u64::from(a.kind) << 32;
        // SAFETY: SSE2 operations (x86-64's baseline); each copy's stores write 24
        // bytes at entry `ends[c]` of `children`, in child `c`'s list by the
        // caller's bound, as [`ActiveEdge`]'s C layout places V1, V2 (16 bytes) and
        // the index and kind (8, little-endian: the index first).
        #[allow(unsafe_code, reason = "SSE2 stores of a child's copy into its list, bounded by the caller")]
        unsafe {
            let v = _mm_set_epi64x(a.v2.0, a.v1.0);
            let m = _mm_set1_epi64x(vm);
            let h = _mm_set1_epi64x(half);
            let first = _mm_unpacklo_epi64(v, m);
            let second = _mm_unpackhi_epi64(m, v);
            let first_shifted = _mm_sub_epi64(first, h);
            let second_shifted = _mm_sub_epi64(second, h);
            let vertical = _mm_set1_epi64x(-i64::from(a.kind & KIND_VERTICAL != 0));
            let swap = _mm_and_si128(_mm_xor_si128(first_shifted, second), vertical);
            let copies = [first, _mm_xor_si128(second, swap), _mm_xor_si128(first_shifted, swap), second_shifted];
            let base = children.as_mut_ptr();
            for (c, copy) in copies.into_iter().enumerate() {
                let at = base.add(ends[c]);
                _mm_storeu_si128(at.cast(), copy);
                at.cast::<u64>().add(2).write(tail);
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    write_children_plain(children, ends, a, vm, half);
    for (c, end) in ends.iter_mut().enumerate() {
        *end += (crossed >> c & 1) as usize;
    }
}

/// [`write_children`]' copies by their definition: the child's half along V's lines,
/// its origin half a cell further across them or not, by TG.
#[cfg_attr(target_arch = "x86_64", allow(dead_code, reason = "the other targets' copy, tested against the SSE2 one"))]
#[inline(always)]
fn write_children_plain(children: &mut [ActiveEdge], ends: &[usize; 4], a: &ActiveEdge, vm: i64, half: i64) {
    for (c, &end) in ends.iter().enumerate() {
        let vertical = a.kind & KIND_VERTICAL != 0;
        let (along, across) = if vertical { (c >> 1, c & 1) } else { (c & 1, c >> 1) };
        let (v1, v2) = if along == 0 { (a.v1.0, vm) } else { (vm, a.v2.0) };
        let shift = if across == 0 { 0 } else { half };
        children[end] = ActiveEdge { v1: EdgeCoord(v1 - shift), v2: EdgeCoord(v2 - shift), ..*a };
    }
}

/// An edge of a start's first cell ([`CellProcessors::start_at_size`]), set up for
/// [`derive_start_list`]: a cell `(dx, dy)` cells further has V `dx ox + dy oy` further
/// (V at a border `k` cells further along the edge's lines is V1 plus `k` times `V2 -
/// V1`, V being linear and exact, and a cell further across has its origin a side
/// further), and with `u` that offset, negated when LR = 0 (`flip` all ones), the
/// cell is OUT for the edge when `u >= t_out` and IN when `u <= t_in`.
#[derive(Clone, Copy, Debug)]
struct StartEdge {
    /// The edge at the first cell ([`ActiveEdge::at_cell`]).
    first: ActiveEdge,
    /// V's change a cell along the columns and a cell along the rows.
    ox: i64,
    oy: i64,
    /// The offsets (signed by `flip`) from which the cell is OUT, and up to which IN.
    t_out: i64,
    t_in: i64,
    /// 0 for LR = 1, all ones for LR = 0.
    flip: i64,
}

impl StartEdge {
    /// An entry of the scratch list before it is written.
    const EMPTY: Self = Self { first: ActiveEdge::EMPTY, ox: 0, oy: 0, t_out: 0, t_in: 0, flip: 0 };

    /// Edge `first` of a start's first cell, of side `side` ([`EdgeCoord`] units). A
    /// cell's parent's split codes the edge IN when the line lies at or before the
    /// cell's near border (`hi <= 0`, the greatest of V1, V2 at the cell) on the
    /// polygon's side, OUT when at or beyond its far one (`lo >= side`) (with LR = 0
    /// the other way round); at a cell `off` further, `hi = hi0 + off`, `lo = lo0 + off`.
    #[inline(always)]
    fn new(first: ActiveEdge, side: i64) -> Self {
        let d = first.v2.0 - first.v1.0;
        let (ox, oy) = if first.vertical() { (-side, d) } else { (d, -side) };
        let (lo0, hi0) = (first.v1.0.min(first.v2.0), first.v1.0.max(first.v2.0));
        let (t_out, t_in, flip) = if first.lr() {
            // OUT: lo0 + off >= side; IN: hi0 + off <= 0.
            (side - lo0, -hi0, 0)
        } else {
            // OUT: hi0 + off <= 0, -off >= hi0; IN: lo0 + off >= side, -off <= lo0 - side.
            (hi0, lo0 - side, -1)
        };
        Self { first, ox, oy, t_out, t_in, flip }
    }
}

/// The edges of the cell `(dx, dy)` cells along from the first of a block
/// ([`CellProcessors::start_at_size`]) from the first cell's (`starts`,
/// [`StartEdge`]) into `out`: the same values as [`ActiveEdge::at_cell`] of the cell
/// (tested by `start_lists_are_at_cell`) by two products and additions. Each edge is
/// coded as the cell's parent's split would code it: IN (the line at or before the
/// cell's near border, or at or beyond its far one, on the polygon's side), OUT (the
/// same on the other side) or crossing. Returns `None` when the cell is OUT for an
/// edge (the cell is dropped; the list is left unfinished), else how many edges cross
/// it: only those are kept, packed at the front of `out`, as a split keeps only the
/// crossing edges on a child's list (an edge IN for the whole cell codes its every
/// child IN, which changes no AND of codes, and crosses none); `Some(0)` is a cell
/// wholly inside. (Terrain's start cells, of about 3 edges, are IN for about a third
/// of them.)
#[inline(always)]
fn derive_start_list(starts: &[StartEdge], out: &mut [ActiveEdge], dx: u32, dy: u32) -> Option<usize> {
    let (dx, dy) = (i64::from(dx), i64::from(dy));
    let out = &mut out[..starts.len()];
    let mut len = 0;
    for (i, s) in starts.iter().enumerate() {
        let off = dx * s.ox + dy * s.oy;
        debug_assert!(len <= i);
        // SAFETY: `len` counts the edges before `i` kept, so `len <= i < starts.len()`,
        // which is `out.len()` (sliced above).
        #[allow(unsafe_code, reason = "a packed list's index, at most the edge's, which the compiler cannot see")]
        let entry = unsafe { out.get_unchecked_mut(len) };
        *entry = ActiveEdge { v1: EdgeCoord(s.first.v1.0 + off), v2: EdgeCoord(s.first.v2.0 + off), ..s.first };
        let u = (off ^ s.flip) - s.flip;
        if u >= s.t_out {
            // The rest of the list is not needed.
            return None;
        }
        len += usize::from(u > s.t_in);
    }
    Some(len)
}

/// The most edges of a polygon whose last-level cells the filling descent finds at
/// once ([`CellProcessors::last_cells`]): triangles and quadrilaterals.
const AT_ONCE_EDGES: usize = 4;

/// `log2` of a last-level cell's side in [`EdgeCoord`] units.
const CELL_V_BITS: u32 = EDGE_FRAC_BITS + 2;
const _: () = assert!(CELL_SIDE == 4);

/// The most cells of level L - 1 each way of a window of [`LastCells`].
const WINDOW_SPAN: u32 = 4;

/// A polygon's edges coded for the 8 x 8 last-level cells of a window of 4 x 4 cells
/// of level L - 1 ([`CellProcessors::last_cells`]), each 64-cell set a word: cell
/// `(i, j)` of the window (columns and rows of last-level cells from its corner) at
/// bit `i + 8 j`, so that the four children of the window's cell `(dx, dy)` of level
/// L - 1 are bits `b`, `b + 1`, `b + 8`, `b + 9` from `b = 2 dx + 16 dy`
/// ([`children_bits`]).
///
/// Per edge, along its lines of cells (the window's rows for a vertical TG, its
/// columns for a horizontal one), V at the line's two borders, least `lo` and
/// greatest `hi`: the line's cells `s` (`0..8` across V) wholly at lower V than the
/// edge are those with `lo >= (s + 1) side`, `s < floor(lo / side)`, and wholly at
/// higher V those with `hi <= s side`, `s >= ceil(hi / side)` (V relative to the
/// window's first border across V): two shifts a line, and the cells' bits, in
/// their places in the window, from a table ([`LINE_CELLS`]). IN and OUT by LR, as the GQ ROM's codes of each child
/// (the tests' `edge_code`). Only the lines the start's cells reach are coded (the others'
/// bits are never read).
struct LastCells {
    /// Per edge, V at the window's first border along it, relative to its first
    /// border across V.
    v0: [i64; AT_ONCE_EDGES],
    /// Per edge, V's change over a cell along it.
    step: [i64; AT_ONCE_EDGES],
    /// Per edge, V's change (relative to the cell) a cell along the window's
    /// columns and a cell along its rows: a cell `(i, j)` of the window has V1 `v0 +
    /// i di + j dj` (for a vertical TG, `di` is a cell's side across V, negated, and
    /// `dj` the step; for a horizontal one the other way round).
    di: [i64; AT_ONCE_EDGES],
    dj: [i64; AT_ONCE_EDGES],
    /// Per edge, the cells it crosses (neither IN nor OUT).
    cross: [u64; AT_ONCE_EDGES],
    /// Per edge, the [`ActiveEdge`]'s kind.
    kind: [u32; AT_ONCE_EDGES],
    /// The cells OUT for some edge.
    outside: u64,
    /// The cells IN for every edge.
    inside: u64,
    /// How many edges.
    n: usize,
}

/// [`LastCells`]' cells of a line: at `[vertical][k][first][n]`, line `k`'s first
/// `n` cells across V (`first` 1) or its cells from the `n`-th on (`first` 0), as
/// bits `s + 8 k` (row `k`'s, vertical TG) or `8 s + k` (column `k`'s, horizontal
/// TG), `n` in `0..=8`: each line's sets in place, so that a line costs no shift by
/// its place (2.3 KB).
const LINE_CELLS: [[[[u64; 9]; 2]; 8]; 2] = {
    let mut table = [[[[0u64; 9]; 2]; 8]; 2];
    let mut k = 0;
    while k < 8 {
        let mut n = 0;
        while n <= 8 {
            let mut s = 0;
            while s < 8 {
                let (h, v) = (1u64 << (8 * s + k), 1u64 << (s + 8 * k));
                let first = if s < n { 1 } else { 0 };
                table[0][k][first][n] |= h;
                table[1][k][first][n] |= v;
                s += 1;
            }
            n += 1;
        }
        k += 1;
    }
    table
};

/// [`LastCells`]' sets of an edge's first `lines` lines (an even number, at most 8),
/// `(low, high)`: the cells wholly at lower V than the edge and those wholly at
/// higher V, by `table` (the TG's [`LINE_CELLS`]), line `k` of least V `lo + k step`
/// and greatest that plus `span`. In SSE4.1 on x86-64 builds that enable it (the
/// project's x86-64-v2 does): two lines a step, their four cell counts
/// `clamp(v >> CELL_V_BITS, 0, 8)` at once; elsewhere [`line_sets_plain`] (tested
/// against each other).
#[inline(always)]
fn line_sets(table: &[[[u64; 9]; 2]; 8], lo: i64, step: i64, span: i64, lines: usize) -> (u64, u64) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    {
        use std::arch::x86_64::*;
        debug_assert!(lines.is_multiple_of(2) && lines <= 8);
        let (mut low, mut high) = (0u64, 0u64);
        // SAFETY: SSE2 and SSE4.1 operations, which the build enables (this block is
        // compiled only then); the table reads' indices are clamped to `0..=8` just
        // before, within the rows of 9.
        #[allow(unsafe_code, reason = "SSE4.1 in a build that requires it; table indices clamped in SIMD")]
        unsafe {
            // Lines `k` and `k + 1`, V as `i64` in two lanes.
            let mut v = _mm_set_epi64x(lo + step, lo);
            let (span, two_steps) = (_mm_set1_epi64x(span), _mm_set1_epi64x(2 * step));
            let (zero, eight) = (_mm_setzero_si128(), _mm_set1_epi32(8));
            for pair in table.chunks_exact(2).take(lines / 2) {
                let far = _mm_add_epi64(v, span);
                // The high halves `floor(V / 2^32)` (exact as `i32`) of the lines' least
                // and greatest V, then `floor(V / 2^CELL_V_BITS)` by a further shift.
                let halves =
                    _mm_castps_si128(_mm_shuffle_ps::<0b11_01_11_01>(_mm_castsi128_ps(v), _mm_castsi128_ps(far)));
                const _: () = assert!(CELL_V_BITS == 32 + 2);
                let counts = _mm_min_epi32(_mm_max_epi32(_mm_srai_epi32::<2>(halves), zero), eight);
                let (a, b) = (_mm_cvtsi128_si64(counts) as u64, _mm_extract_epi64::<1>(counts) as u64);
                let cell = |line: &[[u64; 9]; 2], first: usize, n: u64| *line[first].get_unchecked(n as u32 as usize);
                low |= cell(&pair[0], 1, a) | cell(&pair[1], 1, a >> 32);
                high |= cell(&pair[0], 0, b) | cell(&pair[1], 0, b >> 32);
                v = _mm_add_epi64(v, two_steps);
            }
        }
        (low, high)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    line_sets_plain(table, lo, step, span, lines)
}

/// [`line_sets`] a line at a time.
#[cfg_attr(
    all(target_arch = "x86_64", target_feature = "sse4.1"),
    allow(dead_code, reason = "the other builds' copy, tested against the SSE4.1 one")
)]
#[inline(always)]
fn line_sets_plain(table: &[[[u64; 9]; 2]; 8], mut lo: i64, step: i64, span: i64, lines: usize) -> (u64, u64) {
    let (mut low, mut high) = (0u64, 0u64);
    for line in table.iter().take(lines) {
        let below = (lo >> CELL_V_BITS).clamp(0, 8) as usize;
        let above = ((lo + span) >> CELL_V_BITS).clamp(0, 8) as usize;
        low |= line[1][below];
        high |= line[0][above];
        lo += step;
    }
    (low, high)
}

/// The last-level cells of a window of [`LastCells`] (corner pixel `(wx, wy)`) that
/// the box `bbox` (pixels, `[x0, x1) x [y0, y1)`, not empty, within the window)
/// meets, as a set of the window: the columns of cells from `x0`'s to `x1 - 1`'s,
/// the rows likewise. The split treats the others as masked ([`children_in_box`]):
/// their codes clip to nothing; [`CellProcessors::last_cells`] takes them as OUT
/// (so not IN), once a polygon rather than by comparisons a cell. The columns'
/// and the rows' sets from two tables ([`WINDOW_COLUMNS`], [`WINDOW_ROWS`]; by
/// shifts and a product they cost some 30 instructions a polygon, `many`'s every
/// small triangle; tested against [`window_box_plain`]).
#[inline(always)]
fn window_box(bbox: [u32; 4], wx: u32, wy: u32) -> u64 {
    let [x0, x1, y0, y1] = bbox;
    let (i0, i1) = ((x0 - wx) / CELL_SIDE, (x1 - 1 - wx) / CELL_SIDE);
    let (j0, j1) = ((y0 - wy) / CELL_SIDE, (y1 - 1 - wy) / CELL_SIDE);
    debug_assert!(i0 <= i1 && i1 < 8 && j0 <= j1 && j1 < 8);
    WINDOW_COLUMNS[(i0 | i1 << 3) as usize & 63] & WINDOW_ROWS[(j0 | j1 << 3) as usize & 63]
}

/// [`window_box`] by shifts (for the tables and tests).
const fn window_box_plain(i0: u32, i1: u32, j0: u32, j1: u32) -> u64 {
    let columns = (0xFFu64 >> (7 - i1) & 0xFF << i0) * 0x0101_0101_0101_0101;
    let rows = !0u64 >> (8 * (7 - j1)) & !0u64 << (8 * j0);
    columns & rows
}

/// [`window_box`]'s columns `i0 ..= i1` of the window (every row), at `i0 | i1 << 3`
/// (empty for `i0 > i1`).
const WINDOW_COLUMNS: [u64; 64] = {
    let mut table = [0; 64];
    let mut k = 0;
    while k < 64 {
        let (i0, i1) = (k as u32 & 7, k as u32 >> 3);
        if i0 <= i1 {
            table[k] = window_box_plain(i0, i1, 0, 7);
        }
        k += 1;
    }
    table
};

/// [`window_box`]'s rows `j0 ..= j1` of the window (every column), at `j0 | j1 << 3`
/// (empty for `j0 > j1`).
const WINDOW_ROWS: [u64; 64] = {
    let mut table = [0; 64];
    let mut k = 0;
    while k < 64 {
        let (j0, j1) = (k as u32 & 7, k as u32 >> 3);
        if j0 <= j1 {
            table[k] = window_box_plain(0, 7, j0, j1);
        }
        k += 1;
    }
    table
};

/// The four children of a window's cell of level L - 1 in a set of [`LastCells`]
/// (`b = 2 dx + 16 dy`): child `c = dx + 2 dy` at bit `c`.
#[inline(always)]
fn children_bits(set: u64, b: u32) -> u32 {
    let t = set >> b;
    (t & 3 | t >> 6 & 0xC) as u32
}

impl LastCells {
    /// The codes of `edges` (at most [`AT_ONCE_EDGES`]) for the window whose corner
    /// is pixel `(wx, wy)`, where the cells of level L - 1 `0 ..= columns` by
    /// `0 ..= rows` are read, the cells the polygon's box `bbox` (inside those
    /// cells) does not meet taken as OUT ([`window_box`]).
    ///
    /// Edge by edge: the four edges in the lanes of AVX2 registers (each line's
    /// counts of every edge in one register, the sets gathered from [`LINE_CELLS`];
    /// out of line, after a detection) cut the instructions (session 26, one frame:
    /// `many` 480 x 270 whole VP 1923.9 → 1889.1 M, 960 x 540 raster 1841 → 1809 M
    /// with the rest of that session's changes) but not the time on this machine's
    /// AMD EPYC: `many` 480 x 270 raster 489 / 487 ms → 506 / 511 ms (gathers), 492 /
    /// 490 / 484 → 497 / 505 / 489 ms with the sets by scalar loads (which counted
    /// 1730.9 M); left out (commit `88d6c75` in main's history).
    #[inline(always)]
    fn new(edges: &[EdgeCode], wx: u32, wy: u32, columns: u32, rows: u32, bbox: [u32; 4]) -> Self {
        debug_assert!(edges.len() <= AT_ONCE_EDGES && columns < WINDOW_SPAN && rows < WINDOW_SPAN);
        let mut codes = Self {
            v0: [0; AT_ONCE_EDGES],
            step: [0; AT_ONCE_EDGES],
            di: [0; AT_ONCE_EDGES],
            dj: [0; AT_ONCE_EDGES],
            cross: [0; AT_ONCE_EDGES],
            kind: [0; AT_ONCE_EDGES],
            outside: !window_box(bbox, wx, wy),
            inside: !0,
            n: edges.len(),
        };
        for (e, edge) in edges.iter().enumerate().take(AT_ONCE_EDGES) {
            let vertical = edge.tg() == Tg::Vertical;
            let (t0, u0, lines) = if vertical { (wy, wx, 2 * rows + 2) } else { (wx, wy, 2 * columns + 2) };
            let step = edge.slope.0 * i64::from(CELL_SIDE);
            let v0 = edge.v_at(i64::from(t0)).0 - EdgeCoord::pixels(i64::from(u0)).0;
            let (low_end, span) = (step.min(0), step.abs() + ((1 << CELL_V_BITS) - 1));
            let (low, high) = line_sets(&LINE_CELLS[usize::from(vertical)], v0 + low_end, step, span, lines as usize);
            let (inside, outside) = if edge.lr() { (high, low) } else { (low, high) };
            codes.outside |= outside;
            codes.inside &= inside;
            codes.cross[e] = !(inside | outside);
            codes.v0[e] = v0;
            codes.step[e] = step;
            let across = -(1i64 << CELL_V_BITS);
            (codes.di[e], codes.dj[e]) = if vertical { (across, step) } else { (step, across) };
            codes.kind[e] = if vertical { KIND_VERTICAL } else { 0 }
                | if edge.lr() { KIND_LR } else { 0 }
                | if step < 0 { KIND_DOWN } else { 0 };
        }
        codes
    }

    /// The active edges of the window's cell at bit `b` ([`LastCells`]) into the
    /// front of `out` (at least as long as the edges), in the polygon's order, as
    /// [`ActiveEdge::at_cell`] gives them; returns how many.
    #[inline(always)]
    fn list(&self, b: u32, out: &mut [ActiveEdge]) -> usize {
        let (i, j) = (i64::from(b & 7), i64::from(b >> 3));
        let out = &mut out[..self.n];
        // The edges crossing the cell, bit `e` for edge `e` (the sets of the edges
        // past the polygon's are empty).
        let mut crossing = 0u32;
        for (e, cross) in self.cross.iter().enumerate() {
            crossing |= ((cross >> b & 1) as u32) << e;
        }
        let mut len = 0;
        while crossing != 0 {
            let e = crossing.trailing_zeros() as usize;
            crossing &= crossing - 1;
            let v1 = self.v0[e] + i * self.di[e] + j * self.dj[e];
            debug_assert!(len <= e);
            // SAFETY: `len` counts the crossing edges before `e`, so `len <= e <
            // self.n`, which is `out.len()` (sliced above).
            #[allow(unsafe_code, reason = "a packed list's index, at most the edge's, which the compiler cannot see")]
            let entry = unsafe { out.get_unchecked_mut(len) };
            *entry =
                ActiveEdge { v1: EdgeCoord(v1), v2: EdgeCoord(v1 + self.step[e]), edge: e as u32, kind: self.kind[e] };
            len += 1;
        }
        len
    }
}

/// The most cells each way of a start at the polygon's size
/// ([`CellProcessors::start_at_size`]).
const MAX_START_SPAN: u32 = 8;
// A start's cells lie in at most 2 x 2 aligned 8 x 8 blocks ([`StartBlocks`]).
const _: () = assert!(MAX_START_SPAN <= 8);

/// The cells of a start ([`CellProcessors::start_at_size`]), the block of cells
/// `cx0 ..= cx1` by `cy0 ..= cy1` of one level (at most [`MAX_START_SPAN`] each way),
/// as the aligned 8 x 8 blocks of cells it meets (at most 2 x 2), in Z order
/// ([`Self::block`]). A block's 64 cells come after every cell of the blocks before it
/// in Z order and before those of the blocks after it, and the bits of a block's word
/// go in Z order: so the cells in the order of the blocks and of their bits are in Z
/// order, the order the descent visits them, with no sort (`start_cells_are_in_z_order`
/// checks it against a sort), and a block's word of mask bits is read at once.
#[derive(Clone, Copy, Debug)]
struct StartBlocks {
    /// The first cell's column and row.
    cx0: u32,
    cy0: u32,
    /// The last cell's column and row.
    cx1: u32,
    cy1: u32,
    /// How many blocks: 1, 2 or 4.
    count: u32,
    /// Block `i`'s column is the first block's plus bit `step_x` of `i`, its row plus
    /// bit `step_y` ([`Self::NO_STEP`]: none of `i < 4`).
    step_x: u32,
    step_y: u32,
}

impl StartBlocks {
    /// A bit of the blocks' index `i < 4` that is never set.
    const NO_STEP: u32 = 2;

    /// The blocks of the start of `columns + 1` by `rows + 1` cells from `(cx0, cy0)`.
    /// Of 2 x 2 blocks, the two of a row go first, unless the border between the two
    /// columns is that of a larger cell than the border between the rows (the first
    /// block's column ends in more one bits than its row): then those of a column.
    #[inline(always)]
    fn new(cx0: u32, cy0: u32, columns: u32, rows: u32) -> Self {
        let (cx1, cy1) = (cx0 + columns, cy0 + rows);
        let (bx0, by0) = (cx0 >> 3, cy0 >> 3);
        let (count, step_x, step_y) = match (cx1 >> 3 != bx0, cy1 >> 3 != by0) {
            (false, false) => (1, Self::NO_STEP, Self::NO_STEP),
            (true, false) => (2, 0, Self::NO_STEP),
            (false, true) => (2, Self::NO_STEP, 0),
            (true, true) if bx0.trailing_ones() > by0.trailing_ones() => (4, 1, 0),
            (true, true) => (4, 0, 1),
        };
        Self { cx0, cy0, cx1, cy1, count, step_x, step_y }
    }

    /// Block `i < count` in Z order, as `(bz, bx, by, cells)`: its Z-order index `bz`
    /// and place `(bx, by)` among the level's 8 x 8 blocks, and the start's cells in
    /// it as a word in Z order (bit `p` for the cell of Z-order index `bz << 6 | p`,
    /// at `(8 bx + Z_COLUMN[p], 8 by + Z_ROW[p])`).
    #[inline(always)]
    fn block(&self, i: u32) -> (usize, u32, u32, u64) {
        let (bx, by) = ((self.cx0 >> 3) + (i >> self.step_x & 1), (self.cy0 >> 3) + (i >> self.step_y & 1));
        // The start's first and last column and row in this block.
        let a = if bx == self.cx0 >> 3 { self.cx0 & 7 } else { 0 };
        let b = if bx == self.cx1 >> 3 { self.cx1 & 7 } else { 7 };
        let c = if by == self.cy0 >> 3 { self.cy0 & 7 } else { 0 };
        let d = if by == self.cy1 >> 3 { self.cy1 & 7 } else { 7 };
        (morton(bx, by), bx, by, Z_COLUMNS[(a | b << 3) as usize] & Z_ROWS[(c | d << 3) as usize])
    }

    /// The cells of `open` (of block `(bz, bx, by)`'s word, [`Self::block`], less
    /// those the caller passes over) in Z order: each one's Z-order index and its
    /// column and row from the start's first cell.
    #[inline(always)]
    fn cells(&self, bz: usize, bx: u32, by: u32, mut open: u64) -> impl Iterator<Item = (usize, u32, u32)> {
        let (cx0, cy0) = (self.cx0, self.cy0);
        std::iter::from_fn(move || {
            if open == 0 {
                return None;
            }
            let p = open.trailing_zeros() as usize;
            open &= open - 1;
            Some((bz << 6 | p, bx * 8 + Z_COLUMN[p] - cx0, by * 8 + Z_ROW[p] - cy0))
        })
    }
}

/// The widest and highest box (pixels) [`CellProcessors::box_marked`] reads the marks
/// under: its cells then lie in at most 2 x 2 blocks of [`BLOCK_SIDE`] cells.
pub const MARKED_BOX: u32 = 16;
const _: () = assert!(MARKED_BOX <= (BLOCK_SIDE - 1) * CELL_SIDE + 1);

/// The side of an aligned block of cells whose mask bits are one word (8 x 8 = 64).
const BLOCK_SIDE: u32 = 8;
/// The side of a last-level cell in pixels.
const CELL_SIDE: u32 = super::spp::CELL_SIDE;

/// The column of the cell of Z-order index `p` in an 8 x 8 block (`p`'s even bits).
const Z_COLUMN: [u32; 64] = z_places(0);
/// The row of the cell of Z-order index `p` in an 8 x 8 block (`p`'s odd bits).
const Z_ROW: [u32; 64] = z_places(1);
/// The cells of an 8 x 8 block in columns `a ..= b`, as a word in Z order, at `a | b << 3`.
const Z_COLUMNS: [u64; 64] = z_ranges(&Z_COLUMN);
/// The cells of an 8 x 8 block in rows `a ..= b`, as a word in Z order, at `a | b << 3`.
const Z_ROWS: [u64; 64] = z_ranges(&Z_ROW);

/// Builds [`Z_COLUMN`] (`odd` 0) and [`Z_ROW`] (`odd` 1): the bits of `p` at
/// positions `2 i + odd` gathered.
const fn z_places(odd: u32) -> [u32; 64] {
    let mut table = [0; 64];
    let mut p = 0;
    while p < 64 {
        let mut i = 0;
        while i < 3 {
            table[p] |= ((p as u32 >> (2 * i + odd)) & 1) << i;
            i += 1;
        }
        p += 1;
    }
    table
}

/// Builds [`Z_COLUMNS`] and [`Z_ROWS`] from [`Z_COLUMN`] or [`Z_ROW`] (`place`).
const fn z_ranges(place: &[u32; 64]) -> [u64; 64] {
    let mut table = [0; 64];
    let mut range = 0;
    while range < 64 {
        let (a, b) = (range as u32 & 7, range as u32 >> 3);
        let mut p = 0;
        while p < 64 {
            if place[p] >= a && place[p] <= b {
                table[range] |= 1 << p;
            }
            p += 1;
        }
        range += 1;
    }
    table
}

/// The children of `cell` (bit `c = dx + 2 dy`) that meet the box `bbox` (pixels,
/// `[x0, x1) x [y0, y1)`, not empty), the children's cells being `2^shift` pixels,
/// given that `cell` itself meets the box (every cell the descent splits does: the
/// starting cells hold or meet it, and a child the box misses is not descended). Then
/// the box reaches the cell's first column of children when it starts before the
/// cell's middle pixel line, and its second when it ends after it: one comparison
/// a column and a row against the middle lines, and a 16-entry table.
#[inline(always)]
fn children_in_box(cell: Cell, shift: u32, bbox: [u32; 4]) -> u8 {
    let [x0, x1, y0, y1] = bbox;
    // The cell's middle lines, between its two columns and its two rows of children.
    let (mx, my) = ((2 * cell.x + 1) << shift, (2 * cell.y + 1) << shift);
    let columns = u32::from(x0 < mx) | u32::from(x1 > mx) << 1;
    let rows = u32::from(y0 < my) | u32::from(y1 > my) << 1;
    BOX_CHILDREN[(columns | rows << 2) as usize]
}

/// [`children_in_box`]'s table: at `columns | rows << 2` (bit 0: the first column or
/// row of children, bit 1 the second), the children of those columns and rows.
const BOX_CHILDREN: [u8; 16] = {
    let mut table = [0u8; 16];
    let mut i = 0;
    while i < 16 {
        let (columns, rows) = (i as u8 & 3, (i >> 2) as u8 & 3);
        let mut c = 0;
        while c < 4 {
            if columns >> (c & 1) & 1 == 1 && rows >> (c >> 1) & 1 == 1 {
                table[i] |= 1 << c;
            }
            c += 1;
        }
        i += 1;
    }
    table
};

/// One step of the SPP's `q` (an eighth of a pixel, [`SPP_V_BITS`]) in
/// [`EdgeCoord`] units: V further apart than this rounds to different `q`.
const Q_STEP: i64 = 1 << (EDGE_FRAC_BITS - SPP_V_BITS);

/// Whether a cell's two active edges `list` close the polygon over the whole cell
/// (`cell`, of `side` pixels), so that no subpixel of it can be the polygon's: two
/// edges of the same TG and opposite LR (the polygon lies between them, above the
/// LR = 1 edge's V and below the other's) whose V are ordered the other way by at
/// least a step of `q` ([`Q_STEP`]) at both of the cell's borders, so on every pixel
/// line between (V is linear). Such cells lie beyond a polygon's sharp vertices,
/// where its edges' lines have crossed: each edge alone crosses them, and without
/// this test they are split down to the last level and their fragments' codes come
/// out empty (two fifths of `default`'s fragments with edges were empty, most of
/// them here).
///
/// Sound for the SPPs: on every pixel line the LR = 1 edge's `q` is greater than the
/// other's (or both saturate alike at the row table's bound), and at such a pair of
/// lines the LR = 1 edge's greater-side set lies within the other's, whose complement
/// the LR = 0 edge takes: the AND is empty in every pixel (a fact of both table
/// builds, checked over every pair of row-table entries by a test in `spp`). The
/// exact mode's sets are the sides of lines within 2^-16 pixel of these V, so
/// disjoint too. The exact rule of the vertex pixels samples lines where the table's
/// rounding no longer applies, so a cell near either edge's end is left to the SPPs.
/// Cells of three edges or more are not tested: on `terrain` and `many` the pairs
/// cost more than they saved (BENCHMARKS.md, session 8); nor are last-level cells,
/// where a closed cell is a single empty fragment (session 19).
///
/// A modern shortcut beside the machine's GQ (whose CI/CRI codes are per edge),
/// taken with counting off only ([`CellProcessors::descend_filling`]): the same
/// subpixels, less work.
#[inline(always)]
fn band_closed(list: &[ActiveEdge], edges: &[EdgeCode], cell: Cell, side: u32) -> bool {
    let [a, b] = list else {
        return false;
    };
    if (a.kind ^ b.kind) & (KIND_VERTICAL | KIND_LR) != KIND_LR {
        return false;
    }
    let (lower, upper) = if a.kind & KIND_LR != 0 { (a, b) } else { (b, a) };
    lower.v1.0 - upper.v1.0 >= Q_STEP
        && lower.v2.0 - upper.v2.0 >= Q_STEP
        && !ends_near(&edges[a.edge as usize].ends, cell.x * side, cell.y * side, side)
        && !ends_near(&edges[b.edge as usize].ends, cell.x * side, cell.y * side, side)
}

/// One edge's codes for the four children of a cell ([`child_codes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct ChildCodes {
    /// An entry of [`CHILD_CODES`]: CI in bits 0-3 (the children wholly on the
    /// polygon's side, bit `dx + 2 dy`), CRI in bits 4-7 (those not wholly off it),
    /// `CRI & !CI` in bits 8-11 (those the edge crosses).
    codes: u32,
    /// The midpoint `(V1 + V2) / 2`, relative to the cell.
    vm: i64,
}

/// The GQ ROM's answer ([`GqRom`](super::tables::GqRom), P1 eq. 1) for one edge with
/// `V1 = d1`, `V2 = d2` relative to the cell, half a cell `half` and TG, LR, `V1 > V2`
/// in `kind` (see [`ActiveEdge`]), by comparisons and one read of [`CHILD_CODES`]
/// (the same bits as the plain definition `edge_code`, tested). A child's stretch of
/// the line is `(V1, Vm)` or `(Vm, V2)` (halves 0 and 1 along V's lines); with `lo`,
/// `hi` its least and greatest V, the ROM's readings are the thermometer codes
/// `(hi <= 0) + (hi <= half)` (how many of the children across it the line lies at or
/// before the near border of) and `(lo >= half) + (lo >= 2 half)` (at or beyond the far
/// border of), each 0, 1 or 2 (`half > 0`), two bits of the table's address each
/// ([`ChildThresholds`]): 8 comparisons and no variable shift, the children's bit
/// order by TG, the sides by LR and which half is which by [`KIND_DOWN`] left to the
/// table. The midpoint lies between V1 and V2, so the stretches are `(lo, Vm)` and
/// `(Vm, hi)` with `lo`, `hi` the least and greatest of V1, V2: the first half's when V
/// increases, the second's when it decreases ([`KIND_DOWN`], known for the edge).
///
/// On x86-64, the 8 comparisons as the sign bits of four SSE2 subtractions of two
/// lanes, gathered by two `shufps` and two `movmskps` (~30 instructions an edge
/// rather than ~42: the GQ's splits make ~146 k of these on `default`); elsewhere
/// [`child_codes_plain`]. The same address either way (tested).
#[inline(always)]
fn child_codes(d1: i64, d2: i64, t: &ChildThresholds, kind: u32) -> ChildCodes {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // The midpoint's comparisons on the sum: `(d1 + d2) >> 1 < t` exactly when
        // `d1 + d2 < 2 t` (a shift of two 64-bit lanes is no SSE2 instruction).
        let sum = d1 + d2;
        let (lo, hi) = if kind & KIND_DOWN != 0 { (d2, d1) } else { (d1, d2) };
        // SAFETY: SSE2 operations on values in registers, and SSE2 is x86-64's
        // baseline.
        #[allow(unsafe_code, reason = "SSE2 intrinsics, x86-64's baseline")]
        let bits = unsafe {
            let (m, h, l) = (_mm_set1_epi64x(sum), _mm_set1_epi64x(hi), _mm_set1_epi64x(lo));
            // Lanes (weaker, stronger) of each code; the high halves of the
            // differences hold their signs, the code's two bits.
            let before = _mm_shuffle_ps::<0b11_01_11_01>(
                _mm_castsi128_ps(_mm_sub_epi64(m, t.before_sum)),
                _mm_castsi128_ps(_mm_sub_epi64(h, t.before)),
            );
            let short = _mm_shuffle_ps::<0b11_01_11_01>(
                _mm_castsi128_ps(_mm_sub_epi64(l, t.short)),
                _mm_castsi128_ps(_mm_sub_epi64(m, t.short_sum)),
            );
            (_mm_movemask_ps(before) | _mm_movemask_ps(short) << 4) as u32
        };
        let address = (bits | kind) as usize & (CHILD_CODES.len() - 1);
        ChildCodes { codes: u32::from(CHILD_CODES[address]), vm: sum >> 1 }
    }
    #[cfg(not(target_arch = "x86_64"))]
    child_codes_plain(d1, d2, t.half, kind)
}

/// [`child_codes`] one comparison at a time, by its definition.
#[cfg_attr(target_arch = "x86_64", allow(dead_code, reason = "the other targets' copy, tested against the SSE2 one"))]
#[inline(always)]
fn child_codes_plain(d1: i64, d2: i64, half: i64, kind: u32) -> ChildCodes {
    let dm = (d1 + d2) >> 1;
    let (lo, hi) = if kind & KIND_DOWN != 0 { (d2, d1) } else { (d1, d2) };
    // `neg(v)`: 1 when `v < 0`, by its sign bit (|V| < 2^46: no overflow).
    let neg = |v: i64| (v as u64 >> 63) as u32;
    // A thermometer code as two bits: the weaker condition's in bit 0, the
    // stronger's (which implies it) in bit 1 ([`CHILD_CODES`]).
    let code = |weaker: u32, stronger: u32| weaker | stronger << 1;
    // The stretch `(lo, Vm)`: its greatest V is Vm; `(Vm, hi)`: its least is Vm.
    let before_low = code(neg(dm - (half + 1)), neg(dm - 1));
    let before_high = code(neg(hi - (half + 1)), neg(hi - 1));
    // Two less the "at or beyond" codes.
    let short_low = code(neg(lo - 2 * half), neg(lo - half));
    let short_high = code(neg(dm - 2 * half), neg(dm - half));
    let address =
        (before_low | before_high << 2 | short_low << 4 | short_high << 6 | kind) as usize & (CHILD_CODES.len() - 1);
    ChildCodes { codes: u32::from(CHILD_CODES[address]), vm: dm }
}

/// [`child_codes`]' thresholds for a cell of half side `half`, made once a split: V
/// less each threshold is negative exactly when V lies below it, which is the code's
/// condition (`V <= 0` is `V - 1 < 0`). Two lanes a code, the weaker condition in
/// lane 0: "at or before" `V <= half` and `V <= 0`; "short of" `V < 2 half` and
/// `V < half`; and each doubled, for the midpoint's sum.
#[derive(Clone, Copy)]
struct ChildThresholds {
    #[cfg(target_arch = "x86_64")]
    before: std::arch::x86_64::__m128i,
    #[cfg(target_arch = "x86_64")]
    short: std::arch::x86_64::__m128i,
    #[cfg(target_arch = "x86_64")]
    before_sum: std::arch::x86_64::__m128i,
    #[cfg(target_arch = "x86_64")]
    short_sum: std::arch::x86_64::__m128i,
    #[cfg(not(target_arch = "x86_64"))]
    half: i64,
}

impl ChildThresholds {
    #[inline(always)]
    fn new(half: i64) -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::*;
            // SAFETY: SSE2 operations on values in registers, and SSE2 is x86-64's
            // baseline.
            #[allow(unsafe_code, reason = "SSE2 intrinsics, x86-64's baseline")]
            unsafe {
                Self {
                    before: _mm_set_epi64x(1, half + 1),
                    short: _mm_set_epi64x(half, 2 * half),
                    before_sum: _mm_set_epi64x(2, 2 * (half + 1)),
                    short_sum: _mm_set_epi64x(2 * half, 4 * half),
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        Self { half }
    }
}

/// [`child_codes`]'s table: at address `b0 | b1 << 2 | a0 << 4 | a1 << 6 | kind`
/// (thermometer codes `b` "at or before the near border", `a` "at or beyond the far
/// border" of the stretches `(lo, Vm)` (0) and `(Vm, hi)` (1), each as two bits, the
/// weaker condition's and the stronger's: 0, 1 and 3 for 0, 1 and 2 (for `a`, two less
/// the code); `kind` [`KIND_VERTICAL`], [`KIND_LR`] and [`KIND_DOWN`], which makes
/// stretch 1 the first half along V's lines), CI in bits 0-3, CRI in bits 4-7, `CRI &
/// !CI` in bits 8-11. Addresses with a two-bit field 2 never occur.
const CHILD_CODES: [u16; 2048] = child_code_table();

/// Builds [`CHILD_CODES`]: the bits the plain `edge_code` forms, by the same rule.
const fn child_code_table() -> [u16; 2048] {
    let mut table = [0u16; 2048];
    let mut address = 0;
    while address < 2048 {
        /// A two-bit field 0, 1 or 3 is the code 0, 1 or 2 (2 never occurs: read as 1).
        const fn code(field: usize) -> usize {
            field - (field >> 1)
        }
        let (mut b0, mut b1) = (code(address & 3), code(address >> 2 & 3));
        // The address holds two less the "at or beyond" codes.
        let (mut a0, mut a1) = (2 - code(address >> 4 & 3), 2 - code(address >> 6 & 3));
        if address as u32 & KIND_DOWN != 0 {
            // V decreases: the stretch `(Vm, hi)` is the first half along V's lines.
            (b0, b1, a0, a1) = (b1, b0, a1, a0);
        }
        let vertical = address as u32 & KIND_VERTICAL != 0;
        let lr = address as u32 & KIND_LR != 0;
        // Child bit of (along, across) = (0, 1) and (1, 0), as in `edge_code`.
        let (p01, p10) = if vertical { (1, 2) } else { (2, 1) };
        // Code 2: at or before both the near (0) and far (half) lines; 1: the far only.
        let before = (b0 == 2) as u32 | ((b0 >= 1) as u32) << p01 | ((b1 == 2) as u32) << p10 | ((b1 >= 1) as u32) << 3;
        // Code 2: at or beyond half and 2 half; 1: half only.
        let after = (a0 >= 1) as u32 | ((a0 == 2) as u32) << p01 | ((a1 >= 1) as u32) << p10 | ((a1 == 2) as u32) << 3;
        let (inside, outside) = if lr { (before, after) } else { (after, before) };
        let cri = !outside & 0xF;
        table[address] = (inside | cri << 4 | (cri & !inside) << 8) as u16;
        address += 1;
    }
    table
}

/// One edge's codes for the four children of a cell ([`edge_code`]).
#[cfg(test)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct EdgeChildCodes {
    /// CI: the children wholly on the polygon's side (bit `dx + 2 dy`).
    ci: u8,
    /// CRI: the children not wholly off it.
    cri: u8,
    /// The midpoint `(V1 + V2) / 2`, relative to the cell.
    vm: i64,
}

/// The GQ ROM's answer ([`GqRom`](super::tables::GqRom), P1 eq. 1) for one edge with `V1 = d1`, `V2 = d2`
/// relative to the cell and half a cell `half`, by comparisons instead of the look-up
/// (the same bits, tested against the ROM): a child's stretch of the line is `(V1,
/// Vm)` or `(Vm, V2)`, and for the child `across` half cells from the origin the ROM
/// reads "the line lies at or before the child's near border" as `max <= across half`
/// (its reading of the high bits of V one LSB lower) and "at or beyond its far
/// border" as `min >= (across + 1) half`. With LR = 1 the first is IN and the second
/// OUT; with LR = 0 the other way round. The plain definition [`child_codes`] is
/// tested against.
#[cfg(test)]
fn edge_code(d1: i64, d2: i64, half: i64, vertical: bool, lr: bool) -> EdgeChildCodes {
    let dm = (d1 + d2) >> 1;
    let (lo0, hi0) = (d1.min(dm), d1.max(dm));
    let (lo1, hi1) = (dm.min(d2), dm.max(d2));
    // Child bit of (along, across) = (0, 1) and (1, 0): `dx + 2 dy` with along the
    // rows of a vertical edge (dy) and the columns of a horizontal one (dx).
    let (p01, p10) = if vertical { (1, 2) } else { (2, 1) };
    let before =
        u8::from(hi0 <= 0) | u8::from(hi0 <= half) << p01 | u8::from(hi1 <= 0) << p10 | u8::from(hi1 <= half) << 3;
    let after = u8::from(lo0 >= half)
        | u8::from(lo0 >= 2 * half) << p01
        | u8::from(lo1 >= half) << p10
        | u8::from(lo1 >= 2 * half) << 3;
    let (inside, outside) = if lr { (before, after) } else { (after, before) };
    EdgeChildCodes { ci: inside, cri: !outside & 0xF, vm: dm }
}

/// Appends the four children of `cell` to a recorder with what the GQ decided about
/// each (`cri_all`: IN or CR by the edges; `m`: covered by the mask; `ci`: IN after
/// the mask). Out of line and cold: it only runs when pictures are asked for, and
/// keeps [`CellProcessors::split`]'s counting path short.
#[cold]
#[inline(never)]
fn record_children(rec: &mut Vec<CellRecord>, cell: Cell, cri_all: u8, m: u8, ci: u8) {
    for c in 0..4u32 {
        let kind = if cri_all >> c & 1 == 0 {
            CellKind::Outside
        } else if m >> c & 1 == 1 {
            CellKind::Masked
        } else if ci >> c & 1 == 1 {
            CellKind::Inside
        } else {
            CellKind::Crossed
        };
        let child = Cell { level: cell.level + 1, x: cell.x * 2 + (c & 1), y: cell.y * 2 + (c >> 1) };
        rec.push((child, kind));
    }
}

#[cfg(test)]
mod tests {
    use super::super::edge::{ScreenFx, SNAP_ONE};
    use super::*;

    /// Z order: a bijection of the square, a cell's four children one nibble of the
    /// next level at its index times four, its parent at its index over four.
    #[test]
    fn morton_order_puts_siblings_in_a_nibble() {
        for level in 0..=6u32 {
            let side = 1u32 << level;
            let mut seen = vec![false; (side * side) as usize];
            for y in 0..side {
                for x in 0..side {
                    let z = morton(x, y);
                    assert!(!seen[z], "level {level}: ({x}, {y}) shares index {z}");
                    seen[z] = true;
                    assert_eq!(z >> 2, morton(x >> 1, y >> 1));
                    assert_eq!(z & 3, (x & 1 | (y & 1) << 1) as usize);
                }
            }
        }
        assert_eq!(morton(0xFFFF, 0xFFFF), u32::MAX as usize);
        // The table's copy is the bit-by-bit definition.
        let mut next = xorshift(0x2545_F491_4F6C_DD1D_u64);
        for i in 0..100_000u32 {
            let (x, y) =
                if i < 65_536 { (i, i.rotate_left(8) & 0xFFFF) } else { (next(1 << 32) as u32, next(1 << 32) as u32) };
            assert_eq!(morton(x, y), morton_plain(x, y), "({x}, {y})");
        }
    }

    /// The memory's cells, one by one and as nibbles of children, and its pre-masks:
    /// the cells off the screen read covered, and survive a clear.
    #[test]
    fn mask_memory_cells_and_children() {
        // Level 4: a 16 x 16 square, of which 11 x 7 cells touch the screen.
        let mut m = MaskMemory::new(4, 11, 7);
        for y in 0..16 {
            for x in 0..16 {
                assert_eq!(m.get(x, y), x >= 11 || y >= 7, "({x}, {y})");
            }
        }
        m.set(3, 5);
        assert!(m.get(3, 5));
        assert_eq!(m.children(morton(1, 2)), 1 << 3);
        m.set_children(morton(0, 0), 0b0110);
        assert!(!m.get(0, 0) && m.get(1, 0) && m.get(0, 1) && !m.get(1, 1));
        m.clear();
        assert!(!m.get(3, 5) && !m.get(1, 0) && m.get(11, 0) && m.get(0, 7));
        // Children (10, 6), (11, 6), (10, 7), (11, 7): only the first is on the screen.
        assert_eq!(m.children(morton(5, 3)), 0b1110);
    }

    /// A row of an 8 x 8 block of cells is the cells' bits one by one: random
    /// memories of every size up to 64 x 64 cells, screens smaller than the square.
    #[test]
    fn block_row_is_the_row_of_cells() {
        let mut state = 0x0123_4567_89AB_CDEF_u64;
        for level in 0..=6u32 {
            let side = 1usize << level;
            for _ in 0..20 {
                let mut m = MaskMemory::new(level, side - side / 3, side - side / 5);
                for w in &mut m.bits {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    *w |= state;
                }
                if side * side < 64 {
                    m.bits[0] &= (1u64 << (side * side)) - 1;
                }
                for cy in 0..side {
                    for cx in 0..side {
                        let row = m.block_row(cx, cy);
                        for i in 0..8 {
                            let x = (cx & !7) + i;
                            let want = x < side && m.get(x, cy);
                            assert_eq!(row >> i & 1 == 1, want, "level {level}, cell ({x}, {cy})");
                        }
                    }
                }
            }
        }
    }

    /// [`edge_code`]'s comparisons are the ROM's answer, as `split` formed it before
    /// (two readings of the high bits, V and V one LSB lower, on half-cell lines):
    /// every level, both TG and LR, values on, near and far from the half-cell lines.
    #[test]
    fn edge_code_is_the_rom() {
        let rom = GqRom::get();
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut next = move |n: i64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as i64
        };
        for k in 0..400_000 {
            let half_shift = EDGE_FRAC_BITS + 1 + (k % 12) as u32;
            let half = 1i64 << half_shift;
            // A value in half cells from -3 to 5, on a half-cell line, one off it, or
            // anywhere.
            let mut value = || {
                let base = (next(9) - 3) * half;
                match next(4) {
                    0 => base,
                    1 => base + next(3) - 1,
                    _ => base + next(half),
                }
            };
            let (d1, d2) = (value(), value());
            for vertical in [false, true] {
                for lr in [false, true] {
                    let tg = if vertical { Tg::Vertical } else { Tg::Horizontal };
                    let dm = (d1 + d2) >> 1;
                    let b = |d: i64| (d >> half_shift).clamp(-1, 2) as i32;
                    let address = |b1: i32, bm: i32, b2: i32| GqRom::address(tg, lr, b1, bm, b2);
                    let at_or_after = rom.lookup(address(b(d1), b(dm), b(d2)));
                    let at_or_before = rom.lookup(address(b(d1 - 1), b(dm - 1), b(d2 - 1)));
                    let (ci, cri) = if lr { (at_or_before.0, at_or_after.1) } else { (at_or_after.0, at_or_before.1) };
                    let want = EdgeChildCodes { ci, cri, vm: dm };
                    assert_eq!(
                        edge_code(d1, d2, half, vertical, lr),
                        want,
                        "d1 {d1}, d2 {d2}, half {half}, {tg:?}, lr {lr}"
                    );
                    let kind = if vertical { KIND_VERTICAL } else { 0 }
                        | if lr { KIND_LR } else { 0 }
                        | if d1 > d2 { KIND_DOWN } else { 0 };
                    let codes = u32::from(ci) | u32::from(cri) << 4 | u32::from(cri & !ci) << 8;
                    let want = ChildCodes { codes, vm: dm };
                    let fast = child_codes(d1, d2, &ChildThresholds::new(half), kind);
                    assert_eq!(fast, want, "d1 {d1}, d2 {d2}, half {half}, {tg:?}, lr {lr}");
                    let plain = child_codes_plain(d1, d2, half, kind);
                    assert_eq!(plain, want, "plain: d1 {d1}, d2 {d2}, half {half}, {tg:?}, lr {lr}");
                }
            }
        }
    }

    /// [`write_children`] writes each child's copy as [`write_children_plain`] does
    /// (the copies of both TG, LR and slopes, random V and ends) and moves only the
    /// crossed children's ends, leaving every other entry as it was.
    #[test]
    fn child_writes_are_the_plain_ones() {
        let mut next = xorshift(0x2545_F491_4F6C_DD1D);
        let stride = 8;
        let sentinel = ActiveEdge { edge: u32::MAX, kind: u32::MAX, v1: EdgeCoord(-1), v2: EdgeCoord(-1) };
        for _ in 0..20_000 {
            let half = 1i64 << (EDGE_FRAC_BITS + 1 + next(12) as u32);
            let mut value = || next(1 << 44) as i64 - (1 << 43);
            let (v1, v2, vm) = (value(), value(), value());
            let kind = next(8) as u32 * KIND_VERTICAL;
            let a = ActiveEdge { edge: next(1000) as u32, kind, v1: EdgeCoord(v1), v2: EdgeCoord(v2) };
            let ends: [usize; 4] = std::array::from_fn(|c| c * stride + next(stride as u64) as usize);
            let crossed = next(16) as u32;
            let (mut fast, mut plain) = (vec![sentinel; 4 * stride], vec![sentinel; 4 * stride]);
            let mut fast_ends = ends;
            // SAFETY: `ends[c] < (c + 1) stride`, as made above.
            #[allow(unsafe_code, reason = "the function's own test, its bound kept")]
            unsafe {
                write_children(&mut fast, &mut fast_ends, &a, vm, half, crossed)
            };
            write_children_plain(&mut plain, &ends, &a, vm, half);
            assert_eq!(fast, plain, "{a:?} vm {vm} half {half}");
            let want: [usize; 4] = std::array::from_fn(|c| ends[c] + (crossed >> c & 1) as usize);
            assert_eq!(fast_ends, want);
        }
    }

    /// [`line_sets`] (SSE4.1 in this build) gives [`line_sets_plain`]'s sets: both
    /// TG's tables, every even number of lines, V and steps from well below the
    /// window to well above it (every count clamped both ways), spans of a cell to
    /// two.
    #[test]
    fn line_sets_are_the_plain_ones() {
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        let cell = 1i64 << CELL_V_BITS;
        let (mut clamped_low, mut clamped_high) = (0, 0);
        for _ in 0..200_000 {
            let table = &LINE_CELLS[next(2) as usize];
            let lines = 2 + 2 * next(4) as usize;
            let step = next(2 * cell as u64 + 1) as i64 - cell;
            let span = step.abs() + cell - 1;
            let lo = next(32 * cell as u64) as i64 - 12 * cell;
            let want = line_sets_plain(table, lo, step, span, lines);
            assert_eq!(line_sets(table, lo, step, span, lines), want, "lo {lo} step {step} lines {lines}");
            clamped_low += usize::from(lo < 0);
            clamped_high += usize::from(lo + span > 8 * cell);
        }
        assert!(clamped_low > 10_000 && clamped_high > 10_000, "{clamped_low} {clamped_high}");
    }

    /// [`derive_start_list`] gives [`ActiveEdge::at_cell`]'s values for the cells of a
    /// 3 x 3 block from its first cell's, and the IN and OUT of every edge's codes:
    /// random edges of both TG and LR, cells of several levels.
    #[test]
    fn start_lists_are_at_cell() {
        let snap = i64::from(SNAP_ONE);
        let root_side = 2048;
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15_u64);
        let mut checked = 0;
        for k in 0..4000 {
            // Edges anywhere on a 2048-pixel screen, up to 200 pixels long each way.
            let a = (next(2048 * snap as u64) as i64, next(2048 * snap as u64) as i64);
            let b = (
                (a.0 + next(400 * snap as u64) as i64 - 200 * snap).clamp(0, 2048 * snap - 1),
                (a.1 + next(400 * snap as u64) as i64 - 200 * snap).clamp(0, 2048 * snap - 1),
            );
            let fx = |v: (i64, i64)| (ScreenFx(v.0 as i32), ScreenFx(v.1 as i32));
            let Some(e) = EdgeCode::new(fx(a), fx(b), k % 2 == 0, root_side) else {
                continue;
            };
            let side = 8i64 << next(4);
            // A block around the edge's first end.
            let (cx0, cy0) = ((a.0 / snap / side - 1).max(0), (a.1 / snap / side - 1).max(0));
            let first = ActiveEdge::at_cell(3, &e, cx0 * side, cy0 * side, side);
            let units = EdgeCoord::pixels(side).0;
            for dy in 0..3u32 {
                for dx in 0..3u32 {
                    let mut out = [ActiveEdge::EMPTY];
                    let kept = derive_start_list(&[StartEdge::new(first, units)], &mut out, dx, dy);
                    let (px, py) = ((cx0 + i64::from(dx)) * side, (cy0 + i64::from(dy)) * side);
                    let want = ActiveEdge::at_cell(3, &e, px, py, side);
                    assert_eq!(out[0], want, "cell ({dx}, {dy}) of side {side}");
                    let (lo, hi) = (want.v1.0.min(want.v2.0), want.v1.0.max(want.v2.0));
                    let (near, far) = (hi <= 0, lo >= units);
                    let (inside, outside) = if want.lr() { (near, far) } else { (far, near) };
                    assert_eq!(kept, if outside { None } else { Some(usize::from(!inside)) });
                    checked += 1;
                }
            }
        }
        assert!(checked > 30_000, "{checked} cells checked");
    }

    /// [`StartBlocks`] gives a start's cells, in the order of its blocks and of
    /// their bits, with their Z-order indices, as a sort by them would: every block
    /// of up to 8 x 8 cells from the first 40 x 40 cells.
    #[test]
    fn start_cells_are_in_z_order() {
        for cy0 in 0..40u32 {
            for cx0 in 0..40u32 {
                for (columns, rows) in (0..64u32).map(|i| (i & 7, i >> 3)) {
                    let blocks = StartBlocks::new(cx0, cy0, columns, rows);
                    let mut got = Vec::new();
                    for i in 0..blocks.count {
                        let (bz, bx, by, cells) = blocks.block(i);
                        assert_eq!(bz, morton(bx, by));
                        let mut open = cells;
                        while open != 0 {
                            let p = open.trailing_zeros() as usize;
                            open &= open - 1;
                            got.push((bz << 6 | p, bx * 8 + Z_COLUMN[p], by * 8 + Z_ROW[p]));
                        }
                    }
                    let mut want: Vec<(usize, u32, u32)> = (cy0..=cy0 + rows)
                        .flat_map(|y| (cx0..=cx0 + columns).map(move |x| (morton(x, y), x, y)))
                        .collect();
                    want.sort_unstable();
                    assert_eq!(got, want, "start at ({cx0}, {cy0}), {columns} x {rows}");
                }
            }
        }
    }

    /// [`window_box`] (its tables) is the set of the window's last-level cells that
    /// meet the box, by the definition, for every box in a window, at two corners.
    #[test]
    fn window_box_is_the_cells_meeting_the_box() {
        for (wx, wy) in [(0u32, 0u32), (24, 40)] {
            for x0 in 0..32 {
                for x1 in x0 + 1..=32 {
                    for y0 in 0..32 {
                        for y1 in y0 + 1..=32 {
                            let want = (0..64u32).fold(0u64, |w, bit| {
                                let (i, j) = (bit & 7, bit >> 3);
                                let meets = 4 * i < x1 && 4 * i + 4 > x0 && 4 * j < y1 && 4 * j + 4 > y0;
                                w | u64::from(meets) << bit
                            });
                            let got = window_box([wx + x0, wx + x1, wy + y0, wy + y1], wx, wy);
                            assert_eq!(got, want, "{x0} {x1} {y0} {y1}");
                        }
                    }
                }
            }
        }
    }

    /// [`CellProcessors::box_marked`] is its definition: a box of at most
    /// [`MARKED_BOX`] pixels each way, not empty, all of whose last-level cells are
    /// marked. Every box of up to 18 pixels each way from the 28 x 28 pixels around
    /// a corner of four blocks of 8 x 8 cells (so boxes in one, two and four
    /// blocks), under every last-level memory with one cell open among the 12 x 12
    /// cells there (and with none), and under random marks.
    #[test]
    fn box_marked_is_its_definition() {
        // A 256 x 256 screen: root level 6, 64 x 64 last-level cells, 8 x 8 blocks.
        let mut gq = CellProcessors::new(256, 256, MaskLevels::mode_iv(6));
        gq.clear();
        let last = gq.root_level as usize;
        let check = |gq: &CellProcessors, what: &str| {
            for x0 in 100..128 {
                for y0 in 100..128 {
                    for x1 in x0..=x0 + 18 {
                        for y1 in y0..=y0 + 18 {
                            let bbox = [x0, x1, y0, y1];
                            let small = x1 > x0 && y1 > y0 && x1 - x0 <= MARKED_BOX && y1 - y0 <= MARKED_BOX;
                            let want = small
                                && (y0 / 4..=(y1 - 1) / 4).all(|cy| {
                                    (x0 / 4..=(x1 - 1) / 4).all(|cx| gq.memories[last].get(cx as usize, cy as usize))
                                });
                            assert_eq!(gq.box_marked(bbox), want, "{what}: box {bbox:?}");
                        }
                    }
                }
            }
        };
        gq.memories[last].bits.fill(!0);
        check(&gq, "all marked");
        for cy in 26..38u32 {
            for cx in 26..38u32 {
                let z = morton(cx, cy);
                gq.memories[last].bits.fill(!0);
                gq.memories[last].bits[z >> 6] &= !(1 << (z & 63));
                check(&gq, &format!("cell ({cx}, {cy}) open"));
            }
        }
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        for round in 0..8 {
            for w in gq.memories[last].bits.iter_mut() {
                // Mostly marked (each bit the OR of four draws), xorshift.
                let mut draw = || {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    state
                };
                *w = draw() | draw() | draw() | draw();
            }
            check(&gq, &format!("random marks {round}"));
        }
    }

    /// [`children_in_box`] is the children whose pixel squares meet the box: every
    /// box of a 32-pixel square that meets the cell (its precondition), around cells
    /// of sides 2-16.
    #[test]
    fn children_in_box_meet_the_box() {
        for shift in 1..=3u32 {
            let side = 1u32 << shift;
            let cell = Cell { level: 0, x: 1, y: 1 };
            for x0 in 0..32 {
                for x1 in x0 + 1..=32 {
                    for (y0, y1) in [(0, 32), (3, 5), (2 * side, 2 * side + 1), (0, 2 * side), (3 * side, 32)] {
                        let want = (0..4).fold(0u8, |w, c| {
                            let (cx, cy) = (2 * cell.x + (c & 1), 2 * cell.y + (c >> 1));
                            let meets =
                                cx * side < x1 && (cx + 1) * side > x0 && cy * side < y1 && (cy + 1) * side > y0;
                            w | u8::from(meets) << c
                        });
                        let bbox = [x0, x1, y0, y1];
                        // Its precondition: the cell (pixels `2 side .. 4 side`) meets the box.
                        let meets_cell = 2 * side < x1 && 4 * side > x0 && 2 * side < y1 && 4 * side > y0;
                        if !meets_cell {
                            continue;
                        }
                        assert_eq!(children_in_box(cell, shift, bbox), want, "shift {shift}, box {bbox:?}");
                    }
                }
            }
        }
    }

    /// The plain descent, the GQ's definition before its optimisations: lists in
    /// vectors, pushed per crossed child, the codes by [`edge_code`] (tested against
    /// the ROM), every edge to the end, no mask; the last-level cells with their
    /// active edges, in the descent's order.
    fn plain_descent(root_level: u32, cell: Cell, active: Vec<ActiveEdge>, out: &mut Vec<(u32, u32, Vec<ActiveEdge>)>) {
        if cell.level == root_level {
            out.push((cell.x * 4, cell.y * 4, active));
            return;
        }
        let half = 1i64 << (EDGE_FRAC_BITS + (root_level + 1 - cell.level));
        let mut children: [Vec<ActiveEdge>; 4] = Default::default();
        let mut cri_all = 0xF;
        for a in &active {
            let code = edge_code(a.v1.0, a.v2.0, half, a.vertical(), a.lr());
            cri_all &= code.cri;
            for (c, child) in children.iter_mut().enumerate() {
                if (code.cri & !code.ci) >> c & 1 == 1 {
                    let (along, across) = if a.vertical() { (c >> 1, c & 1) } else { (c & 1, c >> 1) };
                    let (v1, v2) = if along == 0 { (a.v1.0, code.vm) } else { (code.vm, a.v2.0) };
                    let shift = half * across as i64;
                    child.push(ActiveEdge { v1: EdgeCoord(v1 - shift), v2: EdgeCoord(v2 - shift), ..*a });
                }
            }
        }
        for (c, child) in children.into_iter().enumerate() {
            if cri_all >> c & 1 == 1 {
                let (x, y) = (cell.x * 2 + (c as u32 & 1), cell.y * 2 + (c as u32 >> 1));
                plain_descent(root_level, Cell { level: cell.level + 1, x, y }, child, out);
            }
        }
    }

    /// A test triangle: its edges, pixel box and vertices in snapped units.
    type Triangle = (Vec<EdgeCode>, [u32; 4], [(i64, i64); 3]);

    /// Marsaglia's xorshift64 from `state`: `next(n)` is a deterministic number in
    /// `0..n`, so that failures reproduce.
    fn xorshift(mut state: u64) -> impl FnMut(u64) -> u64 {
        move |n| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        }
    }

    /// Triangle `k` of the descent tests on a `SIDE`-pixel square screen (`root_side`
    /// the root cell's side), vertices drawn by `next`: its edges, pixel box as the VP
    /// forms it, and vertices in snapped units; `None` for a degenerate one.
    fn random_triangle(k: u32, root_side: u32, next: &mut impl FnMut(u64) -> u64) -> Option<Triangle> {
        const SIDE: u32 = 256;
        let snap = i64::from(SNAP_ONE);
        // Vertices in snapped units; a third of the triangles slivers (the third
        // vertex near the first two's line), some tiny.
        // Sizes: the screen, 8 pixels, and 1 to 10 pixels (`many`'s triangles).
        let scale = match k % 5 {
            0 => 8 * snap as u64,
            1 | 2 => (1 + next(10)) * snap as u64,
            _ => u64::from(SIDE) * snap as u64,
        };
        let (ox, oy) = (
            next(u64::from(SIDE) * snap as u64 - scale + 1) as i64,
            next(u64::from(SIDE) * snap as u64 - scale + 1) as i64,
        );
        let mut p = [(0i64, 0i64); 3];
        for v in &mut p[..2] {
            *v = (ox + next(scale) as i64, oy + next(scale) as i64);
        }
        p[2] = if k.is_multiple_of(3) {
            let t = next(1024) as i64;
            let (x, y) = (p[0].0 + (p[1].0 - p[0].0) * t / 1024, p[0].1 + (p[1].1 - p[0].1) * t / 1024);
            (
                (x + next(65) as i64 - 32).clamp(0, (SIDE as i64) * snap - 1),
                (y + next(65) as i64 - 32).clamp(0, (SIDE as i64) * snap - 1),
            )
        } else {
            (ox + next(scale) as i64, oy + next(scale) as i64)
        };
        let cross = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0);
        if cross == 0 {
            return None;
        }
        let fx = |v: (i64, i64)| (ScreenFx(v.0 as i32), ScreenFx(v.1 as i32));
        let edges = (0..3)
            .map(|i| EdgeCode::new(fx(p[i]), fx(p[(i + 1) % 3]), cross > 0, root_side))
            .collect::<Option<Vec<_>>>()?;
        // The box as the VP forms it: a pixel wider each way, inside the screen.
        let lo = |v: i64| ((v.div_euclid(snap) - 1).max(0) as u32).min(SIDE);
        let hi = |v: i64| ((v + snap - 1).div_euclid(snap) + 1).clamp(0, i64::from(SIDE)) as u32;
        let (xs, ys) = (p.map(|v| v.0), p.map(|v| v.1));
        let (x0, x1) = (*xs.iter().min().unwrap(), *xs.iter().max().unwrap());
        let (y0, y1) = (*ys.iter().min().unwrap(), *ys.iter().max().unwrap());
        let bbox = [lo(x0), hi(x1), lo(y0), hi(y1)];
        Some((edges, bbox, p))
    }

    /// The descent (lists written by index, codes by the table, the split left when
    /// every child is OUT) reaches the cells the plain descent does, with the same
    /// active edges, in the same order: random triangles, slivers and tiny ones
    /// among them, on a square screen (no cell pre-masked), no mask in use. The
    /// filling descent reaches them too, but for closed bands ([`band_closed`]) and
    /// the cells a start at the polygon's size leaves out
    /// ([`CellProcessors::start_at_size`]), whose codes clipped to the box are empty.
    #[test]
    fn descent_is_the_plain_descent() {
        const SIDE: u32 = 256;
        let mut gq = CellProcessors::new(SIDE, SIDE, MaskLevels::NONE);
        let root_side = gq.side(0);
        let mut next = xorshift(0x2545_F491_4F6C_DD1D_u64);
        let (mut checked, mut dropped, mut sized, mut stray) = (0, 0, 0, 0);
        for k in 0..3000 {
            let Some((edges, bbox, p)) = random_triangle(k, root_side, &mut next) else {
                continue;
            };
            let poly = GqPolygon { edges: &edges, opaque: false, bbox };
            let mut counters = Counters::new(gq.root_level);
            // The three instantiations: counting off, on, and the filling descent
            // (its fragments of cells wholly inside given one cell at a time).
            let mut got = Vec::new();
            gq.clear();
            gq.descend::<false>(&poly, &mut counters, &mut |f: Fragment| got.push((f.px, f.py, f.active.to_vec())));
            let mut counted = Vec::new();
            gq.clear();
            gq.descend::<true>(&poly, &mut counters, &mut |f: Fragment| counted.push((f.px, f.py, f.active.to_vec())));
            let mut filled = Vec::new();
            gq.clear();
            gq.descend_filling(&poly, &mut counters, &mut |f: Fragment| {
                if f.cells == ONE_CELL {
                    filled.push((f.px, f.py, f.active.to_vec()));
                } else {
                    for c in (0..4).filter(|c| f.cells >> c & 1 == 1) {
                        filled.push((f.px + 4 * (c & 1), f.py + 4 * (c >> 1), Vec::new()));
                    }
                }
            });
            let start = gq.bounding_cell(bbox);
            let side = i64::from(gq.side(start.level));
            let active = (0..3)
                .map(|i| {
                    ActiveEdge::at_cell(i as u32, &edges[i], i64::from(start.x) * side, i64::from(start.y) * side, side)
                })
                .collect();
            let mut want = Vec::new();
            plain_descent(gq.root_level, start, active, &mut want);
            if start.level + 1 < gq.root_level && gq.size_level(bbox) > start.level {
                sized += 1;
            }
            assert_eq!(got, want, "triangle {p:?}");
            assert_eq!(counted, want, "counting, triangle {p:?}");
            let (d, s) = filled_drops_only_empty(&filled, &want, &edges, bbox, &format!("triangle {p:?}"));
            (dropped, stray) = (dropped + d, stray + s);
            checked += 1;
        }
        assert!(checked > 2500);
        // Not vacuous: the filling descent drops closed bands, and cells the box
        // clips out.
        assert!(dropped > 1000, "{dropped}");
        // Hundreds start at the cells of their size (988 of them), and some of the
        // cells those descents leave out hold subpixels of the row tables' AND past
        // the box (134, over the three modes): without the clip they would be lost.
        assert!(sized > 500, "{sized}");
        assert!(stray > 20, "{stray}");
    }

    /// The filling descent's fragments `filled` are the plain descent's `want`, in the
    /// same order, less some whose codes (clipped to `bbox`) are empty in every SPP
    /// mode (the cells [`band_closed`] drops, and those outside the cells a start at
    /// the polygon's size descends): returns how many, and how many times (over the
    /// modes) such a cell's code is empty only by the clip to the box.
    fn filled_drops_only_empty(
        filled: &[(u32, u32, Vec<ActiveEdge>)],
        want: &[(u32, u32, Vec<ActiveEdge>)],
        edges: &[EdgeCode],
        bbox: [u32; 4],
        what: &str,
    ) -> (usize, usize) {
        use super::super::spp::SubpixelProcessors;
        use super::super::tables::SppMode;
        let spps = [SppMode::Area, SppMode::Sample, SppMode::Exact].map(|mode| SubpixelProcessors::new(4, 4, mode));
        let mut counters = Counters::new(0);
        let mut rest = filled.iter().peekable();
        let (mut dropped, mut stray) = (0, 0);
        for w in want {
            if rest.peek() == Some(&w) {
                rest.next();
                continue;
            }
            let frag = Fragment { px: w.0, py: w.1, active: &w.2, cells: ONE_CELL, bbox };
            for spp in &spps {
                let code = spp.fragment_code::<false>(&frag, edges, &mut counters);
                assert_eq!(code, [0; 16], "{what}: {:?} dropped the cell ({}, {}) of {:?}", spp.mode, w.0, w.1, w.2);
                let unclipped = spp.fragment_code::<false>(&Fragment { bbox: NO_BOX, ..frag }, edges, &mut counters);
                stray += usize::from(unclipped != [0; 16]);
            }
            dropped += 1;
        }
        assert_eq!(rest.next(), None, "{what}: a fragment the plain descent has not");
        (dropped, stray)
    }

    /// With every level's mask in use and opaque triangles drawn one over another
    /// (the marks of each feeding the next), the descent with counting off, with
    /// counting on, and the filling descent reach the same cells with the same
    /// active edges (the filling descent less closed bands of empty codes) and leave
    /// the same marks (the filling descent a part of them above its start levels, the
    /// same on the last level); the counters of the counting descent
    /// are those of the machine's every step (tested by the golden statistics).
    #[test]
    fn descents_agree_under_masks() {
        const SIDE: u32 = 256;
        let new = || {
            let mut gq = CellProcessors::new(SIDE, SIDE, MaskLevels::ALL);
            gq.clear();
            gq
        };
        let (mut off, mut on, mut filling) = (new(), new(), new());
        let root_side = off.side(0);
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15_u64);
        let mut counters = Counters::new(off.root_level);
        let mut reached = 0;
        for k in 0..3000 {
            let Some((edges, bbox, p)) = random_triangle(k, root_side, &mut next) else {
                continue;
            };
            let poly = GqPolygon { edges: &edges, opaque: true, bbox };
            let mut want = Vec::new();
            off.descend::<false>(&poly, &mut counters, &mut |f: Fragment| want.push((f.px, f.py, f.active.to_vec())));
            let mut counted = Vec::new();
            on.descend::<true>(&poly, &mut counters, &mut |f: Fragment| counted.push((f.px, f.py, f.active.to_vec())));
            let mut filled = Vec::new();
            filling.descend_filling(&poly, &mut counters, &mut |f: Fragment| {
                if f.cells == ONE_CELL {
                    filled.push((f.px, f.py, f.active.to_vec()));
                } else {
                    for c in (0..4).filter(|c| f.cells >> c & 1 == 1) {
                        filled.push((f.px + 4 * (c & 1), f.py + 4 * (c >> 1), Vec::new()));
                    }
                }
            });
            assert_eq!(counted, want, "counting, triangle {k} {p:?}");
            filled_drops_only_empty(&filled, &want, &edges, bbox, &format!("triangle {k} {p:?}"));
            for level in 1..=off.root_level as usize {
                assert_eq!(on.memories[level].bits, off.memories[level].bits, "level {level}, triangle {k}");
                // The filling descent marks a cell wholly inside above its start level
                // only from the start level down ([`CellProcessors::start_at_size`]):
                // a part of the marks, closed downward, the same on the last level.
                let (got, all) = (&filling.memories[level].bits, &off.memories[level].bits);
                assert!(got.iter().zip(all).all(|(g, a)| g & !a == 0), "level {level}, triangle {k}");
                if level == off.root_level as usize {
                    assert_eq!(got, all, "level {level}, triangle {k}");
                }
            }
            assert!(filling.marks_closed_downward(), "triangle {k}");
            reached += want.len();
        }
        assert!(reached > 10_000, "{reached}");
    }

    /// Sets of mask levels in use for the descent's tests: all, none, a range,
    /// every other level, two apart, and the papers' modes I and II.
    fn mask_level_sets() -> [MaskLevels; 7] {
        [
            MaskLevels::ALL,
            MaskLevels::NONE,
            MaskLevels::range(3, 6),
            MaskLevels(1 << 2 | 1 << 4 | 1 << 6),
            MaskLevels(1 << 1 | 1 << 5),
            MaskLevels::mode_i(6),
            MaskLevels::mode_ii(6),
        ]
    }

    /// The filling descent with a small polygon's last-level cells found at once
    /// ([`CellProcessors::last_cells`]) hands the sink the same fragments (pixel,
    /// cells, active edges, box), in the same order, and leaves the same marks and
    /// queued cells on every level, as with the descent level by level: polygons of
    /// one to six random edges (any set of lines: the descent only ANDs their
    /// codes) and random triangles, in boxes of one to a few cells, opaque and not,
    /// one over another, with Greene's rule and without, under several sets of
    /// levels in use, on a square screen and on one whose cells off it are
    /// pre-masked.
    #[test]
    fn last_cells_are_the_descent() {
        let sets = mask_level_sets();
        type Got = Vec<(u32, u32, u8, [u32; 4], Vec<ActiveEdge>)>;
        let mut next = xorshift(0x0DDB_1A5E_5BAD_5EED_u64);
        let snap = i64::from(SNAP_ONE);
        let (mut polygons, mut at_once, mut fragments) = (0, 0, 0);
        for (w, h) in [(256u32, 256u32), (200, 150)] {
            for (i, &masks) in sets.iter().enumerate() {
                for hierarchical in [false, true] {
                    let new = || {
                        let mut gq = CellProcessors::new(w, h, masks);
                        gq.hierarchical = hierarchical;
                        gq.clear();
                        gq
                    };
                    let (mut once, mut split) = (new(), new());
                    split.at_once = false;
                    let root_side = once.side(0);
                    let mut counters = Counters::new(once.root_level);
                    for k in 0..600 {
                        let (edges, bbox) = if k % 3 == 0 {
                            let Some((edges, bbox, _)) = random_triangle(k, root_side, &mut next) else {
                                continue;
                            };
                            (edges, bbox)
                        } else {
                            // A box of 1 to 36 pixels a side, edges through points near it.
                            let (bw, bh) = (1 + next(36) as u32, 1 + next(36) as u32);
                            let (x0, y0) = (next(u64::from(w - bw + 1)) as u32, next(u64::from(h - bh + 1)) as u32);
                            let point = |next: &mut dyn FnMut(u64) -> u64| {
                                let x =
                                    i64::from(x0) * snap - 4 * snap + next((u64::from(bw) + 8) * snap as u64) as i64;
                                let y =
                                    i64::from(y0) * snap - 4 * snap + next((u64::from(bh) + 8) * snap as u64) as i64;
                                (ScreenFx(x as i32), ScreenFx(y as i32))
                            };
                            let count = 1 + next(6) as usize;
                            let edges: Vec<EdgeCode> = (0..count)
                                .filter_map(|_| {
                                    let (a, b) = (point(&mut next), point(&mut next));
                                    EdgeCode::new(a, b, next(2) == 0, root_side)
                                })
                                .collect();
                            if edges.is_empty() {
                                continue;
                            }
                            (edges, [x0, x0 + bw, y0, y0 + bh])
                        };
                        let bbox = [bbox[0].min(w), bbox[1].min(w), bbox[2].min(h), bbox[3].min(h)];
                        if bbox[0] >= bbox[1] || bbox[2] >= bbox[3] {
                            continue;
                        }
                        let poly = GqPolygon { edges: &edges, opaque: next(4) != 0, bbox };
                        let mut run = |gq: &mut CellProcessors| {
                            let mut got: Got = Vec::new();
                            gq.descend_filling(&poly, &mut counters, &mut |f: Fragment| {
                                got.push((f.px, f.py, f.cells, f.bbox, f.active.to_vec()));
                            });
                            let queued = (gq.inside.clone(), gq.queued);
                            gq.mark_covered_cells(&mut Vec::new());
                            (got, queued)
                        };
                        let (want, want_queued) = run(&mut split);
                        let (got, got_queued) = run(&mut once);
                        let what = format!("screen {w}x{h}, levels {i}, hierarchical {hierarchical}, polygon {k}");
                        assert_eq!(got, want, "{what}");
                        assert_eq!(got_queued, want_queued, "{what}");
                        for level in 0..=once.root_level as usize {
                            assert_eq!(once.memories[level].bits, split.memories[level].bits, "{what}, level {level}");
                        }
                        polygons += 1;
                        let [x0, x1, y0, y1] = bbox;
                        at_once += usize::from(
                            edges.len() <= AT_ONCE_EDGES
                                && (x1 - 1) / 8 - x0 / 8 < WINDOW_SPAN
                                && (y1 - 1) / 8 - y0 / 8 < WINDOW_SPAN,
                        );
                        fragments += want.len();
                    }
                }
            }
        }
        // Not vacuous: most polygons take the new path, and reach fragments.
        assert!(polygons > 10_000 && at_once > polygons / 3, "{polygons} {at_once}");
        assert!(fragments > 50_000, "{fragments}");
    }

    /// The marks stay closed downward over the levels in use ([`CellProcessors::covered`]
    /// reads only the deepest), and `covered` answers as the walk over every level
    /// in use does: triangles (opaque and not) descended by the filling and the
    /// counting descents, one over another, with Greene's marks of last-level cells
    /// between them, under several sets of levels in use, on a screen whose side is
    /// not a power of two (cells off it pre-masked).
    #[test]
    fn marks_are_closed_downward() {
        let (w, h) = (200u32, 150u32);
        let sets = mask_level_sets();
        let mut next = xorshift(0x2545_F491_4F6C_DD1D_u64);
        for (i, &masks) in sets.iter().enumerate() {
            for counting in [false, true] {
                let mut gq = CellProcessors::new(w, h, masks);
                gq.hierarchical = !counting;
                gq.clear();
                let root = gq.root_level;
                let root_side = gq.side(0);
                let mut counters = Counters::new(root);
                for k in 0..400 {
                    let Some((edges, bbox, _)) = random_triangle(k, root_side, &mut next) else {
                        continue;
                    };
                    let bbox = [bbox[0].min(w), bbox[1].min(w), bbox[2].min(h), bbox[3].min(h)];
                    if bbox[0] >= bbox[1] || bbox[2] >= bbox[3] {
                        continue;
                    }
                    let poly = GqPolygon { edges: &edges, opaque: next(5) != 0, bbox };
                    if counting {
                        gq.descend::<true>(&poly, &mut counters, &mut |_| {});
                    } else {
                        gq.descend_filling(&poly, &mut counters, &mut |_| {});
                        // Last-level cells the SPPs would find covered.
                        let mut cells: Vec<usize> = (0..next(6))
                            .map(|_| morton(next(u64::from(w / 4)) as u32, next(u64::from(h / 4)) as u32))
                            .collect();
                        cells.sort_unstable();
                        gq.mark_covered_cells(&mut cells);
                    }
                    assert!(gq.marks_closed_downward(), "levels {i}, counting {counting}, triangle {k}");
                    for _ in 0..20 {
                        let level = 1 + next(u64::from(root)) as u32;
                        let from = 1 + next(u64::from(level)) as u32;
                        let z = next(1 << (2 * level)) as usize;
                        let walk = (from..=level)
                            .any(|k| masks.has(k) && gq.memories[k as usize].get_z(z >> (2 * (level - k))));
                        assert_eq!(
                            gq.covered(z, level, from),
                            walk,
                            "levels {i}, cell {z} of level {level} from {from}"
                        );
                    }
                }
            }
        }
    }

    /// A matrix VP's share is pre-masked on every level
    /// ([`CellProcessors::pre_mask_share`]): after `clear`, a cell is marked exactly
    /// when it is wholly off the screen or (tiles of whole cells) holds no pixel of
    /// the share, pixel by pixel ([`Share::owns_pixel`]); the marks are closed
    /// downward. The shares follow one another on one VP, as a strip matrix's move
    /// from frame to frame: nothing of the last one stays.
    #[test]
    fn share_pre_masks_are_exact_and_closed_downward() {
        let (w, h) = (200u32, 150u32);
        let shares = [
            Share::interleaved(16, 3, 2, 2, 1),
            Share::WHOLE,
            Share::strip(16, 0, 96),
            Share::strip(16, 96, 200),
            Share::strip(16, 48, 48),
            Share::strip(8, 0, 200),
            Share::interleaved(4, 2, 1, 1, 0),
            Share::interleaved(64, 2, 2, 0, 1),
            Share::interleaved(2, 2, 2, 1, 1),
            Share::interleaved(256, 1, 2, 0, 1),
            Share::strip(16, 0, 96),
        ];
        let mut gq = CellProcessors::new(w, h, MaskLevels::ALL);
        for share in shares {
            gq.share = share;
            gq.clear();
            assert!(gq.marks_closed_downward(), "{share:?}");
            let masked = !share.is_whole() && share.tile >= CELL_SIDE;
            for level in 0..=gq.root_level {
                let (side, cells) = (gq.side(level), 1u32 << level);
                for cy in 0..cells {
                    for cx in 0..cells {
                        let (x0, y0) = (cx * side, cy * side);
                        let off = x0 >= w || y0 >= h;
                        let holds = (y0..y0 + side).any(|y| (x0..x0 + side).any(|x| share.owns_pixel(x, y)));
                        let want = off || (masked && !holds);
                        let got = gq.memories[level as usize].get(cx as usize, cy as usize);
                        assert_eq!(got, want, "{share:?}: level {level}, cell ({cx}, {cy})");
                    }
                }
            }
        }
    }

    proptest::proptest! {
        /// [`Share::holds_columns`] and [`Share::holds_rows`] say whether one of the
        /// columns (rows) is the share's, as [`Share::owns_column`]
        /// ([`Share::owns_row`]) of each in turn.
        #[test]
        fn a_share_holds_lines_when_it_owns_one(
            tile_log in 0u32..6,
            (p, i) in (1u32..5, 0u32..4),
            (q, j) in (1u32..5, 0u32..4),
            strip in proptest::option::of((0u32..300, 0u32..300)),
            a in 0u32..400,
            n in 0u32..200,
        ) {
            let tile = 1 << tile_log;
            let mut share = Share::interleaved(tile, p, q, i % p, j % q);
            if let Some((s0, s1)) = strip {
                share.strip = (s0.min(s1), s0.max(s1));
            }
            proptest::prop_assert_eq!(share.holds_columns(a, a + n), (a..a + n).any(|x| share.owns_column(x)));
            proptest::prop_assert_eq!(share.holds_rows(a, a + n), (a..a + n).any(|y| share.owns_row(y)));
        }

        /// Marking covered cells all at once leaves the mask memories as marking
        /// them one by one does, in any order, over any earlier marks (IN cells of
        /// every level, cells marked before) and with any levels in use.
        #[test]
        fn marking_cells_at_once_is_marking_them_one_by_one(
            earlier in proptest::collection::vec((1u32..=5, 0u32..32, 0u32..32), 0..60),
            cells in proptest::collection::vec((0u32..32, 0u32..32), 0..200),
            sort in proptest::bool::ANY,
            lowest_mask in 1u32..=5,
        ) {
            // A 128 x 128 screen: root level 5, 32 x 32 last-level cells.
            let mut one = CellProcessors::new(128, 128, MaskLevels::range(lowest_mask, 5));
            one.clear();
            for &(k, x, y) in &earlier {
                let side = 1u32 << k;
                one.memories[k as usize].set((x % side) as usize, (y % side) as usize);
            }
            let mut all = one.clone();
            for &(x, y) in &cells {
                one.mark_covered(x, y);
            }
            let mut z: Vec<usize> = cells.iter().map(|&(x, y)| morton(x, y)).collect();
            if sort {
                z.sort_unstable();
            }
            all.mark_covered_cells(&mut z);
            proptest::prop_assert!(z.is_empty());
            for (k, (a, b)) in one.memories.iter().zip(&all.memories).enumerate() {
                proptest::prop_assert_eq!(&a.bits, &b.bits, "level {}", k);
            }
        }
    }
}
