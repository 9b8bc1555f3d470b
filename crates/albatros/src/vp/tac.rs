//! The ROM tables of the texture address computers (TAC, P2 fig. 1, «ТАС»): the two
//! per-pixel functions the CC does not compute by arithmetic.
//!
//! P2: the TAC multiplies by `Z`, finds the fog factor `exp(-Z/Z0)` and the texture
//! address with the trilinear coefficients, one pixel per clock in each of four
//! TACs. A machine of that time read such functions from ROM; so does this one:
//!
//! - **Fog ROM**: `f = exp(-x)`, `x = Z/Z0`, tabulated at `x = k / 256` for
//!   `k = 0..4096` (`x` up to 16, where `exp(-16) = 1.1e-7` is below anything a VB
//!   mode shows: from there on `f = 0`, fully fogged), and interpolated linearly
//!   between entries: error below `3e-6` (relative, and absolute near the end).
//! - **`log2` ROM** for the level of detail `log2(S/L 2^n)`: the exponent of the
//!   `f32` footprint is the integer part; the fraction is `log2(1 + m)` of the
//!   mantissa `m`, tabulated at `m = k / 256` and interpolated linearly: error below
//!   `4e-6` of a level, exact at powers of two (the levels themselves).
//!
//! Both replace libm's `exp` and `log2` (which cost about 27 instructions each per
//! pixel here and are not what the hardware did); each is a few operations and two
//! reads. The entries are `f32` rounded from `f64`; `albatros tables` writes them.
//! The AVX2 copies read each ROM's steps too (entry `k + 1` less entry `k`, the `f32`
//! difference the interpolation takes, kept beside the entries): one subtraction
//! fewer a read, the same bits.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;
use std::sync::OnceLock;

/// Fog ROM entries per unit of `x = Z / Z0`.
pub const FOG_STEPS_PER_UNIT: u32 = 256;

/// `x = Z / Z0` from which the fog is total (`f = 0`).
pub const FOG_RANGE: u32 = 16;

/// Fog ROM entries: `k = 0..=4096` and a spare zero, so that the interpolation at
/// the end of the range reads inside the table.
const FOG_ENTRIES: usize = (FOG_RANGE * FOG_STEPS_PER_UNIT) as usize + 2;

/// Bits of the mantissa that address the `log2` ROM.
pub const LOG2_ADDRESS_BITS: u32 = 8;

/// `log2` ROM entries: `m = k / 256` for `k = 0..=256`.
const LOG2_ENTRIES: usize = (1 << LOG2_ADDRESS_BITS) + 1;

/// Mantissa bits of an `f32`.
const MANTISSA_BITS: u32 = 23;

/// Entries of the AVX2 copies' window of a ROM ([`window_steps_avx2`]): one
/// register of `f32`.
const WINDOW: usize = 8;

/// Entries of the window below lane 0's entry: the window holds entries `k0 - 3
/// ..= k0 + 4` (and, one further on, their next entries).
const WINDOW_BACK: usize = 3;

/// Spare entries (zeros, never read for a lane) stored before a ROM's first entry
/// and after its last, so that the window around any entry lies inside the stored
/// table: [`WINDOW_BACK`] before; after, the next entries' window of the last
/// pair `len - 2` reaches entry `len - 2 - WINDOW_BACK + WINDOW`, that is
/// `WINDOW - WINDOW_BACK - 1` past the last.
const PAD_BEFORE: usize = WINDOW_BACK;
const PAD_AFTER: usize = WINDOW - WINDOW_BACK - 1;

/// The TAC's ROMs, each stored with [`PAD_BEFORE`] and [`PAD_AFTER`] spare
/// entries around it (entry `k` at `PAD_BEFORE + k`).
#[derive(Debug, Clone, PartialEq)]
pub struct TacRom {
    /// `exp(-k / 256)`, then zeros from `k = 4096` (`fog[0]`); and the steps,
    /// entry `k + 1` less entry `k` (as `f32`, the difference [`Self::fog`]
    /// takes), stored alike (`fog[1]`, the last entry's and the spare ones zero):
    /// the AVX2 copy's window reads them where it had read the entries `k + 1`
    /// and subtracted ([`TacRom::fog_avx2`]). In one allocation, so that the
    /// steps are at a constant offset from the entries (a separate box had cost
    /// a pointer's load and a register: terrain +1.4 M instructions).
    fog: Box<[[f32; PAD_BEFORE + FOG_ENTRIES + PAD_AFTER]; 2]>,
    /// `log2(1 + k / 256)`.
    log2: [f32; PAD_BEFORE + LOG2_ENTRIES + PAD_AFTER],
    /// The `log2` ROM as pairs, entry `k` and its step (entry `k + 1` less entry
    /// `k`, as `f32`, the difference [`Self::log2`] takes), for `k = 0..256`: the
    /// AVX2 copy's 8-byte load of a lane reads both, where it had read entries
    /// `k` and `k + 1` and subtracted ([`Self::log2_avx2`]).
    log2_steps: [[f32; 2]; LOG2_ENTRIES - 1],
}

impl TacRom {
    /// The ROM contents (computed once).
    pub fn get() -> &'static TacRom {
        static ROM: OnceLock<TacRom> = OnceLock::new();
        ROM.get_or_init(Self::build)
    }

    fn build() -> Self {
        let full = (FOG_RANGE * FOG_STEPS_PER_UNIT) as usize;
        // Entry `k` at `PAD_BEFORE + k`; the spare entries zero.
        let entry = |at: usize, entries: usize| at.checked_sub(PAD_BEFORE).filter(|&k| k < entries);
        let fog: [f32; PAD_BEFORE + FOG_ENTRIES + PAD_AFTER] = std::array::from_fn(|at| match entry(at, FOG_ENTRIES) {
            Some(k) if k < full => (-(k as f64) / f64::from(FOG_STEPS_PER_UNIT)).exp() as f32,
            _ => 0.0,
        });
        let steps = std::array::from_fn(|at| match entry(at, FOG_ENTRIES - 1) {
            Some(_) => fog[at + 1] - fog[at],
            None => 0.0,
        });
        let log2 = std::array::from_fn(|at| match entry(at, LOG2_ENTRIES) {
            Some(k) => (1.0 + k as f64 / f64::from(1u32 << LOG2_ADDRESS_BITS)).log2() as f32,
            None => 0.0,
        });
        let log2_steps = std::array::from_fn(|k| {
            let (a, b) = (log2[PAD_BEFORE + k], log2[PAD_BEFORE + k + 1]);
            [a, b - a]
        });
        Self { fog: Box::new([fog, steps]), log2, log2_steps }
    }

    /// The fog factor `f = exp(-x)` for `x = Z / Z0`: 1 at 0, 0 from
    /// [`FOG_RANGE`] on (and for infinities); a NaN or negative `x` gives 1.
    #[inline(always)]
    pub fn fog(&self, x: f32) -> f32 {
        // `max` before `min`, not `clamp`: NaN goes to 0 (no fog), where `clamp`
        // would keep it.
        let s = (x * FOG_STEPS_PER_UNIT as f32).max(0.0).min((FOG_RANGE * FOG_STEPS_PER_UNIT) as f32);
        // Non-negative and at most 4096: the cast is the floor, and `k + 1` is in
        // the table. (Through `i32`: a direct cast to `usize` costs several
        // instructions more.)
        let k = s as i32 as usize;
        let t = s - k as f32;
        let fog = self.fog_table();
        let (a, b) = (fog[k], fog[(k + 1).min(FOG_ENTRIES - 1)]);
        a + t * (b - a)
    }

    /// `log2(x)` for a positive normal `x` (the callers pass footprints above one
    /// texel): the exponent plus the ROM's fraction of the mantissa.
    #[inline(always)]
    pub fn log2(&self, x: f32) -> f32 {
        let bits = x.to_bits();
        let exponent = ((bits >> MANTISSA_BITS) & 0xFF) as i32 - 127;
        let low_bits = MANTISSA_BITS - LOG2_ADDRESS_BITS;
        let k = ((bits >> low_bits) & ((1 << LOG2_ADDRESS_BITS) - 1)) as usize;
        let t = (bits & ((1 << low_bits) - 1)) as f32 * (1.0 / (1u32 << low_bits) as f32);
        let log2 = self.log2_table();
        let (a, b) = (log2[k], log2[(k + 1).min(LOG2_ENTRIES - 1)]);
        exponent as f32 + (a + t * (b - a))
    }

    /// [`Self::fog`] of `N` values side by side, bit for bit lane by lane, laid out
    /// as arrays over the lanes so that the arithmetic vectorises; only the two ROM
    /// reads per lane go one by one. The floor is taken as `floor` and
    /// `small_int` (where `s as i32` costs a branch per lane for Rust's saturating
    /// cast); `s` is in `0..=4096`, so both give the same integer, and `t` is
    /// formed from that integer as in [`Self::fog`].
    #[inline(always)]
    pub fn fog_lanes<const N: usize>(&self, x: &[f32; N]) -> [f32; N] {
        let full = FOG_RANGE * FOG_STEPS_PER_UNIT;
        let mut s = [0.0f32; N];
        let mut k = [0u32; N];
        for l in 0..N {
            s[l] = (x[l] * FOG_STEPS_PER_UNIT as f32).max(0.0).min(full as f32);
            // In `0..=4096` already: the `min` tells the compiler so, and with it
            // that `k + 1` is inside the table (no bounds check).
            k[l] = (small_int(s[l].floor()) as u32).min(full);
        }
        let fog: &[f32; FOG_ENTRIES] = self.fog_table().try_into().expect("the fog ROM's entries");
        let mut f = [0.0f32; N];
        for l in 0..N {
            let t = s[l] - k[l] as i32 as f32;
            let (a, b) = (fog[k[l] as usize], fog[k[l] as usize + 1]);
            f[l] = a + t * (b - a);
        }
        f
    }

    /// [`Self::log2`] of `N` values side by side, bit for bit lane by lane, as
    /// arrays that vectorise (only the ROM reads go one by one). Any bits give a
    /// finite value (the address is 8 bits of the mantissa), so lanes that the
    /// caller will not use may hold anything.
    #[inline(always)]
    pub fn log2_lanes<const N: usize>(&self, x: &[f32; N]) -> [f32; N] {
        let low_bits = MANTISSA_BITS - LOG2_ADDRESS_BITS;
        let mut exponent = [0.0f32; N];
        let mut k = [0u32; N];
        let mut t = [0.0f32; N];
        for l in 0..N {
            let bits = x[l].to_bits();
            exponent[l] = (((bits >> MANTISSA_BITS) & 0xFF) as i32 - 127) as f32;
            k[l] = (bits >> low_bits) & ((1 << LOG2_ADDRESS_BITS) - 1);
            // Below 2^15: through `i32` the same value, in one conversion that
            // vectorises.
            t[l] = (bits & ((1 << low_bits) - 1)) as i32 as f32 * (1.0 / (1u32 << low_bits) as f32);
        }
        let log2: &[f32; LOG2_ENTRIES] = self.log2_table().try_into().expect("the log2 ROM's entries");
        let mut out = [0.0f32; N];
        for l in 0..N {
            let (a, b) = (log2[k[l] as usize], log2[k[l] as usize + 1]);
            out[l] = exponent[l] + (a + t[l] * (b - a));
        }
        out
    }

    /// [`Self::fog_lanes`] of eight values in an AVX2 register, bit for bit: the
    /// same operations in the same order, the two ROM reads per lane as one
    /// 8-byte load ([`entries_avx2`]; `k` is at most 4096 and the table holds
    /// 4098 entries, so both reads are inside it).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn fog_avx2(&self, x: __m256) -> __m256 {
        let full = FOG_RANGE * FOG_STEPS_PER_UNIT;
        // `max(x * 256, 0)` then `min(.., 4096)`, NaN going to 0 as `f32::max`
        // does (`maxps` returns its second operand when either is NaN).
        let s = _mm256_mul_ps(x, _mm256_set1_ps(FOG_STEPS_PER_UNIT as f32));
        let s = _mm256_min_ps(_mm256_max_ps(s, _mm256_setzero_ps()), _mm256_set1_ps(full as f32));
        // `s` is in `0 ..= full` (no NaN), so `k` is too: [`Self::fog_lanes`]'s
        // clamp of `k` to `full`, and [`entries_avx2`]'s to the ROM's last entry but
        // one (`full`), leave it as it is (terrain: ~0.7 M instructions a frame).
        // `t = s - k` from the floor itself: `k` as `f32` is the floor (an
        // integer in `0..=full`), with no conversion back (terrain: ~0.4 M
        // instructions a frame).
        let floor = _mm256_floor_ps(s);
        let k = small_int_avx2(floor);
        let t = _mm256_sub_ps(s, floor);
        debug_assert!(self.fog_table().len() == full as usize + 2);
        // SAFETY: every lane of `k` is at most `full`, the fog ROM's last entry but
        // one (just above).
        #[allow(unsafe_code, reason = "a ROM read at entries known to be inside it")]
        let (a, step) = unsafe { window_steps_avx2(&self.fog[0][..], &self.fog[1][..], k) };
        _mm256_add_ps(a, _mm256_mul_ps(t, step))
    }

    /// [`Self::log2_lanes`] of eight values in an AVX2 register, bit for bit, the
    /// two ROM reads per lane as one 8-byte load of entry `k` and its step from
    /// [`TacRom::log2_steps`] ([`pairs_avx2`]; the address is 8 bits, at most
    /// 255, and the table holds 256 pairs): one subtraction fewer than reading
    /// entries `k` and `k + 1` (default: colour + VB −0.16 M instructions).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn log2_avx2(&self, x: __m256) -> __m256 {
        let low_bits = MANTISSA_BITS - LOG2_ADDRESS_BITS;
        let bits = _mm256_castps_si256(x);
        let exponent = _mm256_sub_epi32(
            _mm256_and_si256(_mm256_srli_epi32::<{ MANTISSA_BITS as i32 }>(bits), _mm256_set1_epi32(0xFF)),
            _mm256_set1_epi32(127),
        );
        let exponent = _mm256_cvtepi32_ps(exponent);
        let k = _mm256_and_si256(
            _mm256_srli_epi32::<{ (MANTISSA_BITS - LOG2_ADDRESS_BITS) as i32 }>(bits),
            _mm256_set1_epi32((1 << LOG2_ADDRESS_BITS) - 1),
        );
        let t = _mm256_cvtepi32_ps(_mm256_and_si256(bits, _mm256_set1_epi32((1 << low_bits) - 1)));
        let t = _mm256_mul_ps(t, _mm256_set1_ps(1.0 / (1u32 << low_bits) as f32));
        let (a, step) = pairs_avx2::<2>(self.log2_steps.as_flattened(), k);
        _mm256_add_ps(exponent, _mm256_add_ps(a, _mm256_mul_ps(t, step)))
    }

    /// [`Self::fog_lanes`] of sixteen values in an AVX-512 register, bit for bit,
    /// as [`Self::fog_avx2`] does it.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(crate) fn fog_avx512(&self, x: __m512) -> __m512 {
        let full = FOG_RANGE * FOG_STEPS_PER_UNIT;
        let s = _mm512_mul_ps(x, _mm512_set1_ps(FOG_STEPS_PER_UNIT as f32));
        let s = _mm512_min_ps(_mm512_max_ps(s, _mm512_setzero_ps()), _mm512_set1_ps(full as f32));
        let k = _mm512_min_epu32(small_int_avx512(floor_avx512(s)), _mm512_set1_epi32(full as i32));
        let t = _mm512_sub_ps(s, _mm512_cvtepi32_ps(k));
        let (a, b) = entries_avx512(self.fog_table(), k);
        _mm512_add_ps(a, _mm512_mul_ps(t, _mm512_sub_ps(b, a)))
    }

    /// [`Self::log2_lanes`] of sixteen values in an AVX-512 register, bit for bit,
    /// as [`Self::log2_avx2`] does it.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(crate) fn log2_avx512(&self, x: __m512) -> __m512 {
        let low_bits = MANTISSA_BITS - LOG2_ADDRESS_BITS;
        let bits = _mm512_castps_si512(x);
        let exponent = _mm512_sub_epi32(
            _mm512_and_si512(_mm512_srli_epi32::<{ MANTISSA_BITS }>(bits), _mm512_set1_epi32(0xFF)),
            _mm512_set1_epi32(127),
        );
        let exponent = _mm512_cvtepi32_ps(exponent);
        let k = _mm512_and_si512(
            _mm512_srli_epi32::<{ MANTISSA_BITS - LOG2_ADDRESS_BITS }>(bits),
            _mm512_set1_epi32((1 << LOG2_ADDRESS_BITS) - 1),
        );
        let t = _mm512_cvtepi32_ps(_mm512_and_si512(bits, _mm512_set1_epi32((1 << low_bits) - 1)));
        let t = _mm512_mul_ps(t, _mm512_set1_ps(1.0 / (1u32 << low_bits) as f32));
        let (a, b) = entries_avx512(self.log2_table(), k);
        _mm512_add_ps(exponent, _mm512_add_ps(a, _mm512_mul_ps(t, _mm512_sub_ps(b, a))))
    }

    /// The fog ROM's entries.
    #[inline(always)]
    pub fn fog_table(&self) -> &[f32] {
        &self.fog[0][PAD_BEFORE..PAD_BEFORE + FOG_ENTRIES]
    }

    /// The `log2` ROM's entries.
    #[inline(always)]
    pub fn log2_table(&self) -> &[f32] {
        &self.log2[PAD_BEFORE..PAD_BEFORE + LOG2_ENTRIES]
    }

    /// The fog ROM in `$readmemh` form: one `f32` bit pattern in hex per line, in
    /// address order (`albatros tables` writes it).
    pub fn fog_hex(&self) -> String {
        self.fog_table().iter().map(|v| format!("{:08x}\n", v.to_bits())).collect()
    }

    /// The `log2` ROM in `$readmemh` form, like [`Self::fog_hex`].
    pub fn log2_hex(&self) -> String {
        self.log2_table().iter().map(|v| format!("{:08x}\n", v.to_bits())).collect()
    }
}

/// `x as i32` for an integral `x` in `-2^22..=2^22`, in operations that vectorise
/// (the cast itself costs a branch per lane for Rust's saturation): adding
/// `1.5 * 2^23`, exact there, puts `x` in the low bits of the mantissa.
#[inline(always)]
pub(crate) fn small_int(x: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0;
    (x + MAGIC).to_bits() as i32 - MAGIC.to_bits() as i32
}

/// [`small_int`] of eight values in an AVX2 register: for an integral `x` in its
/// range the truncating conversion is exact, the same integer in one
/// instruction (where the addition of [`small_int`] takes two).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) fn small_int_avx2(x: __m256) -> __m256i {
    _mm256_cvttps_epi32(x)
}

/// Entry `k` and step `k` (entry `k + 1` less entry `k`) of a ROM for eight
/// lanes of `k` (each lane at most the ROM's last entry but one), `padded` the
/// ROM as [`TacRom`] stores it (with [`PAD_BEFORE`] and [`PAD_AFTER`] spare
/// entries) and `steps` its steps stored alike ([`TacRom::fog`]'s second table): when
/// every lane's `k` lies in the window of [`WINDOW`] entries from lane 0's `k -
/// WINDOW_BACK`, two permutes of the window of entries and of the window of
/// steps, read from memory (the spare entries keep both inside the stored
/// tables for any lane 0); else [`entries_avx2`]'s eight loads and the
/// subtraction. The same values either way: a step is the `f32` difference of
/// the two entries, which the portable copies take. A half cell's `Z` varies
/// little: its fog entries lie in one window in 99 % of terrain's half cells,
/// and in 83 % (one half visible) to 100 % (both) of default's; the window costs
/// ~13 instructions where the loads, their extracts and shuffles cost ~21
/// (colour + VB: default 111.4 → 109.9 M, terrain 170.8 → 166.7 M, city 71.5 →
/// 69.7 M). The steps stored, rather than the window of entries `k + 1` and a
/// subtraction: one instruction fewer a half cell. The `log2` ROM keeps the
/// loads: a footprint's mantissa moves faster than `Z` (its square), and its
/// window missed in most half cells (default +0.4 M).
///
/// # Safety
///
/// Every lane of `k` must be at most the ROM's last entry but one (the window's
/// loads read from lane 0's entry: the clamp it had cost ~2 instructions a half
/// cell, where the fog's `k` is clamped already).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
#[allow(unsafe_code, reason = "the window's start is lane 0's entry, which the caller keeps inside the ROM")]
unsafe fn window_steps_avx2(padded: &[f32], steps: &[f32], k: __m256i) -> (__m256, __m256) {
    assert!(steps.len() == padded.len());
    let table = &padded[PAD_BEFORE..padded.len() - PAD_AFTER];
    // (No clamp: every lane is at most the last entry but one, this function's
    // condition, so `entries_avx2`'s reads the same entries.)
    debug_assert!(
        {
            let mut lanes = [0u32; 8];
            // SAFETY: `lanes` is 8 `u32`, the 32 bytes the store writes.
            #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
            unsafe {
                _mm256_storeu_si256(lanes.as_mut_ptr().cast(), k)
            };
            lanes.iter().all(|&k| (k as usize) < table.len() - 1)
        },
        "an entry past the ROM's last but one"
    );
    // Lane 0's entry, at most `table.len() - 2`; the window starts `WINDOW_BACK`
    // below it, at `k0` in `padded`.
    let k0 = _mm256_cvtsi256_si32(k) as u32 as usize;
    // (Lane 0 broadcast within the registers, not from `k0`: one instruction.)
    let first = _mm256_broadcastd_epi32(_mm256_castsi256_si128(k));
    let at = _mm256_sub_epi32(k, _mm256_sub_epi32(first, _mm256_set1_epi32(WINDOW_BACK as i32)));
    // Offsets in `0..WINDOW` have no bit above the window's; a lane below the
    // window has a negative offset, all its high bits set.
    if _mm256_testz_si256(at, _mm256_set1_epi32(!(WINDOW as i32 - 1))) == 0 {
        let (a, b) = entries_avx2(table, k);
        return (a, _mm256_sub_ps(b, a));
    }
    debug_assert!(k0 + WINDOW < padded.len());
    // SAFETY: `k0` is at most `table.len() - 2` (this function's condition), so the
    // `WINDOW` entries read from `padded[k0]` and from `steps[k0]` end at `k0 +
    // WINDOW - 1`, at most `table.len() - 3 + WINDOW` = `PAD_BEFORE +
    // table.len() + PAD_AFTER - 2`, inside `padded` and `steps` (of its length,
    // the assertion above).
    #[allow(unsafe_code, reason = "loads of a window of a padded ROM, its start inside it")]
    // (`vlddqu`: an unaligned load of 32 bytes in one instruction, where the
    // compiler splits `_mm256_loadu_ps` into two halves and an insert.)
    let (low, high) = unsafe {
        (_mm256_lddqu_si256(padded.as_ptr().add(k0).cast()), _mm256_lddqu_si256(steps.as_ptr().add(k0).cast()))
    };
    (_mm256_permutevar8x32_ps(_mm256_castsi256_ps(low), at), _mm256_permutevar8x32_ps(_mm256_castsi256_ps(high), at))
}

/// Entries `k` and `k + 1` of a ROM for eight lanes of `k` (each lane at most
/// `table.len() - 2`, which the callers' clamps and masks ensure; clamped here too,
/// so that no lane reads outside the table): both at once, one 8-byte load per
/// lane, by scalar loads rather than gathers. On Zen 3 an 8-lane gather costs
/// more than the eight loads and the shuffles that put them in place (the
/// colour computers 5 % faster on default than with two 4-byte gathers, 3 %
/// faster than with two 8-byte gathers of 4 lanes).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn entries_avx2(table: &[f32], k: __m256i) -> (__m256, __m256) {
    pairs_avx2::<1>(table, k)
}

/// [`entries_avx2`] of a table of pairs side by side (`STRIDE` 2, pair `k` at
/// `table[2 k]`): the two `f32` of pair `k` for eight lanes of `k`, each lane
/// clamped to the last pair (`STRIDE` 1: the entries `k` and `k + 1` of
/// [`entries_avx2`]). The scale of the address is the load's own (no
/// instruction).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn pairs_avx2<const STRIDE: usize>(table: &[f32], k: __m256i) -> (__m256, __m256) {
    // The last `k` whose two `f32` at `STRIDE k` are inside the table.
    let last = (table.len() - 2) / STRIDE;
    let k = _mm256_min_epu32(k, _mm256_set1_epi32(last as i32));
    let mut at = [0u32; 8];
    // SAFETY: `at` is 8 `u32`, the 32 bytes the store writes.
    #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
    unsafe {
        _mm256_storeu_si256(at.as_mut_ptr().cast(), k)
    };
    let table = table.as_ptr();
    // Entries `a`, `a + 1`, `b`, `b + 1`.
    let pairs = |a: u32, b: u32| {
        // SAFETY: `a` and `b` are lanes of `k`, each at most `last` (the `min`
        // above), so `STRIDE a` and `STRIDE b` are at most `table.len() - 2`: the
        // 8 bytes at each are two `f32` of the table.
        #[allow(unsafe_code, reason = "8-byte loads from a ROM, the addresses clamped inside it")]
        unsafe {
            _mm_castpd_ps(_mm_loadh_pd(
                _mm_load_sd(table.add(STRIDE * a as usize).cast()),
                table.add(STRIDE * b as usize).cast(),
            ))
        }
    };
    // Lanes 0, 1 | 4, 5 and 2, 3 | 6, 7 (entry and next, interleaved), so that
    // the even and the odd `f32` of each 128-bit half are `k` and `k + 1` in
    // lane order.
    let low = _mm256_set_m128(pairs(at[4], at[5]), pairs(at[0], at[1]));
    let high = _mm256_set_m128(pairs(at[6], at[7]), pairs(at[2], at[3]));
    (_mm256_shuffle_ps::<0b10_00_10_00>(low, high), _mm256_shuffle_ps::<0b11_01_11_01>(low, high))
}

/// Entries `k` and `k + 1` of a ROM for sixteen lanes of `k` (each lane at most
/// `table.len() - 2`, which the callers' clamps and masks ensure; clamped here too,
/// so that no lane reads outside the table). Both are read at once, as one 8-byte
/// gather per lane, in two gathers of 8 lanes, then split into the even and the
/// odd `f32`: half the gathered elements of two 4-byte gathers of 16.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn entries_avx512(table: &[f32], k: __m512i) -> (__m512, __m512) {
    let k = _mm512_min_epu32(k, _mm512_set1_epi32(table.len() as i32 - 2));
    // SAFETY: every lane of `k` is at most `table.len() - 2` (the `min` above):
    // the 8 bytes read at entry `k` are entries `k` and `k + 1`, inside the table.
    #[allow(unsafe_code, reason = "gathers from a ROM, the addresses clamped inside it")]
    let (low, high) = unsafe {
        let at = table.as_ptr().cast::<f64>();
        (
            _mm512_i32gather_pd::<4>(_mm512_castsi512_si256(k), at),
            _mm512_i32gather_pd::<4>(_mm512_extracti64x4_epi64::<1>(k), at),
        )
    };
    let (low, high) = (_mm512_castpd_ps(low), _mm512_castpd_ps(high));
    let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
    let odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
    (_mm512_permutex2var_ps(low, even, high), _mm512_permutex2var_ps(low, odd, high))
}

/// [`small_int`] of sixteen values in an AVX-512 register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
pub(crate) fn small_int_avx512(x: __m512) -> __m512i {
    const MAGIC: f32 = 12_582_912.0;
    _mm512_sub_epi32(
        _mm512_castps_si512(_mm512_add_ps(x, _mm512_set1_ps(MAGIC))),
        _mm512_set1_epi32(MAGIC.to_bits() as i32),
    )
}

/// `floor` of sixteen values in an AVX-512 register (`roundscale` to integers,
/// rounding down, exceptions suppressed: `roundps` with the same mode in AVX2).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
pub(crate) fn floor_avx512(x: __m512) -> __m512 {
    _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fog_rom_follows_exp_and_its_ends() {
        let rom = TacRom::get();
        assert_eq!(rom.fog(0.0), 1.0);
        assert_eq!(rom.fog(-3.0), 1.0);
        assert_eq!(rom.fog(f32::NAN), 1.0);
        assert_eq!(rom.fog(16.0), 0.0);
        assert_eq!(rom.fog(f32::INFINITY), 0.0);
        // Relative error before the last step, absolute error everywhere.
        let (mut relative, mut absolute) = (0.0f64, 0.0f64);
        for i in 0..220_000 {
            let x = i as f32 * 8e-5;
            let want = (-f64::from(x)).exp();
            let error = (f64::from(rom.fog(x)) - want).abs();
            absolute = absolute.max(error);
            if x < 15.99 {
                relative = relative.max(error / want);
            }
        }
        assert!(relative < 3e-6, "fog ROM relative error {relative}");
        assert!(absolute < 3e-6, "fog ROM absolute error {absolute}");
        // Monotone: more distance, more fog.
        let mut last = 2.0;
        for i in 0..=(17 * 256 * 4) {
            let f = rom.fog(i as f32 / 1024.0);
            assert!(f <= last, "fog rises at x = {}", i as f32 / 1024.0);
            last = f;
        }
    }

    /// Values that probe the ROMs' ends and every odd input: zeros of both signs,
    /// NaN, infinities, negatives, the last entries, subnormals.
    const ODD: [f32; 14] = [
        0.0,
        -0.0,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        -3.0,
        15.999_999,
        16.0,
        16.000_002,
        1e30,
        -1e-30,
        1e-40,
        f32::MIN_POSITIVE,
        f32::MAX,
    ];

    /// [`TacRom::fog_avx2`] and [`TacRom::log2_avx2`] of eight values, where the
    /// processor has AVX2.
    #[cfg(target_arch = "x86_64")]
    fn roms_avx2(rom: &TacRom, x: &[f32; 8]) -> Option<([f32; 8], [f32; 8])> {
        #[target_feature(enable = "avx2")]
        #[allow(unsafe_code, reason = "a load and stores of arrays of a register's size")]
        fn run(rom: &TacRom, x: &[f32; 8]) -> ([f32; 8], [f32; 8]) {
            let (mut fog, mut log2) = ([0.0f32; 8], [0.0f32; 8]);
            // SAFETY: each array is 8 `f32`, the 32 bytes each load or store touches.
            unsafe {
                let x = _mm256_loadu_ps(x.as_ptr());
                _mm256_storeu_ps(fog.as_mut_ptr(), rom.fog_avx2(x));
                _mm256_storeu_ps(log2.as_mut_ptr(), rom.log2_avx2(x));
            }
            (fog, log2)
        }
        // SAFETY: the processor has AVX2.
        #[allow(unsafe_code, reason = "a test of the AVX2 copy, after detection")]
        std::is_x86_feature_detected!("avx2").then(|| unsafe { run(rom, x) })
    }

    /// [`TacRom::fog_avx512`] and [`TacRom::log2_avx512`] of sixteen values, where
    /// the processor has AVX-512F.
    #[cfg(target_arch = "x86_64")]
    fn roms_avx512(rom: &TacRom, x: &[f32; 16]) -> Option<([f32; 16], [f32; 16])> {
        #[target_feature(enable = "avx512f")]
        #[allow(unsafe_code, reason = "a load and stores of arrays of a register's size")]
        fn run(rom: &TacRom, x: &[f32; 16]) -> ([f32; 16], [f32; 16]) {
            let (mut fog, mut log2) = ([0.0f32; 16], [0.0f32; 16]);
            // SAFETY: each array is 16 `f32`, the 64 bytes each load or store touches.
            unsafe {
                let x = _mm512_loadu_ps(x.as_ptr());
                _mm512_storeu_ps(fog.as_mut_ptr(), rom.fog_avx512(x));
                _mm512_storeu_ps(log2.as_mut_ptr(), rom.log2_avx512(x));
            }
            (fog, log2)
        }
        // SAFETY: the processor has AVX-512F.
        #[allow(unsafe_code, reason = "a test of the AVX-512 copy, after detection")]
        std::is_x86_feature_detected!("avx512f").then(|| unsafe { run(rom, x) })
    }

    /// The AVX2 and AVX-512 copies against the ROMs, bit for bit, where the
    /// processor has them (the eight values twice for AVX-512, the second time
    /// in reverse order).
    fn check_simd(rom: &TacRom, x: &[f32; 8]) {
        #[cfg(target_arch = "x86_64")]
        if let Some((fog, log2)) = roms_avx2(rom, x) {
            for l in 0..8 {
                assert_eq!(fog[l].to_bits(), rom.fog(x[l]).to_bits(), "AVX2 fog of {}", x[l]);
                assert_eq!(log2[l].to_bits(), rom.log2(x[l]).to_bits(), "AVX2 log2 of {}", x[l]);
            }
        }
        #[cfg(target_arch = "x86_64")]
        if let Some((fog, log2)) = roms_avx512(rom, &std::array::from_fn(|l| x[if l < 8 { l } else { 15 - l }])) {
            for l in 0..16 {
                let x = x[if l < 8 { l } else { 15 - l }];
                assert_eq!(fog[l].to_bits(), rom.fog(x).to_bits(), "AVX-512 fog of {x}");
                assert_eq!(log2[l].to_bits(), rom.log2(x).to_bits(), "AVX-512 log2 of {x}");
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (rom, x);
    }

    #[test]
    fn rom_lanes_are_the_roms_bit_for_bit() {
        let rom = TacRom::get();
        let mut h = 0x2545_F491u32;
        let mut next = || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            h
        };
        for round in 0..200_000 {
            // Fog arguments over the ROM's range and past it; log2 arguments over
            // every bit pattern.
            let x: [f32; 4] = std::array::from_fn(|l| match (round + l) % 7 {
                0 => ODD[(round / 7 + l) % ODD.len()],
                _ => (next() >> 8) as f32 / (1u32 << 24) as f32 * 20.0 - 2.0,
            });
            let fog = rom.fog_lanes(&x);
            let bits: [f32; 4] = std::array::from_fn(|_| f32::from_bits(next()));
            let log2 = rom.log2_lanes(&bits);
            for l in 0..4 {
                assert_eq!(fog[l].to_bits(), rom.fog(x[l]).to_bits(), "fog of {}", x[l]);
                assert_eq!(log2[l].to_bits(), rom.log2(bits[l]).to_bits(), "log2 of {}", bits[l]);
            }
            check_simd(rom, &std::array::from_fn(|l| if l < 4 { x[l] } else { bits[l - 4] }));
        }
        // Every fog entry and the points between.
        for k in 0..=(FOG_RANGE * FOG_STEPS_PER_UNIT * 4 + 8) {
            let x = [k as f32 / 1024.0, (k as f32 + 0.5) / 1024.0];
            let fog = rom.fog_lanes(&x);
            for l in 0..2 {
                assert_eq!(fog[l].to_bits(), rom.fog(x[l]).to_bits(), "fog of {}", x[l]);
            }
        }
        for k in (0..=(FOG_RANGE * FOG_STEPS_PER_UNIT * 4 + 8)).step_by(4) {
            check_simd(rom, &std::array::from_fn(|l| (k as f32 + l as f32 * 0.5) / 1024.0));
        }
        for odd in ODD.chunks(8) {
            check_simd(rom, &std::array::from_fn(|l| odd[l % odd.len()]));
        }
        // Lanes near lane 0's entry (the AVX2 copies' window), at its edges and
        // just past them, over both ROMs and at their ends.
        let spreads = [-5i32, -4, -3, -1, 0, 1, 4, 5, 6];
        for k in (0..=FOG_RANGE * FOG_STEPS_PER_UNIT + 4).step_by(3) {
            for spread in spreads {
                check_simd(
                    rom,
                    &std::array::from_fn(|l| {
                        let entry = k as i32 + [0, spread, l as i32 % 3, -(l as i32 % 4)][l % 4];
                        (entry as f32 + 0.25) / FOG_STEPS_PER_UNIT as f32
                    }),
                );
            }
        }
        let low_bits = MANTISSA_BITS - LOG2_ADDRESS_BITS;
        for k in 0..1u32 << LOG2_ADDRESS_BITS {
            for spread in spreads {
                check_simd(
                    rom,
                    &std::array::from_fn(|l| {
                        let entry = k as i32 + [0, spread, l as i32 % 3, -(l as i32 % 4)][l % 4];
                        // Mantissa address `entry` (wrapped to 8 bits), a
                        // quarter of the way on.
                        let address = (entry as u32) & ((1 << LOG2_ADDRESS_BITS) - 1);
                        f32::from_bits((127 << MANTISSA_BITS) + (address << low_bits) + (1 << (low_bits - 2)))
                    }),
                );
            }
        }
        let log2 = rom.log2_lanes(&ODD);
        for (l, x) in ODD.iter().enumerate() {
            assert_eq!(log2[l].to_bits(), rom.log2(*x).to_bits(), "log2 of {x}");
            assert!(log2[l].is_finite(), "log2 of {x}");
        }
    }

    #[test]
    fn small_int_is_the_cast_for_integers() {
        for x in (-(1i32 << 22)..=(1 << 22)).step_by(997).chain([-1, 0, 1, 4096, 1 << 22, -(1 << 22)]) {
            assert_eq!(small_int(x as f32), x);
        }
        assert_eq!(small_int(-0.0), 0);
    }

    #[test]
    fn log2_rom_follows_log2_and_is_exact_at_powers_of_two() {
        let rom = TacRom::get();
        for e in -10..40 {
            assert_eq!(rom.log2((e as f32).exp2()), e as f32);
        }
        let mut worst = 0.0f64;
        let mut x = 1.0f32;
        while x < 8192.0 {
            worst = worst.max((f64::from(rom.log2(x)) - f64::from(x).log2()).abs());
            x *= 1.000_37;
        }
        assert!(worst < 4e-6, "log2 ROM error {worst}");
    }
}
