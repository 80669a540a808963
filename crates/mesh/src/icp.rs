//! Rigid alignment of two point clouds (the two-pose merge of Sec. 3.2):
//! point-to-plane ICP (Chen & Medioni; the linearised form of Low 2004) with
//! a k-d tree for correspondences, trimming of the worst pairs and Huber
//! weights on the rest, and an automatic global start: centroids and
//! principal axes matched under the 24 proper axis-aligned orientations, the
//! best residual winning.

use crate::kdtree::KdTree;
use geom::{symmetric_eigen, Mat3, Pose, Quat, Vec3};
use rayon::prelude::*;

type V = Vec3<f64>;

/// Settings of the alignment.
#[derive(Clone, Debug, PartialEq)]
pub struct IcpConfig {
    /// Iterations at most. Default 60.
    pub iterations: usize,
    /// Keep this fraction of the closest pairs each iteration (trimmed ICP,
    /// for clouds that overlap only in part). Default 1.
    pub keep_fraction: f64,
    /// Floor of the Huber threshold on the point-to-plane residual, m. The
    /// threshold follows the residuals (1.345 σ, σ from their median absolute
    /// value), so far-off starts are not frozen by a tight kernel. Default 0.1 mm.
    pub huber: f64,
    /// Stop when an iteration moves the source by less than this (m, and rad). Default 1e-9.
    pub tolerance: f64,
    /// Iterations per hypothesis of the automatic start. Default 15.
    pub start_iterations: usize,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            iterations: 60,
            keep_fraction: 0.9,
            huber: 1e-3,
            tolerance: 1e-9,
            start_iterations: 15,
        }
    }
}

/// The alignment found: `target ≈ transform · source`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IcpResult {
    pub transform: Pose<f64>,
    /// RMS point-to-plane distance of the kept pairs, m.
    pub residual: f64,
    /// RMS point-to-point distance of the kept pairs, m.
    pub rms_distance: f64,
    pub iterations: usize,
    /// How well the kept pairs pin the pose down: the smallest over the
    /// largest eigenvalue of the point-to-plane normal matrix, with rotations
    /// scaled by the cloud's RMS radius (1 = every direction equally, 0 = a
    /// direction is free, e.g. sliding along parallel walls).
    pub conditioning: f64,
}

/// A target cloud with normals, indexed for nearest-neighbour queries.
pub struct IcpTarget {
    points: Vec<V>,
    normals: Vec<V>,
    tree: KdTree,
}

impl IcpTarget {
    pub fn new(points: Vec<V>, normals: Vec<V>) -> Self {
        assert_eq!(points.len(), normals.len(), "one normal per target point");
        let tree = KdTree::new(&points);
        Self { points, normals, tree }
    }
}

/// Point-to-plane ICP from `init`.
pub fn icp(source: &[V], target: &IcpTarget, init: Pose<f64>, cfg: &IcpConfig, iterations: usize) -> IcpResult {
    let mut pose = init;
    let mut pairs: Vec<(f64, usize, usize)> = Vec::with_capacity(source.len());
    let mut last = (f64::INFINITY, f64::INFINITY);
    let mut done = 0;
    // Each source point's nearest target point of the iteration before: the search starts from it.
    let mut hints = vec![usize::MAX; source.len()];
    for it in 0..iterations {
        done = it + 1;
        pairs.clear();
        pairs.par_extend(source.par_iter().zip(&hints).enumerate().filter_map(|(i, (p, &hint))| {
            target
                .tree
                .nearest_from(pose.transform_point(*p), hint)
                .map(|(j, d2)| (d2, i, j))
        }));
        for &(_, i, j) in &pairs {
            hints[i] = j;
        }
        let keep = ((pairs.len() as f64 * cfg.keep_fraction).ceil() as usize).clamp(1.min(pairs.len()), pairs.len());
        if keep < pairs.len() {
            pairs.select_nth_unstable_by(keep - 1, |a, b| a.0.total_cmp(&b.0));
            pairs.truncate(keep);
        }
        // Robust scale: σ ≈ 1.4826 · median |r|.
        let mut abs_r: Vec<f64> = pairs
            .iter()
            .map(|&(_, i, j)| {
                (pose.transform_point(source[i]) - target.points[j])
                    .dot(target.normals[j])
                    .abs()
            })
            .collect();
        let mid = abs_r.len() / 2;
        let median = if abs_r.is_empty() {
            0.0
        } else {
            *abs_r.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let huber = (1.345 * 1.4826 * median).max(cfg.huber);
        // Normal equations of Σ w ((R p + t − q)·n + ω·(p' × n) + δt·n)².
        let mut a = [[0.0f64; 6]; 6];
        let mut b = [0.0f64; 6];
        let (mut res2, mut dist2, mut wsum) = (0.0f64, 0.0f64, 0.0f64);
        for &(d2, i, j) in &pairs {
            let p = pose.transform_point(source[i]);
            let (q, n) = (target.points[j], target.normals[j]);
            let r = (p - q).dot(n);
            let w = if r.abs() <= huber { 1.0 } else { huber / r.abs() };
            let c = p.cross(n);
            let row = [c.x, c.y, c.z, n.x, n.y, n.z];
            for u in 0..6 {
                b[u] -= w * row[u] * r;
                for v in 0..6 {
                    a[u][v] += w * row[u] * row[v];
                }
            }
            res2 += r * r;
            dist2 += d2;
            wsum += 1.0;
        }
        last = ((res2 / wsum.max(1.0)).sqrt(), (dist2 / wsum.max(1.0)).sqrt());
        // Small damping keeps the step defined when the shape leaves a direction free.
        let scale = (0..6).map(|k| a[k][k]).fold(0.0, f64::max).max(1e-30);
        for (k, row) in a.iter_mut().enumerate() {
            row[k] += 1e-9 * scale;
        }
        let Some(x) = solve6(a, b) else { break };
        let (w, t) = (V::new(x[0], x[1], x[2]), V::new(x[3], x[4], x[5]));
        let step = Pose::new(Quat::exp(w), t);
        pose = step.compose(&pose);
        pose.q = pose.q.normalize_or_identity();
        if w.norm() < cfg.tolerance && t.norm() < cfg.tolerance {
            break;
        }
    }
    let kept: Vec<(V, V)> = pairs
        .iter()
        .map(|&(_, i, j)| (pose.transform_point(source[i]), target.normals[j]))
        .collect();
    IcpResult {
        transform: pose,
        residual: last.0,
        rms_distance: last.1,
        iterations: done,
        conditioning: conditioning(&kept),
    }
}

/// [`IcpResult::conditioning`] of points with their target normals.
fn conditioning(pairs: &[(V, V)]) -> f64 {
    if pairs.is_empty() {
        return 0.0;
    }
    let n = pairs.len() as f64;
    let c = pairs.iter().fold(V::zero(), |a, (p, _)| a + *p) * (1.0 / n);
    let radius = (pairs.iter().map(|(p, _)| (*p - c).dot(*p - c)).sum::<f64>() / n).sqrt();
    if !(radius > 0.0) {
        return 0.0;
    }
    let mut a = [[0.0f64; 6]; 6];
    for (p, nrm) in pairs {
        let m = (*p - c).cross(*nrm) * (1.0 / radius);
        let row = [m.x, m.y, m.z, nrm.x, nrm.y, nrm.z];
        for u in 0..6 {
            for v in 0..6 {
                a[u][v] += row[u] * row[v] / n;
            }
        }
    }
    let (values, _) = symmetric_eigen(a);
    let max = values.iter().copied().fold(0.0, f64::max);
    let min = values.iter().copied().fold(f64::INFINITY, f64::min);
    if max > 0.0 {
        (min / max).max(0.0)
    } else {
        0.0
    }
}

/// The fit of `source` moved by `pose` to `target`, without moving it: the
/// residuals and conditioning of one round of correspondences at `pose`
/// (for a transform known in advance, e.g. from markers).
pub fn icp_evaluate(source: &[V], target: &IcpTarget, pose: Pose<f64>, cfg: &IcpConfig) -> IcpResult {
    // One iteration measures the residual before it steps; the step is dropped.
    let mut r = icp(source, target, pose, cfg, 1);
    r.transform = pose;
    r.iterations = 0;
    r
}

/// The share of `source` points that land on the target surface when moved
/// by `pose`: within `distance` of its tangent plane at the nearest target
/// point, that point being at most 4 `distance` away (point-to-point alone
/// would count the sampling gaps). Only moved points for which `counts`
/// holds are counted (where the target could have a surface); returns the
/// share and how many were counted. How much of the two surfaces an
/// alignment makes coincide: the largest-common-pointset score.
pub fn inlier_fraction(
    source: &[V],
    target: &IcpTarget,
    pose: Pose<f64>,
    distance: f64,
    counts: &(dyn Fn(V) -> bool + Sync),
) -> (f64, usize) {
    let (inliers, counted) = source
        .par_iter()
        .map(|p| pose.transform_point(*p))
        .filter(|p| counts(*p))
        .map(|p| {
            let on = target.tree.nearest(p).is_some_and(|(j, d2)| {
                d2 <= 16.0 * distance * distance && (p - target.points[j]).dot(target.normals[j]).abs() <= distance
            });
            (on as usize, 1usize)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    (inliers as f64 / counted.max(1) as f64, counted)
}

/// Solve a 6×6 system by Gaussian elimination with partial pivoting.
fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> Option<[f64; 6]> {
    for c in 0..6 {
        let p = (c..6).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..6 {
            let f = a[r][c] / a[c][c];
            for k in c..6 {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 6];
    for r in (0..6).rev() {
        let s: f64 = (r + 1..6).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

/// Centroid and principal axes (columns, by decreasing variance, right-handed).
fn principal_frame(points: &[V]) -> (V, Mat3<f64>) {
    let (c, cov) = geom::point_covariance(points);
    let (vals, vecs) = symmetric_eigen(cov.m);
    let vecs = Mat3::from_rows(vecs);
    let mut idx = [0, 1, 2];
    idx.sort_by(|&i, &j| vals[j].total_cmp(&vals[i]));
    let cols: Vec<V> = idx.iter().map(|&k| vecs.col(k)).collect();
    let third = cols[0].cross(cols[1]);
    (
        c,
        Mat3::from_rows([cols[0].to_array(), cols[1].to_array(), third.to_array()]).transpose(),
    )
}

/// The 24 rotations that map coordinate axes onto coordinate axes.
pub fn axis_rotations() -> Vec<Mat3<f64>> {
    let mut out = Vec::with_capacity(24);
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for perm in perms {
        for signs in 0..8 {
            let mut m = Mat3::<f64>::zero();
            for (row, &col) in perm.iter().enumerate() {
                m.m[row][col] = if signs >> row & 1 == 1 { -1.0 } else { 1.0 };
            }
            if m.det() > 0.0 {
                out.push(m);
            }
        }
    }
    out
}

/// Points used to score each hypothesis of the automatic start.
const HYPOTHESIS_POINTS: usize = 2000;

/// Align `source` to `target` from no prior: every pairing of principal
/// frames under the 24 axis rotations is refined briefly on a subsample, the
/// best is refined fully on every point.
pub fn icp_auto(source: &[V], target: &IcpTarget, cfg: &IcpConfig) -> IcpResult {
    let start = icp_hypotheses(source, target, cfg)[0].transform;
    icp(source, target, start, cfg, cfg.iterations)
}

/// The automatic start's hypotheses, each after `cfg.start_iterations` of
/// ICP on a subsample: distinct poses (more than 5° or 2 % of the cloud's
/// size apart), best (lowest RMS distance) first. A shape with symmetries
/// gives several near-equal ones.
pub fn icp_hypotheses(source: &[V], target: &IcpTarget, cfg: &IcpConfig) -> Vec<IcpResult> {
    let stride = source.len().div_ceil(HYPOTHESIS_POINTS).max(1);
    let sub: Vec<V> = source.iter().step_by(stride).copied().collect();
    let (cs, fs) = principal_frame(source);
    let (ct, ft) = principal_frame(&target.points);
    let size = source.iter().map(|p| (*p - cs).norm()).fold(0.0, f64::max);
    let mut all: Vec<IcpResult> = axis_rotations()
        .into_iter()
        .map(|g| {
            // R maps the source frame's axes onto the target frame's, permuted by g.
            let r = ft.mul_mat(&g).mul_mat(&fs.transpose());
            let q = Quat::from_mat(&r);
            let init = Pose::new(q, ct - q.rotate(cs));
            icp(&sub, target, init, cfg, cfg.start_iterations)
        })
        .collect();
    all.sort_by(|a, b| a.rms_distance.total_cmp(&b.rms_distance));
    let mut distinct: Vec<IcpResult> = Vec::new();
    for h in all {
        let same = |d: &IcpResult| {
            geom::rotation_distance(d.transform.q, h.transform.q) < 5f64.to_radians()
                && (d.transform.t - h.transform.t).norm() < 0.02 * size
        };
        if !distinct.iter().any(same) {
            distinct.push(h);
        }
    }
    distinct
}
