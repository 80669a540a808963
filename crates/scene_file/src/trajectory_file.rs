//! A simulated world's motion as a trajectory file (`trajectory.json`, and the
//! videos of `truth.json`: docs/formats.md), and the body pairs' contact values
//! read back from one. Every writer (`simulate`, `target`, `fit-physics`,
//! `fit`, `synth`) goes through [`trajectory_file`].

use pganeus_io::{BodyState as IoState, Contact, Pose as IoPose, Trajectory as IoTrajectory, VideoBody};
use serde_json::{json, Map, Value};
use sim::{ContactParams, Trajectory, World};

/// The trajectory file of `world` moving as `traj`, captured as `capture`:
/// each body's poses, initial state, mass, contact values, velocities and
/// scene-contact flags per frame; the body pairs' values and contact flags
/// (`contact.pairs`, when there are pairs); the simulator's settings (`sim`).
/// `model` names the engine that made the motion (`pganeus`, `rapier`);
/// `extra` keys are added at the top level.
pub fn trajectory_file(
    capture: &str,
    world: &World,
    traj: &Trajectory<f64>,
    model: &str,
    extra: Map<String, Value>,
) -> IoTrajectory {
    let bodies = world
        .bodies
        .iter()
        .enumerate()
        .map(|(b, body)| {
            let mut e = Map::new();
            e.insert("mass".into(), json!(body.mass));
            e.insert(
                "contact".into(),
                json!({"restitution": world.scene_contact[b].restitution, "friction": world.scene_contact[b].friction}),
            );
            e.insert(
                "velocities".into(),
                json!(traj
                    .frames
                    .iter()
                    .map(|f| [f[b].v.to_array(), f[b].omega.to_array()])
                    .collect::<Vec<_>>()),
            );
            e.insert(
                "scene_contact".into(),
                json!(traj.contacts.iter().map(|c| c.scene[b]).collect::<Vec<_>>()),
            );
            VideoBody {
                name: body.name.clone(),
                initial: {
                    let s = &traj.frames[0][b];
                    IoState::from_geom(&s.pose, s.v, s.omega)
                },
                poses: traj.frames.iter().map(|f| IoPose::from_geom(&f[b].pose)).collect(),
                extra: e,
            }
        })
        .collect();
    let pairs: Vec<Value> = world
        .pairs()
        .iter()
        .zip(&world.pair_contact)
        .enumerate()
        .map(|(k, (&(i, j), c))| {
            json!({
                "bodies": [world.bodies[i].name, world.bodies[j].name],
                "restitution": c.restitution,
                "friction": c.friction,
                "contact": traj.contacts.iter().map(|f| f.pairs[k]).collect::<Vec<_>>(),
            })
        })
        .collect();
    let mut contact_extra = Map::new();
    if !pairs.is_empty() {
        contact_extra.insert("pairs".into(), Value::Array(pairs));
    }
    let mut top = extra;
    top.insert(
        "sim".into(),
        serde_json::to_value(&world.config).expect("config serialises"),
    );
    let c0 = world.scene_contact.first().copied().unwrap_or_default();
    IoTrajectory {
        capture: capture.to_string(),
        fps: world.config.fps,
        bodies,
        contact: Contact {
            restitution: c0.restitution,
            friction: c0.friction,
            model: model.into(),
            extra: contact_extra,
        },
        extra: top,
    }
}

/// The pairs' values of a trajectory file's `contact.pairs`: each pair's body names (sorted), restitution
/// and friction (entries without them are skipped).
pub fn contact_pairs(t: &IoTrajectory) -> Vec<([String; 2], ContactParams)> {
    let list = t
        .contact
        .extra
        .get("pairs")
        .and_then(|p| p.as_array())
        .cloned()
        .unwrap_or_default();
    list.iter()
        .filter_map(|p| {
            let mut names: [String; 2] = serde_json::from_value(p["bodies"].clone()).ok()?;
            names.sort();
            let c = ContactParams {
                restitution: p["restitution"].as_f64()?,
                friction: p["friction"].as_f64()?,
            };
            Some((names, c))
        })
        .collect()
}
