//! Set-up of a clipped polygon for the video processor (SYSTEM.md 3, "Setup for the
//! VP"; P2).
//!
//! Input: the polygon's plane and vertices in eye coordinates, its clipped screen
//! outline, its material. Output: one [`FramePolygon`] in the frame list with
//! - the outline snapped to the 1/256-pixel grid, duplicate, collinear and (after
//!   snapping) reflex vertices removed, so that it is strictly convex;
//! - its edges in the VP's code ([`EdgeCode`]);
//! - `1/Z` as a linear function of pixel `(x, y)` from the plane equation;
//! - intensity, and texture `u`, `v`, as fractional-linear functions
//!   `q = (A x + B y + C) / (1/Z)`: a quantity linear over the face in eye space,
//!   `q = q0 + g . (P - P0)`, divided by `Z` is linear on the screen;
//! - the texture-origin shift of P2: after the transform to eye coordinates the
//!   integer part of `D'` is dropped, so `u`, `v` stay small near the eye whatever the
//!   size of the textured plane;
//! - `PAR = (1/L) (1/|Dn|)` for the level of detail (P2), `1/L = |grad u|`.
//!
//! [`Setup::add_face`] is inlined into the GP's face set-up (`gp::FrameBuilder::face`,
//! whose copy compiled for AVX2 then holds it too); a triangle, nearly every face,
//! is snapped into registers and its three edge codes made inline
//! ([`EdgeCode::push_triangle`]), other outlines go through a scratch list. In the
//! GP's copy compiled for AVX2 (`Setup::add_face_with` with `AVX2`) the
//! triangle's points are snapped, and its edge codes made, in AVX2 lanes
//! (`snap_triangle_points_avx2`, [`EdgeCode::push_triangle_avx2`]; the same
//! bits); that copy hands a triangle's outline over already in lanes
//! (`Outline::TriangleLanes`, as it projected the points), snapped there with
//! no points in memory between (`snap_triangle_lanes_avx2`).

use glam::{DMat3, DMat4, DVec2, DVec3};

use super::View;
use crate::db::bsp::Plane;
use crate::db::{Material, MaterialTexture, Rgb, Scene};
use crate::frame::{FracLin, FrameList, FramePolygon, PixelBox, PolyTexture, PrimitiveKind, ScreenVertex};
#[cfg(target_arch = "x86_64")]
use crate::vp::edge::TriangleRoot;
use crate::vp::edge::{EdgeCode, ScreenFx, SNAP_ONE};
use crate::vp::gq::CellProcessors;

/// A vertex in eye coordinates with its brightness.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeVertex {
    /// Eye-space position.
    pub position: DVec3,
    /// Brightness (P5 formula applied).
    pub intensity: f64,
}

/// What the set-up needs to know about where a polygon came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Source {
    /// Face or light.
    pub kind: PrimitiveKind,
    /// Material index (`u32::MAX` for lights).
    pub material: u32,
    /// Instance and face (or light index and `u32::MAX`).
    pub ids: (u32, u32),
}

/// A polygon's clipped screen outline as [`Setup::add_face_with`] takes it.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Outline<'a> {
    /// The points in order.
    Points(&'a [DVec2]),
    /// A triangle's points in the lanes of AVX2 registers, `x` then `y`: lane `k`
    /// point `k`, lane 3 repeating point 0 (the lanes [`snap_triangle_points_avx2`]
    /// snaps). The GP's face path compiled for AVX2 projects a triangle into them
    /// (`gp::TriangleLanes::project`), with no points in memory between.
    #[cfg(target_arch = "x86_64")]
    TriangleLanes(std::arch::x86_64::__m256d, std::arch::x86_64::__m256d),
}

/// The set-up unit of the GP for one frame.
pub struct Setup {
    view: View,
    root_side: u32,
    /// The root side's constants for [`EdgeCode::push_triangle_avx2_at`] (`None`
    /// where it does not take it), made once a frame rather than at each triangle.
    #[cfg(target_arch = "x86_64")]
    triangle_root: Option<TriangleRoot>,
    background: Rgb,
    fog: Rgb,
    visibility: f32,
    snapped: Vec<(ScreenFx, ScreenFx)>,
    /// The texture axes of the last textured face's instance and material
    /// ([`TextureAxes`]), kept for the next face of the same pair.
    texture_axes: Option<TextureAxes>,
}

/// The part of a textured face's set-up (P2) that depends only on its instance and
/// material, not on the face: `u` and `v` as linear functions of eye coordinates,
/// `g . P + d` with the integer part of `d` dropped, and `|grad u|`. Neighbouring
/// faces nearly always share their instance and material, and each of these cost
/// the inverse of the instance's model-to-eye matrix and two transforms (about 300
/// instructions a textured face: on `default` the matrix inverse alone was 9 % of
/// the GP). Kept from one face to the next in [`Setup`], whose frame fixes every
/// instance's matrix; the same operations on the same inputs, so the same bits.
#[derive(Clone, Copy, Debug)]
struct TextureAxes {
    /// (instance, material) they belong to.
    key: (u32, u32),
    /// `u`: the eye-space gradient and the shifted constant.
    u: (DVec3, f64),
    /// `v` likewise.
    v: (DVec3, f64),
    /// `|grad u|` in eye space (for `PAR`).
    len_u: f64,
}

impl TextureAxes {
    /// The axes of texture `t` on an instance whose model-to-eye matrix is
    /// `model_to_eye`.
    fn new(key: (u32, u32), t: &MaterialTexture, model_to_eye: &DMat4) -> Self {
        let q = model_to_eye.inverse();
        let ql = DMat3::from_mat4(q);
        let qt = q.w_axis.truncate();
        let inv_l = 1.0 / f64::from(t.period);
        let axis = |a: glam::Vec3| {
            let g_model = a.as_dvec3() * inv_l;
            let d_model = -t.origin.as_dvec3().dot(g_model);
            let g_eye = ql.transpose() * g_model;
            let d_eye = g_model.dot(qt) + d_model;
            // P2: drop the integer part of D' (the texture origin moves to a
            // point near the eye by a whole number of periods).
            let d_shift = d_eye - d_eye.floor();
            (g_eye, d_shift)
        };
        let u = axis(t.u_axis);
        Self { key, u, v: axis(t.v_axis), len_u: u.0.length() }
    }
}

impl Setup {
    /// Set-up for a frame of `scene` seen through `view`.
    pub fn new(scene: &Scene, view: &View) -> Self {
        let root_level = CellProcessors::root_level_for(view.screen.width, view.screen.height);
        let root_side = 4 << root_level;
        Self {
            view: *view,
            root_side,
            #[cfg(target_arch = "x86_64")]
            triangle_root: TriangleRoot::new(root_side),
            background: scene.env.sky,
            fog: scene.env.fog_color,
            visibility: scene.env.visibility,
            snapped: Vec::new(),
            texture_axes: None,
        }
    }

    /// An empty frame list with this frame's header.
    pub fn frame_list(&self) -> FrameList {
        let mut list = FrameList::default();
        self.header(&mut list);
        list
    }

    /// Empties `list` (keeping its allocations) and writes this frame's header.
    pub fn header(&self, list: &mut FrameList) {
        list.clear();
        list.width = self.view.screen.width;
        list.height = self.view.screen.height;
        list.background = self.background;
        list.fog_color = self.fog;
        list.visibility = self.visibility;
        list.pixel_angle = (1.0 / self.view.focal) as f32;
    }

    /// `1/Z` as a linear function of pixel coordinates, from the eye-space plane.
    #[inline]
    fn inv_z(&self, plane: &Plane) -> Option<[f64; 3]> {
        let (n, d) = (plane.normal, plane.d);
        if d.abs() < 1e-12 {
            return None;
        }
        let f = self.view.focal;
        let (cx, cy) = (self.view.center.x, self.view.center.y);
        Some([n.x / (f * d), n.y / (f * d), (n.z - (n.x * cx + n.y * cy) / f) / d])
    }

    /// The screen triple of a quantity `q = g . P + k` linear in eye space (on the
    /// plane): `q / Z = g . (x', y', 1) + k / Z`, `x' = (x - cx) / f`.
    #[inline]
    fn screen_triple(&self, g: DVec3, k: f64, inv_z: &[f64; 3]) -> FracLin {
        let f = self.view.focal;
        let (cx, cy) = (self.view.center.x, self.view.center.y);
        FracLin {
            a: (g.x / f + k * inv_z[0]) as f32,
            b: (g.y / f + k * inv_z[1]) as f32,
            c: (g.z - (g.x * cx + g.y * cy) / f + k * inv_z[2]) as f32,
        }
    }

    /// Sets up a face and appends it to `out`; `false` if it vanished (degenerate
    /// after snapping, or seen edge-on).
    ///
    /// `material` is material `source.material`, and `model_to_eye` the matrix of
    /// instance `source.ids.0`, the same for every face of that instance this
    /// `Setup` sets up (one frame's): a textured face reuses the texture axes of the
    /// face before it when both are of the same instance and material
    /// (`TextureAxes`).
    ///
    /// Inline in the GP's face set-up (`gp::FrameBuilder::face`), so that its copy
    /// compiled for AVX2 holds this one's too.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn add_face(
        &mut self,
        source: Source,
        material: Option<&Material>,
        color: Rgb,
        plane_eye: &Plane,
        eye_poly: &[EyeVertex],
        outline: &[DVec2],
        model_to_eye: &DMat4,
        out: &mut FrameList,
    ) -> bool {
        // SAFETY: `AVX2 = false` needs no processor feature.
        #[allow(unsafe_code, reason = "the plain instance of a function unsafe only with AVX2")]
        unsafe {
            self.add_face_with::<false>(
                source,
                material,
                color,
                plane_eye,
                eye_poly,
                Outline::Points(outline),
                model_to_eye,
                out,
            )
        }
    }

    /// [`Setup::add_face`], with `AVX2` a triangle's edge codes made in AVX2
    /// registers ([`EdgeCode::push_triangle_avx2`]; the same codes): for the GP's
    /// face path compiled for AVX2, into which it is inlined.
    ///
    /// # Safety
    /// With `AVX2`, the processor must have AVX2.
    #[allow(clippy::too_many_arguments)]
    #[allow(unsafe_code, reason = "a function that runs AVX2 code when told the processor has it")]
    #[inline(always)]
    pub(crate) unsafe fn add_face_with<const AVX2: bool>(
        &mut self,
        source: Source,
        material: Option<&Material>,
        color: Rgb,
        plane_eye: &Plane,
        eye_poly: &[EyeVertex],
        outline: Outline<'_>,
        model_to_eye: &DMat4,
        out: &mut FrameList,
    ) -> bool {
        // A triangle (nearly every face) is snapped into registers, set up from
        // them and its codes made inline ([`EdgeCode::push_triangle`]); other
        // outlines go through `self.snapped`.
        let (inside_positive, triangle) = match outline {
            Outline::Points([a, b, c]) => match triangle_points::<AVX2>([a, b, c]) {
                Some((inside, points)) => (inside, Some(points)),
                None => return false,
            },
            #[cfg(target_arch = "x86_64")]
            Outline::TriangleLanes(xs, ys) => match triangle_lanes::<AVX2>(xs, ys) {
                Some((inside, points)) => (inside, Some(points)),
                None => return false,
            },
            Outline::Points(outline) => match snap_outline(outline, &mut self.snapped) {
                Some(inside) => (inside, None),
                None => return false,
            },
        };
        let Some(inv_z) = self.inv_z(plane_eye) else { return false };
        let intensity = self.linear_on_face(plane_eye, eye_poly, &inv_z);
        // (Written without a closure, which the compiler kept out of line.)
        let texture = match material.and_then(|m| m.texture.as_ref()) {
            Some(t) => {
                let key = (source.ids.0, source.material);
                let axes = match self.texture_axes {
                    Some(axes) if axes.key == key => axes,
                    _ => {
                        let axes = TextureAxes::new(key, t, model_to_eye);
                        self.texture_axes = Some(axes);
                        axes
                    }
                };
                let u = self.screen_triple(axes.u.0, axes.u.1, &inv_z);
                let v = self.screen_triple(axes.v.0, axes.v.1, &inv_z);
                let par = (axes.len_u / plane_eye.d.abs()) as f32;
                out.textures.push(PolyTexture { map: t.map, u, v, par, color1: t.color1, color2: t.color2 });
                out.textures.len() as u32 - 1
            }
            None => FramePolygon::NO_TEXTURE,
        };
        let vstart = out.vertices.len() as u32;
        let inv_z32 = FracLin { a: inv_z[0] as f32, b: inv_z[1] as f32, c: inv_z[2] as f32 };
        let vertex = |a: &(ScreenFx, ScreenFx)| {
            let (x, y) = (a.0.to_f32(), a.1.to_f32());
            ScreenVertex { x, y, inv_w: inv_z32.eval(x, y) }
        };
        // A triangle's box from its vertices in registers ([`FrameList::push_polygon_in`]).
        let triangle_box = match triangle {
            Some(points) => {
                let bbox = 'bbox: {
                    #[cfg(target_arch = "x86_64")]
                    if AVX2 {
                        // SAFETY: with `AVX2` the caller vouches for the processor.
                        #[allow(unsafe_code, reason = "an AVX2 function, its feature vouched for by the caller")]
                        break 'bbox unsafe {
                            triangle_vertices_avx2(points, &inv_z32, out.width, out.height, &mut out.vertices)
                        };
                    }
                    let vertices = [vertex(&points[0]), vertex(&points[1]), vertex(&points[2])];
                    out.vertices.extend_from_slice(&vertices);
                    PixelBox::of(&vertices, out.width, out.height)
                };
                #[cfg(target_arch = "x86_64")]
                #[allow(unsafe_code, reason = "an AVX2 function, its feature vouched for by the caller")]
                let done = AVX2
                    && match self.triangle_root {
                        // SAFETY: with `AVX2` the caller vouches for the processor.
                        Some(root) => unsafe {
                            EdgeCode::push_triangle_avx2_at(points, inside_positive, root, &mut out.edges)
                        },
                        None => false,
                    };
                #[cfg(not(target_arch = "x86_64"))]
                let done = false;
                if !done {
                    EdgeCode::push_triangle(points, inside_positive, self.root_side, &mut out.edges);
                }
                Some(bbox)
            }
            None => {
                out.vertices.extend(self.snapped.iter().map(vertex));
                EdgeCode::push_outline(&self.snapped, inside_positive, self.root_side, &mut out.edges);
                None
            }
        };
        let polygon = FramePolygon {
            vertices: vstart..out.vertices.len() as u32,
            kind: source.kind,
            material: source.material,
            source: source.ids,
            color,
            inv_z: inv_z32,
            intensity,
            texture,
            transparency: material.map_or(0, |m| m.transparency.code()),
        };
        match triangle_box {
            Some(bbox) => out.push_polygon_in(polygon, bbox),
            None => out.push_polygon(polygon),
        }
        true
    }

    /// Intensity as a fractional-linear function: fitted on the three vertices that
    /// span the largest triangle (exact for a linear distribution).
    #[inline(always)]
    fn linear_on_face(&self, plane: &Plane, vs: &[EyeVertex], inv_z: &[f64; 3]) -> FracLin {
        let n = vs.len();
        // The widest triangle: first vertex against the farthest pair is enough for
        // convex polygons, but n is small, so try all pairs from a few anchors. A
        // triangle has only itself (the search would pick (0, 1, 2) whatever its
        // area, even NaN): no search.
        let best = match n {
            ..=3 => (0.0, 0, 1, 2),
            _ if flat_in_depth(vs) => widest_flat(vs),
            _ => widest(vs),
        };
        let (_, i, j, k) = best;
        let (p0, p1, p2) = (vs[i].position, vs[j].position, vs[k].position);
        let (q0, q1, q2) = (vs[i].intensity, vs[j].intensity, vs[k].intensity);
        // g . (p1 - p0) = q1 - q0, g . (p2 - p0) = q2 - q0, g . N = 0.
        let m = DMat3::from_cols(p1 - p0, p2 - p0, plane.normal).transpose();
        let g = solve_gradient(&m, DVec3::new(q1 - q0, q2 - q0, 0.0));
        let k0 = q0 - g.dot(p0);
        self.screen_triple(g, k0, inv_z)
    }
}

/// `(area, i, j, k)` of the widest triangle `(i, j, k)` of `vs` (`i < j < k`, `i`
/// among the first four; the first of equal ones; `(0.0, 0, 1, 2)` if no area is
/// above zero): [`Setup::linear_on_face`]'s search for a polygon.
#[inline(always)]
fn widest(vs: &[EyeVertex]) -> (f64, usize, usize, usize) {
    widest_by(vs, |a, b| a.cross(b).length())
}

/// [`widest`] of a polygon whose vertices are all at one depth ([`flat_in_depth`]:
/// a light point's octagon, 52 triangles): the edges' depths are zeros, so the
/// cross product's first two coordinates are zeros and its length is
/// `sqrt(z * z)` of its third, bit for bit. The same areas, so the same triangle,
/// with about a third of the operations (the search was ~2000 instructions of a
/// light point's set-up).
#[inline(always)]
fn widest_flat(vs: &[EyeVertex]) -> (f64, usize, usize, usize) {
    // glam's cross product's third coordinate, and its `length()`.
    widest_by(vs, |a, b| {
        let z = a.x * b.y - b.x * a.y;
        (z * z).sqrt()
    })
}

/// The search of [`widest`] with the area of the triangle of edges `a`, `b` (from
/// its first vertex) given by `area`.
#[allow(clippy::needless_range_loop, reason = "the indices are the answer; as an iterator, 0.06 M more on default")]
#[inline(always)]
fn widest_by(vs: &[EyeVertex], area: impl Fn(DVec3, DVec3) -> f64) -> (f64, usize, usize, usize) {
    let n = vs.len();
    let mut best = (0.0, 0, 1, 2);
    for i in 0..n.min(4) {
        let p = vs[i].position;
        for j in i + 1..n {
            let a = vs[j].position - p;
            for k in j + 1..n {
                let s = area(a, vs[k].position - p);
                if s > best.0 {
                    best = (s, i, j, k);
                }
            }
        }
    }
    best
}

/// Whether every vertex of `vs` has the same finite depth (`z`) and `x`, `y` of at
/// most half the largest `f64`: then every difference of two vertices has depth
/// zero (`±0`) and finite `x`, `y`, so that in glam's `a.cross(b)` of two such
/// differences `a.y * b.z - b.y * a.z` and `a.z * b.x - b.z * a.x` are zeros (`±0`),
/// and `length()`, `sqrt((x * x + y * y) + z * z)`, is `sqrt(+0 + z * z)`, i.e.
/// `sqrt(z * z)`, bit for bit (NaN and infinity included), with
/// `z = a.x * b.y - b.x * a.y` ([`Setup::linear_on_face`]).
#[inline(always)]
fn flat_in_depth(vs: &[EyeVertex]) -> bool {
    const LIMIT: f64 = f64::MAX / 2.0;
    let z = vs[0].position.z;
    z.is_finite() && vs.iter().all(|v| v.position.z == z && v.position.x.abs() <= LIMIT && v.position.y.abs() <= LIMIT)
}

/// `m.inverse() * rhs` where `m.determinant().abs() > 1e-18`, else zero: the
/// intensity gradient of [`Setup::linear_on_face`].
///
/// glam 0.29's `DMat3::determinant` and `DMat3::inverse` written out with glam's
/// own operations in its order (the same bits; tested): the compiler kept `inverse`
/// out of line in the GP's face set-up (a call and a matrix through memory per
/// face), and the determinant is the inverse's own (`z . (x × y)`), computed once.
#[inline(always)]
fn solve_gradient(m: &DMat3, rhs: DVec3) -> DVec3 {
    let tmp2 = m.x_axis.cross(m.y_axis);
    let det = m.z_axis.dot(tmp2);
    if det.abs() > 1e-18 {
        let (tmp0, tmp1) = (m.y_axis.cross(m.z_axis), m.z_axis.cross(m.x_axis));
        let inv_det = DVec3::splat(det.recip());
        DMat3::from_cols(tmp0 * inv_det, tmp1 * inv_det, tmp2 * inv_det).transpose() * rhs
    } else {
        DVec3::ZERO
    }
}

/// Snaps an outline to the 1/256-pixel grid into `s`, removes duplicate, collinear
/// and reflex vertices (snapping can bend a nearly straight corner inwards; the VP
/// needs a strictly convex polygon), and returns the orientation (`true`: the interior
/// is where `(b - a) x (p - a) > 0`), or `None` for a degenerate outline.
pub fn snap_outline(outline: &[DVec2], s: &mut Vec<(ScreenFx, ScreenFx)>) -> Option<bool> {
    if let [a, b, c] = outline {
        return snap_triangle([a, b, c], s);
    }
    let sign = snap_points(outline, s)?;
    // Nearly every outline is strictly convex already (every turn the area's
    // way): then the passes of `drop_turns` remove nothing, and each of their checks
    // is the one made here (without their index arithmetic: a division per check).
    // A triangle needs no check: each of its turns `(b - a) x (c - b)` is exactly
    // its doubled area, of the area's sign.
    if s.len() == 3 || strictly_convex(s, sign) {
        return Some(sign > 0);
    }
    drop_turns(s, sign)
}

/// [`snap_outline`] of a triangle (the common case): its passes and checks keep
/// nothing or all three points. Snapped, two equal points leave fewer than three
/// (equal neighbours are merged, then a last point equal to the first); three
/// distinct ones stay, a triangle of non-zero area being strictly convex (each of
/// its turns is its doubled area).
#[inline]
fn snap_triangle(outline: [&DVec2; 3], s: &mut Vec<(ScreenFx, ScreenFx)>) -> Option<bool> {
    s.clear();
    let (inside, q) = snap_triangle_points(outline)?;
    s.extend_from_slice(&q);
    Some(inside)
}

/// [`snap_triangle`] without the list: the orientation and the snapped points,
/// or `None` for a degenerate triangle.
#[inline(always)]
fn snap_triangle_points(outline: [&DVec2; 3]) -> Option<(bool, [(ScreenFx, ScreenFx); 3])> {
    let q = outline.map(|p| (ScreenFx::from_f64(p.x), ScreenFx::from_f64(p.y)));
    if q[0] == q[1] || q[1] == q[2] || q[2] == q[0] {
        return None;
    }
    let area2 = shoelace(&q);
    (area2 != 0).then_some((area2 > 0, q))
}

/// [`snap_triangle_points`], with `AVX2` by [`snap_triangle_points_avx2`] (the
/// same result).
///
/// # Safety
/// With `AVX2`, the processor must have AVX2.
#[allow(unsafe_code, reason = "a function that runs AVX2 code when told the processor has it")]
#[inline(always)]
unsafe fn triangle_points<const AVX2: bool>(outline: [&DVec2; 3]) -> Option<(bool, [(ScreenFx, ScreenFx); 3])> {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: with `AVX2` the caller vouches for the processor.
        return unsafe { snap_triangle_points_avx2(outline) };
    }
    snap_triangle_points(outline)
}

/// [`snap_triangle_points`] of a triangle given in lanes ([`Outline::TriangleLanes`]):
/// with `AVX2` by [`snap_triangle_lanes_avx2`], else (lanes made by AVX2 code
/// reaching a copy compiled without it, which the GP never does) by the points
/// read back from the lanes; the same result.
///
/// # Safety
/// With `AVX2`, the processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code, reason = "a function that runs AVX2 code when told the processor has it")]
#[inline(always)]
unsafe fn triangle_lanes<const AVX2: bool>(
    xs: std::arch::x86_64::__m256d,
    ys: std::arch::x86_64::__m256d,
) -> Option<(bool, [(ScreenFx, ScreenFx); 3])> {
    if AVX2 {
        // SAFETY: with `AVX2` the caller vouches for the processor.
        return unsafe { snap_triangle_lanes_avx2(xs, ys) };
    }
    // SAFETY: a register of four `f64` is their array, bit for bit.
    let (x, y) = unsafe {
        (
            std::mem::transmute::<std::arch::x86_64::__m256d, [f64; 4]>(xs),
            std::mem::transmute::<std::arch::x86_64::__m256d, [f64; 4]>(ys),
        )
    };
    let p = [DVec2::new(x[0], y[0]), DVec2::new(x[1], y[1]), DVec2::new(x[2], y[2])];
    snap_triangle_points([&p[0], &p[1], &p[2]])
}

/// [`snap_triangle_points`] in AVX2 registers, the three points in lanes: the
/// same result for every input (tested, NaN, infinities, ties and huge values
/// among them), where the scalar code converted each coordinate on its own
/// (about 5 instructions each for the saturating conversion) and formed the
/// area by six scalar products.
///
/// - `ScreenFx::from_f64(v)` is `(v * 256).round() as i32`. The product is the
///   same `vmulpd`. `round` (half away from zero) is `t = trunc(x)` plus
///   `copysign(1, x)` where `|x - t| >= 0.5`: `x - t` is exact (for `|x| >= 2^52`
///   both are the same integer, below that it is `x`'s fraction, a float), and so
///   is `t ± 1` then (`|t| < 2^52`); a NaN stays NaN (the comparison is false),
///   an infinity stays itself (`inf - inf` is NaN). `as i32` saturates and takes
///   NaN to 0: NaN lanes are zeroed first, then the values clamped to `i32`'s
///   range (both bounds are floats) and truncated (`vcvttpd2dq`, exact on the
///   clamped integers).
/// - The equal-points test compares each point with the next.
/// - The doubled area is the same three products `x_i y_(i+1) - x_(i+1) y_i`
///   (`vpmuldq`, exact: 32-bit factors) summed with wrapping 64-bit additions:
///   the scalar `i64` sum in release builds, whatever the order.
///
/// # Safety
/// The processor must have AVX2 (inlined always, so compiled with the caller's
/// features: for the GP's face path compiled for AVX2).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code, reason = "AVX2 instructions, inlined into a caller compiled for AVX2")]
#[inline(always)]
unsafe fn snap_triangle_points_avx2(outline: [&DVec2; 3]) -> Option<(bool, [(ScreenFx, ScreenFx); 3])> {
    use std::arch::x86_64::*;
    let [a, b, c] = outline;
    // Lane k: point k; lane 3 repeats point 0 (so that each lane's next point,
    // one lane on, is the triangle's next point for lanes 0 to 2).
    // SAFETY: the caller vouches for AVX2.
    unsafe { snap_triangle_lanes_avx2(_mm256_setr_pd(a.x, b.x, c.x, a.x), _mm256_setr_pd(a.y, b.y, c.y, a.y)) }
}

/// [`snap_triangle_points_avx2`] of the points already in lanes (`xs`, `ys`:
/// lane `k` point `k`, lane 3 repeating point 0; [`Outline::TriangleLanes`]).
///
/// # Safety
/// The processor must have AVX2 (inlined always, so compiled with the caller's
/// features: for the GP's face path compiled for AVX2).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code, reason = "AVX2 instructions, inlined into a caller compiled for AVX2")]
#[inline(always)]
unsafe fn snap_triangle_lanes_avx2(
    xs: std::arch::x86_64::__m256d,
    ys: std::arch::x86_64::__m256d,
) -> Option<(bool, [(ScreenFx, ScreenFx); 3])> {
    use std::arch::x86_64::*;
    // (Macros rather than closures: a closure is a function of its own, kept out
    // of line without the caller's features.)
    macro_rules! snap {
        ($v:expr) => {{
            let x = _mm256_mul_pd($v, _mm256_set1_pd(f64::from(SNAP_ONE)));
            let t = _mm256_round_pd::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(x);
            let sign = _mm256_and_pd(x, _mm256_set1_pd(-0.0));
            let fraction = _mm256_andnot_pd(_mm256_set1_pd(-0.0), _mm256_sub_pd(x, t));
            let half = _mm256_cmp_pd::<_CMP_GE_OQ>(fraction, _mm256_set1_pd(0.5));
            let r = _mm256_add_pd(t, _mm256_and_pd(half, _mm256_or_pd(sign, _mm256_set1_pd(1.0))));
            let r = _mm256_andnot_pd(_mm256_cmp_pd::<_CMP_UNORD_Q>(r, r), r);
            let r = _mm256_max_pd(r, _mm256_set1_pd(f64::from(i32::MIN)));
            _mm256_cvttpd_epi32(_mm256_min_pd(r, _mm256_set1_pd(f64::from(i32::MAX))))
        }};
    }
    macro_rules! wide {
        ($v:expr) => {
            _mm256_cvtepi32_epi64($v)
        };
    }
    let xs = snap!(xs);
    let ys = snap!(ys);
    let (xn, yn) = (_mm_shuffle_epi32::<0b01_00_10_01>(xs), _mm_shuffle_epi32::<0b01_00_10_01>(ys));
    let same = _mm_and_si128(_mm_cmpeq_epi32(xs, xn), _mm_cmpeq_epi32(ys, yn));
    if _mm_movemask_ps(_mm_castsi128_ps(same)) & 0b111 != 0 {
        return None;
    }
    let terms = _mm256_sub_epi64(_mm256_mul_epi32(wide!(xs), wide!(yn)), _mm256_mul_epi32(wide!(xn), wide!(ys)));
    let mut t = [0i64; 4];
    // SAFETY: `t` is 32 bytes, a register's size (an unaligned store).
    unsafe { _mm256_storeu_si256(t.as_mut_ptr().cast(), terms) };
    let area2 = t[0].wrapping_add(t[1]).wrapping_add(t[2]);
    let mut q = [0i32; 8];
    // SAFETY: each half of `q` is 16 bytes, a register's size (unaligned stores).
    unsafe {
        _mm_storeu_si128(q.as_mut_ptr().cast(), xs);
        _mm_storeu_si128(q.as_mut_ptr().add(4).cast(), ys);
    }
    // (Written out: `map` over the indices was a call.)
    let points = [(ScreenFx(q[0]), ScreenFx(q[4])), (ScreenFx(q[1]), ScreenFx(q[5])), (ScreenFx(q[2]), ScreenFx(q[6]))];
    (area2 != 0).then_some((area2 > 0, points))
}

/// Appends a triangle's [`ScreenVertex`]es to `out` (what [`Setup::add_face`] makes of each
/// snapped point: `x`, `y` by [`ScreenFx::to_f32`], `inv_w` by [`FracLin::eval`])
/// with the three points in the lanes of SSE registers: the same `f32` operations
/// in the same order (`i32` to `f32`, a division by 256, `(a x + b y) + c`, no
/// FMA), where the scalar code converted and evaluated each point on its own;
/// and gives its [`PixelBox`] on a `width` x `height` screen from the same lanes
/// (the least and greatest `x, y`, then `bbox_sse41`'s own steps,
/// `crate::vp::box_bounds_sse41`).
///
/// # Safety
/// The processor must have AVX2 (inlined always, so compiled with the caller's
/// features: for the GP's face path compiled for AVX2).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code, reason = "AVX2 instructions, inlined into a caller compiled for AVX2")]
#[inline(always)]
unsafe fn triangle_vertices_avx2(
    points: [(ScreenFx, ScreenFx); 3],
    f: &FracLin,
    width: u32,
    height: u32,
    out: &mut Vec<ScreenVertex>,
) -> PixelBox {
    use std::arch::x86_64::*;
    let [p0, p1, p2] = points;
    let one = _mm_set1_ps(SNAP_ONE as f32);
    // (The first point again in the fourth lane, for the box.)
    let xs = _mm_div_ps(_mm_cvtepi32_ps(_mm_setr_epi32(p0.0 .0, p1.0 .0, p2.0 .0, p0.0 .0)), one);
    let ys = _mm_div_ps(_mm_cvtepi32_ps(_mm_setr_epi32(p0.1 .0, p1.1 .0, p2.1 .0, p0.1 .0)), one);
    // The box as `crate::vp::bbox` makes it of the three vertices: the least and
    // greatest x and y (finite, whole multiples of 1/256), then its bounds.
    let (x_lo, x_hi) = (_mm_min_ps(xs, _mm_movehl_ps(xs, xs)), _mm_max_ps(xs, _mm_movehl_ps(xs, xs)));
    let (y_lo, y_hi) = (_mm_min_ps(ys, _mm_movehl_ps(ys, ys)), _mm_max_ps(ys, _mm_movehl_ps(ys, ys)));
    // Lanes x0 | x1 of each: x0 = min(a, c), x1 = min(b, a); then the lanes' least.
    let lo = _mm_unpacklo_ps(x_lo, y_lo); // x(a,c) y(a,c) x(b,a) y(b,a)
    let hi = _mm_unpacklo_ps(x_hi, y_hi);
    let lo = _mm_min_ps(lo, _mm_movehl_ps(lo, lo)); // x0 y0 . .
    let hi = _mm_max_ps(hi, _mm_movehl_ps(hi, hi)); // x1 y1 . .
                                                    // Lanes x0 y0 x1 y1.
    let v = _mm_movelh_ps(lo, hi);
    // SAFETY: the processor has AVX2 (this function's condition), so SSE4.1.
    #[allow(unsafe_code, reason = "an SSE4.1 function on a processor with AVX2")]
    let bounds = unsafe { crate::vp::box_bounds_sse41(v, width, height) };
    // To 16 bits.
    let packed = _mm_cvtsi128_si64(_mm_packus_epi32(bounds, bounds)) as u64;
    let bbox =
        PixelBox { x0: packed as u16, x1: (packed >> 16) as u16, y0: (packed >> 32) as u16, y1: (packed >> 48) as u16 };
    let ws =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(f.a), xs), _mm_mul_ps(_mm_set1_ps(f.b), ys)), _mm_set1_ps(f.c));
    let mut lanes = [[0f32; 4]; 3];
    for (slot, v) in lanes.iter_mut().zip([xs, ys, ws]) {
        // SAFETY: `slot` is 16 bytes, a register's size (an unaligned store).
        unsafe { _mm_storeu_ps(slot.as_mut_ptr(), v) };
    }
    let [x, y, w] = lanes;
    out.extend_from_slice(&[
        ScreenVertex { x: x[0], y: y[0], inv_w: w[0] },
        ScreenVertex { x: x[1], y: y[1], inv_w: w[1] },
        ScreenVertex { x: x[2], y: y[2], inv_w: w[2] },
    ]);
    bbox
}

/// The first step of [`snap_outline`]: the outline snapped into `s` without
/// repeated points; the sign of its doubled area, or `None` if it has none.
fn snap_points(outline: &[DVec2], s: &mut Vec<(ScreenFx, ScreenFx)>) -> Option<i64> {
    s.clear();
    for p in outline {
        let q = (ScreenFx::from_f64(p.x), ScreenFx::from_f64(p.y));
        if s.last() != Some(&q) {
            s.push(q);
        }
    }
    while s.len() > 1 && s.first() == s.last() {
        s.pop();
    }
    if s.len() < 3 {
        return None;
    }
    let area2 = shoelace(s);
    (area2 != 0).then_some(area2.signum())
}

/// The last step of [`snap_outline`]: removes every vertex whose turn is not of the
/// area's `sign` (collinear or reflex), until none is left; the orientation, or
/// `None` if the outline degenerates.
fn drop_turns(s: &mut Vec<(ScreenFx, ScreenFx)>, sign: i64) -> Option<bool> {
    let mut i = 0;
    while s.len() >= 3 && i < s.len() {
        let n = s.len();
        let (a, b, c) = (s[(i + n - 1) % n], s[i], s[(i + 1) % n]);
        if cross(a, b, c) * sign <= 0 {
            s.remove(i);
            // The neighbours' turns changed: look again from the previous vertex.
            i = i.saturating_sub(1);
        } else {
            i += 1;
        }
    }
    // One more pass around the wrap.
    let mut changed = true;
    while changed && s.len() >= 3 {
        changed = false;
        let n = s.len();
        for k in 0..n {
            if cross(s[(k + n - 1) % n], s[k], s[(k + 1) % n]) * sign <= 0 {
                s.remove(k);
                changed = true;
                break;
            }
        }
    }
    (s.len() >= 3 && shoelace(s) != 0).then_some(sign > 0)
}

/// Appends a flat polygon given by its screen outline (any orientation, inside the
/// screen) with constant depth `1/Z = inv_z` and colour: for tests and tools that
/// feed the VP without a scene. `false` if it is degenerate after snapping.
pub fn push_flat_polygon(out: &mut FrameList, outline: &[DVec2], color: Rgb, inv_z: f32) -> bool {
    let mut snapped = Vec::new();
    let Some(inside_positive) = snap_outline(outline, &mut snapped) else { return false };
    let root_side = 4u32 << CellProcessors::root_level_for(out.width, out.height);
    let vstart = out.vertices.len() as u32;
    out.vertices.extend(snapped.iter().map(|a| ScreenVertex { x: a.0.to_f32(), y: a.1.to_f32(), inv_w: inv_z }));
    EdgeCode::push_outline(&snapped, inside_positive, root_side, &mut out.edges);
    out.push_polygon(FramePolygon {
        vertices: vstart..out.vertices.len() as u32,
        kind: PrimitiveKind::Face,
        material: 0,
        source: (0, out.polygons.len() as u32),
        color,
        inv_z: FracLin { a: 0.0, b: 0.0, c: inv_z },
        intensity: FracLin { a: 0.0, b: 0.0, c: inv_z },
        texture: FramePolygon::NO_TEXTURE,
        transparency: 0,
    });
    true
}

/// Twice the signed area (exact: snapped coordinates are below 2^31, so every
/// product fits in `i64`, and the sum of a screen polygon's terms does too).
fn shoelace(s: &[(ScreenFx, ScreenFx)]) -> i64 {
    let Some(&last) = s.last() else { return 0 };
    let term = |a: (ScreenFx, ScreenFx), b: (ScreenFx, ScreenFx)| {
        i64::from(a.0 .0) * i64::from(b.1 .0) - i64::from(b.0 .0) * i64::from(a.1 .0)
    };
    // Integer sums: the order of the terms does not matter.
    s.windows(2).map(|w| term(w[0], w[1])).sum::<i64>() + term(last, s[0])
}

/// Whether every corner of the closed outline `s` turns the way of `sign` (the
/// sign of its area): the check of [`snap_outline`]'s passes at every vertex.
fn strictly_convex(s: &[(ScreenFx, ScreenFx)], sign: i64) -> bool {
    let n = s.len();
    let (mut a, mut b) = (s[n - 2], s[n - 1]);
    for &c in s {
        if cross(a, b, c) * sign <= 0 {
            return false;
        }
        (a, b) = (b, c);
    }
    true
}

fn cross(a: (ScreenFx, ScreenFx), b: (ScreenFx, ScreenFx), c: (ScreenFx, ScreenFx)) -> i64 {
    let (abx, aby) = (i64::from(b.0 .0 - a.0 .0), i64::from(b.1 .0 - a.1 .0));
    let (bcx, bcy) = (i64::from(c.0 .0 - b.0 .0), i64::from(c.1 .0 - b.1 .0));
    abx * bcy - aby * bcx
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// [`snap_outline`] as first written: the passes alone, with no convexity
    /// check before them.
    fn snap_outline_plain(outline: &[DVec2], s: &mut Vec<(ScreenFx, ScreenFx)>) -> Option<bool> {
        let sign = snap_points(outline, s)?;
        drop_turns(s, sign)
    }

    /// A small xorshift generator (the tests need no better; the GP's tests use it
    /// too).
    pub(crate) struct Rng(pub(crate) u64);

    impl Rng {
        pub(crate) fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        /// A draw in `0..1`, 53 bits.
        pub(crate) fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// [`solve_gradient`] is glam's determinant test and inverse, bit for bit:
    /// random matrices from tiny to huge entries, singular and nearly singular
    /// ones, zero right-hand sides (the signs of zero products) among them.
    #[test]
    fn solve_gradient_is_glams_inverse() {
        let mut rng = Rng(0x6AD1_E27F_0A11);
        let mut taken = [0usize; 2];
        for case in 0..100_000 {
            let scale = [1e-7, 1e-3, 1.0, 1e3, 1e6][case % 5];
            let mut v = || rng.range(-scale, scale);
            let mut m = DMat3::from_cols_array(&[v(), v(), v(), v(), v(), v(), v(), v(), v()]);
            if case % 7 == 0 {
                // Singular: the third row the sum of the first two.
                let t = m.transpose();
                m = DMat3::from_cols(t.x_axis, t.y_axis, t.x_axis + t.y_axis).transpose();
            }
            let rhs = if case % 3 == 0 { DVec3::ZERO } else { DVec3::new(v(), v(), 0.0) };
            let plain = if m.determinant().abs() > 1e-18 { m.inverse() * rhs } else { DVec3::ZERO };
            let got = solve_gradient(&m, rhs);
            assert_eq!(got.to_array().map(f64::to_bits), plain.to_array().map(f64::to_bits), "{m:?} {rhs:?}");
            taken[usize::from(m.determinant().abs() > 1e-18)] += 1;
        }
        assert!(taken.iter().all(|&k| k > 1000), "both branches tested: {taken:?}");
    }

    /// [`widest_flat`] is [`widest`] on polygons at one depth ([`flat_in_depth`]):
    /// random octagons like a light point's, and random points at one depth, at
    /// scales from tiny to near `f64::MAX / 2` (where products overflow), with repeated
    /// points, signed zeros, and depths of either sign; and `flat_in_depth` turns
    /// away other depths, non-finite depths and coordinates beyond its limit.
    #[test]
    fn widest_flat_is_widest() {
        let mut rng = Rng(0x0C7A_6011_F1A7);
        let mut flat = 0;
        for case in 0..20_000 {
            let scale = [1e-150, 1e-3, 1.0, 1e3, 1e150, 1e300, 4e307][case % 7];
            let z = match case % 5 {
                0 => 0.0,
                1 => -0.0,
                2 => -rng.range(0.1, 1e4),
                _ => rng.range(0.1, 1e4),
            };
            let n = 4 + case % 6;
            let mut vs: Vec<EyeVertex> = (0..n)
                .map(|k| {
                    let (x, y) = if case % 2 == 0 {
                        let a = std::f64::consts::TAU * (k as f64 + 0.5) / n as f64;
                        ((rng.unit() * 2.0 - 1.0 + a.cos()) * 0.5 * scale, -a.sin() * scale)
                    } else {
                        ((rng.unit() * 2.0 - 1.0) * scale, (rng.unit() * 2.0 - 1.0) * scale)
                    };
                    EyeVertex { position: DVec3::new(x, y, z), intensity: 1.0 }
                })
                .collect();
            match case % 11 {
                0 => vs[1] = vs[0],
                1 => vs[2].position.x = -0.0,
                2 => vs[3].position = DVec3::new(0.0, -0.0, z),
                _ => {}
            }
            assert!(flat_in_depth(&vs), "{vs:?}");
            flat += 1;
            let (got, want) = (widest_flat(&vs), widest(&vs));
            assert_eq!((got.0.to_bits(), got.1, got.2, got.3), (want.0.to_bits(), want.1, want.2, want.3), "{vs:?}");
        }
        assert_eq!(flat, 20_000);
        let at = |x: f64, y: f64, z: f64| EyeVertex { position: DVec3::new(x, y, z), intensity: 1.0 };
        let square = |z: f64| [at(0.0, 0.0, z), at(1.0, 0.0, z), at(1.0, 1.0, z), at(0.0, 1.0, z)];
        assert!(flat_in_depth(&square(2.0)));
        for z in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            assert!(!flat_in_depth(&square(z)));
        }
        let mut v = square(2.0);
        v[2].position.z = 2.0 + 1e-12;
        assert!(!flat_in_depth(&v));
        for bad in [f64::MAX, f64::INFINITY, f64::NAN] {
            let mut v = square(2.0);
            v[1].position.x = bad;
            assert!(!flat_in_depth(&v));
            let mut v = square(2.0);
            v[3].position.y = -bad;
            assert!(!flat_in_depth(&v));
        }
    }

    /// [`snap_triangle_points_avx2`] is [`snap_triangle_points`]: random
    /// triangles on and far off a screen, tiny ones (equal points, zero areas),
    /// and coordinates at the snap's ties and limits (halves, the largest float
    /// below a half, `-0.0`, `2^52` and neighbours, `i32`'s range and beyond,
    /// infinities, NaN).
    #[test]
    fn snap_triangle_points_avx2_is_the_plain_definition() {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            let s = 1.0 / f64::from(SNAP_ONE);
            let special = [
                0.0,
                -0.0,
                0.5 * s,
                -0.5 * s,
                1.5 * s,
                -2.5 * s,
                0.499_999_999_999_999_94 * s,
                -0.499_999_999_999_999_94 * s,
                (1u64 << 52) as f64 * s,
                ((1u64 << 52) as f64 + 1.0) * s,
                ((1u64 << 52) as f64 - 0.5) * s,
                ((1u64 << 53) as f64 + 2.0) * s,
                f64::from(i32::MAX) * s,
                (f64::from(i32::MAX) + 0.5) * s,
                (f64::from(i32::MAX) + 1.0) * s,
                f64::from(i32::MIN) * s,
                (f64::from(i32::MIN) - 0.5) * s,
                (f64::from(i32::MIN) - 1.0) * s,
                1e300,
                -1e300,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NAN,
                f64::MIN_POSITIVE,
                1_919.998_046_875,
                1_080.001_953_125,
            ];
            let mut rng = Rng(0x5A1D_7E57_0F2A);
            let mut outcomes = [0usize; 3];
            for case in 0..400_000 {
                let mut v = |k: u64| match (case + k as usize) % 4 {
                    0 => special[(rng.next() % special.len() as u64) as usize],
                    1 => rng.range(-4.0, 2000.0),
                    2 => (rng.range(0.0, 512.0).floor() + [0.0, 0.5, 0.25, 0.75][(rng.next() % 4) as usize]) * s,
                    _ => rng.range(-1e10, 1e10),
                };
                let mut c = [v(0), v(1), v(2), v(3), v(4), v(5)];
                if case % 5 == 0 {
                    // Tiny triangles: equal points and zero areas after snapping.
                    for k in 2..6 {
                        c[k] = c[k % 2] + rng.range(-2.0, 2.0) * s;
                    }
                }
                let pts = [DVec2::new(c[0], c[1]), DVec2::new(c[2], c[3]), DVec2::new(c[4], c[5])];
                let want = snap_triangle_points([&pts[0], &pts[1], &pts[2]]);
                // SAFETY: AVX2 was detected above.
                #[allow(unsafe_code, reason = "the AVX2 path under test, after detection")]
                let got = unsafe { snap_triangle_points_avx2([&pts[0], &pts[1], &pts[2]]) };
                assert_eq!(got, want, "{pts:?}");
                outcomes[match got {
                    None => 0,
                    Some((false, _)) => 1,
                    Some((true, _)) => 2,
                }] += 1;
            }
            assert!(outcomes.iter().all(|&k| k > 10_000), "every outcome tested: {outcomes:?}");
            // Each special value in each coordinate of an otherwise ordinary triangle.
            for &x in &special {
                for k in 0..6 {
                    let mut c = [10.0, 20.0, 300.5, 40.25, 17.0, 500.0];
                    c[k] = x;
                    let pts = [DVec2::new(c[0], c[1]), DVec2::new(c[2], c[3]), DVec2::new(c[4], c[5])];
                    let want = snap_triangle_points([&pts[0], &pts[1], &pts[2]]);
                    // SAFETY: AVX2 was detected above.
                    #[allow(unsafe_code, reason = "the AVX2 path under test, after detection")]
                    let got = unsafe { snap_triangle_points_avx2([&pts[0], &pts[1], &pts[2]]) };
                    assert_eq!(got, want, "{pts:?}");
                }
            }
        }
    }

    /// [`triangle_vertices_avx2`] is [`Setup::add_face`]'s scalar vertices, bit
    /// for bit, on random points and coefficients (tiny to huge, signed zeros,
    /// the extreme coordinates), and its box their [`crate::vp::bbox_plain`].
    #[test]
    fn triangle_vertices_avx2_is_the_plain_definition() {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            let mut rng = Rng(0x7E27_1CE5_0A52);
            for case in 0..200_000 {
                let mut c = || match rng.next() % 4 {
                    0 => (rng.next() % 600_000) as i32 - 1000,
                    1 => rng.next() as i32,
                    2 => [i32::MIN, i32::MAX, 0, -1, 1][(rng.next() % 5) as usize],
                    _ => (rng.next() % 512) as i32 - 256,
                };
                let points =
                    [(ScreenFx(c()), ScreenFx(c())), (ScreenFx(c()), ScreenFx(c())), (ScreenFx(c()), ScreenFx(c()))];
                let scale = [1e-12, 1e-3, 1.0, 1e3, 1e30][case % 5];
                let mut k = || match rng.next() % 8 {
                    0 => 0.0,
                    1 => -0.0,
                    _ => rng.range(-scale, scale) as f32,
                };
                let f = FracLin { a: k(), b: k(), c: k() };
                let want = points.map(|a| {
                    let (x, y) = (a.0.to_f32(), a.1.to_f32());
                    ScreenVertex { x, y, inv_w: f.eval(x, y) }
                });
                let (w, h) = (1 + (rng.next() % 8192) as u32, 1 + (rng.next() % 8192) as u32);
                let mut got = Vec::new();
                // SAFETY: AVX2 was detected above.
                #[allow(unsafe_code, reason = "the AVX2 path under test, after detection")]
                let got_box = unsafe { triangle_vertices_avx2(points, &f, w, h, &mut got) };
                let got: [ScreenVertex; 3] = got.try_into().expect("three vertices");
                let bits = |v: [ScreenVertex; 3]| v.map(|v| [v.x.to_bits(), v.y.to_bits(), v.inv_w.to_bits()]);
                assert_eq!(bits(got), bits(want), "{points:?} {f:?}");
                assert_eq!(
                    got_box,
                    PixelBox::from_bounds(crate::vp::bbox_plain(&want, w, h)),
                    "{points:?} on {w} x {h}"
                );
            }
        }
    }

    #[test]
    fn snap_outline_is_the_plain_definition() {
        let mut rng = Rng(0x5EED_0F5A_4B1D);
        let (mut fast, mut plain) = (Vec::new(), Vec::new());
        let mut outcomes = [0usize; 3];
        for case in 0..200_000 {
            let n = 3 + (rng.next() % 6) as usize;
            // Sizes from a hundredth of a pixel (everything snaps together) to a
            // screen; some outlines convex, some not, some with repeated points and
            // nearly collinear runs.
            let scale = [0.01, 0.1, 1.0, 8.0, 500.0][case % 5];
            let (cx, cy) = (rng.range(0.0, 1920.0), rng.range(0.0, 1080.0));
            let mut outline: Vec<DVec2> = if case % 3 == 0 {
                (0..n).map(|_| DVec2::new(cx + rng.range(-scale, scale), cy + rng.range(-scale, scale))).collect()
            } else {
                // Around a circle (convex), either way round.
                let dir = if case % 2 == 0 { 1.0 } else { -1.0 };
                let mut angles: Vec<f64> = (0..n).map(|_| rng.range(0.0, std::f64::consts::TAU)).collect();
                angles.sort_by(f64::total_cmp);
                angles.iter().map(|a| DVec2::new(cx + scale * a.cos(), cy + dir * scale * a.sin())).collect()
            };
            match rng.next() % 4 {
                0 => {
                    let k = (rng.next() as usize) % outline.len();
                    outline.insert(k, outline[k]);
                }
                1 => {
                    // A point on the middle of an edge (collinear after snapping, or
                    // nearly).
                    let k = (rng.next() as usize) % outline.len();
                    let m = (outline[k] + outline[(k + 1) % outline.len()]) * 0.5;
                    outline.insert(k + 1, m + DVec2::splat(rng.range(-0.003, 0.003)));
                }
                _ => {}
            }
            let a = snap_outline(&outline, &mut fast);
            let b = snap_outline_plain(&outline, &mut plain);
            assert_eq!(a, b, "{outline:?}");
            if a.is_some() {
                assert_eq!(fast, plain, "{outline:?}");
            }
            outcomes[match a {
                None => 0,
                Some(false) => 1,
                Some(true) => 2,
            }] += 1;
        }
        assert!(outcomes.iter().all(|&k| k > 1000), "every outcome tested: {outcomes:?}");
    }
}
