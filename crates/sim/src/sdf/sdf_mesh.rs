//! Signed distance to a closed triangle mesh: unsigned distance from a BVH
//! closest-point query, sign from the generalized winding number (Jacobson et
//! al. 2013) evaluated hierarchically (far clusters as dipoles, after Barill
//! et al. 2018), so a slightly open or self-touching mesh still gets a sign.

use super::Sdf;
use geom::{Real, TriMesh, Vec3};

type V = Vec3<f64>;

#[derive(Debug, thiserror::Error)]
pub enum MeshSdfError {
    #[error("the mesh has no triangles")]
    Empty,
    #[error("face {face} uses vertex {index} but the mesh has {count} vertices")]
    BadIndex { face: usize, index: u32, count: usize },
    #[error("vertex {0} is not finite")]
    NotFinite(usize),
}

#[derive(Clone, Debug)]
struct Node {
    min: V,
    max: V,
    /// Leaf: triangles `start..start+count` of `order`; inner (count 0): children at `start`, `start + 1`.
    start: u32,
    count: u32,
    /// Sum of area-weighted outward normals (½ (b−a)×(c−a)) of the triangles below.
    normal_sum: V,
    /// Area-weighted centroid of the triangles below.
    centroid: V,
    /// Radius of a ball about `centroid` holding every vertex below.
    radius: f64,
}

/// Distance queries on a triangle mesh.
#[derive(Clone, Debug)]
pub struct MeshDistance {
    tris: Vec<[V; 3]>,
    order: Vec<u32>,
    nodes: Vec<Node>,
}

/// Far-field accuracy of the winding number: a cluster is treated as a dipole
/// when the query is more than `BETA` of its radius away.
const BETA: f64 = 2.5;

impl MeshDistance {
    pub fn new(mesh: &TriMesh) -> Result<Self, MeshSdfError> {
        if mesh.faces.is_empty() {
            return Err(MeshSdfError::Empty);
        }
        if let Some(i) = mesh.vertices.iter().position(|v| v.iter().any(|c| !c.is_finite())) {
            return Err(MeshSdfError::NotFinite(i));
        }
        let count = mesh.vertices.len();
        let mut tris = Vec::with_capacity(mesh.faces.len());
        for (face, f) in mesh.faces.iter().enumerate() {
            if let Some(&index) = f.iter().find(|&&i| i as usize >= count) {
                return Err(MeshSdfError::BadIndex { face, index, count });
            }
            tris.push(f.map(|i| V::cst(mesh.vertices[i as usize])));
        }
        // An inside-out mesh (negative volume) would flip every sign: turn it.
        let volume: f64 = tris.iter().map(|t| t[0].dot(t[1].cross(t[2]))).sum();
        if volume < 0.0 {
            for t in &mut tris {
                t.swap(1, 2);
            }
        }
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / 3 + 1);
        nodes.push(placeholder());
        build(&tris, &mut order, &mut nodes, 0, 0, tris.len());
        Ok(Self { tris, order, nodes })
    }

    /// Unsigned distance and the closest point on the surface.
    pub fn closest_point(&self, p: V) -> (f64, V) {
        let (d, c, _) = self.closest_point_triangle(p);
        (d, c)
    }

    /// Unsigned distance, closest point, and the index of the triangle it lies on.
    pub fn closest_point_triangle(&self, p: V) -> (f64, V, usize) {
        let mut best = (f64::INFINITY, p, 0usize);
        let mut stack = vec![0usize];
        while let Some(ni) = stack.pop() {
            let n = &self.nodes[ni];
            if box_distance_sq(p, n.min, n.max) >= best.0 {
                continue;
            }
            if n.count > 0 {
                for &t in &self.order[n.start as usize..(n.start + n.count) as usize] {
                    let c = closest_on_triangle(p, &self.tris[t as usize]);
                    let d2 = (c - p).norm_sq();
                    if d2 < best.0 {
                        best = (d2, c, t as usize);
                    }
                }
            } else {
                let (a, b) = (n.start as usize, n.start as usize + 1);
                let (da, db) = (
                    box_distance_sq(p, self.nodes[a].min, self.nodes[a].max),
                    box_distance_sq(p, self.nodes[b].min, self.nodes[b].max),
                );
                // Visit the nearer child first (pushed last).
                if da < db {
                    stack.push(b);
                    stack.push(a);
                } else {
                    stack.push(a);
                    stack.push(b);
                }
            }
        }
        (best.0.sqrt(), best.1, best.2)
    }

    /// Unit normal of triangle `t` (as stored: inside-out meshes were turned outward).
    pub fn face_normal(&self, t: usize) -> V {
        let [a, b, c] = self.tris[t];
        (b - a).cross(c - a).normalize_or(V::new(0.0, 0.0, 1.0))
    }

    /// Generalized winding number: ~1 inside a closed outward-oriented mesh, ~0 outside.
    pub fn winding_number(&self, p: V) -> f64 {
        let mut omega = 0.0;
        let mut stack = vec![0usize];
        while let Some(ni) = stack.pop() {
            let n = &self.nodes[ni];
            let r = n.centroid - p;
            let dist = r.norm();
            if dist > BETA * n.radius && n.radius > 0.0 {
                omega += n.normal_sum.dot(r) / (dist * dist * dist);
            } else if n.count > 0 {
                for &t in &self.order[n.start as usize..(n.start + n.count) as usize] {
                    omega += solid_angle(p, &self.tris[t as usize]);
                }
            } else {
                stack.push(n.start as usize);
                stack.push(n.start as usize + 1);
            }
        }
        omega / (4.0 * std::f64::consts::PI)
    }

    /// Signed distance (negative inside) and the unit gradient at `p`.
    pub fn signed_distance(&self, p: V) -> (f64, V) {
        let (d, c, tri) = self.closest_point_triangle(p);
        let inside = self.winding_number(p) > 0.5;
        let s = if inside { -1.0 } else { 1.0 };
        let g = if d > 1e-9 {
            (p - c) * (s / d)
        } else {
            // On the surface: the face normal.
            let [a, b, cc] = self.tris[tri];
            (b - a).cross(cc - a).normalize_or(V::new(0.0, 0.0, 1.0))
        };
        (s * d, g)
    }
}

impl Sdf for MeshDistance {
    /// Evaluated in `f64`; derivatives flow to first order through the point
    /// (the normal is taken as locally constant, exact on a face).
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        let (d, g) = self.signed_distance(p.re());
        let dp = p - Vec3::lift(p.re());
        (dp.dot(Vec3::lift(g)) + d, Vec3::lift(g))
    }
}

fn placeholder() -> Node {
    Node {
        min: V::zero(),
        max: V::zero(),
        start: 0,
        count: 0,
        normal_sum: V::zero(),
        centroid: V::zero(),
        radius: 0.0,
    }
}

fn build(tris: &[[V; 3]], order: &mut [u32], nodes: &mut Vec<Node>, ni: usize, lo: usize, hi: usize) {
    let mut min = V::splat(f64::INFINITY);
    let mut max = V::splat(f64::NEG_INFINITY);
    let mut cmin = min;
    let mut cmax = max;
    let mut normal_sum = V::zero();
    let mut weighted = V::zero();
    let mut area_sum = 0.0;
    for &t in &order[lo..hi] {
        let [a, b, c] = tris[t as usize];
        for v in [a, b, c] {
            min = vmin(min, v);
            max = vmax(max, v);
        }
        let cen = (a + b + c) * (1.0 / 3.0);
        cmin = vmin(cmin, cen);
        cmax = vmax(cmax, cen);
        let n = (b - a).cross(c - a) * 0.5;
        let area = n.norm();
        normal_sum += n;
        weighted += cen * area;
        area_sum += area;
    }
    let centroid = if area_sum > 0.0 {
        weighted * (1.0 / area_sum)
    } else {
        (min + max) * 0.5
    };
    let mut radius: f64 = 0.0;
    for &t in &order[lo..hi] {
        for v in tris[t as usize] {
            radius = radius.max((v - centroid).norm());
        }
    }
    let mut node = Node {
        min,
        max,
        start: lo as u32,
        count: (hi - lo) as u32,
        normal_sum,
        centroid,
        radius,
    };
    if hi - lo > 4 {
        let ext = cmax - cmin;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = (lo + hi) / 2;
        let key = |t: &u32| {
            let [a, b, c] = tris[*t as usize];
            a[axis] + b[axis] + c[axis]
        };
        order[lo..hi].select_nth_unstable_by(mid - lo, |x, y| key(x).total_cmp(&key(y)));
        let left = nodes.len();
        nodes.push(placeholder());
        nodes.push(placeholder());
        node.start = left as u32;
        node.count = 0;
        build(tris, order, nodes, left, lo, mid);
        build(tris, order, nodes, left + 1, mid, hi);
    }
    nodes[ni] = node;
}

fn vmin(a: V, b: V) -> V {
    V::new(a.x.min(b.x), a.y.min(b.y), a.z.min(b.z))
}
fn vmax(a: V, b: V) -> V {
    V::new(a.x.max(b.x), a.y.max(b.y), a.z.max(b.z))
}

fn box_distance_sq(p: V, min: V, max: V) -> f64 {
    let d = |v: f64, lo: f64, hi: f64| (lo - v).max(0.0).max(v - hi);
    let (dx, dy, dz) = (d(p.x, min.x, max.x), d(p.y, min.y, max.y), d(p.z, min.z, max.z));
    dx * dx + dy * dy + dz * dz
}

/// Signed solid angle of a triangle seen from `p` (Van Oosterom & Strackee 1983).
fn solid_angle(p: V, t: &[V; 3]) -> f64 {
    let (a, b, c) = (t[0] - p, t[1] - p, t[2] - p);
    let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
    let det = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * det.atan2(den)
}

/// Closest point on a triangle (Ericson, Real-Time Collision Detection §5.1.5).
pub(crate) fn closest_on_triangle(p: V, t: &[V; 3]) -> V {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let den = 1.0 / (va + vb + vc);
    a + ab * (vb * den) + ac * (vc * den)
}
