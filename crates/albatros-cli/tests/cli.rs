//! End-to-end tests of the `albatros` command: the README's main job works, and bad
//! input gets a clear error and a non-zero exit, never a panic.

use std::path::PathBuf;
use std::process::{Command, Output};

fn albatros(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_albatros")).args(args).output().expect("the albatros binary runs")
}

/// A scratch file in a folder of this test run, removed when the test binary exits
/// (each test removes what it made at its end).
/// A scratch path `name` in a folder of its own, removed (with whatever the test
/// wrote there) when the returned guard is dropped.
fn tmp(name: &str) -> Scratch {
    let dir = tempfile::Builder::new().prefix("albatros-cli-test-").tempdir().expect("a temporary folder");
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

/// Removes a scratch file or folder made by [`tmp`].
fn cleanup(path: &std::path::Path) {
    let _ = std::fs::remove_dir_all(path).or_else(|_| std::fs::remove_file(path));
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A failure: non-zero exit, a message containing `needle`, no panic.
fn fails_with(args: &[&str], needle: &str) {
    let o = albatros(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(err.contains(needle), "{args:?}: message {err:?} should mention {needle:?}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
}

#[test]
fn render_writes_a_png_of_the_default_scene() {
    let out = tmp("default.png");
    let o = albatros(&["render", "--size", "320x240", "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    cleanup(&out);
}

/// `bench --json` reports which instruction-set copies ran: the AVX2 ones where the
/// processor has AVX2, the AVX-512 ones when `ALBATROS_AVX512=1` asks for them on a
/// processor with AVX-512F.
#[test]
fn bench_reports_the_copies_it_ran() {
    let copies = |asked: bool| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_albatros"));
        command.args(["bench", "rhombus", "--size", "64x64", "--frames", "1", "--warmup", "0", "--json"]);
        command.env_remove("ALBATROS_AVX512");
        if asked {
            command.env("ALBATROS_AVX512", "1");
        }
        let o = command.output().expect("the albatros binary runs");
        assert!(o.status.success(), "{}", stderr(&o));
        let line: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
        line["copies"].as_str().expect("a copies field").to_string()
    };
    #[cfg(target_arch = "x86_64")]
    let (avx2, avx512) = (std::is_x86_feature_detected!("avx2"), std::is_x86_feature_detected!("avx512f"));
    #[cfg(not(target_arch = "x86_64"))]
    let (avx2, avx512) = (false, false);
    let plain = if avx2 { "avx2" } else { "portable" };
    assert_eq!(copies(false), plain);
    assert_eq!(copies(true), if avx512 { "avx512" } else { plain });
}

/// Output into a pipe whose reader has gone (`albatros info many | head -3`): each
/// command that writes to standard output ends quietly and successfully, where
/// `println!` had panicked ("failed printing to stdout: Broken pipe").
#[test]
fn a_closed_output_pipe_ends_the_command_quietly() {
    let commands: [&[&str]; 5] = [
        &["info", "rhombus"],
        &["dump", "rhombus", "--size", "64x64"],
        &["stats", "rhombus", "--size", "64x64"],
        &["stats", "rhombus", "--size", "64x64", "--json"],
        &["bench", "rhombus", "--size", "64x64", "--frames", "1", "--warmup", "0"],
    ];
    for args in commands {
        // The reader closed before the command starts: its first write fails.
        let (reader, writer) = std::io::pipe().expect("a pipe");
        drop(reader);
        let o = Command::new(env!("CARGO_BIN_EXE_albatros"))
            .args(args)
            .stdout(writer)
            .output()
            .expect("the albatros binary runs");
        let err = stderr(&o);
        assert!(o.status.success(), "{args:?} into a closed pipe: {:?}, {err}", o.status);
        assert!(err.is_empty(), "{args:?} into a closed pipe wrote {err:?}");
    }
}

#[test]
fn dump_and_info_work_on_the_default_scene() {
    let out = tmp("dump.json");
    let o = albatros(&["dump", "default", "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert!(v["polygons"].as_array().unwrap().len() > 100);
    let o = albatros(&["info", "default"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    for key in ["models", "faces", "bsp", "frame list"] {
        assert!(text.contains(key), "info lacks {key}: {text}");
    }
    cleanup(&out);
}

#[test]
fn tables_writes_hex_files() {
    let dir = tmp("tables");
    let o = albatros(&["tables", "--out", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rom = std::fs::read_to_string(dir.join("gq_rom.hex")).unwrap();
    assert_eq!(rom.lines().count(), 256);
    assert!(rom.lines().all(|l| l.len() == 2 && u8::from_str_radix(l, 16).is_ok()));
    let spp = std::fs::read_to_string(dir.join("spp_area.hex")).unwrap();
    assert_eq!(spp.lines().count(), 2500);
    // The TAC's ROMs: f32 bit patterns, exp(-k/256) and log2(1 + k/256).
    let word = |l: &str| f32::from_bits(u32::from_str_radix(l, 16).unwrap());
    let fog = std::fs::read_to_string(dir.join("tac_fog.hex")).unwrap();
    let fog: Vec<f32> = fog.lines().map(word).collect();
    assert_eq!(fog.len(), 4098);
    assert_eq!((fog[0], fog[4096], fog[4097]), (1.0, 0.0, 0.0));
    assert!((fog[256] - (-1.0f32).exp()).abs() < 1e-7);
    let log2 = std::fs::read_to_string(dir.join("tac_log2.hex")).unwrap();
    let log2: Vec<f32> = log2.lines().map(word).collect();
    assert_eq!(log2.len(), 257);
    assert_eq!((log2[0], log2[128], log2[256]), (0.0, 1.5f32.log2(), 1.0));
    cleanup(&dir);
}

#[test]
fn bad_input_gets_a_clear_error() {
    fails_with(&["render", "--size", "0x0"], "out of range");
    fails_with(&["render", "--size", "100000x100000"], "out of range");
    fails_with(&["render", "--size", "12by7"], "WxH");
    fails_with(&["render", "no-such-scene"], "neither a built-in scene");
    fails_with(&["render", "--masks", "VII"], "--masks");
    fails_with(&["render", "--gamma=-1"], "gamma");
    fails_with(&["render", "--gamma=0"], "gamma");
    let bad = tmp("bad.toml");
    std::fs::write(&bad, "[screen]\nwidth = 640\nheigth = 480\n").unwrap();
    fails_with(&["render", bad.to_str().unwrap()], "bad.toml:3");
    cleanup(&bad);
}
