//! A field sampled on a regular grid, in batches large enough for a neural
//! field: the input of [`extract_zero_level`](crate::extract_zero_level).

use rayon::prelude::*;

use crate::marching_tetrahedra::ScalarGrid;

/// About this many points per call of the field (whole z-layers at a time).
const BATCH_POINTS: usize = 1 << 16;

/// Samples `sdf` on a regular grid over the box `[min, max]`.
///
/// `resolution` is the number of grid points along the longest side of the
/// box (NeuS's `extract_fields` convention), so the spacing is
/// `longest / (resolution − 1)`; the other sides get as many points as needed
/// to cover the box, and the grid is centred on it. `sdf` receives batches of
/// points (whole z-layers, x fastest, about 65k points per call, several calls
/// in parallel) and must return one value per point.
///
/// # Panics
/// If `resolution < 2`, the box is empty, inverted or not finite, or `sdf`
/// returns a different number of values than it was given points.
pub fn sample_sdf_grid(
    sdf: &(impl Fn(&[[f64; 3]]) -> Vec<f32> + Sync),
    min: [f64; 3],
    max: [f64; 3],
    resolution: usize,
) -> ScalarGrid {
    assert!(resolution >= 2, "sample_sdf_grid: resolution {resolution} < 2");
    let extent = [0, 1, 2].map(|a| max[a] - min[a]);
    let longest = extent.iter().copied().fold(0.0, f64::max);
    assert!(
        extent.iter().all(|e| e.is_finite() && *e >= 0.0) && longest > 0.0,
        "sample_sdf_grid: bad box {min:?}..{max:?}"
    );
    let spacing = longest / (resolution - 1) as f64;
    // Points per side; the 1e-9 keeps an exact multiple of the spacing from gaining a point.
    let dims = extent.map(|e| ((e / spacing - 1e-9).ceil().max(0.0) as usize + 1).max(2));
    let origin = [0, 1, 2].map(|a| 0.5 * (min[a] + max[a]) - 0.5 * (dims[a] - 1) as f64 * spacing);
    let mut grid = ScalarGrid {
        origin,
        spacing,
        dims,
        values: vec![0.0; dims[0] * dims[1] * dims[2]],
    };
    let layer = dims[0] * dims[1];
    let layers_per_batch = (BATCH_POINTS / layer).max(1);
    let geometry = ScalarGrid {
        values: Vec::new(),
        ..grid.clone()
    };
    grid.values
        .par_chunks_mut(layer * layers_per_batch)
        .enumerate()
        .for_each(|(b, out)| {
            let z0 = b * layers_per_batch;
            let points: Vec<[f64; 3]> = (0..out.len())
                .map(|n| {
                    let (i, j, k) = (n % dims[0], (n / dims[0]) % dims[1], z0 + n / layer);
                    geometry.point(i, j, k)
                })
                .collect();
            let values = sdf(&points);
            assert_eq!(
                values.len(),
                points.len(),
                "sample_sdf_grid: the field returned {} values for {} points",
                values.len(),
                points.len()
            );
            out.copy_from_slice(&values);
        });
    grid
}
