//! Reading a candidate's bits: the marker's cells sampled through the homography of its corners, split into
//! black and white by Otsu's threshold, the border checked, the inner bits identified in the dictionary.

use crate::dictionary::BORDER_BITS;
use crate::dictionary::{Dictionary, Identified};
use crate::gray::Gray;
use crate::homography::{apply, fit};

/// What reading a candidate gave.
#[derive(Clone, Copy, Debug)]
pub struct Decoded {
    /// The marker and its rotation.
    pub identified: Identified,
}

/// Limits of a read.
#[derive(Clone, Copy, Debug)]
pub struct DecodeSettings {
    /// The part of each cell's side left out at each edge (blur and misplacement spill over cell edges).
    pub cell_margin: f64,
    /// Border cells that may read white, as a share of the border's cells.
    pub max_border_error_rate: f64,
    /// The share of the dictionary's correction budget a read may use.
    pub error_correction_rate: f64,
    /// The least spread (standard deviation, 0–255) of the cell means: below it the candidate is flat.
    pub min_contrast: f64,
}

/// The marker at `corners` (clockwise, any starting corner), if its cells read as one of the dictionary's.
pub fn decode(gray: &Gray, corners: &[[f64; 2]; 4], dictionary: &Dictionary, s: &DecodeSettings) -> Option<Decoded> {
    let n = dictionary.marker_size;
    let cells = n + 2 * BORDER_BITS;
    let c = cells as f64;
    let h = fit(&[[0.0, 0.0], [c, 0.0], [c, c], [0.0, c]], corners)?;
    // Samples per cell side: more where a cell covers more pixels, so noise averages out.
    let side = (0..4)
        .map(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
        })
        .fold(f64::INFINITY, f64::min);
    let per_cell = ((side / c) * (1.0 - 2.0 * s.cell_margin)).round().clamp(2.0, 8.0) as usize;
    let mut means = vec![0.0f64; cells * cells];
    for row in 0..cells {
        for col in 0..cells {
            let mut sum = 0.0;
            for i in 0..per_cell {
                for j in 0..per_cell {
                    let u =
                        col as f64 + s.cell_margin + (j as f64 + 0.5) / per_cell as f64 * (1.0 - 2.0 * s.cell_margin);
                    let v =
                        row as f64 + s.cell_margin + (i as f64 + 0.5) / per_cell as f64 * (1.0 - 2.0 * s.cell_margin);
                    // Canonical coordinates count cells from the outer corner; pixel (x, y) is sampled at its centre.
                    let p = apply(&h, [u, v]);
                    sum += gray.bilinear(p[0], p[1]) as f64;
                }
            }
            means[row * cells + col] = sum / (per_cell * per_cell) as f64;
        }
    }
    let mean = means.iter().sum::<f64>() / means.len() as f64;
    let spread = (means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / means.len() as f64).sqrt();
    if spread < s.min_contrast {
        return None;
    }
    let threshold = otsu(&means);
    let white = |row: usize, col: usize| means[row * cells + col] > threshold;
    let mut border_errors = 0;
    for row in 0..cells {
        for col in 0..cells {
            let on_border =
                row < BORDER_BITS || col < BORDER_BITS || row >= cells - BORDER_BITS || col >= cells - BORDER_BITS;
            if on_border && white(row, col) {
                border_errors += 1;
            }
        }
    }
    let border_cells = cells * cells - n * n;
    if border_errors as f64 > (border_cells as f64 * s.max_border_error_rate).floor() {
        return None;
    }
    let bits: Vec<bool> = (0..n * n)
        .map(|i| white(i / n + BORDER_BITS, i % n + BORDER_BITS))
        .collect();
    let budget = (dictionary.max_correction_bits as f64 * s.error_correction_rate).floor() as u32;
    let identified = dictionary.identify(&bits, budget)?;
    Some(Decoded { identified })
}

/// Otsu's threshold of a few values: the split that maximises the between-class variance.
fn otsu(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len() as f64;
    let total: f64 = sorted.iter().sum();
    let (mut best, mut best_threshold) = (-1.0, sorted[0]);
    let mut low_sum = 0.0;
    for k in 1..sorted.len() {
        low_sum += sorted[k - 1];
        if sorted[k] == sorted[k - 1] {
            continue;
        }
        let (w0, w1) = (k as f64 / n, 1.0 - k as f64 / n);
        let (m0, m1) = (low_sum / k as f64, (total - low_sum) / (n - k as f64));
        let between = w0 * w1 * (m0 - m1).powi(2);
        if between > best {
            best = between;
            best_threshold = 0.5 * (sorted[k - 1] + sorted[k]);
        }
    }
    best_threshold
}
