//! The state of a body over time, generic over the scalar.

use geom::{Pose, Quat, Real, Vec3};

/// Pose and velocities of one body. `omega` is in the world frame, rad/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState<S> {
    pub pose: Pose<S>,
    pub v: Vec3<S>,
    pub omega: Vec3<S>,
}

/// Number of numbers in [`BodyState::to_array`].
pub const STATE_LEN: usize = 13;

impl<S: Real> BodyState<S> {
    pub fn re(&self) -> BodyState<f64> {
        BodyState {
            pose: self.pose.re(),
            v: self.v.re(),
            omega: self.omega.re(),
        }
    }

    /// `[t(3), q(4) as w,x,y,z, v(3), omega(3)]`.
    pub fn to_array(&self) -> [S; STATE_LEN] {
        let (t, q, v, w) = (self.pose.t, self.pose.q, self.v, self.omega);
        [t.x, t.y, t.z, q.w, q.x, q.y, q.z, v.x, v.y, v.z, w.x, w.y, w.z]
    }
}

impl BodyState<f64> {
    pub fn new(t: [f64; 3], q: [f64; 4], v: [f64; 3], omega: [f64; 3]) -> Self {
        Self {
            pose: Pose::new(Quat::cst(q).unit(), Vec3::cst(t)),
            v: Vec3::cst(v),
            omega: Vec3::cst(omega),
        }
    }
}
