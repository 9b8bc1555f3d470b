//! Scene database (SYSTEM.md 2): models, materials, canonical objects, light points,
//! the scene, and the BSP tree that gives exact front-to-back priority.
//!
//! The database is what the geometric processor (GP) reads every frame. It is built
//! once, at load, from a TOML scene file ([`load`]), a Wavefront OBJ mesh, or one of the
//! built-in scenes ([`builtin`]). After [`Scene::validate`] has passed, every face is a
//! planar convex polygon with at least three distinct vertices, every index is in range
//! and every number is finite: the pipeline stages downstream are infallible on it.
//!
//! Coordinates: world X east, Y north, Z up, in metres. A face lists its vertices
//! counter-clockwise when seen from its front side (the right-hand normal points out).

pub mod bsp;
pub mod builtin;
pub mod canonical;
pub mod load;

use glam::{Mat4, Vec3};
use serde::Serialize;

/// Linear RGB colour, each component in `0.0..=1.0`.
pub type Rgb = Vec3;

/// One vertex of a model (P5's "visualization shell"): position, normal and the
/// vertex's own brightness `P_i` of P5's shading formula.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Vertex {
    /// Position in model coordinates.
    pub position: Vec3,
    /// Unit normal in model coordinates (used for smooth shading).
    pub normal: Vec3,
    /// The vertex's own brightness `P_i` (P5), 1.0 for a plain vertex.
    pub intensity: f32,
}

impl Vertex {
    /// A vertex with a zero normal (filled in later from the faces) and intensity 1.
    pub fn at(position: Vec3) -> Self {
        Self { position, normal: Vec3::ZERO, intensity: 1.0 }
    }
}

/// A convex planar polygon of a model, given by vertex indices (counter-clockwise seen
/// from the front) and a material index into [`Scene::materials`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Face {
    /// Indices into the model's vertex list, at least 3.
    pub vertices: Vec<u32>,
    /// Index into the scene's material list.
    pub material: u32,
}

/// A model: P5's visualization shell, a set of vertices and convex faces.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Model {
    /// The name by which instances refer to it.
    pub name: String,
    /// Vertices in model coordinates.
    pub vertices: Vec<Vertex>,
    /// Faces over those vertices.
    pub faces: Vec<Face>,
}

impl Model {
    /// Appends another model's geometry (used for composite objects).
    pub fn append(&mut self, other: &Model, transform: Mat4) {
        let base = self.vertices.len() as u32;
        let normal_matrix = transform.inverse().transpose();
        self.vertices.extend(other.vertices.iter().map(|v| Vertex {
            position: transform.transform_point3(v.position),
            normal: normal_matrix.transform_vector3(v.normal).normalize_or_zero(),
            intensity: v.intensity,
        }));
        self.faces.extend(
            other
                .faces
                .iter()
                .map(|f| Face { vertices: f.vertices.iter().map(|i| i + base).collect(), material: f.material }),
        );
    }

    /// Sets every vertex normal that is zero to the area-weighted mean of the normals
    /// of the faces that use it (P5: "averaged over the faces meeting at the vertex").
    pub fn fill_normals(&mut self) {
        let mut acc = vec![Vec3::ZERO; self.vertices.len()];
        for f in &self.faces {
            let n = polygon_normal(f.vertices.iter().map(|&i| self.vertices[i as usize].position));
            for &i in &f.vertices {
                acc[i as usize] += n;
            }
        }
        for (v, n) in self.vertices.iter_mut().zip(acc) {
            if v.normal == Vec3::ZERO {
                v.normal = n.normalize_or_zero();
            }
        }
    }

    /// The bounding sphere (centre, radius) of the vertices, about their box's centre.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        bounding_sphere(self.vertices.iter().map(|v| v.position))
    }
}

/// Newell's normal of a polygon: twice the area times the unit normal, robust for
/// any planar polygon and zero for a degenerate one.
pub fn polygon_normal(points: impl Iterator<Item = Vec3> + Clone) -> Vec3 {
    let first = points.clone().next().unwrap_or(Vec3::ZERO);
    let mut n = Vec3::ZERO;
    let mut prev: Option<Vec3> = None;
    for p in points.clone().chain(std::iter::once(first)) {
        if let Some(q) = prev {
            n += (q - first).cross(p - first);
        }
        prev = Some(p);
    }
    n
}

/// The bounding sphere of a set of points, centred at their bounding box's centre.
pub fn bounding_sphere(points: impl Iterator<Item = Vec3> + Clone) -> (Vec3, f32) {
    let (lo, hi) =
        points.clone().fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), p| (lo.min(p), hi.max(p)));
    if lo.x > hi.x {
        return (Vec3::ZERO, 0.0);
    }
    let c = (lo + hi) * 0.5;
    let r = points.fold(0.0f32, |r, p| r.max(p.distance(c)));
    (c, r)
}

/// How a face's brightness varies across it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shading {
    /// One brightness for the whole face (from its plane's normal).
    #[default]
    Flat,
    /// Brightness computed at the vertices (P5) and interpolated as a
    /// fractional-linear function across the face.
    Smooth,
}

/// Transparency code of a face: 6 bits, 0 opaque .. 63 nearly clear (P2).
/// The face contributes and masks a thinned set of about `(64 - t) / 64` of its
/// subpixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct Transparency(u8);

impl Transparency {
    /// An opaque face.
    pub const OPAQUE: Self = Self(0);
    /// The largest code that fits the 6-bit field.
    pub const MAX: u8 = 63;

    /// The code, if it fits in 6 bits.
    pub fn new(code: u8) -> Option<Self> {
        (code <= Self::MAX).then_some(Self(code))
    }

    /// The 6-bit code.
    pub fn code(self) -> u8 {
        self.0
    }

    /// Whether the face hides everything behind it.
    pub fn is_opaque(self) -> bool {
        self.0 == 0
    }
}

/// A material's texture (P2 eq. 1-2): which map, the period `L` (world size of one
/// repeat of the map), the texture axes `U`, `V` and the reference point `P0` in model
/// coordinates, and the two colours `C1`, `C2` between which the map's modulation
/// value `T` blends: `C = C1 T + C2 (1 - T)`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MaterialTexture {
    /// Index into [`Scene::textures`].
    pub map: u32,
    /// Period `L` in metres.
    pub period: f32,
    /// Texture axis `U` (unit length).
    pub u_axis: Vec3,
    /// Texture axis `V` (unit length).
    pub v_axis: Vec3,
    /// Reference point `P0`, where `u = v = 0`.
    pub origin: Vec3,
    /// `C1`, the colour where `T = 1`.
    pub color1: Rgb,
    /// `C2`, the colour where `T = 0`.
    pub color2: Rgb,
}

/// A material: base colour, shading mode, optional texture, transparency code.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Material {
    /// The name by which faces refer to it.
    pub name: String,
    /// Base colour (used when there is no texture).
    pub color: Rgb,
    /// Flat or smooth (per-vertex) brightness.
    pub shading: Shading,
    /// The texture, if any.
    pub texture: Option<MaterialTexture>,
    /// The 6-bit transparency code.
    pub transparency: Transparency,
    /// Self-luminous: brightness is not affected by the sun (light points, markings).
    pub emissive: bool,
}

impl Material {
    /// A plain opaque flat-shaded material of one colour.
    pub fn plain(name: &str, color: Rgb) -> Self {
        Self {
            name: name.to_string(),
            color,
            shading: Shading::Flat,
            texture: None,
            transparency: Transparency::OPAQUE,
            emissive: false,
        }
    }
}

/// Where a texture map's texels come from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum TextureSource {
    /// One of the built-in procedural maps, by name (`grass`, `asphalt`, `concrete`,
    /// `checker`).
    Builtin(String),
    /// A grayscale PNG file.
    File(std::path::PathBuf),
}

/// A texture map declared by the scene (loaded by the colour-computation unit).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TextureDef {
    /// The name by which materials refer to it.
    pub name: String,
    /// Where its texels come from.
    pub source: TextureSource,
}

/// One placement of a model in the world.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Instance {
    /// Index into [`Scene::models`].
    pub model: u32,
    /// Model-to-world transform.
    pub transform: Mat4,
    /// A moving model is not part of the static BSP; it is ordered as a whole
    /// against it by its bounding sphere, and internally by its own BSP.
    pub moving: bool,
}

/// A light point (P1 "lights"): runway edge, approach and similar lights. The
/// preprocessor turns it into a small polygon facing the eye.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LightPoint {
    /// World position.
    pub position: Vec3,
    /// Colour.
    pub color: Rgb,
    /// Brightness multiplier.
    pub intensity: f32,
    /// World diameter in metres (the on-screen size never falls below a minimum).
    pub size: f32,
}

/// The eye: position and orientation in degrees, and the horizontal field of view.
/// Heading 0 looks north (+Y) and grows clockwise seen from above; pitch is positive
/// nose up; roll is positive right side down.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Eye {
    /// World position.
    pub position: Vec3,
    /// Heading in degrees.
    pub heading: f32,
    /// Pitch in degrees.
    pub pitch: f32,
    /// Roll in degrees.
    pub roll: f32,
    /// Horizontal field of view in degrees.
    pub fov: f32,
}

/// Screen size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Screen {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Screen {
    /// The largest side the video processor accepts (its root cell is then 8192).
    pub const MAX_SIDE: u32 = 8192;
}

/// Light, sky and atmosphere.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Environment {
    /// Background (sky) colour, the last fragment of every pixel.
    pub sky: Rgb,
    /// Unit direction towards the sun, world coordinates.
    pub sun: Vec3,
    /// `P_b` of P5's formula: the brightness the medium fades to.
    pub background_brightness: f32,
    /// Ambient brightness added to `cos a` so that faces away from the sun are not black.
    pub ambient: f32,
    /// `beta` of P5's formula, the medium's attenuation per metre of depth.
    pub attenuation: f32,
    /// Fog colour `C_fog`.
    pub fog_color: Rgb,
    /// Visibility range `Z0` in metres; `f32::INFINITY` for no fog.
    pub visibility: f32,
}

impl Default for Environment {
    fn default() -> Self {
        Self {
            sky: Vec3::new(0.55, 0.7, 0.9),
            sun: Vec3::new(0.3, -0.4, 0.85).normalize(),
            background_brightness: 0.0,
            ambient: 0.35,
            attenuation: 0.0,
            fog_color: Vec3::new(0.7, 0.75, 0.8),
            visibility: f32::INFINITY,
        }
    }
}

/// A whole scene: the database plus the eye, the screen and the environment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Scene {
    /// A name for messages and file names.
    pub name: String,
    /// Materials, referred to by faces.
    pub materials: Vec<Material>,
    /// Texture maps, referred to by materials.
    pub textures: Vec<TextureDef>,
    /// Models, referred to by instances.
    pub models: Vec<Model>,
    /// Placed models.
    pub instances: Vec<Instance>,
    /// Light points.
    pub lights: Vec<LightPoint>,
    /// The eye.
    pub eye: Eye,
    /// The screen.
    pub screen: Screen,
    /// Sky, sun, fog.
    pub env: Environment,
}

/// A problem found by [`Scene::validate`], with where it is.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// A number is NaN or infinite.
    #[error("{what}: {field} is not a finite number")]
    NotFinite {
        /// Where (model/face/vertex, light, eye ...).
        what: String,
        /// Which field.
        field: &'static str,
    },
    /// An index points past the end of its list.
    #[error("{what}: {field} index {index} is out of range (there are {len})")]
    IndexOutOfRange {
        /// Where.
        what: String,
        /// Which field.
        field: &'static str,
        /// The bad index.
        index: u32,
        /// The list's length.
        len: usize,
    },
    /// A face is not a usable polygon.
    #[error("{what}: {problem}")]
    BadFace {
        /// Where.
        what: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A value is outside the range it must be in.
    #[error("{what}: {field} = {value} is out of range ({range})")]
    OutOfRange {
        /// Where.
        what: String,
        /// Which field.
        field: &'static str,
        /// The value, printed.
        value: String,
        /// The allowed range, printed.
        range: &'static str,
    },
}

/// How far a face's vertices may lie off its plane, relative to its size, before it is
/// rejected as non-planar.
pub const PLANARITY_TOLERANCE: f32 = 1e-3;
/// The smallest face area (square metres, relative to the square of its size) accepted.
pub const MIN_FACE_AREA_RATIO: f32 = 1e-9;

impl Scene {
    /// An empty scene with a default eye, screen and environment.
    pub fn empty(name: &str) -> Self {
        Self {
            name: name.to_string(),
            materials: Vec::new(),
            textures: Vec::new(),
            models: Vec::new(),
            instances: Vec::new(),
            lights: Vec::new(),
            eye: Eye { position: Vec3::new(0.0, -10.0, 2.0), heading: 0.0, pitch: 0.0, roll: 0.0, fov: 60.0 },
            screen: Screen { width: 640, height: 480 },
            env: Environment::default(),
        }
    }

    /// The index of a material by name, adding a plain one of `color` if absent.
    pub fn material(&mut self, name: &str, color: Rgb) -> u32 {
        if let Some(i) = self.materials.iter().position(|m| m.name == name) {
            return i as u32;
        }
        self.materials.push(Material::plain(name, color));
        (self.materials.len() - 1) as u32
    }

    /// Adds a model and returns its index.
    pub fn add_model(&mut self, model: Model) -> u32 {
        self.models.push(model);
        (self.models.len() - 1) as u32
    }

    /// Places model `model` with `transform`.
    pub fn place(&mut self, model: u32, transform: Mat4) {
        self.instances.push(Instance { model, transform, moving: false });
    }

    /// Total faces over all instances.
    pub fn instance_face_count(&self) -> usize {
        self.instances.iter().map(|i| self.models[i.model as usize].faces.len()).sum()
    }

    /// Checks everything the pipeline relies on: finite numbers, indices in range,
    /// faces planar, convex, non-degenerate; screen size within limits.
    pub fn validate(&self) -> Result<(), SceneError> {
        let Screen { width, height } = self.screen;
        for (field, v) in [("width", width), ("height", height)] {
            if v == 0 || v > Screen::MAX_SIDE {
                return Err(SceneError::OutOfRange {
                    what: "screen".into(),
                    field,
                    value: v.to_string(),
                    range: "1..=8192",
                });
            }
        }
        let e = &self.eye;
        finite("eye", "position", e.position.to_array())?;
        finite("eye", "heading/pitch/roll", [e.heading, e.pitch, e.roll])?;
        if !(e.fov > 0.1 && e.fov < 179.0) {
            return Err(SceneError::OutOfRange {
                what: "eye".into(),
                field: "fov",
                value: e.fov.to_string(),
                range: "0.1..179 degrees",
            });
        }
        finite("environment", "sky", self.env.sky.to_array())?;
        finite("environment", "sun", self.env.sun.to_array())?;
        finite("environment", "fog_color", self.env.fog_color.to_array())?;
        if self.env.visibility.is_nan() || self.env.visibility <= 0.0 {
            return Err(SceneError::OutOfRange {
                what: "environment".into(),
                field: "visibility",
                value: self.env.visibility.to_string(),
                range: "> 0 (inf for no fog)",
            });
        }
        for (mi, m) in self.materials.iter().enumerate() {
            let what = format!("material {mi} '{}'", m.name);
            finite(&what, "color", m.color.to_array())?;
            if let Some(t) = &m.texture {
                if t.map as usize >= self.textures.len() {
                    return Err(SceneError::IndexOutOfRange {
                        what,
                        field: "texture.map",
                        index: t.map,
                        len: self.textures.len(),
                    });
                }
                finite(
                    &what,
                    "texture",
                    [t.period, t.u_axis.x, t.u_axis.y, t.u_axis.z, t.v_axis.x, t.v_axis.y, t.v_axis.z],
                )?;
                finite(&what, "texture.origin", t.origin.to_array())?;
                if t.period <= 0.0 {
                    return Err(SceneError::OutOfRange {
                        what,
                        field: "texture.period",
                        value: t.period.to_string(),
                        range: "> 0",
                    });
                }
            }
        }
        for (mi, m) in self.models.iter().enumerate() {
            validate_model(mi, m, self.materials.len())?;
        }
        for (ii, inst) in self.instances.iter().enumerate() {
            let what = format!("instance {ii}");
            if inst.model as usize >= self.models.len() {
                return Err(SceneError::IndexOutOfRange {
                    what,
                    field: "model",
                    index: inst.model,
                    len: self.models.len(),
                });
            }
            finite(&what, "transform", inst.transform.to_cols_array())?;
            if inst.transform.determinant().abs() < 1e-12 {
                return Err(SceneError::BadFace { what, problem: "transform is singular (zero scale?)".into() });
            }
        }
        for (li, l) in self.lights.iter().enumerate() {
            let what = format!("light {li}");
            finite(&what, "position", l.position.to_array())?;
            finite(&what, "color", l.color.to_array())?;
            finite(&what, "intensity/size", [l.intensity, l.size])?;
            if l.size <= 0.0 {
                return Err(SceneError::OutOfRange { what, field: "size", value: l.size.to_string(), range: "> 0" });
            }
        }
        Ok(())
    }
}

fn finite<const N: usize>(what: &str, field: &'static str, values: [f32; N]) -> Result<(), SceneError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(SceneError::NotFinite { what: what.to_string(), field })
    }
}

/// Validates one model: see [`Scene::validate`].
pub fn validate_model(mi: usize, m: &Model, materials: usize) -> Result<(), SceneError> {
    // The place is named only when something is wrong there: `many` has three
    // million vertices and a million faces, and formatting a name for each was a
    // second of its start.
    for (vi, v) in m.vertices.iter().enumerate() {
        if v.position.is_finite() && v.normal.is_finite() && v.intensity.is_finite() {
            continue;
        }
        let what = format!("model '{}' vertex {vi}", m.name);
        finite(&what, "position", v.position.to_array())?;
        finite(&what, "normal", v.normal.to_array())?;
        finite(&what, "intensity", [v.intensity])?;
    }
    let _ = mi;
    /// Faces with at most this many vertices are checked from a buffer on the stack.
    const SMALL_FACE: usize = 8;
    let mut small = [Vec3::ZERO; SMALL_FACE];
    for (fi, f) in m.faces.iter().enumerate() {
        let what = || format!("model '{}' face {fi}", m.name);
        if f.material as usize >= materials {
            return Err(SceneError::IndexOutOfRange {
                what: what(),
                field: "material",
                index: f.material,
                len: materials,
            });
        }
        for &i in &f.vertices {
            if i as usize >= m.vertices.len() {
                return Err(SceneError::IndexOutOfRange {
                    what: what(),
                    field: "vertices",
                    index: i,
                    len: m.vertices.len(),
                });
            }
        }
        let position = |&i: &u32| m.vertices[i as usize].position;
        let large: Vec<Vec3>;
        let pts: &[Vec3] = if f.vertices.len() <= SMALL_FACE {
            for (p, i) in small.iter_mut().zip(&f.vertices) {
                *p = position(i);
            }
            &small[..f.vertices.len()]
        } else {
            large = f.vertices.iter().map(position).collect();
            &large
        };
        if let Err(problem) = check_convex_planar(pts) {
            return Err(SceneError::BadFace { what: what(), problem });
        }
    }
    Ok(())
}

/// Checks that a polygon has at least 3 vertices, non-zero area, lies in a plane (to
/// [`PLANARITY_TOLERANCE`] of its size) and is convex with the vertices in order.
pub fn check_convex_planar(pts: &[Vec3]) -> Result<(), String> {
    if pts.len() < 3 {
        return Err(format!("has {} vertices, a face needs at least 3", pts.len()));
    }
    let n = polygon_normal(pts.iter().copied());
    let size = pts.iter().fold(0.0f32, |s, p| s.max(p.distance(pts[0])));
    let area = n.length() * 0.5;
    if size == 0.0 || area <= MIN_FACE_AREA_RATIO * size * size {
        return Err("has zero area (its vertices are collinear or coincide)".to_string());
    }
    let unit = n / n.length();
    let d = unit.dot(pts[0]);
    for (k, p) in pts.iter().enumerate() {
        let off = (unit.dot(*p) - d).abs();
        if off > PLANARITY_TOLERANCE * size {
            return Err(format!("is not planar: vertex {k} lies {off} off the face's plane (size {size})"));
        }
    }
    // Convex: every turn has the same sense as the face normal (collinear turns allowed).
    let len = pts.len();
    for k in 0..len {
        let a = pts[k];
        let b = pts[(k + 1) % len];
        let c = pts[(k + 2) % len];
        let turn = (b - a).cross(c - b).dot(unit);
        if turn < -1e-6 * size * size {
            return Err(format!("is not convex: it turns the wrong way at vertex {}", (k + 1) % len));
        }
    }
    Ok(())
}
