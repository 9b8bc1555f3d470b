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
    pub fn shade<const STATS: bool>(
        &self,
        poly: &FramePolygon,
        vis: &Visible,
        out: &mut [Vec3; 16],
        counters: &mut Counters,
    ) {
        // Q: centre of the cell's pixel (1, 1).
        let (qx, qy) = (vis.px as f32 + 1.5, vis.py as f32 + 1.5);
        let z_q = poly.inv_z.eval(qx, qy);
        let i_q = poly.intensity.eval(qx, qy);
        // A texture whose map is missing is not drawn: the face keeps its colour.
        let texture: Option<(&PolyTexture, &TextureMap)> =
            poly.texture.as_ref().and_then(|t| Some((t, self.textures.get(t.map)?)));
        let (u_q, v_q) = texture.map_or((0.0, 0.0), |(t, _)| (t.u.eval(qx, qy), t.v.eval(qx, qy)));
        for (i, c) in out.iter_mut().enumerate() {
            if vis.sets[i] == 0 {
                continue;
            }
            let dx = (i & 3) as f32 - 1.0;
            let dy = (i >> 2) as f32 - 1.0;
            let inv_z = z_q + poly.inv_z.a * dx + poly.inv_z.b * dy;
            let z = 1.0 / inv_z.max(f32::MIN_POSITIVE);
            let intensity = ((i_q + poly.intensity.a * dx + poly.intensity.b * dy) * z).max(0.0);
            let c0 = match texture {
                Some((t, map)) => {
                    let u = (u_q + t.u.a * dx + t.u.b * dy) * z;
                    let v = (v_q + t.v.a * dx + t.v.b * dy) * z;
                    let footprint = self.footprint_scale * z * z * t.par;
                    let m = map.sample(u, v, footprint);
                    t.color1 * m + t.color2 * (1.0 - m)
                }
                None => poly.color,
            };
            let base = c0 * intensity;
            let f = (-z * self.inv_visibility).exp();
            *c = base * f + self.fog_color * (1.0 - f);
        }
        if STATS {
            counters.count_cc_cell(crate::model::stats::visible_pixels(&vis.sets), texture.is_some());
        }
    }
}
