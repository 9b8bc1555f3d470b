//! Built-in scenes, addressable by name wherever a scene is taken: `default` (an
//! airfield on approach), `rombm` (P1 fig. 4's 22 stacked rhombi), `rhombus` (the
//! top rhombus of `rombm` alone: its depth-complexity-1 twin), `terrain`
//! (a 256 x 256 heightfield), `city` (a few thousand boxes), `many` (about a million
//! small triangles facing the eye).
//!
//! Input: a name. Output: a [`Scene`] that passes [`Scene::validate`]. Invariant: the
//! same name gives the same scene, bit for bit, on every call: the pseudo-random
//! placements come from a fixed-seed xorshift generator (`Rng`), not from the
//! system. The scenes are built from canonical objects ([`super::canonical`]) and a
//! few hand-made flat polygons (pavement, markings, roofs), in world coordinates
//! X east, Y north, Z up, metres.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

use glam::{Mat4, Vec2, Vec3};

use super::canonical::{composite, Canonical, Part};
use super::{
    polygon_normal, Eye, Face, Instance, LightPoint, MaterialTexture, Model, Rgb, Scene, Screen, Shading, TextureDef,
    TextureSource, Transparency, Vertex,
};

/// The names of the built-in scenes.
pub const NAMES: &[&str] = &["default", "rombm", "rhombus", "terrain", "city", "many"];

/// The built-in scene of that name, if there is one.
pub fn scene(name: &str) -> Option<Scene> {
    Some(match name {
        "default" => airfield(),
        "rombm" => rombm("rombm", 0..RHOMBI),
        "rhombus" => rombm("rhombus", RHOMBI - 1..RHOMBI),
        "terrain" => terrain(),
        "city" => city(),
        "many" => many(),
        _ => return None,
    })
}

// ---------------------------------------------------------------------------------
// Helpers shared by the scenes.

/// xorshift64* (Marsaglia's xorshift with Vigna's output multiplier): a tiny
/// deterministic generator, good enough to scatter trees, buildings and triangles.
struct Rng(u64);

impl Rng {
    /// Vigna's multiplier for xorshift64*.
    const MULTIPLIER: u64 = 0x2545_F491_4F6C_DD1D;

    /// A generator from a seed (zero, a fixed point of xorshift, is replaced by 1).
    fn new(seed: u64) -> Self {
        Self(seed.max(1))
    }

    fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(Self::MULTIPLIER)
    }

    /// Uniform in `[0, 1)`: the top 24 bits, exactly representable in an `f32`.
    fn unit(&mut self) -> f32 {
        const MANTISSA_BITS: u32 = 24;
        (self.next_u64() >> (64 - MANTISSA_BITS)) as f32 / (1u32 << MANTISSA_BITS) as f32
    }

    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform in `0..n`.
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// A colour from hue (turns), saturation and value, all in `0..=1`.
fn hsv(hue: f32, saturation: f32, value: f32) -> Rgb {
    let h6 = hue.rem_euclid(1.0) * 6.0;
    let channel = |n: f32| {
        let k = (n + h6) % 6.0;
        value - value * saturation * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    Vec3::new(channel(5.0), channel(3.0), channel(1.0))
}

/// Builds a canonical shape whose parameters are constants of this file.
fn shape(canonical: Canonical, material: u32) -> Model {
    canonical.build(material).expect("built-in scenes use fixed, valid shape parameters")
}

/// Builds a composite whose parts are constants of this file.
fn assemble(name: &str, parts: &[Part]) -> Model {
    composite(name, parts).expect("built-in scenes use fixed, valid shape parameters")
}

/// A part of a composite: `shape` moved by `transform`.
fn part(shape: Canonical, transform: Mat4, material: u32) -> Part {
    Part { shape, transform, material }
}

/// Appends a flat convex polygon (counter-clockwise seen from its front) with
/// vertices of its own carrying the face normal.
fn polygon(model: &mut Model, points: &[Vec3], material: u32) {
    let normal = polygon_normal(points.iter().copied()).normalize_or_zero();
    let base = model.vertices.len() as u32;
    model.vertices.extend(points.iter().map(|&position| Vertex { position, normal, intensity: 1.0 }));
    model.faces.push(Face { vertices: (base..base + points.len() as u32).collect(), material });
}

/// Appends a horizontal rectangle between corners `lo` and `hi` (x, y) at height
/// `z`, facing up.
fn rect(model: &mut Model, lo: Vec2, hi: Vec2, z: f32, material: u32) {
    let corners = [(lo.x, lo.y), (hi.x, lo.y), (hi.x, hi.y), (lo.x, hi.y)];
    polygon(model, &corners.map(|(x, y)| Vec3::new(x, y, z)), material);
}

/// A closed prism along y from `y0` to `y1` over a convex `profile` of (x, z) points
/// listed counter-clockwise with x to the right and z up (as seen from -y).
fn prism(name: &str, profile: &[Vec2], y0: f32, y1: f32, material: u32) -> Model {
    let mut model = Model { name: name.to_string(), ..Model::default() };
    let at = |p: Vec2, y: f32| Vec3::new(p.x, y, p.y);
    let front: Vec<Vec3> = profile.iter().map(|&p| at(p, y0)).collect();
    let back: Vec<Vec3> = profile.iter().rev().map(|&p| at(p, y1)).collect();
    polygon(&mut model, &front, material);
    polygon(&mut model, &back, material);
    for (k, &p) in profile.iter().enumerate() {
        let q = profile[(k + 1) % profile.len()];
        polygon(&mut model, &[at(p, y0), at(p, y1), at(q, y1), at(q, y0)], material);
    }
    model
}

/// Adds a texture map declared by name (built-in procedural source), once.
fn texture(scene: &mut Scene, name: &str) -> u32 {
    if let Some(i) = scene.textures.iter().position(|t| t.name == name) {
        return i as u32;
    }
    scene.textures.push(TextureDef { name: name.to_string(), source: TextureSource::Builtin(name.to_string()) });
    (scene.textures.len() - 1) as u32
}

/// A material textured with built-in map `map` of period `period` metres, laid on
/// the ground plane (U east, V north), blending `c1` and `c2` (P2).
fn ground_material(scene: &mut Scene, name: &str, map: &str, period: f32, c1: Rgb, c2: Rgb) -> u32 {
    let map = texture(scene, map);
    let m = scene.material(name, (c1 + c2) * 0.5);
    scene.materials[m as usize].texture = Some(MaterialTexture {
        map,
        period,
        u_axis: Vec3::X,
        v_axis: Vec3::Y,
        origin: Vec3::ZERO,
        color1: c1,
        color2: c2,
    });
    m
}

/// A plain material with smooth (per-vertex) shading, for round shapes.
fn smooth_material(scene: &mut Scene, name: &str, color: Rgb) -> u32 {
    let m = scene.material(name, color);
    scene.materials[m as usize].shading = Shading::Smooth;
    m
}

/// Cubic smoothstep of `t` clamped to `0..=1`.
fn smoothstep(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Heights of a `cells` x `cells` heightfield of `cell` metres centred on `centre`
/// (world x, y), sampled from `height(x, y)`, row by row (y outer) as
/// [`Canonical::Heightfield`] takes them.
fn sample_heights(cells: u32, cell: f32, centre: Vec2, height: impl Fn(f32, f32) -> f32) -> Vec<f32> {
    let half = cells as f32 / 2.0;
    let mut heights = Vec::with_capacity(((cells + 1) * (cells + 1)) as usize);
    for j in 0..=cells {
        for i in 0..=cells {
            let x = centre.x + (i as f32 - half) * cell;
            let y = centre.y + (j as f32 - half) * cell;
            heights.push(height(x, y));
        }
    }
    heights
}

// ---------------------------------------------------------------------------------
// `default`: an airfield on approach.

/// Runway length (north along +y from the threshold at y = 0), metres.
const RUNWAY_LENGTH: f32 = 2000.0;
/// Half the runway width (45 m runway).
const RUNWAY_HALF_WIDTH: f32 = 22.5;
/// Heights of the layered ground surfaces above the flat airfield terrain (z = 0):
/// each layer sits a few centimetres above the one below, so that no two surfaces are
/// coplanar and the BSP order is unambiguous, while the eye cannot see the steps.
const PAVEMENT_Z: f32 = 0.05;
/// Height of the runway surface (see [`PAVEMENT_Z`]).
const RUNWAY_Z: f32 = 0.10;
/// Height of the painted markings (see [`PAVEMENT_Z`]).
const MARKING_Z: f32 = 0.15;
/// The parallel taxiway's centreline x, and its half width (23 m taxiway).
const TAXIWAY_X: f32 = 150.0;
/// Half the taxiway width.
const TAXIWAY_HALF_WIDTH: f32 = 11.5;
/// Where the approach begins: the eye is this far south of the threshold.
const EYE_BEFORE_THRESHOLD: f32 = 500.0;
/// The aiming point (middle of the aiming-point markings) past the threshold.
const AIM_POINT: f32 = 330.0;
/// The glide slope in degrees.
const GLIDE_SLOPE: f32 = 3.0;
/// The terrain: 128 x 128 cells of 93.75 m, 12 km square, centred 2.5 km north of
/// the threshold so that it reaches well past the 8 km visibility from the eye.
const TERRAIN_CELLS: u32 = 128;
/// Terrain cell size in metres (see [`TERRAIN_CELLS`]).
const TERRAIN_CELL: f32 = 93.75;
/// Terrain centre (x, y).
const TERRAIN_CENTRE: Vec2 = Vec2::new(0.0, 2500.0);
/// The airfield's flat zone (z = 0): everything the scene places stands inside it,
/// more than one terrain cell from its border.
const FLAT_LO: Vec2 = Vec2::new(-700.0, -1300.0);
/// Upper corner of the flat zone.
const FLAT_HI: Vec2 = Vec2::new(800.0, 2900.0);
/// Width of the band in which the rolling hills rise from the flat zone.
const FLAT_BLEND: f32 = 400.0;
/// Visibility range in metres.
const AIRFIELD_VISIBILITY: f32 = 8000.0;
/// The glass of the control tower's cab: code 32 of 63, about half the subpixels.
const GLASS_TRANSPARENCY: u8 = 32;

/// The gently rolling country around the airfield: three crossed waves of 0.7 to
/// 2.3 km wavelength, together at most 26 m high, faded to zero over the flat zone.
fn rolling(x: f32, y: f32) -> f32 {
    let hills = 14.0 * (TAU * x / 2300.0 + 0.7).sin() * (TAU * y / 1900.0 + 1.3).sin()
        + 8.0 * (TAU * (x + 0.6 * y) / 1300.0).sin()
        + 4.0 * (TAU * (x - y) / 700.0 + 2.0).sin();
    let outside = Vec2::new(x, y).clamp(FLAT_LO, FLAT_HI).distance(Vec2::new(x, y));
    hills * smoothstep(outside / FLAT_BLEND)
}

/// Appends the runway markings (white, slightly above the runway): threshold stripes,
/// aiming points, centreline dashes and edge stripes, at both ends.
fn runway_markings(model: &mut Model, white: u32) {
    let mut mark =
        |x0: f32, y0: f32, x1: f32, y1: f32| rect(model, Vec2::new(x0, y0), Vec2::new(x1, y1), MARKING_Z, white);
    // Twelve threshold stripes 30 m x 1.8 m, 6 each side of the centreline.
    const STRIPES_PER_SIDE: usize = 6;
    const STRIPE_FIRST: f32 = 3.9;
    const STRIPE_PITCH: f32 = 3.2;
    const STRIPE_HALF_WIDTH: f32 = 0.9;
    const STRIPE_FROM: f32 = 6.0;
    const STRIPE_TO: f32 = 36.0;
    // Aiming point: two 60 m x 10 m blocks 18 m apart, centred on AIM_POINT.
    const AIM_INNER: f32 = 9.0;
    const AIM_OUTER: f32 = 19.0;
    const AIM_HALF_LENGTH: f32 = 30.0;
    for far_end in [false, true] {
        // Distances along the runway from this end.
        let along = |d0: f32, d1: f32| {
            if far_end {
                (RUNWAY_LENGTH - d1, RUNWAY_LENGTH - d0)
            } else {
                (d0, d1)
            }
        };
        for k in 0..STRIPES_PER_SIDE {
            let x = STRIPE_FIRST + STRIPE_PITCH * k as f32;
            let (y0, y1) = along(STRIPE_FROM, STRIPE_TO);
            for side in [-1.0, 1.0] {
                let (xa, xb) = (side * (x - STRIPE_HALF_WIDTH), side * (x + STRIPE_HALF_WIDTH));
                mark(xa.min(xb), y0, xa.max(xb), y1);
            }
        }
        let (y0, y1) = along(AIM_POINT - AIM_HALF_LENGTH, AIM_POINT + AIM_HALF_LENGTH);
        mark(-AIM_OUTER, y0, -AIM_INNER, y1);
        mark(AIM_INNER, y0, AIM_OUTER, y1);
    }
    // Centreline: 30 m dashes, 20 m gaps, 0.9 m wide, clear of the threshold areas.
    const DASH: f32 = 30.0;
    const DASH_PITCH: f32 = 50.0;
    const DASH_HALF_WIDTH: f32 = 0.45;
    const DASH_FROM: f32 = 60.0;
    let mut y = DASH_FROM;
    while y + DASH <= RUNWAY_LENGTH - DASH_FROM {
        mark(-DASH_HALF_WIDTH, y, DASH_HALF_WIDTH, y + DASH);
        y += DASH_PITCH;
    }
    // Edge stripes, 0.9 m wide, 0.5 m in from the edges.
    const EDGE_IN: f32 = 0.5;
    const EDGE_WIDTH: f32 = 0.9;
    let (outer, inner) = (RUNWAY_HALF_WIDTH - EDGE_IN, RUNWAY_HALF_WIDTH - EDGE_IN - EDGE_WIDTH);
    mark(-outer, 0.0, -inner, RUNWAY_LENGTH);
    mark(inner, 0.0, outer, RUNWAY_LENGTH);
}

/// Runway, taxiway, connectors, apron and their markings: one static model in world
/// coordinates.
fn pavement(asphalt: u32, concrete: u32, white: u32, yellow: u32) -> Model {
    let mut m = Model { name: "pavement".into(), ..Model::default() };
    rect(&mut m, Vec2::new(-RUNWAY_HALF_WIDTH, 0.0), Vec2::new(RUNWAY_HALF_WIDTH, RUNWAY_LENGTH), RUNWAY_Z, asphalt);
    runway_markings(&mut m, white);
    // The parallel taxiway runs 10 m short of each runway end.
    const TAXIWAY_FROM: f32 = 10.0;
    let (tx0, tx1) = (TAXIWAY_X - TAXIWAY_HALF_WIDTH, TAXIWAY_X + TAXIWAY_HALF_WIDTH);
    let (ty0, ty1) = (TAXIWAY_FROM, RUNWAY_LENGTH - TAXIWAY_FROM);
    rect(&mut m, Vec2::new(tx0, ty0), Vec2::new(tx1, ty1), PAVEMENT_Z, concrete);
    // Three connectors (at both ends and mid-field), as wide as the taxiway; they
    // abut the runway's and the taxiway's edges without overlapping either.
    let width = 2.0 * TAXIWAY_HALF_WIDTH;
    for y in [ty0, RUNWAY_LENGTH / 2.0 - TAXIWAY_HALF_WIDTH, ty1 - width] {
        rect(&mut m, Vec2::new(RUNWAY_HALF_WIDTH, y), Vec2::new(tx0, y + width), PAVEMENT_Z, concrete);
    }
    // Apron east of the taxiway, in front of the hangars.
    rect(&mut m, Vec2::new(tx1, APRON_LO_Y), Vec2::new(APRON_HI_X, APRON_HI_Y), PAVEMENT_Z, concrete);
    // Yellow taxiway centreline, 0.3 m wide.
    const LINE_HALF_WIDTH: f32 = 0.15;
    rect(
        &mut m,
        Vec2::new(TAXIWAY_X - LINE_HALF_WIDTH, ty0),
        Vec2::new(TAXIWAY_X + LINE_HALF_WIDTH, ty1),
        MARKING_Z,
        yellow,
    );
    m
}

/// The apron's extent: from the taxiway's east edge to x = 400, y = 800 to 1200.
const APRON_HI_X: f32 = 400.0;
/// Apron south edge.
const APRON_LO_Y: f32 = 800.0;
/// Apron north edge.
const APRON_HI_Y: f32 = 1200.0;

/// Hangar size: 40 m wide (x), 50 m deep (y), walls 12 m high; door on the -y side.
const HANGAR: [f32; 3] = [40.0, 50.0, 12.0];

/// A hangar in local coordinates: box walls, a gabled or arched roof (a prism over the
/// walls' top), and a door 5 cm in front of the -y wall.
fn hangar(name: &str, arched: bool, walls: u32, roof: u32, door: u32) -> Model {
    let [w, d, h] = HANGAR;
    let mut model = assemble(name, &[part(Canonical::Box { size: HANGAR }, Mat4::IDENTITY, walls)]);
    let hw = w / 2.0;
    let profile: Vec<Vec2> = if arched {
        // A semi-ellipse of 12 segments rising 9 m.
        const SEGMENTS: usize = 12;
        const RISE: f32 = 9.0;
        (0..=SEGMENTS)
            .map(|k| {
                let t = PI * k as f32 / SEGMENTS as f32;
                Vec2::new(hw * t.cos(), h + RISE * t.sin())
            })
            .collect()
    } else {
        // A gable rising 7 m.
        const RISE: f32 = 7.0;
        vec![Vec2::new(-hw, h), Vec2::new(hw, h), Vec2::new(0.0, h + RISE)]
    };
    model.append(&prism("roof", &profile, -d / 2.0, d / 2.0, roof), Mat4::IDENTITY);
    // The door: 32 m wide, 10 m high, 5 cm proud of the wall (a decal).
    const DOOR_HALF_WIDTH: f32 = 16.0;
    const DOOR_HEIGHT: f32 = 10.0;
    const DECAL_OFFSET: f32 = 0.05;
    let y = -d / 2.0 - DECAL_OFFSET;
    let door_points = [
        Vec3::new(-DOOR_HALF_WIDTH, y, 0.0),
        Vec3::new(DOOR_HALF_WIDTH, y, 0.0),
        Vec3::new(DOOR_HALF_WIDTH, y, DOOR_HEIGHT),
        Vec3::new(-DOOR_HALF_WIDTH, y, DOOR_HEIGHT),
    ];
    polygon(&mut model, &door_points, door);
    model
}

/// The control tower: a 24 m concrete shaft, a cab floor, a glass cab and a roof.
fn tower(shaft: u32, slab: u32, glass: u32) -> Model {
    const SHAFT_HEIGHT: f32 = 24.0;
    const FLOOR: f32 = 0.4;
    const CAB: f32 = 3.0;
    let up = |z: f32| Mat4::from_translation(Vec3::new(0.0, 0.0, z));
    assemble(
        "tower",
        &[
            part(Canonical::Cylinder { radius: 2.5, height: SHAFT_HEIGHT, segments: 16 }, Mat4::IDENTITY, shaft),
            part(Canonical::Box { size: [8.0, 8.0, FLOOR] }, up(SHAFT_HEIGHT), slab),
            part(Canonical::Box { size: [7.6, 7.6, CAB] }, up(SHAFT_HEIGHT + FLOOR), glass),
            part(Canonical::Box { size: [8.6, 8.6, 0.5] }, up(SHAFT_HEIGHT + FLOOR + CAB), slab),
        ],
    )
}

/// A conifer: a cone of foliage on a cylinder trunk, 8 segments each.
fn tree(name: &str, trunk_height: f32, crown_radius: f32, crown_height: f32, trunk: u32, foliage: u32) -> Model {
    const SEGMENTS: u32 = 8;
    const TRUNK_RADIUS: f32 = 0.3;
    assemble(
        name,
        &[
            part(
                Canonical::Cylinder { radius: TRUNK_RADIUS, height: trunk_height, segments: SEGMENTS },
                Mat4::IDENTITY,
                trunk,
            ),
            part(
                Canonical::Cone { radius: crown_radius, height: crown_height, segments: SEGMENTS },
                Mat4::from_translation(Vec3::new(0.0, 0.0, trunk_height)),
                foliage,
            ),
        ],
    )
}

/// A fuel truck, 7.5 m long along +y (front at +y), standing on z = 0.
fn fuel_truck(chassis: u32, cab: u32, tank: u32, tyre: u32) -> Model {
    const CHASSIS_HALF_WIDTH: f32 = 1.2;
    const CHASSIS_BOTTOM: f32 = 0.7;
    const CHASSIS_TOP: f32 = 1.3;
    const WHEEL_RADIUS: f32 = 0.45;
    const WHEEL_WIDTH: f32 = 0.3;
    const WHEEL_GAP: f32 = 0.05;
    const TANK_RADIUS: f32 = 1.0;
    const TANK_LENGTH: f32 = 4.8;
    const TANK_REAR: f32 = -3.6;
    let mut parts = vec![
        part(
            Canonical::Box { size: [2.0 * CHASSIS_HALF_WIDTH, 7.5, CHASSIS_TOP - CHASSIS_BOTTOM] },
            Mat4::from_translation(Vec3::new(0.0, 0.0, CHASSIS_BOTTOM)),
            chassis,
        ),
        part(
            Canonical::Box { size: [2.0 * CHASSIS_HALF_WIDTH, 2.0, 1.9] },
            Mat4::from_translation(Vec3::new(0.0, 2.6, CHASSIS_TOP)),
            cab,
        ),
        // The tank: a cylinder turned from z to +y, 5 cm clear of the chassis.
        part(
            Canonical::Cylinder { radius: TANK_RADIUS, height: TANK_LENGTH, segments: 16 },
            Mat4::from_translation(Vec3::new(0.0, TANK_REAR, CHASSIS_TOP + TANK_RADIUS + WHEEL_GAP))
                * Mat4::from_rotation_x(-FRAC_PI_2),
            tank,
        ),
    ];
    // Four wheels, cylinders turned from z to +x, just outside the chassis.
    for y in [-2.6, 2.6] {
        for x in [CHASSIS_HALF_WIDTH + WHEEL_GAP, -CHASSIS_HALF_WIDTH - WHEEL_GAP - WHEEL_WIDTH] {
            parts.push(part(
                Canonical::Cylinder { radius: WHEEL_RADIUS, height: WHEEL_WIDTH, segments: 12 },
                Mat4::from_translation(Vec3::new(x, y, WHEEL_RADIUS)) * Mat4::from_rotation_y(FRAC_PI_2),
                tyre,
            ));
        }
    }
    assemble("fuel truck", &parts)
}

/// Approach, threshold, end, edge, centreline and taxiway lights, and a PAPI.
fn airfield_lights(scene: &mut Scene) {
    let white = Vec3::new(1.0, 0.97, 0.85);
    let green = Vec3::new(0.2, 1.0, 0.3);
    let red = Vec3::new(1.0, 0.15, 0.1);
    let yellow = Vec3::new(1.0, 0.8, 0.2);
    let blue = Vec3::new(0.25, 0.4, 1.0);
    let mut light = |x: f32, y: f32, z: f32, color: Rgb, size: f32| {
        scene.lights.push(LightPoint { position: Vec3::new(x, y, z), color, intensity: 1.0, size });
    };
    // Approach lights: 5-light barrettes every 30 m out to 900 m, on 1 m poles, and
    // a crossbar 300 m out.
    const BARRETTES: usize = 30;
    const BARRETTE_PITCH: f32 = 30.0;
    const BARRETTE_LIGHT_PITCH: f32 = 1.05;
    const POLE: f32 = 1.0;
    for k in 1..=BARRETTES {
        for i in -2..=2 {
            light(i as f32 * BARRETTE_LIGHT_PITCH, -(k as f32) * BARRETTE_PITCH, POLE, white, 0.6);
        }
    }
    const CROSSBAR_Y: f32 = -300.0;
    for i in 0..8 {
        let x = 4.5 + 1.5 * i as f32;
        light(-x, CROSSBAR_Y, POLE, white, 0.6);
        light(x, CROSSBAR_Y, POLE, white, 0.6);
    }
    // Threshold (green) and runway end (red) rows, 16 lights 3 m apart, 1 m outside
    // the runway.
    const ROW_LIGHTS: usize = 16;
    const ROW_PITCH: f32 = 3.0;
    const LOW: f32 = 0.3;
    for i in 0..ROW_LIGHTS {
        let x = -RUNWAY_HALF_WIDTH + ROW_PITCH * i as f32;
        light(x, -1.0, LOW, green, 0.4);
        light(x, RUNWAY_LENGTH + 1.0, LOW, red, 0.4);
    }
    // Edge lights every ~60 m, 1 m outside the edges; yellow over the last 600 m.
    const EDGE_INTERVALS: usize = 33;
    const CAUTION_ZONE: f32 = 600.0;
    for i in 0..=EDGE_INTERVALS {
        let y = RUNWAY_LENGTH * i as f32 / EDGE_INTERVALS as f32;
        let color = if y > RUNWAY_LENGTH - CAUTION_ZONE { yellow } else { white };
        light(-RUNWAY_HALF_WIDTH - 1.0, y, LOW, color, 0.4);
        light(RUNWAY_HALF_WIDTH + 1.0, y, LOW, color, 0.4);
    }
    // Centreline lights every 15 m: white, then alternating red and white over the
    // last 900 m, red over the last 300 m. Flush with (just above) the markings.
    const CENTRE_PITCH: f32 = 15.0;
    const ALTERNATE_ZONE: f32 = 900.0;
    const RED_ZONE: f32 = 300.0;
    let flush = MARKING_Z + 0.05;
    let mut k = 1;
    while k as f32 * CENTRE_PITCH < RUNWAY_LENGTH - CENTRE_PITCH {
        let y = k as f32 * CENTRE_PITCH;
        let to_go = RUNWAY_LENGTH - y;
        let color = if to_go < RED_ZONE || (to_go < ALTERNATE_ZONE && k % 2 == 1) { red } else { white };
        light(0.0, y, flush, color, 0.3);
        k += 1;
    }
    // Blue taxiway edge lights every 60 m.
    const TAXI_LIGHTS: usize = 34;
    const TAXI_PITCH: f32 = 60.0;
    for i in 0..TAXI_LIGHTS {
        let y = 10.0 + TAXI_PITCH * i as f32;
        light(TAXIWAY_X - TAXIWAY_HALF_WIDTH - 1.0, y, LOW, blue, 0.3);
        light(TAXIWAY_X + TAXIWAY_HALF_WIDTH + 1.0, y, LOW, blue, 0.3);
    }
    // PAPI left of the runway abeam the aiming point: on the glide slope, the two
    // inner units show red, the two outer white (colours fixed here).
    const PAPI_FIRST: f32 = 15.0;
    const PAPI_PITCH: f32 = 9.0;
    for k in 0..4 {
        let color = if k < 2 { red } else { white };
        light(-RUNWAY_HALF_WIDTH - PAPI_FIRST - PAPI_PITCH * k as f32, AIM_POINT, POLE, color, 0.8);
    }
}

/// `default`: an airfield seen on a 3-degree approach from 500 m before the threshold.
fn airfield() -> Scene {
    let mut s = Scene::empty("default");
    let grass =
        ground_material(&mut s, "grass", "grass", 25.0, Vec3::new(0.36, 0.58, 0.22), Vec3::new(0.22, 0.40, 0.13));
    let asphalt =
        ground_material(&mut s, "asphalt", "asphalt", 8.0, Vec3::new(0.27, 0.27, 0.29), Vec3::new(0.15, 0.15, 0.17));
    let concrete =
        ground_material(&mut s, "concrete", "concrete", 10.0, Vec3::new(0.62, 0.62, 0.58), Vec3::new(0.48, 0.48, 0.45));
    let white = s.material("marking white", Vec3::new(0.95, 0.95, 0.95));
    let yellow = s.material("marking yellow", Vec3::new(0.9, 0.75, 0.1));
    for m in [white, yellow] {
        s.materials[m as usize].emissive = true;
    }
    let walls = s.material("hangar walls", Vec3::new(0.72, 0.76, 0.80));
    let roof = s.material("hangar roof", Vec3::new(0.42, 0.52, 0.68));
    let door = s.material("hangar door", Vec3::new(0.35, 0.38, 0.42));
    let terminal = s.material("terminal", Vec3::new(0.82, 0.80, 0.74));
    let shaft = smooth_material(&mut s, "tower", Vec3::new(0.88, 0.87, 0.82));
    let slab = s.material("tower slab", Vec3::new(0.30, 0.30, 0.32));
    let glass = s.material("glass", Vec3::new(0.35, 0.55, 0.65));
    s.materials[glass as usize].transparency =
        Transparency::new(GLASS_TRANSPARENCY).expect("the glass code fits in 6 bits");
    let foliage = s.material("foliage", Vec3::new(0.12, 0.36, 0.12));
    let trunk = s.material("trunk", Vec3::new(0.40, 0.26, 0.12));
    let chassis = s.material("truck chassis", Vec3::new(0.15, 0.15, 0.15));
    let cab = s.material("truck cab", Vec3::new(0.80, 0.15, 0.10));
    let tank = smooth_material(&mut s, "truck tank", Vec3::new(0.80, 0.80, 0.82));
    let tyre = s.material("tyre", Vec3::new(0.05, 0.05, 0.05));

    // Terrain.
    let heights = sample_heights(TERRAIN_CELLS, TERRAIN_CELL, TERRAIN_CENTRE, rolling);
    let ground =
        shape(Canonical::Heightfield { nx: TERRAIN_CELLS, ny: TERRAIN_CELLS, cell: TERRAIN_CELL, heights }, grass);
    let ground = s.add_model(ground);
    s.place(ground, Mat4::from_translation(TERRAIN_CENTRE.extend(0.0)));

    let paved = s.add_model(pavement(asphalt, concrete, white, yellow));
    s.place(paved, Mat4::IDENTITY);

    // Four hangars east of the apron, doors facing west (local -y turned to -x),
    // alternately gabled and arched, 20 m apart.
    let gabled = s.add_model(hangar("hangar gabled", false, walls, roof, door));
    let arched = s.add_model(hangar("hangar arched", true, walls, roof, door));
    const HANGAR_SETBACK: f32 = 5.0;
    let hangar_x = APRON_HI_X + HANGAR_SETBACK + HANGAR[1] / 2.0;
    for (k, model) in [gabled, arched, gabled, arched].into_iter().enumerate() {
        let y = APRON_LO_Y + 40.0 + 60.0 * k as f32;
        s.place(model, Mat4::from_translation(Vec3::new(hangar_x, y, 0.0)) * Mat4::from_rotation_z(-FRAC_PI_2));
    }
    // Terminal north of the apron, tower south of it.
    let term = s.add_model(shape(Canonical::Box { size: [80.0, 18.0, 9.0] }, terminal));
    s.place(term, Mat4::from_translation(Vec3::new(300.0, APRON_HI_Y + 15.0, 0.0)));
    let twr = s.add_model(tower(shaft, slab, glass));
    s.place(twr, Mat4::from_translation(Vec3::new(260.0, 700.0, 0.0)));

    // Trees: three kinds, on jittered 40 m x 100 m lots west of the runway (a quarter
    // of the lots planted) and a copse behind the hangars.
    let kinds = [
        s.add_model(tree("tree small", 2.0, 2.2, 6.0, trunk, foliage)),
        s.add_model(tree("tree medium", 2.5, 2.8, 9.0, trunk, foliage)),
        s.add_model(tree("tree tall", 3.0, 3.4, 12.0, trunk, foliage)),
    ];
    let mut rng = Rng::new(0xA1BA_7205);
    const PLANTED: f32 = 0.25;
    const JITTER: f32 = 12.0;
    let plant = |s: &mut Scene, rng: &mut Rng, x: f32, y: f32| {
        let kind = kinds[rng.below(kinds.len())];
        let position = Vec3::new(x + rng.range(-JITTER, JITTER), y + rng.range(-JITTER, JITTER), 0.0);
        let scale = rng.range(0.8, 1.2);
        let turn = rng.range(0.0, TAU);
        s.place(
            kind,
            Mat4::from_translation(position) * Mat4::from_rotation_z(turn) * Mat4::from_scale(Vec3::splat(scale)),
        );
    };
    for row in 0..26 {
        for col in 0..7 {
            if rng.unit() < PLANTED {
                plant(&mut s, &mut rng, -400.0 + 40.0 * col as f32, -200.0 + 100.0 * row as f32);
            }
        }
    }
    for row in 0..4 {
        for col in 0..3 {
            plant(&mut s, &mut rng, 520.0 + 40.0 * col as f32, 760.0 + 40.0 * row as f32);
        }
    }

    // The fuel truck on the taxiway, 1 cm above it: the one moving model.
    let truck = s.add_model(fuel_truck(chassis, cab, tank, tyre));
    s.instances.push(Instance {
        model: truck,
        transform: Mat4::from_translation(Vec3::new(TAXIWAY_X, 500.0, PAVEMENT_Z + 0.01)),
        moving: true,
    });

    airfield_lights(&mut s);

    let height = RUNWAY_Z + (EYE_BEFORE_THRESHOLD + AIM_POINT) * GLIDE_SLOPE.to_radians().tan();
    s.eye = Eye {
        position: Vec3::new(0.0, -EYE_BEFORE_THRESHOLD, height),
        heading: 0.0,
        pitch: -GLIDE_SLOPE,
        roll: 0.0,
        fov: 60.0,
    };
    s.screen = Screen { width: 1024, height: 768 };
    s.env.sky = Vec3::new(0.52, 0.68, 0.90);
    // Sun behind the approaching aircraft, high in the south-west.
    s.env.sun = Vec3::new(-0.35, -0.55, 0.75).normalize();
    s.env.fog_color = Vec3::new(0.72, 0.76, 0.82);
    s.env.visibility = AIRFIELD_VISIBILITY;
    s
}

// ---------------------------------------------------------------------------------
// `rombm`: P1 fig. 4.

/// Number of rhombi in P1's ROMBM scene.
const RHOMBI: usize = 22;
/// The eye's height above the lowest rhombus.
const ROMBM_EYE_HEIGHT: f32 = 100.0;
/// Vertical spacing of the rhombi: the top one is 52.5 m up, 47.5 m from the eye.
const ROMBM_SPACING: f32 = 2.5;
/// Horizontal field of view of the `rombm` eye (and vertical: the screen is square).
const ROMBM_FOV: f32 = 60.0;

/// `rombm`: 22 horizontal rhombi stacked one above another, each covering most of the
/// square screen, seen straight down; `layers` picks which of them are built
/// (`rhombus`, the top one alone, costs the same per pixel with no depth complexity:
/// issue 6 compares the two).
fn rombm(name: &str, layers: std::ops::Range<usize>) -> Scene {
    let mut s = Scene::empty(name);
    let mut model = Model { name: name.into(), ..Model::default() };
    let half_tan = (ROMBM_FOV / 2.0).to_radians().tan();
    for k in layers {
        let material = s.material(&format!("rhombus {k:02}"), hsv(k as f32 / RHOMBI as f32, 0.65, 0.9));
        let z = ROMBM_SPACING * k as f32;
        // Half the screen's side at this depth; the half diagonals are 1.4 to 1.9
        // times it, so each rhombus covers well over half of the screen.
        let half_screen = (ROMBM_EYE_HEIGHT - z) * half_tan;
        let t = k as f32;
        let a = half_screen * (1.65 + 0.25 * (1.3 * t).sin());
        let b = half_screen * (1.65 + 0.25 * (0.7 * t + 1.0).cos());
        let turn = 0.37 * t;
        let centre = Vec2::new((0.9 * t).sin(), (1.7 * t).cos()) * (0.08 * half_screen);
        let (u, v) = (Vec2::from_angle(turn), Vec2::from_angle(turn + FRAC_PI_2));
        let corners = [u * a, v * b, -u * a, -v * b].map(|p| (centre + p).extend(z));
        polygon(&mut model, &corners, material);
    }
    let m = s.add_model(model);
    s.place(m, Mat4::IDENTITY);
    s.eye =
        Eye { position: Vec3::new(0.0, 0.0, ROMBM_EYE_HEIGHT), heading: 0.0, pitch: -90.0, roll: 0.0, fov: ROMBM_FOV };
    s.screen = Screen { width: 512, height: 512 };
    s
}

// ---------------------------------------------------------------------------------
// `terrain`: a 256 x 256 heightfield.

/// Cells along each side of the `terrain` heightfield (2 x 256^2 = 131072 triangles).
const HILL_CELLS: u32 = 256;
/// Cell size: the patch is 5.12 km square.
const HILL_CELL: f32 = 20.0;

/// `terrain`: hills on a 256 x 256-cell heightfield seen at a low angle from above
/// its south edge, coloured by height (meadow, scrub, rock, snow).
fn terrain() -> Scene {
    let mut s = Scene::empty("terrain");
    let half = HILL_CELLS as f32 * HILL_CELL / 2.0;
    let mut rng = Rng::new(0x7E22_A1E5);
    // Fourteen Gaussian hills: centre, width sigma (300..900 m), height (60..350 m).
    let hills: Vec<(Vec2, f32, f32)> = (0..14)
        .map(|_| {
            let centre = Vec2::new(rng.range(-half, half), rng.range(-half, half));
            (centre, rng.range(300.0, 900.0), rng.range(60.0, 350.0))
        })
        .collect();
    let height = |x: f32, y: f32| {
        let p = Vec2::new(x, y);
        let bumps: f32 =
            hills.iter().map(|&(c, sigma, h)| h * (-(p.distance_squared(c)) / (2.0 * sigma * sigma)).exp()).sum();
        bumps + 8.0 * (x / 170.0).sin() * (y / 230.0).sin()
    };
    let heights = sample_heights(HILL_CELLS, HILL_CELL, Vec2::ZERO, height);
    // Height bands (upper limits in metres) and their colours.
    let bands = [
        (60.0, smooth_material(&mut s, "meadow", Vec3::new(0.30, 0.55, 0.20))),
        (180.0, smooth_material(&mut s, "scrub", Vec3::new(0.47, 0.47, 0.26))),
        (320.0, smooth_material(&mut s, "rock", Vec3::new(0.55, 0.50, 0.45))),
        (f32::INFINITY, smooth_material(&mut s, "snow", Vec3::new(0.95, 0.95, 0.97))),
    ];
    let mut model =
        shape(Canonical::Heightfield { nx: HILL_CELLS, ny: HILL_CELLS, cell: HILL_CELL, heights }, bands[0].1);
    model.name = "hills".into();
    for f in &mut model.faces {
        let mean =
            f.vertices.iter().map(|&i| model.vertices[i as usize].position.z).sum::<f32>() / f.vertices.len() as f32;
        f.material = bands.iter().find(|(limit, _)| mean < *limit).map_or(bands[0].1, |b| b.1);
    }
    let m = s.add_model(model);
    s.place(m, Mat4::IDENTITY);
    // Eye 40 m outside the south edge, 300 m up, looking north 12 degrees down.
    s.eye = Eye { position: Vec3::new(0.0, -half - 40.0, 300.0), heading: 0.0, pitch: -12.0, roll: 0.0, fov: 60.0 };
    s.screen = Screen { width: 1024, height: 768 };
    s.env.visibility = 15_000.0;
    s
}

// ---------------------------------------------------------------------------------
// `city`: a few thousand boxes.

/// Lots along each side of the city (60 x 60 = 3600 buildings).
const CITY_LOTS: usize = 60;
/// Lot pitch in metres: a building of at most 30 m leaves a street of at least 10 m.
const LOT: f32 = 40.0;

/// `city`: 3600 box buildings of random footprint and height on a grid, a ground
/// plane, and the eye at 25 m just outside the south-west corner looking north-east
/// along the diagonal, so that many buildings lie behind one another.
fn city() -> Scene {
    let mut s = Scene::empty("city");
    let asphalt =
        ground_material(&mut s, "street", "asphalt", 8.0, Vec3::new(0.30, 0.30, 0.31), Vec3::new(0.20, 0.20, 0.21));
    let facades = [
        Vec3::new(0.75, 0.72, 0.65),
        Vec3::new(0.60, 0.62, 0.68),
        Vec3::new(0.70, 0.55, 0.45),
        Vec3::new(0.50, 0.55, 0.52),
        Vec3::new(0.82, 0.82, 0.80),
    ];
    // One unit box per facade colour, stretched by each instance's transform.
    let unit: Vec<u32> = facades
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let m = s.material(&format!("facade {k}"), c);
            let mut model = shape(Canonical::Box { size: [1.0; 3] }, m);
            model.name = format!("building {k}");
            s.add_model(model)
        })
        .collect();
    let extent = CITY_LOTS as f32 * LOT;
    // The ground reaches 1 km beyond the city on every side.
    const MARGIN: f32 = 1000.0;
    let mut ground = Model { name: "ground".into(), ..Model::default() };
    rect(&mut ground, Vec2::splat(-MARGIN), Vec2::splat(extent + MARGIN), 0.0, asphalt);
    let g = s.add_model(ground);
    s.place(g, Mat4::IDENTITY);
    let mut rng = Rng::new(0xC17E_5EED);
    const MIN_SIDE: f32 = 18.0;
    const MAX_SIDE: f32 = 30.0;
    const MIN_HEIGHT: f32 = 6.0;
    const EXTRA_HEIGHT: f32 = 90.0;
    for j in 0..CITY_LOTS {
        for i in 0..CITY_LOTS {
            let w = rng.range(MIN_SIDE, MAX_SIDE);
            let d = rng.range(MIN_SIDE, MAX_SIDE);
            // Cubed: mostly low buildings and a few towers up to 96 m.
            let h = MIN_HEIGHT + EXTRA_HEIGHT * rng.unit().powi(3);
            let x = LOT * i as f32 + LOT / 2.0 + rng.range(-1.0, 1.0) * (MAX_SIDE - w) / 2.0;
            let y = LOT * j as f32 + LOT / 2.0 + rng.range(-1.0, 1.0) * (MAX_SIDE - d) / 2.0;
            let model = unit[rng.below(unit.len())];
            s.place(model, Mat4::from_translation(Vec3::new(x, y, 0.0)) * Mat4::from_scale(Vec3::new(w, d, h)));
        }
    }
    // Above the south-west corner, looking along the diagonal over the roofs: the
    // rows of buildings hide one another far into the distance (deep depth
    // complexity).
    const EYE_BACK: f32 = -40.0;
    const EYE_HEIGHT: f32 = 110.0;
    s.eye =
        Eye { position: Vec3::new(EYE_BACK, EYE_BACK, EYE_HEIGHT), heading: 45.0, pitch: -14.0, roll: 0.0, fov: 60.0 };
    s.screen = Screen { width: 1024, height: 768 };
    s.env.visibility = 4000.0;
    s
}

// ---------------------------------------------------------------------------------
// `many`: a million small triangles facing the eye.

/// Number of triangles in `many`.
const MANY_TRIANGLES: usize = 1_000_000;
/// The screen `many` is sized for.
const MANY_SCREEN: Screen = Screen { width: 1920, height: 1080 };
/// Horizontal field of view of `many`.
const MANY_FOV: f32 = 60.0;
/// Depth range of the triangles, metres from the eye.
const MANY_NEAR: f32 = 10.0;
/// Far end of the depth range.
const MANY_FAR: f32 = 1000.0;
/// Triangle areas on the 1920 x 1080 screen, in pixels: a few to a few tens.
const MANY_AREA: (f32, f32) = (3.0, 40.0);
/// Colours in the palette the triangles pick from.
const MANY_COLORS: usize = 256;

/// `many`: a million equilateral triangles, each in a plane perpendicular to the
/// view direction (constant depth), at random depths and places wholly inside the
/// view frustum, counter-clockwise seen from the eye, in one model.
///
/// The eye is at the origin looking north (+y), so a triangle at depth `d` lies in
/// the plane y = d, and the screen's right and up are +x and +z.
fn many() -> Scene {
    let mut s = Scene::empty("many");
    let mut rng = Rng::new(0x3A4E_0001);
    let palette: Vec<u32> = (0..MANY_COLORS)
        .map(|k| {
            let color = hsv(rng.unit(), rng.range(0.4, 1.0), rng.range(0.55, 1.0));
            let m = s.material(&format!("colour {k}"), color);
            s.materials[m as usize].emissive = true;
            m
        })
        .collect();
    let tan_x = (MANY_FOV / 2.0).to_radians().tan();
    let tan_z = tan_x * MANY_SCREEN.height as f32 / MANY_SCREEN.width as f32;
    // One pixel's side at depth d is d * pixel_per_depth.
    let pixel_per_depth = 2.0 * tan_x / MANY_SCREEN.width as f32;
    // An equilateral triangle of circumradius R has area (3 sqrt 3 / 4) R^2.
    let area_per_r2 = 3.0 * 3f32.sqrt() / 4.0;
    let toward_eye = Vec3::NEG_Y;
    let third_turn = Vec2::from_angle(TAU / 3.0);
    let mut model = Model {
        name: "many".into(),
        vertices: Vec::with_capacity(3 * MANY_TRIANGLES),
        faces: Vec::with_capacity(MANY_TRIANGLES),
    };
    for _ in 0..MANY_TRIANGLES {
        let depth = rng.range(MANY_NEAR, MANY_FAR);
        let radius_px = (rng.range(MANY_AREA.0, MANY_AREA.1) / area_per_r2).sqrt();
        let radius = radius_px * pixel_per_depth * depth;
        // The centre keeps the whole triangle inside the frustum at this depth.
        let x = rng.range(-1.0, 1.0) * (depth * tan_x - radius);
        let z = rng.range(-1.0, 1.0) * (depth * tan_z - radius);
        let base = model.vertices.len() as u32;
        // Corners at increasing angle in the (x right, z up) screen plane:
        // counter-clockwise as the eye sees it, so the normal -y faces the eye.
        let mut corner = Vec2::from_angle(rng.range(0.0, TAU)) * radius;
        for _ in 0..3 {
            model.vertices.push(Vertex {
                position: Vec3::new(x + corner.x, depth, z + corner.y),
                normal: toward_eye,
                intensity: 1.0,
            });
            corner = third_turn.rotate(corner);
        }
        model.faces.push(Face { vertices: vec![base, base + 1, base + 2], material: palette[rng.below(MANY_COLORS)] });
    }
    let m = s.add_model(model);
    s.place(m, Mat4::IDENTITY);
    s.eye = Eye { position: Vec3::ZERO, heading: 0.0, pitch: 0.0, roll: 0.0, fov: MANY_FOV };
    s.screen = MANY_SCREEN;
    s
}
