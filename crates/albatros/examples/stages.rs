//! One frame of a built-in scene, stage by stage, for instruction counts under
//! valgrind's callgrind (repeatable on a noisy machine, where timings are not).
//!
//! Each stage runs in a function of its own that is never inlined
//! (`stage_gp`, `stage_raster`, `stage_vp`, `stage_readout`), so that callgrind can
//! cut the run after each one; `stage_raster` runs the raster stages alone (BP, GQ,
//! SPP) and `stage_vp` the whole VP again (raster, colour, VB), so colour + VB is
//! their difference. A first frame is rendered before the counted one, so that
//! one-time work (tables, the GP's memory, first-touch page faults) is not counted.
//!
//! ```sh
//! cargo build --release --example stages
//! valgrind --tool=callgrind --dump-after='stages::stage_*' \
//!     target/release/examples/stages default --size 1920x1080
//! ```
//!
//! Each `callgrind.out.PID.N` after the first two then holds one stage, in the order
//! above (`bench/callgrind-stages` does this and prints the table).

use std::hint::black_box;
use std::path::Path;
use std::process::ExitCode;

use albatros::db::{builtin, Screen};
use albatros::frame::FrameList;
use albatros::gp::{self, Database, GpConfig, GpCounters, GpMemory};
use albatros::vp::texture::TextureMaps;
use albatros::vp::vb::Image;
use albatros::vp::{VideoProcessor, VpConfig};

const USAGE: &str = "usage: stages SCENE [--size WxH]";

/// The GP's frame, into the kept list.
#[inline(never)]
fn stage_gp(db: &Database, memory: &mut GpMemory, frame: &mut FrameList) {
    let mut counters = GpCounters::default();
    gp::frame_into(db, &db.scene.eye, db.scene.screen, &GpConfig::default(), &mut counters, memory, frame);
}

/// The raster stages alone (BP, GQ, SPP).
#[inline(never)]
fn stage_raster(vp: &mut VideoProcessor, frame: &FrameList) -> u64 {
    vp.raster(frame)
}

/// The whole VP: raster, colour computers, VB accumulation.
#[inline(never)]
fn stage_vp(vp: &mut VideoProcessor, frame: &FrameList) {
    vp.render_frame(frame);
}

/// The VB's readout: F2 and gamma.
#[inline(never)]
fn stage_readout(vp: &VideoProcessor, image: &mut Image) {
    vp.vb.read_out_into(&vp.config.readout, image);
}

fn run() -> Result<(), String> {
    let mut it = std::env::args().skip(1);
    let (mut name, mut size) = (None, None);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--size" => {
                let s = it.next().ok_or("--size needs WxH")?;
                let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("size '{s}' is not WxH"))?;
                let width = w.parse().map_err(|_| format!("bad width '{w}'"))?;
                let height = h.parse().map_err(|_| format!("bad height '{h}'"))?;
                size = Some(Screen { width, height });
            }
            "-h" | "--help" => return Err(USAGE.into()),
            _ if name.is_none() && !a.starts_with('-') => name = Some(a),
            _ => return Err(format!("unexpected argument '{a}'\n{USAGE}")),
        }
    }
    let name = name.unwrap_or_else(|| "default".into());
    let mut scene = builtin::scene(&name)
        .ok_or_else(|| format!("'{name}' is not a built-in scene ({})", builtin::NAMES.join(", ")))?;
    if let Some(size) = size {
        scene.screen = size;
    }
    scene.validate().map_err(|e| format!("scene '{name}': {e}"))?;
    let db = Database::new(scene);
    let maps = TextureMaps::from_scene(&db.scene, Path::new("")).map_err(|e| e.to_string())?;
    let screen = db.scene.screen;
    let mut vp = VideoProcessor::new(screen.width, screen.height, VpConfig::default());
    vp.set_textures(maps);
    let (mut memory, mut frame) = (GpMemory::default(), FrameList::default());
    let mut image = Image { width: 0, height: 0, pixels: Vec::new() };
    // A first frame, uncounted; then the counted one.
    for _ in 0..2 {
        stage_gp(&db, &mut memory, &mut frame);
        black_box(stage_raster(&mut vp, &frame));
        // (Uncounted: the raster pass's masks put back, as a render leaves them.)
        vp.restore_masks();
        stage_vp(&mut vp, &frame);
        stage_readout(&vp, &mut image);
        black_box(&image);
    }
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{e}");
            ExitCode::FAILURE
        }
    }
}
