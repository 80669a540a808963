//! Checks that a mesh can stand for a solid body.

use geom::TriMesh;
use std::collections::HashMap;

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshCheckError {
    #[error("the mesh has no faces")]
    Empty,
    #[error("face {face} uses vertex {index}, but there are only {count} vertices")]
    BadIndex { face: usize, index: u32, count: usize },
    #[error("vertex {0} has a NaN or infinite coordinate")]
    NotFinite(usize),
    #[error("the mesh is not closed: edge ({a}, {b}) borders {count} face(s) in that direction and {reverse} in the other (a closed, consistently oriented mesh has exactly one of each)")]
    Open {
        a: u32,
        b: u32,
        count: usize,
        reverse: usize,
    },
    #[error("the mesh encloses no volume")]
    ZeroVolume,
}

/// Closed and consistently oriented: every directed edge appears once and its
/// reverse once.
pub fn check_closed_mesh(mesh: &TriMesh) -> Result<(), MeshCheckError> {
    if mesh.faces.is_empty() {
        return Err(MeshCheckError::Empty);
    }
    if let Some(i) = mesh.vertices.iter().position(|v| v.iter().any(|c| !c.is_finite())) {
        return Err(MeshCheckError::NotFinite(i));
    }
    let count = mesh.vertices.len();
    let mut edges: HashMap<(u32, u32), usize> = HashMap::with_capacity(mesh.faces.len() * 3);
    for (face, f) in mesh.faces.iter().enumerate() {
        if let Some(&index) = f.iter().find(|&&i| i as usize >= count) {
            return Err(MeshCheckError::BadIndex { face, index, count });
        }
        for k in 0..3 {
            *edges.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut keys: Vec<_> = edges.keys().copied().collect();
    keys.sort_unstable();
    for (a, b) in keys {
        let n = edges[&(a, b)];
        let r = edges.get(&(b, a)).copied().unwrap_or(0);
        if n != 1 || r != 1 {
            return Err(MeshCheckError::Open {
                a,
                b,
                count: n,
                reverse: r,
            });
        }
    }
    Ok(())
}
