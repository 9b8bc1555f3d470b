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
//! On a processor with AVX2 the same code runs compiled for it (detected at run time;
//! the build itself targets x86-64-v2): Rust neither fuses nor reorders float
//! operations, so the bits are the same, and the tests compare both with the plain
//! per-pixel definition.

use glam::Vec3;

use super::spp::Visible;
use super::tac::TacRom;
use super::texture::{TextureMap, TextureMaps, LANES};
use crate::frame::{FrameList, FramePolygon, PolyTexture};
use crate::model::stats::Counters;

/// Number of colour channels (P1: four).
pub const CHANNELS: usize = 4;

/// The factor 2 of P2's footprint `S = 2 delta Z^2 / |Dn|`: the footprint is taken as
/// twice the pixel's stretch along the face's slope, a square that holds the
/// projected pixel, so that the far field blurs rather than shimmers.
pub const FOOTPRINT_FACTOR: f32 = 2.0;

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
}

impl<'a> ColorComputers<'a> {
    /// The registers for a frame, with the scene's texture maps.
    pub fn new(frame: &FrameList, textures: &'a TextureMaps) -> Self {
        let inv_visibility = if frame.visibility.is_finite() { 1.0 / frame.visibility } else { 0.0 };
        Self {
            fog_color: frame.fog_color,
            inv_visibility,
            footprint_scale: FOOTPRINT_FACTOR * frame.pixel_angle,
            textures,
        }
    }

    /// Colours the visible pixels of one cell of polygon `poly` into `out` (what it
    /// writes for pixels with no visible subpixel is unspecified).
    ///
    /// The cell's pixels are computed in groups side by side, as arrays that
    /// vectorise ([`Self::shade_lanes`]), so that a cell's hidden pixels cost little
    /// (a cell of an edge or of a small polygon has few visible pixels: about 5 of 16
    /// on the default scene). Every pixel gets the same operations in the same order
    /// as one computed alone would (the stepping `Q + A dx + B dy`, the reciprocal,
    /// the products), so the colours are bit for bit those of a pixel-by-pixel loop.
    pub fn shade<const STATS: bool>(
        &self,
        poly: &FramePolygon,
        vis: &Visible,
        out: &mut [Vec3; 16],
        counters: &mut Counters,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: `shade_avx2` only needs AVX2, which the processor was just
            // found to have.
            #[allow(unsafe_code, reason = "the one call of a function compiled for AVX2, after detection")]
            unsafe {
                return self.shade_avx2::<STATS>(poly, vis, out, counters);
            }
        }
        self.shade_scalar::<STATS>(poly, vis, out, counters)
    }

    /// [`Self::shade`] compiled for AVX2, in groups of [`AVX2_LANES`] pixels: the
    /// same operations on the same values (Rust neither fuses nor reorders float
    /// operations, whatever the target), so the same bits; the compiler lays the
    /// lanes' arithmetic out in 256-bit registers. The whole path (the group, the
    /// texture unit's lanes, the TAC's ROM lanes) is inlined here, so all of it is
    /// compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn shade_avx2<const STATS: bool>(
        &self,
        poly: &FramePolygon,
        vis: &Visible,
        out: &mut [Vec3; 16],
        counters: &mut Counters,
    ) {
        self.shade_lanes::<STATS, AVX2_LANES>(poly, vis, out, counters)
    }

    /// [`Self::shade`] for the build's target (x86-64-v2: SSE4.2) whatever the
    /// processor, in groups of [`LANES`] pixels (one 128-bit register).
    pub fn shade_scalar<const STATS: bool>(
        &self,
        poly: &FramePolygon,
        vis: &Visible,
        out: &mut [Vec3; 16],
        counters: &mut Counters,
    ) {
        self.shade_lanes::<STATS, LANES>(poly, vis, out, counters)
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
    fn shade_lanes<const STATS: bool, const N: usize>(
        &self,
        poly: &FramePolygon,
        vis: &Visible,
        out: &mut [Vec3; 16],
        counters: &mut Counters,
    ) {
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
                for l in 0..N {
                    out[N * b + l] = Vec3::new(c[0][l], c[1][l], c[2][l]);
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
                    out[i] = Vec3::new(c[0][l], c[1][l], c[2][l]);
                }
            }
        }
        if STATS {
            counters.count_cc_cell(visible, cell.texture.is_some());
        }
    }
}

/// Pixels side by side in the AVX2 copy of the colour computers: two rows of a
/// cell, eight `f32` in one 256-bit register.
#[cfg(target_arch = "x86_64")]
const AVX2_LANES: usize = 8;

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
        let texture = poly.texture.as_ref().and_then(|t| Some((t, cc.textures.get(t.map)?)));
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

impl ColorComputers<'_> {
    /// The one colour of a polygon whose every pixel [`Self::shade`] colours alike,
    /// or `None`: a face with no texture drawn, whose `1/Z` and intensity have
    /// `A = B = 0` (a face square to the view axis, of even brightness: `rombm`'s
    /// rhombi, `many`'s triangles). Its `Z`, intensity and fog are then the same at
    /// every pixel (`Q + 0 dx + 0 dy` is `Q`), and so is its colour; it is computed by
    /// `shade` itself, at one pixel, so it is the very value every pixel would get
    /// (zero's sign aside, which no VB mode keeps apart).
    pub fn flat_color(&self, poly: &FramePolygon) -> Option<Vec3> {
        let drawn_texture = poly.texture.as_ref().is_some_and(|t| self.textures.get(t.map).is_some());
        let still = |f: &crate::frame::FracLin| f.a == 0.0 && f.b == 0.0;
        if drawn_texture || !still(&poly.inv_z) || !still(&poly.intensity) {
            return None;
        }
        // Pixel (1, 1) of the first cell, alone.
        const Q_PIXEL: usize = 5;
        let mut sets = [0u16; 16];
        sets[Q_PIXEL] = super::spp::FULL;
        let vis = Visible { px: 0, py: 0, sets, first: 0, covered: false };
        let mut out = [Vec3::ZERO; 16];
        self.shade::<false>(poly, &vis, &mut out, &mut Counters::default());
        Some(out[Q_PIXEL])
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
        let c0 = match poly.texture.as_ref().and_then(|t| Some((t, cc.textures.get(t.map)?))) {
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
            let zero = |k: u32| if k % 2 == 0 { 0.0 } else { -0.0 };
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
                edges: 0..0,
                kind: PrimitiveKind::Face,
                material: 0,
                source: (0, 0),
                color: Vec3::new(next(), next(), next()),
                inv_z,
                intensity,
                texture,
                transparency: 0,
            };
            let cc = ColorComputers {
                fog_color: Vec3::new(next(), next(), next()),
                inv_visibility: if round % 3 == 0 { 0.0 } else { next() * 1e-2 },
                footprint_scale: FOOTPRINT_FACTOR * 1e-3,
                textures: &maps,
            };
            let flat = cc.flat_color(&poly);
            let drawn = poly.texture.as_ref().is_some_and(|t| t.map == 0);
            assert_eq!(flat.is_some(), !moving && !drawn, "round {round}");
            let Some(flat) = flat else { continue };
            for _ in 0..8 {
                let (px, py) = (4 * (next() * 480.0) as u32, 4 * (next() * 270.0) as u32);
                let vis = Visible { px, py, sets: [super::super::spp::FULL; 16], first: 0, covered: false };
                let mut out = [Vec3::splat(-7.0); 16];
                cc.shade::<false>(&poly, &vis, &mut out, &mut Counters::new(9));
                for (i, c) in out.iter().enumerate() {
                    // `==`: zero's sign may differ, and no VB mode tells them apart.
                    assert!(c.to_array() == flat.to_array(), "round {round}, cell ({px}, {py}), pixel {i}");
                }
            }
        }
    }

    #[test]
    fn shading_packed_pixels_is_shading_each_pixel_bit_for_bit() {
        let maps = TextureMaps::new(vec![builtin("grass").unwrap(), builtin("checker").unwrap()]);
        let mut h = 0x9E37_79B9u32;
        let mut next = || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            h as f32 / u32::MAX as f32
        };
        for round in 0..3000 {
            let mut lin = |scale: f32| FracLin { a: (next() - 0.5) * scale, b: (next() - 0.5) * scale, c: next() };
            let (intensity, u, v) = (lin(1e-3), lin(1e-2), lin(1e-2));
            let inv_z = FracLin { a: (next() - 0.5) * 1e-4, b: (next() - 0.5) * 1e-4, c: next() * 0.1 + 1e-4 };
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
                edges: 0..0,
                kind: PrimitiveKind::Face,
                material: 0,
                source: (0, 0),
                color: Vec3::new(next(), next(), next()),
                inv_z,
                intensity,
                texture,
                transparency: 0,
            };
            let cc = ColorComputers {
                fog_color: Vec3::new(next(), next(), next()),
                inv_visibility: if round % 5 == 0 { 0.0 } else { next() * 1e-3 },
                footprint_scale: FOOTPRINT_FACTOR * 1e-3,
                textures: &maps,
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
            let mut out = [unset; 16];
            cc.shade::<false>(&poly, &vis, &mut out, &mut Counters::new(9));
            // The build target's code, whatever the processor has.
            let mut scalar = [unset; 16];
            cc.shade_scalar::<false>(&poly, &vis, &mut scalar, &mut Counters::new(9));
            // The visible pixels; what the others get is unspecified.
            for (i, c) in out.iter().enumerate().filter(|(i, _)| visible >> i & 1 == 1) {
                let expect = plain_pixel(&cc, &poly, px, py, i);
                let bits = |v: &Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(c), bits(&expect), "round {round}, pixel {i}: {c} against {expect}");
                assert_eq!(bits(&scalar[i]), bits(&expect), "round {round}, pixel {i}: the target's code");
            }
        }
    }
}
