//! Tests of the geometric processor and the BSP: exact priority order, area kept by
//! splitting, the frame list's invariants, the dump.

use albatros::db::bsp::{polygon_area, Bsp, BspFace, BspVertex, Piece, Plane, Visit};
use albatros::db::{builtin, Face, Instance, Material, Model, Scene, Screen, Vertex};
use albatros::frame::{FrameList, FramePolygon, PixelBox};
use albatros::gp::{self, Clipper, Database, GpConfig};
use glam::{DVec2, DVec3, Mat4, Vec3};
use proptest::prelude::*;

use crate::vp::Rng;

/// A random orthonormal-ish triangle inside the cube `[c - h, c + h]`.
fn triangle_in_cell(rng: &mut Rng, c: DVec3, h: f64) -> [DVec3; 3] {
    let p = |rng: &mut Rng| c + DVec3::new(rng.range(-h, h), rng.range(-h, h), rng.range(-h, h));
    loop {
        let t = [p(rng), p(rng), p(rng)];
        if (t[1] - t[0]).cross(t[2] - t[0]).length() > h * h * 0.2 {
            return t;
        }
    }
}

/// A scene of `n` random triangles, each in its own cell of a 3D grid in front of
/// the eye (so they never intersect), both sides visible (two faces each).
pub fn random_scene(seed: u64, n: usize, screen: Screen) -> Scene {
    let mut rng = Rng(seed);
    let mut scene = Scene::empty("random");
    scene.screen = screen;
    scene.eye.position = Vec3::ZERO;
    scene.eye.fov = 60.0;
    let mut model = Model { name: "tris".into(), ..Model::default() };
    let side = (n as f64).cbrt().ceil() as usize;
    let mut cells: Vec<(usize, usize, usize)> =
        (0..side.pow(3)).map(|k| (k % side, k / side % side, k / side / side)).collect();
    // Shuffle the cells so the order in the database says nothing.
    for i in (1..cells.len()).rev() {
        cells.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    for &(i, j, k) in cells.iter().take(n) {
        let cell = 4.0;
        // x across, y ahead (north), z up.
        let c = DVec3::new(
            (i as f64 - side as f64 / 2.0) * cell,
            10.0 + j as f64 * cell,
            (k as f64 - side as f64 / 2.0) * cell,
        );
        let t = triangle_in_cell(&mut rng, c, cell * 0.45);
        let m = scene.materials.len() as u32;
        scene.materials.push(Material::plain(&format!("m{m}"), Vec3::new(rng.range(0.1, 1.0) as f32, 0.5, 0.5)));
        let base = model.vertices.len() as u32;
        for p in t {
            model.vertices.push(Vertex::at(p.as_vec3()));
        }
        model.faces.push(Face { vertices: vec![base, base + 1, base + 2], material: m });
        model.faces.push(Face { vertices: vec![base, base + 2, base + 1], material: m });
    }
    model.fill_normals();
    let mi = scene.add_model(model);
    scene.instances.push(Instance { model: mi, transform: Mat4::IDENTITY, moving: false });
    scene
}

fn outline(frame: &FrameList, p: &FramePolygon) -> Vec<DVec2> {
    frame.vertices_of(p).iter().map(|v| DVec2::new(f64::from(v.x), f64::from(v.y))).collect()
}

/// The intersection of two convex polygons (any orientation).
fn intersect(a: &[DVec2], b: &[DVec2]) -> Vec<DVec2> {
    let orient = |p: &[DVec2]| (0..p.len()).map(|i| p[i].perp_dot(p[(i + 1) % p.len()])).sum::<f64>().signum();
    let sb = orient(b);
    let mut out = a.to_vec();
    for i in 0..b.len() {
        let (e0, e1) = (b[i], b[(i + 1) % b.len()]);
        let side = |p: DVec2| (e1 - e0).perp_dot(p - e0) * sb;
        let input = std::mem::take(&mut out);
        for k in 0..input.len() {
            let (p, q) = (input[k], input[(k + 1) % input.len()]);
            let (dp, dq) = (side(p), side(q));
            if dp >= 0.0 {
                out.push(p);
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                out.push(p + (q - p) * (dp / (dp - dq)));
            }
        }
        if out.is_empty() {
            break;
        }
    }
    out
}

fn area(p: &[DVec2]) -> f64 {
    (0..p.len()).map(|i| p[i].perp_dot(p[(i + 1) % p.len()])).sum::<f64>().abs() * 0.5
}

/// For every pair of polygons that overlap on the screen, the one nearer at the
/// centroid of the overlap comes first. Returns the number of overlapping pairs.
fn check_priority(frame: &FrameList) -> usize {
    let polys: Vec<Vec<DVec2>> = frame.polygons.iter().map(|p| outline(frame, p)).collect();
    let mut pairs = 0;
    for i in 0..polys.len() {
        for j in i + 1..polys.len() {
            let common = intersect(&polys[i], &polys[j]);
            if common.len() < 3 || area(&common) < 0.05 {
                continue;
            }
            pairs += 1;
            let c = common.iter().copied().sum::<DVec2>() / common.len() as f64;
            let (x, y) = (c.x as f32, c.y as f32);
            let zi = frame.polygons[i].inv_z.eval(x, y);
            let zj = frame.polygons[j].inv_z.eval(x, y);
            // 1/Z: larger is nearer. Allow f32 rounding where the two are equal.
            assert!(
                zi >= zj * (1.0 - 1e-4),
                "polygon {i} (1/Z {zi}) is behind polygon {j} (1/Z {zj}) at ({x}, {y}) but comes first"
            );
        }
    }
    pairs
}

#[test]
fn priority_is_exact_on_random_non_intersecting_scenes() {
    let screen = Screen { width: 320, height: 240 };
    let mut total = 0;
    for seed in 1..=20u64 {
        let scene = random_scene(seed, 120, screen);
        scene.validate().unwrap();
        let db = Database::new(scene);
        let (frame, c) = gp::frame_of_scene(&db, &GpConfig::default());
        assert!(c.polygons_out > 10);
        total += check_priority(&frame);
    }
    println!("overlapping pairs checked: {total}");
    assert!(total > 1000, "the scenes must overlap a lot to test anything");
}

#[test]
fn priority_holds_for_every_clipper_and_for_eyes_inside_the_scene() {
    let screen = Screen { width: 200, height: 150 };
    let mut rng = Rng(77);
    let scene = random_scene(99, 200, screen);
    let db = Database::new(scene);
    for clipper in [Clipper::Automaton, Clipper::AllBorders, Clipper::Reference] {
        for _ in 0..8 {
            let mut eye = db.scene.eye;
            eye.position =
                Vec3::new(rng.range(-10.0, 10.0) as f32, rng.range(0.0, 25.0) as f32, rng.range(-10.0, 10.0) as f32);
            eye.heading = rng.range(0.0, 360.0) as f32;
            eye.pitch = rng.range(-60.0, 60.0) as f32;
            eye.roll = rng.range(-30.0, 30.0) as f32;
            let mut counters = gp::GpCounters::default();
            let frame = gp::frame(&db, &eye, screen, &GpConfig { clipper, ..GpConfig::default() }, &mut counters);
            check_priority(&frame);
            // Every polygon is inside the window and convex.
            for p in &frame.polygons {
                let o = outline(&frame, p);
                assert!(o.len() >= 3);
                for v in &o {
                    assert!(v.x >= 0.0 && v.y >= 0.0 && v.x <= 200.0 && v.y <= 150.0, "{v} outside");
                }
                let n = o.len();
                let s: Vec<f64> =
                    (0..n).map(|k| (o[(k + 1) % n] - o[k]).perp_dot(o[(k + 2) % n] - o[(k + 1) % n])).collect();
                assert!(s.iter().all(|&t| t > 0.0) || s.iter().all(|&t| t < 0.0), "not strictly convex: {o:?}");
            }
        }
    }
}

fn face_of(points: &[DVec3], instance: u32, face: u32) -> BspFace {
    let vertices: Vec<BspVertex> =
        points.iter().map(|&p| BspVertex { position: p, normal: Vec3::Z, intensity: 1.0 }).collect();
    let n = (points[1] - points[0]).cross(points[2] - points[0]).normalize();
    BspFace { plane: Plane { normal: n, d: n.dot(points[0]) }, vertices, material: 0, instance, face }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Splitting keeps the total area of every face (intersecting input, so that
    /// faces are split a lot).
    #[test]
    fn bsp_splitting_keeps_every_face_area(seed in 1u64..u64::MAX, n in 2usize..120) {
        let mut rng = Rng(seed);
        let faces: Vec<BspFace> = (0..n)
            .map(|k| {
                let t = triangle_in_cell(&mut rng, DVec3::ZERO, 10.0);
                face_of(&t, 0, k as u32)
            })
            .collect();
        let before: Vec<f64> = faces.iter().map(|f| polygon_area(&f.vertices)).collect();
        let bsp = Bsp::build(faces);
        let mut after = vec![0.0; n];
        for f in &bsp.faces {
            after[f.face as usize] += polygon_area(&f.vertices);
        }
        for k in 0..n {
            prop_assert!((after[k] - before[k]).abs() <= 1e-9 * before[k].max(1.0), "face {k}: {} -> {}", before[k], after[k]);
        }
        // Every face is reachable exactly once by a traversal.
        let mut seen = vec![0u32; bsp.faces.len()];
        bsp.traverse(DVec3::new(3.0, -50.0, 2.0), |v| if let albatros::db::bsp::Visit::Face(f) = v { seen[f as usize] += 1 });
        prop_assert!(seen.iter().all(|&s| s == 1));
    }
}

#[test]
fn bsp_pieces_give_the_traversal_order_and_records_the_faces() {
    // The pieces of several GPs, each subtree traversed on its own, in the order
    // given: the whole traversal's order, for any cut size and eye.
    let mut rng = Rng(5);
    for seed in [3u64, 8, 21] {
        let db = Database::new(random_scene(seed, 300, Screen { width: 200, height: 150 }));
        let bsp = &db.bsp;
        assert_eq!(bsp.records.len(), bsp.faces.len());
        for (r, f) in bsp.records.iter().zip(&bsp.faces) {
            assert_eq!(bsp.record_vertices_of(r), &f.vertices[..]);
            assert_eq!((r.plane, r.material, r.instance, r.face), (f.plane, f.material, f.instance, f.face));
        }
        assert_eq!(bsp.subtree_faces(0) as usize, bsp.faces.len());
        for _ in 0..6 {
            let eye = DVec3::new(rng.range(-30.0, 30.0), rng.range(-20.0, 60.0), rng.range(-30.0, 30.0));
            let mut whole = Vec::new();
            bsp.traverse(eye, |v| whole.push(v));
            for max_faces in [0, 1, 2, 7, 40, 299, u32::MAX] {
                let mut cut = Vec::new();
                let mut subtrees = 0;
                bsp.pieces(eye, max_faces, |p| match p {
                    Piece::Visit(v) => cut.push(v),
                    Piece::Subtree(n) => {
                        assert!(n != 0 && bsp.subtree_faces(n) <= max_faces);
                        subtrees += 1;
                        bsp.traverse_subtree(n, eye, |v| cut.push(v));
                    }
                });
                assert!(cut == whole, "seed {seed}, eye {eye}, cut at {max_faces} faces");
                assert!(max_faces < 2 || subtrees > 0);
                let faces = whole.iter().filter(|v| matches!(v, Visit::Face(_))).count();
                assert_eq!(faces, bsp.faces.len());
            }
        }
    }
    // No tree: one place for the guests.
    let empty = Bsp::build(Vec::new());
    let mut pieces = Vec::new();
    empty.pieces(DVec3::ZERO, 4, |p| pieces.push(p));
    assert_eq!(pieces, [Piece::Visit(Visit::Guests(albatros::db::bsp::NONE, albatros::db::bsp::Slot::Straddle))]);
}

#[test]
fn moving_models_are_ordered_as_wholes() {
    // A box (moving) between two walls: it must come after the near wall and before
    // the far one.
    let mut scene = Scene::empty("moving");
    scene.screen = Screen { width: 160, height: 120 };
    scene.eye.position = Vec3::ZERO;
    let grey = scene.material("grey", Vec3::splat(0.5));
    let red = scene.material("red", Vec3::new(1.0, 0.0, 0.0));
    let wall = |y: f32, w: f32| Model {
        name: format!("wall{y}"),
        vertices: [(-w, -w), (w, -w), (w, w), (-w, w)].iter().map(|&(x, z)| Vertex::at(Vec3::new(x, y, z))).collect(),
        // Counter-clockwise seen from the eye (south of the walls).
        faces: vec![Face { vertices: vec![0, 1, 2, 3], material: grey }],
    };
    let near = scene.add_model(wall(10.0, 1.0));
    let far = scene.add_model(wall(40.0, 30.0));
    let boxm = albatros::db::canonical::Canonical::Box { size: [2.0, 2.0, 2.0] }.build(red).unwrap();
    let bm = scene.add_model(boxm);
    scene.place(near, Mat4::IDENTITY);
    scene.place(far, Mat4::IDENTITY);
    scene.instances.push(Instance {
        model: bm,
        transform: Mat4::from_translation(Vec3::new(0.5, 20.0, -1.0)),
        moving: true,
    });
    scene.validate().unwrap();
    let db = Database::new(scene);
    let (frame, _) = gp::frame_of_scene(&db, &GpConfig::default());
    let order: Vec<u32> = frame.polygons.iter().map(|p| p.source.0).collect();
    let first = |inst: u32| order.iter().position(|&i| i == inst).unwrap();
    let last = |inst: u32| order.iter().rposition(|&i| i == inst).unwrap();
    assert!(first(0) < first(2) && last(2) < first(1), "order by instance: {order:?}");
    check_priority(&frame);
}

#[test]
fn builtin_scenes_make_frame_lists() {
    for name in ["default", "rombm", "terrain", "city"] {
        let scene = builtin::scene(name).unwrap();
        let db = Database::new(scene);
        let (frame, c) = gp::frame_of_scene(&db, &GpConfig::default());
        println!("{name}: {} polygons, counters {c:?}", frame.polygons.len());
        assert!(!frame.polygons.is_empty());
        assert_eq!(c.polygons_out as usize, frame.polygons.len());
        assert_eq!(c.faces_in, c.backfacing + c.outside + c.face_class.iter().sum::<u64>());
        // Each polygon's box, made by the GP's set-up (from a triangle's lanes),
        // is the box of its vertices: the VP reads it in their stead.
        assert_eq!(frame.boxes.len(), frame.polygons.len(), "{name}");
        for (i, p) in frame.polygons.iter().enumerate() {
            let want = PixelBox::of(frame.vertices_of(p), frame.width, frame.height);
            assert_eq!(frame.boxes[i], want, "{name}: polygon {i}");
        }
    }
}

#[test]
fn rombm_is_in_exact_stacking_order() {
    let db = Database::new(builtin::scene("rombm").unwrap());
    let (frame, _) = gp::frame_of_scene(&db, &GpConfig::default());
    assert_eq!(frame.polygons.len(), 22);
    let pairs = check_priority(&frame);
    assert!(pairs >= 200, "22 stacked rhombi overlap pairwise: {pairs}");
}

#[test]
fn dump_lists_polygons_in_priority_order() {
    let db = Database::new(builtin::scene("rombm").unwrap());
    let (frame, _) = gp::frame_of_scene(&db, &GpConfig::default());
    let dump = serde_json::to_value(albatros::frame::dump::FrameDump::new(&frame)).unwrap();
    assert_eq!(dump["width"], 512);
    let polys = dump["polygons"].as_array().unwrap();
    assert_eq!(polys.len(), 22);
    for (k, p) in polys.iter().enumerate() {
        assert_eq!(p["priority"], k);
        assert!(p["vertices"].as_array().unwrap().len() >= 3);
        for key in ["color", "material", "inv_z", "intensity"] {
            assert!(!p[key].is_null(), "{key}");
        }
    }
}

#[test]
fn several_geometry_processors_give_the_same_frame_list() {
    for name in ["default", "terrain", "city"] {
        let db = Database::new(builtin::scene(name).unwrap());
        let mut c1 = gp::GpCounters::default();
        let mut c3 = gp::GpCounters::default();
        let one = gp::frame(&db, &db.scene.eye, db.scene.screen, &GpConfig::default(), &mut c1);
        let three =
            gp::frame(&db, &db.scene.eye, db.scene.screen, &GpConfig { threads: 3, ..GpConfig::default() }, &mut c3);
        assert!(one == three, "{name}: the frame list depends on the number of GPs");
        assert_eq!(c1, c3, "{name}: counters");
    }
}

#[test]
fn a_reused_frame_memory_gives_the_same_frame_lists_as_fresh_ones() {
    // Frames from several eyes with one GpMemory and one output list (as the bench and
    // the pipeline reuse them): each must equal a fresh frame, on one and two GPs.
    for name in ["default", "terrain"] {
        let db = Database::new(builtin::scene(name).unwrap());
        let screen = db.scene.screen;
        let eyes: Vec<_> = [0.0, 40.0, -25.0, 0.0]
            .iter()
            .map(|&dh| {
                let mut eye = db.scene.eye;
                eye.heading += dh;
                eye.position.y += dh.abs() * 0.5;
                eye
            })
            .collect();
        for threads in [1, 2] {
            let config = GpConfig { threads, ..GpConfig::default() };
            let (mut memory, mut list) = (gp::GpMemory::default(), FrameList::default());
            for (k, eye) in eyes.iter().enumerate() {
                let (mut c_reused, mut c_fresh) = (gp::GpCounters::default(), gp::GpCounters::default());
                gp::frame_into(&db, eye, screen, &config, &mut c_reused, &mut memory, &mut list);
                let fresh = gp::frame(&db, eye, screen, &config, &mut c_fresh);
                assert!(list == fresh, "{name}, {threads} GPs, eye {k}: a reused memory changes the frame list");
                assert_eq!(c_reused, c_fresh, "{name}, {threads} GPs, eye {k}: counters");
                // On the matrix's threads (the GPs then run in its pool, not their own).
                let matrix = albatros::matrix::Matrix::for_threads(64, 64, Default::default(), threads).unwrap();
                let mut in_pool = FrameList::default();
                let mut c_pool = gp::GpCounters::default();
                matrix.install(|| {
                    gp::frame_into(&db, eye, screen, &config, &mut c_pool, &mut gp::GpMemory::default(), &mut in_pool)
                });
                assert!(in_pool == fresh, "{name}, {threads} GPs on the matrix's threads, eye {k}");
                assert_eq!(c_pool, c_fresh);
            }
        }
    }
}
