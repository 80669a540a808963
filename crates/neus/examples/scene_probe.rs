//! Watch a tabletop scene form (a development probe; CI builds it, does not run it): trains a `synth --preset
//! tabletop` (or `backdrop`) background capture with the scene preset and prints, every 50 steps, the height
//! of the zero level on the wall (true top 70 mm) and on the board (true 0) and the wall's foot (the board
//! before the face and the face near the board, true 0 and 200 mm), after scoring the stereo points against
//! the true surface.
//!
//! `cargo run --release -p neus --example scene_probe -- CAPTURE [CONFIG.toml|-] [STEPS] [LIFT_M]`
//! (`LIFT_M` starts the plane that far above the board; env `SEED`, `STEREO_W` override the config,
//! `STEREO_ONLY=1` stops after the stereo points, `STEREO_PLY=points.ply` writes them, world coordinates).
use geom::Vec3;
use neus::{CaptureSubject, Dataset, NeusField, NeusTrainer, TrainConfig};
use std::path::Path;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let data = Dataset::load(Path::new(&a[1])).unwrap();
    let mut cfg = TrainConfig::preset("fast", CaptureSubject::Scene).unwrap();
    if a.len() > 2 && a[2] != "-" {
        let text = std::fs::read_to_string(&a[2]).unwrap();
        cfg = toml::from_str(&text).unwrap();
    }
    if let Ok(seed) = std::env::var("SEED") {
        cfg.seed = seed.parse().unwrap();
    }
    if let Ok(w) = std::env::var("STEREO_W") {
        cfg.stereo_weight = w.parse().unwrap();
    }
    let steps: usize = a.get(3).map_or(600, |s| s.parse().unwrap());
    let lift: f64 = a.get(4).map_or(0.0, |s| s.parse().unwrap());
    let mut t = NeusTrainer::new(cfg.clone(), data).unwrap();
    if lift != 0.0 {
        let bh = ((lift - t.data.centre.z) / t.data.radius) as f32;
        t.field = NeusField::new(&cfg.field, cfg.seed, bh);
        if cfg.view_independent_steps > 0 {
            t.field.zero_view_weights();
        }
    }
    eprintln!("centre {:?} radius {}", t.data.centre, t.data.radius);
    let ts = std::time::Instant::now();
    let (centre, radius) = (t.data.centre, t.data.radius);
    let pts: Vec<[f64; 3]> = t
        .stereo_points()
        .iter()
        .map(|p| {
            let w = centre + Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * radius;
            [w.x, w.y, w.z]
        })
        .collect();
    // Distance to the tabletop truth: the board's top (z = 0) or the wall box.
    let wall = |p: [f64; 3]| {
        let q = [
            (p[0] - 0.22).abs() - 0.02,
            p[1].abs() - 0.12,
            (p[2] - 0.035).abs() - 0.035,
        ];
        let out = (q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>()).sqrt();
        out + q[0].max(q[1]).max(q[2]).min(0.0)
    };
    let ground = |p: [f64; 3]| {
        if p[0].abs() < 0.3 && p[1].abs() < 0.3 {
            p[2].abs()
        } else {
            (p[2] + 0.01).abs().min(p[2].abs())
        }
    };
    let d: Vec<f64> = pts.iter().map(|&p| ground(p).min(wall(p).abs())).collect();
    let on_wall = pts.iter().filter(|&&p| p[2] > 0.005 && wall(p).abs() < 0.005).count();
    let good = d.iter().filter(|&&v| v < 0.003).count();
    let far = d.iter().filter(|&&v| v > 0.01).count();
    eprintln!(
        "stereo: {} points in {:.1}s, within 3 mm {:.3}, beyond 1 cm {:.3}, on the wall {}",
        pts.len(),
        ts.elapsed().as_secs_f64(),
        good as f64 / pts.len().max(1) as f64,
        far as f64 / pts.len().max(1) as f64,
        on_wall
    );
    if let Ok(path) = std::env::var("STEREO_PLY") {
        let mut text = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
            pts.len()
        );
        for p in &pts {
            text += &format!("{} {} {}\n", p[0], p[1], p[2]);
        }
        std::fs::write(path, text).unwrap();
    }
    if std::env::var("STEREO_ONLY").is_ok() {
        return;
    }
    let t0 = std::time::Instant::now();
    for _ in 0..steps {
        let s = t.step();
        if s.step.is_multiple_of(50) {
            let height = |x, y| {
                t.field
                    .surface_height(t.data.centre, t.data.radius, x, y, -0.05, 0.3)
                    .unwrap_or(f64::NAN)
            };
            let wall: Vec<f64> = [(0.22, 0.0), (0.22, 0.08), (0.22, -0.08), (0.21, 0.04)]
                .iter()
                .map(|&(x, y)| (height(x, y) * 1e3).round())
                .collect();
            let board: Vec<f64> = [(-0.15, -0.05), (0.05, 0.1), (-0.2, -0.15)]
                .iter()
                .map(|&(x, y)| (height(x, y) * 1e4).round() / 10.0)
                .collect();
            let foot = foot_profile(&t, s.active_levels);
            println!(
                "step {} psnr {:.1} inv_s {:.0} occ {:.3} samples {} wall(mm) {:?} board(mm) {:?} foot {} {:.0}s",
                s.step,
                s.psnr,
                s.inv_s,
                s.occupied,
                s.samples,
                wall,
                board,
                foot,
                t0.elapsed().as_secs_f64()
            );
        }
    }
}

/// The wall's foot (the face the tabletop slide hits, true x = 0.2 m): the board's height 30, 10 and 5 mm before
/// the face and the face's x at heights 2, 5, 8 and 12 mm, each the median over 41 lines across y ∈ ±6 cm, in mm.
fn foot_profile(t: &NeusTrainer, levels: usize) -> String {
    let (c, r) = (t.data.centre, t.data.radius);
    // The first outside-to-inside crossing along `from + s·dir`, s in [0, len] (metres), by 0.1 mm samples.
    let crossing = |from: [f64; 3], dir: [f64; 3], len: f64| -> f64 {
        let n = (len / 1e-4) as usize;
        let pts: Vec<f32> = (0..=n)
            .flat_map(|i| {
                let s = i as f64 * 1e-4;
                (0..3).map(move |k| ((from[k] + s * dir[k] - c[k]) / r) as f32)
            })
            .collect();
        let v = t.field.sdf_values(&pts, levels);
        (1..v.len())
            .find(|&i| v[i - 1] > 0.0 && v[i] <= 0.0)
            .map_or(f64::NAN, |i| {
                (i as f64 - 1.0 + (v[i - 1] / (v[i - 1] - v[i])) as f64) * 1e-4
            })
    };
    let median = |mut v: Vec<f64>| {
        v.retain(|x| x.is_finite());
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let ys: Vec<f64> = (0..41).map(|i| -0.06 + 0.003 * i as f64).collect();
    let board: Vec<f64> = [0.17, 0.19, 0.195]
        .iter()
        .map(|&x| {
            median(
                ys.iter()
                    .map(|&y| 0.02 - crossing([x, y, 0.02], [0.0, 0.0, -1.0], 0.03))
                    .collect(),
            )
        })
        .collect();
    let face: Vec<f64> = [0.002, 0.005, 0.008, 0.012]
        .iter()
        .map(|&z| {
            median(
                ys.iter()
                    .map(|&y| 0.16 + crossing([0.16, y, z], [1.0, 0.0, 0.0], 0.06))
                    .collect(),
            )
        })
        .collect();
    format!(
        "board {:.1?} face {:.1?}",
        board.iter().map(|v| v * 1e3).collect::<Vec<_>>(),
        face.iter().map(|v| v * 1e3).collect::<Vec<_>>()
    )
}
