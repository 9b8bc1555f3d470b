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
//! Fog (P2): `C = C0 f + C_fog (1 - f)`, `f = exp(-Z / Z0)`.
//!
//! The visible pixels of a cell are dealt to four channels by their position in each
//! 2 x 2 quad (channel `(x & 1) + 2 (y & 1)`), so that an edge's pixels spread evenly.

use glam::Vec3;

use super::spp::Visible;
use super::texture::{TextureMap, TextureMaps};
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

    /// Colours the visible pixels of one cell of polygon `poly` into `out` (pixels
    /// with no visible subpixel are left alone).
    ///
    /// Laid out as arrays over the 16 pixels, so that the arithmetic vectorises;
    /// every pixel gets the same operations in the same order as one computed alone
    /// would (the stepping `Q + A dx + B dy`, the reciprocal, the products), so the
    /// colours are bit for bit those of a pixel-by-pixel loop. Only `exp` (and the
    /// texture unit's reads and `log2`) go pixel by pixel, for the visible pixels.
    pub fn shade<const STATS: bool>(
        &self,
        poly: &FramePolygon,
        vis: &Visible,
        out: &mut [Vec3; 16],
        counters: &mut Counters,
    ) {
        let visible = crate::model::stats::visible_pixels(&vis.sets);
        // Q: centre of the cell's pixel (1, 1).
        let (qx, qy) = (vis.px as f32 + 1.5, vis.py as f32 + 1.5);
        let z_q = poly.inv_z.eval(qx, qy);
        let i_q = poly.intensity.eval(qx, qy);
        // A texture whose map is missing is not drawn: the face keeps its colour.
        let texture: Option<(&PolyTexture, &TextureMap)> =
            poly.texture.as_ref().and_then(|t| Some((t, self.textures.get(t.map)?)));
        let (u_q, v_q) = texture.map_or((0.0, 0.0), |(t, _)| (t.u.eval(qx, qy), t.v.eval(qx, qy)));
        // `Z` and intensity, stepped from Q (P2 fig. 2).
        let z: [f32; 16] = std::array::from_fn(|i| {
            let inv_z = z_q + poly.inv_z.a * STEP_X[i] + poly.inv_z.b * STEP_Y[i];
            1.0 / inv_z.max(f32::MIN_POSITIVE)
        });
        let intensity: [f32; 16] = std::array::from_fn(|i| {
            ((i_q + poly.intensity.a * STEP_X[i] + poly.intensity.b * STEP_Y[i]) * z[i]).max(0.0)
        });
        // C0, per component.
        let c0: [[f32; 16]; 3] = match texture {
            Some((t, map)) => {
                let u = std::array::from_fn(|i| (u_q + t.u.a * STEP_X[i] + t.u.b * STEP_Y[i]) * z[i]);
                let v = std::array::from_fn(|i| (v_q + t.v.a * STEP_X[i] + t.v.b * STEP_Y[i]) * z[i]);
                let footprint = std::array::from_fn(|i| self.footprint_scale * z[i] * z[i] * t.par);
                let m = map.sample_cell(&u, &v, &footprint, visible);
                let (c1, c2) = (t.color1.to_array(), t.color2.to_array());
                std::array::from_fn(|c| std::array::from_fn(|i| c1[c] * m[i] + c2[c] * (1.0 - m[i])))
            }
            None => poly.color.to_array().map(|c| [c; 16]),
        };
        // Fog: `exp(-0)` is 1 exactly, so no fog needs no `exp`.
        let mut f = [1.0f32; 16];
        if self.inv_visibility != 0.0 {
            let arg: [f32; 16] = std::array::from_fn(|i| -z[i] * self.inv_visibility);
            let mut lanes = visible;
            while lanes != 0 {
                let i = lanes.trailing_zeros() as usize & 15;
                lanes &= lanes - 1;
                f[i] = arg[i].exp();
            }
        }
        let fog = self.fog_color.to_array();
        let c: [[f32; 16]; 3] =
            std::array::from_fn(|c| std::array::from_fn(|i| c0[c][i] * intensity[i] * f[i] + fog[c] * (1.0 - f[i])));
        for (i, px) in out.iter_mut().enumerate() {
            if visible & (1 << i) != 0 {
                *px = Vec3::new(c[0][i], c[1][i], c[2][i]);
            }
        }
        if STATS {
            counters.count_cc_cell(visible, texture.is_some());
        }
    }
}

/// `dx` of pixel `i` (`4 y + x`) of a cell from Q, its pixel (1, 1).
const STEP_X: [f32; 16] = [-1.0, 0.0, 1.0, 2.0, -1.0, 0.0, 1.0, 2.0, -1.0, 0.0, 1.0, 2.0, -1.0, 0.0, 1.0, 2.0];

/// `dy` of pixel `i` (`4 y + x`) of a cell from Q.
const STEP_Y: [f32; 16] = [-1.0, -1.0, -1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0];
