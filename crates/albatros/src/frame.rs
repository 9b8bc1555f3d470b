//! The frame list: what the geometric processor (GP) writes into the frame memory (FB)
//! and the video processor (VP) reads (P1 fig. 1, the double-buffered FB).
//!
//! A frame list is a sequence of set-up, screen-space, convex polygons in exact
//! front-to-back priority order. Vertices and edges of all polygons live in two flat
//! arrays that run in step (edge `i` goes from vertex `i` to the polygon's next
//! vertex), each polygon holding one range into both, and the texture set-ups of
//! textured polygons in a third, so that building a frame allocates per frame, never
//! per polygon.
//!
//! Bytes per polygon decide here: `many` (a million small triangles) writes and
//! reads its frame list every frame (and `dump` or `stats`, which join the several
//! GPs' stretches into one list, copy it). A [`FramePolygon`]
//! is 64 bytes, one cache line (it was 128: the texture set-up inline, 60 bytes
//! even when untextured, and a second range equal to the first); a triangle's whole
//! share of the list is 64 + 3 vertices (36) + 3 edge codes (96) + its box (8)
//! bytes. The VP reads the box of every polygon (a matrix VP to find its own, the
//! look-ahead ahead of it) and the polygon and edges of its own; the vertices are
//! for the tools (`dump`, the peer's triangles).
//!
//! **Invariant**: polygon `i` never lies behind polygon `j > i` where they overlap on
//! the screen (for non-intersecting geometry); every polygon is convex with at least
//! three vertices on the 1/256-pixel grid ([`crate::vp::edge::SNAP_ONE`]) and
//! non-zero area; its edges are in the VP's edge code.

use std::ops::Range;

use serde::Serialize;

use crate::db::Rgb;
use crate::vp::edge::EdgeCode;

/// A fractional-linear function's numerator triple over screen pixels (P2): the value
/// `q` at pixel centre `(x, y)` is `(a x + b y + c) / (1/Z)(x, y)`; for the `1/Z`
/// function itself the triple is `1/Z` directly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FracLin {
    /// Coefficient of x.
    pub a: f32,
    /// Coefficient of y.
    pub b: f32,
    /// Constant.
    pub c: f32,
}

impl FracLin {
    /// `a x + b y + c`.
    #[inline]
    pub fn eval(&self, x: f32, y: f32) -> f32 {
        self.a * x + self.b * y + self.c
    }
}

/// One vertex of a screen polygon: position in pixels (origin top-left, y down) on
/// the snapping grid, and `1/w` (`w` = eye-space depth Z).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ScreenVertex {
    /// x in pixels.
    pub x: f32,
    /// y in pixels.
    pub y: f32,
    /// 1 / eye-space depth.
    pub inv_w: f32,
}

/// What kind of primitive a polygon came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PrimitiveKind {
    /// A face of a model.
    Face,
    /// A light point turned into a polygon by the preprocessor.
    Light,
}

/// Texture parameters of a polygon, set up by the GP (P2).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PolyTexture {
    /// Texture map index.
    pub map: u32,
    /// `u` as a fractional-linear function, origin shifted near the eye.
    pub u: FracLin,
    /// `v` likewise.
    pub v: FracLin,
    /// `PAR = (1/L) (1/|Dn|)` for the level of detail.
    pub par: f32,
    /// `C1`, the colour where the map's `T = 1`.
    pub color1: Rgb,
    /// `C2`, the colour where `T = 0`.
    pub color2: Rgb,
}

/// One set-up polygon of the frame list (64 bytes: see the module's notes).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FramePolygon {
    /// Its vertices in [`FrameList::vertices`], and its edges, the same range of
    /// [`FrameList::edges`] (edge `i` from vertex `i` to the next).
    pub vertices: Range<u32>,
    /// Face or light.
    pub kind: PrimitiveKind,
    /// Material index (for a light: `u32::MAX`).
    pub material: u32,
    /// Instance and face it came from (for a light: light index and `u32::MAX`).
    pub source: (u32, u32),
    /// Base colour (untextured faces and lights).
    pub color: Rgb,
    /// `1/Z` as a linear function of pixel coordinates.
    pub inv_z: FracLin,
    /// Brightness, fractional-linear.
    pub intensity: FracLin,
    /// Its texture set-up in [`FrameList::textures`], or [`FramePolygon::NO_TEXTURE`]
    /// ([`FrameList::texture_of`] reads it).
    pub texture: u32,
    /// 6-bit transparency code.
    pub transparency: u8,
}

impl FramePolygon {
    /// [`FramePolygon::texture`] of an untextured polygon.
    pub const NO_TEXTURE: u32 = u32::MAX;
}

/// A polygon's box of pixels, [`crate::vp::bbox`] of its vertices: columns
/// `x0..x1` and rows `y0..y1`, widened by one pixel each way and clamped to the
/// screen. 8 bytes: a screen's side is at most [`crate::db::Screen::MAX_SIDE`].
///
/// Kept beside the polygons rather than made from their vertices where it is read:
/// a VP of a matrix reads the box of every polygon of the frame to find its own, and
/// the look-ahead every polygon's box ahead; from the vertices that was 36 bytes a
/// triangle read, 8 from here.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct PixelBox {
    /// First column.
    pub x0: u16,
    /// Column past the last.
    pub x1: u16,
    /// First row.
    pub y0: u16,
    /// Row past the last.
    pub y1: u16,
}

impl PixelBox {
    /// The box of `vertices` on a `width` x `height` screen ([`crate::vp::bbox`]).
    #[inline(always)]
    pub fn of(vertices: &[ScreenVertex], width: u32, height: u32) -> Self {
        Self::from_bounds(crate::vp::bbox(vertices, width, height))
    }

    /// The box from `[x0, x1, y0, y1]` (each at most the screen's side, so at most
    /// [`crate::db::Screen::MAX_SIDE`]; saturated beyond `u16`, which no screen is).
    #[inline(always)]
    pub fn from_bounds(b: [u32; 4]) -> Self {
        let side = |v: u32| v.min(u32::from(u16::MAX)) as u16;
        Self { x0: side(b[0]), x1: side(b[1]), y0: side(b[2]), y1: side(b[3]) }
    }

    /// `[x0, x1, y0, y1]`, the form [`crate::vp::bbox`] gives.
    #[inline]
    pub fn bounds(self) -> [u32; 4] {
        [u32::from(self.x0), u32::from(self.x1), u32::from(self.y0), u32::from(self.y1)]
    }
}

/// The frame list of one frame (one half of the FB).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameList {
    /// Screen width in pixels.
    pub width: u32,
    /// Screen height in pixels.
    pub height: u32,
    /// Background (sky) colour, the last fragment of every pixel.
    pub background: Rgb,
    /// Fog colour.
    pub fog_color: Rgb,
    /// Visibility range `Z0` (infinite: no fog).
    pub visibility: f32,
    /// Pixel size at unit depth (`delta` of P2's footprint formula), `1/f`.
    pub pixel_angle: f32,
    /// Polygons in front-to-back order.
    pub polygons: Vec<FramePolygon>,
    /// Vertices of all polygons.
    pub vertices: Vec<ScreenVertex>,
    /// Edges of all polygons in the VP's code, in step with `vertices`.
    #[serde(skip)]
    pub edges: Vec<EdgeCode>,
    /// Each polygon's pixel box, in step with `polygons`: what the VP reads of a
    /// polygon that is not its own (its matrix share) or not yet (its look-ahead).
    #[serde(skip)]
    pub boxes: Vec<PixelBox>,
    /// Texture set-ups of the textured polygons ([`FramePolygon::texture`]).
    pub textures: Vec<PolyTexture>,
}

impl FrameList {
    /// The vertices of polygon `p`.
    pub fn vertices_of(&self, p: &FramePolygon) -> &[ScreenVertex] {
        &self.vertices[p.vertices.start as usize..p.vertices.end as usize]
    }

    /// Appends polygon `p`, whose vertices and edges are the last of
    /// [`FrameList::vertices`] and [`FrameList::edges`] from `p.vertices.start`, with
    /// its box: the one way polygons enter a list, so that
    /// [`FrameList::boxes`] stays in step.
    #[inline]
    pub fn push_polygon(&mut self, p: FramePolygon) {
        let bbox = PixelBox::of(self.vertices_of(&p), self.width, self.height);
        self.push_polygon_in(p, bbox);
    }

    /// [`FrameList::push_polygon`] with the polygon's box worked out by the caller
    /// (it must be [`PixelBox::of`] its vertices).
    #[inline]
    pub fn push_polygon_in(&mut self, p: FramePolygon, bbox: PixelBox) {
        self.boxes.push(bbox);
        self.polygons.push(p);
    }

    /// The edges of polygon `p`.
    pub fn edges_of(&self, p: &FramePolygon) -> &[EdgeCode] {
        &self.edges[p.vertices.start as usize..p.vertices.end as usize]
    }

    /// The texture set-up of polygon `p`, if it is textured.
    #[inline]
    pub fn texture_of(&self, p: &FramePolygon) -> Option<&PolyTexture> {
        // `NO_TEXTURE` is past any list's end.
        self.textures.get(p.texture as usize)
    }

    /// The texture set-up of polygon `index`, to change in place.
    pub fn texture_of_mut(&mut self, index: usize) -> Option<&mut PolyTexture> {
        self.textures.get_mut(self.polygons[index].texture as usize)
    }

    /// Gives polygon `index` the texture set-up `texture` (or none).
    pub fn set_texture(&mut self, index: usize, texture: Option<PolyTexture>) {
        match (texture, self.texture_of_mut(index)) {
            (Some(t), Some(old)) => *old = t,
            (Some(t), None) => {
                self.polygons[index].texture = self.textures.len() as u32;
                self.textures.push(t);
            }
            (None, _) => self.polygons[index].texture = FramePolygon::NO_TEXTURE,
        }
    }

    /// The polygon `p` of another list moved to this one, its vertices (and edges)
    /// starting at `v0` and its texture set-ups at `t0` in this one's lists.
    #[inline]
    pub(crate) fn moved(p: &FramePolygon, v0: u32, t0: u32) -> FramePolygon {
        FramePolygon {
            vertices: p.vertices.start + v0..p.vertices.end + v0,
            texture: if p.texture == FramePolygon::NO_TEXTURE { p.texture } else { p.texture + t0 },
            ..p.clone()
        }
    }

    /// Appends another frame list's polygons (for the same screen) after this one's,
    /// in order.
    pub fn append(&mut self, other: &FrameList) {
        let (v0, t0) = (self.vertices.len() as u32, self.textures.len() as u32);
        self.vertices.extend_from_slice(&other.vertices);
        self.edges.extend_from_slice(&other.edges);
        self.textures.extend_from_slice(&other.textures);
        self.boxes.extend_from_slice(&other.boxes);
        self.polygons.extend(other.polygons.iter().map(|p| Self::moved(p, v0, t0)));
    }

    /// Empties the list for reuse, keeping its allocations.
    pub fn clear(&mut self) {
        self.polygons.clear();
        self.vertices.clear();
        self.edges.clear();
        self.textures.clear();
        self.boxes.clear();
    }
}

/// The frame list as `albatros dump` writes it.
pub mod dump {
    use serde::Serialize;

    use super::{FracLin, FrameList, PolyTexture, PrimitiveKind};
    use crate::db::Rgb;

    /// Version of the dump's JSON layout.
    pub const DUMP_VERSION: u32 = 1;

    /// One polygon of the dump.
    #[derive(Serialize)]
    pub struct PolygonDump {
        /// Priority rank: 0 is the nearest.
        pub priority: usize,
        /// Face or light.
        pub kind: PrimitiveKind,
        /// Material index (`null` for a light).
        pub material: Option<u32>,
        /// (instance, face) or (light, null).
        pub source: (u32, Option<u32>),
        /// Screen vertices `[x, y, 1/w]`.
        pub vertices: Vec<[f32; 3]>,
        /// Base colour.
        pub color: Rgb,
        /// `1/Z = a x + b y + c`.
        pub inv_z: FracLin,
        /// Intensity numerator: `I = (a x + b y + c) / (1/Z)`.
        pub intensity: FracLin,
        /// Texture set-up, if textured.
        pub texture: Option<PolyTexture>,
        /// 6-bit transparency code.
        pub transparency: u8,
    }

    /// The whole dump.
    #[derive(Serialize)]
    pub struct FrameDump {
        /// Layout version.
        pub version: u32,
        /// Screen width.
        pub width: u32,
        /// Screen height.
        pub height: u32,
        /// Background colour.
        pub background: Rgb,
        /// Polygons in priority order, nearest first.
        pub polygons: Vec<PolygonDump>,
    }

    impl FrameDump {
        /// The dump of a frame list.
        pub fn new(frame: &FrameList) -> Self {
            let polygons = frame
                .polygons
                .iter()
                .enumerate()
                .map(|(priority, p)| PolygonDump {
                    priority,
                    kind: p.kind,
                    material: (p.kind == PrimitiveKind::Face).then_some(p.material),
                    source: (p.source.0, (p.kind == PrimitiveKind::Face).then_some(p.source.1)),
                    vertices: frame.vertices_of(p).iter().map(|v| [v.x, v.y, v.inv_w]).collect(),
                    color: p.color,
                    inv_z: p.inv_z,
                    intensity: p.intensity,
                    texture: frame.texture_of(p).copied(),
                    transparency: p.transparency,
                })
                .collect();
            Self {
                version: DUMP_VERSION,
                width: frame.width,
                height: frame.height,
                background: frame.background,
                polygons,
            }
        }
    }
}

// The layout the module's notes give: one cache line a polygon.
const _: () = assert!(std::mem::size_of::<FramePolygon>() == 64);
