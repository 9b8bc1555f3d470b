//! The edge code of the video processor (P1 fig. 2): how one edge of a convex polygon
//! is described to the cell processors (GQ) and subpixel processors (SPP).
//!
//! An edge is the line through two vertices snapped to the 1/256-pixel grid
//! ([`SNAP_BITS`]). Its code is two flags and a linear function:
//! - **TG**: [`Tg::Vertical`] when the line is steeper than 45 degrees (|dy| > |dx|),
//!   else [`Tg::Horizontal`];
//! - **LR**: `true` when the polygon lies on the side of greater V ("right" of a
//!   vertical edge, "below" a horizontal one);
//! - **V**: for a vertical edge, the X where the line meets a horizontal line `y`;
//!   for a horizontal edge, the Y where it meets a vertical line `x`. P1 gives V at the
//!   two opposite borders of a cell (V1, V2); here `V(t) = origin + slope * t` for any
//!   integer pixel line `t`, from which V1 and V2 of every cell follow.
//!
//! # Numbers: why every cell sees the same bits
//! V is an [`EdgeCoord`]: an `i64` with [`EDGE_FRAC_BITS`] = 32 fractional bits. The
//! line is first fixed by its values at the root cell's two borders, rounded down to
//! 2^-16 pixel ([`ROOT_V_BITS`]) from the exact rational through the snapped vertices
//! (computed in `i128`). Every other value is an exact dyadic interpolation of those
//! two: `slope = (V2 - V1) / 2^(L+2)` is exact because `V2 - V1` has 16 zero low bits
//! and the root side `2^(L+2) <= 2^13`. So `V(t)`, and every midpoint `(V1 + V2) / 2`
//! the GQ forms by one addition and a shift, are exact: **an edge's value at a cell is
//! the same whichever cell the descent started from, whichever polygon the edge
//! belongs to and in whichever direction it is listed** (the endpoints are put in a
//! canonical order first). This is what makes shared edges watertight.

use serde::Serialize;

use super::spp::VERTEX_COEFFICIENT_LIMIT;

/// Fractional bits of snapped screen coordinates: vertices lie on a 1/256-pixel grid.
pub const SNAP_BITS: u32 = 8;
/// One pixel in snapped units.
pub const SNAP_ONE: i32 = 1 << SNAP_BITS;
/// Fractional bits of an [`EdgeCoord`].
pub const EDGE_FRAC_BITS: u32 = 32;
/// Fractional bits kept when an edge's values at the root borders are rounded.
pub const ROOT_V_BITS: u32 = 16;
/// The largest root level the numbers support: root side `4 * 2^11 = 8192` pixels.
pub const MAX_ROOT_LEVEL: u32 = 11;
/// The largest root side in pixels, `4 * 2^MAX_ROOT_LEVEL`.
const MAX_ROOT_SIDE: u32 = 4 << MAX_ROOT_LEVEL;
/// [`EdgeCode::new`]'s fast path takes snapped coordinates of magnitude below
/// `2^FAST_COORD_BITS` (2^18 pixels): then `(t - aw) du 2^8` is below
/// `2^27 2^27 2^8 = 2^62` for `t` up to [`MAX_ROOT_SIDE`] pixels.
const FAST_COORD_BITS: u32 = 26;

/// [`EdgeCode::push_triangle_avx2`] takes triangles whose snapped coordinates `c`
/// all have `c ^ (c >> 31)` below `2^FLOAT_COORD_BITS` (`-2^21 <= c < 2^21`: 8192
/// pixels either way, every window the numbers support): then every integer it
/// forms, numerators included, is below `2^53` in magnitude and exact in an `f64`
/// (the bounds are worked out there).
const FLOAT_COORD_BITS: u32 = 21;

// [`EdgeCode::push_triangle_avx2`] stores a code as one aligned 32-byte register:
// `word, slope, ends[0], ends[1]` (the order of [`EdgeCode`]'s `repr(C)`), each end
// `x` then `y`.
const _: () = {
    use std::mem::{offset_of, size_of};
    assert!(
        size_of::<EdgeCode>() == 32
            && std::mem::align_of::<EdgeCode>() == 32
            && offset_of!(EdgeCode, word) == 0
            && offset_of!(EdgeCode, slope) == 8
            && offset_of!(EdgeCode, ends) == 16
            && offset_of!((i32, i32), 0) == 0
            && offset_of!((i32, i32), 1) == 4
    );
};

/// A snapped screen coordinate: pixels in 24.8 fixed point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct ScreenFx(pub i32);

impl ScreenFx {
    /// Rounds a pixel coordinate to the snapping grid (callers pass finite values
    /// inside the clipped window).
    #[inline]
    pub fn from_f64(v: f64) -> Self {
        Self((v * f64::from(SNAP_ONE)).round() as i32)
    }

    /// The coordinate in pixels.
    #[inline]
    pub fn to_f32(self) -> f32 {
        self.0 as f32 / SNAP_ONE as f32
    }
}

/// A value of V: pixels as `i64` with [`EDGE_FRAC_BITS`] fractional bits.
///
/// Bit layout: `[63..32]` signed integer pixels, `[31..0]` fraction.
/// Transparent, so that the GQ's active edges ([`super::gq::ActiveEdge`]) hold V1 and
/// V2 as two adjacent `i64`, written as one SSE2 register.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[repr(transparent)]
pub struct EdgeCoord(pub i64);

impl EdgeCoord {
    /// The value of integer pixel `p`.
    #[inline]
    pub const fn pixels(p: i64) -> Self {
        Self(p << EDGE_FRAC_BITS)
    }

    /// The value as a float (for tests and display).
    pub fn to_f64(self) -> f64 {
        self.0 as f64 / (1u64 << EDGE_FRAC_BITS) as f64
    }
}

/// TG: the edge's class by its angle to the X axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Tg {
    /// Angle to X at most 45 degrees: V is a Y, taken along vertical lines `x = t`.
    Horizontal = 0,
    /// Angle over 45 degrees: V is an X, taken along horizontal lines `y = t`.
    Vertical = 1,
}

/// [`EdgeCode`]'s word: bit of TG ([`Tg::Vertical`] when set).
const WORD_TG: i64 = 1 << 0;
/// [`EdgeCode`]'s word: bit of LR.
const WORD_LR: i64 = 1 << 1;
/// [`EdgeCode`]'s word: bit of [`ExactLine::fits_32`].
const WORD_EXACT32: i64 = 1 << 2;
/// [`EdgeCode`]'s word: bit of [`EdgeCode::vertex32`].
const WORD_VERTEX32: i64 = 1 << 3;
/// [`EdgeCode`]'s word: the bits of V at `t = 0` (all but the low [`ROOT_V_BITS`]:
/// V is rounded to `2^-ROOT_V_BITS` pixel, so its low `EDGE_FRAC_BITS - ROOT_V_BITS`
/// = 16 bits are zero, and the flags take three of them).
const WORD_ORIGIN: i64 = !((1 << (EDGE_FRAC_BITS - ROOT_V_BITS)) - 1);

/// One edge in the VP's code: 32 bytes, half a cache line (the frame list holds
/// three a triangle, and every VP reads them: at 64 bytes they were two thirds of
/// the list, BENCHMARKS.md session 18).
///
/// Aligned to its 32 bytes, so that a list of codes is too: no code straddles two
/// cache lines, and the GP's AVX2 set-up ([`EdgeCode::push_triangle_avx2_at`])
/// stores each as one aligned register, where an unaligned 32-byte store is two
/// instructions in this build's tuning (`many`'s GP: 3 instructions a triangle;
/// session 27).
///
/// Layout (`repr(C)`, 4 x 8 bytes):
/// - `word`: bits `[63..16]` V at line `t = 0` ([`EdgeCode::origin`], an
///   [`EdgeCoord`] whose low 16 bits are zero); bit 3 `vertex32`
///   ([`EdgeCode::vertex32`]); bit 2 `exact32` ([`EdgeCode::exact32`]); bit 1 LR
///   ([`EdgeCode::lr`]); bit 0 TG ([`EdgeCode::tg`]); bits `[15..4]` zero;
/// - `slope`: the change of V per pixel of `t`;
/// - `ends`: the edge's two snapped endpoints in canonical (lexicographic) order,
///   from which its [`ExactLine`] follows ([`EdgeCode::exact`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(C, align(32))]
pub struct EdgeCode {
    /// V at `t = 0` and the flags (see the layout above).
    word: i64,
    /// Change of V per pixel of `t`.
    pub slope: EdgeCoord,
    /// The edge's endpoints (snapped units), the smaller `(x, y)` first.
    pub ends: [(i32, i32); 2],
}

/// The exact line through an edge's snapped endpoints: `E(x, y) = a x + b y + c`,
/// `x`, `y` in snapped units (1/256 pixel), integers; oriented so that `E > 0` on the
/// side of greater V (so `a > 0` for a vertical edge, `b > 0` for a horizontal one).
/// The same for both polygons sharing the edge and for both directions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct ExactLine {
    /// Coefficient of x.
    pub a: i64,
    /// Coefficient of y.
    pub b: i64,
    /// Constant.
    pub c: i64,
    /// The edge's two endpoints (snapped units), for the vertex pixels of
    /// [`super::tables::SppMode::Area`].
    pub ends: [(i32, i32); 2],
}

/// [`ExactLine::fits_32`]: coefficients below this in magnitude (`2^22`).
pub const EXACT32_COEFFICIENT_LIMIT: u64 = 1 << 22;
/// [`ExactLine::fits_32`]: endpoint coordinates below this in magnitude (`2^30`).
pub const EXACT32_END_LIMIT: u32 = 1 << 30;

impl ExactLine {
    /// The line through `ends` (distinct, the smaller `(x, y)` first), oriented
    /// towards greater V: `E = dy (x - x0) - dx (y - y0)`, negated where needed so that
    /// `a > 0` for a vertical edge (`|dy| > |dx|`), `b > 0` for a horizontal one.
    /// The order of the ends does not change the result (only the sign of `dx, dy`,
    /// which the orientation undoes).
    #[inline(always)]
    pub fn through(ends: [(i32, i32); 2]) -> Self {
        let [(x0, y0), (x1, y1)] = ends;
        let (dx, dy) = (i64::from(x1) - i64::from(x0), i64::from(y1) - i64::from(y0));
        Self::oriented(ends, dy.abs() > dx.abs())
    }

    /// [`ExactLine::through`] of an edge whose TG is known (`vertical`: `|dy| > |dx|`).
    #[inline(always)]
    fn oriented(ends: [(i32, i32); 2], vertical: bool) -> Self {
        let [(x0, y0), (x1, y1)] = ends;
        let (x0, y0) = (i64::from(x0), i64::from(y0));
        let (dx, dy) = (i64::from(x1) - x0, i64::from(y1) - y0);
        let flip = if vertical { dy < 0 } else { dx > 0 };
        let (a, b) = if flip { (-dy, dx) } else { (dy, -dx) };
        Self { a, b, c: -(a * x0 + b * y0), ends }
    }

    /// Whether the SPP's 32-bit vertex paths take the line: `|a|, |b|` below
    /// [`EXACT32_COEFFICIENT_LIMIT`] (its 16 subpixel offsets fit 32-bit lanes) and
    /// every endpoint coordinate below [`EXACT32_END_LIMIT`] (its distances to a cell
    /// do).
    #[inline]
    pub fn fits_32(&self) -> bool {
        let small = |c: i32| c.unsigned_abs() < EXACT32_END_LIMIT;
        self.a.unsigned_abs() < EXACT32_COEFFICIENT_LIMIT
            && self.b.unsigned_abs() < EXACT32_COEFFICIENT_LIMIT
            && self.ends.iter().all(|&(x, y)| small(x) && small(y))
    }

    /// Whether the point `(x, y)` (snapped units) lies on the side of greater V, with
    /// points on the line decided as if moved by `(e, e^2)` for an infinitesimal
    /// `e > 0`. One perturbation for every line: at a vertex shared by many edges the
    /// decisions are those of one point off all the lines, so a fan of polygons
    /// splits every sample exactly once.
    #[inline]
    pub fn greater_side(&self, x: i64, y: i64) -> bool {
        let e = self.a * x + self.b * y + self.c;
        if e != 0 {
            e > 0
        } else if self.a != 0 {
            self.a > 0
        } else {
            self.b > 0
        }
    }
}

/// Whether [`EdgeCode::new_fast`] takes edges between `points`: every coordinate
/// of magnitude below `2^FAST_COORD_BITS` and the root side a power of two at
/// most [`MAX_ROOT_SIDE`].
#[inline(always)]
fn fast_bounds(points: &[(ScreenFx, ScreenFx)], root_side: u32) -> bool {
    // `x ^ (x >> 31)` is `|x|` or `|x| - 1`: all magnitudes tested by one OR.
    let mag = points.iter().fold(0, |m, p| m | (p.0 .0 ^ (p.0 .0 >> 31)) | (p.1 .0 ^ (p.1 .0 >> 31)));
    mag >> FAST_COORD_BITS == 0 && root_side <= MAX_ROOT_SIDE && root_side.is_power_of_two()
}

/// A root side that [`EdgeCode::push_triangle_avx2`] takes (a power of two of at
/// most [`MAX_ROOT_SIDE`] pixels) with the two constants of its float divisions
/// that depend on it, made once ([`TriangleRoot::new`]; the GP's set-up keeps one
/// a frame) rather than tested and worked out again at every triangle (about 13
/// instructions a triangle: the power-of-two test, `trailing_zeros`, a shift, a
/// conversion and a subtraction).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleRoot {
    /// `2^(root_bits + ROOT_V_BITS)`, `n2`'s scale of `du`, as an `f64` (exact).
    span: f64,
    /// `EDGE_FRAC_BITS - ROOT_V_BITS - root_bits`: the slope's left shift.
    slope_shift: i32,
}

#[cfg(target_arch = "x86_64")]
impl TriangleRoot {
    /// The constants of root side `root_side` (pixels), or `None` where
    /// [`EdgeCode::push_triangle_avx2`] does not take it (not a power of two, or
    /// above [`MAX_ROOT_SIDE`]).
    pub fn new(root_side: u32) -> Option<Self> {
        if root_side > MAX_ROOT_SIDE || !root_side.is_power_of_two() {
            return None;
        }
        let root_bits = root_side.trailing_zeros();
        let scale_bits = ROOT_V_BITS - SNAP_BITS;
        Some(Self {
            span: (1u64 << (root_bits + SNAP_BITS + scale_bits)) as f64,
            slope_shift: (EDGE_FRAC_BITS - ROOT_V_BITS - root_bits) as i32,
        })
    }
}

impl EdgeCode {
    /// The code of the line through `a` and `b` (snapped, distinct), for a root cell
    /// of `root_side = 4 * 2^L` pixels; `inside_positive` tells whether the polygon
    /// lies where the cross product `(b - a) x (p - a)` is positive (screen axes,
    /// y down). Returns `None` when `a == b`.
    pub fn new(
        a: (ScreenFx, ScreenFx),
        b: (ScreenFx, ScreenFx),
        inside_positive: bool,
        root_side: u32,
    ) -> Option<Self> {
        if fast_bounds(&[a, b], root_side) {
            Self::new_fast(a, b, inside_positive, root_side.trailing_zeros())
        } else {
            Self::new_general(a, b, inside_positive, root_side)
        }
    }

    /// Appends the codes of the closed outline `points` to `out`: the edge from each
    /// point to the next, and from the last back to the first ([`EdgeCode::new`] of
    /// each, the bounds of its fast path checked once for the whole outline). A
    /// triangle within the bounds takes a straight-line path of its own.
    ///
    /// # Panics
    /// If two consecutive points are equal (a snapped outline has none).
    pub fn push_outline(
        points: &[(ScreenFx, ScreenFx)],
        inside_positive: bool,
        root_side: u32,
        out: &mut Vec<EdgeCode>,
    ) {
        if let &[p0, p1, p2] = points {
            if Self::push_triangle_fast([p0, p1, p2], inside_positive, root_side, out) {
                return;
            }
        }
        let (Some(&first), Some(&last)) = (points.first(), points.last()) else { return };
        // Each point with the next one, then the last with the first: one
        // reservation and no bounds check per edge.
        out.reserve(points.len());
        if fast_bounds(points, root_side) {
            let root_bits = root_side.trailing_zeros();
            let code = |a, b| Self::new_fast(a, b, inside_positive, root_bits).expect("consecutive points differ");
            out.extend(points.windows(2).map(|w| code(w[0], w[1])));
            out.push(code(last, first));
        } else {
            let code = |a, b| Self::new_general(a, b, inside_positive, root_side).expect("consecutive points differ");
            out.extend(points.windows(2).map(|w| code(w[0], w[1])));
            out.push(code(last, first));
        }
    }

    /// [`EdgeCode::push_outline`] of a triangle (nearly every polygon of the GP),
    /// inline in its caller (the GP's set-up hands it the snapped points in
    /// registers).
    ///
    /// # Panics
    /// If two of the points are equal (a snapped triangle has none).
    #[inline]
    pub fn push_triangle(
        points: [(ScreenFx, ScreenFx); 3],
        inside_positive: bool,
        root_side: u32,
        out: &mut Vec<EdgeCode>,
    ) {
        if !Self::push_triangle_fast(points, inside_positive, root_side, out) {
            Self::push_outline(&points, inside_positive, root_side, out);
        }
    }

    /// [`EdgeCode::push_triangle`] with the three edges in the lanes of AVX2
    /// registers, for the GP's face path compiled for AVX2: `true` when the
    /// triangle lies within `FLOAT_COORD_BITS` and a root side of at most
    /// [`MAX_ROOT_SIDE`] pixels, a power of two (then its three codes are appended);
    /// else `false`, nothing appended (and [`EdgeCode::push_triangle`] takes it).
    ///
    /// The same codes as [`EdgeCode::new_fast`], bit for bit (tested against the
    /// definition): the integer steps are the same, in 32-bit lanes where they fit,
    /// and the two floor divisions per edge (six 64-bit `idiv`s a triangle,
    /// about a third of [`EdgeCode::new_fast`]'s cost) are float divisions with one
    /// correction, exact for these inputs:
    /// - coordinates `c` satisfy `-2^21 <= c < 2^21`, so `|dx|, |dy| < 2^22` and
    ///   (by TG) `|du| <= |dw| < 2^22`, `|aw| <= 2^21`;
    /// - the numerators `n1 = -aw du 2^8` (at most `2^51`) and `n2 = n1 + du
    ///   2^(root_bits + 16)` (the second term at most `2^22 2^29 = 2^51`, so `|n2| <=
    ///   2^52`) are integers below `2^53`, so each `f64` operation that forms them
    ///   (products and a sum of integers, scalings by powers of two) is exact;
    /// - IEEE division is correctly rounded, hence monotone: with `F = floor(n /
    ///   dw)`, `F <= n / dw < F + 1` and `F`, `F + 1` are floats (below `2^31`, see
    ///   below), so `F <= fl(n / dw) <= F + 1` and `q = floor(fl(n / dw))` is `F` or
    ///   `F + 1`;
    /// - `q dw` is an integer of magnitude at most `|n| + dw < 2^53`, so the product
    ///   is exact, and `r = n - q dw` lies in `[-dw, dw)`, a float, so the difference
    ///   is exact: `r >= 0` for `q = F`, `r < 0` for `q = F + 1`, and `q - (r < 0)`
    ///   is `F`;
    /// - the quotients fit `i32`: `|q1| <= |aw| 2^8 |du / dw| <= 2^29`, `|q2 - q1| <=
    ///   2^(root_bits + 16) + 1 <= 2^29 + 1`; and so do `(au << 8) + q1` (`|au| <=
    ///   2^21`) and `q2 - q1`, which are then widened to `i64` and shifted as in
    ///   [`EdgeCode::new_fast`], whose `(x << 16) >> root_bits` is `x << (16 -
    ///   root_bits)` (`root_bits <= 13`, the low bits zero).
    ///
    /// `exact32` is always `true` here (`|dx|, |dy| < 2^22`).
    ///
    /// Inlined always, and compiled with its caller's features: for the GP's face
    /// path compiled for AVX2 (`#[inline]` on a `#[target_feature]` function left a
    /// call a triangle, with the points passed through memory, the registers saved
    /// and the vector's length written back after each code).
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code, reason = "AVX2 instructions, inlined into a caller compiled for AVX2")]
    #[inline(always)]
    pub unsafe fn push_triangle_avx2(
        points: [(ScreenFx, ScreenFx); 3],
        inside_positive: bool,
        root_side: u32,
        out: &mut Vec<EdgeCode>,
    ) -> bool {
        match TriangleRoot::new(root_side) {
            // SAFETY: the caller vouches for AVX2.
            Some(root) => unsafe { Self::push_triangle_avx2_at(points, inside_positive, root, out) },
            None => false,
        }
    }

    /// [`EdgeCode::push_triangle_avx2`] at a root side checked and its constants
    /// made already ([`TriangleRoot`], once a frame in the GP's set-up): `true`
    /// when the triangle lies within `FLOAT_COORD_BITS` (then its three codes are
    /// appended), else `false`, nothing appended.
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code, reason = "AVX2 instructions, inlined into a caller compiled for AVX2")]
    #[inline(always)]
    pub unsafe fn push_triangle_avx2_at(
        points: [(ScreenFx, ScreenFx); 3],
        inside_positive: bool,
        root: TriangleRoot,
        out: &mut Vec<EdgeCode>,
    ) -> bool {
        use std::arch::x86_64::*;
        const _: () = assert!(1 << (FLOAT_COORD_BITS + 1) <= EXACT32_COEFFICIENT_LIMIT);
        const _: () = assert!(MAX_ROOT_SIDE.trailing_zeros() <= ROOT_V_BITS);
        // Reserved first, while few values are live: the reservation's call (on
        // its rare path) made the compiler keep the lanes below on the stack, and
        // load them again, around it (`many`'s GP at 480x270: 880.3 -> 867.3 M
        // instructions, with the write below through the vector's pointer
        // rather than a slice of its spare capacity, whose length was tested).
        out.reserve(3);
        let [p0, p1, p2] = points;
        // Lane k: the edge from point k to point k + 1; lane 3 repeats lane 0
        // (never stored; a non-zero divisor where lane 0 has one).
        let ax = _mm_setr_epi32(p0.0 .0, p1.0 .0, p2.0 .0, p0.0 .0);
        let ay = _mm_setr_epi32(p0.1 .0, p1.1 .0, p2.1 .0, p0.1 .0);
        let bx = _mm_shuffle_epi32::<0b01_00_10_01>(ax);
        let by = _mm_shuffle_epi32::<0b01_00_10_01>(ay);
        // `x ^ (x >> 31)` is `|x|` or `|x| - 1`: lane k's two magnitudes (point
        // k's) tested by one OR, the lanes' results tested with the divisors'
        // below, one branch (the lanes ORed together and tested on their own were
        // about 5 instructions more a triangle; the steps between wrap, harmless).
        let mag =
            _mm_or_si128(_mm_xor_si128(ax, _mm_srai_epi32::<31>(ax)), _mm_xor_si128(ay, _mm_srai_epi32::<31>(ay)));
        let too_far = _mm_cmpgt_epi32(mag, _mm_set1_epi32((1 << FLOAT_COORD_BITS) - 1));
        let zero = _mm_setzero_si128();
        let (dx, dy) = (_mm_sub_epi32(bx, ax), _mm_sub_epi32(by, ay));
        // All-ones lanes where the edge is vertical (|dy| > |dx|).
        let vertical = _mm_cmpgt_epi32(_mm_abs_epi32(dy), _mm_abs_epi32(dx));
        // The side of greater V is the positive one: dy < 0 for a vertical edge,
        // dx > 0 for a horizontal one.
        let greater = _mm_blendv_epi8(_mm_cmpgt_epi32(dx, zero), _mm_cmpgt_epi32(zero, dy), vertical);
        let inside = _mm_set1_epi32(-i32::from(inside_positive));
        let lr = _mm_cmpeq_epi32(greater, inside);
        // (Macros rather than closures: a closure is a function of its own, kept
        // out of line without the caller's features.)
        // `(x ^ m) - m` is `-x` where `m` is all ones, `x` where it is zero.
        macro_rules! negate_where {
            ($x:expr, $m:expr) => {{
                let m = $m;
                _mm_sub_epi32(_mm_xor_si128($x, m), m)
            }};
        }
        macro_rules! wide {
            ($x:expr) => {
                _mm256_cvtepi32_epi64($x)
            };
        }
        // The ends in (x, y) order: a first where a <= b.
        let a_first =
            _mm_or_si128(_mm_cmpgt_epi32(bx, ax), _mm_andnot_si128(_mm_cmpgt_epi32(ay, by), _mm_cmpeq_epi32(ax, bx)));
        let (e0x, e0y) = (_mm_blendv_epi8(bx, ax, a_first), _mm_blendv_epi8(by, ay, a_first));
        let (e1x, e1y) = (_mm_blendv_epi8(ax, bx, a_first), _mm_blendv_epi8(ay, by, a_first));
        // V along u, t across w, from the end of smaller t.
        let au = _mm_blendv_epi8(ay, ax, vertical);
        let aw = _mm_blendv_epi8(ax, ay, vertical);
        let du = _mm_blendv_epi8(dy, dx, vertical);
        let dw = _mm_blendv_epi8(dx, dy, vertical);
        let backwards = _mm_cmpgt_epi32(zero, dw);
        let au = _mm_add_epi32(au, _mm_and_si128(du, backwards));
        let aw = _mm_add_epi32(aw, _mm_and_si128(dw, backwards));
        let du = negate_where!(du, backwards);
        let dw = negate_where!(dw, backwards);
        if _mm_movemask_ps(_mm_castsi128_ps(_mm_or_si128(too_far, _mm_cmpeq_epi32(dw, zero)))) & 0b111 != 0 {
            // A point beyond the bounds (the scalar path takes it), or two equal
            // points (the scalar path panics as it always did).
            return false;
        }
        // The floor divisions (see above): numerators, quotients, one correction.
        let scale_bits = ROOT_V_BITS - SNAP_BITS;
        let (awf, duf, dwf) = (_mm256_cvtepi32_pd(aw), _mm256_cvtepi32_pd(du), _mm256_cvtepi32_pd(dw));
        let n1 = _mm256_mul_pd(_mm256_mul_pd(awf, duf), _mm256_set1_pd(-f64::from(1u32 << scale_bits)));
        let n2 = _mm256_add_pd(n1, _mm256_mul_pd(duf, _mm256_set1_pd(root.span)));
        macro_rules! floor_div {
            ($n:expr) => {{
                let n = $n;
                let q = _mm256_floor_pd(_mm256_div_pd(n, dwf));
                let r = _mm256_sub_pd(n, _mm256_mul_pd(q, dwf));
                let over = _mm256_cmp_pd::<_CMP_LT_OQ>(r, _mm256_setzero_pd());
                _mm256_cvttpd_epi32(_mm256_sub_pd(q, _mm256_and_pd(over, _mm256_set1_pd(1.0))))
            }};
        }
        let (q1, q2) = (floor_div!(n1), floor_div!(n2));
        let origin = _mm256_slli_epi64::<{ (EDGE_FRAC_BITS - ROOT_V_BITS) as i32 }>(wide!(_mm_add_epi32(
            _mm_slli_epi32::<{ (ROOT_V_BITS - SNAP_BITS) as i32 }>(au),
            q1,
        )));
        let slope = _mm256_sll_epi64(wide!(_mm_sub_epi32(q2, q1)), _mm_cvtsi32_si128(root.slope_shift));
        // The word: V at t = 0 with TG, LR, `exact32` (always set here: the
        // coordinates' bound keeps `|a|, |b|` below `EXACT32_COEFFICIENT_LIMIT`) and
        // `vertex32` in its zero low bits (all-ones lanes masked to their bit).
        let vertex32 = _mm_cmpgt_epi32(
            _mm_set1_epi32(VERTEX_COEFFICIENT_LIMIT as i32),
            _mm_max_epi32(_mm_abs_epi32(dx), _mm_abs_epi32(dy)),
        );
        // The flags are masked and joined in the 32-bit lanes and widened once
        // (each widened and masked in 64-bit lanes: `many`'s GP at 480x270 864.3
        // -> 861.3 M instructions): they are the word's low bits, below the
        // origin's.
        const _: () =
            assert!(WORD_TG < 1 << 16 && WORD_LR < 1 << 16 && WORD_EXACT32 < 1 << 16 && WORD_VERTEX32 < 1 << 16);
        macro_rules! bit {
            ($b:expr) => {
                _mm_set1_epi32($b as i32)
            };
        }
        let flags = _mm_or_si128(
            _mm_or_si128(_mm_and_si128(vertical, bit!(WORD_TG)), _mm_and_si128(lr, bit!(WORD_LR))),
            _mm_or_si128(_mm_and_si128(vertex32, bit!(WORD_VERTEX32)), bit!(WORD_EXACT32)),
        );
        let word = _mm256_or_si256(origin, _mm256_cvtepu32_epi64(flags));
        let len = out.len();
        // Each code is one 32-byte register (its layout asserted above): the lanes' fields
        // transposed in registers and stored whole (the stores of the fields one
        // by one were 48 instructions a triangle, and their reads from the
        // registers' copies on the stack about as many again).
        // An edge's two ends as one 64-bit lane: x in the low half, y above.
        macro_rules! pairs {
            ($x:expr, $y:expr) => {{
                let (x, y) = ($x, $y);
                _mm256_set_m128i(_mm_unpackhi_epi32(x, y), _mm_unpacklo_epi32(x, y))
            }};
        }
        let (ends0, ends1) = (pairs!(e0x, e0y), pairs!(e1x, e1y));
        // Rows `r0..r3` (a field each, lane k edge k) to the first three columns
        // (edge k's four fields in order).
        let (t0, t1) = (_mm256_unpacklo_epi64(word, slope), _mm256_unpackhi_epi64(word, slope));
        let (t2, t3) = (_mm256_unpacklo_epi64(ends0, ends1), _mm256_unpackhi_epi64(ends0, ends1));
        let codes = [
            _mm256_permute2x128_si256::<0x20>(t0, t2),
            _mm256_permute2x128_si256::<0x20>(t1, t3),
            _mm256_permute2x128_si256::<0x31>(t0, t2),
        ];
        // SAFETY: the three slots after `len` were reserved above.
        let dst = unsafe { out.as_mut_ptr().add(len) }.cast::<__m256i>();
        for (k, code) in codes.into_iter().enumerate() {
            // SAFETY: the three codes' 96 bytes after `len` were reserved; code `k`
            // is the 32 bytes at `k`, aligned to 32 as every code in the vector's
            // buffer is (`EdgeCode`'s alignment, asserted above), every field
            // written with a valid value (the word's unused bits zero).
            #[allow(unsafe_code, reason = "the store of a code into reserved capacity")]
            unsafe {
                _mm256_store_si256(dst.add(k), code);
            }
        }
        // (Written in place rather than by `extend` of the three, which was not
        // inlined here: `many`'s GP 990 -> 1152 M instructions.)
        // SAFETY: the three slots after `len` were reserved and are written above.
        unsafe {
            out.set_len(len + 3);
        }
        true
    }

    /// A triangle's three codes when it lies within [`fast_bounds`] (then `true`;
    /// else `false`, nothing appended): the bounds tested on a fixed-size array,
    /// the three codes straight-line, each appended as soon as it is made (after
    /// one reservation). Through [`EdgeCode::push_outline`]'s general loop the
    /// compiler spilled the loop state around the inlined `new_fast`: about 126
    /// more instructions per triangle on `many`.
    #[inline(always)]
    fn push_triangle_fast(
        points: [(ScreenFx, ScreenFx); 3],
        inside_positive: bool,
        root_side: u32,
        out: &mut Vec<EdgeCode>,
    ) -> bool {
        if !fast_bounds(&points, root_side) {
            return false;
        }
        let [p0, p1, p2] = points;
        let root_bits = root_side.trailing_zeros();
        let code = |a, b| Self::new_fast(a, b, inside_positive, root_bits).expect("consecutive points differ");
        out.reserve(3);
        out.push(code(p0, p1));
        out.push(code(p1, p2));
        out.push(code(p2, p0));
        true
    }

    /// [`EdgeCode::new`] for endpoints and root side within [`fast_bounds`] (outside
    /// them its products may overflow), the root side given as `2^root_bits` pixels.
    ///
    /// V's values at the root borders are `floor((au dw + (t - aw) du) 2^8 / dw)`
    /// (see `v_at` in [`EdgeCode::new_general`]). `au 2^8` is an integer, so it comes
    /// out of the floor: `au 2^8 + floor((t - aw) du 2^8 / dw)`, whose numerator
    /// then fits an `i64` with no check per product. The GP makes 3 codes per
    /// triangle: the checked products, the `i128` fallback, the divisions' guards
    /// and a call per edge were about 240 instructions an edge on `many`.
    #[inline(always)]
    fn new_fast(
        a: (ScreenFx, ScreenFx),
        b: (ScreenFx, ScreenFx),
        inside_positive: bool,
        root_bits: u32,
    ) -> Option<Self> {
        let (ax, ay) = (i64::from(a.0 .0), i64::from(a.1 .0));
        let (bx, by) = (i64::from(b.0 .0), i64::from(b.1 .0));
        let (dx, dy) = (bx - ax, by - ay);
        let vertical = dy.abs() > dx.abs();
        let tg = if vertical { Tg::Vertical } else { Tg::Horizontal };
        // The side of greater V: for a vertical edge the point a + (1, 0), whose cross
        // product is -dy; for a horizontal edge a + (0, 1), cross product dx.
        let greater_side_positive = if vertical { dy < 0 } else { dx > 0 };
        let lr = greater_side_positive == inside_positive;
        let (pa, pb) = ((a.0 .0, a.1 .0), (b.0 .0, b.1 .0));
        let ends = if pa <= pb { [pa, pb] } else { [pb, pa] };
        // Swap to V = coordinate along (u), t = coordinate across (w), from the end
        // of smaller t (the canonical order: the rounding cannot depend on the
        // direction): `(au, aw)` that end, `(du, dw)` towards the other.
        let (au, aw, du, dw) = if vertical { (ax, ay, dx, dy) } else { (ay, ax, dy, dx) };
        let (au, aw, du, dw) = if dw < 0 { (au + du, aw + dw, -du, -dw) } else { (au, aw, du, dw) };
        if dw <= 0 {
            // Only when a == b (|dw| >= |du|); the test also tells the compiler that
            // the divisor is positive, so it drops the divisions' guards.
            return None;
        }
        let scale_bits = ROOT_V_BITS - SNAP_BITS;
        // floor(n / dw) for dw > 0 (the quotient and remainder of one division).
        let floor_div = |n: i64| n / dw - i64::from(n % dw < 0);
        // The numerators at t = 0 and t = root_side (in snapped units, a power of
        // two): `(t - aw) du 2^8`, the second the first plus `t du 2^8`.
        let n1 = (-aw * du) << scale_bits;
        let n2 = n1 + (du << (root_bits + SNAP_BITS + scale_bits));
        let (q1, q2) = (floor_div(n1), floor_div(n2));
        let shift = EDGE_FRAC_BITS - ROOT_V_BITS;
        let origin = ((au << scale_bits) + q1) << shift;
        // Exact: the difference has `shift` >= 16 zero low bits and the root side
        // is a power of two at most 2^13.
        let slope = ((q2 - q1) << shift) >> root_bits;
        // `|a|, |b|` are `|dy|, |dx|`; the ends are below `2^FAST_COORD_BITS`, which
        // is below `EXACT32_END_LIMIT`.
        const _: () = assert!(1 << FAST_COORD_BITS <= EXACT32_END_LIMIT);
        let exact32 = (dx.unsigned_abs() | dy.unsigned_abs()) < EXACT32_COEFFICIENT_LIMIT;
        Some(Self::from_fields(tg, lr, exact32, origin, slope, ends))
    }

    /// [`EdgeCode::new`] for any coordinates and root side the numbers support (the
    /// definition: checked products and an `i128` fallback): the GP's polygons,
    /// which lie in the window, never leave [`fast_bounds`].
    #[cold]
    #[inline(never)]
    fn new_general(
        a: (ScreenFx, ScreenFx),
        b: (ScreenFx, ScreenFx),
        inside_positive: bool,
        root_side: u32,
    ) -> Option<Self> {
        let (ax, ay) = (i64::from(a.0 .0), i64::from(a.1 .0));
        let (bx, by) = (i64::from(b.0 .0), i64::from(b.1 .0));
        let (dx, dy) = (bx - ax, by - ay);
        if dx == 0 && dy == 0 {
            return None;
        }
        let tg = if dy.abs() > dx.abs() { Tg::Vertical } else { Tg::Horizontal };
        // The side of greater V: for a vertical edge the point a + (1, 0), whose cross
        // product is -dy; for a horizontal edge a + (0, 1), cross product dx.
        let greater_side_positive = match tg {
            Tg::Vertical => -dy > 0,
            Tg::Horizontal => dx > 0,
        };
        let lr = greater_side_positive == inside_positive;
        // Swap to V = coordinate along (u), t = coordinate across (w).
        let (au, aw, bu, bw) = match tg {
            Tg::Vertical => (ax, ay, bx, by),
            Tg::Horizontal => (ay, ax, by, bx),
        };
        // Canonical order: increasing t, so the rounding cannot depend on direction.
        let (au, aw, bu, bw) = if aw <= bw { (au, aw, bu, bw) } else { (bu, bw, au, aw) };
        let (du, dw) = (bu - au, bw - aw);
        debug_assert!(dw > 0);
        // V(t) = au + (t - aw) du / dw, in snapped units; at t = 0 and t = root_side,
        // rounded down to 2^-ROOT_V_BITS pixel. On screens up to 8192 pixels every
        // term is below 2^51, so i64 is exact; i128 takes over beyond that.
        let scale_bits = ROOT_V_BITS - SNAP_BITS;
        let v_at = |t: i64| -> i128 {
            let exact64 = au
                .checked_mul(dw)
                .and_then(|p| (t - aw).checked_mul(du).and_then(|q| p.checked_add(q)))
                .and_then(|n| n.checked_mul(1 << scale_bits));
            match exact64 {
                Some(num) => i128::from(num.div_euclid(dw)),
                None => ((i128::from(au) * i128::from(dw) + i128::from(t - aw) * i128::from(du)) << scale_bits)
                    .div_euclid(i128::from(dw)),
            }
        };
        let side = i128::from(root_side);
        let v1 = v_at(0);
        let v2 = v_at(i64::from(root_side) * i64::from(SNAP_ONE));
        let shift = EDGE_FRAC_BITS - ROOT_V_BITS;
        let origin = (v1 << shift) as i64;
        let span = (v2 - v1) << shift;
        // Exact: span has `shift` >= 16 zero low bits and root_side <= 2^13, a power
        // of two (the fast path takes the quotient as a shift).
        debug_assert_eq!(span % side, 0);
        let slope = (span / side) as i64;
        let (pa, pb) = ((a.0 .0, a.1 .0), (b.0 .0, b.1 .0));
        let ends = if pa <= pb { [pa, pb] } else { [pb, pa] };
        let exact32 = ExactLine::through(ends).fits_32();
        Some(Self::from_fields(tg, lr, exact32, origin, slope, ends))
    }

    /// The code of its fields; `origin`'s low 16 bits must be zero (V rounded to
    /// `2^-ROOT_V_BITS` pixel).
    #[inline(always)]
    fn from_fields(tg: Tg, lr: bool, exact32: bool, origin: i64, slope: i64, ends: [(i32, i32); 2]) -> Self {
        debug_assert_eq!(origin & !WORD_ORIGIN, 0);
        let flag = |set: bool, bit: i64| if set { bit } else { 0 };
        let [(x0, y0), (x1, y1)] = ends;
        let (dx, dy) = (i64::from(x1) - i64::from(x0), i64::from(y1) - i64::from(y0));
        let vertex32 = exact32 && dx.unsigned_abs().max(dy.unsigned_abs()) < VERTEX_COEFFICIENT_LIMIT as u64;
        let word = origin
            | flag(tg == Tg::Vertical, WORD_TG)
            | flag(lr, WORD_LR)
            | flag(exact32, WORD_EXACT32)
            | flag(vertex32, WORD_VERTEX32);
        Self { word, slope: EdgeCoord(slope), ends }
    }

    /// TG: vertical or horizontal.
    #[inline(always)]
    pub fn tg(&self) -> Tg {
        if self.word & WORD_TG != 0 {
            Tg::Vertical
        } else {
            Tg::Horizontal
        }
    }

    /// LR: the polygon lies on the side of greater V.
    #[inline(always)]
    pub fn lr(&self) -> bool {
        self.word & WORD_LR != 0
    }

    /// TG and LR as one number, `TG + 2 LR` (TG 1 for [`Tg::Vertical`], LR 1 for
    /// [`EdgeCode::lr`]): the index of the SPP's table of an edge's words by its flags,
    /// in one mask of the word.
    #[inline(always)]
    pub fn tg_lr(&self) -> usize {
        const _: () = assert!(WORD_TG == 1 && WORD_LR == 2);
        (self.word & (WORD_TG | WORD_LR)) as usize
    }

    /// [`ExactLine::fits_32`] of [`EdgeCode::exact`], found once per edge: the SPP's
    /// 32-bit path for the exact sets at vertex pixels takes the edge without
    /// checking per cell.
    #[inline(always)]
    pub fn exact32(&self) -> bool {
        self.word & WORD_EXACT32 != 0
    }

    /// The code with [`EdgeCode::exact32`] cleared (the SPP's tests of its 64-bit
    /// vertex paths).
    #[cfg(test)]
    pub(crate) fn without_exact32(self) -> Self {
        Self { word: self.word & !WORD_EXACT32, ..self }
    }

    /// V at line `t = 0`.
    #[inline(always)]
    pub fn origin(&self) -> EdgeCoord {
        EdgeCoord(self.word & WORD_ORIGIN)
    }

    /// The exact line through the snapped endpoints, for
    /// [`super::tables::SppMode::Exact`] and the vertex pixels (made from the ends
    /// where it is needed: a few instructions against 24 more bytes a code).
    #[inline(always)]
    pub fn exact(&self) -> ExactLine {
        ExactLine::oriented(self.ends, self.tg() == Tg::Vertical)
    }

    /// Whether the SPP's 32-bit vertex words take the edge: [`EdgeCode::exact32`], and
    /// `|a|, |b|` (`|dy|, |dx|`) below [`VERTEX_COEFFICIENT_LIMIT`] (then
    /// [`EdgeCode::exact_i32`] is exact).
    #[inline(always)]
    pub fn vertex32(&self) -> bool {
        self.word & WORD_VERTEX32 != 0
    }

    /// `a, b` of [`EdgeCode::exact`] and its `c` modulo `2^32`, in wrapping 32-bit
    /// arithmetic: `a, b` exact where [`EdgeCode::vertex32`] holds, and `c` then
    /// what the SPP's wrapping sums need (fewer instructions than the 64-bit line
    /// made and narrowed, in the vertex cells of every small polygon: the narrowed
    /// line was +2.1 M instructions on terrain's raster, +0.5 M on default's).
    ///
    /// The ends are in canonical order, so `dx >= 0`, and a horizontal edge's `dx`
    /// is not 0 (`|dx| >= |dy|`, distinct ends): its line is always flipped
    /// ([`ExactLine::oriented`]: `dx > 0`), a vertical one's where `dy < 0`. The flip
    /// as a mask (all ones where flipped) and the signs by it: 3 instructions fewer in
    /// each vertex cell than the general test of both signs and two selects.
    #[inline(always)]
    pub fn exact_i32(&self) -> (i32, i32, i32) {
        let [(x0, y0), (x1, y1)] = self.ends;
        let (dx, dy) = (x1.wrapping_sub(x0), y1.wrapping_sub(y0));
        let flip = if self.tg() == Tg::Vertical { dy >> 31 } else { -1 };
        // `flip` all ones: `a = -dy`, `b = dx`; 0: `a = dy`, `b = -dx`.
        let (a, b) = ((dy ^ flip).wrapping_sub(flip), flip.wrapping_sub(dx ^ flip));
        debug_assert!(
            !self.vertex32() || (i64::from(a), i64::from(b)) == (self.exact().a, self.exact().b),
            "exact_i32 is the exact line's a, b"
        );
        (a, b, a.wrapping_mul(x0).wrapping_add(b.wrapping_mul(y0)).wrapping_neg())
    }

    /// V on the integer pixel line `t` (a row `y = t` for a vertical edge, a column
    /// `x = t` for a horizontal one). Exact.
    #[inline]
    pub fn v_at(&self, t: i64) -> EdgeCoord {
        EdgeCoord(self.origin().0 + self.slope.0 * t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64) -> (ScreenFx, ScreenFx) {
        (ScreenFx::from_f64(x), ScreenFx::from_f64(y))
    }

    /// A snapped coordinate from a proptest choice: small, on a screen, near the
    /// fast path's bound either side, or anywhere up to `2^30` (beyond, the exact
    /// line's `c` overflows `i64` in the definition itself).
    fn coordinate() -> impl proptest::strategy::Strategy<Value = i32> {
        use proptest::prelude::*;
        let edge = 1i32 << FAST_COORD_BITS;
        let float = 1i32 << FLOAT_COORD_BITS;
        const FAR: i32 = 1 << 30;
        prop_oneof![
            -64i32..64,
            (float - 300)..(float + 300),
            (-float - 300)..(-float + 300),
            Just(float - 1),
            Just(-float),
            -(4 << SNAP_BITS)..(8192 << SNAP_BITS),
            (edge - 300)..(edge + 300),
            (-edge - 300)..(-edge + 300),
            -FAR..FAR,
            Just(-FAR),
            Just(FAR),
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(20_000))]

        /// The fast path gives the definition's code, bit for bit (and the same
        /// `None`), over random and extreme endpoints, both orientations and every
        /// root level (and one beyond, which takes the general path).
        #[test]
        fn new_is_the_plain_definition(
            ax in coordinate(),
            ay in coordinate(),
            bx in coordinate(),
            by in coordinate(),
            near in proptest::prelude::any::<(bool, bool, i8, i8)>(),
            inside in proptest::prelude::any::<bool>(),
            level in 0u32..=MAX_ROOT_LEVEL + 1,
        ) {
            let root_side = 4u32 << level;
            // Half the cases: b near a (short edges, equal ends, 45-degree ties).
            let (bx, by) = match near {
                (true, flat, ddx, ddy) => {
                    let ddy = if flat { ddx } else { ddy };
                    (ax.saturating_add(i32::from(ddx)), ay.saturating_add(i32::from(ddy)))
                }
                _ => (bx, by),
            };
            let (a, b) = ((ScreenFx(ax), ScreenFx(ay)), (ScreenFx(bx), ScreenFx(by)));
            proptest::prop_assert_eq!(EdgeCode::new(a, b, inside, root_side), EdgeCode::new_general(a, b, inside, root_side));
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(20_000))]

        /// The straight-line triangle path of [`EdgeCode::push_outline`], and
        /// [`EdgeCode::push_triangle`], give the definition's codes, in order, over
        /// random and extreme corners.
        #[test]
        fn push_outline_of_a_triangle_is_the_plain_definition(
            xs in proptest::array::uniform3(coordinate()),
            ys in proptest::array::uniform3(coordinate()),
            inside in proptest::prelude::any::<bool>(),
            level in 0u32..=MAX_ROOT_LEVEL + 1,
        ) {
            let root_side = 4u32 << level;
            let pts: Vec<(ScreenFx, ScreenFx)> = (0..3).map(|i| (ScreenFx(xs[i]), ScreenFx(ys[i]))).collect();
            let want: Option<Vec<EdgeCode>> =
                (0..3).map(|i| EdgeCode::new_general(pts[i], pts[(i + 1) % 3], inside, root_side)).collect();
            // Equal consecutive corners panic (a snapped outline has none).
            if let Some(want) = want {
                let mut got = Vec::new();
                EdgeCode::push_outline(&pts, inside, root_side, &mut got);
                proptest::prop_assert_eq!(&got, &want);
                let mut got = vec![want[0]];
                EdgeCode::push_triangle([pts[0], pts[1], pts[2]], inside, root_side, &mut got);
                proptest::prop_assert_eq!(&got[1..], &want[..]);
            }
        }
    }

    /// [`EdgeCode::push_triangle_avx2`]'s codes of `pts` (`None` where it declines
    /// the triangle), or `None` without AVX2.
    fn triangle_avx2(pts: [(ScreenFx, ScreenFx); 3], inside: bool, root_side: u32) -> Option<Vec<EdgeCode>> {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            let mut got = vec![EdgeCode::new_general(pts[0], pts[1], inside, 4).unwrap_or(DUMMY)];
            // SAFETY: AVX2 was detected just above.
            #[allow(unsafe_code, reason = "the AVX2 path under test, after detection")]
            let taken = unsafe { EdgeCode::push_triangle_avx2(pts, inside, root_side, &mut got) };
            assert_eq!(got.len(), if taken { 4 } else { 1 }, "appends three codes or none");
            return taken.then(|| got[1..].to_vec());
        }
        None
    }

    /// Any code (what [`triangle_avx2`] puts before the appended ones).
    const DUMMY: EdgeCode = EdgeCode { word: 1 << 16, slope: EdgeCoord(2), ends: [(6, 7), (8, 9)] };

    /// The definition's codes of the triangle `pts`, or `None` if two consecutive
    /// points are equal.
    fn triangle_plain(pts: [(ScreenFx, ScreenFx); 3], inside: bool, root_side: u32) -> Option<Vec<EdgeCode>> {
        (0..3).map(|i| EdgeCode::new_general(pts[i], pts[(i + 1) % 3], inside, root_side)).collect()
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(50_000))]

        /// [`EdgeCode::push_triangle_avx2`] gives the definition's codes, in order,
        /// wherever it takes a triangle (random and extreme corners around its
        /// bounds, every root level and one beyond), and takes every triangle of
        /// distinct points within its bounds.
        #[test]
        fn push_triangle_avx2_is_the_plain_definition(
            xs in proptest::array::uniform3(coordinate()),
            ys in proptest::array::uniform3(coordinate()),
            near in proptest::prelude::any::<(bool, [i8; 4])>(),
            inside in proptest::prelude::any::<bool>(),
            level in 0u32..=MAX_ROOT_LEVEL + 1,
        ) {
            let root_side = 4u32 << level;
            let (mut xs, mut ys) = (xs, ys);
            if near.0 {
                // Small triangles (equal points and 45-degree ties among them).
                for k in 1..3 {
                    xs[k] = xs[0].saturating_add(i32::from(near.1[2 * k - 2] >> 4));
                    ys[k] = ys[0].saturating_add(i32::from(near.1[2 * k - 1] >> 4));
                }
            }
            let pts = [0, 1, 2].map(|i| (ScreenFx(xs[i]), ScreenFx(ys[i])));
            let within = xs.iter().chain(&ys).all(|&c| (c ^ (c >> 31)) >> FLOAT_COORD_BITS == 0)
                && level <= MAX_ROOT_LEVEL;
            let want = triangle_plain(pts, inside, root_side);
            if let Some(got) = triangle_avx2(pts, inside, root_side) {
                proptest::prop_assert_eq!(Some(got), want);
            } else if cfg!(target_arch = "x86_64") && std::is_x86_feature_detected!("avx2") {
                proptest::prop_assert!(!within || want.is_none(), "declined {:?}", pts);
            }
        }
    }

    /// [`EdgeCode::push_triangle_avx2`] on every triangle whose corners take the
    /// extreme coordinates of its bounds and their neighbours (where the
    /// numerators, quotients and products of its float divisions are largest), at
    /// the largest and smallest root sides.
    #[test]
    fn push_triangle_avx2_at_its_bounds() {
        let m = 1i32 << FLOAT_COORD_BITS;
        let values = [-m, -m + 1, -m + 2, -1, 0, 1, m - 3, m - 2, m - 1];
        let mut taken = 0;
        for i in 0..values.len().pow(6) {
            let mut k = i;
            let mut c = [0i32; 6];
            for v in &mut c {
                *v = values[k % values.len()];
                k /= values.len();
            }
            let pts =
                [(ScreenFx(c[0]), ScreenFx(c[1])), (ScreenFx(c[2]), ScreenFx(c[3])), (ScreenFx(c[4]), ScreenFx(c[5]))];
            for (inside, level) in [(i % 2 == 0, MAX_ROOT_LEVEL), (i % 2 == 1, 0)] {
                let want = triangle_plain(pts, inside, 4 << level);
                match triangle_avx2(pts, inside, 4 << level) {
                    Some(got) => {
                        assert_eq!(Some(got), want, "{pts:?}");
                        taken += 1;
                    }
                    None => assert!(want.is_none() || !std::is_x86_feature_detected!("avx2"), "{pts:?}"),
                }
            }
        }
        assert!(taken > 500_000 || !std::is_x86_feature_detected!("avx2"), "{taken}");
        // A coordinate just beyond the bounds, of any point: not taken (the
        // scalar path makes those codes).
        for far in [m, -m - 1] {
            for k in 0..6 {
                let mut c = [0, 0, 5, 0, 0, 7];
                c[k] = far;
                let pts = [
                    (ScreenFx(c[0]), ScreenFx(c[1])),
                    (ScreenFx(c[2]), ScreenFx(c[3])),
                    (ScreenFx(c[4]), ScreenFx(c[5])),
                ];
                assert_eq!(triangle_avx2(pts, k % 2 == 0, 4 << MAX_ROOT_LEVEL), None, "{pts:?}");
            }
        }
    }

    #[test]
    fn new_is_the_plain_definition_on_a_grid() {
        // Every pair of points of a small grid around the origin and around a far
        // corner, every root level: ties of |dx| = |dy|, both directions.
        for &(ox, oy) in &[(0i32, 0i32), (1919 << SNAP_BITS, 1079 << SNAP_BITS), (-5, 7)] {
            let pts: Vec<(ScreenFx, ScreenFx)> =
                (-4..=4).flat_map(|x| (-4..=4).map(move |y| (ScreenFx(ox + x * 37), ScreenFx(oy + y * 53)))).collect();
            for level in 0..=MAX_ROOT_LEVEL {
                for &a in &pts {
                    for &b in &pts {
                        for inside in [false, true] {
                            assert_eq!(
                                EdgeCode::new(a, b, inside, 4 << level),
                                EdgeCode::new_general(a, b, inside, 4 << level)
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn push_outline_is_new_per_edge() {
        // Outlines inside and outside the fast path's bounds, either way round.
        let far = 1 << FAST_COORD_BITS;
        let outlines: [&[(i32, i32)]; 4] = [
            &[(0, 0), (2560, 13), (1300, 2700)],
            &[(100, 100), (90, 5000), (-4000, 5100), (-4100, 120), (-2000, -7)],
            &[(0, 0), (far + 5, 3), (7, far - 1)],
            &[(-far - 9, 0), (4, -far), (1 << 29, 1 << 29)],
        ];
        for pts in outlines {
            let pts: Vec<(ScreenFx, ScreenFx)> = pts.iter().map(|&(x, y)| (ScreenFx(x), ScreenFx(y))).collect();
            for level in [0, 5, MAX_ROOT_LEVEL, MAX_ROOT_LEVEL + 1] {
                for inside in [false, true] {
                    let mut got = vec![EdgeCode::new_general(pts[0], pts[1], inside, 4).unwrap()];
                    EdgeCode::push_outline(&pts, inside, 4 << level, &mut got);
                    let n = pts.len();
                    let want: Vec<EdgeCode> = (0..n)
                        .map(|i| EdgeCode::new_general(pts[i], pts[(i + 1) % n], inside, 4 << level).unwrap())
                        .collect();
                    assert_eq!(got[1..], want[..], "{pts:?} level {level}");
                }
            }
        }
    }

    #[test]
    fn direction_does_not_change_the_line() {
        let a = p(10.3, 3.7);
        let b = p(13.9, 200.1);
        let e1 = EdgeCode::new(a, b, true, 512).unwrap();
        let e2 = EdgeCode::new(b, a, false, 512).unwrap();
        assert_eq!(e1, e2, "same line, same side => same code");
        let e3 = EdgeCode::new(b, a, true, 512).unwrap();
        assert_eq!((e1.origin(), e1.slope, e1.tg(), e1.exact()), (e3.origin(), e3.slope, e3.tg(), e3.exact()));
        assert_ne!(e1.lr(), e3.lr());
    }

    #[test]
    fn values_are_close_to_the_true_line() {
        let e = EdgeCode::new(p(10.0, 0.0), p(20.0, 100.0), true, 512).unwrap();
        assert_eq!(e.tg(), Tg::Vertical);
        for t in [0i64, 50, 100, 511] {
            let want = 10.0 + t as f64 * 0.1;
            assert!((e.v_at(t).to_f64() - want).abs() < 1e-4, "t={t}");
        }
        let h = EdgeCode::new(p(0.0, 5.0), p(100.0, 15.0), true, 512).unwrap();
        assert_eq!(h.tg(), Tg::Horizontal);
        assert!((h.v_at(50).to_f64() - 10.0).abs() < 1e-4);
    }

    #[test]
    fn lr_marks_the_inside() {
        // Clockwise on screen (y down): (0,0) -> (10,0) -> (0,10); inside is where the
        // cross product is positive.
        let right = EdgeCode::new(p(0.0, 10.0), p(0.0, 0.0), true, 64).unwrap();
        // Edge x = 0 going up, interior (x > 0): cross((0,-10),(1,0)) = 10 > 0.
        assert_eq!(right.tg(), Tg::Vertical);
        assert!(right.lr());
    }
}
