//! Time of `extract_zero_level` on a sphere SDF (radius 0.6 in [-1, 1]³) at
//! 128 and 256 points per side, and of `sample_sdf_grid` filling the grid.
//! The grids are built outside the timed block. Prints one JSON line per
//! figure: `cargo bench -p mesh --bench extract_zero_level`.

use std::time::Instant;

use mesh::{extract_zero_level, sample_sdf_grid};

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("at least one run"))
}

fn main() {
    let sphere = |pts: &[[f64; 3]]| {
        pts.iter()
            .map(|p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.6) as f32)
            .collect::<Vec<f32>>()
    };
    for res in [128usize, 256] {
        let runs = if res <= 128 { 5 } else { 3 };
        let (t_sample, grid) = best_of(runs, || sample_sdf_grid(&sphere, [-1.0; 3], [1.0; 3], res));
        let (t_extract, m) = best_of(runs, || extract_zero_level(&grid));
        println!(
            "{{\"bench\": \"extract_zero_level\", \"shape\": \"sphere\", \"dims\": {res}, \"seconds\": {t_extract:.4}, \"vertices\": {}, \"faces\": {}, \"threads\": {}}}",
            m.vertices.len(),
            m.faces.len(),
            rayon::current_num_threads()
        );
        println!(
            "{{\"bench\": \"sample_sdf_grid\", \"shape\": \"sphere\", \"dims\": {res}, \"seconds\": {t_sample:.4}}}"
        );
    }
}
