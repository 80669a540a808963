//! Distances between meshes: the symmetric Chamfer distance used to compare a
//! reconstruction with the truth.

use geom::{TriMesh, Vec3};
use rayon::prelude::*;
use sim::sample_surface::sample_surface;
use sim::sdf::MeshDistance;

/// Summary of the point-to-surface distances of [`chamfer`], in the meshes' units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChamferStats {
    /// Mean of the two directions' mean distances.
    pub mean: f64,
    /// 95th percentile (nearest rank) of all distances of both directions.
    pub p95: f64,
    /// Largest distance of either direction.
    pub max: f64,
}

/// Symmetric Chamfer distance between the surfaces of `a` and `b`.
///
/// `samples` points are drawn uniformly by area on each mesh
/// ([`sample_surface`], seeds `seed` for `a` and `seed + 1` for `b`), and each
/// is measured to the closest point of the other mesh's surface. Two empty
/// meshes (no faces) are at distance 0; an empty mesh and a non-empty one at
/// infinity. `samples` of 0 is taken as 1.
///
/// # Panics
/// If a mesh has a face index out of range or a non-finite vertex.
pub fn chamfer(a: &TriMesh, b: &TriMesh, samples: usize, seed: u64) -> ChamferStats {
    let samples = samples.max(1);
    match (a.faces.is_empty(), b.faces.is_empty()) {
        (true, true) => {
            return ChamferStats {
                mean: 0.0,
                p95: 0.0,
                max: 0.0,
            }
        }
        (true, false) | (false, true) => {
            return ChamferStats {
                mean: f64::INFINITY,
                p95: f64::INFINITY,
                max: f64::INFINITY,
            }
        }
        _ => {}
    }
    let ab = surface_distances(&sample_surface(a, samples, seed), b);
    let ba = surface_distances(&sample_surface(b, samples, seed.wrapping_add(1)), a);
    let mean_of = |d: &[f64]| d.iter().sum::<f64>() / d.len() as f64;
    let mean = 0.5 * (mean_of(&ab) + mean_of(&ba));
    let mut all: Vec<f64> = ab.into_iter().chain(ba).collect();
    all.sort_unstable_by(f64::total_cmp);
    let rank = ((0.95 * all.len() as f64).ceil() as usize).clamp(1, all.len());
    ChamferStats {
        mean,
        p95: all[rank - 1],
        max: all[all.len() - 1],
    }
}

/// Distance from each point to the surface of `mesh` (which has faces).
fn surface_distances(points: &[Vec3<f64>], mesh: &TriMesh) -> Vec<f64> {
    let md = MeshDistance::new(mesh).unwrap_or_else(|e| panic!("chamfer: {e}"));
    points.par_iter().map(|&p| md.closest_point(p).0).collect()
}

/// Normal consistency of two surfaces: for points spread by area over each,
/// `|n · n'|` between the normal there and the normal of the nearest face of
/// the other mesh, averaged over both directions. 1 when the surfaces agree
/// everywhere; orientation does not matter.
pub fn normal_consistency(a: &TriMesh, b: &TriMesh, samples: usize, seed: u64) -> f64 {
    if a.faces.is_empty() || b.faces.is_empty() {
        return 0.0;
    }
    let (da, db) = (
        MeshDistance::new(a).unwrap_or_else(|e| panic!("normal_consistency: {e}")),
        MeshDistance::new(b).unwrap_or_else(|e| panic!("normal_consistency: {e}")),
    );
    let one_way = |m: &TriMesh, own: &MeshDistance, other: &MeshDistance, s: u64| {
        let pts = sample_surface(m, samples.max(1), s);
        let sum: f64 = pts
            .par_iter()
            .map(|&p| {
                let n = own.face_normal(own.closest_point_triangle(p).2);
                let n2 = other.face_normal(other.closest_point_triangle(p).2);
                n.dot(n2).abs()
            })
            .sum();
        sum / pts.len() as f64
    };
    0.5 * (one_way(a, &da, &db, seed) + one_way(b, &db, &da, seed.wrapping_add(1)))
}

/// Volume IoU of two closed meshes: `samples` random points in the union of
/// their bounding boxes, inside where the generalized winding number > 0.5.
pub fn volume_iou(a: &TriMesh, b: &TriMesh, samples: usize, seed: u64) -> f64 {
    if a.faces.is_empty() || b.faces.is_empty() {
        return 0.0;
    }
    let (da, db) = (
        MeshDistance::new(a).unwrap_or_else(|e| panic!("volume_iou: {e}")),
        MeshDistance::new(b).unwrap_or_else(|e| panic!("volume_iou: {e}")),
    );
    let (lo, hi) = geom::bounding_box(a.vertices.iter().chain(&b.vertices).copied());
    let mut rng = geom::SplitMix64::new(seed);
    let pts: Vec<Vec3<f64>> = (0..samples.max(1)).map(|_| rng.in_box(lo, hi)).collect();
    let (inter, union) = pts
        .par_iter()
        .map(|&p| {
            let (ia, ib) = (da.winding_number(p) > 0.5, db.winding_number(p) > 0.5);
            (usize::from(ia && ib), usize::from(ia || ib))
        })
        .reduce(|| (0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
    if union == 0 {
        0.0
    } else {
        inter as f64 / union as f64
    }
}
