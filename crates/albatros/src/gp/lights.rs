//! Light points (P1 "огни"): the preprocessor turns each light into a small polygon
//! given by its edges, from then on an ordinary polygon in priority order.
//!
//! A light becomes a regular octagon facing the eye (in the plane of constant depth
//! through the light) whose world diameter is the light's size, but never less than
//! [`MIN_LIGHT_DIAMETER_PX`] on the screen, so that a far light never vanishes. Its
//! place in the priority order is given by the BSP like a tiny moving model: the GP
//! attaches it to the tree by its position.

use glam::{DMat4, DVec2, DVec3};

use super::clip::{clip_reference, Window};
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
    let eye: Vec<EyeVertex> = (0..LIGHT_SIDES)
        .map(|k| {
            let a = std::f64::consts::TAU * (k as f64 + 0.5) / LIGHT_SIDES as f64;
            // Counter-clockwise seen from the eye (y down on the screen).
            EyeVertex {
                position: c + DVec3::new(a.cos(), -a.sin(), 0.0) * radius,
                intensity: f64::from(light.intensity),
            }
        })
        .collect();
    let outline: Vec<DVec2> = eye.iter().map(|v| view.project(v.position)).collect();
    let win = Window { x0: 0.0, y0: 0.0, x1: f64::from(view.screen.width), y1: f64::from(view.screen.height) };
    clip_reference(&outline, &win, scratch);
    let plane = Plane { normal: DVec3::new(0.0, 0.0, -1.0), d: -c.z };
    let source = Source { kind: PrimitiveKind::Light, material: u32::MAX, ids: (li as u32, u32::MAX) };
    setup.add_face(source, None, light.color, &plane, &eye, scratch, &DMat4::IDENTITY, out)
}
