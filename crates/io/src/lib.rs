//! File formats of pganeus, as fixed by `docs/formats.md`:
//!
//! - `truth.json` ([`Truth`]) and `trajectory.json` ([`Trajectory`]): checked on
//!   reading (finite numbers, unit quaternions `[w, x, y, z]`, `fps > 0`) and
//!   round-tripping any extra keys;
//! - PLY meshes and point clouds ([`read_ply`], [`write_ply`]): ASCII and binary
//!   of either byte order;
//! - OBJ meshes ([`read_obj`]);
//! - PNG images ([`read_png`], [`write_png`]), brought to 8-bit gray, RGB or
//!   RGBA ([`Image`]); deterministic, fast encoding;
//! - NumPy arrays: `.npy` ([`read_npy`], [`write_npy`]) and `.npz` archives
//!   ([`read_npz`], [`write_npz`]), the ZIP container through the `zip`
//!   crate (stored and DEFLATE entries, CRC-checked; stored, deterministic
//!   writing);
//! - safetensors checkpoints ([`read_safetensors`], [`write_safetensors`],
//!   [`SafeTensors`]): every offset and length checked on reading;
//! - the NeuS capture folder of docs/formats.md, "A capture": [`open_capture`]
//!   lists and checks `image/`, `mask/`, `mask_<name>/`, `cameras_sphere.npz`
//!   ([`read_cameras_npz`], [`write_cameras_npz`]) and `capture.json`
//!   ([`CaptureInfo`]).
//!
//! Every write goes through [`write_atomic`], so a crash never leaves half a
//! file. Errors are one [`IoError`] enum whose variants carry the path.
//!
//! This crate carries out no equation of the paper; it only moves data.

mod atomic;
mod error;
pub mod formats;
mod paths;

pub use atomic::{write_atomic, StagedDir};
pub use error::{IoError, Result};
pub use formats::image_file::{is_image_file, read_image, read_image_size};
pub use formats::jpeg::{encode_jpeg, read_jpeg, read_jpeg_bytes, write_jpeg};
pub use formats::mesh_file::read_mesh;
pub use formats::neus::{
    open_capture, read_cameras_npz, read_capture_info, write_cameras_npz, write_capture_info, CameraMats, CaptureIndex,
    CaptureInfo, CaptureKind, CaptureSubject, CAMERAS_FILE, CAPTURE_INFO_FILE, EXTRA_MASK_PREFIX, IMAGE_DIR, MASK_DIR,
};
pub use formats::npz::{
    npy_bytes, npz_bytes, read_npy, read_npy_bytes, read_npz, read_npz_bytes, write_npy, write_npz, NpyArray, NpyData,
};
pub use formats::obj::{read_obj, read_obj_bytes};
pub use formats::ply::{
    read_ply, read_ply_bytes, write_ply, write_ply_bytes, write_ply_bytes_with, write_ply_with, PlyEncoding, PlyMesh,
    PlyWriteOptions,
};
pub use formats::png::{
    encode_png, read_png, read_png_bytes, read_png_size, write_apng, write_png, write_png_at_dpi, Image,
};
pub use formats::safetensors::{
    read_safetensors, read_safetensors_bytes, safetensors_bytes, write_safetensors, SafeTensors, Tensor, TensorData,
    TensorError,
};
pub use formats::trajectory::{
    read_trajectory, read_trajectory_bytes, read_truth, read_truth_bytes, write_trajectory, write_trajectory_bytes,
    write_truth, write_truth_bytes, Background, BodyState, Contact, Pose, StaticCapture, Trajectory, Truth, TruthBody,
    VideoBody, QUAT_UNIT_TOLERANCE,
};
pub use paths::{path_relative_to, resolve_from};
