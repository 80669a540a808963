//! File formats of pganeus, as fixed by `FORMATS.md`:
//!
//! - `truth.json` ([`Truth`]) and `trajectory.json` ([`Trajectory`]): checked on
//!   reading (finite numbers, unit quaternions `[w, x, y, z]`, `fps > 0`) and
//!   round-tripping any extra keys;
//! - PLY meshes and point clouds ([`read_ply`], [`write_ply`]): ASCII and binary
//!   of either byte order;
//! - OBJ meshes ([`read_obj`]).
//!
//! Every write goes through [`write_atomic`], so a crash never leaves half a
//! file. Errors are one [`IoError`] enum whose variants carry the path.
//!
//! This crate carries out no equation of the paper; it only moves data.

mod atomic;
mod error;
pub mod formats;

pub use atomic::write_atomic;
pub use error::{IoError, Result};
pub use formats::obj::{read_obj, read_obj_bytes};
pub use formats::ply::{
    read_ply, read_ply_bytes, write_ply, write_ply_bytes, write_ply_bytes_with, write_ply_with, PlyEncoding, PlyMesh,
    PlyWriteOptions,
};
pub use formats::trajectory::{
    read_trajectory, read_trajectory_bytes, read_truth, read_truth_bytes, write_trajectory, write_trajectory_bytes,
    write_truth, write_truth_bytes, Background, BodyState, Contact, Pose, StaticCapture, Trajectory, Truth, TruthBody,
    VideoBody, QUAT_UNIT_TOLERANCE,
};
