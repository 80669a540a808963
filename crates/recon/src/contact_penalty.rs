//! The contact penalty of Eq. 10 for a pose fitted from images (GA): in a
//! frame where the body is known to touch the scene (PA's simulated body on
//! it when the frame is taken, or a contact that lasts over the fitted frames
//! around it), the pose must neither float above the scene (the monocular
//! drift toward the camera of the paper's Fig. 11, invisible from the video's
//! own view) nor sink into it; elsewhere a body near the scene is only kept
//! from sinking (`lambda_out` 0). The points are those within the contact
//! threshold; at the pose being fitted, with `s_j` their signed distances to
//! the scene and σ a length scale:
//!
//! - sinking, `λ_in · mean_j (exp(max(0, −s_j) / σ) − 1)`,
//! - floating, `λ_out · Σ_sides (exp(max(0, min_{j facing the side} s_j) / σ) − 1)`:
//!   on each side of the scene the contact is known on (the board, a wall: the
//!   scene's normal there), the nearest point facing it must touch. A body that
//!   hits a wall while it slides on the board touches both; with one nearest
//!   point for the whole scene, the wall's held it and the body floated up the
//!   wall along the line of sight (the demo slide's frame 10: 10 mm above the
//!   board, 14 mm off).
//!
//! The paper's form divides by PA's own distances instead of σ; a fixed scale
//! keeps the penalty finite where PA's point sat exactly on the surface.
//!
//! Both terms leave to the image what it can tell: a point counts only beyond
//! the image's own precision along the scene's normal there (`τ`, one
//! standard deviation of [`ImagePrecision`] times `image_slack`; `s_j − τ`
//! and `−s_j − τ` above). The penalty is there for the drift the image cannot
//! see (centimetres along the line of sight); at the surface, a reconstructed
//! scene a millimetre high (a board's undulation, the fillet at a wall's
//! foot) would otherwise override the depth the image tells, and a pose held
//! on it is lifted by that millimetre and slid along the line of sight by
//! more (the tabletop slide: 2.8 mm off on average held at the surface,
//! against 1.1 mm without the penalty).

use crate::image_precision::ImagePrecision;
use geom::{Pose, Vec3};
use serde::{Deserialize, Serialize};
use sim::sdf::Shape;
use sim::RigidBody;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactPenaltyConfig {
    /// λ_in. Default 0.05.
    pub lambda_in: f64,
    /// λ_out. Default 0.05.
    pub lambda_out: f64,
    /// σ, m. Default 0.002.
    pub scale: f64,
    /// The image's precision along the scene's normal within which a point costs nothing, in standard
    /// deviations of [`ImagePrecision`] (0: the penalty acts from the surface on, as in the paper).
    /// Default 1.
    pub image_slack: f64,
}

impl Default for ContactPenaltyConfig {
    fn default() -> Self {
        Self {
            lambda_in: 0.05,
            lambda_out: 0.05,
            scale: 0.002,
            image_slack: 1.0,
        }
    }
}

impl ContactPenaltyConfig {
    /// Whether a pose this penalty held on the scene has its depth pinned closer than its image tells it
    /// (PGA then counts that frame's depth as it counts the rest: [`crate::Observed::depth_held`]): only
    /// with less slack than the image's own precision.
    pub fn pins_depth(&self) -> bool {
        self.image_slack < 1.0
    }
}

/// The penalty of one frame: the body, the scene and the body's points PA had in contact.
pub struct ContactTerm<'a> {
    pub body: &'a RigidBody,
    pub scene: &'a Shape,
    /// Indices into the body's contact points.
    pub points: Vec<usize>,
    /// The sides of the scene the body is known to touch ([`contact_sides`]): unit normals of the scene.
    /// Empty: one side, whichever the nearest point faces.
    pub sides: Vec<Vec3<f64>>,
    /// How precisely the frame's image places the body (None: as precisely as the surface, no slack).
    pub seen: Option<ImagePrecision>,
    pub cfg: ContactPenaltyConfig,
}

/// A point's signed distance to the scene, where it is and the scene's normal there.
type Touch = (f64, Vec3<f64>, Vec3<f64>);

/// A point faces a side where the scene's normal at it is within 45° of the side's.
const SIDE_COS: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Whether the scene normal `n` at a point faces `side`.
pub fn faces(n: Vec3<f64>, side: Vec3<f64>) -> bool {
    n.dot(side) >= SIDE_COS * n.norm()
}

/// The sides of the scene that points at these scene normals touch: one unit normal per group of
/// normals within 45° of each other (the first of the group stands for it).
pub fn contact_sides(normals: impl IntoIterator<Item = Vec3<f64>>) -> Vec<Vec3<f64>> {
    let mut sides: Vec<Vec3<f64>> = Vec::new();
    for n in normals {
        let len = n.norm();
        if len > 0.0 && !sides.iter().any(|&s| faces(n, s)) {
            sides.push(n * (1.0 / len));
        }
    }
    sides
}

impl ContactTerm<'_> {
    /// The slack `τ` at a point where the scene's normal is `n`.
    fn slack(&self, n: Vec3<f64>) -> f64 {
        self.seen
            .map_or(0.0, |p| self.cfg.image_slack.max(0.0) * p.along_direction(n))
    }

    /// The penalty at `pose` and its gradient `[dL/dδt, dL/dδω]` (world axes, rotation about the body
    /// origin). The slack follows the scene's normal, whose change from point to point the gradient
    /// leaves out (the normal turns over centimetres, the slack is millimetres).
    pub fn evaluate(&self, pose: &Pose<f64>) -> (f64, [f64; 6]) {
        if self.points.is_empty() {
            return (0.0, [0.0; 6]);
        }
        let rot = pose.q.to_mat();
        let c = &self.cfg;
        let m = self.points.len() as f64;
        let mut value = 0.0;
        let mut grad = [0.0; 6];
        let mut add = |w: f64, x: geom::Vec3<f64>, n: geom::Vec3<f64>| {
            // d s / d δt = ∇s; d s / d δω = (x − t) × ∇s.
            let r = (x - pose.t).cross(n);
            for (g, d) in grad.iter_mut().zip([n.x, n.y, n.z, r.x, r.y, r.z]) {
                *g += w * d;
            }
        };
        // The nearest point on each side (one side, any normal, when none is given).
        let sides = self.sides.len().max(1);
        let mut nearest: Vec<Option<Touch>> = vec![None; sides];
        for &i in &self.points {
            let x = pose.t + rot.mul_vec(self.body.contact_points[i]);
            let (s, n) = sim::sdf::Sdf::distance_grad_local(self.scene, x);
            let sunk = -s - self.slack(n);
            if sunk > 0.0 {
                let e = (sunk / c.scale).exp();
                value += c.lambda_in * (e - 1.0) / m;
                add(-c.lambda_in * e / (c.scale * m), x, n);
            }
            for (k, best) in nearest.iter_mut().enumerate() {
                let facing = self.sides.get(k).is_none_or(|&side| faces(n, side));
                if facing && best.is_none_or(|(b, _, _)| s < b) {
                    *best = Some((s, x, n));
                }
            }
        }
        for (s, x, n) in nearest.into_iter().flatten() {
            let floating = s - self.slack(n);
            if floating <= 0.0 {
                continue;
            }
            let e = (floating / c.scale).exp();
            value += c.lambda_out * (e - 1.0);
            add(c.lambda_out * e / c.scale, x, n);
        }
        (value, grad)
    }
}
