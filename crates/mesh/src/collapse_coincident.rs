//! Welding vertices that sit at the same point, by edge collapse, without
//! breaking the surface.
//!
//! Marching tetrahedra puts several vertices on one grid point where the
//! field is exactly zero there; the triangles between them have zero area. An
//! edge `uv` of zero length is collapsed (u merged into v, the two faces on it
//! dropped) only when the link condition holds (Dey et al. 1999: the common
//! neighbours of u and v are exactly the far corners of the faces on uv) and
//! no vertex is left with fewer than 3 neighbours. Boundary vertices of an
//! open surface are handled by closing the surface with one virtual vertex
//! joined to every boundary edge, as in the usual proof of that condition.
//! The collapses keep a closed manifold closed and an open one a manifold
//! with the same boundary loops. Edges are tried in a fixed order, pass after
//! pass until none more can go, so the result is deterministic.

/// The virtual vertex joined to every boundary edge.
const OUTSIDE: u32 = u32::MAX;

/// Collapses zero-length edges (see the module docs), drops the faces that
/// vanish and the vertices no face uses; the remaining vertices keep their order.
pub(crate) fn collapse_coincident_vertices(vertices: &mut Vec<[f64; 3]>, faces: &mut Vec<[u32; 3]>) {
    let zero_length = |f: &[u32; 3], s: usize| {
        let (a, b) = (f[s], f[(s + 1) % 3]);
        (a != b && vertices[a as usize] == vertices[b as usize]).then_some((a.min(b), a.max(b)))
    };
    if !faces.iter().any(|f| (0..3).any(|s| zero_length(f, s).is_some())) {
        return;
    }
    let mut mesh = Collapser::new(vertices.len(), std::mem::take(faces));
    loop {
        let mut candidates: Vec<(u32, u32)> = mesh
            .faces
            .iter()
            .zip(&mesh.alive)
            .filter(|(_, &alive)| alive)
            .flat_map(|(f, _)| (0..3).filter_map(|s| zero_length(f, s)))
            .collect();
        candidates.sort_unstable();
        candidates.dedup();
        let mut progress = false;
        for (u, v) in candidates {
            progress |= mesh.try_collapse(u, v);
        }
        if !progress {
            break;
        }
    }

    let kept: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .zip(&mesh.alive)
        .filter(|(_, &a)| a)
        .map(|(f, _)| *f)
        .collect();
    let mut new_index = vec![u32::MAX; vertices.len()];
    kept.iter().flatten().for_each(|&v| new_index[v as usize] = 0);
    let mut compact = Vec::with_capacity(vertices.len());
    for (i, p) in vertices.iter().enumerate() {
        if new_index[i] == 0 {
            new_index[i] = compact.len() as u32;
            compact.push(*p);
        }
    }
    *vertices = compact;
    *faces = kept.iter().map(|f| f.map(|v| new_index[v as usize])).collect();
}

struct Collapser {
    faces: Vec<[u32; 3]>,
    alive: Vec<bool>,
    /// Faces using each vertex (dead ones are skipped when read).
    vertex_faces: Vec<Vec<u32>>,
}

impl Collapser {
    fn new(vertex_count: usize, faces: Vec<[u32; 3]>) -> Self {
        let mut vertex_faces = vec![Vec::new(); vertex_count];
        for (fi, f) in faces.iter().enumerate() {
            for &v in f {
                vertex_faces[v as usize].push(fi as u32);
            }
        }
        Self {
            alive: vec![true; faces.len()],
            faces,
            vertex_faces,
        }
    }

    /// The neighbours of `x` in cyclic order, with [`OUTSIDE`] between the
    /// two ends of the fan of a boundary vertex; `None` if `x` has no faces
    /// or its faces do not form one fan (a non-manifold vertex).
    fn ring(&self, x: u32) -> Option<Vec<u32>> {
        // Each face (x, p, q) in winding order gives the link edge p → q.
        let mut link: Vec<(u32, u32)> = Vec::new();
        for &fi in &self.vertex_faces[x as usize] {
            if !self.alive[fi as usize] {
                continue;
            }
            let f = self.faces[fi as usize];
            let s = f.iter().position(|&y| y == x)?;
            link.push((f[(s + 1) % 3], f[(s + 2) % 3]));
        }
        if link.is_empty() {
            return None;
        }
        link.sort_unstable();
        if link.windows(2).any(|w| w[0].0 == w[1].0) {
            return None;
        }
        let mut ends: Vec<u32> = link.iter().map(|e| e.1).collect();
        ends.sort_unstable();
        if ends.windows(2).any(|w| w[0] == w[1]) {
            return None;
        }
        // A start that nothing leads to: the fan is open (x on the boundary).
        let starts: Vec<u32> = link
            .iter()
            .map(|e| e.0)
            .filter(|p| ends.binary_search(p).is_err())
            .collect();
        let (first, open) = match starts.len() {
            0 => (link[0].0, false),
            1 => (starts[0], true),
            _ => return None,
        };
        let mut ring = vec![first];
        let mut cur = first;
        while let Ok(i) = link.binary_search_by_key(&cur, |e| e.0) {
            cur = link[i].1;
            if cur == first {
                break;
            }
            ring.push(cur);
            if ring.len() > link.len() + 1 {
                return None;
            }
        }
        let expected = if open { link.len() + 1 } else { link.len() };
        if ring.len() != expected || (!open && cur != first) {
            return None;
        }
        if open {
            ring.push(OUTSIDE);
        }
        Some(ring)
    }

    /// The length of the boundary loop through boundary vertex `x`, or
    /// `None` once it passes `limit`.
    fn boundary_loop_len(&self, x: u32, limit: usize) -> Option<usize> {
        let mut cur = x;
        for n in 1..=limit {
            let ring = self.ring(cur)?;
            let at = ring.iter().position(|&y| y == OUTSIDE)?;
            cur = ring[(at + 1) % ring.len()];
            if cur == x {
                return Some(n);
            }
        }
        None
    }

    /// Collapses `a` into `b` (or whatever they have been merged into) if that
    /// keeps the surface a manifold; returns whether it did.
    fn try_collapse(&mut self, a: u32, b: u32) -> bool {
        let (u, v) = (a, b);
        let (Some(ring_u), Some(ring_v)) = (self.ring(u), self.ring(v)) else {
            return false;
        };
        let Some(at) = ring_u.iter().position(|&x| x == v) else {
            return false;
        };
        let n = ring_u.len();
        let (c1, c2) = (ring_u[(at + n - 1) % n], ring_u[(at + 1) % n]);
        if c1 == c2 || ring_u.len() + ring_v.len() < 7 {
            return false;
        }
        // Link condition: the only common neighbours are c1 and c2.
        let common = ring_u.iter().filter(|x| ring_v.contains(x)).count();
        if common != 2 || !ring_v.contains(&c1) || !ring_v.contains(&c2) {
            return false;
        }
        for c in [c1, c2] {
            if c != OUTSIDE && self.ring(c).is_none_or(|r| r.len() < 4) {
                return false;
            }
        }
        // Collapsing a boundary edge shortens its loop; keep loops of at least 3 edges.
        if (c1 == OUTSIDE || c2 == OUTSIDE) && self.boundary_loop_len(u, 3).is_some() {
            return false;
        }
        let moved = std::mem::take(&mut self.vertex_faces[u as usize]);
        for fi in moved {
            if !self.alive[fi as usize] {
                continue;
            }
            let f = &mut self.faces[fi as usize];
            if f.contains(&v) {
                self.alive[fi as usize] = false;
            } else {
                f.iter_mut().filter(|x| **x == u).for_each(|x| *x = v);
                self.vertex_faces[v as usize].push(fi);
            }
        }
        let alive = &self.alive;
        self.vertex_faces[v as usize].retain(|&f| alive[f as usize]);
        true
    }
}
