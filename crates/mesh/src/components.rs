//! Connected pieces of a mesh. A field's zero level is the object plus, often,
//! small stray surfaces (floaters, bits of background near the cube's edge);
//! the object is the largest piece.

use geom::TriMesh;

/// Root of `i` in a union-find forest, halving paths on the way.
fn root(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[parent[i as usize] as usize];
        parent[i as usize] = p;
        i = p;
    }
    i
}

/// The faces of each connected piece (faces joined through shared vertices),
/// largest piece (by face count) first.
pub fn components(m: &TriMesh) -> Vec<Vec<usize>> {
    let mut parent: Vec<u32> = (0..m.vertices.len() as u32).collect();
    for f in &m.faces {
        let r0 = root(&mut parent, f[0]);
        for &v in &f[1..] {
            let r = root(&mut parent, v);
            if r != r0 {
                parent[r as usize] = r0;
            }
        }
    }
    let mut piece_of_root = vec![u32::MAX; m.vertices.len()];
    let mut pieces: Vec<Vec<usize>> = Vec::new();
    for (fi, f) in m.faces.iter().enumerate() {
        let r = root(&mut parent, f[0]) as usize;
        if piece_of_root[r] == u32::MAX {
            piece_of_root[r] = pieces.len() as u32;
            pieces.push(Vec::new());
        }
        pieces[piece_of_root[r] as usize].push(fi);
    }
    pieces.sort_by_key(|p| std::cmp::Reverse(p.len()));
    pieces
}

/// The faces `faces` of `m` as a mesh of their own (unused vertices dropped).
pub fn sub_mesh(m: &TriMesh, faces: &[usize]) -> TriMesh {
    let mut new_index = vec![u32::MAX; m.vertices.len()];
    let mut vertices = Vec::new();
    let faces = faces
        .iter()
        .map(|&fi| {
            m.faces[fi].map(|v| {
                if new_index[v as usize] == u32::MAX {
                    new_index[v as usize] = vertices.len() as u32;
                    vertices.push(m.vertices[v as usize]);
                }
                new_index[v as usize]
            })
        })
        .collect();
    TriMesh::new(vertices, faces)
}

/// The faces of `m` whose three corners `keep` accepts, as a mesh of their own (crops by region, height,
/// facing).
pub fn faces_where(m: &TriMesh, keep: impl Fn([[f64; 3]; 3]) -> bool) -> TriMesh {
    let faces: Vec<usize> = (0..m.faces.len())
        .filter(|&f| keep(m.faces[f].map(|i| m.vertices[i as usize])))
        .collect();
    sub_mesh(m, &faces)
}

/// The largest connected piece of `m` (an empty mesh stays empty).
pub fn largest_component(m: &TriMesh) -> TriMesh {
    match components(m).first() {
        Some(faces) => sub_mesh(m, faces),
        None => TriMesh::new(vec![], vec![]),
    }
}
