//! Settings of a simulation and of contacts, with their checks.

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{field}: {msg}")]
pub struct ConfigError {
    /// The offending field, e.g. `contact.restitution`.
    pub field: String,
    pub msg: String,
}

impl ConfigError {
    pub fn new(field: impl Into<String>, msg: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            msg: msg.into(),
        }
    }
}

/// Time stepping and global physics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// Frames per second of the recorded trajectory (one pose per frame). Default 60.
    pub fps: f64,
    /// Number of frames recorded, frame 0 being the initial state. Default 60.
    pub frames: usize,
    /// Solver substeps per frame (dt = 1 / (fps · substeps)). Default 10.
    pub substeps: usize,
    /// m/s². Default (0, 0, −9.81).
    pub gravity: [f64; 3],
    /// Factor applied to the linear velocity every substep (1 = no damping). Default 1.
    pub linear_damping: f64,
    /// Factor applied to the angular velocity every substep (1 = no damping). Default 1.
    pub angular_damping: f64,
    /// Δ of Eq. 8: a point within this distance of a surface may collide, m. Default 0.005.
    pub contact_threshold: f64,
    /// Normal speeds below this bounce with restitution 0, so resting bodies
    /// stay still, m/s. Default: 2 |g| dt.
    pub restitution_threshold: Option<f64>,
    /// Also require that a point would reach the surface within the substep
    /// (`d + dt · v·n ≤ 0`) before it collides. Without it every point inside
    /// the Δ skin that moves inwards is stopped, so bodies hover up to Δ above
    /// the ground, tilted. `false` is Eq. 8 exactly as the paper writes it. Default true.
    pub speculative_contacts: bool,
    /// How friction limits the tangential impulse (`mean_point` only). Default `coulomb`.
    pub friction_model: FrictionModel,
    /// How simultaneous contact points act. Default `mean_point` (the paper's).
    pub contact_model: ContactModel,
    /// Sweeps of the `multi_point` solver over its contact points. Default 10.
    pub solver_sweeps: usize,
    /// Slide each contact point near the other surface along its body's surface to where that surface
    /// faces the other one (its support), where the body curves: a ball rolls as a ball, not as a
    /// polyhedron of its samples that knocks and bounces at each one. Flat faces and corners keep their
    /// samples. Default false (the samples as they are, the paper's): on the reconstructed toy they made
    /// `fit`'s drops worse and its PGA twice as slow (README, "The contact model").
    pub support_points: bool,
}

/// How the colliding points of a body against the scene or another body act.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactModel {
    /// The paper's: one impulse at the mean of the colliding points, plus torsional friction of the patch.
    /// It cannot tip a body over an edge or rock it on its support. A turn about the impulse's point is
    /// free in its derivatives (the values stay flat only because the colliding set shifts), so where a
    /// body rests or slides on a face over its centre of mass the derivatives of its tilt rate are held
    /// at zero (a tilt hold; the values are untouched; see the README).
    #[default]
    MeanPoint,
    /// Each patch of colliding points (grouped by normal) reduced to at most four points spanning its
    /// support polygon; their impulses solved together by sequential impulses (projected Gauss–Seidel,
    /// `solver_sweeps` sweeps), Coulomb friction per point, restitution per point with the threshold.
    MultiPoint,
}

/// The friction law of a contact impulse.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionModel {
    /// Impulse space: the tangential impulse is at most `mu` times the normal
    /// impulse (Coulomb's law for the impulse, as Mirtich and rapier do). A box
    /// sliding on a plane stops after v²/(2 mu g) whatever its shape.
    #[default]
    Coulomb,
    /// Velocity space, as DESIGN.md writes it: `v_t' = max(0, 1 − mu (1+k_n)
    /// |v_n| / |v_t|) v_t` at the contact point. The impulse ratio then
    /// depends on the body's inertia: a flat box on a plane stops ~5 % early.
    Velocity,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            fps: 60.0,
            frames: 60,
            substeps: 10,
            gravity: [0.0, 0.0, -9.81],
            linear_damping: 1.0,
            angular_damping: 1.0,
            contact_threshold: 0.005,
            restitution_threshold: None,
            speculative_contacts: true,
            friction_model: FrictionModel::Coulomb,
            contact_model: ContactModel::MeanPoint,
            solver_sweeps: 10,
            support_points: false,
        }
    }
}

fn finite(field: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::new(field, format!("must be a finite number, got {v}")))
    }
}

impl SimConfig {
    /// Substep length, s.
    pub fn dt(&self) -> f64 {
        1.0 / (self.fps * self.substeps as f64)
    }

    pub fn restitution_threshold(&self) -> f64 {
        let g = self.gravity.iter().map(|v| v * v).sum::<f64>().sqrt();
        self.restitution_threshold.unwrap_or(2.0 * g * self.dt())
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        finite("fps", self.fps)?;
        if self.fps <= 0.0 {
            return Err(ConfigError::new("fps", format!("must be positive, got {}", self.fps)));
        }
        if self.frames == 0 {
            return Err(ConfigError::new("frames", "must be at least 1"));
        }
        if self.substeps == 0 {
            return Err(ConfigError::new("substeps", "must be at least 1"));
        }
        for (i, g) in self.gravity.iter().enumerate() {
            finite(&format!("gravity[{i}]"), *g)?;
        }
        for (name, v) in [
            ("linear_damping", self.linear_damping),
            ("angular_damping", self.angular_damping),
        ] {
            finite(name, v)?;
            if !(0.0..=1.0).contains(&v) {
                return Err(ConfigError::new(name, format!("must be in [0, 1] (1 = none), got {v}")));
            }
        }
        finite("contact_threshold", self.contact_threshold)?;
        if self.contact_threshold < 0.0 {
            return Err(ConfigError::new("contact_threshold", "must not be negative"));
        }
        if let Some(v) = self.restitution_threshold {
            finite("restitution_threshold", v)?;
            if v < 0.0 {
                return Err(ConfigError::new("restitution_threshold", "must not be negative"));
            }
        }
        if self.contact_model == ContactModel::MultiPoint && self.solver_sweeps == 0 {
            return Err(ConfigError::new("solver_sweeps", "must be at least 1"));
        }
        Ok(())
    }
}

/// Restitution `k_n` and friction `mu` of a contact, both in (0, 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactParams {
    pub restitution: f64,
    pub friction: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            restitution: 0.3,
            friction: 0.4,
        }
    }
}

impl ContactParams {
    /// `prefix` names the place in the input, e.g. `contact` or `pairs[0]`.
    pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
        for (name, v) in [("restitution", self.restitution), ("friction", self.friction)] {
            if !(v > 0.0 && v < 1.0) {
                return Err(ConfigError::new(
                    format!("{prefix}.{name}"),
                    format!("must be strictly between 0 and 1, got {v}"),
                ));
            }
        }
        Ok(())
    }
}
