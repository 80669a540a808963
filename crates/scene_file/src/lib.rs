//! The scene file of `simulate`, `target` and `fit-physics` (TOML, or JSON by
//! extension): static shapes, bodies, contact parameters and time stepping,
//! and the [`World`] it describes. Every problem is a [`SceneError`] naming
//! the file and the field that holds it. The world's motion goes back out
//! as a trajectory file through [`trajectory_file`].

use geom::{Pose, Quat, TriMesh, Vec3};
use serde::Deserialize;
use sim::sdf::{Capsule, Cuboid, Plane, RoundedBox, SdfGrid, Shape, Sphere, Wedge};
use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod trajectory_file;
pub use trajectory_file::{contact_pairs, trajectory_file};

/// Why a scene file gave no world.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read scene file {path}: {cause}")]
    Read { path: PathBuf, cause: std::io::Error },
    #[error("{path}: {msg}")]
    Parse { path: PathBuf, msg: String },
    #[error("{path}: {field}: {msg}")]
    Field { path: PathBuf, field: String, msg: String },
}

type Result<T> = std::result::Result<T, SceneError>;

/// One static shape or a body's geometry.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeSpec {
    /// `plane`, `box`, `sphere`, `rounded_box`, `capsule`, `wedge`, `grid` or `mesh`.
    pub shape: String,
    /// plane: outward normal (default [0, 0, 1]).
    pub normal: Option<[f64; 3]>,
    /// plane: `normal · p = offset` on the plane (default 0).
    pub offset: Option<f64>,
    /// box, rounded_box, wedge: half extents, m.
    pub half: Option<[f64; 3]>,
    /// sphere, capsule, rounded_box: radius, m.
    pub radius: Option<f64>,
    /// capsule: half length of the axis segment (along z), m.
    pub half_length: Option<f64>,
    /// grid: a baked SDF grid file; mesh: a closed PLY or OBJ mesh.
    pub file: Option<PathBuf>,
    /// mesh: spacing of the grid it is baked into, m (default: 1/96 of its longest side).
    pub spacing: Option<f64>,
    /// Placement: translation (default 0) and rotation `[w, x, y, z]` (default identity).
    pub t: Option<[f64; 3]>,
    pub q: Option<[f64; 4]>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    pub name: String,
    /// An analytic shape (box, sphere, rounded_box, capsule, wedge) …
    pub shape: Option<ShapeSpec>,
    /// … or a closed mesh (PLY/OBJ); it is moved so its centre of mass is the origin.
    pub mesh: Option<PathBuf>,
    /// kg (give this or `density`).
    pub mass: Option<f64>,
    /// kg/m³.
    pub density: Option<f64>,
    /// Initial position of the centre of mass, m.
    pub t: [f64; 3],
    /// Initial orientation `[w, x, y, z]` (default identity).
    pub q: Option<[f64; 4]>,
    /// Initial velocity, m/s (default 0).
    pub v: Option<[f64; 3]>,
    /// Initial angular velocity (world frame), rad/s (default 0).
    pub omega: Option<[f64; 3]>,
    /// Contact points sampled on the surface (default 1000).
    pub contact_points: Option<usize>,
    /// Use the mesh vertices as contact points instead.
    pub contact_vertices: Option<bool>,
    /// Seed of the contact-point sample (default 0).
    pub seed: Option<u64>,
    /// Contact with the scene (default: the file's `contact`).
    pub contact: Option<ContactParams>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairSpec {
    pub bodies: [String; 2],
    pub restitution: f64,
    pub friction: f64,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    pub name: Option<String>,
    #[serde(default)]
    pub sim: SimConfig,
    /// Default contact parameters (body–scene and body–body).
    #[serde(default)]
    pub contact: ContactParams,
    /// Static shapes; their union is the scene.
    #[serde(default)]
    pub scene: Vec<ShapeSpec>,
    #[serde(default)]
    pub body: Vec<BodySpec>,
    #[serde(default)]
    pub pair: Vec<PairSpec>,
}

/// A loaded scene: the world and the name to give its outputs.
pub struct LoadedScene {
    pub name: String,
    pub world: World,
}

/// Names a place in the file for messages.
struct Ctx<'a> {
    file: &'a Path,
}

impl Ctx<'_> {
    fn err(&self, field: &str, msg: impl std::fmt::Display) -> SceneError {
        SceneError::Field {
            path: self.file.to_path_buf(),
            field: field.to_string(),
            msg: msg.to_string(),
        }
    }
    fn finite<const N: usize>(&self, field: &str, v: [f64; N]) -> Result<()> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(self.err(field, format!("has NaN or infinite values: {v:?}")))
        }
    }
    fn positive(&self, field: &str, v: Option<f64>) -> Result<f64> {
        match v {
            None => Err(self.err(field, "is missing")),
            Some(x) if x.is_finite() && x > 0.0 => Ok(x),
            Some(x) => Err(self.err(field, format!("must be a positive number, got {x}"))),
        }
    }
    fn half(&self, field: &str, v: Option<[f64; 3]>) -> Result<[f64; 3]> {
        let h = v.ok_or_else(|| self.err(field, "is missing"))?;
        if h.iter().all(|x| x.is_finite() && *x > 0.0) {
            Ok(h)
        } else {
            Err(self.err(field, format!("every half extent must be positive, got {h:?}")))
        }
    }
    fn quat(&self, field: &str, q: Option<[f64; 4]>) -> Result<Quat<f64>> {
        let Some(q) = q else { return Ok(Quat::identity()) };
        self.finite(field, q)?;
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if n < 1e-9 {
            return Err(self.err(field, "quaternion has zero length"));
        }
        if (n - 1.0).abs() > 1e-3 {
            tracing::warn!(
                "{}: {field}: quaternion has length {n}; normalising",
                self.file.display()
            );
        }
        Ok(Quat::cst(q).normalize_or_identity())
    }
    fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.file.parent().unwrap_or(Path::new(".")).join(p)
        }
    }
}

impl ShapeSpec {
    fn build(&self, ctx: &Ctx, field: &str, as_body: bool) -> Result<Shape> {
        let f = |name: &str| format!("{field}.{name}");
        let shape = match self.shape.as_str() {
            "plane" => {
                let n = self.normal.unwrap_or([0.0, 0.0, 1.0]);
                ctx.finite(&f("normal"), n)?;
                let n = Vec3::cst(n)
                    .try_normalize()
                    .ok_or_else(|| ctx.err(&f("normal"), "has zero length"))?;
                let offset = self.offset.unwrap_or(0.0);
                ctx.finite(&f("offset"), [offset])?;
                Shape::Plane(Plane {
                    normal: n.to_array(),
                    offset,
                })
            }
            "box" => Shape::Cuboid(Cuboid {
                half: ctx.half(&f("half"), self.half)?,
            }),
            "sphere" => Shape::Sphere(Sphere {
                radius: ctx.positive(&f("radius"), self.radius)?,
            }),
            "rounded_box" => {
                let half = ctx.half(&f("half"), self.half)?;
                let radius = ctx.positive(&f("radius"), self.radius)?;
                if radius >= half.iter().cloned().fold(f64::INFINITY, f64::min) {
                    return Err(ctx.err(&f("radius"), format!("must be below the smallest half extent {half:?}")));
                }
                Shape::RoundedBox(RoundedBox { half, radius })
            }
            "capsule" => {
                let half_length = self
                    .half_length
                    .ok_or_else(|| ctx.err(&f("half_length"), "is missing"))?;
                if !(half_length.is_finite() && half_length >= 0.0) {
                    return Err(ctx.err(&f("half_length"), format!("must be ≥ 0, got {half_length}")));
                }
                Shape::Capsule(Capsule {
                    half_length,
                    radius: ctx.positive(&f("radius"), self.radius)?,
                })
            }
            "wedge" => Shape::Wedge(Wedge {
                half: ctx.half(&f("half"), self.half)?,
            }),
            "grid" if !as_body => {
                let file = self.file.as_ref().ok_or_else(|| ctx.err(&f("file"), "is missing"))?;
                Shape::Grid(Arc::new(
                    SdfGrid::load(&ctx.resolve(file)).map_err(|e| ctx.err(&f("file"), e))?,
                ))
            }
            "mesh" if !as_body => {
                let file = self.file.as_ref().ok_or_else(|| ctx.err(&f("file"), "is missing"))?;
                let path = ctx.resolve(file);
                let mesh = pganeus_io::read_mesh(&path).map_err(|e| ctx.err(&f("file"), e))?;
                sim::check_closed_mesh(&mesh)
                    .map_err(|e| ctx.err(&f("file"), format!("{} is not usable: {e}", path.display())))?;
                // 96 cells across by default, or the requested spacing.
                let cells = self
                    .spacing
                    .map_or(96, |h| (mesh_extent(&mesh) / h).ceil().max(1.0) as usize);
                Shape::Grid(Arc::new(
                    SdfGrid::from_mesh(&mesh, cells, 4.0)
                        .map_err(|e| ctx.err(&f("file"), format!("baking {}: {e}", path.display())))?,
                ))
            }
            "grid" | "mesh" => {
                return Err(ctx.err(
                    &f("shape"),
                    "a body's shape is analytic; give a mesh with `mesh = \"file.ply\"` instead",
                ))
            }
            other => {
                return Err(ctx.err(
                    &f("shape"),
                    format!("unknown shape \"{other}\" (plane, box, sphere, rounded_box, capsule, wedge, grid, mesh)"),
                ))
            }
        };
        if self.t.is_none() && self.q.is_none() {
            return Ok(shape);
        }
        let t = self.t.unwrap_or([0.0; 3]);
        ctx.finite(&f("t"), t)?;
        Ok(shape.transformed(Pose::new(ctx.quat(&f("q"), self.q)?, Vec3::cst(t))))
    }
}

/// Longest side of a mesh's bounding box.
fn mesh_extent(m: &TriMesh) -> f64 {
    (0..3)
        .map(|a| {
            let (lo, hi) = m.vertices.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(v[a]), h.max(v[a]))
            });
            hi - lo
        })
        .fold(0.0, f64::max)
}

impl SceneFile {
    pub fn load(path: &Path) -> Result<LoadedScene> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            path: path.to_path_buf(),
            cause: source,
        })?;
        let parse = |msg: String| SceneError::Parse {
            path: path.to_path_buf(),
            msg,
        };
        let file: SceneFile = if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) {
            serde_json::from_str(&text).map_err(|e| parse(e.to_string()))?
        } else {
            toml::from_str(&text).map_err(|e| parse(e.to_string()))?
        };
        file.build(path)
    }

    pub fn build(&self, path: &Path) -> Result<LoadedScene> {
        let ctx = Ctx { file: path };
        self.sim
            .validate()
            .map_err(|e| ctx.err(&format!("sim.{}", e.field), e.msg))?;
        self.contact.validate("contact").map_err(|e| ctx.err(&e.field, e.msg))?;
        let mut parts = Vec::with_capacity(self.scene.len());
        for (i, s) in self.scene.iter().enumerate() {
            parts.push(s.build(&ctx, &format!("scene[{i}]"), false)?);
        }
        if parts.is_empty() {
            tracing::warn!("{}: no [[scene]] shapes: bodies fly freely", path.display());
        }
        let scene = if parts.len() == 1 {
            parts.pop().expect("one part")
        } else {
            Shape::Union(parts)
        };
        let mut world = World::new(self.sim.clone(), scene);
        if self.body.is_empty() {
            return Err(ctx.err("body", "the scene has no [[body]]"));
        }
        for (i, b) in self.body.iter().enumerate() {
            let field = format!("body[{i}] ({})", b.name);
            if self.body[..i].iter().any(|o| o.name == b.name) {
                return Err(ctx.err(&field, "two bodies have this name"));
            }
            let (body, state, contact) = self.build_body(&ctx, &field, b)?;
            world.add_body(body, state, contact, self.contact);
        }
        for (k, p) in self.pair.iter().enumerate() {
            let field = format!("pair[{k}]");
            let find = |n: &str| {
                self.body
                    .iter()
                    .position(|b| b.name == n)
                    .ok_or_else(|| ctx.err(&format!("{field}.bodies"), format!("no body named \"{n}\"")))
            };
            let (a, b) = (find(&p.bodies[0])?, find(&p.bodies[1])?);
            if a == b {
                return Err(ctx.err(&format!("{field}.bodies"), "a pair needs two different bodies"));
            }
            let c = ContactParams {
                restitution: p.restitution,
                friction: p.friction,
            };
            c.validate(&field).map_err(|e| ctx.err(&e.field, e.msg))?;
            let idx = world.pair_index(a, b);
            world.pair_contact[idx] = c;
        }
        world.validate().map_err(|e| ctx.err(&e.field, e.msg))?;
        let name = self.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".into())
        });
        Ok(LoadedScene { name, world })
    }

    fn build_body(&self, ctx: &Ctx, field: &str, b: &BodySpec) -> Result<(RigidBody, BodyState<f64>, ContactParams)> {
        let f = |name: &str| format!("{field}.{name}");
        let mass = match (b.mass, b.density) {
            (Some(m), None) => MassSpec::Mass(ctx.positive(&f("mass"), Some(m))?),
            (None, Some(d)) => MassSpec::Density(ctx.positive(&f("density"), Some(d))?),
            (Some(_), Some(_)) => return Err(ctx.err(field, "give `mass` or `density`, not both")),
            (None, None) => return Err(ctx.err(field, "give `mass` (kg) or `density` (kg/m³)")),
        };
        let sampling = if b.contact_vertices.unwrap_or(false) {
            ContactSampling::Vertices
        } else {
            let count = b.contact_points.unwrap_or(1000);
            if count == 0 {
                return Err(ctx.err(&f("contact_points"), "must be at least 1"));
            }
            ContactSampling::Surface {
                count,
                seed: b.seed.unwrap_or(0),
            }
        };
        let body = match (&b.shape, &b.mesh) {
            (Some(s), None) => {
                let shape = s.build(ctx, &f("shape"), true)?;
                RigidBody::from_shape(&b.name, &shape, mass, sampling).map_err(|e| ctx.err(field, e))?
            }
            (None, Some(m)) => {
                let path = ctx.resolve(m);
                let mesh = pganeus_io::read_mesh(&path).map_err(|e| ctx.err(&f("mesh"), e))?;
                let body = RigidBody::from_mesh(&b.name, &mesh, mass, sampling, None)
                    .map_err(|e| ctx.err(&f("mesh"), format!("{}: {e}", path.display())))?;
                if body.mesh_offset.norm() > 1e-3 {
                    tracing::warn!(
                        "{}: the centre of mass of {} is at {:?} in its file; `t` places the centre of mass",
                        ctx.file.display(),
                        path.display(),
                        body.mesh_offset.to_array()
                    );
                }
                body
            }
            (Some(_), Some(_)) => return Err(ctx.err(field, "give `shape` or `mesh`, not both")),
            (None, None) => return Err(ctx.err(field, "give a `shape` table or a `mesh` file")),
        };
        ctx.finite(&f("t"), b.t)?;
        let v = b.v.unwrap_or([0.0; 3]);
        let omega = b.omega.unwrap_or([0.0; 3]);
        ctx.finite(&f("v"), v)?;
        ctx.finite(&f("omega"), omega)?;
        let q = ctx.quat(&f("q"), b.q)?;
        let contact = b.contact.unwrap_or(self.contact);
        contact.validate(&f("contact")).map_err(|e| ctx.err(&e.field, e.msg))?;
        Ok((body, BodyState::new(b.t, q.to_array_re(), v, omega), contact))
    }
}
