//! The matrix of video processors (P3, SYSTEM.md 5): `p x q` VPs on threads.
//!
//! The GP broadcasts one frame list to every VP; VP `(i, j)` renders only its share
//! of the screen ([`Share`]): the tiles at tile column `i mod p`, row `j mod q`. With
//! one-pixel tiles this is P3's interleave by single pixels (each VP on a sparse
//! raster of the whole screen); with tiles of `4 * 2^m` pixels it is an interleave by
//! whole cells, which keeps a VP's work above the tile level from being repeated by
//! the others. Everything outside a VP's share is pre-masked in its mask memories, so
//! the descent is the ordinary one.
//!
//! The video memories together form one interleaved image: each pixel is taken from
//! the VP that owns it, then read out once (the F2 filter needs neighbours from other
//! VPs). **Invariant: the image is the same, byte for byte, whatever the matrix size,
//! the tile size and the number of threads** — every pixel sees the same polygons in
//! the same order with the same subpixel decisions.

use rayon::prelude::*;

use crate::frame::FrameList;
use crate::model::stats::Counters;
use crate::vp::gq::Share;
use crate::vp::vb::{Image, VideoBuffer};
use crate::vp::{VideoProcessor, VpConfig};

/// A matrix of video processors.
pub struct Matrix {
    /// Columns.
    pub p: u32,
    /// Rows.
    pub q: u32,
    /// Tile side in pixels (1 for P3's pixel interleave).
    pub tile: u32,
    vps: Vec<VideoProcessor>,
    /// The matrix's threads (shared, so that [`Self::render_beside`] can run a
    /// frame on them while it borrows the VPs).
    pool: std::sync::Arc<rayon::ThreadPool>,
}

/// A matrix shape that is not possible.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MatrixError {
    /// Zero rows or columns, or too many VPs.
    #[error("matrix {p} x {q}: each side must be 1..=64")]
    Shape {
        /// Columns.
        p: u32,
        /// Rows.
        q: u32,
    },
    /// The tile side is not a power of two or is too big.
    #[error("tile side {0}: must be a power of two from 1 to 4096 pixels")]
    Tile(u32),
    /// The thread pool could not be made.
    #[error("thread pool: {0}")]
    Threads(String),
}

/// The largest matrix side.
pub const MAX_SIDE: u32 = 64;
/// The largest tile side in pixels.
pub const MAX_TILE: u32 = 4096;
/// The tile side used when none is given ([`Matrix::for_threads`]): 64-pixel tiles
/// (cells of level L-4). Each VP repeats the descent of a polygon above the tile
/// level, so small tiles cost work; large ones balance the load worse. Measured on
/// `default` at 1920 x 1080, a 2 x 1 matrix against one VP: the VPs' instructions
/// together +7.0 % with 16-pixel tiles, +4.2 % with 32, +2.5 % with 64, +1.7 % with
/// 128; on two threads 64 was the fastest (1.90x one VP on default, 1.86x on
/// terrain, against 1.81x and 1.77x with 16).
pub const DEFAULT_TILE: u32 = 64;

impl Matrix {
    /// A `p x q` matrix for a `width x height` screen, running on `threads` threads.
    pub fn new(
        width: u32,
        height: u32,
        config: VpConfig,
        p: u32,
        q: u32,
        tile: u32,
        threads: usize,
    ) -> Result<Self, MatrixError> {
        if p == 0 || q == 0 || p > MAX_SIDE || q > MAX_SIDE {
            return Err(MatrixError::Shape { p, q });
        }
        if !tile.is_power_of_two() || tile > MAX_TILE {
            return Err(MatrixError::Tile(tile));
        }
        let mut vps = Vec::with_capacity((p * q) as usize);
        for j in 0..q {
            for i in 0..p {
                let mut vp = VideoProcessor::new(width, height, config);
                let share = Share { tile, p, q, i, j };
                vp.gq.share = share;
                vp.spp.share = share;
                vps.push(vp);
            }
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build()
            .map_err(|e| MatrixError::Threads(e.to_string()))?;
        Ok(Self { p, q, tile, vps, pool: std::sync::Arc::new(pool) })
    }

    /// A matrix for `n` threads: `n` VPs in a near-square shape, interleaved by
    /// [`DEFAULT_TILE`]-pixel tiles.
    pub fn for_threads(width: u32, height: u32, config: VpConfig, n: usize) -> Result<Self, MatrixError> {
        let n = n.clamp(1, (MAX_SIDE * MAX_SIDE) as usize) as u32;
        let mut p = (n as f64).sqrt().floor() as u32;
        while !n.is_multiple_of(p) {
            p -= 1;
        }
        Self::new(width, height, config, n / p, p, DEFAULT_TILE, n as usize)
    }

    /// Renders a frame list on every VP and gathers the interleaved image.
    pub fn render(&mut self, frame: &FrameList) -> Image {
        self.render_frame(frame);
        self.read_out()
    }

    /// Gathers the VPs' video memories into one interleaved image and reads it out
    /// (in bands of rows on the matrix's threads).
    pub fn read_out(&mut self) -> Image {
        let mut image = Image { width: 0, height: 0, pixels: Vec::new() };
        self.read_out_into(&mut image);
        image
    }

    /// [`Self::read_out`] into an image kept from frame to frame (its allocation
    /// reused).
    pub fn read_out_into(&mut self, image: &mut Image) {
        // P1's 8-bit code: each tile read from its VP's memory, no gathering copy.
        let parts: Vec<_> = self.vps.iter().map(|vp| (&vp.vb, &vp.gq.share)).collect();
        let readout = self.vps[0].config.readout;
        if self.pool.install(|| VideoBuffer::read_out_shares_into(&parts, &readout, image)) {
            return;
        }
        let (first, rest) = self.vps.split_first_mut().expect("at least one VP");
        let others: Vec<_> = rest.iter().map(|vp| (&vp.vb, &vp.gq.share)).collect();
        self.pool.install(|| {
            first.vb.copy_shares_from(&others);
            first.vb.read_out_parallel_into(&first.config.readout, image)
        })
    }

    /// Renders a frame list on every VP (their video memories hold the result).
    pub fn render_frame(&mut self, frame: &FrameList) {
        let vps = &mut self.vps;
        self.pool.install(|| vps.par_iter_mut().for_each(|vp| vp.render_frame(frame)));
    }

    /// Runs `f` on the matrix's threads: the GP's several processors
    /// (`gp::frame_into` with as many threads) then share the cores with the VPs
    /// instead of competing with them from a pool of their own.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        self.pool.install(f)
    }

    /// Renders `frame` and reads it out into `image` while `beside` runs on the same
    /// threads, and returns what `beside` returns: P1's double-buffered frame
    /// memory, the GP setting up the next frame in one half while the VPs read the
    /// other (see [`crate::pipeline`]). The threads take whichever work is waiting,
    /// so the GP's serial part overlaps the VPs' work instead of leaving cores idle.
    /// The image is the one [`Self::render_frame`] and [`Self::read_out_into`] give.
    pub fn render_beside<R: Send>(
        &mut self,
        frame: &FrameList,
        image: &mut Image,
        beside: impl FnOnce() -> R + Send,
    ) -> R {
        let pool = std::sync::Arc::clone(&self.pool);
        // Inside the pool, the nested `install`s of `render_frame` and
        // `read_out_into` run in place on the current worker.
        pool.install(|| {
            rayon::join(beside, || {
                self.render_frame(frame);
                self.read_out_into(image);
            })
            .0
        })
    }

    /// Gives every VP the texture maps.
    pub fn set_textures(&mut self, maps: std::sync::Arc<crate::vp::texture::TextureMaps>) {
        for vp in &mut self.vps {
            vp.set_textures(maps.clone());
        }
    }

    /// The VPs' counters, summed.
    pub fn counters(&self) -> Counters {
        let mut c = Counters::new(self.vps[0].gq.root_level);
        for vp in &self.vps {
            c.add(&vp.counters);
        }
        c.polygons = self.vps[0].counters.polygons;
        c
    }

    /// The video processors.
    pub fn vps(&self) -> &[VideoProcessor] {
        &self.vps
    }
}
