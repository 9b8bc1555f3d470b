//! Video buffer (VB, P1 fig. 6): per-pixel accumulation of colour x area, the
//! readout filter F2 and the gamma table.
//!
//! Accumulation (device F1): each pixel sums `colour_i * area_i` over its visible
//! fragments, in priority order; the background is the last fragment of every pixel
//! and fills what is left, so the areas of a pixel always sum to one. The first
//! fragment of a pixel is written, later ones read-modify-write (P1's first-write
//! flag).
//!
//! Readout: the coarse filter F2 gives each pixel the mean of itself and its right,
//! lower and lower-right neighbours (a 2 x 2 box, two passes with a line buffer; at
//! the last row and column the pixel's own value stands in for the missing
//! neighbours), then the gamma table maps linear intensity to 8-bit output.
//!
//! This is the float reference path (f32 accumulators).

use glam::Vec3;

use super::spp::{Visible, CELL_SIDE};
use crate::model::stats::Counters;

/// Entries of the gamma table (linear input resolution).
pub const GAMMA_TABLE_SIZE: usize = 4096;

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

/// Readout options.
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

/// The video memory: colour accumulators of every pixel.
#[derive(Clone, Debug)]
pub struct VideoBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    accum: Vec<Vec3>,
}

impl VideoBuffer {
    /// A cleared buffer.
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, accum: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    /// Clears for a new frame.
    pub fn clear(&mut self) {
        self.accum.fill(Vec3::ZERO);
    }

    /// Accumulates one cell's visible pixels with their colours.
    pub fn accumulate<const STATS: bool>(&mut self, vis: &Visible, colors: &[Vec3; 16], counters: &mut Counters) {
        for (i, (&set, &c)) in vis.sets.iter().zip(colors).enumerate() {
            if set == 0 {
                continue;
            }
            let x = vis.px + (i as u32 & 3);
            let y = vis.py + (i as u32 >> 2);
            debug_assert!(x < self.width && y < self.height, "visible pixel off screen");
            let area = set.count_ones() as f32 / 16.0;
            let p = &mut self.accum[y as usize * self.width as usize + x as usize];
            if vis.first >> i & 1 == 1 {
                *p = c * area;
                if STATS {
                    counters.color.first_writes += 1;
                }
            } else {
                *p += c * area;
                if STATS {
                    counters.color.read_modify_writes += 1;
                }
            }
        }
    }

    /// The accumulated linear colour of a pixel.
    pub fn linear(&self, x: u32, y: u32) -> Vec3 {
        self.accum[y as usize * self.width as usize + x as usize]
    }

    /// Reads the frame out through F2 and the gamma table.
    pub fn read_out(&self, opts: &Readout) -> Image {
        let (w, h) = (self.width as usize, self.height as usize);
        let table = gamma_table(opts.gamma);
        let mut pixels = Vec::with_capacity(w * h * 3);
        let mut line = vec![Vec3::ZERO; w];
        for y in 0..h {
            let below = (y + 1).min(h - 1);
            // Pass 1: half sums of vertically adjacent pixels (the line buffer).
            for (x, l) in line.iter_mut().enumerate() {
                *l = if opts.filter {
                    (self.accum[y * w + x] + self.accum[below * w + x]) * 0.5
                } else {
                    self.accum[y * w + x]
                };
            }
            // Pass 2: half sums of horizontally adjacent ones.
            for x in 0..w {
                let c = if opts.filter { (line[x] + line[(x + 1).min(w - 1)]) * 0.5 } else { line[x] };
                for ch in c.to_array() {
                    let idx = (ch.clamp(0.0, 1.0) * (GAMMA_TABLE_SIZE - 1) as f32).round() as usize;
                    pixels.push(table[idx]);
                }
            }
        }
        Image { width: self.width, height: self.height, pixels }
    }

    /// Cells per row and rows of 4x4 cells covering the buffer.
    pub fn cells(&self) -> (usize, usize) {
        (self.width.div_ceil(CELL_SIDE) as usize, self.height.div_ceil(CELL_SIDE) as usize)
    }
}

/// The gamma table: linear intensity (`GAMMA_TABLE_SIZE` steps over 0..1) to 8-bit
/// display code, `255 x^(1/gamma)` rounded.
pub fn gamma_table(gamma: f32) -> Vec<u8> {
    (0..GAMMA_TABLE_SIZE)
        .map(|i| {
            let x = i as f64 / (GAMMA_TABLE_SIZE - 1) as f64;
            (255.0 * x.powf(1.0 / f64::from(gamma))).round() as u8
        })
        .collect()
}
