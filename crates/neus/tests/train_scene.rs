//! A scene capture (no masks; here a plain backdrop beyond the board) trains
//! into a clean surface: the board where it is, the obstacles standing, sparse
//! occupancy, no fog above it. Before the scene kind (a sphere start and a
//! constant colour behind the sphere), such a capture gave a fog filling most
//! of the sphere. The tabletop twin (a table beyond the board) is checked the
//! same way on the run `pganeus train` makes, in the CLI's scene test.
use neus::{CaptureSubject, Dataset, NeusTrainer, TrainConfig};
use std::path::{Path, PathBuf};

use crate::common;

/// The background capture of a preset at 96×72, 16 views.
fn scene_capture(preset: &str, dir: &Path) -> PathBuf {
    common::tiny_synth(preset, dir);
    dir.join("background")
}

fn tiny_scene_config() -> TrainConfig {
    let mut c = TrainConfig {
        iterations: 600,
        batch_rays: 512,
        steps_per_ray: 256,
        max_samples_per_ray: 32,
        occupancy_res: 32,
        occupancy_warmup: 100,
        anneal_end: 100,
        level_start: 4,
        level_every: 25,
        holdout_every: 8,
        ..TrainConfig::preset("fast", CaptureSubject::Scene).unwrap()
    };
    c.field.grid.levels = 10;
    c.field.grid.log2_table_size = 15;
    c.field.grid.max_resolution = 512;
    if let Some(b) = &mut c.field.background {
        b.grid.levels = 4;
        b.grid.log2_table_size = 12;
        b.grid.max_resolution = 64;
        b.samples = 12;
    }
    c
}

fn check_scene(preset: &str) {
    let dir = testkit::scratch_dir("neus", &format!("scene_{preset}"));
    let capture = scene_capture(preset, &dir);
    let data = Dataset::load(&capture).unwrap();
    assert!(!data.has_masks());
    let mut t = NeusTrainer::new(tiny_scene_config(), data).unwrap();
    let stats: Vec<_> = (0..600).map(|_| t.step()).collect();
    let last = stats.last().unwrap();
    let psnr: f32 = stats[550..].iter().map(|s| s.psnr).sum::<f32>() / 50.0;
    let h = testkit::TabletopHeights::measure(|x, y| {
        t.field.surface_height(t.data.centre, t.data.radius, x, y, -0.05, 0.2)
    });
    let (median, worst) = h.board_error();
    eprintln!(
        "{preset}: occupied {:.3}, inv_s {:.0}, batch PSNR {psnr:.1} dB, {}",
        last.occupied,
        last.inv_s,
        h.in_mm()
    );
    for w in &h.wall {
        // Measured 57–76 mm (tabletop) and 65–74 mm (backdrop); painted onto the board it is below 10 mm.
        assert!(
            (w - 0.07).abs() < 0.015,
            "{preset}: the wall's top at {:.1} mm, not 70",
            w * 1e3
        );
    }
    // Measured: median 2.6 / 2.1 mm, worst 4.3 / 4.2 mm (tabletop / backdrop; at 96×72 a pixel spans ~13 mm
    // of the board).
    assert!(
        median < 0.003,
        "{preset}: board height off by {:.1} mm (median)",
        median * 1e3
    );
    assert!(
        worst < 0.005,
        "{preset}: board height off by {:.1} mm (worst)",
        worst * 1e3
    );
    // The wall stands on the board: the share of points inside the wall's base, 3–15 mm up, where the field
    // is inside. Measured 100 % with and without `overhang_weight` at this size: the slot the term removes at
    // 320×240 (README) does not form here, so this guards the base, not the term.
    let (c, r) = (t.data.centre, t.data.radius);
    let mut base = Vec::new();
    for i in 0..4 {
        for j in 0..9 {
            for k in 0..4 {
                let p = [
                    0.205 + 0.01 * i as f64,
                    -0.08 + 0.02 * j as f64,
                    0.003 + 0.004 * k as f64,
                ];
                base.extend([(p[0] - c.x) / r, (p[1] - c.y) / r, (p[2] - c.z) / r].map(|v| v as f32));
            }
        }
    }
    let levels = t.field.config.grid.levels;
    let values = t.field.sdf_values(&base, levels);
    let solid = values.iter().filter(|v| **v < 0.0).count() as f64 / values.len() as f64;
    eprintln!(
        "{preset}: the wall's base solid at {:.0} % of its points",
        solid * 100.0
    );
    assert!(
        solid > 0.9,
        "{preset}: the wall's base is solid at {:.0} % of its points",
        solid * 100.0
    );
    // Empty space is known to be empty: samples concentrate at the surface (measured 0.124 / 0.164; a fog fills most
    // of the grid).
    assert!(last.occupied < 0.2, "{preset}: occupancy {:.3}", last.occupied);
    // The background field runs only for rays that get past the scene inside the sphere: the backdrop's
    // above the board's edge, not the board's own (measured: 266 of 512 a step at the end).
    let behind: usize = stats[550..].iter().map(|s| s.background_rays).sum::<usize>() / 50;
    eprintln!("{preset}: the background field ran for {behind} of 512 rays a step");
    assert!(
        behind > 0 && behind < 400,
        "{preset}: the background field ran for {behind} of 512 rays a step"
    );
    assert!(psnr > 20.0, "{preset}: batch PSNR {psnr:.1} dB");
    let _ = std::fs::remove_dir_all(&dir);
}

/// With no table, the plane start alone turned into a fog (sharpness falling to ~10, heights off by
/// centimetres): nothing anchored it beyond the board. The stereo points do.
#[test]
#[ignore = "slow: a scene before a plain backdrop trained into a clean surface, ~25 s"]
fn board_before_a_plain_backdrop_trains_into_a_clean_surface() {
    check_scene("backdrop");
}
