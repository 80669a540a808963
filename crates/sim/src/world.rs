//! A world (static scene + bodies + contact parameters), its parameter
//! vector, and the time loop: semi-implicit Euler with substeps.

use crate::config::{ConfigError, ContactParams, SimConfig};
use crate::contact::{contact_body_body, contact_body_scene, Detection};
use crate::sdf::Shape;
use crate::{BodyState, RigidBody};
use geom::{Mat3, Quat, Real, Vec3};

/// Parameters per body in the flat parameter vector: translation (3),
/// rotation tangent (3), v (3), omega (3), restitution and friction against the scene.
pub const BODY_PARAMS: usize = 14;
/// Parameters per body pair: restitution and friction.
pub const PAIR_PARAMS: usize = 2;

/// Names of the per-body parameters, in order.
pub const BODY_PARAM_NAMES: [&str; BODY_PARAMS] = [
    "t.x",
    "t.y",
    "t.z",
    "rot.x",
    "rot.y",
    "rot.z",
    "v.x",
    "v.y",
    "v.z",
    "omega.x",
    "omega.y",
    "omega.z",
    "restitution",
    "friction",
];

#[derive(Clone, Debug)]
pub struct World {
    pub config: SimConfig,
    /// The static scene (infinite mass).
    pub scene: Shape,
    pub bodies: Vec<RigidBody>,
    /// State of each body at frame 0.
    pub initial: Vec<BodyState<f64>>,
    /// Contact of each body with the scene.
    pub scene_contact: Vec<ContactParams>,
    /// Contact of each pair `(i, j)`, `i < j`, in the order of [`World::pairs`].
    pub pair_contact: Vec<ContactParams>,
}

/// Which bodies touched what during one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameContacts {
    /// Per body: an impulse against the scene was applied in this frame.
    pub scene: Vec<bool>,
    /// Per body: the most contact points that pushed it against the scene together in one substep (the
    /// mean-point model applies one impulse per contact patch: as many as the patches, at most 3).
    pub scene_points: Vec<usize>,
    /// Per pair (order of [`World::pairs`]): an impulse between the two.
    pub pairs: Vec<bool>,
}

/// States of every body at every frame.
#[derive(Clone, Debug)]
pub struct Trajectory<S> {
    /// `frames[k][b]`: body `b` at frame `k` (its velocity, after frame 0, the one over the last substep:
    /// in flight, the velocity half a substep before the frame).
    pub frames: Vec<Vec<BodyState<S>>>,
    /// `contacts[k]`: contacts during the substeps that led to frame `k` (empty at 0).
    pub contacts: Vec<FrameContacts>,
}

impl World {
    /// An empty world over `scene`.
    pub fn new(config: SimConfig, scene: Shape) -> Self {
        Self {
            config,
            scene,
            bodies: vec![],
            initial: vec![],
            scene_contact: vec![],
            pair_contact: vec![],
        }
    }

    /// Add a body; its pairs with the bodies already present get `pair_contact`.
    pub fn add_body(
        &mut self,
        body: RigidBody,
        initial: BodyState<f64>,
        scene_contact: ContactParams,
        pair_contact: ContactParams,
    ) -> usize {
        // Pairs are ordered (0,1), (0,2), …, (1,2), …: insert the new pairs
        // (i, new) at the end of each i's run.
        let n = self.bodies.len();
        let mut pairs = Vec::with_capacity(self.pair_contact.len() + n);
        let mut old = self.pair_contact.iter();
        for i in 0..n {
            for _ in i + 1..n {
                pairs.push(*old.next().expect("pair count matches bodies"));
            }
            pairs.push(pair_contact);
        }
        self.pair_contact = pairs;
        self.bodies.push(body);
        self.initial.push(initial);
        self.scene_contact.push(scene_contact);
        n
    }

    /// Index of pair `(i, j)` in [`World::pairs`].
    pub fn pair_index(&self, i: usize, j: usize) -> usize {
        let (i, j) = if i < j { (i, j) } else { (j, i) };
        let n = self.bodies.len();
        // Pairs before row i: Σ_{r<i} (n − 1 − r)
        i * (2 * n - i - 1) / 2 + (j - i - 1)
    }

    /// All body pairs `(i, j)` with `i < j`.
    pub fn pairs(&self) -> Vec<(usize, usize)> {
        let n = self.bodies.len();
        (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).collect()
    }

    pub fn param_count(&self) -> usize {
        BODY_PARAMS * self.bodies.len() + PAIR_PARAMS * self.pair_contact.len()
    }

    /// Index of the first parameter of body `b`.
    pub fn body_param_offset(&self, b: usize) -> usize {
        BODY_PARAMS * b
    }

    /// Index of the first parameter of pair `p`.
    pub fn pair_param_offset(&self, p: usize) -> usize {
        BODY_PARAMS * self.bodies.len() + PAIR_PARAMS * p
    }

    /// Readable names of all parameters, e.g. `toy.v.x`, `toy-box.friction`.
    pub fn param_names(&self) -> Vec<String> {
        let mut names = Vec::with_capacity(self.param_count());
        for b in &self.bodies {
            names.extend(BODY_PARAM_NAMES.iter().map(|p| format!("{}.{p}", b.name)));
        }
        for (i, j) in self.pairs() {
            let pair = format!("{}-{}", self.bodies[i].name, self.bodies[j].name);
            names.push(format!("{pair}.restitution"));
            names.push(format!("{pair}.friction"));
        }
        names
    }

    /// The parameter vector of the world as it is (rotation tangents zero).
    pub fn params(&self) -> Vec<f64> {
        let mut p = Vec::with_capacity(self.param_count());
        for (s, c) in self.initial.iter().zip(&self.scene_contact) {
            p.extend(s.pose.t.to_array());
            p.extend([0.0; 3]);
            p.extend(s.v.to_array());
            p.extend(s.omega.to_array());
            p.extend([c.restitution, c.friction]);
        }
        for c in &self.pair_contact {
            p.extend([c.restitution, c.friction]);
        }
        p
    }

    /// Write a parameter vector back (rotation tangents are applied to the
    /// initial orientations).
    pub fn set_params(&mut self, p: &[f64]) {
        assert_eq!(p.len(), self.param_count(), "parameter count");
        for b in 0..self.bodies.len() {
            let o = self.body_param_offset(b);
            let s = &mut self.initial[b];
            s.pose.t = Vec3::new(p[o], p[o + 1], p[o + 2]);
            s.pose.q = (Quat::exp(Vec3::new(p[o + 3], p[o + 4], p[o + 5])) * s.pose.q).normalize_or_identity();
            s.v = Vec3::new(p[o + 6], p[o + 7], p[o + 8]);
            s.omega = Vec3::new(p[o + 9], p[o + 10], p[o + 11]);
            self.scene_contact[b] = ContactParams {
                restitution: p[o + 12],
                friction: p[o + 13],
            };
        }
        for k in 0..self.pair_contact.len() {
            let o = self.pair_param_offset(k);
            self.pair_contact[k] = ContactParams {
                restitution: p[o],
                friction: p[o + 1],
            };
        }
    }

    /// Check everything a run depends on.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.config.validate()?;
        if self.initial.len() != self.bodies.len() || self.scene_contact.len() != self.bodies.len() {
            return Err(ConfigError::new(
                "bodies",
                "every body needs an initial state and contact parameters",
            ));
        }
        if self.pair_contact.len() != self.pairs().len() {
            return Err(ConfigError::new("pairs", "every body pair needs contact parameters"));
        }
        for (b, s) in self.initial.iter().enumerate() {
            let name = &self.bodies[b].name;
            if !s.to_array().iter().all(|v| v.is_finite()) {
                return Err(ConfigError::new(
                    format!("bodies[{b}] ({name})"),
                    "initial state has NaN or infinite values",
                ));
            }
            self.scene_contact[b].validate(&format!("bodies[{b}].contact"))?;
        }
        for (k, c) in self.pair_contact.iter().enumerate() {
            c.validate(&format!("pairs[{k}]"))?;
        }
        Ok(())
    }

    /// Run the simulation with parameters `p` (see [`World::params`]); the
    /// scalar type decides whether derivatives are carried.
    pub fn simulate<S: Real>(&self, p: &[S]) -> Trajectory<S> {
        self.simulate_with_progress(p, &mut |_| {})
    }

    /// [`World::simulate`], calling `on_frame(k)` after each frame is done.
    pub fn simulate_with_progress<S: Real>(&self, p: &[S], on_frame: &mut dyn FnMut(usize)) -> Trajectory<S> {
        assert_eq!(p.len(), self.param_count(), "parameter count");
        let cfg = &self.config;
        let dt = cfg.dt();
        let gdt = Vec3::<S>::cst(cfg.gravity).map(|g| g * dt);
        let det = Detection {
            delta: cfg.contact_threshold,
            speculative_dt: cfg.speculative_contacts.then_some(dt),
            restitution_threshold: cfg.restitution_threshold(),
            friction: cfg.friction_model,
            model: cfg.contact_model,
            sweeps: cfg.solver_sweeps,
            supports: cfg.support_points,
        };
        let pairs = self.pairs();
        let mut states: Vec<BodyState<S>> = (0..self.bodies.len())
            .map(|b| {
                let o = self.body_param_offset(b);
                let v3 = |k: usize| Vec3::new(p[o + k], p[o + k + 1], p[o + k + 2]);
                let q0 = Quat::lift(self.initial[b].pose.q);
                BodyState {
                    pose: geom::Pose::new((Quat::exp(v3(3)) * q0).normalize_or_identity(), v3(0)),
                    v: v3(6),
                    omega: v3(9),
                }
            })
            .collect();
        let mut frames = Vec::with_capacity(cfg.frames);
        let mut contacts = Vec::with_capacity(cfg.frames);
        frames.push(states.clone());
        // Leapfrog's start: the velocity held between substeps is the one at their middle (what moves the
        // body over the substep), so it starts half a substep of gravity back. Free flight then follows the
        // exact parabola (plain semi-implicit Euler from v0 adds ½ g t dt, a few millimetres after a
        // second, which a video of a real throw does not have); contacts are unchanged.
        for st in states.iter_mut() {
            st.v -= gdt * S::cst(0.5);
        }
        contacts.push(FrameContacts {
            scene: vec![false; states.len()],
            scene_points: vec![0; states.len()],
            pairs: vec![false; pairs.len()],
        });
        for _ in 1..cfg.frames {
            let mut log = FrameContacts {
                scene: vec![false; states.len()],
                scene_points: vec![0; states.len()],
                pairs: vec![false; pairs.len()],
            };
            for _ in 0..cfg.substeps {
                for st in states.iter_mut() {
                    st.v = (st.v + gdt) * S::cst(cfg.linear_damping);
                    st.omega = st.omega * S::cst(cfg.angular_damping);
                }
                for (b, st) in states.iter_mut().enumerate() {
                    let o = self.body_param_offset(b);
                    let points = contact_body_scene(&self.bodies[b], st, &self.scene, p[o + 12], p[o + 13], &det);
                    log.scene[b] |= points > 0;
                    log.scene_points[b] = log.scene_points[b].max(points);
                }
                for (k, &(i, j)) in pairs.iter().enumerate() {
                    let o = self.pair_param_offset(k);
                    let (lo, hi) = states.split_at_mut(j);
                    let (si, sj) = (&mut lo[i], &mut hi[0]);
                    let (bi, bj) = (&self.bodies[i], &self.bodies[j]);
                    let h1 = contact_body_body(bi, si, bj, sj, p[o], p[o + 1], &det);
                    let h2 = contact_body_body(bj, sj, bi, si, p[o], p[o + 1], &det);
                    log.pairs[k] |= h1 | h2;
                }
                for (st, body) in states.iter_mut().zip(&self.bodies) {
                    integrate(st, body, dt);
                }
            }
            frames.push(states.clone());
            contacts.push(log);
            on_frame(frames.len() - 1);
        }
        Trajectory { frames, contacts }
    }
}

/// `t ← t + v dt`, `q ← normalize(q + ½ [0, ω dt] ⊗ q)`, then `ω` from the
/// world angular momentum `L = I_w ω`, which no torque changes: without this
/// step an asymmetric body would keep `ω` and lose `L` as it turns.
fn integrate<S: Real>(st: &mut BodyState<S>, body: &RigidBody, dt: f64) {
    st.pose.t += st.v * S::cst(dt);
    let rot = st.pose.q.to_mat();
    let inertia = Mat3::lift(body.inertia);
    let l = rot.mul_mat(&inertia).mul_vec(rot.transpose().mul_vec(st.omega));
    let w = st.omega * S::cst(0.5 * dt);
    let dq = Quat::new(S::zero(), w.x, w.y, w.z) * st.pose.q;
    let q = st.pose.q;
    st.pose.q = Quat::new(q.w + dq.w, q.x + dq.x, q.y + dq.y, q.z + dq.z).normalize_or_identity();
    let rot = st.pose.q.to_mat();
    let inertia_inv = Mat3::lift(body.inertia_inv);
    st.omega = rot.mul_mat(&inertia_inv).mul_vec(rot.transpose().mul_vec(l));
}
