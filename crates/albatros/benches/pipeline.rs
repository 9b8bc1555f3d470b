//! Criterion benches of the machine's stages on the built-in scenes at 1920 x 1080:
//! the GP's frame (`gp`), the raster stages alone (`raster`: BP, GQ, SPP), the whole
//! VP frame (`vp`: raster, CC, VB accumulation), the VB readout (`readout`: F2,
//! gamma) and the matrix on two threads (`matrix2`). `cargo bench` runs them; CI only
//! builds them (these machines are too noisy for timings in CI).

// criterion's macros generate undocumented public functions.
#![allow(missing_docs)]

use std::path::Path;
use std::sync::Arc;

use albatros::db::{builtin, Screen};
use albatros::gp::{self, Database, GpConfig, GpCounters};
use albatros::matrix::Matrix;
use albatros::vp::texture::TextureMaps;
use albatros::vp::{VideoProcessor, VpConfig};
use criterion::{criterion_group, criterion_main, Criterion};

/// The scenes benched; `many` is left to `albatros bench` (a frame takes seconds).
/// `rombm` against `rhombus` (its top layer alone) shows what depth complexity costs.
const SCENES: [&str; 5] = ["default", "terrain", "city", "rombm", "rhombus"];
const SCREEN: Screen = Screen { width: 1920, height: 1080 };

fn stages(c: &mut Criterion) {
    for name in SCENES {
        let mut scene = builtin::scene(name).expect("built-in scene");
        scene.screen = SCREEN;
        let db = Database::new(scene);
        let maps = Arc::new(TextureMaps::from_scene(&db.scene, Path::new("")).expect("built-in maps"));
        let mut counters = GpCounters::default();
        let frame = gp::frame(&db, &db.scene.eye, SCREEN, &GpConfig::default(), &mut counters);
        let mut vp = VideoProcessor::new(SCREEN.width, SCREEN.height, VpConfig::default());
        vp.set_textures(maps.clone());
        let mut m = Matrix::for_threads(SCREEN.width, SCREEN.height, VpConfig::default(), 2).expect("2 threads");
        m.set_textures(maps);
        let mut g = c.benchmark_group(name);
        g.sample_size(10);
        g.bench_function("gp", |b| {
            b.iter(|| gp::frame(&db, &db.scene.eye, SCREEN, &GpConfig::default(), &mut counters))
        });
        // The raster pass timed alone: its masks put back between passes, untimed,
        // as a render's background pass leaves them (`restore_masks`).
        g.bench_function("raster", |b| {
            b.iter_custom(|iters| {
                let mut time = std::time::Duration::ZERO;
                for _ in 0..iters {
                    let start = std::time::Instant::now();
                    std::hint::black_box(vp.raster(&frame));
                    time += start.elapsed();
                    vp.restore_masks();
                }
                time
            })
        });
        g.bench_function("vp", |b| b.iter(|| vp.render_frame(&frame)));
        vp.render_frame(&frame);
        g.bench_function("readout", |b| b.iter(|| vp.vb.read_out(&vp.config.readout)));
        g.bench_function("matrix2", |b| b.iter(|| m.render(&frame)));
        g.finish();
    }
}

criterion_group!(benches, stages);
criterion_main!(benches);
