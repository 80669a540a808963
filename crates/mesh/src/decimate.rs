//! Mesh simplification by quadric error metrics (Garland & Heckbert 1997):
//! repeatedly collapse the edge whose merged vertex stays closest, in the sum
//! of squared distances, to the planes of the faces around both ends. Flat
//! regions vanish first and sharp features last, so a marching mesh of
//! hundreds of thousands of faces becomes a few thousand for the
//! simulator's contact points with little change in shape.
//!
//! A collapse is refused when it would break the surface: when the two ends
//! share neighbours other than the two vertices opposite the edge (the link
//! condition, which keeps a closed manifold closed and manifold), when it
//! would turn a face over, or when it touches the border of an open mesh
//! (borders stay as they are).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use geom::{Mat3, TriMesh, Vec3};

type V = Vec3<f64>;

/// A symmetric 4×4 quadric `Q` with `error(p) = [p 1] Q [p 1]ᵀ`, stored as
/// its upper triangle.
#[derive(Clone, Copy, Default)]
struct Quadric([f64; 10]);

impl Quadric {
    /// Squared distance to the plane `n·p + d = 0` (unit `n`), times `weight`.
    fn plane(n: V, d: f64, weight: f64) -> Self {
        let (a, b, c) = (n.x, n.y, n.z);
        Self([a * a, a * b, a * c, a * d, b * b, b * c, b * d, c * c, c * d, d * d].map(|v| v * weight))
    }
    fn add(&self, o: &Self) -> Self {
        Self(std::array::from_fn(|i| self.0[i] + o.0[i]))
    }
    fn error(&self, p: V) -> f64 {
        let q = &self.0;
        let (x, y, z) = (p.x, p.y, p.z);
        q[0] * x * x
            + 2.0 * q[1] * x * y
            + 2.0 * q[2] * x * z
            + 2.0 * q[3] * x
            + q[4] * y * y
            + 2.0 * q[5] * y * z
            + 2.0 * q[6] * y
            + q[7] * z * z
            + 2.0 * q[8] * z
            + q[9]
    }
    /// The point of least error, if the 3×3 part is well conditioned.
    fn minimiser(&self) -> Option<V> {
        let q = &self.0;
        let a = Mat3 {
            m: [[q[0], q[1], q[2]], [q[1], q[4], q[5]], [q[2], q[5], q[7]]],
        };
        let det = a.det();
        let scale = q[0] + q[4] + q[7];
        if !(det.abs() > 1e-9 * scale * scale * scale) {
            return None;
        }
        Some(a.try_inverse()?.mul_vec(V::new(-q[3], -q[6], -q[8])))
    }
}

/// A candidate collapse in the queue: cheapest first; stale when either end
/// has changed since it was queued.
struct Candidate {
    cost: f64,
    a: u32,
    b: u32,
    stamp: (u32, u32),
    target: V,
}

impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.cost == o.cost
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> Ordering {
        o.cost
            .total_cmp(&self.cost)
            .then_with(|| (o.a, o.b).cmp(&(self.a, self.b)))
    }
}

struct Decimator {
    pos: Vec<V>,
    quadric: Vec<Quadric>,
    faces: Vec<[u32; 3]>,
    face_alive: Vec<bool>,
    vertex_faces: Vec<Vec<u32>>,
    stamp: Vec<u32>,
    vertex_alive: Vec<bool>,
    on_border: Vec<bool>,
}

impl Decimator {
    fn new(m: &TriMesh) -> Self {
        let pos: Vec<V> = m.vertices.iter().map(|v| V::cst(*v)).collect();
        let mut quadric = vec![Quadric::default(); pos.len()];
        let mut vertex_faces = vec![Vec::new(); pos.len()];
        for (fi, f) in m.faces.iter().enumerate() {
            let [p0, p1, p2] = f.map(|i| pos[i as usize]);
            let n = (p1 - p0).cross(p2 - p0);
            let area2 = n.norm();
            if area2 > 0.0 {
                let n = n * (1.0 / area2);
                let q = Quadric::plane(n, -n.dot(p0), 0.5 * area2);
                for &i in f {
                    quadric[i as usize] = quadric[i as usize].add(&q);
                }
            }
            for &i in f {
                vertex_faces[i as usize].push(fi as u32);
            }
        }
        // A border edge belongs to one face only.
        let mut edges = std::collections::HashMap::new();
        for f in &m.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
            }
        }
        let mut on_border = vec![false; pos.len()];
        for ((a, b), n) in edges {
            if n != 2 {
                on_border[a as usize] = true;
                on_border[b as usize] = true;
            }
        }
        Self {
            stamp: vec![0; pos.len()],
            vertex_alive: vec![true; pos.len()],
            face_alive: vec![true; m.faces.len()],
            faces: m.faces.clone(),
            pos,
            quadric,
            vertex_faces,
            on_border,
        }
    }

    fn neighbours(&self, v: u32) -> Vec<u32> {
        let mut n: Vec<u32> = self.vertex_faces[v as usize]
            .iter()
            .filter(|&&f| self.face_alive[f as usize])
            .flat_map(|&f| self.faces[f as usize])
            .filter(|&u| u != v)
            .collect();
        n.sort_unstable();
        n.dedup();
        n
    }

    fn candidate(&self, a: u32, b: u32) -> Candidate {
        let q = self.quadric[a as usize].add(&self.quadric[b as usize]);
        let (pa, pb) = (self.pos[a as usize], self.pos[b as usize]);
        let mut options = vec![pa, pb, (pa + pb) * 0.5];
        if let Some(p) = q.minimiser() {
            // Keep the optimum near the edge: far ones come from nearly flat quadrics.
            if (p - (pa + pb) * 0.5).norm() <= (pb - pa).norm() {
                options.push(p);
            }
        }
        let (target, cost) = options
            .into_iter()
            .map(|p| (p, q.error(p)))
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .expect("options are not empty");
        // Where the error is zero (a flat region) every collapse ties, and
        // collapsing onto one vertex builds a fan of ever higher valence; a
        // tiny length term makes short edges go first and keeps it even.
        let area = q.0[0] + q.0[4] + q.0[7];
        let tie_break = 1e-6 * area * (pb - pa).dot(pb - pa);
        Candidate {
            cost: cost.max(0.0) + tie_break,
            a,
            b,
            stamp: (self.stamp[a as usize], self.stamp[b as usize]),
            target,
        }
    }

    /// Whether collapsing `b` into `a` at `target` keeps the mesh a manifold
    /// and turns no face over.
    fn can_collapse(&self, a: u32, b: u32, target: V) -> bool {
        if self.on_border[a as usize] || self.on_border[b as usize] {
            return false;
        }
        let (na, nb) = (self.neighbours(a), self.neighbours(b));
        let shared = na.iter().filter(|v| nb.binary_search(v).is_ok()).count();
        let edge_faces = self.vertex_faces[a as usize]
            .iter()
            .filter(|&&f| self.face_alive[f as usize] && self.faces[f as usize].contains(&b))
            .count();
        if shared != 2 || edge_faces != 2 {
            return false;
        }
        // Faces that stay (they hold one end only) must keep their orientation.
        for &v in &[a, b] {
            for &f in &self.vertex_faces[v as usize] {
                let face = self.faces[f as usize];
                if !self.face_alive[f as usize] || (face.contains(&a) && face.contains(&b)) {
                    continue;
                }
                let p = face.map(|i| self.pos[i as usize]);
                let q = face.map(|i| if i == v { target } else { self.pos[i as usize] });
                let n0 = (p[1] - p[0]).cross(p[2] - p[0]);
                let n1 = (q[1] - q[0]).cross(q[2] - q[0]);
                if n0.dot(n1) <= 0.2 * n0.norm() * n1.norm() {
                    return false;
                }
            }
        }
        true
    }

    fn collapse(&mut self, a: u32, b: u32, target: V) -> usize {
        let mut removed = 0;
        let b_faces = std::mem::take(&mut self.vertex_faces[b as usize]);
        for &f in &b_faces {
            if !self.face_alive[f as usize] {
                continue;
            }
            let face = &mut self.faces[f as usize];
            if face.contains(&a) {
                self.face_alive[f as usize] = false;
                removed += 1;
            } else {
                for i in face.iter_mut() {
                    if *i == b {
                        *i = a;
                    }
                }
                self.vertex_faces[a as usize].push(f);
            }
        }
        self.vertex_faces[a as usize].retain(|&f| self.face_alive[f as usize]);
        self.pos[a as usize] = target;
        self.quadric[a as usize] = self.quadric[a as usize].add(&self.quadric[b as usize]);
        self.vertex_alive[b as usize] = false;
        self.stamp[a as usize] += 1;
        self.stamp[b as usize] += 1;
        removed
    }
}

/// `m` with at most `target_faces` faces (and no fewer than 4), by quadric
/// edge collapses that keep a closed manifold closed and manifold. Stops
/// early when no allowed collapse remains.
pub fn decimate(m: &TriMesh, target_faces: usize) -> TriMesh {
    let target_faces = target_faces.max(4);
    let mut d = Decimator::new(m);
    let mut faces_left = m.faces.len();
    let mut heap = BinaryHeap::new();
    for f in &m.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a < b {
                heap.push(d.candidate(a, b));
            }
        }
    }
    while faces_left > target_faces {
        let Some(c) = heap.pop() else { break };
        let (a, b) = (c.a, c.b);
        if !d.vertex_alive[a as usize]
            || !d.vertex_alive[b as usize]
            || c.stamp != (d.stamp[a as usize], d.stamp[b as usize])
        {
            continue;
        }
        if !d.can_collapse(a, b, c.target) {
            continue;
        }
        faces_left -= d.collapse(a, b, c.target);
        for n in d.neighbours(a) {
            heap.push(d.candidate(a.min(n), a.max(n)));
        }
    }
    // Compact: live faces, used vertices.
    let faces: Vec<usize> = (0..d.faces.len()).filter(|&f| d.face_alive[f]).collect();
    let compacted = TriMesh::new(d.pos.iter().map(|p| p.to_array()).collect(), d.faces.clone());
    crate::components::sub_mesh(&compacted, &faces)
}
