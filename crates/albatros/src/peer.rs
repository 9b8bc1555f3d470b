//! The frame's triangles for a peer renderer: the frame list written as plain
//! triangles in OpenGL clip space with vertex colours, in a small little-endian binary
//! format that any harness can read (issue 6, "a peer in the same run";
//! `bench/peers/llvmpipe.py` renders it with Mesa's llvmpipe).
//!
//! # Format (version 1, all little-endian)
//!
//! A 32-byte header of eight 4-byte fields:
//!
//! | offset | field | value |
//! |-------:|-------|-------|
//! | 0 | magic | the bytes `SGSC` |
//! | 4 | version | u32, 1 |
//! | 8 | width | u32, pixels |
//! | 12 | height | u32, pixels |
//! | 16 | msaa | u32, 4 (samples per pixel the peer uses) |
//! | 20 | triangle count N | u32 |
//! | 24 | flags | u32, 0 |
//! | 28 | clear colour | u32, packed RGBA8, R in the low byte, A = 255 |
//!
//! then `3 N` vertices of 7 f32 each: `x, y, z, w` in OpenGL clip space, then
//! `r, g, b` in `0..=1`. NDC `(-1, +1)` is the image's top-left corner, so a peer draws
//! with OpenGL's conventions and flips the rows it reads back (OpenGL's origin is the
//! bottom-left); smaller `z / w` is nearer. Triangles come in the frame list's
//! priority order (nearest first), so that with a `LESS` depth test ties go to the
//! polygon the frame list puts first.
//!
//! # From the frame list
//!
//! - Each convex polygon becomes a fan of `vertices - 2` triangles around its first
//!   vertex.
//! - `w = Z = 1 / inv_w` (eye-space depth); `x = (2 x_px / W - 1) w`,
//!   `y = (1 - 2 y_px / H) w`.
//! - `z` is OpenGL's perspective depth, `z = ((f + n) Z - 2 f n) / (f - n)`, with
//!   `n = Z_min / 2` and `f = 2 Z_max` over all the frame's vertices ([`DepthRange`]),
//!   so that `z / w` increases with `Z` and stays inside `(-1, 1)`; it is kept at
//!   least [`DepthRange::MARGIN`] inside, so that `f32` rounding never lets the
//!   farthest vertices be clipped (in frames whose `Z_max / Z_min` exceeds about
//!   `10^6`, the farthest vertices then share one depth and the priority order
//!   decides between them).
//! - Colour per vertex is `base * I`, `I = intensity(x, y) / inv_z(x, y)` (clamped at
//!   0 as the colour computer does), clamped to `0..=1`; OpenGL interpolates it
//!   perspective-correctly, as the colour computer does. `base` is the polygon's
//!   colour, or for a textured polygon the mean of the texture's two colours `C1`,
//!   `C2`: **the peer ignores textures, fog, transparency and the readout filter and
//!   gamma** (colours are linear, as before Albatros's video buffer readout; a peer
//!   that shows the image applies the display gamma itself). The work a peer does is
//!   the same rasterization, depth test and colour interpolation of the same
//!   triangles at the same size; what it does not do is listed here.

use std::io::{self, Write};

use crate::frame::{FrameList, FramePolygon};

/// The file's magic bytes.
pub const MAGIC: [u8; 4] = *b"SGSC";
/// The format version this module writes and reads.
pub const VERSION: u32 = 1;
/// Header length in bytes.
pub const HEADER_LEN: usize = 32;
/// Multisampling the peer is asked for (llvmpipe's maximum).
pub const MSAA: u32 = 4;
/// `f32` values per vertex: `x, y, z, w, r, g, b`.
pub const FLOATS_PER_VERTEX: usize = 7;
/// Bytes per vertex.
pub const VERTEX_LEN: usize = FLOATS_PER_VERTEX * 4;

/// One vertex of the file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeerVertex {
    /// `x, y, z, w` in OpenGL clip space.
    pub clip: [f32; 4],
    /// `r, g, b` in `0..=1`, linear.
    pub color: [f32; 3],
}

/// A whole file, as [`read_triangles`] returns it.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleFile {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub msaa: u32,
    /// Flags (0 in version 1).
    pub flags: u32,
    /// Clear colour, RGBA8.
    pub clear: [u8; 4],
    /// `3 N` vertices, three per triangle.
    pub vertices: Vec<PeerVertex>,
}

impl TriangleFile {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.vertices.len() / 3
    }
}

/// Why bytes are not a triangle file.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PeerFormatError {
    /// Fewer bytes than the header.
    #[error("{0} bytes is shorter than the 32-byte header")]
    TooShort(usize),
    /// The magic is not `SGSC`.
    #[error("bad magic {0:02x?}, expected \"SGSC\"")]
    BadMagic([u8; 4]),
    /// A version this reader does not know.
    #[error("version {0} is not supported (expected 1)")]
    BadVersion(u32),
    /// The length does not match the triangle count.
    #[error("{triangles} triangles need {expected} bytes, the file has {actual}")]
    LengthMismatch {
        /// Triangle count from the header.
        triangles: u32,
        /// Bytes that count needs.
        expected: u64,
        /// Bytes present.
        actual: u64,
    },
}

/// The perspective depth mapping of a frame: eye-space depth `Z` to clip-space `z`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthRange {
    /// Near plane `n` (half the frame's smallest `Z`).
    pub near: f64,
    /// Far plane `f` (twice the frame's largest `Z`).
    pub far: f64,
}

impl DepthRange {
    /// How far inside `(-1, 1)` `z / w` is kept.
    pub const MARGIN: f64 = 1.0 / (1u32 << 20) as f64;

    /// The range for a frame: `n = Z_min / 2`, `f = 2 Z_max` over all its vertices
    /// (`n = 0.5`, `f = 2` for an empty frame).
    pub fn of_frame(frame: &FrameList) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for v in &frame.vertices {
            let z = depth_of(v.inv_w);
            lo = lo.min(z);
            hi = hi.max(z);
        }
        if lo > hi {
            (lo, hi) = (1.0, 1.0);
        }
        Self { near: lo * 0.5, far: hi * 2.0 }
    }

    /// `z / w` for eye-space depth `Z`: increasing in `Z`, inside
    /// `[-1 + MARGIN, 1 - MARGIN]`.
    pub fn ndc_z(&self, z: f64) -> f64 {
        let (n, f) = (self.near, self.far);
        let ndc = (f + n) / (f - n) - 2.0 * f * n / ((f - n) * z);
        ndc.clamp(-1.0 + Self::MARGIN, 1.0 - Self::MARGIN)
    }
}

/// Eye-space depth `Z` from `1/Z`, guarded against a non-positive `1/Z` from rounding.
fn depth_of(inv_w: f32) -> f64 {
    1.0 / f64::from(inv_w).max(1e-30)
}

/// Number of triangles the fan triangulation gives: the sum of `vertices - 2`.
pub fn triangle_count(frame: &FrameList) -> u64 {
    frame.polygons.iter().map(|p| u64::from(p.vertices.end - p.vertices.start).saturating_sub(2)).sum()
}

/// The base colour the peer uses for a polygon: its colour, or for a textured one the
/// mean of the texture's two colours.
fn base_color(frame: &FrameList, p: &FramePolygon) -> [f32; 3] {
    match frame.texture_of(p) {
        Some(t) => ((t.color1 + t.color2) * 0.5).to_array(),
        None => p.color.to_array(),
    }
}

/// `0..=1` to a byte, rounded.
fn to_u8(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Writes the frame's triangles in the format above (see the module docs).
///
/// Writes in chunks of about 64 KiB, so `out` needs no buffering of its own. Fails
/// with `InvalidInput` if the frame has more than `u32::MAX` triangles, and with
/// whatever `out` fails with.
pub fn write_triangles(frame: &FrameList, out: &mut impl Write) -> io::Result<()> {
    let n = u32::try_from(triangle_count(frame))
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "more than u32::MAX triangles"))?;
    let bg = frame.background;
    let clear = u32::from_le_bytes([to_u8(bg.x), to_u8(bg.y), to_u8(bg.z), 255]);
    let mut buf = Vec::with_capacity(1 << 16);
    buf.extend_from_slice(&MAGIC);
    for field in [VERSION, frame.width, frame.height, MSAA, n, 0, clear] {
        buf.extend_from_slice(&field.to_le_bytes());
    }
    let depth = DepthRange::of_frame(frame);
    let (sx, sy) = (2.0 / f64::from(frame.width.max(1)), 2.0 / f64::from(frame.height.max(1)));
    let mut fan: Vec<[f32; FLOATS_PER_VERTEX]> = Vec::new();
    for p in &frame.polygons {
        let vs = frame.vertices_of(p);
        if vs.len() < 3 {
            continue;
        }
        let base = base_color(frame, p);
        fan.clear();
        fan.extend(vs.iter().map(|v| {
            let w = depth_of(v.inv_w);
            let x = (f64::from(v.x) * sx - 1.0) * w;
            let y = (1.0 - f64::from(v.y) * sy) * w;
            let z = depth.ndc_z(w) * w;
            let intensity = (p.intensity.eval(v.x, v.y) / p.inv_z.eval(v.x, v.y).max(f32::MIN_POSITIVE)).max(0.0);
            let c = base.map(|b| (b * intensity).clamp(0.0, 1.0));
            [x as f32, y as f32, z as f32, w as f32, c[0], c[1], c[2]]
        }));
        for i in 1..fan.len() - 1 {
            for v in [&fan[0], &fan[i], &fan[i + 1]] {
                for f in v {
                    buf.extend_from_slice(&f.to_le_bytes());
                }
            }
            if buf.len() >= (1 << 16) - 3 * VERTEX_LEN {
                out.write_all(&buf)?;
                buf.clear();
            }
        }
    }
    out.write_all(&buf)
}

/// Reads a file written by [`write_triangles`] (for tests and tools).
pub fn read_triangles(bytes: &[u8]) -> Result<TriangleFile, PeerFormatError> {
    if bytes.len() < HEADER_LEN {
        return Err(PeerFormatError::TooShort(bytes.len()));
    }
    let word = |i: usize| u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().expect("4 bytes"));
    let magic: [u8; 4] = bytes[0..4].try_into().expect("4 bytes");
    if magic != MAGIC {
        return Err(PeerFormatError::BadMagic(magic));
    }
    if word(1) != VERSION {
        return Err(PeerFormatError::BadVersion(word(1)));
    }
    let triangles = word(5);
    let expected = HEADER_LEN as u64 + u64::from(triangles) * 3 * VERTEX_LEN as u64;
    if bytes.len() as u64 != expected {
        return Err(PeerFormatError::LengthMismatch { triangles, expected, actual: bytes.len() as u64 });
    }
    let vertices = bytes[HEADER_LEN..]
        .chunks_exact(VERTEX_LEN)
        .map(|v| {
            let f = |i: usize| f32::from_le_bytes(v[4 * i..4 * i + 4].try_into().expect("4 bytes"));
            PeerVertex { clip: [f(0), f(1), f(2), f(3)], color: [f(4), f(5), f(6)] }
        })
        .collect();
    Ok(TriangleFile {
        width: word(2),
        height: word(3),
        msaa: word(4),
        flags: word(6),
        clear: word(7).to_le_bytes(),
        vertices,
    })
}
