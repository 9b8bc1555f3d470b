//! Canonical objects (P5): triangulated box, sphere, cylinder, cone, torus and a
//! grid/heightfield terrain, with resolution parameters, and composite objects built
//! of them.
//!
//! Input: a [`Canonical`] shape description and a material index. Output: a [`Model`]
//! whose faces are convex planar polygons, counter-clockwise seen from outside, with
//! vertex normals set (smooth surfaces get the analytic normal, flat sides the face
//! normal). Every model built here passes [`crate::db::validate_model`].

use std::f64::consts::{PI, TAU};

use glam::{DVec3, Mat4};
use serde::{Deserialize, Serialize};

use super::{check_convex_planar, Face, Model, Vertex};

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

/// The most segments a round shape may have around (or along) one direction. A
/// 4096 x 4096 sphere is already 16.8 million faces; more is a mistake, not a model.
pub const MAX_SEGMENTS: u32 = 4096;
/// The most heightfield cells along one side (4096 x 4096 cells, 33.5 million
/// triangles, is the largest terrain patch accepted).
pub const MAX_CELLS: u32 = 4096;
/// The smallest dimension accepted, in metres (1 mm: below anything a visual
/// simulation draws, and far above where `f32` areas of the faces would underflow).
pub const MIN_DIMENSION: f32 = 1e-3;
/// The largest dimension (and heightfield height) accepted, in metres (1000 km).
pub const MAX_DIMENSION: f32 = 1e6;
/// The steepest rise between neighbouring heightfield points, in height per cell
/// size. At 1000:1 the thinnest triangle still has an area of about 1e-7 of its
/// squared size, well above [`crate::db::MIN_FACE_AREA_RATIO`].
pub const MAX_SLOPE: f32 = 1000.0;
/// The thinnest torus accepted: `minor / major` at least this. Thinner tubes lose
/// their cross-section to `f32` rounding of the positions on the large ring.
pub const MIN_TORUS_RATIO: f32 = 1e-3;

impl Canonical {
    /// Triangulates the shape into a model with all faces in `material`.
    ///
    /// Faces are counter-clockwise seen from outside. The box, the cylinder's caps and
    /// the cone's base have their own vertices with the face normal (flat sides); the
    /// sphere, the torus, the cylinder's side, the cone's side and the heightfield share
    /// vertices whose normal is the surface's own (analytic, or from central
    /// differences of the heights). Positions are computed in `f64` and rounded once,
    /// so that a point shared by two faces has bit-identical coordinates in both.
    ///
    /// Errors name the parameter that is out of range, e.g.
    /// `sphere: slices = 2, must be >= 3`. A model returned `Ok` passes
    /// [`crate::db::validate_model`]: the faces are checked before returning, so that
    /// parameters that are each in range but together too extreme for `f32` geometry
    /// (a 1 mm thick, 1000 km long cylinder) give an error rather than bad faces.
    pub fn build(&self, material: u32) -> Result<Model, String> {
        let mut b = Builder::new(self.kind(), material);
        match self {
            Canonical::Box { size } => {
                let mut half = [0.0; 3];
                for (k, (&s, h)) in size.iter().zip(&mut half).enumerate() {
                    *h = dimension("box", &format!("size[{k}]"), s)? * 0.5;
                }
                b.cuboid(half);
            }
            &Canonical::Sphere { radius, slices, stacks } => {
                let r = dimension("sphere", "radius", radius)?;
                let slices = count("sphere", "slices", slices, 3, MAX_SEGMENTS)?;
                let stacks = count("sphere", "stacks", stacks, 2, MAX_SEGMENTS)?;
                b.sphere(r, slices, stacks);
            }
            &Canonical::Cylinder { radius, height, segments } => {
                let r = dimension("cylinder", "radius", radius)?;
                let h = dimension("cylinder", "height", height)?;
                let n = count("cylinder", "segments", segments, 3, MAX_SEGMENTS)?;
                b.cylinder(r, h, n);
            }
            &Canonical::Cone { radius, height, segments } => {
                let r = dimension("cone", "radius", radius)?;
                let h = dimension("cone", "height", height)?;
                let n = count("cone", "segments", segments, 3, MAX_SEGMENTS)?;
                b.cone(r, h, n);
            }
            &Canonical::Torus { major, minor, major_segments, minor_segments } => {
                let big = dimension("torus", "major", major)?;
                let small = dimension("torus", "minor", minor)?;
                if minor >= major {
                    return Err(format!(
                        "torus: minor = {minor}, must be < major = {major} (the tube would cross the axis)"
                    ));
                }
                if minor < major * MIN_TORUS_RATIO {
                    return Err(format!(
                        "torus: minor = {minor}, must be >= major * {MIN_TORUS_RATIO} = {}",
                        major * MIN_TORUS_RATIO
                    ));
                }
                let m = count("torus", "major_segments", major_segments, 3, MAX_SEGMENTS)?;
                let n = count("torus", "minor_segments", minor_segments, 3, MAX_SEGMENTS)?;
                b.torus(big, small, m, n);
            }
            Canonical::Heightfield { nx, ny, cell, heights } => {
                let nx = count("heightfield", "nx", *nx, 1, MAX_CELLS)?;
                let ny = count("heightfield", "ny", *ny, 1, MAX_CELLS)?;
                let cell = dimension("heightfield", "cell", *cell)?;
                let grid = Grid::new(nx, ny, cell, heights)?;
                b.heightfield(&grid);
            }
        }
        b.finish(self)
    }

    /// The shape's kind as written in scene files: `box`, `sphere`, `cylinder`, `cone`,
    /// `torus`, `heightfield`.
    pub fn kind(&self) -> &'static str {
        match self {
            Canonical::Box { .. } => "box",
            Canonical::Sphere { .. } => "sphere",
            Canonical::Cylinder { .. } => "cylinder",
            Canonical::Cone { .. } => "cone",
            Canonical::Torus { .. } => "torus",
            Canonical::Heightfield { .. } => "heightfield",
        }
    }

    /// The shape and its parameters for messages (the heights are left out).
    fn describe(&self) -> String {
        match self {
            Canonical::Box { size } => format!("box (size = {size:?})"),
            Canonical::Sphere { radius, slices, stacks } => {
                format!("sphere (radius = {radius}, slices = {slices}, stacks = {stacks})")
            }
            Canonical::Cylinder { radius, height, segments } => {
                format!("cylinder (radius = {radius}, height = {height}, segments = {segments})")
            }
            Canonical::Cone { radius, height, segments } => {
                format!("cone (radius = {radius}, height = {height}, segments = {segments})")
            }
            Canonical::Torus { major, minor, major_segments, minor_segments } => format!(
                "torus (major = {major}, minor = {minor}, major_segments = {major_segments}, \
                 minor_segments = {minor_segments})"
            ),
            Canonical::Heightfield { nx, ny, cell, .. } => {
                format!("heightfield (nx = {nx}, ny = {ny}, cell = {cell})")
            }
        }
    }
}

/// A size parameter, checked to be a finite number in
/// `MIN_DIMENSION..=MAX_DIMENSION`, widened to `f64` for the geometry.
fn dimension(shape: &str, name: &str, value: f32) -> Result<f64, String> {
    if value.is_finite() && (MIN_DIMENSION..=MAX_DIMENSION).contains(&value) {
        Ok(f64::from(value))
    } else {
        Err(format!("{shape}: {name} = {value}, must be a finite size in {MIN_DIMENSION}..={MAX_DIMENSION} m"))
    }
}

/// A resolution parameter, checked to be in `min..=max`.
fn count(shape: &str, name: &str, value: u32, min: u32, max: u32) -> Result<usize, String> {
    if value < min {
        Err(format!("{shape}: {name} = {value}, must be >= {min}"))
    } else if value > max {
        Err(format!("{shape}: {name} = {value}, must be <= {max}"))
    } else {
        Ok(value as usize)
    }
}

/// The angle of step `i` of `n` around a circle, in radians; `i = n` gives exactly
/// the angle of `i = 0`, so that a closed ring ends on its first point.
fn step_angle(i: usize, n: usize) -> f64 {
    TAU * (i % n) as f64 / n as f64
}

/// A checked heightfield: its size, cell and heights (all zero when none were given).
struct Grid<'a> {
    nx: usize,
    ny: usize,
    cell: f64,
    heights: &'a [f32],
}

impl<'a> Grid<'a> {
    fn new(nx: usize, ny: usize, cell: f64, heights: &'a [f32]) -> Result<Self, String> {
        let points = (nx + 1) * (ny + 1);
        if !heights.is_empty() && heights.len() != points {
            return Err(format!(
                "heightfield: heights has {} values, must have (nx + 1) * (ny + 1) = {points} \
                 (or none, for flat ground)",
                heights.len()
            ));
        }
        if let Some((k, h)) = heights.iter().enumerate().find(|(_, h)| !(h.is_finite() && h.abs() <= MAX_DIMENSION)) {
            return Err(format!("heightfield: heights[{k}] = {h}, must be a finite number within +-{MAX_DIMENSION} m"));
        }
        let grid = Self { nx, ny, cell, heights };
        let limit = f64::from(MAX_SLOPE) * cell;
        for j in 0..=ny {
            for i in 0..=nx {
                for (di, dj) in [(1, 0), (0, 1)] {
                    let (i2, j2) = (i + di, j + dj);
                    if i2 > nx || j2 > ny {
                        continue;
                    }
                    let rise = (grid.height(i2, j2) - grid.height(i, j)).abs();
                    if rise > limit {
                        return Err(format!(
                            "heightfield: heights[{}] and heights[{}] differ by {rise} m over one cell of {cell} m, \
                             a slope over {MAX_SLOPE}:1",
                            grid.index(i, j),
                            grid.index(i2, j2)
                        ));
                    }
                }
            }
        }
        Ok(grid)
    }

    /// The index of grid point `(i, j)`, row by row (y outer).
    fn index(&self, i: usize, j: usize) -> usize {
        j * (self.nx + 1) + i
    }

    /// The height at grid point `(i, j)`.
    fn height(&self, i: usize, j: usize) -> f64 {
        self.heights.get(self.index(i, j)).map_or(0.0, |&h| f64::from(h))
    }
}

/// Collects vertices and faces of one canonical object in one material.
struct Builder {
    model: Model,
    material: u32,
}

impl Builder {
    fn new(name: &str, material: u32) -> Self {
        Self { model: Model { name: name.to_string(), ..Model::default() }, material }
    }

    fn vertex(&mut self, position: DVec3, normal: DVec3) -> u32 {
        self.model.vertices.push(Vertex {
            position: position.as_vec3(),
            normal: normal.normalize_or_zero().as_vec3(),
            intensity: 1.0,
        });
        (self.model.vertices.len() - 1) as u32
    }

    fn face(&mut self, vertices: Vec<u32>) {
        self.model.faces.push(Face { vertices, material: self.material });
    }

    /// A flat face with vertices of its own that carry the face's normal.
    fn flat_face(&mut self, points: &[DVec3]) {
        let first = points[0];
        let normal = points.windows(2).fold(DVec3::ZERO, |n, w| n + (w[0] - first).cross(w[1] - first));
        let vertices = points.iter().map(|&p| self.vertex(p, normal)).collect();
        self.face(vertices);
    }

    /// Six quads; corner `k` has bit 0 for +x, bit 1 for +y, bit 2 for the top.
    fn cuboid(&mut self, half: [f64; 3]) {
        let corner = |k: usize| {
            let sign = |bit: usize| if k & bit != 0 { 1.0 } else { -1.0 };
            DVec3::new(sign(1) * half[0], sign(2) * half[1], if k & 4 != 0 { 2.0 * half[2] } else { 0.0 })
        };
        // Each quad counter-clockwise seen from outside: -x, +x, -y, +y, bottom, top.
        const QUADS: [[usize; 4]; 6] =
            [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
        for quad in QUADS {
            self.flat_face(&quad.map(corner));
        }
    }

    /// A vertex at each pole, `stacks - 1` rings of `slices` vertices between them;
    /// triangles at the poles, quads (isosceles trapezoids, hence planar) elsewhere.
    fn sphere(&mut self, r: f64, slices: usize, stacks: usize) {
        let north = self.vertex(DVec3::new(0.0, 0.0, r), DVec3::Z);
        for k in 1..stacks {
            let (sin_phi, cos_phi) = (PI * k as f64 / stacks as f64).sin_cos();
            for i in 0..slices {
                let (sin_t, cos_t) = step_angle(i, slices).sin_cos();
                let dir = DVec3::new(sin_phi * cos_t, sin_phi * sin_t, cos_phi);
                self.vertex(dir * r, dir);
            }
        }
        let south = self.vertex(DVec3::new(0.0, 0.0, -r), DVec3::NEG_Z);
        // Vertex of ring k (1 = next to the north pole) at step i.
        let ring = |k: usize, i: usize| (1 + (k - 1) * slices + i % slices) as u32;
        for i in 0..slices {
            self.face(vec![north, ring(1, i), ring(1, i + 1)]);
        }
        for k in 1..stacks - 1 {
            for i in 0..slices {
                self.face(vec![ring(k, i), ring(k + 1, i), ring(k + 1, i + 1), ring(k, i + 1)]);
            }
        }
        for i in 0..slices {
            self.face(vec![south, ring(stacks - 1, i + 1), ring(stacks - 1, i)]);
        }
    }

    /// Side quads with radial normals and two `n`-gon caps.
    fn cylinder(&mut self, r: f64, h: f64, n: usize) {
        let dirs: Vec<DVec3> = (0..n)
            .map(|i| {
                let (s, c) = step_angle(i, n).sin_cos();
                DVec3::new(c, s, 0.0)
            })
            .collect();
        let bottom: Vec<DVec3> = dirs.iter().map(|&d| d * r).collect();
        let top: Vec<DVec3> = bottom.iter().map(|&p| p + DVec3::new(0.0, 0.0, h)).collect();
        let first = self.model.vertices.len();
        for i in 0..n {
            self.vertex(bottom[i], dirs[i]);
            self.vertex(top[i], dirs[i]);
        }
        let low = |i: usize| (first + 2 * (i % n)) as u32;
        let high = |i: usize| low(i) + 1;
        for i in 0..n {
            self.face(vec![low(i), low(i + 1), high(i + 1), high(i)]);
        }
        self.flat_face(&top);
        let reversed: Vec<DVec3> = bottom.into_iter().rev().collect();
        self.flat_face(&reversed);
    }

    /// Side triangles with the cone's own normals (each triangle has its own apex
    /// vertex, with the normal halfway round its segment) and an `n`-gon base.
    fn cone(&mut self, r: f64, h: f64, n: usize) {
        let apex = DVec3::new(0.0, 0.0, h);
        // Outward normal of the side at angle t: perpendicular to the slant line.
        let side_normal = |t: f64| DVec3::new(h * t.cos(), h * t.sin(), r);
        let base: Vec<DVec3> = (0..n)
            .map(|i| {
                let (s, c) = step_angle(i, n).sin_cos();
                DVec3::new(r * c, r * s, 0.0)
            })
            .collect();
        let first = self.model.vertices.len() as u32;
        for (i, &p) in base.iter().enumerate() {
            self.vertex(p, side_normal(step_angle(i, n)));
        }
        for i in 0..n {
            let mid = TAU * (i as f64 + 0.5) / n as f64;
            let top = self.vertex(apex, side_normal(mid));
            self.face(vec![first + i as u32, first + ((i + 1) % n) as u32, top]);
        }
        let reversed: Vec<DVec3> = base.into_iter().rev().collect();
        self.flat_face(&reversed);
    }

    /// An `m` x `n` grid of quads, each an isosceles trapezoid (planar): its two
    /// edges around the axis are symmetric about the plane through the axis halfway
    /// between them.
    fn torus(&mut self, big: f64, small: f64, m: usize, n: usize) {
        let first = self.model.vertices.len();
        for i in 0..m {
            let (sin_u, cos_u) = step_angle(i, m).sin_cos();
            for j in 0..n {
                let (sin_v, cos_v) = step_angle(j, n).sin_cos();
                let normal = DVec3::new(cos_v * cos_u, cos_v * sin_u, sin_v);
                let centre = DVec3::new(big * cos_u, big * sin_u, 0.0);
                self.vertex(centre + normal * small, normal);
            }
        }
        let at = |i: usize, j: usize| (first + (i % m) * n + j % n) as u32;
        for i in 0..m {
            for j in 0..n {
                self.face(vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }

    /// Two triangles per cell, always split along the same diagonal, from grid point
    /// `(i, j)` to `(i + 1, j + 1)` (south-west to north-east), so that the surface
    /// does not depend on anything but the heights. Vertex normals from central
    /// differences of the heights (one-sided at the border).
    fn heightfield(&mut self, g: &Grid) {
        let (nx, ny, cell) = (g.nx, g.ny, g.cell);
        let first = self.model.vertices.len() as u32;
        for j in 0..=ny {
            for i in 0..=nx {
                let x = (i as f64 - nx as f64 / 2.0) * cell;
                let y = (j as f64 - ny as f64 / 2.0) * cell;
                let (i0, i1) = (i.saturating_sub(1), (i + 1).min(nx));
                let (j0, j1) = (j.saturating_sub(1), (j + 1).min(ny));
                let dx = (g.height(i1, j) - g.height(i0, j)) / ((i1 - i0) as f64 * cell);
                let dy = (g.height(i, j1) - g.height(i, j0)) / ((j1 - j0) as f64 * cell);
                self.vertex(DVec3::new(x, y, g.height(i, j)), DVec3::new(-dx, -dy, 1.0));
            }
        }
        let at = |i: usize, j: usize| first + g.index(i, j) as u32;
        for j in 0..ny {
            for i in 0..nx {
                self.face(vec![at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                self.face(vec![at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }

    /// Checks every face as [`crate::db::validate_model`] will, so that `build` never
    /// returns a model that fails it.
    fn finish(self, shape: &Canonical) -> Result<Model, String> {
        let mut points = Vec::new();
        for (fi, f) in self.model.faces.iter().enumerate() {
            points.clear();
            points.extend(f.vertices.iter().map(|&i| self.model.vertices[i as usize].position));
            check_convex_planar(&points).map_err(|problem| {
                format!(
                    "{}: face {fi} {problem}; the parameters together are too extreme for f32 geometry",
                    shape.describe()
                )
            })?;
        }
        Ok(self.model)
    }
}
