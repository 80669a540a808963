//! Inverse problems on the differentiable simulator: the PGA step of Eq. 11
//! (physics from a pose sequence) and target reaching (Sec. 4.1).

pub mod body_masks;
pub mod brightness_drift;
mod clearance;
pub mod colliding_bodies;
pub mod contact_penalty;
pub mod exposure_gain;
pub mod first_pose_search;
pub mod fit_physics;
pub mod flight;
pub mod horizon;
pub mod image_loss;
pub mod image_precision;
pub mod least_squares;
pub mod mask_edges;
pub mod object_masks;
pub mod physics_from_video;
pub mod pick;
pub mod pose_from_image;
pub mod poses_from_video;
pub mod reported_poses;
pub mod rest;
pub mod resting_start;
pub mod seen_space;
pub mod shutter;
pub mod target;
mod unknowns;
pub mod value_ranges;
pub mod video_fit;
pub mod video_masks;

pub use brightness_drift::brightness_drift;
pub use colliding_bodies::{
    colliding_value_ranges, first_contacts, fit_colliding_bodies, fit_colliding_bodies_holding_launch, CollidingFit,
    LaunchSettings, ObservedBodies, ScheduleStep,
};
pub use contact_penalty::{contact_sides, ContactPenaltyConfig, ContactTerm};
pub use first_pose_search::{search_first_pose, Candidate, FirstPoseSearchConfig};
pub use fit_physics::{
    fit_multi_start, fit_multi_start_bodies, ContactValue, FitError, FitStats, MultiStart, Observed, PhysicsFit,
    PhysicsFitConfig, PoseError, StartContact, StartResult, StartsOn, CONTACT_STARTS,
};
pub use flight::{check_flight, check_window, first_contact_frame, fit_holding_launch, FlightCheck, MIN_FLIGHT_FRAMES};
pub use horizon::{predictable_frames, Horizon, HORIZON_PX};
pub use image_loss::{FrameError, FrameTarget, ImageLoss, ImageLossWeights, PreparedFrame};
pub use image_precision::ImagePrecision;
pub use physics_from_video::{
    PhysicsFromVideo, VideoPhysicsConfig, VideoPhysicsError, VideoPhysicsResult, VideoPhysicsStats,
};
pub use pick::{among_ties, better_per_frame, PGA_TIE};
pub use pose_from_image::{PoseFitConfig, PoseFitError, PoseFromImage};
pub use poses_from_video::{
    FramePose, PosesFromVideo, PosesFromVideoConfig, PosesFromVideoError, StartFrom, STILL_LOSS_SLACK,
};
pub use reported_poses::{reported_poses, simulation_misses, ReportedPose};
pub use resting_start::{resting_start, RestingStart};
pub use seen_space::scene_less_seen;
pub use shutter::Motion;
pub use target::{TargetConfig, TargetError, TargetReach, TargetStats};
pub use value_ranges::{
    contact_value_ranges, widen_by_ranges, widen_by_starts, RangeScan, ValueRange, RANGE_LOSS_RATIO,
};
pub use video_fit::VideoFitConfig;
pub use video_masks::{video_masks, VideoMaskConfig, VideoMaskStats};
