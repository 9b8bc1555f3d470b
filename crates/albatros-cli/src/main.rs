//! `albatros`: the command-line face of the Albatros image generator. A thin layer of
//! argument parsing and file I/O over the `albatros` library, which does the work.
//!
//! Subcommands: `render` (the main job: a scene to an antialiased PNG), `dump` (the
//! geometric processor's frame list as JSON), `info` (database and frame counts),
//! `tables` (the VP's ROM tables as hex files).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

/// `print!` to standard output that returns the write's error rather than panicking
/// as `print!` does: the output piped into a reader that stops early (`albatros
/// info many | head -3`) closes the pipe, and [`main`] then ends quietly.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($arg)*)
    }};
}

/// `println!` that returns the write's error, as [`out!`].
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
    }};
}

mod cells;
mod stats;

use albatros::db::{builtin, load, Scene, Screen};
use albatros::frame::FrameList;
use albatros::gp::{self, Clipper, Database, GpConfig, GpCounters, GpMemory};
use albatros::matrix::Matrix;
use albatros::pipeline::Pipeline;
use albatros::vp::gq::{CellProcessors, MaskLevels};
use albatros::vp::tables::{GqRom, SppMode, SppTable};
use albatros::vp::tac::TacRom;
use albatros::vp::texture::TextureMaps;
use albatros::vp::vb::{Image, Readout, VbMode};
use albatros::vp::{VideoProcessor, VpConfig};

/// The Albatros image generator: a software model of the 1990s «Альбатрос» visual
/// systems.
#[derive(Parser)]
#[command(name = "albatros", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to a PNG (the built-in `default` scene to out.png by default).
    Render(RenderArgs),
    /// Write the geometric processor's frame list as JSON.
    Dump(DumpArgs),
    /// Print counts: models, faces, BSP, and what the GP does with them.
    Info(SceneArgs),
    /// The architecture model: per-unit counters, the estimated time of each stage on
    /// a hardware configuration, the bottleneck; P1 fig. 4 with `--masks all-modes`.
    Stats(stats::StatsArgs),
    /// Time frames: median and spread after warm-up, frames/s, and each stage's time.
    Bench(BenchArgs),
    /// Write the VP's ROM tables (GQ CI/CRI table, SPP tables) as $readmemh hex files.
    Tables {
        /// Output directory.
        #[arg(long, default_value = "tables")]
        out: PathBuf,
    },
}

#[derive(clap::Args)]
struct SceneArgs {
    /// A built-in scene (default, rombm, rhombus, terrain, city, many) or a TOML scene file.
    #[arg(default_value = "default")]
    scene: String,
    /// Screen size WxH (overrides the scene's).
    #[arg(long, value_parser = parse_size)]
    size: Option<Screen>,
    /// Window clipper of the GP.
    #[arg(long, value_enum, default_value_t = ClipperArg::Automaton)]
    clipper: ClipperArg,
}

#[derive(clap::Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output PNG.
    #[arg(short, long, default_value = "out.png")]
    output: PathBuf,
    /// Also write the cell subdivision drawn over the image to this PNG.
    #[arg(long, value_name = "PNG")]
    cells: Option<PathBuf>,
    /// Mask memory levels in use: I, II, III, IV (P1 fig. 4), none, all, or levels
    /// like "5-7" or "3,5,7".
    #[arg(long, default_value = "IV")]
    masks: String,
    /// P1's mask rule only: mark just the cells one polygon covers wholly (by default
    /// Greene's hierarchical coverage also marks cells that several polygons cover
    /// together, and parents of four marked children: less work, the same image).
    #[arg(long)]
    p1_masks: bool,
    /// Turn the 2x2 readout filter F2 off.
    #[arg(long)]
    no_filter: bool,
    /// Display gamma (1 gives linear output).
    #[arg(long, default_value_t = 2.2)]
    gamma: f32,
    /// Video buffer: log (P1's logarithm codes, 8 bits; logN for N bits), float
    /// (the reference), linear or linearN (fixed-point codes, for comparison).
    #[arg(long, default_value = "log", value_parser = parse_vb)]
    vb: VbMode,
    /// Subpixel rule: area-faithful table (P1), point-sample table, or exact edge lines.
    #[arg(long, value_enum, default_value_t = SppArg::Area)]
    spp: SppArg,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Built-in scenes or scene files (default: all built-in scenes).
    scenes: Vec<String>,
    /// Screen size WxH (overrides the scenes').
    #[arg(long, value_parser = parse_size)]
    size: Option<Screen>,
    /// Worker threads (video processors of the matrix).
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// How the matrix's VPs share the screen: strips whose widths follow the work
    /// (the default), or P3's interleave by 64-pixel tiles.
    #[arg(long, value_enum, default_value_t = MatrixArg::Strips)]
    matrix: MatrixArg,
    /// Frames timed after the warm-up.
    #[arg(long, default_value_t = 10)]
    frames: usize,
    /// Frames run before timing.
    #[arg(long, default_value_t = 2)]
    warmup: usize,
    /// JSON lines instead of a table.
    #[arg(long)]
    json: bool,
    /// P1's mask rule only (no hierarchical coverage).
    #[arg(long)]
    p1_masks: bool,
    /// Run the machine's three stages together on the same threads: the GP on
    /// frame n+2 while the VPs render frame n+1 and the VB reads out frame n (P1's
    /// double-buffered frame memory and the VB's double-buffered video memory):
    /// reports the interval between finished frames.
    #[arg(long)]
    pipeline: bool,
}

/// How a matrix's VPs share the screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum MatrixArg {
    /// Vertical strips moved after every frame to even out the work.
    Strips,
    /// P3's fixed interleave by 64-pixel tiles, near-square.
    Tiles,
}

impl MatrixArg {
    fn make(self, screen: Screen, config: VpConfig, threads: usize) -> Result<Matrix, albatros::matrix::MatrixError> {
        match self {
            MatrixArg::Strips => Matrix::for_threads(screen.width, screen.height, config, threads),
            MatrixArg::Tiles => Matrix::tiled_for_threads(screen.width, screen.height, config, threads),
        }
    }
}

#[derive(clap::Args)]
struct DumpArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output file (standard output if absent; required for `triangles`).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// `json`: the frame list; `triangles`: the frame's triangles in clip space in
    /// the SGSC binary format, for a peer renderer (bench/peers/README.md).
    #[arg(long, value_enum, default_value_t = DumpFormat::Json)]
    format: DumpFormat,
}

#[derive(Clone, Copy, ValueEnum)]
enum DumpFormat {
    Json,
    Triangles,
}

#[derive(Clone, Copy, ValueEnum)]
enum ClipperArg {
    Automaton,
    AllBorders,
    Reference,
}

#[derive(Clone, Copy, ValueEnum)]
enum SppArg {
    /// P1's area-faithful table.
    Area,
    /// The table of point samples of the quantized line.
    Sample,
    /// Point samples of the exact edge lines (no table).
    Exact,
}

fn parse_size(s: &str) -> Result<Screen, String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("size '{s}' is not WxH, e.g. 1024x768"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("width '{w}' is not a whole number"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("height '{h}' is not a whole number"))?;
    if w == 0 || h == 0 || w > Screen::MAX_SIDE || h > Screen::MAX_SIDE {
        return Err(format!("size {w}x{h} is out of range: each side must be 1..={}", Screen::MAX_SIDE));
    }
    Ok(Screen { width: w, height: h })
}

fn parse_vb(s: &str) -> Result<VbMode, String> {
    s.parse::<VbMode>().map_err(|e| e.to_string())
}

fn parse_masks(s: &str, root_level: u32) -> Result<MaskLevels> {
    Ok(match s.to_ascii_lowercase().as_str() {
        "i" | "1" if s.eq_ignore_ascii_case("i") => MaskLevels::mode_i(root_level),
        "ii" => MaskLevels::mode_ii(root_level),
        "iii" => MaskLevels::mode_iii(root_level),
        "iv" => MaskLevels::mode_iv(root_level),
        "none" | "off" => MaskLevels::NONE,
        "all" => MaskLevels::ALL,
        other => {
            let mut m = MaskLevels::NONE;
            for part in other.split(',') {
                let (lo, hi) = match part.split_once('-') {
                    Some((a, b)) => (a.trim().parse::<u32>(), b.trim().parse::<u32>()),
                    None => (part.trim().parse::<u32>(), part.trim().parse::<u32>()),
                };
                match (lo, hi) {
                    (Ok(lo), Ok(hi)) if lo >= 1 && lo <= hi && hi <= root_level => m.0 |= MaskLevels::range(lo, hi).0,
                    _ => bail!("--masks '{s}': expected I, II, III, IV, none, all, or levels 1..={root_level} like 5-7 or 3,5,7"),
                }
            }
            m
        }
    })
}

fn load_scene(args: &SceneArgs) -> Result<Scene> {
    let mut scene = match builtin::scene(&args.scene) {
        Some(s) => s,
        None => {
            let path = Path::new(&args.scene);
            if !path.exists() {
                bail!(
                    "'{}' is neither a built-in scene ({}) nor an existing scene file",
                    args.scene,
                    builtin::NAMES.join(", ")
                );
            }
            load::load_scene(path)?
        }
    };
    if let Some(size) = args.size {
        scene.screen = size;
    }
    scene.validate().with_context(|| format!("scene '{}'", args.scene))?;
    Ok(scene)
}

fn gp_config(args: &SceneArgs) -> GpConfig {
    GpConfig {
        clipper: match args.clipper {
            ClipperArg::Automaton => Clipper::Automaton,
            ClipperArg::AllBorders => Clipper::AllBorders,
            ClipperArg::Reference => Clipper::Reference,
        },
        threads: 1,
    }
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let done = match cli.command {
        Command::Render(args) => render(args),
        Command::Dump(args) => dump(args),
        Command::Info(args) => info(args),
        Command::Bench(args) => bench(args),
        Command::Stats(args) => stats::run(args),
        Command::Tables { out } => tables(&out),
    };
    match done {
        // The reader of the output went away (`| head`): what it wanted it has, as
        // with any Unix filter; no error, no message.
        Err(e) if closed_output(&e) => Ok(()),
        done => done,
    }
}

/// Whether `e` is a write to a closed pipe (`EPIPE`: Rust ignores `SIGPIPE`, so the
/// write fails rather than the process being killed).
fn closed_output(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe))
}

fn render(args: RenderArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let screen = scene.screen;
    if !(args.gamma > 0.0 && args.gamma.is_finite()) {
        bail!("--gamma {} must be a positive number", args.gamma);
    }
    let root_level = CellProcessors::root_level_for(screen.width, screen.height);
    let masks = parse_masks(&args.masks, root_level)?;
    let db = Database::new(scene);
    let (frame, _) = gp::frame_of_scene(&db, &gp_config(&args.scene));
    let config = VpConfig {
        masks,
        spp: match args.spp {
            SppArg::Area => SppMode::Area,
            SppArg::Sample => SppMode::Sample,
            SppArg::Exact => SppMode::Exact,
        },
        stats: false,
        hierarchical: !args.p1_masks,
        readout: Readout { filter: !args.no_filter, gamma: args.gamma },
        vb: args.vb,
    };
    let mut vp = VideoProcessor::new(screen.width, screen.height, config);
    // Texture files were resolved against the scene file's folder by the loader.
    vp.set_textures(TextureMaps::from_scene(&db.scene, Path::new(""))?);
    let image = match &args.cells {
        Some(path) => {
            let (image, overlay) = cells::render_with_cells(&mut vp, &frame);
            std::fs::write(path, overlay.encode_png()).with_context(|| format!("writing {}", path.display()))?;
            image
        }
        None => vp.render(&frame),
    };
    std::fs::write(&args.output, image.encode_png()).with_context(|| format!("writing {}", args.output.display()))?;
    outln!(
        "{}: {}x{}, {} polygons -> {}",
        db.scene.name,
        screen.width,
        screen.height,
        frame.polygons.len(),
        args.output.display()
    )?;
    keep_till_exit(db);
    Ok(())
}

/// Leaves the scene database to the process's exit rather than freeing it block by
/// block when a one-scene command returns: `many`'s (a million faces, each with its
/// vertices in a heap block of its own) took ~10 % of `render many` to free. The
/// command ends right after; the system takes the pages back at once.
fn keep_till_exit(db: Database) {
    std::mem::forget(db);
}

fn dump(args: DumpArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let db = Database::new(scene);
    let (frame, _) = gp::frame_of_scene(&db, &gp_config(&args.scene));
    if let DumpFormat::Triangles = args.format {
        let Some(path) = args.output else { bail!("--format triangles writes binary: give the file with -o") };
        let file = std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        let mut w = std::io::BufWriter::new(file);
        albatros::peer::write_triangles(&frame, &mut w).with_context(|| format!("writing {}", path.display()))?;
        std::io::Write::flush(&mut w).with_context(|| format!("writing {}", path.display()))?;
        keep_till_exit(db);
        return Ok(());
    }
    let json = serde_json::to_string_pretty(&albatros::frame::dump::FrameDump::new(&frame))?;
    match args.output {
        Some(path) => std::fs::write(&path, json).with_context(|| format!("writing {}", path.display()))?,
        None => outln!("{json}")?,
    }
    keep_till_exit(db);
    Ok(())
}

fn info(args: SceneArgs) -> Result<()> {
    let scene = load_scene(&args)?;
    let t0 = std::time::Instant::now();
    let db = Database::new(scene);
    let build = t0.elapsed();
    let mut counters = GpCounters::default();
    let s = &db.scene;
    let frame = gp::frame(&db, &s.eye, s.screen, &gp_config(&args), &mut counters);
    let (nodes, splits) = db.bsp_totals();
    outln!("scene        {}", s.name)?;
    outln!("screen       {}x{}", s.screen.width, s.screen.height)?;
    outln!("models       {}", s.models.len())?;
    outln!("instances    {} ({} moving)", s.instances.len(), db.moving_count())?;
    outln!("materials    {}", s.materials.len())?;
    outln!("textures     {}", s.textures.len())?;
    outln!("light points {}", s.lights.len())?;
    outln!("faces        {} (over all instances)", s.instance_face_count())?;
    outln!(
        "bsp          {nodes} nodes, {splits} splits, {} faces in the static tree, depth {}, built in {:.2?}",
        db.bsp.stats.faces,
        db.bsp.stats.depth,
        build
    )?;
    let c = &counters;
    outln!(
        "gp: instances rejected {} of {}; by class 1/2/3: {:?}",
        c.instances_rejected,
        c.instances,
        c.instance_class
    )?;
    outln!(
        "gp: faces in {}, back-facing {}, outside {}, by class 1/2/3 {:?}",
        c.faces_in,
        c.backfacing,
        c.outside,
        c.face_class
    )?;
    outln!(
        "gp: near-clipped {}, window-clipped {}, degenerate {}, light points {}",
        c.near_clipped,
        c.window_clipped,
        c.degenerate,
        c.lights
    )?;
    outln!("frame list   {} polygons", frame.polygons.len())?;
    keep_till_exit(db);
    Ok(())
}

/// One line of `albatros bench`'s output.
struct BenchRow<'a> {
    name: &'a str,
    screen: Screen,
    threads: usize,
    frames: usize,
    /// GP, raster, colour + VB, readout medians (ms); `None` for the pipelined run.
    stages: Option<[f64; 4]>,
}

impl BenchRow<'_> {
    /// Prints the row as a table line or a JSON line; `(median, min, max)` in ms.
    fn print(&self, (median, min, max): (f64, f64, f64), json: bool) -> std::io::Result<()> {
        let size = format!("{}x{}", self.screen.width, self.screen.height);
        if json {
            let mut v = serde_json::json!({
                "scene": self.name, "width": self.screen.width, "height": self.screen.height,
                "threads": self.threads, "pipeline": self.stages.is_none(), "frames": self.frames,
                "median_ms": median, "min_ms": min, "max_ms": max, "fps": 1e3 / median,
                "copies": albatros::isa::copies(),
            });
            if let Some([gp, raster, color, readout]) = self.stages {
                v["stages"] = serde_json::json!({
                    "gp_ms": gp, "raster_ms": raster, "color_vb_ms": color, "readout_ms": readout,
                });
            }
            return outln!("{v}");
        }
        let head = format!(
            "{:<10} {:>10} {:>7} {:>7.2}ms {:>7.2}ms {:>7.2}ms {:>8.1}",
            self.name,
            size,
            self.frames,
            median,
            min,
            max,
            1e3 / median
        );
        match self.stages {
            Some([gp, raster, color, readout]) => {
                outln!("{head} {gp:>7.2}ms {raster:>7.2}ms {color:>7.2}ms   readout {readout:.2}ms")
            }
            None => outln!("{head}   (pipelined: GP of frame n+2, VPs of n+1, readout of n)"),
        }
    }
}

/// Median, minimum and maximum of a sample, in milliseconds.
fn spread(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    let median = if v.len() % 2 == 1 { v[v.len() / 2] } else { (v[v.len() / 2 - 1] + v[v.len() / 2]) * 0.5 };
    (median, v[0], v[v.len() - 1])
}

fn bench(args: BenchArgs) -> Result<()> {
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    if args.threads == 0 || args.threads > 256 {
        bail!("--threads {} must be 1..=256", args.threads);
    }
    let names: Vec<String> = if args.scenes.is_empty() {
        builtin::NAMES.iter().map(|s| s.to_string()).collect()
    } else {
        args.scenes.clone()
    };
    if !args.json {
        // Which instruction-set copies run (`ALBATROS_AVX512=1` asks for the AVX-512
        // ones): figures from two machines or settings compare only alike.
        outln!("VP copies: {} (ALBATROS_AVX512=1: the AVX-512 ones)", albatros::isa::copies())?;
        outln!(
            "{:<10} {:>10} {:>7} {:>9} {:>9} {:>9} {:>8} {:>9} {:>9} {:>9}",
            "scene",
            "size",
            "frames",
            "median",
            "min",
            "max",
            "fps",
            "gp",
            "raster",
            "color+vb",
        )?;
        if args.threads > 1 && !args.pipeline {
            // The matrix's VPs run raster, colour and VB together, and a strip
            // matrix's VPs read out their own strips in the same task.
            outln!("({} threads: color+vb is the VPs' whole time, with strips their readout too)", args.threads)?;
        }
    }
    for name in names {
        let scene_args = SceneArgs { scene: name.clone(), size: args.size, clipper: ClipperArg::Automaton };
        let scene = load_scene(&scene_args)?;
        let screen = scene.screen;
        let db = Database::new(scene);
        let maps = std::sync::Arc::new(TextureMaps::from_scene(&db.scene, Path::new(""))?);
        let vp_cfg = VpConfig { hierarchical: !args.p1_masks, ..VpConfig::default() };
        let mut vp = VideoProcessor::new(screen.width, screen.height, vp_cfg);
        vp.set_textures(maps.clone());
        let mut matrix = args.matrix.make(screen, vp_cfg, args.threads)?;
        matrix.set_textures(maps.clone());
        if args.pipeline {
            let intervals =
                pipelined(&db, screen, vp_cfg, &maps, args.threads, args.matrix, args.warmup + args.frames)?;
            let row = BenchRow { name: &name, screen, threads: args.threads, frames: args.frames, stages: None };
            row.print(spread(intervals[args.warmup..].to_vec()), args.json)?;
            continue;
        }
        let (mut total, mut gp_t, mut raster_t, mut color_t, mut readout_t) = (vec![], vec![], vec![], vec![], vec![]);
        let mut counters = GpCounters::default();
        let gp_cfg = GpConfig { threads: args.threads, ..GpConfig::default() };
        // The GP's memory and the frame list are kept from frame to frame.
        let (mut gp_memory, mut frame) = (GpMemory::default(), FrameList::default());
        let mut stretches: Vec<FrameList> = Vec::new();
        // The displayed image, kept like a display's frame store.
        let mut shown = Image { width: 0, height: 0, pixels: Vec::new() };
        for f in 0..args.warmup + args.frames {
            let t0 = std::time::Instant::now();
            if args.threads == 1 {
                gp::frame_into(&db, &db.scene.eye, screen, &gp_cfg, &mut counters, &mut gp_memory, &mut frame);
            } else {
                // The several GPs on the matrix's threads, their stretches left
                // unjoined for the matrix to walk in order.
                matrix.install(|| {
                    gp::frame_stretches_into(
                        &db,
                        &db.scene.eye,
                        screen,
                        &gp_cfg,
                        &mut counters,
                        &mut gp_memory,
                        &mut stretches,
                    )
                });
            }
            let t1 = std::time::Instant::now();
            // One thread: the raster stages alone, then the whole VP (colour and VB by
            // difference). More: the matrix, all stages together.
            let t2 = if args.threads == 1 {
                vp.raster(&frame);
                std::time::Instant::now()
            } else {
                t1
            };
            // (Untimed: the raster pass's masks put back, as a render leaves them.)
            let t2b = if args.threads == 1 {
                vp.restore_masks();
                std::time::Instant::now()
            } else {
                t2
            };
            let image = if args.threads == 1 {
                vp.render_frame(&frame);
                None
            } else {
                matrix.render_stretches(&stretches);
                Some(())
            };
            let t3 = std::time::Instant::now();
            match image {
                None => vp.vb.read_out_into(&vp.config.readout, &mut shown),
                Some(()) => matrix.read_out_into(&mut shown),
            };
            let t4 = std::time::Instant::now();
            std::hint::black_box(&shown);
            if f >= args.warmup {
                let ms = |a: std::time::Instant, b: std::time::Instant| (b - a).as_secs_f64() * 1e3;
                gp_t.push(ms(t0, t1));
                raster_t.push(ms(t1, t2));
                color_t.push((ms(t2b, t3) - ms(t1, t2)).max(0.0));
                readout_t.push(ms(t3, t4));
                total.push(ms(t0, t1) + ms(t2b, t3) + ms(t3, t4));
            }
        }
        let stages = [spread(gp_t).0, spread(raster_t).0, spread(color_t).0, spread(readout_t).0];
        let row = BenchRow { name: &name, screen, threads: args.threads, frames: args.frames, stages: Some(stages) };
        row.print(spread(total), args.json)?;
    }
    Ok(())
}

/// The three stages as a pipeline ([`Pipeline`]): the GP sets up frame n+2 while the
/// matrix renders frame n+1 and reads out frame n, all on the matrix's `threads`
/// threads. Returns the intervals between steps, in milliseconds.
fn pipelined(
    db: &Database,
    screen: Screen,
    vp_cfg: VpConfig,
    maps: &std::sync::Arc<TextureMaps>,
    threads: usize,
    shape: MatrixArg,
    frames: usize,
) -> Result<Vec<f64>> {
    let mut matrix = shape.make(screen, vp_cfg, threads)?;
    matrix.set_textures(maps.clone());
    let gp_cfg = GpConfig { threads, ..GpConfig::default() };
    let mut pipeline = Pipeline::new(db, screen, gp_cfg, matrix);
    // The displayed image, kept like a display's frame store.
    let mut shown = Image { width: 0, height: 0, pixels: Vec::new() };
    // The first step only sets up a frame, the second renders it too.
    for _ in 0..2 {
        pipeline.step(&db.scene.eye, &mut shown);
    }
    let mut intervals = Vec::with_capacity(frames);
    let mut last = std::time::Instant::now();
    for _ in 0..frames {
        pipeline.step(&db.scene.eye, &mut shown);
        std::hint::black_box(&shown);
        let now = std::time::Instant::now();
        intervals.push((now - last).as_secs_f64() * 1e3);
        last = now;
    }
    Ok(intervals)
}

fn tables(out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let files = [
        ("gq_rom.hex", GqRom::get().to_hex()),
        ("spp_area.hex", SppTable::get(SppMode::Area).to_hex()),
        ("spp_sample.hex", SppTable::get(SppMode::Sample).to_hex()),
        ("tac_fog.hex", TacRom::get().fog_hex()),
        ("tac_log2.hex", TacRom::get().log2_hex()),
    ];
    for (name, text) in files {
        let path = out.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        outln!("{}", path.display())?;
    }
    let readme = out.join("README.txt");
    std::fs::write(&readme, albatros::vp::tables::TABLES_README)?;
    outln!("{}", readme.display())?;
    Ok(())
}
