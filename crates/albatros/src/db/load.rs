//! Scene loaders at the edge of the library (SYSTEM.md 2): the TOML scene format
//! (`docs/scene-format.md`) here, Wavefront OBJ meshes in [`obj`]. This is the only part of the
//! scene database that touches files; everything downstream takes the in-memory
//! [`Scene`] it returns.
//!
//! Input: the text of a scene file (or an OBJ file's bytes). Output: a [`Scene`] that
//! has passed [`Scene::validate`], or a [`LoadError`] whose message names the file,
//! the line and column, and the field or item that is wrong, e.g.
//! `scenes/a.toml:12:5: model 'hangar' face 3: is not convex: ...`.
//!
//! How the locations are kept: the file is read in two steps. First serde and the
//! `toml` crate turn it into the `Raw*` structures below; syntax errors, unknown keys,
//! missing fields, wrong types and non-finite numbers (TOML can write `nan` and `inf`)
//! fail here, and `toml` gives the byte span of the offending key or value. Every
//! table the second step may complain about is wrapped in [`Spanned`], so the second
//! step (names resolved, indices checked, faces checked for planarity and convexity,
//! canonical objects built, OBJ files read) can point at the material, model, face,
//! part, instance or light it rejects. The invariant: **no input makes this module
//! panic**; every problem is a `LoadError`.

use std::collections::HashMap;
use std::fmt;
use std::ops::Range;
use std::path::Path;

use glam::{Mat4, Vec3};
use serde::Deserialize;
use toml::Spanned;

pub mod obj;

pub use obj::{load_obj, parse_obj};

use super::canonical::Canonical;
use super::{
    check_convex_planar, Environment, Eye, Face, Instance, LightPoint, Material, MaterialTexture, Model, Rgb, Scene,
    SceneError, Screen, Shading, TextureDef, TextureSource, Transparency, Vertex,
};

/// The names a `[[texture]]` may give as `builtin`: the texture unit's procedural maps.
pub const BUILTIN_TEXTURES: &[&str] = crate::vp::texture::BUILTIN_NAMES;

/// The largest product of a canonical part's integer (resolution) parameters. The
/// face count of every canonical shape is at most a small multiple of that product;
/// 2^22 (4 Mi cells, about the size of the `many` built-in scene) keeps a typo such
/// as `slices = 1200000` from asking for gigabytes.
pub const MAX_PART_CELLS: u64 = 1 << 22;

/// The most lights one `[[light_row]]` may expand to. A long runway with approach
/// lights has a few hundred; the cap keeps a typo from allocating gigabytes.
pub const MAX_LIGHTS_PER_ROW: u32 = 100_000;

/// How many lines [`key_of_value`] reads backwards looking for a value's key: a long
/// multi-line array of vertices may put its key far above the failing element.
const KEY_SEARCH_LINES: usize = 10_000;

/// How many known names an "unknown name" message lists.
const NAMES_LISTED: usize = 8;

/// A place in a file: the file as given for messages, and the 1-based line and
/// column (in characters) when known. Displays as `file:line:column`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file, as the caller named it.
    pub file: String,
    /// 1-based line, if known.
    pub line: Option<usize>,
    /// 1-based column in characters, if known.
    pub column: Option<usize>,
}

impl Location {
    /// A whole file, no line.
    pub fn file(file: &str) -> Self {
        Self { file: file.to_string(), line: None, column: None }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(column) = self.column {
                write!(f, ":{column}")?;
            }
        }
        Ok(())
    }
}

/// A scene or OBJ file that could not be used. Every message starts with the
/// [`Location`] (`file:line:column`) and names the item and field at fault.
///
/// No variant carries a `source()`: the message is complete in itself (the cause is
/// part of the text), so an error chain printer does not repeat it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LoadError {
    /// The file could not be read.
    #[error("{path}: cannot read: {reason}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        reason: std::io::Error,
    },
    /// The TOML is malformed, or does not fit the format: a syntax error, an unknown
    /// key, a missing field, a value of the wrong type, a non-finite number.
    #[error("{at}: {message}")]
    Syntax {
        /// Where.
        at: Location,
        /// What `toml` said, prefixed with the key when it could be found.
        message: String,
    },
    /// The file parses but its content is wrong (unknown name, index out of range,
    /// bad face, value out of range, ...).
    #[error("{at}: {what}: {problem}")]
    Invalid {
        /// Where.
        at: Location,
        /// Which item (`material 'grass'`, `model 'hangar' face 3`, ...).
        what: String,
        /// What is wrong, naming the field.
        problem: String,
    },
    /// A file the scene refers to (an OBJ mesh) is wrong: where the scene refers to
    /// it, then that file's own error.
    #[error("{at}: {what}: {inner}")]
    Nested {
        /// Where the scene refers to the file.
        at: Location,
        /// Which item refers to it.
        what: String,
        /// The error in that file.
        inner: Box<LoadError>,
    },
    /// [`Scene::validate`] rejected the assembled scene (a safety net behind the
    /// loader's own checks), located as well as its message allows.
    #[error("{at}: {error}")]
    Scene {
        /// Where, as near as known.
        at: Location,
        /// The validation error.
        error: Box<SceneError>,
    },
}

impl LoadError {
    /// Where the error is (for a [`LoadError::Nested`] error, where the scene refers
    /// to the file that is wrong).
    pub fn location(&self) -> Option<&Location> {
        match self {
            LoadError::Io { .. } => None,
            LoadError::Syntax { at, .. }
            | LoadError::Invalid { at, .. }
            | LoadError::Nested { at, .. }
            | LoadError::Scene { at, .. } => Some(at),
        }
    }
}

/// Loads a scene from a TOML file (format: `docs/scene-format.md`). Files the scene
/// names (OBJ meshes, PNG textures) are found relative to the scene file's folder.
pub fn load_scene(path: &Path) -> Result<Scene, LoadError> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|reason| LoadError::Io { path: shown.clone(), reason })?;
    let base_dir = path.parent().unwrap_or(Path::new("."));
    parse_scene(&text, &shown, base_dir)
}

/// Parses a scene from TOML text. `path_for_messages` names the text in errors (and
/// gives the scene its default name); `base_dir` is where relative file names in it
/// are resolved.
pub fn parse_scene(text: &str, path_for_messages: &str, base_dir: &Path) -> Result<Scene, LoadError> {
    let ctx = Ctx::new(text, path_for_messages, base_dir);
    let raw: RawScene = toml::from_str(text).map_err(|e| ctx.syntax(&e))?;
    ctx.build(raw)
}

/// The transform of a placed part or instance: scale, then roll about Y, pitch about
/// X, heading about Z (clockwise seen from above, as the eye's heading), then move
/// to `position`. Angles in degrees.
pub fn placement(position: Vec3, heading: f32, pitch: f32, roll: f32, scale: Vec3) -> Mat4 {
    let rotation = Mat4::from_rotation_z(-heading.to_radians())
        * Mat4::from_rotation_x(pitch.to_radians())
        * Mat4::from_rotation_y(roll.to_radians());
    Mat4::from_translation(position) * rotation * Mat4::from_scale(scale)
}

// ---------------------------------------------------------------------------------
// The file as serde reads it.

/// A finite number. TOML can write `nan` and `inf`; they are rejected while parsing
/// so that `toml` reports the value's exact position.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Fin(f32);

impl<'de> Deserialize<'de> for Fin {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Fin;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number")
            }

            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Fin, E> {
                let f = v as f32;
                if v.is_nan() {
                    Err(E::custom("expected a finite number, found nan"))
                } else if v.is_infinite() {
                    Err(E::custom(format!("expected a finite number, found {v}")))
                } else if !f.is_finite() {
                    Err(E::custom(format!("{v:e} is too large (32-bit numbers reach about 3.4e38)")))
                } else {
                    Ok(Fin(f))
                }
            }

            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Fin, E> {
                self.visit_f64(v as f64)
            }

            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Fin, E> {
                self.visit_f64(v as f64)
            }
        }
        d.deserialize_f64(Visitor)
    }
}

type Vec3Raw = [Fin; 3];

fn v3(a: Vec3Raw) -> Vec3 {
    Vec3::new(a[0].0, a[1].0, a[2].0)
}

/// A scale: one factor, or one per axis.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged, expecting = "expected a number or an array of 3 numbers")]
enum RawScale {
    Uniform(Fin),
    Axes(Vec3Raw),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    name: Option<String>,
    screen: Option<Spanned<RawScreen>>,
    eye: Option<Spanned<RawEye>>,
    environment: Option<Spanned<RawEnvironment>>,
    #[serde(default)]
    texture: Vec<Spanned<RawTexture>>,
    #[serde(default)]
    material: Vec<Spanned<RawMaterial>>,
    #[serde(default)]
    model: Vec<Spanned<RawModel>>,
    #[serde(default)]
    instance: Vec<Spanned<RawInstance>>,
    #[serde(default)]
    light: Vec<Spanned<RawLight>>,
    #[serde(default)]
    light_row: Vec<Spanned<RawLightRow>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScreen {
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEye {
    position: Option<Vec3Raw>,
    heading: Option<Fin>,
    pitch: Option<Fin>,
    roll: Option<Fin>,
    fov: Option<Spanned<Fin>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEnvironment {
    sky: Option<Spanned<Vec3Raw>>,
    sun: Option<Spanned<Vec3Raw>>,
    background_brightness: Option<Fin>,
    ambient: Option<Fin>,
    attenuation: Option<Spanned<Fin>>,
    fog_color: Option<Spanned<Vec3Raw>>,
    /// Plain `f32`: `inf` is allowed here and means no fog.
    visibility: Option<Spanned<f32>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTexture {
    name: Spanned<String>,
    builtin: Option<Spanned<String>>,
    file: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    name: Spanned<String>,
    color: Spanned<Vec3Raw>,
    #[serde(default)]
    shading: Shading,
    transparency: Option<Spanned<u32>>,
    #[serde(default)]
    emissive: bool,
    texture: Option<Spanned<RawMaterialTexture>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterialTexture {
    map: Spanned<String>,
    period: Spanned<Fin>,
    u_axis: Option<Spanned<Vec3Raw>>,
    v_axis: Option<Spanned<Vec3Raw>>,
    origin: Option<Vec3Raw>,
    color1: Spanned<Vec3Raw>,
    color2: Spanned<Vec3Raw>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModel {
    name: Spanned<String>,
    material: Option<Spanned<String>>,
    vertices: Option<Spanned<Vec<Vec3Raw>>>,
    normals: Option<Spanned<Vec<Vec3Raw>>>,
    intensities: Option<Spanned<Vec<Fin>>>,
    faces: Option<Spanned<Vec<Spanned<RawFace>>>>,
    obj: Option<Spanned<String>>,
    parts: Option<Spanned<Vec<Spanned<RawPart>>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFace {
    v: Vec<u32>,
    material: Option<Spanned<String>>,
}

/// A part of a composite model: placement keys here, the rest is the canonical
/// shape. Not `deny_unknown_fields` (serde cannot combine it with `flatten`): unknown
/// keys land in `shape`, where [`Canonical`]'s own `deny_unknown_fields` rejects them.
#[derive(Debug, Deserialize)]
struct RawPart {
    material: Option<Spanned<String>>,
    position: Option<Vec3Raw>,
    heading: Option<Fin>,
    pitch: Option<Fin>,
    roll: Option<Fin>,
    scale: Option<Spanned<RawScale>>,
    #[serde(flatten)]
    shape: toml::Table,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInstance {
    model: Spanned<String>,
    position: Option<Vec3Raw>,
    heading: Option<Fin>,
    pitch: Option<Fin>,
    roll: Option<Fin>,
    scale: Option<Spanned<RawScale>>,
    #[serde(default)]
    moving: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    position: Vec3Raw,
    color: Spanned<Vec3Raw>,
    intensity: Option<Spanned<Fin>>,
    size: Spanned<Fin>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLightRow {
    from: Vec3Raw,
    to: Vec3Raw,
    count: Spanned<u32>,
    color: Spanned<Vec3Raw>,
    intensity: Option<Spanned<Fin>>,
    size: Spanned<Fin>,
}

// ---------------------------------------------------------------------------------
// From the raw file to the scene.

/// Names declared in the file: index and where declared.
type Names = HashMap<String, (u32, Range<usize>)>;

/// Where each item of the built scene came from, to locate [`Scene::validate`]'s
/// errors.
#[derive(Default)]
struct Spans {
    screen: Option<Range<usize>>,
    eye: Option<Range<usize>>,
    environment: Option<Range<usize>>,
    materials: Vec<Range<usize>>,
    /// Per model: its table and, for explicit meshes, each face.
    models: Vec<(Range<usize>, Vec<Range<usize>>)>,
    instances: Vec<Range<usize>>,
    lights: Vec<Range<usize>>,
}

/// The text being loaded and how to name places in it.
struct Ctx<'a> {
    text: &'a str,
    file: &'a str,
    base_dir: &'a Path,
    /// Byte offset of the start of every line.
    line_starts: Vec<usize>,
}

impl<'a> Ctx<'a> {
    fn new(text: &'a str, file: &'a str, base_dir: &'a Path) -> Self {
        let line_starts = std::iter::once(0).chain(text.match_indices('\n').map(|(i, _)| i + 1)).collect();
        Self { text, file, base_dir, line_starts }
    }

    /// The location of a byte offset.
    fn at(&self, offset: usize) -> Location {
        let offset = floor_char_boundary(self.text, offset);
        let line = self.line_starts.partition_point(|&s| s <= offset).max(1);
        let start = self.line_starts[line - 1];
        let column = self.text.get(start..offset).map_or(0, |s| s.chars().count()) + 1;
        Location { file: self.file.to_string(), line: Some(line), column: Some(column) }
    }

    fn at_span(&self, span: &Range<usize>) -> Location {
        self.at(span.start)
    }

    fn invalid(&self, span: &Range<usize>, what: impl Into<String>, problem: impl Into<String>) -> LoadError {
        LoadError::Invalid { at: self.at_span(span), what: what.into(), problem: problem.into() }
    }

    /// A `toml` error, located, and named by its key when the error is about a value.
    fn syntax(&self, e: &toml::de::Error) -> LoadError {
        let message = e.message().trim().replace('\n', "; ");
        let Some(span) = e.span() else {
            return LoadError::Syntax { at: Location::file(self.file), message };
        };
        let message = match (key_of_value(self.text, span.start, span.end), self.header_at(span.start)) {
            (Some(key), _) => format!("{key}: {message}"),
            (None, Some(header)) => format!("{header}: {message}"),
            (None, None) => message,
        };
        LoadError::Syntax { at: self.at(span.start), message }
    }

    /// The table header (`[[material]]`, `[material.texture]`) that starts a line at
    /// `offset`, if one does: `toml` places a table's errors (a missing field) there.
    fn header_at(&self, offset: usize) -> Option<&'a str> {
        let offset = floor_char_boundary(self.text, offset);
        let line_start = self.text[..offset].rfind('\n').map_or(0, |i| i + 1);
        if !self.text[line_start..offset].trim().is_empty() {
            return None;
        }
        let rest = &self.text[offset..];
        let line = rest.split('\n').next().unwrap_or("");
        let header = line.split('#').next().unwrap_or("").trim();
        (header.starts_with('[') && header.ends_with(']')).then_some(header)
    }

    fn build(&self, raw: RawScene) -> Result<Scene, LoadError> {
        let default_name =
            Path::new(self.file).file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let mut scene = Scene::empty(raw.name.as_deref().unwrap_or(&default_name));
        let mut spans = Spans::default();

        if let Some(screen) = &raw.screen {
            spans.screen = Some(screen.span());
            scene.screen = self.screen(screen.get_ref(), scene.screen)?;
        }
        if let Some(eye) = &raw.eye {
            spans.eye = Some(eye.span());
            scene.eye = self.eye(eye.get_ref(), scene.eye)?;
        }
        if let Some(env) = &raw.environment {
            spans.environment = Some(env.span());
            scene.env = self.environment(env.get_ref())?;
        }

        let mut textures = Names::new();
        for t in &raw.texture {
            let def = self.texture(t.get_ref())?;
            self.declare(&mut textures, "texture", &t.get_ref().name, scene.textures.len())?;
            scene.textures.push(def);
        }

        let mut materials = Names::new();
        for m in &raw.material {
            let material = self.material(m.get_ref(), &textures)?;
            self.declare(&mut materials, "material", &m.get_ref().name, scene.materials.len())?;
            scene.materials.push(material);
            spans.materials.push(m.span());
        }

        let mut models = Names::new();
        for m in &raw.model {
            let (model, face_spans) = self.model(m, &materials)?;
            self.declare(&mut models, "model", &m.get_ref().name, scene.models.len())?;
            scene.models.push(model);
            spans.models.push((m.span(), face_spans));
        }

        for (ii, i) in raw.instance.iter().enumerate() {
            scene.instances.push(self.instance(ii, i.get_ref(), &models)?);
            spans.instances.push(i.span());
        }

        for (li, l) in raw.light.iter().enumerate() {
            let l = l.get_ref();
            let what = format!("light {li}");
            let (color, intensity, size) = self.light_look(&what, &l.color, &l.intensity, &l.size)?;
            scene.lights.push(LightPoint { position: v3(l.position), color, intensity, size });
        }
        spans.lights.extend(raw.light.iter().map(|l| l.span()));
        for (ri, r) in raw.light_row.iter().enumerate() {
            let span = r.span();
            let r = r.get_ref();
            let what = format!("light_row {ri}");
            let (color, intensity, size) = self.light_look(&what, &r.color, &r.intensity, &r.size)?;
            let count = *r.count.get_ref();
            if count == 0 || count > MAX_LIGHTS_PER_ROW {
                return Err(self.invalid(
                    &r.count.span(),
                    what,
                    format!("count = {count} is out of range (1..={MAX_LIGHTS_PER_ROW})"),
                ));
            }
            let (from, to) = (v3(r.from), v3(r.to));
            for k in 0..count {
                let t = if count == 1 { 0.0 } else { k as f32 / (count - 1) as f32 };
                scene.lights.push(LightPoint { position: from.lerp(to, t), color, intensity, size });
                spans.lights.push(span.clone());
            }
        }

        scene.validate().map_err(|error| self.locate(error, &scene, &spans))?;
        Ok(scene)
    }

    /// Records a declared name, rejecting a duplicate.
    fn declare(&self, names: &mut Names, kind: &str, name: &Spanned<String>, index: usize) -> Result<(), LoadError> {
        let span = name.span();
        if let Some((_, first)) = names.get(name.get_ref()) {
            let first = self.at_span(first).line.unwrap_or(0);
            return Err(self.invalid(
                &span,
                format!("{kind} '{}'", name.get_ref()),
                format!("name is already used by the {kind} on line {first}"),
            ));
        }
        names.insert(name.get_ref().clone(), (index as u32, span));
        Ok(())
    }

    /// Looks up a name, or says which names there are.
    fn lookup(&self, names: &Names, kind: &str, name: &Spanned<String>, what: &str) -> Result<u32, LoadError> {
        if let Some((i, _)) = names.get(name.get_ref()) {
            return Ok(*i);
        }
        let mut known: Vec<&str> = names.keys().map(String::as_str).collect();
        known.sort_unstable();
        let list = if known.is_empty() {
            format!("no {kind} is declared")
        } else if known.len() > NAMES_LISTED {
            format!("{kind}s are {}, ...", known[..NAMES_LISTED].join(", "))
        } else {
            format!("{kind}s are {}", known.join(", "))
        };
        Err(self.invalid(&name.span(), what, format!("unknown {kind} '{}' ({list})", name.get_ref())))
    }

    fn screen(&self, raw: &RawScreen, default: Screen) -> Result<Screen, LoadError> {
        let side = |v: &Option<Spanned<u32>>, field: &str, default: u32| match v {
            None => Ok(default),
            Some(s) if (1..=Screen::MAX_SIDE).contains(s.get_ref()) => Ok(*s.get_ref()),
            Some(s) => Err(self.invalid(
                &s.span(),
                "screen",
                format!("{field} = {} is out of range (1..={})", s.get_ref(), Screen::MAX_SIDE),
            )),
        };
        Ok(Screen {
            width: side(&raw.width, "width", default.width)?,
            height: side(&raw.height, "height", default.height)?,
        })
    }

    fn eye(&self, raw: &RawEye, default: Eye) -> Result<Eye, LoadError> {
        let fov = match &raw.fov {
            None => default.fov,
            Some(f) => {
                let fov = f.get_ref().0;
                // Scene::validate's limits: a view narrower than 0.1 degree or wider
                // than 179 degrees makes the projection degenerate.
                if !(fov > 0.1 && fov < 179.0) {
                    return Err(self.invalid(
                        &f.span(),
                        "eye",
                        format!("fov = {fov} is out of range (0.1..179 degrees)"),
                    ));
                }
                fov
            }
        };
        Ok(Eye {
            position: raw.position.map_or(default.position, v3),
            heading: raw.heading.map_or(default.heading, |f| f.0),
            pitch: raw.pitch.map_or(default.pitch, |f| f.0),
            roll: raw.roll.map_or(default.roll, |f| f.0),
            fov,
        })
    }

    fn environment(&self, raw: &RawEnvironment) -> Result<Environment, LoadError> {
        let d = Environment::default();
        let what = "environment";
        let color = |c: &Option<Spanned<Vec3Raw>>, field, default| match c {
            None => Ok(default),
            Some(c) => self.color(c, what, field),
        };
        let sun = match &raw.sun {
            None => d.sun,
            Some(s) => {
                let v = v3(*s.get_ref());
                if v.length_squared() == 0.0 || !v.normalize().is_finite() {
                    return Err(self.invalid(&s.span(), what, "sun is not a direction (zero length)"));
                }
                v.normalize()
            }
        };
        let attenuation = match &raw.attenuation {
            None => d.attenuation,
            Some(a) if a.get_ref().0 >= 0.0 => a.get_ref().0,
            Some(a) => {
                return Err(self.invalid(&a.span(), what, format!("attenuation = {} must be >= 0", a.get_ref().0)));
            }
        };
        let visibility = match &raw.visibility {
            None => d.visibility,
            Some(v) if *v.get_ref() > 0.0 => *v.get_ref(),
            Some(v) => {
                return Err(self.invalid(
                    &v.span(),
                    what,
                    format!("visibility = {} must be > 0 (inf for no fog)", v.get_ref()),
                ));
            }
        };
        Ok(Environment {
            sky: color(&raw.sky, "sky", d.sky)?,
            sun,
            background_brightness: raw.background_brightness.map_or(d.background_brightness, |f| f.0),
            ambient: raw.ambient.map_or(d.ambient, |f| f.0),
            attenuation,
            fog_color: color(&raw.fog_color, "fog_color", d.fog_color)?,
            visibility,
        })
    }

    /// A colour, each component in 0..=1.
    fn color(&self, c: &Spanned<Vec3Raw>, what: &str, field: &str) -> Result<Rgb, LoadError> {
        let v = v3(*c.get_ref());
        if v.min_element() < 0.0 || v.max_element() > 1.0 {
            return Err(self.invalid(
                &c.span(),
                what,
                format!("{field} = [{}, {}, {}] is out of range (each component 0..=1)", v.x, v.y, v.z),
            ));
        }
        Ok(v)
    }

    fn texture(&self, raw: &RawTexture) -> Result<TextureDef, LoadError> {
        let what = format!("texture '{}'", raw.name.get_ref());
        let source = match (&raw.builtin, &raw.file) {
            (Some(b), None) => {
                if !BUILTIN_TEXTURES.contains(&b.get_ref().as_str()) {
                    return Err(self.invalid(
                        &b.span(),
                        what,
                        format!("unknown builtin '{}' (builtins are {})", b.get_ref(), BUILTIN_TEXTURES.join(", ")),
                    ));
                }
                TextureSource::Builtin(b.get_ref().clone())
            }
            (None, Some(f)) => {
                let path = self.base_dir.join(f.get_ref());
                if !path.is_file() {
                    return Err(self.invalid(&f.span(), what, format!("file {} does not exist", path.display())));
                }
                TextureSource::File(path)
            }
            _ => return Err(self.invalid(&raw.name.span(), what, "give exactly one of `builtin` and `file`")),
        };
        Ok(TextureDef { name: raw.name.get_ref().clone(), source })
    }

    fn material(&self, raw: &RawMaterial, textures: &Names) -> Result<Material, LoadError> {
        let what = format!("material '{}'", raw.name.get_ref());
        let transparency = match &raw.transparency {
            None => Transparency::OPAQUE,
            Some(t) => u8::try_from(*t.get_ref()).ok().and_then(Transparency::new).ok_or_else(|| {
                self.invalid(
                    &t.span(),
                    &what,
                    format!("transparency = {} is out of range (0..={}, a 6-bit code)", t.get_ref(), Transparency::MAX),
                )
            })?,
        };
        let texture = match &raw.texture {
            None => None,
            Some(t) => Some(self.material_texture(t.get_ref(), &what, textures)?),
        };
        Ok(Material {
            name: raw.name.get_ref().clone(),
            color: self.color(&raw.color, &what, "color")?,
            shading: raw.shading,
            texture,
            transparency,
            emissive: raw.emissive,
        })
    }

    fn material_texture(
        &self,
        t: &RawMaterialTexture,
        what: &str,
        textures: &Names,
    ) -> Result<MaterialTexture, LoadError> {
        let map = self.lookup(textures, "texture", &t.map, what)?;
        let period = t.period.get_ref().0;
        if period <= 0.0 {
            return Err(self.invalid(&t.period.span(), what, format!("texture.period = {period} must be > 0")));
        }
        let axis = |a: &Option<Spanned<Vec3Raw>>, field: &str, default: Vec3| match a {
            None => Ok((default, None)),
            Some(a) => {
                let v = v3(*a.get_ref()).normalize_or_zero();
                if v == Vec3::ZERO {
                    return Err(self.invalid(&a.span(), what, format!("texture.{field} has zero length")));
                }
                Ok((v, Some(a.span())))
            }
        };
        let (u_axis, _) = axis(&t.u_axis, "u_axis", Vec3::X)?;
        let (v_axis, v_span) = axis(&t.v_axis, "v_axis", Vec3::Y)?;
        // Parallel axes would map the whole plane onto one line of the texture.
        if u_axis.cross(v_axis).length() < 1e-3 {
            let span = v_span.or_else(|| t.u_axis.as_ref().map(Spanned::span)).unwrap_or_else(|| t.map.span());
            return Err(self.invalid(&span, what, "texture.u_axis and texture.v_axis are parallel"));
        }
        Ok(MaterialTexture {
            map,
            period,
            u_axis,
            v_axis,
            origin: t.origin.map_or(Vec3::ZERO, v3),
            color1: self.color(&t.color1, what, "texture.color1")?,
            color2: self.color(&t.color2, what, "texture.color2")?,
        })
    }

    /// Builds one model, returning it and the span of each explicit face.
    fn model(&self, m: &Spanned<RawModel>, materials: &Names) -> Result<(Model, Vec<Range<usize>>), LoadError> {
        let raw = m.get_ref();
        let name = raw.name.get_ref().clone();
        let what = format!("model '{name}'");
        if raw.vertices.is_none() {
            let stray = [
                ("faces", raw.faces.as_ref().map(Spanned::span)),
                ("normals", raw.normals.as_ref().map(Spanned::span)),
            ];
            let stray = stray.into_iter().chain([("intensities", raw.intensities.as_ref().map(Spanned::span))]);
            if let Some((field, Some(span))) = stray.into_iter().find(|(_, s)| s.is_some()) {
                return Err(self.invalid(&span, what, format!("`{field}` needs `vertices`")));
            }
        }
        let default_material =
            raw.material.as_ref().map(|n| self.lookup(materials, "material", n, &what)).transpose()?;

        let (model, face_spans) = match (&raw.vertices, &raw.obj, &raw.parts) {
            (Some(vertices), None, None) => self.mesh(raw, vertices, default_material, materials, &what)?,
            (None, Some(obj), None) => {
                let Some(material) = default_material else {
                    return Err(self.invalid(&obj.span(), what, "an `obj` model needs `material`"));
                };
                let path = self.base_dir.join(obj.get_ref());
                let mut model = load_obj(&path, material).map_err(|inner| LoadError::Nested {
                    at: self.at_span(&obj.span()),
                    what: format!("{what} obj"),
                    inner: Box::new(inner),
                })?;
                model.name = name;
                (model, Vec::new())
            }
            (None, None, Some(parts)) => {
                (self.composite(&name, parts, default_material, materials, &what)?, Vec::new())
            }
            _ => {
                return Err(self.invalid(
                    &m.span(),
                    what,
                    "give exactly one of `vertices` (with `faces`), `obj` and `parts`",
                ))
            }
        };
        if model.faces.is_empty() {
            return Err(self.invalid(&m.span(), what, "has no faces"));
        }
        Ok((model, face_spans))
    }

    /// An explicit mesh: vertices, optional normals and intensities, faces.
    fn mesh(
        &self,
        raw: &RawModel,
        vertices: &Spanned<Vec<Vec3Raw>>,
        default_material: Option<u32>,
        materials: &Names,
        what: &str,
    ) -> Result<(Model, Vec<Range<usize>>), LoadError> {
        let n = vertices.get_ref().len();
        let mut model = Model { name: raw.name.get_ref().clone(), ..Model::default() };
        model.vertices = vertices.get_ref().iter().map(|&p| Vertex::at(v3(p))).collect();
        if let Some(normals) = &raw.normals {
            if normals.get_ref().len() != n {
                return Err(self.invalid(
                    &normals.span(),
                    what,
                    format!("normals has {} entries but there are {n} vertices", normals.get_ref().len()),
                ));
            }
            for (v, &nrm) in model.vertices.iter_mut().zip(normals.get_ref()) {
                // A zero normal is filled in from the faces below.
                v.normal = v3(nrm).normalize_or_zero();
            }
        }
        if let Some(intensities) = &raw.intensities {
            if intensities.get_ref().len() != n {
                return Err(self.invalid(
                    &intensities.span(),
                    what,
                    format!("intensities has {} entries but there are {n} vertices", intensities.get_ref().len()),
                ));
            }
            for (v, i) in model.vertices.iter_mut().zip(intensities.get_ref()) {
                v.intensity = i.0;
            }
        }
        let Some(faces) = &raw.faces else {
            return Err(self.invalid(&vertices.span(), what, "has `vertices` but no `faces`"));
        };
        let mut spans = Vec::with_capacity(faces.get_ref().len());
        for (fi, f) in faces.get_ref().iter().enumerate() {
            let span = f.span();
            let face = f.get_ref();
            let what = format!("{what} face {fi}");
            let material = match &face.material {
                Some(name) => self.lookup(materials, "material", name, &what)?,
                None => default_material.ok_or_else(|| {
                    self.invalid(&span, &what, "has no material (give `material` on the face or the model)")
                })?,
            };
            if let Some(&i) = face.v.iter().find(|&&i| i as usize >= n) {
                return Err(self.invalid(
                    &span,
                    what,
                    format!("vertex index {i} is out of range (the model has {n} vertices, indices start at 0)"),
                ));
            }
            let pts: Vec<Vec3> = face.v.iter().map(|&i| model.vertices[i as usize].position).collect();
            check_convex_planar(&pts).map_err(|problem| self.invalid(&span, &what, problem))?;
            model.faces.push(Face { vertices: face.v.clone(), material });
            spans.push(span);
        }
        model.fill_normals();
        Ok((model, spans))
    }

    /// A composite of canonical parts (P5).
    fn composite(
        &self,
        name: &str,
        parts: &Spanned<Vec<Spanned<RawPart>>>,
        default_material: Option<u32>,
        materials: &Names,
        what: &str,
    ) -> Result<Model, LoadError> {
        let mut model = Model { name: name.to_string(), ..Model::default() };
        for (pi, p) in parts.get_ref().iter().enumerate() {
            let span = p.span();
            let raw = p.get_ref();
            let what = format!("{what} part {pi}");
            let material = match &raw.material {
                Some(n) => self.lookup(materials, "material", n, &what)?,
                None => default_material.ok_or_else(|| {
                    self.invalid(&span, &what, "has no material (give `material` on the part or the model)")
                })?,
            };
            if let Some(key) = first_non_finite(&raw.shape) {
                return Err(self.invalid(&span, what, format!("{key} is not a finite number")));
            }
            let cells = raw
                .shape
                .values()
                .filter_map(toml::Value::as_integer)
                .fold(1u64, |acc, i| acc.saturating_mul(i.unsigned_abs().max(1)));
            if cells > MAX_PART_CELLS {
                return Err(self.invalid(
                    &span,
                    what,
                    format!("resolution too high: its parameters multiply to {cells} cells (at most {MAX_PART_CELLS})"),
                ));
            }
            let shape: Canonical = toml::Value::Table(raw.shape.clone())
                .try_into()
                .map_err(|e: toml::de::Error| self.invalid(&span, &what, e.message().trim().replace('\n', "; ")))?;
            let built = shape.build(material).map_err(|e| self.invalid(&span, &what, e))?;
            let scale = self.scale(&raw.scale, &what)?;
            let transform = placement(
                raw.position.map_or(Vec3::ZERO, v3),
                raw.heading.map_or(0.0, |f| f.0),
                raw.pitch.map_or(0.0, |f| f.0),
                raw.roll.map_or(0.0, |f| f.0),
                scale,
            );
            model.append(&built, transform);
        }
        Ok(model)
    }

    /// A scale; every factor must be > 0 (a mirror would turn faces inside out).
    fn scale(&self, scale: &Option<Spanned<RawScale>>, what: &str) -> Result<Vec3, LoadError> {
        let Some(s) = scale else { return Ok(Vec3::ONE) };
        let v = match *s.get_ref() {
            RawScale::Uniform(f) => Vec3::splat(f.0),
            RawScale::Axes(a) => v3(a),
        };
        if v.min_element() <= 0.0 {
            return Err(self.invalid(
                &s.span(),
                what,
                "scale must be > 0 on every axis (zero flattens the model, negative turns it inside out)",
            ));
        }
        Ok(v)
    }

    fn instance(&self, ii: usize, raw: &RawInstance, models: &Names) -> Result<Instance, LoadError> {
        let what = format!("instance {ii}");
        let model = self.lookup(models, "model", &raw.model, &what)?;
        let scale = self.scale(&raw.scale, &what)?;
        let transform = placement(
            raw.position.map_or(Vec3::ZERO, v3),
            raw.heading.map_or(0.0, |f| f.0),
            raw.pitch.map_or(0.0, |f| f.0),
            raw.roll.map_or(0.0, |f| f.0),
            scale,
        );
        Ok(Instance { model, transform, moving: raw.moving })
    }

    /// A light's colour, intensity (default 1, >= 0) and size (> 0).
    fn light_look(
        &self,
        what: &str,
        color: &Spanned<Vec3Raw>,
        intensity: &Option<Spanned<Fin>>,
        size: &Spanned<Fin>,
    ) -> Result<(Rgb, f32, f32), LoadError> {
        let color = self.color(color, what, "color")?;
        let intensity = match intensity {
            None => 1.0,
            Some(i) if i.get_ref().0 >= 0.0 => i.get_ref().0,
            Some(i) => {
                return Err(self.invalid(&i.span(), what, format!("intensity = {} must be >= 0", i.get_ref().0)))
            }
        };
        if size.get_ref().0 <= 0.0 {
            return Err(self.invalid(&size.span(), what, format!("size = {} must be > 0", size.get_ref().0)));
        }
        Ok((color, intensity, size.get_ref().0))
    }

    /// Places a [`Scene::validate`] error as well as its `what` allows: every message
    /// starts with `what:`, naming `screen`, `eye`, `environment`, `material N '..'`,
    /// `model '..' face N`, `model '..' vertex N`, `instance N` or `light N`.
    fn locate(&self, error: SceneError, scene: &Scene, spans: &Spans) -> LoadError {
        let text = error.to_string();
        let what = text.split(": ").next().unwrap_or("");
        let mut words = what.split_whitespace();
        let index = |w: Option<&str>| w.and_then(|w| w.parse::<usize>().ok());
        let span = match words.next() {
            Some("screen") => spans.screen.clone(),
            Some("eye") => spans.eye.clone(),
            Some("environment") => spans.environment.clone(),
            Some("material") => index(words.next()).and_then(|i| spans.materials.get(i).cloned()),
            Some("instance") => index(words.next()).and_then(|i| spans.instances.get(i).cloned()),
            Some("light") => index(words.next()).and_then(|i| spans.lights.get(i).cloned()),
            Some("model") => {
                let rest = what.strip_prefix("model '").unwrap_or("");
                let (name, tail) = rest.rsplit_once('\'').unwrap_or((rest, ""));
                scene.models.iter().position(|m| m.name == name).and_then(|mi| {
                    let (model_span, faces) = spans.models.get(mi)?;
                    let face = tail.trim().strip_prefix("face ").and_then(|f| f.parse::<usize>().ok());
                    Some(face.and_then(|f| faces.get(f).cloned()).unwrap_or_else(|| model_span.clone()))
                })
            }
            _ => None,
        };
        let at = span.map_or_else(|| Location::file(self.file), |s| self.at_span(&s));
        LoadError::Scene { at, error: Box::new(error) }
    }
}

/// The first key (dotted path) in a table whose value is a non-finite float.
fn first_non_finite(table: &toml::Table) -> Option<String> {
    fn walk(v: &toml::Value) -> bool {
        match v {
            toml::Value::Float(f) => !(*f as f32).is_finite(),
            toml::Value::Array(a) => a.iter().any(walk),
            toml::Value::Table(t) => t.values().any(walk),
            _ => false,
        }
    }
    table.iter().find(|(_, v)| walk(v)).map(|(k, _)| k.clone())
}

/// The largest char boundary at or below `offset`, clamped to the text.
fn floor_char_boundary(text: &str, offset: usize) -> usize {
    let mut o = offset.min(text.len());
    while !text.is_char_boundary(o) {
        o -= 1;
    }
    o
}

/// The key whose value is at `start..end` in a TOML text, for naming the field in a
/// `toml` error that only gives the value's position ("invalid type: string, expected
/// f32"). Reads backwards from the value, skipping strings, comments and whole
/// nested arrays and inline tables, to the `=` that introduces the innermost
/// enclosing value, and returns the key before it. `None` when the span is a key or a
/// table header rather than a value, or when the text is too involved to read
/// backwards with confidence (multi-line strings, quoted keys).
fn key_of_value(text: &str, start: usize, end: usize) -> Option<String> {
    let start = floor_char_boundary(text, start);
    let end = floor_char_boundary(text, end.max(start));
    // A span that is itself a key (unknown field, duplicate key) needs no key.
    if text[end..].trim_start_matches([' ', '\t']).starts_with('=') {
        return None;
    }
    let mut depth = 0i32;
    let mut first = true;
    for line in text[..start].rsplit('\n').take(KEY_SEARCH_LINES) {
        let code = code_chars(line)?;
        for (i, &c) in code.iter().enumerate().rev() {
            if c.is_whitespace() {
                continue;
            }
            if first {
                first = false;
                // A value follows `=`, or `[` / `,` inside an array.
                if !matches!(c, '=' | '[' | ',') {
                    return None;
                }
            }
            match c {
                ']' | '}' => depth += 1,
                '[' | '{' => depth -= 1,
                '=' if depth <= 0 => {
                    let before: String = code[..i].iter().collect();
                    let key: String = before
                        .trim_end()
                        .chars()
                        .rev()
                        .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
                        .collect::<Vec<_>>()
                        .into_iter()
                        .rev()
                        .collect();
                    return (!key.is_empty()).then_some(key);
                }
                _ => {}
            }
        }
    }
    None
}

/// The characters of one TOML line outside strings and comments, each string
/// replaced by a single `"`. `None` for a line with a multi-line string delimiter.
fn code_chars(line: &str) -> Option<Vec<char>> {
    if line.contains("\"\"\"") || line.contains("'''") {
        return None;
    }
    let mut out = Vec::with_capacity(line.len());
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match c {
            '#' => break,
            '"' => {
                out.push('"');
                let mut escaped = false;
                for c in chars.by_ref() {
                    match c {
                        '\\' if !escaped => escaped = true,
                        '"' if !escaped => break,
                        _ => escaped = false,
                    }
                }
            }
            '\'' => {
                out.push('"');
                for c in chars.by_ref() {
                    if c == '\'' {
                        break;
                    }
                }
            }
            _ => out.push(c),
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_of_value_finds_the_innermost_key() {
        let check = |text: &str, needle: &str, expected: Option<&str>| {
            let start = text.find(needle).expect("needle");
            assert_eq!(key_of_value(text, start, start + needle.len()).as_deref(), expected, "{text:?} at {needle:?}");
        };
        check("heading = \"x\"\n", "\"x\"", Some("heading"));
        check("color = [1, 0, \"x\"]", "\"x\"", Some("color"));
        check("vertices = [[0, 0, 0],\n  [0, nan, 0]]", "[0, nan", Some("vertices"));
        check("faces = [{ v = [1], material = \"a\" }, { v = [1, -2] }]", "-2", Some("v"));
        check("x = { a = [1], b = [\"]\", 2] }", "2", Some("b"));
        check("name = \"a = [\" # = [\ncolr = 3", "colr", None);
        check("[[material]]\nname = \"a\"", "[[material]]", None);
        check("a = \"\"\"\nx = 1\n\"\"\"\nb = [\n 1, \"q\"]", "\"q\"", Some("b"));
        check("a = [\"\"\"\nx = [\n\"\"\", \"q\"]", "\"q\"", None);
    }

    #[test]
    fn locations_count_lines_and_characters() {
        let ctx = Ctx::new("ab\nçd = 1\n", "f.toml", Path::new("."));
        assert_eq!(ctx.at(0).to_string(), "f.toml:1:1");
        assert_eq!(ctx.at(3).to_string(), "f.toml:2:1");
        assert_eq!(ctx.at(6).to_string(), "f.toml:2:3");
        assert_eq!(ctx.at(100).line, Some(3));
    }
}
