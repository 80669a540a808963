//! The two-pose object (Sec. 3.2, Fig. 2b): an object reconstructed upright
//! (A) and turned over (B), each closed but guessed underneath where it stood
//! on the board. Keep from each only what its cameras could see (above the
//! board plane z = 0 of its capture, with a margin), align A to B by ICP on
//! those parts, and make one closed surface: the zero level of a fused SDF
//! that takes B's distance where B was seen, A's where only A was seen, and
//! blends across the seam.
//!
//! Each part is a [`PartialSurface`]: a signed distance evaluated in batches
//! (a trained field's own SDF, or a closed mesh's) and its zero-level mesh,
//! cut down to its largest piece (the object, without floaters). The fused
//! SDF uses the distances themselves, so the merged surface is as good as the
//! fields, not as their meshes; its largest piece is the result.

use crate::components::largest_component;
use crate::icp::{icp_auto, IcpConfig, IcpResult, IcpTarget};
use crate::marching_tetrahedra::{extract_zero_level, ScalarGrid};
use crate::zero_level_points::{zero_level_points, BatchSdf};
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
    /// Finite-difference step of a field's gradient when ICP samples are projected onto its zero level, m. Default 0.2 mm.
    pub fd_step: f64,
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
            fd_step: 2e-4,
            icp: IcpConfig {
                keep_fraction: 0.7,
                ..IcpConfig::default()
            },
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("part {0}: {1}")]
    Mesh(char, String),
    #[error("mesh {0} has nothing above its board plane (z > {1} m): was it reconstructed in its capture's frame?")]
    NothingVisible(char, f64),
    #[error("ICP did not converge: RMS residual {residual:.3e} m is above {limit:.1e} m (the two parts may not overlap enough, or be different objects)")]
    NoConvergence { residual: f64, limit: f64 },
    #[error("the fused SDF has no zero level")]
    Empty,
    #[error("part {0}: the signed distance returned {1} values for {2} points")]
    ValueCount(char, usize, usize),
}

/// One partial reconstruction, in its capture's frame (board at z = 0).
pub struct PartialSurface<'a> {
    /// The zero level's largest piece.
    mesh: TriMesh,
    sdf: Box<BatchSdf<'a>>,
    /// Whether ICP samples taken on `mesh` are projected onto the SDF's zero
    /// level (a field's mesh is only a marching approximation of it).
    project: bool,
}

impl<'a> PartialSurface<'a> {
    /// A closed mesh: its distance by the generalized winding number.
    pub fn from_mesh(mesh: TriMesh) -> Result<PartialSurface<'static>, String> {
        if mesh.faces.is_empty() {
            return Err("the mesh has no faces".into());
        }
        sim::check_closed_mesh(&mesh).map_err(|e| e.to_string())?;
        let dist = MeshDistance::new(&mesh).map_err(|e| e.to_string())?;
        Ok(PartialSurface {
            mesh: largest_component(&mesh),
            sdf: Box::new(move |pts: &[V]| pts.iter().map(|p| dist.signed_distance(*p).0).collect()),
            project: false,
        })
    }

    /// A field: its signed distance in metres (`sdf`, batched) and its
    /// extracted zero level, of which the largest piece is kept.
    pub fn from_field(zero_level: &TriMesh, sdf: impl Fn(&[V]) -> Vec<f64> + Sync + 'a) -> Result<Self, String> {
        let mesh = largest_component(zero_level);
        if mesh.faces.is_empty() {
            return Err("the field has no zero level".into());
        }
        Ok(Self {
            mesh,
            sdf: Box::new(sdf),
            project: true,
        })
    }

    /// The object's zero-level mesh (largest piece).
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// Signed distances at `points`, checked for count.
    fn distances(&self, name: char, points: &[V]) -> Result<Vec<f64>, MergeError> {
        let d = (self.sdf)(points);
        if d.len() != points.len() {
            return Err(MergeError::ValueCount(name, d.len(), points.len()));
        }
        Ok(d)
    }

    /// Points (spread by area) with normals on the part above `z_min`.
    fn visible_cloud(&self, z_min: f64, count: usize, fd_step: f64, seed: u64) -> (Vec<V>, Vec<V>) {
        let m = &self.mesh;
        let faces: Vec<[u32; 3]> = m
            .faces
            .iter()
            .filter(|f| f.iter().all(|&i| m.vertices[i as usize][2] > z_min))
            .copied()
            .collect();
        if faces.is_empty() {
            return (vec![], vec![]);
        }
        let part = TriMesh::new(m.vertices.clone(), faces);
        let pts = sim::sample_surface::sample_surface(&part, count, seed);
        if self.project {
            let (p, n) = zero_level_points(&*self.sdf, &pts, fd_step, 2, fd_step);
            p.into_iter().zip(n).filter(|(p, _)| p.z > z_min).unzip()
        } else {
            let md = MeshDistance::new(&part).expect("faces are not empty");
            let normals = pts
                .iter()
                .map(|p| md.face_normal(md.closest_point_triangle(*p).2))
                .collect();
            (pts, normals)
        }
    }
}

/// What a merge produced.
pub struct Merged {
    /// The whole object, in B's frame.
    pub mesh: TriMesh,
    /// `p_B = a_to_b · p_A`.
    pub a_to_b: Pose<f64>,
    pub icp: IcpResult,
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Merge `a` (upright) and `b` (turned over), each in its own capture's
/// frame (board at z = 0).
pub fn merge_two_poses(a: &PartialSurface, b: &PartialSurface, cfg: &MergeConfig) -> Result<Merged, MergeError> {
    let (pa, _) = a.visible_cloud(cfg.board_margin, cfg.icp_points, cfg.fd_step, 1);
    let (pb, nb) = b.visible_cloud(cfg.board_margin, cfg.icp_points, cfg.fd_step, 2);
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
    let fused = |xs: &[V]| -> Result<Vec<f64>, MergeError> {
        let xa: Vec<V> = xs.iter().map(|x| b_to_a.transform_point(*x)).collect();
        let sb = b.distances('B', xs)?;
        let sa = a.distances('A', &xa)?;
        let edge = |z: f64| smoothstep(cfg.board_margin, cfg.board_margin + cfg.blend, z);
        Ok((0..xs.len())
            .map(|i| {
                let (wb, wa) = (edge(xs[i].z), edge(xa[i].z));
                if wa + wb <= 0.0 {
                    // Seen by neither (only in a thin sliver at both boards): the nearer guess.
                    if sa[i].abs() < sb[i].abs() {
                        sa[i]
                    } else {
                        sb[i]
                    }
                } else {
                    // Prefer B where B saw it; A fills where only A saw.
                    let w = wb / (wb + wa * (1.0 - wb));
                    w * sb[i] + (1.0 - w) * sa[i]
                }
            })
            .collect())
    };
    // The box of the object in B's frame: B's box and A's moved into it.
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let moved_a = a
        .mesh
        .vertices
        .iter()
        .map(|v| a_to_b.transform_point(V::cst(*v)).to_array());
    for v in b.mesh.vertices.iter().copied().chain(moved_a) {
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
    let values = narrow_band(&fused, origin, h, dims)?;
    let grid = ScalarGrid {
        origin,
        spacing: h,
        dims,
        values,
    };
    let mesh = largest_component(&extract_zero_level(&grid));
    if mesh.faces.is_empty() {
        return Err(MergeError::Empty);
    }
    Ok(Merged { mesh, a_to_b, icp })
}

/// The fused SDF at a batch of points.
type FusedSdf<'a> = dyn Fn(&[V]) -> Result<Vec<f64>, MergeError> + Sync + 'a;

/// Points per call of the fused SDF.
const BATCH: usize = 1 << 14;

/// `f` at every point, in parallel batches.
fn eval_batched(f: &FusedSdf, points: &[V]) -> Result<Vec<f64>, MergeError> {
    let parts: Vec<Vec<f64>> = points.par_chunks(BATCH).map(f).collect::<Result<_, _>>()?;
    Ok(parts.concat())
}

/// Sample `f` on the fine grid, exactly only near its zero level: a grid four
/// times coarser first; a fine point whose coarse cell has every corner
/// farther from the surface than the cell's diagonal takes the coarse
/// interpolation (its sign, all marching needs there, is right).
fn narrow_band(f: &FusedSdf, origin: [f64; 3], h: f64, dims: [usize; 3]) -> Result<Vec<f32>, MergeError> {
    const K: usize = 4;
    let cd: [usize; 3] = std::array::from_fn(|a| (dims[a] - 1).div_ceil(K) + 1);
    let at = |i: usize, j: usize, k: usize, step: f64| {
        V::new(
            origin[0] + i as f64 * step,
            origin[1] + j as f64 * step,
            origin[2] + k as f64 * step,
        )
    };
    let coarse_points: Vec<V> = (0..cd.iter().product::<usize>())
        .map(|idx| at(idx % cd[0], (idx / cd[0]) % cd[1], idx / (cd[0] * cd[1]), h * K as f64))
        .collect();
    let coarse = eval_batched(f, &coarse_points)?;
    let far = 1.8 * (K as f64) * h;
    let c = |i: usize, j: usize, k: usize| coarse[i + cd[0] * (j + cd[1] * k)];
    let mut exact = Vec::new();
    let mut values: Vec<f32> = (0..dims.iter().product::<usize>())
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
                exact.push(idx);
                0.0
            }
        })
        .collect();
    let exact_points: Vec<V> = exact
        .iter()
        .map(|&idx| at(idx % dims[0], (idx / dims[0]) % dims[1], idx / (dims[0] * dims[1]), h))
        .collect();
    for (idx, v) in exact.iter().zip(eval_batched(f, &exact_points)?) {
        values[*idx] = v as f32;
    }
    Ok(values)
}
