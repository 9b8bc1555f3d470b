//! Geometric processor (GP, SYSTEM.md 3): from the scene database and the eye to the
//! frame list.
//!
//! Per frame, for every face in the BSP's front-to-back order (moving models slotted
//! in as wholes): the model-to-eye transform (one 4x4 matrix per model, P5),
//! coarse rejection of whole models by their bounding sphere and of faces by their
//! outcodes against the view volume in homogeneous coordinates (P5 b), back-face
//! culling (P5 d), the object classes of P4 (1: inside the window, passed on
//! untouched; 2: crosses the window border, clipped by the window; 3: crosses the
//! screen (near) plane, clipped by that plane first), perspective projection,
//! clipping by the window in the P4 clipping block ([`clip`]), snapping to the
//! VP's 1/256-pixel grid and set-up ([`setup`]).
//!
//! Work shared between faces: a vertex shared by several faces of a mesh (a
//! terrain's by about six) is transformed and outcoded once while its faces are
//! met together (a small cache by the tree's position numbers, `VertexCache`;
//! such a tree's faces' vertices read through their numbers from its distinct
//! vertices, [`Bsp::shared_vertex`]: 12 bytes a triangle rather than 120),
//! and a textured face's texture axes are reused by the next face of its instance
//! and material ([`setup::Setup::add_face`]); both give the very bits the face
//! by face arithmetic gives.
//!
//! A face's whole path (transform, lighting, clipping, set-up, edge codes) is one
//! function body compiled twice: for the baseline processor and for AVX2 with
//! BMI1/2, chosen once a frame by detection ([`FrameBuilder::face`]). The same
//! operations in the same order, so the same bits: the AVX2 copy's three-operand
//! VEX forms and register shifts, with the set-up and the edge codes inline in it
//! (no call per face into them), took `many`'s GP from about 1510 to 1240
//! instructions a triangle (callgrind, with the set-up's triangle path). In that
//! copy alone (`face_body::<true>`), a triangle is also snapped and its three
//! edge codes made with the three points or edges in the lanes of AVX2 registers
//! (`setup::snap_triangle_points_avx2`, [`EdgeCode::push_triangle_avx2`], the
//! edge codes' six 64-bit divisions as two float divisions with an exact
//! correction): about 1240 to 1020 instructions a triangle. Its triangles are
//! also placed, outcoded and projected with the three vertices in the lanes of
//! AVX2 registers (`TriangleLanes`, the projection handed to the snap in lanes,
//! `setup::Outline::TriangleLanes`; a cached triangle, terrain's, projected in
//! them), and a triangle's lighting choices made once for its three vertices:
//! `many`'s GP about 980 to 870 instructions a triangle (session 14). A face of
//! the static tree goes to its own copy by its number alone
//! ([`FrameBuilder::static_face_avx2`]; the tree walked with the guests' test a
//! constant, [`Bsp::traverse_subtree_culled`]), and the per-frame constants of the
//! edge codes ([`TriangleRoot`](crate::vp::edge::TriangleRoot)) and the outcodes (`View::size`) are made once a
//! frame: about 870 to 820 (session 15). The walk of the static tree is itself
//! compiled for AVX2 with a face's set-up inlined at its visit of a face
//! (`FrameBuilder::traverse_static_avx2`): no call a face, about 17 fewer
//! instructions a face (session 20). The matrix the lanes load is kept aligned
//! (`EyeMatrix`), as are the edge codes they store, an instance's class and
//! matrix lie side by side (one bounds check), and the lighting's environment
//! constants are made once a frame and taken by reference (`LightConstants`):
//! `many`'s GP 853.3 to 834.0 M instructions (session 27).
//!
//! The static tree's records and vertices are asked for a few visits before the
//! GP reads them (`FrameBuilder::visit_ahead`, [`Bsp::prefetch_record`]): the
//! traversal's order jumps in memory, and the VPs' pass leaves none of the
//! database in the caches, so that a third of the GP's time went waiting on
//! memory; the visits are made in the same order, so the frame is the same.
//!
//! Eye coordinates: X right, Y down, Z forward (depth); screen `x = W/2 + f X/Z`,
//! `y = H/2 + f Y/Z` with `f = (W/2) / tan(fov/2)`. The GP computes in `f64` (the
//! papers' GP used 32-bit floats; a modern CPU pays nothing for the extra bits) and
//! hands the VP `f32` coefficients.
//!
//! **Invariant**: the frame list is in exact priority order for non-intersecting
//! geometry, and every polygon in it is convex, inside the window, non-degenerate.

pub mod clip;
pub mod lights;
pub mod setup;

use std::cell::Cell;
use std::fmt;

use glam::{DMat3, DMat4, DVec2, DVec3};
use rayon::prelude::*;
use serde::Serialize;

use crate::db::bsp::{Bsp, BspFace, BspVertex, FaceRecord, NodeBounds, Piece, Plane, Slot, Visit};
use crate::db::{Eye, Scene, Screen};
use crate::frame::{FrameList, PixelBox, PrimitiveKind};
#[cfg(doc)]
use crate::vp::edge::EdgeCode;
use clip::Window;
use setup::{EyeVertex, Outline, Setup, Source};

/// The near (screen) plane's depth in metres.
pub const NEAR: f64 = 0.1;

/// Which window clipper the GP uses (all three give the same polygons).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum Clipper {
    /// P4 table 1: four half-plane automata in a pipeline.
    #[default]
    Automaton,
    /// P4 fig. 3: all borders at once.
    AllBorders,
    /// Plain Sutherland-Hodgman.
    Reference,
}

/// Counters of the GP for one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct GpCounters {
    /// Instances (models) considered.
    pub instances: u64,
    /// Instances rejected whole by their bounding sphere.
    pub instances_rejected: u64,
    /// Instances per P4 class 1, 2, 3 (by bounding sphere).
    pub instance_class: [u64; 3],
    /// Faces read from the database (after the BSP's splits).
    pub faces_in: u64,
    /// Faces culled as back-facing.
    pub backfacing: u64,
    /// Faces rejected as outside the view volume.
    pub outside: u64,
    /// Faces per P4 class 1, 2, 3.
    pub face_class: [u64; 3],
    /// Faces clipped by the near plane.
    pub near_clipped: u64,
    /// Faces clipped by the window.
    pub window_clipped: u64,
    /// Faces that vanished after clipping or snapping (zero area).
    pub degenerate: u64,
    /// Light points turned into polygons.
    pub lights: u64,
    /// Polygons in the frame list.
    pub polygons_out: u64,
}

impl GpCounters {
    /// Adds another worker's counts into these.
    pub fn add(&mut self, o: &GpCounters) {
        self.instances += o.instances;
        self.instances_rejected += o.instances_rejected;
        for k in 0..3 {
            self.instance_class[k] += o.instance_class[k];
            self.face_class[k] += o.face_class[k];
        }
        self.faces_in += o.faces_in;
        self.backfacing += o.backfacing;
        self.outside += o.outside;
        self.near_clipped += o.near_clipped;
        self.window_clipped += o.window_clipped;
        self.degenerate += o.degenerate;
        self.lights += o.lights;
        self.polygons_out += o.polygons_out;
    }
}

/// A moving model: its own BSP in model coordinates.
#[derive(Clone, Debug)]
struct Moving {
    instance: u32,
    bsp: Bsp,
}

/// Per-instance data fixed at load.
#[derive(Clone, Debug)]
struct InstanceInfo {
    model_to_world: DMat4,
    world_to_model: DMat4,
    /// Bounding sphere in world coordinates.
    center: DVec3,
    radius: f64,
}

/// The database as the GP holds it: the scene, the static BSP (world coordinates),
/// the moving models with their own BSPs.
#[derive(Clone, Debug)]
pub struct Database {
    /// The scene.
    pub scene: Scene,
    /// The static BSP over all non-moving instances, world coordinates.
    pub bsp: Bsp,
    moving: Vec<Moving>,
    instances: Vec<InstanceInfo>,
}

impl Database {
    /// Builds the database (BSP trees) from a validated scene.
    pub fn new(scene: Scene) -> Self {
        let mut instances = Vec::with_capacity(scene.instances.len());
        let mut static_faces = Vec::new();
        let mut moving = Vec::new();
        for (ii, inst) in scene.instances.iter().enumerate() {
            let m = inst.transform.as_dmat4();
            let model = &scene.models[inst.model as usize];
            let (c, r) = model.bounding_sphere();
            let scale =
                m.x_axis.truncate().length().max(m.y_axis.truncate().length()).max(m.z_axis.truncate().length());
            instances.push(InstanceInfo {
                model_to_world: m,
                world_to_model: m.inverse(),
                center: m.transform_point3(c.as_dvec3()),
                radius: f64::from(r) * scale,
            });
            if inst.moving {
                let faces = bsp_faces(&scene, ii as u32, DMat4::IDENTITY);
                moving.push(Moving { instance: ii as u32, bsp: Bsp::build(faces) });
            } else {
                static_faces.extend(bsp_faces(&scene, ii as u32, m));
            }
        }
        Self { bsp: Bsp::build(static_faces), moving, instances, scene }
    }

    /// Number of moving models.
    pub fn moving_count(&self) -> usize {
        self.moving.len()
    }

    /// Total BSP nodes and splits, static and moving trees together.
    pub fn bsp_totals(&self) -> (usize, usize) {
        let nodes = self.bsp.stats.nodes + self.moving.iter().map(|m| m.bsp.stats.nodes).sum::<usize>();
        let splits = self.bsp.stats.splits + self.moving.iter().map(|m| m.bsp.stats.splits).sum::<usize>();
        (nodes, splits)
    }
}

/// The faces of instance `ii` transformed by `m`, as BSP faces.
fn bsp_faces(scene: &Scene, ii: u32, m: DMat4) -> Vec<BspFace> {
    let inst = &scene.instances[ii as usize];
    let model = &scene.models[inst.model as usize];
    let normal_m = DMat3::from_mat4(m).inverse().transpose();
    model
        .faces
        .iter()
        .enumerate()
        .filter_map(|(fi, f)| {
            let vertices: Vec<BspVertex> = f
                .vertices
                .iter()
                .map(|&i| {
                    let v = &model.vertices[i as usize];
                    BspVertex {
                        position: m.transform_point3(v.position.as_dvec3()),
                        normal: (normal_m * v.normal.as_dvec3()).normalize_or_zero().as_vec3(),
                        intensity: v.intensity,
                    }
                })
                .collect();
            let n = newell(&vertices);
            let len = n.length();
            (len > 0.0).then(|| {
                let normal = n / len;
                BspFace {
                    plane: Plane { normal, d: normal.dot(vertices[0].position) },
                    vertices,
                    material: f.material,
                    instance: ii,
                    face: fi as u32,
                }
            })
        })
        .collect()
}

fn newell(vs: &[BspVertex]) -> DVec3 {
    let p0 = vs[0].position;
    let mut n = DVec3::ZERO;
    for i in 1..vs.len() - 1 {
        n += (vs[i].position - p0).cross(vs[i + 1].position - p0);
    }
    n
}

/// The eye's view: world-to-eye matrix and projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// World to eye coordinates.
    pub world_to_eye: DMat4,
    /// Eye position (world).
    pub position: DVec3,
    /// Focal length in pixels.
    pub focal: f64,
    /// Screen centre.
    pub center: DVec2,
    /// Screen size.
    pub screen: Screen,
    /// The screen size as `f64` (`f64::from` of each, exact), the outcodes'
    /// borders' scales: kept rather than converted at each triangle
    /// ([`TriangleLanes::place`]).
    pub size: DVec2,
}

impl View {
    /// The view of `eye` on `screen`.
    pub fn new(eye: &Eye, screen: Screen) -> Self {
        let (h, p, r) =
            (f64::from(eye.heading).to_radians(), f64::from(eye.pitch).to_radians(), f64::from(eye.roll).to_radians());
        // Orientation: roll about forward, then pitch about right, then heading
        // (clockwise seen from above) about world Z. At rest: right = +X,
        // forward = +Y, up = +Z.
        let o = DMat3::from_rotation_z(-h) * DMat3::from_rotation_x(p) * DMat3::from_rotation_y(r);
        let right = o * DVec3::X;
        let forward = o * DVec3::Y;
        let up = o * DVec3::Z;
        let down = -up;
        let pos = eye.position.as_dvec3();
        let rot = DMat3::from_cols(right, down, forward).transpose();
        let world_to_eye = DMat4::from_mat3(rot) * DMat4::from_translation(-pos);
        let focal = f64::from(screen.width) * 0.5 / (f64::from(eye.fov).to_radians() * 0.5).tan();
        Self {
            world_to_eye,
            position: pos,
            focal,
            center: DVec2::new(f64::from(screen.width) * 0.5, f64::from(screen.height) * 0.5),
            screen,
            size: DVec2::new(f64::from(screen.width), f64::from(screen.height)),
        }
    }

    /// Screen position of an eye-space point in front of the eye.
    #[inline]
    pub fn project(&self, p: DVec3) -> DVec2 {
        DVec2::new(self.center.x + self.focal * p.x / p.z, self.center.y + self.focal * p.y / p.z)
    }

    /// Outcode of an eye-space point against the view volume in homogeneous
    /// coordinates (`hx = f X + cx Z`, `hy = f Y + cy Z`, `w = Z`): bit 0 left
    /// (`hx < 0`), 1 right (`hx > W w`), 2 top, 3 bottom, 4 near (`Z < NEAR`).
    #[inline]
    pub fn outcode(&self, p: DVec3) -> u8 {
        let hx = self.focal * p.x + self.center.x * p.z;
        let hy = self.focal * p.y + self.center.y * p.z;
        let (w, wx, wy) = (p.z, f64::from(self.screen.width) * p.z, f64::from(self.screen.height) * p.z);
        (hx < 0.0) as u8
            | ((hx > wx) as u8) << 1
            | ((hy < 0.0) as u8) << 2
            | ((hy > wy) as u8) << 3
            | ((w < NEAR) as u8) << 4
    }

    /// The view volume's five borders as world-space linear functions, for
    /// rejecting whole boxes of the static tree ([`Frustum`]).
    fn frustum(&self) -> Frustum {
        let m = &self.world_to_eye;
        let row = |i: usize| (DVec3::new(m.x_axis[i], m.y_axis[i], m.z_axis[i]), m.w_axis[i]);
        let ((r0, t0), (r1, t1), (r2, t2)) = (row(0), row(1), row(2));
        let (f, cx, cy) = (self.focal, self.center.x, self.center.y);
        let (w, h) = (f64::from(self.screen.width), f64::from(self.screen.height));
        // Each as `g = a . P + b`, a vertex's outcode bit set where `g > 0`:
        // `hx < 0`, `hx > W Z`, `hy < 0`, `hy > H Z`, `Z < NEAR` (see `outcode`).
        let borders = [
            (-(r0 * f + r2 * cx), -(t0 * f + t2 * cx)),
            (r0 * f + r2 * (cx - w), t0 * f + t2 * (cx - w)),
            (-(r1 * f + r2 * cy), -(t1 * f + t2 * cy)),
            (r1 * f + r2 * (cy - h), t1 * f + t2 * (cy - h)),
            (-r2, -(t2 - NEAR)),
        ];
        Frustum {
            borders,
            coefficients: 1.0 + f.abs() + cx.abs() + cy.abs() + w + h,
            translation: t0.abs() + t1.abs() + t2.abs() + NEAR,
        }
    }

    /// The P4 class and rejection of a sphere (eye-space centre, radius): `None` when
    /// wholly outside the view volume, else `Some(1 | 2 | 3)`.
    pub fn sphere_class(&self, c: DVec3, r: f64) -> Option<u8> {
        if c.z < NEAR - r {
            return None;
        }
        let (w, h) = (f64::from(self.screen.width), f64::from(self.screen.height));
        // Side planes through the eye: normals of the four window borders.
        let planes = [
            DVec3::new(self.focal, 0.0, self.center.x),
            DVec3::new(-self.focal, 0.0, w - self.center.x),
            DVec3::new(0.0, self.focal, self.center.y),
            DVec3::new(0.0, -self.focal, h - self.center.y),
        ];
        let mut crosses = false;
        for n in planes {
            let d = n.dot(c) / n.length();
            if d < -r {
                return None;
            }
            if d < r {
                crosses = true;
            }
        }
        Some(if c.z - r < NEAR {
            3
        } else if crosses {
            2
        } else {
            1
        })
    }
}

/// The view volume as five world-space borders, to reject a box of the static tree
/// whose every point lies outside one of them: then every vertex of every face in
/// it has that outcode bit, and each such face would be rejected as outside.
struct Frustum {
    /// `(a, b)` per border: outside where `a . P + b > 0`.
    borders: [(DVec3, f64); 5],
    /// A bound on the magnitudes of the outcodes' coefficients (focal length,
    /// centre, screen size; the view's rotation has entries at most 1).
    coefficients: f64,
    /// A bound on the view translation's part of an eye coordinate.
    translation: f64,
}

/// A box counts as outside only when it is beyond a border by this much relative
/// to the magnitudes in the outcodes' arithmetic. Each vertex's outcode is computed
/// in `f64` with a relative error of a few 2^-52 (about 1e-15) of those
/// magnitudes, the box test with as little: a margin of 1e-9 leaves the bits of
/// every vertex in a rejected box certain; the faces of boxes nearer a border
/// than that take the face-by-face path.
const CULL_MARGIN: f64 = 1e-9;

/// Subtrees with fewer faces are not tested against the view volume: the test
/// (about 40 instructions) would cost more than the work it could save at the
/// borders of the view.
const CULL_MIN_FACES: u32 = 16;

impl Frustum {
    /// `Some(false)` where the box lies wholly outside one border (by
    /// [`CULL_MARGIN`]: then rejected), `Some(true)` where it lies wholly inside
    /// every border (by the margin too), `None` where it may cross one.
    ///
    /// A box inside every border holds no box that is rejected: a
    /// subtree's box holds its children's (each the least box of its faces'
    /// vertices, the union of its children's and its own faces'), and a point
    /// inside a border by the margin is not outside it by the margin, whatever
    /// the rounding (of a few 2^-52 of the magnitudes, the margin 1e-9 of them).
    #[inline]
    fn place(&self, b: &NodeBounds) -> Option<bool> {
        let size = (b.center.abs() + b.half).element_sum();
        let margin = CULL_MARGIN * self.coefficients * (size + self.translation);
        let mut inside = true;
        for (a, k) in &self.borders {
            let (middle, reach) = (a.dot(b.center) + k, a.abs().dot(b.half));
            if middle - reach > margin {
                return Some(false);
            }
            inside &= middle + reach < -margin;
        }
        inside.then_some(true)
    }
}

/// Options of the GP.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GpConfig {
    /// The window clipper.
    pub clipper: Clipper,
    /// Geometry processors working in parallel (threads); 1 for one.
    pub threads: usize,
}

impl Default for GpConfig {
    fn default() -> Self {
        Self { clipper: Clipper::default(), threads: 1 }
    }
}

/// Scratch buffers reused from face to face (no allocation per face).
#[derive(Default)]
struct Scratch {
    eye: Vec<EyeVertex>,
    clipped_eye: Vec<EyeVertex>,
    screen: Vec<DVec2>,
    window: Vec<DVec2>,
    places: VertexCache,
}

/// log2 of the slots of a [`VertexCache`].
const VERTEX_CACHE_BITS: u32 = 10;
/// The slots of a [`VertexCache`].
const VERTEX_CACHE_SLOTS: usize = 1 << VERTEX_CACHE_BITS;

/// The eye-space positions and outcodes of the vertices met last, by their
/// position numbers in the tree being traversed
/// ([`SharedVertex::position`](crate::db::bsp::SharedVertex::position)): one slot
/// per number modulo [`VERTEX_CACHE_SLOTS`].
///
/// Why: the faces of a mesh share their vertices (each of a terrain grid's in about
/// six triangles), and the traversal meets a subtree's faces together; the
/// transform and outcode of a position seen a few faces before are taken from
/// here (about 60 instructions a vertex, on `terrain` ~70 % of them). The same
/// operations on the same position and matrix give the same bits, so the frame
/// is unchanged: a slot holds a value only for the tree whose numbers it was
/// stored under (the cache is emptied when a moving model's tree, with its own
/// numbers and matrix, is entered and left).
struct VertexCache {
    /// Per slot: the position number stored there, or `u32::MAX` for none.
    tags: Box<[u32; VERTEX_CACHE_SLOTS]>,
    /// Per slot: its eye-space position and outcode.
    places: Box<[(DVec3, u8); VERTEX_CACHE_SLOTS]>,
}

impl Default for VertexCache {
    fn default() -> Self {
        Self {
            tags: Box::new([u32::MAX; VERTEX_CACHE_SLOTS]),
            places: Box::new([(DVec3::ZERO, 0); VERTEX_CACHE_SLOTS]),
        }
    }
}

impl VertexCache {
    /// The place of the vertex numbered `id`, from its slot or else `place()`
    /// (then stored).
    #[inline(always)]
    fn get(&mut self, id: u32, place: impl FnOnce() -> (DVec3, u8)) -> (DVec3, u8) {
        let slot = id as usize & (VERTEX_CACHE_SLOTS - 1);
        if self.tags[slot] == id {
            return self.places[slot];
        }
        let p = place();
        self.tags[slot] = id;
        self.places[slot] = p;
        p
    }

    /// Forgets every place (before and after another tree's vertices).
    fn clear(&mut self) {
        self.tags.fill(u32::MAX);
    }
}

/// What is slotted into the static tree's order besides its own faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Guest {
    /// A moving model (index into `Database::moving`).
    Moving(usize),
    /// A light point (index into `Scene::lights`).
    Light(usize),
}

/// One instance as this frame's view sees it.
struct InstanceView {
    /// P4 class by bounding sphere (`None`: rejected).
    class: Option<u8>,
    /// Model-to-eye matrix.
    model_to_eye: DMat4,
}

/// What the GP knows of one frame before it processes faces: the view, the
/// instances' classes and matrices, the guests' places. Shared, read-only, by the
/// workers that process stretches of the priority order in parallel.
struct Shared<'a> {
    db: &'a Database,
    view: View,
    config: GpConfig,
    /// Per instance: its P4 class and model-to-eye matrix, side by side (a face
    /// reads both: one bounds check).
    instances: Vec<InstanceView>,
    /// The view's world-to-eye matrix (`View::world_to_eye`), aligned for
    /// [`TriangleLanes::place`]: the static tree's faces' matrix.
    world_to_eye: EyeMatrix,
    /// Guests sorted by (node, slot, distance from the eye).
    guests: Vec<(u32, u8, f64, Guest)>,
    sun_world: DVec3,
    /// The environment's lighting constants, made once a frame.
    light: LightConstants,
    /// The view volume, for rejecting the static tree's subtrees.
    frustum: Frustum,
    /// Whether subtrees outside it are passed over ([`Shared::culls_within`]).
    cull: bool,
    /// Whether triangles take [`FrameBuilder::face`]'s path for triangles (the
    /// tests compare it with the general one).
    triangles: bool,
    /// Whether shared vertices are placed once ([`VertexCache`]; the tests
    /// compare it with placing every vertex of every face).
    vertex_cache: bool,
    /// Whether faces are set up by the copy of [`FrameBuilder::face`] compiled for
    /// AVX2 ([`has_avx2`]; the tests compare it with the plain copy).
    avx2: bool,
    /// Instance counters (counted once, here).
    counters: GpCounters,
}

/// One geometry processor at work on a stretch of the frame's priority order.
struct FrameBuilder<'a> {
    f: &'a Shared<'a>,
    /// Per node of the static tree: bit `slot` set where guests are attached.
    places: &'a [u8],
    setup: Setup,
    out: &'a mut FrameList,
    counters: GpCounters,
    /// Lists reused face to face, and the vertex cache; one per task when the GP
    /// runs on several threads, kept across the tasks a thread takes in a frame
    /// (the cache's places hold for the whole frame).
    scratch: &'a mut Scratch,
    /// The static tree's visits named but not yet made ([`FrameBuilder::visit_ahead`]).
    ahead: Ahead,
}

/// Visits of the static tree that the traversal has named and the GP will make
/// [`VISITS_AHEAD`] visits later: visit `k` (counting from 0) in `ring[k %
/// VISITS_AHEAD]` until visit `k + VISITS_AHEAD` is named.
#[derive(Clone, Copy)]
struct Ahead {
    ring: [Visit; VISITS_AHEAD],
    /// The visits named so far.
    named: usize,
}

impl Default for Ahead {
    fn default() -> Self {
        Self { ring: [Visit::Culled(0); VISITS_AHEAD], named: 0 }
    }
}

/// How many visits ahead of the one it makes the GP asks for a face's record
/// ([`Bsp::prefetch_record`]); its vertices are asked for
/// [`VERTICES_AHEAD`] visits ahead, when the record has had time to come.
///
/// Why: the GP's per-frame pass reads ~6 MB of records and vertices on
/// `default` (35 000 faces), which the VPs' pass has pushed out of the caches:
/// fetched only when read, face after face, they held the GP up (one thread, the
/// GP alone after 64 MB of other writes: ~2.9 ms, against ~1.8 with its data in
/// the caches). A face takes tens of nanoseconds (a back-facing one) to a few
/// hundred (a set-up one), a line from memory about a hundred. Asked for ahead:
/// ~2.5 ms there, `many`'s GP (a million faces) 330-370 → 200-280 ms, for about
/// 28 instructions a visited face (default's GP 15.1 → 16.1 M, session 16).
const VISITS_AHEAD: usize = 16;
/// See [`VISITS_AHEAD`] (less than it).
const VERTICES_AHEAD: usize = 8;

/// Faces per task when the GP runs on several threads (small enough to balance the
/// load, large enough that the VPs' switch from one task's list to the next costs
/// nothing). Each task is a
/// stretch of the priority order, whole subtrees of the BSP traversed by the GP
/// that sets them up, so that the traversal too runs in parallel: on `terrain` it
/// was a tenth of the GP's work, done on one thread before the others started.
const FACES_PER_TASK: u32 = 2048;

/// Builds the frame list of one frame: the GP's whole job (a fresh list; see
/// [`frame_into`] to reuse one frame to frame).
pub fn frame(db: &Database, eye: &Eye, screen: Screen, config: &GpConfig, counters: &mut GpCounters) -> FrameList {
    let mut out = FrameList::default();
    frame_into(db, eye, screen, config, counters, &mut GpMemory::default(), &mut out);
    out.polygons.shrink_to_fit();
    out
}

/// The GP's working memory kept from frame to frame: the traversal's pieces and
/// tasks, the guests' places, the stretches' frame lists and the threads of the
/// several GPs. Reusing it (and the
/// output list, one half of P1's double-buffered frame memory) means a frame
/// allocates nothing once the lists have grown to the scene's size.
#[derive(Default)]
pub struct GpMemory {
    /// The traversal's pieces for several GPs ([`Bsp::pieces`]).
    pieces: Vec<Piece>,
    /// Where each task's pieces end.
    tasks: Vec<u32>,
    /// Per node of the static tree: bit `slot` set where guests are attached.
    guest_places: Vec<u8>,
    stretches: Vec<FrameList>,
    pool: Option<(usize, rayon::ThreadPool)>,
}

impl fmt::Debug for GpMemory {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("GpMemory")
            .field("pieces", &self.pieces.len())
            .field("stretches", &self.stretches.len())
            .field("threads", &self.pool.as_ref().map(|(n, _)| *n))
            .finish()
    }
}

impl GpMemory {
    /// A pool of `threads` workers, made once and kept (`None` if the system
    /// refuses threads: the stretches then run one after another).
    fn pool(&mut self, threads: usize) -> Option<&rayon::ThreadPool> {
        if self.pool.as_ref().is_none_or(|(n, _)| *n != threads) {
            self.pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().ok().map(|p| (threads, p));
        }
        self.pool.as_ref().map(|(_, p)| p)
    }
}

/// Builds the frame list of one frame into `out` (cleared first, its allocations
/// kept), with working memory `memory` kept between frames.
///
/// With `config.threads > 1` the priority order is cut into stretches (whole
/// subtrees of the BSP and the visits above them) that several geometry processors
/// traverse and set up in parallel (P5's several GPs); their frame lists are
/// joined in order, so the result is the same, byte for byte.
pub fn frame_into(
    db: &Database,
    eye: &Eye,
    screen: Screen,
    config: &GpConfig,
    counters: &mut GpCounters,
    memory: &mut GpMemory,
    out: &mut FrameList,
) {
    let mut stretches = std::mem::take(&mut memory.stretches);
    frame_with(db, eye, screen, config, counters, memory, &mut stretches, Some(out), true, true);
    memory.stretches = stretches;
}

/// [`frame_into`] without the join: the frame as its stretches, frame lists (each
/// with the frame's header, their polygon, vertex and texture indices their own)
/// whose polygons in order, one list after another, are [`frame_into`]'s list
/// (with one GP, or a scene of one task, a single list). The VPs walk them in order
/// ([`crate::matrix::Matrix::render_stretches`]), so the copy of every polygon,
/// vertex and edge code into one list is left out: on `many` (a million
/// triangles, ~292 bytes each) it was ~290 MB a frame, ~12 % of the GP's time on
/// two threads. `stretches` keeps its lists' allocations from frame to frame.
pub fn frame_stretches_into(
    db: &Database,
    eye: &Eye,
    screen: Screen,
    config: &GpConfig,
    counters: &mut GpCounters,
    memory: &mut GpMemory,
    stretches: &mut Vec<FrameList>,
) {
    frame_with(db, eye, screen, config, counters, memory, stretches, None, true, true);
}

/// [`frame_into`] (the stretches joined into `out`) or, with `out` `None`,
/// [`frame_stretches_into`] (the frame left as `stretches`), with or without its
/// shortcuts (`shortcuts`: passing over the static tree's subtrees outside the view
/// volume, and over the guests' places in a frame with no guests; triangles set up
/// by a path of their own; shared vertices placed once; the tests compare the two),
/// and with or without the copy of the faces' path compiled for AVX2 (`avx2`, where
/// the processor has it: [`Shared::avx2`]).
#[allow(clippy::too_many_arguments)]
fn frame_with(
    db: &Database,
    eye: &Eye,
    screen: Screen,
    config: &GpConfig,
    counters: &mut GpCounters,
    memory: &mut GpMemory,
    stretches: &mut Vec<FrameList>,
    out: Option<&mut FrameList>,
    shortcuts: bool,
    avx2: bool,
) {
    let view = View::new(eye, screen);
    let mut shared = Shared::new(db, view, *config);
    shared.cull = shortcuts;
    shared.triangles = shortcuts;
    shared.vertex_cache = shortcuts;
    shared.avx2 = avx2 && has_avx2();
    let shared = shared;
    // Only the places where guests are attached this frame are visited (a
    // terrain's tree has twice as many empty places as faces).
    let mut place_bits = std::mem::take(&mut memory.guest_places);
    place_bits.clear();
    place_bits.resize(db.bsp.nodes.len(), 0);
    for g in &shared.guests {
        if let Some(p) = place_bits.get_mut(g.0 as usize) {
            *p |= 1 << g.1;
        }
    }
    let places = &place_bits[..];
    // With no guest attached this frame, their places need no visits.
    let guests = !shared.guests.is_empty() || !shortcuts;
    // The priority order: the BSP's traversal, cut into pieces (whole subtrees and
    // the single visits above them) and the pieces into tasks of about
    // `FACES_PER_TASK` faces, each traversed and set up by one GP.
    let parallel = config.threads > 1 && db.bsp.records.len() > FACES_PER_TASK as usize;
    let mut pieces = std::mem::take(&mut memory.pieces);
    let mut tasks = std::mem::take(&mut memory.tasks);
    pieces.clear();
    tasks.clear();
    if parallel {
        let mut faces = 0;
        db.bsp.pieces(view.position, FACES_PER_TASK, |piece| {
            faces += match piece {
                Piece::Subtree(n) => db.bsp.subtree_faces(n),
                Piece::Visit(Visit::Face(_)) => 1,
                Piece::Visit(Visit::Guests(..) | Visit::Culled(_)) => 0,
            };
            pieces.push(piece);
            if faces >= FACES_PER_TASK {
                tasks.push(pieces.len() as u32);
                faces = 0;
            }
        });
        if tasks.last().is_none_or(|&t| t as usize != pieces.len()) {
            tasks.push(pieces.len() as u32);
        }
    }
    let run = |pieces: &[Piece], list: &mut FrameList, scratch: &mut Scratch| {
        let setup = Setup::new(&db.scene, &view);
        setup.header(list);
        let mut b = FrameBuilder {
            f: &shared,
            places,
            setup,
            out: list,
            counters: GpCounters::default(),
            scratch,
            ahead: Ahead::default(),
        };
        for &piece in pieces {
            match piece {
                Piece::Visit(v) => b.visit_ahead(v),
                Piece::Subtree(n) => b.traverse_static(n, guests),
            }
        }
        b.drain();
        b.counters
    };
    let mut c = GpCounters::default();
    let set_up = |stretches: &mut Vec<FrameList>| -> Vec<GpCounters> {
        stretches.resize_with(tasks.len(), FrameList::default);
        // One scratch per run of tasks a thread takes, not per task: a scratch's
        // vertex cache is 36 KiB to set up (and its places, this frame's, hold in
        // every task).
        stretches
            .par_iter_mut()
            .enumerate()
            .map_init(Scratch::default, |scratch, (k, l)| {
                let start = if k == 0 { 0 } else { tasks[k - 1] as usize };
                run(&pieces[start..tasks[k] as usize], l, scratch)
            })
            .collect()
    };
    // Called on a rayon pool of as many threads (the matrix's, `Matrix::install`):
    // work there rather than wake a second set of threads for the same cores.
    let in_pool = rayon::current_thread_index().is_some() && rayon::current_num_threads() == config.threads;
    let parts = match (parallel, in_pool) {
        (false, _) => None,
        (true, true) => Some(set_up(stretches)),
        (true, false) => memory.pool(config.threads).map(|pool| pool.install(|| set_up(stretches))),
    };
    let polygons_out = match parts {
        Some(parts) => {
            if let Some(out) = out {
                // The header empties the lists; their elements are kept here
                // instead, so that the join overwrites them rather than writing
                // them afresh.
                let kept = (
                    std::mem::take(&mut out.polygons),
                    std::mem::take(&mut out.vertices),
                    std::mem::take(&mut out.edges),
                    std::mem::take(&mut out.textures),
                );
                Setup::new(&db.scene, &view).header(out);
                (out.polygons, out.vertices, out.edges, out.textures) = kept;
                // On the threads that set the stretches up.
                match (in_pool, memory.pool.as_ref()) {
                    (true, _) => join_stretches(stretches, out, true),
                    (false, Some((_, pool))) => pool.install(|| join_stretches(stretches, out, true)),
                    (false, None) => join_stretches(stretches, out, false),
                }
            }
            for k in &parts {
                c.add(k);
            }
            stretches.iter().map(|l| l.polygons.len() as u64).sum()
        }
        None => {
            // With no list to join into, a frame set up by one GP is one stretch.
            let out = match out {
                Some(out) => out,
                None => {
                    stretches.truncate(1);
                    if stretches.is_empty() {
                        stretches.push(FrameList::default());
                    }
                    &mut stretches[0]
                }
            };
            let setup = Setup::new(&db.scene, &view);
            setup.header(out);
            let mut scratch = Scratch::default();
            let mut b = FrameBuilder {
                f: &shared,
                places,
                setup,
                out,
                counters: GpCounters::default(),
                scratch: &mut scratch,
                ahead: Ahead::default(),
            };
            if db.bsp.nodes.is_empty() {
                db.bsp.traverse(view.position, |v| b.visit_ahead(v));
            } else {
                b.traverse_static(0, guests);
            }
            b.drain();
            c = b.counters;
            b.out.polygons.len() as u64
        }
    };
    memory.pieces = pieces;
    memory.tasks = tasks;
    memory.guest_places = place_bits;
    c.add(&shared.counters);
    c.polygons_out = polygons_out;
    *counters = c;
}

/// Joins the stretches' frame lists into `out` (its header made, its lists holding
/// anything), in order:
/// [`FrameList::append`] of each, the same list. With `parallel` the stretches are
/// copied side by side on the current rayon pool, each into its own part of the
/// output (a terrain frame is about 17 MB of polygons, vertices and edge codes:
/// copied one stretch after another it was the several GPs' largest serial part).
fn join_stretches(stretches: &[FrameList], out: &mut FrameList, parallel: bool) {
    if !parallel {
        out.clear();
        for list in stretches {
            out.append(list);
        }
        return;
    }
    let total = |f: fn(&FrameList) -> usize| stretches.iter().map(f).sum::<usize>();
    let (np, nv, nt) = (total(|l| l.polygons.len()), total(|l| l.vertices.len()), total(|l| l.textures.len()));
    // Every element is overwritten below; these only size the lists (with any
    // element of the right kind as filler).
    let Some(first) = stretches.iter().find(|l| !l.polygons.is_empty()) else {
        out.clear();
        return;
    };
    out.polygons.resize(np, first.polygons[0].clone());
    out.boxes.resize(np, PixelBox::default());
    out.vertices.resize(nv, first.vertices[0]);
    out.edges.resize(nv, first.edges[0]);
    match stretches.iter().find_map(|l| l.textures.first()) {
        Some(&t) => out.textures.resize(nt, t),
        None => out.textures.clear(),
    }
    // Each stretch's part of the four lists, and its offsets (edges run in step
    // with vertices).
    let mut parts = Vec::with_capacity(stretches.len());
    let (mut polygons, mut boxes, mut vertices, mut edges, mut textures) =
        (&mut out.polygons[..], &mut out.boxes[..], &mut out.vertices[..], &mut out.edges[..], &mut out.textures[..]);
    let (mut v0, mut t0) = (0u32, 0u32);
    for list in stretches {
        let (p, rest_p) = std::mem::take(&mut polygons).split_at_mut(list.polygons.len());
        let (b, rest_b) = std::mem::take(&mut boxes).split_at_mut(list.boxes.len());
        let (v, rest_v) = std::mem::take(&mut vertices).split_at_mut(list.vertices.len());
        let (e, rest_e) = std::mem::take(&mut edges).split_at_mut(list.edges.len());
        let (t, rest_t) = std::mem::take(&mut textures).split_at_mut(list.textures.len());
        (polygons, boxes, vertices, edges, textures) = (rest_p, rest_b, rest_v, rest_e, rest_t);
        parts.push((list, p, b, v, e, t, v0, t0));
        v0 += list.vertices.len() as u32;
        t0 += list.textures.len() as u32;
    }
    parts.into_par_iter().for_each(|(list, p, b, v, e, t, v0, t0)| {
        b.copy_from_slice(&list.boxes);
        v.copy_from_slice(&list.vertices);
        e.copy_from_slice(&list.edges);
        t.copy_from_slice(&list.textures);
        for (d, s) in p.iter_mut().zip(&list.polygons) {
            *d = FrameList::moved(s, v0, t0);
        }
    });
}

impl<'a> Shared<'a> {
    fn new(db: &'a Database, view: View, config: GpConfig) -> Self {
        let mut s = Shared {
            db,
            view,
            config,
            instances: Vec::with_capacity(db.instances.len()),
            world_to_eye: EyeMatrix(view.world_to_eye),
            guests: Vec::new(),
            sun_world: db.scene.env.sun.as_dvec3().normalize_or_zero(),
            light: LightConstants {
                ambient: f64::from(db.scene.env.ambient),
                pb: f64::from(db.scene.env.background_brightness),
                neg_beta: Lighting::neg_beta(db.scene.env.attenuation),
            },
            frustum: view.frustum(),
            cull: true,
            triangles: true,
            vertex_cache: true,
            avx2: false,
            counters: GpCounters::default(),
        };
        s.instances();
        s.guests();
        s
    }

    /// Instance transforms, rejection and P4 classes by bounding sphere.
    fn instances(&mut self) {
        for info in &self.db.instances {
            self.counters.instances += 1;
            let c_eye = self.view.world_to_eye.transform_point3(info.center);
            let cl = self.view.sphere_class(c_eye, info.radius);
            match cl {
                None => self.counters.instances_rejected += 1,
                Some(k) => self.counters.instance_class[k as usize - 1] += 1,
            }
            self.instances.push(InstanceView { class: cl, model_to_eye: self.view.world_to_eye * info.model_to_world });
        }
    }

    /// Whether the subtree of node `n` of the static tree is passed over whole
    /// ([`Visit::Culled`]): large enough, wholly outside the view volume, and with
    /// no guest attached inside (a guest's place would be lost). A walk keeps in
    /// `inside` the nodes of the last subtree found wholly inside the view volume
    /// (`start..end` of the tree's depth-first numbering, a subtree's nodes
    /// numbered together; empty at the walk's start): none of them is culled
    /// ([`Frustum::place`]), so none is tested. The walk enters a subtree's nodes
    /// one after another, so that one subtree remembered is enough.
    ///
    /// Why: on `many` (a million triangles in view, none culled) the test of every
    /// node of at least [`CULL_MIN_FACES`] faces was ~12 M instructions a frame,
    /// and the read of every node's face count a load from memory at each node;
    /// with the root inside, one test. Which nodes are culled is unchanged.
    ///
    /// Asked at every node the traversal enters (on `many` about one a face): the
    /// range and size tests, which turn nearly every node away, inline in the
    /// traversal; the box test out of line.
    #[inline(always)]
    fn culls_within(&self, n: u32, inside: &Cell<(u32, u32)>) -> bool {
        let (start, end) = inside.get();
        // The range first: on `many` it turns every node away.
        !(start..end).contains(&n)
            && self.cull
            && self.db.bsp.subtree_faces(n) >= CULL_MIN_FACES
            && self.culls_large(n, inside)
    }

    /// [`Shared::culls_within`] of a node with at least [`CULL_MIN_FACES`] faces
    /// below it, not known to be inside.
    #[inline(never)]
    fn culls_large(&self, n: u32, inside: &Cell<(u32, u32)>) -> bool {
        let bsp = &self.db.bsp;
        let end = n + bsp.subtree_nodes(n);
        match self.frustum.place(bsp.bounds(n)) {
            Some(false) => {}
            Some(true) => {
                inside.set((n, end));
                return false;
            }
            None => return false,
        }
        let first = self.guests.partition_point(|g| g.0 < n);
        self.guests.get(first).is_none_or(|g| g.0 >= end)
    }

    /// Attaches moving models and light points to the static tree.
    fn guests(&mut self) {
        let db = self.db;
        for (mi, m) in db.moving.iter().enumerate() {
            let info = &db.instances[m.instance as usize];
            if self.instances[m.instance as usize].class.is_none() {
                continue;
            }
            let (node, slot) = db.bsp.attach(info.center, info.radius);
            self.guests.push((node, slot as u8, info.center.distance(self.view.position), Guest::Moving(mi)));
        }
        for (li, l) in db.scene.lights.iter().enumerate() {
            let p = l.position.as_dvec3();
            let (node, slot) = db.bsp.attach(p, f64::from(l.size) * 0.5);
            self.guests.push((node, slot as u8, p.distance(self.view.position), Guest::Light(li)));
        }
        self.guests.sort_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)).then(a.2.total_cmp(&b.2)));
    }
}

impl FrameBuilder<'_> {
    /// [`FrameBuilder::visit`] of `step` [`VISITS_AHEAD`] visits later (and now of
    /// the step named that many visits before), its face's record and vertices asked
    /// for meanwhile. The same visits in the same order ([`FrameBuilder::drain`]
    /// makes the last ones), less the guests' places where none is attached, which
    /// do nothing (on `default` about two a node: kept out of the ring).
    #[inline(always)]
    fn visit_ahead(&mut self, step: Visit) {
        self.visit_ahead_with::<false>(step);
    }

    /// [`FrameBuilder::visit_ahead`]; with `AVX2` (only in
    /// [`FrameBuilder::traverse_static_avx2`]) its faces set up inline
    /// ([`FrameBuilder::visit_with`]).
    #[inline(always)]
    fn visit_ahead_with<const AVX2: bool>(&mut self, step: Visit) {
        let bsp = &self.f.db.bsp;
        match step {
            Visit::Face(i) => bsp.prefetch_record(i),
            Visit::Guests(n, slot) => {
                if !self.has_guests(n, slot) {
                    return;
                }
            }
            Visit::Culled(_) => {}
        }
        let a = &mut self.ahead;
        let named = a.named;
        a.named += 1;
        if let Some(Visit::Face(j)) = named.checked_sub(VERTICES_AHEAD).map(|k| a.ring[k % VISITS_AHEAD]) {
            bsp.prefetch_record_vertices(j);
        }
        let slot = &mut a.ring[named % VISITS_AHEAD];
        let oldest = std::mem::replace(slot, step);
        if named >= VISITS_AHEAD {
            self.visit_with::<AVX2>(oldest);
        }
    }

    /// The static tree's subtree below node `n` ([`Bsp::traverse_subtree_culled`])
    /// through [`FrameBuilder::visit_ahead`].
    ///
    /// With AVX2 by a copy of the walk compiled for it
    /// ([`FrameBuilder::traverse_static_avx2`]), the face set-up inlined into it: no
    /// call a face (the face function's prologue and epilogue: ~17 instructions a
    /// face on `many`).
    fn traverse_static(&mut self, n: u32, guests: bool) {
        #[cfg(target_arch = "x86_64")]
        if self.f.avx2 {
            // SAFETY: `traverse_static_avx2` only needs AVX2 and BMI1/2, which
            // `has_avx2` found the processor to have when `Shared::avx2` was set.
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return self.traverse_static_avx2(n, guests);
            }
        }
        self.traverse_static_body::<false>(n, guests);
    }

    /// [`FrameBuilder::traverse_static`] compiled for AVX2 and BMI1/2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
    #[inline(never)]
    fn traverse_static_avx2(&mut self, n: u32, guests: bool) {
        self.traverse_static_body::<true>(n, guests);
    }

    /// What [`FrameBuilder::traverse_static`] does, inlined into each of its copies.
    #[inline(always)]
    fn traverse_static_body<const AVX2: bool>(&mut self, n: u32, guests: bool) {
        let f = self.f;
        let inside = Cell::new((0, 0));
        f.db.bsp.traverse_subtree_culled(
            n,
            f.view.position,
            guests,
            #[inline(always)]
            |n| f.culls_within(n, &inside),
            // The face set-up inline at the walk's visit of a face, the one most
            // visits are made at; at its other visits (of a culled subtree, of
            // guests) by a call, not a copy of the set-up at each.
            #[inline(always)]
            |v| match v {
                Visit::Face(_) => self.visit_ahead_with::<AVX2>(v),
                _ => self.visit_ahead_with::<false>(v),
            },
        );
    }

    /// Makes the visits [`FrameBuilder::visit_ahead`] still holds, in order.
    fn drain(&mut self) {
        let named = self.ahead.named;
        for k in named.saturating_sub(VISITS_AHEAD)..named {
            let step = self.ahead.ring[k % VISITS_AHEAD];
            self.visit(step);
        }
        self.ahead.named = 0;
    }

    /// Whether guests are attached at `(n, slot)` this frame (or the tree has no
    /// node `n`, the place of a tree with no nodes).
    #[inline(always)]
    fn has_guests(&self, n: u32, slot: Slot) -> bool {
        self.places.get(n as usize).is_none_or(|&p| p >> slot as u8 & 1 != 0)
    }

    /// One step of the static tree's traversal, made by [`FrameBuilder::visit_ahead`]
    /// (which keeps out the guests' places with none attached).
    #[inline(always)]
    fn visit(&mut self, step: Visit) {
        self.visit_with::<false>(step);
    }

    /// [`FrameBuilder::visit`]; with `AVX2` (only in
    /// [`FrameBuilder::traverse_static_avx2`]) a face set up by
    /// [`FrameBuilder::face_body`] inline rather than by a call.
    #[inline(always)]
    fn visit_with<const AVX2: bool>(&mut self, step: Visit) {
        match step {
            Visit::Face(i) if AVX2 => self.static_face_body::<true>(i),
            Visit::Face(i) => self.static_face(i),
            Visit::Guests(n, slot) => {
                debug_assert!(self.has_guests(n, slot));
                self.emit_guests(n, slot);
            }
            Visit::Culled(n) => self.outside_faces(n),
        }
    }

    /// [`FrameBuilder::face`] of face `i` of the static tree.
    ///
    /// With AVX2 by a copy that finds the face, its tree and the view's matrix,
    /// eye and light itself ([`FrameBuilder::static_face_avx2`]): the traversal
    /// passes one number rather than five pointers, worked out again from `self`
    /// after each call (about 5 instructions a face on `many`).
    #[inline(always)]
    fn static_face(&mut self, i: u32) {
        #[cfg(target_arch = "x86_64")]
        if self.f.avx2 {
            // SAFETY: `static_face_avx2` only needs AVX2 and BMI1/2, which `has_avx2`
            // found the processor to have when `Shared::avx2` was set (nowhere else).
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return self.static_face_avx2(i);
            }
        }
        let f = self.f;
        let bsp = &f.db.bsp;
        self.face_plain(&bsp.records[i as usize], bsp, &f.world_to_eye, &f.view.position, &f.sun_world);
    }

    /// [`FrameBuilder::face_avx2`] of face `i` of the static tree, seen from the
    /// frame's eye ([`FrameBuilder::static_face`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
    #[inline(never)]
    fn static_face_avx2(&mut self, i: u32) {
        self.static_face_body::<true>(i);
    }

    /// [`FrameBuilder::face_body`] of face `i` of the static tree, seen from the
    /// frame's eye; with `AVX2` only where [`FrameBuilder::face_body`] allows it.
    #[inline(always)]
    fn static_face_body<const AVX2: bool>(&mut self, i: u32) {
        let f = self.f;
        let bsp = &f.db.bsp;
        self.face_body::<AVX2>(&bsp.records[i as usize], bsp, &f.world_to_eye, &f.view.position, &f.sun_world);
    }

    /// The faces of a subtree wholly outside the view volume ([`Shared::culls_within`]):
    /// counted as [`FrameBuilder::face`] counts them (every one that is not
    /// back-facing would have every vertex beyond the same border), without their
    /// transforms.
    fn outside_faces(&mut self, n: u32) {
        let f = self.f;
        let bsp = &f.db.bsp;
        let range = bsp.subtree_face_range(n);
        let c = &mut self.counters;
        for r in &bsp.records[range.start as usize..range.end as usize] {
            if f.instances[r.instance as usize].class.is_none() {
                continue;
            }
            c.faces_in += 1;
            if r.plane.distance(f.view.position) <= 0.0 {
                c.backfacing += 1;
            } else {
                c.outside += 1;
            }
        }
    }

    /// Emits the guests attached at `(node, slot)`, nearest first.
    fn emit_guests(&mut self, node: u32, slot: Slot) {
        let key = (node, slot as u8);
        let start = self.f.guests.partition_point(|g| (g.0, g.1) < key);
        let end = start + self.f.guests[start..].iter().take_while(|g| (g.0, g.1) == key).count();
        for gi in start..end {
            match self.f.guests[gi].3 {
                Guest::Moving(mi) => self.moving(mi),
                Guest::Light(li) => {
                    if lights::add_light_point(
                        &self.f.db.scene,
                        li,
                        &self.f.view,
                        &mut self.setup,
                        self.out,
                        &mut self.scratch.window,
                    ) {
                        self.counters.lights += 1;
                    }
                }
            }
        }
    }

    fn moving(&mut self, mi: usize) {
        let db = self.f.db;
        let m = &db.moving[mi];
        let inst = m.instance as usize;
        let to_eye = EyeMatrix(self.f.instances[inst].model_to_eye);
        let info = &db.instances[inst];
        let eye_model = info.world_to_model.transform_point3(self.f.view.position);
        // P5: the light direction is taken into model coordinates.
        let sun_model = (DMat3::from_mat4(info.model_to_world).transpose() * self.f.sun_world).normalize_or_zero();
        // Its tree's own position numbers and matrix.
        self.scratch.places.clear();
        m.bsp.traverse(eye_model, |step| {
            if let Visit::Face(f) = step {
                let r = &m.bsp.records[f as usize];
                self.face(r, &m.bsp, &to_eye, &eye_model, &sun_model);
            }
        });
        // The static tree's numbers again.
        self.scratch.places.clear();
    }

    /// Transforms, culls, clips and sets up one face. `to_eye` takes the face's
    /// coordinates to the eye's; `eye_local` is the eye in the face's coordinates;
    /// `tree` is the tree it is a record of (its vertices, and their position
    /// numbers for the [`VertexCache`] if the tree keeps them).
    ///
    /// By the copy compiled for AVX2 where the processor has it ([`Shared::avx2`]),
    /// else by the plain one: the same source ([`FrameBuilder::face_body`]), so the
    /// same operations in the same order, the same bits.
    #[inline(always)]
    fn face(&mut self, face: &FaceRecord, tree: &Bsp, to_eye: &EyeMatrix, eye_local: &DVec3, sun: &DVec3) {
        #[cfg(target_arch = "x86_64")]
        if self.f.avx2 {
            // SAFETY: `face_avx2` only needs AVX2 and BMI1/2, which `has_avx2`
            // found the processor to have when `Shared::avx2` was set (nowhere else).
            #[allow(unsafe_code, reason = "a function compiled for AVX2, after detection")]
            unsafe {
                return self.face_avx2(face, tree, to_eye, eye_local, sun);
            }
        }
        self.face_plain(face, tree, to_eye, eye_local, sun);
    }

    /// [`FrameBuilder::face_body`] compiled for the baseline processor.
    #[inline(never)]
    fn face_plain(&mut self, face: &FaceRecord, tree: &Bsp, to_eye: &EyeMatrix, eye_local: &DVec3, sun: &DVec3) {
        self.face_body::<false>(face, tree, to_eye, eye_local, sun);
    }

    /// [`FrameBuilder::face_body`] compiled for AVX2 and BMI1/2, the set-up and
    /// the edge codes inlined into it: the same `f64` and integer operations in the
    /// same order (Rust neither fuses nor reorders float operations), in VEX
    /// three-operand form (no register copies before each destructive SSE
    /// operation) with BMI2's shifts by a register.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
    #[inline(never)]
    fn face_avx2(&mut self, face: &FaceRecord, tree: &Bsp, to_eye: &EyeMatrix, eye_local: &DVec3, sun: &DVec3) {
        self.face_body::<true>(face, tree, to_eye, eye_local, sun);
    }

    /// What [`FrameBuilder::face`] does, inlined into each of its copies; with
    /// `AVX2` (only in the functions compiled for AVX2, after detection:
    /// [`FrameBuilder::face_avx2`], [`FrameBuilder::static_face_avx2`] and
    /// [`FrameBuilder::traverse_static_avx2`]) a triangle's edge codes are made in
    /// AVX2 registers ([`Setup::add_face_with`]).
    #[inline(always)]
    fn face_body<const AVX2: bool>(
        &mut self,
        face: &FaceRecord,
        tree: &Bsp,
        to_eye: &EyeMatrix,
        eye_local: &DVec3,
        sun: &DVec3,
    ) {
        // Where the tree numbers its vertices, they are read through the numbers
        // from its distinct vertices (with their position numbers for the cache);
        // else the record's own copies (and with no cache: the tests compare it).
        let ids = if self.f.vertex_cache { tree.record_vertex_ids_of(face) } else { None };
        let vertices = if ids.is_some() { &[] } else { tree.record_vertices_of(face) };
        let instance = &self.f.instances[face.instance as usize];
        let Some(instance_class) = instance.class else { return };
        let counters = &mut self.counters;
        counters.faces_in += 1;
        // Back-face culling: the eye must be in front of the face's plane.
        if face.plane.distance(*eye_local) <= 0.0 {
            counters.backfacing += 1;
            return;
        }
        let db = self.f.db;
        let view = &self.f.view;
        let material = &db.scene.materials[face.material as usize];
        let scratch = &mut self.scratch;
        // The face's and the environment's constants, out of the vertex loop: an
        // emissive or flat-shaded face's `cos a` is the same at every vertex.
        let ambient = self.f.light.ambient;
        let lit = |normal: DVec3| ambient + (1.0 - ambient) * normal.dot(*sun).max(0.0);
        let cos_a = match (material.emissive, material.shading) {
            (true, _) => Some(1.0),
            (false, crate::db::Shading::Smooth) => None,
            (false, _) => Some(lit(face.plane.normal)),
        };
        let light = Lighting { to_eye, view, cos_a, env: &self.f.light, sun };
        // The vertices' places from the cache when the tree numbers them (the test
        // made once a face: a tree that does not, `many`'s, pays nothing); their
        // light always per face.
        let (and, or);
        let corners = match (ids, vertices) {
            _ if !self.f.triangles => None,
            (Some(&[i, j, k]), _) => {
                let (a, b, c) = (tree.shared_vertex(i), tree.shared_vertex(j), tree.shared_vertex(k));
                Some(([&a.vertex, &b.vertex, &c.vertex], Some([a.position, b.position, c.position])))
            }
            (None, [a, b, c]) => Some(([a, b, c], None)),
            _ => None,
        };
        if let Some(([a, b, c], positions)) = corners {
            // A triangle (nearly every face of `many` and `terrain`): its vertices
            // in registers, and when it lies inside the window (class 1) set up
            // from them with no scratch list: the operations of the general path
            // below, in the same order, without its loops and pushes.
            // In the copy compiled for AVX2 the three vertices are projected in
            // AVX2 lanes ([`TriangleLanes`]); with no cache (`many`'s tree) also
            // placed in them.
            let ([a, b, c], lanes) = match positions {
                Some([i, j, k]) => {
                    let places = &mut scratch.places;
                    let ((pa, ca), (pb, cb), (pc, cc)) = (
                        light.cached_place(places, i, a),
                        light.cached_place(places, j, b),
                        light.cached_place(places, k, c),
                    );
                    (and, or) = (ca & cb & cc, ca | cb | cc);
                    // SAFETY: with `AVX2` this runs only in a copy compiled for AVX2
                    // (`face_body::<true>`, see its doc), after detection.
                    #[allow(unsafe_code, reason = "the AVX2 lanes in the face path compiled for AVX2")]
                    let lanes = unsafe { TriangleLanes::of::<AVX2>([pa, pb, pc]) };
                    (light.lit_triangle([a, b, c], [pa, pb, pc]), lanes)
                }
                _ => {
                    // SAFETY: with `AVX2` this runs only in a copy compiled for AVX2
                    // (`face_body::<true>`, see its doc), after detection.
                    #[allow(unsafe_code, reason = "the AVX2 placing in the face path compiled for AVX2")]
                    let (eye, lanes, all, any) = unsafe { light.triangle::<AVX2>([a, b, c]) };
                    (and, or) = (all, any);
                    (eye, lanes)
                }
            };
            if and != 0 {
                counters.outside += 1;
                return;
            }
            if instance_class == 1 || or == 0 {
                counters.face_class[0] += 1;
                let eye = [a, b, c];
                let plane_eye = eye_plane(&eye);
                let screen;
                let outline = match lanes {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: lanes are made only with `AVX2`, in a copy compiled for it.
                    #[allow(unsafe_code, reason = "the AVX2 projection in the face path compiled for AVX2")]
                    Some(lanes) => unsafe { lanes.project(view) },
                    #[cfg(not(target_arch = "x86_64"))]
                    Some(lanes) => match lanes {},
                    None => {
                        screen = eye.map(|v| view.project(v.position));
                        Outline::Points(&screen)
                    }
                };
                let model_to_eye = &instance.model_to_eye;
                Self::set_up_face::<AVX2>(
                    &mut self.setup,
                    self.out,
                    counters,
                    face,
                    material,
                    model_to_eye,
                    &plane_eye,
                    &eye,
                    outline,
                );
                return;
            }
            scratch.eye.clear();
            scratch.eye.extend_from_slice(&[a, b, c]);
        } else {
            scratch.eye.clear();
            let (mut all, mut any) = (0x1Fu8, 0u8);
            if let Some(ids) = ids {
                scratch.eye.reserve(ids.len());
                for &id in ids {
                    let v = tree.shared_vertex(id);
                    let (e, code) = light.cached_vertex(&mut scratch.places, v.position, &v.vertex);
                    all &= code;
                    any |= code;
                    scratch.eye.push(e);
                }
            } else {
                scratch.eye.reserve(vertices.len());
                for v in vertices {
                    let (e, code) = light.vertex(v);
                    all &= code;
                    any |= code;
                    scratch.eye.push(e);
                }
            }
            (and, or) = (all, any);
        }
        if and != 0 {
            counters.outside += 1;
            return;
        }
        let face_class = if instance_class == 1 || or == 0 {
            1
        } else if or & 0x10 != 0 {
            3
        } else {
            2
        };
        counters.face_class[face_class - 1] += 1;
        // The eye-space plane, from the transformed vertices.
        let plane_eye = eye_plane(&scratch.eye);
        // Class 3: clip by the near plane first, in eye space.
        if face_class == 3 {
            counters.near_clipped += 1;
            clip_near(&scratch.eye, &mut scratch.clipped_eye);
            std::mem::swap(&mut scratch.eye, &mut scratch.clipped_eye);
        }
        if scratch.eye.len() < 3 {
            counters.degenerate += 1;
            return;
        }
        scratch.screen.clear();
        scratch.screen.extend(scratch.eye.iter().map(|v| view.project(v.position)));
        let outline: &[DVec2] = if face_class == 1 {
            &scratch.screen
        } else {
            counters.window_clipped += 1;
            let win = Window { x0: 0.0, y0: 0.0, x1: f64::from(view.screen.width), y1: f64::from(view.screen.height) };
            match self.f.config.clipper {
                Clipper::Automaton => clip::clip_automaton(&scratch.screen, &win, &mut scratch.window),
                Clipper::AllBorders => clip::clip_all_borders(&scratch.screen, &win, &mut scratch.window),
                Clipper::Reference => clip::clip_reference(&scratch.screen, &win, &mut scratch.window),
            }
            &scratch.window
        };
        let model_to_eye = &instance.model_to_eye;
        Self::set_up_face::<AVX2>(
            &mut self.setup,
            self.out,
            counters,
            face,
            material,
            model_to_eye,
            &plane_eye,
            &scratch.eye,
            Outline::Points(outline),
        );
    }

    /// A face's set-up into the frame list ([`Setup::add_face_with`]), counted as
    /// degenerate if it has none: the end of both of [`FrameBuilder::face_body`]'s
    /// paths (its fields apart, as the body holds others borrowed).
    #[allow(clippy::too_many_arguments, reason = "the face body's registers and its builder's fields")]
    #[inline(always)]
    fn set_up_face<const AVX2: bool>(
        setup: &mut Setup,
        out: &mut FrameList,
        counters: &mut GpCounters,
        face: &FaceRecord,
        material: &crate::db::Material,
        model_to_eye: &DMat4,
        plane_eye: &Plane,
        eye: &[EyeVertex],
        outline: Outline<'_>,
    ) {
        let source = Source { kind: PrimitiveKind::Face, material: face.material, ids: (face.instance, face.face) };
        // SAFETY: with `AVX2` this runs only in a copy compiled for AVX2
        // (`face_body::<true>`, see its doc), after detection.
        #[allow(unsafe_code, reason = "the AVX2 set-up in the face path compiled for AVX2")]
        let ok = unsafe {
            setup.add_face_with::<AVX2>(
                source,
                Some(material),
                material.color,
                plane_eye,
                eye,
                outline,
                model_to_eye,
                out,
            )
        };
        if !ok {
            counters.degenerate += 1;
        }
    }
}

/// A model-to-eye matrix aligned to 32 bytes, so that [`TriangleLanes::place`]
/// loads each of its columns (32 bytes) as one aligned register: an unaligned
/// 32-byte load is two instructions in this build's tuning (`many`'s GP: 4
/// instructions a triangle; session 27).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
struct EyeMatrix(DMat4);

const _: () = assert!(std::mem::size_of::<DMat4>() == 128 && std::mem::align_of::<EyeMatrix>() == 32);

/// What [`FrameBuilder::face`] needs to take a face's vertices to the eye and light
/// them (P5).
struct Lighting<'a> {
    to_eye: &'a EyeMatrix,
    view: &'a View,
    /// `cos a` of every vertex (emissive and flat-shaded faces), or `None` for
    /// each vertex's own (smooth shading).
    cos_a: Option<f64>,
    /// The environment's constants (the frame's, by reference: not copied
    /// face by face).
    env: &'a LightConstants,
    /// The light's direction in the face's coordinates.
    sun: &'a DVec3,
}

/// The environment's lighting constants as [`Lighting`] takes them, made once a
/// frame rather than converted (and the attenuation tested) at each face, and
/// taken by reference, with the light's direction: copied into each face's
/// `Lighting` they were stored to the stack and read back face by face (`many`'s
/// GP 843.0 -> 834.0 M instructions, session 27).
struct LightConstants {
    /// The ambient light, `f64`.
    ambient: f64,
    /// The background brightness `Pb`, `f64`.
    pb: f64,
    /// `-beta`, the medium's attenuation negated ([`Lighting::neg_beta`]), or
    /// `None` where it is zero.
    neg_beta: Option<f64>,
}

impl Lighting<'_> {
    /// One vertex's place: its eye-space position and outcode.
    #[inline(always)]
    fn place(&self, v: &BspVertex) -> (DVec3, u8) {
        let p = self.to_eye.0.transform_point3(v.position);
        (p, self.view.outcode(p))
    }

    /// One vertex in eye space, lit, and its outcode.
    #[inline(always)]
    fn vertex(&self, v: &BspVertex) -> (EyeVertex, u8) {
        let (p, code) = self.place(v);
        (self.lit(v, p), code)
    }

    /// [`Lighting::vertex`] of the vertex numbered `id` (`v`), its place from
    /// `places` when there.
    #[inline(always)]
    fn cached_vertex(&self, places: &mut VertexCache, id: u32, v: &BspVertex) -> (EyeVertex, u8) {
        let (p, code) = places.get(id, || self.place(v));
        (self.lit(v, p), code)
    }

    /// [`Lighting::place`] of the vertex numbered `id` (`v`), from `places` when
    /// there.
    #[inline(always)]
    fn cached_place(&self, places: &mut VertexCache, id: u32, v: &BspVertex) -> (DVec3, u8) {
        places.get(id, || self.place(v))
    }

    /// A triangle's three vertices in eye space and lit ([`Lighting::vertex`] of
    /// each), and the AND and the OR of their outcodes; with `AVX2` placed in
    /// AVX2 lanes ([`TriangleLanes::place`]), which are returned too for the
    /// projection (`None` without).
    ///
    /// # Safety
    /// With `AVX2`, the processor must have AVX2.
    #[allow(unsafe_code, reason = "a function that runs AVX2 code when told the processor has it")]
    #[inline(always)]
    unsafe fn triangle<const AVX2: bool>(
        &self,
        vs: [&BspVertex; 3],
    ) -> ([EyeVertex; 3], Option<TriangleLanes>, u8, u8) {
        let [a, b, c] = vs;
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            // SAFETY: with `AVX2` the caller vouches for the processor.
            let (lanes, p, and, or) = unsafe { TriangleLanes::place(self.to_eye, self.view, vs) };
            return (self.lit_triangle(vs, p), Some(lanes), and, or);
        }
        let ((pa, ca), (pb, cb), (pc, cc)) = (self.place(a), self.place(b), self.place(c));
        (self.lit_triangle(vs, [pa, pb, pc]), None, ca & cb & cc, ca | cb | cc)
    }

    /// One vertex in eye space at `p` (its [`Lighting::place`]), lit.
    #[inline(always)]
    fn lit(&self, v: &BspVertex, p: DVec3) -> EyeVertex {
        let cos_a = match self.cos_a {
            Some(c) => c,
            None => self.own_cos_a(v),
        };
        // P5: P' = Pb + (P cos a - Pb) exp(-beta z). With no attenuation the
        // factor is exp(0) = 1 exactly (z is finite), and not computed.
        let fade = match self.env.neg_beta {
            None => 1.0,
            Some(k) => Self::fade(k, p),
        };
        EyeVertex { position: p, intensity: self.intensity(v, cos_a, fade) }
    }

    /// [`Lighting::lit`] of a triangle's three vertices at `p`, the face's
    /// choices (one `cos a` or each vertex's own, attenuation or none) made once
    /// for the three rather than at each (the same operations per vertex).
    #[inline(always)]
    fn lit_triangle(&self, vs: [&BspVertex; 3], p: [DVec3; 3]) -> [EyeVertex; 3] {
        let [a, b, c] = vs;
        let cos_a = match self.cos_a {
            Some(k) => [k; 3],
            None => [self.own_cos_a(a), self.own_cos_a(b), self.own_cos_a(c)],
        };
        let fade = match self.env.neg_beta {
            None => [1.0; 3],
            Some(k) => [Self::fade(k, p[0]), Self::fade(k, p[1]), Self::fade(k, p[2])],
        };
        [
            EyeVertex { position: p[0], intensity: self.intensity(a, cos_a[0], fade[0]) },
            EyeVertex { position: p[1], intensity: self.intensity(b, cos_a[1], fade[1]) },
            EyeVertex { position: p[2], intensity: self.intensity(c, cos_a[2], fade[2]) },
        ]
    }

    /// `cos a` of a smooth-shaded vertex, by its own normal.
    #[inline(always)]
    fn own_cos_a(&self, v: &BspVertex) -> f64 {
        let ambient = self.env.ambient;
        ambient + (1.0 - ambient) * v.normal.as_dvec3().dot(*self.sun).max(0.0)
    }

    /// [`Lighting::neg_beta`] of attenuation `beta`: `-beta` (exact), or `None`
    /// for zero (either sign), where the factor `exp(-beta z)` is 1 exactly (`z`
    /// is finite) and not computed.
    fn neg_beta(beta: f32) -> Option<f64> {
        (beta != 0.0).then(|| -f64::from(beta))
    }

    /// The medium's attenuation `exp(-beta z)` at eye-space `p`, `neg_beta` being
    /// `-beta`.
    #[inline(always)]
    fn fade(neg_beta: f64, p: DVec3) -> f64 {
        (neg_beta * p.z).exp()
    }

    /// P5's brightness of vertex `v` with `cos a` and the attenuation `fade`.
    #[inline(always)]
    fn intensity(&self, v: &BspVertex, cos_a: f64, fade: f64) -> f64 {
        let pb = self.env.pb;
        pb + (f64::from(v.intensity) * cos_a - pb) * fade
    }
}

/// A triangle's three vertices in eye space in the lanes of AVX2 registers, one
/// register a coordinate: lane `k` vertex `k`, lane 3 repeating vertex 0 (the
/// layout of [`Outline::TriangleLanes`], so that the projection feeds the snap
/// with no points in memory between).
///
/// Why: the scalar path placed, outcoded and projected each vertex on its own
/// (about 80 instructions a vertex on `many`, a third of the face path); in lanes
/// the outcodes' and the projection's arithmetic is done once for the three. The
/// same `f64` operations in the same order on each lane (tested against
/// [`Lighting::place`] and [`View::project`]), so the same bits.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
struct TriangleLanes {
    x: std::arch::x86_64::__m256d,
    y: std::arch::x86_64::__m256d,
    z: std::arch::x86_64::__m256d,
}

/// No lanes without `x86_64` (never made: [`Lighting::triangle`] gives `None`).
#[cfg(not(target_arch = "x86_64"))]
#[derive(Clone, Copy, Debug)]
enum TriangleLanes {}

#[cfg(not(target_arch = "x86_64"))]
impl TriangleLanes {
    /// No lanes (the `x86_64` version's counterpart).
    #[allow(unsafe_code, reason = "the same signature as the x86_64 version")]
    #[inline(always)]
    unsafe fn of<const AVX2: bool>(_: [DVec3; 3]) -> Option<Self> {
        None
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code, reason = "AVX2 instructions, inlined into the face path compiled for AVX2")]
impl TriangleLanes {
    /// The three vertices taken to the eye by `to_eye` (each as
    /// `DMat4::transform_point3`: `((x_axis x + y_axis y) + z_axis z) + w_axis`,
    /// the four lanes of a register the four rows), in lanes, their positions, and
    /// the AND and the OR of their outcodes ([`View::outcode`], each border
    /// compared in the three lanes at once).
    ///
    /// # Safety
    /// The processor must have AVX2 (inlined always, so compiled with the caller's
    /// features: for the GP's face path compiled for AVX2).
    #[inline(always)]
    unsafe fn place(to_eye: &EyeMatrix, view: &View, vs: [&BspVertex; 3]) -> (Self, [DVec3; 3], u8, u8) {
        use std::arch::x86_64::*;
        let m: &[f64; 16] = to_eye.0.as_ref();
        // SAFETY (this block): the matrix's columns are four `f64` each, in
        // order, each 32 bytes at a multiple of 32 from the matrix's start, which
        // is aligned to 32 (`EyeMatrix`): aligned loads; the caller vouches for
        // AVX2.
        unsafe {
            let c = m.as_ptr();
            let (c0, c1, c2, c3) =
                (_mm256_load_pd(c), _mm256_load_pd(c.add(4)), _mm256_load_pd(c.add(8)), _mm256_load_pd(c.add(12)));
            // (Macros rather than closures: a closure is a function of its own,
            // kept out of line without the caller's features.)
            macro_rules! to_eye {
                ($v:expr) => {{
                    let p = &$v.position;
                    let r = _mm256_mul_pd(c0, _mm256_broadcast_sd(&p.x));
                    let r = _mm256_add_pd(_mm256_mul_pd(c1, _mm256_broadcast_sd(&p.y)), r);
                    let r = _mm256_add_pd(_mm256_mul_pd(c2, _mm256_broadcast_sd(&p.z)), r);
                    _mm256_add_pd(c3, r)
                }};
            }
            let [a, b, c] = vs;
            // Per vertex `[x, y, z, w]`; then per coordinate `[a, b, c, a]`.
            let (ra, rb, rc) = (to_eye!(a), to_eye!(b), to_eye!(c));
            let (ab_xz, ab_yw) = (_mm256_unpacklo_pd(ra, rb), _mm256_unpackhi_pd(ra, rb));
            let (ca_xz, ca_yw) = (_mm256_unpacklo_pd(rc, ra), _mm256_unpackhi_pd(rc, ra));
            let x = _mm256_permute2f128_pd::<0x20>(ab_xz, ca_xz);
            let y = _mm256_permute2f128_pd::<0x20>(ab_yw, ca_yw);
            let z = _mm256_permute2f128_pd::<0x31>(ab_xz, ca_xz);
            // `View::outcode`'s borders, its bits as 64-bit lanes.
            let f = _mm256_set1_pd(view.focal);
            let hx = _mm256_add_pd(_mm256_mul_pd(f, x), _mm256_mul_pd(_mm256_set1_pd(view.center.x), z));
            let hy = _mm256_add_pd(_mm256_mul_pd(f, y), _mm256_mul_pd(_mm256_set1_pd(view.center.y), z));
            let wx = _mm256_mul_pd(_mm256_set1_pd(view.size.x), z);
            let wy = _mm256_mul_pd(_mm256_set1_pd(view.size.y), z);
            let zero = _mm256_setzero_pd();
            macro_rules! bit {
                ($mask:expr, $bit:expr) => {
                    _mm256_and_si256(_mm256_castpd_si256($mask), _mm256_set1_epi64x($bit))
                };
            }
            let codes = _mm256_or_si256(
                _mm256_or_si256(
                    _mm256_or_si256(
                        bit!(_mm256_cmp_pd::<_CMP_LT_OQ>(hx, zero), 1),
                        bit!(_mm256_cmp_pd::<_CMP_GT_OQ>(hx, wx), 2),
                    ),
                    _mm256_or_si256(
                        bit!(_mm256_cmp_pd::<_CMP_LT_OQ>(hy, zero), 4),
                        bit!(_mm256_cmp_pd::<_CMP_GT_OQ>(hy, wy), 8),
                    ),
                ),
                bit!(_mm256_cmp_pd::<_CMP_LT_OQ>(z, _mm256_set1_pd(NEAR)), 16),
            );
            // Across the lanes (lane 3 is vertex 0 again: no effect on either).
            let (low, high) = (_mm256_castsi256_si128(codes), _mm256_extracti128_si256::<1>(codes));
            let (and, or) = (_mm_and_si128(low, high), _mm_or_si128(low, high));
            let and = _mm_and_si128(and, _mm_unpackhi_epi64(and, and));
            let or = _mm_or_si128(or, _mm_unpackhi_epi64(or, or));
            let mut p = [[0f64; 4]; 3];
            _mm256_storeu_pd(p[0].as_mut_ptr(), ra);
            _mm256_storeu_pd(p[1].as_mut_ptr(), rb);
            _mm256_storeu_pd(p[2].as_mut_ptr(), rc);
            let [pa, pb, pc] = p;
            let positions =
                [DVec3::new(pa[0], pa[1], pa[2]), DVec3::new(pb[0], pb[1], pb[2]), DVec3::new(pc[0], pc[1], pc[2])];
            (Self { x, y, z }, positions, _mm_cvtsi128_si64(and) as u8, _mm_cvtsi128_si64(or) as u8)
        }
    }

    /// With `AVX2`, the lanes of a triangle placed already (from the
    /// [`VertexCache`]), for [`TriangleLanes::project`]; `None` without.
    ///
    /// # Safety
    /// With `AVX2`, the processor must have AVX2 (inlined always, so compiled with
    /// the caller's features: for the GP's face path compiled for AVX2).
    #[inline(always)]
    unsafe fn of<const AVX2: bool>(p: [DVec3; 3]) -> Option<Self> {
        use std::arch::x86_64::*;
        if !AVX2 {
            return None;
        }
        let [a, b, c] = p;
        // SAFETY: the caller vouches for AVX2.
        unsafe {
            Some(Self {
                x: _mm256_setr_pd(a.x, b.x, c.x, a.x),
                y: _mm256_setr_pd(a.y, b.y, c.y, a.y),
                z: _mm256_setr_pd(a.z, b.z, c.z, a.z),
            })
        }
    }

    /// The triangle's screen points ([`View::project`] of each: `c + (f X) / Z`),
    /// in lanes, as the set-up's outline.
    ///
    /// # Safety
    /// The processor must have AVX2 (inlined always, so compiled with the caller's
    /// features: for the GP's face path compiled for AVX2).
    #[inline(always)]
    unsafe fn project(&self, view: &View) -> Outline<'static> {
        use std::arch::x86_64::*;
        // SAFETY: the caller vouches for AVX2.
        unsafe {
            let f = _mm256_set1_pd(view.focal);
            let x = _mm256_add_pd(_mm256_set1_pd(view.center.x), _mm256_div_pd(_mm256_mul_pd(f, self.x), self.z));
            let y = _mm256_add_pd(_mm256_set1_pd(view.center.y), _mm256_div_pd(_mm256_mul_pd(f, self.y), self.z));
            Outline::TriangleLanes(x, y)
        }
    }
}

/// The plane of an eye-space polygon (Newell), normal towards the front.
#[inline(always)]
fn eye_plane(vs: &[EyeVertex]) -> Plane {
    let p0 = vs[0].position;
    let mut n = DVec3::ZERO;
    for i in 1..vs.len() - 1 {
        n += (vs[i].position - p0).cross(vs[i + 1].position - p0);
    }
    // `n.normalize_or_zero()`, its test `rcp.is_finite() && rcp > 0.0` as two
    // float comparisons, `0 < rcp <= f64::MAX` (NaN fails both): glam's (and
    // `rcp < INFINITY`, which the compiler turns into the same) tests the bits,
    // ~12 instructions more.
    let rcp = n.length_recip();
    let normal = if rcp > 0.0 && rcp <= f64::MAX { n * rcp } else { DVec3::ZERO };
    Plane { normal, d: normal.dot(p0) }
}

/// Whether the processor runs [`FrameBuilder::face`]'s copy compiled for AVX2 (it
/// needs AVX2 and BMI1/2; every processor with AVX2 has them).
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
            && std::is_x86_feature_detected!("bmi1")
            && std::is_x86_feature_detected!("bmi2")
            && std::is_x86_feature_detected!("lzcnt")
            && std::is_x86_feature_detected!("popcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Sutherland-Hodgman by the near plane `Z = NEAR`, interpolating intensity.
fn clip_near(input: &[EyeVertex], out: &mut Vec<EyeVertex>) {
    out.clear();
    let n = input.len();
    for i in 0..n {
        let a = input[i];
        let b = input[(i + 1) % n];
        let (ina, inb) = (a.position.z >= NEAR, b.position.z >= NEAR);
        if ina {
            out.push(a);
        }
        if ina != inb {
            let t = (NEAR - a.position.z) / (b.position.z - a.position.z);
            let mut position = a.position + (b.position - a.position) * t;
            position.z = NEAR;
            out.push(EyeVertex { position, intensity: a.intensity + (b.intensity - a.intensity) * t });
        }
    }
}

/// Convenience: validates nothing, builds the database and the frame list of the
/// scene's own eye and screen.
pub fn frame_of_scene(db: &Database, config: &GpConfig) -> (FrameList, GpCounters) {
    let mut counters = GpCounters::default();
    let f = frame(db, &db.scene.eye, db.scene.screen, config, &mut counters);
    (f, counters)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::builtin;

    /// The GP's shortcuts (passing over the subtrees outside the view volume, and
    /// over the guests' places when there are none; the path for triangles; the
    /// cache of shared vertices' places), and the faces' path compiled for AVX2,
    /// change neither the frame list (polygons, vertices, edge codes, texture set-ups) nor
    /// a counter: built-in scenes with and without light points and moving models,
    /// textured and not, of triangles (terrain) and other polygons, eyes turned
    /// every way (much of the tree behind or beside them, faces clipped by the
    /// window and the near plane), one and two GPs; and the frame left as stretches
    /// ([`frame_stretches_into`]) is, stretch after stretch, the same list.
    #[test]
    fn traversal_shortcuts_change_nothing() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = |lo: f32, hi: f32| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            lo + (hi - lo) * (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut culled_some, mut multiple_stretches, mut numbered) = (false, false, false);
        // Triangles set up, texture set-ups, faces clipped by the window and by the
        // near plane.
        let mut seen = [0usize; 4];
        // Terrain has no guests; default has light points and a moving model.
        for (name, eyes) in [("default", 16), ("city", 16), ("terrain", 6)] {
            let db = Database::new(builtin::scene(name).expect("built-in"));
            let screen = Screen { width: 320, height: 200 };
            // Where the tree numbers its vertices, each record's numbers give
            // its own vertices bit for bit from the distinct ones; distinct
            // vertices are distinct; one position number, one position, and
            // one position, one number (then the cache's places are theirs);
            // terrain's grid and city's boxes are numbered.
            if let Some(ids) = db.bsp.records.first().and_then(|r| db.bsp.record_vertex_ids_of(r)) {
                numbered |= !ids.is_empty();
                let bits = |v: &BspVertex| {
                    (
                        v.position.to_array().map(f64::to_bits),
                        v.normal.to_array().map(f32::to_bits),
                        v.intensity.to_bits(),
                    )
                };
                let (mut vertex_of, mut id_of) = (std::collections::HashMap::new(), std::collections::HashMap::new());
                let (mut position_of, mut number_of) =
                    (std::collections::HashMap::new(), std::collections::HashMap::new());
                for r in &db.bsp.records {
                    let ids = db.bsp.record_vertex_ids_of(r).expect("numbered tree");
                    let vertices = db.bsp.record_vertices_of(r);
                    assert_eq!(ids.len(), vertices.len(), "{name}: a record's numbers");
                    for (v, &id) in vertices.iter().zip(ids) {
                        let s = db.bsp.shared_vertex(id);
                        assert_eq!(bits(&s.vertex), bits(v), "{name}: distinct vertex {id}");
                        assert_eq!(*vertex_of.entry(id).or_insert(bits(v)), bits(v), "{name}: number {id}");
                        assert_eq!(*id_of.entry(bits(v)).or_insert(id), id, "{name}: two numbers for {v:?}");
                        let p = bits(v).0;
                        assert_eq!(*position_of.entry(s.position).or_insert(p), p, "{name}: position {}", s.position);
                        assert_eq!(*number_of.entry(p).or_insert(s.position), s.position, "{name}: at {p:?}");
                    }
                }
                assert!(name != "city" || position_of.len() < vertex_of.len(), "city's positions are not shared");
            } else {
                assert!(name != "terrain" && name != "city", "{name} is not numbered");
            }
            for k in 0..eyes {
                let mut eye = db.scene.eye;
                if k > 0 {
                    eye.position += glam::Vec3::new(next(-300.0, 300.0), next(-300.0, 300.0), next(0.0, 80.0));
                    eye.heading = next(0.0, 360.0);
                    eye.pitch = next(-80.0, 40.0);
                    eye.roll = next(-30.0, 30.0);
                    eye.fov = next(20.0, 100.0);
                }
                let mut one_gp: Option<(FrameList, GpCounters)> = None;
                for threads in [1, 2] {
                    let config = GpConfig { threads, ..GpConfig::default() };
                    let run = |shortcuts: bool, avx2: bool| {
                        let (mut c, mut out) = (GpCounters::default(), FrameList::default());
                        let mut stretches = Vec::new();
                        let memory = &mut GpMemory::default();
                        frame_with(
                            &db,
                            &eye,
                            screen,
                            &config,
                            &mut c,
                            memory,
                            &mut stretches,
                            Some(&mut out),
                            shortcuts,
                            avx2,
                        );
                        (out, c)
                    };
                    let (plain, fast) = (run(false, false), run(true, true));
                    assert!(plain == fast, "{name}, eye {eye:?}, {threads} threads");
                    // Each copy of the faces' path, with the shortcuts and without.
                    assert!(run(true, false) == fast, "{name}, eye {eye:?}, {threads} threads: plain copy");
                    assert!(run(false, true) == fast, "{name}, eye {eye:?}, {threads} threads: AVX2 copy");
                    // The frame as stretches, unjoined: in order, the same polygons
                    // with the same vertices, edge codes and texture set-ups, and
                    // the same counters (twice, the second time into kept lists).
                    let (mut c, mut stretches) = (GpCounters::default(), Vec::new());
                    let memory = &mut GpMemory::default();
                    for _ in 0..2 {
                        frame_stretches_into(&db, &eye, screen, &config, &mut c, memory, &mut stretches);
                        let mut joined = stretches[0].clone();
                        joined.clear();
                        for l in &stretches {
                            let header = |l: &FrameList| {
                                (l.width, l.height, l.background, l.fog_color, l.visibility, l.pixel_angle)
                            };
                            assert_eq!(header(l), header(&fast.0), "{name}: a stretch's header");
                            joined.append(l);
                        }
                        assert!(joined == fast.0 && c == fast.1, "{name}, eye {eye:?}, {threads} threads: stretches");
                        multiple_stretches |= stretches.len() > 1;
                    }
                    // One GP or two, the same frame.
                    match &one_gp {
                        None => one_gp = Some(fast.clone()),
                        Some(one) => assert!(*one == fast, "{name}, eye {eye:?}: 1 and {threads} GPs"),
                    }
                    let (list, c) = &fast;
                    let triangles = list.polygons.iter().filter(|p| p.vertices.len() == 3).count();
                    seen[0] += triangles;
                    seen[1] += list.textures.len();
                    seen[2] += c.window_clipped as usize;
                    seen[3] += c.near_clipped as usize;
                    let shared = Shared::new(&db, View::new(&eye, screen), config);
                    culled_some |= (0..db.bsp.nodes.len() as u32).any(|n| shared.culls_within(n, &Cell::new((0, 0))));
                }
            }
        }
        assert!(culled_some, "no subtree was culled: the test tests nothing");
        assert!(multiple_stretches, "never more than one stretch: the test tests nothing");
        assert!(numbered, "no tree numbers its vertices: the cache is not tested");
        assert!(seen.iter().all(|&k| k > 20), "every kind of face tested: {seen:?}");
    }

    /// The walk that passes over the nodes of a subtree found wholly inside the
    /// view volume ([`Shared::culls_within`]) culls the very nodes that testing
    /// every node as first written does (large enough, some border's test of the
    /// node's box beyond the margin, no guest inside): random eyes on scenes with
    /// and without guests, the whole tree walked as one and as its pieces; and
    /// it both culls and passes over nodes.
    #[test]
    fn culling_within_inside_subtrees_is_testing_every_node() {
        use crate::gp::setup::tests::Rng;
        let mut rng = Rng(0xC011_1D5E_0F00_0001);
        let (mut culled, skipped) = (0usize, Cell::new(0usize));
        for name in ["default", "city", "terrain"] {
            let db = Database::new(builtin::scene(name).expect("built-in"));
            let bsp = &db.bsp;
            for k in 0..24 {
                let mut eye = db.scene.eye;
                if k > 0 {
                    let mut r = |lo: f64, hi: f64| (lo + (hi - lo) * rng.unit()) as f32;
                    eye.position += glam::Vec3::new(r(-300.0, 300.0), r(-300.0, 300.0), r(0.0, 80.0));
                    (eye.heading, eye.pitch, eye.roll, eye.fov) =
                        (r(0.0, 360.0), r(-80.0, 40.0), r(-30.0, 30.0), r(20.0, 100.0));
                }
                let shared = Shared::new(&db, View::new(&eye, Screen { width: 320, height: 200 }), GpConfig::default());
                let fr = &shared.frustum;
                // The test of every node, as first written.
                let plain = |n: u32| {
                    let b = bsp.bounds(n);
                    let size = (b.center.abs() + b.half).element_sum();
                    let margin = CULL_MARGIN * fr.coefficients * (size + fr.translation);
                    let outside = fr.borders.iter().any(|(a, k)| a.dot(b.center) + k - a.abs().dot(b.half) > margin);
                    let end = n + bsp.subtree_nodes(n);
                    let first = shared.guests.partition_point(|g| g.0 < n);
                    bsp.subtree_faces(n) >= CULL_MIN_FACES
                        && outside
                        && shared.guests.get(first).is_none_or(|g| g.0 >= end)
                };
                let eye_at = shared.view.position;
                let mut roots = vec![0];
                bsp.pieces(eye_at, FACES_PER_TASK, |p| {
                    if let Piece::Subtree(n) = p {
                        roots.push(n);
                    }
                });
                for root in roots {
                    let walk = |cull: &dyn Fn(u32) -> bool| {
                        let mut out = Vec::new();
                        bsp.traverse_subtree_culled(root, eye_at, true, cull, |v| out.push(v));
                        out
                    };
                    let inside = Cell::new((0, 0));
                    let got = walk(&|n| {
                        let (start, end) = inside.get();
                        skipped.set(skipped.get() + usize::from((start..end).contains(&n)));
                        shared.culls_within(n, &inside)
                    });
                    let want = walk(&|n| plain(n));
                    assert_eq!(got, want, "{name}, eye {eye:?}, subtree {root}");
                    culled += got.iter().filter(|v| matches!(v, Visit::Culled(_))).count();
                }
            }
        }
        let skipped = skipped.get();
        assert!(culled > 100 && skipped > 1000, "culled {culled}, passed over {skipped}: the test tests nothing");
    }

    /// [`TriangleLanes::place`] and [`TriangleLanes::project`] are
    /// [`Lighting::place`] and [`View::project`] of each vertex, bit for bit
    /// (NaN for NaN): random eyes, screens and model matrices, vertices in front
    /// of the eye, behind it, across every border and on the near plane, tiny and
    /// huge coordinates, infinities and NaN.
    #[test]
    fn triangle_lanes_are_the_plain_definitions() {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            use crate::gp::setup::tests::Rng;
            let mut rng = Rng(0x51A7_E5C0_DE00_0001);
            let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
            let special = [0.0, -0.0, NEAR, 1e-300, -1e300, 1e300, f64::INFINITY, f64::NEG_INFINITY, f64::NAN];
            let (mut outcomes, mut codes) = ([0usize; 3], 0u8);
            for case in 0..200_000 {
                let eye = Eye {
                    position: glam::Vec3::new(
                        rng.unit() as f32 * 200.0 - 100.0,
                        rng.unit() as f32 * 200.0 - 100.0,
                        0.0,
                    ),
                    heading: rng.unit() as f32 * 360.0,
                    pitch: rng.unit() as f32 * 120.0 - 60.0,
                    roll: rng.unit() as f32 * 60.0 - 30.0,
                    fov: 20.0 + rng.unit() as f32 * 80.0,
                };
                let screen = Screen { width: 64 + (rng.next() % 2000) as u32, height: 64 + (rng.next() % 1200) as u32 };
                let view = View::new(&eye, screen);
                let scale = [1e-3, 1.0, 10.0, 1e3][case % 4];
                let model = DMat4::from_scale_rotation_translation(
                    DVec3::splat(0.5 + rng.unit() * scale),
                    glam::DQuat::from_euler(glam::EulerRot::XYZ, rng.unit() * 7.0, rng.unit() * 7.0, rng.unit() * 7.0),
                    DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * 100.0,
                );
                let to_eye = EyeMatrix(if case % 3 == 0 { view.world_to_eye } else { view.world_to_eye * model });
                let mut coordinate = |k: usize| match (case + k) % 7 {
                    0 => special[(rng.next() % special.len() as u64) as usize],
                    1 => (rng.unit() - 0.5) * 1e-6,
                    _ => (rng.unit() - 0.5) * 2.0 * scale * 100.0,
                };
                let mut vs: Vec<BspVertex> = (0..3)
                    .map(|k| BspVertex {
                        position: DVec3::new(coordinate(3 * k), coordinate(3 * k + 1), coordinate(3 * k + 2)),
                        normal: glam::Vec3::Z,
                        intensity: 1.0,
                    })
                    .collect();
                if case % 4 == 1 {
                    // In the view volume, or nearly: eye-space points taken back.
                    let to_model = to_eye.0.inverse();
                    for v in &mut vs {
                        let z = NEAR + rng.unit() * 100.0;
                        let (x, y) = (rng.unit() * 1.02 - 0.01, rng.unit() * 1.02 - 0.01);
                        let (w, h) = (f64::from(screen.width), f64::from(screen.height));
                        let p = DVec3::new(
                            (x * w - view.center.x) * z / view.focal,
                            (y * h - view.center.y) * z / view.focal,
                            z,
                        );
                        v.position = to_model.transform_point3(p);
                    }
                }
                let light = Lighting {
                    to_eye: &to_eye,
                    view: &view,
                    cos_a: Some(1.0),
                    env: &LightConstants { ambient: 0.2, pb: 0.0, neg_beta: None },
                    sun: &DVec3::Z,
                };
                let want = [light.place(&vs[0]), light.place(&vs[1]), light.place(&vs[2])];
                // SAFETY: AVX2 was detected above.
                #[allow(unsafe_code, reason = "the AVX2 path under test, after detection")]
                let (lanes, got, and, or) = unsafe { TriangleLanes::place(&to_eye, &view, [&vs[0], &vs[1], &vs[2]]) };
                for k in 0..3 {
                    let (w, g) = (want[k].0.to_array(), got[k].to_array());
                    assert!((0..3).all(|i| same(w[i], g[i])), "{to_eye:?} {vs:?}: vertex {k}");
                }
                assert_eq!(and, want[0].1 & want[1].1 & want[2].1, "{to_eye:?} {vs:?}");
                assert_eq!(or, want[0].1 | want[1].1 | want[2].1, "{to_eye:?} {vs:?}");
                codes |= or;
                outcomes[if and != 0 {
                    0
                } else if or == 0 {
                    1
                } else {
                    2
                }] += 1;
                // SAFETY: AVX2 was detected above.
                #[allow(unsafe_code, reason = "the AVX2 path under test, after detection")]
                let Outline::TriangleLanes(xs, ys) = (unsafe { lanes.project(&view) }) else {
                    unreachable!("the lanes project into lanes")
                };
                // SAFETY: a register of four `f64` is their array.
                #[allow(unsafe_code, reason = "reading the lanes back")]
                let (xs, ys) = unsafe {
                    (
                        std::mem::transmute::<std::arch::x86_64::__m256d, [f64; 4]>(xs),
                        std::mem::transmute::<std::arch::x86_64::__m256d, [f64; 4]>(ys),
                    )
                };
                for k in 0..4 {
                    let p = view.project(want[k % 3].0);
                    assert!(same(xs[k], p.x) && same(ys[k], p.y), "{to_eye:?} {vs:?}: screen point {k}");
                }
            }
            assert_eq!(codes, 0x1F, "every border crossed");
            assert!(outcomes.iter().all(|&k| k > 10_000), "outside, across and inside: {outcomes:?}");
        }
    }
}
