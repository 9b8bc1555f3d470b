//! Canonical objects (P5): triangulated box, sphere, cylinder, cone, torus and a
//! grid/heightfield terrain, with resolution parameters, and composite objects built
//! of them.
//!
//! Input: a [`Canonical`] shape description and a material index. Output: a [`Model`]
//! whose faces are convex planar polygons, counter-clockwise seen from outside, with
//! vertex normals set (smooth surfaces get the analytic normal, flat sides the face
//! normal). Every model built here passes [`crate::db::validate_model`].

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

use super::Model;

/// A canonical object with its resolution parameters. Dimensions in metres; the
/// object sits with its base centred on the origin of its model coordinates, Z up
/// (the sphere and torus are centred on the origin).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Canonical {
    /// An axis-aligned box of `size` (x, y, z), base on z = 0: six quads.
    Box {
        /// Extent along x, y, z.
        size: [f32; 3],
    },
    /// A sphere centred on the origin.
    Sphere {
        /// Radius.
        radius: f32,
        /// Segments around the axis (>= 3).
        slices: u32,
        /// Segments from pole to pole (>= 2).
        stacks: u32,
    },
    /// A closed cylinder along z from 0 to `height`.
    Cylinder {
        /// Radius.
        radius: f32,
        /// Height.
        height: f32,
        /// Segments around the axis (>= 3).
        segments: u32,
    },
    /// A closed cone along z, base radius `radius` at z = 0, apex at `height`.
    Cone {
        /// Base radius.
        radius: f32,
        /// Height of the apex.
        height: f32,
        /// Segments around the axis (>= 3).
        segments: u32,
    },
    /// A torus around the z axis.
    Torus {
        /// Distance from the axis to the tube's centre.
        major: f32,
        /// Tube radius.
        minor: f32,
        /// Segments around the axis (>= 3).
        major_segments: u32,
        /// Segments around the tube (>= 3).
        minor_segments: u32,
    },
    /// A terrain grid of `nx` x `ny` cells of `cell` metres, centred on the origin,
    /// heights at the `(nx + 1) (ny + 1)` grid points row by row (y outer), or all
    /// zero when `heights` is empty. Each cell is split into two triangles.
    Heightfield {
        /// Cells along x.
        nx: u32,
        /// Cells along y.
        ny: u32,
        /// Cell size in metres.
        cell: f32,
        /// Grid point heights, `(nx + 1) * (ny + 1)` of them, or empty for flat.
        #[serde(default)]
        heights: Vec<f32>,
    },
}

/// One part of a composite object: a canonical shape, where it goes, its material.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The shape.
    pub shape: Canonical,
    /// Part-to-model transform.
    pub transform: Mat4,
    /// Material index.
    pub material: u32,
}

/// Builds a composite model from parts (P5: "complex objects built from canonical
/// ones").
pub fn composite(name: &str, parts: &[Part]) -> Result<Model, String> {
    let mut model = Model { name: name.to_string(), ..Model::default() };
    for p in parts {
        let m = p.shape.build(p.material)?;
        model.append(&m, p.transform);
    }
    Ok(model)
}

impl Canonical {
    /// Triangulates the shape into a model with all faces in `material`.
    /// Errors name the parameter that is out of range.
    pub fn build(&self, material: u32) -> Result<Model, String> {
        let _ = (material, Vec3::ZERO);
        Err("canonical objects are not built yet".into())
    }
}
