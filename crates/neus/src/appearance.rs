//! A camera's exposure and white balance, per view: the colour a view records is `gain ⊙ c` of the colour
//! `c` the field renders (a gain per channel, on the images' sRGB values, where an exposure's linear gain
//! stays a gain: sRGB is nearly a power law). Training learns one per training view, their mean held at
//! one, so the field keeps the captures' common colour and not each photo's exposure (NeRF-W's appearance,
//! reduced to what a camera changes: three numbers, not an embedding that could learn anything). A
//! held-out view's is unknown: it is fitted on the left half of the view and the view scored on the right
//! half.

use serde::{Deserialize, Serialize};

/// The colour map of one view: a gain per channel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewAppearance {
    pub gain: [f32; 3],
}

impl Default for ViewAppearance {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl ViewAppearance {
    pub const IDENTITY: ViewAppearance = ViewAppearance { gain: [1.0; 3] };

    /// The colour the view records of the rendered `c`.
    #[inline]
    pub fn apply(&self, c: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|k| self.gain[k] * c[k])
    }

    /// Least squares per channel of `target ≈ gain · rendered` over the pixels with weight > 0 (the
    /// identity's gain for a channel that is black throughout).
    pub fn fit(rendered: &[[f32; 3]], target: &[[f32; 3]], weight: impl Fn(usize) -> f32) -> Self {
        let mut out = Self::IDENTITY;
        for k in 0..3 {
            let (mut sxx, mut sxy) = (0.0f64, 0.0f64);
            for (i, (r, t)) in rendered.iter().zip(target).enumerate() {
                let w = weight(i).max(0.0) as f64;
                sxx += w * (r[k] as f64).powi(2);
                sxy += w * r[k] as f64 * t[k] as f64;
            }
            if sxx > 1e-9 {
                out.gain[k] = (sxy / sxx) as f32;
            }
        }
        out
    }
}

/// One ray's colour loss as its view records it: `weight ×` the mean over channels of
/// `|gain ⊙ rendered − target|`, with its gradients with respect to the rendered colour and to the gains.
pub fn recorded_l1(
    map: &ViewAppearance,
    rendered: [f32; 3],
    target: [f32; 3],
    weight: f32,
) -> (f32, [f32; 3], [f32; 3]) {
    let recorded = map.apply(rendered);
    let (mut loss, mut d_rendered, mut d_gain) = (0.0, [0.0; 3], [0.0; 3]);
    for k in 0..3 {
        let diff = recorded[k] - target[k];
        loss += weight * diff.abs() / 3.0;
        let d = weight * diff.signum() / 3.0;
        d_rendered[k] = map.gain[k] * d;
        d_gain[k] = rendered[k] * d;
    }
    (loss, d_rendered, d_gain)
}

/// PSNR of a held-out view whose appearance is not known: the colour map fitted on the left half of the
/// image (`width` pixels a row), the right half scored through it (inside `mask` when given).
pub fn psnr_right_half(rendered: &[[f32; 3]], target: &[[f32; 3]], mask: Option<&[f32]>, width: usize) -> f32 {
    let weight = |i: usize| mask.map_or(1.0, |m| m[i]);
    let left = |i: usize| i % width < width / 2;
    let map = ViewAppearance::fit(rendered, target, |i| if left(i) { weight(i) } else { 0.0 });
    let (mut se, mut n) = (0.0f64, 0.0f64);
    for (i, (r, t)) in rendered.iter().zip(target).enumerate() {
        if left(i) {
            continue;
        }
        let w = weight(i) as f64;
        let c = map.apply(*r);
        for k in 0..3 {
            se += w * ((c[k] - t[k]) as f64).powi(2);
        }
        n += 3.0 * w;
    }
    (-10.0 * (se / n.max(1.0)).max(1e-12).log10()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(n: usize) -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let x = i as f32 / n as f32;
                [x, (3.0 * x).sin() * 0.4 + 0.5, 0.2 + 0.6 * x * x]
            })
            .collect()
    }

    #[test]
    fn a_colour_map_is_found_again_and_scores_the_other_half() {
        let rendered = image(400);
        let truth = ViewAppearance {
            gain: [1.08, 0.95, 1.02],
        };
        let recorded: Vec<[f32; 3]> = rendered.iter().map(|c| truth.apply(*c)).collect();
        let fitted = ViewAppearance::fit(&rendered, &recorded, |_| 1.0);
        for k in 0..3 {
            assert!((fitted.gain[k] - truth.gain[k]).abs() < 1e-5, "{fitted:?}");
        }
        // The map of the left half scores the right: exact here, so the PSNR is the floor's.
        assert!(psnr_right_half(&rendered, &recorded, None, 20) > 80.0);
        // Without a map the same view scores the exposure's difference.
        assert!(crate::render_view::psnr(&rendered, &recorded, None) < 35.0);
        // A channel black throughout keeps the identity's gain.
        let black = vec![[0.0f32, 0.5, 0.5]; 10];
        let f = ViewAppearance::fit(&black, &black, |_| 1.0);
        assert_eq!(f.gain[0], 1.0);
    }

    #[test]
    fn the_recorded_loss_gradients_match_finite_differences() {
        let map = ViewAppearance {
            gain: [1.1, 0.93, 1.04],
        };
        let (rendered, target, w) = ([0.4f32, 0.55, 0.2], [0.47f32, 0.5, 0.26], 0.8);
        let (_, d_rendered, d_gain) = recorded_l1(&map, rendered, target, w);
        let h = 1e-3f32;
        for k in 0..3 {
            let (mut up, mut down) = (rendered, rendered);
            up[k] += h;
            down[k] -= h;
            let fd = (recorded_l1(&map, up, target, w).0 - recorded_l1(&map, down, target, w).0) / (2.0 * h);
            assert!(
                (fd - d_rendered[k]).abs() < 1e-3,
                "rendered {k}: {fd} vs {}",
                d_rendered[k]
            );
        }
        for k in 0..3 {
            let (mut up, mut down) = (map, map);
            up.gain[k] += h;
            down.gain[k] -= h;
            let fd = (recorded_l1(&up, rendered, target, w).0 - recorded_l1(&down, rendered, target, w).0) / (2.0 * h);
            assert!((fd - d_gain[k]).abs() < 1e-3, "gain {k}: {fd} vs {}", d_gain[k]);
        }
    }
}
