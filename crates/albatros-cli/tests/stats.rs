//! End-to-end tests of `albatros stats` and `albatros render --cells`: the table, the
//! JSON report, P1 fig. 4's modes, hardware-file errors naming the key, charts and
//! the cell overlay as PNG files.

use std::path::PathBuf;
use std::process::{Command, Output};

fn albatros(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_albatros")).args(args).output().expect("the albatros binary runs")
}

/// A scratch path `name` in a folder of its own, removed (with whatever the test
/// wrote there) when the returned guard is dropped.
fn tmp(name: &str) -> Scratch {
    let dir = tempfile::Builder::new().prefix("albatros-stats-test-").tempdir().expect("a temporary folder");
    let path = dir.path().join(name);
    Scratch { _dir: dir, path }
}

/// A path in a temporary folder that lives as long as this.
struct Scratch {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl std::ops::Deref for Scratch {
    type Target = std::path::Path;

    fn deref(&self) -> &std::path::Path {
        &self.path
    }
}

impl AsRef<std::path::Path> for Scratch {
    fn as_ref(&self) -> &std::path::Path {
        &self.path
    }
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn stats_prints_every_unit_and_the_bottleneck() {
    let o = albatros(&["stats", "rombm"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    for needle in ["level", "SPP", "CC", "VB", "GQ6", "depth complexity", "bottleneck", "R_p", "half-frame"] {
        assert!(out.contains(needle), "stats lacks {needle}: {out}");
    }
}

#[test]
fn all_modes_reruns_p1_fig4() {
    let o = albatros(&["stats", "rombm", "--masks", "all-modes", "--json"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["schema"], "albatros-stats/1");
    let runs = v["runs"].as_array().unwrap();
    let modes: Vec<_> = runs.iter().map(|r| r["mode"].as_str().unwrap()).collect();
    assert_eq!(modes, ["I", "II", "III", "IV"]);
    let ms = |i: usize| runs[i]["timing"]["frame_ms"].as_f64().unwrap();
    assert!(ms(0) >= 2.0 * ms(3), "mode I {} vs IV {}", ms(0), ms(3));
    assert_eq!(runs[0]["timing"]["fits_half_frame"], false);
    assert_eq!(runs[3]["timing"]["fits_half_frame"], true);
}

#[test]
fn a_bad_hardware_file_names_the_file_and_key() {
    let hw = tmp("bad.toml");
    std::fs::write(&hw, "[units]\nspp = 0\n").unwrap();
    let o = albatros(&["stats", "rombm", "--hw", hw.to_str().unwrap()]);
    let err = text(&o.stderr);
    assert!(!o.status.success());
    for needle in ["bad.toml", "line 2", "units.spp"] {
        assert!(err.contains(needle), "message {err:?} lacks {needle:?}");
    }
    assert!(!err.contains("panicked"), "{err}");
    let o = albatros(&["stats", "rombm", "--hw", "no/such/hw.toml"]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("hw.toml"));
}

#[test]
fn the_base_hardware_file_gives_the_default_times() {
    let base = concat!(env!("CARGO_MANIFEST_DIR"), "/../../hw/albatros-base.toml");
    let a = albatros(&["stats", "rombm", "--json"]);
    let b = albatros(&["stats", "rombm", "--json", "--hw", base]);
    assert!(a.status.success() && b.status.success(), "{}", text(&b.stderr));
    assert_eq!(a.stdout, b.stdout);
}

#[test]
fn render_cells_writes_the_overlay() {
    let (image, cells) = (tmp("rombm.png"), tmp("cells.png"));
    let o = albatros(&[
        "render",
        "rombm",
        "--size",
        "128x128",
        "-o",
        image.to_str().unwrap(),
        "--cells",
        cells.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let png = std::fs::read(&cells).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    // Drawn at twice the size: width and height in the IHDR chunk.
    let width = u32::from_be_bytes(png[16..20].try_into().unwrap());
    assert_eq!(width, 256);
}

#[test]
fn plot_writes_the_charts() {
    // The charts need a TrueType font for their labels; skip where there is none.
    let fonts = ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"];
    if std::env::var_os("ALBATROS_FONT").is_none() && !fonts.iter().any(|f| std::path::Path::new(f).exists()) {
        eprintln!("no font: skipping the charts");
        return;
    }
    let dir = tmp("plots");
    let o = albatros(&["stats", "rombm", "--size", "128x128", "--plot", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    for name in ["cells_per_level.png", "stage_times.png", "fig4.png"] {
        let png = std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(&png[1..4], b"PNG", "{name}");
    }
}
