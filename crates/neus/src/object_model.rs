//! A reconstructed object as every later stage sees it (render, fit,
//! simulate, eval): its field(s), its closed mesh and mass properties, and
//! the body frame they share (docs/formats.md: origin at the centre of mass of the
//! closed mesh, axes of the reference capture; `p_world = R(q) p_body + t`).
//!
//! Loaded from a `merge` output folder (two fields and their `transform.json`:
//! the two-pose switching of Eq. 3–4) or from a single `train` run (one field;
//! its zero level is the mesh).

use crate::checkpoint::{load_field, load_field_bytes, CheckpointError, LoadedField};
use crate::switching::{route, Route};
use geom::{Camera, Pose, Quat, TriMesh, Vec3};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// One field of the object and where the body frame sits in its capture.
pub struct ObjectField {
    pub field: LoadedField,
    /// `p_capture = capture_from_body · p_body`.
    pub capture_from_body: Pose<f64>,
}

/// A reconstructed object.
pub struct ObjectModel {
    /// Where it was loaded from.
    pub source: PathBuf,
    /// The field of the reference capture (B for a merge).
    pub primary: ObjectField,
    /// The field of the other pose (A for a merge), seen by cameras below the primary's board.
    pub other: Option<ObjectField>,
    /// The closed mesh, body frame.
    pub mesh: TriMesh,
    /// `mesh`'s bounding box (`mesh.bounds()`), kept beside it: the pose fit asks for it at every step, and a
    /// merged mesh has some 200,000 vertices (6 % of a fit's time went to recomputing it).
    pub mesh_bounds: ([f64; 3], [f64; 3]),
    /// Volume (m³) of the closed mesh.
    pub volume: f64,
    /// The reference capture's name (its folder's) and where the body frame sat in it.
    pub reference_capture: String,
    pub reference_pose: Pose<f64>,
}

#[derive(Debug, thiserror::Error)]
pub enum ObjectError {
    #[error("{path}: {msg}")]
    Invalid { path: PathBuf, msg: String },
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error(transparent)]
    Io(#[from] pganeus_io::IoError),
}

fn invalid(path: &Path, msg: impl Into<String>) -> ObjectError {
    ObjectError::Invalid {
        path: path.to_path_buf(),
        msg: msg.into(),
    }
}

#[derive(Deserialize)]
struct TransformJson {
    q_1to2: [f64; 4],
    #[serde(rename = "T_1to2")]
    t_1to2: [f64; 3],
}

/// The runs a `merge` output was made from.
#[derive(Deserialize)]
struct MergeSources {
    a: PathBuf,
    b: PathBuf,
}

/// `p_b = a_to_b · p_a` from a `transform.json` (as `merge` writes it, or given by hand with `q_1to2` and
/// `T_1to2`).
pub fn read_transform(path: &Path) -> Result<Pose<f64>, ObjectError> {
    let text = std::fs::read_to_string(path).map_err(|e| invalid(path, e.to_string()))?;
    transform_of(path, &text)
}

fn transform_of(path: &Path, text: &str) -> Result<Pose<f64>, ObjectError> {
    let t: TransformJson = serde_json::from_str(text).map_err(|e| invalid(path, e.to_string()))?;
    let q = Quat::<f64>::cst(t.q_1to2);
    if !((q.norm() - 1.0).abs() < 1e-6 && t.t_1to2.iter().all(|v| v.is_finite())) {
        return Err(invalid(path, "q_1to2 must be a unit quaternion and T_1to2 finite"));
    }
    Ok(Pose::new(q.normalize_or_identity(), Vec3::cst(t.t_1to2)))
}

/// The checkpoint of a run folder (or the file itself).
fn checkpoint_in(p: &Path) -> PathBuf {
    if p.is_dir() {
        p.join("checkpoint.safetensors")
    } else {
        p.to_path_buf()
    }
}

/// Grid resolution of a run's zero level when it is the object's mesh.
const RUN_MESH_RES: usize = 192;

/// A 64-bit digest of `bytes` (FNV-1a over 8-byte words): what names a checkpoint's cached zero level.
fn digest(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325 ^ bytes.len() as u64;
    let mut words = bytes.chunks_exact(8);
    for w in &mut words {
        h = (h ^ u64::from_le_bytes(w.try_into().expect("8 bytes"))).wrapping_mul(0x0000_0100_0000_01b3);
        h ^= h >> 29;
    }
    for &b in words.remainder() {
        h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The zero level of a run's field at `res` ([`RUN_MESH_RES`]), the object's mesh, kept beside the checkpoint
/// (`object_mesh.ply`, positions in double precision, so it is the very mesh extraction gives) under the
/// checkpoint's digest (`object_mesh.json`): every `fit`, `render` and `eval` of the run used to extract
/// it again (seconds each). A missing, stale or unreadable copy is made again; a folder that cannot be
/// written only costs the extraction. `checkpoint_digest`: [`digest`] of the checkpoint's bytes.
fn zero_level_cached(ckpt: &Path, checkpoint_digest: u64, field: &LoadedField, res: usize) -> TriMesh {
    let dir = ckpt.parent().unwrap_or(Path::new("."));
    let (mesh_path, key_path) = (dir.join("object_mesh.ply"), dir.join("object_mesh.json"));
    let key = serde_json::json!({"checkpoint_digest": format!("{checkpoint_digest:016x}"), "res": res});
    let stored = std::fs::read(&key_path)
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok());
    if stored.as_ref() == Some(&key) {
        match pganeus_io::read_ply(&mesh_path) {
            Ok(ply) if !ply.mesh.faces.is_empty() => {
                tracing::debug!("{}: the cached zero level", mesh_path.display());
                return ply.mesh;
            }
            _ => tracing::debug!("{}: unreadable, extracted again", mesh_path.display()),
        }
    }
    let levels = field.config.field.grid.levels;
    let zero = crate::surface::zero_level_mesh(&field.field, levels, field.centre, field.radius, res);
    let opts = pganeus_io::PlyWriteOptions {
        positions_f64: true,
        ..Default::default()
    };
    let written = pganeus_io::write_ply_with(&mesh_path, &pganeus_io::PlyMesh::from_mesh(zero.clone()), &opts)
        .and_then(|()| pganeus_io::write_atomic(&key_path, key.to_string().as_bytes()));
    if let Err(e) = written {
        tracing::debug!("the zero level is not cached: {e}");
    }
    zero
}

/// The capture's folder name, as truth.json names captures.
fn capture_name(field: &LoadedField) -> String {
    field
        .capture
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

impl ObjectModel {
    /// Bake each field's geometry `sub` lattice steps a cell of its occupancy grid for the renders that
    /// follow, on its first use ([`LoadedField::bake`]; 0 drops a bake): the object no longer trains.
    pub fn bake(&mut self, sub: usize) -> Result<(), ObjectError> {
        for f in std::iter::once(&mut self.primary).chain(self.other.as_mut()) {
            f.field
                .bake(sub)
                .map_err(|msg| invalid(&self.source, format!("bake_object = {sub}: {msg}")))?;
        }
        Ok(())
    }

    /// Load a `merge` output folder (`transform.json`, `merged.ply`) or a `train` run folder.
    pub fn load(path: &Path) -> Result<Self, ObjectError> {
        Self::load_with_mesh_res(path, RUN_MESH_RES)
    }

    /// [`Self::load`], a run's zero level extracted on a `res`³ grid (cached under that resolution) instead of
    /// the default 192³: coarser is faster where the mesh's detail does not matter (tests).
    pub fn load_with_mesh_res(path: &Path, res: usize) -> Result<Self, ObjectError> {
        if path.join("transform.json").exists() {
            Self::load_merge(path)
        } else if checkpoint_in(path).exists() {
            Self::load_run(path, res)
        } else {
            Err(invalid(
                path,
                "neither a merge output (transform.json, merged.ply) nor a run (checkpoint.safetensors)",
            ))
        }
    }

    fn load_merge(dir: &Path) -> Result<Self, ObjectError> {
        let tpath = dir.join("transform.json");
        let text = std::fs::read_to_string(&tpath).map_err(|e| invalid(&tpath, e.to_string()))?;
        let a_to_b = transform_of(&tpath, &text)?;
        let t: MergeSources = serde_json::from_str(&text).map_err(|e| invalid(&tpath, e.to_string()))?;
        let (a, b) = (pganeus_io::resolve_from(dir, &t.a), pganeus_io::resolve_from(dir, &t.b));
        for p in [&a, &b] {
            if !checkpoint_in(p).exists() {
                return Err(invalid(
                    &tpath,
                    format!(
                        "{} is not a run folder with a checkpoint (an object made from meshes has no field to render)",
                        p.display()
                    ),
                ));
            }
        }
        let mpath = dir.join("merged.ply");
        let merged = pganeus_io::read_mesh(&mpath)?;
        let props = closed_volume(&mpath, &merged)?;
        let com = props.1;
        // The body frame: origin at the centre of mass, axes of B's capture.
        let b_from_body = Pose::from_translation(com);
        let a_from_body = a_to_b.inverse().compose(&b_from_body);
        let mesh = to_body(&merged, com);
        let mesh_bounds = mesh.bounds();
        let primary = ObjectField {
            field: load_field(&checkpoint_in(&b))?,
            capture_from_body: b_from_body,
        };
        let other = ObjectField {
            field: load_field(&checkpoint_in(&a))?,
            capture_from_body: a_from_body,
        };
        Ok(Self {
            source: dir.to_path_buf(),
            reference_capture: capture_name(&primary.field),
            reference_pose: b_from_body,
            primary,
            other: Some(other),
            mesh,
            mesh_bounds,
            volume: props.0,
        })
    }

    fn load_run(run: &Path, res: usize) -> Result<Self, ObjectError> {
        let ckpt = checkpoint_in(run);
        // Read once: the field and the digest that names its cached zero level.
        let bytes = std::fs::read(&ckpt).map_err(|e| invalid(&ckpt, e.to_string()))?;
        let field = load_field_bytes(&bytes, &ckpt)?;
        let zero = zero_level_cached(&ckpt, digest(&bytes), &field, res);
        let (volume, com) = closed_volume(run, &zero)?;
        let capture_from_body = Pose::from_translation(com);
        let mesh = to_body(&zero, com);
        Ok(Self {
            source: run.to_path_buf(),
            reference_capture: capture_name(&field),
            reference_pose: capture_from_body,
            mesh_bounds: mesh.bounds(),
            mesh,
            volume,
            primary: ObjectField {
                field,
                capture_from_body,
            },
            other: None,
        })
    }

    /// The field that renders `camera` (world) when the body stands at `pose` (Eq. 4: the primary field
    /// when the camera is above its board in the primary capture's frame, else the other).
    pub fn route(&self, pose: &Pose<f64>, camera: &Camera<f64>) -> &ObjectField {
        let Some(other) = &self.other else {
            return &self.primary;
        };
        // The camera seen from the primary capture's frame.
        let mut cam = *camera;
        let capture_from_world = self.primary.capture_from_body.compose(&pose.inverse());
        cam.world_to_cam = camera.world_to_cam.compose(&capture_from_world.inverse());
        let primary_to_other = other
            .capture_from_body
            .compose(&self.primary.capture_from_body.inverse());
        match route(&cam, &primary_to_other) {
            Route::Primary => &self.primary,
            Route::Other(_) => other,
        }
    }
}

/// Volume and centre of mass of a closed mesh, or an error naming `path`.
fn closed_volume(path: &Path, m: &TriMesh) -> Result<(f64, Vec3<f64>), ObjectError> {
    if m.faces.is_empty() {
        return Err(invalid(path, "the object's mesh is empty"));
    }
    let p = sim::mass_properties(m, 1.0);
    if !(p.volume.is_finite() && p.volume > 0.0) {
        return Err(invalid(
            path,
            format!("the object's mesh is not closed (volume {:.3e} m³)", p.volume),
        ));
    }
    Ok((p.volume, p.center_of_mass))
}

fn to_body(m: &TriMesh, com: Vec3<f64>) -> TriMesh {
    let mut out = m.clone();
    for v in &mut out.vertices {
        *v = (Vec3::cst(*v) - com).to_array();
    }
    out
}
