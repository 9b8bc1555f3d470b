//! The architecture model: counter identities on every built-in scene, P1 fig. 4's
//! finding on `rombm`, the timing model's arithmetic, hardware-file errors, the GQ's
//! cell recorder, and the pinned JSON schema of `albatros stats --json`.

use std::collections::BTreeSet;

use albatros::db::{builtin, Screen};
use albatros::frame::FrameList;
use albatros::gp::{self, Database, GpConfig};
use albatros::model::experiment::{self, Experiment};
use albatros::model::stats::{ColorCounters, Counters, LevelCounters, SppCounters};
use albatros::model::timing::{HwConfig, HwError, Timing, Unit, BASE_TOML};
use albatros::vp::gq::{CellKind, MaskLevels};

/// The frame of a built-in scene (`many` at a reduced size, as in the VP tests).
fn frame(name: &str) -> FrameList {
    let mut scene = builtin::scene(name).unwrap();
    if name == "many" {
        scene.screen = Screen { width: 480, height: 270 };
    }
    let db = Database::new(scene);
    gp::frame_of_scene(&db, &GpConfig::default()).0
}

/// Modes none, I, II, III, IV for a root level, in order of more levels masked.
fn modes(root_level: u32) -> Vec<(&'static str, MaskLevels)> {
    let mut m = vec![("none", MaskLevels::NONE)];
    m.extend(experiment::p1_modes(root_level));
    m
}

#[test]
fn counter_identities_hold_on_every_builtin_scene() {
    for name in builtin::NAMES {
        let frame = frame(name);
        let ex = Experiment::new(&frame);
        let l = ex.root_level();
        // The ownership probe: which polygon owns each subpixel (u32::MAX: none).
        let owner = ex.video_processor(MaskLevels::NONE).ownership(&frame);
        let mut covered_pixels = 0u64;
        let mut covered_subpixels = 0u64;
        for pixel in owner.chunks_exact(16) {
            let n = pixel.iter().filter(|&&o| o != u32::MAX).count() as u64;
            covered_subpixels += n;
            covered_pixels += u64::from(n > 0);
        }
        let mut previous: Option<Counters> = None;
        for (mode, masks) in modes(l) {
            let c = ex.counters(masks);
            let broken = c.violations();
            assert!(broken.is_empty(), "{name} mode {mode}: {broken:#?}");
            // Fragments' visible areas summed = the covered area of the screen; each
            // covered pixel is one first write; no subpixel is set twice.
            assert_eq!(c.spp.subpixels_set, covered_subpixels, "{name} mode {mode}: subpixels");
            assert_eq!(c.covered_pixels(), covered_pixels, "{name} mode {mode}: covered pixels");
            assert!(c.spp.subpixels_set <= 16 * c.covered_pixels());
            if let Some(p) = &previous {
                // Masks change work, never the image: what is visible is the same...
                assert_eq!(c.spp.pixels_visible, p.spp.pixels_visible, "{name} mode {mode}");
                assert_eq!(c.color, p.color, "{name} mode {mode}: CC/VB counters");
                // ...and more masked levels never add work, level by level.
                assert!(c.spp.fragments <= p.spp.fragments, "{name} mode {mode}: fragments");
                for k in 0..=l as usize {
                    assert!(
                        c.levels[k].tested <= p.levels[k].tested,
                        "{name} mode {mode}: level {k} tests {} > {}",
                        c.levels[k].tested,
                        p.levels[k].tested
                    );
                }
            }
            previous = Some(c);
        }
    }
}

#[test]
fn rombm_reproduces_p1_fig4_in_kind() {
    let frame = frame("rombm");
    let ex = Experiment::new(&frame);
    let l = ex.root_level();
    assert_eq!(l, 7, "rombm is P1's 512 x 512 screen");
    let hw = HwConfig::default();
    let modes: Vec<(String, MaskLevels)> = experiment::p1_modes(l).iter().map(|(n, m)| (n.to_string(), *m)).collect();
    let report = ex.report("rombm", None, &modes, &hw);
    for run in &report.runs {
        let t = &run.timing;
        println!(
            "rombm mode {:>3}: {:6.2} ms (bottleneck {}, R_p {:.2}); cells tested per level {:?}",
            run.mode,
            t.frame_ms,
            t.bottleneck,
            t.mean_load,
            run.counters.levels.iter().map(|c| c.tested).collect::<Vec<_>>()
        );
    }
    let (i, iv) = (&report.runs[0], &report.runs[3]);
    // P1: over 25 ms with the last level's mask only, a little over 12 ms with all.
    assert!(i.timing.frame_ms >= 2.0 * iv.timing.frame_ms, "I {} vs IV {}", i.timing.frame_ms, iv.timing.frame_ms);
    assert!(!i.timing.fits_half_frame && iv.timing.fits_half_frame);
    // Each mode is at most as slow as the one before it.
    for w in report.runs.windows(2) {
        assert!(w[1].timing.frame_ms <= w[0].timing.frame_ms, "{} slower than {}", w[1].mode, w[0].mode);
    }
    // Why: in mode I every rhombus is split down to the last GQ, which the cells of
    // levels 6 and 7 then swamp; with all levels the stack is cut at the top.
    assert!(i.timing.bottleneck.starts_with("GQ"), "mode I bottleneck {}", i.timing.bottleneck);
    let tested = |r: &experiment::ModeRun, k: usize| r.counters.levels[k].tested;
    for k in 4..=l as usize {
        assert!(tested(i, k) >= 2 * tested(iv, k), "level {k}: I {} vs IV {}", tested(i, k), tested(iv, k));
    }
    // The last GQ splits a quarter of level L's tested cells: 86,473 against 6,335.
    assert!(tested(i, l as usize) >= 8 * tested(iv, l as usize));
    // The same image: the same visible fragments, the same fragments at the SPPs
    // (mode I's last-level mask drops the hidden cells before the SPPs).
    assert_eq!(i.counters.spp, iv.counters.spp);
    assert!(iv.counters.levels.iter().map(|c| c.masked).sum::<u64>() > 0);
    // Deep: 22 rhombi each over half the screen.
    assert!(report.depth_complexity > 11.0, "depth complexity {}", report.depth_complexity);
    assert!(report.runs.iter().all(|r| r.derived.visible_fragments_per_covered_pixel < 1.1));
    assert!(iv.removed_by_masks.fragments_share > 0.9);
}

#[test]
fn upper_level_masks_never_slow_a_scene_down() {
    // P1 fig. 4: turning on the upper levels' masks only ever shortens the time.
    for name in ["default", "city"] {
        let frame = frame(name);
        let ex = Experiment::new(&frame);
        let l = ex.root_level();
        let hw = HwConfig::default();
        let i = Timing::estimate(&hw, &ex.counters(MaskLevels::mode_i(l)));
        let iv = Timing::estimate(&hw, &ex.counters(MaskLevels::mode_iv(l)));
        println!(
            "{name}: mode I {:.2} ms ({}), mode IV {:.2} ms ({})",
            i.frame_ms, i.bottleneck, iv.frame_ms, iv.bottleneck
        );
        assert!(iv.frame_ms <= i.frame_ms);
    }
}

/// Counters with only the given CC channel loads and VB writes.
fn color_only(channels: [u64; 4], first: u64, rmw: u64) -> Counters {
    let mut c = Counters::new(7);
    c.color = ColorCounters { pixels_per_channel: channels, textured: 0, first_writes: first, read_modify_writes: rmw };
    c
}

#[test]
fn timing_follows_the_model() {
    let hw = HwConfig::default();
    // CC: the busiest of the 4 channels; VB: writes spread over 4 modules.
    let t = Timing::estimate(&hw, &color_only([100, 400, 100, 100], 400, 300));
    let cc = t.stage("CC").unwrap();
    assert_eq!(cc.unit, Unit::Cc);
    assert_eq!(cc.cycles, 400.0);
    let vb = t.stage("VB").unwrap();
    assert_eq!(vb.cycles, (400.0 * 1.0 + 300.0 * 2.0) / 4.0);
    assert_eq!(t.bottleneck, "CC");
    assert_eq!(t.frame_ms, 400.0 / (5.5 * 1000.0));
    assert_eq!(vb.load, 250.0 / 400.0);
    // R_p (P3 eq. 10): the mean stage time over the slowest, over all 10 stages.
    assert!((t.mean_load - (400.0 + 250.0) / 10.0 / 400.0).abs() < 1e-12);
    assert_eq!(t.stages.len(), 7 + 3);
    assert!((t.sequential_ms - 650.0 / 5500.0).abs() < 1e-12);

    // GQ of level k: tests and outputs of the children, plus edge look-ups.
    let mut c = Counters::new(7);
    c.levels[0].starts = 1;
    c.levels[1] = LevelCounters { tested: 4, inside: 1, crossed: 2, outside: 1, edge_tests: 3, ..Default::default() };
    let t = Timing::estimate(&hw, &c);
    assert_eq!(t.stage("GQ0").unwrap().cycles, 2.0 * (1.0 + 1.0) + 3.0 + 1.0 * 3.0);
    assert_eq!(t.stage("GQ0").unwrap().levels, vec![0]);
    // SPP: per fragment plus per edge (16 look-ups per edge, one per SPP).
    c.spp = SppCounters { fragments: 10, edge_lookups: 16 * 5, ..Default::default() };
    let t = Timing::estimate(&hw, &c);
    assert_eq!(t.stage("SPP").unwrap().cycles, 2.0 * 10.0 + 5.0);
    // Four SPPs take four passes per fragment.
    let mut four = hw.clone();
    four.units.spp = 4;
    assert_eq!(Timing::estimate(&four, &c).stage("SPP").unwrap().cycles, 4.0 * 25.0);
    // Twice the clock, half the time.
    let mut fast = hw.clone();
    fast.clock_mhz *= 2.0;
    assert_eq!(Timing::estimate(&fast, &c).frame_ms, t.frame_ms / 2.0);
}

#[test]
fn a_larger_root_than_gqs_folds_the_top_levels_into_gq0() {
    let frame = frame("default"); // 1024 x 768: root level 8 on 7 GQs
    let ex = Experiment::new(&frame);
    assert_eq!(ex.root_level(), 8);
    let c = ex.counters(MaskLevels::mode_iv(8));
    let t = Timing::estimate(&HwConfig::default(), &c);
    let gq0 = t.stage("GQ0").unwrap();
    assert_eq!(gq0.levels, vec![0, 1]);
    assert_eq!(t.stage("GQ6").unwrap().levels, vec![7]);
    let gq_total: f64 = t.stages.iter().filter(|s| s.unit == Unit::Gq).map(|s| s.cycles).sum();
    // Every level's work is counted once whatever the mapping.
    let mut one_per_level = HwConfig::default();
    one_per_level.units.gq = 8;
    let t8 = Timing::estimate(&one_per_level, &c);
    let gq8: f64 = t8.stages.iter().filter(|s| s.unit == Unit::Gq).map(|s| s.cycles).sum();
    assert_eq!(gq_total, gq8);
}

#[test]
fn the_base_file_is_the_default_configuration() {
    assert_eq!(HwConfig::from_toml(BASE_TOML).unwrap(), HwConfig::default());
    // Every key may be left out.
    assert_eq!(HwConfig::from_toml("").unwrap(), HwConfig::default());
    let hw = HwConfig::from_toml("clock_mhz = 16\n[units]\nspp = 4\n").unwrap();
    assert_eq!((hw.clock_mhz, hw.units.spp, hw.units.gq), (16.0, 4, 7));
}

#[test]
fn bad_hardware_files_name_the_key() {
    let cases: &[(&str, &[&str])] = &[
        ("[units]\ngqq = 7\n", &["units.gqq", "line 2", "unknown field"]),
        ("[units]\ngq = \"seven\"\n", &["units.gq", "line 2"]),
        ("[units]\ngq = 0\n", &["units.gq", "line 2", "1..=12"]),
        ("[units]\nspp = 32\n", &["units.spp", "1..=16"]),
        ("[units]\ncc = -1\n", &["units.cc", "line 2"]),
        ("[cycles]\nspp_edge = -1.0\n", &["cycles.spp_edge", ">= 0"]),
        ("[cycles]\ncc_pixel = nan\n", &["cycles.cc_pixel", "finite"]),
        ("clock_mhz = 0\n", &["clock_mhz", "> 0"]),
        ("half_frame_ms = inf\n", &["half_frame_ms", "finite"]),
        ("speed = 3\n", &["speed", "unknown field"]),
        ("[clock]\nmhz = 8\n", &["clock", "unknown field"]),
        ("[units\ngq = 7\n", &["line 1"]),
    ];
    for (text, needles) in cases {
        let err = HwConfig::from_toml(text).expect_err(text);
        let msg = err.to_string();
        for needle in *needles {
            assert!(msg.contains(needle), "{text:?}: message {msg:?} lacks {needle:?}");
        }
        assert!(matches!(err, HwError::Syntax { .. } | HwError::Invalid { .. }));
    }
}

#[test]
fn the_cell_recorder_agrees_with_the_counters() {
    let frame = frame("rombm");
    let ex = Experiment::new(&frame);
    let l = ex.root_level();
    for masks in [MaskLevels::mode_i(l), MaskLevels::mode_iv(l)] {
        let mut vp = ex.video_processor(masks);
        vp.gq.recorder = Some(Vec::new());
        vp.render_frame(&frame);
        let cells = vp.gq.recorder.take().unwrap();
        let mut seen = vec![LevelCounters::default(); l as usize + 1];
        for (cell, kind) in &cells {
            let s = &mut seen[cell.level as usize];
            match kind {
                CellKind::Inside => s.inside += 1,
                CellKind::Crossed => s.crossed += 1,
                CellKind::Outside => s.outside += 1,
                CellKind::Masked => s.masked += 1,
                CellKind::PolygonMasked => s.polygons_masked += 1,
                CellKind::Start => s.starts += 1,
            }
            if !matches!(kind, CellKind::PolygonMasked | CellKind::Start) {
                s.tested += 1;
            }
        }
        for (k, (s, c)) in seen.iter().zip(&vp.counters.levels).enumerate() {
            let want = (c.tested, c.inside, c.crossed, c.outside, c.masked, c.polygons_masked, c.starts);
            let got =
                (s.tested, s.inside, s.crossed, s.outside, s.masked, s.polygons_masked, s.starts + s.polygons_masked);
            assert_eq!(got, want, "level {k}");
        }
    }
    // Counting off: nothing is recorded.
    let mut vp = ex.video_processor(MaskLevels::mode_iv(l));
    vp.config.stats = false;
    vp.gq.recorder = Some(Vec::new());
    vp.render_frame(&frame);
    assert_eq!(vp.gq.recorder.as_ref().map(Vec::len), Some(0));
}

/// Every key path of a JSON value: objects' keys joined by `.`, arrays as `[]`
/// (their elements' keys merged).
fn key_paths(v: &serde_json::Value, prefix: &str, out: &mut BTreeSet<String>) {
    match v {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                let path = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                out.insert(path.clone());
                key_paths(v, &path, out);
            }
        }
        serde_json::Value::Array(items) => {
            for item in items {
                key_paths(item, &format!("{prefix}[]"), out);
            }
        }
        _ => {}
    }
}

/// The documented schema of `albatros stats --json` (docs/architecture-model.md).
/// Changing it is a schema change: update the docs and, for a rename or removal,
/// `experiment::SCHEMA`'s version.
const SCHEMA_KEYS: &[&str] = &[
    "covered_pixels",
    "depth_complexity",
    "gp",
    "gp.backfacing",
    "gp.degenerate",
    "gp.face_class",
    "gp.faces_in",
    "gp.instance_class",
    "gp.instances",
    "gp.instances_rejected",
    "gp.lights",
    "gp.near_clipped",
    "gp.outside",
    "gp.polygons_out",
    "gp.window_clipped",
    "height",
    "hw",
    "hw.clock_mhz",
    "hw.cycles",
    "hw.cycles.cc_pixel",
    "hw.cycles.gq_cell_out",
    "hw.cycles.gq_cell",
    "hw.cycles.gq_edge_test",
    "hw.cycles.spp_edge",
    "hw.cycles.spp_fragment",
    "hw.cycles.vb_read_modify_write",
    "hw.cycles.vb_write",
    "hw.half_frame_ms",
    "hw.name",
    "hw.units",
    "hw.units.cc",
    "hw.units.gq",
    "hw.units.spp",
    "hw.units.vb",
    "no_masks",
    "no_masks.cells_tested",
    "no_masks.fragments",
    "no_masks.frame_ms",
    "no_masks.pixels_touched",
    "polygon_pixels",
    "polygons",
    "root_level",
    "runs",
    "runs[].counters",
    "runs[].counters.color",
    "runs[].counters.color.first_writes",
    "runs[].counters.color.pixels_per_channel",
    "runs[].counters.color.read_modify_writes",
    "runs[].counters.color.textured",
    "runs[].counters.levels",
    "runs[].counters.levels[].crossed",
    "runs[].counters.levels[].edge_tests",
    "runs[].counters.levels[].inside",
    "runs[].counters.levels[].masked",
    "runs[].counters.levels[].outside",
    "runs[].counters.levels[].polygons_masked",
    "runs[].counters.levels[].starts",
    "runs[].counters.levels[].tested",
    "runs[].counters.polygons",
    "runs[].counters.root_level",
    "runs[].counters.spp",
    "runs[].counters.spp.edge_lookups",
    "runs[].counters.spp.fragments",
    "runs[].counters.spp.pixels_touched",
    "runs[].counters.spp.pixels_visible",
    "runs[].counters.spp.subpixels_set",
    "runs[].derived",
    "runs[].derived.cells_masked",
    "runs[].derived.cells_tested",
    "runs[].derived.covered_pixels",
    "runs[].derived.masked_share_of_candidates",
    "runs[].derived.masked_share_per_level",
    "runs[].derived.polygons_masked",
    "runs[].derived.spp_pixels_per_covered_pixel",
    "runs[].derived.visible_area_pixels",
    "runs[].derived.visible_fragments_per_covered_pixel",
    "runs[].mask_levels",
    "runs[].mode",
    "runs[].removed_by_masks",
    "runs[].removed_by_masks.cells_tested_share",
    "runs[].removed_by_masks.fragments_share",
    "runs[].timing",
    "runs[].timing.bottleneck",
    "runs[].timing.fits_half_frame",
    "runs[].timing.frame_ms",
    "runs[].timing.half_frame_ms",
    "runs[].timing.mean_load",
    "runs[].timing.sequential_ms",
    "runs[].timing.stages",
    "runs[].timing.stages[].cycles",
    "runs[].timing.stages[].levels",
    "runs[].timing.stages[].load",
    "runs[].timing.stages[].ms",
    "runs[].timing.stages[].name",
    "runs[].timing.stages[].unit",
    "schema",
    "scene",
    "width",
];

#[test]
fn the_stats_json_schema_is_pinned() {
    let scene = builtin::scene("rombm").unwrap();
    let db = Database::new(scene);
    let (frame, gp) = gp::frame_of_scene(&db, &GpConfig::default());
    let ex = Experiment::new(&frame);
    let report = ex.report("rombm", Some(gp), &[("IV".into(), MaskLevels::mode_iv(7))], &HwConfig::default());
    let json = serde_json::to_value(&report).unwrap();
    let mut keys = BTreeSet::new();
    key_paths(&json, "", &mut keys);
    let want: BTreeSet<String> = SCHEMA_KEYS.iter().map(|s| s.to_string()).collect();
    let extra: Vec<_> = keys.difference(&want).collect();
    let missing: Vec<_> = want.difference(&keys).collect();
    assert!(extra.is_empty() && missing.is_empty(), "schema changed: new keys {extra:?}, gone {missing:?}");
    assert_eq!(json["schema"], experiment::SCHEMA);
    assert_eq!(json["runs"][0]["mask_levels"], serde_json::json!([1, 2, 3, 4, 5, 6, 7]));
    let units: Vec<_> =
        json["runs"][0]["timing"]["stages"].as_array().unwrap().iter().map(|s| s["unit"].clone()).collect();
    assert_eq!(units.iter().filter(|u| *u == "gq").count(), 7);
    assert_eq!(&units[7..], &[serde_json::json!("spp"), serde_json::json!("cc"), serde_json::json!("vb")]);
}

#[test]
fn cell_counting_helpers_agree_with_pixel_by_pixel_counting() {
    use albatros::model::stats::{visible_pixels, CHANNEL_PIXELS};
    use albatros::vp::cc::channel;
    // The channel masks are the CC's dealing.
    for (ch, bits) in CHANNEL_PIXELS.iter().enumerate() {
        let want: u16 = (0..16).filter(|&i| channel(i) == ch).map(|i| 1u16 << i).sum();
        assert_eq!(*bits, want, "channel {ch}");
    }
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..1000 {
        let mut sets = [0u16; 16];
        for s in &mut sets {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            *s = if seed & 3 == 0 { 0 } else { (seed >> 8) as u16 };
        }
        let (mut a, mut b) = (Counters::new(1), Counters::new(1));
        a.count_cc_cell(visible_pixels(&sets), true);
        a.count_spp_fragment(&sets, 12);
        for (i, &s) in sets.iter().enumerate() {
            if s != 0 {
                b.color.pixels_per_channel[channel(i)] += 1;
                b.color.textured += 1;
                b.spp.pixels_visible += 1;
                b.spp.subpixels_set += u64::from(s.count_ones());
            }
        }
        b.spp.fragments = 1;
        b.spp.pixels_touched = 12;
        assert_eq!(a, b);
    }
}

#[test]
fn depth_complexity_costs_no_work_with_the_rendering_masks() {
    // Issue 6: `rombm` (22 layers) may cost at most 1.3x `rhombus` (its top layer
    // alone) on the same screen. In work, not time: the cells the GQ tests, the
    // fragments the SPPs take, the pixels the CC colours, with the masks that
    // rendering uses (all levels, Greene's hierarchical coverage).
    let screen = Screen { width: 1920, height: 1080 };
    let counters = |name: &str| {
        let mut scene = builtin::scene(name).unwrap();
        scene.screen = screen;
        let frame = gp::frame_of_scene(&Database::new(scene), &GpConfig::default()).0;
        let config = albatros::vp::VpConfig { stats: true, ..albatros::vp::VpConfig::default() };
        let mut vp = albatros::vp::VideoProcessor::new(screen.width, screen.height, config);
        vp.render_frame(&frame);
        vp.counters.clone()
    };
    let (many, one) = (counters("rombm"), counters("rhombus"));
    let colored = |c: &Counters| c.color.pixels_per_channel.iter().sum::<u64>();
    let ratios = [
        ("cells tested", many.cells_tested() as f64 / one.cells_tested() as f64),
        ("SPP fragments", many.spp.fragments as f64 / one.spp.fragments as f64),
        ("CC pixels", colored(&many) as f64 / colored(&one) as f64),
    ];
    println!("rombm / rhombus at 1920x1080: {ratios:?}");
    for (what, r) in ratios {
        assert!(r <= 1.3, "{what}: rombm does {r:.2}x the work of one rhombus");
    }
    // And without the masks the depth complexity does cost: the measure can fail.
    let config = albatros::vp::VpConfig { stats: true, masks: MaskLevels::NONE, ..albatros::vp::VpConfig::default() };
    let mut scene = builtin::scene("rombm").unwrap();
    scene.screen = screen;
    let frame = gp::frame_of_scene(&Database::new(scene), &GpConfig::default()).0;
    let mut vp = albatros::vp::VideoProcessor::new(screen.width, screen.height, config);
    vp.render_frame(&frame);
    assert!(vp.counters.spp.fragments as f64 > 5.0 * one.spp.fragments as f64);
}
