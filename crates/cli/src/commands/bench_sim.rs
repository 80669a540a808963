//! Simulator timings: a 50-frame trajectory at 60 fps with 10 substeps and
//! 1,000 contact points per body, sliding on a table, for 1, 2 and 4 bodies:
//! forward only, with the gradients of one body (14 parameters), and with all
//! gradients. One JSON line per figure, median of several runs.

use anyhow::Result;
use clap::Args;
use sim::sdf::{Cuboid, Plane, Shape};
use sim::{simulate_with_gradients, BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};
use std::time::Instant;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus bench-sim
  pganeus bench-sim --threads 1 --runs 7 --contact-model multi-point
  pganeus bench-sim --scene grid")]
pub struct BenchSimArgs {
    /// Threads (the target figure is for one core).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Runs per figure (the median is printed).
    #[arg(long, default_value_t = 7)]
    pub runs: usize,
    /// The contact model timed: mean-point (the paper's) or multi-point.
    #[arg(long, value_enum, default_value = "mean-point")]
    pub contact_model: ContactModelArg,
    /// The scene as analytic shapes (exact distances) or baked into a grid of 3.5 mm cells, as a
    /// reconstructed scene is.
    #[arg(long, value_enum, default_value = "analytic")]
    pub scene: SceneArg,
}

#[derive(Clone, Copy, PartialEq, clap::ValueEnum)]
pub enum SceneArg {
    Analytic,
    Grid,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum ContactModelArg {
    MeanPoint,
    MultiPoint,
}

impl ContactModelArg {
    fn model(self) -> sim::ContactModel {
        match self {
            ContactModelArg::MeanPoint => sim::ContactModel::MeanPoint,
            ContactModelArg::MultiPoint => sim::ContactModel::MultiPoint,
        }
    }

    fn name(self) -> &'static str {
        match self {
            ContactModelArg::MeanPoint => "mean_point",
            ContactModelArg::MultiPoint => "multi_point",
        }
    }
}

fn bench_world(bodies: usize, model: sim::ContactModel, scene: SceneArg) -> Result<World> {
    let ground = Shape::Plane(Plane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    });
    let wall = Shape::Cuboid(Cuboid {
        half: [0.02, 0.5, 0.05],
    })
    .transformed(geom::Pose::from_translation(geom::Vec3::new(0.6, 0.0, 0.05)));
    let mut w = World::new(
        SimConfig {
            fps: 60.0,
            frames: 50,
            substeps: 10,
            contact_model: model,
            ..SimConfig::default()
        },
        bench_scene(Shape::Union(vec![ground, wall]), scene)?,
    );
    let c = ContactParams {
        restitution: 0.4,
        friction: 0.3,
    };
    for i in 0..bodies {
        let b = RigidBody::from_shape(
            &format!("box{i}"),
            &Shape::Cuboid(Cuboid {
                half: [0.03, 0.025, 0.02],
            }),
            MassSpec::Mass(0.2),
            ContactSampling::Surface {
                count: 1000,
                seed: i as u64,
            },
        )
        .expect("valid body");
        let y = 0.1 * i as f64;
        w.add_body(
            b,
            BodyState::new([0.0, y, 0.05], [1.0, 0.0, 0.0, 0.0], [1.5, 0.0, 0.5], [0.0, 0.0, 1.0]),
            c,
            c,
        );
    }
    Ok(w)
}

/// The scene as `scene` asks: the shapes themselves, or baked over the table's part the bodies reach
/// (a reconstructed scene's spacing).
fn bench_scene(shapes: Shape, scene: SceneArg) -> Result<Shape> {
    Ok(match scene {
        SceneArg::Analytic => shapes,
        SceneArg::Grid => Shape::Grid(std::sync::Arc::new(sim::sdf::SdfGrid::bake(
            &shapes,
            [-0.3, -0.3, -0.05],
            [0.9, 0.6, 0.15],
            0.0035,
        )?)),
    })
}

impl SceneArg {
    fn name(self) -> &'static str {
        match self {
            SceneArg::Analytic => "analytic",
            SceneArg::Grid => "grid",
        }
    }
}

fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    f(); // warm-up
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

pub fn run(a: BenchSimArgs) -> Result<()> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads.max(1)).build()?;
    pool.install(|| -> Result<()> {
        for bodies in [1, 2, 4] {
            let w = bench_world(bodies, a.contact_model.model(), a.scene)?;
            let p = w.params();
            let forward = median_ms(a.runs, || {
                std::hint::black_box(w.simulate(&p));
            });
            let one: Vec<usize> = (0..sim::BODY_PARAMS).collect();
            let grad_one = median_ms(a.runs, || {
                std::hint::black_box(simulate_with_gradients(&w, &p, &one));
            });
            let all: Vec<usize> = (0..w.param_count()).collect();
            let grad_all = median_ms(a.runs, || {
                std::hint::black_box(simulate_with_gradients(&w, &p, &all));
            });
            for (mode, ms, params) in [("forward", forward, 0), ("gradients_one_body", grad_one, one.len()), ("gradients_all", grad_all, all.len())] {
                println!(
                    "{}",
                    serde_json::json!({
                        "bench": "sim", "contact_model": a.contact_model.name(), "scene": a.scene.name(), "bodies": bodies, "mode": mode, "params": params, "ms": (ms * 1000.0).round() / 1000.0,
                        "frames": 50, "fps": 60, "substeps": 10, "contact_points": 1000, "threads": a.threads,
                    })
                );
            }
        }
        Ok(())
    })
}
