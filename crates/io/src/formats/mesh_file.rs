//! A triangle mesh from a file, by extension: `.ply` or `.obj`.

use crate::{read_obj, read_ply, IoError, Result};
use geom::TriMesh;
use std::path::Path;

/// Read a mesh from a PLY or OBJ file (chosen by the extension, any case).
pub fn read_mesh(path: &Path) -> Result<TriMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "ply" => Ok(read_ply(path)?.mesh),
        "obj" => read_obj(path),
        _ => Err(IoError::Invalid {
            path: path.to_path_buf(),
            field: "extension".into(),
            msg: "expected a .ply or .obj mesh".into(),
        }),
    }
}

/// A vertex with a coordinate that is not finite, as an error naming it: every consumer (metrics, baking,
/// rendering) would fail on it later, or panic. The PLY and OBJ readers check with it.
pub(crate) fn check_finite_vertices(mesh: &TriMesh, path: &Path) -> Result<()> {
    match mesh
        .vertices
        .iter()
        .enumerate()
        .find(|(_, v)| v.iter().any(|x| !x.is_finite()))
    {
        Some((i, v)) => Err(IoError::Invalid {
            path: path.to_path_buf(),
            field: format!("vertex {i}"),
            msg: format!("a coordinate is not finite: {v:?}"),
        }),
        None => Ok(()),
    }
}
