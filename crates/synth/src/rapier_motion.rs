//! Motion made by Rapier (`rapier3d-f64`), a well-kept engine this project did
//! not write: `synth --physics rapier` records a video's motion with it, so the
//! project's simulator and fitting are tested against motion they did not
//! make.
//!
//! Both engines move the same bodies: Rapier is given each body's mass and
//! inertia about its centre of mass from the project's `RigidBody` (its
//! colliders carry no density), and its shape as it is: the board a box, the
//! table a slab below it, boxes, spheres and capsules as Rapier's own shapes,
//! a rounded box as a round cuboid, a ramp as the convex hull of its corners,
//! mesh obstacles as triangle meshes and mesh bodies as a convex
//! decomposition (V-HACD; Rapier's triangle meshes have no inside, so a
//! moving one would not stay out of the scene). Every collider has the
//! video's restitution and friction, so Rapier's combination of the two
//! colliders' coefficients gives them back. Gyroscopic forces are on (a
//! tumbling body's ω changes with its orientation) and bodies never sleep;
//! Rapier's length unit is 10 cm, so its tolerances suit bodies that size.
//! Rapier steps `substeps` times a frame with dt = 1 / (fps · substeps).

use crate::build::StaticScene;
use crate::desc::{ShapeDesc, SynthScene, VideoDesc};
use geom::{Pose, Quat, Vec3};
use rapier3d_f64::prelude::{
    ColliderBuilder, ColliderHandle, MassProperties, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle,
};
use rapier3d_f64::prelude::{Matrix, Pose as RPose, Rotation, Vector};
use sim::{BodyState, FrameContacts, RigidBody, World};

/// Rapier's length unit for tabletop scenes, m (its default of 1 m suits bodies a metre across).
const LENGTH_UNIT: f64 = 0.1;

fn vector(v: Vec3<f64>) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

fn rotation(q: Quat<f64>) -> Rotation {
    let [w, x, y, z] = q.to_array_re();
    Rotation::from_xyzw(x, y, z, w)
}

fn pose(p: &Pose<f64>) -> RPose {
    RPose::from_parts(vector(p.t), rotation(p.q))
}

/// A shape's collider in its own frame (`mesh`: its surface there).
fn collider(shape: &ShapeDesc, mesh: &geom::TriMesh, moving: bool) -> ColliderBuilder {
    let points = || {
        mesh.vertices
            .iter()
            .map(|v| Vector::new(v[0], v[1], v[2]))
            .collect::<Vec<_>>()
    };
    match shape {
        ShapeDesc::Box { half } => ColliderBuilder::cuboid(half[0], half[1], half[2]),
        ShapeDesc::Sphere { radius } => ColliderBuilder::ball(*radius),
        ShapeDesc::RoundedBox { half, radius } => {
            ColliderBuilder::round_cuboid(half[0] - radius, half[1] - radius, half[2] - radius, *radius)
        }
        ShapeDesc::Capsule { half_length, radius } => ColliderBuilder::capsule_z(*half_length, *radius),
        ShapeDesc::Wedge { .. } => ColliderBuilder::convex_hull(&points()).expect("a ramp has a volume"),
        ShapeDesc::Mesh { .. } if moving => ColliderBuilder::convex_decomposition(&points(), &mesh.faces),
        ShapeDesc::Mesh { .. } => {
            ColliderBuilder::trimesh(points(), mesh.faces.clone()).expect("the mesh was checked closed")
        }
    }
}

/// The bodies of `world` (built for the project's simulator from `scene`), moved by Rapier over the static
/// scene `stat` for the frames of `video`. The trajectory's contact reports are the frames in which Rapier's
/// solver applied a contact impulse.
pub(crate) fn simulate_with_rapier(
    scene: &SynthScene,
    stat: &StaticScene,
    video: &VideoDesc,
    world: &World,
) -> sim::Trajectory<f64> {
    let cfg = &world.config;
    let mut pw = PhysicsWorld::new();
    pw.gravity = Vector::new(cfg.gravity[0], cfg.gravity[1], cfg.gravity[2]);
    pw.integration_parameters.dt = cfg.dt();
    // Tabletop objects are centimetres across: Rapier's tolerances (its slop, its prediction distance) are
    // tuned for metre-sized ones and scale with this.
    pw.integration_parameters.length_unit = LENGTH_UNIT;
    // Rapier gives a contact the mean of its two colliders' values: bodies carry the pair's values and the
    // scene `2 c − p`, so a body meets the scene with `c` and another body with `p`.
    let (c, p) = (video.contact, video.pair_contact.unwrap_or(video.contact));
    let scene_side = |c: f64, p: f64| (2.0 * c - p).max(0.0);
    let (e, mu) = (
        scene_side(c.restitution, p.restitution),
        scene_side(c.friction, p.friction),
    );
    let with_contact = |c: ColliderBuilder| c.restitution(e).friction(mu).density(0.0);
    let with_pair_contact = |c: ColliderBuilder| c.restitution(p.restitution).friction(p.friction).density(0.0);

    // The static scene: the board, the table, the obstacles.
    let b = &scene.board;
    let mut statics: Vec<ColliderHandle> = Vec::new();
    statics.push(pw.insert_collider(
        with_contact(ColliderBuilder::cuboid(b.half[0], b.half[1], 0.5 * b.thickness)).translation(Vector::new(
            0.0,
            0.0,
            -0.5 * b.thickness,
        )),
        None,
    ));
    if b.table.is_some() {
        // A slab 2 m thick and 100 m wide: the endless table under the board.
        statics.push(pw.insert_collider(
            with_contact(ColliderBuilder::cuboid(50.0, 50.0, 1.0)).translation(Vector::new(
                0.0,
                0.0,
                -b.thickness - 1.0,
            )),
            None,
        ));
    }
    // `stat.meshes`: the board, then each obstacle in the world frame.
    for (o, world_mesh) in scene.obstacles.iter().zip(&stat.meshes[1..]) {
        let c = match o.shape {
            // Built from the mesh: already placed.
            ShapeDesc::Wedge { .. } | ShapeDesc::Mesh { .. } => collider(&o.shape, world_mesh, false),
            _ => collider(&o.shape, world_mesh, false).position(pose(&pganeus_io::Pose { t: o.t, q: o.q }.to_geom())),
        };
        statics.push(pw.insert_collider(with_contact(c), None));
    }

    // The bodies, at their initial states, with the project's mass properties.
    let initial = world.initial.clone();
    let mut handles: Vec<(RigidBodyHandle, ColliderHandle)> = Vec::new();
    for (body, st) in world.bodies.iter().zip(&initial) {
        let desc = scene
            .bodies
            .iter()
            .find(|d| d.name == body.name)
            .expect("the world was built from the scene's bodies");
        let i = &body.inertia;
        let inertia = Matrix::from_cols(
            Vector::new(i.m[0][0], i.m[1][0], i.m[2][0]),
            Vector::new(i.m[0][1], i.m[1][1], i.m[2][1]),
            Vector::new(i.m[0][2], i.m[1][2], i.m[2][2]),
        );
        let rb = RigidBodyBuilder::dynamic()
            .pose(pose(&st.pose))
            .linvel(vector(st.v))
            .angvel(vector(st.omega))
            .additional_mass_properties(MassProperties::with_inertia_matrix(Vector::ZERO, body.mass, inertia))
            .gyroscopic_forces_enabled(true)
            .can_sleep(false);
        let h = pw.insert_body(rb);
        let c = pw.insert_collider(with_pair_contact(body_collider(body, &desc.shape)), Some(h));
        handles.push((h, c));
    }

    let read = |pw: &PhysicsWorld| -> Vec<BodyState<f64>> {
        handles
            .iter()
            .map(|&(h, _)| {
                let rb = &pw.bodies[h];
                let p = rb.position();
                let r = p.rotation;
                let (v, w) = (rb.linvel(), rb.angvel());
                BodyState::new(
                    [p.translation.x, p.translation.y, p.translation.z],
                    [r.w, r.x, r.y, r.z],
                    [v.x, v.y, v.z],
                    [w.x, w.y, w.z],
                )
            })
            .collect()
    };
    let pairs = world.pairs();
    let mut frames = vec![read(&pw)];
    // Every frame's record has a slot per body and per pair, frame 0's too (nothing touched yet), as the
    // project's simulator writes them: the truth file reads one per body.
    let none = FrameContacts {
        scene: vec![false; handles.len()],
        scene_points: vec![0; handles.len()],
        pairs: vec![false; pairs.len()],
    };
    let mut contacts = vec![none.clone()];
    for _ in 1..cfg.frames {
        let mut touched = none.clone();
        for _ in 0..cfg.substeps {
            pw.step();
            for (bi, &(_, c)) in handles.iter().enumerate() {
                for pair in pw.narrow_phase.contact_pairs_with(c) {
                    // An impulse was applied (as the project's simulator reports contacts).
                    if pair.total_impulse_magnitude() <= 0.0 {
                        continue;
                    }
                    let other = if pair.collider1 == c {
                        pair.collider2
                    } else {
                        pair.collider1
                    };
                    if statics.contains(&other) {
                        touched.scene[bi] = true;
                        let points = pushing_points(pair);
                        touched.scene_points[bi] = touched.scene_points[bi].max(points);
                    } else if let Some(bj) = handles.iter().position(|&(_, oc)| oc == other) {
                        let (lo, hi) = (bi.min(bj), bi.max(bj));
                        if let Some(k) = pairs.iter().position(|&p| p == (lo, hi)) {
                            touched.pairs[k] = true;
                        }
                    }
                }
            }
        }
        frames.push(read(&pw));
        contacts.push(touched);
    }
    sim::Trajectory { frames, contacts }
}

/// How many of a pair's contact points Rapier pushed apart (a positive normal impulse).
fn pushing_points(pair: &rapier3d_f64::prelude::ContactPair) -> usize {
    match &pair.contacts {
        rapier3d_f64::prelude::PairContacts::Rigid(r) => r
            .manifolds
            .iter()
            .map(|m| m.points.iter().filter(|p| p.data.impulse > 0.0).count())
            .sum(),
        _ => 0,
    }
}

/// A body's collider in its body frame (origin at the centre of mass: the shape's own frame moved by
/// `−mesh_offset`).
fn body_collider(body: &RigidBody, shape: &ShapeDesc) -> ColliderBuilder {
    let c = collider(shape, &body.mesh, true);
    match shape {
        // Already in the body frame: built from the body's own mesh.
        ShapeDesc::Wedge { .. } | ShapeDesc::Mesh { .. } => c,
        _ => c.translation(vector(-body.mesh_offset)),
    }
}
