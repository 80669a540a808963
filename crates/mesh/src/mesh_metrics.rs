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
