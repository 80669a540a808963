//! Composed-rendering timings (issue "Objects in their scene"): rays per second
//! of the composed forward and of forward + pose backward, for the window of
//! pixels whose rays meet the object and for the whole frame; the reference
//! (every field along every ray) and the fixed camera's fast path (the object
//! over the scene rendered once); buffers reused across chunks or fresh per
//! chunk (what rendering did before the composer kept them). One JSON line per
//! figure, the best of `--runs`.

use anyhow::{anyhow, bail, Result};
use clap::Args;
use geom::Vec3;
use neus::checkpoint::load_field;
use neus::compose::{prerender_scene, Behind, ComposedRay, Composer, Layer, RayGradient};
use pipeline::cameras::world_cameras;
use pipeline::render_trajectory::read_motion;
use pipeline::run_folder::checkpoint_of;
use pipeline::{load_objects, parse_objects};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus bench-compose --scene runs/scene --object toy=merged/toy --trajectory data/tabletop_large/truth.json --video slide --frame 20 --views data/tabletop_large/slide")]
pub struct BenchComposeArgs {
    /// The scene's run folder.
    #[arg(long)]
    pub scene: PathBuf,
    /// NAME=DIR: the object (a merge output or a run folder) and its body's name in the trajectory.
    #[arg(long)]
    pub object: String,
    /// A trajectory.json or truth.json giving the object's pose (pick a truth.json's video with --video).
    #[arg(long)]
    pub trajectory: PathBuf,
    #[arg(long)]
    pub video: Option<String>,
    /// The frame whose pose to use.
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// The capture whose first camera looks (e.g. the video's).
    #[arg(long)]
    pub views: PathBuf,
    /// Runs per figure (the best is printed).
    #[arg(long, default_value_t = 1)]
    pub runs: usize,
    /// Only the window around the object (skip the whole-frame figures).
    #[arg(long)]
    pub window_only: bool,
    /// Bake the object's geometry this many lattice steps a cell of its occupancy grid (0: the network),
    /// and print how far its renders are from the network's.
    #[arg(long, default_value_t = 0)]
    pub bake: usize,
}

/// A figure's rays: case, path, origins, directions and the pre-rendered scene behind them (fast path).
type Case<'a> = (
    &'a str,
    &'a str,
    &'a [Vec3<f64>],
    &'a [Vec3<f64>],
    Option<&'a [ComposedRay]>,
);

/// Rays through the composer in chunks of 2,048; the seconds it took.
fn time_rays(
    layers: &[Layer<'_>],
    behind: Option<&[ComposedRay]>,
    o: &[Vec3<f64>],
    d: &[Vec3<f64>],
    backward: bool,
    reuse: bool,
) -> f64 {
    const CHUNK: usize = 2048;
    let t = Instant::now();
    let mut composer = Composer::default();
    let mut under = Vec::new();
    for start in (0..o.len()).step_by(CHUNK) {
        let end = (start + CHUNK).min(o.len());
        if !reuse {
            composer = Composer::default();
        }
        let b = match behind {
            Some(s) => {
                under.clear();
                under.extend_from_slice(&s[start..end]);
                Behind::Scene(&under)
            }
            None => Behind::Colour([1.0; 3]),
        };
        composer.forward(layers, 1, b, &o[start..end], &d[start..end]);
        if backward {
            let g = RayGradient {
                rgb: [1.0; 3],
                depth: 1.0,
                object_opacity: vec![1.0],
            };
            let grads = vec![g; end - start];
            std::hint::black_box(composer.backward(layers, &grads));
        }
        std::hint::black_box(&composer.out);
    }
    t.elapsed().as_secs_f64()
}

pub fn run(a: BenchComposeArgs) -> Result<()> {
    let objects = load_objects(&parse_objects(std::slice::from_ref(&a.object))?, a.bake)?;
    let name = objects[0].0.as_str();
    let (_, _, motion) = read_motion(&a.trajectory, a.video.as_deref(), &objects)?;
    let body = motion
        .iter()
        .find(|m| m.name == name)
        .ok_or_else(|| anyhow!("{}: no body named {name:?}", a.trajectory.display()))?;
    let Some(pose) = body.poses.get(a.frame) else {
        bail!(
            "{}: no frame {} (it has {})",
            a.trajectory.display(),
            a.frame,
            body.poses.len()
        );
    };
    let capture = pganeus_io::open_capture(&a.views)?;
    let cam = world_cameras(&capture)?[0];
    let scene = load_field(&checkpoint_of(&a.scene))?;
    let model = &objects[0].1;
    let routed = model.route(pose, &cam);
    let object = || Layer::object(&routed.field, &routed.capture_from_body, pose, 0);

    let probe = object();
    let (mut all_o, mut all_d, mut win_o, mut win_d, mut win_px) = (vec![], vec![], vec![], vec![], vec![]);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let r = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
            all_o.push(r.origin);
            all_d.push(r.dir);
            if probe.meets(r.origin, r.dir) {
                win_o.push(r.origin);
                win_d.push(r.dir);
                win_px.push((y * cam.width + x) as usize);
            }
        }
    }
    if win_o.is_empty() {
        bail!(
            "the object is not in view of {}'s camera at frame {}",
            a.views.display(),
            a.frame
        );
    }
    let t = Instant::now();
    let pre = prerender_scene(&scene, &cam, &mut Composer::default());
    let prerender_s = t.elapsed().as_secs_f64();
    println!(
        "{}",
        serde_json::json!({"bench": "compose", "case": "prerender scene", "rays": pre.len(),
            "seconds": prerender_s, "rays_per_s": pre.len() as f64 / prerender_s})
    );
    let win_behind: Vec<ComposedRay> = win_px.iter().map(|&p| pre[p].clone()).collect();
    if a.bake > 0 {
        let network = load_objects(&parse_objects(std::slice::from_ref(&a.object))?, 0)?;
        let net_routed = network[0].1.route(pose, &cam);
        let net = Layer::object(&net_routed.field, &net_routed.capture_from_body, pose, 0);
        let moved = geom::Pose::new(
            geom::Quat::exp(Vec3::new(0.0, 0.0, 1f64.to_radians())) * pose.q,
            pose.t + Vec3::new(0.001, 0.0, 0.0),
        );
        let moved_net = Layer::object(&net_routed.field, &net_routed.capture_from_body, &moved, 0);
        println!(
            "{}",
            baked_against_network(&object(), &net, &moved_net, &win_behind, &win_o, &win_d)
        );
    }
    let reference = [Layer::scene(&scene), object()];
    let fast = [object()];
    let mut cases: Vec<Case<'_>> = vec![
        ("window", "reference", &win_o, &win_d, None),
        ("window", "fast", &win_o, &win_d, Some(&win_behind)),
    ];
    if !a.window_only {
        cases.push(("frame", "reference", &all_o, &all_d, None));
        cases.push(("frame", "fast", &all_o, &all_d, Some(&pre)));
    }
    for (case, path, o, d, behind) in cases {
        let layers: &[Layer<'_>] = if behind.is_some() { &fast } else { &reference };
        for backward in [false, true] {
            for reuse in [true, false] {
                let best = (0..a.runs.max(1))
                    .map(|_| time_rays(layers, behind, o, d, backward, reuse))
                    .fold(f64::INFINITY, f64::min);
                println!(
                    "{}",
                    serde_json::json!({"bench": "compose", "case": case, "path": path,
                        "pass": if backward { "forward+backward" } else { "forward" },
                        "buffers": if reuse { "reused" } else { "fresh per chunk" },
                        "rays": o.len(), "seconds": best, "rays_per_s": o.len() as f64 / best})
                );
            }
        }
    }
    Ok(())
}

/// How far the baked object's window is from the network's: colour (PSNR over the window, worst channel),
/// opacity, and the pose gradient of an image loss (the squared difference from the network's render at a
/// pose 1 mm and 1° away, as a fit's step sees it), relative to the network's (translation and rotation).
fn baked_against_network(
    baked: &Layer<'_>,
    net: &Layer<'_>,
    moved_net: &Layer<'_>,
    behind: &[ComposedRay],
    o: &[Vec3<f64>],
    d: &[Vec3<f64>],
) -> serde_json::Value {
    let forward = |layer: &Layer<'_>, c: &mut Composer| {
        c.forward(std::slice::from_ref(layer), 1, Behind::Scene(behind), o, d);
    };
    let mut c = Composer::default();
    forward(moved_net, &mut c);
    let target: Vec<[f32; 3]> = c.out.iter().map(|r| r.rgb).collect();
    let render = |layer: &Layer<'_>| {
        let mut c = Composer::default();
        forward(layer, &mut c);
        let grads: Vec<RayGradient> = c
            .out
            .iter()
            .zip(&target)
            .map(|(r, t)| RayGradient {
                rgb: std::array::from_fn(|k| 2.0 * (r.rgb[k] - t[k])),
                depth: 0.0,
                object_opacity: vec![0.0],
            })
            .collect();
        let grad = c.backward(std::slice::from_ref(layer), &grads)[0];
        (c.out.clone(), c.object_opacity.clone(), grad)
    };
    let (bo, bop, bg) = render(baked);
    let (no, nop, ng) = render(net);
    let mut sq = 0.0f64;
    let mut worst = 0.0f32;
    for (b, n) in bo.iter().zip(&no) {
        for k in 0..3 {
            let e = b.rgb[k] - n.rgb[k];
            sq += (e * e) as f64;
            worst = worst.max(e.abs());
        }
    }
    let mse = sq / (3 * bo.len()) as f64;
    let opacity = bop.iter().zip(&nop).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    let rel = |r: std::ops::Range<usize>| {
        let diff: f64 = r.clone().map(|k| (bg[k] - ng[k]).powi(2)).sum::<f64>().sqrt();
        diff / r.map(|k| ng[k].powi(2)).sum::<f64>().sqrt().max(1e-12)
    };
    // Where the baked render is less opaque: rays the network draws opaque, and the silhouette's edge.
    let deficit = |keep: fn(f32) -> bool| -> f32 {
        nop.iter()
            .zip(&bop)
            .filter(|(n, _)| keep(**n))
            .map(|(n, b)| n - b)
            .sum()
    };
    serde_json::json!({"bench": "compose", "case": "baked against the network", "rays": o.len(),
        "psnr_db": -10.0 * mse.max(1e-12).log10(), "worst_colour": worst, "worst_opacity": opacity,
        "translation_gradient_rel": rel(0..3), "rotation_gradient_rel": rel(3..6),
        "opacity_sum_baked": bop.iter().sum::<f32>(), "opacity_sum_network": nop.iter().sum::<f32>(),
        "opacity_deficit_inside": deficit(|n| n > 0.99), "opacity_deficit_edge": deficit(|n| n <= 0.99),
        "gradient_baked": bg, "gradient_network": ng})
}
