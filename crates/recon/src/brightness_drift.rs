//! A video's brightness from frame to frame, measured on the scene alone. A phone's auto exposure drifts
//! while it films (a body entering or leaving the view is enough), and the image terms compare the body's
//! rendered colours with each frame after one gain ([`crate::exposure_gain`], measured at the first pose):
//! held for the whole video, a drift of a few percent biases the colour term of every later frame. The
//! scene around the bodies needs no pose to measure it: each frame against the scene rendered through the
//! video's camera, over the pixels that show the scene alone.
//!
//! The measure is the median over those pixels of the ratio of their summed channels (a shadow or a
//! reflection the bodies cast moves a few pixels' ratios, not the median), relative to the first frame's:
//! the scene's own rendering error is the same in every frame and divides out.

/// Pixels around a body's mask left out: its shadow, its motion blur, a mask a pixel or two short.
pub const MARGIN_PX: usize = 6;

/// Rendered scene pixels darker than this (summed channels, 0–3) are left out: their ratios are noise.
const DARK: f32 = 0.15;

/// Frame pixels brighter than this (summed channels) are left out: clipped, they do not scale.
const BRIGHT: f32 = 2.9;

/// Each frame's brightness relative to the first's (1 for the first): `frames[k]` the frame's pixels,
/// `bodies[k]` where any body is in it, `scene` the scene rendered through the video's camera, all
/// `width` pixels a row. A frame with too few scene pixels (under a hundred) keeps the previous frame's.
pub fn brightness_drift(frames: &[&[[f32; 3]]], bodies: &[Vec<bool>], scene: &[[f32; 3]], width: usize) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(frames.len());
    let mut first = None;
    for (k, (frame, body)) in frames.iter().zip(bodies).enumerate() {
        let near = geom::mask::dilate(body, width, MARGIN_PX);
        let mut ratios: Vec<f32> = frame
            .iter()
            .zip(scene)
            .zip(&near)
            .filter_map(|((f, s), &near)| {
                let (fs, ss) = (f[0] + f[1] + f[2], s[0] + s[1] + s[2]);
                (!near && ss > DARK && fs < BRIGHT).then(|| fs / ss)
            })
            .collect();
        let level = if ratios.len() >= 100 {
            let mid = ratios.len() / 2;
            Some(*ratios.select_nth_unstable_by(mid, f32::total_cmp).1 as f64)
        } else {
            None
        };
        let relative = match (level, first) {
            (Some(l), None) => {
                first = Some(l);
                1.0
            }
            (Some(l), Some(f)) => l / f,
            (None, _) => out.last().copied().unwrap_or(1.0),
        };
        if k == 0 && level.is_none() {
            tracing::warn!("the first frame shows too little of the scene to measure its brightness");
        }
        out.push(relative);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drifting_exposure_is_read_off_the_scene_around_a_moving_body() {
        let (w, h) = (80usize, 60usize);
        let mut rng = geom::SplitMix64::new(2);
        let scene: Vec<[f32; 3]> = (0..w * h)
            .map(|_| std::array::from_fn(|_| 0.2 + 0.6 * rng.next_f64() as f32))
            .collect();
        // The rendering is off by 5 % everywhere (a field is not the scene): it divides out.
        let rendered: Vec<[f32; 3]> = scene.iter().map(|c| c.map(|v| v * 0.95)).collect();
        let gains = [1.0, 1.03, 1.07, 1.04, 0.96];
        let mut frames = Vec::new();
        let mut bodies = Vec::new();
        for (k, g) in gains.iter().enumerate() {
            let mut body = vec![false; w * h];
            let mut frame: Vec<[f32; 3]> = scene.iter().map(|c| c.map(|v| v * *g as f32)).collect();
            for y in 20..35 {
                for x in (10 + 12 * k)..(25 + 12 * k) {
                    body[y * w + x] = true;
                    frame[y * w + x] = [0.9, 0.1, 0.1];
                }
            }
            // Its shadow beside it, darker, outside the mask; and noise everywhere.
            for y in 35..39 {
                for x in (10 + 12 * k)..(25 + 12 * k) {
                    frame[y * w + x] = frame[y * w + x].map(|v| 0.5 * v);
                }
            }
            for c in &mut frame {
                for v in c.iter_mut() {
                    *v += 0.02 * (rng.next_f64() as f32 - 0.5);
                }
            }
            frames.push(frame);
            bodies.push(body);
        }
        let refs: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.as_slice()).collect();
        let drift = brightness_drift(&refs, &bodies, &rendered, w);
        for (d, g) in drift.iter().zip(gains) {
            assert!((d - g).abs() < 0.005, "{drift:?}");
        }
        // A frame that is all body keeps the previous frame's brightness.
        let all = vec![true; w * h];
        let drift = brightness_drift(&[refs[0], refs[1]], &[bodies[0].clone(), all], &rendered, w);
        assert_eq!(drift, vec![1.0, 1.0]);
    }
}
