//! Tests: the scene loaders (`db::load`). Every bad input is checked for the file
//! name, the line number and the field in its message; the line a message must name
//! is marked in the input with a `#<` comment. A proptest feeds mutated scene and OBJ
//! files and asserts only that the loaders answer, Ok or Err, without panicking.

use std::path::{Path, PathBuf};

use albatros::db::load::{load_obj, load_scene, parse_obj, parse_scene, LoadError};
use albatros::db::Scene;
use proptest::prelude::*;

const FILE: &str = "test.toml";

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

fn example_text() -> String {
    std::fs::read_to_string(scenes_dir().join("example.toml")).expect("scenes/example.toml")
}

/// A folder of its own for a test's files, removed when the test ends.
fn temp_dir(test: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("albatros-load-{test}-")).tempdir().expect("temp dir")
}

fn parse_in(text: &str, dir: &Path) -> Result<Scene, LoadError> {
    parse_scene(text, FILE, dir)
}

/// The 1-based line that carries the `#<` marker.
fn marked_line(text: &str) -> usize {
    text.lines().position(|l| l.contains("#<")).expect("input has a #< marker") + 1
}

/// Asserts that `text` fails with a message that starts `test.toml:LINE:` (LINE the
/// marked line) and contains every one of `needles`.
fn check_err_in(text: &str, dir: &Path, needles: &[&str]) -> String {
    let line = marked_line(text);
    let msg = match parse_in(text, dir) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    };
    let prefix = format!("{FILE}:{line}:");
    assert!(msg.starts_with(&prefix), "message {msg:?} does not start with {prefix:?}");
    for n in needles {
        assert!(msg.contains(n), "message {msg:?} lacks {n:?}");
    }
    msg
}

fn check_err(text: &str, needles: &[&str]) -> String {
    check_err_in(text, &scenes_dir(), needles)
}

/// A valid scene head: one material `m` and a triangle model `tri`; cases append to it.
const HEAD: &str = r#"
[[material]]
name = "m"
color = [0.5, 0.5, 0.5]

[[model]]
name = "tri"
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
faces = [{ v = [0, 1, 2], material = "m" }]
"#;

fn with_head(tail: &str) -> String {
    format!("{HEAD}{tail}")
}

#[test]
fn head_is_valid() {
    let scene = parse_in(&with_head("[[instance]]\nmodel = \"tri\"\n"), &scenes_dir()).expect("valid");
    assert_eq!(scene.models.len(), 1);
    assert_eq!(scene.instances.len(), 1);
    assert_eq!(scene.name, "test");
}

// --- the example ----------------------------------------------------------------

#[test]
fn example_scene_loads_and_validates() {
    let scene = load_scene(&scenes_dir().join("example.toml")).unwrap_or_else(|e| panic!("{e}"));
    scene.validate().expect("validates");
    assert_eq!(scene.name, "example");
    assert_eq!(scene.textures.len(), 3);
    assert_eq!(scene.materials.len(), 9);
    let names: Vec<&str> = scene.models.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["ground", "runway", "tower", "water_tower", "hangar", "aircraft"]);
    assert_eq!(scene.instances.len(), 7);
    assert_eq!(scene.instances.iter().filter(|i| i.moving).count(), 1);
    assert_eq!(scene.lights.len(), 31 + 31 + 3);
    assert_eq!((scene.screen.width, scene.screen.height), (640, 480));
    assert!((scene.env.sun.length() - 1.0).abs() < 1e-6, "sun is normalised");
    assert_eq!(scene.env.visibility, 6000.0);
    let glass = scene.materials.iter().find(|m| m.name == "glass").expect("glass");
    assert_eq!(glass.transparency.code(), 32);
    let runway = &scene.models[1];
    assert_eq!(runway.faces.len(), 3);
    assert_eq!(runway.faces[1].material, 2, "the marking material");
    assert_eq!(runway.vertices[4].intensity, 1.2);
}

#[test]
fn example_obj_keeps_polygons() {
    let model = load_obj(&scenes_dir().join("example.obj"), 7).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(model.name, "example");
    let arities: Vec<usize> = model.faces.iter().map(|f| f.vertices.len()).collect();
    assert_eq!(arities, [5, 5, 4, 4, 4, 4]);
    assert!(model.faces.iter().all(|f| f.material == 7));
    assert!(model.vertices.iter().all(|v| (v.normal.length() - 1.0).abs() < 1e-3), "normals from vn");
    albatros::db::validate_model(0, &model, 8).expect("valid");
}

#[test]
fn obj_without_normals_gets_face_normals() {
    let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    let model = parse_obj(obj, "q.obj", "q", 0).expect("valid");
    assert_eq!(model.faces.len(), 1);
    assert!(model.vertices.iter().all(|v| v.normal == glam::Vec3::Z));
}

// --- TOML-level errors: syntax, unknown keys, missing fields, types ------------

#[test]
fn syntax_error() {
    check_err("[screen]\nwidth = = 3 #<\n", &["width"]);
}

#[test]
fn unknown_key() {
    check_err(&with_head("[[material]]\nname = \"x\"\ncolr = [1, 0, 0] #<\n"), &["unknown field `colr`"]);
}

#[test]
fn unknown_table() {
    check_err("[[mode]] #<\nname = \"a\"\n", &["unknown field `mode`"]);
}

#[test]
fn unknown_key_in_face() {
    check_err(
        &with_head("[[model]]\nname = \"q\"\nvertices = [[0, 0, 0]]\nfaces = [{ v = [0], mat = \"m\" }] #<\n"),
        &["`mat`"],
    );
}

#[test]
fn unknown_key_in_canonical_part() {
    check_err(
        &with_head(
            r#"[[model]]
name = "q"
parts = [{ kind = "sphere", radius = 1, slices = 8, stacks = 4, slicez = 3, material = "m" }] #<
"#,
        ),
        &["model 'q' part 0", "slicez"],
    );
}

#[test]
fn missing_field() {
    check_err(&with_head("[[material]] #<\nname = \"x\"\n"), &["[[material]]", "missing field `color`"]);
}

#[test]
fn missing_field_in_instance() {
    check_err(&with_head("[[instance]] #<\nposition = [0, 0, 0]\n"), &["missing field `model`"]);
}

#[test]
fn wrong_type() {
    check_err(&with_head("[[instance]]\nmodel = \"tri\"\nheading = \"north\" #<\n"), &["heading", "invalid type"]);
}

#[test]
fn wrong_type_in_array() {
    check_err(&with_head("[[material]]\nname = \"x\"\ncolor = [1, 0, \"red\"] #<\n"), &["color", "invalid type"]);
}

#[test]
fn wrong_shading() {
    check_err(
        &with_head("[[material]]\nname = \"x\"\ncolor = [1, 0, 0]\nshading = \"phong\" #<\n"),
        &["shading", "phong"],
    );
}

#[test]
fn nan_coordinate() {
    let text = "[[model]]\nname = \"q\"\nvertices = [\n  [0, 0, 0],\n  [0, nan, 0], #<\n  [1, 1, 0],\n]\n";
    check_err(text, &["vertices", "nan"]);
}

#[test]
fn inf_coordinate() {
    check_err(&with_head("[[instance]]\nmodel = \"tri\"\nposition = [inf, 0, 0] #<\n"), &["position", "inf"]);
}

#[test]
fn too_large_for_f32() {
    check_err(&with_head("[[instance]]\nmodel = \"tri\"\nheading = 1e39 #<\n"), &["heading", "too large"]);
}

#[test]
fn nan_visibility() {
    check_err("[environment]\nvisibility = nan #<\n", &["visibility"]);
}

#[test]
fn infinite_visibility_means_no_fog() {
    let scene = parse_in(&with_head("[environment]\nvisibility = inf\n"), &scenes_dir()).expect("valid");
    assert_eq!(scene.env.visibility, f32::INFINITY);
}

// --- faces ----------------------------------------------------------------------

fn face_case(vertices: &str, face: &str) -> String {
    format!(
        r#"{HEAD}[[model]]
name = "q"
vertices = {vertices}
faces = [
  {{ v = [0, 1, 2], material = "m" }},
  {face} #<
]
"#
    )
}

#[test]
fn non_convex_face() {
    // An arrow head: vertex 3 is a reflex corner.
    let text = face_case(
        "[[0, 0, 0], [4, 0, 0], [4, 4, 0], [2, 1, 0], [0, 4, 0]]",
        "{ v = [0, 1, 2, 3, 4], material = \"m\" }",
    );
    check_err(&text, &["model 'q' face 1", "not convex"]);
}

#[test]
fn non_planar_face() {
    let text = face_case("[[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0]]", "{ v = [0, 1, 2, 3], material = \"m\" }");
    check_err(&text, &["model 'q' face 1", "not planar"]);
}

#[test]
fn zero_area_face() {
    let text = face_case("[[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]]", "{ v = [0, 1, 3], material = \"m\" }");
    check_err(&text, &["model 'q' face 1", "zero area"]);
}

#[test]
fn too_few_vertices() {
    let text = face_case("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "{ v = [0, 1], material = \"m\" }");
    check_err(&text, &["model 'q' face 1", "at least 3"]);
}

#[test]
fn vertex_index_out_of_range() {
    let text = face_case("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "{ v = [0, 1, 7], material = \"m\" }");
    check_err(&text, &["model 'q' face 1", "vertex index 7", "3 vertices"]);
}

#[test]
fn negative_vertex_index() {
    let text = face_case("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "{ v = [0, 1, -2], material = \"m\" }");
    check_err(&text, &["v", "-2"]);
}

#[test]
fn unknown_material() {
    let text = face_case("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "{ v = [0, 2, 1], material = \"steel\" }");
    check_err(&text, &["model 'q' face 1", "unknown material 'steel'", "materials are m"]);
}

#[test]
fn face_without_material() {
    let text = face_case("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "{ v = [0, 2, 1] }");
    check_err(&text, &["model 'q' face 1", "no material"]);
}

#[test]
fn normals_count_must_match() {
    check_err(
        &with_head(
            r#"[[model]]
name = "q"
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
normals = [[0, 0, 1]] #<
faces = [{ v = [0, 1, 2], material = "m" }]
"#,
        ),
        &["model 'q'", "normals has 1"],
    );
}

#[test]
fn model_needs_exactly_one_kind() {
    check_err(
        &with_head(
            r#"[[model]] #<
name = "q"
material = "m"
obj = "example.obj"
parts = [{ kind = "box", size = [1, 1, 1] }]
"#,
        ),
        &["model 'q'", "exactly one"],
    );
    check_err(&with_head("[[model]] #<\nname = \"q\"\nmaterial = \"m\"\n"), &["model 'q'", "exactly one"]);
}

#[test]
fn duplicate_model_name() {
    check_err(
        &with_head("[[model]]\nname = \"tri\" #<\nobj = \"example.obj\"\nmaterial = \"m\"\n"),
        &["model 'tri'", "already used", "line 7"],
    );
}

// --- materials and textures -----------------------------------------------------

#[test]
fn transparency_64() {
    check_err(
        &with_head("[[material]]\nname = \"x\"\ncolor = [1, 0, 0]\ntransparency = 64 #<\n"),
        &["material 'x'", "transparency = 64", "0..=63"],
    );
}

#[test]
fn transparency_63_is_fine() {
    let scene =
        parse_in(&with_head("[[material]]\nname = \"x\"\ncolor = [1, 0, 0]\ntransparency = 63\n"), &scenes_dir())
            .expect("valid");
    assert_eq!(scene.materials[1].transparency.code(), 63);
}

#[test]
fn color_out_of_range() {
    check_err(&with_head("[[material]]\nname = \"x\"\ncolor = [1, 0, 2] #<\n"), &["material 'x'", "color", "0..=1"]);
}

#[test]
fn texture_with_no_map() {
    let text = with_head(
        r#"[[texture]]
name = "g"
builtin = "grass"
[[material]]
name = "x"
color = [1, 0, 0]
[material.texture] #<
period = 10
color1 = [1, 1, 1]
color2 = [0, 0, 0]
"#,
    );
    check_err(&text, &["[material.texture]", "missing field `map`"]);
}

#[test]
fn texture_with_unknown_map() {
    let text = with_head(
        r#"[[material]]
name = "x"
color = [1, 0, 0]
[material.texture]
map = "moss" #<
period = 10
color1 = [1, 1, 1]
color2 = [0, 0, 0]
"#,
    );
    check_err(&text, &["material 'x'", "unknown texture 'moss'", "no texture is declared"]);
}

#[test]
fn texture_with_zero_period() {
    let text = with_head(
        r#"[[texture]]
name = "g"
builtin = "grass"
[[material]]
name = "x"
color = [1, 0, 0]
[material.texture]
map = "g"
period = 0 #<
color1 = [1, 1, 1]
color2 = [0, 0, 0]
"#,
    );
    check_err(&text, &["material 'x'", "texture.period"]);
}

#[test]
fn unknown_builtin_texture() {
    check_err("[[texture]]\nname = \"g\"\nbuiltin = \"moss\" #<\n", &["texture 'g'", "unknown builtin 'moss'"]);
}

#[test]
fn missing_texture_file() {
    check_err("[[texture]]\nname = \"g\"\nfile = \"nope.png\" #<\n", &["texture 'g'", "nope.png", "does not exist"]);
}

// --- OBJ models -----------------------------------------------------------------

fn obj_scene(file: &str) -> String {
    format!("{HEAD}[[model]]\nname = \"o\"\nmaterial = \"m\"\nobj = \"{file}\" #<\n")
}

#[test]
fn missing_obj() {
    check_err(&obj_scene("nope.obj"), &["model 'o' obj", "nope.obj", "cannot read"]);
}

#[test]
fn obj_needs_a_material() {
    check_err(&with_head("[[model]]\nname = \"o\"\nobj = \"example.obj\" #<\n"), &["model 'o'", "needs `material`"]);
}

#[test]
fn garbage_obj() {
    let dir = temp_dir("garbage_obj");
    std::fs::write(dir.path().join("garbage.obj"), [0xffu8, 0xfe, 0x00, 0x13, 0x80, 0x81, 0x0a, 0xc3]).expect("write");
    let msg = check_err_in(&obj_scene("garbage.obj"), dir.path(), &["model 'o' obj", "garbage.obj:1: ", "not text"]);
    assert!(msg.contains("garbage.obj"), "{msg}");
}

#[test]
fn text_obj_without_faces() {
    let dir = temp_dir("text_obj_without_faces");
    std::fs::write(dir.path().join("prose.obj"), "Dear reader,\nthis is not a mesh.\n").expect("write");
    check_err_in(&obj_scene("prose.obj"), dir.path(), &["prose.obj", "no faces"]);
}

#[test]
fn obj_with_bad_index() {
    let dir = temp_dir("obj_with_bad_index");
    std::fs::write(dir.path().join("bad.obj"), "# bad\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n").expect("write");
    check_err_in(&obj_scene("bad.obj"), dir.path(), &["bad.obj:6: ", "position index 9", "out of range"]);
}

#[test]
fn obj_with_zero_index() {
    let msg = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "z.obj", "z", 0).expect_err("index 0").to_string();
    assert!(msg.starts_with("z.obj:4: ") && msg.contains("index 0"), "{msg}");
}

#[test]
fn obj_with_bad_normal_index() {
    let msg = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//0\n", "n.obj", "n", 0)
        .expect_err("vn 0")
        .to_string();
    assert!(msg.starts_with("n.obj:5: ") && msg.contains("normal index 0"), "{msg}");
}

#[test]
fn obj_with_unparsable_vertex() {
    let msg = parse_obj(b"v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n", "p.obj", "p", 0).expect_err("bad v").to_string();
    assert!(msg.starts_with("p.obj:2: ") && msg.contains("cannot parse"), "{msg}");
}

#[test]
fn obj_with_nan_vertex() {
    let msg = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n", "n.obj", "n", 0).expect_err("nan").to_string();
    assert!(msg.starts_with("n.obj:3: ") && msg.contains("not a finite number"), "{msg}");
}

#[test]
fn obj_non_convex_polygon() {
    let obj = b"v 0 0 0\nv 4 0 0\nv 4 4 0\nv 2 1 0\nv 0 4 0\n# the arrow\ng arrow\nf 1 2 3\nf 1 2 3 4 5\n";
    let msg = parse_obj(obj, "arrow.obj", "arrow", 0).expect_err("non-convex").to_string();
    assert!(msg.starts_with("arrow.obj:9: face 1: is not convex"), "{msg}");
}

#[test]
fn obj_lines_are_skipped() {
    let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\nf 1 2 3\n";
    let model = parse_obj(obj, "l.obj", "l", 0).expect("valid");
    assert_eq!(model.faces.len(), 1);
}

// --- screen, eye, instances, lights ---------------------------------------------

#[test]
fn screen_size_zero() {
    check_err("[screen]\nwidth = 0 #<\nheight = 480\n", &["screen", "width = 0", "1..=8192"]);
}

#[test]
fn screen_size_100000() {
    check_err("[screen]\nwidth = 640\nheight = 100000 #<\n", &["screen", "height = 100000"]);
}

#[test]
fn negative_screen_size() {
    check_err("[screen]\nwidth = -640 #<\n", &["width", "-640"]);
}

#[test]
fn eye_fov_out_of_range() {
    check_err("[eye]\nfov = 180 #<\n", &["eye", "fov = 180"]);
}

#[test]
fn unknown_model_in_instance() {
    check_err(
        &with_head("[[instance]]\nmodel = \"hanger\" #<\n"),
        &["instance 0", "unknown model 'hanger'", "models are tri"],
    );
}

#[test]
fn zero_scale() {
    check_err(&with_head("[[instance]]\nmodel = \"tri\"\nscale = 0 #<\n"), &["instance 0", "scale"]);
}

#[test]
fn validate_errors_are_located() {
    // Positive but tiny: the loader accepts it, Scene::validate finds the transform
    // singular, and the error is placed at the instance.
    check_err(&with_head("[[instance]] #<\nmodel = \"tri\"\nscale = 1e-5\n"), &["instance 0", "singular"]);
}

#[test]
fn negative_axis_scale() {
    check_err(&with_head("[[instance]]\nmodel = \"tri\"\nscale = [1, -1, 1] #<\n"), &["instance 0", "scale"]);
}

#[test]
fn bad_scale_type() {
    check_err(
        &with_head("[[instance]]\nmodel = \"tri\"\nscale = \"big\" #<\n"),
        &["scale", "a number or an array of 3 numbers"],
    );
}

#[test]
fn light_size_zero() {
    check_err("[[light]]\nposition = [0, 0, 0]\ncolor = [1, 1, 1]\nsize = 0 #<\n", &["light 0", "size = 0"]);
}

#[test]
fn light_row_count_zero() {
    check_err(
        "[[light_row]]\nfrom = [0, 0, 0]\nto = [0, 100, 0]\ncolor = [1, 1, 1]\nsize = 0.3\ncount = 0 #<\n",
        &["light_row 0", "count = 0"],
    );
}

#[test]
fn light_row_spacing() {
    let scene = parse_in(
        "[[light_row]]\nfrom = [0, 0, 0]\nto = [0, 100, 0]\ncolor = [1, 1, 1]\nsize = 0.3\ncount = 5\n",
        &scenes_dir(),
    )
    .expect("valid");
    let ys: Vec<f32> = scene.lights.iter().map(|l| l.position.y).collect();
    assert_eq!(ys, [0.0, 25.0, 50.0, 75.0, 100.0]);
}

#[test]
fn placement_follows_the_eye_convention() {
    // Heading 90 turns the model's north (+Y) to the east (+X).
    let m = albatros::db::load::placement(glam::Vec3::ZERO, 90.0, 0.0, 0.0, glam::Vec3::ONE);
    assert!(m.transform_vector3(glam::Vec3::Y).abs_diff_eq(glam::Vec3::X, 1e-6));
    // Pitch up raises the nose; roll right lowers the right wing.
    let m = albatros::db::load::placement(glam::Vec3::ZERO, 0.0, 90.0, 0.0, glam::Vec3::ONE);
    assert!(m.transform_vector3(glam::Vec3::Y).abs_diff_eq(glam::Vec3::Z, 1e-6));
    let m = albatros::db::load::placement(glam::Vec3::ZERO, 0.0, 0.0, 90.0, glam::Vec3::ONE);
    assert!(m.transform_vector3(glam::Vec3::X).abs_diff_eq(-glam::Vec3::Z, 1e-6));
}

// --- canonical parts (need Canonical::build) -------------------------------------

#[test]
fn canonical_slices_1() {
    check_err(
        &with_head(
            r#"[[model]]
name = "ball"
parts = [
  { kind = "sphere", radius = 1, slices = 1, stacks = 4, material = "m" }, #<
]
"#,
        ),
        &["model 'ball' part 0", "slices"],
    );
}

#[test]
fn canonical_too_many_cells() {
    check_err(
        &with_head(
            r#"[[model]]
name = "ball"
material = "m"
parts = [{ kind = "sphere", radius = 1, slices = 100000, stacks = 100000 }] #<
"#,
        ),
        &["model 'ball' part 0", "resolution"],
    );
}

#[test]
fn canonical_nan_parameter() {
    check_err(
        &with_head(
            r#"[[model]]
name = "ball"
material = "m"
parts = [{ kind = "sphere", radius = nan, slices = 8, stacks = 4 }] #<
"#,
        ),
        &["model 'ball' part 0", "radius"],
    );
}

#[test]
fn canonical_unknown_kind() {
    check_err(
        &with_head("[[model]]\nname = \"q\"\nmaterial = \"m\"\nparts = [{ kind = \"pyramid\", size = 3 }] #<\n"),
        &["model 'q' part 0", "pyramid"],
    );
}

#[test]
fn canonical_box_part() {
    let scene = parse_in(
        &with_head(
            r#"[[model]]
name = "b"
material = "m"
parts = [{ kind = "box", size = [2, 2, 2], position = [0, 0, 1], heading = 30, scale = 2 }]
"#,
        ),
        &scenes_dir(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let b = &scene.models[1];
    assert_eq!(b.faces.len(), 6);
    let (lo, hi) =
        b.vertices.iter().fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v.position.z), hi.max(v.position.z)));
    assert!((lo - 1.0).abs() < 1e-5 && (hi - 5.0).abs() < 1e-5, "z from {lo} to {hi}");
}

// --- robustness -----------------------------------------------------------------

/// One edit of a file's text.
#[derive(Clone, Debug)]
enum Edit {
    Delete(usize, usize),
    Insert(usize, String),
    DuplicateLine(usize),
    SwapLines(usize, usize),
    /// Replace the k-th number (or run of digits) with another value: reaches the
    /// range checks that syntax-level edits rarely get past.
    Number(usize, &'static str),
    /// Replace the k-th quoted string: reaches name resolution and file lookup.
    Quoted(usize, &'static str),
}

fn edit() -> impl Strategy<Value = Edit> {
    let token = prop_oneof![
        prop::sample::select(vec![
            "nan",
            "inf",
            "-inf",
            "-",
            "0",
            "9",
            "99999999999",
            "1e39",
            "[",
            "]",
            "{",
            "}",
            "\"",
            "'",
            "=",
            ",",
            ".",
            "\n",
            "#",
            "\\",
            "x",
            "[[model]]\n",
            "[[instance]]\nmodel = \"tower\"\n",
            "\"\"\"",
            "kind = \"torus\"",
        ])
        .prop_map(str::to_string),
        "\\PC{0,6}",
    ];
    prop_oneof![
        // Value edits weigh more: most text edits stop at the TOML syntax check.
        1 => (any::<usize>(), 1..24usize).prop_map(|(at, n)| Edit::Delete(at, n)),
        1 => (any::<usize>(), token).prop_map(|(at, s)| Edit::Insert(at, s)),
        1 => any::<usize>().prop_map(Edit::DuplicateLine),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Edit::SwapLines(a, b)),
        4 => (any::<usize>(), prop::sample::select(NUMBERS)).prop_map(|(k, n)| Edit::Number(k, n)),
        2 => (any::<usize>(), prop::sample::select(QUOTED)).prop_map(|(k, q)| Edit::Quoted(k, q)),
    ]
}

const NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "3",
    "63",
    "64",
    "0.0001",
    "1e-30",
    "1e30",
    "1e39",
    "nan",
    "inf",
    "-inf",
    "8192",
    "100000",
    "4294967296",
    "-0.0",
];
const QUOTED: &[&str] = &[
    "\"\"",
    "\"grass\"",
    "\"tower\"",
    "\"nope\"",
    "\"example.obj\"",
    "\"example.toml\"",
    "\"box\"",
    "\"torus\"",
    "\"heightfield\"",
    "\"smooth\"",
    "\".\"",
    "\"m\\u00e9\"",
];

/// The byte ranges of the numbers (runs of digits, `.`, `e`, `-` starting with a
/// digit or `-`) or the quoted strings of a text.
fn tokens(s: &str, quoted: bool) -> Vec<std::ops::Range<usize>> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if quoted && b[i] == b'"' {
            let end = s[i + 1..].find('"').map_or(b.len(), |j| i + 2 + j);
            out.push(i..end);
            i = end;
        } else if !quoted && (b[i].is_ascii_digit() || (b[i] == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit))) {
            let start = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'e' | b'-')) {
                i += 1;
            }
            out.push(start..i);
        } else {
            i += 1;
        }
    }
    out
}

fn floor_boundary(s: &str, at: usize) -> usize {
    let mut at = at % (s.len() + 1);
    while !s.is_char_boundary(at) {
        at -= 1;
    }
    at
}

fn apply(text: &str, edits: &[Edit]) -> String {
    let mut s = text.to_string();
    for e in edits {
        match e {
            Edit::Delete(at, n) => {
                let a = floor_boundary(&s, *at);
                let b = floor_boundary(&s, (a + n).min(s.len()));
                s.replace_range(a..b.max(a), "");
            }
            Edit::Insert(at, t) => {
                let a = floor_boundary(&s, *at);
                s.insert_str(a, t);
            }
            Edit::DuplicateLine(k) => {
                let mut lines: Vec<&str> = s.lines().collect();
                if !lines.is_empty() {
                    let k = k % lines.len();
                    lines.insert(k, lines[k]);
                }
                s = lines.join("\n");
            }
            Edit::SwapLines(a, b) => {
                let mut lines: Vec<&str> = s.lines().collect();
                if !lines.is_empty() {
                    let n = lines.len();
                    lines.swap(a % n, b % n);
                }
                s = lines.join("\n");
            }
            Edit::Number(k, t) | Edit::Quoted(k, t) => {
                let found = tokens(&s, matches!(e, Edit::Quoted(..)));
                if !found.is_empty() {
                    let r = found[k % found.len()].clone();
                    s.replace_range(r, t);
                }
            }
        }
    }
    s
}

proptest! {
    #[test]
    fn mutated_scenes_never_panic(edits in prop::collection::vec(edit(), 1..6)) {
        let text = apply(&example_text(), &edits);
        let _ = parse_scene(&text, "mutant.toml", &scenes_dir());
    }

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,200}") {
        let _ = parse_scene(&text, "random.toml", &scenes_dir());
    }

    #[test]
    fn mutated_objs_never_panic(edits in prop::collection::vec(edit(), 1..6)) {
        let obj = std::fs::read_to_string(scenes_dir().join("example.obj")).expect("example.obj");
        let text = apply(&obj, &edits);
        let _ = parse_obj(text.as_bytes(), "mutant.obj", "mutant", 0);
    }

    #[test]
    fn arbitrary_bytes_as_obj_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = parse_obj(&bytes, "random.obj", "random", 0);
    }
}
