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
//! longer waits for the `log2` ROM); the TAC's ROM entries `k` and `k + 1` one
//! 8-byte read, by gathers in the AVX-512 copy and by scalar loads in the AVX2
//! copy (Zen 3's gathers cost more). Rust neither
//! fuses nor reorders float operations, and each copy does the same operations in
//! the same order, so the bits are the same; the tests compare every copy the
//! processor can run with the plain per-pixel definition.
//!
//! A cell's colours go to the VB as [`CellColors`], an array per component, which
//! the explicit copies here and the VB's F1 store and load as whole registers. With
//! AVX2 (and not AVX-512) and the VB's 8-bit code, the VB's F1 of the cell runs at
//! the end of the AVX2 copy's own function ([`ColorComputers::shade_accumulate`]):
//! no call, dispatch or set-up of F1 per cell.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

use glam::Vec3;

use super::spp::Visible;
use super::tac::TacRom;
use super::texture::{TextureMap, TextureMaps, LANES};
#[cfg(target_arch = "x86_64")]
use super::vb::F1Avx2;
use super::vb::VideoBuffer;
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
        &self,
        poly: &FramePolygon,
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
    /// ([`VideoBuffer::accumulate`]). With AVX2 (not AVX-512) and the VB's 8-bit code,
    /// both in one function ([`Self::shade_avx2`] with its `f1`): no call, dispatch or set-up of
    /// F1 per cell. The same colours and words. Inlined into its caller, the VP's
    /// loop over cells: its own call had cost ~46 instructions a cell (saved
    /// registers, the features found again; default colour + VB 148.3 → 145.1 M,
    /// terrain 226.5 → 220.4 M).
    #[inline(always)]
    pub fn shade_accumulate<const STATS: bool>(
        &self,
        poly: &FramePolygon,
        vis: &Visible,
        out: &mut CellColors,
        counters: &mut Counters,
        vb: &mut VideoBuffer,
    ) {
        #[cfg(target_arch = "x86_64")]
        if !std::is_x86_feature_detected!("avx512f") {
            if let Some(mut f1) = vb.f1_avx2() {
                // SAFETY: `shade_f1_avx2` only needs AVX2, which the processor has
                // (`f1_avx2` is `Some` only then).
                #[allow(unsafe_code, reason = "the one call of a function compiled for AVX2, after detection")]
                unsafe {
                    self.shade_avx2(poly, vis, out, Some(&mut f1))
                };
                if STATS {
                    let visible = crate::model::stats::visible_pixels(&vis.sets);
                    counters.count_cc_cell(visible, self.drawn_texture(poly));
                }
                return;
            }
        }
        self.shade::<STATS>(poly, vis, out, counters);
        vb.accumulate(vis, out);
    }

    /// Whether `poly` has a texture whose map exists (a texture whose map is
    /// missing is not drawn: the face keeps its colour).
    fn drawn_texture(&self, poly: &FramePolygon) -> bool {
        self.set_up(poly).is_some_and(|t| self.textures.get(t.map).is_some())
    }

    /// [`Self::shade`]'s colours by the best copy the processor runs. (Not generic
    /// over the counting: one copy of each, the groups inlined into it.)
    fn shade_cell(&self, poly: &FramePolygon, vis: &Visible, out: &mut CellColors) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: `shade_avx512` only needs AVX-512F, which the processor was
            // just found to have.
            #[allow(unsafe_code, reason = "the one call of a function compiled for AVX-512, after detection")]
            unsafe {
                return self.shade_avx512(poly, vis, out);
            }
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: `shade_avx2` only needs AVX2, which the processor was just
            // found to have.
            #[allow(unsafe_code, reason = "the one call of a function compiled for AVX2, after detection")]
            unsafe {
                return self.shade_avx2(poly, vis, out, None);
            }
        }
        self.shade_scalar(poly, vis, out)
    }

    /// [`Self::shade`] in explicit AVX2: the cell's halves (two rows, [`AVX2_LANES`]
    /// pixels, one 256-bit register) with a visible pixel; when both have one,
    /// the two side by side ([`CellShader::cell_avx2`]), else the one alone
    /// ([`CellShader::group_avx2`]). The same operations on the same values as
    /// [`Self::shade_lanes`] (Rust neither fuses nor reorders float operations),
    /// so the same bits.
    ///
    /// No packing of a cell's visible pixels into fewer groups (as the portable
    /// copy does): on Zen 3 the two halves side by side cost hardly more than one
    /// (their chains of dependent steps overlap), and a packed group costs its
    /// lanes' scattered stores: terrain's colour computers 3 % faster without it,
    /// default's the same.
    ///
    /// With `f1`, the VB's F1 of the cell follows in the same function
    /// ([`Self::shade_accumulate`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn shade_avx2(&self, poly: &FramePolygon, vis: &Visible, out: &mut CellColors, f1: Option<&mut F1Avx2>) {
        const N: usize = AVX2_LANES;
        let visible = visible_avx2(&vis.sets);
        if visible == 0 {
            return;
        }
        let cell = CellShader::new(self, poly, vis);
        if visible & 0xFF != 0 && visible >> N != 0 {
            for (half, c) in cell.cell_avx2().iter().enumerate() {
                for (out, c) in out.rgb.iter_mut().zip(c) {
                    store_lanes(*c, (&mut out[N * half..N * (half + 1)]).try_into().expect("8 lanes"));
                }
            }
        } else {
            let half = usize::from(visible & 0xFF == 0);
            let first = (N * half) as i32;
            let pixel = _mm256_add_epi32(_mm256_set1_epi32(first), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
            for (out, c) in out.rgb.iter_mut().zip(cell.group_avx2(pixel)) {
                store_lanes(c, (&mut out[N * half..N * (half + 1)]).try_into().expect("8 lanes"));
            }
        }
        if let Some(f1) = f1 {
            f1.accumulate(vis, out);
        }
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

/// [`CellShader::front_avx2`]'s values of eight pixels.
#[cfg(target_arch = "x86_64")]
struct Front {
    /// `Z`.
    z: __m256,
    /// Intensity.
    intensity: __m256,
    /// With a texture: `u`, `v`, the footprint.
    texture: Option<(__m256, __m256, __m256)>,
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
            rom: TacRom::get(),
        }
    }

    /// [`Self::group`] of the cell's 16 pixels (lane `i` pixel `i`) in AVX-512
    /// registers, bit for bit: [`Self::group_avx2`] over the whole cell.
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

    /// [`Self::group`] of eight pixels (`4 y + x` per lane) in AVX2 registers,
    /// bit for bit: the same operations in the same order.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn group_avx2(&self, pixel: __m256i) -> [__m256; 3] {
        let front = self.front_avx2(pixel);
        let m = match (self.texture, front.texture) {
            (Some((_, map)), Some((u, v, footprint))) => Some(map.sample_avx2(u, v, footprint)),
            _ => None,
        };
        self.back_avx2(&front, m)
    }

    /// [`Self::group_avx2`] of the cell's two halves (pixels `0..8` and `8..16`),
    /// each step done for both before the next ([`TextureMap::sample2_avx2`]):
    /// two chains of dependent operations side by side.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn cell_avx2(&self) -> [[__m256; 3]; 2] {
        let halves = [_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_setr_epi32(8, 9, 10, 11, 12, 13, 14, 15)];
        let front = halves.map(|h| self.front_avx2(h));
        let m = match (self.texture, front[0].texture, front[1].texture) {
            (Some((_, map)), Some((u0, v0, f0)), Some((u1, v1, f1))) => {
                let m = map.sample2_avx2([u0, u1], [v0, v1], [f0, f1]);
                [Some(m[0]), Some(m[1])]
            }
            _ => [None, None],
        };
        [self.back_avx2(&front[0], m[0]), self.back_avx2(&front[1], m[1])]
    }

    /// The first steps of [`Self::group_avx2`]: `Z`, intensity, and with a
    /// texture `u`, `v` and the footprint.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn front_avx2(&self, pixel: __m256i) -> Front {
        let poly = self.poly;
        // `dx = x - 1`, `dy = y - 1`: Q is pixel (1, 1).
        let one_i = _mm256_set1_epi32(1);
        let dx = _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_and_si256(pixel, _mm256_set1_epi32(3)), one_i));
        let dy = _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_srli_epi32::<2>(pixel), one_i));
        let one = _mm256_set1_ps(1.0);
        // `Z` and intensity; `max` with the constant second: `maxps` gives it for
        // a NaN, as `f32::max` does.
        let inv_z = step_avx2(self.z_q, &poly.inv_z, dx, dy);
        let z = _mm256_div_ps(one, _mm256_max_ps(inv_z, _mm256_set1_ps(f32::MIN_POSITIVE)));
        let intensity = _mm256_mul_ps(step_avx2(self.i_q, &poly.intensity, dx, dy), z);
        let intensity = _mm256_max_ps(intensity, _mm256_setzero_ps());
        let texture = self.texture.map(|(t, _)| {
            let u = _mm256_mul_ps(step_avx2(self.u_q, &t.u, dx, dy), z);
            let v = _mm256_mul_ps(step_avx2(self.v_q, &t.v, dx, dy), z);
            let footprint = _mm256_mul_ps(
                _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(self.footprint_scale), z), z),
                _mm256_set1_ps(t.par),
            );
            (u, v, footprint)
        });
        Front { z, intensity, texture }
    }

    /// The last steps of [`Self::group_avx2`]: `C0` from the texture's value `m`
    /// (or the flat colour), brightness and fog.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn back_avx2(&self, front: &Front, m: Option<__m256>) -> [__m256; 3] {
        let one = _mm256_set1_ps(1.0);
        let c0: [__m256; 3] = match (self.texture, m) {
            (Some((t, _)), Some(m)) => {
                let not_m = _mm256_sub_ps(one, m);
                let (c1, c2) = (t.color1.to_array(), t.color2.to_array());
                [0, 1, 2].map(|c| {
                    _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(c1[c]), m), _mm256_mul_ps(_mm256_set1_ps(c2[c]), not_m))
                })
            }
            _ => {
                let c = self.poly.color.to_array();
                [_mm256_set1_ps(c[0]), _mm256_set1_ps(c[1]), _mm256_set1_ps(c[2])]
            }
        };
        let f = if self.inv_visibility != 0.0 {
            self.rom.fog_avx2(_mm256_mul_ps(front.z, _mm256_set1_ps(self.inv_visibility)))
        } else {
            one
        };
        let not_f = _mm256_sub_ps(one, f);
        let fog = self.fog;
        let intensity = front.intensity;
        [0, 1, 2].map(|c| {
            _mm256_add_ps(
                _mm256_mul_ps(_mm256_mul_ps(c0[c], intensity), f),
                _mm256_mul_ps(_mm256_set1_ps(fog[c]), not_f),
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

/// `q + a dx + b dy` of eight lanes, in that order (P2 fig. 2's stepping).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn step_avx2(q: f32, f: &FracLin, dx: __m256, dy: __m256) -> __m256 {
    _mm256_add_ps(
        _mm256_add_ps(_mm256_set1_ps(q), _mm256_mul_ps(_mm256_set1_ps(f.a), dx)),
        _mm256_mul_ps(_mm256_set1_ps(f.b), dy),
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
    pub fn flat_color(&self, poly: &FramePolygon) -> Option<Vec3> {
        let drawn_texture = self.drawn_texture(poly);
        let still = |f: &crate::frame::FracLin| f.a == 0.0 && f.b == 0.0;
        if drawn_texture || !still(&poly.inv_z) || !still(&poly.intensity) {
            return None;
        }
        // Pixel (1, 1) of the first cell, alone.
        const Q_PIXEL: usize = 5;
        let mut sets = [0u16; 16];
        sets[Q_PIXEL] = super::spp::FULL;
        let vis = Visible { px: 0, py: 0, sets, first: 0, covered: false };
        let mut out = CellColors::default();
        self.shade::<false>(poly, &vis, &mut out, &mut Counters::default());
        Some(out.pixel(Q_PIXEL))
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
        let mut h = 0x2545_F491u32;
        let mut next = || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            h as f32 / u32::MAX as f32
        };
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
            let poly = FramePolygon {
                vertices: 0..0,
                kind: PrimitiveKind::Face,
                material: 0,
                source: (0, 0),
                color: Vec3::new(next(), next(), next()),
                inv_z,
                intensity,
                texture: if texture.is_some() { 0 } else { FramePolygon::NO_TEXTURE },
                transparency: 0,
            };
            let set_ups = texture.as_slice();
            let cc = ColorComputers {
                fog_color: Vec3::new(next(), next(), next()),
                inv_visibility: if round % 3 == 0 { 0.0 } else { next() * 1e-2 },
                footprint_scale: FOOTPRINT_FACTOR * 1e-3,
                textures: &maps,
                set_ups,
            };
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

    #[test]
    fn shading_packed_pixels_is_shading_each_pixel_bit_for_bit() {
        let maps = TextureMaps::new(vec![builtin("grass").unwrap(), builtin("checker").unwrap()]);
        // Two VBs of the 8-bit code: one written by `shade_accumulate` (with AVX2, the
        // CC and F1 in one function), the other by `shade` and `accumulate`.
        let (w, h_px) = (1924, 1084);
        let [mut fused, mut apart] = [0, 1].map(|_| VideoBuffer::new(w, h_px, crate::vp::vb::VbMode::default()));
        let mut h = 0x9E37_79B9u32;
        let mut next = || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            h as f32 / u32::MAX as f32
        };
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
            let texture = (round % 4 != 0).then(|| PolyTexture {
                // Map 2 is missing: the face keeps its colour.
                map: round % 3,
                u,
                v,
                par: next() * 4.0,
                color1: Vec3::new(next(), next(), next()),
                color2: Vec3::new(next(), next(), next()),
            });
            let poly = FramePolygon {
                vertices: 0..0,
                kind: PrimitiveKind::Face,
                material: 0,
                source: (0, 0),
                color: Vec3::new(next(), next(), next()),
                inv_z,
                intensity,
                texture: if texture.is_some() { 0 } else { FramePolygon::NO_TEXTURE },
                transparency: 0,
            };
            let set_ups = texture.as_slice();
            let cc = ColorComputers {
                fog_color: Vec3::new(next(), next(), next()),
                inv_visibility: if round % 5 == 0 { 0.0 } else { next() * 1e-3 },
                footprint_scale: FOOTPRINT_FACTOR * 1e-3,
                textures: &maps,
                set_ups,
            };
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
                    cc.shade_avx2(&poly, &vis, &mut avx2, None);
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
            cc.shade_accumulate::<false>(&poly, &vis, &mut colors, &mut counters, &mut fused);
            cc.shade::<false>(&poly, &vis, &mut colors, &mut counters);
            apart.accumulate(&vis, &colors);
            for i in 0..16 {
                let (x, y) = (px + i % 4, py + i / 4);
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(fused.linear(x, y)), bits(apart.linear(x, y)), "round {round}, pixel {i}: F1");
            }
        }
    }
}
