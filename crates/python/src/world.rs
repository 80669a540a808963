//! The simulator from Python: a world (a static scene, bodies, contact values) simulated to every body's
//! state in every frame, and the exact derivatives of those states with respect to any of the world's
//! parameters (forward-mode dual numbers, as the fit uses them). Simulations run with the GIL released.

use crate::errors::{self, PganeusError, SettingsError};
use numpy::ndarray::{Array3, Array4};
use numpy::{
    IntoPyArray, PyArray1, PyArray3, PyArray4, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use sim::sdf::{Cuboid, Plane, SdfGrid, Shape, Sphere};
use sim::{BodyState, ContactModel, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, STATE_LEN};
use std::path::PathBuf;
use std::sync::Arc;

/// A rigid-body world: a static scene (a plane or an SDF grid), bodies with their initial states, and the
/// contact values of each body with the scene and of each pair of bodies.
///
/// The parameter vector (`params`, `param_names`) holds, per body, `t` (3), a rotation tangent (3, applied
/// before the initial orientation), `v` (3), `omega` (3, world frame, rad/s), restitution and friction
/// against the scene; then, per pair `(i, j)`, `i < j`, restitution and friction. A state is `[t(3), q(4) as
/// w, x, y, z, v(3), omega(3)]`, metres and seconds, z up.
#[pyclass(module = "pganeus", name = "World")]
pub struct World {
    inner: sim::World,
}

fn settings(e: impl std::fmt::Display) -> PyErr {
    SettingsError::new_err(e.to_string())
}

/// The simulation settings: the defaults, with the fields of `sim` (a JSON object of `SimConfig`'s fields,
/// `[sim]` of a scene file) over them.
fn sim_config(sim: Option<&str>) -> PyResult<SimConfig> {
    let config: SimConfig = match sim {
        Some(text) => serde_json::from_str(text).map_err(|e| settings(format!("sim: {e}")))?,
        None => SimConfig::default(),
    };
    config.validate().map_err(|e| settings(format!("sim.{e}")))?;
    Ok(config)
}

/// `x` as a C-contiguous numpy array of `dtype` (numpy converts lists and other dtypes).
fn contiguous<'py>(x: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    x.py().import("numpy")?.call_method1("ascontiguousarray", (x, dtype))
}

fn state_array<'py>(py: Python<'py>, frames: &[Vec<BodyState<f64>>]) -> Bound<'py, PyArray3<f64>> {
    let bodies = frames.first().map_or(0, |f| f.len());
    let flat: Vec<f64> = frames.iter().flatten().flat_map(|s| s.to_array()).collect();
    Array3::from_shape_vec((frames.len(), bodies, STATE_LEN), flat)
        .expect("every frame has every body")
        .into_pyarray(py)
}

impl World {
    fn params_or_current(&self, params: Option<PyReadonlyArray1<'_, f64>>) -> PyResult<Vec<f64>> {
        match params {
            None => Ok(self.inner.params()),
            Some(p) => {
                let p = p.as_slice().map_err(settings)?.to_vec();
                if p.len() != self.inner.param_count() {
                    return Err(settings(format!(
                        "params: {} values for a world of {} parameters",
                        p.len(),
                        self.inner.param_count()
                    )));
                }
                Ok(p)
            }
        }
    }

    /// Parameter indices from names or indices (all of them when none are given).
    fn columns(&self, wrt: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<usize>> {
        let n = self.inner.param_count();
        let Some(wrt) = wrt else { return Ok((0..n).collect()) };
        let names = self.inner.param_names();
        let mut out = Vec::new();
        for item in wrt.try_iter()? {
            let item = item?;
            let index = if let Ok(name) = item.extract::<String>() {
                names
                    .iter()
                    .position(|n| *n == name)
                    .ok_or_else(|| settings(format!("wrt: no parameter \"{name}\" (World.param_names lists them)")))?
            } else {
                let i: usize = item.extract()?;
                if i >= n {
                    return Err(settings(format!("wrt: index {i} out of range for {n} parameters")));
                }
                i
            };
            out.push(index);
        }
        Ok(out)
    }
}

#[pymethods]
impl World {
    /// A world over the plane `normal · x = offset` (default: the board, z = 0), solid below it. `sim` is a
    /// JSON object of simulation settings (`fps`, `frames`, `substeps`, `contact_model`, ...; docs/python.md).
    #[staticmethod]
    #[pyo3(signature = (normal=[0.0, 0.0, 1.0], offset=0.0, sim=None))]
    fn on_plane(normal: [f64; 3], offset: f64, sim: Option<&str>) -> PyResult<Self> {
        let len = normal.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(len.is_finite() && len > 0.0) {
            return Err(settings("normal: must be a non-zero finite vector"));
        }
        let normal = normal.map(|v| v / len);
        Ok(World {
            inner: sim::World::new(sim_config(sim)?, Shape::Plane(Plane { normal, offset })),
        })
    }

    /// A world over a scene given as an SDF grid: `values[i, j, k]` the signed distance (m, negative inside)
    /// at `origin + spacing * (i, j, k)`.
    #[staticmethod]
    #[pyo3(signature = (values, origin, spacing, sim=None))]
    fn on_grid(values: &Bound<'_, PyAny>, origin: [f64; 3], spacing: f64, sim: Option<&str>) -> PyResult<Self> {
        let array = contiguous(values, "float32")?;
        let array: PyReadonlyArray3<'_, f32> = array.extract()?;
        let [nx, ny, nz]: [usize; 3] = array.shape().try_into().expect("three axes");
        // The grid stores x fastest: the transpose of the [i, j, k] array in C order.
        let values: Vec<f32> = array.as_array().reversed_axes().iter().copied().collect();
        let grid = SdfGrid::from_values(origin, spacing, [nx, ny, nz], values).map_err(settings)?;
        Ok(World {
            inner: sim::World::new(sim_config(sim)?, Shape::Grid(Arc::new(grid))),
        })
    }

    /// A world over the scene grid a `bake` wrote (`.sdf`).
    #[staticmethod]
    #[pyo3(signature = (path, sim=None))]
    fn from_sdf_file(path: PathBuf, sim: Option<&str>) -> PyResult<Self> {
        let grid = SdfGrid::load(&path).map_err(errors::input)?;
        Ok(World {
            inner: sim::World::new(sim_config(sim)?, Shape::Grid(Arc::new(grid))),
        })
    }

    /// The world a scene file describes (TOML or JSON; the format of `pganeus simulate --scene`).
    #[staticmethod]
    fn from_scene_file(path: PathBuf) -> PyResult<Self> {
        let scene = scene_file::SceneFile::load(&path).map_err(errors::input)?;
        Ok(World { inner: scene.world })
    }

    /// Adds a body and returns its index. Its shape: `vertices` and `faces` of a closed mesh (any frame: it is
    /// moved so its centre of mass is the origin, and `t`, `q` place that frame), a box of half extents `box`,
    /// or a sphere of radius `sphere`. Its mass: `mass` (kg) or `density` (kg/m³, default 1000). Its
    /// contact points: `contact_points` spread over its surface (seeded by `seed`). Contacts with the scene:
    /// `restitution`, `friction`; with each body already in the world: `pair_restitution`, `pair_friction`
    /// (default: the scene's).
    #[pyo3(signature = (name, *, vertices=None, faces=None, r#box=None, sphere=None, mass=None, density=None,
        t=[0.0, 0.0, 0.0], q=[1.0, 0.0, 0.0, 0.0], v=[0.0, 0.0, 0.0], omega=[0.0, 0.0, 0.0],
        restitution=0.5, friction=0.3, pair_restitution=None, pair_friction=None, contact_points=1000, seed=0))]
    #[allow(clippy::too_many_arguments)]
    fn add_body(
        &mut self,
        name: &str,
        vertices: Option<&Bound<'_, PyAny>>,
        faces: Option<&Bound<'_, PyAny>>,
        r#box: Option<[f64; 3]>,
        sphere: Option<f64>,
        mass: Option<f64>,
        density: Option<f64>,
        t: [f64; 3],
        q: [f64; 4],
        v: [f64; 3],
        omega: [f64; 3],
        restitution: f64,
        friction: f64,
        pair_restitution: Option<f64>,
        pair_friction: Option<f64>,
        contact_points: usize,
        seed: u64,
    ) -> PyResult<usize> {
        let mass = match (mass, density) {
            (Some(_), Some(_)) => return Err(settings(format!("{name}: give mass or density, not both"))),
            (Some(m), None) => MassSpec::Mass(m),
            (None, d) => MassSpec::Density(d.unwrap_or(1000.0)),
        };
        let sampling = ContactSampling::Surface {
            count: contact_points,
            seed,
        };
        let body = match (vertices, faces, r#box, sphere) {
            (Some(v), Some(f), None, None) => {
                let v = contiguous(v, "float64")?;
                let v: PyReadonlyArray2<'_, f64> = v.extract()?;
                let f = contiguous(f, "uint32")?;
                let f: PyReadonlyArray2<'_, u32> = f.extract()?;
                if v.shape()[1] != 3 || f.shape()[1] != 3 {
                    return Err(settings(format!("{name}: vertices must be [N, 3] and faces [M, 3]")));
                }
                let vs = v.as_slice().map_err(settings)?;
                let fs = f.as_slice().map_err(settings)?;
                let mesh = geom::TriMesh::new(
                    vs.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                    fs.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                );
                RigidBody::from_mesh(name, &mesh, mass, sampling, None)
            }
            (None, None, Some(half), None) => {
                RigidBody::from_shape(name, &Shape::Cuboid(Cuboid { half }), mass, sampling)
            }
            (None, None, None, Some(radius)) => {
                RigidBody::from_shape(name, &Shape::Sphere(Sphere { radius }), mass, sampling)
            }
            _ => {
                return Err(settings(format!(
                    "{name}: give the shape as vertices and faces, as box or as sphere (one of them)"
                )))
            }
        }
        .map_err(|e| settings(format!("{name}: {e}")))?;
        let scene = ContactParams { restitution, friction };
        let pair = ContactParams {
            restitution: pair_restitution.unwrap_or(restitution),
            friction: pair_friction.unwrap_or(friction),
        };
        let index = self.inner.add_body(body, BodyState::new(t, q, v, omega), scene, pair);
        Ok(index)
    }

    /// The bodies' names, in order.
    #[getter]
    fn bodies(&self) -> Vec<String> {
        self.inner.bodies.iter().map(|b| b.name.clone()).collect()
    }

    /// Each body's mass, kg.
    #[getter]
    fn masses(&self) -> Vec<f64> {
        self.inner.bodies.iter().map(|b| b.mass).collect()
    }

    /// The names of the parameters (`toy.v.x`, `toy.restitution`, `toy-block.friction`), in order.
    #[getter]
    fn param_names(&self) -> Vec<String> {
        self.inner.param_names()
    }

    /// The parameter vector of the world as it is (rotation tangents zero).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.params())
    }

    /// Writes a parameter vector into the world (rotation tangents turn the initial orientations).
    fn set_params(&mut self, params: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        let p = self.params_or_current(Some(params))?;
        self.inner.set_params(&p);
        Ok(())
    }

    /// Frames recorded, frame 0 the initial state.
    #[getter]
    fn get_frames(&self) -> usize {
        self.inner.config.frames
    }

    #[setter]
    fn set_frames(&mut self, frames: usize) -> PyResult<()> {
        self.configure(|c| c.frames = frames)
    }

    /// Solver substeps per frame.
    #[getter]
    fn get_substeps(&self) -> usize {
        self.inner.config.substeps
    }

    #[setter]
    fn set_substeps(&mut self, substeps: usize) -> PyResult<()> {
        self.configure(|c| c.substeps = substeps)
    }

    /// Frames per second.
    #[getter]
    fn get_fps(&self) -> f64 {
        self.inner.config.fps
    }

    #[setter]
    fn set_fps(&mut self, fps: f64) -> PyResult<()> {
        self.configure(|c| c.fps = fps)
    }

    /// `"mean_point"` (the paper's: one impulse at the mean of the colliding points) or `"multi_point"`.
    #[getter]
    fn get_contact_model(&self) -> &'static str {
        match self.inner.config.contact_model {
            ContactModel::MeanPoint => "mean_point",
            ContactModel::MultiPoint => "multi_point",
        }
    }

    #[setter]
    fn set_contact_model(&mut self, model: &str) -> PyResult<()> {
        let model = match model {
            "mean_point" => ContactModel::MeanPoint,
            "multi_point" => ContactModel::MultiPoint,
            _ => {
                return Err(settings(format!(
                    "contact_model: \"{model}\" is not mean_point or multi_point"
                )))
            }
        };
        self.configure(|c| c.contact_model = model)
    }

    /// Every body's state in every frame, `float64[frames, bodies, 13]`, from the world's parameters or from
    /// `params`.
    #[pyo3(signature = (params=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        params: Option<PyReadonlyArray1<'_, f64>>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let p = self.params_or_current(params)?;
        self.check()?;
        let world = &self.inner;
        let trajectory = py.detach(|| world.simulate(&p));
        let frames: Vec<Vec<BodyState<f64>>> = trajectory.frames;
        Ok(state_array(py, &frames))
    }

    /// The states (as [`simulate`](World::simulate)) and their exact derivatives with respect to the
    /// parameters `wrt` (names or indices; all when none): `(states float64[T, B, 13], jacobian float64[T, B,
    /// 13, len(wrt)], wrt int64[len(wrt)])`.
    #[pyo3(signature = (params=None, wrt=None))]
    #[allow(clippy::type_complexity)]
    fn simulate_with_gradients<'py>(
        &self,
        py: Python<'py>,
        params: Option<PyReadonlyArray1<'_, f64>>,
        wrt: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(
        Bound<'py, PyArray3<f64>>,
        Bound<'py, PyArray4<f64>>,
        Bound<'py, PyArray1<i64>>,
    )> {
        let p = self.params_or_current(params)?;
        let columns = self.columns(wrt)?;
        self.check()?;
        let world = &self.inner;
        let grad = py.detach(|| sim::simulate_with_gradients(world, &p, &columns));
        let (t, b, w) = (grad.frames.len(), world.bodies.len(), columns.len());
        let mut jac = Vec::with_capacity(t * b * STATE_LEN * w);
        for frame in 0..t {
            for body in 0..b {
                for component in 0..STATE_LEN {
                    jac.extend_from_slice(grad.row(frame, body, component));
                }
            }
        }
        let jac = Array4::from_shape_vec((t, b, STATE_LEN, w), jac).expect("one row per state component");
        let wrt: Vec<i64> = columns.iter().map(|&c| c as i64).collect();
        Ok((
            state_array(py, &grad.frames),
            jac.into_pyarray(py),
            PyArray1::from_vec(py, wrt),
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "World(bodies={:?}, frames={}, fps={}, substeps={}, contact_model=\"{}\")",
            self.bodies(),
            self.inner.config.frames,
            self.inner.config.fps,
            self.inner.config.substeps,
            self.get_contact_model()
        )
    }
}

impl World {
    /// Changes the settings, keeping the old ones if the new ones are invalid.
    fn configure(&mut self, change: impl FnOnce(&mut SimConfig)) -> PyResult<()> {
        let mut config = self.inner.config.clone();
        change(&mut config);
        config.validate().map_err(|e| settings(format!("sim.{e}")))?;
        self.inner.config = config;
        Ok(())
    }

    fn check(&self) -> PyResult<()> {
        if self.inner.bodies.is_empty() {
            return Err(PganeusError::new_err(
                "the world has no bodies: add one with World.add_body",
            ));
        }
        self.inner.validate().map_err(|e| settings(format!("{e}")))
    }
}
