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
//! the tile size, the strips and the number of threads** — every pixel sees the same
//! polygons in the same order with the same subpixel decisions.
//!
//! Beside P3's interleave, a *strip matrix* ([`Matrix::striped`], what
//! [`Matrix::for_threads`] makes) puts its VPs side by side in vertical strips of
//! the screen and moves the strips' borders after every frame so that each VP gets
//! an even part of the work the last frame took (each VP's time, spread over its
//! strip by its tallies of work per cell column, [`VideoProcessor::column_work`]): a
//! VP then repeats only the descents of the polygons that cross its strip's
//! borders, touches only its strip of the memories, and drops every polygon outside
//! its strip before its descent. Each VP then reads its strip of the image out
//! (P1's 8-bit code), in the same task, from the memory its thread has just
//! written, all but the one column before each border, whose F2 reads the next
//! strip's memory and is read out after all are done. On a frame like the last one
//! (a simulator's frames follow each other closely) the VPs finish together,
//! readout and all. Strips, not bands of rows:
//! the work of a frame crowds into rows (the far ground at the horizon of `default`:
//! one row of cells held a tenth of the frame), not into columns. A modern choice
//! beside the papers' fixed interleave, measured in BENCHMARKS.md; the image is the
//! same either way, and which VP renders which strip is the only thing the times
//! decide.

use rayon::prelude::*;

use crate::frame::FrameList;
use crate::model::stats::Counters;
use crate::vp::gq::Share;
use crate::vp::vb::{Image, Readout, VideoBuffer, READOUT_BAND_ROWS};
use crate::vp::{VideoProcessor, VpConfig};

/// A matrix of video processors.
pub struct Matrix {
    /// Columns.
    pub p: u32,
    /// Rows.
    pub q: u32,
    /// Tile side in pixels (1 for P3's pixel interleave; the step of the strips'
    /// borders in a strip matrix).
    pub tile: u32,
    /// The VPs are side by side in strips that follow the work
    /// ([`Matrix::striped`]); `p` is their number.
    pub striped: bool,
    vps: Vec<VideoProcessor>,
    /// The strips of the next frame (a strip matrix), chosen from the last frame's
    /// work: the VPs' shares change only as a frame starts, so that the readout of
    /// a frame reads the shares it was rendered with.
    next_strips: Option<Vec<(u32, u32)>>,
    /// Each VP's render time of the last frame, in seconds (a strip matrix).
    times: Vec<f64>,
    /// Each VP's seconds per unit of its tally, smoothed (a strip matrix).
    scales: Vec<f64>,
    /// The matrix's threads (shared, so that [`Self::step`] can run a frame on
    /// them while it borrows the VPs).
    pool: std::sync::Arc<rayon::ThreadPool>,
    /// The other halves of the VPs' double-buffered video memories (SYSTEM.md
    /// 4.4, [`Self::step`]), made at the first step: each holds the frame its VP
    /// rendered at the last step, read out while the VP renders the next.
    back: Vec<VideoBuffer>,
    /// The shares that frame was rendered with (a strip matrix moves its strips
    /// as a frame starts).
    back_shares: Vec<Share>,
    /// Whether the VPs' memories hold a frame rendered by a step and not read out
    /// yet.
    rendered: bool,
    /// The image of the frame in the VPs' memories, read out by the VPs as each
    /// finished its render (a strip matrix of P1's 8-bit code, [`Self::render_stretches`]),
    /// when `read` says so; handed over by [`Self::read_out_into`].
    shown: Image,
    /// Whether `shown` holds the image of the frame in the VPs' memories.
    read: bool,
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
    /// Strips that do not suit the matrix.
    #[error("strips {0:?}: a strip matrix needs one strip per VP, left to right from column 0 to the screen's width, borders at multiples of the step")]
    Strips(Vec<(u32, u32)>),
}

/// The largest matrix side.
pub const MAX_SIDE: u32 = 64;
/// The step of a strip matrix's borders in pixel columns: cells of level L-2, and a
/// whole number of the readout's F2 runs (so that a row is read out by whole runs
/// from each VP). Each step is a tile of the VPs' shares, pre-masked in the mask
/// memory of that level.
pub const STRIP_STEP: u32 = 16;
/// The largest tile side in pixels.
pub const MAX_TILE: u32 = 4096;
/// The tile side of [`Matrix::tiled_for_threads`]: 64-pixel tiles
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
                let share = Share::interleaved(tile, p, q, i, j);
                vp.gq.share = share;
                vp.spp.share = share;
                vps.push(vp);
            }
        }
        Ok(Self {
            p,
            q,
            tile,
            striped: false,
            vps,
            next_strips: None,
            times: Vec::new(),
            scales: Vec::new(),
            pool: Self::pool(threads)?,
            back: Vec::new(),
            back_shares: Vec::new(),
            rendered: false,
            shown: Image { width: 0, height: 0, pixels: Vec::new() },
            read: false,
        })
    }

    fn pool(threads: usize) -> Result<std::sync::Arc<rayon::ThreadPool>, MatrixError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build()
            .map_err(|e| MatrixError::Threads(e.to_string()))?;
        Ok(std::sync::Arc::new(pool))
    }

    /// A strip matrix of `n` VPs (module docs) on `threads` threads: vertical
    /// strips of whole [`STRIP_STEP`]-column steps, of even widths for the first
    /// frame and then of even work. One VP renders the whole screen.
    pub fn striped(width: u32, height: u32, config: VpConfig, n: u32, threads: usize) -> Result<Self, MatrixError> {
        if n == 0 || n > MAX_SIDE {
            return Err(MatrixError::Shape { p: n, q: 1 });
        }
        let steps = width.div_ceil(STRIP_STEP);
        let vps = (0..n)
            .map(|k| {
                let mut vp = VideoProcessor::new(width, height, config);
                if n > 1 {
                    let border = |k: u32| if k == n { width } else { (steps * k / n * STRIP_STEP).min(width) };
                    let share = Share::strip(STRIP_STEP, border(k), border(k + 1));
                    vp.gq.share = share;
                    vp.spp.share = share;
                }
                vp
            })
            .collect();
        Ok(Self {
            p: n,
            q: 1,
            tile: STRIP_STEP,
            striped: n > 1,
            vps,
            next_strips: None,
            times: Vec::new(),
            scales: Vec::new(),
            pool: Self::pool(threads)?,
            back: Vec::new(),
            back_shares: Vec::new(),
            rendered: false,
            shown: Image { width: 0, height: 0, pixels: Vec::new() },
            read: false,
        })
    }

    /// A matrix for `n` threads: a strip matrix of `n` VPs ([`Self::striped`]).
    /// (Measured against [`Self::tiled_for_threads`] in BENCHMARKS.md.)
    pub fn for_threads(width: u32, height: u32, config: VpConfig, n: usize) -> Result<Self, MatrixError> {
        let n = n.clamp(1, MAX_SIDE as usize);
        Self::striped(width, height, config, n as u32, n)
    }

    /// P3's matrix for `n` threads: `n` VPs in a near-square shape, interleaved by
    /// [`DEFAULT_TILE`]-pixel tiles.
    pub fn tiled_for_threads(width: u32, height: u32, config: VpConfig, n: usize) -> Result<Self, MatrixError> {
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
    /// reused). A strip matrix's VPs read the frame out as they rendered it
    /// ([`Self::render_stretches`]): that image is handed over (swapped with
    /// `image`, whose allocation the next frame's readout reuses).
    pub fn read_out_into(&mut self, image: &mut Image) {
        if std::mem::take(&mut self.read) {
            std::mem::swap(image, &mut self.shown);
            return;
        }
        let readout = self.vps[0].config.readout;
        let (first, rest) = self.vps.split_first_mut().expect("at least one VP");
        let rest: Vec<_> = rest.iter().map(|vp| (&vp.vb, &vp.gq.share)).collect();
        self.pool.install(|| read_out_memories((&mut first.vb, &first.gq.share), &rest, &readout, image));
    }

    /// Renders a frame list on every VP (their video memories hold the result).
    pub fn render_frame(&mut self, frame: &FrameList) {
        self.render_stretches(std::slice::from_ref(frame));
    }

    /// [`Self::render_frame`] of a frame given as stretches, the several GPs' lists
    /// left unjoined ([`crate::gp::frame_stretches_into`]): every VP walks them in
    /// order ([`VideoProcessor::render_stretches`]); the same image as their join.
    ///
    /// In a strip matrix of P1's 8-bit code each VP then reads its strip out, in
    /// the same task, from the memory its thread has just written
    /// ([`VideoBuffer::read_out_strip`]), in bands of rows from the top (a thread
    /// left idle takes bands from the bottom: rayon's stealing), and the pixels at
    /// the strips' borders, whose F2 reads two memories, are read out once all are
    /// done ([`VideoBuffer::read_out_strip_borders`]); [`Self::read_out_into`]
    /// hands that image over. Why: the readout by bands of whole rows after the
    /// render read every VP's memory on every thread, and scaled 1.28x on two
    /// (default at 1920 x 1080, session 26: 2.3 ms on one thread, 1.8 on two).
    /// Session 27, quiet host, two threads, 6 pairs: default's frame 13.1-14.1 ->
    /// 12.8-13.7 ms (~2 %, the VPs and readout ~0.3 ms less), city 12.2-12.5 ->
    /// 11.4-12.4, terrain 30.1 -> 29.2; the same within the noise when loaded.
    pub fn render_stretches(&mut self, stretches: &[FrameList]) {
        self.render_stretches_then(stretches, &|| (), true);
    }

    /// [`Self::render_stretches`], each thread running `fill` as its VP is done
    /// and no VP is left to start ([`Self::step`]); `fill` runs at least once.
    /// `read`: the VPs read their strips out ([`Self::render_stretches`]'s).
    fn render_stretches_then(&mut self, stretches: &[FrameList], fill: &(dyn Fn() + Sync), read: bool) {
        if let Some(strips) = self.next_strips.take() {
            for (vp, (x0, x1)) in self.vps.iter_mut().zip(strips) {
                let share = Share::strip(self.tile, x0, x1);
                vp.gq.share = share;
                vp.spp.share = share;
            }
        }
        // The readout by strips: its gamma table, and each VP's part of the image's
        // rows (the strips tile the columns left to right).
        self.read = false;
        let readout = match read && self.striped {
            true => self.vps[0].vb.log8_readout(&self.vps[0].config.readout),
            false => None,
        };
        let strips = self.strips();
        let mut parts: Vec<Vec<&mut [u8]>> = Vec::new();
        if readout.is_some() {
            let (w, h) = (self.vps[0].vb.width as usize, self.vps[0].vb.height as usize);
            self.shown.width = w as u32;
            self.shown.height = h as u32;
            // Every byte is written below; `resize` only zeroes a first or larger frame.
            self.shown.pixels.resize(3 * w * h, 0);
            parts = strips.iter().map(|_| Vec::with_capacity(h)).collect();
            for row in self.shown.pixels.chunks_exact_mut(3 * w.max(1)) {
                let mut rest = row;
                for (part, &(x0, x1)) in parts.iter_mut().zip(&strips) {
                    let (strip, after) = rest.split_at_mut(3 * (x1 - x0) as usize);
                    part.push(strip);
                    rest = after;
                }
                assert!(rest.is_empty(), "strips that tile the columns");
            }
        }
        parts.resize_with(self.vps.len(), Vec::new);
        let (vps, times) = (&mut self.vps, &mut self.times);
        times.resize(vps.len(), 0.0);
        let timed = self.striped;
        let (count, started) = (vps.len(), std::sync::atomic::AtomicUsize::new(0));
        let readout = readout.as_ref();
        self.pool.install(|| {
            vps.par_iter_mut().zip(times.par_iter_mut()).zip(parts.into_par_iter()).for_each(|((vp, time), rows)| {
                started.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let start = timed.then(std::time::Instant::now);
                vp.render_stretches(stretches);
                if let Some(readout) = readout {
                    // In bands of rows, top to bottom on this thread; a thread
                    // left idle (its VP done first, or the host's noise on this
                    // one) takes bands from the bottom.
                    let (vb, strip, mut rows) = (&vp.vb, vp.gq.share.strip, rows);
                    rows.par_chunks_mut(READOUT_BAND_ROWS).enumerate().for_each(|(k, band)| {
                        let y0 = k * READOUT_BAND_ROWS;
                        vb.read_out_strip(readout, strip, y0..y0 + band.len(), band.iter_mut().map(|row| &mut **row));
                    });
                }
                // (With the strip's readout: the strips are cut so that the VPs
                // finish together, readout and all.)
                if let Some(start) = start {
                    *time = start.elapsed().as_secs_f64();
                }
                if started.load(std::sync::atomic::Ordering::Relaxed) == count {
                    fill();
                }
            });
            fill();
        });
        if let Some(readout) = readout {
            let strips: Vec<_> = self.vps.iter().map(|vp| (&vp.vb, vp.gq.share.strip)).collect();
            VideoBuffer::read_out_strip_borders(&strips, readout, &mut self.shown);
            self.read = true;
        }
        if self.striped {
            self.next_strips = Some(self.balance(stretches[0].width));
        }
    }

    /// A strip matrix's strips for the next frame: each cell column's work as its
    /// VP tallied it ([`VideoProcessor::column_work`] and a background pass per
    /// column), scaled by how long that VP took for its strip's tally (the tallies'
    /// weights are estimates; the time puts them in seconds on this machine, whose
    /// units may weigh otherwise), the scale smoothed from frame to frame; then
    /// [`even_strips`].
    fn balance(&mut self, width: u32) -> Vec<(u32, u32)> {
        use crate::vp::{spp::CELL_SIDE, work::BACKGROUND_COLUMN};
        let columns = self.vps[0].column_work.len();
        let cells = |vp: &VideoProcessor| {
            let (x0, x1) = vp.gq.share.strip;
            (x0 / CELL_SIDE) as usize..(x1.div_ceil(CELL_SIDE) as usize).min(columns)
        };
        // Each strip's tallies, and its VP's seconds per unit.
        let mut cost = vec![0.0f64; columns];
        self.scales.resize(self.vps.len(), 0.0);
        for (k, vp) in self.vps.iter().enumerate() {
            let cells = cells(vp);
            for (c, &w) in cost[cells.clone()].iter_mut().zip(&vp.column_work[cells.clone()]) {
                *c = f64::from(w) + BACKGROUND_COLUMN as f64;
            }
            let total: f64 = cost[cells].iter().sum();
            if total > 0.0 && self.times[k] > 0.0 {
                let scale = self.times[k] / total;
                // Smoothed: one frame's time is noisy on a shared machine.
                self.scales[k] = if self.scales[k] > 0.0 { 0.5 * (self.scales[k] + scale) } else { scale };
            }
        }
        // In seconds; a VP not timed yet (an empty strip) at the others' mean scale.
        let timed: Vec<f64> = self.scales.iter().copied().filter(|&s| s > 0.0).collect();
        let mean = if timed.is_empty() { 1.0 } else { timed.iter().sum::<f64>() / timed.len() as f64 };
        for (k, vp) in self.vps.iter().enumerate() {
            let scale = if self.scales[k] > 0.0 { self.scales[k] } else { mean };
            cost[cells(vp)].iter_mut().for_each(|c| *c *= scale);
        }
        even_strips(&cost, self.vps.len(), self.tile, width)
    }

    /// The strips of a strip matrix's VPs now (pixel columns `x0 .. x1`, left to
    /// right).
    pub fn strips(&self) -> Vec<(u32, u32)> {
        self.vps.iter().map(|vp| vp.gq.share.strip).collect()
    }

    /// Sets the strips of a strip matrix's next frame (the matrix moves them again
    /// after it): one per VP, left to right, each from where the last ended (the
    /// first from 0, the last to the screen's width), borders at multiples of the
    /// matrix's step. For experiments and tests: the image does not depend on them.
    pub fn set_strips(&mut self, strips: &[(u32, u32)]) -> Result<(), MatrixError> {
        let width = self.vps[0].vb.width;
        let mut x = 0;
        let fits = self.striped
            && strips.len() == self.vps.len()
            && strips.iter().all(|&(x0, x1)| {
                let ok = x0 == x && x1 >= x0 && (x1 == width || (x1 < width && x1 % self.tile == 0));
                x = x1;
                ok
            })
            && x == width;
        if !fits {
            return Err(MatrixError::Strips(strips.to_vec()));
        }
        self.next_strips = Some(strips.to_vec());
        Ok(())
    }

    /// Runs `f` on the matrix's threads: the GP's several processors
    /// (`gp::frame_into` with as many threads) then share the cores with the VPs
    /// instead of competing with them from a pool of their own.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        self.pool.install(f)
    }

    /// One frame period of the machine's three stages (SYSTEM.md 1, 4.4; see
    /// [`crate::pipeline`]), on the matrix's threads: the VPs render `frame` (as
    /// stretches, [`Self::render_stretches`]; none: they rest) into one half of
    /// their double-buffered video memories while the other half, the frame they
    /// rendered at the last step, is read out into `image`, and `beside` (the GP
    /// setting up the next frame in its half of the frame memory) runs with them.
    /// Returns what `beside` returns, and whether `image` now holds a frame (not
    /// when the last step rendered none). The image is the one
    /// [`Self::render_frame`] and [`Self::read_out_into`] give for that frame.
    ///
    /// The VPs start first, one long task each (their shares are even); as a
    /// thread finishes its VP, and no VP is left to start, it takes `beside`, then
    /// the readout, both cut into many small tasks that the other thread joins when
    /// its VP is done. The two stages beside the VPs thus fill whatever the VPs
    /// leave: their uneven ends (the host's noise falls on one thread at a time)
    /// and the GP's serial parts.
    pub fn step<R: Send>(
        &mut self,
        frame: Option<&[FrameList]>,
        image: &mut Image,
        beside: impl FnOnce() -> R + Send,
    ) -> (R, bool) {
        if self.back.len() != self.vps.len() {
            self.back = self.vps.iter().map(|vp| VideoBuffer::new(vp.vb.width, vp.vb.height, vp.vb.mode())).collect();
            self.back_shares = self.vps.iter().map(|vp| vp.gq.share).collect();
        }
        // The halves swap: the frame just rendered goes to be read out, with the
        // shares it was rendered with (the strips move as the next frame starts).
        let read = std::mem::take(&mut self.rendered);
        // (The memories change halves: an image read out by strips is not theirs.)
        self.read = false;
        if read {
            for ((vp, back), share) in self.vps.iter_mut().zip(&mut self.back).zip(&mut self.back_shares) {
                std::mem::swap(&mut vp.vb, back);
                *share = vp.gq.share;
            }
        }
        let readout = self.vps[0].config.readout;
        let pool = std::sync::Arc::clone(&self.pool);
        // (Taken out of `self` while the VPs render, and put back after.)
        let (mut back, back_shares) = (std::mem::take(&mut self.back), std::mem::take(&mut self.back_shares));
        // The stages beside the VPs, each taken by the first thread free.
        let beside = std::sync::Mutex::new(Some(beside));
        let done = std::sync::Mutex::new(None);
        let read_out = std::sync::Mutex::new(read.then_some((&mut back, image)));
        // (Each taken in a statement of its own: a lock held through the stage
        // would keep the other threads waiting on it, not helping.)
        let fill = || {
            let job = beside.lock().expect("no panic holding the lock").take();
            if let Some(beside) = job {
                let r = beside();
                *done.lock().expect("no panic holding the lock") = Some(r);
            }
            let job = read_out.lock().expect("no panic holding the lock").take();
            if let Some((back, image)) = job {
                let (first, rest) = back.split_first_mut().expect("at least one VP");
                let rest: Vec<_> = rest.iter().zip(&back_shares[1..]).collect();
                read_out_memories((first, &back_shares[0]), &rest, &readout, image);
            }
        };
        // Inside the pool, the nested `install` of `render_stretches` runs in place.
        pool.install(|| match frame {
            Some(frame) => self.render_stretches_then(frame, &fill, false),
            None => fill(),
        });
        (self.back, self.back_shares) = (back, back_shares);
        self.rendered = frame.is_some();
        let r = done.into_inner().expect("no panic holding the lock").expect("`beside` ran");
        (r, read)
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

/// Reads out a matrix's video memories, each with the share of the screen its VP
/// rendered, into one image: P1's 8-bit code in place, each tile read from its
/// VP's memory ([`VideoBuffer::read_out_shares_into`]); the other codes gathered
/// into the first memory, then read out. On the current rayon pool.
fn read_out_memories(
    first: (&mut VideoBuffer, &Share),
    rest: &[(&VideoBuffer, &Share)],
    readout: &Readout,
    image: &mut Image,
) {
    let mut parts = Vec::with_capacity(rest.len() + 1);
    parts.push((&*first.0, first.1));
    parts.extend_from_slice(rest);
    if VideoBuffer::read_out_shares_into(&parts, readout, image) {
        return;
    }
    drop(parts);
    first.0.copy_shares_from(rest);
    first.0.read_out_parallel_into(readout, image);
}

/// The borders of `n` strips of whole `step`-column steps of a `width`-column screen
/// that share `cost` (per column of last-level cells) most evenly: strip `k` ends at
/// the step border nearest to where the running sum reaches `(k + 1) / n` of the
/// whole. Left to right, every column in exactly one strip; a strip may be empty.
pub fn even_strips(cost: &[f64], n: usize, step: u32, width: u32) -> Vec<(u32, u32)> {
    let cells_per_step = (step / crate::vp::spp::CELL_SIDE).max(1) as usize;
    let steps = width.div_ceil(step) as usize;
    let per_step: Vec<f64> = (0..steps)
        .map(|s| cost[(s * cells_per_step).min(cost.len())..((s + 1) * cells_per_step).min(cost.len())].iter().sum())
        .collect();
    let total: f64 = per_step.iter().sum();
    let mut strips = Vec::with_capacity(n);
    let (mut s, mut sum, mut x0) = (0usize, 0.0f64, 0u32);
    for k in 1..=n {
        let x1 = if k == n {
            width
        } else {
            let target = total * k as f64 / n as f64;
            // Take steps while the running sum comes closer to the target with them.
            while s < steps && sum + per_step[s] / 2.0 < target {
                sum += per_step[s];
                s += 1;
            }
            (s as u32 * step).min(width)
        };
        strips.push((x0, x1));
        x0 = x1;
    }
    strips
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Strips of even cost split an even screen evenly, and a screen whose cost
    /// is all in one place puts a border next to it.
    #[test]
    fn even_strips_split_the_cost() {
        assert_eq!(even_strips(&[1.0; 480], 2, 16, 1920), vec![(0, 960), (960, 1920)]);
        assert_eq!(even_strips(&[1.0; 480], 3, 16, 1920), vec![(0, 640), (640, 1280), (1280, 1920)]);
        let mut cost = vec![0.0; 480];
        cost[100] = 1.0;
        let strips = even_strips(&cost, 2, 16, 1920);
        assert!(strips[0].1 == 400 || strips[0].1 == 416, "{strips:?}");
        // No cost at all: every strip but the last empty is still a split of the
        // screen.
        assert_eq!(even_strips(&[0.0; 10], 2, 16, 40), vec![(0, 0), (0, 40)]);
    }

    /// The several GPs' stretches walked in order ([`Matrix::render_stretches`],
    /// [`VideoProcessor::render_stretches`]) give the image of their join, and with
    /// counting on the same counters: scenes with textures, light points, a moving
    /// model, faces clipped by the window and the near plane (eyes moved and turned).
    #[test]
    fn stretches_render_as_their_join() {
        use crate::db::{builtin, Screen};
        use crate::gp::{self, Database, GpConfig, GpCounters, GpMemory};
        use crate::vp::texture::TextureMaps;
        let screen = Screen { width: 256, height: 160 };
        let mut several = false;
        for name in ["default", "city", "terrain"] {
            let db = Database::new(builtin::scene(name).expect("built-in"));
            let maps = std::sync::Arc::new(TextureMaps::from_scene(&db.scene, std::path::Path::new("")).expect("maps"));
            let (mut memory, mut stretches, mut c) = (GpMemory::default(), Vec::new(), GpCounters::default());
            let mut eye = db.scene.eye;
            for k in 0..3 {
                if k > 0 {
                    eye.position += glam::Vec3::new(37.0, -23.0, 4.0);
                    eye.heading += 70.0;
                    eye.pitch -= 9.0;
                }
                let config = GpConfig { threads: 2, ..GpConfig::default() };
                gp::frame_stretches_into(&db, &eye, screen, &config, &mut c, &mut memory, &mut stretches);
                let joined = gp::frame(&db, &eye, screen, &GpConfig::default(), &mut c);
                several |= stretches.len() > 1;
                let image = |stretched: bool| {
                    let mut m =
                        Matrix::for_threads(screen.width, screen.height, VpConfig::default(), 2).expect("matrix");
                    m.set_textures(maps.clone());
                    match stretched {
                        true => m.render_stretches(&stretches),
                        false => m.render_frame(&joined),
                    }
                    m.read_out().pixels
                };
                assert!(image(true) == image(false), "{name}, eye {k}: the matrix's image");
                let config = VpConfig { stats: true, ..VpConfig::default() };
                let one_vp = |stretched: bool| {
                    let mut vp = VideoProcessor::new(screen.width, screen.height, config);
                    vp.set_textures(maps.clone());
                    match stretched {
                        true => vp.render_stretches(&stretches),
                        false => vp.render_frame(&joined),
                    }
                    (vp.vb.read_out(&config.readout).pixels, vp.counters.clone())
                };
                assert!(one_vp(true) == one_vp(false), "{name}, eye {k}: one VP's image and counters");
            }
        }
        assert!(several, "never more than one stretch: the test tests nothing");
    }

    /// A strip matrix's image read out by its VPs as they finish their renders
    /// ([`VideoBuffer::read_out_strip`], then the borders) is the readout by bands
    /// of rows of the same memories ([`read_out_memories`]) and one VP's image:
    /// scenes with textures and light points, the eye moved, the strips moved by
    /// the matrix and set (an empty one, one of a step), a short last strip (the
    /// width not a multiple of the step), F2 on and off.
    #[test]
    fn read_out_by_strips_is_the_readout_by_bands() {
        use crate::db::{builtin, Screen};
        use crate::gp::{self, Database, GpConfig, GpCounters};
        use crate::vp::texture::TextureMaps;
        let screen = Screen { width: 328, height: 120 };
        for (name, filter) in [("default", true), ("city", false), ("terrain", true), ("city", true)] {
            let db = Database::new(builtin::scene(name).expect("built-in"));
            let maps = std::sync::Arc::new(TextureMaps::from_scene(&db.scene, std::path::Path::new("")).expect("maps"));
            let config = VpConfig { readout: Readout { filter, gamma: 2.2 }, ..VpConfig::default() };
            let mut m = Matrix::striped(screen.width, screen.height, config, 3, 2).expect("matrix");
            m.set_textures(maps.clone());
            let mut one = VideoProcessor::new(screen.width, screen.height, config);
            one.set_textures(maps);
            let (mut eye, mut image) = (db.scene.eye, Image { width: 0, height: 0, pixels: Vec::new() });
            for k in 0..5 {
                eye.position += glam::Vec3::new(17.0, -3.0, 9.0);
                eye.heading += 23.0;
                let frame = gp::frame(&db, &eye, screen, &GpConfig::default(), &mut GpCounters::default());
                match k {
                    2 => m.set_strips(&[(0, 0), (0, 16), (16, screen.width)]).expect("strips"),
                    3 => m.set_strips(&[(0, 320), (320, 320), (320, screen.width)]).expect("strips"),
                    _ => {}
                }
                m.render_frame(&frame);
                assert!(m.read, "{name}, frame {k}: the VPs read their strips out");
                m.read_out_into(&mut image);
                // Now by bands of rows, from the same memories.
                let bands = m.read_out();
                assert!(image == bands, "{name}, frame {k}, strips {:?}: by strips and by bands", m.strips());
                assert!(image == one.render(&frame), "{name}, frame {k}: one VP's image");
            }
        }
    }

    proptest! {
        /// The strips tile the screen left to right at multiples of the step, and
        /// none costs more than an even share and one step.
        #[test]
        fn even_strips_tile_the_screen_and_even_out_the_cost(
            cost in proptest::collection::vec(0.0f64..100.0, 1..200),
            n in 1usize..6,
            step_log in 2u32..6,
        ) {
            let step = 1 << step_log;
            let width = cost.len() as u32 * crate::vp::spp::CELL_SIDE;
            let strips = even_strips(&cost, n, step, width);
            prop_assert_eq!(strips.len(), n);
            let mut x = 0;
            for &(x0, x1) in &strips {
                prop_assert_eq!(x0, x);
                prop_assert!(x1 >= x0 && (x1 == width || x1 % step == 0));
                x = x1;
            }
            prop_assert_eq!(x, width);
            let cells = |(x0, x1): (u32, u32)| (x0 / crate::vp::spp::CELL_SIDE) as usize..(x1 / crate::vp::spp::CELL_SIDE) as usize;
            let total: f64 = cost.iter().sum();
            let per_cell = (step / crate::vp::spp::CELL_SIDE).max(1) as usize;
            let max_step = cost.chunks(per_cell).map(|c| c.iter().sum::<f64>()).fold(0.0, f64::max);
            for &strip in &strips {
                let c: f64 = cost[cells(strip)].iter().sum();
                prop_assert!(c <= total / n as f64 + max_step + 1e-6, "strip {:?} costs {} of {}", strip, c, total);
            }
        }
    }
}
