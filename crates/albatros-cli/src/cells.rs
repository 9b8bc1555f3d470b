//! `albatros render --cells out.png`: the cell subdivision drawn over the image, a
//! picture of what the cell processors (GQ) did. One render with the GQ's cell
//! recorder on (`CellProcessors::recorder`, which needs counting on) gives both the
//! image and every decision of every GQ, which are drawn over a dimmed grey copy of
//! the image:
//! - **masked** cells (IN or CR, dropped by a mask memory) outlined red, and the
//!   starting cells of polygons dropped whole outlined magenta; the screen under them
//!   is tinted once, by the coarsest cell dropped there: big squares are work saved
//!   high in the tree (P1 fig. 4's point);
//! - **CR** cells (crossed by an edge) outlined in yellow: the edges' trail down the
//!   levels;
//! - **IN** cells outlined in green, only the top cell of each inside subtree (its
//!   descendants are all IN too);
//! - **OUT** cells outlined in dark blue: the subdivision's waste.
//!
//! Colour by level: the outline is brighter the coarser the cell (level 0 full
//! colour, level `L` at [`FINEST_SHADE`] of it). Screens up to [`ENLARGE_UP_TO`]
//! pixels are drawn at twice the size so that the 4 x 4 cells stay visible.

use std::collections::HashSet;

use albatros::frame::FrameList;
use albatros::vp::gq::{Cell, CellKind, CellRecord};
use albatros::vp::vb::Image;
use albatros::vp::VideoProcessor;

/// Screens whose longer side is at most this are drawn at twice the size.
pub const ENLARGE_UP_TO: u32 = 1024;
/// The brightness of the finest level's outlines relative to the coarsest.
pub const FINEST_SHADE: f32 = 0.55;
/// The dimmed image's brightness under the overlay.
const BACKDROP: f32 = 0.45;
/// Opacity of the tint under dropped cells.
const MASK_FILL: f32 = 0.35;
/// Opacity of the OUT cells' outline.
const OUT_ALPHA: f32 = 0.5;
/// Inside (IN).
const GREEN: [f32; 3] = [40.0, 220.0, 60.0];
/// Crossed (CR).
const YELLOW: [f32; 3] = [255.0, 215.0, 0.0];
/// Outside (OUT).
const BLUE: [f32; 3] = [60.0, 100.0, 230.0];
/// Dropped by a mask.
const RED: [f32; 3] = [235.0, 30.0, 30.0];
/// Polygon dropped whole.
const MAGENTA: [f32; 3] = [235.0, 0.0, 235.0];

/// Renders `frame` on `vp` (whose configuration, textures and masks are kept) and
/// returns the image and the cell overlay. Counting is switched on for the render
/// (it never changes the image) and back as it was.
pub fn render_with_cells(vp: &mut VideoProcessor, frame: &FrameList) -> (Image, Image) {
    let stats = vp.config.stats;
    vp.config.stats = true;
    vp.gq.recorder = Some(Vec::new());
    let image = vp.render(frame);
    let cells = vp.gq.recorder.take().unwrap_or_default();
    vp.config.stats = stats;
    let overlay = overlay(&image, &cells, vp.gq.root_level);
    (image, overlay)
}

/// A canvas of floating-point RGB.
struct Canvas {
    width: u32,
    height: u32,
    scale: u32,
    rgb: Vec<[f32; 3]>,
}

impl Canvas {
    /// Blends `color` over pixel `(x, y)` of the canvas (already scaled) at opacity `a`.
    fn blend(&mut self, x: u32, y: u32, color: [f32; 3], a: f32) {
        if x < self.width && y < self.height {
            let p = &mut self.rgb[(y * self.width + x) as usize];
            for (c, v) in p.iter_mut().zip(color) {
                *c = *c * (1.0 - a) + v * a;
            }
        }
    }

    /// The canvas rectangle of a cell of side `side` (screen pixels).
    fn rect(&self, cell: &Cell, side: u32) -> (u32, u32, u32) {
        let s = side * self.scale;
        (cell.x * s, cell.y * s, s)
    }

    fn outline(&mut self, cell: &Cell, side: u32, color: [f32; 3], a: f32) {
        let (x0, y0, s) = self.rect(cell, side);
        for i in 0..s {
            self.blend(x0 + i, y0, color, a);
            self.blend(x0 + i, y0 + s - 1, color, a);
            if i > 0 && i + 1 < s {
                self.blend(x0, y0 + i, color, a);
                self.blend(x0 + s - 1, y0 + i, color, a);
            }
        }
    }
}

/// Draws the recorded cells of a frame of root level `root_level` over `image`.
pub fn overlay(image: &Image, cells: &[CellRecord], root_level: u32) -> Image {
    let scale = if image.width.max(image.height) <= ENLARGE_UP_TO { 2 } else { 1 };
    let (width, height) = (image.width * scale, image.height * scale);
    let mut canvas = Canvas { width, height, scale, rgb: vec![[0.0; 3]; (width * height) as usize] };
    for y in 0..height {
        for x in 0..width {
            let i = (((y / scale) * image.width + x / scale) * 3) as usize;
            let p = &image.pixels[i..i + 3];
            let grey = BACKDROP * (0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]));
            canvas.rgb[(y * width + x) as usize] = [grey; 3];
        }
    }
    let side = |level: u32| 4u32 << (root_level - level.min(root_level));
    let shade = |color: [f32; 3], level: u32| {
        let t = if root_level == 0 { 0.0 } else { level as f32 / root_level as f32 };
        color.map(|c| c * (1.0 - t * (1.0 - FINEST_SHADE)))
    };
    // The work the masks saved: each screen pixel tinted once, by the coarsest cell
    // dropped over it (many polygons may be dropped over the same place).
    let mut dropped: Vec<Option<(u32, [f32; 3])>> = vec![None; (image.width * image.height) as usize];
    for (cell, kind) in cells {
        let color = match kind {
            CellKind::Masked => RED,
            CellKind::PolygonMasked => MAGENTA,
            _ => continue,
        };
        let s = side(cell.level);
        for y in (cell.y * s)..((cell.y + 1) * s).min(image.height) {
            for x in (cell.x * s)..((cell.x + 1) * s).min(image.width) {
                let d = &mut dropped[(y * image.width + x) as usize];
                if d.is_none_or(|(level, _)| cell.level < level) {
                    *d = Some((cell.level, color));
                }
            }
        }
    }
    for y in 0..height {
        for x in 0..width {
            if let Some((level, color)) = dropped[((y / scale) * image.width + x / scale) as usize] {
                canvas.blend(x, y, shade(color, level), MASK_FILL);
            }
        }
    }
    // Outlines: OUT, IN subtree tops and CR cells, per polygon's descent.
    let mut inside: HashSet<(u32, u32, u32)> = HashSet::new();
    for (cell, kind) in cells {
        let s = side(cell.level);
        match kind {
            CellKind::Start => inside.clear(),
            CellKind::Outside => canvas.outline(cell, s, shade(BLUE, cell.level), OUT_ALPHA),
            CellKind::Crossed => canvas.outline(cell, s, shade(YELLOW, cell.level), 1.0),
            CellKind::Inside => {
                let parent = (cell.level.wrapping_sub(1), cell.x / 2, cell.y / 2);
                if !inside.contains(&parent) {
                    canvas.outline(cell, s, shade(GREEN, cell.level), 1.0);
                }
                inside.insert((cell.level, cell.x, cell.y));
            }
            CellKind::Masked | CellKind::PolygonMasked => {}
        }
    }
    // The dropped cells' outlines on top: where, and at which level, work was saved.
    for (cell, kind) in cells {
        let color = match kind {
            CellKind::Masked => RED,
            CellKind::PolygonMasked => MAGENTA,
            _ => continue,
        };
        canvas.outline(cell, side(cell.level), shade(color, cell.level), 1.0);
    }
    let pixels = canvas.rgb.iter().flat_map(|p| p.map(|c| c.round().clamp(0.0, 255.0) as u8)).collect();
    Image { width, height, pixels }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(width: u32, height: u32) -> Image {
        Image { width, height, pixels: vec![100; (width * height * 3) as usize] }
    }

    #[test]
    fn a_masked_cell_is_red_and_an_outside_one_blue() {
        // An 8 x 8 screen: root level 1, cells of level 1 are 4 x 4, drawn twice the size.
        let cells = [
            (Cell { level: 0, x: 0, y: 0 }, CellKind::Start),
            (Cell { level: 1, x: 0, y: 0 }, CellKind::Masked),
            (Cell { level: 1, x: 1, y: 0 }, CellKind::Outside),
            (Cell { level: 1, x: 0, y: 1 }, CellKind::Inside),
            (Cell { level: 1, x: 1, y: 1 }, CellKind::Crossed),
        ];
        let out = overlay(&grey(8, 8), &cells, 1);
        assert_eq!((out.width, out.height), (16, 16));
        let px = |x: u32, y: u32| {
            let i = ((y * 16 + x) * 3) as usize;
            [out.pixels[i], out.pixels[i + 1], out.pixels[i + 2]]
        };
        let [r, g, b] = px(3, 3); // inside the masked cell: red tint
        assert!(r > g && r > b, "{:?}", px(3, 3));
        let [r, g, b] = px(8, 0); // the OUT cell's outline: blue
        assert!(b > r && b > g, "{:?}", px(8, 0));
        let [r, g, b] = px(8, 8); // the CR cell's outline: yellow
        assert!(r > b && g > b);
        let [r, g, b] = px(0, 8); // the IN cell's outline: green
        assert!(g > r && g > b);
        let [r, g, b] = px(12, 12); // inside the CR cell: the grey backdrop
        assert!(r == g && g == b);
    }
}
