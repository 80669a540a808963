//! Closed meshes of the analytic shapes, for mass properties, contact points
//! and export. Convex shapes are meshed by pushing a subdivided cube out along
//! rays from the centre onto the surface; boxes and wedges are exact.

use crate::sdf::{Capsule, Cuboid, RoundedBox, Sdf, Sphere, Wedge};
use geom::{TriMesh, Vec3};
use std::collections::HashMap;

/// The surface grid of the cube [-1, 1]³ with `n` cells per edge, welded so
/// that the mesh is closed, with outward faces.
fn cube_grid(n: usize) -> TriMesh {
    let n = n.max(1) as i64;
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    let mut vid = |c: [i64; 3], vertices: &mut Vec<[f64; 3]>| {
        *index.entry(c).or_insert_with(|| {
            vertices.push(c.map(|v| 2.0 * v as f64 / n as f64 - 1.0));
            (vertices.len() - 1) as u32
        })
    };
    for axis in 0..3 {
        for side in [0, n] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..n {
                for j in 0..n {
                    let corner = |di: i64, dj: i64| {
                        let mut c = [0i64; 3];
                        c[axis] = side;
                        c[u] = i + di;
                        c[v] = j + dj;
                        c
                    };
                    let q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)].map(|c| vid(c, &mut vertices));
                    // (u, v, axis) is right-handed, so u→v winding faces +axis.
                    if side == n {
                        faces.push([q[0], q[1], q[2]]);
                        faces.push([q[0], q[2], q[3]]);
                    } else {
                        faces.push([q[0], q[2], q[1]]);
                        faces.push([q[0], q[3], q[2]]);
                    }
                }
            }
        }
    }
    TriMesh::new(vertices, faces)
}

/// A box with `n` cells per edge.
pub fn cuboid_mesh(c: &Cuboid, n: usize) -> TriMesh {
    let mut m = cube_grid(n);
    for v in &mut m.vertices {
        for (x, h) in v.iter_mut().zip(c.half) {
            *x *= h;
        }
    }
    m
}

/// A convex shape that contains the origin, meshed radially from the cube
/// grid: each vertex moves along its ray to the zero level (bisection).
fn radial_mesh(sdf: &impl Sdf, n: usize, reach: f64) -> TriMesh {
    let mut m = cube_grid(n);
    for v in &mut m.vertices {
        let dir = Vec3::cst(*v).normalize_or(Vec3::new(0.0, 0.0, 1.0));
        let (mut lo, mut hi) = (0.0, reach);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if sdf.distance_local(dir * mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        *v = (dir * (0.5 * (lo + hi))).to_array();
    }
    m
}

pub fn sphere_mesh(s: &Sphere, n: usize) -> TriMesh {
    radial_mesh(s, n, 2.0 * s.radius)
}

pub fn rounded_box_mesh(s: &RoundedBox, n: usize) -> TriMesh {
    let reach = 2.0 * (s.half[0].powi(2) + s.half[1].powi(2) + s.half[2].powi(2)).sqrt();
    radial_mesh(s, n, reach)
}

pub fn capsule_mesh(s: &Capsule, n: usize) -> TriMesh {
    radial_mesh(s, n, 2.0 * (s.half_length + s.radius))
}

/// The wedge's prism: 6 corners, 8 triangles.
pub fn wedge_mesh(w: &Wedge) -> TriMesh {
    let [hx, hy, hz] = w.half;
    let vertices = vec![
        [-hx, -hy, -hz],
        [hx, -hy, -hz],
        [hx, -hy, hz],
        [-hx, hy, -hz],
        [hx, hy, -hz],
        [hx, hy, hz],
    ];
    let faces = vec![
        [0, 2, 1],
        [3, 4, 5],
        [0, 1, 4],
        [0, 4, 3],
        [1, 2, 5],
        [1, 5, 4],
        [0, 3, 5],
        [0, 5, 2],
    ];
    let mut m = TriMesh::new(vertices, faces);
    orient_outward_convex(&mut m);
    m
}

/// Flip the faces of a convex mesh whose normal points towards its centroid.
fn orient_outward_convex(m: &mut TriMesh) {
    let n = m.vertices.len() as f64;
    let c = m.vertices.iter().fold(Vec3::zero(), |acc, v| acc + Vec3::cst(*v)) * (1.0 / n);
    for f in 0..m.faces.len() {
        let [a, b, cc] = m.triangle(f).map(Vec3::<f64>::cst);
        let normal = (b - a).cross(cc - a);
        if normal.dot((a + b + cc) * (1.0 / 3.0) - c) < 0.0 {
            m.faces[f].swap(1, 2);
        }
    }
}

/// A closed mesh of an analytic shape that can be a body, with `n` cells per
/// cube edge for the curved ones; `None` for planes, grids and unions.
pub fn shape_mesh(shape: &crate::sdf::Shape, n: usize) -> Option<TriMesh> {
    use crate::sdf::Shape;
    Some(match shape {
        Shape::Cuboid(c) => cuboid_mesh(c, n.div_ceil(4).max(1)),
        Shape::Sphere(s) => sphere_mesh(s, n),
        Shape::RoundedBox(s) => rounded_box_mesh(s, n),
        Shape::Capsule(s) => capsule_mesh(s, n),
        Shape::Wedge(w) => wedge_mesh(w),
        Shape::Transformed { pose, shape } => {
            let mut m = shape_mesh(shape, n)?;
            for v in &mut m.vertices {
                *v = pose.transform_point(Vec3::cst(*v)).to_array();
            }
            m
        }
        Shape::Plane(_) | Shape::Grid(_) | Shape::Union(_) => return None,
    })
}
