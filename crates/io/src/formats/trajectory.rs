//! `truth.json` and `trajectory.json` (docs/formats.md, "Ground truth" and "Outputs").
//!
//! A `trajectory.json` has exactly the shape of one `videos[*]` entry of a
//! `truth.json`, so both use [`Trajectory`]. Keys this module does not know are
//! kept in the `extra` maps and written back, so per-frame losses, metrics and
//! configs survive a read/modify/write cycle.
//!
//! Reading checks what docs/formats.md promises (finite numbers, unit quaternions,
//! `fps > 0`, one pose per frame for every body) and then normalises the
//! quaternions exactly. Writing runs the same checks before serialising, so a
//! file this module writes is always one it can read.

use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};

/// How far `|q|` may be from 1 before a quaternion is rejected rather than normalised.
pub const QUAT_UNIT_TOLERANCE: f64 = 1e-3;

/// A rigid pose: `p_world = R(q) * p_body + t`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Translation in metres: the body's centre of mass in the world.
    #[serde(deserialize_with = "null_as_nan::array")]
    pub t: [f64; 3],
    /// Rotation as a unit quaternion `[w, x, y, z]`.
    #[serde(deserialize_with = "null_as_nan::array")]
    pub q: [f64; 4],
}

impl Default for Pose {
    /// The identity pose.
    fn default() -> Self {
        Self {
            t: [0.0; 3],
            q: [1.0, 0.0, 0.0, 0.0],
        }
    }
}

impl Pose {
    /// The pose as geometry (the quaternion normalised; a zero one becomes the identity).
    pub fn to_geom(&self) -> geom::Pose<f64> {
        geom::Pose::new(geom::Quat::cst(self.q).normalize_or_identity(), geom::Vec3::cst(self.t))
    }

    /// A pose of the geometry as written in files.
    pub fn from_geom(p: &geom::Pose<f64>) -> Self {
        Self {
            t: p.t.to_array(),
            q: p.q.to_array_re(),
        }
    }
}

/// A pose with its velocities: the state of a body at one instant.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyState {
    /// Translation in metres (centre of mass in the world).
    #[serde(deserialize_with = "null_as_nan::array")]
    pub t: [f64; 3],
    /// Rotation as a unit quaternion `[w, x, y, z]`.
    #[serde(deserialize_with = "null_as_nan::array")]
    pub q: [f64; 4],
    /// Linear velocity of the centre of mass, m/s, world frame.
    #[serde(deserialize_with = "null_as_nan::array")]
    pub v: [f64; 3],
    /// Angular velocity, rad/s, world frame.
    #[serde(deserialize_with = "null_as_nan::array")]
    pub omega: [f64; 3],
}

impl BodyState {
    /// A state of the geometry's pose and velocities (m/s, rad/s, world frame) as written in files.
    pub fn from_geom(pose: &geom::Pose<f64>, v: geom::Vec3<f64>, omega: geom::Vec3<f64>) -> Self {
        Self {
            t: pose.t.to_array(),
            q: pose.q.to_array_re(),
            v: v.to_array(),
            omega: omega.to_array(),
        }
    }
}

impl Default for BodyState {
    /// At rest at the identity pose.
    fn default() -> Self {
        Self {
            t: [0.0; 3],
            q: [1.0, 0.0, 0.0, 0.0],
            v: [0.0; 3],
            omega: [0.0; 3],
        }
    }
}

/// One body's motion in one video.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VideoBody {
    /// Name of the body, as in `truth.json`'s `bodies[*].name`.
    pub name: String,
    /// State at frame 0.
    pub initial: BodyState,
    /// Pose at every frame, frame 0 first.
    pub poses: Vec<Pose>,
    /// Keys not listed above, kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Contact parameters of the simulator that made (or fits) the motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    /// Coefficient of restitution.
    #[serde(deserialize_with = "null_as_nan::scalar")]
    pub restitution: f64,
    /// Coefficient of friction.
    #[serde(deserialize_with = "null_as_nan::scalar")]
    pub friction: f64,
    /// Which simulator these parameters belong to; only `"pganeus"` ones are
    /// the project's `k_n` and `mu`.
    pub model: String,
    /// Other keys (pairwise values, simulator settings), kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// The motion of the bodies in one video capture: a `trajectory.json`, or one
/// `videos[*]` entry of a `truth.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Name of the video capture folder.
    pub capture: String,
    /// Frames per second, > 0.
    #[serde(deserialize_with = "null_as_nan::scalar")]
    pub fps: f64,
    /// Every moving body, each with one pose per frame.
    pub bodies: Vec<VideoBody>,
    /// Contact parameters.
    pub contact: Contact,
    /// Other keys (per-frame losses, metrics, the config), kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// The background of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Background {
    /// Name of the background's capture folder.
    pub capture: String,
    /// Its mesh file, relative to `truth.json`.
    pub mesh: String,
    /// Keys not listed above, kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Where a body stood while one of its static captures was taken.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StaticCapture {
    /// Name of the capture folder.
    pub capture: String,
    /// The body's pose during that capture.
    pub pose: Pose,
    /// Keys not listed above, kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// A body of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthBody {
    /// Unique name, used by `videos[*].bodies[*].name`.
    pub name: String,
    /// Mesh file in the body frame (origin at the centre of mass), relative to `truth.json`.
    pub mesh: String,
    /// Mass in kilograms, if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// The static captures of this body.
    #[serde(default)]
    pub static_captures: Vec<StaticCapture>,
    /// Keys not listed above, kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Ground truth of a scene: `truth.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Gravity in m/s², world frame; `[0, 0, -9.81]` when the file has none.
    #[serde(default = "default_gravity", deserialize_with = "null_as_nan::array")]
    pub gravity: [f64; 3],
    /// The background, if the scene has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background: Option<Background>,
    /// The bodies of the scene.
    #[serde(default)]
    pub bodies: Vec<TruthBody>,
    /// How the bodies moved in each video.
    #[serde(default)]
    pub videos: Vec<Trajectory>,
    /// Keys not listed above, kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

impl Default for Truth {
    /// No bodies, no videos, standard gravity.
    fn default() -> Self {
        Self {
            gravity: default_gravity(),
            background: None,
            bodies: Vec::new(),
            videos: Vec::new(),
            extra: Map::new(),
        }
    }
}

impl Truth {
    /// The body called `name`, if any.
    pub fn body(&self, name: &str) -> Option<&TruthBody> {
        self.bodies.iter().find(|b| b.name == name)
    }

    /// The video whose capture folder is `capture`, if any.
    pub fn video(&self, capture: &str) -> Option<&Trajectory> {
        self.videos.iter().find(|v| v.capture == capture)
    }
}

impl Trajectory {
    /// The motion of the body called `name`, if any.
    pub fn body(&self, name: &str) -> Option<&VideoBody> {
        self.bodies.iter().find(|b| b.name == name)
    }
}

/// serde_json writes a non-finite float as `null`. Reading `null` back as NaN
/// (instead of failing with a type error) lets the checks name the field.
mod null_as_nan {
    use serde::{Deserialize, Deserializer};

    pub fn scalar<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }

    pub fn array<'de, D, const N: usize>(d: D) -> Result<[f64; N], D::Error>
    where
        D: Deserializer<'de>,
        [Option<f64>; N]: Deserialize<'de>,
    {
        let a = <[Option<f64>; N]>::deserialize(d)?;
        Ok(a.map(|x| x.unwrap_or(f64::NAN)))
    }
}

/// Reads and checks a `trajectory.json`, normalising its quaternions.
pub fn read_trajectory(path: &Path) -> Result<Trajectory> {
    read_trajectory_bytes(&read_file(path)?, path)
}

/// [`read_trajectory`] from bytes already in memory; `path` is only used in errors.
pub fn read_trajectory_bytes(bytes: &[u8], path: &Path) -> Result<Trajectory> {
    let mut traj: Trajectory = parse_json(bytes, path)?;
    check_trajectory(&traj, "", path)?;
    normalize_trajectory(&mut traj);
    Ok(traj)
}

/// Checks `traj` and writes it as pretty JSON to `path`, atomically.
/// Nothing is written if the check fails.
pub fn write_trajectory(path: &Path, traj: &Trajectory) -> Result<()> {
    write_atomic(path, &write_trajectory_bytes(traj, path)?)
}

/// Checks `traj` and serialises it as pretty JSON; `path` is only used in errors.
pub fn write_trajectory_bytes(traj: &Trajectory, path: &Path) -> Result<Vec<u8>> {
    check_trajectory(traj, "", path)?;
    to_json(traj, path)
}

/// Reads and checks a `truth.json`, normalising its quaternions.
pub fn read_truth(path: &Path) -> Result<Truth> {
    read_truth_bytes(&read_file(path)?, path)
}

/// [`read_truth`] from bytes already in memory; `path` is only used in errors.
pub fn read_truth_bytes(bytes: &[u8], path: &Path) -> Result<Truth> {
    let mut truth: Truth = parse_json(bytes, path)?;
    check_truth(&truth, path)?;
    normalize_truth(&mut truth);
    Ok(truth)
}

/// Checks `truth` and writes it as pretty JSON to `path`, atomically.
/// Nothing is written if the check fails.
pub fn write_truth(path: &Path, truth: &Truth) -> Result<()> {
    write_atomic(path, &write_truth_bytes(truth, path)?)
}

/// Checks `truth` and serialises it as pretty JSON; `path` is only used in errors.
pub fn write_truth_bytes(truth: &Truth, path: &Path) -> Result<Vec<u8>> {
    check_truth(truth, path)?;
    to_json(truth, path)
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })
}

fn to_json<T: Serialize>(value: &T, path: &Path) -> Result<Vec<u8>> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|source| IoError::Json {
        path: path.to_path_buf(),
        cause: source,
    })?;
    bytes.push(b'\n');
    Ok(bytes)
}

/// Parses JSON. Python's `json.dump` writes bare `NaN` / `Infinity`, which is not
/// JSON; when the strict parse fails and such tokens are present, they are read
/// as `null` (i.e. NaN) so that the checks can say which field holds them.
/// Such a token inside an `extra` map stays `null`.
fn parse_json<T: serde::de::DeserializeOwned>(bytes: &[u8], path: &Path) -> Result<T> {
    match serde_json::from_slice(bytes) {
        Ok(v) => Ok(v),
        Err(err) => {
            if err.is_syntax() {
                if let Some(fixed) = non_finite_tokens_to_null(bytes) {
                    if let Ok(v) = serde_json::from_slice(&fixed) {
                        return Ok(v);
                    }
                }
            }
            Err(IoError::Json {
                path: path.to_path_buf(),
                cause: err,
            })
        }
    }
}

/// Replaces the bare tokens `NaN`, `Infinity` and `-Infinity` (outside strings)
/// by `null`. `None` when there are none.
fn non_finite_tokens_to_null(bytes: &[u8]) -> Option<Vec<u8>> {
    const TOKENS: [&[u8]; 3] = [b"-Infinity", b"Infinity", b"NaN"];
    let mut out = Vec::with_capacity(bytes.len());
    let (mut in_string, mut escaped, mut replaced) = (false, false, false);
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if in_string {
            if escaped {
                escaped = false;
            } else if c == b'\\' {
                escaped = true;
            } else if c == b'"' {
                in_string = false;
            }
        } else if c == b'"' {
            in_string = true;
        } else if let Some(tok) = TOKENS.iter().find(|t| bytes[i..].starts_with(t)) {
            out.extend_from_slice(b"null");
            i += tok.len();
            replaced = true;
            continue;
        }
        out.push(c);
        i += 1;
    }
    replaced.then_some(out)
}

fn invalid(path: &Path, field: String, msg: String) -> IoError {
    IoError::Invalid {
        path: path.to_path_buf(),
        field,
        msg,
    }
}

fn check_finite(path: &Path, field: &str, x: f64) -> Result<()> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(invalid(
            path,
            field.to_string(),
            format!("must be a finite number, found {x} (null, NaN and Infinity read as NaN)"),
        ))
    }
}

fn check_array(path: &Path, field: &str, a: &[f64]) -> Result<()> {
    for (i, &x) in a.iter().enumerate() {
        check_finite(path, &format!("{field}[{i}]"), x)?;
    }
    Ok(())
}

fn check_quat(path: &Path, field: &str, q: &[f64; 4]) -> Result<()> {
    check_array(path, field, q)?;
    let n = norm(q);
    if (n - 1.0).abs() > QUAT_UNIT_TOLERANCE {
        return Err(invalid(
            path,
            field.to_string(),
            format!(
                "quaternion [w, x, y, z] must have unit length (within {QUAT_UNIT_TOLERANCE}), \
                 its length is {n}"
            ),
        ));
    }
    Ok(())
}

fn check_pose(path: &Path, field: &str, p: &Pose) -> Result<()> {
    check_array(path, &format!("{field}.t"), &p.t)?;
    check_quat(path, &format!("{field}.q"), &p.q)
}

/// `prefix` is `""` for a `trajectory.json` and `"videos[i]."` inside a `truth.json`.
fn check_trajectory(traj: &Trajectory, prefix: &str, path: &Path) -> Result<()> {
    let fps = traj.fps;
    check_finite(path, &format!("{prefix}fps"), fps)?;
    if fps <= 0.0 {
        return Err(invalid(
            path,
            format!("{prefix}fps"),
            format!("frames per second must be > 0, found {fps}"),
        ));
    }
    for (i, body) in traj.bodies.iter().enumerate() {
        let f = format!("{prefix}bodies[{i}]");
        let s = &body.initial;
        check_array(path, &format!("{f}.initial.t"), &s.t)?;
        check_quat(path, &format!("{f}.initial.q"), &s.q)?;
        check_array(path, &format!("{f}.initial.v"), &s.v)?;
        check_array(path, &format!("{f}.initial.omega"), &s.omega)?;
        for (k, pose) in body.poses.iter().enumerate() {
            check_pose(path, &format!("{f}.poses[{k}]"), pose)?;
        }
    }
    // poses[k] is frame k for every body, so all bodies must have the same count.
    if let Some(first) = traj.bodies.first() {
        for (i, body) in traj.bodies.iter().enumerate().skip(1) {
            if body.poses.len() != first.poses.len() {
                return Err(invalid(
                    path,
                    format!("{prefix}bodies[{i}].poses"),
                    format!(
                        "has {} poses but {prefix}bodies[0].poses has {}; \
                         every body needs one pose per frame",
                        body.poses.len(),
                        first.poses.len()
                    ),
                ));
            }
        }
    }
    check_finite(path, &format!("{prefix}contact.restitution"), traj.contact.restitution)?;
    check_finite(path, &format!("{prefix}contact.friction"), traj.contact.friction)
}

fn check_truth(truth: &Truth, path: &Path) -> Result<()> {
    check_array(path, "gravity", &truth.gravity)?;
    for (i, body) in truth.bodies.iter().enumerate() {
        if let Some(m) = body.mass {
            let field = format!("bodies[{i}].mass");
            check_finite(path, &field, m)?;
            if m <= 0.0 {
                return Err(invalid(path, field, format!("mass must be > 0, found {m}")));
            }
        }
        for (j, sc) in body.static_captures.iter().enumerate() {
            check_pose(path, &format!("bodies[{i}].static_captures[{j}].pose"), &sc.pose)?;
        }
    }
    for (v, video) in truth.videos.iter().enumerate() {
        check_trajectory(video, &format!("videos[{v}]."), path)?;
    }
    Ok(())
}

fn norm(q: &[f64; 4]) -> f64 {
    q.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// `q` made unit length by dividing by its norm; one already unit to within rounding (the tolerance of
/// [`geom::Quat::unit`]) is left as it is, so what a program wrote reads back bit for bit. Only called after
/// the checks, so `|q|` is within 1e-3 of 1.
fn normalize(q: &mut [f64; 4]) {
    let n = norm(q);
    if (n - 1.0).abs() <= 8.0 * f64::EPSILON {
        return;
    }
    for x in q.iter_mut() {
        *x /= n;
    }
}

fn normalize_trajectory(traj: &mut Trajectory) {
    for body in &mut traj.bodies {
        normalize(&mut body.initial.q);
        for pose in &mut body.poses {
            normalize(&mut pose.q);
        }
    }
}

fn normalize_truth(truth: &mut Truth) {
    for body in &mut truth.bodies {
        for sc in &mut body.static_captures {
            normalize(&mut sc.pose.q);
        }
    }
    for video in &mut truth.videos {
        normalize_trajectory(video);
    }
}
