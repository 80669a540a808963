//! Small untrained fields with smooth outputs, for tests of what consumes
//! fields (the composed renderer, pose fitting) without training one: a
//! sphere (an object) or the board plane (a scene), the colour network
//! randomised so colour varies over the surface. Smooth everywhere, so central
//! differences converge: a softplus colour network (ReLU kinks at every sample
//! would not), and the hash tables enter the SDF network with the geometric
//! initialisation's zero weights (trilinear interpolation is only C0).

use crate::checkpoint::LoadedField;
use crate::occupancy::OccupancyGrid;
use crate::{FieldConfig, FieldInit, NeusField, TrainConfig};
use geom::Vec3;
use std::path::PathBuf;

/// A field of shape `init` whose unit sphere is centred at `centre` (its capture's frame) with radius
/// `radius` m; `seed` draws its networks. Its capture is named `toy_b`.
pub fn untrained_field(init: FieldInit, centre: Vec3<f64>, radius: f64, seed: u64) -> LoadedField {
    let mut config = TrainConfig {
        field: FieldConfig {
            init,
            color_activation: field::Activation::Softplus { beta: 10.0 },
            init_radius: 0.45,
            ..FieldConfig::default()
        },
        ..TrainConfig::default()
    };
    // A coarse full grid: nothing to skip in an untrained field, and `save_field` round-trips it.
    config.occupancy_res = 8;
    let g = &mut config.field.grid;
    g.levels = 6;
    g.log2_table_size = 12;
    g.base_resolution = 4;
    g.max_resolution = 48;
    let board = (-centre.z / radius) as f32;
    let mut f = NeusField::new(&config.field, seed, board);
    for v in &mut f.color_params {
        *v *= 3.0;
    }
    // inv_s = exp(10 v) = 30: a surface a few per cent of the unit sphere thick.
    f.extra[0] = 30f32.ln() / 10.0;
    f.extra[1..4].copy_from_slice(&[0.2, 0.4, 0.6]);
    LoadedField {
        config,
        field: f,
        occupancy: OccupancyGrid::full(8),
        step: 1_000_000,
        centre,
        radius,
        capture: PathBuf::from("toy_b"),
        bake_steps: 0,
        baked: Default::default(),
    }
}
