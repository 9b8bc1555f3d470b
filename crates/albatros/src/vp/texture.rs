//! The texture unit of the colour computers (CC, P2 "Блок текстуры", fig. 1): texture
//! maps, their mip pyramids and trilinear filtering.
//!
//! Input: a pixel's texture coordinates `u`, `v` (in periods, from the CC's
//! fractional-linear evaluation) and its footprint `S/L = 2 delta Z^2 PAR` (in
//! periods). Output: the modulation value `T` in `0..=1` that blends the face's two
//! colours, `C = C1 T + C2 (1 - T)` (done by the CC, [`super::cc`]).
//!
//! The rules, after P2:
//! - A map holds **one modulation value per texel** (not a colour), `2^n x 2^n`
//!   texels, with its pyramid of `2^(n-1) x 2^(n-1)` ... `1 x 1` levels, each level
//!   the 2 x 2 box filter of the one above it.
//! - The map address is the **fractional part** of `u`, `v`: maps repeat.
//! - **Trilinear**: bilinear interpolation in a level between the four texel centres
//!   nearest to the point (P2 eq. 3), in two adjacent levels, blended by the footprint.
//!   The level of detail is `lod = log2((S/L) 2^n)`, the footprint in level-0 texels,
//!   clamped to the pyramid; the `log2` is the TAC's ROM ([`super::tac`]).
//!
//! **Texel format**: `u8`, `T = texel / 255`, as the hardware's map memory held it.
//! Texel `(i, j)` is column `i` (along `u`, texel `i` covers `u` in
//! `[i, i + 1) / 2^n`) and row `j` (along `v`, likewise), rows stored from `v = 0` up.
//! A PNG's top row is the map's last row, so an image appears upright on a face seen
//! from its front with `u` to the right and `v` up.
//!
//! **Invariant**: sampling never panics and never leaves `0..=1`, whatever `u`, `v`
//! and the footprint (NaN and infinities included): every address is wrapped with a
//! mask, and a NaN level of detail falls to level 0.
//!
//! Files: [`load_png`] and [`TextureMaps::from_scene`] read PNG files; they sit at the
//! library's edge like `db::load` and are called once at load, never per frame.

use std::fmt;
use std::path::{Path, PathBuf};

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

#[cfg(target_arch = "x86_64")]
use super::tac::{floor_avx512, small_int_avx2, small_int_avx512};
use super::tac::{small_int, TacRom};
use crate::db::{Scene, TextureSource};

/// The names of the built-in procedural maps ([`builtin`]), the names a scene's
/// texture may give as `builtin`.
pub const BUILTIN_NAMES: &[&str] = &["grass", "asphalt", "concrete", "checker"];

/// `log2` of the side of the built-in maps: 256 x 256 texels, as fine as a runway
/// needs and quick to generate (about a millisecond each).
pub const BUILTIN_LOG2_SIDE: u32 = 8;

/// `log2` of the largest map side accepted from a file: 4096 x 4096 texels (16 MiB of
/// level 0 texels, 21 MiB with the pyramid).
pub const MAX_LOG2_SIDE: u32 = 12;

/// The largest map side accepted from a file.
pub const MAX_SIDE: u32 = 1 << MAX_LOG2_SIDE;

/// Squares per period along `u` and along `v` of the built-in `checker` map: square
/// `(a, b)` (`a = floor(8 u)`, `b = floor(8 v)` of the fractional parts) has `T = 1`
/// when `a + b` is even, else `T = 0`.
pub const CHECKER_SQUARES: u32 = 8;

/// The texel value of `T = 1`.
const TEXEL_ONE: f32 = 255.0;

/// A single-channel modulation map `2^n x 2^n` with its mip pyramid down to 1 x 1.
#[derive(Clone, PartialEq, Eq)]
pub struct TextureMap {
    /// `n`: level 0 is `2^n x 2^n`.
    log2_side: u32,
    /// All levels, level 0 first, each row-major (`j * side + i`).
    texels: Vec<u8>,
    /// Where each level starts in `texels`, `n + 1` entries.
    offsets: Vec<usize>,
    /// The same levels laid out for one 4-byte read per bilinear look-up (the
    /// AVX2 copy's gathers, [`MapAvx2::sample_avx2`]): level `k` (side `s`)
    /// is `s` rows of `s + 1` texel pairs, pair `(r, c)` at byte
    /// `pair_start(n, s) + 2 (r (s + 1) + c)` holding texels `(c mod s, r)` and
    /// `(c mod s, (r + 1) mod s)`. So the 4 bytes at pair `(r0, c0)` are `T1, T2,
    /// T3, T4` of P2 eq. (3), wrapped, with no mask of the `+ 1`s. Twice the
    /// texels' memory (plus a column per level).
    pairs: Vec<u8>,
    /// Each level `k`'s constants of a look-up in the pair layout, `[2^(n-k)` as
    /// `f32` bits, `2^(n-k) - 1`, `2^(n-k) + 1`, `pair_start]`, levels above `n`
    /// as `n`: where a group's lanes are all in one level, the AVX2 look-up takes
    /// them from here ([`MapAvx2::level_lanes`]).
    level_constants: [[u32; 4]; LEVEL_CONSTANTS],
}

/// [`TextureMap::level_constants`]' entries: levels `0..=MAX_LOG2_SIDE`, and as
/// many more, so that a level masked to 4 bits is inside.
const LEVEL_CONSTANTS: usize = 16;
const _: () = assert!((MAX_LOG2_SIDE as usize) < LEVEL_CONSTANTS && LEVEL_CONSTANTS.is_power_of_two());

impl fmt::Debug for TextureMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TextureMap").field("side", &self.side()).field("levels", &self.levels()).finish_non_exhaustive()
    }
}

impl TextureMap {
    /// A map from its level-0 texels (row-major, `side * side` of them, rows from
    /// `v = 0` up); builds the pyramid. `None` unless `side` is a power of two not
    /// above [`MAX_SIDE`] and the texel count fits it.
    pub fn from_texels(side: u32, texels: Vec<u8>) -> Option<Self> {
        if !side.is_power_of_two() || side > MAX_SIDE || texels.len() != (side as usize).pow(2) {
            return None;
        }
        let n = side.trailing_zeros();
        Some(Self::build(n, texels))
    }

    /// Builds the pyramid over level 0. Every level is the 2 x 2 box filter of the one
    /// above, computed exactly (as sums of level-0 texels) and rounded once, so that
    /// rounding does not drift down the pyramid: a map's 1 x 1 level is its mean to
    /// half a texel step.
    fn build(n: u32, level0: Vec<u8>) -> Self {
        let mut offsets = Vec::with_capacity(n as usize + 1);
        let total: usize = (0..=n).map(|k| 1usize << (2 * (n - k))).sum();
        let mut texels = Vec::with_capacity(total);
        // Sums of level-0 texels over each texel of the current level (at most
        // 4^12 * 255 < 2^32).
        let mut sums: Vec<u32> = level0.iter().map(|&t| u32::from(t)).collect();
        offsets.push(0);
        texels.extend_from_slice(&level0);
        for k in 1..=n {
            let side = 1usize << (n - k);
            let above = side * 2;
            let next: Vec<u32> = (0..side * side)
                .map(|idx| {
                    let (i, j) = (idx % side, idx / side);
                    let (i2, j2) = (2 * i, 2 * j);
                    sums[j2 * above + i2]
                        + sums[j2 * above + i2 + 1]
                        + sums[(j2 + 1) * above + i2]
                        + sums[(j2 + 1) * above + i2 + 1]
                })
                .collect();
            // A level-k texel is the mean of 4^k level-0 texels: round half up.
            let count_log2 = 2 * k;
            offsets.push(texels.len());
            texels.extend(next.iter().map(|&s| ((s + (1 << (count_log2 - 1))) >> count_log2) as u8));
            sums = next;
        }
        let pairs = Self::pairs(n, &texels, &offsets);
        let level_constants = std::array::from_fn(|k| {
            let side = 1u32 << (n - (k as u32).min(n));
            [(side as f32).to_bits(), side - 1, side + 1, pair_start(n, side)]
        });
        Self { log2_side: n, texels, offsets, pairs, level_constants }
    }

    /// The pair layout of the levels (see [`Self::pairs`]'s field).
    fn pairs(n: u32, texels: &[u8], offsets: &[usize]) -> Vec<u8> {
        // The last level (side 1) starts at `pair_start(n, 1)` and holds 4 bytes.
        let mut pairs = Vec::with_capacity(pair_start(n, 1) as usize + 4);
        for k in 0..=n {
            let s = 1usize << (n - k);
            let level = &texels[offsets[k as usize]..][..s * s];
            debug_assert_eq!(pairs.len(), pair_start(n, s as u32) as usize);
            for r in 0..s {
                for c in 0..=s {
                    pairs.push(level[r * s + c % s]);
                    pairs.push(level[(r + 1) % s * s + c % s]);
                }
            }
        }
        pairs
    }

    /// `n`, where level 0 is `2^n x 2^n`.
    pub fn log2_side(&self) -> u32 {
        self.log2_side
    }

    /// The side of level 0.
    pub fn side(&self) -> u32 {
        1 << self.log2_side
    }

    /// Number of levels, `n + 1` (the last is 1 x 1).
    pub fn levels(&self) -> u32 {
        self.log2_side + 1
    }

    /// The texels of level `k` (side `2^(n-k)`), row-major; empty past the last level.
    pub fn level(&self, k: u32) -> &[u8] {
        let Some(&start) = self.offsets.get(k as usize) else { return &[] };
        let side = 1usize << (self.log2_side - k);
        &self.texels[start..start + side * side]
    }

    /// Texel `(i, j)` of level `k`, the indices wrapped (maps repeat).
    #[inline]
    pub fn texel(&self, k: u32, i: i32, j: i32) -> u8 {
        let k = k.min(self.log2_side);
        let mask = (1i32 << (self.log2_side - k)) - 1;
        let side = (mask + 1) as usize;
        self.texels[self.offsets[k as usize] + (j & mask) as usize * side + (i & mask) as usize]
    }

    /// Bilinear interpolation in level `k` at `(u, v)` (in periods; the fractional parts
    /// address the map), P2 eq. (3):
    /// `T' = (1 - Ku)((1 - Kv) T1 + Kv T2) + Ku((1 - Kv) T3 + Kv T4)`, `T1..T4` the
    /// texels at the four texel centres around the point (`T1` lower-left, `T2` above
    /// it, `T3` right of it, `T4` diagonal). The hardware stored
    /// `T1, T3 - T1, T2 - T1, T4 - T3 - T2 + T1` to save multipliers (P2); the value is
    /// the same.
    #[inline]
    pub fn bilinear(&self, k: u32, u: f32, v: f32) -> f32 {
        let k = k.min(self.log2_side);
        let side = (1u32 << (self.log2_side - k)) as f32;
        // Texel centres sit at (i + 1/2) / side.
        let (i0, ku) = split(fract01(u) * side - 0.5);
        let (j0, kv) = split(fract01(v) * side - 0.5);
        let [t1, t2, t3, t4] = self.quad(k, i0, j0).map(f32::from);
        eq3(ku, kv, t1, t2, t3, t4)
    }

    /// The texels `T1..T4` of P2 eq. (3) for the texel centres `(i0, j0)` to
    /// `(i0 + 1, j0 + 1)` of level `k` (at most `n`), wrapped: `[T1, T2, T3, T4]` =
    /// `(i0, j0)`, `(i0, j0 + 1)`, `(i0 + 1, j0)`, `(i0 + 1, j0 + 1)`. The level's
    /// offset, side and mask are found once for the four.
    #[inline]
    fn quad(&self, k: u32, i0: i32, j0: i32) -> [u8; 4] {
        let log2_side = self.log2_side - k;
        let mask = (1i32 << log2_side) - 1;
        let level = &self.texels[self.offsets[k as usize]..];
        let (c0, c1) = ((i0 & mask) as usize, (i0.wrapping_add(1) & mask) as usize);
        let (r0, r1) = (((j0 & mask) as usize) << log2_side, ((j0.wrapping_add(1) & mask) as usize) << log2_side);
        [level[r0 + c0], level[r1 + c0], level[r0 + c1], level[r1 + c1]]
    }

    /// The level of detail for a footprint of `footprint` periods (P2's `S/L`): `log2`
    /// of the footprint in level-0 texels, clamped to `0..=n` (NaN gives 0).
    #[inline]
    pub fn lod(&self, footprint: f32) -> f32 {
        let n = self.log2_side;
        lod_of_texels(TacRom::get(), footprint * self.side() as f32, n as f32, (2u32 << n) as f32)
    }

    /// Trilinear filtering: bilinear in levels `floor(lod)` and the next, blended by
    /// the fractional part of `lod` (P2: `T = Kr T' + (1 - Kr) T''`, `Kr` from the
    /// footprint).
    #[inline]
    pub fn trilinear(&self, u: f32, v: f32, lod: f32) -> f32 {
        let lod = lod.max(0.0).min(self.log2_side as f32);
        // Non-negative and at most n: the cast is the floor.
        let k = lod as u32;
        let kr = lod - k as f32;
        let fine = self.bilinear(k, u, v);
        if kr == 0.0 || k >= self.log2_side {
            return fine;
        }
        let coarse = self.bilinear(k + 1, u, v);
        fine + kr * (coarse - fine)
    }

    /// The filtered modulation `T` at `(u, v)` for a footprint of `footprint` periods.
    #[inline]
    pub fn sample(&self, u: f32, v: f32, footprint: f32) -> f32 {
        self.trilinear(u, v, self.lod(footprint))
    }

    /// [`Self::sample`] for `N` pixels side by side: lane `l` of the result is
    /// `self.sample(u[l], v[l], footprint[l])`, bit for bit. Every lane is sampled,
    /// whatever its inputs (the addresses are wrapped with masks), so that no
    /// lane-by-lane branch is needed; the colour computers fill a group's spare
    /// lanes with its last pixel.
    ///
    /// The same operations as [`Self::sample`] lane by lane, in the same order, laid
    /// out as arrays over the lanes so that the arithmetic vectorises: only the
    /// TAC's `log2` ROM reads and the texel reads go lane by lane. The clamps of
    /// the level of detail are selects over lanes (all computed, one kept). Both
    /// levels' look-ups share the fractional parts of `u`, `v`; when no lane blends
    /// in a coarser level (every `kr` is 0: a magnified map, or the last level),
    /// that level is not read.
    #[inline(always)]
    pub fn sample_lanes<const N: usize>(&self, u: &[f32; N], v: &[f32; N], footprint: &[f32; N]) -> [f32; N] {
        let n = self.log2_side;
        // Level of detail ([`Self::lod`], [`lod_of_texels`]).
        let (side, top, beyond) = (self.side() as f32, n as f32, (2u32 << n) as f32);
        let texels: [f32; N] = std::array::from_fn(|l| footprint[l] * side);
        // `log2` of every lane (finite whatever the bits), kept where the clamp
        // does not settle the level.
        let log = TacRom::get().log2_lanes(&texels);
        let mut lod = [0.0f32; N];
        for l in 0..N {
            let above = if texels[l] < beyond { log[l].min(top) } else { top };
            lod[l] = if texels[l] > 1.0 { above } else { 0.0 };
        }
        // [`Self::trilinear`]: `lod` is already in `0..=n`, so its clamp is the
        // identity (a zero's sign aside, which changes neither `k` nor `kr`), and
        // its integer part is its floor.
        let mut kr = [0.0f32; N];
        let mut k = [0i32; N];
        let mut fu = [0.0f32; N];
        let mut fv = [0.0f32; N];
        for l in 0..N {
            let floor = lod[l].floor();
            kr[l] = lod[l] - floor;
            k[l] = small_int(floor);
            fu[l] = fract01(u[l]);
            fv[l] = fract01(v[l]);
        }
        // [`Self::bilinear`] in level `k`.
        let fine = LevelLookup::new(n, &k, &fu, &fv).read(&self.texels);
        if kr == [0.0; N] {
            // Trilinear keeps the fine value alone in every lane.
            return fine;
        }
        // And in level `k + 1` (`k` again at the last level, where `kr` is 0 and
        // the coarse value drops out of the blend).
        for k in &mut k {
            *k = (*k + 1).min(n as i32);
        }
        let coarse = LevelLookup::new(n, &k, &fu, &fv).read(&self.texels);
        // Where `kr` is 0 the blend is the fine value exactly: both values are
        // finite, the fine one is not -0, and `fine + 0 * d` is `fine`.
        std::array::from_fn(|l| fine[l] + kr[l] * (coarse[l] - fine[l]))
    }
}

/// A map's constants for the AVX2 copy of the texture unit, each in a register's
/// lanes ([`TextureMap::avx2`]): set up once per polygon by the colour computers
/// ([`super::cc`]), so that a cell's look-ups take them from memory as operands
/// rather than finding the side, the clamps and the pair layout's sizes again per
/// half-cell (about 25 instructions a half-cell: conversions, shifts, broadcasts).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub(crate) struct MapAvx2<'a> {
    /// The map.
    map: &'a TextureMap,
    /// The TAC's ROMs.
    rom: &'static TacRom,
    /// The side `2^n` (as `f32`), `n` (as `f32`), and `2^(n+1)`: [`Self::level_avx2`]'s
    /// scale and clamps ([`lod_of_texels`]).
    side: __m256,
    top: __m256,
    beyond: __m256,
    /// `n`.
    n: __m256i,
    /// Where each level `k` starts in the pair layout ([`pair_start`]), levels
    /// `0..8` in the first register's lanes and `8..16` in the second's (levels
    /// above `n` as `n`): one permute of each and a select per look-up, where the
    /// start had been found from the side per lane (two dependent `vpmulld` on the
    /// gather's address, nine instructions).
    starts: [__m256i; 2],
    /// The last 4-byte read's start in the pair layout.
    last: __m256i,
    /// The last level's `T1..T4` as `f32`: its one texel four times, the 4 bytes
    /// at its start in the pair layout, which every look-up in that level reads
    /// ([`Self::top_avx2`]).
    top_quad: [f32; 4],
}

#[cfg(target_arch = "x86_64")]
impl TextureMap {
    /// This map's constants for the AVX2 look-ups ([`MapAvx2`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn avx2(&self) -> MapAvx2<'_> {
        // Every level's start in the two registers of [`MapAvx2::starts`].
        const { assert!(MAX_LOG2_SIDE < 2 * 8) };
        let n = self.log2_side;
        MapAvx2 {
            map: self,
            rom: TacRom::get(),
            side: _mm256_set1_ps(self.side() as f32),
            top: _mm256_set1_ps(n as f32),
            beyond: _mm256_set1_ps((2u32 << n) as f32),
            n: _mm256_set1_epi32(n as i32),
            starts: [0, 8].map(|first| {
                let start = |l: i32| pair_start(n, 1 << (n - (first + l as u32).min(n))) as i32;
                _mm256_setr_epi32(start(0), start(1), start(2), start(3), start(4), start(5), start(6), start(7))
            }),
            last: _mm256_set1_epi32((self.pairs.len() - 4) as i32),
            top_quad: std::array::from_fn(|i| f32::from(self.pairs[self.pairs.len() - 4 + i])),
        }
    }
}

#[cfg(target_arch = "x86_64")]
/// The lanes where the trilinear blend takes the coarser level: `kr != 0` (either
/// zero's sign is none; `kr` is never NaN).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn blends_avx2(kr: __m256) -> __m256 {
    _mm256_cmp_ps::<_CMP_NEQ_UQ>(kr, _mm256_setzero_ps())
}

/// The trilinear blend of the two levels' bilinear values: `fine + kr (coarse - fine)`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn trilinear_avx2(fine: __m256, coarse: __m256, kr: __m256) -> __m256 {
    _mm256_add_ps(fine, _mm256_mul_ps(kr, _mm256_sub_ps(coarse, fine)))
}

impl MapAvx2<'_> {
    /// [`TextureMap::sample_lanes`] of eight pixels in AVX2 registers, bit for bit:
    /// the same operations in the same order, the TAC's `log2` ROM by
    /// [`TacRom::log2_avx2`] and the four texels `T1..T4` by one gather of
    /// 4-byte reads of the pair layout per level. The finer level's look-up is
    /// started at the level the footprint's exponent gives ([`Level::guess`]),
    /// checked against the ROM's level after.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn sample_avx2(&self, u: __m256, v: __m256, footprint: __m256) -> __m256 {
        let texels = _mm256_mul_ps(footprint, self.side);
        if _mm256_movemask_ps(self.beyond_avx2(texels)) == 0xFF {
            return self.top_avx2(u, v);
        }
        let level = self.level_avx2(u, v, texels);
        let fine = self.bilinear_avx2(level.guess, level.fu, level.fv);
        let (k, fine) = if _mm256_movemask_epi8(_mm256_cmpeq_epi32(level.guess, level.k)) == -1 {
            (level.guess, fine)
        } else {
            (level.k, self.bilinear_avx2(level.k, level.fu, level.fv))
        };
        let kr = level.kr;
        if _mm256_movemask_ps(blends_avx2(kr)) == 0 {
            return fine;
        }
        let k = self.coarser_avx2(k);
        let coarse = self.bilinear_avx2(k, level.fu, level.fv);
        trilinear_avx2(fine, coarse, kr)
    }

    /// [`Self::sample_avx2`] of two groups of eight pixels side by side (a whole
    /// cell), bit for bit: each step done for both before the next, so that the
    /// two chains of dependent operations overlap, one test of both groups'
    /// guessed levels and one of both groups' `kr` for the coarser level.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn sample2_avx2(&self, u: [__m256; 2], v: [__m256; 2], footprint: [__m256; 2]) -> [__m256; 2] {
        let texels = [_mm256_mul_ps(footprint[0], self.side), _mm256_mul_ps(footprint[1], self.side)];
        if _mm256_movemask_ps(_mm256_and_ps(self.beyond_avx2(texels[0]), self.beyond_avx2(texels[1]))) == 0xFF {
            return [self.top_avx2(u[0], v[0]), self.top_avx2(u[1], v[1])];
        }
        let level = [self.level_avx2(u[0], v[0], texels[0]), self.level_avx2(u[1], v[1], texels[1])];
        // Every lane of both groups guessed in one level (that of lane 0, at most
        // `n`), and guessed right: the common case (96 % of default's whole
        // textured cells), its constants from the map's table. The tests are made
        // before the look-ups, so that the exact levels `k` are not kept across
        // them (the branch is predicted: the look-ups need not wait for the ROM).
        let first = _mm256_broadcastd_epi32(_mm256_castsi256_si128(level[0].guess));
        let one_level = _mm256_movemask_epi8(_mm256_and_si256(
            _mm256_cmpeq_epi32(level[0].guess, first),
            _mm256_cmpeq_epi32(level[1].guess, first),
        )) == -1;
        let guessed = _mm256_movemask_epi8(_mm256_and_si256(
            _mm256_cmpeq_epi32(level[0].guess, level[0].k),
            _mm256_cmpeq_epi32(level[1].guess, level[1].k),
        )) == -1;
        if !(one_level && guessed) {
            return self.sample2_levels_avx2(u[0], u[1], v[0], v[1], texels[0], texels[1]);
        }
        let guess = _mm256_cvtsi256_si32(level[0].guess) as usize;
        let (kr0, kr1) = (level[0].kr, level[1].kr);
        let blends = _mm256_movemask_ps(_mm256_or_ps(blends_avx2(kr0), blends_avx2(kr1))) != 0;
        // (Both look-ups written out, not an array's `map` of a closure: the closure
        // compiled out of line whenever the code units were laid out differently,
        // +9.7 M instructions on default.)
        let lanes = self.level_lanes(guess);
        let fine = [
            self.bilinear_in_avx2(lanes, level[0].fu, level[0].fv),
            self.bilinear_in_avx2(lanes, level[1].fu, level[1].fv),
        ];
        if !blends {
            return fine;
        }
        // The next level (or `n` again, [`Self::coarser_avx2`]) in every lane.
        let lanes = self.level_lanes(guess + usize::from(guess < self.map.log2_side as usize));
        let coarse = [
            self.bilinear_in_avx2(lanes, level[0].fu, level[0].fv),
            self.bilinear_in_avx2(lanes, level[1].fu, level[1].fv),
        ];
        [trilinear_avx2(fine[0], coarse[0], kr0), trilinear_avx2(fine[1], coarse[1], kr1)]
    }

    /// [`Self::sample2_avx2`] of groups (`u0`, `v0`, `texels0`) and (`u1`, `v1`,
    /// `texels1`) whose levels are not all one level or not all guessed right:
    /// their levels found again, then each lane's look-ups in its level `k` and
    /// the next. Out of line (4 % of default's whole textured cells), so that its
    /// registers are not the common case's; the levels found again from the
    /// inputs, not passed (an array of them passed by reference was written to
    /// the stack in every cell, ~14 stores).
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    #[cold]
    fn sample2_levels_avx2(
        &self,
        u0: __m256,
        u1: __m256,
        v0: __m256,
        v1: __m256,
        texels0: __m256,
        texels1: __m256,
    ) -> [__m256; 2] {
        let level = [self.level_avx2(u0, v0, texels0), self.level_avx2(u1, v1, texels1)];
        let fine = [
            self.bilinear_avx2(level[0].k, level[0].fu, level[0].fv),
            self.bilinear_avx2(level[1].k, level[1].fu, level[1].fv),
        ];
        let (kr0, kr1) = (level[0].kr, level[1].kr);
        if _mm256_movemask_ps(_mm256_or_ps(blends_avx2(kr0), blends_avx2(kr1))) == 0 {
            return fine;
        }
        let (k0, k1) = (self.coarser_avx2(level[0].k), self.coarser_avx2(level[1].k));
        let coarse =
            [self.bilinear_avx2(k0, level[0].fu, level[0].fv), self.bilinear_avx2(k1, level[1].fu, level[1].fv)];
        [trilinear_avx2(fine[0], coarse[0], kr0), trilinear_avx2(fine[1], coarse[1], kr1)]
    }

    /// The lanes whose footprint in level-0 texels `texels` is at least `2^(n+1)`
    /// ([`lod_of_texels`]'s `beyond`): their level of detail is `n`, the last
    /// level, with no blend (`kr` 0). Where all eight lanes are, sampling is
    /// [`Self::top_avx2`] (21 % of default's half cells: far ground).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn beyond_avx2(&self, texels: __m256) -> __m256 {
        _mm256_cmp_ps::<_CMP_GE_OQ>(texels, self.beyond)
    }

    /// [`TextureMap::sample_lanes`] of eight pixels all at the last level `n`
    /// ([`Self::beyond_avx2`]), bit for bit: their `lod` is `n` (its clamp), so `k`
    /// is `n` and `kr` 0, and the value is [`Self::bilinear_avx2`]'s in level `n`.
    /// There the side is 1, so `fu side` is `fu` (times 1, exact), and every read
    /// is the level's one texel ([`MapAvx2::top_quad`]): the same weights `Ku`,
    /// `Kv` and [`eq3_avx2`] on the same `T1..T4`, with no level found, no `log2`
    /// ROM, no address and no gather (the gather's wait was the longest step of
    /// such a half cell).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn top_avx2(&self, u: __m256, v: __m256) -> __m256 {
        let half = _mm256_set1_ps(0.5);
        let s = _mm256_sub_ps(fract01_avx2(u), half);
        let t = _mm256_sub_ps(fract01_avx2(v), half);
        let (ku, kv) = (_mm256_sub_ps(s, _mm256_floor_ps(s)), _mm256_sub_ps(t, _mm256_floor_ps(t)));
        let quad = self.top_quad.map(|t| _mm256_set1_ps(t));
        eq3_avx2(ku, kv, quad)
    }

    /// The level `k`, the blend `kr` to the next and the fractional parts of `u`,
    /// `v` of eight pixels ([`TextureMap::sample_lanes`] up to its first look-up,
    /// `texels` its footprint times the side), and the guess of `k` from the
    /// footprint's exponent ([`Level::guess`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn level_avx2(&self, u: __m256, v: __m256, texels: __m256) -> Level {
        // Level of detail ([`TextureMap::lod`], [`lod_of_texels`]).
        let top = self.top;
        // `log.min(top)` (never NaN: the ROM's `log2` is finite) where below
        // `beyond`, else `top`; all that where above one texel, else 0 (NaN too:
        // ordered compares are false for it).
        //
        // Where `texels` is above one texel it is not NaN, so there "below
        // `beyond`" is "not [`Self::beyond_avx2`]": the callers' test of that
        // compare is reused (one compare fewer a half cell), the select swapped.
        let beyond = self.beyond_avx2(texels);
        let over_one = _mm256_cmp_ps::<_CMP_GT_OQ>(texels, _mm256_set1_ps(1.0));
        let lod = if _mm256_movemask_ps(_mm256_andnot_ps(beyond, over_one)) == 0 {
            // No lane between the clamps (a magnified map: 65 % of default's
            // cells with one half visible): each lane's level is `top` or 0 as
            // below, and the `log2` ROM is not read (colour + VB: default 109.9
            // → 109.2 M, city 69.7 → 69.1 M).
            _mm256_and_ps(top, over_one)
        } else {
            let log = self.rom.log2_avx2(texels);
            _mm256_and_ps(_mm256_blendv_ps(_mm256_min_ps(log, top), top, beyond), over_one)
        };
        let floor = _mm256_floor_ps(lod);
        let kr = _mm256_sub_ps(lod, floor);
        let k = small_int_avx2(floor);
        // The exponent of `texels` (biased: 0 to 255 for any bits but the sign's),
        // clamped to `0..=n`.
        let biased = _mm256_and_si256(_mm256_srli_epi32::<23>(_mm256_castps_si256(texels)), _mm256_set1_epi32(0xFF));
        let exponent = _mm256_sub_epi32(biased, _mm256_set1_epi32(127));
        let guess = _mm256_min_epi32(_mm256_max_epi32(exponent, _mm256_setzero_si256()), self.n);
        Level { guess, k, kr, fu: fract01_avx2(u), fv: fract01_avx2(v) }
    }

    /// Level `k + 1`, or `k` again at the last level (where `kr` is 0 and the
    /// coarse value drops out of the blend).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn coarser_avx2(&self, k: __m256i) -> __m256i {
        _mm256_min_epi32(_mm256_add_epi32(k, _mm256_set1_epi32(1)), self.n)
    }

    /// [`LevelLookup`] and its read in level `k` per lane (at most `n`) at the
    /// fractional parts `fu`, `fv`: P2 eq. (3) from one gather of the pair layout.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn bilinear_avx2(&self, k: __m256i, fu: __m256, fv: __m256) -> __m256 {
        self.bilinear_in_avx2(self.lanes_of_avx2(k), fu, fv)
    }

    /// The constants of a look-up in level `k` per lane (at most `n`).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn lanes_of_avx2(&self, k: __m256i) -> LevelLanes {
        let level_log2 = _mm256_sub_epi32(self.n, k);
        // The side `2^(n-k)` as `f32` from its bits, and as an integer.
        let side_f = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(level_log2, _mm256_set1_epi32(127))));
        let side = _mm256_sllv_epi32(_mm256_set1_epi32(1), level_log2);
        let one = _mm256_set1_epi32(1);
        // [`pair_start`] of level `k` from the map's table (`k` is at most `n`).
        let start = _mm256_blendv_epi8(
            _mm256_permutevar8x32_epi32(self.starts[0], k),
            _mm256_permutevar8x32_epi32(self.starts[1], k),
            _mm256_cmpgt_epi32(k, _mm256_set1_epi32(7)),
        );
        LevelLanes { side_f, mask: _mm256_sub_epi32(side, one), row: _mm256_add_epi32(side, one), start }
    }

    /// The constants of a look-up in level `k` (at most `n`) in every lane, from
    /// the map's table ([`TextureMap::level_constants`]): broadcasts from memory,
    /// where [`Self::lanes_of_avx2`] finds them lane by lane (two permutes, a
    /// select, a variable shift: ~10 instructions a look-up). A cell's lanes are
    /// in one level in 96 % of default's whole textured cells.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn level_lanes(&self, k: usize) -> LevelLanes {
        let [side_f, mask, row, start] = self.map.level_constants[k & (LEVEL_CONSTANTS - 1)];
        LevelLanes {
            side_f: _mm256_set1_ps(f32::from_bits(side_f)),
            mask: _mm256_set1_epi32(mask as i32),
            row: _mm256_set1_epi32(row as i32),
            start: _mm256_set1_epi32(start as i32),
        }
    }

    /// [`Self::bilinear_avx2`] with its level's constants `level`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn bilinear_in_avx2(&self, level: LevelLanes, fu: __m256, fv: __m256) -> __m256 {
        let LevelLanes { side_f, mask, row, start } = level;
        let half = _mm256_set1_ps(0.5);
        // [`split`] of `fu side - 1/2` and `fv side - 1/2`.
        let s = _mm256_sub_ps(_mm256_mul_ps(fu, side_f), half);
        let fs = _mm256_floor_ps(s);
        let (i0, ku) = (small_int_avx2(fs), _mm256_sub_ps(s, fs));
        let t = _mm256_sub_ps(_mm256_mul_ps(fv, side_f), half);
        let ft = _mm256_floor_ps(t);
        let (j0, kv) = (small_int_avx2(ft), _mm256_sub_ps(t, ft));
        let (c0, r0) = (_mm256_and_si256(i0, mask), _mm256_and_si256(j0, mask));
        // Pair `(r0, c0)`: `start + 2 (r0 (s + 1) + c0)`.
        let pair = _mm256_add_epi32(_mm256_mullo_epi32(r0, row), c0);
        let index = _mm256_add_epi32(start, _mm256_slli_epi32::<1>(pair));
        // Inside the layout already (the masks, and the starts of levels at most
        // `n`); the `min` makes every read safe whatever the lanes hold.
        let index = _mm256_min_epu32(index, self.last);
        // SAFETY: every lane of `index` is at most `pairs.len() - 4` (the `min`
        // above, `last`): the 4 bytes read at it are inside `pairs`.
        #[allow(unsafe_code, reason = "one gather of the texel pairs, the addresses clamped inside them")]
        let quad = unsafe { _mm256_i32gather_epi32::<1>(self.map.pairs.as_ptr().cast::<i32>(), index) };
        let byte = _mm256_set1_epi32(0xFF);
        let t1 = _mm256_cvtepi32_ps(_mm256_and_si256(quad, byte));
        let t2 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<8>(quad), byte));
        let t3 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<16>(quad), byte));
        let t4 = _mm256_cvtepi32_ps(_mm256_srli_epi32::<24>(quad));
        eq3_avx2(ku, kv, [t1, t2, t3, t4])
    }
}

/// [`eq3`] of eight lanes, `T1..T4` in `t`, then the texel scale: the value in
/// `0..=1`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn eq3_avx2(ku: __m256, kv: __m256, t: [__m256; 4]) -> __m256 {
    let [t1, t2, t3, t4] = t;
    let one = _mm256_set1_ps(1.0);
    let (nku, nkv) = (_mm256_sub_ps(one, ku), _mm256_sub_ps(one, kv));
    let left = _mm256_add_ps(_mm256_mul_ps(nkv, t1), _mm256_mul_ps(kv, t2));
    let right = _mm256_add_ps(_mm256_mul_ps(nkv, t3), _mm256_mul_ps(kv, t4));
    let value = _mm256_add_ps(_mm256_mul_ps(nku, left), _mm256_mul_ps(ku, right));
    _mm256_div_ps(value, _mm256_set1_ps(TEXEL_ONE))
}

#[cfg(target_arch = "x86_64")]
impl TextureMap {
    /// [`Self::sample_lanes`] of sixteen pixels in AVX-512 registers, bit for bit:
    /// [`MapAvx2::sample_avx2`] over twice the lanes, the selects as masks.
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(crate) fn sample_avx512(&self, u: __m512, v: __m512, footprint: __m512) -> __m512 {
        let n = self.log2_side;
        let (side, top, beyond) = (self.side() as f32, n as f32, (2u32 << n) as f32);
        let texels = _mm512_mul_ps(footprint, _mm512_set1_ps(side));
        let log = TacRom::get().log2_avx512(texels);
        let top = _mm512_set1_ps(top);
        let below = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(texels, _mm512_set1_ps(beyond));
        let above = _mm512_mask_blend_ps(below, top, _mm512_min_ps(log, top));
        // Zero (`+0`) where not above one texel, NaN included.
        let lod = _mm512_maskz_mov_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(texels, _mm512_set1_ps(1.0)), above);
        let floor = floor_avx512(lod);
        let kr = _mm512_sub_ps(lod, floor);
        let k = small_int_avx512(floor);
        let (fu, fv) = (fract01_avx512(u), fract01_avx512(v));
        let fine = self.bilinear_avx512(k, fu, fv);
        if _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(kr, _mm512_setzero_ps()) == 0 {
            return fine;
        }
        let k = _mm512_min_epi32(_mm512_add_epi32(k, _mm512_set1_epi32(1)), _mm512_set1_epi32(n as i32));
        let coarse = self.bilinear_avx512(k, fu, fv);
        _mm512_add_ps(fine, _mm512_mul_ps(kr, _mm512_sub_ps(coarse, fine)))
    }

    /// [`MapAvx2::bilinear_avx2`] over sixteen lanes.
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn bilinear_avx512(&self, k: __m512i, fu: __m512, fv: __m512) -> __m512 {
        let n = _mm512_set1_epi32(self.log2_side as i32);
        let level_log2 = _mm512_sub_epi32(n, k);
        let side_f = _mm512_castsi512_ps(_mm512_slli_epi32::<23>(_mm512_add_epi32(level_log2, _mm512_set1_epi32(127))));
        let side = _mm512_sllv_epi32(_mm512_set1_epi32(1), level_log2);
        let half = _mm512_set1_ps(0.5);
        let s = _mm512_sub_ps(_mm512_mul_ps(fu, side_f), half);
        let fs = floor_avx512(s);
        let (i0, ku) = (small_int_avx512(fs), _mm512_sub_ps(s, fs));
        let t = _mm512_sub_ps(_mm512_mul_ps(fv, side_f), half);
        let ft = floor_avx512(t);
        let (j0, kv) = (small_int_avx512(ft), _mm512_sub_ps(t, ft));
        let mask = _mm512_sub_epi32(side, _mm512_set1_epi32(1));
        let (c0, r0) = (_mm512_and_si512(i0, mask), _mm512_and_si512(j0, mask));
        let n4 = _mm512_set1_epi32((4u32 << (2 * self.log2_side)) as i32);
        let n2 = _mm512_set1_epi32((2u32 << self.log2_side) as i32);
        let squares = _mm512_sub_epi32(n4, _mm512_slli_epi32::<2>(_mm512_mullo_epi32(side, side)));
        let start = _mm512_add_epi32(
            _mm512_slli_epi32::<1>(_mm512_mullo_epi32(squares, _mm512_set1_epi32(0xAAAA_AAABu32 as i32))),
            _mm512_slli_epi32::<1>(_mm512_sub_epi32(n2, _mm512_slli_epi32::<1>(side))),
        );
        let pair = _mm512_add_epi32(_mm512_mullo_epi32(r0, _mm512_add_epi32(side, _mm512_set1_epi32(1))), c0);
        let index = _mm512_add_epi32(start, _mm512_slli_epi32::<1>(pair));
        let last = (self.pairs.len() - 4) as i32;
        let index = _mm512_min_epu32(index, _mm512_set1_epi32(last));
        // SAFETY: every lane of `index` is at most `pairs.len() - 4` (the `min`
        // above): the 4 bytes read at it are inside `pairs`.
        #[allow(unsafe_code, reason = "one gather of the texel pairs, the addresses clamped inside them")]
        let quad = unsafe { _mm512_i32gather_epi32::<1>(index, self.pairs.as_ptr().cast::<i32>()) };
        let byte = _mm512_set1_epi32(0xFF);
        let t1 = _mm512_cvtepi32_ps(_mm512_and_si512(quad, byte));
        let t2 = _mm512_cvtepi32_ps(_mm512_and_si512(_mm512_srli_epi32::<8>(quad), byte));
        let t3 = _mm512_cvtepi32_ps(_mm512_and_si512(_mm512_srli_epi32::<16>(quad), byte));
        let t4 = _mm512_cvtepi32_ps(_mm512_srli_epi32::<24>(quad));
        let one = _mm512_set1_ps(1.0);
        let (nku, nkv) = (_mm512_sub_ps(one, ku), _mm512_sub_ps(one, kv));
        let left = _mm512_add_ps(_mm512_mul_ps(nkv, t1), _mm512_mul_ps(kv, t2));
        let right = _mm512_add_ps(_mm512_mul_ps(nkv, t3), _mm512_mul_ps(kv, t4));
        let value = _mm512_add_ps(_mm512_mul_ps(nku, left), _mm512_mul_ps(ku, right));
        _mm512_div_ps(value, _mm512_set1_ps(TEXEL_ONE))
    }
}

/// The constants of a look-up in one level per lane ([`MapAvx2::bilinear_in_avx2`]):
/// the side `s` as `f32`, `s - 1` (the address mask), `s + 1` (pairs a row) and
/// the level's start in the pair layout.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct LevelLanes {
    side_f: __m256,
    mask: __m256i,
    row: __m256i,
    start: __m256i,
}

/// [`MapAvx2::level_avx2`]'s values of eight pixels.
#[cfg(target_arch = "x86_64")]
struct Level {
    /// The level `floor(lod)` ([`TextureMap::trilinear`]'s `k`).
    k: __m256i,
    /// `k` as the exponent of the footprint in level-0 texels gives it, clamped to
    /// `0..=n`: `k` itself but where the `log2` ROM's fraction of the mantissa,
    /// added to the exponent, rounds up to the next integer (the ROM's last
    /// entry, a 256th of each octave), and in lanes with no real footprint (NaN,
    /// negative). Ready some 20 cycles before `k` (no ROM read, no `floor`), so
    /// that the finer level's look-up, the longest chain of the colour computers,
    /// starts that much sooner; `k` checks it after (no look-up again in
    /// default's or city's frames).
    guess: __m256i,
    /// The blend `kr` to level `k + 1`.
    kr: __m256,
    /// The fractional parts of `u` and `v`.
    fu: __m256,
    fv: __m256,
}

/// [`fract01`] of sixteen values in an AVX-512 register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn fract01_avx512(x: __m512) -> __m512 {
    let d = _mm512_sub_ps(x, floor_avx512(x));
    _mm512_min_ps(_mm512_max_ps(d, _mm512_setzero_ps()), _mm512_set1_ps(1.0))
}

/// [`fract01`] of eight values in an AVX2 register, bit for bit (`maxps` returns
/// its second operand, 0, for a NaN, as `f32::max` does). With no `min` with 1:
/// for a finite `x`, `x - floor(x)` is exactly in `[0, 1)` and 1 is a float, so
/// its rounding is at most 1 (1 only for a tiny negative `x`) and `min(.., 1)`
/// is the identity; an infinite `x` gives `inf - inf`, NaN, which the `max` makes
/// 0 (one instruction fewer a coordinate, four in a whole textured cell).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn fract01_avx2(x: __m256) -> __m256 {
    let d = _mm256_sub_ps(x, _mm256_floor_ps(x));
    _mm256_max_ps(d, _mm256_setzero_ps())
}

/// Pixels the colour computers and the texture unit work on side by side in the
/// build target's code: one 128-bit register of `f32` (x86-64-v2's SSE).
pub const LANES: usize = 4;

/// Where level `k` of side `s = 2^(n-k)` starts in [`TextureMap`]'s pair layout:
/// after levels `0..k`, `2 s_i (s_i + 1)` bytes each, `2 (4^(n+1) - 4 s^2) / 3 +
/// 2 (2^(n+1) - 2 s)` in all. Exact in `u32` for `n` up to [`MAX_LOG2_SIDE`].
#[inline(always)]
fn pair_start(n: u32, s: u32) -> u32 {
    2 * ((4u32 << (2 * n)) - 4 * s * s) / 3 + 2 * ((2u32 << n) - 2 * s)
}

/// The bilinear look-ups of [`TextureMap::sample_lanes`] in one level per lane: the
/// weights `Ku`, `Kv` and the addresses in the map's texels of `T1..T4` (P2 eq. 3).
struct LevelLookup<const N: usize> {
    /// `Ku` per lane.
    ku: [f32; N],
    /// `Kv` per lane.
    kv: [f32; N],
    /// Where `T1, T2, T3, T4` are, per lane ([`TextureMap::quad`]).
    index: [[u32; N]; 4],
}

impl<const N: usize> LevelLookup<N> {
    /// The look-ups in level `k[l]` (at most `n`) at the fractional parts
    /// `fu[l]`, `fv[l]`, as [`TextureMap::bilinear`] makes them.
    #[inline(always)]
    fn new(n: u32, k: &[i32; N], fu: &[f32; N], fv: &[f32; N]) -> Self {
        let mut lookup = Self { ku: [0.0; N], kv: [0.0; N], index: [[0; N]; 4] };
        let [t1, t2, t3, t4] = &mut lookup.index;
        for l in 0..N {
            // The side `2^(n-k)`, exactly `(1 << (n - k)) as f32`, from its bits.
            let side = f32::from_bits((127 + (n as i32 - k[l]) as u32) << 23);
            let (i0, ku) = split(fu[l] * side - 0.5);
            let (j0, kv) = split(fv[l] * side - 0.5);
            lookup.ku[l] = ku;
            lookup.kv[l] = kv;
            let side = small_int(side) as u32;
            let mask = side - 1;
            // Level k starts after levels 0..k, `4^n + ... + 4^(n-k+1)` texels:
            // `(4^(n+1) - 4 side^2) / 3`, an exact division done as the product by
            // the inverse of 3 modulo 2^32.
            let start = ((4u32 << (2 * n)) - 4 * side * side).wrapping_mul(0xAAAA_AAAB);
            let (c0, c1) = (i0 as u32 & mask, (i0 as u32).wrapping_add(1) & mask);
            let (r0, r1) = ((j0 as u32 & mask) * side + start, ((j0 as u32).wrapping_add(1) & mask) * side + start);
            (t1[l], t2[l], t3[l], t4[l]) = (r0 + c0, r1 + c0, r0 + c1, r1 + c1);
        }
        lookup
    }

    /// P2 eq. (3) per lane: the texels `T1..T4` read, then interpolated.
    ///
    /// Every address is inside the map: level `k`'s texels start at `start` and
    /// hold `side^2`, and a row and a column are masked to `side - 1`. The `min`
    /// with the last texel is therefore the identity; it is there to show the
    /// compiler so (one vector operation per quad, where a bounds check costs a
    /// compare and a branch per read).
    #[inline(always)]
    fn read(&self, texels: &[u8]) -> [f32; N] {
        let last = (texels.len() - 1) as u32;
        let texels = &texels[..=last as usize];
        let mut t = [[0.0f32; N]; 4];
        for (t, index) in t.iter_mut().zip(&self.index) {
            let index: [u32; N] = index.map(|i| i.min(last));
            for (t, i) in t.iter_mut().zip(index) {
                *t = f32::from(texels[i as usize]);
            }
        }
        std::array::from_fn(|l| eq3(self.ku[l], self.kv[l], t[0][l], t[1][l], t[2][l], t[3][l]))
    }
}

/// [`TextureMap::lod`] of a footprint of `texels` level-0 texels, `top` = `n`,
/// `beyond` = `2^(n+1)`: the TAC's `log2` ([`TacRom::log2`]) clamped to `0..=n`,
/// read only where the clamp does not settle it: at most one texel (or NaN) is level
/// 0; from `2^(n+1)` texels on (an infinite footprint too) it is `n`, since the
/// ROM's `log2` of such a number is its exponent, at least `n + 1`, plus a fraction
/// that is never negative.
#[inline(always)]
fn lod_of_texels(rom: &TacRom, texels: f32, top: f32, beyond: f32) -> f32 {
    if texels > 1.0 && texels < beyond {
        rom.log2(texels).min(top)
    } else if texels > 1.0 {
        top
    } else {
        0.0
    }
}

/// P2 eq. (3), `T' = (1 - Ku)((1 - Kv) T1 + Kv T2) + Ku((1 - Kv) T3 + Kv T4)`, in
/// texel units, scaled to `0..=1`.
#[inline]
fn eq3(ku: f32, kv: f32, t1: f32, t2: f32, t3: f32, t4: f32) -> f32 {
    ((1.0 - ku) * ((1.0 - kv) * t1 + kv * t2) + ku * ((1.0 - kv) * t3 + kv * t4)) / TEXEL_ONE
}

/// The fractional part of `x` in `0..=1` (1 only by rounding of tiny negatives); NaN
/// and infinities give 0.
#[inline]
#[expect(clippy::manual_clamp, reason = "max then min maps NaN to 0, where clamp would keep it")]
fn fract01(x: f32) -> f32 {
    (x - x.floor()).max(0.0).min(1.0)
}

/// Integer part (floor) and fraction of a texel-space coordinate, `s` in
/// `-0.5..=2^12` (a fractional part times a side, minus a half).
#[inline]
fn split(s: f32) -> (i32, f32) {
    let f = s.floor();
    (small_int(f), s - f)
}

/// The texture maps of a scene, indexed like [`Scene::textures`] (a material's
/// `texture.map`).
#[derive(Clone, Default, PartialEq, Eq)]
pub struct TextureMaps {
    maps: Vec<TextureMap>,
}

impl fmt::Debug for TextureMaps {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(&self.maps).finish()
    }
}

impl TextureMaps {
    /// Maps given in scene order.
    pub fn new(maps: Vec<TextureMap>) -> Self {
        Self { maps }
    }

    /// Builds or loads every map the scene declares: built-in maps are generated,
    /// files are read with [`load_png`]. A relative file path is joined to `base_dir`;
    /// the paths of a scene from `db::load::load_scene` are already joined with the
    /// scene file's folder, so for those pass `Path::new("")`.
    pub fn from_scene(scene: &Scene, base_dir: &Path) -> Result<Self, TextureError> {
        let maps = scene
            .textures
            .iter()
            .map(|def| match &def.source {
                TextureSource::Builtin(name) => builtin(name)
                    .ok_or_else(|| TextureError::UnknownBuiltin { texture: def.name.clone(), builtin: name.clone() }),
                TextureSource::File(path) => load_png(&base_dir.join(path)),
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { maps })
    }

    /// Map `index`, if there is one.
    #[inline]
    pub fn get(&self, index: u32) -> Option<&TextureMap> {
        self.maps.get(index as usize)
    }

    /// Number of maps.
    pub fn len(&self) -> usize {
        self.maps.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.maps.is_empty()
    }
}

/// Why a texture map could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TextureError {
    /// The file does not exist.
    #[error("texture file {}: no such file", path.display())]
    Missing {
        /// The file.
        path: PathBuf,
    },
    /// The file exists but could not be read.
    #[error("texture file {}: cannot read it: {reason}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        #[source]
        reason: std::io::Error,
    },
    /// The bytes are not a PNG image the decoder can read.
    #[error("texture file {}: not a readable PNG image ({reason})", path.display())]
    NotPng {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        reason: String,
    },
    /// The image is larger than the largest map.
    #[error("texture file {}: {width} x {height} pixels is larger than the largest map, {max} x {max}", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// [`MAX_SIDE`].
        max: u32,
    },
    /// A built-in map name that does not exist.
    #[error("texture '{texture}': unknown builtin map '{builtin}' (builtins are {})", BUILTIN_NAMES.join(", "))]
    UnknownBuiltin {
        /// The texture's name in the scene.
        texture: String,
        /// The name it gave.
        builtin: String,
    },
}

/// Reads a PNG file into a map (see [`decode_png`] for the conversions).
pub fn load_png(path: &Path) -> Result<TextureMap, TextureError> {
    let bytes = std::fs::read(path).map_err(|reason| match reason.kind() {
        std::io::ErrorKind::NotFound => TextureError::Missing { path: path.to_path_buf() },
        _ => TextureError::Io { path: path.to_path_buf(), reason },
    })?;
    decode_png(&bytes, path)
}

/// Decodes PNG bytes into a map; `path` names them in errors.
///
/// - Colour images are converted to luminance, `0.2126 R + 0.7152 G + 0.0722 B` on
///   the stored 8-bit values (the `image` crate's conversion); alpha is dropped;
///   16-bit samples are reduced to 8 bits. The stored value is taken as `T` directly
///   (`T = value / 255`), with no transfer curve: the map holds modulation factors,
///   not light.
/// - An image that is not square with a power-of-two side is **resampled** (bilinear,
///   wrapping around, since maps repeat) to the next power of two of its larger side:
///   the whole image is one period of the texture whatever its size, so this only
///   changes the texel density. Images larger than [`MAX_SIDE`] are an error.
pub fn decode_png(bytes: &[u8], path: &Path) -> Result<TextureMap, TextureError> {
    let not_png = |e: image::ImageError| TextureError::NotPng { path: path.to_path_buf(), reason: e.to_string() };
    // The size first, from the header, so that a huge image is refused before decoding.
    let (width, height) = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Png)
        .into_dimensions()
        .map_err(not_png)?;
    if width == 0 || height == 0 {
        // The decoder refuses these already; the resampler must never see one.
        return Err(TextureError::NotPng { path: path.to_path_buf(), reason: "the image is empty".into() });
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(TextureError::TooLarge { path: path.to_path_buf(), width, height, max: MAX_SIDE });
    }
    let luma = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).map_err(not_png)?.into_luma8();
    let (w, h) = (luma.width(), luma.height());
    let side = w.max(h).next_power_of_two();
    let raw = luma.into_raw();
    let square = if w == side && h == side { raw } else { resample_periodic(&raw, w, h, side) };
    // PNG rows run top down; map rows run from v = 0 up.
    let s = side as usize;
    let texels: Vec<u8> = (0..s).rev().flat_map(|row| square[row * s..(row + 1) * s].iter().copied()).collect();
    Ok(TextureMap::from_texels(side, texels).expect("side is a power of two within MAX_SIDE"))
}

/// Bilinear resampling of a `w x h` row-major image to `side x side`, wrapping around
/// at the borders (the image is one period of a repeating pattern).
fn resample_periodic(src: &[u8], w: u32, h: u32, side: u32) -> Vec<u8> {
    // Source position of each target texel centre along one axis: the two source
    // texels around it (wrapped) and the weight of the second.
    let taps = |n: u32| -> Vec<(usize, usize, f64)> {
        (0..side)
            .map(|i| {
                let s = (f64::from(i) + 0.5) * f64::from(n) / f64::from(side) - 0.5;
                let f = s.floor();
                let i0 = (f as i64).rem_euclid(i64::from(n)) as usize;
                ((i0), (i0 + 1) % n as usize, s - f)
            })
            .collect()
    };
    let (tx, ty) = (taps(w), taps(h));
    let w = w as usize;
    let mut out = Vec::with_capacity((side as usize).pow(2));
    for &(y0, y1, fy) in &ty {
        for &(x0, x1, fx) in &tx {
            let at = |x: usize, y: usize| f64::from(src[y * w + x]);
            let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
            let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
            out.push((top * (1.0 - fy) + bottom * fy).round().clamp(0.0, 255.0) as u8);
        }
    }
    out
}

/// A built-in procedural map by name ([`BUILTIN_NAMES`]), 256 x 256, deterministic.
pub fn builtin(name: &str) -> Option<TextureMap> {
    let side = 1u32 << BUILTIN_LOG2_SIDE;
    let f: fn(u32, u32) -> f32 = match name {
        "grass" => grass,
        "asphalt" => asphalt,
        "concrete" => concrete,
        "checker" => checker,
        _ => return None,
    };
    let texels = (0..side * side).map(|k| to_texel(f(k % side, k / side))).collect();
    TextureMap::from_texels(side, texels)
}

/// `T` in `0..=1` to a texel, rounded.
fn to_texel(t: f32) -> u8 {
    (t.clamp(0.0, 1.0) * TEXEL_ONE).round() as u8
}

/// Side of the built-in maps.
const BUILTIN_SIDE: u32 = 1 << BUILTIN_LOG2_SIDE;

/// `checker`: [`CHECKER_SQUARES`] x [`CHECKER_SQUARES`] squares of `T = 1` and `T = 0`.
fn checker(i: u32, j: u32) -> f32 {
    let square = BUILTIN_SIDE / CHECKER_SQUARES;
    if (i / square + j / square).is_multiple_of(2) {
        1.0
    } else {
        0.0
    }
}

/// `grass`: clumps at several scales (periodic value noise, cells of 64 down to 4
/// texels) over blade-sized texel noise.
fn grass(i: u32, j: u32) -> f32 {
    const SEED: u32 = 0x6772_6173;
    // (cells per side, amplitude): coarse clumps strongest.
    const OCTAVES: [(u32, f32); 5] = [(4, 0.30), (8, 0.22), (16, 0.16), (32, 0.12), (64, 0.08)];
    const BLADES: f32 = 0.18;
    let clumps: f32 = OCTAVES.iter().map(|&(cells, a)| a * (value_noise(i, j, cells, SEED ^ cells) - 0.5) * 2.0).sum();
    0.5 + clumps + BLADES * (unit(hash(i, j, SEED)) - 0.5) * 2.0
}

/// `asphalt`: fine grain (texel noise) over faint patches.
fn asphalt(i: u32, j: u32) -> f32 {
    const SEED: u32 = 0x6173_7068;
    const PATCH_CELLS: u32 = 8;
    const PATCHES: f32 = 0.08;
    const GRAIN: f32 = 0.22;
    const SPECK_EVERY: u32 = 61;
    let patches = PATCHES * (value_noise(i, j, PATCH_CELLS, SEED) - 0.5) * 2.0;
    let grain = GRAIN * (unit(hash(i, j, SEED ^ 1)) - 0.5) * 2.0;
    // A few light stones.
    let speck = if hash(i, j, SEED ^ 2).is_multiple_of(SPECK_EVERY) { 0.3 } else { 0.0 };
    0.5 + patches + grain + speck
}

/// `concrete`: 2 x 2 slabs per period, each with its own tone, fine grain, and dark
/// joints between them.
fn concrete(i: u32, j: u32) -> f32 {
    const SEED: u32 = 0x636f_6e63;
    const SLABS: u32 = 2;
    const JOINT_HALF_WIDTH: u32 = 2;
    const JOINT: f32 = 0.08;
    const SLAB: f32 = 0.62;
    const SLAB_TONE: f32 = 0.08;
    const GRAIN: f32 = 0.08;
    const STAINS: f32 = 0.06;
    const STAIN_CELLS: u32 = 16;
    let slab = BUILTIN_SIDE / SLABS;
    let (a, b) = (i % slab, j % slab);
    let near_joint = |x: u32| x < JOINT_HALF_WIDTH || x >= slab - JOINT_HALF_WIDTH;
    if near_joint(a) || near_joint(b) {
        return JOINT;
    }
    let tone = SLAB_TONE * (unit(hash(i / slab, j / slab, SEED)) - 0.5) * 2.0;
    let stains = STAINS * (value_noise(i, j, STAIN_CELLS, SEED ^ 1) - 0.5) * 2.0;
    SLAB + tone + stains + GRAIN * (unit(hash(i, j, SEED ^ 2)) - 0.5) * 2.0
}

/// Periodic value noise over the built-in map: a lattice of `cells x cells` random
/// values (wrapping, so the map tiles), smoothly interpolated; in `0..=1`.
fn value_noise(i: u32, j: u32, cells: u32, seed: u32) -> f32 {
    let cell = BUILTIN_SIDE / cells;
    let (ci, cj) = (i / cell, j / cell);
    let smooth = |t: f32| t * t * (3.0 - 2.0 * t);
    let fx = smooth(((i % cell) as f32 + 0.5) / cell as f32);
    let fy = smooth(((j % cell) as f32 + 0.5) / cell as f32);
    let at = |x: u32, y: u32| unit(hash(x % cells, y % cells, seed));
    let top = at(ci, cj) + (at(ci + 1, cj) - at(ci, cj)) * fx;
    let bottom = at(ci, cj + 1) + (at(ci + 1, cj + 1) - at(ci, cj + 1)) * fx;
    top + (bottom - top) * fy
}

/// An integer hash of a lattice point (a `lowbias32`-style mixer).
fn hash(x: u32, y: u32, seed: u32) -> u32 {
    const K1: u32 = 0x7feb_352d;
    const K2: u32 = 0x846c_a68b;
    const Y_MIX: u32 = 0x9e37_79b9;
    let mut h = x ^ y.wrapping_mul(Y_MIX) ^ seed.rotate_left(16);
    h ^= h >> 16;
    h = h.wrapping_mul(K1);
    h ^= h >> 15;
    h = h.wrapping_mul(K2);
    h ^= h >> 16;
    h
}

/// A hash as a number in `[0, 1)`.
fn unit(h: u32) -> f32 {
    // The top 24 bits: exactly representable in f32.
    (h >> 8) as f32 / (1u32 << 24) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(side: u32) -> TextureMap {
        let texels = (0..side * side).map(|k| ((k * 7 + k / side * 13) % 256) as u8).collect();
        TextureMap::from_texels(side, texels).unwrap()
    }

    #[test]
    fn pyramid_levels_are_box_filtered() {
        let m = ramp(16);
        assert_eq!(m.levels(), 5);
        for k in 0..m.levels() {
            assert_eq!(m.level(k).len(), (16usize >> k).pow(2));
        }
        assert!(m.level(5).is_empty());
        // Level 1 from level 0, exactly (one rounding).
        for j in 0..8 {
            for i in 0..8 {
                let s: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|&(a, b)| u32::from(m.texel(0, 2 * i + a, 2 * j + b)))
                    .sum();
                assert_eq!(u32::from(m.texel(1, i, j)), (s + 2) / 4);
            }
        }
        // The last level is the rounded mean.
        let sum: u32 = m.level(0).iter().map(|&t| u32::from(t)).sum();
        assert_eq!(u32::from(m.level(4)[0]), (sum + 128) / 256);
    }

    #[test]
    fn rejects_bad_sizes() {
        assert!(TextureMap::from_texels(3, vec![0; 9]).is_none());
        assert!(TextureMap::from_texels(4, vec![0; 15]).is_none());
        assert!(TextureMap::from_texels(0, vec![]).is_none());
        assert!(TextureMap::from_texels(1, vec![7]).is_some());
    }

    #[test]
    fn bilinear_hits_texel_centres_and_wraps() {
        let m = ramp(8);
        for j in 0..8 {
            for i in 0..8 {
                let (u, v) = ((i as f32 + 0.5) / 8.0, (j as f32 + 0.5) / 8.0);
                let t = f32::from(m.texel(0, i, j)) / 255.0;
                assert!((m.bilinear(0, u, v) - t).abs() < 1e-6);
                // Whole periods away: the same.
                assert!((m.bilinear(0, u + 3.0, v - 5.0) - t).abs() < 1e-5);
            }
        }
        // Between the last and the first texel the map wraps.
        let mid = m.bilinear(0, 0.0, 0.5 / 8.0);
        let expect = (f32::from(m.texel(0, 7, 0)) + f32::from(m.texel(0, 0, 0))) / 2.0 / 255.0;
        assert!((mid - expect).abs() < 1e-6);
    }

    #[test]
    fn sampling_survives_any_input() {
        let m = builtin("grass").unwrap();
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1e30, 1e30, -1e-12, 0.999_999_9] {
            for fp in [f32::NAN, f32::INFINITY, 0.0, -1.0, 1e-9, 1e9] {
                let t = m.sample(x, 0.25, fp);
                assert!((0.0..=1.0).contains(&t), "u = {x}, footprint = {fp}: {t}");
                let t = m.sample(0.25, x, fp);
                assert!((0.0..=1.0).contains(&t), "v = {x}, footprint = {fp}: {t}");
            }
        }
    }

    /// [`TextureMap::sample`] written out plainly, texel by texel, as a reference
    /// for the faster paths.
    fn plain_sample(m: &TextureMap, u: f32, v: f32, footprint: f32) -> f32 {
        let n = m.log2_side();
        let texels = footprint * m.side() as f32;
        let lod = if texels > 1.0 { TacRom::get().log2(texels).min(n as f32) } else { 0.0 };
        let bilinear = |k: u32| {
            let side = (1u32 << (n - k)) as f32;
            let s = fract01(u) * side - 0.5;
            let t = fract01(v) * side - 0.5;
            let (i0, ku) = (s.floor() as i32, s - s.floor());
            let (j0, kv) = (t.floor() as i32, t - t.floor());
            let [t1, t2, t3, t4] =
                [(i0, j0), (i0, j0 + 1), (i0 + 1, j0), (i0 + 1, j0 + 1)].map(|(i, j)| f32::from(m.texel(k, i, j)));
            ((1.0 - ku) * ((1.0 - kv) * t1 + kv * t2) + ku * ((1.0 - kv) * t3 + kv * t4)) / TEXEL_ONE
        };
        let k = lod as u32;
        let kr = lod - k as f32;
        let fine = bilinear(k);
        if kr == 0.0 || k >= n {
            return fine;
        }
        fine + kr * (bilinear(k + 1) - fine)
    }

    /// Eight lanes of [`MapAvx2::sample_avx2`], where the processor has AVX2.
    #[cfg(target_arch = "x86_64")]
    fn sample_avx2_lanes(map: &TextureMap, u: &[f32; 8], v: &[f32; 8], footprint: &[f32; 8]) -> Option<[f32; 8]> {
        #[target_feature(enable = "avx2")]
        #[allow(unsafe_code, reason = "loads and a store of arrays of a register's size")]
        fn run(map: &TextureMap, u: &[f32; 8], v: &[f32; 8], footprint: &[f32; 8]) -> [f32; 8] {
            let mut out = [0.0f32; 8];
            // SAFETY: each array is 8 `f32`, the 32 bytes each load or store touches.
            unsafe {
                let t = map.avx2().sample_avx2(
                    _mm256_loadu_ps(u.as_ptr()),
                    _mm256_loadu_ps(v.as_ptr()),
                    _mm256_loadu_ps(footprint.as_ptr()),
                );
                _mm256_storeu_ps(out.as_mut_ptr(), t);
            }
            out
        }
        // SAFETY: the processor has AVX2.
        #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
        std::is_x86_feature_detected!("avx2").then(|| unsafe { run(map, u, v, footprint) })
    }

    /// Two groups of eight lanes of [`MapAvx2::sample2_avx2`], where the
    /// processor has AVX2.
    #[cfg(target_arch = "x86_64")]
    fn sample2_avx2_lanes(map: &TextureMap, points: [[&[f32; 8]; 3]; 2]) -> Option<[[f32; 8]; 2]> {
        #[target_feature(enable = "avx2")]
        #[allow(unsafe_code, reason = "loads and stores of arrays of a register's size")]
        fn run(map: &TextureMap, points: [[&[f32; 8]; 3]; 2]) -> [[f32; 8]; 2] {
            let mut out = [[0.0f32; 8]; 2];
            // SAFETY: each array is 8 `f32`, the 32 bytes each load or store touches.
            unsafe {
                let load = |g: usize, i: usize| _mm256_loadu_ps(points[g][i].as_ptr());
                let t = map.avx2().sample2_avx2(
                    [load(0, 0), load(1, 0)],
                    [load(0, 1), load(1, 1)],
                    [load(0, 2), load(1, 2)],
                );
                for (out, t) in out.iter_mut().zip(t) {
                    _mm256_storeu_ps(out.as_mut_ptr(), t);
                }
            }
            out
        }
        // SAFETY: the processor has AVX2.
        #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
        std::is_x86_feature_detected!("avx2").then(|| unsafe { run(map, points) })
    }

    /// Sixteen lanes of [`TextureMap::sample_avx512`], where the processor has
    /// AVX-512F: the eight points twice, the second time in reverse order.
    #[cfg(target_arch = "x86_64")]
    fn sample_avx512_lanes(map: &TextureMap, u: &[f32; 8], v: &[f32; 8], footprint: &[f32; 8]) -> Option<[f32; 16]> {
        #[target_feature(enable = "avx512f")]
        #[allow(unsafe_code, reason = "loads and a store of arrays of a register's size")]
        fn run(map: &TextureMap, u: &[f32; 16], v: &[f32; 16], footprint: &[f32; 16]) -> [f32; 16] {
            let mut out = [0.0f32; 16];
            // SAFETY: each array is 16 `f32`, the 64 bytes each load or store touches.
            unsafe {
                let t = map.sample_avx512(
                    _mm512_loadu_ps(u.as_ptr()),
                    _mm512_loadu_ps(v.as_ptr()),
                    _mm512_loadu_ps(footprint.as_ptr()),
                );
                _mm512_storeu_ps(out.as_mut_ptr(), t);
            }
            out
        }
        let twice = |x: &[f32; 8]| -> [f32; 16] { std::array::from_fn(|l| if l < 8 { x[l] } else { x[15 - l] }) };
        // SAFETY: the processor has AVX-512F.
        #[allow(unsafe_code, reason = "a test of the AVX-512 copy, after detection")]
        std::is_x86_feature_detected!("avx512f").then(|| unsafe { run(map, &twice(u), &twice(v), &twice(footprint)) })
    }

    /// Every path of the texture unit against [`plain_sample`], bit for bit, at
    /// eight points: [`TextureMap::sample`], [`TextureMap::sample_lanes`] by 8 and
    /// by 4, and the AVX2 and AVX-512 copies where the processor has them.
    fn check_sampling(map: &TextureMap, u: &[f32; 8], v: &[f32; 8], footprint: &[f32; 8]) {
        let eight = map.sample_lanes(u, v, footprint);
        let half = |x: &[f32; 8], h: usize| -> [f32; LANES] { std::array::from_fn(|l| x[LANES * h + l]) };
        let four = [0, 1].map(|h| map.sample_lanes(&half(u, h), &half(v, h), &half(footprint, h)));
        #[cfg(target_arch = "x86_64")]
        let avx2 = sample_avx2_lanes(map, u, v, footprint);
        #[cfg(not(target_arch = "x86_64"))]
        let avx2: Option<[f32; 8]> = None;
        #[cfg(target_arch = "x86_64")]
        let avx512 = sample_avx512_lanes(map, u, v, footprint);
        #[cfg(not(target_arch = "x86_64"))]
        let avx512: Option<[f32; 16]> = None;
        for l in 0..8 {
            let expect = plain_sample(map, u[l], v[l], footprint[l]).to_bits();
            let at = format!("{map:?} u {} v {} fp {}", u[l], v[l], footprint[l]);
            assert_eq!(map.sample(u[l], v[l], footprint[l]).to_bits(), expect, "{at}: sample");
            assert_eq!(eight[l].to_bits(), expect, "{at}: 8 lanes");
            assert_eq!(four[l / LANES][l % LANES].to_bits(), expect, "{at}: 4 lanes");
            if let Some(avx2) = avx2 {
                assert_eq!(avx2[l].to_bits(), expect, "{at}: AVX2");
            }
            if let Some(avx512) = avx512 {
                assert_eq!(avx512[l].to_bits(), expect, "{at}: AVX-512");
                assert_eq!(avx512[15 - l].to_bits(), expect, "{at}: AVX-512, upper lanes");
            }
        }
        // The AVX2 copy's two groups side by side: with the eight points in
        // reverse order, at their footprints and at footprints a millionth of
        // them (mostly magnified: no coarser level in that group alone).
        #[cfg(target_arch = "x86_64")]
        {
            let reverse = |x: &[f32; 8]| -> [f32; 8] { std::array::from_fn(|l| x[7 - l]) };
            let (ru, rv, rf) = (reverse(u), reverse(v), reverse(footprint));
            let tiny = rf.map(|f| f * 1e-6);
            for second in [&rf, &tiny] {
                for (a, b) in [(0, 1), (1, 0)] {
                    let groups = [[u, v, footprint], [&ru, &rv, second]];
                    let Some(pair) = sample2_avx2_lanes(map, [groups[a], groups[b]]) else { return };
                    for (g, out) in [(a, pair[0]), (b, pair[1])] {
                        let [u, v, f] = groups[g];
                        for l in 0..8 {
                            let expect = plain_sample(map, u[l], v[l], f[l]).to_bits();
                            let at = format!("{map:?} u {} v {} fp {}", u[l], v[l], f[l]);
                            assert_eq!(out[l].to_bits(), expect, "{at}: AVX2, two groups");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn cell_sampling_is_sampling_bit_for_bit() {
        // Ordinary points, footprints across the pyramid (the clamped ends and the
        // levels between), and the inputs sampling must survive.
        let mut h = 0x1234_5678u32;
        let mut next = || {
            h = hash(h, 7, 11);
            unit(h)
        };
        let odd = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1e30, 1e30, -1e-12, 0.0, -0.0, 0.999_999_9];
        for map in [ramp(1), ramp(2), ramp(16), builtin("grass").unwrap(), TextureMap::build(12, vec![9; 1 << 24])] {
            let scale = map.side() as f32;
            for round in 0..1600 {
                let u: [f32; 8] = std::array::from_fn(|i| match round % 4 {
                    0 => odd[(i + round) % odd.len()],
                    _ => (next() - 0.5) * 40.0,
                });
                let v: [f32; 8] = std::array::from_fn(|i| match round % 5 {
                    0 => odd[(i + round / 5) % odd.len()],
                    _ => (next() - 0.5) * 40.0,
                });
                let footprint: [f32; 8] = std::array::from_fn(|i| match round % 3 {
                    0 if (i + round) % 5 == 0 => odd[(i + round) % odd.len()],
                    _ => (next() * 30.0 - 15.0).exp2() / scale,
                });
                check_sampling(&map, &u, &v, &footprint);
            }
            // Groups whose every footprint is at least `2^(n+1)` texels (the last
            // level in every lane: [`MapAvx2::top_avx2`]), from just there up, at
            // points anywhere and at the map's edges.
            let beyond = (2u32 << map.log2_side()) as f32 / scale;
            for round in 0..200 {
                let u: [f32; 8] = std::array::from_fn(|i| match round % 4 {
                    0 => odd[(i + round) % odd.len()],
                    _ => (next() - 0.5) * 40.0,
                });
                let v: [f32; 8] = std::array::from_fn(|_| (next() - 0.5) * 40.0);
                let footprint: [f32; 8] = std::array::from_fn(|i| match (round + i) % 4 {
                    0 => beyond,
                    1 => f32::INFINITY,
                    _ => beyond * (next() * 20.0).exp2(),
                });
                check_sampling(&map, &u, &v, &footprint);
            }
            // Groups whose every lane is in one level (footprints in one octave of
            // texels: [`MapAvx2::level_lanes`]), each level and the octave below
            // the pyramid's first, blended with the next level or not.
            for e in -1..=map.log2_side() as i32 {
                for round in 0..40 {
                    let u: [f32; 8] = std::array::from_fn(|_| (next() - 0.5) * 40.0);
                    let v: [f32; 8] = std::array::from_fn(|_| (next() - 0.5) * 40.0);
                    let footprint: [f32; 8] = std::array::from_fn(|i| match (round + i) % 5 {
                        0 if round % 2 == 0 => (e as f32).exp2() / scale,
                        _ => (e as f32 + next() * 0.999).exp2() / scale,
                    });
                    check_sampling(&map, &u, &v, &footprint);
                }
            }
            // Exact powers of two and their neighbours: the clamp's edges; and the
            // map's edges, where the look-ups wrap.
            for e in -3..=14 {
                let x = (e as f32).exp2() / scale;
                let fp: [f32; 8] = std::array::from_fn(|i| match i % 3 {
                    0 => x,
                    1 => f32::from_bits(x.to_bits() + 1),
                    _ => f32::from_bits(x.to_bits() - 1),
                });
                let edge = [0.0, 1e-7, 0.5 / scale, 1.0 - 0.5 / scale, 1.0 - 1e-7, 1.0, -1e-7, 0.3];
                check_sampling(&map, &[0.3; 8], &[0.7; 8], &fp);
                check_sampling(&map, &edge, &[0.7; 8], &fp);
                check_sampling(&map, &[0.3; 8], &edge, &fp);
            }
        }
    }

    /// The AVX2 copy's guess of the level ([`Level::guess`]) is the level but in
    /// the cases it documents, among them footprints just below a power of two
    /// texels, where the `log2` ROM rounds up (the look-up again, which
    /// [`cell_sampling_is_sampling_bit_for_bit`] checks bit for bit, is taken
    /// there).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn guessed_level_is_the_level_but_where_the_rom_rounds_up() {
        #[target_feature(enable = "avx2")]
        #[allow(unsafe_code, reason = "stores of registers into arrays of their size")]
        fn levels(map: &TextureMap, texels: &[f32; 8]) -> ([i32; 8], [i32; 8]) {
            let footprint: [f32; 8] = std::array::from_fn(|l| texels[l] / map.side() as f32);
            let (mut guess, mut k) = ([0i32; 8], [0i32; 8]);
            // SAFETY: each array is 8 `f32` or `i32`, the 32 bytes each load or
            // store touches.
            unsafe {
                let zero = _mm256_setzero_ps();
                let map = map.avx2();
                let level = map.level_avx2(zero, zero, _mm256_mul_ps(_mm256_loadu_ps(footprint.as_ptr()), map.side));
                _mm256_storeu_si256(guess.as_mut_ptr().cast(), level.guess);
                _mm256_storeu_si256(k.as_mut_ptr().cast(), level.k);
            }
            (guess, k)
        }
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let map = builtin("grass").unwrap();
        let n = map.log2_side() as i32;
        let (mut same, mut rounded_up) = (0, 0);
        let mut texels = 1e-3f32;
        while texels < 1e4 {
            let x: [f32; 8] = std::array::from_fn(|l| texels * (1.0 + l as f32 * 1e-4));
            // SAFETY: the processor has AVX2.
            #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
            let (guess, k) = unsafe { levels(&map, &x) };
            for l in 0..8 {
                let bits = x[l].to_bits();
                let exponent = (bits >> 23) as i32 - 127;
                if guess[l] == k[l] {
                    same += 1;
                } else {
                    // Only where the ROM's fraction rounds up: its last entry,
                    // below a level, and one level up.
                    assert_eq!(bits >> 15 & 0xFF, 0xFF, "{}", x[l]);
                    assert!((0..n).contains(&exponent) && k[l] == exponent + 1, "{}", x[l]);
                    rounded_up += 1;
                }
            }
            texels *= 1.000_9;
        }
        // Just below each power of two texels up to the top level.
        for e in 1..=n {
            let x = [f32::from_bits((e as f32).exp2().to_bits() - 1); 8];
            // SAFETY: the processor has AVX2.
            #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
            let (guess, k) = unsafe { levels(&map, &x) };
            // `e - 1` plus a fraction a few of its ulps below 1, which rounds
            // up from some `e` on.
            assert_eq!(guess[0], e - 1, "just below 2^{e} texels");
            assert!(k[0] == e - 1 || k[0] == e, "just below 2^{e} texels");
            rounded_up += usize::from(k[0] == e);
        }
        assert!(same > 100_000 && rounded_up >= 4, "{same} {rounded_up}");
    }

    /// [`fract01_avx2`] (with no `min`) against [`fract01`], bit for bit: random
    /// bit patterns, small values of either sign around integers, and the odd
    /// ones (zeros, infinities, NaN, the largest and smallest).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn fract01_avx2_is_fract01_bit_for_bit() {
        #[target_feature(enable = "avx2")]
        #[allow(unsafe_code, reason = "a load and a store of arrays of a register's size")]
        fn run(x: &[f32; 8]) -> [f32; 8] {
            let mut out = [0.0f32; 8];
            // SAFETY: both arrays are 8 `f32`, the 32 bytes the load and the store touch.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), fract01_avx2(_mm256_loadu_ps(x.as_ptr()))) };
            out
        }
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let odd = [
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            -f32::from_bits(1),
            -1e-10,
            -1.0,
            1.0,
            -0.5,
            16_777_217.0,
            -8_388_607.5,
        ];
        let mut h = 0x9E37_79B9u32;
        let mut next = || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            h
        };
        for round in 0..400_000u32 {
            let x: [f32; 8] = std::array::from_fn(|l| match (round as usize + l) % 4 {
                0 => odd[(round as usize + l) % odd.len()],
                1 => f32::from_bits(next()),
                // Near an integer of either sign, by a tiny amount.
                2 => (next() % 64) as f32 - 32.0 + f32::from_bits(next() & 0x33FF_FFFF) * [1.0, -1.0][l % 2],
                _ => (next() >> 8) as f32 / (1u32 << 20) as f32 - 8.0,
            });
            // SAFETY: the processor has AVX2 (detected above).
            #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
            let avx2 = unsafe { run(&x) };
            for l in 0..8 {
                assert_eq!(avx2[l].to_bits(), fract01(x[l]).to_bits(), "fract01 of {} ({:#x})", x[l], x[l].to_bits());
            }
        }
    }

    /// The pair layout holds, at pair `(r, c)` of each level, texels `(c, r)` and
    /// `(c, r + 1)`, wrapped.
    #[test]
    fn pair_layout_holds_the_texels() {
        for map in [ramp(1), ramp(2), ramp(16), builtin("grass").unwrap()] {
            let n = map.log2_side();
            assert_eq!(map.pairs.len(), pair_start(n, 1) as usize + 4);
            for k in 0..=n {
                let s = 1u32 << (n - k);
                for r in 0..s {
                    for c in 0..=s {
                        let at = (pair_start(n, s) + 2 * (r * (s + 1) + c)) as usize;
                        let (c, r) = (c as i32, r as i32);
                        assert_eq!(map.pairs[at..at + 2], [map.texel(k, c, r), map.texel(k, c, r + 1)]);
                    }
                }
            }
        }
    }

    #[test]
    fn lod_is_the_footprint_in_texels() {
        let m = builtin("checker").unwrap();
        assert_eq!(m.lod(1.0 / 256.0), 0.0);
        assert_eq!(m.lod(4.0 / 256.0), 2.0);
        assert_eq!(m.lod(1e-6), 0.0);
        assert_eq!(m.lod(100.0), 8.0);
        assert_eq!(m.lod(f32::NAN), 0.0);
        // Far beyond the pyramid: the mean.
        assert!((m.sample(0.3, 0.7, 1.0) - 128.0 / 255.0).abs() < 1e-6);
    }

    #[test]
    fn builtins_are_deterministic_and_distinct() {
        for name in BUILTIN_NAMES {
            let a = builtin(name).unwrap();
            assert_eq!(a, builtin(name).unwrap(), "{name}");
            assert_eq!(a.side(), 256);
            let mean = f64::from(a.level(8)[0]) / 255.0;
            assert!((0.1..0.9).contains(&mean), "{name}: mean {mean}");
        }
        assert!(builtin("marble").is_none());
        assert_ne!(builtin("grass").unwrap(), builtin("asphalt").unwrap());
    }

    #[test]
    fn checker_matches_its_definition() {
        let m = builtin("checker").unwrap();
        for (u, v, t) in [(0.01, 0.01, 255), (0.13, 0.01, 0), (0.13, 0.13, 255), (0.99, 0.01, 0)] {
            let (i, j) = ((u * 256.0) as i32, (v * 256.0) as i32);
            assert_eq!(m.texel(0, i, j), t, "({u}, {v})");
        }
    }

    #[test]
    fn resampling_keeps_constants_and_power_of_two_sides() {
        let src = vec![77u8; 3 * 5];
        let out = resample_periodic(&src, 3, 5, 8);
        assert_eq!(out, vec![77u8; 64]);
        // Already square: the identity.
        let src: Vec<u8> = (0..16).map(|k| k * 10).collect();
        assert_eq!(resample_periodic(&src, 4, 4, 4), src);
    }
}
