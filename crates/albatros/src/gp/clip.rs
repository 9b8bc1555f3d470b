//! The clipping block of the geometric processor (P4 «блок отсечения», SYSTEM.md 3):
//! class-2 faces, convex polygons in screen coordinates, are cut to the rectangular
//! screen window. Input: the face's vertices in order; output: the vertices of the
//! clipped face in the same order and winding, ready for setup.
//!
//! Three clippers, which must all give the same polygon up to the starting vertex and
//! rounding (the integration tests in `tests/it/clip.rs` hold them to it):
//! - [`clip_reference`]: plain Sutherland-Hodgman, the obviously-correct reference;
//! - [`clip_automaton`]: P4's pipeline of four half-plane stages, each written as the
//!   flag automaton of P4 table 1 (flags F1..F4, operations P1..P5);
//! - [`clip_all_borders`]: P4 fig. 3, every vertex tested against all four borders at
//!   once (P6..P12), window corners inserted through corner counters and a corner
//!   buffer.
//!
//! # Conventions
//!
//! - **Input**: an open vertex list (the edge from the last vertex back to the first is
//!   implied). A closing repeat of the first vertex, repeated vertices and collinear
//!   vertices are accepted: they are zero-length or straight-through edges. Either
//!   winding. The polygon must be convex (faces are, SYSTEM.md 2): for a non-convex
//!   polygon the output is unspecified, but nothing panics.
//! - **Inside is inclusive**: a point on a border is inside (P4: F2 = 0 iff X2 < Xmin).
//! - **Output**: the clipped polygon, strictly convex, with the **same winding as the
//!   input** (none of the clippers looks at the orientation: Sutherland-Hodgman and
//!   the automaton keep the input order by construction, and the all-borders clipper
//!   inserts window corners in the order the polygon's boundary goes round them). No
//!   vertex lies within the tolerance below of the line through its neighbours: so no
//!   two consecutive points (cyclically) are equal, and collinear input vertices are
//!   dropped (harmless: the clipper carries positions only; the setup interpolates
//!   from plane equations). Empty if fewer than three points remain or the area is
//!   zero. An improper window (not `x0 < x1 && y0 < y1`, or NaN) clips everything
//!   away.
//! - **Tolerance**: rounding in the intersection formulas is of the order of an ulp of
//!   the largest coordinate involved, so the clean-up works relative to
//!   `scale = max |coordinate|` over the input polygon and the window: a vertex within
//!   `REL_EPS * scale` of the line through its neighbours goes, and a polygon whose
//!   area is at most `REL_EPS * scale * perimeter` (narrower than about
//!   `2 * REL_EPS * scale` everywhere) has zero area. With pixel coordinates up to
//!   10^4 that is 10^-8 pixel: nothing that could cover a sample is dropped.
//!
//! # The face stream
//!
//! Inside the block a face travels as in P4: its vertices one by one, and then the
//! first vertex again, which "closes" the polygon. P4 counts the vertices with a
//! counter C = K to know when the last one arrives; a pipeline stage cannot know how
//! many vertices its upstream stage will produce, so here the counter becomes a `last`
//! tag on the closing vertex (a hardware pipeline passes such a tag bit along with the
//! data). Every stage closes its output the same way (P4: the first-point buffer
//! «БПТ» is output once more at the end), so stages chain without knowing counts, and
//! nothing is allocated per vertex: a vertex goes through all four stages before the
//! next one enters.

use glam::{DVec2, Vec2Swizzles};

/// The clipping window: `x0 <= x <= x1`, `y0 <= y <= y1` (screen pixels, y down).
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

impl Window {
    /// A proper rectangle: `x0 < x1` and `y0 < y1` (false if any is NaN).
    fn is_proper(&self) -> bool {
        self.x0 < self.x1 && self.y0 < self.y1
    }

    /// Window corner `k` in the order around the window (see [`Border::AROUND`]):
    /// 0 top-left, 1 top-right, 2 bottom-right, 3 bottom-left. Corner k joins border k
    /// and border k + 1.
    fn corner(&self, k: usize) -> DVec2 {
        match k {
            0 => DVec2::new(self.x0, self.y0),
            1 => DVec2::new(self.x1, self.y0),
            2 => DVec2::new(self.x1, self.y1),
            _ => DVec2::new(self.x0, self.y1),
        }
    }
}

/// Relative tolerance of the output clean-up (see the module doc): about 10^4 ulps,
/// far above the rounding of a few chained intersection formulas, far below anything
/// visible.
const REL_EPS: f64 = 1e-12;

// ---------------------------------------------------------------------------------
// Borders
// ---------------------------------------------------------------------------------

/// One border of the window: a clipping half-plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Border {
    Left,
    Top,
    Right,
    Bottom,
}

/// Which end of a window side a crossing of the side's line outside the window lies
/// beyond (P7's coding "above", "below"; the paper's flags N_i1, N_i2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum End {
    /// Beyond the side's first end, corner `i - 1` (N_i1).
    First,
    /// Beyond the side's second end, corner `i` (N_i2).
    Second,
}

impl Border {
    /// The borders in the fixed order of the pipeline and of P7 (P4 fig. 4 is not in
    /// the text we have; this is the order around the window, clockwise on the y-down
    /// screen). Border i runs from corner i - 1 to corner i: left from bottom-left to
    /// top-left, top from top-left to top-right, and so on.
    const AROUND: [Border; 4] = [Border::Left, Border::Top, Border::Right, Border::Bottom];

    /// Whether `p` is inside this half-plane (inclusive: P4's F2 = 0 iff X2 < Xmin).
    fn inside(self, w: &Window, p: DVec2) -> bool {
        match self {
            Border::Left => p.x >= w.x0,
            Border::Top => p.y >= w.y0,
            Border::Right => p.x <= w.x1,
            Border::Bottom => p.y <= w.y1,
        }
    }

    /// P2 (and P7): the point where the edge `p1 -> p2` meets this border's line, and
    /// its parameter t along the edge (0 at `p1`, 1 at `p2`). Only called for edges
    /// whose ends are on different sides, so the denominator is not zero, and t is in
    /// [0, 1] (rounding is monotonic).
    fn cut(self, w: &Window, p1: DVec2, p2: DVec2) -> (f64, DVec2) {
        match self {
            Border::Left => cut_vertical(w.x0, p1, p2),
            Border::Right => cut_vertical(w.x1, p1, p2),
            Border::Top => {
                let (t, q) = cut_vertical(w.y0, p1.yx(), p2.yx());
                (t, q.yx())
            }
            Border::Bottom => {
                let (t, q) = cut_vertical(w.y1, p1.yx(), p2.yx());
                (t, q.yx())
            }
        }
    }

    /// The coordinate of a point of this border's line along the line, and the side's
    /// range of it: (s, lo, hi), and whether lo is the side's first end.
    fn along(self, w: &Window, p: DVec2) -> (f64, f64, f64, bool) {
        match self {
            Border::Left => (p.y, w.y0, w.y1, false),
            Border::Top => (p.x, w.x0, w.x1, true),
            Border::Right => (p.y, w.y0, w.y1, true),
            Border::Bottom => (p.x, w.x0, w.x1, false),
        }
    }

    /// P7 for a crossing on the window side (IP_i): the point, held to the side (a
    /// rounded crossing may land a hair beyond its end).
    fn onto_side(self, w: &Window, p: DVec2) -> DVec2 {
        let (s, lo, hi, _) = self.along(w, p);
        let s = s.clamp(lo, hi);
        match self {
            Border::Left | Border::Right => DVec2::new(p.x, s),
            Border::Top | Border::Bottom => DVec2::new(s, p.y),
        }
    }

    /// P7 for a crossing outside the window (N_i1 or N_i2): which end of the side it
    /// lies beyond; the nearer end if rounding has put it on the side.
    fn beyond(self, w: &Window, p: DVec2) -> End {
        let (s, lo, hi, first_is_lo) = self.along(w, p);
        let below_lo = s - lo < hi - s;
        if below_lo == first_is_lo {
            End::First
        } else {
            End::Second
        }
    }
}

/// P4's formula for P2, for the line x = `x`:
/// Y = (Xmin - X1) / (X2 - X1) (Y2 - Y1) + Y1; also returns t = (Xmin - X1) / (X2 - X1).
fn cut_vertical(x: f64, p1: DVec2, p2: DVec2) -> (f64, DVec2) {
    let t = (x - p1.x) / (p2.x - p1.x);
    (t, DVec2::new(x, t * (p2.y - p1.y) + p1.y))
}

// ---------------------------------------------------------------------------------
// Output clean-up, shared by the three clippers
// ---------------------------------------------------------------------------------

/// The scale for the tolerances: the largest coordinate magnitude of the input and the
/// window. `f64::max` skips NaN, so this stays finite; NaN input ends in a NaN area,
/// which [`finish`] treats as empty.
fn scale(poly: &[DVec2], win: &Window) -> f64 {
    let w = win.x0.abs().max(win.x1.abs()).max(win.y0.abs()).max(win.y1.abs());
    poly.iter().fold(w, |m, p| m.max(p.abs().max_element()))
}

/// Brings a raw clipper output to the conventions of the module doc: drops every
/// vertex that lies within the tolerance of the line through its two neighbours
/// (repeated points, collinear points, and the hair-thin notches and spikes that
/// rounding can leave), until none does; then empties a polygon of fewer than three
/// points or of zero area.
fn finish(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    let tol = REL_EPS * scale(poly, win);
    // At most one pass per vertex removed, and faces have a handful of vertices.
    let mut i = 0;
    let mut kept = 0;
    while out.len() >= 3 && kept < out.len() {
        let n = out.len();
        let (a, v, b) = (out[(i + n - 1) % n], out[i % n], out[(i + 1) % n]);
        let d = b - a;
        let len = d.length();
        // Distance of v from the line a b, times len; a and b one point: v goes.
        if len <= tol || d.perp_dot(v - a).abs() <= tol * len {
            out.remove(i % n);
            kept = 0;
        } else {
            i += 1;
            kept += 1;
        }
        i %= out.len().max(1);
    }
    if out.len() < 3 {
        out.clear();
        return;
    }
    let o = out[0];
    let (mut area2, mut perimeter) = (0.0, 0.0);
    for (i, &a) in out.iter().enumerate() {
        let b = out[(i + 1) % out.len()];
        area2 += (a - o).perp_dot(b - o);
        perimeter += (b - a).length();
    }
    if !area2.is_finite() || 0.5 * area2.abs() <= tol * perimeter {
        out.clear();
    }
}

// ---------------------------------------------------------------------------------
// Reference: Sutherland-Hodgman
// ---------------------------------------------------------------------------------

/// Plain Sutherland-Hodgman clipping of `poly` by `win` into `out` (cleared first):
/// the polygon is run through the four half-planes in turn, each pass keeping the
/// inside vertices and the crossings of the border line. Deliberately simple and
/// independent of the other two clippers (its own intersection formula), to judge
/// them by. Output conventions: see the module doc.
pub fn clip_reference(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    out.clear();
    if !win.is_proper() {
        return;
    }
    let mut cur = poly.to_vec();
    let mut next = Vec::with_capacity(poly.len() + 4);
    for border in Border::AROUND {
        next.clear();
        for (i, &q) in cur.iter().enumerate() {
            let p = cur[(i + cur.len() - 1) % cur.len()];
            let (pin, qin) = (border.inside(win, p), border.inside(win, q));
            if pin != qin {
                next.push(reference_cut(border, win, p, q));
            }
            if qin {
                next.push(q);
            }
        }
        std::mem::swap(&mut cur, &mut next);
    }
    out.extend_from_slice(&cur);
    finish(poly, win, out);
}

/// [`clip_reference`], with a shortcut for a polygon whose every vertex is inside
/// every border (a light point away from the screen's edge, nearly all of them): its
/// vertices as they are, then [`finish`], the reference's own output for it (each
/// of its passes keeps an inside vertex in its place and cuts no edge), without the
/// four passes and their two lists.
pub fn clip_reference_unless_inside(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    let inside = |p: DVec2| Border::AROUND.iter().all(|b| b.inside(win, p));
    if win.is_proper() && poly.iter().all(|&p| inside(p)) {
        out.clear();
        out.extend_from_slice(poly);
        finish(poly, win, out);
    } else {
        clip_reference(poly, win, out);
    }
}

/// The reference's own crossing of the edge `p -> q` with a border line: p + t (q - p),
/// with the coordinate across the border set exactly.
fn reference_cut(border: Border, w: &Window, p: DVec2, q: DVec2) -> DVec2 {
    let d = q - p;
    match border {
        Border::Left | Border::Right => {
            let x = if border == Border::Left { w.x0 } else { w.x1 };
            DVec2::new(x, p.y + d.y * ((x - p.x) / d.x))
        }
        Border::Top | Border::Bottom => {
            let y = if border == Border::Top { w.y0 } else { w.y1 };
            DVec2::new(p.x + d.x * ((y - p.y) / d.y), y)
        }
    }
}

// ---------------------------------------------------------------------------------
// P4 table 1: the half-plane automaton
// ---------------------------------------------------------------------------------

/// The automaton's state: P4's flag word F1 F2 F3 F4 read as a binary number, F1 the
/// high bit, so that row N of table 1 is entry N - 1 of [`TABLE_1`].
///
/// Bit layout (`u8`, bits 7..4 zero): `0000 F1 F2 F3 F4`.
/// - F1 (bit 3): the previous vertex is inside.
/// - F2 (bit 2): the current vertex is inside, F2 = 0 iff X2 < Xmin; set on the
///   arrival of every vertex, before the table is consulted.
/// - F3 (bit 1): the first point of the clipped polygon has not been found yet (the
///   first-point buffer БПТ is empty); set in the initial state 0010.
/// - F4 (bit 0): the last vertex (the repeat of the first) has arrived. While F3 = 1
///   it has a second use, which the table makes plain: row 3 (0010, first vertex
///   outside) sets it to say "a previous vertex exists", so that a later inside vertex
///   goes to row 8 (0111) and its entering edge is cut, where the very first vertex,
///   inside, goes to row 7 (0110) and has no edge; row 8 then clears it again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Flags(u8);

impl Flags {
    const F1: Flags = Flags(0b1000);
    const F2: Flags = Flags(0b0100);
    const F3: Flags = Flags(0b0010);
    const F4: Flags = Flags(0b0001);
    /// Nothing to set or clear.
    const NONE: Flags = Flags(0);
    /// P4: "the initial state of the automaton is F1F2F3F4 = 0010".
    const INITIAL: Flags = Flags::F3;

    /// `|`, for the `const` table.
    const fn or(self, f: Flags) -> Flags {
        Flags(self.0 | f.0)
    }

    fn set(self, f: Flags, on: bool) -> Flags {
        if on {
            Flags(self.0 | f.0)
        } else {
            Flags(self.0 & !f.0)
        }
    }

    /// Row index into [`TABLE_1`].
    fn word(self) -> usize {
        usize::from(self.0 & 0b1111)
    }
}

/// The operations of P4 table 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Op {
    /// P1: output the current point.
    P1,
    /// P2: compute the intersection of the edge (previous, current) with the border
    /// (into the working register).
    P2,
    /// P3: write the current point or the intersection into the first-point buffer
    /// БПТ. Which one: the point this row has just output (row 7: P1 then P3, the
    /// current point; row 8: P2, P5 then P3, the intersection); that point is the
    /// first point of the clipped polygon.
    P3,
    /// P4: output the point of the first-point buffer БПТ: it closes the clipped
    /// polygon, so it is the stage's last output for the face.
    P4,
    /// P5: output the point of the working register (the intersection).
    P5,
}

/// One row of P4 table 1.
#[derive(Clone, Copy, Debug)]
enum Row {
    /// «Выход из таблицы», leave the table: nothing to do, wait for the next vertex.
    Exit,
    /// Run `ops` in order, then set the flags `set` and clear the flags `clear`.
    Run { ops: &'static [Op], set: Flags, clear: Flags },
    /// «Запрещенное состояние», a forbidden state: F1 = 1 with F3 = 1 (an inside
    /// previous vertex has always been output, so the first point is known). No input
    /// leads here (a unit test walks the table to show it).
    Forbidden,
}

/// P4 table 1, indexed by the flag word F1F2F3F4 (row N of the paper is entry N - 1).
/// The operations and flag changes are the paper's, with one typo fixed: row 5 reads
/// "F_i = 1", which can only be F1 = 1 (the current vertex is inside and becomes the
/// previous one; every other row keeps F1 equal to the F2 just consumed, and with F1
/// left 0 the next outside vertex would go to row 1 and its exit point would be lost).
/// After the last vertex (the rows with F4 = 1 and F3 = 0, and row 4 when the whole
/// face is outside) the stage returns to the initial state 0010 for the next face.
const TABLE_1: [Row; 16] = {
    use Op::{P1, P2, P3, P4, P5};
    const F1: Flags = Flags::F1;
    const F3: Flags = Flags::F3;
    const F4: Flags = Flags::F4;
    const NO: Flags = Flags::NONE;
    [
        // 1  0000: previous and current outside: nothing.
        Row::Exit,
        // 2  0001: last vertex, outside after outside: close.
        Row::Run { ops: &[P4], set: NO, clear: NO },
        // 3  0010: first vertex, outside: remember that a previous vertex exists.
        Row::Run { ops: &[], set: F4, clear: NO },
        // 4  0011: still no inside vertex: nothing.
        Row::Exit,
        // 5  0100: entering: intersection, current point. Paper "F_i = 1" (typo).
        Row::Run { ops: &[P2, P5, P1], set: F1, clear: NO },
        // 6  0101: last vertex, entering: intersection, close.
        Row::Run { ops: &[P2, P5, P4], set: NO, clear: NO },
        // 7  0110: first vertex, inside: it is the first point.
        Row::Run { ops: &[P1, P3], set: F1, clear: F3 },
        // 8  0111: first entering edge: the intersection is the first point.
        Row::Run { ops: &[P2, P5, P3, P1], set: F1, clear: F3.or(F4) },
        // 9  1000: leaving: intersection.
        Row::Run { ops: &[P2, P5], set: NO, clear: F1 },
        // 10 1001: last vertex, leaving: intersection, close.
        Row::Run { ops: &[P2, P5, P4], set: NO, clear: NO },
        // 11 1010
        Row::Forbidden,
        // 12 1011
        Row::Forbidden,
        // 13 1100: inside after inside: current point.
        Row::Run { ops: &[P1], set: NO, clear: NO },
        // 14 1101: last vertex, inside after inside: close.
        Row::Run { ops: &[P4], set: NO, clear: NO },
        // 15 1110
        Row::Forbidden,
        // 16 1111
        Row::Forbidden,
    ]
};

/// One stage of the pipeline: P4 fig. 2, the run of a face's vertices through one
/// clipping half-plane, as the flag automaton of table 1.
#[derive(Clone, Copy, Debug)]
struct HalfPlaneStage {
    border: Border,
    win: Window,
    flags: Flags,
    /// The previous vertex (X1, Y1).
    prev: DVec2,
    /// The working register: the last intersection computed by P2.
    reg: DVec2,
    /// БПТ, the first-point buffer: the first point of the clipped polygon, which is
    /// also its last.
    bpt: DVec2,
    /// The point output last (P1 or P5), what P3 writes into БПТ.
    last_out: DVec2,
}

impl HalfPlaneStage {
    fn new(border: Border, win: Window) -> Self {
        HalfPlaneStage {
            border,
            win,
            flags: Flags::INITIAL,
            prev: DVec2::ZERO,
            reg: DVec2::ZERO,
            bpt: DVec2::ZERO,
            last_out: DVec2::ZERO,
        }
    }

    /// Takes the next vertex of the face stream (`last`: it is the closing repeat of
    /// the first vertex) and passes this stage's output stream to `emit`, with the
    /// same convention.
    fn feed<F: FnMut(DVec2, bool)>(&mut self, cur: DVec2, last: bool, emit: &mut F) {
        self.flags = self.flags.set(Flags::F2, self.border.inside(&self.win, cur));
        if last {
            self.flags = self.flags.set(Flags::F4, true);
        }
        match TABLE_1[self.flags.word()] {
            Row::Exit => {}
            Row::Run { ops, set, clear } => {
                for op in ops {
                    match op {
                        Op::P1 => {
                            emit(cur, false);
                            self.last_out = cur;
                        }
                        Op::P2 => self.reg = self.border.cut(&self.win, self.prev, cur).1,
                        Op::P3 => self.bpt = self.last_out,
                        Op::P4 => emit(self.bpt, true),
                        Op::P5 => {
                            emit(self.reg, false);
                            self.last_out = self.reg;
                        }
                    }
                }
                self.flags = self.flags.set(set, true).set(clear, false);
            }
            Row::Forbidden => {
                // Unreachable (see `Row::Forbidden`); should it ever be reached, drop
                // the face rather than panic in a release build.
                if cfg!(debug_assertions) {
                    unreachable!("P4 table 1: forbidden state {:04b}", self.flags.0);
                }
                *self = HalfPlaneStage::new(self.border, self.win);
                return;
            }
        }
        self.prev = cur;
        if last {
            self.flags = Flags::INITIAL;
        }
    }
}

/// P4's pipeline: the face stream through four half-plane stages (`HalfPlaneStage`
/// in the source), one per border, in the order left, top, right, bottom, each written
/// literally as the flag automaton of P4 table 1; each stage's output stream is the
/// next stage's input, vertex by vertex, without intermediate buffers. Clips `poly` by
/// `win` into `out` (cleared first); output conventions: see the module doc.
pub fn clip_automaton(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    out.clear();
    if !win.is_proper() || poly.is_empty() {
        return;
    }
    let [mut left, mut top, mut right, mut bottom] = Border::AROUND.map(|b| HalfPlaneStage::new(b, *win));
    {
        // The closing point of the last stage repeats its first output: drop it.
        let mut sink = |p: DVec2, last: bool| {
            if !last {
                out.push(p);
            }
        };
        let mut pipeline = |p: DVec2, last: bool| {
            left.feed(p, last, &mut |p, last| {
                top.feed(p, last, &mut |p, last| {
                    right.feed(p, last, &mut |p, last| bottom.feed(p, last, &mut sink));
                });
            });
        };
        for &v in poly {
            pipeline(v, false);
        }
        pipeline(poly[0], true);
    }
    finish(poly, win, out);
}

// ---------------------------------------------------------------------------------
// P4 fig. 3: all borders at once
// ---------------------------------------------------------------------------------

/// P6 outcode of a point: bit i set iff the point is outside border
/// `Border::AROUND[i]` (bit 0 left, 1 top, 2 right, 3 bottom; bits 7..4 zero).
fn outcode(w: &Window, p: DVec2) -> u8 {
    Border::AROUND.iter().enumerate().fold(0, |code, (i, b)| code | (u8::from(!b.inside(w, p)) << i))
}

/// A crossing of a border line outside the window: the paper's flag N_i1 or N_i2,
/// packed as `2 i + e` (bits 2..1: border i in the order of [`Border::AROUND`]; bit 0:
/// e = 0 beyond the side's first end, corner i - 1; e = 1 beyond its second end,
/// corner i). It is a crossing of one of the two rays that continue the window's sides
/// beyond a corner.
type Ray = u8;

/// The window corner at which ray `r` starts.
fn ray_corner(r: Ray) -> usize {
    let border = usize::from(r >> 1);
    if r & 1 == 1 {
        border
    } else {
        (border + 3) % 4
    }
}

/// The two rays that start at corner k: N_k2 (border k beyond its second end) and
/// N_(k+1)1 (border k + 1 beyond its first end), as bits of the N flag word. (P4's
/// example pairs N11 with N22 and N12 with N42: it numbers the ends after fig. 4,
/// which the text we have lacks; here they are numbered round the window.)
fn corner_rays(k: usize) -> u8 {
    (1u8 << (2 * k + 1)) | (1u8 << (2 * ((k + 1) % 4)))
}

/// БВО, the window-corner buffer: corners that the polygon's boundary has gone round
/// since the last output, at most the four corners, each at most once.
#[derive(Clone, Copy, Debug, Default)]
struct CornerBuffer {
    corners: [u8; 4],
    len: usize,
}

impl CornerBuffer {
    fn push(&mut self, k: usize) {
        if self.len < self.corners.len() {
            self.corners[self.len] = k as u8;
            self.len += 1;
        }
    }

    /// Takes corner k out. It is always the top of the stack (the proof is in
    /// [`AllBorders`]), which is what P4's last-in first-out buffer gives; searching
    /// keeps it right even if rounding ever broke the nesting.
    fn remove(&mut self, k: usize) {
        if let Some(i) = self.corners[..self.len].iter().rposition(|&c| usize::from(c) == k) {
            self.corners.copy_within(i + 1..self.len, i);
            self.len -= 1;
        }
    }
}

/// A crossing of an edge with a border line (P7).
#[derive(Clone, Copy, Debug)]
struct Cut {
    /// Parameter along the edge, 0 at its start, 1 at its end.
    t: f64,
    /// The crossing point.
    p: DVec2,
    /// Index of the border in [`Border::AROUND`].
    border: usize,
    /// The edge starts outside this border and ends inside it.
    entering: bool,
}

/// An event on an edge, found by P7 and ordered by P8/P9.
#[derive(Clone, Copy, Debug)]
enum Event {
    /// The edge crosses a border line on the window side: a point of the clipped
    /// polygon.
    Inner(DVec2),
    /// The edge crosses a border line outside the window.
    Outer(Ray),
}

/// P4 fig. 3: the all-borders clipper, a streaming unit like a [`HalfPlaneStage`]
/// that takes the face stream and gives the clipped face stream.
///
/// For each edge (previous, current vertex):
/// - P6: the outcodes of both ends, all four borders at once ([`outcode`]);
/// - P7: for each border whose bit differs, in the fixed order, the crossing of the
///   edge with the border line and its place: on the window side (IP_i) or beyond
///   one of the side's ends (N_i1, N_i2). Which crossings are on the window sides is
///   decided by their order along the edge rather than by their rounded positions
///   (see "Rounding");
/// - P8, P9: the crossings ordered along the edge. P8 asks for the distance S of each
///   crossing; its parameter t along the edge is proportional to that distance and
///   needs no square root, so the crossings are ordered by t (stably, so that equal t
///   keep the fixed border order);
/// - P10: in that order, a crossing on the window side is output, after the corners
///   waiting in БВО (P4: "before each output of an intersection with an inner border
///   of the window"); a crossing beyond a corner toggles that ray's N flag, and when
///   both rays of corner k are set (the boundary has gone from one side's outer
///   region round corner k to the other's) both flags are cleared and C_k is
///   incremented: at 1 the corner goes into the corner buffer БВО, at 2 it is taken
///   out again and C_k reset (the boundary went round the corner and back: no wrap);
/// - P11: the current vertex is output if it is inside.
///
/// At the end the corner buffer is emptied too; P12: if nothing has been output yet
/// (the window lies inside the polygon), the first corner out of it becomes the first
/// point, in БПТ.
///
/// # Why it is correct, and where it departs from P4
///
/// The paper's corner logic is a sketch; this is how it is made exact for a convex
/// polygon (in exact arithmetic; rounding: below). Corner k is a vertex of the
/// clipped polygon iff the polygon contains it.
/// Look at the two rays that continue the window's sides beyond k; between them lies
/// the corner region, where a point is outside two borders.
/// - If the polygon contains k, its boundary crosses each ray exactly once (a ray from
///   an inside point leaves a convex polygon once), and the boundary between the two
///   crossings stays in the corner region, outside the window: the crossings come one
///   after the other, within the excursion outside the window that goes round k, so
///   C_k becomes 1 there and k is output before the next point of the polygon, the
///   re-entry into the window: the right place.
/// - If it does not, each ray is crossed 0 or 2 times. One ray crossed twice (the
///   boundary dips into the corner region and leaves it the way it came) toggles its
///   flag back: no count. Both rays crossed twice happens only when the polygon lies
///   beyond the corner and misses the window altogether; its boundary then meets the
///   rays in the cyclic order a a b b, which, read from wherever the vertex list
///   starts, gives no count (a a b b, b b a a) or C_k = 1 and then C_k = 2, which
///   takes k out again (a b b a, b a a b). Departure: the paper *sets* the flags;
///   read as a a b b, set flags would leave a lone corner for a face that misses the
///   window, so they are toggled (a ray crossed twice cancels).
/// - The removed corner is always the top of БВО: between its two counts the boundary
///   stays beyond one border line, where no other corner can be gone round. This is
///   what a last-in first-out buffer is right for (`remove` searches all the same, in
///   case rounding ever broke the nesting).
/// - Departure: the buffer is emptied into the output first-in first-out, in the order
///   the corners were gone round. The paper says "first in, last out"; that would
///   reverse a run of two or more corners: a polygon over the top of the window,
///   leaving through the left side and coming back through the right, goes round
///   top-left and then top-right, and must output them in that order.
/// - Emptying the buffer before each intersection with an inner border, as P4 does,
///   is enough: the boundary always comes back into the window through such an
///   intersection (also when it enters through a vertex on a border: the crossing is
///   then at t = 1), so a corner never waits past an inside vertex.
/// - The start of the vertex list needs no care, although it may cut the excursion
///   that goes round a corner: the flags pair the corner's two crossings whatever
///   comes between them. A corner completed before the first output is output first,
///   one completed after the last output is output at the end; in the cyclic polygon
///   both land between the last exit from the window and the first entry, in the
///   order gone round. If nothing is output before the end (the window lies inside
///   the polygon), P12 makes the first corner the first point.
///
/// # Rounding
///
/// In exact arithmetic a crossing is on a window side iff it is where the edge enters
/// or leaves the window: the last crossing into a half-plane (t_in) or the first
/// crossing out of one (t_out), when t_in <= t_out (the Liang-Barsky rule). P7 decides
/// it so, not by comparing the rounded crossing with the side's ends, because near a
/// corner the two disagree: an edge from a corner region into the window crosses both
/// lines of the corner, exactly one of them on a side; rounded, both may land on the
/// sides, or both beyond, and for an edge nearly parallel to a border the crossing
/// with that border is uncertain along it by far more than a rounding error (slope
/// 10^-5: 10^5 times more). The tests found both: a bottom-left corner lost (both
/// crossings beyond, in the wrong order along the edge, so the flags never paired) and
/// a spurious second entry point 10^-10 from the first, making a notch. With the
/// order rule every entry and exit gives exactly one point on a side, every return
/// into the window starts with one (which the corner buffer waits for), and a crossing
/// that rounding puts on a side but that is not the entry or exit counts as beyond
/// the nearer end. A ray then read for the other ray of the same corner changes only
/// that corner's count, next to its entry or exit point, where taking or leaving the
/// corner moves the polygon by a rounding error.
#[derive(Clone, Copy, Debug)]
struct AllBorders {
    win: Window,
    /// A vertex has arrived (cleared again after the last one).
    started: bool,
    /// The previous vertex and its P6 outcode.
    prev: DVec2,
    prev_code: u8,
    /// БПТ, the first-point buffer: the first output point, output again to close.
    bpt: Option<DVec2>,
    /// The N flags, one per ray: bit r for ray r (see [`Ray`]).
    n_flags: u8,
    /// C_k, the wrap counters of the corners.
    counters: [u8; 4],
    /// БВО, the corner buffer.
    bvo: CornerBuffer,
}

impl AllBorders {
    fn new(win: Window) -> Self {
        AllBorders {
            win,
            started: false,
            prev: DVec2::ZERO,
            prev_code: 0,
            bpt: None,
            n_flags: 0,
            counters: [0; 4],
            bvo: CornerBuffer::default(),
        }
    }

    /// Takes the next vertex of the face stream (`last`: it is the closing repeat of
    /// the first vertex) and passes the clipped face stream to `emit`.
    fn feed<F: FnMut(DVec2, bool)>(&mut self, cur: DVec2, last: bool, emit: &mut F) {
        let code = outcode(&self.win, cur); // P6
        if self.started {
            self.edge(cur, code, emit);
        } else {
            self.started = true;
        }
        // P11, except for the closing repeat of the first vertex: already output.
        if code == 0 && !last {
            self.emit_point(cur, emit);
        }
        self.prev = cur;
        self.prev_code = code;
        if last {
            self.close(emit);
        }
    }

    /// P7..P10 for the edge from the previous vertex to `cur`.
    fn edge<F: FnMut(DVec2, bool)>(&mut self, cur: DVec2, code: u8, emit: &mut F) {
        let crossed = self.prev_code ^ code;
        if crossed == 0 {
            return;
        }
        // P7: the crossings, in the fixed border order.
        let mut cuts = [Cut { t: 0.0, p: DVec2::ZERO, border: 0, entering: false }; 4];
        let mut n = 0;
        for (i, border) in Border::AROUND.into_iter().enumerate() {
            if crossed & (1 << i) != 0 {
                let (t, p) = border.cut(&self.win, self.prev, cur);
                let entering = self.prev_code & (1 << i) != 0;
                cuts[n] = Cut { t, p, border: i, entering };
                n += 1;
            }
        }
        // Which crossings are on the window sides: the edge is in the window from the
        // last crossing into a half-plane to the first crossing out of one (t_in,
        // t_out), if those come in that order and no border has both ends outside.
        let cuts = &cuts[..n];
        let t_in = cuts.iter().filter(|c| c.entering).fold(0.0, |m, c| c.t.max(m));
        let t_out = cuts.iter().filter(|c| !c.entering).fold(1.0, |m, c| c.t.min(m));
        let meets = self.prev_code & code == 0 && t_in <= t_out;
        let mut events = [(0.0, Event::Outer(0)); 4];
        for (event, c) in events.iter_mut().zip(cuts) {
            let border = Border::AROUND[c.border];
            let on_side = meets && c.t == if c.entering { t_in } else { t_out };
            *event = if on_side {
                (c.t, Event::Inner(border.onto_side(&self.win, c.p)))
            } else {
                let end = border.beyond(&self.win, c.p);
                (c.t, Event::Outer(2 * c.border as u8 + u8::from(end == End::Second)))
            };
        }
        // P8, P9: along the edge (a stable insertion sort of at most four).
        for i in 1..n {
            let mut j = i;
            while j > 0 && events[j].0 < events[j - 1].0 {
                events.swap(j, j - 1);
                j -= 1;
            }
        }
        // P10.
        for &(_, event) in &events[..n] {
            match event {
                Event::Inner(p) => {
                    self.flush(emit);
                    self.emit_point(p, emit);
                }
                Event::Outer(r) => self.count(r),
            }
        }
    }

    /// P10's corner logic for a crossing of ray `r`: toggle its N flag; when both rays
    /// of its corner are set, clear them and count.
    fn count(&mut self, r: Ray) {
        self.n_flags ^= 1 << r;
        let k = ray_corner(r);
        let rays = corner_rays(k);
        if self.n_flags & rays == rays {
            self.n_flags &= !rays;
            self.counters[k] += 1;
            if self.counters[k] == 1 {
                self.bvo.push(k);
            } else {
                self.bvo.remove(k);
                self.counters[k] = 0;
            }
        }
    }

    /// Empties БВО into the output, in the order the corners were gone round.
    fn flush<F: FnMut(DVec2, bool)>(&mut self, emit: &mut F) {
        let bvo = std::mem::take(&mut self.bvo);
        for &k in &bvo.corners[..bvo.len] {
            self.emit_point(self.win.corner(usize::from(k)), emit);
        }
    }

    /// Outputs a point of the clipped polygon; the first one also goes into БПТ (P12
    /// when it is a corner).
    fn emit_point<F: FnMut(DVec2, bool)>(&mut self, p: DVec2, emit: &mut F) {
        if self.bpt.is_none() {
            self.bpt = Some(p);
        }
        emit(p, false);
    }

    /// The end of the face: empty БВО (P12 if nothing was output before), close with
    /// БПТ, and get ready for the next face.
    fn close<F: FnMut(DVec2, bool)>(&mut self, emit: &mut F) {
        self.flush(emit);
        if let Some(p) = self.bpt {
            emit(p, true);
        }
        *self = AllBorders::new(self.win);
    }
}

/// P4 fig. 3: clips `poly` by `win` into `out` (cleared first) testing each vertex
/// against all four borders at once, ordering the border crossings along each edge,
/// and inserting the window corners that the polygon wraps through the corner
/// counters C_k and the corner buffer. Output conventions: see the module doc.
///
/// The operations P6..P12, why the corner logic is exact, and where it departs from
/// the paper are documented on `AllBorders` in the source. In short: the corner
/// buffer is emptied in the order the corners were gone round (the paper's "first in,
/// last out" would reverse two or more corners in a row), the flags of the rays
/// beyond a corner are toggled rather than set, and which crossings are on the
/// window sides is decided by their order along the edge, robust to rounding.
pub fn clip_all_borders(poly: &[DVec2], win: &Window, out: &mut Vec<DVec2>) {
    out.clear();
    if !win.is_proper() || poly.is_empty() {
        return;
    }
    let mut block = AllBorders::new(*win);
    {
        let mut sink = |p: DVec2, last: bool| {
            if !last {
                out.push(p);
            }
        };
        for &v in poly {
            block.feed(v, false, &mut sink);
        }
        block.feed(poly[0], true, &mut sink);
    }
    finish(poly, win, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No input leads the automaton into a forbidden state: walk every state reachable
    /// from the initial one under every input (inside or not, last or not).
    #[test]
    fn table_1_never_reaches_a_forbidden_state() {
        let mut seen = [false; 16];
        let mut todo = vec![Flags::INITIAL];
        while let Some(state) = todo.pop() {
            for inside in [false, true] {
                for last in [false, true] {
                    let mut f = state.set(Flags::F2, inside);
                    if last {
                        f = f.set(Flags::F4, true);
                    }
                    let next = match TABLE_1[f.word()] {
                        Row::Exit => f,
                        Row::Run { set, clear, .. } => f.set(set, true).set(clear, false),
                        Row::Forbidden => panic!("forbidden state {:04b}", f.0),
                    };
                    let next = if last { Flags::INITIAL } else { next.set(Flags::F2, false) };
                    if !seen[next.word()] {
                        seen[next.word()] = true;
                        todo.push(next);
                    }
                }
            }
        }
    }

    /// One stage alone, exhaustively: every inside/outside pattern of up to 8 vertices
    /// gives a closed stream whose open part is the Sutherland-Hodgman pass.
    #[test]
    fn one_stage_is_one_sutherland_hodgman_pass() {
        let win = Window { x0: 0.0, y0: -10.0, x1: 10.0, y1: 10.0 };
        for n in 1..=8 {
            for pattern in 0u32..1 << n {
                let poly: Vec<DVec2> = (0..n)
                    .map(|i| {
                        let x = if pattern >> i & 1 == 1 { 1.0 + i as f64 } else { -1.0 - i as f64 };
                        DVec2::new(x, i as f64)
                    })
                    .collect();
                let mut stage = HalfPlaneStage::new(Border::Left, win);
                let mut got = Vec::new();
                for (i, &v) in poly.iter().chain(&poly[..1]).enumerate() {
                    stage.feed(v, i == n, &mut |p, last| got.push((p, last)));
                }
                let mut want = Vec::new();
                for (i, &q) in poly.iter().enumerate() {
                    let p = poly[(i + n - 1) % n];
                    let (pin, qin) = (p.x >= 0.0, q.x >= 0.0);
                    if pin != qin {
                        want.push(Border::Left.cut(&win, p, q).1);
                    }
                    if qin {
                        want.push(q);
                    }
                }
                if want.is_empty() {
                    assert!(got.is_empty(), "pattern {pattern:0n$b}: {got:?}");
                    continue;
                }
                let (closing, last) = got.pop().expect("closed stream");
                assert!(last && got.iter().all(|&(_, l)| !l));
                assert_eq!(closing, got[0].0);
                let got: Vec<DVec2> = got.into_iter().map(|(p, _)| p).collect();
                let k = (0..want.len()).find(|&k| want[k] == got[0]).expect("same first point");
                want.rotate_left(k);
                assert_eq!(got, want, "pattern {pattern:0n$b}");
            }
        }
    }

    /// A face beyond the top-left corner whose boundary crosses both rays of the corner
    /// twice: whatever the starting vertex and the winding, the raw stream of the
    /// all-borders clipper is empty (with set flags instead of toggled ones, the
    /// reading a a b b would leave a lone corner).
    #[test]
    fn corner_gone_round_and_back_cancels() {
        let win = Window { x0: 0.0, y0: 0.0, x1: 4.0, y1: 4.0 };
        // Two vertices in the corner region (on the quad's edges), so that some start
        // reads the crossings as a a b b.
        let mut face = [
            DVec2::new(-3.0, 1.0),
            DVec2::new(-2.0, 0.5),
            DVec2::new(-0.5, -0.75),
            DVec2::new(1.0, -2.0),
            DVec2::new(0.5, -3.0),
            DVec2::new(-1.25, -1.0),
        ];
        for _ in 0..2 {
            face.reverse();
            for k in 0..face.len() {
                face.rotate_left(1);
                let mut block = AllBorders::new(win);
                let mut got = Vec::new();
                for (i, &v) in face.iter().chain(&face[..1]).enumerate() {
                    block.feed(v, i == face.len(), &mut |p, _| got.push(p));
                }
                assert!(got.is_empty(), "start {k}: {got:?}");
            }
        }
    }

    #[test]
    fn rays_and_corners_agree() {
        for k in 0..4 {
            let rays = corner_rays(k);
            assert_eq!(rays.count_ones(), 2);
            for r in 0..8 {
                assert_eq!(rays >> r & 1 == 1, ray_corner(r) == k, "ray {r} corner {k}");
            }
        }
    }
}
