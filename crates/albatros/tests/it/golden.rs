//! Golden images: small renders of the built-in scenes, compared bit for bit with the
//! PNGs committed in `tests/golden/`. On a mismatch the test writes the new image and
//! a difference image to `target/golden-diff/`; `UPDATE_GOLDEN=1 cargo test` rewrites
//! the references (look at them before committing).

use std::path::{Path, PathBuf};

use albatros::db::{builtin, Screen};
use albatros::matrix::Matrix;
use albatros::vp::texture::TextureMaps;
use albatros::vp::vb::Image;
use albatros::vp::{VideoProcessor, VpConfig};

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn decode(bytes: &[u8]) -> Image {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    assert_eq!(info.color_type, png::ColorType::Rgb, "golden images are RGB");
    buf.truncate(info.buffer_size());
    Image { width: info.width, height: info.height, pixels: buf }
}

/// Compares `image` with the golden `name.png` (or rewrites it with UPDATE_GOLDEN=1).
pub fn check_golden(name: &str, image: &Image) {
    let path = golden_dir().join(format!("{name}.png"));
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, image.encode_png()).unwrap();
        return;
    }
    let want =
        decode(&std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e} (UPDATE_GOLDEN=1 makes it)", path.display())));
    if &want == image {
        return;
    }
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/golden-diff");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join(format!("{name}.png")), image.encode_png()).unwrap();
    if (want.width, want.height) == (image.width, image.height) {
        let diff: Vec<u8> =
            want.pixels.iter().zip(&image.pixels).map(|(a, b)| a.abs_diff(*b).saturating_mul(8)).collect();
        let d = Image { width: want.width, height: want.height, pixels: diff };
        std::fs::write(out.join(format!("{name}-diff.png")), d.encode_png()).unwrap();
    }
    panic!("{name}: the image differs from {} (new image and difference in {})", path.display(), out.display());
}

/// Renders a built-in scene small, with its textures, on one VP and on a 2 x 2
/// matrix on two threads: both must match the golden image.
fn golden_scene(name: &str, w: u32, h: u32) {
    let mut scene = builtin::scene(name).unwrap();
    scene.screen = Screen { width: w, height: h };
    let db = albatros::gp::Database::new(scene);
    let (frame, _) = albatros::gp::frame_of_scene(&db, &albatros::gp::GpConfig::default());
    let maps = std::sync::Arc::new(TextureMaps::from_scene(&db.scene, Path::new("")).unwrap());
    let mut vp = VideoProcessor::new(w, h, VpConfig::default());
    vp.set_textures(maps.clone());
    let single = vp.render(&frame);
    check_golden(name, &single);
    let mut m = Matrix::new(w, h, VpConfig::default(), 2, 2, 16, 2).unwrap();
    m.set_textures(maps);
    assert!(m.render(&frame) == single, "{name}: the 2 x 2 matrix on two threads differs");
}

#[test]
fn golden_default() {
    golden_scene("default", 128, 96);
}

#[test]
fn golden_rombm() {
    golden_scene("rombm", 128, 128);
}

#[test]
fn golden_city() {
    golden_scene("city", 128, 96);
}

#[test]
fn golden_terrain() {
    golden_scene("terrain", 128, 96);
}
