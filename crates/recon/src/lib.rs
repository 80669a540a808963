//! Inverse problems on the differentiable simulator: the PGA step of Eq. 11
//! (physics from a pose sequence) and target reaching (Sec. 4.1).

pub mod fit_physics;
pub mod least_squares;
pub mod target;

pub use fit_physics::{
    fit_multi_start, FitError, FitStats, MultiStart, PhysicsFit, PhysicsFitConfig, PoseError, StartResult,
    CONTACT_STARTS,
};
pub use target::{TargetConfig, TargetError, TargetReach, TargetStats};
