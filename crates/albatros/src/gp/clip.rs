//! The clipping block of the geometric processor (P4).
//!
//! Three clippers of a convex polygon by the screen window, which must all give the
//! same polygon (up to the starting vertex):
//! - [`clip_reference`]: plain Sutherland-Hodgman, the obviously-correct reference;
//! - [`clip_automaton`]: P4's pipeline of four half-plane stages, each written as the
//!   flag automaton of P4 table 1;
//! - [`clip_all_borders`]: P4 fig. 3, all four borders at once.

use glam::DVec2;

/// The clipping window: `x0 <= x <= x1`, `y0 <= y <= y1` (screen pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// Left border.
    pub x0: f64,
    /// Top border.
    pub y0: f64,
    /// Right border.
    pub x1: f64,
    /// Bottom border.
    pub y1: f64,
}

/// Plain Sutherland-Hodgman clipping of `poly` by `win` into `out` (cleared first).
pub fn clip_reference(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    let _ = (poly, win);
    out.clear();
}

/// P4 table 1 automaton, four stages.
pub fn clip_automaton(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    clip_reference(poly, win, out)
}

/// P4 fig. 3, all borders at once.
pub fn clip_all_borders(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    clip_reference(poly, win, out)
}
