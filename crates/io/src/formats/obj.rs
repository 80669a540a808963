//! Wavefront OBJ meshes: positions and faces only.
//!
//! Texture coordinates, normals, groups, smoothing groups and materials are
//! ignored; polygons are fan-triangulated.

use std::path::Path;

use geom::TriMesh;

use crate::error::{IoError, Result};

/// Reads an OBJ file. See [`read_obj_bytes`].
pub fn read_obj(path: &Path) -> Result<TriMesh> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })?;
    read_obj_bytes(&bytes, path)
}

/// Parses an OBJ file already in memory; `path` is only used in errors.
///
/// Reads `v x y z [w]` (anything after `z`, such as vertex colours, is ignored)
/// and `f` with corners `i`, `i/j`, `i/j/k` or `i//k`, where a negative `i`
/// counts back from the last vertex read so far. Other statements are ignored.
pub fn read_obj_bytes(bytes: &[u8], path: &Path) -> Result<TriMesh> {
    let mesh = parse(&String::from_utf8_lossy(bytes)).map_err(|msg| IoError::Obj {
        path: path.to_path_buf(),
        msg,
    })?;
    super::mesh_file::check_finite_vertices(&mesh, path)?;
    Ok(mesh)
}

fn parse(text: &str) -> std::result::Result<TriMesh, String> {
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    // Positive indices may point forward to vertices defined later (some
    // exporters do this), so the largest one is checked at the end.
    let mut max_index: Option<(usize, usize)> = None; // (index, line)
    let mut corners: Vec<u32> = Vec::new();

    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let bad = |what: String| format!("line {line_no}: {what}");
        match words.next() {
            Some("v") => {
                let mut p = [0.0; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let w = words
                        .next()
                        .ok_or_else(|| bad(format!("`v` needs 3 coordinates, found {k}")))?;
                    *c = w.parse().map_err(|_| bad(format!("`{w}` is not a number")))?;
                }
                vertices.push(p);
            }
            Some("f") => {
                corners.clear();
                for w in words {
                    let first = w.split('/').next().unwrap_or("");
                    let i: i64 = first.parse().map_err(|_| bad(format!("`{w}` is not a face corner")))?;
                    let idx = if i > 0 {
                        let idx = (i - 1) as usize;
                        match max_index {
                            Some((m, _)) if m >= idx => {}
                            _ => max_index = Some((idx, line_no)),
                        }
                        idx
                    } else if i < 0 {
                        let back = i.unsigned_abs() as usize;
                        vertices.len().checked_sub(back).ok_or_else(|| {
                            bad(format!(
                                "relative index {i} goes before the first vertex \
                                 ({} vertices so far)",
                                vertices.len()
                            ))
                        })?
                    } else {
                        return Err(bad("vertex index 0 (OBJ indices start at 1)".into()));
                    };
                    let idx = u32::try_from(idx).map_err(|_| bad(format!("vertex index {i} is too large")))?;
                    corners.push(idx);
                }
                if corners.len() < 3 {
                    return Err(bad(format!("a face needs at least 3 corners, found {}", corners.len())));
                }
                for j in 1..corners.len() - 1 {
                    faces.push([corners[0], corners[j], corners[j + 1]]);
                }
            }
            // vt, vn, vp, o, g, s, usemtl, mtllib, l, p, comments, blank lines...
            _ => {}
        }
    }
    if let Some((idx, line_no)) = max_index {
        if idx >= vertices.len() {
            return Err(format!(
                "line {line_no}: vertex index {} out of range: the file has {} vertices",
                idx + 1,
                vertices.len()
            ));
        }
    }
    Ok(TriMesh { vertices, faces })
}
