//! Where the bodies are in each frame of a fixed-camera video, from the frames and the reconstructed scene
//! alone: no mask drawn, no network. The background a body stands out from is taken from the frames
//! themselves, sharp where a field renders the board a little blurred: per pixel, the frames are grouped
//! by the mean colour around it, and the group that shows the scene is the larger one unless the scene's
//! field, rendered through the video's camera, says the other (a body resting there for most of the
//! video). Where no frame shows the scene (a body resting in place through the whole video) the rendering
//! is the background, so a body at rest is still found.
//!
//! A pixel belongs to a body where its colour, after the frame's exposure gain, differs from the
//! background by more than the frame's noise allows, in a measure that forgives a shadow and bounced
//! light: the background may darken (down to [`VideoMaskConfig::shadow`] of its brightness) or brighten
//! (up to [`VideoMaskConfig::bounce`]), its colour kept, without a difference. Exposure, white balance and
//! a power-law gamma all scale a colour, so the gain, the shadow and the measure hold on encoded (sRGB)
//! values as on linear ones. The pixels far above the noise seed the mask; those joined to them and above
//! [`VideoMaskConfig::grow`] of that bar complete it (hysteresis: a body's soft edge, motion blur); then
//! specks go, one-pixel gaps close, holes fill, and components much smaller than the largest (one body)
//! are dropped.

use geom::mask::{components, dilate, erode, fill_holes};

/// How a video's masks are computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VideoMaskConfig {
    /// A pixel seeds the mask where its difference exceeds this many times the frame's typical background
    /// difference (the median over the frame: most pixels show the scene).
    pub seed_sigmas: f32,
    /// Pixels joined to a seed join the mask above this fraction of the seed bar.
    pub grow: f32,
    /// Seeds also need a difference above this (summed colour distance, 0–1 values): a frame the
    /// background matches almost exactly has a tiny median, and its noise is not a body.
    pub floor: f32,
    /// The darkest a shadow makes the background (brightness ratio): darker with the colour kept still
    /// counts as a body.
    pub shadow: f32,
    /// The brightest light bounced off a body makes the background (brightness ratio).
    pub bounce: f32,
    /// Components smaller than this fraction of the image are specks.
    pub speck: f64,
    /// Components smaller than this fraction of the largest are dropped (a reflection, the rendering's error
    /// in one place).
    pub minor: f64,
}

impl Default for VideoMaskConfig {
    fn default() -> Self {
        Self {
            seed_sigmas: 8.0,
            grow: 0.75,
            floor: 0.08,
            shadow: 0.4,
            bounce: 1.3,
            speck: 3e-4,
            minor: 0.15,
        }
    }
}

/// What was measured on the way, per frame (for the log).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VideoMaskStats {
    /// Each frame's exposure against the rendering (the median brightness ratio).
    pub gains: Vec<f64>,
    /// Each frame's seed bar (the summed colour distance a seed exceeds).
    pub bars: Vec<f64>,
    /// Pixels whose background stayed the rendering (no frame showed the scene there).
    pub rendered_background: usize,
    /// The background the frames were compared with (at the rendering's exposure).
    pub background: Vec<[f32; 3]>,
}

/// Rendered pixels darker than this (summed channels, 0–3) take no part in a frame's gain.
const DARK: f32 = 0.15;

/// The masks of the moving and resting bodies in `frames` (each `width` pixels a row), against `scene`,
/// the scene rendered through the video's camera at the frames' size.
pub fn video_masks(
    frames: &[&[[f32; 3]]],
    scene: &[[f32; 3]],
    width: usize,
    cfg: &VideoMaskConfig,
) -> (Vec<Vec<bool>>, VideoMaskStats) {
    let n = scene.len();
    let gains: Vec<f64> = frames.iter().map(|f| gain(f, scene)).collect();
    // Each frame as the rendering's exposure sees it.
    let levelled: Vec<Vec<[f32; 3]>> = frames
        .iter()
        .zip(&gains)
        .map(|(f, &g)| f.iter().map(|c| c.map(|v| v / g as f32)).collect())
        .collect();
    let (background, rendered) = background(&levelled, scene, width, (cfg.shadow, cfg.bounce));
    let mut stats = VideoMaskStats {
        gains,
        rendered_background: rendered.iter().filter(|&&r| r).count(),
        background: background.clone(),
        ..Default::default()
    };
    let masks = levelled
        .iter()
        .map(|frame| {
            // Where the background is the rendering, the frame as it is or blurred as the rendering is,
            // whichever is nearer: the board's sharp edges are not a body, nor is the board beside a body
            // that its blur would smear.
            let blurred = box_mean(frame, width, 1);
            let d: Vec<f32> = (0..n)
                .map(|p| {
                    let sharp = shadow_distance(frame[p], background[p], (cfg.shadow, cfg.bounce));
                    if rendered[p] {
                        sharp.min(shadow_distance(blurred[p], background[p], (cfg.shadow, cfg.bounce)))
                    } else {
                        sharp
                    }
                })
                .collect();
            let bar = (cfg.seed_sigmas * median(&d)).max(cfg.floor);
            stats.bars.push(bar as f64);
            let seeds: Vec<bool> = d.iter().map(|&v| v > bar).collect();
            let weak: Vec<bool> = d.iter().map(|&v| v > cfg.grow * bar).collect();
            clean(&grown_from(&weak, &seeds, width), width, cfg.speck, cfg.minor)
        })
        .collect();
    (masks, stats)
}

/// The frame's exposure against the rendering: the median ratio of summed channels over the rendered
/// pixels bright enough to tell (a body covers a few percent of a frame: not the median).
fn gain(frame: &[[f32; 3]], scene: &[[f32; 3]]) -> f64 {
    let ratios: Vec<f32> = frame
        .iter()
        .zip(scene)
        .filter_map(|(f, s)| {
            let ss = s[0] + s[1] + s[2];
            (ss > DARK).then(|| (f[0] + f[1] + f[2]) / ss)
        })
        .collect();
    let g = median(&ratios) as f64;
    if g.is_finite() && g > 0.0 {
        g
    } else {
        1.0
    }
}

/// Half the side of the square whose mean colours decide which frames show a pixel's background: wide
/// enough that a field's blur (a pixel or two) barely moves them, narrow enough that a body in the square
/// does.
const WINDOW: usize = 3;

/// Two frames' window means closer than this (summed colour distance) show the same thing there: the
/// noise of a mean over 49 pixels and the gains' error, well under what a body moves.
const SAME_WINDOW: f32 = 0.03;

/// How much nearer the rendering a smaller group of frames must be to show the background instead of the
/// larger (summed colour distance of window means): a tie goes to the larger group.
const NEARER: f32 = 0.03;

/// The same for the groups' colours at the pixel, where their windows tie: a field's blur moves a pixel
/// more than a mean.
const NEARER_PIXEL: f32 = 0.05;

/// Where even the chosen group's window mean is farther than this from the rendering's (beyond the typical
/// distance), no frame shows the scene there: the rendering is the background.
const FAR: f32 = 0.1;

/// The background per pixel, from the frames that show it. The frames are grouped by the mean colour of
/// the square around the pixel (a body in the square moves it; a field's blur and the frames' noise barely
/// do): the larger group, the one around the frames' median, shows the background, unless the other group
/// is nearer the rendering's mean there (a body resting on the pixel for most of the video). The
/// background is the median of the chosen group's colours; where even that group is far from the rendering
/// (a body resting there through the whole video), the rendering is. Also which pixels kept the rendering.
fn background(
    frames: &[Vec<[f32; 3]>],
    scene: &[[f32; 3]],
    width: usize,
    light: (f32, f32),
) -> (Vec<[f32; 3]>, Vec<bool>) {
    let n = scene.len();
    let rendered_mean = box_mean(scene, width, WINDOW);
    let means: Vec<Vec<[f32; 3]>> = frames.iter().map(|f| box_mean(f, width, WINDOW)).collect();
    let channel_median = |of: &mut dyn Iterator<Item = [f32; 3]>| -> [f32; 3] {
        let all: Vec<[f32; 3]> = of.collect();
        std::array::from_fn(|i| median(&all.iter().map(|c| c[i]).collect::<Vec<_>>()))
    };
    // Per pixel: the frames of the chosen group and how far its mean is from the rendering's.
    // How far a group is from the rendering, a shadow or bounced light forgiven (a field renders a cast
    // shadow faint): by its window mean (which forgives the field's blur) and by its median colour at the
    // pixel (which tells a body's edge, where the square straddles it, from the board).
    let off = |group: &[usize], p: usize| {
        let mean = channel_median(&mut group.iter().map(|&k| means[k][p]));
        let colour = channel_median(&mut group.iter().map(|&k| frames[k][p]));
        (
            shadow_distance(mean, rendered_mean[p], light),
            shadow_distance(colour, scene[p], light),
        )
    };
    let groups: Vec<(Vec<usize>, f32)> = (0..n)
        .map(|p| {
            let at: Vec<[f32; 3]> = means.iter().map(|m| m[p]).collect();
            let all: Vec<usize> = (0..frames.len()).collect();
            let (near, majority) = largest_cluster(&at, &all);
            let far: Vec<usize> = all.into_iter().filter(|k| !near.contains(k)).collect();
            let (window_a, pixel_a) = off(&near, p);
            let (minority_group, minority) = largest_cluster(&at, &far);
            if minority_group.is_empty() {
                return (near, window_a);
            }
            let (window_b, pixel_b) = off(&minority_group, p);
            // The windows decide where they differ; where they tie, the pixels; where both tie and one
            // group is the other in shadow, the lit one (a body resting beside the pixel shades it for
            // most of the video, and a shadow is forgiven where lit board would not be); else the larger.
            let minority_nearer = if (window_a - window_b).abs() > NEARER {
                window_b < window_a
            } else if (pixel_a - pixel_b).abs() > NEARER_PIXEL {
                pixel_b < pixel_a
            } else {
                lit_of_shadow_pair(majority, minority, light).unwrap_or_default()
            };
            if minority_nearer {
                (minority_group, window_b)
            } else {
                (near, window_a)
            }
        })
        .collect();
    // How far the rendering's means are from the frames' where it shows the scene: the typical group's.
    let typical = median(&groups.iter().map(|g| g.1).collect::<Vec<_>>()).max(1e-3);
    let rendered: Vec<bool> = groups
        .iter()
        .map(|(g, off)| g.is_empty() || *off > 6.0 * typical + FAR)
        .collect();
    // Where the chosen frames show the board in a body's shadow (a body falling onto the pixel shades it
    // until it lands), the board is lit again to the rendering's brightness: a shadow is forgiven against
    // the lit board, lit board against a shadow would not be.
    let shade_tolerance = SHADOW_PAIR.max(2.0 * typical);
    let bg = (0..n)
        .map(|p| {
            if rendered[p] {
                return scene[p];
            }
            let colour = channel_median(&mut groups[p].0.iter().map(|&k| frames[k][p]));
            let mean = channel_median(&mut groups[p].0.iter().map(|&k| means[k][p]));
            let lit = rendered_mean[p];
            let (sm, sl) = (mean[0] + mean[1] + mean[2], lit[0] + lit[1] + lit[2]);
            let shaded = sl > RELIGHT * sm && shadow_distance(mean, lit, (light.0, 1.0)) <= shade_tolerance;
            if shaded {
                colour.map(|v| v * sl / sm)
            } else {
                colour
            }
        })
        .collect();
    (bg, rendered)
}

/// The largest group of the frames `among` whose window means `at` agree (to [`SAME_WINDOW`] of the group's
/// median), and that median: the frames around the one with the most such neighbours. A median over all
/// frames would fall between two groups of similar size (a body passing, then resting).
fn largest_cluster(at: &[[f32; 3]], among: &[usize]) -> (Vec<usize>, [f32; 3]) {
    largest_cluster_within(at, among, SAME_WINDOW)
}

/// [`largest_cluster`] with colours alike within `same`.
pub(crate) fn largest_cluster_within(at: &[[f32; 3]], among: &[usize], same: f32) -> (Vec<usize>, [f32; 3]) {
    let near = |c: [f32; 3]| -> Vec<usize> { among.iter().copied().filter(|&k| distance(at[k], c) <= same).collect() };
    let Some(centre) = among
        .iter()
        .copied()
        .max_by_key(|&k| (near(at[k]).len(), std::cmp::Reverse(k)))
    else {
        return (Vec::new(), [0.0; 3]);
    };
    let members = near(at[centre]);
    let mid: [f32; 3] = std::array::from_fn(|i| median(&members.iter().map(|&k| at[k][i]).collect::<Vec<_>>()));
    let group = near(mid);
    if group.is_empty() {
        (members, mid)
    } else {
        (group, mid)
    }
}

/// Whether `b` is `a` in shadow (darker, its colour kept to within [`SHADOW_PAIR`]) or the other way:
/// then `Some(true)` when `b` is the lit one.
fn lit_of_shadow_pair(a: [f32; 3], b: [f32; 3], light: (f32, f32)) -> Option<bool> {
    let (sa, sb) = (a[0] + a[1] + a[2], b[0] + b[1] + b[2]);
    let (dark, lit) = if sa < sb { (a, b) } else { (b, a) };
    (shadow_distance(dark, lit, (light.0, 1.0)) <= SHADOW_PAIR).then_some(sb > sa)
}

/// The most a shadow's window mean may differ from the lit board's once darkened to its brightness (the
/// shade's light a little bluer, the noise of two means).
const SHADOW_PAIR: f32 = 2.0 * SAME_WINDOW;

/// How much brighter than the chosen frames the rendering must be for them to show a shadow there.
const RELIGHT: f32 = 1.15;

/// `img` averaged over the `2r + 1` square around each pixel (at the edges, over the part inside): along
/// rows, then along columns.
pub(crate) fn box_mean(img: &[[f32; 3]], width: usize, r: usize) -> Vec<[f32; 3]> {
    let height = img.len() / width.max(1);
    let pass = |src: &[[f32; 3]], along_rows: bool| -> Vec<[f32; 3]> {
        let (lines, len) = if along_rows { (height, width) } else { (width, height) };
        let at = |line: usize, i: usize| if along_rows { line * width + i } else { i * width + line };
        let mut out = vec![[0.0f32; 3]; src.len()];
        for line in 0..lines {
            for i in 0..len {
                let (lo, hi) = (i.saturating_sub(r), (i + r + 1).min(len));
                let mut s = [0.0f32; 3];
                for j in lo..hi {
                    let c = src[at(line, j)];
                    (0..3).for_each(|ch| s[ch] += c[ch]);
                }
                out[at(line, i)] = s.map(|v| v / (hi - lo) as f32);
            }
        }
        out
    };
    pass(&pass(img, true), false)
}

/// Euclidean distance of two colours.
pub(crate) fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The distance of colour `c` from background `b`, the background first darkened or brightened toward
/// `c`'s brightness by as much as a shadow or the light a body bounces can (to `shadow` or `bounce` of its
/// own): a shadow's pixel is near 0, a body's differs in colour or in brightness beyond either.
pub(crate) fn shadow_distance(c: [f32; 3], b: [f32; 3], (shadow, bounce): (f32, f32)) -> f32 {
    let (sc, sb) = (c[0] + c[1] + c[2], b[0] + b[1] + b[2]);
    let ratio = if sb > 1e-4 {
        (sc / sb).clamp(shadow, bounce)
    } else {
        1.0
    };
    distance(c, b.map(|v| v * ratio))
}

/// The median of `v` (NaN for none).
pub(crate) fn median(v: &[f32]) -> f32 {
    if v.is_empty() {
        return f32::NAN;
    }
    let mut v = v.to_vec();
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// The components of `weak` that hold a pixel of `seeds`.
pub(crate) fn grown_from(weak: &[bool], seeds: &[bool], width: usize) -> Vec<bool> {
    let height = weak.len() / width.max(1);
    let (labels, sizes) = components(weak, width, height);
    let mut seeded = vec![false; sizes.len()];
    for (l, &s) in labels.iter().zip(seeds) {
        if s {
            seeded[*l as usize] = true;
        }
    }
    seeded[0] = false;
    labels.iter().map(|&l| seeded[l as usize]).collect()
}

/// Specks dropped, one-pixel gaps closed, holes filled, and the components much smaller than the largest
/// dropped.
pub(crate) fn clean(mask: &[bool], width: usize, speck: f64, minor: f64) -> Vec<bool> {
    let n = mask.len();
    let height = n / width.max(1);
    let speck = (speck * n as f64).ceil() as usize;
    let keep_large = |m: &[bool], least: usize| -> Vec<bool> {
        let (labels, sizes) = components(m, width, height);
        labels.iter().map(|&l| l != 0 && sizes[l as usize] >= least).collect()
    };
    let m = keep_large(mask, speck);
    let m = fill_holes(&erode(&dilate(&m, width, 1), width, 1), width);
    let (_, sizes) = components(&m, width, height);
    let largest = sizes.iter().skip(1).copied().max().unwrap_or(0);
    keep_large(&m, ((minor * largest as f64).ceil() as usize).max(speck))
}

#[cfg(test)]
mod tests {
    use super::*;
    use geom::SplitMix64;

    /// A textured board, a coloured disc moving across it (resting for its last frames), its shadow beside
    /// it, each frame at its own exposure with noise; the rendering a little off.
    struct Video {
        width: usize,
        frames: Vec<Vec<[f32; 3]>>,
        truth: Vec<Vec<bool>>,
        shadows: Vec<Vec<bool>>,
        rendered: Vec<[f32; 3]>,
    }

    fn video(frames: usize, rest_from: usize) -> Video {
        let (w, h) = (96usize, 72usize);
        let mut rng = SplitMix64::new(5);
        let board: Vec<[f32; 3]> = (0..w * h)
            .map(|p| {
                let (x, y) = (p % w, p / w);
                let light = ((x / 8 + y / 8) % 2 == 0) as i32 as f32;
                let g = 0.25 + 0.5 * light + 0.05 * rng.next_f64() as f32;
                [g, g * 0.97, g * 0.92]
            })
            .collect();
        // The rendering: blurred by a box of 3 and 4 % dark.
        let rendered: Vec<[f32; 3]> = (0..w * h)
            .map(|p| {
                let (x, y) = ((p % w) as i64, (p / w) as i64);
                let mut s = [0.0f32; 3];
                let mut k = 0.0;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (xx, yy) = ((x + dx).clamp(0, w as i64 - 1), (y + dy).clamp(0, h as i64 - 1));
                        let c = board[yy as usize * w + xx as usize];
                        (0..3).for_each(|i| s[i] += c[i]);
                        k += 1.0;
                    }
                }
                s.map(|v| 0.96 * v / k)
            })
            .collect();
        let mut out = Video {
            width: w,
            frames: vec![],
            truth: vec![],
            shadows: vec![],
            rendered,
        };
        for k in 0..frames {
            let t = k.min(rest_from) as f64;
            let (cx, cy, r) = (14.0 + 4.0 * t, 30.0 + 1.5 * t, 8.0);
            let gain = 1.0 + 0.1 * (k as f64 * 0.9).sin();
            let mut frame = Vec::with_capacity(w * h);
            let (mut mask, mut shade) = (vec![false; w * h], vec![false; w * h]);
            for p in 0..w * h {
                let (x, y) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
                let on = (x - cx).powi(2) + (y - cy).powi(2) < r * r;
                let in_shadow = !on && (x - cx - 5.0).powi(2) / 2.0 + (y - cy - 7.0).powi(2) < r * r;
                let c = if on {
                    // Red and blue halves.
                    if x < cx {
                        [0.8, 0.2, 0.15]
                    } else {
                        [0.15, 0.3, 0.8]
                    }
                } else if in_shadow {
                    board[p].map(|v| 0.7 * v)
                } else {
                    board[p]
                };
                mask[p] = on;
                shade[p] = in_shadow;
                frame.push(c.map(|v| (v * gain as f32 + 0.015 * (rng.next_f64() as f32 - 0.5)).clamp(0.0, 1.0)));
            }
            out.frames.push(frame);
            out.truth.push(mask);
            out.shadows.push(shade);
        }
        out
    }

    #[test]
    fn a_moving_then_resting_body_is_found_and_its_shadow_is_not() {
        let v = video(14, 9);
        let frames: Vec<&[[f32; 3]]> = v.frames.iter().map(|f| f.as_slice()).collect();
        let (masks, stats) = video_masks(&frames, &v.rendered, v.width, &VideoMaskConfig::default());
        for (k, (m, t)) in masks.iter().zip(&v.truth).enumerate() {
            let score = geom::coverage_iou(m, t);
            assert!(score > 0.95, "frame {k}: IoU {score:.3}");
            let shadow_in = m.iter().zip(&v.shadows[k]).filter(|(m, s)| **m && **s).count();
            assert!(shadow_in < 5, "frame {k}: {shadow_in} shadow pixels in the mask");
        }
        // The exposure is read off the scene (the rendering is 4 % dark: every gain is 1/0.96 high).
        for (k, g) in stats.gains.iter().enumerate() {
            let truth = (1.0 + 0.1 * (k as f64 * 0.9).sin()) / 0.96;
            assert!((g - truth).abs() < 0.01, "frame {k}: gain {g:.4}, truth {truth:.4}");
        }
    }

    #[test]
    fn a_body_resting_for_most_of_the_video_leaves_no_ghost_of_its_shadow() {
        // Resting from frame 4 of 20: its shadow shades the board beside it in 16 frames, the board there
        // shows lit in 4. The shadowed board must not become the background (then the lit board would be a
        // body in the first frames), nor the body itself.
        let v = video(20, 4);
        let frames: Vec<&[[f32; 3]]> = v.frames.iter().map(|f| f.as_slice()).collect();
        let (masks, _) = video_masks(&frames, &v.rendered, v.width, &VideoMaskConfig::default());
        for (k, (m, t)) in masks.iter().zip(&v.truth).enumerate() {
            let score = geom::coverage_iou(m, t);
            let (a, b) = (m.iter().filter(|&&x| x).count(), t.iter().filter(|&&x| x).count());
            assert!(score > 0.95, "frame {k}: IoU {score:.3}: {a} px found, {b} true");
        }
    }

    #[test]
    fn the_largest_cluster_is_a_mode_not_a_median() {
        // Two tight groups of 5 and 4 frames and three frames scattered between them: a median falls
        // between the groups; the cluster is the five.
        let at: Vec<[f32; 3]> = [0.2, 0.201, 0.199, 0.2, 0.202, 0.35, 0.45, 0.55, 0.8, 0.801, 0.799, 0.8]
            .iter()
            .map(|&g| [g, g, g])
            .collect();
        let all: Vec<usize> = (0..at.len()).collect();
        let (group, centre) = largest_cluster(&at, &all);
        assert_eq!(group, vec![0, 1, 2, 3, 4]);
        assert!((centre[0] - 0.2).abs() < 0.002, "{centre:?}");
        let rest: Vec<usize> = (5..at.len()).collect();
        assert_eq!(largest_cluster(&at, &rest).0, vec![8, 9, 10, 11]);
    }

    #[test]
    fn a_body_that_never_moves_is_found_from_the_rendering() {
        let v = video(6, 0);
        let frames: Vec<&[[f32; 3]]> = v.frames.iter().map(|f| f.as_slice()).collect();
        let (masks, stats) = video_masks(&frames, &v.rendered, v.width, &VideoMaskConfig::default());
        assert!(stats.rendered_background > 100, "{}", stats.rendered_background);
        for (k, (m, t)) in masks.iter().zip(&v.truth).enumerate() {
            let score = geom::coverage_iou(m, t);
            let (a, b) = (m.iter().filter(|&&x| x).count(), t.iter().filter(|&&x| x).count());
            let both = m.iter().zip(t).filter(|(x, y)| **x && **y).count();
            assert!(
                score > 0.9,
                "frame {k}: IoU {score:.3}: {a} px found, {b} true, {both} both; {stats:?}"
            );
        }
    }
}
