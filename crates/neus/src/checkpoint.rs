//! Checkpoints in safetensors: the field's parameters, Adam's moments, the
//! occupancy grid, the views' colour maps, and (in the header) the full training config with the
//! architecture, the step, the random state and the unit-sphere frame, so a
//! checkpoint loads without its config file and training resumes exactly.

use crate::baked_geometry::BakedGeometry;
use crate::config::TrainConfig;
use crate::dataset::Dataset;
use crate::neus_field::NeusField;
use crate::occupancy::OccupancyGrid;
use crate::surface_band::CentreSdf;
use crate::trainer::NeusTrainer;
use geom::{SplitMix64, Vec3};
use pganeus_io::{read_safetensors, write_safetensors, IoError, SafeTensors, Tensor, TensorData};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const FORMAT: &str = "pganeus-neus-1";

#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error(transparent)]
    Io(#[from] IoError),
    #[error("{path}: {msg}")]
    Invalid { path: PathBuf, msg: String },
}

/// A trained field as loaded for rendering or meshing.
pub struct LoadedField {
    pub config: TrainConfig,
    pub field: NeusField,
    pub occupancy: OccupancyGrid,
    pub step: usize,
    /// Unit sphere → world: `p_world = centre + radius · p_unit`.
    pub centre: Vec3<f64>,
    pub radius: f64,
    /// The capture it was trained on.
    pub capture: PathBuf,
    /// Lattice steps a cell its geometry is baked at for rendering ([`LoadedField::bake`]; 0: not baked).
    pub(crate) bake_steps: usize,
    /// The baked geometry, made by the first render that reads it ([`LoadedField::baked`]): a merged object's
    /// field that no camera of a video routes to is never baked. None inside when over [`BAKE_BUDGET`].
    pub(crate) baked: std::sync::OnceLock<Option<BakedGeometry>>,
}

/// At most this many lattice points are baked (about 0.7 GB and 8 s on two cores): a field whose occupancy
/// grid is not yet refined (a short training: every cell occupied, 33 M points at 4 steps a cell, 2.9 GB and
/// 35–40 s) is read through its network instead. The demo's toy bakes 2.5 M.
pub const BAKE_BUDGET: usize = 8_000_000;

impl LoadedField {
    /// Bake the field's geometry `sub` lattice steps a cell of its occupancy grid, its normals at the
    /// renderer's finite-difference step (see [`crate::baked_geometry`]), on the first render that reads it;
    /// `sub = 0` drops a bake. Refused (an error naming why) for one step a cell: the SDF's curvature, which
    /// the lookup takes off, needs two.
    pub fn bake(&mut self, sub: usize) -> Result<(), String> {
        if sub == 1 {
            return Err(format!("{sub} lattice step a cell: at least 2 (0: not baked)"));
        }
        self.bake_steps = sub;
        self.baked = std::sync::OnceLock::new();
        Ok(())
    }

    /// Lattice steps a cell the geometry is baked at (0: the network is read).
    pub fn bake_steps(&self) -> usize {
        self.bake_steps
    }

    /// The baked geometry the composer reads in place of the hash grid and SDF MLP (`render_view` does not),
    /// made now if this is its first use; None when not baked.
    pub fn baked(&self) -> Option<&BakedGeometry> {
        if self.bake_steps == 0 {
            return None;
        }
        self.baked
            .get_or_init(|| {
                let occupied = self.occupancy.occupied_cells();
                let points = occupied * (self.bake_steps + 1).pow(3);
                if points > BAKE_BUDGET {
                    tracing::info!(
                        "{}: not baked ({occupied} occupied cells, {points} lattice points over the budget of \
                         {BAKE_BUDGET}: its occupancy grid is not yet refined); the network is read",
                        self.capture.display()
                    );
                    return None;
                }
                Some(self.bake_now())
            })
            .as_ref()
    }

    /// The lattice, made now (logged with its size and time).
    fn bake_now(&self) -> BakedGeometry {
        let t = std::time::Instant::now();
        // The renderer's step (`RenderSettings::of`).
        let fd_eps = self.config.field.grid.finest_cell();
        let b = BakedGeometry::bake(&self.field, &self.occupancy, self.bake_steps, fd_eps);
        tracing::info!(
            "{}: geometry baked on a {:.2} mm lattice, {} bricks, {:.0} MB, {:.1} s",
            self.capture.display(),
            1e3 * b.step() as f64 * self.radius,
            b.bricks(),
            b.bytes() as f64 / 1e6,
            t.elapsed().as_secs_f64()
        );
        b
    }
}

fn f32_tensor(v: &[f32]) -> Tensor {
    Tensor {
        shape: vec![v.len()],
        data: TensorData::F32(v.to_vec()),
    }
}

/// The tensors and header entries of a field (parameters, occupancy, where its unit sphere sits).
fn field_entries(
    f: &NeusField,
    occ: &OccupancyGrid,
    config: &TrainConfig,
    step: usize,
    (centre, radius, capture): (Vec3<f64>, f64, &Path),
) -> (BTreeMap<String, Tensor>, BTreeMap<String, String>) {
    let mut tensors = BTreeMap::new();
    for (name, p) in f.params() {
        tensors.insert(name.to_string(), f32_tensor(p));
    }
    tensors.insert(
        "occupancy".into(),
        Tensor {
            shape: vec![occ.res, occ.res, occ.res],
            data: TensorData::U8(occ.cells().to_vec()),
        },
    );
    let mut metadata = BTreeMap::new();
    metadata.insert("format".into(), FORMAT.into());
    metadata.insert(
        "config".into(),
        serde_json::to_string(config).expect("config serialises"),
    );
    metadata.insert("step".into(), step.to_string());
    metadata.insert(
        "centre".into(),
        serde_json::to_string(&centre.to_array()).expect("numbers"),
    );
    metadata.insert("radius".into(), radius.to_string());
    metadata.insert("capture".into(), capture.display().to_string());
    (tensors, metadata)
}

/// Write the trainer's state to `path` (atomically).
pub fn save(trainer: &NeusTrainer, path: &Path) -> Result<(), CheckpointError> {
    let d = &trainer.data;
    let (mut tensors, mut metadata) = field_entries(
        &trainer.field,
        &trainer.occupancy,
        &trainer.config,
        trainer.step,
        (d.centre, d.radius, &d.dir),
    );
    // Adam's state and the parameter average follow the field's parameters, named as they are.
    let names: Vec<&str> = trainer.field.params().into_iter().map(|(name, _)| name).collect();
    let adams = trainer.adam.iter().chain(trainer.bg_optim.iter().flat_map(|o| &o.adam));
    for (name, a) in names.iter().zip(adams) {
        tensors.insert(format!("adam.{name}.m"), f32_tensor(&a.m));
        tensors.insert(format!("adam.{name}.v"), f32_tensor(&a.v));
    }
    // Inside the averaging window: the running mean, so a resumed run averages as an uninterrupted one.
    if trainer.average.count > 0 {
        for (name, mean) in names.iter().zip(&trainer.average.means) {
            tensors.insert(format!("average.{name}"), f32_tensor(mean));
        }
        metadata.insert("average_count".into(), trainer.average.count.to_string());
    }
    // The views' colour maps and their optimiser (a training state: a field renders without them).
    let app = &trainer.appearance;
    tensors.insert("appearance".into(), f32_tensor(&app.params));
    tensors.insert("adam.appearance.m".into(), f32_tensor(&app.adam.m));
    tensors.insert("adam.appearance.v".into(), f32_tensor(&app.adam.v));
    metadata.insert("appearance_adam_step".into(), app.adam.step.to_string());
    metadata.insert("rng".into(), trainer.rng.0.to_string());
    // Where the refresh placed the surface inside each cell (`sample_band`): a resumed run keeps the same
    // samples as an uninterrupted one.
    if trainer.config.sample_band > 0.0 {
        tensors.insert("centre_sdf".into(), f32_tensor(trainer.centre_sdf.values()));
    }
    let bg_steps = trainer.bg_optim.iter().flat_map(|o| o.adam.iter().map(|a| a.step));
    metadata.insert(
        "adam_steps".into(),
        serde_json::to_string(&trainer.adam.iter().map(|a| a.step).chain(bg_steps).collect::<Vec<_>>())
            .expect("numbers"),
    );
    write_safetensors(path, &SafeTensors { metadata, tensors })?;
    Ok(())
}

/// Write a field alone (no optimiser state: it renders, meshes and bakes, but training cannot resume from
/// it) to `path`, atomically; [`load_field`] reads it back.
pub fn save_field(l: &LoadedField, path: &Path) -> Result<(), CheckpointError> {
    let (tensors, metadata) = field_entries(
        &l.field,
        &l.occupancy,
        &l.config,
        l.step,
        (l.centre, l.radius, &l.capture),
    );
    write_safetensors(path, &SafeTensors { metadata, tensors })?;
    Ok(())
}

fn invalid(path: &Path, msg: impl Into<String>) -> CheckpointError {
    CheckpointError::Invalid {
        path: path.to_path_buf(),
        msg: msg.into(),
    }
}

fn meta<'a>(st: &'a SafeTensors, path: &Path, key: &str) -> Result<&'a str, CheckpointError> {
    st.metadata
        .get(key)
        .map(|s| s.as_str())
        .ok_or_else(|| invalid(path, format!("header has no \"{key}\" entry")))
}

fn floats(st: &SafeTensors, path: &Path, name: &str, len: usize) -> Result<Vec<f32>, CheckpointError> {
    match st.tensors.get(name).map(|t| &t.data) {
        Some(TensorData::F32(v)) if v.len() == len => Ok(v.clone()),
        Some(TensorData::F32(v)) => Err(invalid(
            path,
            format!("tensor \"{name}\" has {} values, the architecture needs {len}", v.len()),
        )),
        Some(_) => Err(invalid(path, format!("tensor \"{name}\" is not F32"))),
        None => Err(invalid(path, format!("no tensor \"{name}\""))),
    }
}

fn parse<T: std::str::FromStr>(path: &Path, key: &str, s: &str) -> Result<T, CheckpointError> {
    s.parse()
        .map_err(|_| invalid(path, format!("header entry \"{key}\" is not a number: {s}")))
}

/// Read a checkpoint's field (for rendering and meshing).
pub fn load_field(path: &Path) -> Result<LoadedField, CheckpointError> {
    let st = read_safetensors(path)?;
    load_from(&st, path)
}

/// [`load_field`] from the file's bytes already in memory; `path` is only used in errors.
pub fn load_field_bytes(bytes: &[u8], path: &Path) -> Result<LoadedField, CheckpointError> {
    let st = pganeus_io::read_safetensors_bytes(bytes, path)?;
    load_from(&st, path)
}

fn load_from(st: &SafeTensors, path: &Path) -> Result<LoadedField, CheckpointError> {
    if meta(st, path, "format")? != FORMAT {
        return Err(invalid(path, format!("not a {FORMAT} checkpoint")));
    }
    let config: TrainConfig = serde_json::from_str(meta(st, path, "config")?)
        .map_err(|e| invalid(path, format!("config in the header: {e}")))?;
    // The start does not matter: every parameter is read below.
    let mut field = NeusField::new(&config.field, config.seed, 0.0);
    for (name, p) in field.params_mut() {
        *p = floats(st, path, name, p.len())?;
    }
    let res = config.occupancy_res;
    let occupancy = match st.tensors.get("occupancy").map(|t| &t.data) {
        Some(TensorData::U8(c)) if c.len() == res * res * res => OccupancyGrid::from_cells(res, c.clone()),
        _ => return Err(invalid(path, format!("tensor \"occupancy\" must be {res}³ U8 values"))),
    };
    let centre: [f64; 3] = serde_json::from_str(meta(st, path, "centre")?)
        .map_err(|e| invalid(path, format!("centre in the header: {e}")))?;
    Ok(LoadedField {
        step: parse(path, "step", meta(st, path, "step")?)?,
        radius: parse(path, "radius", meta(st, path, "radius")?)?,
        centre: Vec3::cst(centre),
        capture: PathBuf::from(meta(st, path, "capture")?),
        config,
        field,
        occupancy,
        bake_steps: 0,
        baked: Default::default(),
    })
}

/// Rebuild a trainer from a checkpoint to continue where it stopped.
pub fn resume(path: &Path, data: Dataset) -> Result<NeusTrainer, CheckpointError> {
    let st = read_safetensors(path)?;
    let loaded = load_from(&st, path)?;
    let mut t = NeusTrainer::new(loaded.config.clone(), data).map_err(|e| invalid(path, e.to_string()))?;
    t.field = loaded.field;
    t.occupancy = loaded.occupancy;
    t.step = loaded.step;
    t.rng = SplitMix64(parse(path, "rng", meta(&st, path, "rng")?)?);
    let steps: Vec<u64> = serde_json::from_str(meta(&st, path, "adam_steps")?)
        .map_err(|e| invalid(path, format!("adam_steps in the header: {e}")))?;
    let expected = 4 + 3 * usize::from(t.bg_optim.is_some());
    if steps.len() != expected {
        return Err(invalid(path, format!("adam_steps must list {expected} counters")));
    }
    let params: Vec<(&str, usize)> = t.field.params().into_iter().map(|(name, p)| (name, p.len())).collect();
    let adams = t.adam.iter_mut().chain(t.bg_optim.iter_mut().flat_map(|o| &mut o.adam));
    for (((name, _), adam), &step) in params.iter().zip(adams).zip(&steps) {
        let n = adam.m.len();
        adam.m = floats(&st, path, &format!("adam.{name}.m"), n)?;
        adam.v = floats(&st, path, &format!("adam.{name}.v"), n)?;
        adam.step = step;
    }
    // Checkpoints from before the colour maps existed have none: the identity, as they trained.
    if st.tensors.contains_key("appearance") {
        let app = &mut t.appearance;
        let n = app.params.len();
        app.params = floats(&st, path, "appearance", n)?;
        app.adam.m = floats(&st, path, "adam.appearance.m", n)?;
        app.adam.v = floats(&st, path, "adam.appearance.v", n)?;
        app.adam.step = parse(path, "appearance_adam_step", meta(&st, path, "appearance_adam_step")?)?;
    }
    if st.tensors.contains_key("centre_sdf") {
        let res = t.config.occupancy_res;
        let values = floats(&st, path, "centre_sdf", res * res * res)?;
        t.centre_sdf = CentreSdf::from_values(res, values).expect("res³ values read");
    }
    if let Some(count) = st.metadata.get("average_count") {
        t.average.count = parse(path, "average_count", count)?;
        t.average.means = params
            .iter()
            .map(|&(name, n)| floats(&st, path, &format!("average.{name}"), n))
            .collect::<Result<_, _>>()?;
    }
    Ok(t)
}
