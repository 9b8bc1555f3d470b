//! Tests of the pipeline (P1's double-buffered frame memory and the VB's
//! double-buffered video memory): the GP of frame n+2 beside the VPs of frame n+1
//! and the readout of frame n gives, two steps late, the images of the stages run
//! one after another, whatever the thread count and matrix size.

use albatros::db::{builtin, Eye, Screen};
use albatros::gp::{self, Database, GpConfig, GpCounters};
use albatros::matrix::Matrix;
use albatros::pipeline::Pipeline;
use albatros::vp::texture::TextureMaps;
use albatros::vp::vb::Image;
use albatros::vp::{VideoProcessor, VpConfig};

#[test]
fn a_pipelined_frame_is_the_frame_of_the_stages_two_steps_late() {
    let screen = Screen { width: 160, height: 120 };
    for name in ["default", "terrain"] {
        let mut scene = builtin::scene(name).unwrap();
        scene.screen = screen;
        let db = Database::new(scene);
        let maps = std::sync::Arc::new(TextureMaps::from_scene(&db.scene, std::path::Path::new("")).unwrap());
        // A flight: the eye moves and turns from frame to frame.
        let eyes: Vec<Eye> = (0..4)
            .map(|k| {
                let mut eye = db.scene.eye;
                eye.position += glam::Vec3::new(30.0, 2.0, -25.0) * k as f32;
                eye.heading += 7.0 * k as f32;
                eye
            })
            .collect();
        // Each eye's image, the stages one after another on one VP.
        let want: Vec<Image> = eyes
            .iter()
            .map(|eye| {
                let mut counters = GpCounters::default();
                let frame = gp::frame(&db, eye, screen, &GpConfig::default(), &mut counters);
                let mut vp = VideoProcessor::new(screen.width, screen.height, VpConfig::default());
                vp.set_textures(maps.clone());
                vp.render(&frame)
            })
            .collect();
        assert!(want.windows(2).all(|w| w[0] != w[1]), "{name}: the flight's frames must differ");
        // P3's interleave, and strip matrices (their strips move from step to step).
        let shapes =
            [(1, 1, 1, false), (2, 1, 2, false), (2, 2, 2, false), (3, 1, 3, false), (2, 1, 2, true), (3, 1, 2, true)];
        for (p, q, threads, striped) in shapes {
            let mut matrix = match striped {
                false => Matrix::new(screen.width, screen.height, VpConfig::default(), p, q, 16, threads).unwrap(),
                true => Matrix::striped(screen.width, screen.height, VpConfig::default(), p, threads).unwrap(),
            };
            matrix.set_textures(maps.clone());
            let mut pipeline = Pipeline::new(&db, screen, GpConfig { threads, ..GpConfig::default() }, matrix);
            let mut image = Image { width: 0, height: 0, pixels: Vec::new() };
            assert!(!pipeline.step(&eyes[0], &mut image), "the first step only sets a frame up");
            assert!(!pipeline.step(&eyes[1], &mut image), "the second step renders the first frame, reads none out");
            for k in 2..eyes.len() {
                assert!(pipeline.step(&eyes[k], &mut image));
                assert!(
                    image == want[k - 2],
                    "{name} {p}x{q} (strips: {striped}) on {threads} threads: step {k} is not frame {}",
                    k - 2
                );
            }
            for last in [eyes.len() - 2, eyes.len() - 1] {
                assert!(pipeline.finish(&mut image));
                assert!(
                    image == want[last],
                    "{name} {p}x{q} (strips: {striped}) on {threads} threads: frame {last} after the last step"
                );
            }
            assert!(!pipeline.finish(&mut image), "nothing is left after the last frame");
        }
    }
}
