//! Writes a built-in scene's frame as the peer's triangle file (`albatros::peer`), the
//! same file `albatros dump SCENE --format triangles` writes:
//!
//! ```sh
//! cargo run --release --example triangles -- default --size 1920x1080 -o /tmp/default.sgsc
//! python3 bench/peers/llvmpipe.py /tmp/default.sgsc --png /tmp/default-llvmpipe.png
//! ```

use std::io::BufWriter;
use std::process::ExitCode;

use albatros::db::{builtin, Screen};
use albatros::gp::{self, Database, GpConfig};
use albatros::peer;

const USAGE: &str = "usage: triangles SCENE [--size WxH] -o FILE";

/// The command line: scene name, optional size, output path.
struct Args {
    scene: String,
    size: Option<Screen>,
    output: String,
}

fn parse_args() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let (mut scene, mut size, mut output) = (None, None, None);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--size" => {
                let s = it.next().ok_or("--size needs WxH")?;
                let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("size '{s}' is not WxH"))?;
                let w: u32 = w.parse().map_err(|_| format!("bad width '{w}'"))?;
                let h: u32 = h.parse().map_err(|_| format!("bad height '{h}'"))?;
                size = Some(Screen { width: w, height: h });
            }
            "-o" | "--output" => output = Some(it.next().ok_or("-o needs a file")?),
            "-h" | "--help" => return Err(USAGE.into()),
            _ if scene.is_none() && !a.starts_with('-') => scene = Some(a),
            _ => return Err(format!("unexpected argument '{a}'\n{USAGE}")),
        }
    }
    Ok(Args {
        scene: scene.unwrap_or_else(|| "default".into()),
        size,
        output: output.ok_or_else(|| format!("no output file\n{USAGE}"))?,
    })
}

fn run() -> Result<(), String> {
    let args = parse_args()?;
    let mut scene = builtin::scene(&args.scene)
        .ok_or_else(|| format!("'{}' is not a built-in scene ({})", args.scene, builtin::NAMES.join(", ")))?;
    if let Some(size) = args.size {
        scene.screen = size;
    }
    scene.validate().map_err(|e| format!("scene '{}': {e}", args.scene))?;
    let db = Database::new(scene);
    let (frame, _) = gp::frame_of_scene(&db, &GpConfig::default());
    let file = std::fs::File::create(&args.output).map_err(|e| format!("creating {}: {e}", args.output))?;
    let mut out = BufWriter::new(file);
    peer::write_triangles(&frame, &mut out)
        .and_then(|()| std::io::Write::flush(&mut out))
        .map_err(|e| format!("writing {}: {e}", args.output))?;
    println!(
        "{}: {}x{}, {} polygons, {} triangles -> {}",
        args.scene,
        frame.width,
        frame.height,
        frame.polygons.len(),
        peer::triangle_count(&frame),
        args.output
    );
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("triangles: {e}");
            ExitCode::FAILURE
        }
    }
}
