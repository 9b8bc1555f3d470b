//! Video buffer (VB, P1 fig. 6): per-pixel accumulation of colour x area (P1's device
//! F1), the readout filter F2 and the gamma table; P1's logarithmic number format
//! beside a float reference and a linear fixed-point format for comparison.
//!
//! Accumulation (F1): each pixel sums `colour_i * area_i` over its visible fragments,
//! in priority order; the background is the last fragment of every pixel and fills
//! what is left, so the areas of a pixel always sum to one. The first fragment of a
//! pixel is written as it is, later ones read-modify-write (P1's first-write flag from
//! the subpixel mask memory: no clearing pass is needed for correctness).
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
//!   tables against float rounding).
//! - [`VbMode::Float`]: `f32` accumulators, the reference.
//! - [`VbMode::Linear`]: a linear fixed-point code of the same width, what P1's log
//!   scale replaced; kept to measure the contouring it avoids.
//!
//! # The log code (P1 eq. 3-4)
//! A VMEM word holds three `b`-bit codes (`b` = [`VbMode::Log`]`::bits`, 8 by
//! default: P1's 24-bit colour word). Layout of one code `q`, unsigned:
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
//! - **Gamma** ([`LogScale::gamma_table`], `u8`): index an F2 result in quarter codes,
//!   `0 ..= 4 Q1` (`b + 2` bits: 1021 entries for 8 bits), entry
//!   `round(255 c^(1/gamma))` with `c = exp(alpha (i/4 - Q1))` and 0 for zero (index
//!   below 4). It depends on the readout's gamma, so each readout builds it (1021
//!   powers for 8 bits, microseconds).
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

use glam::Vec3;

use super::gq::Share;
use super::spp::{Visible, CELL_SIDE};
use crate::model::stats::Counters;

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
    /// `T[0] = round(4 K ln 2)`: halving in quarter codes.
    ln2: i32,
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
            ln2,
        };
        scale.build_encoder();
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

/// The video memory of one [`VbMode`].
#[derive(Clone, Debug)]
enum Memory {
    /// Linear `f32` RGB.
    Float(Vec<Vec3>),
    /// Three log codes per pixel.
    Log { scale: &'static LogScale, codes: Vec<[u16; 3]> },
    /// Three linear codes per pixel.
    Linear { scale: LinearScale, codes: Vec<[u16; 3]> },
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
            VbMode::Log { bits } => Memory::Log { scale: LogScale::get(bits), codes: vec![[0; 3]; n] },
            VbMode::Linear { bits } => Memory::Linear { scale: LinearScale::new(bits), codes: vec![[0; 3]; n] },
        };
        Self { width, height, memory }
    }

    /// The mode (bit counts as clamped).
    pub fn mode(&self) -> VbMode {
        match &self.memory {
            Memory::Float(_) => VbMode::Float,
            Memory::Log { scale, .. } => VbMode::Log { bits: scale.bits },
            Memory::Linear { scale, .. } => VbMode::Linear { bits: (scale.max + 1).trailing_zeros() },
        }
    }

    /// Clears for a new frame (every mode's zero is all bits 0).
    pub fn clear(&mut self) {
        match &mut self.memory {
            Memory::Float(a) => a.fill(Vec3::ZERO),
            Memory::Log { codes, .. } | Memory::Linear { codes, .. } => codes.fill([0; 3]),
        }
    }

    /// Accumulates one cell's visible pixels with their colours (device F1): the
    /// first fragment of a pixel (`vis.first`) is written, later ones added.
    pub fn accumulate<const STATS: bool>(&mut self, vis: &Visible, colors: &[Vec3; 16], counters: &mut Counters) {
        let width = self.width as usize;
        match &mut self.memory {
            Memory::Float(accum) => for_visible(vis, width, |p, n, first, i| {
                let c = colors[i] * (n as f32 / AREA_DENOMINATOR as f32);
                let a = &mut accum[p];
                *a = if first { c } else { *a + c };
            }),
            Memory::Log { scale, codes } => for_visible(vis, width, |p, n, first, i| {
                let c = colors[i].to_array();
                let word = &mut codes[p];
                for ch in 0..3 {
                    let v = scale.weigh(scale.encode(c[ch]), n);
                    let v = if first { v } else { scale.sum(v, LogFine::from_code(word[ch])) };
                    word[ch] = scale.store(v);
                }
            }),
            Memory::Linear { scale, codes } => for_visible(vis, width, |p, n, first, i| {
                let c = colors[i].to_array();
                let word = &mut codes[p];
                for ch in 0..3 {
                    let v = scale.weigh(scale.encode(c[ch]), n);
                    let v = if first { v } else { (v + i32::from(word[ch])).min(scale.max) };
                    word[ch] = v as u16;
                }
            }),
        }
        if STATS {
            let visible = vis.sets.iter().enumerate().fold(0u16, |m, (i, &s)| m | u16::from(s != 0) << i);
            let first = (vis.first & visible).count_ones();
            counters.color.first_writes += u64::from(first);
            counters.color.read_modify_writes += u64::from(visible.count_ones() - first);
        }
    }

    /// The accumulated linear colour of a pixel (decoded from the mode's codes).
    pub fn linear(&self, x: u32, y: u32) -> Vec3 {
        let p = y as usize * self.width as usize + x as usize;
        match &self.memory {
            Memory::Float(accum) => accum[p],
            Memory::Log { scale, codes } => Vec3::from_array(codes[p].map(|q| scale.value(q) as f32)),
            Memory::Linear { scale, codes } => Vec3::from_array(codes[p].map(|q| f32::from(q) / scale.max as f32)),
        }
    }

    /// Reads the frame out through F2 and the gamma table.
    pub fn read_out(&self, opts: &Readout) -> Image {
        let mut pixels = vec![0u8; self.width as usize * self.height as usize * 3];
        self.read_out_rows(opts, 0..self.height as usize, &mut pixels);
        Image { width: self.width, height: self.height, pixels }
    }

    /// Reads the frame out in bands of rows on the current rayon pool: the same
    /// bytes as [`Self::read_out`] (each output row depends only on its own row and
    /// the one below).
    pub fn read_out_parallel(&self, opts: &Readout) -> Image {
        use rayon::prelude::*;
        let (w, h) = (self.width as usize, self.height as usize);
        let mut pixels = vec![0u8; w * h * 3];
        let band = READOUT_BAND_ROWS;
        pixels.par_chunks_mut(band * w * 3).enumerate().for_each(|(k, out)| {
            let y0 = k * band;
            self.read_out_rows(opts, y0..(y0 + band).min(h), out);
        });
        Image { width: self.width, height: self.height, pixels }
    }

    /// Reads out rows `rows` (F2 uses the row below the last one) into `out`, RGB8,
    /// `3 * width * rows.len()` bytes.
    pub fn read_out_rows(&self, opts: &Readout, rows: std::ops::Range<usize>, out: &mut [u8]) {
        let (w, h) = (self.width as usize, self.height as usize);
        match &self.memory {
            Memory::Float(accum) => read_out_float(w, h, accum, opts, rows, out),
            Memory::Log { scale, codes } => {
                read_out_fine(w, h, codes, opts.filter, *scale, &scale.gamma_table(opts.gamma), rows, out)
            }
            Memory::Linear { scale, codes } => {
                read_out_fine(w, h, codes, opts.filter, scale, &scale.gamma_table(opts.gamma), rows, out)
            }
        }
    }

    /// Copies the pixels of a matrix VP's share from its buffer, of the same size and
    /// mode (P3: the video memories of a VP matrix together form one interleaved
    /// image), a tile run at a time. Panics on a buffer of another size or mode.
    pub fn copy_share_from(&mut self, other: &VideoBuffer, share: &Share) {
        assert_eq!(
            (self.width, self.height, self.mode()),
            (other.width, other.height, other.mode()),
            "video buffers of different sizes or modes"
        );
        let (w, h) = (self.width as usize, self.height as usize);
        match (&mut self.memory, &other.memory) {
            (Memory::Float(dst), Memory::Float(src)) => copy_share(dst, src, w, h, share),
            (Memory::Log { codes: dst, .. }, Memory::Log { codes: src, .. })
            | (Memory::Linear { codes: dst, .. }, Memory::Linear { codes: src, .. }) => {
                copy_share(dst, src, w, h, share)
            }
            _ => unreachable!("the modes were compared above"),
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
            _ => unreachable!("the modes were compared above"),
        }
    }

    /// Cells per row and rows of 4x4 cells covering the buffer.
    pub fn cells(&self) -> (usize, usize) {
        (self.width.div_ceil(CELL_SIDE) as usize, self.height.div_ceil(CELL_SIDE) as usize)
    }
}

/// Copies the pixels of a matrix VP's share: whole tile runs of the rows it owns.
fn copy_share<T: Copy>(dst: &mut [T], src: &[T], width: usize, height: usize, share: &Share) {
    let tile = share.tile as usize;
    for y in 0..height {
        if (y / tile) % share.q as usize != share.j as usize {
            continue;
        }
        let row = y * width;
        let mut x = share.i as usize * tile;
        while x < width {
            let end = (x + tile).min(width);
            dst[row + x..row + end].copy_from_slice(&src[row + x..row + end]);
            x += tile * share.p as usize;
        }
    }
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
fn read_out_float(w: usize, h: usize, accum: &[Vec3], opts: &Readout, rows: std::ops::Range<usize>, out: &mut [u8]) {
    let table = gamma_table(opts.gamma);
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
trait QuarterCodes {
    /// A stored code as a quarter-code value.
    fn load(&self, q: u16) -> i32;
    /// The half sum of two values.
    fn mean(&self, a: i32, b: i32) -> i32;
    /// The gamma table's address of a value.
    fn address(&self, v: i32) -> usize;
}

impl QuarterCodes for LogScale {
    #[inline]
    fn load(&self, q: u16) -> i32 {
        LogFine::from_code(q).0
    }

    #[inline]
    fn mean(&self, a: i32, b: i32) -> i32 {
        LogScale::mean(self, LogFine(a), LogFine(b)).0
    }

    #[inline]
    fn address(&self, v: i32) -> usize {
        // Zero is far below 0; every other result is at least code 1.
        v.max(0) as usize
    }
}

impl QuarterCodes for LinearScale {
    #[inline]
    fn load(&self, q: u16) -> i32 {
        i32::from(q) << LOG_FRAC_BITS
    }

    #[inline]
    fn mean(&self, a: i32, b: i32) -> i32 {
        // Exact: the first pass's sums are even in quarter codes.
        (a + b) >> 1
    }

    #[inline]
    fn address(&self, v: i32) -> usize {
        v as usize
    }
}

/// The fixed-point paths' readout: F2 on quarter codes, then the gamma table.
#[allow(clippy::too_many_arguments, reason = "the readout's registers, passed as they are")]
fn read_out_fine(
    w: usize,
    h: usize,
    codes: &[[u16; 3]],
    filter: bool,
    f2: &impl QuarterCodes,
    table: &[u8],
    rows: std::ops::Range<usize>,
    out: &mut [u8],
) {
    let mut line = vec![[0i32; 3]; w];
    let mut pixels = out.chunks_exact_mut(3);
    for y in rows {
        let below = (y + 1).min(h - 1);
        // Pass 1: half sums of vertically adjacent pixels (the line buffer).
        for (x, l) in line.iter_mut().enumerate() {
            let (a, b) = (codes[y * w + x], codes[below * w + x]);
            *l = if filter {
                std::array::from_fn(|ch| f2.mean(f2.load(a[ch]), f2.load(b[ch])))
            } else {
                a.map(|q| f2.load(q))
            };
        }
        // Pass 2: half sums of horizontally adjacent ones.
        for x in 0..w {
            let (a, b) = (line[x], line[(x + 1).min(w - 1)]);
            let px = pixels.next().expect("out holds the rows");
            for ch in 0..3 {
                let v = if filter { f2.mean(a[ch], b[ch]) } else { a[ch] };
                px[ch] = table[f2.address(v)];
            }
        }
    }
}

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
