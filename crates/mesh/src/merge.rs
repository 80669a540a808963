//! The two-pose object (Sec. 3.2, Fig. 2b): an object reconstructed upright
//! (A) and turned over (B), each closed but guessed underneath where it stood
//! on the board. Keep from each only what its cameras could see (above the
//! board plane z = 0 of its capture, with a margin), align A to B by ICP on
//! those parts, and make one closed surface: the zero level of a fused SDF
//! that takes B's distance where B was seen, A's where only A was seen, and
//! blends across the seam.

use crate::icp::{icp_auto, IcpConfig, IcpResult, IcpTarget};
use crate::marching_tetrahedra::{extract_zero_level, ScalarGrid};
use geom::{Pose, TriMesh, Vec3};
use rayon::prelude::*;
use sim::sdf::MeshDistance;

type V = Vec3<f64>;

#[derive(Clone, Debug, PartialEq)]
pub struct MergeConfig {
    /// Parts within this height of a capture's board (z ≤ margin) were not seen. Default 3 mm.
    pub board_margin: f64,
    /// Width of the blend between the two SDFs across the seam, m. Default 3 mm.
    pub blend: f64,
    /// Grid points along the longest side of the merged object's box. Default 128.
    pub resolution: usize,
    /// Points per cloud given to ICP. Default 20 000.
    pub icp_points: usize,
    /// Refuse the result when ICP's RMS point-to-plane residual is above this, m. Default 1 mm.
    pub max_residual: f64,
    pub icp: IcpConfig,
}

impl Default for MergeConfig {
    fn default() -> Self {
        Self {
            board_margin: 3e-3,
            blend: 3e-3,
            resolution: 128,
            icp_points: 20000,
            max_residual: 1e-3,
            icp: IcpConfig {
                keep_fraction: 0.7,
                ..IcpConfig::default()
            },
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("mesh {0}: {1}")]
    Mesh(char, String),
    #[error("mesh {0} has nothing above its board plane (z > {1} m): was it reconstructed in its capture's frame?")]
    NothingVisible(char, f64),
    #[error("ICP did not converge: RMS residual {residual:.3e} m is above {limit:.1e} m (the two parts may not overlap enough, or be different objects)")]
    NoConvergence { residual: f64, limit: f64 },
    #[error("the fused SDF has no zero level")]
    Empty,
}

/// What a merge produced.
pub struct Merged {
    /// The whole object, in B's frame.
    pub mesh: TriMesh,
    /// `p_B = a_to_b · p_A`.
    pub a_to_b: Pose<f64>,
    pub icp: IcpResult,
}

/// Points (spread by area) with their face normals, of faces entirely above `z_min`.
fn visible_cloud(m: &TriMesh, md: &MeshDistance, z_min: f64, count: usize, seed: u64) -> (Vec<V>, Vec<V>) {
    let faces = m
        .faces
        .iter()
        .filter(|f| f.iter().all(|&i| m.vertices[i as usize][2] > z_min))
        .copied()
        .collect();
    let part = TriMesh::new(m.vertices.clone(), faces);
    if part.faces.is_empty() {
        return (vec![], vec![]);
    }
    let pts = sim::sample_surface::sample_surface(&part, count, seed);
    let normals = pts
        .iter()
        .map(|p| md.face_normal(md.closest_point_triangle(*p).2))
        .collect();
    (pts, normals)
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Merge `a` (upright) and `b` (turned over), each closed and in its own
/// capture's frame (board at z = 0).
pub fn merge_two_poses(a: &TriMesh, b: &TriMesh, cfg: &MergeConfig) -> Result<Merged, MergeError> {
    let da = MeshDistance::new(a).map_err(|e| MergeError::Mesh('A', e.to_string()))?;
    let db = MeshDistance::new(b).map_err(|e| MergeError::Mesh('B', e.to_string()))?;
    let (pa, _) = visible_cloud(a, &da, cfg.board_margin, cfg.icp_points, 1);
    let (pb, nb) = visible_cloud(b, &db, cfg.board_margin, cfg.icp_points, 2);
    if pa.is_empty() {
        return Err(MergeError::NothingVisible('A', cfg.board_margin));
    }
    if pb.is_empty() {
        return Err(MergeError::NothingVisible('B', cfg.board_margin));
    }
    let icp = icp_auto(&pa, &IcpTarget::new(pb, nb), &cfg.icp);
    if !(icp.residual <= cfg.max_residual) {
        return Err(MergeError::NoConvergence {
            residual: icp.residual,
            limit: cfg.max_residual,
        });
    }
    let a_to_b = icp.transform;
    let b_to_a = a_to_b.inverse();
    // The fused SDF in B's frame: B where B saw (z_B above the margin), else A.
    let fused = |x: V| -> f64 {
        let xa = b_to_a.transform_point(x);
        let (sb, sa) = (db.signed_distance(x).0, da.signed_distance(xa).0);
        let wb = smoothstep(cfg.board_margin, cfg.board_margin + cfg.blend, x.z);
        let wa = smoothstep(cfg.board_margin, cfg.board_margin + cfg.blend, xa.z);
        if wa + wb <= 0.0 {
            // Seen by neither (can only happen in a thin sliver at both boards): the nearer guess.
            if sa.abs() < sb.abs() {
                sa
            } else {
                sb
            }
        } else {
            // Prefer B where B saw it; A fills where only A saw.
            let w = wb / (wb + wa * (1.0 - wb));
            w * sb + (1.0 - w) * sa
        }
    };
    // The box of the object in B's frame: B's box and A's moved into it.
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let moved_a = a.vertices.iter().map(|v| a_to_b.transform_point(V::cst(*v)).to_array());
    for v in b.vertices.iter().copied().chain(moved_a) {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let longest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let h = longest / (cfg.resolution.max(8) - 1) as f64;
    let pad = 3.0 * h;
    let origin = lo.map(|v| v - pad);
    let dims: [usize; 3] = std::array::from_fn(|k| ((hi[k] - lo[k] + 2.0 * pad) / h).ceil() as usize + 1);
    let values = narrow_band(&fused, origin, h, dims);
    let grid = ScalarGrid {
        origin,
        spacing: h,
        dims,
        values,
    };
    let mesh = extract_zero_level(&grid);
    if mesh.faces.is_empty() {
        return Err(MergeError::Empty);
    }
    Ok(Merged { mesh, a_to_b, icp })
}

/// Sample `f` on the fine grid, exactly only near its zero level: a grid four
/// times coarser first; a fine point whose coarse cell has every corner
/// farther from the surface than the cell's diagonal takes the coarse
/// interpolation (its sign, all marching needs there, is right).
fn narrow_band(f: &(dyn Fn(V) -> f64 + Sync), origin: [f64; 3], h: f64, dims: [usize; 3]) -> Vec<f32> {
    const K: usize = 4;
    let cd: [usize; 3] = std::array::from_fn(|a| (dims[a] - 1).div_ceil(K) + 1);
    let at = |i: usize, j: usize, k: usize, step: f64| {
        V::new(
            origin[0] + i as f64 * step,
            origin[1] + j as f64 * step,
            origin[2] + k as f64 * step,
        )
    };
    let coarse: Vec<f64> = (0..cd.iter().product::<usize>())
        .into_par_iter()
        .map(|idx| {
            f(at(
                idx % cd[0],
                (idx / cd[0]) % cd[1],
                idx / (cd[0] * cd[1]),
                h * K as f64,
            ))
        })
        .collect();
    let far = 1.8 * (K as f64) * h;
    let c = |i: usize, j: usize, k: usize| coarse[i + cd[0] * (j + cd[1] * k)];
    (0..dims.iter().product::<usize>())
        .into_par_iter()
        .map(|idx| {
            let (i, j, k) = (idx % dims[0], (idx / dims[0]) % dims[1], idx / (dims[0] * dims[1]));
            let (ci, cj, ck) = ((i / K).min(cd[0] - 2), (j / K).min(cd[1] - 2), (k / K).min(cd[2] - 2));
            let corners = [
                c(ci, cj, ck),
                c(ci + 1, cj, ck),
                c(ci, cj + 1, ck),
                c(ci + 1, cj + 1, ck),
                c(ci, cj, ck + 1),
                c(ci + 1, cj, ck + 1),
                c(ci, cj + 1, ck + 1),
                c(ci + 1, cj + 1, ck + 1),
            ];
            if corners.iter().all(|v| *v > far) || corners.iter().all(|v| *v < -far) {
                let t = |n: usize, cn: usize| (n as f64 - (cn * K) as f64) / K as f64;
                let (u, v, w) = (t(i, ci), t(j, cj), t(k, ck));
                let lerp = |a: f64, b: f64, s: f64| a + (b - a) * s;
                let x0 = lerp(lerp(corners[0], corners[1], u), lerp(corners[2], corners[3], u), v);
                let x1 = lerp(lerp(corners[4], corners[5], u), lerp(corners[6], corners[7], u), v);
                lerp(x0, x1, w) as f32
            } else {
                f(at(i, j, k, h)) as f32
            }
        })
        .collect()
}
