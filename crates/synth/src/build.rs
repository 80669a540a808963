//! From a description to things that simulate and render: checks every field,
//! meshes and bodies, the static scene as the simulator sees it, and render
//! objects.

use crate::desc::{ShapeDesc, SynthScene};
use crate::render::RenderObject;
use crate::texture::Texture;
use geom::{Pose, Quat, TriMesh, Vec3};
use sim::sdf::{Capsule, Cuboid, Plane, RoundedBox, SdfGrid, Shape, Sphere, Wedge};
use sim::{ContactSampling, MassSpec, RigidBody};
use std::path::Path;
use std::sync::Arc;

#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// A field of the scene description is wrong.
    #[error("{field}: {msg}")]
    Field { field: String, msg: String },
    #[error(transparent)]
    Io(#[from] pganeus_io::IoError),
    #[error("{path}: {msg}")]
    File { path: String, msg: String },
}

pub(crate) fn field(field: impl Into<String>, msg: impl Into<String>) -> SynthError {
    SynthError::Field {
        field: field.into(),
        msg: msg.into(),
    }
}

fn finite<const N: usize>(f: &str, v: [f64; N]) -> Result<(), SynthError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(field(f, format!("has NaN or infinite values: {v:?}")))
    }
}

fn positive(f: &str, v: f64) -> Result<(), SynthError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(field(f, format!("must be positive, got {v}")))
    }
}

fn positive3(f: &str, v: [f64; 3]) -> Result<(), SynthError> {
    if v.iter().all(|x| x.is_finite() && *x > 0.0) {
        Ok(())
    } else {
        Err(field(f, format!("every component must be positive, got {v:?}")))
    }
}

pub(crate) fn unit_quat(f: &str, q: [f64; 4]) -> Result<Quat<f64>, SynthError> {
    finite(f, q)?;
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if n < 1e-9 {
        return Err(field(f, "quaternion has zero length"));
    }
    Ok(Quat::cst(q).normalize_or_identity())
}

fn texture(f: &str, t: &Texture) -> Result<(), SynthError> {
    t.validate(f).map_err(|m| {
        let (fld, msg) = m.split_once(": ").unwrap_or((f, &m));
        field(fld, msg)
    })
}

/// A shape in its own frame, and a closed mesh of it.
pub(crate) fn build_shape(f: &str, s: &ShapeDesc, base: &Path) -> Result<(Shape, TriMesh), SynthError> {
    use sim::tessellate::shape_mesh;
    let shape = match s {
        ShapeDesc::Box { half } => {
            positive3(&format!("{f}.half"), *half)?;
            Shape::Cuboid(Cuboid { half: *half })
        }
        ShapeDesc::Sphere { radius } => {
            positive(&format!("{f}.radius"), *radius)?;
            Shape::Sphere(Sphere { radius: *radius })
        }
        ShapeDesc::RoundedBox { half, radius } => {
            positive3(&format!("{f}.half"), *half)?;
            positive(&format!("{f}.radius"), *radius)?;
            if *radius >= half.iter().cloned().fold(f64::INFINITY, f64::min) {
                return Err(field(format!("{f}.radius"), "must be below every half extent"));
            }
            Shape::RoundedBox(RoundedBox {
                half: *half,
                radius: *radius,
            })
        }
        ShapeDesc::Capsule { half_length, radius } => {
            if !(half_length.is_finite() && *half_length >= 0.0) {
                return Err(field(
                    format!("{f}.half_length"),
                    format!("must be ≥ 0, got {half_length}"),
                ));
            }
            positive(&format!("{f}.radius"), *radius)?;
            Shape::Capsule(Capsule {
                half_length: *half_length,
                radius: *radius,
            })
        }
        ShapeDesc::Wedge { half } => {
            positive3(&format!("{f}.half"), *half)?;
            Shape::Wedge(Wedge { half: *half })
        }
        ShapeDesc::Mesh { file } => {
            let path = if file.is_absolute() {
                file.clone()
            } else {
                base.join(file)
            };
            let mesh = pganeus_io::read_mesh(&path)?;
            sim::check_closed_mesh(&mesh).map_err(|e| SynthError::File {
                path: path.display().to_string(),
                msg: e.to_string(),
            })?;
            // 1/128 of its size: fine enough that sharp corners render sharp.
            let grid = SdfGrid::from_mesh(&mesh, 128, 4.0).map_err(|e| SynthError::File {
                path: path.display().to_string(),
                msg: e.to_string(),
            })?;
            return Ok((Shape::Grid(Arc::new(grid)), mesh));
        }
    };
    let mesh = shape_mesh(&shape, 24).expect("analytic solids have meshes");
    Ok((shape, mesh))
}

/// The static part of a scene: the board, the table under it, obstacles.
pub(crate) struct StaticScene {
    /// What the simulator collides with.
    pub shape: Shape,
    /// What the camera sees, and each obstacle's mesh (world frame) for background.ply.
    pub objects: Vec<RenderObject>,
    /// `objects` starts with the board and the table (if any): this many, then the obstacles.
    pub board_and_table: usize,
    pub meshes: Vec<TriMesh>,
    /// The region of interest: a ball around the board top and the obstacles.
    pub region: (Vec3<f64>, f64),
}

/// Bodies ready to simulate, with their textures.
pub(crate) struct Bodies {
    pub bodies: Vec<RigidBody>,
    pub textures: Vec<Texture>,
}

pub(crate) fn build_static(scene: &SynthScene, base: &Path) -> Result<StaticScene, SynthError> {
    let b = &scene.board;
    if !(b.half.iter().all(|v| v.is_finite() && *v > 0.0)) {
        return Err(field("board.half", format!("must be positive, got {:?}", b.half)));
    }
    positive("board.thickness", b.thickness)?;
    texture("board.texture", &b.texture)?;
    if let Some(t) = &b.table {
        texture("board.table", t)?;
    }
    let slab = Cuboid {
        half: [b.half[0], b.half[1], 0.5 * b.thickness],
    };
    let slab_pose = Pose::from_translation(Vec3::new(0.0, 0.0, -0.5 * b.thickness));
    let board_shape = Shape::Cuboid(slab);
    let print = match &b.print {
        Some(spec) => {
            let board = calib::Board::new(spec.clone()).map_err(|e| field("board.print", e.to_string()))?;
            let print = crate::print::Print { board, margin: 0.01 };
            let [hx, hy] = print.half_paper();
            if hx > b.half[0] || hy > b.half[1] {
                return Err(field(
                    "board.print",
                    format!(
                        "the print ({:.0} x {:.0} mm with its margin) is larger than the board ({:.0} x {:.0} mm)",
                        2e3 * hx,
                        2e3 * hy,
                        2e3 * b.half[0],
                        2e3 * b.half[1]
                    ),
                ));
            }
            Some(std::sync::Arc::new(print))
        }
        None => None,
    };
    let mut objects = vec![RenderObject {
        shape: board_shape.clone(),
        pose: slab_pose,
        texture: b.texture.clone(),
        bound: Some((slab_pose.t, Vec3::cst(slab.half).norm())),
        mask_id: None,
        print: print.clone(),
    }];
    let mut sim_parts = vec![board_shape.clone().transformed(slab_pose)];
    if let Some(texture) = &b.table {
        let table = Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: -b.thickness,
        });
        objects.push(RenderObject {
            shape: table.clone(),
            pose: Pose::identity(),
            texture: texture.clone(),
            bound: None,
            mask_id: None,
            print: None,
        });
        sim_parts.push(table);
    }
    let board_and_table = objects.len();
    let mut board_mesh = sim::tessellate::cuboid_mesh(&slab, 1);
    for v in &mut board_mesh.vertices {
        v[2] -= 0.5 * b.thickness;
    }
    let mut meshes = vec![board_mesh];
    let mut top = 0.0f64;
    let mut far = Vec3::new(b.half[0], b.half[1], 0.0).norm();
    let mut names: Vec<&str> = Vec::new();
    for (i, o) in scene.obstacles.iter().enumerate() {
        let f = format!("obstacles[{i}] ({})", o.name);
        if names.contains(&o.name.as_str()) {
            return Err(field(&f, "two obstacles have this name"));
        }
        names.push(&o.name);
        finite(&format!("{f}.t"), o.t)?;
        let q = unit_quat(&format!("{f}.q"), o.q)?;
        texture(&format!("{f}.texture"), &o.texture)?;
        let (shape, mesh) = build_shape(&format!("{f}.shape"), &o.shape, base)?;
        let pose = Pose::new(q, Vec3::cst(o.t));
        let radius = mesh.vertices.iter().map(|v| Vec3::cst(*v).norm()).fold(0.0, f64::max);
        let world_mesh = TriMesh::new(
            mesh.vertices
                .iter()
                .map(|v| pose.transform_point(Vec3::cst(*v)).to_array())
                .collect(),
            mesh.faces.clone(),
        );
        for v in &world_mesh.vertices {
            top = top.max(v[2]);
            far = far.max(Vec3::new(v[0], v[1], 0.0).norm());
        }
        meshes.push(world_mesh);
        sim_parts.push(shape.clone().transformed(pose));
        objects.push(RenderObject {
            shape,
            pose,
            texture: o.texture.clone(),
            bound: Some((pose.t, radius)),
            mask_id: None,
            print: None,
        });
    }
    let centre = Vec3::new(0.0, 0.0, 0.5 * top);
    let region = (centre, (far * far + 0.25 * top * top).sqrt() * 1.05);
    Ok(StaticScene {
        shape: Shape::Union(sim_parts),
        objects,
        board_and_table,
        meshes,
        region,
    })
}

pub(crate) fn build_bodies(scene: &SynthScene, base: &Path) -> Result<Bodies, SynthError> {
    let mut bodies = Vec::new();
    let mut textures = Vec::new();
    if scene.bodies.is_empty() {
        return Err(field("bodies", "the scene has no bodies"));
    }
    for (i, b) in scene.bodies.iter().enumerate() {
        let f = format!("bodies[{i}] ({})", b.name);
        if scene.bodies[..i].iter().any(|o| o.name == b.name) {
            return Err(field(&f, "two bodies have this name"));
        }
        if b.name.is_empty()
            || !b
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(field(
                format!("{f}.name"),
                "use letters, digits, '_' and '-' (it names folders)",
            ));
        }
        positive(&format!("{f}.mass"), b.mass)?;
        texture(&format!("{f}.texture"), &b.texture)?;
        if b.contact_points == 0 {
            return Err(field(format!("{f}.contact_points"), "must be at least 1"));
        }
        for (k, q) in b.static_orientations.iter().enumerate() {
            unit_quat(&format!("{f}.static_orientations[{k}]"), *q)?;
        }
        let (shape, mesh) = build_shape(&format!("{f}.shape"), &b.shape, base)?;
        let sampling = ContactSampling::Surface {
            count: b.contact_points,
            seed: i as u64,
        };
        // The exact shape, or the mesh's grid baked above (finer than the
        // simulator's default body grid, so sharp corners render sharp).
        let body = RigidBody::from_mesh(&b.name, &mesh, MassSpec::Mass(b.mass), sampling, Some(shape))
            .map_err(|e| field(&f, e.to_string()))?;
        bodies.push(body);
        textures.push(b.texture.clone());
    }
    Ok(Bodies { bodies, textures })
}

/// The pose at which a body rests on the board (lowest point at z = 0) with
/// orientation `q`, centred at `xy`.
pub(crate) fn resting_pose(body: &RigidBody, q: Quat<f64>, xy: [f64; 2]) -> Pose<f64> {
    let low = body
        .mesh
        .vertices
        .iter()
        .map(|v| q.rotate(Vec3::cst(*v)).z)
        .fold(f64::INFINITY, f64::min);
    Pose::new(q, Vec3::new(xy[0], xy[1], -low))
}

/// A body placed in the world as a render object.
pub(crate) fn body_object(body: &RigidBody, texture: &Texture, pose: Pose<f64>, mask_id: usize) -> RenderObject {
    RenderObject {
        shape: body.sdf.clone(),
        pose,
        texture: texture.clone(),
        bound: Some((pose.t, body.bounding_radius * 1.01 + 1e-4)),
        mask_id: Some(mask_id),
        print: None,
    }
}
