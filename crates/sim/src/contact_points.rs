//! A body's contact points: spread evenly over its surface and over its
//! normals. What decides a contact is the body's support in the direction of
//! the other surface (its lowest point over a plane), and an area-uniform
//! sample represents that badly where the surface curves: on a rounded edge a
//! few millimetres across, a gap of one sample spacing leaves the lowest
//! sample a millimetre above the true edge, so a body landing on that edge is
//! solved on one end of it. Farthest-point thinning in position and normal
//! together puts the samples densely where the normal turns (edges, corners,
//! rounded ends) and evenly on flat faces, without clumps or gaps.

use crate::sample_surface::sample_surface_with_normals;
use geom::{TriMesh, Vec3};

/// Candidates drawn per contact point before thinning.
const CANDIDATES_PER_POINT: usize = 12;

/// `count` contact points of `mesh` (body frame), from `seed`.
pub fn spread_contact_points(mesh: &TriMesh, count: usize, seed: u64) -> Vec<Vec3<f64>> {
    let candidates = sample_surface_with_normals(mesh, count * CANDIDATES_PER_POINT, seed);
    // A turn of the normal by one radian weighs as much as this distance: half the body's size, so a
    // rounded edge gets points about as dense in angle as the faces get them in distance.
    let (lo, hi) = mesh.bounds();
    let size = (Vec3::<f64>::cst(hi) - Vec3::cst(lo)).norm();
    let weight = 0.25 * size;
    let keys: Vec<[f64; 6]> = candidates
        .iter()
        .map(|(p, n)| [p.x, p.y, p.z, weight * n.x, weight * n.y, weight * n.z])
        .collect();
    farthest_points(&keys, count)
        .into_iter()
        .map(|i| candidates[i].0)
        .collect()
}

/// Indices of a greedy farthest-point subset of `keys` of size `count` (all of them if fewer), from the
/// first.
fn farthest_points(keys: &[[f64; 6]], count: usize) -> Vec<usize> {
    if keys.len() <= count {
        return (0..keys.len()).collect();
    }
    let dist2 = |a: &[f64; 6], b: &[f64; 6]| -> f64 { a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum() };
    let mut nearest = vec![f64::INFINITY; keys.len()];
    let mut chosen = Vec::with_capacity(count);
    let mut next = 0;
    for _ in 0..count {
        chosen.push(next);
        let p = keys[next];
        let mut far = (0, -1.0);
        for (i, q) in keys.iter().enumerate() {
            let d = dist2(q, &p).min(nearest[i]);
            nearest[i] = d;
            if d > far.1 {
                far = (i, d);
            }
        }
        next = far.0;
    }
    chosen
}
