//! Helpers shared by the neus integration tests.
#![allow(dead_code)] // each test file uses some of them

use neus::TrainConfig;
use std::path::Path;

/// A preset rendered small (96×72, 16 views, one video frame) into `dir`: the dataset's root.
pub fn tiny_synth(preset: &str, dir: &Path) {
    let mut scene = synth::preset(preset, synth::Scale::Small).unwrap();
    scene.cameras.width = 96;
    scene.cameras.height = 72;
    scene.cameras.views = 16;
    scene.videos.truncate(1);
    scene.videos[0].frames = 1;
    synth::generate(&scene, Path::new("."), dir, &mut |_, _, _| {}).unwrap();
}

/// A small, fast object training (300 steps of 256 rays, a coarse grid and one-layer MLPs): for 64×48 captures.
pub fn tiny_config() -> TrainConfig {
    let mut c = TrainConfig {
        iterations: 300,
        batch_rays: 256,
        steps_per_ray: 128,
        max_samples_per_ray: 32,
        occupancy_res: 32,
        occupancy_warmup: 100,
        anneal_end: 100,
        level_start: 2,
        level_every: 25,
        holdout_every: 6,
        checkpoint_every: 100,
        ..TrainConfig::default()
    };
    c.field.grid.levels = 8;
    c.field.grid.log2_table_size = 14;
    c.field.grid.base_resolution = 8;
    c.field.grid.max_resolution = 256;
    c.field.sdf_hidden = vec![32];
    c.field.color_hidden = vec![32];
    c
}
