//! Colour computers (CC, P2 fig. 1-2): the colour of every visible pixel.
//!
//! The fractional-linear functions of a polygon (`1/Z`, intensity, texture `u`, `v`)
//! are evaluated once per 4 x 4 cell at the point Q, the centre of the cell's pixel
//! (1, 1), and stepped to the 16 pixels by `A dx + B dy`, `dx, dy` in
//! `{-1, 0, 1, 2}` (P2 fig. 2). `Z` comes from a reciprocal of `1/Z`; intensity and
//! `u`, `v` are their numerators times `Z`: perspective correct.
//!
//! Texture (P2): the texture unit ([`super::texture`]) filters the face's map
//! trilinearly at `(u, v)` with the footprint `S/L = 2 delta Z^2 PAR`; its value `T`
//! blends the face's two colours, `C0 = C1 T + C2 (1 - T)` (an untextured face, or
//! one whose map is missing, has its flat colour). Then brightness: `C0 I`.
//!
//! Fog (P2): `C = C0 f + C_fog (1 - f)`, `f = exp(-Z / Z0)` from the TAC's ROM
//! ([`super::tac`]).
//!
//! The visible pixels of a cell are dealt to four channels by their position in each
//! 2 x 2 quad (channel `(x & 1) + 2 (y & 1)`), so that an edge's pixels spread evenly.
//!
//! Three copies of the same arithmetic, chosen at run time (the build itself targets
//! x86-64-v2): the portable one, arrays of 4 lanes that the compiler vectorises; with
//! AVX2, explicit 256-bit code, 8 pixels (half a cell) per register, a cell with
//! visible pixels in both halves done as the two halves side by side, step by step
//! (two chains of dependent steps that overlap: on Zen 3 the colour computers 20 %
//! faster on default than one half after the other); with AVX-512F, 512-bit code,
//! the whole cell as one group of 16 (on Zen 4 the cell's operations are one chain
//! of dependent steps rather than two: shade's share of a default frame's time 14 %
//! lower than AVX2's one half after the other). The map's four texels of a bilinear
//! look-up are one 4-byte read ([`super::texture`]'s pair layout), a gather, which
//! the AVX2 copy starts at the level the footprint's exponent gives and checks
//! against the ROM's level after (the look-up's chain, the cell's longest, no
//! longer waits for the `log2` ROM, which is not read at all where every lane's
//! level is settled by the clamps: a magnified map; where every lane's footprint
//! is past the pyramid, the last level's one texel is known, with no look-up);
//! the AVX2 copy's function is compiled twice, for polygons with a texture drawn
//! and without (each copy its own registers); the TAC's ROM entries `k`
//! and `k + 1` one 8-byte read, by gathers in the AVX-512 copy and by scalar
//! loads in the AVX2 copy (Zen 3's gathers cost more), the fog ROM's from a
//! window of eight entries around lane 0's when every lane's lie in it
//! ([`super::tac`]). Rust neither
//! fuses nor reorders float operations, and each copy does the same operations in
//! the same order, so the bits are the same; the tests compare every copy the
//! processor can run with the plain per-pixel definition.
//!
//! A cell's colours go to the VB as [`CellColors`], an array per component, which
//! the explicit copies here and the VB's F1 store and load as whole registers. With
//! AVX2 (and not AVX-512) and the VB's 8-bit code, the VB's F1 of the cell runs at
//! the end of the AVX2 copy's own function ([`ColorComputers::shade_accumulate`]):
//! no call, dispatch or set-up of F1 per cell.
//!
//! The AVX2 copy sets a polygon up once ([`PolyAvx2`], kept in `ColorComputers`
//! until a cell of another polygon comes: the VP colours a polygon's cells one
//! after another): its texture and map, the functions' coefficients side by side
//! (the four at Q in one evaluation), the stepping's products `A dx`, `B dy` of
//! each half-cell, the colours and the map's constants in registers' lanes. A cell
//! then starts from Q (default: ~1000 instructions a shaded cell before, colour +
//! VB 143.3 → 127.5 M).

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

use glam::Vec3;

use super::spp::Visible;
use super::tac::TacRom;
#[cfg(target_arch = "x86_64")]
use super::texture::MapAvx2;
use super::texture::{TextureMap, TextureMaps, LANES};
#[cfg(target_arch = "x86_64")]
use super::vb::F1Avx2;
use super::vb::{FusedF1, VideoBuffer};
use crate::frame::{FracLin, FrameList, FramePolygon, PolyTexture};
use crate::model::stats::Counters;

/// Number of colour channels (P1: four).
pub const CHANNELS: usize = 4;

/// The factor 2 of P2's footprint `S = 2 delta Z^2 / |Dn|`: the footprint is taken as
/// twice the pixel's stretch along the face's slope, a square that holds the
/// projected pixel, so that the far field blurs rather than shimmers.
pub const FOOTPRINT_FACTOR: f32 = 2.0;

/// The colours of a cell's 16 pixels as the colour computers hand them to the VB
/// (one cell of one polygon): structure of arrays, component `c` (R, G, B) of pixel
/// `i` (`4 y + x`) at `rgb[c][i]`, so that the SIMD copies of the CC and of the VB's
/// F1 store and load a component's lanes whole, with no transposes (AoS `[Vec3;
/// 16]` took 6 two-source permutes per cell in the CC's AVX-512 copy and 12
/// shuffles per half cell in the VB's AVX2 copy). 64-byte aligned: a component is
/// one AVX-512 register.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct CellColors {
    /// `rgb[c][i]`: component `c` of pixel `i`.
    pub rgb: [[f32; 16]; 3],
}

impl CellColors {
    /// Every pixel `color`.
    pub fn splat(color: Vec3) -> Self {
        Self { rgb: color.to_array().map(|c| [c; 16]) }
    }

    /// The colour of pixel `i` (`4 y + x`).
    #[inline]
    pub fn pixel(&self, i: usize) -> Vec3 {
        Vec3::new(self.rgb[0][i], self.rgb[1][i], self.rgb[2][i])
    }

    /// Sets the colour of pixel `i`.
    #[inline]
    pub fn set(&mut self, i: usize, color: Vec3) {
        for (c, v) in self.rgb.iter_mut().zip(color.to_array()) {
            c[i] = v;
        }
    }
}

impl Default for CellColors {
    /// Black.
    fn default() -> Self {
        Self::splat(Vec3::ZERO)
    }
}

impl From<[Vec3; 16]> for CellColors {
    fn from(pixels: [Vec3; 16]) -> Self {
        Self { rgb: std::array::from_fn(|c| std::array::from_fn(|i| pixels[i][c])) }
    }
}

/// The channel that colours pixel `i` (`4 y + x`) of a cell.
#[inline]
pub fn channel(i: usize) -> usize {
    (i & 1) | ((i >> 2) & 1) << 1
}

/// The colour computers' per-frame registers (P2: loaded from the host) and the
/// texture map memory.
#[derive(Clone, Copy, Debug)]
pub struct ColorComputers<'a> {
    /// Fog colour `C_fog`.
    pub fog_color: Vec3,
    /// `1 / Z0`, zero for no fog.
    pub inv_visibility: f32,
    /// `2 delta`: the footprint factor times the pixel size at unit depth.
    pub footprint_scale: f32,
    /// The texture maps.
    pub textures: &'a TextureMaps,
    /// The frame's texture set-ups ([`FrameList::textures`]).
    pub set_ups: &'a [PolyTexture],
    /// The TAC's ROMs, found once for the frame ([`TacRom::get`], a lock's test
    /// per call: ~11 instructions of a one-colour polygon's ~92).
    rom: &'static TacRom,
    /// The AVX2 copy's set-up of the last polygon it coloured ([`PolyAvx2`]), made
    /// again when a cell of another polygon comes.
    #[cfg(target_arch = "x86_64")]
    prepared: Option<PolyAvx2<'a>>,
}

impl<'a> ColorComputers<'a> {
    /// The registers for a frame, with the scene's texture maps.
    pub fn new(frame: &'a FrameList, textures: &'a TextureMaps) -> Self {
        let inv_visibility = if frame.visibility.is_finite() { 1.0 / frame.visibility } else { 0.0 };
        Self {
            fog_color: frame.fog_color,
            inv_visibility,
            footprint_scale: FOOTPRINT_FACTOR * frame.pixel_angle,
            textures,
            set_ups: &frame.textures,
            rom: TacRom::get(),
            #[cfg(target_arch = "x86_64")]
            prepared: None,
        }
    }

    /// The registers with the given values (and no polygon set up).
    #[cfg(test)]
    fn with(
        fog_color: Vec3,
        inv_visibility: f32,
        footprint_scale: f32,
        textures: &'a TextureMaps,
        set_ups: &'a [PolyTexture],
    ) -> Self {
        Self {
            fog_color,
            inv_visibility,
            footprint_scale,
            textures,
            set_ups,
            rom: TacRom::get(),
            #[cfg(target_arch = "x86_64")]
            prepared: None,
        }
    }

    /// The AVX2 copy's set-up of `poly` ([`PolyAvx2`]): the one kept if it is of
    /// `poly` (known by its address: the frame list is borrowed for `'a`, so a
    /// polygon at the same address is the same polygon), else made now. The VP
    /// colours the cells of a polygon one after another, so it is made about once a
    /// polygon. Inlined into the caller's loop (the test needs no AVX2; as a
    /// function of the AVX2 copy it stayed a call per cell, ~10 instructions).
    ///
    /// # Safety
    ///
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(unsafe_code, reason = "a call of a function compiled for AVX2, whose condition the caller keeps")]
    unsafe fn prepared_avx2(&mut self, poly: &'a FramePolygon) -> &PolyAvx2<'a> {
        if !self.prepared.as_ref().is_some_and(|p| std::ptr::eq(p.poly, poly)) {
            // SAFETY: the processor has AVX2 (this function's condition).
            unsafe { self.prepare_avx2(poly) };
        }
        match &self.prepared {
            Some(p) => p,
            None => unreachable!("set up just above"),
        }
    }

    /// [`Self::prepared_avx2`]'s set-up, out of line (once a polygon).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    fn prepare_avx2(&mut self, poly: &'a FramePolygon) {
        // (A match, not `and_then` with a closure: that stayed a call.)
        let drawn = match self.set_up(poly) {
            Some(t) => self.textures.get(t.map).map(|map| (t, map)),
            None => None,
        };
        let footprint_scale = self.footprint_scale;
        let prepared = self.prepared.insert(PolyAvx2::new(self, poly, drawn.map(|(t, _)| t)));
        // The texture set apart, in place and only with a texture drawn: made
        // with the rest as one `Option` (a `map`), its ~400 bytes were copied for
        // every polygon, with a texture or not (terrain, nearly all untextured:
        // ~60 instructions a polygon).
        if let Some((t, map)) = drawn {
            prepared.texture = Some(TextureAvx2::new(footprint_scale, t, map));
        }
    }

    /// The texture set-up of `poly` ([`FrameList::texture_of`]).
    #[inline(always)]
    fn set_up(&self, poly: &FramePolygon) -> Option<&'a PolyTexture> {
        self.set_ups.get(poly.texture as usize)
    }

    /// Colours the visible pixels of one cell of polygon `poly` into `out` (what it
    /// writes for pixels with no visible subpixel is unspecified).
    ///
    /// The cell's pixels are computed in groups side by side, as arrays that
    /// vectorise (the copies below), so that a cell's hidden pixels cost little
    /// (a cell of an edge or of a small polygon has few visible pixels: about 5 of 16
    /// on the default scene). Every pixel gets the same operations in the same order
    /// as one computed alone would (the stepping `Q + A dx + B dy`, the reciprocal,
    /// the products), so the colours are bit for bit those of a pixel-by-pixel loop.
    pub fn shade<const STATS: bool>(
        &mut self,
        poly: &'a FramePolygon,
        vis: &Visible,
        out: &mut CellColors,
        counters: &mut Counters,
    ) {
        self.shade_cell(poly, vis, out);
        if STATS {
            let visible = crate::model::stats::visible_pixels(&vis.sets);
            counters.count_cc_cell(visible, self.drawn_texture(poly));
        }
    }

    /// [`Self::shade`], then the VB's F1 of the cell's colours
    /// ([`VideoBuffer::accumulate`]), for each of `cells` (of `poly`) in order.
    /// With AVX2 (not AVX-512) and the VB's 8-bit code, both in one function
    /// ([`PolyAvx2::shade_avx2`] with its `f1`): no call, dispatch or set-up of
    /// F1 per cell: `fused` is [`VideoBuffer::fused_f1`], found once a frame (per
    /// cell, the features and F1's registers looked up again had cost ~20
    /// instructions a cell). The same colours and words. Inlined into its caller,
    /// the VP's loop over cells: its own call had cost ~46 instructions a cell (saved
    /// registers, the features found again; default colour + VB 148.3 → 145.1 M,
    /// terrain 226.5 → 220.4 M).
    #[inline(always)]
    pub fn shade_accumulate<const STATS: bool>(
        &mut self,
        poly: &'a FramePolygon,
        cells: &[Visible],
        out: &mut CellColors,
        counters: &mut Counters,
        vb: &mut VideoBuffer,
        fused: Option<FusedF1>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if let Some(mut f1) = fused.and_then(|fused| vb.f1_avx2(fused)) {
            // SAFETY: `prepared_avx2` and `shade_textured_avx2` only need AVX2,
            // which the processor has (a `FusedF1` is made only then).
            #[allow(unsafe_code, reason = "calls of functions compiled for AVX2, after detection")]
            unsafe {
                // [`PolyAvx2::shade_avx2`]'s choice of copy, here (a function for
                // AVX2 is not inlined into this one, so there it was a call and a
                // jump a cell: terrain ~3 instructions a cell), and with the set-up
                // and F1's registers once for the polygon's cells (per cell: terrain
                // ~18 instructions a cell, 5.5 M; session 20); the run's cells in
                // one call (session 21).
                let prepared = self.prepared_avx2(poly);
                if prepared.texture.is_some() {
                    prepared.shade_textured_avx2::<true>(cells, out, Some(&mut f1));
                } else {
                    prepared.shade_textured_avx2::<false>(cells, out, Some(&mut f1));
                }
            };
            if STATS {
                let drawn = self.drawn_texture(poly);
                for vis in cells {
                    counters.count_cc_cell(crate::model::stats::visible_pixels(&vis.sets), drawn);
                }
            }
            return;
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = fused;
        for vis in cells {
            self.shade::<STATS>(poly, vis, out, counters);
            vb.accumulate(vis, out);
        }
    }

    /// Whether `poly` has a texture whose map exists (a texture whose map is
    /// missing is not drawn: the face keeps its colour).
    fn drawn_texture(&self, poly: &FramePolygon) -> bool {
        self.set_up(poly).is_some_and(|t| self.textures.get(t.map).is_some())
    }

    /// [`Self::shade`]'s colours by the best copy the processor runs. (Not generic
    /// over the counting: one copy of each, the groups inlined into it.)
    fn shade_cell(&mut self, poly: &'a FramePolygon, vis: &Visible, out: &mut CellColors) {
        #[cfg(target_arch = "x86_64")]
        if crate::isa::avx512_copies() {
            // SAFETY: `shade_avx512` only needs AVX-512F, which `avx512_copies`
            // found the processor to have. (Asked for only: the AVX2 copy below is
            // the faster, [`crate::isa`].)
            #[allow(unsafe_code, reason = "the one call of a function compiled for AVX-512, after detection")]
            unsafe {
                return self.shade_avx512(poly, vis, out);
            }
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: `prepared_avx2` and `shade_avx2` only need AVX2, which the
            // processor was just found to have.
            #[allow(unsafe_code, reason = "calls of functions compiled for AVX2, after detection")]
            unsafe {
                return self.prepared_avx2(poly).shade_avx2(vis, out, None);
            }
        }
        self.shade_scalar(poly, vis, out)
    }

    /// [`Self::shade`] in explicit AVX-512: the whole cell as one group of 16
    /// lanes, lane `i` its pixel `i` (`4 y + x`), with no packing (a hidden
    /// pixel's lane is computed and its colour unspecified). One chain of
    /// dependent operations per cell where AVX2 has one per half.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn shade_avx512(&self, poly: &FramePolygon, vis: &Visible, out: &mut CellColors) {
        let cell = CellShader::new(self, poly, vis);
        for (out, c) in out.rgb.iter_mut().zip(cell.group_avx512()) {
            // SAFETY: `out` is 16 `f32`, the 64 bytes the store writes.
            #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
            unsafe {
                _mm512_storeu_ps(out.as_mut_ptr(), c)
            };
        }
    }

    /// [`Self::shade_lanes`] compiled for AVX2, in groups of [`AVX2_LANES`]: the
    /// compiler's vectorisation of the portable code, kept to test that it gives
    /// the same bits as the explicit copy on any processor with AVX2.
    #[cfg(all(test, target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn shade_lanes_avx2(&self, poly: &FramePolygon, vis: &Visible, out: &mut CellColors) {
        self.shade_lanes::<AVX2_LANES>(poly, vis, out)
    }

    /// [`Self::shade`] for the build's target (x86-64-v2: SSE4.2) whatever the
    /// processor, in groups of [`LANES`] pixels (one 128-bit register).
    pub fn shade_scalar(&self, poly: &FramePolygon, vis: &Visible, out: &mut CellColors) {
        self.shade_lanes::<LANES>(poly, vis, out)
    }

    /// [`Self::shade`] in groups of `N` pixels (4, 8 or 16: one, two or four rows
    /// of the cell), inlined into each target's copy.
    ///
    /// A cell is coloured by its blocks of `N / 4` whole rows (the blocks with no
    /// visible pixel skipped) when they are no more groups than its visible pixels
    /// packed `N` to a group; else by the packed pixels, a last group's spare lanes
    /// repeating its last pixel. A hidden pixel's lane is computed like the others
    /// and left unused: no branch per lane.
    #[inline(always)]
    fn shade_lanes<const N: usize>(&self, poly: &FramePolygon, vis: &Visible, out: &mut CellColors) {
        const { assert!(N == 4 || N == 8 || N == 16) };
        let visible = crate::model::stats::visible_pixels(&vis.sets);
        let cell = CellShader::new(self, poly, vis);
        let count = visible.count_ones() as usize;
        let blocks = 16 / N;
        let block_mask = (1u32 << N) - 1;
        let live_blocks = (0..blocks).filter(|b| u32::from(visible) >> (N * b) & block_mask != 0).count();
        if live_blocks <= count.div_ceil(N) {
            for b in 0..blocks {
                if u32::from(visible) >> (N * b) & block_mask == 0 {
                    continue;
                }
                let dx: &[f32; N] = STEP_X[N * b..N * (b + 1)].try_into().expect("N lanes");
                let dy: &[f32; N] = STEP_Y[N * b..N * (b + 1)].try_into().expect("N lanes");
                let c = cell.group(dx, dy);
                for (out, c) in out.rgb.iter_mut().zip(&c) {
                    out[N * b..N * (b + 1)].copy_from_slice(c);
                }
            }
        } else {
            // The visible pixels (`4 y + x`), packed.
            let mut pixels = [0usize; 16];
            let mut rest = visible;
            for p in &mut pixels[..count] {
                *p = rest.trailing_zeros() as usize;
                rest &= rest - 1;
            }
            for chunk in pixels[..count].chunks(N) {
                let live = chunk.len();
                let lane: [usize; N] = std::array::from_fn(|l| chunk[l.min(live - 1)]);
                let c = cell.group(&lane.map(|i| STEP_X[i]), &lane.map(|i| STEP_Y[i]));
                for (l, &i) in chunk.iter().enumerate() {
                    for (out, c) in out.rgb.iter_mut().zip(&c) {
                        out[i] = c[l];
                    }
                }
            }
        }
    }
}

/// Pixels side by side in the AVX2 copy of the colour computers: two rows of a
/// cell, eight `f32` in one 256-bit register.
#[cfg(target_arch = "x86_64")]
const AVX2_LANES: usize = 8;

/// The AVX2 colour computers' set-up of one polygon: what every cell of it shares,
/// in registers' lanes, so that a cell takes it from memory as operands
/// ([`ColorComputers::prepared_avx2`] makes it once per polygon). A cell had
/// found all this again (~140 instructions a cell on default: the texture's set-up
/// and map, the functions' coefficients broadcast and shuffled, the stepping's
/// products `A dx`, `B dy` of each half, the colours broadcast, the map's side and
/// clamps).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
struct PolyAvx2<'a> {
    /// The polygon.
    poly: &'a FramePolygon,
    /// `a`, `b`, `c` of `1/Z`, intensity, `u` and `v`, in lanes 0 to 3 (`u`, `v`
    /// zero with no texture drawn): the four at Q in one evaluation.
    a: __m128,
    b: __m128,
    c: __m128,
    /// `a dx` and `b dy` of the four functions (in that order) in the lanes of each
    /// half of the cell (pixels `0..8`, `8..16`): P2 fig. 2's products, the same
    /// in every cell (zeros for `u`, `v` with no texture drawn).
    a_dx: [[__m256; 4]; 2],
    b_dy: [[__m256; 4]; 2],
    /// With a texture whose map exists, its set-up ([`TextureAvx2`]).
    texture: Option<TextureAvx2<'a>>,
    /// The flat colour (with no texture drawn).
    color: [__m256; 3],
    /// `C_fog`.
    fog: [__m256; 3],
    /// `1 / Z0`, and whether it is not zero (fog).
    inv_visibility: __m256,
    fogged: bool,
    /// The TAC's ROMs.
    rom: &'static TacRom,
}

/// [`PolyAvx2`]'s texture: the map's constants and the face's.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
struct TextureAvx2<'a> {
    /// The map ([`MapAvx2`]).
    map: MapAvx2<'a>,
    /// `2 delta` and `PAR`: the footprint's factors.
    footprint_scale: __m256,
    par: __m256,
    /// `C1`, `C2`.
    color1: [__m256; 3],
    color2: [__m256; 3],
}

#[cfg(target_arch = "x86_64")]
impl<'a> TextureAvx2<'a> {
    /// The set-up of the texture `t` whose map is `map`, `footprint_scale` the
    /// colour computers' `2 delta`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn new(footprint_scale: f32, t: &PolyTexture, map: &'a TextureMap) -> Self {
        Self {
            map: map.avx2(),
            footprint_scale: _mm256_set1_ps(footprint_scale),
            par: _mm256_set1_ps(t.par),
            color1: splat3(t.color1),
            color2: splat3(t.color2),
        }
    }
}

/// A colour's components, each in every lane of a register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn splat3(c: Vec3) -> [__m256; 3] {
    let [r, g, b] = c.to_array();
    [_mm256_set1_ps(r), _mm256_set1_ps(g), _mm256_set1_ps(b)]
}

/// [`PolyAvx2::front`]'s values of eight pixels.
#[cfg(target_arch = "x86_64")]
struct Front {
    /// `Z`.
    z: __m256,
    /// Intensity.
    intensity: __m256,
    /// With a texture: `u`, `v`, the footprint.
    texture: Option<(__m256, __m256, __m256)>,
}

#[cfg(target_arch = "x86_64")]
impl<'a> PolyAvx2<'a> {
    /// The set-up of `poly` under `cc`'s registers, with the texture set-up `drawn`
    /// when its map exists, but no texture ([`TextureAvx2::new`], which the
    /// caller adds).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn new(cc: &ColorComputers<'a>, poly: &'a FramePolygon, drawn: Option<&PolyTexture>) -> Self {
        let none = FracLin::default();
        let (u, v) = match drawn {
            Some(t) => (t.u, t.v),
            None => (none, none),
        };
        let f = [poly.inv_z, poly.intensity, u, v];
        // The functions stepped: `u`, `v` only with a texture drawn.
        let stepped = if drawn.is_some() { 4 } else { 2 };
        let (mut a_dx, mut b_dy) = ([[_mm256_setzero_ps(); 4]; 2], [[_mm256_setzero_ps(); 4]; 2]);
        for half in 0..2 {
            let lanes = AVX2_LANES * half..AVX2_LANES * (half + 1);
            let (dx, dy): (&[f32; AVX2_LANES], &[f32; AVX2_LANES]) =
                (STEP_X[lanes.clone()].try_into().expect("8 lanes"), STEP_Y[lanes].try_into().expect("8 lanes"));
            // SAFETY: `dx` and `dy` are 8 `f32`, the 32 bytes each load reads.
            #[allow(unsafe_code, reason = "unaligned loads of arrays of a register's size")]
            let (dx, dy) = unsafe { (_mm256_loadu_ps(dx.as_ptr()), _mm256_loadu_ps(dy.as_ptr())) };
            for i in 0..stepped {
                a_dx[half][i] = _mm256_mul_ps(_mm256_set1_ps(f[i].a), dx);
                b_dy[half][i] = _mm256_mul_ps(_mm256_set1_ps(f[i].b), dy);
            }
        }
        Self {
            poly,
            a: _mm_setr_ps(f[0].a, f[1].a, f[2].a, f[3].a),
            b: _mm_setr_ps(f[0].b, f[1].b, f[2].b, f[3].b),
            c: _mm_setr_ps(f[0].c, f[1].c, f[2].c, f[3].c),
            a_dx,
            b_dy,
            texture: None,
            color: splat3(poly.color),
            fog: splat3(cc.fog_color),
            inv_visibility: _mm256_set1_ps(cc.inv_visibility),
            fogged: cc.inv_visibility != 0.0,
            rom: cc.rom,
        }
    }

    /// [`ColorComputers::shade`] in explicit AVX2: the cell's halves (two rows,
    /// [`AVX2_LANES`] pixels, one 256-bit register) with a visible pixel; when
    /// both have one, the two side by side ([`Self::cell`]), else the one alone
    /// ([`Self::group`]). The same operations on the same values as
    /// [`ColorComputers::shade_lanes`] (Rust neither fuses nor reorders float
    /// operations), so the same bits.
    ///
    /// No packing of a cell's visible pixels into fewer groups (as the portable
    /// copy does): on Zen 3 the two halves side by side cost hardly more than one
    /// (their chains of dependent steps overlap), and a packed group costs its
    /// lanes' scattered stores: terrain's colour computers 3 % faster without it,
    /// default's the same.
    ///
    /// With `f1`, the VB's F1 of the cell follows in the same function
    /// ([`ColorComputers::shade_accumulate`]).
    ///
    /// Two copies, with and without a texture drawn ([`Self::shade_textured_avx2`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn shade_avx2(&self, vis: &Visible, out: &mut CellColors, f1: Option<&mut F1Avx2>) {
        if self.texture.is_some() {
            self.shade_textured_avx2::<true>(std::slice::from_ref(vis), out, f1);
        } else {
            self.shade_textured_avx2::<false>(std::slice::from_ref(vis), out, f1);
        }
    }

    /// [`Self::shade_avx2`] of a polygon with a texture drawn (`TEXTURED`, the
    /// set-up's `texture`) or without: a copy of the function for each, so that
    /// the texture's code and registers are not in the copy of the polygons with
    /// none (terrain's, city's nearly all), and a change to one copy does not move
    /// the other's register allocation. (In one function, the texture unit's
    /// shortcut for the last level, [`MapAvx2::top_avx2`], had cost terrain's
    /// untextured cells ~2 instructions a cell of spills.)
    ///
    /// It takes a run of cells (`cells`, of this polygon, coloured and handed to
    /// `f1` in order; [`Self::shade_avx2`] one): the loop over them is inside the
    /// function, so a cell costs no call (six saved registers, a frame, the F1
    /// registers' pointers read again; colour + VB terrain 151.0 → 147.0 M,
    /// default 99.1 → 98.0 M, city 64.6 → 60.9 M, session 21). `many`'s runs are
    /// mostly one cell, and a run now pays the polygon's registers hoisted out of
    /// the loop and spilled (~60 instructions): its colour + VB 358.0 → 369.3 M at
    /// 960 x 540 (raster −4.0 M by the layout). A copy for one-cell runs (a second
    /// const parameter) made F1's copies calls again: terrain 156.6 M, dropped.
    #[target_feature(enable = "avx2")]
    fn shade_textured_avx2<const TEXTURED: bool>(
        &self,
        cells: &[Visible],
        out: &mut CellColors,
        f1: Option<&mut F1Avx2>,
    ) {
        const N: usize = AVX2_LANES;
        let mut f1 = f1.map(|f1| f1.registers());
        for vis in cells {
            let visible = visible_avx2(&vis.sets);
            if visible == 0 {
                continue;
            }
            let q = self.at_q(vis);
            if visible & 0xFF != 0 && visible >> N != 0 {
                for (half, c) in self.cell::<TEXTURED>(&q).iter().enumerate() {
                    for (out, c) in out.rgb.iter_mut().zip(c) {
                        store_lanes(*c, (&mut out[N * half..N * (half + 1)]).try_into().expect("8 lanes"));
                    }
                }
            } else {
                let half = usize::from(visible & 0xFF == 0);
                for (out, c) in out.rgb.iter_mut().zip(self.group::<TEXTURED>(&q, half)) {
                    store_lanes(c, (&mut out[N * half..N * (half + 1)]).try_into().expect("8 lanes"));
                }
            }
            if let Some(f1) = f1.as_mut() {
                f1.accumulate::<TEXTURED>(vis, out);
            }
        }
    }

    /// `1/Z`, intensity, `u` and `v` (times `1/Z`) at the cell's Q, the centre of
    /// its pixel (1, 1), each in every lane: [`FracLin::eval`]'s `a x + b y + c`
    /// of the four in one register.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn at_q(&self, vis: &Visible) -> [__m256; 4] {
        // The cell's corner as `f32` (the screen's coordinates are far below
        // 2^31, so through `i32` they convert as from `u32`), plus 1.5.
        // (`px` and `py` as one 64-bit integer: one load where the two fields are
        // side by side, and one move to the register.)
        let corner = _mm_cvtepi32_ps(_mm_cvtsi64_si128((u64::from(vis.px) | u64::from(vis.py) << 32) as i64));
        let q = _mm_add_ps(corner, _mm_set1_ps(1.5));
        let (qx, qy) = (_mm_permute_ps::<0b00_00_00_00>(q), _mm_permute_ps::<0b01_01_01_01>(q));
        let at = _mm_add_ps(_mm_add_ps(_mm_mul_ps(self.a, qx), _mm_mul_ps(self.b, qy)), self.c);
        [
            _mm256_broadcastss_ps(at),
            _mm256_broadcastss_ps(_mm_permute_ps::<0b01_01_01_01>(at)),
            _mm256_broadcastss_ps(_mm_permute_ps::<0b10_10_10_10>(at)),
            _mm256_broadcastss_ps(_mm_permute_ps::<0b11_11_11_11>(at)),
        ]
    }

    /// The colours of half `half` of the cell (pixels `8 half .. 8 half + 8`), `q`
    /// the functions at Q ([`Self::at_q`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn group<const TEXTURED: bool>(&self, q: &[__m256; 4], half: usize) -> [__m256; 3] {
        let front = self.front::<TEXTURED>(q, half);
        let m = match (&self.texture, front.texture) {
            (Some(t), Some((u, v, footprint))) => Some(t.map.sample_avx2(u, v, footprint)),
            _ => None,
        };
        self.back(&front, m)
    }

    /// [`Self::group`] of the cell's two halves, each step done for both before
    /// the next ([`MapAvx2::sample2_avx2`]): two chains of dependent operations
    /// side by side.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn cell<const TEXTURED: bool>(&self, q: &[__m256; 4]) -> [[__m256; 3]; 2] {
        let front = [self.front::<TEXTURED>(q, 0), self.front::<TEXTURED>(q, 1)];
        let m = match (&self.texture, front[0].texture, front[1].texture) {
            (Some(t), Some((u0, v0, f0)), Some((u1, v1, f1))) => {
                let m = t.map.sample2_avx2([u0, u1], [v0, v1], [f0, f1]);
                [Some(m[0]), Some(m[1])]
            }
            _ => [None, None],
        };
        [self.back(&front[0], m[0]), self.back(&front[1], m[1])]
    }

    /// The first steps of [`Self::group`]: `Z`, intensity, and with a texture `u`,
    /// `v` and the footprint (`TEXTURED`: whether the set-up has a texture drawn).
    /// Each function stepped from Q as `(q + a dx) + b dy` (P2 fig. 2), the
    /// products from the set-up.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn front<const TEXTURED: bool>(&self, q: &[__m256; 4], half: usize) -> Front {
        let (a_dx, b_dy) = (&self.a_dx[half & 1], &self.b_dy[half & 1]);
        let step = |i: usize| _mm256_add_ps(_mm256_add_ps(q[i], a_dx[i]), b_dy[i]);
        let one = _mm256_set1_ps(1.0);
        // `Z` and intensity; `max` with the constant second: `maxps` gives it for
        // a NaN, as `f32::max` does.
        let z = _mm256_div_ps(one, _mm256_max_ps(step(0), _mm256_set1_ps(f32::MIN_POSITIVE)));
        let intensity = _mm256_mul_ps(step(1), z);
        let intensity = _mm256_max_ps(intensity, _mm256_setzero_ps());
        let texture = if TEXTURED { self.texture.as_ref() } else { None }.map(|t| {
            let u = _mm256_mul_ps(step(2), z);
            let v = _mm256_mul_ps(step(3), z);
            let footprint = _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(t.footprint_scale, z), z), t.par);
            (u, v, footprint)
        });
        Front { z, intensity, texture }
    }

    /// The last steps of [`Self::group`]: `C0` from the texture's value `m` (or
    /// the flat colour), brightness and fog.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn back(&self, front: &Front, m: Option<__m256>) -> [__m256; 3] {
        let one = _mm256_set1_ps(1.0);
        let mut c0 = self.color;
        if let (Some(t), Some(m)) = (&self.texture, m) {
            let not_m = _mm256_sub_ps(one, m);
            for (c, c0) in c0.iter_mut().enumerate() {
                *c0 = _mm256_add_ps(_mm256_mul_ps(t.color1[c], m), _mm256_mul_ps(t.color2[c], not_m));
            }
        }
        let f = if self.fogged { self.rom.fog_avx2(_mm256_mul_ps(front.z, self.inv_visibility)) } else { one };
        let not_f = _mm256_sub_ps(one, f);
        let intensity = front.intensity;
        let mut out = [one; 3];
        for (c, out) in out.iter_mut().enumerate() {
            *out = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(c0[c], intensity), f), _mm256_mul_ps(self.fog[c], not_f));
        }
        out
    }
}

/// The colour computers' values for one cell of one polygon: the functions at the
/// cell's point Q and what the groups of its pixels share.
struct CellShader<'a> {
    /// The polygon.
    poly: &'a FramePolygon,
    /// Its texture and map, if it has a texture whose map exists (a texture whose
    /// map is missing is not drawn: the face keeps its colour).
    texture: Option<(&'a PolyTexture, &'a TextureMap)>,
    /// `1/Z` at Q.
    z_q: f32,
    /// Intensity (times `1/Z`) at Q.
    i_q: f32,
    /// `u`, `v` (times `1/Z`) at Q; zero with no texture.
    u_q: f32,
    v_q: f32,
    /// `C_fog`.
    fog: [f32; 3],
    /// `1 / Z0`, zero for no fog.
    inv_visibility: f32,
    /// `2 delta`.
    footprint_scale: f32,
    /// The TAC's ROMs.
    rom: &'static TacRom,
}

impl<'a> CellShader<'a> {
    /// The values at Q, the centre of the cell's pixel (1, 1).
    #[inline(always)]
    fn new(cc: &ColorComputers<'a>, poly: &'a FramePolygon, vis: &Visible) -> Self {
        let (qx, qy) = (vis.px as f32 + 1.5, vis.py as f32 + 1.5);
        let texture = cc.set_up(poly).and_then(|t| Some((t, cc.textures.get(t.map)?)));
        let (u_q, v_q) = texture.map_or((0.0, 0.0), |(t, _)| (t.u.eval(qx, qy), t.v.eval(qx, qy)));
        Self {
            poly,
            texture,
            z_q: poly.inv_z.eval(qx, qy),
            i_q: poly.intensity.eval(qx, qy),
            u_q,
            v_q,
            fog: cc.fog_color.to_array(),
            inv_visibility: cc.inv_visibility,
            footprint_scale: cc.footprint_scale,
            rom: cc.rom,
        }
    }

    /// [`Self::group`] of the cell's 16 pixels (lane `i` pixel `i`) in AVX-512
    /// registers, bit for bit: [`PolyAvx2::group`] over the whole cell.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn group_avx512(&self) -> [__m512; 3] {
        let poly = self.poly;
        let dx = _mm512_setr_ps(
            STEP_X[0], STEP_X[1], STEP_X[2], STEP_X[3], STEP_X[4], STEP_X[5], STEP_X[6], STEP_X[7], STEP_X[8],
            STEP_X[9], STEP_X[10], STEP_X[11], STEP_X[12], STEP_X[13], STEP_X[14], STEP_X[15],
        );
        let dy = _mm512_setr_ps(
            STEP_Y[0], STEP_Y[1], STEP_Y[2], STEP_Y[3], STEP_Y[4], STEP_Y[5], STEP_Y[6], STEP_Y[7], STEP_Y[8],
            STEP_Y[9], STEP_Y[10], STEP_Y[11], STEP_Y[12], STEP_Y[13], STEP_Y[14], STEP_Y[15],
        );
        let one = _mm512_set1_ps(1.0);
        let inv_z = step_avx512(self.z_q, &poly.inv_z, dx, dy);
        let z = _mm512_div_ps(one, _mm512_max_ps(inv_z, _mm512_set1_ps(f32::MIN_POSITIVE)));
        let intensity = _mm512_mul_ps(step_avx512(self.i_q, &poly.intensity, dx, dy), z);
        let intensity = _mm512_max_ps(intensity, _mm512_setzero_ps());
        let c0: [__m512; 3] = match self.texture {
            Some((t, map)) => {
                let u = _mm512_mul_ps(step_avx512(self.u_q, &t.u, dx, dy), z);
                let v = _mm512_mul_ps(step_avx512(self.v_q, &t.v, dx, dy), z);
                let footprint = _mm512_mul_ps(
                    _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(self.footprint_scale), z), z),
                    _mm512_set1_ps(t.par),
                );
                let m = map.sample_avx512(u, v, footprint);
                let not_m = _mm512_sub_ps(one, m);
                let (c1, c2) = (t.color1.to_array(), t.color2.to_array());
                [0, 1, 2].map(|c| {
                    _mm512_add_ps(_mm512_mul_ps(_mm512_set1_ps(c1[c]), m), _mm512_mul_ps(_mm512_set1_ps(c2[c]), not_m))
                })
            }
            None => {
                let c = poly.color.to_array();
                [_mm512_set1_ps(c[0]), _mm512_set1_ps(c[1]), _mm512_set1_ps(c[2])]
            }
        };
        let f = if self.inv_visibility != 0.0 {
            self.rom.fog_avx512(_mm512_mul_ps(z, _mm512_set1_ps(self.inv_visibility)))
        } else {
            one
        };
        let not_f = _mm512_sub_ps(one, f);
        let fog = self.fog;
        [0, 1, 2].map(|c| {
            _mm512_add_ps(
                _mm512_mul_ps(_mm512_mul_ps(c0[c], intensity), f),
                _mm512_mul_ps(_mm512_set1_ps(fog[c]), not_f),
            )
        })
    }

    /// The colours of `N` pixels side by side, `dx`, `dy` from Q per lane, as
    /// `[r, g, b]` arrays over the lanes.
    #[inline(always)]
    fn group<const N: usize>(&self, dx: &[f32; N], dy: &[f32; N]) -> [[f32; N]; 3] {
        let poly = self.poly;
        // `Z` and intensity, stepped from Q (P2 fig. 2).
        let mut z = [0.0f32; N];
        let mut intensity = [0.0f32; N];
        for l in 0..N {
            let inv_z = self.z_q + poly.inv_z.a * dx[l] + poly.inv_z.b * dy[l];
            z[l] = 1.0 / inv_z.max(f32::MIN_POSITIVE);
            intensity[l] = ((self.i_q + poly.intensity.a * dx[l] + poly.intensity.b * dy[l]) * z[l]).max(0.0);
        }
        // C0, per component.
        let c0: [[f32; N]; 3] = match self.texture {
            Some((t, map)) => {
                let mut u = [0.0f32; N];
                let mut v = [0.0f32; N];
                let mut footprint = [0.0f32; N];
                for l in 0..N {
                    u[l] = (self.u_q + t.u.a * dx[l] + t.u.b * dy[l]) * z[l];
                    v[l] = (self.v_q + t.v.a * dx[l] + t.v.b * dy[l]) * z[l];
                    footprint[l] = self.footprint_scale * z[l] * z[l] * t.par;
                }
                let m = map.sample_lanes(&u, &v, &footprint);
                let (c1, c2) = (t.color1.to_array(), t.color2.to_array());
                std::array::from_fn(|c| std::array::from_fn(|l| c1[c] * m[l] + c2[c] * (1.0 - m[l])))
            }
            None => poly.color.to_array().map(|c| [c; N]),
        };
        // Fog, `exp(-Z / Z0)` from the TAC's ROM; none is `f = 1`.
        let f = if self.inv_visibility != 0.0 {
            self.rom.fog_lanes(&z.map(|z| z * self.inv_visibility))
        } else {
            [1.0f32; N]
        };
        let fog = self.fog;
        std::array::from_fn(|c| std::array::from_fn(|l| c0[c][l] * intensity[l] * f[l] + fog[c] * (1.0 - f[l])))
    }
}

/// [`crate::model::stats::visible_pixels`] in AVX2: a bit per pixel with a
/// visible subpixel, from one compare of the cell's 16 sets.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn visible_avx2(sets: &[u16; 16]) -> u16 {
    // SAFETY: `sets` is 16 `u16`, the 32 bytes the load reads.
    #[allow(unsafe_code, reason = "an unaligned load of an array of a register's size")]
    let sets = unsafe { _mm256_loadu_si256(sets.as_ptr().cast()) };
    let hidden = _mm256_cmpeq_epi16(sets, _mm256_setzero_si256());
    // Each pixel's 16-bit compare to one byte, in pixel order.
    let bytes = _mm_packs_epi16(_mm256_castsi256_si128(hidden), _mm256_extracti128_si256::<1>(hidden));
    !(_mm_movemask_epi8(bytes) as u16)
}

/// Lane `l` of `v` at `out[l]`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn store_lanes(v: __m256, out: &mut [f32; AVX2_LANES]) {
    // SAFETY: `out` is 8 `f32`, the 32 bytes the store writes.
    #[allow(unsafe_code, reason = "an unaligned store of a register into an array of its size")]
    unsafe {
        _mm256_storeu_ps(out.as_mut_ptr(), v)
    };
}

/// `q + a dx + b dy` of sixteen lanes, in that order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn step_avx512(q: f32, f: &FracLin, dx: __m512, dy: __m512) -> __m512 {
    _mm512_add_ps(
        _mm512_add_ps(_mm512_set1_ps(q), _mm512_mul_ps(_mm512_set1_ps(f.a), dx)),
        _mm512_mul_ps(_mm512_set1_ps(f.b), dy),
    )
}

impl ColorComputers<'_> {
    /// The one colour of a polygon whose every pixel [`Self::shade`] colours alike,
    /// or `None`: a face with no texture drawn, whose `1/Z` and intensity have
    /// `A = B = 0` (a face square to the view axis, of even brightness: `rombm`'s
    /// rhombi, `many`'s triangles). Its `Z`, intensity and fog are then the same at
    /// every pixel (`Q + 0 dx + 0 dy` is `Q`), and so is its colour; it is computed by
    /// `shade` itself, at one pixel, so it is the very value every pixel would get
    /// (zero's sign aside, which no VB mode keeps apart).
    ///
    /// Asked once a polygon (terrain: 39 387 times a frame, almost every answer
    /// `None`): the gradients are tested first, and the pixel is shaded out of line
    /// ([`Self::flat_pixel`]), so that a shaded polygon's answer costs a few
    /// compares and no saved registers (terrain: ~26 instructions a polygon before).
    #[inline]
    pub fn flat_color(&self, poly: &FramePolygon) -> Option<Vec3> {
        let still = |f: &crate::frame::FracLin| f.a == 0.0 && f.b == 0.0;
        if !still(&poly.inv_z) || !still(&poly.intensity) || self.drawn_texture(poly) {
            return None;
        }
        Some(self.flat_pixel(poly))
    }

    /// [`Self::flat_color`]'s colour of a polygon found to have one.
    #[inline(never)]
    fn flat_pixel(&self, poly: &FramePolygon) -> Vec3 {
        // Pixel (1, 1) of the first cell, alone, in a group of one lane (every
        // copy's operations are the same: the AVX2 copy's per-polygon set-up
        // would cost more than this pixel).
        const Q_PIXEL: usize = 5;
        let vis = Visible { px: 0, py: 0, sets: [0; 16], first: 0, covered: false };
        let c = CellShader::new(self, poly, &vis).group::<1>(&[STEP_X[Q_PIXEL]], &[STEP_Y[Q_PIXEL]]);
        Vec3::new(c[0][0], c[1][0], c[2][0])
    }
}

/// `dx` of pixel `i` (`4 y + x`) of a cell from Q, its pixel (1, 1).
const STEP_X: [f32; 16] = [-1.0, 0.0, 1.0, 2.0, -1.0, 0.0, 1.0, 2.0, -1.0, 0.0, 1.0, 2.0, -1.0, 0.0, 1.0, 2.0];

/// `dy` of pixel `i` (`4 y + x`) of a cell from Q.
const STEP_Y: [f32; 16] = [-1.0, -1.0, -1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{FracLin, PrimitiveKind};
    use crate::vp::texture::builtin;

    /// Numbers in `0..=1` from a xorshift generator started at `seed`.
    fn unit_floats(seed: u32) -> impl FnMut() -> f32 {
        let mut h = seed;
        move || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            h as f32 / u32::MAX as f32
        }
    }

    /// Colour computers with a fog colour from `next` and, unless `clear`, a visibility
    /// `1 / (next() scale)` (the footprint scale of a 1e-3 pixel angle).
    fn random_computers<'a>(
        next: &mut impl FnMut() -> f32,
        clear: bool,
        scale: f32,
        maps: &'a TextureMaps,
        set_ups: &'a [PolyTexture],
    ) -> ColorComputers<'a> {
        let fog = Vec3::new(next(), next(), next());
        let inv_visibility = if clear { 0.0 } else { next() * scale };
        ColorComputers::with(fog, inv_visibility, FOOTPRINT_FACTOR * 1e-3, maps, set_ups)
    }

    /// A texture set-up of map `map` with the functions `u` and `v`, its `PAR` and
    /// colours drawn from `next`.
    fn random_texture(map: u32, u: FracLin, v: FracLin, next: &mut impl FnMut() -> f32) -> PolyTexture {
        PolyTexture {
            map,
            u,
            v,
            par: next() * 4.0,
            color1: Vec3::new(next(), next(), next()),
            color2: Vec3::new(next(), next(), next()),
        }
    }

    /// A face of colour `color` with the functions `inv_z` and `intensity`, textured
    /// by the side table's entry 0 when `textured`.
    fn face_polygon(color: Vec3, inv_z: FracLin, intensity: FracLin, textured: bool) -> FramePolygon {
        FramePolygon {
            vertices: 0..0,
            kind: PrimitiveKind::Face,
            material: 0,
            source: (0, 0),
            color,
            inv_z,
            intensity,
            texture: if textured { 0 } else { FramePolygon::NO_TEXTURE },
            transparency: 0,
        }
    }

    /// The colour of pixel `(x, y)` by P2's definitions written out plainly, pixel
    /// by pixel: the reference for [`ColorComputers::shade`].
    fn plain_pixel(cc: &ColorComputers, poly: &FramePolygon, px: u32, py: u32, i: usize) -> Vec3 {
        let (qx, qy) = (px as f32 + 1.5, py as f32 + 1.5);
        let (dx, dy) = ((i & 3) as f32 - 1.0, (i >> 2) as f32 - 1.0);
        let step = |f: &FracLin| f.eval(qx, qy) + f.a * dx + f.b * dy;
        let z = 1.0 / step(&poly.inv_z).max(f32::MIN_POSITIVE);
        let intensity = (step(&poly.intensity) * z).max(0.0);
        let c0 = match cc.set_up(poly).and_then(|t| Some((t, cc.textures.get(t.map)?))) {
            Some((t, map)) => {
                let m = map.sample(step(&t.u) * z, step(&t.v) * z, cc.footprint_scale * z * z * t.par);
                t.color1 * m + t.color2 * (1.0 - m)
            }
            None => poly.color,
        };
        let f = if cc.inv_visibility != 0.0 { TacRom::get().fog(z * cc.inv_visibility) } else { 1.0 };
        let c = c0.to_array();
        let fog = cc.fog_color.to_array();
        Vec3::from_array(std::array::from_fn(|k| c[k] * intensity * f + fog[k] * (1.0 - f)))
    }

    /// A polygon with `A = B = 0` in `1/Z` and intensity and no texture drawn has
    /// one colour, which `shade` gives every pixel of every cell, fog or none; any
    /// other polygon has none.
    #[test]
    fn flat_color_is_every_pixels_colour() {
        let maps = TextureMaps::new(vec![builtin("grass").unwrap()]);
        let mut next = unit_floats(0x2545_F491);
        for round in 0..2000 {
            let zero = |k: u32| if k.is_multiple_of(2) { 0.0 } else { -0.0 };
            let still = |c: f32| FracLin { a: zero(round), b: zero(round / 2), c };
            let moving = round % 7 == 6;
            let inv_z = if moving { FracLin { a: 1e-6, b: 0.0, c: 0.05 } } else { still(next() * 0.1 + 1e-4) };
            // Brightness from none to full, zero included.
            let intensity = still(if round % 11 == 0 { 0.0 } else { next() * inv_z.c });
            // Map 1 is missing: the face keeps its colour.
            let texture = (round % 5 == 4).then(|| PolyTexture {
                map: u32::from(round % 10 == 4),
                u: still(next()),
                v: still(next()),
                par: 1.0,
                color1: Vec3::ONE,
                color2: Vec3::ZERO,
            });
            let poly = face_polygon(Vec3::new(next(), next(), next()), inv_z, intensity, texture.is_some());
            let set_ups = texture.as_slice();
            let mut cc = random_computers(&mut next, round % 3 == 0, 1e-2, &maps, set_ups);
            let flat = cc.flat_color(&poly);
            let drawn = texture.is_some_and(|t| t.map == 0);
            assert_eq!(flat.is_some(), !moving && !drawn, "round {round}");
            let Some(flat) = flat else { continue };
            for _ in 0..8 {
                let (px, py) = (4 * (next() * 480.0) as u32, 4 * (next() * 270.0) as u32);
                let vis = Visible { px, py, sets: [super::super::spp::FULL; 16], first: 0, covered: false };
                let mut out = CellColors::splat(Vec3::splat(-7.0));
                cc.shade::<false>(&poly, &vis, &mut out, &mut Counters::new(9));
                for (i, c) in (0..16).map(|i| (i, out.pixel(i))) {
                    // `==`: zero's sign may differ, and no VB mode tells them apart.
                    assert!(c.to_array() == flat.to_array(), "round {round}, cell ({px}, {py}), pixel {i}");
                }
            }
        }
    }

    /// The AVX2 copy's per-polygon set-up ([`ColorComputers::prepared_avx2`]) is made
    /// again when the polygon changes: cells of three polygons in turn, the same
    /// polygon twice running now and then, give the target's colours.
    #[test]
    fn set_up_follows_the_polygon() {
        let maps = TextureMaps::new(vec![builtin("grass").unwrap(), builtin("checker").unwrap()]);
        let lin = |a: f32, b: f32, c: f32| FracLin { a, b, c };
        let set_ups = [0, 1].map(|m| PolyTexture {
            map: m,
            u: lin(0.01, -0.003, 0.2 + m as f32),
            v: lin(-0.002, 0.008, 0.7),
            par: 1.0 + m as f32,
            color1: Vec3::new(0.9, 0.5, 0.1),
            color2: Vec3::new(0.1, 0.2, 0.3 * m as f32),
        });
        let polys = [0u32, 1, FramePolygon::NO_TEXTURE].map(|texture| FramePolygon {
            vertices: 0..0,
            kind: PrimitiveKind::Face,
            material: 0,
            source: (0, 0),
            color: Vec3::new(0.3, 0.6, 0.9),
            inv_z: lin(1e-6 * (texture % 7) as f32, -2e-6, 0.02 + 1e-3 * (texture % 5) as f32),
            intensity: lin(1e-5, 2e-5 * (texture % 3) as f32, 0.015),
            texture,
            transparency: 0,
        });
        let mut cc = ColorComputers::with(Vec3::new(0.5, 0.6, 0.7), 1e-3, FOOTPRINT_FACTOR * 1e-3, &maps, &set_ups);
        for (n, p) in [0, 0, 1, 0, 2, 2, 1, 1, 2, 0].into_iter().enumerate() {
            let vis = Visible {
                px: 4 * (37 * n as u32 % 480),
                py: 4 * (11 * n as u32 % 270),
                sets: [super::super::spp::FULL; 16],
                first: 0,
                covered: false,
            };
            let (mut out, mut expect) = (CellColors::default(), CellColors::default());
            cc.shade::<false>(&polys[p], &vis, &mut out, &mut Counters::new(9));
            cc.shade_scalar(&polys[p], &vis, &mut expect);
            let bits = |c: &CellColors| c.rgb.map(|c| c.map(f32::to_bits));
            assert_eq!(bits(&out), bits(&expect), "cell {n}, polygon {p}");
        }
    }

    #[test]
    fn shading_packed_pixels_is_shading_each_pixel_bit_for_bit() {
        let maps = TextureMaps::new(vec![builtin("grass").unwrap(), builtin("checker").unwrap()]);
        // Two VBs of the 8-bit code: one written by `shade_accumulate` (with AVX2, the
        // CC and F1 in one function), the other by `shade` and `accumulate`.
        let (w, h_px) = (1924, 1084);
        let [mut fused, mut apart] = [0, 1].map(|_| VideoBuffer::new(w, h_px, crate::vp::vb::VbMode::default()));
        let mut next = unit_floats(0x9E37_79B9);
        for round in 0..3000 {
            let mut lin = |scale: f32| FracLin { a: (next() - 0.5) * scale, b: (next() - 0.5) * scale, c: next() };
            // Odd faces now and then: texture coordinates out of any range
            // (infinite or NaN at some pixels), `1/Z` through zero or below it
            // (`Z` clamped to `1 / MIN_POSITIVE`: infinite footprints, total fog).
            let (intensity, u, v) = match round % 13 {
                5 => (lin(1e-3), lin(1e36), lin(3e38)),
                _ => (lin(1e-3), lin(1e-2), lin(1e-2)),
            };
            let inv_z = match round % 11 {
                7 => FracLin { a: (next() - 0.5) * 1e-1, b: (next() - 0.5) * 1e-1, c: next() * 1e-3 },
                9 => FracLin { a: 0.0, b: 0.0, c: -next() },
                _ => FracLin { a: (next() - 0.5) * 1e-4, b: (next() - 0.5) * 1e-4, c: next() * 0.1 + 1e-4 },
            };
            // Map 2 is missing: the face keeps its colour.
            let texture = (round % 4 != 0).then(|| random_texture(round % 3, u, v, &mut next));
            let poly = face_polygon(Vec3::new(next(), next(), next()), inv_z, intensity, texture.is_some());
            let set_ups = texture.as_slice();
            let mut cc = random_computers(&mut next, round % 5 == 0, 1e-3, &maps, set_ups);
            // Any set of visible pixels, from one to all sixteen; a third of them
            // most of the cell (coloured as whole rows), all of it, or all but one.
            let mut sets = [0u16; 16];
            let visible = match round % 6 {
                0 => 0xFFFF,
                1 => !(1u16 << (round / 6 % 16)),
                _ => (next() * 65535.0) as u16 | 1 << (round % 16),
            };
            for (i, s) in sets.iter_mut().enumerate() {
                *s = if visible >> i & 1 == 1 { 1 + (next() * 65534.0) as u16 } else { 0 };
            }
            let (px, py) = (4 * (next() * 480.0) as u32, 4 * (next() * 270.0) as u32);
            let vis = Visible { px, py, sets, first: 0, covered: false };
            let unset = Vec3::splat(-7.0);
            let mut out = CellColors::splat(unset);
            cc.shade::<false>(&poly, &vis, &mut out, &mut Counters::new(9));
            // The build target's code, whatever the processor has.
            let mut scalar = CellColors::splat(unset);
            cc.shade_scalar(&poly, &vis, &mut scalar);
            // Each x86-64 copy the processor can run (else the target's colours
            // again): the compiler's AVX2 code of the portable lanes, the explicit
            // AVX2 copy, the AVX-512 copy.
            let (mut lanes_avx2, mut avx2, mut avx512) = (scalar, scalar, scalar);
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor has AVX2.
                #[allow(unsafe_code, reason = "a test of the AVX2 copies, after detection")]
                unsafe {
                    cc.shade_lanes_avx2(&poly, &vis, &mut lanes_avx2);
                    cc.prepared_avx2(&poly).shade_avx2(&vis, &mut avx2, None);
                }
            }
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx512f") {
                // SAFETY: the processor has AVX-512F.
                #[allow(unsafe_code, reason = "a test of the AVX-512 copy, after detection")]
                unsafe {
                    cc.shade_avx512(&poly, &vis, &mut avx512)
                };
            }
            // The visible pixels; what the others get is unspecified.
            for (i, c) in (0..16).map(|i| (i, out.pixel(i))).filter(|(i, _)| visible >> i & 1 == 1) {
                let expect = plain_pixel(&cc, &poly, px, py, i);
                let bits = |v: &Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(&c), bits(&expect), "round {round}, pixel {i}: {c} against {expect}");
                assert_eq!(bits(&scalar.pixel(i)), bits(&expect), "round {round}, pixel {i}: the target's code");
                assert_eq!(bits(&lanes_avx2.pixel(i)), bits(&expect), "round {round}, pixel {i}: the AVX2 lanes");
                assert_eq!(bits(&avx2.pixel(i)), bits(&expect), "round {round}, pixel {i}: the AVX2 copy");
                assert_eq!(bits(&avx512.pixel(i)), bits(&expect), "round {round}, pixel {i}: the AVX-512 copy");
            }
            // First writes, whole and partial, and later ones over what the VBs hold.
            let mut vis = vis;
            vis.first = (next() * 65535.0) as u16;
            if round % 3 == 0 {
                for s in vis.sets.iter_mut().filter(|s| **s != 0) {
                    *s = crate::vp::spp::FULL;
                }
            }
            let mut counters = Counters::new(9);
            let mut colors = CellColors::splat(unset);
            let fused_f1 = fused.fused_f1();
            #[cfg(target_arch = "x86_64")]
            assert_eq!(
                fused_f1.is_some(),
                std::is_x86_feature_detected!("avx2") && !crate::isa::avx512_copies(),
                "F1 runs inside the AVX2 colour computers exactly when they run"
            );
            cc.shade_accumulate::<false>(
                &poly,
                std::slice::from_ref(&vis),
                &mut colors,
                &mut counters,
                &mut fused,
                fused_f1,
            );
            cc.shade::<false>(&poly, &vis, &mut colors, &mut counters);
            apart.accumulate(&vis, &colors);
            for i in 0..16 {
                let (x, y) = (px + i % 4, py + i / 4);
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(fused.linear(x, y)), bits(apart.linear(x, y)), "round {round}, pixel {i}: F1");
            }
        }
    }

    /// A run of cells given to [`ColorComputers::shade_accumulate`] at once (with
    /// AVX2, the loop over them inside the colour computers' function) writes the
    /// VB as the same cells given one at a time: cells with no visible pixel in the
    /// run (skipped, not ending it), cells over one another (later fragments over
    /// the run's own earlier words), textured and untextured polygons, fog and none.
    #[test]
    fn a_run_of_cells_is_its_cells_one_by_one() {
        let maps = TextureMaps::new(vec![builtin("grass").unwrap()]);
        let (w, h_px) = (64, 48);
        let [mut run, mut one] = [0, 1].map(|_| VideoBuffer::new(w, h_px, crate::vp::vb::VbMode::default()));
        let mut next = unit_floats(0x2545_F491);
        for round in 0..400 {
            let mut lin = |scale: f32| FracLin { a: (next() - 0.5) * scale, b: (next() - 0.5) * scale, c: next() };
            let (intensity, u, v) = (lin(1e-2), lin(1e-1), lin(1e-1));
            let inv_z = FracLin { a: (next() - 0.5) * 1e-4, b: (next() - 0.5) * 1e-4, c: next() * 0.1 + 1e-4 };
            let texture = (round % 2 == 0).then(|| random_texture(0, u, v, &mut next));
            let poly = face_polygon(Vec3::new(next(), next(), next()), inv_z, intensity, texture.is_some());
            let set_ups = texture.as_slice();
            let mut cc = random_computers(&mut next, round % 3 == 0, 1e-2, &maps, set_ups);
            // 1 to 12 cells in a 4 x 3 block of cells, some twice, some empty.
            let len = 1 + (next() * 11.0) as usize;
            let cells: Vec<Visible> = (0..len)
                .map(|k| {
                    let cell = (next() * 12.0) as u32 % 12;
                    let (px, py) = (4 * (cell % 4) + 8 * (round % 4), 4 * (cell / 4) + 4 * (round % 3));
                    let visible = match k % 5 {
                        3 => 0,
                        4 => 0xFFFF,
                        _ => (next() * 65535.0) as u16,
                    };
                    let mut sets = [0u16; 16];
                    for (i, s) in sets.iter_mut().enumerate() {
                        if visible >> i & 1 == 1 {
                            *s = if k % 2 == 0 { crate::vp::spp::FULL } else { 1 + (next() * 65534.0) as u16 };
                        }
                    }
                    Visible { px, py, sets, first: (next() * 65535.0) as u16 & visible, covered: false }
                })
                .collect();
            let (mut colors, mut counters) = (CellColors::default(), Counters::new(9));
            let fused = run.fused_f1();
            cc.shade_accumulate::<false>(&poly, &cells, &mut colors, &mut counters, &mut run, fused);
            for vis in &cells {
                let fused = one.fused_f1();
                cc.shade_accumulate::<false>(
                    &poly,
                    std::slice::from_ref(vis),
                    &mut colors,
                    &mut counters,
                    &mut one,
                    fused,
                );
            }
            for (x, y) in (0..w).flat_map(|x| (0..h_px).map(move |y| (x, y))) {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(run.linear(x, y)), bits(one.linear(x, y)), "round {round}, pixel ({x}, {y})");
            }
        }
    }
}
