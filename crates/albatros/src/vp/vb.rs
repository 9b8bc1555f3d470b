//! Video buffer (VB, P1 fig. 6): per-pixel accumulation of colour x area (P1's device
//! F1), the readout filter F2 and the gamma table; P1's logarithmic number format
//! beside a float reference and a linear fixed-point format for comparison.
//!
//! Accumulation (F1): each pixel sums `colour_i * area_i` over its visible fragments,
//! in priority order; the background is the last fragment of every pixel and fills
//! what is left, so the areas of a pixel always sum to one. The first fragment of a
//! pixel is written as it is, later ones read-modify-write (P1's first-write flag from
//! the subpixel mask memory: no clearing pass is needed for correctness). The 8-bit
//! code's F1 in AVX2 (`F1Avx2`) runs inside the AVX2 colour computers' function,
//! the cell's colours handed over in [`CellColors`] with no call between.
//!
//! Readout: the coarse filter F2 gives each pixel the mean of itself and its right,
//! lower and lower-right neighbours (a 2 x 2 box) in two passes, first the half sums
//! of vertically adjacent pixels (kept in a line buffer), then the half sums of
//! horizontally adjacent ones; at the last row and column the pixel's own value
//! stands in for the missing neighbours. Then the gamma table gives 8-bit output.
//!
//! # The modes ([`VbMode`])
//! - [`VbMode::Log`] (the default, 8 bits): P1's video memory. Every component is a
//!   logarithm code; weighting by area is an addition (P1 eq. 3), summation an
//!   addition with a table of `ln(1 + e^x)` (P1 eq. 4), F2 works on the codes, and the
//!   gamma table composes the antilog with the display curve. It is the default
//!   because it meets the two targets of issue 4, measured in `tests/it/vb.rs`: a
//!   mean difference from the float path under 1.5 output levels on every built-in
//!   scene (0.50 to 0.98 with F2, at most 8 levels in a pixel), and no contouring on
//!   a smooth dark gradient (linear 0 to 0.1 at gamma 2.2: no step over one level
//!   wherever the ideal picture changes by less than half a level per pixel, where
//!   an 8-bit linear buffer steps by 7). Its limit is the floor: below its smallest
//!   value, 1/400 (level 17), it steps from zero as a linear code does from 0 to
//!   1/255 (level 20); 9 bits move the floor to level 1.
//!
//!   Cost, measured on the default scene (1024 x 768, `vb_cost` in the tests): F1
//!   takes about 19 ns per pixel write against 5 for the float path, the whole
//!   `render_frame` about 14% more; the readout is faster (18 ms against 22: integer
//!   tables against float rounding). Since then the log readout has become about
//!   three times faster (rombm, 1920 x 1080, one thread: it skips the half sums of
//!   runs of pixels equal to their neighbours and runs without branches or bounds
//!   checks).
//! - [`VbMode::Float`]: `f32` accumulators, the reference.
//! - [`VbMode::Linear`]: a linear fixed-point code of the same width, what P1's log
//!   scale replaced; kept to measure the contouring it avoids.
//!
//! # The log code (P1 eq. 3-4)
//! A VMEM word holds three `b`-bit codes (`b` = [`VbMode::Log`]`::bits`, 8 by
//! default: P1's 24-bit colour word, stored as one `u32` per pixel, [`Word8`]; wider
//! codes as three `u16`). Layout of one code `q`, unsigned:
//! - `q = 0`: zero (black). The logarithm of zero does not exist, so zero has a code
//!   of its own, below every value;
//! - `q = 1 ..= Q1`, `Q1 = 2^b - 1`: the linear value `c = exp(alpha (q - Q1))`, i.e.
//!   `q = Q1 + K ln c` with `K = 1/alpha`: P1's `C = (1/alpha) ln c`, offset so that
//!   `Q1` codes 1.0 (brighter values saturate there) and code 1 the smallest value
//!   `c_min = exp(-alpha (Q1 - 1))`.
//!
//! The numbers that decided `alpha` for 8 bits: the 254 steps span 1/400 .. 1
//! ([`LOG8_RANGE`], 52 dB), `alpha = ln 400 / 254 = 0.02359`, a step of 2.39% in
//! luminance, about the eye's contrast threshold. At gamma 2.2 one step is
//! `(e^(alpha/2.2) - 1) o = 0.0108 o` output levels at output level `o`: under one
//! level up to level 92 (linear 0.108), so a smooth gradient up to linear 0.1 shows
//! no step; 2.75 levels at white. A wider range costs step size (1/512 gives exactly
//! one level at linear 0.1, no margin), a narrower one lifts the floor: `c_min` =
//! 1/400 shows as level 16.7 at gamma 2.2, and between zero and it a gradient steps
//! as it does in an 8-bit linear code from 0 to 1/255 (level 20.5).
//!
//! More bits first widen the range at the same `alpha`, down to the floor of an 8-bit
//! gamma-2.2 output, `(0.5/255)^2.2 = 1.1e-6` ([`OUTPUT_FLOOR_LN`]: nothing darker
//! shows): 9 bits cover 6.0e-6 .. 1 (floor at level 1.1); beyond that they refine
//! `alpha`: `K = max(K_8, (2^b - 2) / 13.72)`, 74.5 for 10 bits, 298 for 12.
//!
//! Inside F1 and F2 values carry [`LOG_FRAC_BITS`] = 2 fraction bits ([`LogFine`],
//! quarter codes in an `i32`). The VMEM stores whole codes, rounded half to even once
//! per write; F2's results keep the fraction (a half sum has one more bit per pass,
//! two passes) and address the gamma table. A result below code 1 rounds in linear
//! terms: to code 1 if it is at least `c_min / 2`, else to zero.
//!
//! # The tables (built once per bit count from their definitions)
//! - **ln S** ([`LogScale::ln_area_table`], 16 x `i32`): index `n - 1` for `n` =
//!   1..=16 visible subpixels, entry `round(4 K ln(n / 16))` in quarter codes (P1
//!   eq. 3's `(1/alpha) ln S`); 0 down to -470 for 8 bits.
//! - **ln(1 + e^x)** ([`LogScale::softplus_table`], `u16`): index `i = hi - lo >= 0`,
//!   the difference of the two operands in quarter codes (max minus min, so that the
//!   table's argument `-i` is never positive and its values stay in `0 ..= 4 K ln 2`),
//!   entry `round(4 K ln(1 + exp(-i / (4 K))))` in quarter codes; the table ends where
//!   its entries round to 0 (and reads 0 beyond), after `~4 K ln(8 K)` entries: 988
//!   entries of 7 bits for 8 bits, 9287 of 10 bits for 12. Sum (eq. 4):
//!   `hi + T[hi - lo]`; mean (F2): `hi + T[hi - lo] - T[0]` (`T[0]` = `4 K ln 2`).
//!   F1 and F2 read a copy padded with zeros to `2^14` entries at index
//!   `min(hi - lo, 2^14 - 1)`: the same value for every difference, with neither a
//!   bounds check nor a branch at the table's end.
//! - **Gamma** ([`LogScale::gamma_table`], `u8`): index an F2 result in quarter codes,
//!   `0 ..= 4 Q1` (`b + 2` bits: 1021 entries for 8 bits), entry
//!   `round(255 c^(1/gamma))` with `c = exp(alpha (i/4 - Q1))` and 0 for zero (index
//!   below 4). It depends on the readout's gamma, so each readout builds it (1021
//!   powers for 8 bits, microseconds; once for all the bands of a parallel
//!   readout). The readout pads it with zeros to `2^14` entries and addresses it
//!   with the F2 result masked to 14 bits: every result is in `0 ..= 4 Q1` (kept)
//!   or zero's [`LogFine::ZERO`], `-2^24` (masked to 0).
//! - **Encoder** ([`LogScale::encoder_table`], `(u32, u16)`): the CC's output
//!   converter. The CC hands the VB a `b`-bit code per component (P1: a 24-bit colour
//!   word); in this model the CC computes in `f32` and the conversion is the first
//!   step of [`VideoBuffer::accumulate`]. Address: the f32's exponent and top `M`
//!   mantissa bits, `(bits >> (23 - M)) - base`, over the binades from the one that
//!   holds `c_min / 2` up to 1.0 (below: code 0; from 1.0: `Q1`). Entry: the f32 bit
//!   pattern from which the code is one more, and the code at the bucket's start.
//!   `M` is the least that makes a bucket narrower than a code (`K ln(1 + 2^-M) <
//!   1`): 6 for 8 bits (10 binades, 640 entries), 9 for 12 bits (10752 entries).
//!   Built from the f64 definition ([`LogScale::encode_exact`]: `Q1 + round(K ln
//!   c)`, half up, with the rules above), it reproduces it exactly with no `ln` per
//!   pixel (`logf` was a quarter of F1's time).
//!
//! # The linear code ([`VbMode::Linear`])
//! `q = round(c M)`, `M = 2^b - 1`, saturated; weighted by `round(q n / 16)` (half to
//! even), summed with saturation; F2's half sums are exact with two fraction bits
//! and address a gamma table of `4 M + 1` entries.

use std::fmt;
use std::str::FromStr;
use std::sync::OnceLock;

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

use glam::Vec3;

use super::cc::CellColors;
use super::gq::Share;
use super::spp::{Visible, CELL_SIDE, FULL};

/// Entries of the float path's gamma table (linear input resolution).
pub const GAMMA_TABLE_SIZE: usize = 4096;
/// Rows per band when the readout runs on several threads.
pub const READOUT_BAND_ROWS: usize = 32;

/// Smallest bit count of a fixed-point VB code.
pub const VB_BITS_MIN: u32 = 8;
/// Largest bit count of a fixed-point VB code.
pub const VB_BITS_MAX: u32 = 12;
/// Bits of a log code by default (P1: 8 per component, a 24-bit VMEM word).
pub const LOG_BITS_DEFAULT: u32 = 8;
/// The dynamic range `1 / c_min` of the 8-bit log code (see the module docs).
pub const LOG8_RANGE: f64 = 400.0;
/// `-ln` of the darkest linear value an 8-bit gamma-2.2 output shows,
/// `-ln (0.5/255)^2.2 = 2.2 ln 510`: more log bits widen the range down to it, then
/// refine the step. (Checked against its formula in the tests.)
pub const OUTPUT_FLOOR_LN: f64 = 13.715_703_596_580_418;
/// Fraction bits inside F1 and F2 (quarter codes).
pub const LOG_FRAC_BITS: u32 = 2;
/// Subpixels per pixel: the denominator of a fragment's area.
const AREA_DENOMINATOR: u32 = 16;
/// Largest output code.
const OUTPUT_MAX: f64 = 255.0;
/// Half a code: the rounding offset of the linear encoder.
const HALF_CODE: f32 = 0.5;
/// Quarter codes per code.
const FINE_PER_CODE: i32 = 1 << LOG_FRAC_BITS;
/// Entries of the padded `ln(1 + e^x)` table the hot loops read (module docs: "The
/// tables"): more than the longest table (9287 entries for 12 bits), a power of two.
const SOFTPLUS_PADDED: usize = 1 << 14;
/// Entries of the padded gamma table of the fixed-point readouts: more than the
/// largest address (`4 Q1 = 16380` for 12 bits), a power of two that divides
/// `-LogFine::ZERO`, so that an address masked with `GAMMA_PADDED - 1` is itself and
/// zero's is 0.
const GAMMA_PADDED: usize = 1 << 14;

/// How the video memory stores a colour component.
///
/// A small value type with named constants: [`VbMode::LOG8`] (the default),
/// [`VbMode::FLOAT`], [`VbMode::LINEAR8`]. [`VideoBuffer::new`] clamps bit counts to
/// `VB_BITS_MIN..=VB_BITS_MAX`; parsing (`"float"`, `"log"`, `"log10"`, `"linear8"`,
/// see [`VbMode::from_str`]) rejects them with a message.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum VbMode {
    /// `f32` accumulators: the reference.
    Float,
    /// P1's logarithm codes (module docs: "The log code").
    Log {
        /// Bits per component, `VB_BITS_MIN..=VB_BITS_MAX`.
        bits: u32,
    },
    /// Linear fixed-point codes, for comparison with the log codes.
    Linear {
        /// Bits per component, `VB_BITS_MIN..=VB_BITS_MAX`.
        bits: u32,
    },
}

impl VbMode {
    /// The float reference.
    pub const FLOAT: Self = Self::Float;
    /// P1's 8-bit log codes: the default.
    pub const LOG8: Self = Self::Log { bits: LOG_BITS_DEFAULT };
    /// 8-bit linear codes.
    pub const LINEAR8: Self = Self::Linear { bits: 8 };

    /// The mode with its bit count clamped to `VB_BITS_MIN..=VB_BITS_MAX`.
    pub fn clamped(self) -> Self {
        match self {
            Self::Float => Self::Float,
            Self::Log { bits } => Self::Log { bits: bits.clamp(VB_BITS_MIN, VB_BITS_MAX) },
            Self::Linear { bits } => Self::Linear { bits: bits.clamp(VB_BITS_MIN, VB_BITS_MAX) },
        }
    }
}

impl Default for VbMode {
    /// [`VbMode::LOG8`]: it meets issue 4's targets (module docs).
    fn default() -> Self {
        Self::LOG8
    }
}

impl fmt::Display for VbMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Float => write!(f, "float"),
            Self::Log { bits } => write!(f, "log{bits}"),
            Self::Linear { bits } => write!(f, "linear{bits}"),
        }
    }
}

/// A video buffer mode that does not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum VbModeError {
    /// Not one of the mode names.
    #[error("unknown video buffer mode {0:?}: expected float, log, logN, linear or linearN (N in 8..=12)")]
    Unknown(String),
    /// A bit count out of range.
    #[error("video buffer codes of {0} bits: expected 8..=12")]
    Bits(u32),
}

impl FromStr for VbMode {
    type Err = VbModeError;

    /// `float`; `log` (8 bits) or `logN`; `linear` (8 bits) or `linearN`; `N` in
    /// `VB_BITS_MIN..=VB_BITS_MAX`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bits = |rest: &str| -> Result<u32, VbModeError> {
            if rest.is_empty() {
                return Ok(LOG_BITS_DEFAULT);
            }
            let bits: u32 = rest.parse().map_err(|_| VbModeError::Unknown(s.to_owned()))?;
            if (VB_BITS_MIN..=VB_BITS_MAX).contains(&bits) {
                Ok(bits)
            } else {
                Err(VbModeError::Bits(bits))
            }
        };
        let s_lower = s.trim().to_ascii_lowercase();
        if s_lower == "float" {
            Ok(Self::Float)
        } else if let Some(rest) = s_lower.strip_prefix("linear") {
            Ok(Self::Linear { bits: bits(rest)? })
        } else if let Some(rest) = s_lower.strip_prefix("log") {
            Ok(Self::Log { bits: bits(rest)? })
        } else {
            Err(VbModeError::Unknown(s.to_owned()))
        }
    }
}

/// A log-scale value inside F1 and F2: a code with [`LOG_FRAC_BITS`] fraction bits
/// (quarter codes). Layout of the `i32`: `[31:2]` the whole code (signed: a weighted
/// fragment may fall below code 1), `[1:0]` the fraction. Zero (black) is
/// [`LogFine::ZERO`], far below every value, so that the sum and the mean need no
/// special case for it: its difference from any value is past the end of the
/// `ln(1 + e^x)` table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LogFine(pub i32);

impl LogFine {
    /// Zero: `2^24` quarter codes below code 0, beyond any table (at most `2^15`
    /// entries) plus any code (`4 Q1 < 2^14`) plus any `ln S` (`> -2^12`).
    pub const ZERO: Self = Self(-(1 << 24));
    /// Code 1, the smallest non-zero value.
    pub const CODE_ONE: Self = Self(FINE_PER_CODE);

    /// The value of a stored code.
    #[inline]
    pub fn from_code(q: u16) -> Self {
        if q == 0 {
            Self::ZERO
        } else {
            Self(i32::from(q) << LOG_FRAC_BITS)
        }
    }
}

/// The log scale of one bit count: its constants and its tables (module docs: "The
/// log code" and "The tables").
#[derive(Clone, Debug, PartialEq)]
pub struct LogScale {
    bits: u32,
    /// `Q1 = 2^b - 1`, the code of linear 1.0.
    one: i32,
    /// `alpha`: the natural-log step of one code.
    alpha: f64,
    /// `K = 1 / alpha`, codes per natural-log unit.
    k: f64,
    /// The encoder ROM's address shift, `23 - M`.
    encoder_shift: u32,
    /// The encoder ROM's first address: the f32 bits of `2^e_lo` shifted.
    encoder_base: u32,
    /// The encoder ROM: per bucket, the f32 bits from which the code is one more,
    /// and the code at the bucket's start.
    encoder: Vec<(u32, u16)>,
    /// `round(4 K ln(n / 16))`, index `n - 1`.
    ln_area: [i32; AREA_DENOMINATOR as usize],
    /// `round(4 K ln(1 + exp(-i / 4K)))`, index `i >= 0`, until it rounds to 0.
    softplus: Vec<u16>,
    /// The same padded with zeros to [`SOFTPLUS_PADDED`] entries: index `d.min(SOFTPLUS_PADDED - 1)`
    /// reads `T[d]` for every `d >= 0`, with no bounds check.
    softplus_padded: Box<[u16; SOFTPLUS_PADDED]>,
    /// `T[0] = round(4 K ln 2)`: halving in quarter codes.
    ln2: i32,
    /// 8 bits only: F2's first pass as a table ([`PairMeans`]).
    pair_means: Option<PairMeans>,
    /// 8 bits only: the encoder ROM over every `f32` ([`Encoder8`]).
    encoder8: Option<Encoder8>,
}

impl LogScale {
    /// The scale of `bits` (clamped to `VB_BITS_MIN..=VB_BITS_MAX`), built once.
    pub fn get(bits: u32) -> &'static LogScale {
        const COUNT: usize = (VB_BITS_MAX - VB_BITS_MIN + 1) as usize;
        static SCALES: [OnceLock<LogScale>; COUNT] = [const { OnceLock::new() }; COUNT];
        let bits = bits.clamp(VB_BITS_MIN, VB_BITS_MAX);
        SCALES[(bits - VB_BITS_MIN) as usize].get_or_init(|| LogScale::build(bits))
    }

    /// Builds the scale and its tables from their definitions (module docs).
    pub fn build(bits: u32) -> Self {
        let bits = bits.clamp(VB_BITS_MIN, VB_BITS_MAX);
        let one = (1i32 << bits) - 1;
        // 8 bits: 254 steps over 1/400 .. 1; more bits widen to the output floor,
        // then refine.
        let k8 = f64::from((1 << LOG_BITS_DEFAULT) - 2) / LOG8_RANGE.ln();
        let k = k8.max(f64::from(one - 1) / OUTPUT_FLOOR_LN);
        let fine = f64::from(FINE_PER_CODE);
        let ln_area =
            std::array::from_fn(|i| (fine * k * ((i + 1) as f64 / f64::from(AREA_DENOMINATOR)).ln()).round() as i32);
        let softplus: Vec<u16> = (0u32..)
            .map(|i| (fine * k * (-f64::from(i) / (fine * k)).exp().ln_1p()).round() as u16)
            .take_while(|&t| t > 0)
            .collect();
        let ln2 = i32::from(softplus[0]);
        assert!(softplus.len() < SOFTPLUS_PADDED, "the padded table ends in a zero");
        let mut softplus_padded = Box::new([0; SOFTPLUS_PADDED]);
        softplus_padded[..softplus.len()].copy_from_slice(&softplus);
        let mut scale = Self {
            bits,
            one,
            alpha: 1.0 / k,
            k,
            encoder_shift: 0,
            encoder_base: 0,
            encoder: Vec::new(),
            ln_area,
            softplus,
            softplus_padded,
            ln2,
            pair_means: None,
            encoder8: None,
        };
        scale.build_encoder();
        if bits == PAIR_MEANS_BITS {
            scale.pair_means = Some(PairMeans::build(&scale));
            scale.encoder8 = Some(Encoder8::build(&scale));
        }
        scale
    }

    /// The encoder's definition in f64: `Q1 + round(K ln c)` (half up), saturated at
    /// `Q1`; below code 1 to code 1 from `c_min / 2` up, else 0.
    pub fn encode_exact(&self, c: f64) -> u16 {
        if c.is_nan() || c <= 0.0 {
            return 0;
        }
        if c >= 1.0 {
            return self.one as u16;
        }
        let x = f64::from(self.one) + self.k * c.ln();
        if x >= 0.5 {
            ((x + 0.5).floor() as i32).min(self.one) as u16
        } else if c >= self.min_value() / 2.0 {
            1
        } else {
            0
        }
    }

    /// Builds the encoder ROM (module docs) from [`Self::encode_exact`]: buckets of
    /// `2^(23 - M)` f32 bit patterns, each narrower than one code, so that one
    /// threshold per bucket gives the definition exactly (the encoder is monotone).
    fn build_encoder(&mut self) {
        const F32_MANTISSA_BITS: u32 = 23;
        const F32_EXPONENT_BIAS: i32 = 127;
        let mut m = 1;
        while self.k * (-f64::from(m)).exp2().ln_1p() >= 1.0 {
            m += 1;
        }
        let shift = F32_MANTISSA_BITS - m;
        let e_lo = (self.min_value() / 2.0).log2().floor() as i32;
        let start = ((F32_EXPONENT_BIAS + e_lo) as u32) << F32_MANTISSA_BITS;
        let end = 1.0f32.to_bits();
        let code = |bits: u32| self.encode_exact(f64::from(f32::from_bits(bits)));
        let encoder = (start >> shift..end >> shift)
            .map(|bucket| {
                let (lo, hi) = (bucket << shift, (bucket + 1) << shift);
                let q0 = code(lo);
                // The first pattern of the bucket with a larger code, by bisection.
                let up_from = if code(hi - 1) == q0 {
                    u32::MAX
                } else {
                    let (mut a, mut b) = (lo, hi - 1);
                    while b - a > 1 {
                        let mid = a + (b - a) / 2;
                        if code(mid) == q0 {
                            a = mid;
                        } else {
                            b = mid;
                        }
                    }
                    b
                };
                debug_assert!(code(hi - 1) <= q0 + 1, "a bucket narrower than a code");
                (up_from, q0)
            })
            .collect();
        self.encoder_shift = shift;
        self.encoder_base = start >> shift;
        self.encoder = encoder;
    }

    /// The encoder ROM: entries `(f32 bits from which the code is one more, code at
    /// the bucket's start)`, address `(bits >> shift) - base`; and its `shift`.
    pub fn encoder_table(&self) -> (&[(u32, u16)], u32) {
        (&self.encoder, self.encoder_shift)
    }

    /// Bits per code.
    pub fn bits(&self) -> u32 {
        self.bits
    }

    /// `alpha`, the natural-log step of one code (P1's `alpha`).
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// `Q1`, the code of linear 1.0 (the largest).
    pub fn one(&self) -> u16 {
        self.one as u16
    }

    /// The linear value of code 1, the smallest non-zero value.
    pub fn min_value(&self) -> f64 {
        self.value(1)
    }

    /// The `ln S` table (eq. 3): index `n - 1`, quarter codes.
    pub fn ln_area_table(&self) -> &[i32; AREA_DENOMINATOR as usize] {
        &self.ln_area
    }

    /// The `ln(1 + e^x)` table: index `-x` in quarter codes, quarter codes.
    pub fn softplus_table(&self) -> &[u16] {
        &self.softplus
    }

    /// The CC's code of a linear component by the encoder ROM: exactly
    /// [`Self::encode_exact`] of `c` (`Q1 + round(K ln c)`, saturated at `Q1`; below
    /// code 1 rounded in linear terms; 0 for zero, negative or NaN input).
    #[inline]
    pub fn encode(&self, c: f32) -> u16 {
        if c >= 1.0 {
            return self.one as u16;
        }
        // Zero, negatives, NaN and values below the ROM's first binade fall outside it.
        let bits = c.to_bits();
        let address = (bits >> self.encoder_shift).wrapping_sub(self.encoder_base) as usize;
        match self.encoder.get(address) {
            Some(&(up_from, q)) => q + u16::from(bits >= up_from),
            None => 0,
        }
    }

    /// The linear value of a code (0 for zero).
    pub fn value(&self, q: u16) -> f64 {
        if q == 0 {
            0.0
        } else {
            (self.alpha * f64::from(i32::from(q) - self.one)).exp()
        }
    }

    /// The linear value of a quarter-code value (0 for [`LogFine::ZERO`] and what
    /// lies near it).
    pub fn fine_value(&self, v: LogFine) -> f64 {
        if v.0 <= LogFine::ZERO.0 / 2 {
            0.0
        } else {
            (self.alpha * (f64::from(v.0) / f64::from(FINE_PER_CODE) - f64::from(self.one))).exp()
        }
    }

    /// P1 eq. (3), weighting by area: `C' = C + (1/alpha) ln S` with `S = n / 16`,
    /// `n` in `1..=16` visible subpixels.
    #[inline]
    pub fn weigh(&self, q: u16, n: u32) -> LogFine {
        debug_assert!((1..=AREA_DENOMINATOR).contains(&n), "a visible fragment covers 1..=16 subpixels");
        LogFine(LogFine::from_code(q).0 + self.ln_area[n as usize - 1])
    }

    /// P1 eq. (4), the sum of two values: `hi + (1/alpha) ln(1 + exp(alpha (lo -
    /// hi)))`, the larger operand plus the table at their difference.
    #[inline]
    pub fn sum(&self, a: LogFine, b: LogFine) -> LogFine {
        let (hi, lo) = if a >= b { (a.0, b.0) } else { (b.0, a.0) };
        LogFine(hi + self.softplus_at(hi - lo))
    }

    /// F2's half sum: `ln((a + b) / 2) = sum - ln 2`, kept in quarter codes (below
    /// code 1 rounded in linear terms to code 1 or zero).
    #[inline]
    pub fn mean(&self, a: LogFine, b: LogFine) -> LogFine {
        let v = self.sum(a, b).0 - self.ln2;
        if v >= FINE_PER_CODE {
            LogFine(v)
        } else if v >= FINE_PER_CODE - self.ln2 {
            LogFine::CODE_ONE
        } else {
            LogFine::ZERO
        }
    }

    /// The VMEM word of a value: rounded half to even to a whole code, saturated at
    /// `Q1`; below code 1 rounded in linear terms to code 1 or zero.
    #[inline]
    pub fn store(&self, v: LogFine) -> u16 {
        let v = v.0;
        if v >= FINE_PER_CODE {
            (round_half_even(v, LOG_FRAC_BITS)).min(self.one) as u16
        } else if v >= FINE_PER_CODE - self.ln2 {
            1
        } else {
            0
        }
    }

    /// `T[d]`: the table, 0 past its end.
    #[inline]
    fn softplus_at(&self, d: i32) -> i32 {
        debug_assert!(d >= 0, "the table's index is max - min");
        self.softplus.get(d as usize).map_or(0, |&t| i32::from(t))
    }

    /// The gamma table (module docs): index an F2 result in quarter codes, `0..=4
    /// Q1`; output `round(255 c^(1/gamma))`, 0 for zero.
    pub fn gamma_table(&self, gamma: f32) -> Vec<u8> {
        let inv_gamma = 1.0 / f64::from(gamma);
        (0..=self.one * FINE_PER_CODE)
            .map(|i| {
                if i < FINE_PER_CODE {
                    return 0;
                }
                let c = self.fine_value(LogFine(i));
                (OUTPUT_MAX * c.powf(inv_gamma)).round() as u8
            })
            .collect()
    }
}

/// `v / 2^shift` rounded half to even.
#[inline]
fn round_half_even(v: i32, shift: u32) -> i32 {
    let whole = v >> shift;
    let frac = v & ((1 << shift) - 1);
    let half = 1 << (shift - 1);
    whole + i32::from(frac > half || (frac == half && whole & 1 == 1))
}

/// The log arithmetic of F1 and F2 as their loops run it: [`LogScale`]'s `sum`,
/// `mean` and `store` with the scale's registers in locals, the padded `ln(1 + e^x)`
/// table (no bounds check, no branch at its end) and no branches on the operands'
/// range. The same results as [`LogScale`]'s, bit for bit (checked exhaustively in
/// the tests).
#[derive(Clone, Copy)]
struct LogArith<'a> {
    /// `T` padded with zeros ([`LogScale::softplus_padded`]).
    softplus: &'a [u16; SOFTPLUS_PADDED],
    /// `T[0] = 4 K ln 2`.
    ln2: i32,
    /// The smallest value stored as code 1, `4 - T[0]` (below it: zero).
    floor: i32,
    /// `Q1`.
    one: i32,
}

impl<'a> LogArith<'a> {
    fn new(scale: &'a LogScale) -> Self {
        Self { softplus: &scale.softplus_padded, ln2: scale.ln2, floor: FINE_PER_CODE - scale.ln2, one: scale.one }
    }

    /// `T[d]`, `d >= 0`: the padded table at `d`, or at its last entry (a zero)
    /// for any `d` past it.
    #[inline(always)]
    fn softplus(self, d: i32) -> i32 {
        debug_assert!(d >= 0, "the table's index is max - min");
        i32::from(self.softplus[(d as u32 as usize).min(SOFTPLUS_PADDED - 1)])
    }

    /// P1 eq. (4), [`LogScale::sum`]: `hi + T[hi - lo]`.
    #[inline(always)]
    fn sum(self, a: i32, b: i32) -> i32 {
        let (hi, lo) = (a.max(b), a.min(b));
        hi + self.softplus(hi - lo)
    }

    /// F2's half sum, [`LogScale::mean`], of two of F2's operands: each
    /// [`LogFine::ZERO`] or at least code 1 (a loaded code or an earlier mean).
    /// `v = hi + T[hi - lo] - T[0]` is then at least `4 - T[0]` unless both are zero
    /// (`T` is at most `T[0]`), and exactly `ZERO` if they are: the mean is `ZERO`
    /// for two zeros, else `v` raised to code 1. Equal operands give themselves.
    #[inline(always)]
    fn mean(self, a: i32, b: i32) -> i32 {
        debug_assert!(
            [a, b].iter().all(|&v| v == LogFine::ZERO.0 || v >= FINE_PER_CODE),
            "F2's operands are zero or at least code 1"
        );
        let (hi, lo) = (a.max(b), a.min(b));
        (hi + self.softplus(hi - lo) - self.ln2).max(hi.min(FINE_PER_CODE))
    }

    /// The VMEM word of a value, [`LogScale::store`]: rounded half to even,
    /// `(v + 1 + the whole code's low bit) >> 2`, clamped to `1..=Q1` (below code 1 that
    /// rounding gives at most 1); zero below `4 - T[0]`.
    #[inline(always)]
    fn store(self, v: i32) -> u16 {
        let rounded = (v + (FINE_PER_CODE / 2 - 1) + ((v >> LOG_FRAC_BITS) & 1)) >> LOG_FRAC_BITS;
        let code = rounded.clamp(1, self.one) as u16;
        if v >= self.floor {
            code
        } else {
            0
        }
    }
}

/// The bit count whose F2 first pass is a table ([`PairMeans`]): P1's 8-bit code,
/// the default (`2^16` pairs; 10 bits would take `2^20`).
const PAIR_MEANS_BITS: u32 = 8;

/// Zero's value in [`PairMeans`]'s `i16` entries and F2's line buffer of the 8-bit
/// code. [`LogFine::ZERO`] does not fit an `i16`; any value far enough below every
/// other one gives the same means: its difference from a value (at least code 1,
/// 4 quarter codes) is above 4100, past the end of the 8-bit `ln(1 + e^x)` table
/// (988 entries), so a mean with it is `hi - T[0]` raised to code 1, as with
/// `LogFine::ZERO`; and two of them give itself. As an address of
/// [`log8_gamma_table`] (a `u16`, 61440) it reads one of the zeros between the
/// codes' entries and the raised ones (checked at compile time below: `T[0]` is less
/// than `4 Q1`).
const LOG8_ZERO: i16 = -4096;

const _: () = assert!(
    LOG8_ZERO as u16 as usize > 4 * ((1 << PAIR_MEANS_BITS) - 1)
        && (LOG8_ZERO as u16 as usize) < LOG8_ADDRESSES - 4 * ((1 << PAIR_MEANS_BITS) - 1),
    "zero's gamma address lies between the codes' and the raised ones"
);

/// Entries of the 8-bit code's second-pass tables ([`PairMeans::softplus`] and the
/// readout's gamma table, [`log8_gamma_table`]): every `u16`, so that an `i16`
/// difference or F2 result read as a `u16` addresses them with neither a bounds
/// check nor a clamp.
const LOG8_ADDRESSES: usize = 1 << 16;

/// F2's tables for the 8-bit log code (P1's F2 was a table-driven adder too).
///
/// - `means`, the first pass: entry `a << 8 | b` is the half sum `mean(load(a),
///   load(b))` of two stored codes in quarter codes, [`LOG8_ZERO`] for zero. One read
///   in place of the half sum's nine operations (max, min, difference, clamp, `T`
///   read, two additions, the raise to code 1); 128 KiB.
/// - `softplus`, the second pass: `T[d]` ([`LogScale::softplus_table`], at most
///   `T[0] = 118` for 8 bits, so a byte) at every `d` as a `u16`, 0 past the table's
///   end: the padded table's `T[min(d, 2^14 - 1)]` for every difference of two
///   `i16`, with no clamp; 64 KiB, of which the first 988 entries are read but for
///   a mean with zero.
///
/// Built once.
#[derive(Clone, Debug, PartialEq)]
struct PairMeans {
    means: Box<[i16; 1 << (2 * PAIR_MEANS_BITS)]>,
    softplus: Box<[u8; LOG8_ADDRESSES]>,
    /// `T[0]`, in the line buffer's `i16`.
    ln2: i16,
    /// `T[4 k]` at `k = 0..=255`: `T` at the difference of two loaded codes `k`
    /// apart (quarter codes), for the first pass by arithmetic
    /// (the tests' `PairMeans::mean_codes`); 0 from `k = 247` on (past the table's end).
    code_softplus: [u8; 1 << PAIR_MEANS_BITS],
}

impl PairMeans {
    fn build(scale: &LogScale) -> Self {
        let arith = LogArith::new(scale);
        let load = |q: u16| LogFine::from_code(q).0;
        let mut means = Box::new([0i16; 1 << (2 * PAIR_MEANS_BITS)]);
        for (i, m) in means.iter_mut().enumerate() {
            let (a, b) = ((i >> PAIR_MEANS_BITS) as u16, (i & ((1 << PAIR_MEANS_BITS) - 1)) as u16);
            let v = arith.mean(load(a), load(b));
            *m = if v == LogFine::ZERO.0 { LOG8_ZERO } else { v as i16 };
        }
        let mut softplus = Box::new([0u8; LOG8_ADDRESSES]);
        for (d, t) in softplus.iter_mut().enumerate() {
            *t = u8::try_from(arith.softplus(d as i32)).expect("the 8-bit table's entries fit a byte");
        }
        let code_softplus = std::array::from_fn(|k| softplus[FINE_PER_CODE as usize * k]);
        Self { means, softplus, ln2: i16::try_from(scale.ln2).expect("T[0] fits an i16"), code_softplus }
    }

    /// The half sum of two stored codes by arithmetic: [`LogArith::mean`] of the
    /// loaded codes, `hi + T[hi - lo] - T[0]` raised to code 1, with
    /// `hi - lo = 4 (qh - ql)` for two codes (`T` from [`Self::code_softplus`]) and
    /// past the table's end (`T = 0`) with zero's code; two zeros give
    /// [`LOG8_ZERO`]. The same as the table's entry (tested on every pair); the
    /// definition of the SIMD first pass.
    #[cfg(test)]
    fn mean_codes(&self, a: u8, b: u8) -> i16 {
        let (hi, lo) = (a.max(b), a.min(b));
        if hi == 0 {
            return LOG8_ZERO;
        }
        let t = if lo == 0 { 0 } else { self.code_softplus[usize::from(hi - lo)] };
        (i16::from(hi) * FINE_PER_CODE as i16 - self.ln2 + i16::from(t)).max(FINE_PER_CODE as i16)
    }

    /// The half sum of two stored codes.
    #[inline(always)]
    #[cfg(test)]
    fn mean(&self, a: u16, b: u16) -> i16 {
        self.means[usize::from(a & 0xFF) << PAIR_MEANS_BITS | usize::from(b & 0xFF)]
    }

    /// The half sums of two VMEM words, component by component, as a [`Line8`].
    #[inline(always)]
    fn mean_words(&self, a: Word8, b: Word8) -> Line8 {
        let at = |ch: u32| {
            let (a, b) = ((a >> (WORD8_SHIFT * ch)) & 0xFF, (b >> (WORD8_SHIFT * ch)) & 0xFF);
            self.means[(a << PAIR_MEANS_BITS | b) as usize]
        };
        [at(0), at(1), at(2), 0]
    }

    /// F2's second pass on two of the line buffer's values (each [`LOG8_ZERO`] or
    /// at least code 1), as the address of the output in [`log8_gamma_table`]:
    /// [`LogArith::mean`]'s `hi + T[hi - lo] - T[0]` before its raise to code 1 (the
    /// table's entries below code 1 do the raise), as a `u16`.
    #[inline(always)]
    fn mean_address(&self, a: i16, b: i16) -> u16 {
        let (hi, lo) = (a.max(b), a.min(b));
        Self::address(hi.wrapping_sub(self.ln2), self.softplus[usize::from(hi.wrapping_sub(lo) as u16)])
    }

    /// F2's output bytes (R, G, B) of the pixel whose line-buffer value is `a` and
    /// its right neighbour's `b`: [`Self::mean_address`] of each component, through
    /// the gamma table.
    #[inline(always)]
    fn output(&self, a: Line8, b: Line8, table: &[u8; LOG8_ADDRESSES]) -> [u8; 3] {
        [0, 1, 2].map(|ch| table[usize::from(self.mean_address(a[ch], b[ch]))])
    }

    /// `hi - T[0]` and `T[hi - lo]` to [`Self::mean_address`]'s address.
    #[inline(always)]
    fn address(hi_less_ln2: i16, t: u8) -> u16 {
        hi_less_ln2.wrapping_add(i16::from(t)) as u16
    }
}

/// The 8-bit code's gamma table: an F2 result `v` before its raise to code 1
/// ([`PairMeans::mean_address`]) or a loaded code, read as a `u16`, to the output
/// byte. F2's second pass gives either [`LOG8_ZERO`] (two zeros: entry 0) or
/// `hi + T - T[0]` for `hi` at least code 1, in `4 - T[0] ..= 4 Q1`, whose values below code
/// 1 are raised to it: entries `0..4` and the top `T[0] - 4` (the negative ones) hold
/// code 1's output, `4..=4 Q1` the gamma table's, the rest 0. `table`: the scale's
/// [`LogScale::gamma_table`].
fn log8_gamma_table(table: &[u8], ln2: i32) -> Vec<u8> {
    let mut g = vec![0u8; LOG8_ADDRESSES];
    g[..table.len()].copy_from_slice(table);
    let code_one = table[FINE_PER_CODE as usize];
    g[..FINE_PER_CODE as usize].fill(code_one);
    g[LOG8_ADDRESSES - (ln2 - FINE_PER_CODE) as usize..].fill(code_one);
    debug_assert_eq!(g[usize::from(LOG8_ZERO as u16)], 0, "zero's address is below the raised ones");
    g
}

/// The address shift of the 8-bit code's encoder ROM, `23 - M` with `M = 6`
/// mantissa bits (module docs: "The tables").
const ENCODER8_SHIFT: u32 = 17;
/// [`Encoder8`]'s entries: one per address `bits >> 17` of every `f32`.
const ENCODER8_ENTRIES: usize = 1 << (32 - ENCODER8_SHIFT);
/// Entries of a window of [`Encoder8`]'s table that the SIMD copies of F1 read in one
/// load when a component's addresses over a cell are that close (P1's pixels of a
/// cell have near colours: a window is a range of `2^(16/64) = 1.19` in value).
const ENCODER8_WINDOW: usize = 8;
/// Entries of [`Encoder8`]'s window below the address of the pixel that places it
/// (the first visible one of half a cell): the window then holds that address and
/// the 3 below and 4 above it.
#[cfg(target_arch = "x86_64")]
const ENCODER8_BACK: usize = 3;
/// [`Encoder8`]'s table with room for a window from its last entry (zeros, never
/// selected: a wanted lane's address is below `ENCODER8_ENTRIES`).
const ENCODER8_PADDED: usize = ENCODER8_ENTRIES + ENCODER8_WINDOW - 1;

/// The encoder ROM of the 8-bit code ([`LogScale::encode`]) over every `f32`, so that
/// it needs no test of its input's range: address `bits >> 17`, one `u32` entry per
/// bucket (one read per component, the same for a gather of 8 or 16):
/// - `[7:0]` `next`: the larger code of the bucket (`q + 1`, in 8 bits);
/// - `[25:8]` `from`: the low 17 bits of the first f32 pattern of the bucket whose
///   code is `next`, `0 ..= 2^17` (`2^17`: none is);
/// - `[31:26]` zero.
///
/// The code is `next - (bits & (2^17 - 1) < from)` in 8 bits (a compare and a
/// subtract with borrow; in SIMD lanes, the compare's all-ones added). The buckets of
/// the scale's ROM are its entries; below its first binade (zero, the denormals) the
/// code is 0 (`next` 1, `from` `2^17`); from 1.0 up and for infinity `Q1 = 255`
/// (`next` 0, `from` `2^17`; infinity's bucket `from` 1); for NaN and negative inputs
/// 0 (`next` 0, `from` 0 after infinity's bucket, its NaNs included). 128 KiB, of
/// which the 640 entries in `c_min / 2 .. 1` and the few just above 1 are read.
#[derive(Clone, Debug, PartialEq)]
struct Encoder8 {
    entries: Box<[u32; ENCODER8_PADDED]>,
}

/// The low bits of an f32 pattern inside its [`Encoder8`] bucket.
const ENCODER8_LOW: u32 = (1 << ENCODER8_SHIFT) - 1;
/// The shift of `from` in an [`Encoder8`] entry.
const ENCODER8_FROM_SHIFT: u32 = 8;

impl Encoder8 {
    fn build(scale: &LogScale) -> Self {
        assert_eq!(scale.encoder_shift, ENCODER8_SHIFT, "the 8-bit ROM's buckets");
        let max = u8::try_from(scale.one).expect("Q1 of 8 bits");
        // Per bucket: the pattern from which the code is `next`, and `next`.
        let (mut up_from, mut next) = (vec![u32::MAX; ENCODER8_ENTRIES], vec![1u8; ENCODER8_ENTRIES]);
        let base = scale.encoder_base as usize;
        for (i, &(up, q)) in scale.encoder.iter().enumerate() {
            (up_from[base + i], next[base + i]) = (up, u8::try_from(q).expect("an 8-bit code").wrapping_add(1));
        }
        let (one, infinity) = (1.0f32.to_bits(), f32::INFINITY.to_bits());
        debug_assert_eq!(base + scale.encoder.len(), (one >> ENCODER8_SHIFT) as usize, "the ROM ends at 1.0");
        let (one, inf) = ((one >> ENCODER8_SHIFT) as usize, (infinity >> ENCODER8_SHIFT) as usize);
        next[one..].fill(max.wrapping_add(1));
        up_from[inf] = infinity + 1;
        up_from[inf + 1..].fill(0);
        let mut entries = Box::new([0u32; ENCODER8_PADDED]);
        for (bucket, e) in entries[..ENCODER8_ENTRIES].iter_mut().enumerate() {
            // `bits < up_from` for the bucket's patterns as a threshold on their low bits.
            let start = i64::from((bucket as u32) << ENCODER8_SHIFT);
            let from = (i64::from(up_from[bucket]) - start).clamp(0, 1 << ENCODER8_SHIFT) as u32;
            *e = from << ENCODER8_FROM_SHIFT | u32::from(next[bucket]);
        }
        Self { entries }
    }

    /// The table by reference, for a loop to keep in a register.
    #[inline(always)]
    fn tables(&self) -> Encoder8Tables<'_> {
        Encoder8Tables { entries: &self.entries }
    }
}

/// [`Encoder8`]'s table as a loop reads it.
#[derive(Clone, Copy)]
struct Encoder8Tables<'a> {
    entries: &'a [u32; ENCODER8_PADDED],
}

impl Encoder8Tables<'_> {
    /// [`LogScale::encode`] for 8 bits.
    #[inline(always)]
    fn encode(self, c: f32) -> u8 {
        let bits = c.to_bits();
        let e = self.entries[(bits >> ENCODER8_SHIFT) as usize];
        (e as u8).wrapping_sub(u8::from(bits & ENCODER8_LOW < e >> ENCODER8_FROM_SHIFT))
    }
}

/// The linear fixed-point code of one bit count (module docs: "The linear code").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LinearScale {
    /// `M = 2^b - 1`, the code of 1.0.
    max: i32,
}

impl LinearScale {
    fn new(bits: u32) -> Self {
        Self { max: (1 << bits.clamp(VB_BITS_MIN, VB_BITS_MAX)) - 1 }
    }

    /// `round(c M)`, saturated (NaN to 0).
    #[inline]
    fn encode(self, c: f32) -> i32 {
        (c.clamp(0.0, 1.0) * self.max as f32 + HALF_CODE) as i32
    }

    /// The weighted fragment `round(q n / 16)`, half to even.
    #[inline]
    fn weigh(self, q: i32, n: u32) -> i32 {
        round_half_even(q * n as i32, AREA_DENOMINATOR.trailing_zeros())
    }

    /// Gamma table over F2 results in quarter codes, `0..=4 M`.
    fn gamma_table(self, gamma: f32) -> Vec<u8> {
        let inv_gamma = 1.0 / f64::from(gamma);
        let top = f64::from(self.max * FINE_PER_CODE);
        (0..=self.max * FINE_PER_CODE)
            .map(|i| (OUTPUT_MAX * (f64::from(i) / top).powf(inv_gamma)).round() as u8)
            .collect()
    }
}

/// An 8-bit RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` bytes, RGB.
    pub pixels: Vec<u8>,
}

impl Image {
    /// Encodes the image as PNG bytes.
    pub fn encode_png(&self) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            // Writing into a Vec cannot fail for a well-formed header and buffer.
            let mut w = enc.write_header().expect("PNG header into memory");
            w.write_image_data(&self.pixels).expect("PNG data into memory");
        }
        out
    }

    /// The RGB of pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
    }
}

/// Readout options (every [`VbMode`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Readout {
    /// Apply the 2 x 2 filter F2.
    pub filter: bool,
    /// Display gamma; 1 gives linear output.
    pub gamma: f32,
}

impl Default for Readout {
    fn default() -> Self {
        Self { filter: true, gamma: 2.2 }
    }
}

/// A readout of the 8-bit code in parts ([`VideoBuffer::log8_readout`]): whether F2
/// runs, and the gamma table (`log8_gamma_table`, 64 KiB) for the readout's gamma.
pub struct Log8Readout {
    filter: bool,
    table: Vec<u8>,
}

/// The video memory of one [`VbMode`].
#[derive(Clone, Debug)]
enum Memory {
    /// Linear `f32` RGB.
    Float(Vec<Vec3>),
    /// Three log codes per pixel (9 to 12 bits).
    Log { scale: &'static LogScale, codes: Vec<[u16; 3]> },
    /// P1's VMEM: three 8-bit log codes per pixel in one 24-bit word ([`Word8`]).
    Log8 { scale: &'static LogScale, codes: Vec<u32> },
    /// Three linear codes per pixel.
    Linear { scale: LinearScale, codes: Vec<[u16; 3]> },
}

/// A colour encoded for one [`VideoBuffer`]'s mode ([`VideoBuffer::prepare_flat`]):
/// its code word, and the colour itself for the modes that keep no code.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlatColor {
    color: Vec3,
    word: [u16; 3],
    /// `word` as the 8-bit code's VMEM word ([`Word8`]; 0 for other modes): a
    /// whole cell of it is filled without packing it again.
    word8: Word8,
}

/// The video memory: colour accumulators of every pixel, in one [`VbMode`].
#[derive(Clone, Debug)]
pub struct VideoBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    memory: Memory,
}

impl VideoBuffer {
    /// A cleared buffer storing colours as `mode` says (bit counts clamped to
    /// `VB_BITS_MIN..=VB_BITS_MAX`).
    pub fn new(width: u32, height: u32, mode: VbMode) -> Self {
        let n = width as usize * height as usize;
        let memory = match mode.clamped() {
            VbMode::Float => Memory::Float(vec![Vec3::ZERO; n]),
            VbMode::Log { bits: PAIR_MEANS_BITS } => {
                Memory::Log8 { scale: LogScale::get(PAIR_MEANS_BITS), codes: vec![0; n] }
            }
            VbMode::Log { bits } => Memory::Log { scale: LogScale::get(bits), codes: vec![[0; 3]; n] },
            VbMode::Linear { bits } => Memory::Linear { scale: LinearScale::new(bits), codes: vec![[0; 3]; n] },
        };
        Self { width, height, memory }
    }

    /// The mode (bit counts as clamped).
    pub fn mode(&self) -> VbMode {
        match &self.memory {
            Memory::Float(_) => VbMode::Float,
            Memory::Log { scale, .. } | Memory::Log8 { scale, .. } => VbMode::Log { bits: scale.bits },
            Memory::Linear { scale, .. } => VbMode::Linear { bits: (scale.max + 1).trailing_zeros() },
        }
    }

    /// Clears for a new frame (every mode's zero is all bits 0).
    pub fn clear(&mut self) {
        match &mut self.memory {
            Memory::Float(a) => a.fill(Vec3::ZERO),
            Memory::Log { codes, .. } | Memory::Linear { codes, .. } => codes.fill([0; 3]),
            Memory::Log8 { codes, .. } => codes.fill(0),
        }
    }

    /// Accumulates one cell's visible pixels with their colours (device F1): the
    /// first fragment of a pixel (`vis.first`) is written, later ones added. (The
    /// VB's writes are counted once per frame, by `VideoProcessor::run`.)
    pub fn accumulate(&mut self, vis: &Visible, colors: &CellColors) {
        let width = self.width as usize;
        match &mut self.memory {
            Memory::Float(accum) => for_visible(vis, width, |p, n, first, i| {
                let c = colors.pixel(i) * (n as f32 / AREA_DENOMINATOR as f32);
                let a = &mut accum[p];
                *a = if first { c } else { *a + c };
            }),
            Memory::Log { scale, codes } => {
                let f1 = LogF1::new(scale);
                accumulate_log::<_, true>(codes, width, vis, f1, |i| colors.pixel(i).to_array().map(|c| f1.encode(c)));
            }
            Memory::Log8 { codes, .. } => accumulate_log8(codes, width, vis, colors),
            Memory::Linear { scale, codes } => for_visible(vis, width, |p, n, first, i| {
                let c = colors.pixel(i).to_array();
                let word = &mut codes[p];
                for ch in 0..3 {
                    let v = scale.weigh(scale.encode(c[ch]), n);
                    let v = if first { v } else { (v + i32::from(word[ch])).min(scale.max) };
                    word[ch] = v as u16;
                }
            }),
        }
    }

    /// Asks the caches for the video memory under a small box of pixels
    /// (`[x0, x1, y0, y1]`, ends excluded, as [`super::bbox`] gives it) ahead of the
    /// polygon that will write there: a hint only, no result changes. A small
    /// polygon's pixels lie anywhere on the screen, so without it its first
    /// accumulation waits on memory (on `many`, three quarters of the 8-bit flat
    /// accumulation's samples sat on that load). Boxes wider than
    /// [`PREFETCH_BOX_WIDTH`] or taller than [`PREFETCH_BOX_ROWS`] are left to the
    /// processor's own prefetcher (a long polygon hides the wait in its own work).
    #[inline]
    pub fn prefetch_box(&self, [x0, x1, y0, y1]: [u32; 4]) {
        if x1 <= x0 || y1 <= y0 || x1 - x0 > PREFETCH_BOX_WIDTH || y1 - y0 > PREFETCH_BOX_ROWS {
            return;
        }
        let Memory::Log8 { codes, .. } = &self.memory else { return };
        use crate::hint::LINE;
        let width = self.width as usize;
        // The box's first row's first word, and the words from a row's first to its last.
        let mut first = codes.as_ptr().wrapping_add(y0 as usize * width + x0 as usize);
        let span = (x1 - x0 - 1) as usize;
        let line = |p: *const Word8| p as usize / LINE;
        if width.is_multiple_of(LINE / std::mem::size_of::<Word8>()) {
            // Rows a whole number of lines apart: every row of the box meets its
            // lines as the first does (`many`'s boxes, ~5 rows each: the row's
            // test once, not per row).
            let two = line(first) != line(first.wrapping_add(span));
            for _ in y0..y1 {
                crate::hint::prefetch(first.cast());
                if two {
                    crate::hint::prefetch(first.wrapping_add(span).cast());
                }
                first = first.wrapping_add(width);
            }
            return;
        }
        for _ in y0..y1 {
            // The row's first and last words: the box is at most two lines wide.
            let last = first.wrapping_add(span);
            crate::hint::prefetch(first.cast());
            if line(first) != line(last) {
                crate::hint::prefetch(last.cast());
            }
            first = first.wrapping_add(width);
        }
    }

    /// [`Self::accumulate`] of one colour for the whole cell (the background): the
    /// same values, with the colour encoded once rather than per pixel (the same
    /// as [`Self::accumulate_prepared`] of [`Self::prepare_flat`]; kept apart for
    /// the one-colour polygons: through those two, `many`'s colour + VB took 222.5
    /// M instructions at 480 x 270 rather than 210.2 M).
    pub fn accumulate_flat(&mut self, vis: &Visible, color: Vec3) {
        let width = self.width as usize;
        match &mut self.memory {
            Memory::Log { scale, codes } => {
                let f1 = LogF1::new(scale);
                let word = color.to_array().map(|c| f1.encode(c));
                accumulate_log_flat(codes, width, vis, f1, word);
            }
            Memory::Log8 { scale, codes } => {
                let encoder = scale.encoder8.as_ref().expect("the 8-bit encoder").tables();
                let word = color.to_array().map(|c| u16::from(encoder.encode(c)));
                accumulate_log8_flat(codes, width, vis, LogF1::new(scale), word);
            }
            Memory::Float(_) | Memory::Linear { .. } => self.accumulate(vis, &CellColors::splat(color)),
        }
    }

    /// `color` encoded for [`Self::accumulate_prepared`]: the VP encodes the
    /// background's colour once a frame rather than once per cell (default's
    /// colour + VB 145.6 -> 143.3 M instructions).
    ///
    /// Once a one-colour polygon too (at its first visible cell): the 8-bit code's
    /// word from the registers made once ([`F1Log8`]), the mode matched once.
    #[inline]
    pub fn prepare_flat(&self, color: Vec3) -> FlatColor {
        match &self.memory {
            Memory::Log8 { .. } => {
                let encoder = F1Log8::get().encoder;
                let word = color.to_array().map(|c| u16::from(encoder.encode(c)));
                FlatColor { color, word, word8: Word8::pack(word) }
            }
            Memory::Log { scale, .. } => {
                let f1 = LogF1::new(scale);
                FlatColor { color, word: color.to_array().map(|c| f1.encode(c)), word8: 0 }
            }
            Memory::Float(_) | Memory::Linear { .. } => FlatColor { color, word: [0; 3], word8: 0 },
        }
    }

    /// [`Self::accumulate_flat`] of a colour [`Self::prepare_flat`] encoded for this
    /// buffer. The common case, a whole cell of first fragments of the 8-bit code
    /// (the background behind everything), fills the cell's rows with the prepared
    /// word in this function's few instructions; any other cell goes to
    /// [`Self::accumulate_prepared_cell`], out of line, whose set-up (F1's registers,
    /// saved registers) the whole cells no longer pay (default: 55 364 calls, ~84
    /// instructions each before).
    pub fn accumulate_prepared(&mut self, vis: &Visible, flat: &FlatColor) {
        let width = self.width as usize;
        if let Memory::Log8 { codes, .. } = &mut self.memory {
            if vis.first == FULL && vis.sets == [FULL; 16] {
                // The cell's rows in one slice (one bounds check); its 16 pixels
                // are on the screen (pixels off it have no visible subpixel).
                let side = CELL_SIDE as usize;
                let start = vis.py as usize * width + vis.px as usize;
                let cell = &mut codes[start..start + (side - 1) * width + side];
                for row in 0..side {
                    cell[row * width..row * width + side].fill(flat.word8);
                }
                return;
            }
        }
        self.accumulate_prepared_cell(vis, flat);
    }

    /// [`Self::accumulate_prepared`] of each cell of each of `runs` in turn: the
    /// queued runs of one-colour polygons that follow one another, each run's cells
    /// with its colour [`Self::prepare_flat`] encoded once for the polygon. The
    /// memory's mode is matched and F1's registers are set up once for them all, not
    /// per cell (`many`'s triangles, of one or two visible cells each, ~1.4 cells a
    /// run: before, each cell paid the colour's encoding, the dispatch and F1's
    /// set-up, ~80 instructions of its ~270).
    #[inline]
    pub fn accumulate_prepared_runs<'c>(&mut self, runs: impl Iterator<Item = (&'c [Visible], FlatColor)>) {
        let width = self.width as usize;
        if let Memory::Log8 { scale, codes } = &mut self.memory {
            accumulate_log8_flat_runs(codes, width, runs, LogF1::new(scale));
            return;
        }
        for (cells, flat) in runs {
            for vis in cells {
                self.accumulate_prepared(vis, &flat);
            }
        }
    }

    /// [`Self::accumulate_prepared`] of any cell in any mode.
    #[inline(never)]
    fn accumulate_prepared_cell(&mut self, vis: &Visible, flat: &FlatColor) {
        let width = self.width as usize;
        match &mut self.memory {
            Memory::Log { scale, codes } => accumulate_log_flat(codes, width, vis, LogF1::new(scale), flat.word),
            Memory::Log8 { scale, codes } => accumulate_log8_flat(codes, width, vis, LogF1::new(scale), flat.word),
            Memory::Float(_) | Memory::Linear { .. } => self.accumulate(vis, &CellColors::splat(flat.color)),
        }
    }

    /// The accumulated linear colour of a pixel (decoded from the mode's codes).
    pub fn linear(&self, x: u32, y: u32) -> Vec3 {
        let p = y as usize * self.width as usize + x as usize;
        match &self.memory {
            Memory::Float(accum) => accum[p],
            Memory::Log { scale, codes } => Vec3::from_array(codes[p].map(|q| scale.value(q) as f32)),
            Memory::Log8 { scale, codes } => Vec3::from_array(codes[p].unpack().map(|q| scale.value(q) as f32)),
            Memory::Linear { scale, codes } => Vec3::from_array(codes[p].map(|q| f32::from(q) / scale.max as f32)),
        }
    }

    /// Reads the frame out through F2 and the gamma table.
    pub fn read_out(&self, opts: &Readout) -> Image {
        let mut image = Image { width: 0, height: 0, pixels: Vec::new() };
        self.read_out_into(opts, &mut image);
        image
    }

    /// [`Self::read_out`] into an image kept from frame to frame (its allocation
    /// reused: a display's frame store).
    pub fn read_out_into(&self, opts: &Readout, image: &mut Image) {
        image.width = self.width;
        image.height = self.height;
        // Every byte is written; `resize` only zeroes a first or larger frame.
        image.pixels.resize(self.width as usize * self.height as usize * 3, 0);
        self.read_out_rows(opts, 0..self.height as usize, &mut image.pixels);
    }

    /// Reads the frame out in bands of rows on the current rayon pool: the same
    /// bytes as [`Self::read_out`] (each output row depends only on its own row and
    /// the one below).
    pub fn read_out_parallel(&self, opts: &Readout) -> Image {
        let mut image = Image { width: 0, height: 0, pixels: Vec::new() };
        self.read_out_parallel_into(opts, &mut image);
        image
    }

    /// [`Self::read_out_parallel`] into an image kept from frame to frame (resized
    /// to this buffer; its allocation is reused: a display's frame store).
    pub fn read_out_parallel_into(&self, opts: &Readout, image: &mut Image) {
        use rayon::prelude::*;
        let (w, h) = (self.width as usize, self.height as usize);
        image.width = self.width;
        image.height = self.height;
        // Every byte is written below; `resize` only zeroes a first or larger frame.
        image.pixels.resize(w * h * 3, 0);
        let band = READOUT_BAND_ROWS;
        // One gamma table for all the bands.
        let table = self.gamma_table(opts);
        image.pixels.par_chunks_mut(band * w * 3).enumerate().for_each(|(k, out)| {
            let y0 = k * band;
            self.read_out_rows_with(opts, &table, y0..(y0 + band).min(h), out);
        });
    }

    /// Reads out the one interleaved image of a matrix's video memories (P3) into
    /// `image`, in bands of rows on the current rayon pool, reading each tile from the
    /// memory of the VP that owns it: the bytes of [`Self::copy_shares_from`] then
    /// [`Self::read_out_parallel_into`], without the copy (4 MiB a frame at 1920 x
    /// 1080). Only for the 8-bit log code with tiles of whole F2 runs, each tile
    /// owned by exactly one share, where it returns `true`;
    /// otherwise it does nothing and returns `false`. `parts`: the buffers (same
    /// size and mode) with their shares, of one tile side.
    pub fn read_out_shares_into(parts: &[(&VideoBuffer, &Share)], opts: &Readout, image: &mut Image) -> bool {
        use rayon::prelude::*;
        let Some(&(first, first_share)) = parts.first() else { return false };
        let tile = first_share.tile as usize;
        let (w, h) = (first.width as usize, first.height as usize);
        if !tile.is_power_of_two() || !tile.is_multiple_of(LOG8_RUN) || w == 0 || h == 0 {
            return false;
        }
        let mut memories = Vec::with_capacity(parts.len());
        for (vb, share) in parts {
            match &vb.memory {
                Memory::Log8 { codes, .. }
                    if (vb.width, vb.height) == (first.width, first.height) && share.tile == first_share.tile =>
                {
                    memories.push(codes.as_slice())
                }
                _ => return false,
            }
        }
        let Memory::Log8 { scale, .. } = &first.memory else { return false };
        // Per tile, the VP that owns it and the end of the run of tiles of the row
        // that VP owns from there (P3's interleave: the tile; a strip: the strip), looked
        // up once a frame: a segment then costs two shifts and a read.
        let shift = tile.trailing_zeros();
        let (tiles_w, tiles_h) = (w.div_ceil(tile), h.div_ceil(tile));
        let mut owner = vec![(u32::MAX, 0u32); tiles_w * tiles_h];
        for ty in 0..tiles_h {
            let row = &mut owner[ty * tiles_w..][..tiles_w];
            for (tx, o) in row.iter_mut().enumerate() {
                let (x, y) = ((tx * tile) as u32, (ty * tile) as u32);
                let mut owners = parts.iter().enumerate().filter(|(_, (_, share))| share.owns_pixel(x, y));
                match (owners.next(), owners.next()) {
                    (Some((k, _)), None) => o.0 = k as u32,
                    _ => return false,
                }
            }
            let mut end = tiles_w;
            for tx in (0..tiles_w).rev() {
                if tx + 1 < tiles_w && row[tx + 1].0 != row[tx].0 {
                    end = tx + 1;
                }
                row[tx].1 = ((end * tile).min(w)) as u32;
            }
        }
        // Pixels `x0..` of row `y` to the end of their VP's run of tiles.
        let segment = |y: usize, x0: usize| {
            let (k, end) = owner[(y >> shift) * tiles_w + (x0 >> shift)];
            &memories[k as usize][y * w + x0..y * w + end as usize]
        };
        let pairs = scale.pair_means.as_ref().expect("the 8-bit scale has the pair table");
        let table = first.gamma_table(opts);
        let table: &[u8; LOG8_ADDRESSES] = table.as_slice().try_into().expect("the 8-bit gamma table");
        image.width = first.width;
        image.height = first.height;
        // Every byte is written below; `resize` only zeroes a first or larger frame.
        image.pixels.resize(w * h * 3, 0);
        let band = READOUT_BAND_ROWS;
        image.pixels.par_chunks_mut(band * w * 3).enumerate().for_each(|(k, out)| {
            let y0 = k * band;
            let rows = y0..(y0 + band).min(h);
            read_out_log8_from(w, h, &segment, opts.filter, pairs, table, rows.clone(), out_rows(w, &rows, out));
        });
        true
    }

    /// The 8-bit code's readout of a frame in parts, a strip matrix's VPs' strips
    /// ([`Self::read_out_strip`], [`Self::read_out_strip_borders`]): `opts` with its
    /// gamma table, made once for all the parts. `None` for the other modes.
    pub fn log8_readout(&self, opts: &Readout) -> Option<Log8Readout> {
        matches!(self.memory, Memory::Log8 { .. })
            .then(|| Log8Readout { filter: opts.filter, table: self.gamma_table(opts) })
    }

    /// Reads out pixel columns `x0..x1` of rows `rows` (a strip matrix's VP's strip,
    /// P1's 8-bit code, `ro` from [`Self::log8_readout`]) into `out`, one slice a
    /// row, top to bottom, each the row's bytes `3 x0 .. 3 x1`. The strip is read as
    /// an image of its own, from this memory alone: every byte is the whole image's
    /// ([`Self::read_out`]'s) but column `x1 - 1`'s when `x1` is not the screen's
    /// right edge, whose F2 needs column `x1` of the next strip's memory (its own
    /// value stands in here; [`Self::read_out_strip_borders`] writes the byte).
    ///
    /// Why: a matrix's VP reads its strip out as its render ends, on its own thread,
    /// from the memory that thread just wrote, rather than every thread reading bands
    /// of rows of every VP's memory after all have finished ([`crate::matrix`]).
    /// Panics on a buffer of another mode.
    pub fn read_out_strip<'o>(
        &self,
        ro: &Log8Readout,
        (x0, x1): (u32, u32),
        rows: std::ops::Range<usize>,
        out: impl Iterator<Item = &'o mut [u8]>,
    ) {
        let Memory::Log8 { scale, codes } = &self.memory else { panic!("a strip's readout of the 8-bit code only") };
        let (w, h) = (self.width as usize, self.height as usize);
        let (x0, x1) = (x0 as usize, (x1 as usize).min(w));
        if x0 >= x1 || h == 0 {
            return;
        }
        let pairs = scale.pair_means.as_ref().expect("the 8-bit scale has the pair table");
        let table: &[u8; LOG8_ADDRESSES] = ro.table.as_slice().try_into().expect("the 8-bit gamma table");
        let segment = |y: usize, x: usize| &codes[y * w + x0 + x..y * w + x1];
        read_out_log8_from(x1 - x0, h, &segment, ro.filter, pairs, table, rows.start..rows.end.min(h), out);
    }

    /// The bytes a strip matrix's readout by strips ([`Self::read_out_strip`]) leaves
    /// to be written: with F2, column `x - 1` of every row where one strip ends and
    /// the next non-empty one starts at `x`, from the two memories, into `image`
    /// (of the buffers' size). `strips`: each VP's buffer (P1's 8-bit code, all of
    /// one size) and its strip, left to right, the strips tiling the columns.
    pub fn read_out_strip_borders(strips: &[(&VideoBuffer, (u32, u32))], ro: &Log8Readout, image: &mut Image) {
        let Some(&(first, _)) = strips.first() else { return };
        let Memory::Log8 { scale, .. } = &first.memory else { panic!("a strip's readout of the 8-bit code only") };
        if !ro.filter {
            return;
        }
        let (w, h) = (first.width as usize, first.height as usize);
        assert_eq!(image.pixels.len(), 3 * w * h, "an image of the buffers' size");
        let pairs = scale.pair_means.as_ref().expect("the 8-bit scale has the pair table");
        let table: &[u8; LOG8_ADDRESSES] = ro.table.as_slice().try_into().expect("the 8-bit gamma table");
        // The last non-empty strip's memory and its end.
        let mut left: Option<(&[Word8], usize)> = None;
        for &(vb, (x0, x1)) in strips {
            let Memory::Log8 { codes, .. } = &vb.memory else { panic!("a strip's readout of the 8-bit code only") };
            assert_eq!((vb.width, vb.height), (first.width, first.height), "video buffers of different sizes");
            let (x0, x1) = (x0 as usize, (x1 as usize).min(w));
            if x0 >= x1 {
                continue;
            }
            if let Some((left, x)) = left {
                assert_eq!(x, x0, "strips that tile the columns");
                for y in 0..h {
                    let below = (y + 1).min(h - 1);
                    // The line buffer's two values (F2's first pass) and their mean.
                    let a = pairs.mean_words(left[y * w + x - 1], left[below * w + x - 1]);
                    let b = pairs.mean_words(codes[y * w + x], codes[below * w + x]);
                    image.pixels[3 * (y * w + x - 1)..][..3].copy_from_slice(&pairs.output(a, b, table));
                }
            }
            left = Some((codes, x1));
        }
    }

    /// Reads out rows `rows` (F2 uses the row below the last one) into `out`, RGB8,
    /// `3 * width * rows.len()` bytes.
    pub fn read_out_rows(&self, opts: &Readout, rows: std::ops::Range<usize>, out: &mut [u8]) {
        self.read_out_rows_with(opts, &self.gamma_table(opts), rows, out);
    }

    /// The mode's gamma table for `opts` (the fixed-point ones padded to
    /// [`GAMMA_PADDED`] entries, the 8-bit log code's to [`LOG8_ADDRESSES`]:
    /// [`log8_gamma_table`]).
    fn gamma_table(&self, opts: &Readout) -> Vec<u8> {
        match &self.memory {
            Memory::Float(_) => gamma_table(opts.gamma),
            Memory::Log { scale, .. } => padded(scale.gamma_table(opts.gamma)),
            Memory::Log8 { scale, .. } => log8_gamma_table(&scale.gamma_table(opts.gamma), scale.ln2),
            Memory::Linear { scale, .. } => padded(scale.gamma_table(opts.gamma)),
        }
    }

    /// [`Self::read_out_rows`] with the table of [`Self::gamma_table`].
    fn read_out_rows_with(&self, opts: &Readout, table: &[u8], rows: std::ops::Range<usize>, out: &mut [u8]) {
        let (w, h) = (self.width as usize, self.height as usize);
        match &self.memory {
            Memory::Float(accum) => read_out_float(w, h, accum, opts, table, rows, out),
            Memory::Log { scale, codes } => {
                let table = table.try_into().expect("a padded gamma table");
                read_out_fine(w, h, codes, opts.filter, LogArith::new(scale), table, rows, out)
            }
            Memory::Log8 { scale, codes } => {
                let table = table.try_into().expect("the 8-bit gamma table");
                let pairs = scale.pair_means.as_ref().expect("the 8-bit scale has the pair table");
                read_out_log8(w, h, codes, opts.filter, pairs, table, rows, out)
            }
            Memory::Linear { scale, codes } => {
                let table = table.try_into().expect("a padded gamma table");
                read_out_fine(w, h, codes, opts.filter, *scale, table, rows, out)
            }
        }
    }

    /// Copies the pixels of matrix VPs' shares from their buffers, of the same size and
    /// mode (P3: the video memories of a VP matrix together form one interleaved
    /// image), a tile run at a time, in bands of rows on the current rayon pool. The
    /// shares do not overlap. Panics on a buffer of another size or mode.
    pub fn copy_shares_from(&mut self, others: &[(&VideoBuffer, &Share)]) {
        for (other, _) in others {
            assert_eq!(
                (self.width, self.height, self.mode()),
                (other.width, other.height, other.mode()),
                "video buffers of different sizes or modes"
            );
        }
        let w = self.width as usize;
        match &mut self.memory {
            Memory::Float(dst) => {
                let srcs: Vec<(&[Vec3], &Share)> = others
                    .iter()
                    .map(|(o, share)| match &o.memory {
                        Memory::Float(src) => (src.as_slice(), *share),
                        _ => unreachable!("the modes were compared above"),
                    })
                    .collect();
                copy_shares_parallel(dst, &srcs, w);
            }
            Memory::Log { codes: dst, .. } | Memory::Linear { codes: dst, .. } => {
                let srcs: Vec<(&[[u16; 3]], &Share)> = others
                    .iter()
                    .map(|(o, share)| match &o.memory {
                        Memory::Log { codes: src, .. } | Memory::Linear { codes: src, .. } => (src.as_slice(), *share),
                        _ => unreachable!("the modes were compared above"),
                    })
                    .collect();
                copy_shares_parallel(dst, &srcs, w);
            }
            Memory::Log8 { codes: dst, .. } => {
                let srcs: Vec<(&[u32], &Share)> = others
                    .iter()
                    .map(|(o, share)| match &o.memory {
                        Memory::Log8 { codes: src, .. } => (src.as_slice(), *share),
                        _ => unreachable!("the modes were compared above"),
                    })
                    .collect();
                copy_shares_parallel(dst, &srcs, w);
            }
        }
    }

    /// Copies the pixels `(x, y)` for which `owns(x, y)` holds from a buffer of the
    /// same size and mode. Panics on a buffer of another size or mode.
    pub fn copy_from(&mut self, other: &VideoBuffer, owns: impl Fn(u32, u32) -> bool) {
        assert_eq!(
            (self.width, self.height, self.mode()),
            (other.width, other.height, other.mode()),
            "video buffers of different sizes or modes"
        );
        let width = self.width;
        match (&mut self.memory, &other.memory) {
            (Memory::Float(dst), Memory::Float(src)) => copy_owned(dst, src, width, &owns),
            (Memory::Log { codes: dst, .. }, Memory::Log { codes: src, .. })
            | (Memory::Linear { codes: dst, .. }, Memory::Linear { codes: src, .. }) => {
                copy_owned(dst, src, width, &owns)
            }
            (Memory::Log8 { codes: dst, .. }, Memory::Log8 { codes: src, .. }) => copy_owned(dst, src, width, &owns),
            _ => unreachable!("the modes were compared above"),
        }
    }

    /// Cells per row and rows of 4x4 cells covering the buffer.
    pub fn cells(&self) -> (usize, usize) {
        (self.width.div_ceil(CELL_SIDE) as usize, self.height.div_ceil(CELL_SIDE) as usize)
    }
}

/// F1 of the log code as its loop runs it: the encoder ROM, the `ln S` table and
/// [`LogArith`] in locals.
#[derive(Clone, Copy)]
struct LogF1<'a> {
    arith: LogArith<'a>,
    /// The encoder ROM ([`LogScale::encoder_table`]), its address shift and base.
    encoder: &'a [(u32, u16)],
    shift: u32,
    base: u32,
    /// `round(4 K ln(n / 16))`, index `n - 1`.
    ln_area: &'a [i32; AREA_DENOMINATOR as usize],
}

impl<'a> LogF1<'a> {
    fn new(scale: &'a LogScale) -> Self {
        Self {
            arith: LogArith::new(scale),
            encoder: &scale.encoder,
            shift: scale.encoder_shift,
            base: scale.encoder_base,
            ln_area: &scale.ln_area,
        }
    }

    /// [`LogScale::encode`].
    #[inline(always)]
    fn encode(self, c: f32) -> u16 {
        if c >= 1.0 {
            return self.arith.one as u16;
        }
        let bits = c.to_bits();
        let address = (bits >> self.shift).wrapping_sub(self.base) as usize;
        match self.encoder.get(address) {
            Some(&(up_from, q)) => q + u16::from(bits >= up_from),
            None => 0,
        }
    }
}

/// The bits of one row of a cell in its 16-bit masks (`first`, pixel `4 y + x`).
const ROW_BITS: u16 = (1 << CELL_SIDE) - 1;

/// F1 on the log code for one cell: pixel `i` (`4 y + x`) of the cell brings the
/// code word `word(i)` (called only for visible pixels). A whole pixel's first
/// fragment stores its word (eq. 3 adds `ln 1 = 0`, and the store of a whole code is
/// the code); a partial one adds `ln S` (eq. 3); a later one is summed with the
/// stored word (eq. 4). `ROW_STORES`: a row of four whole first fragments is stored
/// without the tests per pixel (city's colour + VB 265 -> 239 M instructions); not
/// for one word over the cell, whose whole cells are filled before and whose other
/// rows are mostly partial (many's small triangles: the test costs 3 %).
#[inline(always)]
fn accumulate_log<W: LogWord, const ROW_STORES: bool>(
    codes: &mut [W],
    width: usize,
    vis: &Visible,
    f1: LogF1,
    word: impl Fn(usize) -> [u16; 3],
) {
    let (px, py) = (vis.px as usize, vis.py as usize);
    for row in 0..CELL_SIDE as usize {
        let sets = &vis.sets[4 * row..4 * row + 4];
        if sets == [0; 4] {
            continue;
        }
        // Pixels beyond the screen's right edge have no visible subpixel.
        let start = (py + row) * width + px;
        if ROW_STORES && sets == [FULL; 4] && (vis.first >> (4 * row)) & ROW_BITS == ROW_BITS {
            // A row of whole first fragments (a polygon's inside): four stores,
            // without the tests per pixel.
            for (x, w) in codes[start..start + CELL_SIDE as usize].iter_mut().enumerate() {
                *w = W::pack(word(4 * row + x));
            }
            continue;
        }
        let words = &mut codes[start..start + (width - px).min(CELL_SIDE as usize)];
        for (x, w) in words.iter_mut().enumerate() {
            let (i, set) = (4 * row + x, sets[x]);
            if set == 0 {
                continue;
            }
            let (n, first) = (set.count_ones(), vis.first >> i & 1 == 1);
            let q = word(i);
            if first && n == AREA_DENOMINATOR {
                *w = W::pack(q);
                continue;
            }
            let ln_s = f1.ln_area[(n as usize - 1) & (AREA_DENOMINATOR as usize - 1)];
            let mut stored = w.unpack();
            for (s, q) in stored.iter_mut().zip(q) {
                let v = LogFine::from_code(q).0 + ln_s;
                let v = if first { v } else { f1.arith.sum(v, LogFine::from_code(*s).0) };
                *s = f1.arith.store(v);
            }
            *w = W::pack(stored);
        }
    }
}

/// [`accumulate_log`] of one code word for the whole cell. A whole cell's first
/// fragments (a large polygon's inside, the open sky) fill its rows with the word.
/// (Its 16 pixels are then on the screen: pixels off it have no visible subpixel.)
#[inline(always)]
fn accumulate_log_flat<W: LogWord>(codes: &mut [W], width: usize, vis: &Visible, f1: LogF1, word: [u16; 3]) {
    if vis.first == FULL && vis.sets == [FULL; 16] {
        let (side, packed) = (CELL_SIDE as usize, W::pack(word));
        // The cell's rows in one slice (one bounds check).
        let start = vis.py as usize * width + vis.px as usize;
        let cell = &mut codes[start..start + (side - 1) * width + side];
        for row in 0..side {
            cell[row * width..row * width + side].fill(packed);
        }
        return;
    }
    accumulate_log::<_, false>(codes, width, vis, f1, |_| word);
}

/// [`accumulate_log_flat`] of the 8-bit code: a cell of whole first fragments
/// filled with the word, any other pixel by pixel in SSE4.1 lanes
/// ([`accumulate_log8_flat_sse41`]) where the build has it (x86-64-v2), else by the
/// portable [`accumulate_log`].
#[inline(always)]
fn accumulate_log8_flat(codes: &mut [Word8], width: usize, vis: &Visible, f1: LogF1, word: [u16; 3]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    if !(vis.first == FULL && vis.sets == [FULL; 16]) {
        // SAFETY: `accumulate_log8_flat_sse41` needs SSE4.1, which the build enables
        // for every function (this branch is compiled only then).
        #[allow(unsafe_code, reason = "a function compiled for SSE4.1 in a build that requires it")]
        unsafe {
            let cell = (std::slice::from_ref(vis), Word8::pack(word));
            return accumulate_log8_flat_sse41(codes, width, std::iter::once(cell), &f1);
        }
    }
    accumulate_log_flat(codes, width, vis, f1, word);
}

/// [`accumulate_log8_flat`] of the cells of each run in turn, its colour encoded
/// beforehand ([`VideoBuffer::accumulate_prepared_runs`]): in one call of the
/// SSE4.1 copy where the build has it, else cell by cell.
#[inline(always)]
fn accumulate_log8_flat_runs<'c>(
    codes: &mut [Word8],
    width: usize,
    runs: impl Iterator<Item = (&'c [Visible], FlatColor)>,
    f1: LogF1,
) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    {
        // SAFETY: `accumulate_log8_flat_sse41` needs SSE4.1, which the build enables
        // for every function (this block is compiled only then).
        #[allow(unsafe_code, reason = "a function compiled for SSE4.1 in a build that requires it")]
        unsafe {
            accumulate_log8_flat_sse41(codes, width, runs.map(|(cells, flat)| (cells, flat.word8)), &f1);
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    for (cells, flat) in runs {
        for vis in cells {
            accumulate_log_flat(codes, width, vis, f1, flat.word);
        }
    }
}

/// [`accumulate_log`] of each run's word for each of its cells in turn (the
/// queued runs of one-colour polygons, or one cell), the constants set up once: a whole cell of first
/// fragments filled with the word, any other cell's visible pixels one by
/// one (by their bits), each pixel's three components side by side in the 32-bit
/// lanes of one SSE register: `from_code` of the word once for the cell; per
/// pixel, `ln S` added, and for a later fragment eq. 4 with the stored word (`T` read
/// at the three lanes' differences one by one), then `store` and the three low
/// bytes packed into the word (the fourth lane, 0 in both words, stores 0). A
/// whole first fragment stores the word as it is. The same operations on the same
/// integers as the portable path, so the same words (tested against it). For a
/// one-colour polygon's cells that are not whole first fragments: `many`'s
/// triangles, of two or three visible pixels a cell, where the portable path spent
/// ~175 instructions a pixel, each component's steps apart and a test per pixel of
/// the cell; F1 of the whole cell in AVX2 lanes ([`f1_cell16_avx2`]) costs more than
/// that for so few pixels (~340 a cell).
#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
#[target_feature(enable = "sse4.1")]
#[inline]
fn accumulate_log8_flat_sse41<'c>(
    codes: &mut [Word8],
    width: usize,
    runs: impl Iterator<Item = (&'c [Visible], Word8)>,
    f1: &LogF1,
) {
    let arith = f1.arith;
    // Bytes 0, 4 and 8 (the lanes' low bytes, the codes) to bytes 0, 1, 2; byte 3 zero.
    const NONE: i8 = -1;
    let to_word = _mm_setr_epi8(0, 4, 8, NONE, NONE, NONE, NONE, NONE, NONE, NONE, NONE, NONE, NONE, NONE, NONE, NONE);
    let zero_fine = _mm_set1_epi32(LogFine::ZERO.0);
    // `LogFine::from_code` of the four lanes.
    let from_code = |q: __m128i| {
        _mm_blendv_epi8(
            _mm_slli_epi32::<{ LOG_FRAC_BITS as i32 }>(q),
            zero_fine,
            _mm_cmpeq_epi32(q, _mm_setzero_si128()),
        )
    };
    let (round, one, below) =
        (_mm_set1_epi32(FINE_PER_CODE / 2 - 1), _mm_set1_epi32(arith.one), _mm_set1_epi32(arith.floor - 1));
    let cap = _mm_set1_epi32(SOFTPLUS_PADDED as i32 - 1);
    for (cells, word) in runs {
        let new = from_code(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(word as i32)));
        for vis in cells {
            if vis.first == FULL && vis.sets == [FULL; 16] {
                // A whole cell of first fragments: its rows filled with the word, in one
                // slice (one bounds check); its 16 pixels are on the screen.
                let side = CELL_SIDE as usize;
                let start = vis.py as usize * width + vis.px as usize;
                let cell = &mut codes[start..start + (side - 1) * width + side];
                for row in 0..side {
                    cell[row * width..row * width + side].fill(word);
                }
                continue;
            }
            let mut pixels = visible_pixels(vis);
            while pixels != 0 {
                let i = pixels.trailing_zeros() as usize;
                pixels &= pixels - 1;
                let (set, first) = (vis.sets[i], vis.first >> i & 1 == 1);
                // (A visible pixel is on the screen.)
                // (The pixel's word found once, one bounds test.)
                let slot = &mut codes[(vis.py as usize + i / 4) * width + vis.px as usize + i % 4];
                let n = set.count_ones();
                if first && n == AREA_DENOMINATOR {
                    *slot = word;
                    continue;
                }
                let ln_s = f1.ln_area[(n as usize - 1) & (AREA_DENOMINATOR as usize - 1)];
                let mut v = _mm_add_epi32(new, _mm_set1_epi32(ln_s));
                if !first {
                    let stored = from_code(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(*slot as i32)));
                    let (hi, lo) = (_mm_max_epi32(v, stored), _mm_min_epi32(v, stored));
                    let d = _mm_min_epi32(_mm_sub_epi32(hi, lo), cap);
                    // `T[d]` of each component's lane (`d` in `0..SOFTPLUS_PADDED` after the
                    // clamp); the fourth lane, whose byte the word leaves out, read not at all.
                    let t = |k: i32| i32::from(arith.softplus[k as usize & (SOFTPLUS_PADDED - 1)]);
                    let t = _mm_setr_epi32(
                        t(_mm_extract_epi32::<0>(d)),
                        t(_mm_extract_epi32::<1>(d)),
                        t(_mm_extract_epi32::<2>(d)),
                        0,
                    );
                    v = _mm_add_epi32(hi, t);
                }
                // `LogArith::store`.
                let odd = _mm_and_si128(_mm_srai_epi32::<{ LOG_FRAC_BITS as i32 }>(v), _mm_set1_epi32(1));
                let rounded = _mm_srai_epi32::<{ LOG_FRAC_BITS as i32 }>(_mm_add_epi32(_mm_add_epi32(v, round), odd));
                let code = _mm_min_epi32(_mm_max_epi32(rounded, _mm_set1_epi32(1)), one);
                let code = _mm_and_si128(code, _mm_cmpgt_epi32(v, below));
                *slot = _mm_cvtsi128_si32(_mm_shuffle_epi8(code, to_word)) as u32;
            }
        }
    }
}

/// The pixels of a cell with a visible subpixel, bit `4 y + x`:
/// [`crate::model::stats::visible_pixels`] in the build's SSE lanes (the colour
/// computers' copy, `cc::visible_avx2`, needs AVX2; this one runs in the baseline
/// F1 of one-colour cells).
#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
#[inline(always)]
fn visible_pixels(vis: &Visible) -> u32 {
    // SAFETY: the build has SSE2 (x86-64's baseline); `vis.sets` is 16 `u16`, the 32
    // bytes the loads read.
    #[allow(unsafe_code, reason = "unaligned loads of an array of two registers' size")]
    unsafe {
        let w = vis.sets.as_ptr().cast::<__m128i>();
        let zero = _mm_setzero_si128();
        let (lo, hi) = (_mm_cmpeq_epi16(_mm_loadu_si128(w), zero), _mm_cmpeq_epi16(_mm_loadu_si128(w.add(1)), zero));
        !(_mm_movemask_epi8(_mm_packs_epi16(lo, hi)) as u32) & 0xFFFF
    }
}

/// F1 of the 8-bit code for one cell of shaded colours ([`accumulate_log`] of
/// [`Word8`] with [`Encoder8`]) by the best copy the processor runs: the portable
/// one, or the explicit AVX2 copy, which encodes half a cell's 24 components in
/// lanes and runs eq. 3 and 4 in lanes (P1's F1 for the pixels side by side). The
/// same operations on the same integers, so the same words; the tests compare every
/// copy the processor can run with the portable one.
///
/// Measured on Zen 4 (1920 x 1080, one thread, medians of 9 frames, alternating
/// binaries): the AVX2 copy takes city's colour + VB from 11.7 to 11.1 ms, default's
/// from 17.9 to 17.1 ms. An AVX-512 copy (the whole cell as 16 lanes, masked row
/// loads and stores) was slower than either, 13.0 and 19.0 ms, with the ROM read by
/// gathers or by windows of 16 or 32 entries alike: not kept. The ROM read by
/// gathers alone (no window) left the AVX2 copy no faster than the portable one:
/// Zen 4's gathers cost about as much as the scalar loads they replace (valgrind
/// counts a gather as one instruction: it showed city's colour + VB 148 -> 119 M).
#[inline]
fn accumulate_log8(codes: &mut [Word8], width: usize, vis: &Visible, colors: &CellColors) {
    let regs = F1Log8::get();
    let (f1, encoder) = (&regs.f1, &regs.encoder);
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: `accumulate_log8_avx2` only needs AVX2, which the processor was
        // just found to have.
        #[allow(unsafe_code, reason = "the one call of a function compiled for AVX2, after detection")]
        unsafe {
            return accumulate_log8_avx2::<{ F1_ALONE }>(codes, width, vis, colors, f1, *encoder, &regs.ln_area);
        }
    }
    accumulate_log8_portable(codes, width, vis, colors, *f1, *encoder)
}

/// The 8-bit code's F1 registers ([`LogF1`], [`Encoder8Tables`]) made once: a cell's
/// F1 then starts from one pointer, not from the scale's fields copied per call
/// (default: ~20 instructions a cell of ~520).
struct F1Log8 {
    f1: LogF1<'static>,
    encoder: Encoder8Tables<'static>,
    /// The `ln S` table as [`ln_area16_avx2`] reads it.
    #[cfg(target_arch = "x86_64")]
    ln_area: LnArea16,
}

impl F1Log8 {
    /// The 8-bit scale's registers.
    #[inline]
    fn get() -> &'static Self {
        static F1: OnceLock<F1Log8> = OnceLock::new();
        F1.get_or_init(|| {
            let scale = LogScale::get(PAIR_MEANS_BITS);
            // The bounds [`F1_ZERO16`] is chosen for: `T[0]` and the table's end.
            #[cfg(target_arch = "x86_64")]
            assert!(scale.ln2 <= 118 && scale.softplus_table().len() <= 988, "the 8-bit ln(1 + e^x) table");
            // [`store16_avx2`]'s constants.
            #[cfg(target_arch = "x86_64")]
            assert!(
                scale.one == LOG8_ONE16.into() && FINE_PER_CODE - scale.ln2 == LOG8_FLOOR16.into(),
                "the 8-bit scale's Q1 and floor"
            );
            Self {
                f1: LogF1::new(scale),
                encoder: scale.encoder8.as_ref().expect("the 8-bit encoder").tables(),
                #[cfg(target_arch = "x86_64")]
                ln_area: LnArea16::new(&scale.ln_area),
            }
        })
    }
}

/// F1 of the 8-bit code for the AVX2 colour computers to run inside their own
/// function ([`super::cc::ColorComputers::shade_accumulate`]): the cell's colours go
/// from the CC's registers to F1's through [`CellColors`] in one function, with
/// neither a call nor F1's set-up per cell (default: ~90 instructions a cell of
/// dispatch, arguments and saved registers).
#[cfg(target_arch = "x86_64")]
pub(crate) struct F1Avx2<'a> {
    codes: &'a mut [Word8],
    width: usize,
    regs: &'static F1Log8,
}

#[cfg(target_arch = "x86_64")]
impl F1Avx2<'_> {
    /// This F1's registers for a run of cells ([`F1Registers`]).
    #[inline(always)]
    pub(crate) fn registers(&mut self) -> F1Registers<'_> {
        let regs = self.regs;
        F1Registers {
            codes: &mut *self.codes,
            width: self.width,
            f1: regs.f1,
            encoder: regs.encoder,
            ln_area: &regs.ln_area,
        }
    }
}

/// [`F1Avx2`]'s registers read out of the VB and the 8-bit scale's [`F1Log8`] once
/// for a run of cells, as a local of the colour computers' function
/// ([`super::cc::ColorComputers::shade_accumulate`]): the VMEM's pointer, length and
/// width, the encoder ROM's and the `ln(1 + e^x)` table's pointers stay in registers
/// or the function's frame over the run, where read through [`F1Avx2`]'s pointers
/// they were loaded again for every cell (the stores to VMEM between them) and two
/// of them spilled again (terrain: ~7 instructions a cell).
#[cfg(target_arch = "x86_64")]
pub(crate) struct F1Registers<'a> {
    codes: &'a mut [Word8],
    width: usize,
    f1: LogF1<'static>,
    encoder: Encoder8Tables<'static>,
    ln_area: &'static LnArea16,
}

#[cfg(target_arch = "x86_64")]
impl F1Registers<'_> {
    /// [`VideoBuffer::accumulate`] of one cell, in [`accumulate_log8_avx2`]. `SITE`
    /// tells the copies of the colour computers' function apart (one a copy, so
    /// that each is inlined into its one caller).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn accumulate<const SITE: bool>(&mut self, vis: &Visible, colors: &CellColors) {
        let (codes, width) = (&mut *self.codes, self.width);
        let (f1, encoder, ln_area) = (&self.f1, self.encoder, self.ln_area);
        // (Stable Rust takes no `if` as a const argument: one call a site.)
        if SITE {
            accumulate_log8_avx2::<{ F1_FUSED_TEXTURED }>(codes, width, vis, colors, f1, encoder, ln_area);
        } else {
            accumulate_log8_avx2::<{ F1_FUSED }>(codes, width, vis, colors, f1, encoder, ln_area);
        }
    }
}

/// That the VB's F1 can run inside the AVX2 colour computers ([`F1Avx2`]), found
/// once a frame ([`VideoBuffer::fused_f1`]) rather than per cell (the processor's
/// features and the 8-bit scale's registers looked up again for every cell had cost
/// ~20 instructions a cell), with the 8-bit scale's registers.
#[derive(Clone, Copy)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code, reason = "made only on x86-64"))]
pub struct FusedF1 {
    #[cfg(target_arch = "x86_64")]
    regs: &'static F1Log8,
}

impl VideoBuffer {
    /// [`FusedF1`] when the VB holds the 8-bit code and the processor has AVX2, unless
    /// the AVX-512 colour computers run ([`crate::isa`]: they hand their cells to
    /// [`Self::accumulate`]).
    #[inline]
    pub fn fused_f1(&self) -> Option<FusedF1> {
        #[cfg(target_arch = "x86_64")]
        if matches!(self.memory, Memory::Log8 { .. })
            && std::is_x86_feature_detected!("avx2")
            && !crate::isa::avx512_copies()
        {
            return Some(FusedF1 { regs: F1Log8::get() });
        }
        None
    }

    /// The VB's F1 for the AVX2 colour computers ([`F1Avx2`]), found possible by
    /// [`Self::fused_f1`] (the same words as [`Self::accumulate`]); `None` if the VB
    /// no longer holds the 8-bit code.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    pub(crate) fn f1_avx2(&mut self, fused: FusedF1) -> Option<F1Avx2<'_>> {
        let width = self.width as usize;
        match &mut self.memory {
            Memory::Log8 { codes, .. } => Some(F1Avx2 { codes, width, regs: fused.regs }),
            _ => None,
        }
    }
}

/// [`accumulate_log8`] for the build's target, whatever the processor.
fn accumulate_log8_portable(
    codes: &mut [Word8],
    width: usize,
    vis: &Visible,
    colors: &CellColors,
    f1: LogF1,
    encoder: Encoder8Tables,
) {
    let word = |i: usize| colors.pixel(i).to_array().map(|c| u16::from(encoder.encode(c)));
    accumulate_log::<_, true>(codes, width, vis, f1, word);
}

/// The largest index of the padded `ln(1 + e^x)` table a lane reads: its gathers read
/// 4 bytes (two entries) at an entry's address, so they stop one entry short of the
/// end; the entries there are zeros past the 8-bit table's end (988 entries), as
/// `T[d]` is for every larger `d`.
#[cfg(target_arch = "x86_64")]
const SOFTPLUS_LANE_MAX: i32 = SOFTPLUS_PADDED as i32 - 2;

/// [`accumulate_log8`] in explicit AVX2: half a cell (two rows, 8 pixels) per group
/// of lanes. The cell's masks (visible, whole) from one compare of its 16 sets each,
/// and its rows down to the last visible one as one slice (one bounds check). Per
/// half with a visible pixel: the three components' codes ([`encode8_rgb_avx2`]: the
/// encoder ROM's entries by windows of the table placed at the first visible pixel,
/// near colours being the common case); then unless every visible pixel of the half
/// is a whole first fragment (stored as its codes, as [`accumulate_log`] does), eq.
/// 3 and 4 in lanes, with the cell's `ln S` found once in 16-bit lanes
/// ([`ln_area16_avx2`]): when both halves run them, the whole cell's in 16-bit lanes
/// ([`f1_cell16_avx2`]), else the half's, its words split into two registers of
/// 16-bit lanes ([`f1_half_avx2`]). Rows of the half are stored whole, or their visible pixels
/// by a masked store. Each step of each half is its own copy of the code.
///
/// Measured (callgrind, default at 1920 x 1080, one thread): the windows placed at a
/// pixel rather than at the least address over the lanes (a reduction and a test
/// per component: ~31 instructions a component) took colour + VB from 166.1 to
/// 157.7 M instructions (F1 had been ~465 instructions a cell); inside the CC's
/// function ([`F1Avx2`]), 154.3 M. The cell's masks and bounds once rather than per
/// half and row cost 1 M alone but save 0.7 M inside the CC's function (the
/// per-half form there: 155.0 M). A copy per half rather than a loop over the
/// halves (session 10): default 153.7 → 148.3 M, terrain 241.2 → 226.5 M. Dropped
/// then: a row with a later fragment, loaded for eq. 4, blended with the new words
/// and stored whole instead of its visible pixels one by one (default 145.1 →
/// 147.6 M, terrain 220.4 → 225.5 M: the loaded words kept alive to the stores).
/// Session 12: `ln S` once a cell in 16-bit lanes (it had been a popcount by shifts
/// and two permutes per half), a partial row by `vpmaskmovd` rather than a branch
/// per pixel, the rows with later fragments loaded without a loop: colour + VB
/// default 125.0 → 120.8 M, terrain 212.4 → 195.0 M (77 % of terrain's half-cells
/// run eq. 3-4, and a third of its rows are partial); then eq. 3-4 of a cell whose
/// two halves both run them in 16-bit lanes (one register a component for the 16
/// pixels, half the operations but the gathers): default 120.8 → 120.9 M, terrain
/// 195.0 → 191.1 M (shade's perf samples over the SPP's on terrain 0.689 → 0.668,
/// five runs each). Session 13: the rows read and written without a bounds check
/// per row ([`cell_row`]), the encoder's windows loaded by `vlddqu`
/// ([`load_window`]) and placed from the anchor colour in lanes
/// ([`encode8_rgb_avx2`]): colour + VB default 115.9 → 111.5 M, terrain 179.6 →
/// 170.3 M, city 77.0 → 71.5 M. Tried then and dropped: the colour computers'
/// registers handed to F1 rather than loaded again from [`CellColors`] (three
/// loads a half saved, but more spills: default +0.1 M); the store's bounds
/// (`Q1`, `floor - 1`) as aligned lanes in memory rather than broadcast per half
/// (default +0.1 M, terrain −0.3 M). Session 22 (Zen 3, one thread pinned), tried
/// and dropped: `ln(1 + e^x)` by cubics in lanes (`f32`, 8 segments of 128 read by
/// `vpermps`, exact at every index) instead of the gathers: 6.1 against 9.3 ns per
/// 16 lanes in a loop of its own, yet no faster in the frame (terrain's fastest of
/// 40 frames 71.9 against 72.1 ms, 3 of 8 pairs; default 30.3 against 30.1), the
/// gathers' wait hidden among the cell's other work; and the partial rows' masked
/// stores as a load, blend and store (terrain the same within the host's noise).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn accumulate_log8_avx2<const F1: u8>(
    codes: &mut [Word8],
    width: usize,
    vis: &Visible,
    colors: &CellColors,
    f1: &LogF1,
    encoder: Encoder8Tables,
    ln_area: &LnArea16,
) {
    const SIDE: usize = CELL_SIDE as usize;
    // SAFETY: `vis.sets` is 16 `u16`, the 32 bytes the load reads.
    #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
    let sets = unsafe { _mm256_loadu_si256(vis.sets.as_ptr().cast()) };
    let hidden = _mm256_cmpeq_epi16(sets, _mm256_setzero_si256());
    let visible = u32::from(!mask16_avx2(hidden));
    if visible == 0 {
        return;
    }
    // Whole first fragments: stored as their codes.
    let done = visible
        & u32::from(mask16_avx2(_mm256_cmpeq_epi16(sets, _mm256_set1_epi16(FULL as i16))))
        & u32::from(vis.first);
    let (px, py) = (vis.px as usize, vis.py as usize);
    // Pixels of each row on the screen (those beyond have no visible subpixel).
    let cols = width.saturating_sub(px).min(SIDE);
    // The rows down to the last one with a visible pixel (those below may be off
    // the screen), as one slice: row `r` at `r * width .. r * width + cols`.
    let last = (u32::BITS - 1 - visible.leading_zeros()) as usize / SIDE;
    let start = py * width + px;
    let cell = &mut codes[start..start + last * width + cols];
    // Both halves run eq. 3 or 4 (each has a visible pixel that is not a whole
    // first fragment): the whole cell's in 16-bit lanes.
    if done & 0xFF != visible & 0xFF && done >> 8 != visible >> 8 {
        let words = [
            encode_half_avx2::<0, CELL_PATH, F1>(colors, encoder, hidden, visible),
            encode_half_avx2::<1, CELL_PATH, F1>(colors, encoder, hidden, visible),
        ];
        // SAFETY: `cell` holds the cell's rows down to its last one with a visible
        // pixel (just above), each `cols` words from `r * width`.
        #[allow(unsafe_code, reason = "the cell's rows read and written without a bounds check per row")]
        unsafe {
            let words = f1_cell16_avx2::<F1>(cell, width, cols, vis, words, sets, f1, ln_area);
            store_half_avx2::<0, CELL_PATH, F1>(cell, width, cols, words[0], visible);
            store_half_avx2::<1, CELL_PATH, F1>(cell, width, cols, words[1], visible);
        }
        return;
    }
    // `ln S` of the 16 pixels once for the cell, when a half runs eq. 3 or 4 (it
    // has a visible pixel that is not a whole first fragment).
    let ln_s = if done != visible { ln_area16_avx2(sets, ln_area) } else { _mm256_setzero_si256() };
    // The halves one after the other, each its own copy of the code with its
    // lanes' shifts and register halves known at compile time (a loop over the
    // halves kept them in registers and the F1 registers on the stack).
    if visible & 0xFF != 0 {
        let word = encode_half_avx2::<0, HALF_PATH, F1>(colors, encoder, hidden, visible);
        // SAFETY: as for the whole cell's path above.
        #[allow(unsafe_code, reason = "the cell's rows read and written without a bounds check per row")]
        unsafe {
            let word = f1_half_avx2::<0, F1>(cell, width, cols, vis, f1, word, ln_s, visible, done);
            store_half_avx2::<0, HALF_PATH, F1>(cell, width, cols, word, visible);
        }
    }
    if visible >> 8 != 0 {
        let word = encode_half_avx2::<1, HALF_PATH, F1>(colors, encoder, hidden, visible);
        // SAFETY: as for the whole cell's path above.
        #[allow(unsafe_code, reason = "the cell's rows read and written without a bounds check per row")]
        unsafe {
            let word = f1_half_avx2::<1, F1>(cell, width, cols, vis, f1, word, ln_s, visible, done);
            store_half_avx2::<1, HALF_PATH, F1>(cell, width, cols, word, visible);
        }
    }
}

/// [`accumulate_log8_avx2`]'s callers, its parameter `F1`: each copy of it has
/// one caller, so that it is inlined there (called from the two copies of the
/// colour computers' function, it stayed out of line, a call a cell).
#[cfg(target_arch = "x86_64")]
const F1_ALONE: u8 = 0;
#[cfg(target_arch = "x86_64")]
const F1_FUSED: u8 = 1;
#[cfg(target_arch = "x86_64")]
const F1_FUSED_TEXTURED: u8 = 2;

/// [`encode_half_avx2`]'s and [`store_half_avx2`]'s call sites, their second
/// parameter: each copy of them has one caller, so that it is inlined (called
/// from both [`accumulate_log8_avx2`]'s paths, they stayed out of line: default's
/// colour + VB 2.6 M instructions more).
#[cfg(target_arch = "x86_64")]
const CELL_PATH: usize = 0;
#[cfg(target_arch = "x86_64")]
const HALF_PATH: usize = 1;

/// The `ln S` table ([`LogScale::ln_area_table`]) as [`ln_area16_avx2`] reads it:
/// each entry as an `i16` (0 down to -470 for 8 bits), its low bytes in `low` and
/// its high bytes in `high`, each table of 16 bytes in both halves of a register
/// (the `vpshufb` tables), entry `n - 1` at byte `n mod 16`.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct LnArea16 {
    low: [u8; 2 * SHUFFLE_TABLE],
    high: [u8; 2 * SHUFFLE_TABLE],
}

#[cfg(target_arch = "x86_64")]
impl LnArea16 {
    /// The bytes of `ln_area`'s entries, each a 16-bit integer.
    fn new(ln_area: &[i32; AREA_DENOMINATOR as usize]) -> Self {
        // The bounds [`F1_ZERO16`] is chosen for (the 8-bit scale's).
        assert!(ln_area.iter().all(|e| (-470..=0).contains(e)), "the 8-bit ln S table");
        // Byte `i` of a table holds entry `i - 1` (entry 15, `ln 1 = 0`, at 0), so
        // that a count `n` of 1 to 16 reads entry `n - 1` at `n mod 16`.
        let word = |i: usize| {
            let entry = ln_area[(i + SHUFFLE_TABLE - 1) % SHUFFLE_TABLE];
            i16::try_from(entry).expect("an ln S entry of 16 bits") as u16
        };
        Self {
            low: std::array::from_fn(|i| (word(i) & 0xFF) as u8),
            high: std::array::from_fn(|i| (word(i) >> 8) as u8),
        }
    }
}

/// `ln S` of the cell's 16 pixels from their subpixel sets `sets` (16-bit lanes):
/// [`LogScale::ln_area_table`]'s entry `n - 1`, `n` the set's subpixels (entry 15,
/// `ln 1 = 0`, for an empty set, whose pixel is not stored), in 16-bit lanes. The
/// counts by a `vpshufb` table of the nibbles' bits, the entry's two bytes by two
/// `vpshufb` of [`LnArea16`]; once a cell, where the 32-bit lanes of a half had
/// taken a popcount by shifts and two permutes a half.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn ln_area16_avx2(sets: __m256i, table: &LnArea16) -> __m256i {
    let nibble = _mm256_set1_epi8(0x0F);
    let bits = _mm256_setr_epi8(
        0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4,
    );
    let low = _mm256_and_si256(sets, nibble);
    let high = _mm256_and_si256(_mm256_srli_epi16::<4>(sets), nibble);
    // Each byte's count, 0 to 8.
    let bytes = _mm256_add_epi8(_mm256_shuffle_epi8(bits, low), _mm256_shuffle_epi8(bits, high));
    // The low byte's count plus the high byte's: `n` in the low byte (at most 16:
    // no carry), the high byte's count above it; `n` to four bits (an empty set's
    // 0 as a full one's 16: entry 15 for both), the high byte cleared, the tables
    // shifted by one entry ([`LnArea16::new`]; `n - 1` had cost an addition).
    let n = _mm256_add_epi16(bytes, _mm256_srli_epi16::<8>(bytes));
    let index = _mm256_and_si256(n, _mm256_set1_epi16(15));
    // The entry's low byte at the lane's low byte (an index byte with bit 7 set
    // gives 0), its high byte at the high byte.
    // SAFETY: `table.low` and `table.high` are 32 bytes each, which the loads read.
    #[allow(unsafe_code, reason = "aligned loads of arrays of a register's size")]
    let (low_table, high_table) =
        unsafe { (_mm256_load_si256(table.low.as_ptr().cast()), _mm256_load_si256(table.high.as_ptr().cast())) };
    let entry_low = _mm256_shuffle_epi8(low_table, _mm256_or_si256(index, _mm256_set1_epi16(i16::MIN)));
    let entry_high =
        _mm256_shuffle_epi8(high_table, _mm256_or_si256(_mm256_slli_epi16::<8>(index), _mm256_set1_epi16(0x80)));
    _mm256_or_si256(entry_low, entry_high)
}

/// Zero's value in [`f1_cell16_avx2`]'s 16-bit lanes ([`LogFine::ZERO`] does not
/// fit an `i16`). The same results as `ZERO`: a code's value (weighed, at least
/// `4 - 470`) is more than the 988 entries of the 8-bit `ln(1 + e^x)` table above
/// it and its weighed value (so a sum with it is the other operand, as past the
/// table's end); a sum of two zeros (at most `T[0]`, 118, above it) is below the
/// floor `4 - T[0]` (stored as 0); the differences (at most `4 Q1 + 470 - F1_ZERO16`)
/// and the rounding stay inside an `i16`.
#[cfg(target_arch = "x86_64")]
const F1_ZERO16: i16 = -4096;

#[cfg(target_arch = "x86_64")]
const _: () = assert!(
    (F1_ZERO16 as i32) < 4 - 470 - 988
        && (F1_ZERO16 as i32) + 118 < 4 - 118
        && 4 * 255 + 470 - (F1_ZERO16 as i32) < SOFTPLUS_LANE_MAX
);

/// The codes of component `C` of a cell's two halves' [`Word8`]s in 16-bit lanes, in
/// [`f1_cell16_avx2`]'s order: lanes 0-3 pixels 0-3 (row 0), lanes 4-7 pixels 8-11
/// (row 2), lanes 8-11 pixels 4-7 (row 1), lanes 12-15 pixels 12-15 (row 3), the
/// order in which two half-cells' 32-bit lanes (rows 0 and 1, rows 2 and 3) unpack
/// into one register and back.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn component16_avx2<const C: i8>(words: [__m256i; 2]) -> __m256i {
    // Byte `C` of each word to a 16-bit lane, in the low 8 bytes of each half.
    let z = -1i8;
    let pick = _mm256_setr_epi8(
        C,
        z,
        4 + C,
        z,
        8 + C,
        z,
        12 + C,
        z,
        z,
        z,
        z,
        z,
        z,
        z,
        z,
        z,
        C,
        z,
        4 + C,
        z,
        8 + C,
        z,
        12 + C,
        z,
        z,
        z,
        z,
        z,
        z,
        z,
        z,
        z,
    );
    _mm256_unpacklo_epi64(_mm256_shuffle_epi8(words[0], pick), _mm256_shuffle_epi8(words[1], pick))
}

/// [`LogFine::from_code`] in 16-bit lanes: `4 q`, or [`F1_ZERO16`] for 0.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn from_code16_avx2(q: __m256i) -> __m256i {
    let zero = _mm256_cmpeq_epi16(q, _mm256_setzero_si256());
    _mm256_add_epi16(
        _mm256_slli_epi16::<{ LOG_FRAC_BITS as i32 }>(q),
        _mm256_and_si256(zero, _mm256_set1_epi16(F1_ZERO16)),
    )
}

/// The 8-bit scale's `Q1` and `4 - T[0]` (the least value stored as code 1,
/// [`LogArith::floor`]), as constants of [`store16_avx2`] (checked when the scale's
/// registers are made, [`F1Log8::get`]): taken from the scale's registers, each was
/// a load, a move and a broadcast a half cell (terrain: ~0.9 M instructions).
#[cfg(target_arch = "x86_64")]
const LOG8_ONE16: i16 = 255;
#[cfg(target_arch = "x86_64")]
const LOG8_FLOOR16: i16 = FINE_PER_CODE as i16 - 118;

/// [`LogArith::store`] in 16-bit lanes: fine values `v` to 8-bit codes (rounded to
/// the nearest code, ties to even; raised to code 1; 0 below the floor), for the
/// F1 copies in 16-bit lanes ([`f1_cell16_avx2`], [`f1_half_avx2`]); the 8-bit
/// scale's `Q1` and floor ([`LOG8_ONE16`], [`LOG8_FLOOR16`]) are `arith`'s.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn store16_avx2(arith: LogArith<'_>, v: __m256i) -> __m256i {
    debug_assert!(arith.one == LOG8_ONE16.into() && arith.floor == LOG8_FLOOR16.into(), "the 8-bit scale");
    let rounded = _mm256_srai_epi16::<2>(_mm256_add_epi16(
        _mm256_add_epi16(v, _mm256_set1_epi16((FINE_PER_CODE / 2 - 1) as i16)),
        _mm256_and_si256(_mm256_srai_epi16::<2>(v), _mm256_set1_epi16(1)),
    ));
    let clamped = _mm256_min_epi16(_mm256_max_epi16(rounded, _mm256_set1_epi16(1)), _mm256_set1_epi16(LOG8_ONE16));
    let kept = _mm256_cmpgt_epi16(v, _mm256_set1_epi16(LOG8_FLOOR16 - 1));
    _mm256_and_si256(clamped, kept)
}

/// Eq. 3 and 4 of a whole cell whose two halves both run them, in 16-bit lanes
/// (one register a component for the 16 pixels, where 32-bit lanes took two): the halves' codes `words` weighed by `ln S` (the cell's sets
/// `sets`), summed with the stored words where a pixel has a later fragment
/// (`ln(1 + e^x)` by two gathers a component), and stored ([`LogArith::store`]),
/// zero as [`F1_ZERO16`]; the halves' new words. The same values as the 32-bit
/// lanes' (every value in them but zero's fits an `i16`), so the same words.
///
/// # Safety
///
/// `cell` must hold the cell's rows down to its last one with a visible pixel (a
/// non-empty set in `sets`), row `r` at `r * width .. r * width + cols`
/// ([`cell_row`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
#[allow(clippy::too_many_arguments, reason = "the cell's registers, passed as they are")]
#[allow(unsafe_code, reason = "the cell's rows read without a bounds check per row")]
unsafe fn f1_cell16_avx2<const F1: u8>(
    cell: &[Word8],
    width: usize,
    cols: usize,
    vis: &Visible,
    words: [__m256i; 2],
    sets: __m256i,
    f1: &LogF1,
    ln_area: &LnArea16,
) -> [__m256i; 2] {
    let visible = u32::from(!mask16_avx2(_mm256_cmpeq_epi16(sets, _mm256_setzero_si256())));
    let later = visible & !u32::from(vis.first);
    // Rows 0 and 2 in the 64-bit halves of the low 128 bits, rows 1 and 3 above.
    let ln_s = ln_area16_avx2(_mm256_permute4x64_epi64::<0b11_01_10_00>(sets), ln_area);
    // The rows with a later fragment (each has a visible pixel: it is in `cell`),
    // their later fragments' words ([`load_later_row`]: a first write's sum is its
    // new value).
    // (No closure: it would not take this function's target feature.)
    let mut rows = [_mm_setzero_si128(); 4];
    for (r, row) in rows.iter_mut().enumerate() {
        let lanes = later >> (4 * r) & 0xF;
        if lanes != 0 {
            // SAFETY: row `r` has a visible pixel, so it is in `cell` (this
            // function's condition).
            *row = load_later_row(unsafe { cell_row(cell, r, width, cols) }, lanes);
        }
    }
    let stored = [_mm256_set_m128i(rows[1], rows[0]), _mm256_set_m128i(rows[3], rows[2])];
    let arith = f1.arith;
    let mut codes = [_mm256_setzero_si256(); 3];
    for (c, code) in codes.iter_mut().enumerate() {
        let (new, old) = match c {
            0 => (component16_avx2::<0>(words), component16_avx2::<0>(stored)),
            1 => (component16_avx2::<1>(words), component16_avx2::<1>(stored)),
            _ => (component16_avx2::<2>(words), component16_avx2::<2>(stored)),
        };
        let mut v = _mm256_add_epi16(from_code16_avx2(new), ln_s);
        if later != 0 {
            let s = from_code16_avx2(old);
            let (hi, lo) = (_mm256_max_epi16(v, s), _mm256_min_epi16(v, s));
            let d = _mm256_min_epi16(_mm256_sub_epi16(hi, lo), _mm256_set1_epi16(SOFTPLUS_LANE_MAX as i16));
            let table = arith.softplus.as_ptr().cast::<i32>();
            let (d0, d1) = (
                _mm256_cvtepi16_epi32(_mm256_castsi256_si128(d)),
                _mm256_cvtepi16_epi32(_mm256_extracti128_si256::<1>(d)),
            );
            // SAFETY: every lane of `d0`, `d1` is `0 ..= SOFTPLUS_PADDED - 2` (a
            // difference max - min, clamped), so the 4 bytes read at entry `d` are
            // entries `d` and `d + 1` of the padded table.
            #[allow(unsafe_code, reason = "gathers from the padded ln(1 + e^x) table, the indices clamped inside it")]
            let (t0, t1) = unsafe { (_mm256_i32gather_epi32::<2>(table, d0), _mm256_i32gather_epi32::<2>(table, d1)) };
            // Entry `d` (the low 16 bits), back in 16-bit lanes in `d`'s order.
            let zero = _mm256_setzero_si256();
            let (t0, t1) = (_mm256_blend_epi16::<0b1010_1010>(t0, zero), _mm256_blend_epi16::<0b1010_1010>(t1, zero));
            let t = _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_packus_epi32(t0, t1));
            v = _mm256_add_epi16(hi, t);
        }
        *code = store16_avx2(arith, v);
    }
    // R | G << 8 in 16-bit lanes, then B above them in 32-bit lanes: rows 0 and 1
    // (the low 64 bits of each half), rows 2 and 3.
    let rg = _mm256_or_si256(codes[0], _mm256_slli_epi16::<8>(codes[1]));
    [_mm256_unpacklo_epi16(rg, codes[2]), _mm256_unpackhi_epi16(rg, codes[2])]
}

/// Eq. 3 and 4 of half `HALF` (pixels `8 HALF .. 8 HALF + 8`, rows `2 HALF` and `2
/// HALF + 1`) of [`accumulate_log8_avx2`] in 16-bit lanes when it runs them (`done`:
/// a bit per whole first fragment) and the other half does not: the half's new words
/// from its codes `word`. `cell`: the cell's rows in one slice; `ln_s`: the cell's 16
/// `ln S` in 16-bit lanes ([`ln_area16_avx2`]); `visible`: a bit per pixel of the
/// cell. A row with a later fragment is loaded whole (when the cell's rows are whole
/// on the screen).
///
/// The half's [`Word8`]s are split in place into two registers of 16-bit lanes, no
/// shuffles: `R | B << 16` (the word and `0x00FF_00FF`) and `G` (the word shifted
/// right by 8 in 16-bit lanes: `G` in the low lane, the word's zero top byte in the
/// high one); each pixel's `ln S` fills both lanes of its word.
/// Eq. 3-4 and the store then run on 2 registers where 32-bit lanes took 3 (one a
/// component), with the same values as [`f1_cell16_avx2`]'s (zero as
/// [`F1_ZERO16`]), so the same words; `ln(1 + e^x)` by a gather per component as
/// before (`R`'s from the low lanes, `B`'s from the high ones). The `G` register's
/// high lanes hold zeros (code 0, stored below the floor: 0), so the words are
/// `R | B << 16` or'ed with `G << 8`.
///
/// Measured (callgrind, 1920 x 1080, one thread): colour + VB terrain 165.3 → 159.8 M,
/// default 109.1 → 107.8 M, city 68.9 → 68.4 M (the 32-bit lanes, one register a
/// component, had taken ~140 instructions a half with later fragments and ~75
/// without; terrain runs eq. 3-4 in ~200 000 half cells alone).
///
/// # Safety
///
/// `cell` must hold the cell's rows down to its last one with a visible pixel (in
/// `visible`), row `r` at `r * width .. r * width + cols` ([`cell_row`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
#[allow(clippy::too_many_arguments, reason = "the cell's registers, passed as they are")]
#[allow(unsafe_code, reason = "the cell's rows read without a bounds check per row")]
unsafe fn f1_half_avx2<const HALF: usize, const F1: u8>(
    cell: &[Word8],
    width: usize,
    cols: usize,
    vis: &Visible,
    f1: &LogF1,
    word: __m256i,
    ln_s: __m256i,
    visible: u32,
    done: u32,
) -> __m256i {
    let lanes = visible >> (8 * HALF) & 0xFF;
    if done >> (8 * HALF) & 0xFF == lanes {
        return word;
    }
    let first = u32::from(vis.first) >> (8 * HALF) & 0xFF;
    let later = lanes & !first;
    // Each pixel's `ln S` in both 16-bit lanes of its word: the half's two rows'
    // 64 bits moved to the low 64 bits of each 128-bit lane, then each 16-bit lane
    // paired with itself.
    let rows = if HALF == 0 {
        _mm256_permute4x64_epi64::<0b01_01_00_00>(ln_s)
    } else {
        _mm256_permute4x64_epi64::<0b11_11_10_10>(ln_s)
    };
    let ln_s = _mm256_unpacklo_epi16(rows, rows);
    let low_bytes = _mm256_set1_epi32(0x00FF_00FF);
    // `R | B << 16` and `G` of the new codes (the encoder's words have a zero top
    // byte).
    let new = [_mm256_and_si256(word, low_bytes), _mm256_srli_epi16::<8>(word)];
    let mut old = [_mm256_setzero_si256(); 2];
    if later != 0 {
        // Rows `2 HALF` and `2 HALF + 1`, each where it has a later fragment, its
        // later fragments' words ([`load_later_row`]).
        // SAFETY (both): such a row has a visible pixel, so it is in `cell` (this
        // function's condition).
        let low = if later & 0xF != 0 {
            load_later_row(unsafe { cell_row(cell, 2 * HALF, width, cols) }, later & 0xF)
        } else {
            _mm_setzero_si128()
        };
        let high = if later >> 4 != 0 {
            load_later_row(unsafe { cell_row(cell, 2 * HALF + 1, width, cols) }, later >> 4)
        } else {
            _mm_setzero_si128()
        };
        let stored = _mm256_set_m128i(high, low);
        // (`G` masked to its byte: a stored word's top byte is not relied on.)
        old = [
            _mm256_and_si256(stored, low_bytes),
            _mm256_and_si256(_mm256_srli_epi32::<8>(stored), _mm256_set1_epi32(0xFF)),
        ];
    }
    let arith = f1.arith;
    let table = arith.softplus.as_ptr().cast::<i32>();
    let mut codes = [_mm256_setzero_si256(); 2];
    for (r, code) in codes.iter_mut().enumerate() {
        let mut v = _mm256_add_epi16(from_code16_avx2(new[r]), ln_s);
        if later != 0 {
            let s = from_code16_avx2(old[r]);
            let (hi, lo) = (_mm256_max_epi16(v, s), _mm256_min_epi16(v, s));
            let d = _mm256_min_epi16(_mm256_sub_epi16(hi, lo), _mm256_set1_epi16(SOFTPLUS_LANE_MAX as i16));
            // Entry `d` of each wanted 16-bit lane, in that lane.
            let low_lanes = _mm256_and_si256(d, _mm256_set1_epi32(0xFFFF));
            // SAFETY: every 16-bit lane of `d` is `0 ..= SOFTPLUS_PADDED - 2` (a
            // difference max - min, clamped), so the 4 bytes read at entry `d` are
            // entries `d` and `d + 1` of the padded table.
            #[allow(unsafe_code, reason = "gathers from the padded ln(1 + e^x) table, the indices clamped inside it")]
            let t = unsafe {
                let t_low = _mm256_i32gather_epi32::<2>(table, low_lanes);
                if r == 0 {
                    // `B`'s entries from the high lanes' indices, moved up.
                    let t_high = _mm256_i32gather_epi32::<2>(table, _mm256_srli_epi32::<16>(d));
                    _mm256_blend_epi16::<0b1010_1010>(t_low, _mm256_slli_epi32::<16>(t_high))
                } else {
                    _mm256_blend_epi16::<0b1010_1010>(t_low, _mm256_setzero_si256())
                }
            };
            v = _mm256_add_epi16(hi, t);
        }
        *code = store16_avx2(arith, v);
    }
    _mm256_or_si256(codes[0], _mm256_slli_epi16::<8>(codes[1]))
}

/// The codes of half `HALF` of a cell ([`encode8_rgb_avx2`]), which has a visible
/// pixel; `hidden`: the zero compares of the cell's 16 sets; `visible`: a bit per
/// pixel.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn encode_half_avx2<const HALF: usize, const SITE: usize, const F1: u8>(
    colors: &CellColors,
    encoder: Encoder8Tables,
    hidden: __m256i,
    visible: u32,
) -> __m256i {
    let lanes = visible >> (8 * HALF) & 0xFF;
    let hidden = _mm256_cvtepi16_epi32(if HALF == 0 {
        _mm256_castsi256_si128(hidden)
    } else {
        _mm256_extracti128_si256::<1>(hidden)
    });
    // The first visible pixel's colour places the ROM's windows: its lane of the
    // half, in every lane (`lanes` is not 0, so the lane is 0 to 7).
    let anchor = _mm256_set1_epi32(lanes.trailing_zeros() as i32);
    encode8_rgb_avx2(load_colors_half(colors, HALF), hidden, anchor, encoder.entries)
}

/// Stores the words `word` of half `HALF` of a cell at its visible pixels
/// (`visible`, a bit per pixel of the cell): a row whole, or its visible pixels by
/// a masked store (`vpmaskmovd`: no branch per pixel, where terrain's small
/// polygons leave a third of their rows partial), at the screen's right edge one
/// by one.
///
/// # Safety
///
/// `cell` must hold the cell's rows down to its last one with a visible pixel (in
/// `visible`), row `r` at `r * width .. r * width + cols` ([`cell_row_mut`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
#[allow(unsafe_code, reason = "the cell's rows written without a bounds check per row")]
unsafe fn store_half_avx2<const HALF: usize, const SITE: usize, const F1: u8>(
    cell: &mut [Word8],
    width: usize,
    cols: usize,
    word: __m256i,
    visible: u32,
) {
    const SIDE: usize = CELL_SIDE as usize;
    let lanes = visible >> (8 * HALF) & 0xFF;
    for row in 0..2 {
        let lanes = lanes >> (4 * row) & 0xF;
        if lanes == 0 {
            continue;
        }
        let new = if row == 0 { _mm256_castsi256_si128(word) } else { _mm256_extracti128_si256::<1>(word) };
        // SAFETY: the row has a visible pixel, so it is in `cell` (this function's
        // condition).
        let dst = unsafe { cell_row_mut(cell, 2 * HALF + row, width, cols) };
        if cols == SIDE {
            if lanes == 0xF {
                store_row(dst, new);
            } else {
                store_row_masked(dst, new, lanes);
            }
        } else {
            // At the screen's right edge: the visible pixels one by one (a load of
            // the row to blend with would often miss the cache: city's colour + VB
            // 0.4 ms slower).
            let mut words = [0u32; SIDE];
            store_row(&mut words, new);
            for (x, w) in dst.iter_mut().enumerate() {
                if lanes >> x & 1 == 1 {
                    *w = words[x];
                }
            }
        }
    }
}

/// Row `r` of a cell's rows `cell` as [`accumulate_log8_avx2`] slices them (row
/// `r` at `r * width .. r * width + cols`, down to the last row with a visible
/// pixel), with no bounds check: F1 reads and writes only rows with a visible pixel,
/// which that slice holds, and a check per row had cost ~5 instructions (default:
/// ~2.8 rows written a cell).
///
/// # Safety
///
/// Row `r` must be inside `cell`: `r * width + cols <= cell.len()` (a row with a
/// visible pixel of the cell whose rows `cell` is).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(unsafe_code, reason = "a row of a cell's slice, known to be inside it, without a bounds check")]
unsafe fn cell_row(cell: &[Word8], r: usize, width: usize, cols: usize) -> &[Word8] {
    debug_assert!(r * width + cols <= cell.len(), "row {r} outside the cell's rows");
    // SAFETY: the range is inside `cell` (this function's condition).
    unsafe { cell.get_unchecked(r * width..r * width + cols) }
}

/// [`cell_row`], to write.
///
/// # Safety
///
/// As [`cell_row`]'s.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(unsafe_code, reason = "a row of a cell's slice, known to be inside it, without a bounds check")]
unsafe fn cell_row_mut(cell: &mut [Word8], r: usize, width: usize, cols: usize) -> &mut [Word8] {
    debug_assert!(r * width + cols <= cell.len(), "row {r} outside the cell's rows");
    // SAFETY: the range is inside `cell` (this function's condition).
    unsafe { cell.get_unchecked_mut(r * width..r * width + cols) }
}

/// Stores the words of `v` whose bits are set in `lanes` (bit `x`, word `x`) into a
/// row of four VMEM words, by one masked store; the others are left as they are.
///
/// The store's mask is [`ROW_MASKS`]' entry, one load, where made in the lanes
/// (`lanes` moved, broadcast, and'ed with the lanes' bits and compared) it had cost
/// four instructions more (terrain: ~0.8 M, ~200 000 partial rows a frame).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn store_row_masked(row: &mut [Word8], v: __m128i, lanes: u32) {
    let row: &mut [Word8; 4] = row.try_into().expect("a row of four words");
    // SAFETY: `row` is 16 bytes, of which the store writes the words the mask selects.
    #[allow(unsafe_code, reason = "a masked store of a register into an array of its size")]
    unsafe {
        _mm_maskstore_epi32(row.as_mut_ptr().cast(), row_mask(lanes), v)
    }
}

/// [`ROW_MASKS`]' entry `lanes & 15` in a register: word `x` all ones where bit `x`
/// of `lanes` is set, else zero.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn row_mask(lanes: u32) -> __m128i {
    let mask: &[i32; 4] = &ROW_MASKS.0[lanes as usize & 0xF];
    // SAFETY: `mask` is 16 bytes aligned to 16 (`RowMasks`), which the load reads.
    #[allow(unsafe_code, reason = "an aligned load of an array of a register's size")]
    unsafe {
        _mm_load_si128(mask.as_ptr().cast())
    }
}

/// [`store_row_masked`]'s masks: entry `lanes`, word `x` all ones where bit `x` of
/// `lanes` is set, else zero.
#[cfg(target_arch = "x86_64")]
#[repr(C, align(16))]
struct RowMasks([[i32; 4]; 16]);

/// [`RowMasks`].
#[cfg(target_arch = "x86_64")]
static ROW_MASKS: RowMasks = RowMasks({
    let mut masks = [[0i32; 4]; 16];
    let mut lanes = 0;
    while lanes < 16 {
        let mut x = 0;
        while x < 4 {
            if lanes >> x & 1 == 1 {
                masks[lanes][x] = -1;
            }
            x += 1;
        }
        lanes += 1;
    }
    masks
});

/// A bit per 16-bit lane of `v` (all ones or zeros in each), lane `i` at bit `i`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn mask16_avx2(v: __m256i) -> u16 {
    let bytes = _mm_packs_epi16(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
    _mm_movemask_epi8(bytes) as u16
}

/// A row of a cell's VMEM words: four words whole, fewer (at the screen's right
/// edge) in the low lanes, the others zero.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn load_row(row: &[Word8]) -> __m128i {
    match <&[Word8; 4]>::try_from(row) {
        // SAFETY: `row` is 16 bytes, which the load reads.
        #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
        Ok(row) => unsafe { _mm_loadu_si128(row.as_ptr().cast()) },
        Err(_) => {
            let mut words = [0u32; 4];
            words[..row.len().min(4)].copy_from_slice(&row[..row.len().min(4)]);
            // SAFETY: `words` is 16 bytes, which the load reads.
            #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
            unsafe {
                _mm_loadu_si128(words.as_ptr().cast())
            }
        }
    }
}

/// The words of a cell's row `row` ([`load_row`]) at its later fragments' pixels
/// (`lanes`, a bit per pixel of the row), zero (code 0) at the others, by
/// [`ROW_MASKS`]' entry. A first write's stored codes are then 0, whose value
/// [`F1_ZERO16`] sums with a new value `v` to `v` (zero's conditions there), so eq.
/// 4 runs on the first writes' lanes too and gives eq. 3's value: the F1 copies in
/// 16-bit lanes ([`f1_cell16_avx2`], [`f1_half_avx2`]) keep no first-write lanes
/// (a broadcast, an and and a compare) and blend (one a register) to choose
/// between the two (session 27: terrain's colour + VB ~1 M instructions less).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn load_later_row(row: &[Word8], lanes: u32) -> __m128i {
    _mm_and_si128(load_row(row), row_mask(lanes))
}

/// Stores a row of four VMEM words.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn store_row(row: &mut [Word8], v: __m128i) {
    let row: &mut [Word8; 4] = row.try_into().expect("a row of four words");
    // SAFETY: `row` is 16 bytes, which the store writes.
    #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
    unsafe {
        _mm_storeu_si128(row.as_mut_ptr().cast(), v)
    }
}

/// The colours of pixels `8 half .. 8 half + 8` of a cell as `[r, g, b]` over the
/// lanes: three 32-byte loads.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn load_colors_half(colors: &CellColors, half: usize) -> [__m256; 3] {
    let lanes = 8 * (half & 1)..8 * (half & 1) + 8;
    // (A loop, not a closure: a closure would not inherit the target feature.)
    let mut rgb = [_mm256_setzero_ps(); 3];
    for (v, c) in rgb.iter_mut().zip(&colors.rgb) {
        let c: &[f32; 8] = c[lanes.clone()].try_into().expect("8 lanes");
        // SAFETY: `c` is 8 `f32`, the 32 bytes the load reads.
        #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
        let loaded = unsafe { _mm256_loadu_ps(c.as_ptr()) };
        *v = loaded;
    }
    rgb
}

/// [`Encoder8Tables::encode`] of eight lanes of the three components, packed into
/// [`Word8`]s (`hidden`: all ones in the lanes whose codes are not wanted; `lane`:
/// the index of a lane that is wanted, 0 to 7, in every lane). Each
/// component's entries come from one window of the table, [`ENCODER8_BACK`] entries
/// below `lane`'s address to `ENCODER8_WINDOW - ENCODER8_BACK - 1` above it (a load
/// and a permute), when every wanted lane's address of every component lies in its
/// window (one test, no reduction over the lanes); else from gathers. The window's
/// entries are the table's, so the codes are the same either way.
///
/// The window's start found in the lanes, from `lane` broadcast from memory (a
/// shift, a saturating subtraction, and one move to a general register for the
/// window's address), where the scalar start shifted, clamped, moved back and
/// broadcast had cost two instructions a component more (default: ~10 a cell).
/// Since session 27 the anchor's address is taken from the component's addresses
/// by a permute with the lane's index, where its colour was loaded again from
/// [`CellColors`], shifted and broadcast (a load, a shift and a broadcast a
/// component, the index's two-step place in the cell a half; any lane places a
/// correct window, the test below the permute checks every wanted lane): terrain's
/// encoding ~1 M instructions less.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn encode8_rgb_avx2(rgb: [__m256; 3], hidden: __m256i, lane: __m256i, table: &[u32; ENCODER8_PADDED]) -> __m256i {
    const LANES: usize = ENCODER8_WINDOW;
    // (Loops, not closures: a closure would not inherit the target feature.)
    let (mut bits, mut address, mut d) =
        ([_mm256_setzero_si256(); 3], [_mm256_setzero_si256(); 3], [_mm256_setzero_si256(); 3]);
    let mut start = [0usize; 3];
    let back = _mm256_set1_epi32(ENCODER8_BACK as i32);
    for c in 0..3 {
        bits[c] = _mm256_castps_si256(rgb[c]);
        address[c] = _mm256_srli_epi32::<{ ENCODER8_SHIFT as i32 }>(bits[c]);
        // A window's first entry, `lane`'s address less `ENCODER8_BACK` or 0
        // (`saturating_sub`), in every lane: the address is 15 bits, so a
        // saturating subtraction of 16-bit halves (the upper half 0 - 0) is
        // `saturating_sub`'s. At most `ENCODER8_ENTRIES - 1`, so the window is
        // inside the padded table (the mask, the identity, tells the compiler so).
        let first = _mm256_subs_epu16(_mm256_permutevar8x32_epi32(address[c], lane), back);
        start[c] = _mm256_cvtsi256_si32(first) as u32 as usize & (ENCODER8_ENTRIES - 1);
        d[c] = _mm256_sub_epi32(address[c], first);
    }
    // Offsets in `0..LANES` have no bit above the window's; a negative one has.
    let spread = _mm256_andnot_si256(hidden, _mm256_or_si256(_mm256_or_si256(d[0], d[1]), d[2]));
    let windows = _mm256_testz_si256(spread, _mm256_set1_epi32(!(LANES as i32 - 1))) == 1;
    let mut word = _mm256_setzero_si256();
    for c in 0..3 {
        let e = if windows {
            let window: &[u32; LANES] = table[start[c]..start[c] + LANES].try_into().expect("a window");
            _mm256_permutevar8x32_epi32(load_window(window), d[c])
        } else {
            entries8_avx2(address[c], hidden, table)
        };
        let below = _mm256_cmpgt_epi32(
            _mm256_srli_epi32::<{ ENCODER8_FROM_SHIFT as i32 }>(e),
            _mm256_and_si256(bits[c], _mm256_set1_epi32(ENCODER8_LOW as i32)),
        );
        // `next - 1` where below `from` (the compare's -1), in 8 bits.
        let code = _mm256_and_si256(_mm256_add_epi32(e, below), _mm256_set1_epi32(0xFF));
        word = _mm256_or_si256(word, _mm256_sll_epi32(code, _mm_cvtsi32_si128(8 * c as i32)));
    }
    word
}

/// A window of the encoder ROM ([`ENCODER8_WINDOW`] entries at any entry) in a
/// register, by `vlddqu`: the build's x86-64-v2 tuning splits an unaligned 32-byte
/// load (`vmovdqu`) into two 16-byte halves, two instructions, where `vlddqu` is
/// one (on Zen 3 the same load as `vmovdqu`): three a half-cell on the fused F1's
/// windows (default: ~6 instructions a cell).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn load_window(window: &[u32; ENCODER8_WINDOW]) -> __m256i {
    // SAFETY: `window` is 32 bytes, which the load reads.
    #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
    unsafe {
        _mm256_lddqu_si256(window.as_ptr().cast())
    }
}

/// The encoder ROM's entries of eight lanes at `address` (`hidden`: all ones in the
/// lanes whose entries are not wanted): from one window of the table when the
/// wanted lanes' addresses lie within [`ENCODER8_WINDOW`] of their least (a load and
/// a permute), else by a gather. [`encode8_rgb_avx2`]'s way when a pixel's windows
/// miss (~5 % of default's half cells: a window around the least address holds more
/// of them than one around the first visible pixel's).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn entries8_avx2(address: __m256i, hidden: __m256i, table: &[u32; ENCODER8_PADDED]) -> __m256i {
    const LANES: usize = ENCODER8_WINDOW;
    // The least address of the visible lanes (the hidden ones raised to all ones).
    let m = _mm256_or_si256(address, hidden);
    let m = _mm256_min_epu32(m, _mm256_permute2x128_si256::<0x01>(m, m));
    let m = _mm256_min_epu32(m, _mm256_shuffle_epi32::<0b01_00_11_10>(m));
    let m = _mm256_min_epu32(m, _mm256_shuffle_epi32::<0b10_11_00_01>(m));
    let least = _mm256_cvtsi256_si32(m) as u32 as usize;
    let d = _mm256_sub_epi32(address, _mm256_set1_epi32(least as i32));
    let outside = _mm256_andnot_si256(hidden, d);
    if _mm256_testz_si256(outside, _mm256_set1_epi32(!(LANES as i32 - 1))) == 1 && least < ENCODER8_ENTRIES {
        // Every visible lane in the window of 8 entries from the least address.
        let window: &[u32; LANES] = table[least..least + LANES].try_into().expect("a window");
        _mm256_permutevar8x32_epi32(load_window(window), d)
    } else {
        // SAFETY: the address is 15 bits (a `u32` shifted right by 17), below the
        // table's `2^15` entries.
        #[allow(unsafe_code, reason = "a gather from the encoder ROM, the address inside it")]
        unsafe {
            _mm256_i32gather_epi32::<4>(table.as_ptr().cast::<i32>(), address)
        }
    }
}

/// A VMEM word of three log codes.
trait LogWord: Copy {
    /// The word of three codes.
    fn pack(codes: [u16; 3]) -> Self;
    /// Its three codes.
    fn unpack(self) -> [u16; 3];
}

impl LogWord for [u16; 3] {
    #[inline(always)]
    fn pack(codes: [u16; 3]) -> Self {
        codes
    }

    #[inline(always)]
    fn unpack(self) -> [u16; 3] {
        self
    }
}

/// P1's 24-bit VMEM word of the 8-bit log code, in a `u32`: bits `[7:0]` R, `[15:8]`
/// G, `[23:16]` B, `[31:24]` zero. One word per pixel compares, copies and fills
/// at once (the readout's flat runs), in two thirds of the memory of three `u16`.
pub type Word8 = u32;

/// The widest box (pixels) [`VideoBuffer::prefetch_box`] asks for: 16 words of the
/// 8-bit memory's rows, at most two cache lines a row.
pub const PREFETCH_BOX_WIDTH: u32 = 16;
/// The tallest box (rows) [`VideoBuffer::prefetch_box`] asks for.
pub const PREFETCH_BOX_ROWS: u32 = 16;

/// Bits per component of a [`Word8`].
const WORD8_SHIFT: u32 = 8;

impl LogWord for Word8 {
    #[inline(always)]
    fn pack(codes: [u16; 3]) -> Self {
        u32::from(codes[0] & 0xFF)
            | u32::from(codes[1] & 0xFF) << WORD8_SHIFT
            | u32::from(codes[2] & 0xFF) << (2 * WORD8_SHIFT)
    }

    #[inline(always)]
    fn unpack(self) -> [u16; 3] {
        [self as u16 & 0xFF, (self >> WORD8_SHIFT) as u16 & 0xFF, (self >> (2 * WORD8_SHIFT)) as u16 & 0xFF]
    }
}

/// Copies `share`'s pixels of rows `rows` from `src` (whole screen) to `dst` (holding
/// just those rows), a tile run at a time.
fn copy_share_rows<T: Copy>(dst: &mut [T], src: &[T], width: usize, rows: std::ops::Range<usize>, share: &Share) {
    let tile = share.tile as usize;
    let first = rows.start;
    for y in rows {
        if (y / tile) % share.q as usize != share.j as usize {
            continue;
        }
        let (d, s) = (&mut dst[(y - first) * width..][..width], &src[y * width..][..width]);
        let strip = (share.strip.0 as usize).min(width)..(share.strip.1 as usize).min(width);
        let mut x = share.i as usize * tile;
        while x < width {
            let run = x.max(strip.start)..(x + tile).min(width).min(strip.end);
            if !run.is_empty() {
                d[run.clone()].copy_from_slice(&s[run]);
            }
            x += tile * share.p as usize;
        }
    }
}

/// The shares of several buffers copied into `dst`, in bands of rows on the
/// current rayon pool.
fn copy_shares_parallel<T: Copy + Send + Sync>(dst: &mut [T], srcs: &[(&[T], &Share)], width: usize) {
    use rayon::prelude::*;
    if width == 0 {
        return;
    }
    dst.par_chunks_mut(READOUT_BAND_ROWS * width).enumerate().for_each(|(k, band)| {
        let y0 = k * READOUT_BAND_ROWS;
        for &(src, share) in srcs {
            copy_share_rows(band, src, width, y0..y0 + band.len() / width, share);
        }
    });
}

/// Copies the row-major pixels that `owns(x, y)` selects.
fn copy_owned<T: Copy>(dst: &mut [T], src: &[T], width: u32, owns: &impl Fn(u32, u32) -> bool) {
    for (i, (d, &s)) in dst.iter_mut().zip(src).enumerate() {
        if owns(i as u32 % width, i as u32 / width) {
            *d = s;
        }
    }
}

/// Calls `f(pixel index, visible subpixels, first write, index in the cell)` for
/// every visible pixel of a cell.
#[inline]
fn for_visible(vis: &Visible, width: usize, mut f: impl FnMut(usize, u32, bool, usize)) {
    for (i, &set) in vis.sets.iter().enumerate() {
        if set == 0 {
            continue;
        }
        let x = vis.px as usize + (i & 3);
        let y = vis.py as usize + (i >> 2);
        f(y * width + x, set.count_ones(), vis.first >> i & 1 == 1, i);
    }
}

/// The float path's readout: F2 in `f32`, then the gamma table over `0..=1`.
fn read_out_float(
    w: usize,
    h: usize,
    accum: &[Vec3],
    opts: &Readout,
    table: &[u8],
    rows: std::ops::Range<usize>,
    out: &mut [u8],
) {
    let mut line = vec![Vec3::ZERO; w];
    let mut pixels = out.chunks_exact_mut(3);
    for y in rows {
        let below = (y + 1).min(h - 1);
        // Pass 1: half sums of vertically adjacent pixels (the line buffer).
        for (x, l) in line.iter_mut().enumerate() {
            *l = if opts.filter { (accum[y * w + x] + accum[below * w + x]) * 0.5 } else { accum[y * w + x] };
        }
        // Pass 2: half sums of horizontally adjacent ones.
        for x in 0..w {
            let c = if opts.filter { (line[x] + line[(x + 1).min(w - 1)]) * 0.5 } else { line[x] };
            let px = pixels.next().expect("out holds the rows");
            for (o, ch) in px.iter_mut().zip(c.to_array()) {
                let idx = (ch.clamp(0.0, 1.0) * (GAMMA_TABLE_SIZE - 1) as f32).round() as usize;
                *o = table[idx];
            }
        }
    }
}

/// The arithmetic of F2 on a fixed-point code, in quarter codes.
trait QuarterCodes: Copy {
    /// A stored code as a quarter-code value.
    fn load(self, q: u16) -> i32;
    /// The half sum of two values (loaded codes or earlier half sums); the mean of
    /// a value with itself is the value.
    fn mean(self, a: i32, b: i32) -> i32;
}

impl QuarterCodes for LogArith<'_> {
    #[inline(always)]
    fn load(self, q: u16) -> i32 {
        LogFine::from_code(q).0
    }

    #[inline(always)]
    fn mean(self, a: i32, b: i32) -> i32 {
        LogArith::mean(self, a, b)
    }
}

impl QuarterCodes for LinearScale {
    #[inline(always)]
    fn load(self, q: u16) -> i32 {
        i32::from(q) << LOG_FRAC_BITS
    }

    #[inline(always)]
    fn mean(self, a: i32, b: i32) -> i32 {
        // Exact: the first pass's sums are even in quarter codes.
        (a + b) >> 1
    }
}

/// A fixed-point gamma table padded with zeros to [`GAMMA_PADDED`] entries.
fn padded(mut table: Vec<u8>) -> Vec<u8> {
    debug_assert!(table.len() <= GAMMA_PADDED, "addresses up to 4 Q1 < GAMMA_PADDED");
    table.resize(GAMMA_PADDED, 0);
    table
}

/// Pixels F2 takes at a time: a run equal to its neighbours is copied, the others
/// are summed without a branch per pixel.
const F2_RUN: usize = 8;

/// Pixels the 8-bit code's F2 takes at a time ([`F2_RUN`] of the other codes): a
/// run equal to its neighbours is one half sum and one output pattern, the others
/// go through the tables side by side. Instructions per frame of the readout at
/// 1920 x 1080 by run: 8: rombm 18.2 M, city 41.4, default 72.8; 16: 14.0, 39.2,
/// 54.9; 32: 11.0, 51.4, 57.0 (fewer flat runs on city); 64: 7.7, 66.1, 57.7.
const LOG8_RUN: usize = 16;

/// The fixed-point paths' readout: F2 on quarter codes, then the gamma table.
///
/// The gamma table's address of a result is the result masked with
/// `GAMMA_PADDED - 1`: every result is zero's code or in `0..=4 Q1`, so the mask
/// keeps it as it is and takes [`LogFine::ZERO`] to 0. Where a run of [`F2_RUN`]
/// operands equals its neighbours (flat areas) the means are the operands and are not
/// computed.
#[allow(clippy::too_many_arguments, reason = "the readout's registers, passed as they are")]
fn read_out_fine(
    w: usize,
    h: usize,
    codes: &[[u16; 3]],
    filter: bool,
    f2: impl QuarterCodes,
    table: &[u8; GAMMA_PADDED],
    rows: std::ops::Range<usize>,
    out: &mut [u8],
) {
    if w == 0 || rows.is_empty() {
        return;
    }
    assert!(out.len() >= 3 * w * rows.len(), "out holds the rows");
    let gamma = |v: i32| table[v as usize & (GAMMA_PADDED - 1)];
    let mut line = vec![[0i32; 3]; w];
    for (y, out_row) in rows.zip(out.chunks_exact_mut(3 * w)) {
        let row = &codes[y * w..][..w];
        if !filter {
            for (px, word) in out_row.chunks_exact_mut(3).zip(row) {
                for (o, &q) in px.iter_mut().zip(word) {
                    *o = gamma(f2.load(q));
                }
            }
            continue;
        }
        let below = &codes[(y + 1).min(h - 1) * w..][..w];
        // Pass 1: half sums of vertically adjacent pixels (the line buffer), a run
        // of F2_RUN pixels at a time: a run equal to the one below (flat areas) is
        // only loaded; the others are summed without a branch per pixel.
        for ((l, a), b) in line.chunks_mut(F2_RUN).zip(row.chunks(F2_RUN)).zip(below.chunks(F2_RUN)) {
            if a == b {
                for (l, a) in l.iter_mut().zip(a) {
                    *l = a.map(|q| f2.load(q));
                }
            } else {
                for ((l, a), b) in l.iter_mut().zip(a).zip(b) {
                    *l = std::array::from_fn(|ch| f2.mean(f2.load(a[ch]), f2.load(b[ch])));
                }
            }
        }
        // Pass 2: half sums of horizontally adjacent ones, by runs the same way; the
        // last column's own value stands in for its right neighbour, and its mean
        // with itself is itself.
        let (row_out, last) = out_row.split_last_chunk_mut::<3>().expect("a row holds a pixel");
        for (k, out_run) in row_out.chunks_mut(3 * F2_RUN).enumerate() {
            let x0 = k * F2_RUN;
            let n = out_run.len() / 3;
            let (a, b) = (&line[x0..x0 + n], &line[x0 + 1..x0 + n + 1]);
            if a == b {
                for (px, a) in out_run.chunks_exact_mut(3).zip(a) {
                    for (o, &v) in px.iter_mut().zip(a) {
                        *o = gamma(v);
                    }
                }
            } else {
                for ((px, a), b) in out_run.chunks_exact_mut(3).zip(a).zip(b) {
                    for (ch, o) in px.iter_mut().enumerate() {
                        *o = gamma(f2.mean(a[ch], b[ch]));
                    }
                }
            }
        }
        *last = line[w - 1].map(gamma);
    }
}

/// [`read_out_fine`] for the 8-bit log code in [`Word8`]s: F2's first pass by the
/// [`PairMeans`] table into a line buffer of [`Line8`]s, the second by
/// [`PairMeans::mean_address`] into [`log8_gamma_table`]. Where a run of [`LOG8_RUN`]
/// pixels is flat (every word of the run and of the run below the same: a face of
/// one colour, the open sky) the first pass makes one half sum for the run; where
/// the line buffer is flat over a run and the pixel after it, the second pass makes
/// one output pixel for the run. The same bytes as `read_out_fine` (the tests
/// compare both with the reference readout).
#[allow(clippy::too_many_arguments, reason = "the readout's registers, passed as they are")]
fn read_out_log8(
    w: usize,
    h: usize,
    codes: &[Word8],
    filter: bool,
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
    rows: std::ops::Range<usize>,
    out: &mut [u8],
) {
    let segment = |y: usize, x0: usize| &codes[y * w + x0..(y + 1) * w];
    read_out_log8_from(w, h, &segment, filter, pairs, table, rows.clone(), out_rows(w, &rows, out));
}

/// `out` as the output rows of `rows` (`3 w` bytes each) for [`read_out_log8_from`].
fn out_rows<'o>(w: usize, rows: &std::ops::Range<usize>, out: &'o mut [u8]) -> std::slice::ChunksExactMut<'o, u8> {
    assert!(out.len() >= 3 * w * rows.len(), "out holds the rows");
    out[..3 * w * rows.len()].chunks_exact_mut(3 * w.max(1))
}

/// [`read_out_log8`] with row `y` read from `segment(y, x0)`: the words of pixels
/// `x0..` of row `y` up to the end of a segment (at least one pixel; segments start
/// at multiples of [`LOG8_RUN`] or at 0 and end there or at the row's end). A
/// matrix's readout reads each tile's pixels from the VP that owns it, with no copy
/// of the memories into one.
///
/// `out`: the output rows, `3 w` bytes each, one for each of `rows` (the rows of an
/// image, or of a strip of it: [`VideoBuffer::read_out_strip`]).
///
/// Its passes by the best copy the processor runs ([`Log8Passes`]): the portable one,
/// AVX-512 (BW and VBMI) by arithmetic on the codes and byte permutes, or AVX2 by
/// arithmetic on the codes and byte shuffles (the second pass for smooth runs, the
/// common case, else the portable one); the same half sums and table entries, so the
/// same bytes (tested against each other and the reference readout). On Zen 3 (no
/// AVX-512) the AVX2 copy takes default's readout from 54.1 to 29.5 M instructions and
/// about 6.3 to 4.4 ms (one thread, 1920 x 1080).
#[allow(clippy::too_many_arguments, reason = "the readout's registers, passed as they are")]
fn read_out_log8_from<'a, 'o>(
    w: usize,
    h: usize,
    segment: &impl Fn(usize, usize) -> &'a [Word8],
    filter: bool,
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
    rows: std::ops::Range<usize>,
    out: impl Iterator<Item = &'o mut [u8]>,
) {
    #[cfg(target_arch = "x86_64")]
    if let Some(passes) = Log8Avx512::detect() {
        return read_out_log8_rows(passes, w, h, segment, filter, pairs, table, rows, out);
    }
    #[cfg(target_arch = "x86_64")]
    if let Some(passes) = Log8Avx2::detect() {
        return passes.read_out_rows(w, h, segment, filter, pairs, table, rows, out);
    }
    read_out_log8_rows(Log8Portable, w, h, segment, filter, pairs, table, rows, out);
}

/// [`Log8Passes`] in AVX2 ([`read_out_log8_pass1_avx2`], [`read_out_log8_pass2_avx2`]);
/// made only by [`Log8Avx2::detect`], on a processor that has the feature.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Log8Avx2(());

#[cfg(target_arch = "x86_64")]
impl Log8Avx2 {
    /// The token if the processor has AVX2.
    #[inline]
    fn detect() -> Option<Self> {
        std::is_x86_feature_detected!("avx2").then_some(Self(()))
    }

    /// [`read_out_log8_rows`] with these passes, the whole loop compiled for AVX2 so
    /// that the first pass is inlined into it.
    #[inline]
    #[allow(clippy::too_many_arguments, reason = "the readout's registers, passed as they are")]
    fn read_out_rows<'a, 'o>(
        self,
        w: usize,
        h: usize,
        segment: &impl Fn(usize, usize) -> &'a [Word8],
        filter: bool,
        pairs: &PairMeans,
        table: &[u8; LOG8_ADDRESSES],
        rows: std::ops::Range<usize>,
        out: impl Iterator<Item = &'o mut [u8]>,
    ) {
        // SAFETY: a `Log8Avx2` is made only by `detect`, after the processor was
        // found to have the feature the function is compiled for.
        #[allow(unsafe_code, reason = "a function compiled for AVX2, on a processor found to have it")]
        unsafe {
            read_out_log8_rows_avx2(self, w, h, segment, filter, pairs, table, rows, out)
        }
    }
}

/// [`read_out_log8_rows`] compiled for AVX2 (see [`Log8Avx2::read_out_rows`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments, reason = "the readout's registers, passed as they are")]
fn read_out_log8_rows_avx2<'a, 'o>(
    passes: Log8Avx2,
    w: usize,
    h: usize,
    segment: &impl Fn(usize, usize) -> &'a [Word8],
    filter: bool,
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
    rows: std::ops::Range<usize>,
    out: impl Iterator<Item = &'o mut [u8]>,
) {
    read_out_log8_rows(passes, w, h, segment, filter, pairs, table, rows, out);
}

#[cfg(target_arch = "x86_64")]
impl Log8Passes for Log8Avx2 {
    #[inline(always)]
    fn flat(self, row: &[Word8; LOG8_RUN], below: &[Word8; LOG8_RUN]) -> bool {
        // SAFETY: as in `read_out_rows`.
        #[allow(unsafe_code, reason = "a function compiled for AVX2, on a processor found to have it")]
        unsafe {
            run_flat_avx2(row, below)
        }
    }

    #[inline(always)]
    fn pass1(
        self,
        line: &mut [Line8; LOG8_RUN],
        row: &[Word8; LOG8_RUN],
        below: &[Word8; LOG8_RUN],
        pairs: &PairMeans,
    ) {
        // SAFETY: as in `read_out_rows`.
        #[allow(unsafe_code, reason = "a function compiled for AVX2, on a processor found to have it")]
        unsafe {
            read_out_log8_pass1_avx2(line, row, below, pairs)
        }
    }

    #[inline(always)]
    fn pass2(
        self,
        out: &mut [u8; 3 * LOG8_RUN],
        run: &[Line8; LOG8_RUN + 1],
        pairs: &PairMeans,
        table: &[u8; LOG8_ADDRESSES],
    ) {
        // SAFETY: as in `read_out_rows`.
        #[allow(unsafe_code, reason = "a function compiled for AVX2, on a processor found to have it")]
        unsafe {
            read_out_log8_pass2_avx2(out, run, pairs, table)
        }
    }
}

/// Words `8 half .. 8 half + 8` of a run, one register, by `vlddqu` (as
/// [`load_window`]: the build's tuning splits an unaligned `vmovdqu` in two).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn words_avx2(run: &[Word8; LOG8_RUN], half: usize) -> __m256i {
    let part: &[Word8; 8] = run[8 * half..][..8].try_into().expect("8 words");
    // SAFETY: `part` is 32 bytes, which the load reads.
    #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
    unsafe {
        _mm256_lddqu_si256(part.as_ptr().cast())
    }
}

/// [`Log8Passes::flat`] in AVX2: the differing bits of the run's words from its
/// first word and from the words below, or-ed in two registers. (The portable
/// copy's comparison with an array of the first word built that array on the stack
/// and read it back, each 32-byte access split in two halves by the build's tuning.
/// With the line buffer's aligned stores ([`store_line8_avx2`]): the readout 29.5 ->
/// 28.3 M instructions on default, 19.8 -> 17.2 M on terrain, 1920 x 1080.)
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn run_flat_avx2(row: &[Word8; LOG8_RUN], below: &[Word8; LOG8_RUN]) -> bool {
    const WORDS: usize = 8;
    let first = _mm256_set1_epi32(row[0] as i32);
    let mut differ = _mm256_setzero_si256();
    for half in 0..LOG8_RUN / WORDS {
        let (a, b) = (words_avx2(row, half), words_avx2(below, half));
        differ = _mm256_or_si256(differ, _mm256_or_si256(_mm256_xor_si256(a, first), _mm256_xor_si256(a, b)));
    }
    _mm256_testz_si256(differ, differ) == 1
}

/// Entries of the table that one `vpshufb` reads ([`bytes16_avx2`]).
const SHUFFLE_TABLE: usize = 16;
/// Entries of a block of [`PairMeans::code_softplus`] that one `vpshufb` reads.
const SOFTPLUS_BLOCK: usize = SHUFFLE_TABLE;
/// Blocks of [`PairMeans::code_softplus`].
const SOFTPLUS_BLOCKS: usize = (1 << PAIR_MEANS_BITS) / SOFTPLUS_BLOCK;

/// Block `k` of [`PairMeans::code_softplus`] in both halves of a register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn block_avx2(table: &[u8; 1 << PAIR_MEANS_BITS], k: usize) -> __m256i {
    bytes16_avx2(&table[SOFTPLUS_BLOCK * k..])
}

/// The first [`SHUFFLE_TABLE`] bytes of `at` in both halves of a register (the
/// table a `vpshufb` reads).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn bytes16_avx2(at: &[u8]) -> __m256i {
    let part: &[u8; SHUFFLE_TABLE] = at[..SHUFFLE_TABLE].try_into().expect("16 bytes");
    // SAFETY: `part` is 16 bytes, which the load reads.
    #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
    let loaded = unsafe { _mm_loadu_si128(part.as_ptr().cast()) };
    _mm256_broadcastsi128_si256(loaded)
}

/// `T[4 k]` ([`PairMeans::code_softplus`]) at each byte `k` of `d`: the table's 16
/// blocks of 16 bytes each by `vpshufb` at the low four bits, then a tree of 15
/// byte blends chosen by bits 4, 5, 6 and 7 (each moved to the byte's top bit, which
/// `vpblendvb` reads).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn code_softplus_avx2(table: &[u8; 1 << PAIR_MEANS_BITS], d: __m256i) -> __m256i {
    let blocks: [__m256i; SOFTPLUS_BLOCKS] = std::array::from_fn(|k| block_avx2(table, k));
    let low = _mm256_and_si256(d, _mm256_set1_epi8(SOFTPLUS_BLOCK as i8 - 1));
    let mut level: [__m256i; SOFTPLUS_BLOCKS] = std::array::from_fn(|k| _mm256_shuffle_epi8(blocks[k], low));
    // (A 16-bit shift by `s` moves each byte's bit `7 - s` to its top bit.)
    let selectors = [_mm256_slli_epi16::<3>(d), _mm256_slli_epi16::<2>(d), _mm256_slli_epi16::<1>(d), d];
    let mut n = SOFTPLUS_BLOCKS;
    for sel in selectors {
        n /= 2;
        for k in 0..n {
            level[k] = _mm256_blendv_epi8(level[2 * k], level[2 * k + 1], sel);
        }
    }
    level[0]
}

/// [`Log8Portable::pass1`] in AVX2 by `PairMeans::mean_codes` (the tests') on the bytes of the
/// run (two registers of 8 words, 32 codes each): the larger and smaller codes and
/// their difference in bytes, `T[4 k]` by [`code_softplus_avx2`], 0 where the smaller
/// is zero; then in 16-bit lanes `4 hi - T[0] + T` raised to code 1, [`LOG8_ZERO`]
/// where both are zero and 0 in the spare lanes. No reads of the 128 KiB pair table,
/// which does not stay in L1.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn read_out_log8_pass1_avx2(
    line: &mut [Line8; LOG8_RUN],
    row: &[Word8; LOG8_RUN],
    below: &[Word8; LOG8_RUN],
    pairs: &PairMeans,
) {
    const WORDS: usize = 8;
    let zero = _mm256_setzero_si256();
    let (code_one, ln2) = (_mm256_set1_epi16(FINE_PER_CODE as i16), _mm256_set1_epi16(pairs.ln2));
    let log8_zero = _mm256_set1_epi16(LOG8_ZERO);
    // Each pixel's R, G, B lanes (the fourth, the word's zero byte, set to 0).
    let components = _mm256_set1_epi64x(0x0000_FFFF_FFFF_FFFF);
    for half in 0..LOG8_RUN / WORDS {
        let (a, b) = (words_avx2(row, half), words_avx2(below, half));
        let (hi, lo) = (_mm256_max_epu8(a, b), _mm256_min_epu8(a, b));
        let d = _mm256_sub_epi8(hi, lo);
        // Codes less than 16 apart (the common case) read the first block.
        let far = _mm256_subs_epu8(d, _mm256_set1_epi8(SOFTPLUS_BLOCK as i8 - 1));
        let t = if _mm256_testz_si256(far, far) != 0 {
            _mm256_shuffle_epi8(block_avx2(&pairs.code_softplus, 0), d)
        } else {
            code_softplus_avx2(&pairs.code_softplus, d)
        };
        let t = _mm256_andnot_si256(_mm256_cmpeq_epi8(lo, zero), t);
        for quarter in 0..2 {
            let (hi, t) = if quarter == 0 {
                (_mm256_castsi256_si128(hi), _mm256_castsi256_si128(t))
            } else {
                (_mm256_extracti128_si256::<1>(hi), _mm256_extracti128_si256::<1>(t))
            };
            let (hi, t) = (_mm256_cvtepu8_epi16(hi), _mm256_cvtepu8_epi16(t));
            let v = _mm256_add_epi16(_mm256_sub_epi16(_mm256_slli_epi16::<2>(hi), ln2), t);
            let v = _mm256_max_epi16(v, code_one);
            let v = _mm256_blendv_epi8(v, log8_zero, _mm256_cmpeq_epi16(hi, zero));
            let v = _mm256_and_si256(v, components);
            let dst: &mut [Line8; WORDS / 2] =
                (&mut line[WORDS * half + WORDS / 2 * quarter..][..WORDS / 2]).try_into().expect("4 pixels");
            store_line8_avx2(dst, v);
        }
    }
}

/// Stores `v` into the four [`Line8`]s of `dst`: by the aligned instruction when
/// `dst` is 32-byte aligned (the line buffer starts so, [`LINE8_ALIGN`], and its
/// segments start on cells of 4 pixels), else by the unaligned one, which the
/// build's tuning splits in two 16-byte halves.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn store_line8_avx2(dst: &mut [Line8; 4], v: __m256i) {
    let at = dst.as_mut_ptr().cast::<__m256i>();
    if at.is_aligned() {
        // SAFETY: `dst` is 32 bytes, which the store writes, at an address just
        // found 32-byte aligned.
        #[allow(unsafe_code, reason = "an aligned store of a register into an array of its size")]
        unsafe {
            _mm256_store_si256(at, v)
        }
    } else {
        // SAFETY: `dst` is 32 bytes, which the store writes.
        #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
        unsafe {
            _mm256_storeu_si256(at, v)
        }
    }
}

/// [`read_out_log8_pass2`] out of line: the AVX2 pass's way out for the runs that are
/// not smooth, kept out of that pass's body.
#[inline(never)]
fn read_out_log8_pass2_outlined(
    out: &mut [u8; 3 * LOG8_RUN],
    run: &[Line8; LOG8_RUN + 1],
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
) {
    read_out_log8_pass2(out, run, pairs, table);
}

/// Entries of a window of the second pass's tables that its AVX2 copy reads by one
/// byte shuffle: the run's differences `hi - lo` all below it (`T[0..16]`), and each
/// component's gamma addresses over the run within one window. On default, of the
/// runs that are not flat, 97 % have every difference below 16 and 90 % each
/// component's addresses within 16.
const LOG8_WINDOW: usize = SHUFFLE_TABLE;

/// [`read_out_log8_pass2`] in AVX2 for a smooth run (the common case: a shaded face,
/// neighbours a few quarter codes apart), else the portable pass. The run's 16
/// pixels and the one after as 64 `i16` lanes (four registers); `hi`, `lo` and
/// `d = hi - lo` as the portable pass makes them; if every `d` is below
/// [`LOG8_WINDOW`] and each component's addresses `hi - T[0] + T[d]` (as `u16`, as
/// the portable pass reads them) lie within a window from their least one, `T` is
/// read by one `vpshufb` from `T[0..16]` and the output by one `vpshufb` per
/// component from its window of the gamma table (two and a blend where a
/// component's addresses span up to [`LOG8_WIDE_WINDOW`]: [`gamma_pick_avx2`]), the
/// same entries as the portable pass reads (zero's address, 61440, reads the zeros
/// there: no masking); then the bytes packed into place.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn read_out_log8_pass2_avx2(
    out: &mut [u8; 3 * LOG8_RUN],
    run: &[Line8; LOG8_RUN + 1],
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
) {
    const LANES: usize = 16;
    const REGISTERS: usize = 4 * LOG8_RUN / LANES;
    let lanes = run.as_flattened();
    // (By `vlddqu`, one instruction: see [`words_avx2`].)
    let load = |at: usize| {
        let part: &[i16; LANES] = lanes[at..][..LANES].try_into().expect("16 lanes");
        // SAFETY: `part` is 32 bytes, which the load reads.
        #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
        unsafe {
            _mm256_lddqu_si256(part.as_ptr().cast())
        }
    };
    // (A lane's index with its high byte's top bit set: `vpshufb` gives 0 there, so
    // a 16-bit lane reads one entry.)
    let high_zero = _mm256_set1_epi16(0xFF00u16 as i16);
    let below_window = _mm256_set1_epi16((LOG8_WINDOW - 1) as i16);
    let ln2 = _mm256_set1_epi16(pairs.ln2);
    // A pixel's right neighbour is 4 lanes on.
    let (mut address, mut d) = ([_mm256_setzero_si256(); REGISTERS], [_mm256_setzero_si256(); REGISTERS]);
    for k in 0..REGISTERS {
        let (a, b) = (load(LANES * k), load(LANES * k + 4));
        let hi = _mm256_max_epi16(a, b);
        (address[k], d[k]) = (_mm256_sub_epi16(hi, ln2), _mm256_sub_epi16(hi, _mm256_min_epi16(a, b)));
    }
    let most = _mm256_max_epu16(_mm256_max_epu16(d[0], d[1]), _mm256_max_epu16(d[2], d[3]));
    let mut far = _mm256_subs_epu16(most, below_window);
    if _mm256_testz_si256(far, far) == 0 {
        return read_out_log8_pass2_outlined(out, run, pairs, table);
    }
    let softplus = bytes16_avx2(&pairs.softplus[..]);
    for k in 0..REGISTERS {
        let t = _mm256_shuffle_epi8(softplus, _mm256_or_si256(d[k], high_zero));
        address[k] = _mm256_add_epi16(address[k], t);
    }
    // Each component's least and largest address over the run (in every pixel's
    // lanes: the four registers, their halves, the two pixels of each half).
    let least = _mm256_min_epu16(_mm256_min_epu16(address[0], address[1]), _mm256_min_epu16(address[2], address[3]));
    let least = _mm256_min_epu16(least, _mm256_permute2x128_si256::<1>(least, least));
    let least = _mm256_min_epu16(least, _mm256_shuffle_epi32::<0b01_00_11_10>(least));
    let largest = _mm256_max_epu16(_mm256_max_epu16(address[0], address[1]), _mm256_max_epu16(address[2], address[3]));
    let largest = _mm256_max_epu16(largest, _mm256_permute2x128_si256::<1>(largest, largest));
    let largest = _mm256_max_epu16(largest, _mm256_shuffle_epi32::<0b01_00_11_10>(largest));
    let span = _mm256_sub_epi16(largest, least);
    far = _mm256_subs_epu16(span, below_window);
    let wide = _mm256_testz_si256(far, far) == 0;
    far = _mm256_subs_epu16(span, _mm256_set1_epi16((LOG8_WIDE_WINDOW - 1) as i16));
    // (The three lanes by extracts: a store of the register to a buffer on the
    // stack was split in two halves by the build's tuning and reloaded.)
    let least_low = _mm256_castsi256_si128(least);
    let bases = [
        _mm_extract_epi16::<0>(least_low) as usize,
        _mm_extract_epi16::<1>(least_low) as usize,
        _mm_extract_epi16::<2>(least_low) as usize,
    ];
    let reach = if wide { LOG8_WIDE_WINDOW } else { LOG8_WINDOW };
    if _mm256_testz_si256(far, far) == 0 || bases.iter().any(|&b| b > LOG8_ADDRESSES - reach) {
        return read_out_log8_pass2_outlined(out, run, pairs, table);
    }
    let windows = bases.map(|b| bytes16_avx2(&table[b..]));
    let packed = if wide {
        let upper = bases.map(|b| bytes16_avx2(&table[b + LOG8_WINDOW..]));
        gamma_pick_avx2::<true>(&address, least, windows, upper)
    } else {
        gamma_pick_avx2::<false>(&address, least, windows, windows)
    };
    store_pixels_avx2(out, packed);
}

/// The entries of a gamma window a component's addresses over a run may span for
/// [`read_out_log8_pass2_avx2`] to read them by two byte shuffles and a blend (two
/// [`LOG8_WINDOW`]s): on default, of the non-flat runs whose differences are below
/// the window, ~10 % have a component's addresses over more than one window.
const LOG8_WIDE_WINDOW: usize = 2 * LOG8_WINDOW;

/// The output bytes of [`read_out_log8_pass2_avx2`]'s run from its gamma addresses
/// (four registers of the run's 16 pixels' lanes) less each component's `least`:
/// each component's entry from its window (`lower`, the table from the least
/// address on) by one byte shuffle, or with `WIDE` from the two windows `lower` and
/// `upper` (the next [`LOG8_WINDOW`] entries) by two and a blend on the index's
/// bit 4; the three components' lanes blended into one register and packed to
/// bytes, pixels `0, 1, 4, 5 | 2, 3, 6, 7` of each pair of registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn gamma_pick_avx2<const WIDE: bool>(
    address: &[__m256i; 4],
    least: __m256i,
    lower: [__m256i; 3],
    upper: [__m256i; 3],
) -> [__m256i; 2] {
    // (A lane's index with its high byte's top bit set: `vpshufb` gives 0 there, so
    // a 16-bit lane reads one entry.)
    let high_zero = _mm256_set1_epi16(0xFF00u16 as i16);
    // Lanes of R and of G (the rest, B and the spare lanes, take B's window).
    let (red, green) = (_mm256_set1_epi64x(0xFFFF), _mm256_set1_epi64x(0xFFFF_0000));
    let mut packed = [_mm256_setzero_si256(); 2];
    for (k, packed) in packed.iter_mut().enumerate() {
        let index = |r: usize| _mm256_or_si256(_mm256_sub_epi16(address[r], least), high_zero);
        let (i0, i1) = (index(2 * k), index(2 * k + 1));
        let pick = |i: __m256i| {
            let entry = |c: usize| {
                let low = _mm256_shuffle_epi8(lower[c], i);
                if WIDE {
                    // (Bit 4 of the low byte moved to its top bit, which the blend
                    // reads; the high bytes are 0 in both.)
                    _mm256_blendv_epi8(low, _mm256_shuffle_epi8(upper[c], i), _mm256_slli_epi16::<3>(i))
                } else {
                    low
                }
            };
            let rgb = [entry(0), entry(1), entry(2)];
            _mm256_blendv_epi8(_mm256_blendv_epi8(rgb[2], rgb[1], green), rgb[0], red)
        };
        *packed = _mm256_packus_epi16(pick(i0), pick(i1));
    }
    packed
}

/// Stores 16 pixels' output bytes, each pixel's R, G, B in the first three bytes of
/// a dword, in two registers of pixels `0, 1, 4, 5 | 2, 3, 6, 7` (and 8 on): their
/// dwords put in order and squeezed to 12 bytes per 128-bit half, written by
/// overlapping stores in order straight into `out` (each writes the 4 bytes the
/// previous one left undefined), the last by 8 and 4 bytes. (Through a buffer on the
/// stack, the 16-byte reads across two stores miss store forwarding.)
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn store_pixels_avx2(out: &mut [u8; 3 * LOG8_RUN], packed: [__m256i; 2]) {
    const NONE: i8 = -1;
    const QUARTER: usize = 3 * LOG8_RUN / 4;
    let order = _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7);
    let squeeze = _mm256_setr_epi8(
        0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, NONE, NONE, NONE, NONE, 0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, NONE,
        NONE, NONE, NONE,
    );
    let [a, b] = packed.map(|v| _mm256_shuffle_epi8(_mm256_permutevar8x32_epi32(v, order), squeeze));
    let (first, last) = out.split_at_mut(3 * QUARTER);
    let (first, last): (&mut [u8; 3 * QUARTER], &mut [u8; QUARTER]) =
        (first.try_into().expect("36 bytes"), last.try_into().expect("12 bytes"));
    let d = _mm256_extracti128_si256::<1>(b);
    // SAFETY: the 16-byte stores write bytes 0..16, 12..28 and 24..40 of `out`, whose
    // first 36 bytes `first` is, and `last` is 12 bytes, which the 8- and 4-byte
    // stores write.
    #[allow(unsafe_code, reason = "unaligned stores into arrays")]
    unsafe {
        _mm_storeu_si128(first.as_mut_ptr().cast(), _mm256_castsi256_si128(a));
        _mm_storeu_si128(first[QUARTER..].as_mut_ptr().cast(), _mm256_extracti128_si256::<1>(a));
        _mm_storeu_si128(first[2 * QUARTER..].as_mut_ptr().cast(), _mm256_castsi256_si128(b));
        _mm_storel_epi64(last.as_mut_ptr().cast(), d);
        _mm_storeu_si32(last[8..].as_mut_ptr().cast(), _mm_srli_si128::<8>(d));
    }
}

/// F2's first pass over a run of [`LOG8_RUN`] pixels that is not flat: `line[i]` the
/// [`PairMeans::mean_words`] of `row[i]` and `below[i]` (the spare lane 0).
trait Log8Passes: Copy {
    /// The run's half sums.
    fn pass1(self, line: &mut [Line8; LOG8_RUN], row: &[Word8; LOG8_RUN], below: &[Word8; LOG8_RUN], pairs: &PairMeans);

    /// Whether a run is flat: every word of the run (`row`) and of the run below
    /// it the same.
    #[inline(always)]
    fn flat(self, row: &[Word8; LOG8_RUN], below: &[Word8; LOG8_RUN]) -> bool {
        // (Array comparisons of eight words: the compiler compares them in vector
        // registers; of more, it calls `memcmp`.)
        let same = |a: &[Word8], b: &[Word8]| {
            let eight = |s: &[Word8]| <[Word8; 8]>::try_from(s).expect("eight words");
            a.chunks_exact(8).zip(b.chunks_exact(8)).all(|(a, b)| eight(a) == eight(b))
        };
        same(row, &[row[0]; LOG8_RUN]) && same(row, below)
    }

    /// F2's second pass over a run that is not flat and the pixel after it,
    /// [`read_out_log8_pass2`].
    #[inline(always)]
    fn pass2(
        self,
        out: &mut [u8; 3 * LOG8_RUN],
        run: &[Line8; LOG8_RUN + 1],
        pairs: &PairMeans,
        table: &[u8; LOG8_ADDRESSES],
    ) {
        read_out_log8_pass2(out, run, pairs, table);
    }
}

/// [`Log8Passes`] for the build's target, whatever the processor: the pair table.
#[derive(Clone, Copy)]
struct Log8Portable;

impl Log8Passes for Log8Portable {
    #[inline(always)]
    fn pass1(
        self,
        line: &mut [Line8; LOG8_RUN],
        row: &[Word8; LOG8_RUN],
        below: &[Word8; LOG8_RUN],
        pairs: &PairMeans,
    ) {
        // The table's addresses `a << 8 | b` of every component side by side: the
        // bytes of the two runs interleaved, then one read per component. (The
        // spare lanes stay 0.)
        let (a, b) = (row.map(u32::to_le_bytes), below.map(u32::to_le_bytes));
        let (a, b) = (a.as_flattened(), b.as_flattened());
        let mut address = [[0u8; 2]; 4 * LOG8_RUN];
        for (k, address) in address.iter_mut().enumerate() {
            *address = [b[k], a[k]];
        }
        for (i, l) in line.iter_mut().enumerate() {
            for (ch, l) in l[..3].iter_mut().enumerate() {
                *l = pairs.means[usize::from(u16::from_le_bytes(address[4 * i + ch]))];
            }
        }
    }
}

/// [`Log8Passes`] in AVX-512 ([`read_out_log8_pass1_avx512`]); made only by
/// [`Log8Avx512::detect`], on a processor that has the features.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Log8Avx512(());

#[cfg(target_arch = "x86_64")]
impl Log8Avx512 {
    /// The token if the AVX-512 copies run ([`crate::isa::avx512_copies`]: asked for,
    /// on a processor with AVX-512F; the AVX2 passes are the faster on a Zen 4) and
    /// the processor has AVX-512 BW and VBMI too.
    #[inline]
    fn detect() -> Option<Self> {
        (crate::isa::avx512_copies()
            && std::is_x86_feature_detected!("avx512bw")
            && std::is_x86_feature_detected!("avx512vbmi"))
        .then_some(Self(()))
    }
}

#[cfg(target_arch = "x86_64")]
impl Log8Passes for Log8Avx512 {
    #[inline(always)]
    fn pass1(
        self,
        line: &mut [Line8; LOG8_RUN],
        row: &[Word8; LOG8_RUN],
        below: &[Word8; LOG8_RUN],
        pairs: &PairMeans,
    ) {
        // SAFETY: a `Log8Avx512` is made only by `detect`, after the processor was
        // found to have the features the function is compiled for.
        #[allow(unsafe_code, reason = "a function compiled for AVX-512, on a processor found to have it")]
        unsafe {
            read_out_log8_pass1_avx512(line, row, below, pairs)
        }
    }

    #[inline(always)]
    fn pass2(
        self,
        out: &mut [u8; 3 * LOG8_RUN],
        run: &[Line8; LOG8_RUN + 1],
        pairs: &PairMeans,
        table: &[u8; LOG8_ADDRESSES],
    ) {
        // SAFETY: as in `pass1`.
        #[allow(unsafe_code, reason = "a function compiled for AVX-512, on a processor found to have it")]
        unsafe {
            read_out_log8_pass2_avx512(out, run, pairs, table)
        }
    }
}

/// [`read_out_log8_from`]'s rows with the first pass of `pass1`.
#[inline(always)]
#[allow(clippy::too_many_arguments, reason = "the readout's registers, passed as they are")]
fn read_out_log8_rows<'a, 'o>(
    passes: impl Log8Passes,
    w: usize,
    h: usize,
    segment: &impl Fn(usize, usize) -> &'a [Word8],
    filter: bool,
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
    rows: std::ops::Range<usize>,
    out: impl Iterator<Item = &'o mut [u8]>,
) {
    if w == 0 || rows.is_empty() {
        return;
    }
    // A loaded code or a first-pass mean (`LOG8_ZERO` or at least code 1) is its own
    // address in the 8-bit gamma table.
    let pixel = |l: Line8| [0, 1, 2].map(|ch| table[usize::from(l[ch] as u16)]);
    // The line buffer: pass 1's half sums, of a flat run only the first. It starts
    // on a 32-byte boundary ([`LINE8_ALIGN`]), so that the AVX2 passes' 32-byte
    // accesses at the runs' starts are aligned.
    let mut line_storage: Vec<Line8> = vec![[0; 4]; w + LINE8_ALIGN / size_of::<Line8>() - 1];
    let skip = line_storage.as_ptr().align_offset(LINE8_ALIGN).min(line_storage.len() - w);
    let line = &mut line_storage[skip..skip + w];
    // Per run of the line buffer: whether pass 1 found it flat.
    let mut flat_runs = vec![false; w.div_ceil(LOG8_RUN)];
    // The last flat run's word and its half sum (flat areas repeat them).
    let mut flat_mean: (Word8, Line8) = (0, pairs.mean_words(0, 0));
    // The last flat run's value and its output bytes, a whole run's (copied as one
    // block of 48 bytes: three 16-byte stores).
    let run_bytes = |value: Line8| -> [u8; 3 * LOG8_RUN] {
        let words = pattern(pixel(value));
        let mut bytes = [0; 3 * LOG8_RUN];
        for (o, p) in bytes.chunks_exact_mut(8).zip(words.iter().cycle()) {
            o.copy_from_slice(&p.to_le_bytes());
        }
        bytes
    };
    let mut flat_out: (Line8, [u8; 3 * LOG8_RUN]) = (flat_mean.1, run_bytes(flat_mean.1));
    for (y, out_row) in rows.zip(out) {
        assert_eq!(out_row.len(), 3 * w, "an output row of the row's pixels");
        if !filter {
            let mut x0 = 0;
            while x0 < w {
                let row = segment(y, x0);
                for (px, &word) in out_row[3 * x0..].chunks_exact_mut(3).zip(row) {
                    px.copy_from_slice(&pixel(pairs.mean_words(word, word)));
                }
                x0 += row.len();
            }
            continue;
        }
        let below_y = (y + 1).min(h - 1);
        // The whole runs from the row's start whose every word, and every word
        // below, is the row's first (the open sky): their half sums are that word's
        // mean with itself, so each is a flat run (found here a run at a time, as
        // pass 1 would, with no loop of its own); a row of them all and nothing
        // else, its output is the flat runs' bytes over and over.
        let (word, uniform) = uniform_runs(segment, w, y, below_y);
        if uniform > 0 {
            if flat_mean.0 != word {
                flat_mean = (word, pairs.mean_words(word, word));
            }
            let value = flat_mean.1;
            if uniform == w {
                if flat_out.0 != value {
                    flat_out = (value, run_bytes(value));
                }
                for out_run in out_row.chunks_exact_mut(3 * LOG8_RUN) {
                    out_run.copy_from_slice(&flat_out.1);
                }
                continue;
            }
            for k in 0..uniform / LOG8_RUN {
                flat_runs[k] = true;
                line[k * LOG8_RUN] = value;
            }
        }
        // Pass 1: half sums of vertically adjacent pixels, a segment at a time (the
        // shorter of the row's and the row below's), after the uniform runs.
        let mut x0 = uniform;
        while x0 < w {
            let (row, below) = (segment(y, x0), segment(below_y, x0));
            let n = row.len().min(below.len());
            let (line, flat_runs) = (&mut line[x0..x0 + n], &mut flat_runs[x0 / LOG8_RUN..]);
            read_out_log8_pass1(passes, line, &row[..n], &below[..n], flat_runs, &mut flat_mean, pairs);
            x0 += n;
        }
        // Pass 2: half sums of horizontally adjacent ones, a run at a time; the
        // last column's own value stands in for its right neighbour, and its mean
        // with itself is itself.
        let mut runs_out = out_row.chunks_exact_mut(3 * LOG8_RUN);
        for (k, out_run) in runs_out.by_ref().enumerate() {
            let out_run: &mut [u8; 3 * LOG8_RUN] = out_run.try_into().expect("a whole run");
            let x0 = k * LOG8_RUN;
            // The first pixel after the run, if there is one.
            let next = line.get(x0 + LOG8_RUN);
            if flat_runs[k] {
                // Every half sum of the run's pixels but the last is its value (the
                // mean of a value with itself), and so is the last's if the pixel
                // after it has the value or there is none.
                let value = line[x0];
                if flat_out.0 != value {
                    flat_out = (value, run_bytes(value));
                }
                *out_run = flat_out.1;
                match next {
                    Some(next) if *next != value => {
                        out_run[3 * (LOG8_RUN - 1)..].copy_from_slice(&pairs.output(value, *next, table));
                    }
                    _ => {}
                }
            } else if next.is_some() {
                let run = line[x0..=x0 + LOG8_RUN].try_into().expect("a run and the pixel after it");
                passes.pass2(out_run, run, pairs, table);
            } else {
                // The row's last whole run (and a strip's, [`VideoBuffer::read_out_strip`]):
                // its last value stands in for the pixel after it, as in
                // [`read_out_log8_pass2_end`], by the run's pass (default at 1920 x
                // 1080 on two VPs: readout 24.8 -> 22.7 M instructions a frame).
                let mut run = [line[x0 + LOG8_RUN - 1]; LOG8_RUN + 1];
                run[..LOG8_RUN].copy_from_slice(&line[x0..x0 + LOG8_RUN]);
                passes.pass2(out_run, &run, pairs, table);
            }
        }
        // The row's last run if it is short (pass 1 made it a tail, never flat).
        let x0 = w / LOG8_RUN * LOG8_RUN;
        read_out_log8_pass2_end(runs_out.into_remainder(), &line[x0..], pairs, table);
    }
}

/// Row `y`'s first word and how many of the pixels `0..w` of rows `y` and `below`
/// (read by `segment` as [`read_out_log8_from`]'s) hold it in both, counted in
/// whole runs of [`LOG8_RUN`] from the start: `w` only when `w` is a whole number
/// of runs and both rows are that word throughout. Each run's 32 words are
/// compared at once (the compiler does it in vector registers), the same work as
/// the first pass's test of a flat run, which these runs then skip.
#[inline(always)]
fn uniform_runs<'a>(
    segment: &impl Fn(usize, usize) -> &'a [Word8],
    w: usize,
    y: usize,
    below: usize,
) -> (Word8, usize) {
    let word = segment(y, 0)[0];
    let whole = w / LOG8_RUN * LOG8_RUN;
    let mut x0 = 0;
    while x0 < whole {
        let (a, b) = (segment(y, x0), segment(below, x0));
        let n = a.len().min(b.len()).min(whole - x0) / LOG8_RUN * LOG8_RUN;
        if n == 0 {
            break;
        }
        for (a, b) in a[..n].chunks_exact(LOG8_RUN).zip(b[..n].chunks_exact(LOG8_RUN)) {
            if a.iter().zip(b).fold(0, |d, (&p, &q)| d | (p ^ word) | (q ^ word)) != 0 {
                return (word, x0);
            }
            x0 += LOG8_RUN;
        }
    }
    (word, x0)
}

/// F2's second pass over the last pixels of a row (`line`: their half sums from
/// pass 1), the last one's own value standing in for its right neighbour.
#[inline(always)]
fn read_out_log8_pass2_end(out: &mut [u8], line: &[Line8], pairs: &PairMeans, table: &[u8; LOG8_ADDRESSES]) {
    for (i, px) in out.chunks_exact_mut(3).enumerate() {
        px.copy_from_slice(&pairs.output(line[i], line[(i + 1).min(line.len() - 1)], table));
    }
}

/// The output bytes of eight pixels of one colour (the definition of [`pattern`]).
#[cfg(test)]
fn pattern_bytes(rgb: [u8; 3]) -> [u8; 3 * 8] {
    std::array::from_fn(|i| rgb[i % 3])
}

/// The output bytes of eight pixels of one colour (a run of one colour repeats
/// them) as three little-endian words, made by shifts (from bytes, the compiler
/// keeps them apart and stores them one by one).
#[inline(always)]
fn pattern(rgb: [u8; 3]) -> [u64; 3] {
    const BYTE: u32 = 8;
    let w = u64::from(rgb[0]) | u64::from(rgb[1]) << BYTE | u64::from(rgb[2]) << (2 * BYTE);
    // Bytes 0..8: r g b r g b r g; 8..16: b r g b r g b r; 16..24: g b r g b r g b.
    [
        w | w << (3 * BYTE) | w << (6 * BYTE),
        w >> (2 * BYTE) | w << BYTE | w << (4 * BYTE) | w << (7 * BYTE),
        w >> BYTE | w << (2 * BYTE) | w << (5 * BYTE),
    ]
}

/// F2's first pass over a stretch of a row (`row`) and the row below it, into the
/// line buffer, a run of [`LOG8_RUN`] at a time. A flat run (every word of the run and
/// of the run below the same) is recorded in `flat_runs` and its one half sum
/// written to its first pixel only; `flat_mean` keeps the last flat run's word and
/// half sum, which the next flat run most likely repeats.
#[inline(always)]
fn read_out_log8_pass1(
    passes: impl Log8Passes,
    line: &mut [Line8],
    row: &[Word8],
    below: &[Word8],
    flat_runs: &mut [bool],
    flat_mean: &mut (Word8, Line8),
    pairs: &PairMeans,
) {
    let (runs, below_runs) = (row.chunks_exact(LOG8_RUN), below.chunks_exact(LOG8_RUN));
    let whole = row.len() / LOG8_RUN * LOG8_RUN;
    for (((l, a), b), flat_run) in line.chunks_exact_mut(LOG8_RUN).zip(runs).zip(below_runs).zip(&mut *flat_runs) {
        let l: &mut [Line8; LOG8_RUN] = l.try_into().expect("a whole run");
        let (a, b): (&[Word8; LOG8_RUN], &[Word8; LOG8_RUN]) =
            (a.try_into().expect("a whole run"), b.try_into().expect("a whole run"));
        let first = a[0];
        let flat = passes.flat(a, b);
        *flat_run = flat;
        if flat {
            if flat_mean.0 != first {
                *flat_mean = (first, pairs.mean_words(first, first));
            }
            l[0] = flat_mean.1;
        } else {
            passes.pass1(l, a, b, pairs);
        }
    }
    if whole < row.len() {
        flat_runs[whole / LOG8_RUN] = false;
        for ((l, &a), &b) in line[whole..].iter_mut().zip(&row[whole..]).zip(&below[whole..]) {
            *l = pairs.mean_words(a, b);
        }
    }
}

/// F2's second pass over a run of [`LOG8_RUN`] pixels and the one after it: the
/// larger operands less `T[0]` and the differences side by side (the compiler
/// lays them out in vector registers), then two table reads per component.
#[inline(always)]
fn read_out_log8_pass2(
    out: &mut [u8; 3 * LOG8_RUN],
    run: &[Line8; LOG8_RUN + 1],
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
) {
    let (a, b) = (run[..LOG8_RUN].as_flattened(), run[1..].as_flattened());
    let (a, b): (&[i16; 4 * LOG8_RUN], &[i16; 4 * LOG8_RUN]) =
        (a.try_into().expect("a run of lanes"), b.try_into().expect("a run of lanes"));
    let (mut hi, mut d) = ([0i16; 4 * LOG8_RUN], [0u16; 4 * LOG8_RUN]);
    for j in 0..4 * LOG8_RUN {
        (hi[j], d[j]) = (a[j].max(b[j]).wrapping_sub(pairs.ln2), a[j].max(b[j]).wrapping_sub(a[j].min(b[j])) as u16);
    }
    for (i, px) in out.chunks_exact_mut(3).enumerate() {
        for (ch, o) in px.iter_mut().enumerate() {
            let j = 4 * i + ch;
            let t = pairs.softplus[usize::from(d[j])];
            *o = table[usize::from(PairMeans::address(hi[j], t))];
        }
    }
}

/// [`Log8Portable::pass1`] in AVX-512 by `PairMeans::mean_codes` (the tests') on the bytes of
/// the run (one register: 16 words, 64 codes): the larger and smaller codes and their
/// difference in bytes, `T[4 k]` by two two-register byte permutes (128 entries
/// each) chosen by the difference's top bit, 0 where the smaller is zero; then in
/// 16-bit lanes `4 hi - T[0] + T` raised to code 1, [`LOG8_ZERO`] where both are
/// zero and 0 in the spare lanes: 32 lanes, 8 pixels' [`Line8`]s, per register.
/// No table reads: the pair table's 128 KiB does not stay in L1.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vbmi")]
fn read_out_log8_pass1_avx512(
    line: &mut [Line8; LOG8_RUN],
    row: &[Word8; LOG8_RUN],
    below: &[Word8; LOG8_RUN],
    pairs: &PairMeans,
) {
    const QUARTER: usize = 64;
    // SAFETY: `row`, `below` and the table's quarters are 64 bytes each, which the
    // loads read.
    #[allow(unsafe_code, reason = "unaligned loads of arrays of a register's size")]
    let (a, b, t) = unsafe {
        let t = |k: usize| _mm512_loadu_si512(pairs.code_softplus[QUARTER * k..].as_ptr().cast());
        (_mm512_loadu_si512(row.as_ptr().cast()), _mm512_loadu_si512(below.as_ptr().cast()), [t(0), t(1), t(2), t(3)])
    };
    let (hi, lo) = (_mm512_max_epu8(a, b), _mm512_min_epu8(a, b));
    let d = _mm512_sub_epi8(hi, lo);
    // `T[4 d]`: entries `d mod 128` of the table's first or second half.
    let first = _mm512_permutex2var_epi8(t[0], d, t[1]);
    let second = _mm512_permutex2var_epi8(t[2], d, t[3]);
    let t = _mm512_mask_blend_epi8(_mm512_movepi8_mask(d), first, second);
    let t = _mm512_maskz_mov_epi8(_mm512_test_epi8_mask(lo, lo), t);
    // Each pixel's R, G, B lanes (the fourth, the word's zero byte, set to 0).
    const COMPONENTS: u32 = 0x7777_7777;
    let (code_one, ln2) = (_mm512_set1_epi16(FINE_PER_CODE as i16), _mm512_set1_epi16(pairs.ln2));
    for half in 0..2 {
        let (hi, t) = if half == 0 {
            (_mm512_castsi512_si256(hi), _mm512_castsi512_si256(t))
        } else {
            (_mm512_extracti64x4_epi64::<1>(hi), _mm512_extracti64x4_epi64::<1>(t))
        };
        let (hi, t) = (_mm512_cvtepu8_epi16(hi), _mm512_cvtepu8_epi16(t));
        let v = _mm512_add_epi16(_mm512_sub_epi16(_mm512_slli_epi16::<2>(hi), ln2), t);
        let v = _mm512_max_epi16(v, code_one);
        let v = _mm512_mask_mov_epi16(v, _mm512_testn_epi16_mask(hi, hi), _mm512_set1_epi16(LOG8_ZERO));
        let v = _mm512_maskz_mov_epi16(COMPONENTS, v);
        let dst: &mut [Line8; LOG8_RUN / 2] =
            (&mut line[LOG8_RUN / 2 * half..][..LOG8_RUN / 2]).try_into().expect("8 pixels");
        // SAFETY: `dst` is 64 bytes, which the store writes.
        #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
        unsafe {
            _mm512_storeu_si512(dst.as_mut_ptr().cast(), v)
        }
    }
}

/// Entries of the second pass's tables that its AVX-512 copy reads: `T[d]` is 0
/// from `d = 988` on, and a mean's gamma address is at most `4 Q1 = 1020`.
const LOG8_SHORT_TABLE: usize = 1024;

/// 64 bytes of `table[..LOG8_SHORT_TABLE]` at indices `low[7:0] | high[1:0] << 8`
/// (each byte lane of `low` and `high`): the eight 128-byte blocks by two-register
/// byte permutes (`vpermi2b`, the index's low 7 bits), chosen by bits 7, 8 and 9.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vbmi")]
#[inline]
fn lookup1024_avx512(table: &[u8; LOG8_SHORT_TABLE], low: __m512i, high: __m512i) -> __m512i {
    const BLOCK: usize = 64;
    let mut blocks = [_mm512_setzero_si512(); LOG8_SHORT_TABLE / BLOCK];
    for (k, b) in blocks.iter_mut().enumerate() {
        let part: &[u8; BLOCK] = table[BLOCK * k..][..BLOCK].try_into().expect("a block");
        // SAFETY: `part` is 64 bytes, which the load reads.
        #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
        let loaded = unsafe { _mm512_loadu_si512(part.as_ptr().cast()) };
        *b = loaded;
    }
    let bit7 = _mm512_movepi8_mask(low);
    let mut quarters = [_mm512_setzero_si512(); 4];
    for (k, q) in quarters.iter_mut().enumerate() {
        let (a, b, c, d) = (blocks[4 * k], blocks[4 * k + 1], blocks[4 * k + 2], blocks[4 * k + 3]);
        *q = _mm512_mask_blend_epi8(bit7, _mm512_permutex2var_epi8(a, low, b), _mm512_permutex2var_epi8(c, low, d));
    }
    let bit8 = _mm512_test_epi8_mask(high, _mm512_set1_epi8(1));
    let bit9 = _mm512_test_epi8_mask(high, _mm512_set1_epi8(2));
    let halves = [
        _mm512_mask_blend_epi8(bit8, quarters[0], quarters[1]),
        _mm512_mask_blend_epi8(bit8, quarters[2], quarters[3]),
    ];
    _mm512_mask_blend_epi8(bit9, halves[0], halves[1])
}

/// The first [`LOG8_SHORT_TABLE`] entries of a table of the second pass.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn short_table(table: &[u8; LOG8_ADDRESSES]) -> &[u8; LOG8_SHORT_TABLE] {
    table[..LOG8_SHORT_TABLE].try_into().expect("1024 entries")
}

/// The 64 `i16` lanes of two registers as their low bytes and their bits `[9:8]` in
/// two registers of 64 bytes (lane order kept).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vbmi")]
#[inline]
fn index_bytes_avx512(v: [__m512i; 2]) -> (__m512i, __m512i) {
    let join = |a: __m256i, b: __m256i| _mm512_inserti64x4::<1>(_mm512_castsi256_si512(a), b);
    (
        join(_mm512_cvtepi16_epi8(v[0]), _mm512_cvtepi16_epi8(v[1])),
        join(_mm512_cvtepi16_epi8(_mm512_srli_epi16::<8>(v[0])), _mm512_cvtepi16_epi8(_mm512_srli_epi16::<8>(v[1]))),
    )
}

/// [`read_out_log8_pass2`] in AVX-512 (BW, VBMI): the run's 16 pixels and the
/// one after as 64 `i16` lanes (two registers, the spare lanes' results unused);
/// `hi - lo` clamped to 1023 (`T` is 0 there as at every larger difference) and
/// `T` at it by [`lookup1024_avx512`]; the address `hi - T[0] + T` raised to 0
/// (the gamma table's entries below 0 and 0..4 are all code 1's output) and the
/// output by the same look-up in the gamma table's first 1024 entries, 0 where
/// both operands are zero (`hi` negative: [`LOG8_ZERO`]); then the 48 bytes packed
/// by one byte permute and stored under a mask.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vbmi")]
fn read_out_log8_pass2_avx512(
    out: &mut [u8; 3 * LOG8_RUN],
    run: &[Line8; LOG8_RUN + 1],
    pairs: &PairMeans,
    table: &[u8; LOG8_ADDRESSES],
) {
    const LANES: usize = 32;
    let lanes = run.as_flattened();
    let load = |at: usize| {
        let part: &[i16; LANES] = lanes[at..][..LANES].try_into().expect("32 lanes");
        // SAFETY: `part` is 64 bytes, which the load reads.
        #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
        unsafe {
            _mm512_loadu_si512(part.as_ptr().cast())
        }
    };
    // A pixel's right neighbour is 4 lanes on.
    let (a, b) = ([load(0), load(LANES)], [load(4), load(LANES + 4)]);
    let hi = [_mm512_max_epi16(a[0], b[0]), _mm512_max_epi16(a[1], b[1])];
    let top = _mm512_set1_epi16((LOG8_SHORT_TABLE - 1) as i16);
    let d = [0, 1].map(|k| _mm512_min_epu16(_mm512_sub_epi16(hi[k], _mm512_min_epi16(a[k], b[k])), top));
    let (low, high) = index_bytes_avx512(d);
    let t = lookup1024_avx512(short_table(&pairs.softplus), low, high);
    let t = [_mm512_cvtepu8_epi16(_mm512_castsi512_si256(t)), _mm512_cvtepu8_epi16(_mm512_extracti64x4_epi64::<1>(t))];
    let ln2 = _mm512_set1_epi16(pairs.ln2);
    let address =
        [0, 1].map(|k| _mm512_max_epi16(_mm512_add_epi16(_mm512_sub_epi16(hi[k], ln2), t[k]), _mm512_setzero_si512()));
    let (low, high) = index_bytes_avx512(address);
    let g = lookup1024_avx512(short_table(table), low, high);
    let zero = _mm512_kunpackd(u64::from(_mm512_movepi16_mask(hi[1])), u64::from(_mm512_movepi16_mask(hi[0])));
    let g = _mm512_maskz_mov_epi8(!zero, g);
    // Byte `3 i + ch` of the output is lane `4 i + ch`.
    let pack: [u8; 64] = std::array::from_fn(|j| if j < 3 * LOG8_RUN { (4 * (j / 3) + j % 3) as u8 } else { 0 });
    // SAFETY: `pack` is 64 bytes, which the load reads; the masked store writes the
    // mask's 48 bytes, `out`'s.
    #[allow(unsafe_code, reason = "a load of an array of a register's size, a masked store into `out`")]
    unsafe {
        let g = _mm512_permutexvar_epi8(_mm512_loadu_si512(pack.as_ptr().cast()), g);
        _mm512_mask_storeu_epi8(out.as_mut_ptr().cast(), (1u64 << (3 * LOG8_RUN)) - 1, g);
    }
}

/// F2's three operands of the 8-bit code, R, G, B and a zero: eight bytes, compared
/// and filled at once.
type Line8 = [i16; 4];

/// The alignment of the readout's line buffer (of [`Line8`]s): a 256-bit
/// register's, so that the AVX2 passes' accesses at the starts of runs and of their
/// quarters may use the aligned instructions, which the build's x86-64-v2 tuning
/// (Sandy Bridge's) does not split in two 16-byte halves as it does the unaligned.
const LINE8_ALIGN: usize = 32;

/// The float path's gamma table: linear intensity (`GAMMA_TABLE_SIZE` steps over
/// 0..1) to 8-bit display code, `255 x^(1/gamma)` rounded.
pub fn gamma_table(gamma: f32) -> Vec<u8> {
    (0..GAMMA_TABLE_SIZE)
        .map(|i| {
            let x = i as f64 / (GAMMA_TABLE_SIZE - 1) as f64;
            (OUTPUT_MAX * x.powf(1.0 / f64::from(gamma))).round() as u8
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*, for test inputs.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }

        /// A code, zero about one time in eight.
        fn code(&mut self, one: u16) -> u16 {
            let r = self.next();
            if r.is_multiple_of(8) {
                0
            } else {
                (r >> 8) as u16 % one + 1
            }
        }
    }

    /// F2's operands of a bit count: zero and every quarter code from code 1 to Q1,
    /// all of them (8 and 9 bits) or every `step`-th (plus both ends).
    fn f2_operands(s: &LogScale, step: usize) -> Vec<i32> {
        let top = 4 * s.one;
        let mut v: Vec<i32> = (FINE_PER_CODE..=top).step_by(step).collect();
        v.extend([LogFine::ZERO.0, FINE_PER_CODE, FINE_PER_CODE + 1, top - 1, top]);
        v
    }

    /// The hot loops' log arithmetic gives [`LogScale`]'s results bit for bit.
    #[test]
    fn log_arith_matches_log_scale() {
        for bits in VB_BITS_MIN..=VB_BITS_MAX {
            let s = LogScale::get(bits);
            let f = LogArith::new(s);
            assert_eq!(&s.softplus_padded[..s.softplus.len()], &s.softplus[..]);
            // F2's mean, on all pairs of its operands (8, 9 bits) or many.
            let all = f2_operands(s, 1);
            let some = f2_operands(s, if bits <= 9 { 1 } else { 61 });
            for &a in &all {
                for &b in &some {
                    let m = f.mean(a, b);
                    assert_eq!(m, s.mean(LogFine(a), LogFine(b)).0, "log{bits}: mean({a}, {b})");
                    assert_eq!(m, f.mean(b, a));
                }
                assert_eq!(f.mean(a, a), a, "log{bits}: mean({a}, {a})");
            }
            // Eq. (4) and the store, on every weighted code (eq. 3) and stored word.
            let codes: Vec<u16> = (0..=s.one as u16).step_by(if bits <= 9 { 1 } else { 7 }).chain([s.one()]).collect();
            for &q in &codes {
                for n in 1..=AREA_DENOMINATOR {
                    let v = s.weigh(q, n);
                    assert_eq!(f.store(v.0), s.store(v), "log{bits}: store({v:?})");
                    for &stored in &codes {
                        let b = LogFine::from_code(stored);
                        let sum = f.sum(v.0, b.0);
                        assert_eq!(sum, s.sum(v, b).0, "log{bits}: sum({v:?}, {b:?})");
                        assert_eq!(f.store(sum), s.store(s.sum(v, b)));
                    }
                }
                // A whole pixel's first fragment stores its code.
                assert_eq!(s.store(s.weigh(q, AREA_DENOMINATOR)), q);
            }
            // The store on every value from far below zero's code to far above Q1.
            for v in (LogFine::ZERO.0 - 5000..LogFine::ZERO.0 + 5000).chain(-20_000..20_000) {
                assert_eq!(f.store(v), s.store(LogFine(v)), "log{bits}: store({v})");
            }
        }
    }

    /// The 8-bit code's F2 with zero as [`LOG8_ZERO`] in `i16` gives the general
    /// half sums: the pair table on every pair of codes; and the second pass's
    /// address in the 8-bit gamma table, on every pair of its operands (zero and
    /// every quarter code from code 1 to Q1), reads the output of the general half
    /// sum, as does every operand by itself (the flat runs' and the last column's
    /// pixels).
    #[test]
    fn log8_f2_matches_log_arith() {
        let s = LogScale::get(PAIR_MEANS_BITS);
        let (f, pairs) = (LogArith::new(s), s.pair_means.as_ref().expect("the 8-bit scale has the table"));
        let narrow = |v: i32| if v == LogFine::ZERO.0 { LOG8_ZERO } else { i16::try_from(v).unwrap() };
        for a in 0..=s.one() {
            for b in 0..=s.one() {
                let want = f.mean(LogFine::from_code(a).0, LogFine::from_code(b).0);
                assert_eq!(pairs.mean(a, b), narrow(want), "mean of codes {a} and {b}");
            }
        }
        let operands = f2_operands(s, 1);
        for gamma in [2.2, 1.0, 0.45] {
            let general = s.gamma_table(gamma);
            let table = log8_gamma_table(&general, s.ln2);
            let output = |v: i32| general[v.max(0) as usize];
            for &a in &operands {
                assert_eq!(table[usize::from(narrow(a) as u16)], output(a), "gamma {gamma}: {a}");
                for &b in &operands {
                    let got = table[usize::from(pairs.mean_address(narrow(a), narrow(b)))];
                    assert_eq!(got, output(f.mean(a, b)), "gamma {gamma}: mean({a}, {b})");
                }
            }
        }
        // The second pass's table is the padded one at every difference.
        for d in 0..LOG8_ADDRESSES {
            assert_eq!(i32::from(pairs.softplus[d]), f.softplus(d as i32), "T[{d}]");
        }
        assert!(LogScale::get(PAIR_MEANS_BITS + 1).pair_means.is_none());
    }

    /// The 8-bit encoder over every `f32` gives the scale's ROM (itself tested against
    /// its f64 definition): on every bucket's first, second and last patterns and on
    /// both sides of every threshold, on a sample of all patterns, and on the special
    /// values.
    #[test]
    fn encoder8_matches_encode() {
        let s = LogScale::get(PAIR_MEANS_BITS);
        let e = s.encoder8.as_ref().expect("the 8-bit encoder").tables();
        let check = |bits: u32| {
            let c = f32::from_bits(bits);
            assert_eq!(u16::from(e.encode(c)), s.encode(c), "encode({c:e}) of bits {bits:#x}");
        };
        for bucket in 0..=u32::MAX >> ENCODER8_SHIFT {
            let lo = bucket << ENCODER8_SHIFT;
            [lo, lo + 1, lo | ((1 << ENCODER8_SHIFT) - 1)].into_iter().for_each(check);
        }
        for &(up_from, _) in &s.encoder {
            [up_from.wrapping_sub(1), up_from, up_from.wrapping_add(1)].into_iter().for_each(check);
        }
        (0..=u32::MAX).step_by(251).for_each(check);
        let specials = [0.0, -0.0, 1.0, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -f32::NAN, f32::MAX];
        for c in specials.into_iter().chain([f32::MIN_POSITIVE, 1e-40, 0.999_999_94, 1.000_000_1]) {
            check(c.to_bits());
        }
        check(0x7FC0_0001);
        check(0xFFFF_FFFF);
    }

    /// A flat run's output words are its bytes.
    #[test]
    fn pattern_words_are_the_bytes() {
        for rgb in [[0, 0, 0], [1, 2, 3], [255, 0, 128], [255, 255, 255], [7, 200, 91]] {
            let words = pattern(rgb);
            let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
            assert_eq!(bytes, pattern_bytes(rgb), "{rgb:?}");
        }
    }

    impl VideoBuffer {
        /// The fixed-point modes' codes, three per pixel.
        fn codes(&self) -> Vec<[u16; 3]> {
            match &self.memory {
                Memory::Log { codes, .. } | Memory::Linear { codes, .. } => codes.clone(),
                Memory::Log8 { codes, .. } => codes.iter().map(|w| w.unpack()).collect(),
                Memory::Float(_) => unreachable!("fixed-point modes"),
            }
        }

        /// Sets the fixed-point modes' codes.
        fn set_codes(&mut self, new: &[[u16; 3]]) {
            match &mut self.memory {
                Memory::Log { codes, .. } | Memory::Linear { codes, .. } => codes.copy_from_slice(new),
                Memory::Log8 { codes, .. } => {
                    for (c, &n) in codes.iter_mut().zip(new) {
                        *c = Word8::pack(n);
                    }
                }
                Memory::Float(_) => unreachable!("fixed-point modes"),
            }
        }
    }

    /// A VMEM word of the 8-bit code holds its three codes.
    #[test]
    fn word8_packs_three_codes() {
        for q in 0..=255u16 {
            let codes = [q, 255 - q, q / 3];
            assert_eq!(Word8::pack(codes).unpack(), codes);
            assert_eq!(Word8::pack(codes) >> 24, 0);
        }
        assert_eq!(Word8::pack([1, 2, 3]), 0x03_02_01);
        assert!(matches!(VideoBuffer::new(4, 4, VbMode::LOG8).memory, Memory::Log8 { .. }));
    }

    /// The readout as it was first written (P1's arithmetic, one operation at a
    /// time), to compare the fast one with.
    fn reference_read_out(w: usize, h: usize, codes: &[[u16; 3]], filter: bool, mode: VbMode, gamma: f32) -> Vec<u8> {
        type Load = Box<dyn Fn(u16) -> i32>;
        type Mean = Box<dyn Fn(i32, i32) -> i32>;
        let (load, mean, table): (Load, Mean, Vec<u8>) = match mode {
            VbMode::Log { bits } => {
                let s = LogScale::get(bits);
                (
                    Box::new(|q| LogFine::from_code(q).0),
                    Box::new(move |a, b| s.mean(LogFine(a), LogFine(b)).0),
                    s.gamma_table(gamma),
                )
            }
            VbMode::Linear { bits } => {
                let s = LinearScale::new(bits);
                (Box::new(|q| i32::from(q) << 2), Box::new(|a, b| (a + b) >> 1), s.gamma_table(gamma))
            }
            VbMode::Float => unreachable!("fixed-point modes"),
        };
        let mut out = Vec::new();
        for y in 0..h {
            let below = (y + 1).min(h - 1);
            let line: Vec<[i32; 3]> = (0..w)
                .map(|x| {
                    let (a, b) = (codes[y * w + x], codes[below * w + x]);
                    std::array::from_fn(|ch| if filter { mean(load(a[ch]), load(b[ch])) } else { load(a[ch]) })
                })
                .collect();
            for x in 0..w {
                let (a, b) = (line[x], line[(x + 1).min(w - 1)]);
                for ch in 0..3 {
                    let v = if filter { mean(a[ch], b[ch]) } else { a[ch] };
                    out.push(table[v.max(0) as usize]);
                }
            }
        }
        out
    }

    /// The readout, whole and in bands, gives the reference's bytes: every
    /// fixed-point mode, with and without F2, on random codes with runs of equal
    /// words and zeros.
    /// The 8-bit log code's shortcut for the uniform runs at a row's start
    /// (`uniform_runs`): rows wholly of one word (a whole number of runs or not),
    /// rows of it for some runs and then not, a row of it whose row below is not,
    /// and the last row (its own row below), against the reference readout.
    #[test]
    fn read_out_log8_uniform_rows_match_reference() {
        let mode = VbMode::Log { bits: 8 };
        let (a, b, c) = ([40, 90, 200], [41, 90, 200], [255, 3, 0]);
        for w in [16usize, 33, 48, 53, 64] {
            // Row 0, 1, 3: all `a`; row 2: `a` for two runs, then `b`; row 4: `a` but
            // its last pixel; row 5: all `c`.
            let rows: [Box<dyn Fn(usize) -> [u16; 3]>; 6] = [
                Box::new(|_| a),
                Box::new(|_| a),
                Box::new(|x| if x < 2 * LOG8_RUN { a } else { b }),
                Box::new(|_| a),
                Box::new(move |x| if x + 1 < w { a } else { b }),
                Box::new(|_| c),
            ];
            let h = rows.len();
            let codes: Vec<[u16; 3]> = (0..h).flat_map(|y| (0..w).map(|x| rows[y](x)).collect::<Vec<_>>()).collect();
            let mut vb = VideoBuffer::new(w as u32, h as u32, mode);
            vb.set_codes(&codes);
            for gamma in [2.2, 1.0] {
                let opts = Readout { filter: true, gamma };
                let expect = reference_read_out(w, h, &codes, true, mode, gamma);
                assert_eq!(vb.read_out(&opts).pixels, expect, "{w}x{h} gamma {gamma}");
                for y in 0..h {
                    let mut row = vec![0; 3 * w];
                    vb.read_out_rows(&opts, y..y + 1, &mut row);
                    assert_eq!(row, expect[3 * w * y..][..3 * w], "{w}x{h} row {y} alone");
                }
            }
        }
    }

    #[test]
    fn read_out_matches_reference() {
        let mut rng = Rng(0x0F2_0F2);
        let modes = (VB_BITS_MIN..=VB_BITS_MAX).flat_map(|bits| [VbMode::Log { bits }, VbMode::Linear { bits }]);
        for mode in modes {
            // Short runs, and long ones (whole F2 runs equal to their neighbours).
            let sizes = [
                (1, 1, 6),
                (1, 5, 6),
                (7, 1, 6),
                (37, 23, 6),
                (37, 23, 90),
                (64, 9, 400),
                (48, 7, 60),
                (80, 5, 2000),
                (9, 3, 400),
            ];
            for (w, h, change) in sizes {
                let mut vb = VideoBuffer::new(w, h, mode);
                let one = match mode {
                    VbMode::Log { bits } | VbMode::Linear { bits } => ((1u32 << bits) - 1) as u16,
                    VbMode::Float => unreachable!(),
                };
                let mut word = [0; 3];
                let codes: Vec<[u16; 3]> = (0..w * h)
                    .map(|_| {
                        // Runs: a new word two times in `change`, a component once.
                        match rng.next() % change {
                            0 | 1 => word = [rng.code(one), rng.code(one), rng.code(one)],
                            2 => word[(rng.next() % 3) as usize] = rng.code(one),
                            _ => {}
                        }
                        word
                    })
                    .collect();
                vb.set_codes(&codes);
                for filter in [true, false] {
                    for gamma in [2.2, 1.0] {
                        let opts = Readout { filter, gamma };
                        let expect = reference_read_out(w as usize, h as usize, &codes, filter, mode, gamma);
                        assert_eq!(vb.read_out(&opts).pixels, expect, "{mode} {w}x{h} filter {filter}");
                        let (w, h) = (w as usize, h as usize);
                        let mut banded = vec![0; 3 * w * h];
                        for (k, out) in banded.chunks_mut(3 * w * 3).enumerate() {
                            vb.read_out_rows(&opts, 3 * k..(3 * k + 3).min(h), out);
                        }
                        assert_eq!(banded, expect, "{mode} {w}x{h} filter {filter}, bands of 3 rows");
                    }
                }
            }
        }
    }

    /// The first pass by arithmetic on codes gives the pair table on every pair.
    #[test]
    fn mean_codes_match_pair_table() {
        let pairs = LogScale::get(PAIR_MEANS_BITS).pair_means.as_ref().expect("the 8-bit scale has the pair table");
        for a in 0..=255u8 {
            for b in 0..=255u8 {
                assert_eq!(pairs.mean_codes(a, b), pairs.mean(a.into(), b.into()), "codes {a} and {b}");
            }
        }
    }

    /// A word with one component moved a step of at most 3 codes, kept in `0..=255`
    /// (smooth shading, the second pass's AVX2 windows; codes near zero and code 1).
    fn nudge(rng: &mut Rng, word: Word8) -> Word8 {
        let ch = (rng.next() % 3) as u32;
        let code = (word >> (WORD8_SHIFT * ch) & 0xFF) as i32;
        let step = (rng.next() % 7) as i32 - 3;
        let code = (code + step).clamp(0, 255) as u32;
        word & !(0xFF << (WORD8_SHIFT * ch)) | code << (WORD8_SHIFT * ch)
    }

    /// The AVX2 first pass gives the portable one's half sums on every pair of codes
    /// (16 words of 3 codes a run: the codes 16 apart or more by the blend tree, the
    /// others by the first block).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn read_out_log8_pass1_avx2_matches_portable() {
        let Some(avx2) = Log8Avx2::detect() else { return };
        let pairs = LogScale::get(PAIR_MEANS_BITS).pair_means.as_ref().expect("the 8-bit scale has the pair table");
        let all: Vec<(u8, u8)> = (0..=255u8).flat_map(|a| (0..=255u8).map(move |b| (a, b))).collect();
        // Near pairs apart from the far ones, so that whole registers take the first block.
        let (near, far): (Vec<_>, Vec<_>) = all.into_iter().partition(|&(a, b)| a.abs_diff(b) < 16);
        for list in [near, far] {
            for run in list.chunks(3 * LOG8_RUN) {
                let (mut row, mut below) = ([0 as Word8; LOG8_RUN], [0 as Word8; LOG8_RUN]);
                for (k, &(a, b)) in run.iter().enumerate() {
                    row[k / 3] |= Word8::from(a) << (WORD8_SHIFT * (k % 3) as u32);
                    below[k / 3] |= Word8::from(b) << (WORD8_SHIFT * (k % 3) as u32);
                }
                let (mut expect, mut got) = ([[0i16; 4]; LOG8_RUN], [[7i16; 4]; LOG8_RUN]);
                Log8Portable.pass1(&mut expect, &row, &below, pairs);
                avx2.pass1(&mut got, &row, &below, pairs);
                assert_eq!(got, expect, "rows {row:x?} and {below:x?}");
            }
        }
    }

    /// The AVX2 test of a flat run agrees with the portable one: flat runs, and runs
    /// with one word changed (any word, any bit, in the run or below it).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn read_out_log8_flat_avx2_matches_portable() {
        let Some(avx2) = Log8Avx2::detect() else { return };
        for word in [0 as Word8, 1, 0x00FF_FFFF, 0x0012_3456] {
            let flat = [word; LOG8_RUN];
            assert!(avx2.flat(&flat, &flat) && Log8Portable.flat(&flat, &flat));
            for i in 0..2 * LOG8_RUN {
                for bit in 0..Word8::BITS {
                    let (mut row, mut below) = (flat, flat);
                    let changed = if i < LOG8_RUN { &mut row[i] } else { &mut below[i - LOG8_RUN] };
                    *changed ^= 1 << bit;
                    assert_eq!(avx2.flat(&row, &below), Log8Portable.flat(&row, &below), "word {i}, bit {bit}");
                    assert!(!avx2.flat(&row, &below));
                }
            }
        }
    }

    /// The AVX2 second pass gives the portable one's bytes on runs of half sums
    /// (zero's value, code 1 and near it, Q1; neighbours equal, a few quarter codes
    /// apart or far apart), smooth ones (the windows) and not.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn read_out_log8_pass2_avx2_matches_portable() {
        let Some(avx2) = Log8Avx2::detect() else { return };
        let s = LogScale::get(PAIR_MEANS_BITS);
        let pairs = s.pair_means.as_ref().expect("the 8-bit scale has the pair table");
        let top = i16::try_from(FINE_PER_CODE * i32::from(s.one())).expect("4 Q1 fits an i16");
        let mut rng = Rng(0xF2B7);
        for gamma in [2.2, 1.0] {
            let table = log8_gamma_table(&s.gamma_table(gamma), s.ln2);
            let table: &[u8; LOG8_ADDRESSES] = table.as_slice().try_into().expect("the 8-bit gamma table");
            for trial in 0..20_000 {
                // The largest step between neighbours: smooth runs mostly.
                let step = [2, 5, 16, 40, 2000][trial % 5];
                let mut v: [i16; 3] = std::array::from_fn(|_| (rng.next() % 1030) as i16);
                let mut run = [[0i16; 4]; LOG8_RUN + 1];
                for l in &mut run {
                    for v in &mut v {
                        let d = (rng.next() % (2 * step + 1)) as i16 - step as i16;
                        *v = (*v + d).clamp(FINE_PER_CODE as i16 - 8, top + 8);
                    }
                    // Zero's value below code 1 (one in three runs, all of a component's pixels).
                    *l = std::array::from_fn(|ch| match ch {
                        3 => 0,
                        _ if trial % 3 == 0 && ch == trial % 7 % 3 => LOG8_ZERO,
                        _ if v[ch] < FINE_PER_CODE as i16 => LOG8_ZERO,
                        _ => v[ch].min(top),
                    });
                }
                let (mut expect, mut got) = ([0u8; 3 * LOG8_RUN], [7u8; 3 * LOG8_RUN]);
                read_out_log8_pass2(&mut expect, &run, pairs, table);
                avx2.pass2(&mut got, &run, pairs, table);
                assert_eq!(got, expect, "run {run:?} gamma {gamma}");
            }
        }
    }

    /// Every copy of the 8-bit readout's first pass the processor can run gives the
    /// portable copy's bytes: random codes with flat and non-flat runs (long runs of
    /// one word, one component changing, zeros, Q1, neighbours far apart), odd widths
    /// (a short last run, rows of fewer pixels than a run), bands ending at the
    /// bottom row.
    #[test]
    fn read_out_log8_copies_match_portable() {
        let s = LogScale::get(PAIR_MEANS_BITS);
        let pairs = s.pair_means.as_ref().expect("the 8-bit scale has the pair table");
        let mut rng = Rng(0xF2A5);
        let sizes = [(1, 3, 4), (15, 4, 3), (16, 5, 40), (17, 6, 2), (33, 9, 8), (100, 13, 300), (129, 7, 30)];
        // Then smooth images: every other pixel moved by a small step.
        let smooth = [(64, 8, 4), (97, 11, 40), (160, 9, 400)];
        for (w, h, change, nudged) in
            sizes.map(|(w, h, c)| (w, h, c, false)).into_iter().chain(smooth.map(|(w, h, c)| (w, h, c, true)))
        {
            let mut word = 0u32;
            let codes: Vec<Word8> = (0..w * h)
                .map(|_| {
                    match rng.next() % change {
                        0 => word = Word8::pack([rng.code(255), rng.code(255), rng.code(255)]),
                        1 => word = [0, 0x00FF_FFFF, 0x00FF_0000, 0x0001_00FF][(rng.next() % 4) as usize],
                        2 => word ^= 0xFF << (8 * (rng.next() % 3)),
                        _ if nudged && rng.next().is_multiple_of(2) => word = nudge(&mut rng, word),
                        _ => {}
                    }
                    word
                })
                .collect();
            for gamma in [2.2, 1.0] {
                let table = log8_gamma_table(&s.gamma_table(gamma), s.ln2);
                let table: &[u8; LOG8_ADDRESSES] = table.as_slice().try_into().expect("the 8-bit gamma table");
                let segment = |y: usize, x0: usize| &codes[y * w + x0..(y + 1) * w];
                for filter in [true, false] {
                    for rows in [0..h, h - 1..h, h / 2..h, 0..1] {
                        let mut expect = vec![0u8; 3 * w * rows.len()];
                        read_out_log8_rows(
                            Log8Portable,
                            w,
                            h,
                            &segment,
                            filter,
                            pairs,
                            table,
                            rows.clone(),
                            out_rows(w, &rows, &mut expect),
                        );
                        let mut got = vec![0u8; expect.len()];
                        let out = out_rows(w, &rows, &mut got);
                        read_out_log8_from(w, h, &segment, filter, pairs, table, rows.clone(), out);
                        assert_eq!(got, expect, "{w}x{h} rows {rows:?} gamma {gamma} filter {filter}");
                        #[cfg(target_arch = "x86_64")]
                        if let Some(avx2) = Log8Avx2::detect() {
                            got.fill(0);
                            let out = out_rows(w, &rows, &mut got);
                            avx2.read_out_rows(w, h, &segment, filter, pairs, table, rows.clone(), out);
                            assert_eq!(got, expect, "AVX2 {w}x{h} rows {rows:?} gamma {gamma} filter {filter}");
                        }
                    }
                }
            }
        }
    }

    /// A readout by strips ([`VideoBuffer::read_out_strip`] of each strip from its
    /// own buffer, then [`VideoBuffer::read_out_strip_borders`]) gives the bytes of
    /// one buffer holding every strip's pixels read out whole: random codes (flat
    /// runs, smooth runs, zeros), strips at multiples of 16 columns and not, empty
    /// ones, a short last one, one-row images, F2 on and off. Each buffer's pixels
    /// outside its strip are another image's, so a read across a border shows.
    #[test]
    fn read_out_by_strips_is_the_readout() {
        let mut rng = Rng(0x5781);
        let sizes = [(16, 1), (40, 3), (64, 9), (100, 13), (129, 7), (200, 20)];
        for (case, &(w, h)) in sizes.iter().cycle().take(60).enumerate() {
            let n = 1 + case % 4;
            let mut word = 0u32;
            let mut image = |rng: &mut Rng| -> Vec<Word8> {
                (0..w * h)
                    .map(|_| {
                        match rng.next() % 12 {
                            0 => word = Word8::pack([rng.code(255), rng.code(255), rng.code(255)]),
                            1 => word = [0, 0x00FF_FFFF][(rng.next() % 2) as usize],
                            2..=5 => word = nudge(rng, word),
                            _ => {}
                        }
                        word
                    })
                    .collect()
            };
            let buffers: Vec<VideoBuffer> = (0..n)
                .map(|_| {
                    let mut vb = VideoBuffer::new(w as u32, h as u32, VbMode::LOG8);
                    let Memory::Log8 { codes, .. } = &mut vb.memory else { unreachable!("the 8-bit code") };
                    *codes = image(&mut rng);
                    vb
                })
                .collect();
            // Borders at random columns, at multiples of 16 in even cases.
            let mut cuts: Vec<u32> = (1..n)
                .map(|_| match case % 2 {
                    0 => (rng.next() % (w as u64 / 16 + 1)) as u32 * 16,
                    _ => (rng.next() % (w as u64 + 1)) as u32,
                })
                .map(|x| x.min(w as u32))
                .collect();
            cuts.sort_unstable();
            let ends: Vec<u32> = cuts.iter().copied().chain([w as u32]).collect();
            let strips: Vec<(u32, u32)> =
                ends.iter().scan(0, |x0, &x1| Some((std::mem::replace(x0, x1), x1))).collect();
            // The whole image: each column from its strip's buffer.
            let mut whole = VideoBuffer::new(w as u32, h as u32, VbMode::LOG8);
            for (vb, &(x0, x1)) in buffers.iter().zip(&strips) {
                whole.copy_from(vb, |x, _| x >= x0 && x < x1);
            }
            for opts in
                [Readout::default(), Readout { filter: false, gamma: 1.0 }, Readout { filter: true, gamma: 1.0 }]
            {
                let expect = whole.read_out(&opts);
                let ro = buffers[0].log8_readout(&opts).expect("the 8-bit code");
                let mut got = Image { width: w as u32, height: h as u32, pixels: vec![0xA5; 3 * w * h] };
                for (vb, &(x0, x1)) in buffers.iter().zip(&strips) {
                    // In two parts of rows (a band ends at the bottom row, or before it).
                    let mid = (rng.next() % (h as u64 + 1)) as usize;
                    let mut rows =
                        got.pixels.chunks_exact_mut(3 * w).map(|row| &mut row[3 * x0 as usize..3 * x1 as usize]);
                    vb.read_out_strip(&ro, (x0, x1), 0..mid, rows.by_ref().take(mid));
                    vb.read_out_strip(&ro, (x0, x1), mid..h, rows);
                }
                let parts: Vec<(&VideoBuffer, (u32, u32))> = buffers.iter().zip(strips.iter().copied()).collect();
                VideoBuffer::read_out_strip_borders(&parts, &ro, &mut got);
                assert!(got == expect, "{w}x{h} strips {strips:?} {opts:?}");
            }
        }
        assert!(VideoBuffer::new(4, 4, VbMode::FLOAT).log8_readout(&Readout::default()).is_none());
    }

    /// The background's F1 with its colour encoded once (in the call, or
    /// beforehand) gives the per-pixel F1's words, in every mode, on random cells
    /// and colours (black, white, above one); so do runs of cells of one colour
    /// ([`VideoBuffer::accumulate_prepared_runs`]: 1 to 3 runs of 1 to 9 cells a
    /// call, each run its own colour).
    #[test]
    fn accumulate_flat_matches_accumulate() {
        let mut rng = Rng(0xF1A7);
        let modes = [VbMode::FLOAT, VbMode::LOG8, VbMode::Log { bits: 12 }, VbMode::LINEAR8];
        for mode in modes {
            // 10 x 6: cells reaching past the right and bottom edges.
            let (mut a, mut b) = (VideoBuffer::new(10, 6, mode), VideoBuffer::new(10, 6, mode));
            // The colour encoded beforehand (the VP's background).
            let mut c = VideoBuffer::new(10, 6, mode);
            // Runs of cells of one colour, taken a few runs at a time.
            let mut d = VideoBuffer::new(10, 6, mode);
            let (mut run, mut run_color, mut run_left) = (Vec::new(), Vec3::ZERO, 0);
            let (mut runs, mut batch): (Vec<(Vec<Visible>, FlatColor)>, usize) = (Vec::new(), 1);
            let new_color = |rng: &mut Rng| {
                Vec3::from_array(std::array::from_fn(|_| match rng.next() % 6 {
                    0 => 0.0,
                    1 => 1.0,
                    2 => 1.25,
                    _ => (rng.next() % 10_000) as f32 / 10_000.0,
                }))
            };
            for _ in 0..3000 {
                if run_left == 0 {
                    runs.push((std::mem::take(&mut run), d.prepare_flat(run_color)));
                    if runs.len() >= batch {
                        d.accumulate_prepared_runs(runs.iter().map(|(cells, flat)| (&cells[..], *flat)));
                        runs.clear();
                        batch = 1 + (rng.next() % 3) as usize;
                        // (Checked after each call: a later first write would hide it.)
                        for (x, y) in (0..6).flat_map(|y| (0..10).map(move |x| (x, y))) {
                            assert_eq!(a.linear(x, y), d.linear(x, y), "{mode} pixel ({x}, {y}): runs");
                        }
                    }
                    run_color = new_color(&mut rng);
                    run_left = 1 + rng.next() % 9;
                }
                run_left -= 1;
                let (px, py) = ((rng.next() % 3) as u32 * 4, (rng.next() % 2) as u32 * 4);
                let sets: [u16; 16] = std::array::from_fn(|i| {
                    let (x, y) = (px + i as u32 % 4, py + i as u32 / 4);
                    match rng.next() % 4 {
                        _ if x >= 10 || y >= 6 => 0,
                        0 => 0,
                        1 => 0xFFFF,
                        _ => rng.next() as u16,
                    }
                });
                let color = run_color;
                // Whole cells' first fragments too (the cells wholly on the screen).
                let whole = px <= 4 && py == 0 && rng.next().is_multiple_of(4);
                let (sets, first) = if whole { ([FULL; 16], FULL) } else { (sets, rng.next() as u16) };
                let vis = Visible { px, py, sets, first, covered: false };
                a.accumulate(&vis, &CellColors::splat(color));
                b.accumulate_flat(&vis, color);
                let flat = c.prepare_flat(color);
                c.accumulate_prepared(&vis, &flat);
                run.push(vis);
            }
            runs.push((run, d.prepare_flat(run_color)));
            d.accumulate_prepared_runs(runs.iter().map(|(cells, flat)| (&cells[..], *flat)));
            for y in 0..6 {
                for x in 0..10 {
                    assert_eq!(a.linear(x, y), b.linear(x, y), "{mode} pixel ({x}, {y})");
                    assert_eq!(a.linear(x, y), c.linear(x, y), "{mode} pixel ({x}, {y}): prepared");
                    assert_eq!(a.linear(x, y), d.linear(x, y), "{mode} pixel ({x}, {y}): runs");
                }
            }
        }
    }

    /// [`ln_area16_avx2`] is the `ln S` table's entry `n - 1` for every count `n`
    /// of subpixels, 1 to 16, in every lane, whichever subpixels make the count
    /// (and entry 15 for an empty set, as the 32-bit lanes had it).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn ln_area16_is_the_ln_s_table() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
        fn run(sets: &[u16; 16], table: &LnArea16) -> [i16; 16] {
            let mut out = [0i16; 16];
            // SAFETY: the processor has AVX2 (checked above); `sets` and `out` are
            // 32 bytes each, which the load reads and the store writes.
            unsafe {
                let v = ln_area16_avx2(_mm256_loadu_si256(sets.as_ptr().cast()), table);
                _mm256_storeu_si256(out.as_mut_ptr().cast(), v);
            }
            out
        }
        let s = LogScale::get(PAIR_MEANS_BITS);
        let table = LnArea16::new(&s.ln_area);
        let mut rng = Rng(0x1A_5E);
        for round in 0..20_000 {
            let sets: [u16; 16] = std::array::from_fn(|i| match (round + i) % 5 {
                0 => 0,
                1 => FULL,
                2 => 1 << (rng.next() % 16),
                _ => rng.next() as u16,
            });
            let got = run(&sets, &table);
            for (set, got) in sets.iter().zip(got) {
                let n = set.count_ones() as usize;
                let want = s.ln_area[n.wrapping_sub(1) & 15];
                assert_eq!(i32::from(got), want, "set {set:#06x}");
            }
        }
    }

    /// A random cell of the F1 tests, at one of the 3 x 2 cells of a 12 x 8 area: its
    /// pixel, its 16 sets (each empty in `empty` cases of `empty + 3`, whole in one,
    /// random in two) and first-write flags, and one row in `row_every` made whole
    /// first fragments.
    fn random_f1_cell(rng: &mut Rng, empty: u64, row_every: u64) -> (u32, u32, [u16; 16], u16) {
        let (px, py) = ((rng.next() % 3) as u32 * 4, (rng.next() % 2) as u32 * 4);
        let mut sets: [u16; 16] = std::array::from_fn(|_| match rng.next() % (empty + 3) {
            k if k < empty => 0,
            k if k == empty => FULL,
            _ => rng.next() as u16,
        });
        let mut first = rng.next() as u16;
        for row in 0..4 {
            if rng.next().is_multiple_of(row_every) {
                sets[4 * row..4 * row + 4].fill(FULL);
                first |= ROW_BITS << (4 * row);
            }
        }
        (px, py, sets, first)
    }

    /// The sets of a cell at pixel `(px, py)` emptied beyond a `w x h` screen (its
    /// pixels there have no visible subpixel).
    fn off_screen_hidden(sets: &mut [u16; 16], px: u32, py: u32, w: usize, h: usize) {
        for (i, set) in sets.iter_mut().enumerate() {
            if px as usize + i % 4 >= w || py as usize + i / 4 >= h {
                *set = 0;
            }
        }
    }

    /// Every copy of the 8-bit F1 the processor can run (AVX2) gives the
    /// portable copy's words: random cells (whole and partial pixels, first writes
    /// and read-modify-writes, rows of whole first fragments, cells past the right
    /// and bottom edges) with any colours (random bit patterns: NaN, infinities,
    /// negatives, denormals; zero, one, just below and above one).
    #[test]
    fn accumulate_log8_copies_match_portable() {
        type Copy8 = fn(&mut [Word8], usize, &Visible, &CellColors, LogF1, Encoder8Tables);
        let mut copies: Vec<(&str, Copy8)> = Vec::new();
        #[cfg(target_arch = "x86_64")]
        {
            #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
            fn avx2(c: &mut [Word8], w: usize, v: &Visible, k: &CellColors, f: LogF1, e: Encoder8Tables) {
                // SAFETY: called only when the processor has AVX2 (below).
                unsafe { accumulate_log8_avx2::<{ F1_ALONE }>(c, w, v, k, &f, e, &LnArea16::new(f.ln_area)) }
            }
            if std::is_x86_feature_detected!("avx2") {
                copies.push(("AVX2", avx2));
            }
        }
        let s = LogScale::get(PAIR_MEANS_BITS);
        let (f1, encoder) = (LogF1::new(s), s.encoder8.as_ref().expect("the 8-bit encoder").tables());
        let mut rng = Rng(0xF1_A5);
        // 10 x 7: cells reaching past the right and bottom edges.
        let (w, h) = (10usize, 7usize);
        let mut expect = vec![0u32; w * h];
        let mut got = vec![expect.clone(); copies.len()];
        let odd = [0.0, -0.0, 1.0, 0.999_999_94, 1.000_000_1, 1e-3, 2.4e-3, 1e-40, f32::INFINITY, -1.0, f32::NAN];
        for round in 0..20_000 {
            let (px, py, mut sets, mut first) = random_f1_cell(&mut rng, 1, 3);
            if round % 7 == 0 {
                first = FULL;
            }
            // Every third cell with one half empty or of whole first fragments, so
            // that the other half runs eq. 3-4 alone ([`f1_half_avx2`]).
            if round % 3 == 1 {
                let half = (rng.next() % 2) as usize;
                let (fill, flags) = if rng.next().is_multiple_of(2) { (0, 0) } else { (FULL, 0xFF) };
                sets[8 * half..8 * half + 8].fill(fill);
                first |= flags << (8 * half);
            }
            off_screen_hidden(&mut sets, px, py, w, h);
            // Half the cells of near colours (a component's ROM addresses in a
            // window of the table, or just past it), now and then an odd one.
            let near = round % 2 == 0;
            let base: [f32; 3] = std::array::from_fn(|_| (rng.next() % 100_000) as f32 / 100_000.0);
            let spread = [1e-3, 0.05, 0.2, 0.3][(rng.next() % 4) as usize];
            let colors: [Vec3; 16] = std::array::from_fn(|_| {
                Vec3::from_array(std::array::from_fn(|c| match rng.next() % 8 {
                    0 if !near || rng.next().is_multiple_of(8) => f32::from_bits(rng.next() as u32),
                    1 if !near || rng.next().is_multiple_of(8) => odd[(rng.next() % odd.len() as u64) as usize],
                    _ if near => base[c] * (1.0 + spread * (rng.next() % 1000) as f32 / 1000.0),
                    _ => (rng.next() % 100_000) as f32 / 100_000.0,
                }))
            });
            let vis = Visible { px, py, sets, first, covered: false };
            let colors = CellColors::from(colors);
            accumulate_log8_portable(&mut expect, w, &vis, &colors, f1, encoder);
            for ((name, copy), got) in copies.iter().zip(&mut got) {
                copy(got, w, &vis, &colors, f1, encoder);
                assert_eq!(*got, expect, "{name}, round {round}");
            }
        }
    }

    /// The 8-bit F1 of one word for a cell ([`accumulate_log8_flat`]: pixel by
    /// pixel in SSE4.1 lanes where the build has them) gives the portable one's
    /// words ([`accumulate_log_flat`]): random cells (whole and partial pixels,
    /// first writes and read-modify-writes, whole rows and cells of first fragments,
    /// cells past the right and bottom edges) of random colours, each round on the
    /// words the rounds before left.
    #[test]
    fn accumulate_log8_flat_matches_portable() {
        let s = LogScale::get(PAIR_MEANS_BITS);
        let (f1, encoder) = (LogF1::new(s), s.encoder8.as_ref().expect("the 8-bit encoder").tables());
        let mut rng = Rng(0xF1_A7);
        // 10 x 7: cells reaching past the right and bottom edges.
        let (w, h) = (10usize, 7usize);
        let (mut expect, mut got) = (vec![0u32; w * h], vec![0u32; w * h]);
        for round in 0..20_000 {
            let (px, py, mut sets, mut first) = random_f1_cell(&mut rng, 2, 4);
            if round % 11 == 0 {
                (sets, first) = ([FULL; 16], FULL);
            }
            off_screen_hidden(&mut sets, px, py, w, h);
            let color: [f32; 3] = std::array::from_fn(|_| match rng.next() % 6 {
                0 => 0.0,
                1 => 1.0,
                2 => 1e-3,
                _ => (rng.next() % 100_000) as f32 / 100_000.0,
            });
            let word = color.map(|c| u16::from(encoder.encode(c)));
            let vis = Visible { px, py, sets, first, covered: false };
            accumulate_log_flat(&mut expect, w, &vis, f1, word);
            accumulate_log8_flat(&mut got, w, &vis, f1, word);
            assert_eq!(got, expect, "round {round}");
        }
    }

    /// F1 gives P1's eq. (3) and (4) one operation at a time: random cells of
    /// first writes and read-modify-writes, whole and partial pixels.
    #[test]
    fn accumulate_matches_equations() {
        let mut rng = Rng(0xF1_F1);
        for bits in VB_BITS_MIN..=VB_BITS_MAX {
            let s = LogScale::get(bits);
            let mut vb = VideoBuffer::new(8, 8, VbMode::Log { bits });
            let mut expect = vec![[0u16; 3]; 64];
            for _ in 0..4000 {
                let (px, py) = ((rng.next() % 2) as u32 * 4, (rng.next() % 2) as u32 * 4);
                let mut sets: [u16; 16] = std::array::from_fn(|_| match rng.next() % 4 {
                    0 => 0,
                    1 => 0xFFFF,
                    _ => rng.next() as u16,
                });
                let mut first = rng.next() as u16;
                // Rows of whole first fragments (a polygon's inside), often.
                for row in 0..4 {
                    if rng.next().is_multiple_of(3) {
                        sets[4 * row..4 * row + 4].fill(FULL);
                        first |= ROW_BITS << (4 * row);
                    }
                }
                let colors: [Vec3; 16] = std::array::from_fn(|_| {
                    Vec3::from_array(std::array::from_fn(|_| match rng.next() % 8 {
                        0 => 0.0,
                        1 => 1.5,
                        2 => 1e-4,
                        _ => (rng.next() % 10_000) as f32 / 10_000.0,
                    }))
                });
                let vis = Visible { px, py, sets, first, covered: false };
                vb.accumulate(&vis, &CellColors::from(colors));
                for (i, &set) in sets.iter().enumerate().filter(|(_, &set)| set != 0) {
                    let p = (py as usize + i / 4) * 8 + px as usize + i % 4;
                    let n = set.count_ones();
                    for ch in 0..3 {
                        let v = s.weigh(s.encode(colors[i][ch]), n);
                        let v = if first >> i & 1 == 1 { v } else { s.sum(v, LogFine::from_code(expect[p][ch])) };
                        expect[p][ch] = s.store(v);
                    }
                }
                assert_eq!(vb.codes(), expect, "log{bits}");
            }
        }
    }
}
