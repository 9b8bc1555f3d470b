//! `albatros stats`: the architecture model on a scene. Renders the scene with the
//! video processor's counters on, under one mask mode or P1 fig. 4's four
//! (`--masks all-modes`), and prints what every unit did, the depth complexity, and
//! the estimated time of each pipeline stage on a hardware configuration (`--hw
//! FILE`, default P1's base variant `hw/albatros-base.toml`): frame time, bottleneck,
//! loads. `--json` prints the library's [`Report`] instead (schema in
//! `docs/architecture-model.md`); `--plot DIR` writes PNG charts ([`plot`]);
//! `--overhead N` measures what counting costs.
//!
//! A thin layer: the work is `albatros::model::{experiment, timing}`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};

use albatros::gp::{self, Database};
use albatros::model::experiment::{self, Experiment, ModeRun, Report};
use albatros::model::timing::HwConfig;
use albatros::vp::gq::{CellProcessors, MaskLevels};
use albatros::vp::texture::TextureMaps;

pub mod plot;

/// The `--masks` value that runs P1 fig. 4's modes I..IV.
pub const ALL_MODES: &str = "all-modes";

/// Arguments of `albatros stats`.
#[derive(clap::Args)]
pub struct StatsArgs {
    #[command(flatten)]
    scene: super::SceneArgs,
    /// Mask memory levels in use: I, II, III, IV (P1 fig. 4), none, all, levels like
    /// "5-7" or "3,5,7", or all-modes (I, II, III and IV, against the half-frame).
    #[arg(long, default_value = "IV")]
    masks: String,
    /// Greene's hierarchical coverage in the mask memories (off: P1's rule).
    #[arg(long)]
    hier_masks: bool,
    /// Hardware configuration, a TOML file (default: P1's base variant,
    /// hw/albatros-base.toml).
    #[arg(long, value_name = "FILE")]
    hw: Option<PathBuf>,
    /// Print the report as JSON (schema in docs/architecture-model.md).
    #[arg(long)]
    json: bool,
    /// Write PNG charts into DIR: cells per level per mode and the stage times of this
    /// scene, and P1 fig. 4 (time per mode) for the built-in scenes.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Measure the counters' cost: N renders with counting off and N with it on,
    /// interleaved; prints the medians and their ratio.
    #[arg(long, value_name = "N")]
    overhead: Option<usize>,
}

/// Reads a hardware file; errors name the file, line, column and key.
pub fn load_hw(path: Option<&Path>) -> Result<HwConfig> {
    let Some(path) = path else { return Ok(HwConfig::default()) };
    let text = std::fs::read_to_string(path).with_context(|| format!("reading hardware file {}", path.display()))?;
    HwConfig::from_toml(&text).map_err(|e| anyhow::anyhow!("hardware file {}: {e}", path.display()))
}

/// The modes to run: P1's four for `all-modes`, else the one `--masks` names.
fn modes_of(masks: &str, root_level: u32) -> Result<Vec<(String, MaskLevels)>> {
    if masks.eq_ignore_ascii_case(ALL_MODES) {
        return Ok(experiment::p1_modes(root_level).iter().map(|(n, m)| (n.to_string(), *m)).collect());
    }
    let levels = super::parse_masks(masks, root_level)?;
    let name = match masks.to_ascii_lowercase().as_str() {
        "i" | "ii" | "iii" | "iv" => masks.to_ascii_uppercase(),
        _ => masks.to_string(),
    };
    Ok(vec![(name, levels)])
}

/// Runs `albatros stats`.
pub fn run(args: StatsArgs) -> Result<()> {
    let hw = load_hw(args.hw.as_deref())?;
    let scene = super::load_scene(&args.scene)?;
    let screen = scene.screen;
    let root_level = CellProcessors::root_level_for(screen.width, screen.height);
    let modes = modes_of(&args.masks, root_level)?;
    let db = Database::new(scene);
    let (frame, gp_counters) = gp::frame_of_scene(&db, &super::gp_config(&args.scene));
    // Texture files were resolved against the scene file's folder by the loader.
    let textures = TextureMaps::from_scene(&db.scene, Path::new(""))?;
    let mut ex = Experiment::new(&frame);
    ex.textures = textures.into();
    ex.hierarchical = args.hier_masks;
    let report = ex.report(&db.scene.name, Some(gp_counters), &modes, &hw);
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        out!("{}", table(&report))?;
    }
    if let Some(n) = args.overhead {
        let (off, on) = overhead(&ex, modes[0].1, n.max(1));
        eprintln!(
            "counters' cost: median of {n} renders {off:.2} ms off, {on:.2} ms on: ratio {:.3} ({:+.1}%)",
            on / off,
            (on / off - 1.0) * 100.0
        );
    }
    if let Some(dir) = &args.plot {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let all = if args.masks.eq_ignore_ascii_case(ALL_MODES) {
            report.clone()
        } else {
            ex.report(&db.scene.name, None, &modes_of(ALL_MODES, root_level)?, &hw)
        };
        for path in plot::write_all(dir, &all, &hw, &super::gp_config(&args.scene))? {
            eprintln!("{}", path.display());
        }
    }
    super::keep_till_exit(db);
    Ok(())
}

/// Median of a sample.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Median render times (ms) of `n` renders with counting off and `n` with it on,
/// alternating on one video processor so that both see the same memory and machine
/// state.
fn overhead(ex: &Experiment, masks: MaskLevels, n: usize) -> (f64, f64) {
    let mut vp = ex.video_processor(masks);
    let mut time = |stats: bool| {
        vp.config.stats = stats;
        let t = Instant::now();
        vp.render_frame(ex.frame);
        t.elapsed().as_secs_f64() * 1e3
    };
    // One warm-up of each.
    time(false);
    time(true);
    let (mut off, mut on) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        off.push(time(false));
        on.push(time(true));
    }
    (median(off), median(on))
}

/// Thousands separated by commas.
fn n(v: u64) -> String {
    let s = v.to_string();
    let mut out = String::with_capacity(s.len() + s.len() / 3);
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Levels as a short list: "1-7", "6-7", "3,5,7", "none".
fn levels_text(levels: &[u32]) -> String {
    if levels.is_empty() {
        return "none".into();
    }
    let contiguous = levels.windows(2).all(|w| w[1] == w[0] + 1);
    match (contiguous, levels.len()) {
        (_, 1) => levels[0].to_string(),
        (true, _) => format!("{}-{}", levels[0], levels[levels.len() - 1]),
        _ => levels.iter().map(u32::to_string).collect::<Vec<_>>().join(","),
    }
}

/// The readable report: one run in full, or a comparison of several.
pub fn table(r: &Report) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let hw = &r.hw;
    let u = &hw.units;
    let _ = writeln!(
        o,
        "{}: {}x{}, root level {}, {} polygons; hw \"{}\": {} GQ, {} SPP, {} CC, {} VB at {} MHz",
        r.scene,
        r.width,
        r.height,
        r.root_level,
        n(r.polygons),
        hw.name,
        u.gq,
        u.spp,
        u.cc,
        u.vb,
        hw.clock_mhz
    );
    if let Some(g) = &r.gp {
        let _ = writeln!(
            o,
            "GP: {} faces in, {} back-facing, {} outside, class 1/2/3 {}/{}/{}, near-clipped {}, window-clipped {}, \
             {} light points, {} polygons out",
            n(g.faces_in),
            n(g.backfacing),
            n(g.outside),
            n(g.face_class[0]),
            n(g.face_class[1]),
            n(g.face_class[2]),
            n(g.near_clipped),
            n(g.window_clipped),
            n(g.lights),
            n(g.polygons_out)
        );
    }
    let _ = writeln!(
        o,
        "depth complexity {:.2} ({} polygon pixels over {} covered pixels); with no masks: {} cells tested, {} \
         fragments, {:.2} ms",
        r.depth_complexity,
        n(r.polygon_pixels),
        n(r.covered_pixels),
        n(r.no_masks.cells_tested),
        n(r.no_masks.fragments),
        r.no_masks.frame_ms
    );
    if let [run] = r.runs.as_slice() {
        one_run(&mut o, r, run);
    } else {
        compare_runs(&mut o, r);
    }
    o
}

/// The full table of one run.
fn one_run(o: &mut String, r: &Report, run: &ModeRun) {
    use std::fmt::Write;
    let c = &run.counters;
    let _ = writeln!(o, "\nmode {} (mask levels {})", run.mode, levels_text(&run.mask_levels));
    let _ = writeln!(
        o,
        "{:>5} {:>5} {:>11} {:>11} {:>11} {:>11} {:>11} {:>11} {:>7} {:>7}",
        "level", "side", "tested", "IN", "CR", "OUT", "masked", "edge tests", "starts", "dropped"
    );
    for (k, l) in c.levels.iter().enumerate() {
        let _ = writeln!(
            o,
            "{:>5} {:>5} {:>11} {:>11} {:>11} {:>11} {:>11} {:>11} {:>7} {:>7}",
            k,
            4u32 << (r.root_level - k as u32),
            n(l.tested),
            n(l.inside),
            n(l.crossed),
            n(l.outside),
            n(l.masked),
            n(l.edge_tests),
            n(l.starts),
            n(l.polygons_masked)
        );
    }
    let s = &c.spp;
    let _ = writeln!(
        o,
        "SPP  {} fragments, {} edge look-ups, {} pixels touched, {} with visible area, {} subpixels set",
        n(s.fragments),
        n(s.edge_lookups),
        n(s.pixels_touched),
        n(s.pixels_visible),
        n(s.subpixels_set)
    );
    let ch = &c.color.pixels_per_channel;
    let _ = writeln!(
        o,
        "CC   pixels per channel {} / {} / {} / {}, {} textured",
        n(ch[0]),
        n(ch[1]),
        n(ch[2]),
        n(ch[3]),
        n(c.color.textured)
    );
    let _ = writeln!(
        o,
        "VB   {} first writes, {} read-modify-writes",
        n(c.color.first_writes),
        n(c.color.read_modify_writes)
    );
    let d = &run.derived;
    let _ = writeln!(
        o,
        "     {:.3} visible fragments and {:.2} SPP pixels per covered pixel; masks dropped {} cells and {} \
         polygons whole, removing {:.1}% of the cell tests and {:.1}% of the fragments",
        d.visible_fragments_per_covered_pixel,
        d.spp_pixels_per_covered_pixel,
        n(d.cells_masked),
        n(d.polygons_masked),
        100.0 * run.removed_by_masks.cells_tested_share,
        100.0 * run.removed_by_masks.fragments_share
    );
    let t = &run.timing;
    let _ = writeln!(o, "\n{:<6} {:>7} {:>14} {:>9} {:>6}", "stage", "levels", "cycles", "ms", "load");
    for st in &t.stages {
        let levels = if st.levels.is_empty() { "-".to_string() } else { levels_text(&st.levels) };
        let mark = if st.name == t.bottleneck { "  <- bottleneck" } else { "" };
        let _ = writeln!(
            o,
            "{:<6} {:>7} {:>14} {:>9.3} {:>6.2}{mark}",
            st.name,
            levels,
            n(st.cycles.round() as u64),
            st.ms,
            st.load
        );
    }
    let _ = writeln!(
        o,
        "frame time {:.2} ms (bottleneck {}), mean load R_p {:.2}, all stages in turn {:.2} ms; half-frame {} ms: {}",
        t.frame_ms,
        t.bottleneck,
        t.mean_load,
        t.sequential_ms,
        t.half_frame_ms,
        if t.fits_half_frame { "fits" } else { "over" }
    );
}

/// Several runs side by side (P1 fig. 4's experiment).
fn compare_runs(o: &mut String, r: &Report) {
    use std::fmt::Write;
    let runs = &r.runs;
    let budget = runs.first().map_or(0.0, |x| x.timing.half_frame_ms);
    let _ = writeln!(o, "\nP1 fig. 4: {} under the mask modes, against the {budget} ms half-frame", r.scene);
    let _ = writeln!(
        o,
        "{:<5} {:>7} {:>13} {:>11} {:>9} {:>10} {:>5} {:>10}",
        "mode", "levels", "cells tested", "fragments", "ms", "bottleneck", "R_p", "half-frame"
    );
    for run in runs {
        let t = &run.timing;
        let _ = writeln!(
            o,
            "{:<5} {:>7} {:>13} {:>11} {:>9.2} {:>10} {:>5.2} {:>10}",
            run.mode,
            levels_text(&run.mask_levels),
            n(run.counters.cells_tested()),
            n(run.counters.spp.fragments),
            t.frame_ms,
            t.bottleneck,
            t.mean_load,
            if t.fits_half_frame { "fits" } else { "over" }
        );
    }
    let header: String = runs.iter().map(|x| format!(" {:>11}", x.mode)).collect();
    let _ = writeln!(o, "\ncells tested per level\n{:>5} {:>5}{header}", "level", "side");
    for k in 0..=r.root_level as usize {
        let cells: String = runs.iter().map(|x| format!(" {:>11}", n(x.counters.levels[k].tested))).collect();
        let _ = writeln!(o, "{:>5} {:>5}{cells}", k, 4u32 << (r.root_level - k as u32));
    }
    let _ = writeln!(o, "\nstage times, ms\n{:<11}{header}", "stage");
    if let Some(first) = runs.first() {
        for (i, st) in first.timing.stages.iter().enumerate() {
            let times: String = runs.iter().map(|x| format!(" {:>11.3}", x.timing.stages[i].ms)).collect();
            let _ = writeln!(o, "{:<11}{times}", st.name);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_levels_print_plainly() {
        assert_eq!(n(0), "0");
        assert_eq!(n(999), "999");
        assert_eq!(n(1000), "1,000");
        assert_eq!(n(4_194_304), "4,194,304");
        assert_eq!(levels_text(&[1, 2, 3, 4, 5, 6, 7]), "1-7");
        assert_eq!(levels_text(&[7]), "7");
        assert_eq!(levels_text(&[3, 5, 7]), "3,5,7");
        assert_eq!(levels_text(&[]), "none");
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
    }

    #[test]
    fn all_modes_are_p1s_four() {
        let m = modes_of("all-modes", 7).unwrap();
        let names: Vec<_> = m.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["I", "II", "III", "IV"]);
        assert_eq!(m[0].1, MaskLevels::mode_i(7));
        assert_eq!(modes_of("iv", 7).unwrap()[0].0, "IV");
        assert!(modes_of("9-12", 7).is_err());
    }

    #[test]
    fn the_default_hw_is_p1s_base_variant() {
        let hw = load_hw(None).unwrap();
        assert_eq!((hw.units.gq, hw.units.spp, hw.units.cc, hw.units.vb), (7, 16, 4, 4));
        assert_eq!(hw.half_frame_ms, 20.0);
    }
}
