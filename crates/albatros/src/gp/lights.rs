//! Light points (P1 "огни"): the preprocessor turns each light into a small polygon
//! given by its edges, from then on an ordinary polygon in priority order.
//!
//! A light becomes a regular octagon facing the eye (in the plane of constant depth
//! through the light) whose world diameter is the light's size, but never less than
//! [`MIN_LIGHT_DIAMETER_PX`] on the screen, so that a far light never vanishes. Its
//! place in the priority order is given by the BSP like a tiny moving model: the GP
//! attaches it to the tree by its position.

use glam::{DMat4, DVec2, DVec3};

use super::clip::{clip_reference_unless_inside, Window};
use super::setup::{EyeVertex, Setup, Source};
use super::{View, NEAR};
use crate::db::bsp::Plane;
use crate::db::Scene;
use crate::frame::{FrameList, PrimitiveKind};

/// The smallest on-screen diameter of a light point, pixels.
pub const MIN_LIGHT_DIAMETER_PX: f64 = 2.0;
/// Sides of a light point's polygon.
pub const LIGHT_SIDES: usize = 8;

/// Appends light `li` to the frame list if it is in view; `false` if not.
pub fn add_light_point(
    scene: &Scene,
    li: usize,
    view: &View,
    setup: &mut Setup,
    out: &mut FrameList,
    scratch: &mut Vec<DVec2>,
) -> bool {
    let light = &scene.lights[li];
    let c = view.world_to_eye.transform_point3(light.position.as_dvec3());
    if c.z < NEAR * 2.0 {
        return false;
    }
    let radius = (f64::from(light.size) * 0.5).max(MIN_LIGHT_DIAMETER_PX * 0.5 * c.z / view.focal);
    let corners = octagon();
    let eye: [EyeVertex; LIGHT_SIDES] =
        std::array::from_fn(|k| EyeVertex { position: c + corners[k] * radius, intensity: f64::from(light.intensity) });
    let outline: [DVec2; LIGHT_SIDES] = std::array::from_fn(|k| view.project(eye[k].position));
    let win = Window { x0: 0.0, y0: 0.0, x1: f64::from(view.screen.width), y1: f64::from(view.screen.height) };
    clip_reference_unless_inside(&outline, &win, scratch);
    let plane = Plane { normal: DVec3::new(0.0, 0.0, -1.0), d: -c.z };
    let source = Source { kind: PrimitiveKind::Light, material: u32::MAX, ids: (li as u32, u32::MAX) };
    setup.add_face(source, None, light.color, &plane, &eye, scratch, &DMat4::IDENTITY, out)
}

/// The corners of a light point's octagon of radius 1 about its centre in the eye's
/// axes, counter-clockwise seen from the eye (y down on the screen): the same
/// `cos` and `sin` for every light, computed once (they were ~2.5 % of default's GP
/// as eight `sincos` calls a light).
fn octagon() -> &'static [DVec3; LIGHT_SIDES] {
    static CORNERS: std::sync::LazyLock<[DVec3; LIGHT_SIDES]> = std::sync::LazyLock::new(|| {
        std::array::from_fn(|k| {
            let a = std::f64::consts::TAU * (k as f64 + 0.5) / LIGHT_SIDES as f64;
            DVec3::new(a.cos(), -a.sin(), 0.0)
        })
    });
    &CORNERS
}
