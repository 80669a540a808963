//! A camera's lens and each view's pose from a planar board seen in several views: Zhang's closed form for
//! the start, then Levenberg–Marquardt over every lens parameter and view pose jointly (the normal equations
//! reduced to the lens by the Schur complement), with a Huber loss and a second pass without the outliers.

use geom::{Dual, Mat3, Quat, Vec3};

use crate::homography;
use crate::lens::{project_with, Lens, LENS_PARAMETERS};
use crate::linalg::{cholesky_solve, spd_inverse};

/// One view: board points (OpenCV's board frame, metres, z = 0) and the pixels they are seen at.
#[derive(Clone, Debug, Default)]
pub struct ViewPoints {
    pub board: Vec<[f64; 2]>,
    pub image: Vec<[f64; 2]>,
}

impl ViewPoints {
    /// A view's points from what was detected in it: each marker's four corners, and (ChArUco) the
    /// chessboard corners.
    pub fn from_detections(
        board: &crate::Board,
        markers: &[crate::detect::DetectedMarker],
        chess: &[crate::charuco::ChessCorner],
    ) -> Self {
        let mut v = ViewPoints::default();
        for m in markers {
            if let Some(on_board) = board.marker(m.id) {
                v.board.extend_from_slice(&on_board.corners);
                v.image.extend_from_slice(&m.corners);
            }
        }
        for c in chess {
            v.board.push(board.chessboard_corners[c.id]);
            v.image.push(c.image);
        }
        v
    }

    /// Another view's points added (frames of a fixed camera pooled into one view).
    pub fn extend(&mut self, other: &ViewPoints) {
        self.board.extend_from_slice(&other.board);
        self.image.extend_from_slice(&other.image);
    }
}

/// A view's pose: board frame to camera frame, `p_cam = rotation · p_board + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardPose {
    pub rotation: Quat<f64>,
    pub translation: Vec3<f64>,
}

/// Which lens parameters are solved for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationSettings {
    /// A lens to hold (none of its numbers solved for: poses only).
    pub known_lens: Option<Lens>,
    /// Solve for k3 (a wide-angle lens); otherwise it stays 0, as most lenses need.
    pub solve_k3: bool,
    /// Solve for the tangential terms p1, p2.
    pub solve_tangential: bool,
    /// Levenberg–Marquardt iterations at most, per pass.
    pub max_iterations: usize,
    /// Points farther than this many robust standard deviations (and over half a pixel) from their
    /// projection after the first pass are left out of the second.
    pub outlier_sigmas: f64,
}

impl Default for CalibrationSettings {
    fn default() -> Self {
        CalibrationSettings {
            known_lens: None,
            solve_k3: false,
            solve_tangential: true,
            max_iterations: 100,
            outlier_sigmas: 4.0,
        }
    }
}

/// What the calibration found.
#[derive(Clone, Debug)]
pub struct Calibration {
    pub lens: Lens,
    /// One pose per view.
    pub poses: Vec<BoardPose>,
    /// Root-mean-square reprojection error of each view's kept points, pixels.
    pub view_rms: Vec<f64>,
    /// Root-mean-square reprojection error of every kept point, pixels.
    pub rms: f64,
    /// Per view, whether each point was kept (false: an outlier).
    pub kept: Vec<Vec<bool>>,
    /// Per view, the standard deviation of its camera's centre (metres) that its points' scatter leaves,
    /// the lens taken as known: a board small in the view, or a few markers, leave it large.
    pub centre_sigma: Vec<f64>,
}

/// Calibrates from `views` of a board in images of `size` (width, height).
pub fn calibrate(views: &[ViewPoints], size: (usize, usize), s: &CalibrationSettings) -> Result<Calibration, String> {
    for (i, v) in views.iter().enumerate() {
        if v.board.len() != v.image.len() || v.board.len() < 6 {
            return Err(format!("view {i}: {} points; a view needs at least 6", v.board.len()));
        }
    }
    let lens0 = match s.known_lens {
        Some(l) => l,
        None => initial_lens(views, size)?,
    };
    let mut poses: Vec<BoardPose> = views
        .iter()
        .map(|v| initial_pose(&lens0, v))
        .collect::<Option<_>>()
        .ok_or("a view's homography is degenerate (its points on a line?)")?;
    unflip(views, &mut poses);
    let free = free_parameters(s);
    let mut lens = lens0;
    let mut kept: Vec<Vec<bool>> = views.iter().map(|v| vec![true; v.board.len()]).collect();
    // A first pass robust to the odd wrong corner, then one without the points it finds far off.
    let scale = size.0.max(size.1) as f64;
    refine(views, &kept, &mut lens, &mut poses, &free, 1.0, s.max_iterations, scale);
    unflip(views, &mut poses);
    let residuals = residual_norms(views, &lens, &poses);
    let mut all: Vec<f64> = residuals.iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    let sigma = 1.4826 * all[all.len() / 2];
    let limit = (s.outlier_sigmas * sigma).max(0.5);
    for (k, r) in kept.iter_mut().zip(&residuals) {
        for (keep, &e) in k.iter_mut().zip(r) {
            *keep = e <= limit;
        }
    }
    refine(
        views,
        &kept,
        &mut lens,
        &mut poses,
        &free,
        f64::INFINITY,
        s.max_iterations,
        scale,
    );
    unflip(views, &mut poses);
    let residuals = residual_norms(views, &lens, &poses);
    let mut view_rms = Vec::new();
    let (mut total, mut count) = (0.0, 0usize);
    for (r, k) in residuals.iter().zip(&kept) {
        let (sum, n) = r
            .iter()
            .zip(k)
            .filter(|(_, &k)| k)
            .fold((0.0, 0), |(s, n), (e, _)| (s + e * e, n + 1));
        view_rms.push((sum / n.max(1) as f64).sqrt());
        total += sum;
        count += n;
    }
    let rms = (total / count.max(1) as f64).sqrt();
    let centre_sigma = views
        .iter()
        .zip(&poses)
        .zip(&kept)
        .map(|((v, p), k)| centre_sigma(v, k, &lens, p, rms))
        .collect();
    Ok(Calibration {
        lens,
        poses,
        view_rms,
        rms,
        kept,
        centre_sigma,
    })
}

/// The standard deviation of a view's camera centre (the root of its covariance's trace), from the pose block
/// of the normal equations with each image coordinate's error `rms / √2`.
fn centre_sigma(v: &ViewPoints, kept: &[bool], lens: &Lens, pose: &BoardPose, rms: f64) -> f64 {
    const L: usize = LENS_PARAMETERS;
    let mut vv = vec![0.0; 36];
    for ((b, i), &keep) in v.board.iter().zip(&v.image).zip(kept) {
        if !keep {
            continue;
        }
        for comp in &residual_with_jacobian(lens, pose, *b, *i) {
            for a in 0..6 {
                for c in 0..6 {
                    vv[a * 6 + c] += comp.eps[L + a] * comp.eps[L + c];
                }
            }
        }
    }
    let Some(inv) = spd_inverse(&vv, 6) else {
        return f64::INFINITY;
    };
    let variance = (rms * rms / 2.0).max(1e-6);
    // The centre c = -Rᵀ exp(-φ) (t + δt): dc/dφ = -Rᵀ [t]×, dc/dδt = -Rᵀ.
    let t = pose.translation;
    let cross = [[0.0, -t.z, t.y], [t.z, 0.0, -t.x], [-t.y, t.x, 0.0]];
    let r = pose.rotation.conj().to_mat().m;
    let mut j = [[0.0f64; 6]; 3];
    for row in 0..3 {
        for col in 0..3 {
            j[row][col] = -(0..3).map(|k| r[row][k] * cross[k][col]).sum::<f64>();
            j[row][3 + col] = -r[row][col];
        }
    }
    let mut trace = 0.0;
    for row in 0..3 {
        for a in 0..6 {
            for b in 0..6 {
                trace += j[row][a] * inv[a * 6 + b] * j[row][b];
            }
        }
    }
    (variance * trace).max(0.0).sqrt()
}

/// The lens parameters solved for, by index.
fn free_parameters(s: &CalibrationSettings) -> [bool; LENS_PARAMETERS] {
    if s.known_lens.is_some() {
        return [false; LENS_PARAMETERS];
    }
    [
        true,
        true,
        true,
        true,
        true,
        true,
        s.solve_tangential,
        s.solve_tangential,
        s.solve_k3,
    ]
}

/// Zhang's closed form for fx, fy, cx, cy (no skew) from the views' homographies; with fewer than three
/// views, or where it fails, the principal point at the image centre and one focal length.
fn initial_lens(views: &[ViewPoints], size: (usize, usize)) -> Result<Lens, String> {
    // Pixels normalised around the image centre, for a well-conditioned system.
    let (w, h) = (size.0 as f64, size.1 as f64);
    let (c0, scale) = ([(w - 1.0) / 2.0, (h - 1.0) / 2.0], w.max(h));
    let mut hs = Vec::new();
    for v in views {
        let image: Vec<[f64; 2]> = v
            .image
            .iter()
            .map(|p| [(p[0] - c0[0]) / scale, (p[1] - c0[1]) / scale])
            .collect();
        if let Some(hm) = homography::fit(&v.board, &image) {
            hs.push(hm);
        }
    }
    if hs.is_empty() {
        return Err("no view gives a homography of the board".into());
    }
    let from_zhang = (hs.len() >= 3).then(|| zhang(&hs)).flatten();
    let (fx, fy, cx, cy) = match from_zhang {
        Some((fx, fy, cx, cy))
            if fx > 0.1 && fy > 0.1 && cx.abs() < 0.3 && cy.abs() < 0.3 && (fx / fy - 1.0).abs() < 0.2 =>
        {
            (fx, fy, cx, cy)
        }
        _ => {
            let f = focal_with_centred_point(&hs)
                .ok_or("cannot find a focal length from the views (all fronto-parallel?)")?;
            (f, f, 0.0, 0.0)
        }
    };
    Ok(Lens::pinhole(
        fx * scale,
        fy * scale,
        cx * scale + c0[0],
        cy * scale + c0[1],
    ))
}

/// Zhang's solution for the image of the absolute conic B = K⁻ᵀK⁻¹ (zero skew imposed), then K.
fn zhang(hs: &[[[f64; 3]; 3]]) -> Option<(f64, f64, f64, f64)> {
    let col = |h: &[[f64; 3]; 3], i: usize| [h[0][i], h[1][i], h[2][i]];
    let v = |a: [f64; 3], b: [f64; 3]| {
        [
            a[0] * b[0],
            a[0] * b[1] + a[1] * b[0],
            a[1] * b[1],
            a[2] * b[0] + a[0] * b[2],
            a[2] * b[1] + a[1] * b[2],
            a[2] * b[2],
        ]
    };
    let mut vtv = [[0.0f64; 6]; 6];
    let mut add = |row: [f64; 6], weight: f64| {
        for i in 0..6 {
            for j in 0..6 {
                vtv[i][j] += weight * row[i] * row[j];
            }
        }
    };
    for h in hs {
        let (h1, h2) = (col(h, 0), col(h, 1));
        let v12 = v(h1, h2);
        let (v11, v22) = (v(h1, h1), v(h2, h2));
        let norm = v11.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-12);
        add(v12.map(|x| x / norm), 1.0);
        add([0, 1, 2, 3, 4, 5].map(|k| (v11[k] - v22[k]) / norm), 1.0);
    }
    add([0.0, 1.0, 0.0, 0.0, 0.0, 0.0], 1.0); // no skew
    let (values, vectors) = geom::symmetric_eigen(vtv);
    let k = (0..6).min_by(|&i, &j| values[i].total_cmp(&values[j]))?;
    let mut b: [f64; 6] = [0, 1, 2, 3, 4, 5].map(|i| vectors[i][k]);
    if b[0] < 0.0 {
        b = b.map(|x| -x);
    }
    let [b11, b12, b22, b13, b23, b33] = b;
    let den = b11 * b22 - b12 * b12;
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha = (lambda / b11).sqrt();
    let beta = (lambda * b11 / den).sqrt();
    let u0 = -b13 * alpha * alpha / lambda;
    [alpha, beta, u0, v0]
        .iter()
        .all(|x| x.is_finite())
        .then_some((alpha, beta, u0, v0))
}

/// One focal length with the principal point at the origin (normalised pixels): from each homography's two
/// orthogonality constraints, least squares in 1/f².
fn focal_with_centred_point(hs: &[[[f64; 3]; 3]]) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for h in hs {
        let (h11, h21, h31) = (h[0][0], h[1][0], h[2][0]);
        let (h12, h22, h32) = (h[0][1], h[1][1], h[2][1]);
        // a · (1/f²) = b for each constraint.
        for (a, b) in [
            (h11 * h12 + h21 * h22, -h31 * h32),
            (h11 * h11 + h21 * h21 - h12 * h12 - h22 * h22, h32 * h32 - h31 * h31),
        ] {
            num += a * b;
            den += a * a;
        }
    }
    let inv_f2 = num / den;
    (inv_f2 > 0.0 && inv_f2.is_finite()).then(|| 1.0 / inv_f2.sqrt())
}

/// A view's pose from its homography and the lens (distortion ignored), the rotation made orthonormal.
fn initial_pose(lens: &Lens, v: &ViewPoints) -> Option<BoardPose> {
    let normalised: Vec<[f64; 2]> = v.image.iter().map(|p| lens.undistort(p[0], p[1])).collect();
    let h = homography::fit(&v.board, &normalised)?;
    let col = |i: usize| Vec3::new(h[0][i], h[1][i], h[2][i]);
    let (h1, h2, h3) = (col(0), col(1), col(2));
    let mut lambda = 1.0 / h1.norm();
    if (h3 * lambda).z < 0.0 {
        lambda = -lambda; // the board in front of the camera
    }
    let (r1, r2, t) = (h1 * lambda, h2 * lambda, h3 * lambda);
    // The nearest rotation to [r1 r2 r1×r2]: Gram–Schmidt on the mean of the two in-plane axes.
    let r1n = r1 * (1.0 / r1.norm());
    let r2o = r2 - r1n * r1n.dot(r2);
    let r2n = r2o * (1.0 / r2o.norm());
    let r3 = r1n.cross(r2n);
    let m = Mat3 {
        m: [[r1n.x, r2n.x, r3.x], [r1n.y, r2n.y, r3.y], [r1n.z, r2n.z, r3.z]],
    };
    Some(BoardPose {
        rotation: Quat::from_mat(&m).unit(),
        translation: t,
    })
}

/// Lens numbers, then a view's rotation increment (3) and translation increment (3).
const SLOTS: usize = LENS_PARAMETERS + 6;

/// A point's reprojection residual (pixels) and its derivatives by the lens numbers and the view's pose
/// increments at zero.
pub fn residual_with_jacobian(lens: &Lens, pose: &BoardPose, board: [f64; 2], image: [f64; 2]) -> [Dual<SLOTS>; 2] {
    let a = lens.to_array();
    let lens_d: [Dual<SLOTS>; LENS_PARAMETERS] = std::array::from_fn(|i| Dual::var(a[i], i));
    let phi = Vec3::new(Dual::var(0.0, 9), Dual::var(0.0, 10), Dual::var(0.0, 11));
    let dt = Vec3::new(Dual::var(0.0, 12), Dual::var(0.0, 13), Dual::var(0.0, 14));
    let rotation = Quat::exp(phi) * Quat::lift(pose.rotation);
    let p = rotation.rotate(Vec3::new(Dual::new(board[0]), Dual::new(board[1]), Dual::new(0.0)))
        + Vec3::lift(pose.translation)
        + dt;
    let [u, v] = project_with(&lens_d, p);
    [u - image[0], v - image[1]]
}

/// Each point's reprojection error, pixels.
fn residual_norms(views: &[ViewPoints], lens: &Lens, poses: &[BoardPose]) -> Vec<Vec<f64>> {
    views
        .iter()
        .zip(poses)
        .map(|(v, pose)| {
            v.board
                .iter()
                .zip(&v.image)
                .map(|(b, i)| {
                    let p = pose.rotation.rotate(Vec3::new(b[0], b[1], 0.0)) + pose.translation;
                    let [u, w] = lens.project(p);
                    ((u - i[0]).powi(2) + (w - i[1]).powi(2)).sqrt()
                })
                .collect()
        })
        .collect()
}

/// The robust cost: Huber on each point's error with threshold `huber` pixels (∞: least squares).
fn cost(views: &[ViewPoints], kept: &[Vec<bool>], lens: &Lens, poses: &[BoardPose], huber: f64) -> f64 {
    residual_norms(views, lens, poses)
        .iter()
        .zip(kept)
        .flat_map(|(r, k)| r.iter().zip(k).filter(|(_, &k)| k).map(|(e, _)| *e))
        .map(|e| {
            if e <= huber {
                0.5 * e * e
            } else {
                huber * (e - 0.5 * huber)
            }
        })
        .sum()
}

/// Levenberg–Marquardt over the free lens numbers and every pose.
#[allow(clippy::too_many_arguments)]
fn refine(
    views: &[ViewPoints],
    kept: &[Vec<bool>],
    lens: &mut Lens,
    poses: &mut [BoardPose],
    free: &[bool; LENS_PARAMETERS],
    huber: f64,
    max_iterations: usize,
    image_scale: f64,
) {
    const L: usize = LENS_PARAMETERS;
    let mut damping = 1e-3;
    let mut current = cost(views, kept, lens, poses, huber);
    for _ in 0..max_iterations {
        // Normal equations: U (lens), W (lens × view), V (view), and the gradients.
        let mut u = vec![0.0; L * L];
        let mut g_lens = vec![0.0; L];
        let mut blocks = Vec::with_capacity(views.len());
        for ((v, pose), k) in views.iter().zip(poses.iter()).zip(kept) {
            let mut w = vec![0.0; L * 6];
            let mut vv = vec![0.0; 36];
            let mut g_view = vec![0.0; 6];
            for ((b, i), &keep) in v.board.iter().zip(&v.image).zip(k) {
                if !keep {
                    continue;
                }
                let r = residual_with_jacobian(lens, pose, *b, *i);
                let e = (r[0].re * r[0].re + r[1].re * r[1].re).sqrt();
                let weight = if e <= huber { 1.0 } else { huber / e };
                for comp in &r {
                    let mut j = comp.eps;
                    for (slot, f) in free.iter().enumerate() {
                        if !f {
                            j[slot] = 0.0;
                        }
                    }
                    for a in 0..L {
                        g_lens[a] += weight * j[a] * comp.re;
                        for c in 0..L {
                            u[a * L + c] += weight * j[a] * j[c];
                        }
                        for c in 0..6 {
                            w[a * 6 + c] += weight * j[a] * j[L + c];
                        }
                    }
                    for a in 0..6 {
                        g_view[a] += weight * j[L + a] * comp.re;
                        for c in 0..6 {
                            vv[a * 6 + c] += weight * j[L + a] * j[L + c];
                        }
                    }
                }
            }
            blocks.push((w, vv, g_view));
        }
        let mut accepted = false;
        while damping < 1e12 {
            let Some((d_lens, d_views)) = solve_step(&u, &g_lens, &blocks, free, damping, image_scale) else {
                damping *= 10.0;
                continue;
            };
            let mut a = lens.to_array();
            for i in 0..L {
                a[i] += d_lens[i];
            }
            let trial_lens = Lens::from_array(a);
            let trial_poses: Vec<BoardPose> = poses.iter().zip(&d_views).map(|(p, d)| apply_increment(p, d)).collect();
            let trial = cost(views, kept, &trial_lens, &trial_poses, huber);
            if trial.is_finite() && trial < current {
                let gain = (current - trial) / current.max(1e-300);
                *lens = trial_lens;
                poses.copy_from_slice(&trial_poses);
                current = trial;
                damping = (damping / 3.0).max(1e-9);
                accepted = true;
                if gain < 1e-12 {
                    return;
                }
                break;
            }
            damping *= 4.0;
        }
        if !accepted {
            return;
        }
    }
}

/// The damped step: views eliminated by the Schur complement, the lens solved, the views back-substituted.
fn solve_step(
    u: &[f64],
    g_lens: &[f64],
    blocks: &[(Vec<f64>, Vec<f64>, Vec<f64>)],
    free: &[bool; LENS_PARAMETERS],
    damping: f64,
    image_scale: f64,
) -> Option<(Vec<f64>, Vec<[f64; 6]>)> {
    const L: usize = LENS_PARAMETERS;
    let mut s = u.to_vec();
    let mut rhs: Vec<f64> = g_lens.iter().map(|g| -g).collect();
    for i in 0..L {
        if free[i] {
            // Marquardt's scaling, with a floor so a parameter the data barely sees still moves a little.
            s[i * L + i] += damping * (u[i * L + i] + 1e-9 * image_scale * image_scale);
        } else {
            for c in 0..L {
                s[i * L + c] = 0.0;
                s[c * L + i] = 0.0;
            }
            s[i * L + i] = 1.0;
            rhs[i] = 0.0;
        }
    }
    let mut inverses = Vec::with_capacity(blocks.len());
    for (w, vv, g_view) in blocks {
        let mut damped = vv.clone();
        for i in 0..6 {
            damped[i * 6 + i] += damping * vv[i * 6 + i] + 1e-12;
        }
        let inv = spd_inverse(&damped, 6)?;
        // s -= W V⁻¹ Wᵀ; rhs -= W V⁻¹ (−g_view)
        let mut wv = vec![0.0; L * 6];
        for a in 0..L {
            for c in 0..6 {
                wv[a * 6 + c] = (0..6).map(|k| w[a * 6 + k] * inv[k * 6 + c]).sum();
            }
        }
        for a in 0..L {
            if !free[a] {
                continue;
            }
            for c in 0..L {
                if free[c] {
                    s[a * L + c] -= (0..6).map(|k| wv[a * 6 + k] * w[c * 6 + k]).sum::<f64>();
                }
            }
            rhs[a] += (0..6).map(|k| wv[a * 6 + k] * g_view[k]).sum::<f64>();
        }
        inverses.push(inv);
    }
    let d_lens = cholesky_solve(&s, &rhs, L)?;
    let mut d_views = Vec::with_capacity(blocks.len());
    for ((w, _, g_view), inv) in blocks.iter().zip(&inverses) {
        // V δv = −g_view − Wᵀ δlens
        let b: Vec<f64> = (0..6)
            .map(|c| -g_view[c] - (0..L).map(|a| w[a * 6 + c] * d_lens[a]).sum::<f64>())
            .collect();
        d_views.push(std::array::from_fn(|r| (0..6).map(|k| inv[r * 6 + k] * b[k]).sum()));
    }
    Some((d_lens, d_views))
}

/// Whether a view's camera is on the printed side of the board (OpenCV's board frame: the printed face
/// looks along −z), as every real photo's is.
pub fn sees_printed_face(pose: &BoardPose) -> bool {
    pose.rotation.conj().rotate(pose.translation).z > 0.0
}

/// Views whose board points ended up behind their camera, turned to the pose in front of it that projects
/// every point of the board's plane to the same pixel.
///
/// A pinhole divides by depth, so `p ↦ −p` (every board point behind the camera, mirrored through it) leaves
/// every projection as it was: the pose `(R·Rz(π), −t)` has exactly the cost of `(R, t)`. A view seen
/// small (a few markers) can start there or slide there; it is the camera mirrored through the board,
/// turned 180° (seen in a ChArUco session at 480 × 360 with three markers in view: 170 mm off, the
/// reprojection error 0.13 px).
fn unflip(views: &[ViewPoints], poses: &mut [BoardPose]) {
    let half_turn = Quat::new(0.0, 0.0, 0.0, 1.0); // π about z
    for (v, p) in views.iter().zip(poses.iter_mut()) {
        let depth: f64 = v
            .board
            .iter()
            .map(|b| (p.rotation.rotate(Vec3::new(b[0], b[1], 0.0)) + p.translation).z)
            .sum();
        if depth < 0.0 {
            *p = BoardPose {
                rotation: (p.rotation * half_turn).unit(),
                translation: p.translation * -1.0,
            };
        }
    }
}

/// The pose moved by a rotation increment (applied on the left) and a translation increment.
fn apply_increment(p: &BoardPose, d: &[f64; 6]) -> BoardPose {
    BoardPose {
        rotation: (Quat::exp(Vec3::new(d[0], d[1], d[2])) * p.rotation).unit(),
        translation: p.translation + Vec3::new(d[3], d[4], d[5]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geom::SplitMix64;

    fn board_grid() -> Vec<[f64; 2]> {
        (0..9 * 6)
            .map(|i| [(i % 9) as f64 * 0.03, (i / 9) as f64 * 0.03])
            .collect()
    }

    fn true_lens() -> Lens {
        Lens {
            fx: 912.0,
            fy: 908.0,
            cx: 486.0,
            cy: 352.0,
            distortion: [-0.21, 0.09, 0.0008, -0.0005, 0.0],
        }
    }

    /// Views of the grid from around it, the board 35–60 cm away, tilted up to ~45°.
    fn views(noise: f64, seed: u64) -> (Vec<ViewPoints>, Vec<BoardPose>) {
        let lens = true_lens();
        let mut rng = SplitMix64::new(seed);
        let (mut out, mut poses) = (Vec::new(), Vec::new());
        let centre = Vec3::new(0.12, 0.075, 0.0);
        for k in 0..12 {
            let axis = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0);
            let tilt = rng.range(0.15, 0.75);
            let rotation =
                Quat::exp(axis * (tilt / axis.norm())) * Quat::exp(Vec3::new(0.0, 0.0, rng.range(-3.0, 3.0)));
            let distance = rng.range(0.35, 0.6);
            let shift = Vec3::new(rng.range(-0.08, 0.08), rng.range(-0.05, 0.05), distance);
            let translation = shift - rotation.rotate(centre);
            let pose = BoardPose { rotation, translation };
            let mut v = ViewPoints::default();
            for b in board_grid() {
                let p = rotation.rotate(Vec3::new(b[0], b[1], 0.0)) + translation;
                let [u, w] = lens.project(p);
                let gauss = |rng: &mut SplitMix64| {
                    (-2.0 * rng.next_f64().max(1e-12).ln()).sqrt() * (std::f64::consts::TAU * rng.next_f64()).cos()
                };
                if u > 0.0 && w > 0.0 && u < 971.0 && w < 719.0 {
                    v.board.push(b);
                    v.image.push([u + noise * gauss(&mut rng), w + noise * gauss(&mut rng)]);
                }
            }
            let _ = k;
            out.push(v);
            poses.push(pose);
        }
        (out, poses)
    }

    /// The pose with every point behind the camera projects the same; `unflip` turns it back in front.
    #[test]
    fn a_pose_behind_the_camera_is_turned_to_the_one_in_front() {
        let (views, truth) = views(0.0, 4);
        let lens = true_lens();
        let mirrored: Vec<BoardPose> = truth
            .iter()
            .map(|p| BoardPose {
                rotation: p.rotation * Quat::new(0.0, 0.0, 0.0, 1.0),
                translation: p.translation * -1.0,
            })
            .collect();
        let before = residual_norms(&views, &lens, &mirrored);
        assert!(before.iter().flatten().all(|e| *e < 1e-6), "the same pixels");
        assert!(mirrored.iter().all(|p| !sees_printed_face(p)));
        let mut poses = mirrored.clone();
        unflip(&views, &mut poses);
        for (p, t) in poses.iter().zip(&truth) {
            assert!(geom::rotation_distance(p.rotation, t.rotation) < 1e-9);
            assert!((p.translation - t.translation).norm() < 1e-12);
            assert!(sees_printed_face(p));
        }
    }

    #[test]
    fn the_jacobian_is_the_finite_difference_one() {
        let (vs, poses) = views(0.0, 3);
        let lens = true_lens();
        let (b, i) = (vs[2].board[7], vs[2].image[7]);
        let r = residual_with_jacobian(&lens, &poses[2], b, i);
        let f = |x: &[f64]| {
            let mut a = lens.to_array();
            a.copy_from_slice(&x[..9]);
            let p = apply_increment(&poses[2], &[x[9], x[10], x[11], x[12], x[13], x[14]]);
            let q = p.rotation.rotate(Vec3::new(b[0], b[1], 0.0)) + p.translation;
            let [u, v] = Lens::from_array(a).project(q);
            vec![u - i[0], v - i[1]]
        };
        let mut x = lens.to_array().to_vec();
        x.extend([0.0; 6]);
        let numeric = testkit::finite_difference_jacobian(&f, &x, 1e-6);
        for c in 0..2 {
            for k in 0..SLOTS {
                let (a, n) = (r[c].eps[k], numeric[c][k]);
                assert!((a - n).abs() <= 1e-4 * (1.0 + n.abs()), "d r{c} / d x{k}: {a} vs {n}");
            }
        }
    }

    #[test]
    fn recovers_the_lens_and_poses_from_noisy_views() {
        let (vs, truth) = views(0.15, 11);
        let c = calibrate(&vs, (972, 720), &CalibrationSettings::default()).unwrap();
        let t = true_lens();
        assert!(
            (c.lens.fx / t.fx - 1.0).abs() < 0.002 && (c.lens.fy / t.fy - 1.0).abs() < 0.002,
            "{:?}",
            c.lens
        );
        assert!(
            (c.lens.cx - t.cx).abs() < 1.5 && (c.lens.cy - t.cy).abs() < 1.5,
            "{:?}",
            c.lens
        );
        assert!((c.lens.distortion[0] - t.distortion[0]).abs() < 0.01, "{:?}", c.lens);
        assert!(c.rms < 0.25, "rms {}", c.rms);
        assert!(
            c.centre_sigma.iter().all(|s| *s > 0.0 && *s < 0.002),
            "{:?}",
            c.centre_sigma
        );
        for (p, q) in c.poses.iter().zip(&truth) {
            let centre = |p: &BoardPose| p.rotation.conj().rotate(-p.translation);
            assert!(
                (centre(p) - centre(q)).norm() < 0.002,
                "{:?} vs {:?}",
                centre(p),
                centre(q)
            );
            assert!(geom::rotation_distance(p.rotation, q.rotation) < 0.2f64.to_radians());
        }
    }
}
