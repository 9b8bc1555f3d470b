//! Tests: canonical objects (P5) and the built-in scenes.
//!
//! Canonical objects: every model built passes `validate_model` (proptest over the
//! parameters), closed solids use every edge exactly twice, once in each direction,
//! faces face outwards, vertex normals agree with the faces, and areas and volumes
//! approach the analytic values at fine resolution; bad parameters give an error that
//! names them. Built-in scenes: valid, deterministic, and of the size each promises.

use std::collections::HashMap;
use std::f64::consts::PI;

use albatros::db::builtin::{self, NAMES};
use albatros::db::canonical::{composite, Canonical, Part, MAX_CELLS, MAX_SEGMENTS};
use albatros::db::{polygon_normal, validate_model, Face, Model, Scene};
use glam::{DVec3, Mat4, Vec3};
use proptest::prelude::*;

/// The material index the shapes are built with; `validate_model` gets one more.
const MATERIAL: u32 = 3;

fn build(shape: &Canonical) -> Model {
    let model = shape.build(MATERIAL).unwrap_or_else(|e| panic!("{shape:?}: {e}"));
    validate_model(0, &model, MATERIAL as usize + 1).unwrap_or_else(|e| panic!("{shape:?}: {e}"));
    assert!(model.faces.iter().all(|f| f.material == MATERIAL));
    model
}

fn points(m: &Model, f: &Face) -> Vec<DVec3> {
    f.vertices.iter().map(|&i| m.vertices[i as usize].position.as_dvec3()).collect()
}

/// Newell's normal (twice the area times the unit normal), in f64.
fn newell(m: &Model, f: &Face) -> DVec3 {
    polygon_normal(f.vertices.iter().map(|&i| m.vertices[i as usize].position)).as_dvec3()
}

fn centroid(m: &Model, f: &Face) -> DVec3 {
    let p = points(m, f);
    p.iter().sum::<DVec3>() / p.len() as f64
}

fn area(m: &Model) -> f64 {
    m.faces.iter().map(|f| newell(m, f).length() / 2.0).sum()
}

/// Volume by the divergence theorem: the sum over faces of (point . N) / 6.
fn volume(m: &Model) -> f64 {
    m.faces.iter().map(|f| points(m, f)[0].dot(newell(m, f)) / 6.0).sum()
}

/// A position's bits, with -0 folded into +0, to weld coincident vertices.
fn key(p: Vec3) -> [u32; 3] {
    (p + Vec3::ZERO).to_array().map(f32::to_bits)
}

/// Counts of directed edges between welded positions.
fn directed_edges(m: &Model) -> HashMap<([u32; 3], [u32; 3]), u32> {
    let mut edges = HashMap::new();
    for f in &m.faces {
        let n = f.vertices.len();
        for k in 0..n {
            let a = key(m.vertices[f.vertices[k] as usize].position);
            let b = key(m.vertices[f.vertices[(k + 1) % n] as usize].position);
            *edges.entry((a, b)).or_insert(0) += 1;
        }
    }
    edges
}

/// Every edge is used exactly twice, once in each direction.
fn assert_closed(m: &Model) {
    let edges = directed_edges(m);
    for (&(a, b), &count) in &edges {
        assert_eq!(count, 1, "{}: edge {a:?} -> {b:?} used {count} times in one direction", m.name);
        assert_eq!(edges.get(&(b, a)), Some(&1), "{}: edge {a:?} -> {b:?} has no twin", m.name);
    }
}

/// Each face's Newell normal points away from `centre`.
fn assert_outward(m: &Model, centre: DVec3) {
    for (fi, f) in m.faces.iter().enumerate() {
        let out = newell(m, f).dot(centroid(m, f) - centre);
        assert!(out > 0.0, "{}: face {fi} faces inwards ({out})", m.name);
    }
}

/// Vertex normals are unit length and on the front side of every face using them.
fn assert_normals_agree(m: &Model) {
    for v in &m.vertices {
        assert!((v.normal.length() - 1.0).abs() < 1e-5, "{}: normal {:?}", m.name, v.normal);
    }
    for (fi, f) in m.faces.iter().enumerate() {
        let n = newell(m, f);
        for &i in &f.vertices {
            let d = m.vertices[i as usize].normal.as_dvec3().dot(n);
            assert!(d > 0.0, "{}: face {fi} vertex {i} normal points behind the face", m.name);
        }
    }
}

fn assert_close(what: &str, got: f64, want: f64, rel: f64) {
    assert!((got - want).abs() <= rel * want.abs(), "{what}: got {got}, want {want} (relative tolerance {rel})");
}

/// A size from 1 cm to 100 m, log-uniform.
fn size() -> impl Strategy<Value = f32> {
    (-2.0f32..2.0).prop_map(|e| 10f32.powf(e))
}

fn segments(max: u32) -> impl Strategy<Value = u32> {
    3..=max
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn box_is_valid_closed_outward(x in size(), y in size(), z in size()) {
        let m = build(&Canonical::Box { size: [x, y, z] });
        prop_assert_eq!(m.faces.len(), 6);
        assert_closed(&m);
        assert_outward(&m, DVec3::new(0.0, 0.0, f64::from(z) / 2.0));
        assert_normals_agree(&m);
        assert_close("box volume", volume(&m), f64::from(x) * f64::from(y) * f64::from(z), 1e-5);
    }

    #[test]
    fn sphere_is_valid_closed_outward(r in size(), slices in segments(128), stacks in 2u32..128) {
        let m = build(&Canonical::Sphere { radius: r, slices, stacks });
        prop_assert_eq!(m.faces.len() as u32, slices * stacks);
        let triangles = m.faces.iter().filter(|f| f.vertices.len() == 3).count() as u32;
        prop_assert_eq!(triangles, 2 * slices, "triangles at the poles only");
        assert_closed(&m);
        assert_outward(&m, DVec3::ZERO);
        assert_normals_agree(&m);
        for v in &m.vertices {
            prop_assert!((v.normal - v.position / r).length() < 1e-4, "analytic normal");
        }
    }

    #[test]
    fn cylinder_is_valid_closed_outward(r in size(), h in size(), n in segments(300)) {
        let m = build(&Canonical::Cylinder { radius: r, height: h, segments: n });
        prop_assert_eq!(m.faces.len() as u32, n + 2);
        assert_closed(&m);
        assert_outward(&m, DVec3::new(0.0, 0.0, f64::from(h) / 2.0));
        assert_normals_agree(&m);
    }

    #[test]
    fn cone_is_valid_closed_outward(r in size(), h in size(), n in segments(300)) {
        let m = build(&Canonical::Cone { radius: r, height: h, segments: n });
        prop_assert_eq!(m.faces.len() as u32, n + 1);
        assert_closed(&m);
        // The centroid of a cone lies a quarter of the way up.
        assert_outward(&m, DVec3::new(0.0, 0.0, f64::from(h) / 4.0));
        assert_normals_agree(&m);
    }

    #[test]
    fn torus_is_valid_closed_outward(
        // 10 cm to 100 m, and a tube of at least 2% of that (so at least 2 mm).
        major in (-1.0f32..2.0).prop_map(|e| 10f32.powf(e)),
        ratio in 0.02f32..0.95,
        m_seg in segments(96),
        n_seg in segments(96)
    ) {
        let minor = major * ratio;
        let m = build(&Canonical::Torus { major, minor, major_segments: m_seg, minor_segments: n_seg });
        prop_assert_eq!(m.faces.len() as u32, m_seg * n_seg);
        assert_closed(&m);
        assert_normals_agree(&m);
        // Outward from the tube: away from the middle of the segment of the
        // (polygonal) centre line that the face surrounds.
        let step = std::f64::consts::TAU / f64::from(m_seg);
        for (fi, f) in m.faces.iter().enumerate() {
            let c = centroid(&m, f);
            let i = (c.y.atan2(c.x).rem_euclid(std::f64::consts::TAU) / step).floor();
            let ring = |k: f64| DVec3::new((k * step).cos(), (k * step).sin(), 0.0) * f64::from(major);
            let centre = (ring(i) + ring(i + 1.0)) / 2.0;
            prop_assert!(newell(&m, f).dot(c - centre) > 0.0, "face {} faces inwards", fi);
        }
    }

    #[test]
    fn heightfield_is_valid_and_faces_up(
        nx in 1u32..40, ny in 1u32..40, cell in size(), seed in any::<u64>(), relief in 0.0f32..5.0
    ) {
        let mut state = seed | 1;
        let heights: Vec<f32> = (0..(nx + 1) * (ny + 1))
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * relief * cell
            })
            .collect();
        let m = build(&Canonical::Heightfield { nx, ny, cell, heights });
        prop_assert_eq!(m.faces.len() as u32, 2 * nx * ny);
        for f in &m.faces {
            prop_assert!(newell(&m, f).z > 0.0, "faces up");
        }
        for v in &m.vertices {
            prop_assert!((v.normal.length() - 1.0).abs() < 1e-5 && v.normal.z > 0.0);
        }
        // An open sheet: inner edges twice (once each way), the border once.
        let edges = directed_edges(&m);
        let border = edges.keys().filter(|&&(a, b)| !edges.contains_key(&(b, a))).count() as u32;
        prop_assert_eq!(border, 2 * (nx + ny));
        prop_assert!(edges.values().all(|&c| c == 1));
    }
}

#[test]
fn fine_resolution_areas_and_volumes_match_analytic_values() {
    const TOL: f64 = 2e-3;
    let (r, h) = (2.0f64, 3.0f64);
    let sphere = build(&Canonical::Sphere { radius: r as f32, slices: 256, stacks: 128 });
    assert_close("sphere area", area(&sphere), 4.0 * PI * r * r, TOL);
    assert_close("sphere volume", volume(&sphere), 4.0 / 3.0 * PI * r.powi(3), TOL);

    let cyl = build(&Canonical::Cylinder { radius: r as f32, height: h as f32, segments: 512 });
    assert_close("cylinder area", area(&cyl), 2.0 * PI * r * h + 2.0 * PI * r * r, TOL);
    assert_close("cylinder volume", volume(&cyl), PI * r * r * h, TOL);

    let cone = build(&Canonical::Cone { radius: r as f32, height: h as f32, segments: 512 });
    assert_close("cone area", area(&cone), PI * r * (r + (r * r + h * h).sqrt()), TOL);
    assert_close("cone volume", volume(&cone), PI * r * r * h / 3.0, TOL);

    let (big, small) = (3.0f64, 1.0f64);
    let torus =
        build(&Canonical::Torus { major: big as f32, minor: small as f32, major_segments: 256, minor_segments: 128 });
    assert_close("torus area", area(&torus), 4.0 * PI * PI * big * small, TOL);
    assert_close("torus volume", volume(&torus), 2.0 * PI * PI * big * small * small, TOL);

    let bx = build(&Canonical::Box { size: [1.0, 2.0, 3.0] });
    assert_close("box area", area(&bx), 22.0, 1e-6);

    // A tilted plane z = a x + b y: exactly planar, area nx ny cell^2 sqrt(1 + a^2 + b^2).
    let (nx, ny, cell, a, b) = (30u32, 20u32, 0.5f32, 0.3f32, -0.2f32);
    let heights = (0..=ny).flat_map(|j| (0..=nx).map(move |i| a * i as f32 * cell + b * j as f32 * cell)).collect();
    let hf = build(&Canonical::Heightfield { nx, ny, cell, heights });
    let flat = f64::from(nx * ny) * f64::from(cell).powi(2);
    let tilt = (1.0 + f64::from(a).powi(2) + f64::from(b).powi(2)).sqrt();
    assert_close("heightfield area", area(&hf), flat * tilt, 1e-4);
}

#[test]
fn resolution_and_size_extremes_are_valid() {
    let max = MAX_SEGMENTS;
    for shape in [
        Canonical::Sphere { radius: 1.0, slices: max, stacks: 3 },
        Canonical::Sphere { radius: 1.0, slices: 3, stacks: max },
        Canonical::Sphere { radius: 0.001, slices: 64, stacks: 32 },
        Canonical::Sphere { radius: 1e6, slices: 64, stacks: 32 },
        Canonical::Cylinder { radius: 1.0, height: 1.0, segments: max },
        Canonical::Cylinder { radius: 0.01, height: 100.0, segments: 64 },
        Canonical::Cone { radius: 1.0, height: 1.0, segments: max },
        Canonical::Cone { radius: 100.0, height: 0.01, segments: 64 },
        Canonical::Torus { major: 1.0, minor: 0.5, major_segments: max, minor_segments: 3 },
        Canonical::Torus { major: 1.0, minor: 0.999, major_segments: 3, minor_segments: max },
        Canonical::Heightfield { nx: MAX_CELLS, ny: 1, cell: 1.0, heights: Vec::new() },
        Canonical::Box { size: [0.001, 1e6, 1.0] },
    ] {
        let m = build(&shape);
        if !matches!(shape, Canonical::Heightfield { .. }) {
            assert_closed(&m);
        }
    }
}

/// Builds `shape` and checks the error mentions `expected`.
fn check_error(shape: Canonical, expected: &str) {
    match shape.build(0) {
        Ok(_) => panic!("{shape:?} built, expected an error naming {expected:?}"),
        Err(e) => assert!(e.contains(expected), "{shape:?}: error {e:?} does not contain {expected:?}"),
    }
}

#[test]
fn bad_parameters_are_named() {
    check_error(Canonical::Sphere { radius: 1.0, slices: 2, stacks: 4 }, "sphere: slices = 2, must be >= 3");
    check_error(Canonical::Sphere { radius: 1.0, slices: 8, stacks: 1 }, "sphere: stacks = 1, must be >= 2");
    check_error(Canonical::Sphere { radius: f32::NAN, slices: 8, stacks: 4 }, "sphere: radius = NaN");
    check_error(
        Canonical::Sphere { radius: 1.0, slices: MAX_SEGMENTS + 1, stacks: 4 },
        "slices = 4097, must be <= 4096",
    );
    check_error(Canonical::Box { size: [1.0, 0.0, 1.0] }, "box: size[1] = 0");
    check_error(Canonical::Box { size: [1.0, 1.0, -2.0] }, "box: size[2] = -2");
    check_error(Canonical::Box { size: [f32::INFINITY, 1.0, 1.0] }, "box: size[0] = inf");
    check_error(Canonical::Cylinder { radius: 1.0, height: -1.0, segments: 8 }, "cylinder: height = -1");
    check_error(Canonical::Cylinder { radius: 1.0, height: 1.0, segments: 100_000 }, "cylinder: segments = 100000");
    check_error(Canonical::Cone { radius: 0.0, height: 1.0, segments: 8 }, "cone: radius = 0");
    check_error(Canonical::Cone { radius: 1.0, height: 1.0, segments: 0 }, "cone: segments = 0");
    check_error(Canonical::Torus { major: 1.0, minor: 1.0, major_segments: 8, minor_segments: 8 }, "torus: minor = 1");
    check_error(
        Canonical::Torus { major: 1.0, minor: 0.5, major_segments: 2, minor_segments: 8 },
        "major_segments = 2",
    );
    check_error(
        Canonical::Torus { major: 1.0, minor: 0.5, major_segments: 8, minor_segments: 2 },
        "minor_segments = 2",
    );
    check_error(Canonical::Heightfield { nx: 0, ny: 4, cell: 1.0, heights: vec![] }, "heightfield: nx = 0");
    check_error(
        Canonical::Heightfield { nx: 4, ny: MAX_CELLS + 1, cell: 1.0, heights: vec![] },
        "heightfield: ny = 4097",
    );
    check_error(Canonical::Heightfield { nx: 4, ny: 4, cell: 1.0, heights: vec![0.0; 24] }, "heights has 24 values");
    check_error(Canonical::Heightfield { nx: 1, ny: 1, cell: f32::NAN, heights: vec![] }, "heightfield: cell = NaN");
    check_error(
        Canonical::Heightfield { nx: 1, ny: 1, cell: 1.0, heights: vec![0.0, 0.0, f32::NAN, 0.0] },
        "heights[2] = NaN",
    );
    check_error(Canonical::Heightfield { nx: 1, ny: 1, cell: 1.0, heights: vec![0.0, 5000.0, 0.0, 0.0] }, "slope");
}

#[test]
fn composite_parts_keep_their_materials_and_stay_valid() {
    let parts = [
        Part {
            shape: Canonical::Cylinder { radius: 0.3, height: 2.0, segments: 8 },
            transform: Mat4::IDENTITY,
            material: 0,
        },
        Part {
            shape: Canonical::Cone { radius: 2.0, height: 6.0, segments: 8 },
            transform: Mat4::from_translation(Vec3::new(0.0, 0.0, 2.0)),
            material: 1,
        },
        Part {
            shape: Canonical::Sphere { radius: 1.0, slices: 8, stacks: 4 },
            transform: Mat4::from_scale_rotation_translation(
                Vec3::new(1.0, 2.0, 0.5),
                glam::Quat::from_rotation_x(0.7),
                Vec3::new(5.0, 0.0, 1.0),
            ),
            material: 1,
        },
    ];
    let m = composite("tree", &parts).unwrap();
    assert_eq!(m.name, "tree");
    assert_eq!(m.faces.len(), 10 + 9 + 32);
    validate_model(0, &m, 2).unwrap();
    assert_eq!(m.faces.iter().filter(|f| f.material == 0).count(), 10);
    let bad = [Part { shape: Canonical::Sphere { radius: 1.0, slices: 2, stacks: 2 }, ..parts[0].clone() }];
    assert!(composite("bad", &bad).unwrap_err().contains("slices"));
}

// ---------------------------------------------------------------------------------
// Built-in scenes.

fn builtin(name: &str) -> Scene {
    builtin::scene(name).unwrap_or_else(|| panic!("no built-in scene {name:?}"))
}

#[test]
fn builtin_scenes_are_valid_and_deterministic() {
    // `many` is checked on its own (it is large).
    for &name in NAMES.iter().filter(|&&n| n != "many") {
        let s = builtin(name);
        assert_eq!(s.name, name);
        s.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(s.instance_face_count() > 0, "{name} is empty");
        assert!(s == builtin(name), "{name} differs between two calls");
    }
    assert!(builtin::scene("no such scene").is_none());
}

#[test]
fn default_is_an_airfield_on_approach() {
    let s = builtin("default");
    assert_eq!((s.screen.width, s.screen.height), (1024, 768));
    assert_eq!(s.eye.fov, 60.0);
    // 400-600 m before the threshold (y = 0), 30-60 m up, looking down the runway.
    assert!((-600.0..=-400.0).contains(&s.eye.position.y), "{:?}", s.eye);
    assert!((30.0..=60.0).contains(&s.eye.position.z), "{:?}", s.eye);
    assert_eq!(s.eye.heading, 0.0);
    assert!((-6.0..0.0).contains(&s.eye.pitch));
    assert!((200..=600).contains(&s.lights.len()), "{} lights", s.lights.len());
    assert_eq!(s.instances.iter().filter(|i| i.moving).count(), 1);
    assert!((7000.0..=9000.0).contains(&s.env.visibility));
    for map in ["grass", "asphalt"] {
        assert!(s.textures.iter().any(|t| t.name == map), "no texture {map}");
    }
    assert!(s.materials.iter().any(|m| !m.transparency.is_opaque()), "no glass");
    let faces = s.instance_face_count();
    assert!((10_000..=100_000).contains(&faces), "{faces} faces");
    // Approach lights before the threshold.
    assert!(s.lights.iter().filter(|l| l.position.y < -10.0).count() >= 100);
}

#[test]
fn rombm_is_22_stacked_rhombi_seen_from_above() {
    let s = builtin("rombm");
    assert_eq!((s.screen.width, s.screen.height), (512, 512));
    assert_eq!(s.eye.pitch, -90.0);
    let eye = s.eye.position;
    let faces: Vec<Vec<Vec3>> = s
        .instances
        .iter()
        .flat_map(|inst| {
            let m = &s.models[inst.model as usize];
            m.faces.iter().map(move |f| {
                f.vertices.iter().map(|&i| inst.transform.transform_point3(m.vertices[i as usize].position)).collect()
            })
        })
        .collect();
    assert_eq!(faces.len(), 22);
    let mut heights: Vec<f32> = faces.iter().map(|f| f[0].z).collect();
    heights.sort_by(f32::total_cmp);
    heights.dedup();
    assert_eq!(heights.len(), 22, "all at different heights");
    // Samples of the screen on a 32 x 32 grid: each rhombus covers over 60% of them.
    const GRID: usize = 32;
    let half_tan = (s.eye.fov / 2.0).to_radians().tan();
    for (k, f) in faces.iter().enumerate() {
        assert_eq!(f.len(), 4);
        assert!(f.iter().all(|p| p.z == f[0].z), "rhombus {k} is not horizontal");
        assert!(f[0].z < eye.z);
        let n = polygon_normal(f.iter().copied());
        assert!(n.z > 0.0, "rhombus {k} faces away from the eye");
        let depth = eye.z - f[0].z;
        let mut inside = 0;
        for i in 0..GRID {
            for j in 0..GRID {
                let sx = ((i as f32 + 0.5) / GRID as f32 * 2.0 - 1.0) * depth * half_tan;
                let sy = ((j as f32 + 0.5) / GRID as f32 * 2.0 - 1.0) * depth * half_tan;
                let p = Vec3::new(eye.x + sx, eye.y + sy, f[0].z);
                if (0..4).all(|e| (f[(e + 1) % 4] - f[e]).cross(p - f[e]).z >= 0.0) {
                    inside += 1;
                }
            }
        }
        assert!(inside * 10 > GRID * GRID * 6, "rhombus {k} covers only {inside} of {} samples", GRID * GRID);
    }
}

#[test]
fn terrain_and_city_sizes() {
    let t = builtin("terrain");
    assert_eq!(t.instance_face_count(), 2 * 256 * 256);
    assert_eq!((t.screen.width, t.screen.height), (1024, 768));
    let c = builtin("city");
    let boxes = c.instances.iter().filter(|i| c.models[i.model as usize].faces.len() == 6).count();
    assert!((2000..=10_000).contains(&boxes), "{boxes} buildings");
    assert_eq!((c.screen.width, c.screen.height), (1024, 768));
    assert!(c.eye.position.z < 150.0, "low over the roofs, so the rows of buildings hide one another");
}

#[test]
fn many_is_a_million_triangles_facing_the_eye() {
    let s = builtin("many");
    s.validate().unwrap();
    let faces = s.instance_face_count();
    assert!((950_000..=1_050_000).contains(&faces), "{faces} faces");
    assert_eq!(s.models.len(), 1, "one model");
    assert_eq!((s.eye.heading, s.eye.pitch, s.eye.roll), (0.0, 0.0, 0.0));
    let m = &s.models[0];
    let eye = s.eye.position;
    let tan_x = (s.eye.fov / 2.0).to_radians().tan();
    let tan_z = tan_x * s.screen.height as f32 / s.screen.width as f32;
    let pixel = 2.0 * tan_x / s.screen.width as f32;
    for f in &m.faces {
        assert_eq!(f.vertices.len(), 3);
        let p: Vec<Vec3> = f.vertices.iter().map(|&i| m.vertices[i as usize].position).collect();
        // Perpendicular to the view direction (+y): constant depth.
        let depth = p[0].y - eye.y;
        assert!(p.iter().all(|q| q.y == p[0].y) && depth > 0.0);
        // Counter-clockwise from the eye.
        assert!(polygon_normal(p.iter().copied()).dot(eye - p[0]) > 0.0);
        // Inside the frustum.
        for q in &p {
            assert!(q.x.abs() <= depth * tan_x * 1.0001 && q.z.abs() <= depth * tan_z * 1.0001);
        }
        // A few to a few tens of pixels.
        let area_px = polygon_normal(p.iter().copied()).length() / 2.0 / (pixel * depth).powi(2);
        assert!((2.0..=50.0).contains(&area_px), "{area_px} pixels");
    }
    assert!(s == builtin("many"), "many differs between two calls");
}
