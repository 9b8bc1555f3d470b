//! Wavefront OBJ meshes for the scene database (SYSTEM.md 2), read with `tobj`.
//!
//! Input: an OBJ file's bytes. Output: a [`Model`] whose faces are the file's
//! polygons as they are (not triangulated), every one checked convex and planar, or a
//! [`LoadError`] naming the file and the line of the statement at fault. `tobj`
//! reports neither lines nor, until a group ends, bad indices, and it overflows on
//! index 0, so `scan_obj` reads the statements first: it records the line of every
//! face (tobj keeps faces in file order) and rejects bad references with their line.
//! The invariant: no input makes this module panic.

use std::io::Cursor;
use std::path::Path;

use glam::Vec3;

use super::{LoadError, Location};
use crate::db::{check_convex_planar, Face, Model, Vertex};

/// Loads a Wavefront OBJ mesh as a model named after the file's stem, every face in
/// `material`. See [`parse_obj`] for what is accepted.
pub fn load_obj(path: &Path, material: u32) -> Result<Model, LoadError> {
    let shown = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|reason| LoadError::Io { path: shown.clone(), reason })?;
    let name = path.file_stem().map_or_else(|| shown.clone(), |s| s.to_string_lossy().into_owned());
    parse_obj(&bytes, &shown, &name, material)
}

/// Parses a Wavefront OBJ mesh from its bytes with `tobj`: positions and, when every
/// face vertex has one, normals (otherwise normals are averaged from the faces).
/// Polygons are kept as they are (not triangulated) and must be convex and planar;
/// texture coordinates, groups and `usemtl`/`mtllib` are ignored (the whole mesh is
/// in `material`), and so are line (`l`) and point (`p`) elements. Errors name
/// `path_for_messages` and the line of the statement at fault.
pub fn parse_obj(bytes: &[u8], path_for_messages: &str, name: &str, material: u32) -> Result<Model, LoadError> {
    let at_line = |line: Option<usize>| Location { file: path_for_messages.to_string(), line, column: None };
    let invalid = |line: Option<usize>, what: &str, problem: String| LoadError::Invalid {
        at: at_line(line),
        what: what.into(),
        problem,
    };
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        invalid(Some(line), "OBJ file", "is not text (invalid UTF-8): is it a Wavefront OBJ file?".into())
    })?;
    let scan = scan_obj(text).map_err(|(line, problem)| invalid(Some(line), "OBJ file", problem))?;

    let options = tobj::LoadOptions { single_index: true, triangulate: false, ..Default::default() };
    let mut reader = Cursor::new(scan.text.as_bytes());
    // MTL files are not read: the scene gives the material.
    let loaded = tobj::load_obj_buf(&mut reader, &options, |_| Err(tobj::LoadError::OpenFileFailed));
    let (meshes, _materials) = loaded.map_err(|e| {
        // tobj reads line by line and stops on the line it cannot parse: the reader's
        // position is just past that line.
        let end = usize::try_from(reader.position()).unwrap_or(usize::MAX).min(scan.text.len());
        let line = scan.text.as_bytes()[..end.saturating_sub(1)].iter().filter(|&&b| b == b'\n').count() + 1;
        invalid(Some(line), "OBJ file", format!("cannot parse this line ({e})"))
    })?;

    let mut model = Model { name: name.to_string(), ..Model::default() };
    let mut face_no = 0usize;
    for tobj::Model { mesh, .. } in &meshes {
        let base = model.vertices.len();
        let with_normals = mesh.normals.len() == mesh.positions.len();
        for (k, p) in mesh.positions.chunks_exact(3).enumerate() {
            let normal = if with_normals {
                Vec3::from_slice(&mesh.normals[3 * k..3 * k + 3]).normalize_or_zero()
            } else {
                Vec3::ZERO
            };
            model.vertices.push(Vertex { position: Vec3::from_slice(p), normal, intensity: 1.0 });
        }
        // tobj leaves `face_arities` empty when every face is a triangle.
        let arities: Vec<usize> = if mesh.face_arities.is_empty() {
            vec![3; mesh.indices.len() / 3]
        } else {
            mesh.face_arities.iter().map(|&a| a as usize).collect()
        };
        let mut next = 0usize;
        for arity in arities {
            let line = scan.face_lines.get(face_no).copied();
            let what = format!("face {face_no}");
            let Some(indices) = mesh.indices.get(next..next + arity) else {
                return Err(invalid(line, &what, "refers to vertices tobj did not return".into()));
            };
            next += arity;
            let mut vertices = Vec::with_capacity(arity);
            for &i in indices {
                let global = base + i as usize;
                if global >= model.vertices.len() {
                    return Err(invalid(line, &what, format!("vertex index {} is out of range", i as usize + 1)));
                }
                vertices.push(global as u32);
            }
            let pts: Vec<Vec3> = vertices.iter().map(|&i| model.vertices[i as usize].position).collect();
            if let Some(k) = pts.iter().position(|p| !p.is_finite()) {
                return Err(invalid(line, &what, format!("vertex {k} has a position that is not a finite number")));
            }
            check_convex_planar(&pts).map_err(|problem| invalid(line, &what, problem))?;
            model.faces.push(Face { vertices, material });
            face_no += 1;
        }
    }
    if model.faces.is_empty() {
        return Err(invalid(
            None,
            "OBJ file",
            "contains no faces (`f` statements): is it a Wavefront OBJ file?".into(),
        ));
    }
    model.fill_normals();
    Ok(model)
}

/// What [`scan_obj`] learns from an OBJ file before `tobj` reads it.
struct ObjScan<'a> {
    /// The 1-based line of every `f` statement, in order: `tobj` keeps faces in file
    /// order, so face k of the result comes from line `face_lines[k]`.
    face_lines: Vec<usize>,
    /// The text to give `tobj`: the file with `l` statements blanked (tobj would
    /// otherwise turn a polyline into a face), line numbering unchanged.
    text: std::borrow::Cow<'a, str>,
}

/// Reads an OBJ file's statements ahead of `tobj` to find the line of each face and
/// to reject, with that line, what `tobj` would only notice later without a line
/// (index out of range is found when a group ends) or would overflow on (index 0).
/// Returns `(line, problem)` on error.
fn scan_obj(text: &str) -> Result<ObjScan<'_>, (usize, String)> {
    // Counts of positions, texture coordinates and normals defined so far.
    let mut defined = [0i64; 3];
    let mut face_lines = Vec::new();
    let mut has_lines = false;
    for (n, line) in text.lines().enumerate() {
        let n = n + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some(kind @ ("v" | "vn")) => {
                let (slot, what) = if kind == "v" { (0, "vertex position") } else { (2, "normal") };
                defined[slot] += 1;
                // Unparsable numbers are left to tobj, which names the line too.
                if words.take(3).filter_map(|w| w.parse::<f32>().ok()).any(|v| !v.is_finite()) {
                    return Err((n, format!("{what} is not a finite number")));
                }
            }
            Some("vt") => defined[1] += 1,
            Some("l") => has_lines = true,
            Some("f") => {
                let refs: Vec<&str> = words.collect();
                if refs.len() < 3 {
                    return Err((n, format!("face has {} vertices, a face needs at least 3", refs.len())));
                }
                for r in refs {
                    check_obj_ref(r, &defined).map_err(|problem| (n, problem))?;
                }
                face_lines.push(n);
            }
            _ => {}
        }
    }
    let text = if has_lines {
        let blanked: Vec<&str> =
            text.split('\n').map(|l| if l.split_whitespace().next() == Some("l") { "" } else { l }).collect();
        std::borrow::Cow::Owned(blanked.join("\n"))
    } else {
        std::borrow::Cow::Borrowed(text)
    };
    Ok(ObjScan { face_lines, text })
}

/// Checks one face vertex reference `v`, `v/vt`, `v//vn` or `v/vt/vn` against the
/// counts defined so far (OBJ indices start at 1; negative ones count back from the
/// last defined).
fn check_obj_ref(r: &str, defined: &[i64; 3]) -> Result<(), String> {
    const KINDS: [&str; 3] = ["position", "texture coordinate", "normal"];
    let parts: Vec<&str> = r.split('/').collect();
    if parts.len() > 3 || parts[0].is_empty() {
        return Err(format!("bad vertex reference `{r}` (expected v, v/vt, v//vn or v/vt/vn)"));
    }
    for (k, part) in parts.iter().enumerate() {
        if part.is_empty() {
            continue;
        }
        let Ok(index) = part.parse::<i64>() else {
            return Err(format!("bad vertex reference `{r}`: `{part}` is not an index"));
        };
        let ok = match index {
            0 => false,
            i if i > 0 => i <= defined[k],
            i => defined[k].checked_add(i).is_some_and(|j| j >= 0),
        };
        if !ok {
            let within = if parts.len() > 1 { format!(" in `{r}`") } else { String::new() };
            return Err(format!(
                "{} index {index}{within} is out of range ({} defined before this line; indices start at 1)",
                KINDS[k], defined[k]
            ));
        }
    }
    Ok(())
}
