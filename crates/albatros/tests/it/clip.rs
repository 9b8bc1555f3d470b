//! Tests: the clipping block (`gp::clip`, P4). Hand-checked examples through one
//! data-driven `check(input, window, expected)` helper, then properties over tens of
//! thousands of random faces: the automaton (P4 table 1) and the all-borders clipper
//! (P4 fig. 3) give the reference Sutherland-Hodgman polygon up to the starting vertex
//! and rounding; every output is convex, inside the window, wound like its input, free
//! of repeated points, and its area is the area of the exact intersection, computed
//! here independently by integrating the polygon's vertical sections over the window.
//! Generators: random convex polygons over a range several times the window's, so that
//! every case occurs (a coverage test counts them); polygons built to wrap exactly 1,
//! 2, 3 or 4 corners; small-integer polygons, where vertices fall on borders, edges run
//! along them and through corners; repeated, collinear and closing vertices; and
//! wholly collinear faces, which must clip to nothing.

use std::f64::consts::TAU;

use albatros::gp::clip::*;
use glam::DVec2;
use proptest::prelude::*;
use proptest::sample::{subsequence, Index};
use proptest::strategy::ValueTree;
use proptest::test_runner::{Config, TestRunner};

type Clipper = fn(&[DVec2], &Window, &mut Vec<DVec2>);

const CLIPPERS: [(&str, Clipper); 3] =
    [("reference", clip_reference), ("automaton", clip_automaton), ("all_borders", clip_all_borders)];

/// Agreement between clippers, and with hand-checked values, relative to the scale.
const REL_TOL: f64 = 1e-9;

fn win(x0: f64, y0: f64, x1: f64, y1: f64) -> Window {
    Window { x0, y0, x1, y1 }
}

fn pts(p: &[(f64, f64)]) -> Vec<DVec2> {
    p.iter().map(|&(x, y)| DVec2::new(x, y)).collect()
}

/// The largest coordinate magnitude of the polygon and the window.
fn scale(poly: &[DVec2], w: &Window) -> f64 {
    poly.iter().fold(w.x0.abs().max(w.x1.abs()).max(w.y0.abs()).max(w.y1.abs()), |m, p| m.max(p.abs().max_element()))
}

/// Twice the signed area (positive for counter-clockwise with y up).
fn area2(poly: &[DVec2]) -> f64 {
    let Some(&o) = poly.first() else { return 0.0 };
    (0..poly.len()).map(|i| (poly[i] - o).perp_dot(poly[(i + 1) % poly.len()] - o)).sum()
}

/// Drops every vertex within `tol` of the line through its neighbours, until none is:
/// what is one point, or one straight side, to rounding.
fn to_rounding(poly: &[DVec2], tol: f64) -> Vec<DVec2> {
    let mut p = poly.to_vec();
    let mut i = 0;
    let mut kept = 0;
    while p.len() >= 3 && kept < p.len() {
        let n = p.len();
        let (a, v, b) = (p[(i + n - 1) % n], p[i], p[(i + 1) % n]);
        let d = b - a;
        if d.length() <= tol || d.perp_dot(v - a).abs() <= tol * d.length() {
            p.remove(i);
            kept = 0;
        } else {
            i += 1;
            kept += 1;
        }
        i %= p.len().max(1);
    }
    if p.len() < 3 {
        p.clear();
    }
    p
}

/// The same polygon to rounding: after [`to_rounding`], equal up to the starting
/// vertex, each coordinate within `tol`.
fn same_to_rounding(a: &[DVec2], b: &[DVec2], tol: f64) -> bool {
    same_cyclic(&to_rounding(a, tol), &to_rounding(b, tol), tol)
}

/// Equal up to the starting vertex, each coordinate within `tol`.
fn same_cyclic(a: &[DVec2], b: &[DVec2], tol: f64) -> bool {
    a.len() == b.len()
        && (a.is_empty()
            || (0..b.len()).any(|k| (0..a.len()).all(|i| (a[i] - b[(i + k) % b.len()]).abs().max_element() <= tol)))
}

/// The area of `poly ∩ win`, independently of any clipper: the length of the vertical
/// section of the polygon inside the window is piecewise linear in x, with breaks at
/// the vertices and where edges cross the window's horizontal borders, so the midpoint
/// rule is exact between breaks. Convex (or degenerate convex) polygons only.
fn exact_area(poly: &[DVec2], w: &Window) -> f64 {
    let n = poly.len();
    let edges = || (0..n).map(move |i| (poly[i], poly[(i + 1) % n]));
    let mut xs = vec![w.x0, w.x1];
    for (a, b) in edges() {
        xs.push(a.x);
        for y in [w.y0, w.y1] {
            if (a.y - y) * (b.y - y) < 0.0 {
                xs.push(a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y));
            }
        }
    }
    xs.retain(|&x| x >= w.x0 && x <= w.x1);
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let section = |x: f64| {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (a, b) in edges() {
            if a.x != b.x && a.x.min(b.x) <= x && x <= a.x.max(b.x) {
                let y = a.y + (b.y - a.y) * (x - a.x) / (b.x - a.x);
                lo = lo.min(y);
                hi = hi.max(y);
            }
        }
        (hi.min(w.y1) - lo.max(w.y0)).max(0.0)
    };
    xs.windows(2).map(|p| section(0.5 * (p[0] + p[1])) * (p[1] - p[0])).sum()
}

/// Whether the convex polygon (either winding) strictly contains `c`.
fn contains(poly: &[DVec2], c: DVec2) -> bool {
    let s = area2(poly).signum();
    s != 0.0
        && (0..poly.len()).all(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            s * (b - a).perp_dot(c - a) > 0.0
        })
}

fn corners(w: &Window) -> [DVec2; 4] {
    [DVec2::new(w.x0, w.y0), DVec2::new(w.x1, w.y0), DVec2::new(w.x1, w.y1), DVec2::new(w.x0, w.y1)]
}

/// Convex hull (Andrew's monotone chain), counter-clockwise with y up, no collinear
/// vertices; fewer than three points for degenerate input.
fn hull(points: &[DVec2]) -> Vec<DVec2> {
    let mut p = points.to_vec();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let turn = |h: &[DVec2], q: DVec2| {
        let (o, a) = (h[h.len() - 2], h[h.len() - 1]);
        (a - o).perp_dot(q - o)
    };
    // The lower chain left to right, then the upper chain back, never popping into
    // the lower one.
    let mut h: Vec<DVec2> = Vec::with_capacity(2 * p.len());
    for &q in &p {
        while h.len() >= 2 && turn(&h, q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    let lower = h.len() + 1;
    for &q in p.iter().rev().skip(1) {
        while h.len() >= lower && turn(&h, q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    h.pop(); // the first point again
    h
}

/// Hand-checked example: every clipper gives `expected` up to the starting vertex.
#[track_caller]
fn check(input: &[(f64, f64)], w: Window, expected: &[(f64, f64)]) {
    let (input, expected) = (pts(input), pts(expected));
    let tol = REL_TOL * scale(&input, &w);
    let mut out = Vec::new();
    for (name, clip) in CLIPPERS {
        clip(&input, &w, &mut out);
        assert!(same_cyclic(&out, &expected, tol), "{name}: {input:?} in {w:?}\n got {out:?}\nwant {expected:?}");
    }
}

/// The properties every face must have; returns the reference output.
#[track_caller]
fn check_properties(poly: &[DVec2], w: &Window) -> Vec<DVec2> {
    let s = scale(poly, w);
    let tol = REL_TOL * s;
    let exact = exact_area(poly, w);
    let area_tol = tol * 2.0 * ((w.x1 - w.x0) + (w.y1 - w.y0));
    let in_sign = area2(poly).signum();
    let mut outs: [Vec<DVec2>; 3] = Default::default();
    for ((name, clip), out) in CLIPPERS.iter().zip(&mut outs) {
        clip(poly, w, out);
        let ctx = || format!("{name}: {poly:?} in {w:?}\n got {out:?}");
        let n = out.len();
        assert!(n == 0 || n >= 3, "{}", ctx());
        for (i, &p) in out.iter().enumerate() {
            let q = out[(i + 1) % n];
            assert!(p != q, "repeated point {p}: {}", ctx());
            assert!(
                p.x >= w.x0 - tol && p.x <= w.x1 + tol && p.y >= w.y0 - tol && p.y <= w.y1 + tol,
                "{p} outside the window: {}",
                ctx()
            );
        }
        let a2 = area2(out);
        if n > 0 {
            assert_eq!(a2.signum(), in_sign, "winding changed: {}", ctx());
            // Convex: every vertex on the inner side of every edge, to rounding: as if
            // each point could move by `tol` (which can turn a short edge a lot).
            for i in 0..n {
                let (a, b) = (out[i], out[(i + 1) % n]);
                for &c in out.iter() {
                    assert!(
                        in_sign * (b - a).perp_dot(c - a) >= -tol * ((c - a).length() + (c - b).length()),
                        "not convex at edge {a} {b}, vertex {c}: {}",
                        ctx()
                    );
                }
            }
        }
        assert!((0.5 * a2.abs() - exact).abs() <= area_tol, "area {} != exact {exact}: {}", 0.5 * a2.abs(), ctx());
    }
    let [reference, automaton, all_borders] = outs;
    for (name, out) in [("automaton", &automaton), ("all_borders", &all_borders)] {
        assert!(
            same_to_rounding(out, &reference, tol),
            "{name} != reference: {poly:?} in {w:?}\n  got {out:?}\n want {reference:?}"
        );
    }
    reference
}

// ---------------------------------------------------------------------------------
// Hand-checked examples (window [0, 4] x [0, 4] unless stated; y is down, so the
// top border is y = 0)
// ---------------------------------------------------------------------------------

const W4: Window = Window { x0: 0.0, y0: 0.0, x1: 4.0, y1: 4.0 };

#[test]
fn inside_is_unchanged() {
    check(&[(1.0, 1.0), (3.0, 1.0), (2.0, 3.0)], W4, &[(1.0, 1.0), (3.0, 1.0), (2.0, 3.0)]);
    let square = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)];
    check(&square, W4, &square);
}

#[test]
fn outside_is_empty() {
    check(&[(5.0, 1.0), (7.0, 1.0), (6.0, 3.0)], W4, &[]);
    // Round a corner, crossing both rays beyond it, without touching the window.
    check(&[(-3.0, 1.0), (-2.0, 0.5), (1.0, -2.0), (0.5, -3.0)], W4, &[]);
}

#[test]
fn one_vertex_beyond_the_left_border() {
    check(&[(-2.0, 2.0), (2.0, 0.0), (2.0, 4.0)], W4, &[(0.0, 1.0), (2.0, 0.0), (2.0, 4.0), (0.0, 3.0)]);
}

#[test]
fn wraps_one_corner() {
    // The edge (-2, 1) -> (1, -2) passes outside the top-left corner.
    check(&[(-2.0, 1.0), (1.0, -2.0), (3.0, 3.0)], W4, &[(0.0, 0.0), (1.8, 0.0), (3.0, 3.0), (0.0, 1.8)]);
}

#[test]
fn wraps_two_corners_in_the_order_gone_round() {
    // Leaves through the left side, goes round top-left then top-right, comes back
    // through the right side: a last-in first-out corner buffer would swap them.
    check(&[(-1.0, 2.0), (5.0, 2.0), (2.0, -6.0)], W4, &[(0.0, 2.0), (4.0, 2.0), (4.0, 0.0), (0.0, 0.0)]);
}

#[test]
fn wraps_three_corners() {
    check(
        &[(-2.0, -2.0), (6.0, -2.0), (6.0, 6.0), (-2.0, 3.0)],
        W4,
        &[(4.0, 0.0), (4.0, 4.0), (2.0 / 3.0, 4.0), (0.0, 3.75), (0.0, 0.0)],
    );
}

#[test]
fn window_inside_a_huge_triangle_keeps_the_winding() {
    let w = win(0.0, 0.0, 640.0, 480.0);
    let big = [(-1e6, -1e6), (2e6, -1e6), (-1e6, 2e6)];
    let window = [(0.0, 0.0), (640.0, 0.0), (640.0, 480.0), (0.0, 480.0)];
    check(&big, w, &window);
    let (mut big_rev, mut window_rev) = (big, window);
    big_rev.reverse();
    window_rev.reverse();
    check(&big_rev, w, &window_rev);
}

#[test]
fn diamond_cuts_all_four_corners() {
    check(
        &[(2.0, -1.0), (5.0, 2.0), (2.0, 5.0), (-1.0, 2.0)],
        W4,
        &[(3.0, 0.0), (4.0, 1.0), (4.0, 3.0), (3.0, 4.0), (1.0, 4.0), (0.0, 3.0), (0.0, 1.0), (1.0, 0.0)],
    );
}

#[test]
fn edge_through_a_corner() {
    check(&[(-1.0, 1.0), (1.0, -1.0), (3.0, 3.0)], W4, &[(0.0, 0.0), (1.5, 0.0), (3.0, 3.0), (0.0, 1.5)]);
}

/// Found by `edges_through_corners`: the edge from (68.5, 17.7) to (17.9, 55.8)
/// passes through the bottom-left corner; rounded, both its crossings there fell
/// beyond the corner, in the wrong order along the edge, and the all-borders clipper
/// lost the corner.
#[test]
fn regression_corner_lost_to_rounding() {
    let poly = pts(&[
        (-9.324753297961639, 70.77940583078043),
        (68.51683217248525, 17.657861443143183),
        (17.94172469406047, 55.8240634970338),
    ]);
    let w = win(24.351395373768415, 0.0, 52.255807409460154, 50.98704389475235);
    let corner = DVec2::new(w.x0, w.y1);
    let tol = REL_TOL * scale(&poly, &w);
    check_properties(&poly, &w);
    for (name, clip) in CLIPPERS {
        let mut out = Vec::new();
        clip(&poly, &w, &mut out);
        assert!(out.iter().any(|p| p.distance(corner) <= tol), "{name}: {out:?}");
    }
}

/// Found by `edges_through_corners` (at 25 times the usual number of cases): the
/// edge from (98.3, 31.83424) to (85.5, 31.83438), nearly parallel to the top
/// border, passes within 10^-15 of the top-right corner; both its crossings there
/// came out on the window sides, 10^-10 apart, and the all-borders clipper made a
/// notch of two entry points.
#[test]
fn regression_notch_at_a_grazed_corner() {
    let poly = pts(&[
        (98.33554002255958, 31.834241832017156),
        (85.54324210691748, 31.834381380755246),
        (0.0, 31.834375231238923),
    ]);
    let w = win(0.0, 31.834375231238923, 86.1069623235282, 43.108779564124085);
    let mut out = Vec::new();
    clip_all_borders(&poly, &w, &mut out);
    assert_eq!(out.len(), 3, "{out:?}");
    check_properties(&poly, &w);
}

#[test]
fn touching_only_is_empty() {
    // An edge along the right border, the rest outside.
    check(&[(4.0, 1.0), (6.0, 1.0), (4.0, 3.0)], W4, &[]);
    // A vertex on the top-left corner, the rest outside.
    check(&[(0.0, 0.0), (-2.0, -1.0), (-1.0, -2.0)], W4, &[]);
}

#[test]
fn degenerate_input() {
    // Collinear: zero area.
    check(&[(-1.0, -1.0), (2.0, 2.0), (5.0, 5.0)], W4, &[]);
    // Repeated vertices and an explicit closing vertex.
    check(
        &[(1.0, 1.0), (1.0, 1.0), (3.0, 1.0), (3.0, 1.0), (2.0, 3.0), (1.0, 1.0)],
        W4,
        &[(1.0, 1.0), (3.0, 1.0), (2.0, 3.0)],
    );
    // Fewer than three vertices.
    check(&[], W4, &[]);
    check(&[(1.0, 1.0)], W4, &[]);
    check(&[(1.0, 1.0), (2.0, 2.0)], W4, &[]);
    // An improper window.
    check(&[(1.0, 1.0), (3.0, 1.0), (2.0, 3.0)], win(4.0, 0.0, 0.0, 4.0), &[]);
}

#[test]
fn non_finite_input_does_not_panic() {
    let mut out = Vec::new();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let poly = pts(&[(1.0, 1.0), (bad, 1.0), (2.0, 3.0)]);
        for (_, clip) in CLIPPERS {
            clip(&poly, &W4, &mut out);
            assert!(out.iter().all(|p| p.is_finite()) || out.is_empty());
        }
    }
}

#[test]
fn output_is_cleared_first() {
    for (name, clip) in CLIPPERS {
        let mut out = pts(&[(9.0, 9.0)]);
        clip(&pts(&[(5.0, 1.0), (7.0, 1.0), (6.0, 3.0)]), &W4, &mut out);
        assert!(out.is_empty(), "{name}");
    }
}

// ---------------------------------------------------------------------------------
// Generators
// ---------------------------------------------------------------------------------

fn window() -> impl Strategy<Value = Window> {
    (-50.0..50.0f64, -50.0..50.0f64, 1.0..100.0f64, 1.0..100.0f64)
        .prop_map(|(x0, y0, w, h)| win(x0, y0, x0 + w, y0 + h))
}

/// A point of the window's frame: (0, 0) is the top-left corner, (1, 1) the
/// bottom-right one.
fn at(w: &Window, u: f64, v: f64) -> DVec2 {
    DVec2::new(w.x0 + u * (w.x1 - w.x0), w.y0 + v * (w.y1 - w.y0))
}

/// Either winding, any starting vertex.
fn arrange(mut poly: Vec<DVec2>, reverse: bool, start: Index) -> Vec<DVec2> {
    if reverse {
        poly.reverse();
    }
    if !poly.is_empty() {
        let k = start.index(poly.len());
        poly.rotate_left(k);
    }
    poly
}

/// Random convex polygons: hulls of 3..12 random points spread over 0.8 to 2000 times
/// the window's size around its centre.
fn convex_case() -> impl Strategy<Value = (Vec<DVec2>, Window)> {
    (
        window(),
        prop_oneof![Just(0.4), Just(1.0), Just(2.0), Just(20.0), Just(1000.0)],
        prop::collection::vec((-1.0..1.0f64, -1.0..1.0f64), 3..12),
        any::<bool>(),
        any::<Index>(),
    )
        .prop_map(|(w, spread, uv, reverse, start)| {
            let p: Vec<DVec2> = uv.iter().map(|&(u, v)| at(&w, 0.5 + spread * u, 0.5 + spread * v)).collect();
            (arrange(hull(&p), reverse, start), w)
        })
}

/// Polygons that wrap exactly the corners in `chosen`: the hull of an equilateral
/// triangle around each chosen corner (circumradius under 0.45 of the window's
/// smaller side), plus up to two points out along each chosen corner's outward
/// diagonal. Everything stays within that radius of the chosen corners and their
/// outward diagonals, which keeps every other corner at least 0.7 of the smaller side
/// away: outside.
fn wrap_case(k: usize) -> impl Strategy<Value = (Vec<DVec2>, Window, Vec<usize>)> {
    (
        window(),
        subsequence(vec![0usize, 1, 2, 3], k),
        prop::collection::vec((0.05..0.45f64, 0.0..TAU), 4),
        prop::collection::vec((0usize..4, 0.0..5.0f64, 0.0..0.45f64, 0.0..TAU), 0..3),
        any::<bool>(),
        any::<Index>(),
    )
        .prop_map(|(w, chosen, tri, extra, reverse, start)| {
            let m = (w.x1 - w.x0).min(w.y1 - w.y0);
            let cs = corners(&w);
            let dir = |a: f64| DVec2::new(a.cos(), a.sin());
            let mut p = Vec::new();
            for (&c, &(r, a)) in chosen.iter().zip(&tri) {
                for i in 0..3 {
                    p.push(cs[c] + r * m * dir(a + i as f64 * TAU / 3.0));
                }
            }
            for &(j, s, r, a) in &extra {
                let c = chosen[j % chosen.len()];
                let out = (cs[c] - at(&w, 0.5, 0.5)).signum();
                p.push(cs[c] + s * m * out + r * m * dir(a));
            }
            (arrange(hull(&p), reverse, start), w, chosen)
        })
}

/// Small-integer polygons in small integer windows: vertices on borders and corners,
/// edges along borders and through corners; then decorated with repeated vertices,
/// edge midpoints (collinear vertices) and a closing repeat of the first vertex.
fn grid_case() -> impl Strategy<Value = (Vec<DVec2>, Window)> {
    ((-2i32..2, -2i32..2, 1i32..5, 1i32..5), prop::collection::vec((-3i32..9, -3i32..9), 3..9), decorations()).prop_map(
        |((x0, y0, w, h), p, deco)| {
            let w = win(x0.into(), y0.into(), (x0 + w).into(), (y0 + h).into());
            let p: Vec<DVec2> = p.iter().map(|&(x, y)| DVec2::new((x0 - 1 + x).into(), (y0 - 1 + y).into())).collect();
            (deco.apply(hull(&p)), w)
        },
    )
}

/// Random convex polygons, decorated.
fn decorated_case() -> impl Strategy<Value = (Vec<DVec2>, Window)> {
    (convex_case(), decorations()).prop_map(|((p, w), deco)| (deco.apply(p), w))
}

#[derive(Clone, Debug)]
struct Decorations {
    repeats: Vec<Index>,
    midpoints: Vec<Index>,
    close: bool,
    reverse: bool,
    start: Index,
}

impl Decorations {
    fn apply(&self, mut p: Vec<DVec2>) -> Vec<DVec2> {
        if p.is_empty() {
            return p;
        }
        for i in &self.midpoints {
            let i = i.index(p.len());
            let m = 0.5 * (p[i] + p[(i + 1) % p.len()]);
            p.insert(i + 1, m);
        }
        for i in &self.repeats {
            let i = i.index(p.len());
            p.insert(i, p[i]);
        }
        let mut p = arrange(p, self.reverse, self.start);
        if self.close {
            p.push(p[0]);
        }
        p
    }
}

fn decorations() -> impl Strategy<Value = Decorations> {
    (
        prop::collection::vec(any::<Index>(), 0..4),
        prop::collection::vec(any::<Index>(), 0..3),
        any::<bool>(),
        any::<bool>(),
        any::<Index>(),
    )
        .prop_map(|(repeats, midpoints, close, reverse, start)| Decorations {
            repeats,
            midpoints,
            close,
            reverse,
            start,
        })
}

/// Wholly collinear faces: points along a line through the window's neighbourhood,
/// in order along it (a degenerate convex polygon: there and back), or three in any
/// order.
fn collinear_case() -> impl Strategy<Value = (Vec<DVec2>, Window)> {
    (
        window(),
        (-1.0..2.0f64, -1.0..2.0f64, 0.0..TAU),
        prop::collection::vec(-3.0..3.0f64, 2..8),
        any::<bool>(),
        any::<Index>(),
    )
        .prop_map(|(w, (u, v, a), mut s, sorted, start)| {
            if sorted || s.len() > 3 {
                s.sort_by(f64::total_cmp);
            }
            let m = (w.x1 - w.x0).max(w.y1 - w.y0);
            let (o, d) = (at(&w, u, v), DVec2::new(a.cos(), a.sin()));
            let p = s.iter().map(|&t| o + t * m * d).collect();
            (arrange(p, false, start), w)
        })
}

/// Triangles with an edge through a window corner (exactly in decimal, to rounding
/// in binary), in every direction: entering the window there, grazing it, or passing
/// from one side's outer region to the other's. With `near_axis`, the edge is within
/// 10^-4..10^-2 radians of a border's direction: the hard case, where the crossing
/// with that border is uncertain along it by a rounding error over the slope. (Much
/// flatter and any two correct clippers differ there by more than 10^-9 of the scale,
/// while still agreeing to 10^-15 as sets.)
fn through_corner_case(near_axis: bool) -> impl Strategy<Value = (Vec<DVec2>, Window)> {
    (
        window(),
        0usize..4,
        (0.0..TAU, 0u32..4, -4.0..-2.0f64, any::<bool>()),
        (0.05..3.0f64, 0.05..3.0f64),
        (-1.5..2.5f64, -1.5..2.5f64),
        any::<bool>(),
        any::<Index>(),
    )
        .prop_map(move |(w, k, (a, axis, log_slope, neg), (s1, s2), (u, v), reverse, start)| {
            let a = if near_axis {
                let off = 10f64.powf(log_slope);
                f64::from(axis) * TAU / 4.0 + if neg { -off } else { off }
            } else {
                a
            };
            let m = (w.x1 - w.x0).min(w.y1 - w.y0);
            let (c, d) = (corners(&w)[k], m * DVec2::new(a.cos(), a.sin()));
            let p = vec![c - s1 * d, c + s2 * d, at(&w, u, v)];
            (arrange(p, reverse, start), w)
        })
}

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

// ---------------------------------------------------------------------------------
// Properties
// ---------------------------------------------------------------------------------

proptest! {
    #![proptest_config(config(40_000))]
    #[test]
    fn random_convex_polygons((poly, w) in convex_case()) {
        check_properties(&poly, &w);
    }
}

proptest! {
    #![proptest_config(config(5_000))]
    #[test]
    fn wrapping_one_corner((poly, w, chosen) in wrap_case(1)) {
        check_wrap(&poly, &w, &chosen);
    }

    #[test]
    fn wrapping_two_corners((poly, w, chosen) in wrap_case(2)) {
        check_wrap(&poly, &w, &chosen);
    }

    #[test]
    fn wrapping_three_corners((poly, w, chosen) in wrap_case(3)) {
        check_wrap(&poly, &w, &chosen);
    }

    #[test]
    fn wrapping_four_corners((poly, w, chosen) in wrap_case(4)) {
        check_wrap(&poly, &w, &chosen);
    }

    #[test]
    fn collinear_faces_clip_to_nothing((poly, w) in collinear_case()) {
        for (name, clip) in CLIPPERS {
            let mut out = Vec::new();
            clip(&poly, &w, &mut out);
            prop_assert!(out.is_empty(), "{}: {:?} in {:?} gave {:?}", name, poly, w, out);
        }
    }
}

proptest! {
    #![proptest_config(config(20_000))]
    #[test]
    fn small_integer_polygons((poly, w) in grid_case()) {
        check_properties(&poly, &w);
    }

    #[test]
    fn decorated_convex_polygons((poly, w) in decorated_case()) {
        check_properties(&poly, &w);
    }

    #[test]
    fn edges_through_corners((poly, w) in through_corner_case(false)) {
        check_properties(&poly, &w);
    }

    #[test]
    fn nearly_flat_edges_through_corners((poly, w) in through_corner_case(true)) {
        check_properties(&poly, &w);
    }
}

proptest! {
    #![proptest_config(config(20_000))]
    /// The light points' clipper, with its shortcut for polygons wholly inside, is
    /// the reference bit for bit: on random convex polygons (inside, outside,
    /// crossing), on small-integer ones (vertices on the borders, where the
    /// shortcut's test must agree with the reference's `inside`), and on polygons
    /// with a non-finite coordinate.
    #[test]
    fn the_reference_unless_inside_is_the_reference(
        (poly, w) in prop_oneof![convex_case(), grid_case()],
        spoil in prop::option::of((any::<Index>(), prop_oneof![Just(f64::NAN), Just(f64::INFINITY)])),
    ) {
        let mut poly = poly;
        if let (Some((k, bad)), false) = (spoil, poly.is_empty()) {
            let k = k.index(poly.len());
            poly[k].x = bad;
        }
        let (mut want, mut got) = (Vec::new(), vec![DVec2::ONE]);
        clip_reference(&poly, &w, &mut want);
        clip_reference_unless_inside(&poly, &w, &mut got);
        let bits = |p: &[DVec2]| p.iter().map(|v| (v.x.to_bits(), v.y.to_bits())).collect::<Vec<_>>();
        prop_assert_eq!(bits(&got), bits(&want), "{:?} in {:?}", poly, w);
    }
}

/// The generator wraps exactly the chosen corners, and every one of them is a vertex
/// of the clipped polygon.
#[track_caller]
fn check_wrap(poly: &[DVec2], w: &Window, chosen: &[usize]) {
    let cs = corners(w);
    let wrapped: Vec<usize> = (0..4).filter(|&k| contains(poly, cs[k])).collect();
    assert_eq!(wrapped, chosen, "generator: {poly:?} in {w:?}");
    let out = check_properties(poly, w);
    for k in wrapped {
        assert!(out.contains(&cs[k]), "corner {k} missing: {poly:?} in {w:?}: {out:?}");
    }
}

/// The random generator really produces every case: faces inside, outside, crossing,
/// and wrapping each number of corners.
#[test]
fn random_generator_covers_every_case() {
    let mut runner = TestRunner::new(Config::default());
    let strategy = convex_case();
    let (mut inside, mut outside, mut crossing) = (0, 0, 0);
    let mut wraps = [0; 5];
    for _ in 0..4000 {
        let (poly, w) = strategy.new_tree(&mut runner).expect("case").current();
        let cs = corners(&w);
        wraps[cs.iter().filter(|&&c| contains(&poly, c)).count()] += 1;
        let exact = exact_area(&poly, &w);
        let area = 0.5 * area2(&poly).abs();
        if exact == 0.0 {
            outside += 1;
        } else if (exact - area).abs() <= 1e-9 * area {
            inside += 1;
        } else {
            crossing += 1;
        }
    }
    assert!(inside > 100 && outside > 100 && crossing > 100, "{inside} {outside} {crossing}");
    assert!(wraps.iter().all(|&n| n > 50), "corners wrapped: {wraps:?}");
}
