//! One mask per body from the mask of everything that moves in a video ([`mod@crate::video_masks`]): the
//! bodies told apart by their colours where they first appear, then followed from frame to frame.
//!
//! - **Which body a region is**: each body's look is the spread of its colours' chromaticity (the share of
//!   red and of green in a pixel: a video's exposure drops out), from its reconstruction rendered from a
//!   few sides. A region no body was near in the frame before goes to the body whose look it matches best,
//!   the bodies not yet found in the frame first.
//! - **Followed**: a region that overlaps one body's mask of the frame before, moved on by that body's pace
//!   and grown by a few pixels, is that body's; one that overlaps several (the bodies touch, or one passes
//!   in front of the other) is split pixel by pixel, each to the body whose moved-on mask is nearest (or,
//!   where they overlap, the one it lies deeper in).
//!   A body that no region claims in a frame (hidden, or out of view) keeps its last mask and pace for the
//!   frames after.

use crate::image_loss::distance_to_mask;

/// A body's colours: a normalised histogram of their chromaticity (`r / (r + g + b)`, `g / (r + g + b)`).
#[derive(Clone, Debug, PartialEq)]
pub struct Look {
    bins: Vec<f32>,
}

/// Bins of the chromaticity histogram along each of its two axes.
const LOOK_BINS: usize = 12;

/// Pixels darker than this (summed channels, 0–3) have no chromaticity to speak of.
const LOOK_DARK: f32 = 0.15;

/// How far past a body's moved-on mask a region still counts as near it, pixels.
const REACH: usize = 3;

impl Look {
    /// The look of a body showing `colours` (linear RGB, 0–1).
    pub fn of(colours: impl IntoIterator<Item = [f32; 3]>) -> Self {
        let mut bins = vec![0.0f32; LOOK_BINS * LOOK_BINS];
        for c in colours {
            let s = c[0] + c[1] + c[2];
            if s < LOOK_DARK {
                continue;
            }
            let bin = |v: f32| ((v / s * LOOK_BINS as f32) as usize).min(LOOK_BINS - 1);
            bins[bin(c[1]) * LOOK_BINS + bin(c[0])] += 1.0;
        }
        let total: f32 = bins.iter().sum();
        if total > 0.0 {
            bins.iter_mut().for_each(|b| *b /= total);
        }
        Self { bins }
    }

    /// How alike two looks are: the Bhattacharyya coefficient of their histograms (1 the same, 0 nothing
    /// shared).
    pub fn likeness(&self, other: &Look) -> f32 {
        self.bins.iter().zip(&other.bins).map(|(a, b)| (a * b).sqrt()).sum()
    }
}

/// Where a body was last seen: its mask and its pace (the mask's centroid's move per frame, pixels).
struct Track {
    mask: Vec<bool>,
    centroid: [f64; 2],
    pace: [f64; 2],
}

fn centroid(mask: &[bool], width: usize) -> Option<[f64; 2]> {
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0usize);
    for (p, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        sx += (p % width) as f64;
        sy += (p / width) as f64;
        n += 1;
    }
    (n > 0).then(|| [sx / n as f64, sy / n as f64])
}

/// `mask` moved by `shift` pixels (rounded).
fn shifted(mask: &[bool], width: usize, shift: [f64; 2]) -> Vec<bool> {
    let height = mask.len() / width.max(1);
    let (dx, dy) = (shift[0].round() as i64, shift[1].round() as i64);
    let mut out = vec![false; mask.len()];
    for (p, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = ((p % width) as i64 + dx, (p / width) as i64 + dy);
        if x >= 0 && y >= 0 && (x as usize) < width && (y as usize) < height {
            out[y as usize * width + x as usize] = true;
        }
    }
    out
}

/// Each body's mask in every frame (`[body][frame]`): `moving[k]`, the mask of everything that moves in
/// frame `k` of `frames` (`width` pixels a row), split among the bodies whose looks are `looks`. `seeds`: where
/// a body is expected in the first frame, when known (a guessed pose drawn through the camera): it is
/// followed from there, whatever its look (bodies that look alike are told apart so).
pub fn split_by_body(
    moving: &[Vec<bool>],
    frames: &[&[[f32; 3]]],
    width: usize,
    looks: &[Look],
    seeds: &[Option<Vec<bool>>],
) -> Vec<Vec<Vec<bool>>> {
    let bodies = looks.len();
    let mut out: Vec<Vec<Vec<bool>>> = vec![Vec::with_capacity(moving.len()); bodies];
    let mut tracks: Vec<Option<Track>> = (0..bodies)
        .map(|b| {
            let mask = seeds.get(b)?.clone()?;
            Some(Track {
                centroid: centroid(&mask, width)?,
                mask,
                pace: [0.0, 0.0],
            })
        })
        .collect();
    for (k, union) in moving.iter().enumerate() {
        let n = union.len();
        let height = n / width.max(1);
        let mut masks = vec![vec![false; n]; bodies];
        // Where each tracked body should be now, and how far each pixel is from it.
        let predicted: Vec<Option<Vec<bool>>> = tracks
            .iter()
            .map(|t| t.as_ref().map(|t| shifted(&t.mask, width, t.pace)))
            .collect();
        let near: Vec<Option<Vec<bool>>> = predicted
            .iter()
            .map(|m| m.as_ref().map(|m| geom::mask::dilate(m, width, REACH)))
            .collect();
        // Signed: outside, the distance to the mask; inside, less the distance to its edge (where two moved-on
        // masks overlap, a pixel goes to the one it lies deeper in).
        let distance: Vec<Option<Vec<f32>>> = predicted
            .iter()
            .map(|m| {
                m.as_ref().map(|m| {
                    let outside = distance_to_mask(m, width as u32, height as u32);
                    let complement: Vec<bool> = m.iter().map(|&x| !x).collect();
                    let inside = distance_to_mask(&complement, width as u32, height as u32);
                    outside.iter().zip(&inside).map(|(o, i)| o - i).collect()
                })
            })
            .collect();
        let (labels, sizes) = geom::mask::components(union, width, height);
        let mut pixels: Vec<Vec<usize>> = vec![Vec::new(); sizes.len()];
        for (p, &l) in labels.iter().enumerate() {
            if l != 0 {
                pixels[l as usize].push(p);
            }
        }
        let mut unclaimed = Vec::new();
        for region in pixels.iter().skip(1) {
            let claimants: Vec<usize> = (0..bodies)
                .filter(|&b| near[b].as_ref().is_some_and(|m| region.iter().any(|&p| m[p])))
                .collect();
            match claimants.as_slice() {
                [] => unclaimed.push(region),
                [b] => region.iter().for_each(|&p| masks[*b][p] = true),
                _ => {
                    for &p in region {
                        let nearest = claimants
                            .iter()
                            .copied()
                            .min_by(|&a, &b| {
                                let d = |i: usize| distance[i].as_ref().map_or(f32::INFINITY, |d| d[p]);
                                d(a).total_cmp(&d(b))
                            })
                            .expect("claimants is not empty");
                        masks[nearest][p] = true;
                    }
                }
            }
        }
        // Regions no body was near: by their colours, the bodies not found in this frame first.
        let found: Vec<bool> = masks.iter().map(|m| m.iter().any(|&x| x)).collect();
        let mut pairs: Vec<(f32, usize, usize)> = Vec::new();
        for (r, region) in unclaimed.iter().enumerate() {
            let look = Look::of(region.iter().map(|&p| frames[k][p]));
            for (b, body) in looks.iter().enumerate() {
                pairs.push((look.likeness(body), r, b));
            }
        }
        pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut taken = vec![false; unclaimed.len()];
        let mut filled = found.clone();
        for &(_, r, b) in &pairs {
            if !taken[r] && !filled[b] {
                taken[r] = true;
                filled[b] = true;
                unclaimed[r].iter().for_each(|&p| masks[b][p] = true);
            }
        }
        for &(_, r, b) in &pairs {
            if !taken[r] {
                taken[r] = true;
                unclaimed[r].iter().for_each(|&p| masks[b][p] = true);
            }
        }
        for (b, mask) in masks.into_iter().enumerate() {
            if let Some(c) = centroid(&mask, width) {
                let pace = tracks[b]
                    .as_ref()
                    .map_or([0.0, 0.0], |t| [c[0] - t.centroid[0], c[1] - t.centroid[1]]);
                tracks[b] = Some(Track {
                    mask: mask.clone(),
                    centroid: c,
                    pace,
                });
            } else if let Some(t) = &mut tracks[b] {
                // Hidden in this frame: where it would be, for the next.
                t.mask = shifted(&t.mask, width, t.pace);
                t.centroid = [t.centroid[0] + t.pace[0], t.centroid[1] + t.pace[1]];
            }
            out[b].push(mask);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two discs of their own colours on a grey board: the red one moves right into the resting blue one,
    /// touches it, and pushes it on; `frames` frames of 64 × 40.
    /// Per frame: the image, the mask of what moves, and each disc's true mask.
    type Discs = (Vec<Vec<[f32; 3]>>, Vec<Vec<bool>>, [Vec<Vec<bool>>; 2]);

    fn two_discs(frames: usize) -> Discs {
        let (w, h) = (64usize, 40usize);
        let (red, blue, board) = ([0.8f32, 0.25, 0.2], [0.2f32, 0.3, 0.8], [0.5f32, 0.5, 0.5]);
        let mut images = Vec::new();
        let mut unions = Vec::new();
        let mut truths = [Vec::new(), Vec::new()];
        for k in 0..frames {
            let a = [8.0 + 3.0 * k as f64, 20.0];
            // The blue disc rests until the red one reaches it (frame 4), then moves on at its pace.
            let b = [30.0 + (3.0 * k as f64 - 10.0).max(0.0), 21.0];
            let (mut img, mut union) = (Vec::new(), Vec::new());
            let (mut ta, mut tb) = (Vec::new(), Vec::new());
            for p in 0..w * h {
                let (x, y) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
                let ina = (x - a[0]).hypot(y - a[1]) < 6.0;
                let inb = !ina && (x - b[0]).hypot(y - b[1]) < 6.0;
                // A mottle, as a textured body shows.
                let m = 0.85 + 0.15 * ((x * 0.9).sin() * (y * 0.7).cos()) as f32;
                img.push(if ina {
                    red.map(|v| v * m)
                } else if inb {
                    blue.map(|v| v * m)
                } else {
                    board
                });
                union.push(ina || inb);
                ta.push(ina);
                tb.push(inb);
            }
            images.push(img);
            unions.push(union);
            truths[0].push(ta);
            truths[1].push(tb);
        }
        (images, unions, truths)
    }

    #[test]
    fn two_bodies_are_told_apart_by_colour_and_followed_through_their_contact() {
        let (images, unions, truths) = two_discs(10);
        let looks = [
            Look::of(std::iter::repeat_n([0.8f32, 0.25, 0.2], 50).chain(std::iter::repeat_n([0.7, 0.22, 0.18], 50))),
            Look::of(std::iter::repeat_n([0.2f32, 0.3, 0.8], 50).chain(std::iter::repeat_n([0.18, 0.27, 0.7], 50))),
        ];
        assert!(looks[0].likeness(&looks[0]) > 0.99 && looks[0].likeness(&looks[1]) < 0.1);
        let refs: Vec<&[[f32; 3]]> = images.iter().map(|i| i.as_slice()).collect();
        // The bodies given in the other order: the colours decide, not the order.
        let swapped = [looks[1].clone(), looks[0].clone()];
        let split = split_by_body(&unions, &refs, 64, &swapped, &[]);
        for (body, truth) in [(1, &truths[0]), (0, &truths[1])] {
            for (k, (m, t)) in split[body].iter().zip(truth).enumerate() {
                let iou = geom::coverage_iou(m, t);
                // Touching discs (frames 4 on) are split by the nearest moved-on mask: a pixel's column.
                assert!(iou > 0.9, "body {body}, frame {k}: IoU {iou:.3}");
            }
        }
    }

    #[test]
    fn a_body_hidden_for_a_frame_is_found_again_where_it_went() {
        let (images, mut unions, truths) = two_discs(4);
        // Frame 2 loses the red disc (behind something): the blue disc is not mistaken for it.
        for (u, t) in unions[2].iter_mut().zip(&truths[0][2]) {
            if *t {
                *u = false;
            }
        }
        let looks = [
            Look::of(std::iter::repeat_n([0.8f32, 0.25, 0.2], 10)),
            Look::of(std::iter::repeat_n([0.2f32, 0.3, 0.8], 10)),
        ];
        let refs: Vec<&[[f32; 3]]> = images.iter().map(|i| i.as_slice()).collect();
        let split = split_by_body(&unions, &refs, 64, &looks, &[]);
        assert!(split[0][2].iter().all(|&x| !x), "the hidden body has no mask");
        assert!(geom::coverage_iou(&split[1][2], &truths[1][2]) > 0.99);
        assert!(geom::coverage_iou(&split[0][3], &truths[0][3]) > 0.9);
    }

    #[test]
    fn bodies_that_look_alike_are_told_apart_by_where_they_were_expected() {
        let (images, unions, truths) = two_discs(6);
        // Both bodies grey to the look: only the seeds (a little off, as a guessed pose draws) tell them apart.
        let look = Look::of(std::iter::repeat_n([0.5f32, 0.5, 0.5], 10));
        let refs: Vec<&[[f32; 3]]> = images.iter().map(|i| i.as_slice()).collect();
        let seeds: Vec<Option<Vec<bool>>> = truths.iter().map(|t| Some(shifted(&t[0], 64, [2.0, 1.0]))).collect();
        let reversed: Vec<Option<Vec<bool>>> = seeds.iter().rev().cloned().collect();
        for (order, seeds) in [([0, 1], seeds), ([1, 0], reversed)] {
            let split = split_by_body(&unions, &refs, 64, &[look.clone(), look.clone()], &seeds);
            for (b, &t) in order.iter().enumerate() {
                for k in 0..6 {
                    let iou = geom::coverage_iou(&split[b][k], &truths[t][k]);
                    assert!(iou > 0.9, "body {b}, frame {k}: IoU {iou:.3}");
                }
            }
        }
    }
}
