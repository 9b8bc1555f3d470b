//! The charts of `albatros stats --plot DIR`, drawn with plotters into an RGB buffer
//! and written as PNG by the library's encoder:
//! - `cells_per_level.png`: cells tested per level (log scale), one line per mask
//!   mode: where the masks cut the quadtree;
//! - `stage_times.png`: each pipeline stage's estimated time per mode, with the
//!   half-frame: which stage bounds the pipeline and how the bottleneck moves;
//! - `fig4.png`: P1 fig. 4 redrawn: the estimated time of every built-in scene under
//!   modes I..IV against the half-frame, each scene rendered at the hardware's
//!   screen (the largest size with the scene's aspect whose root level is the number
//!   of GQs: 512 on P1's base variant).
//!
//! Labels need a TrueType font: `ALBATROS_FONT` if set, else the first of a few
//! usual system paths ([`FONT_PATHS`]); without one the charts are refused with a
//! message saying so.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{anyhow, bail, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use albatros::db::{builtin, Screen};
use albatros::gp::{self, Database, GpConfig};
use albatros::model::experiment::{self, Experiment, Report};
use albatros::model::timing::{HwConfig, Timing};
use albatros::vp::gq::CellProcessors;
use albatros::vp::texture::TextureMaps;
use albatros::vp::vb::Image;

/// Chart size, pixels.
const CHART_SIZE: (u32, u32) = (960, 600);
/// The font family name the charts use (registered from the font file).
const FAMILY: &str = "sans-serif";
/// Caption and label sizes, pixels.
const CAPTION_SIZE: u32 = 24;
/// Axis label size, pixels.
const LABEL_SIZE: u32 = 16;
/// Margin around the plot area, pixels.
const MARGIN: u32 = 16;
/// Space for the axes' labels, pixels.
const AXIS_AREA: u32 = 60;
/// Headroom above the largest value.
const HEADROOM: f64 = 1.12;
/// Line width of the series.
const STROKE: u32 = 2;
/// Marker radius.
const MARKER: u32 = 4;
/// The environment variable naming a TrueType font for the labels.
pub const FONT_ENV: &str = "ALBATROS_FONT";
/// Where a sans-serif TrueType font usually is (Debian/Ubuntu, Fedora, Arch, macOS,
/// Windows).
pub const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "/Library/Fonts/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];
/// One colour per mode or scene.
const COLORS: [RGBColor; 6] = [
    RGBColor(214, 39, 40),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(31, 119, 180),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Finds and registers the labels' font once.
fn font() -> Result<()> {
    static FONT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let found = FONT.get_or_init(|| {
        let candidates: Vec<PathBuf> = std::env::var_os(FONT_ENV)
            .map(PathBuf::from)
            .into_iter()
            .chain(FONT_PATHS.iter().map(PathBuf::from))
            .collect();
        for path in candidates {
            if let Ok(bytes) = std::fs::read(&path) {
                // plotters keeps fonts for the life of the program.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if register_font(FAMILY, FontStyle::Normal, bytes).is_ok() {
                    return Ok(path);
                }
            }
        }
        Err(format!(
            "no TrueType font for the chart labels: set {FONT_ENV} to a .ttf file (looked in {})",
            FONT_PATHS.join(", ")
        ))
    });
    found.as_ref().map(|_| ()).map_err(|e| anyhow!("{e}"))
}

/// Draws a chart into a PNG file.
fn png(path: &Path, draw: impl FnOnce(&DrawingArea<BitMapBackend, Shift>) -> Result<()>) -> Result<()> {
    font()?;
    let (w, h) = CHART_SIZE;
    let mut pixels = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        draw(&root)?;
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    let image = Image { width: w, height: h, pixels };
    std::fs::write(path, image.encode_png()).with_context(|| format!("writing {}", path.display()))
}

/// Turns a plotters error (not `Send` in general) into an `anyhow` one.
fn pe<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("drawing a chart: {e}")
}

/// Writes every chart into `dir` and returns their paths. `report` is the scene's
/// report under P1's four modes.
pub fn write_all(dir: &Path, report: &Report, hw: &HwConfig, gp: &GpConfig) -> Result<Vec<PathBuf>> {
    if report.runs.is_empty() {
        bail!("no runs to plot");
    }
    let cells = dir.join("cells_per_level.png");
    cells_per_level(&cells, report)?;
    let stages = dir.join("stage_times.png");
    stage_times(&stages, report)?;
    let fig4 = dir.join("fig4.png");
    let times = builtin_mode_times(hw, gp)?;
    fig4_chart(&fig4, &times, hw)?;
    Ok(vec![cells, stages, fig4])
}

/// Cells tested per level, a line per mode, log scale.
fn cells_per_level(path: &Path, r: &Report) -> Result<()> {
    let top = r.runs.iter().flat_map(|x| x.counters.levels.iter().map(|l| l.tested)).max().unwrap_or(1).max(1);
    let ymax = ((top as f64 * HEADROOM * HEADROOM) as u64).max(10);
    png(path, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("{} ({}x{}): cells tested per level, by mask mode", r.scene, r.width, r.height),
                (FAMILY, CAPTION_SIZE),
            )
            .margin(MARGIN)
            .x_label_area_size(AXIS_AREA)
            .y_label_area_size(AXIS_AREA + 20)
            .build_cartesian_2d(1u32..r.root_level, (1u64..ymax).log_scale())
            .map_err(pe)?;
        chart
            .configure_mesh()
            .x_desc("level (cell side 4 x 2^(L - level) pixels)")
            .y_desc("cells tested")
            .x_labels(r.root_level as usize)
            .label_style((FAMILY, LABEL_SIZE))
            .draw()
            .map_err(pe)?;
        for (i, run) in r.runs.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let points: Vec<(u32, u64)> =
                run.counters.levels.iter().enumerate().skip(1).map(|(k, l)| (k as u32, l.tested.max(1))).collect();
            chart
                .draw_series(LineSeries::new(points.clone(), color.stroke_width(STROKE)))
                .map_err(pe)?
                .label(format!("mode {} (mask levels {})", run.mode, super::levels_text(&run.mask_levels)))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(STROKE)));
            chart.draw_series(points.iter().map(|&p| Circle::new(p, MARKER, color.filled()))).map_err(pe)?;
        }
        legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        Ok(())
    })
}

/// Each stage's time per mode, bars grouped by stage, with the half-frame line.
fn stage_times(path: &Path, r: &Report) -> Result<()> {
    let names: Vec<String> = r.runs[0].timing.stages.iter().map(|s| s.name.clone()).collect();
    let top = r.runs.iter().flat_map(|x| x.timing.stages.iter().map(|s| s.ms)).fold(r.hw.half_frame_ms, f64::max);
    let modes = r.runs.len() as f64;
    let n = names.len();
    png(path, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("{}: estimated time per pipeline stage, by mask mode ({} MHz)", r.scene, r.hw.clock_mhz),
                (FAMILY, CAPTION_SIZE),
            )
            .margin(MARGIN)
            .x_label_area_size(AXIS_AREA)
            .y_label_area_size(AXIS_AREA)
            .build_cartesian_2d(-0.5f64..n as f64 - 0.5, 0f64..top * HEADROOM)
            .map_err(pe)?;
        let label = |x: &f64| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&label)
            .y_desc("ms")
            .label_style((FAMILY, LABEL_SIZE))
            .draw()
            .map_err(pe)?;
        let width = 0.8 / modes;
        for (m, run) in r.runs.iter().enumerate() {
            let color = COLORS[m % COLORS.len()];
            let bars = run.timing.stages.iter().enumerate().map(move |(i, s)| {
                let x0 = i as f64 - 0.4 + m as f64 * width;
                Rectangle::new([(x0, 0.0), (x0 + width, s.ms)], color.filled())
            });
            chart
                .draw_series(bars)
                .map_err(pe)?
                .label(format!(
                    "mode {}: {:.1} ms, bottleneck {}",
                    run.mode, run.timing.frame_ms, run.timing.bottleneck
                ))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], color.filled()));
        }
        let budget = r.hw.half_frame_ms;
        chart
            .draw_series(LineSeries::new(vec![(-0.5, budget), (n as f64 - 0.5, budget)], BLACK.stroke_width(1)))
            .map_err(pe)?
            .label(format!("half-frame {budget} ms"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        Ok(())
    })
}

/// The charts' legend box, in one style, at `position`.
fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .label_font((FAMILY, LABEL_SIZE))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(pe)
}

/// The screen a scene is shown on for fig. 4: the scene's aspect, its longer side the
/// root cell of `gq` levels (`4 * 2^gq`, 512 for P1), never enlarged.
pub fn hardware_screen(screen: Screen, gq: u32) -> Screen {
    let side = 4u64 << gq.min(Screen::MAX_SIDE.ilog2());
    let long = u64::from(screen.width.max(screen.height));
    if long <= side {
        return screen;
    }
    let scale = |v: u32| ((u64::from(v) * side).div_ceil(long) as u32).max(1);
    Screen { width: scale(screen.width), height: scale(screen.height) }
}

/// One scene's estimated times under modes I..IV.
pub struct SceneTimes {
    /// Scene name.
    pub scene: String,
    /// The screen it was rendered at.
    pub screen: Screen,
    /// `(mode, timing)` for I..IV.
    pub modes: Vec<(String, Timing)>,
}

/// Every built-in scene at the hardware's screen under modes I..IV.
fn builtin_mode_times(hw: &HwConfig, gp_config: &GpConfig) -> Result<Vec<SceneTimes>> {
    let mut out = Vec::new();
    for name in builtin::NAMES {
        let mut scene = builtin::scene(name).ok_or_else(|| anyhow!("built-in scene {name}"))?;
        scene.screen = hardware_screen(scene.screen, hw.units.gq);
        let screen = scene.screen;
        eprintln!("fig. 4: {name} at {}x{} ...", screen.width, screen.height);
        let db = Database::new(scene);
        let (frame, _) = gp::frame_of_scene(&db, gp_config);
        let mut ex = Experiment::new(&frame);
        ex.textures = TextureMaps::from_scene(&db.scene, Path::new(""))?.into();
        let root = CellProcessors::root_level_for(screen.width, screen.height);
        let modes = experiment::p1_modes(root)
            .iter()
            .map(|(mode, masks)| (mode.to_string(), Timing::estimate(hw, &ex.counters(*masks))))
            .collect();
        out.push(SceneTimes { scene: name.to_string(), screen, modes });
    }
    Ok(out)
}

/// P1 fig. 4: time per mode, a line per scene, and the half-frame.
fn fig4_chart(path: &Path, scenes: &[SceneTimes], hw: &HwConfig) -> Result<()> {
    let top = scenes.iter().flat_map(|s| s.modes.iter().map(|m| m.1.frame_ms)).fold(hw.half_frame_ms, f64::max);
    let names: Vec<String> = scenes.first().map(|s| s.modes.iter().map(|m| m.0.clone()).collect()).unwrap_or_default();
    let n = names.len().max(1);
    png(path, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("P1 fig. 4: estimated time against the mask levels in use ({}, {} MHz)", hw.name, hw.clock_mhz),
                (FAMILY, CAPTION_SIZE),
            )
            .margin(MARGIN)
            .x_label_area_size(AXIS_AREA)
            .y_label_area_size(AXIS_AREA)
            .build_cartesian_2d(-0.25f64..n as f64 - 0.75, (0.5f64..top * HEADROOM * HEADROOM).log_scale())
            .map_err(pe)?;
        let label = |x: &f64| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).map(|m| format!("mode {m}")).unwrap_or_default()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&label)
            .y_desc("estimated frame time, ms")
            .y_label_formatter(&|v| format!("{v}"))
            .label_style((FAMILY, LABEL_SIZE))
            .draw()
            .map_err(pe)?;
        for (i, s) in scenes.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let points: Vec<(f64, f64)> = s.modes.iter().enumerate().map(|(m, t)| (m as f64, t.1.frame_ms)).collect();
            chart
                .draw_series(LineSeries::new(points.clone(), color.stroke_width(STROKE)))
                .map_err(pe)?
                .label(format!("{} ({}x{})", s.scene, s.screen.width, s.screen.height))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(STROKE)));
            chart.draw_series(points.iter().map(|&p| Circle::new(p, MARKER, color.filled()))).map_err(pe)?;
        }
        let budget = hw.half_frame_ms;
        chart
            .draw_series(LineSeries::new(vec![(-0.25, budget), (n as f64 - 0.75, budget)], BLACK.stroke_width(1)))
            .map_err(pe)?
            .label(format!("half-frame {budget} ms"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        legend(&mut chart, SeriesLabelPosition::LowerRight)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_fit_the_hardware_screen() {
        let s = |width, height| Screen { width, height };
        assert_eq!(hardware_screen(s(1024, 768), 7), s(512, 384));
        assert_eq!(hardware_screen(s(1920, 1080), 7), s(512, 288));
        assert_eq!(hardware_screen(s(512, 512), 7), s(512, 512));
        assert_eq!(hardware_screen(s(320, 240), 7), s(320, 240));
        for screen in [s(1024, 768), s(1920, 1080), s(2000, 3)] {
            let fit = hardware_screen(screen, 7);
            assert_eq!(CellProcessors::root_level_for(fit.width, fit.height), 7);
        }
    }
}
