//! Masks computed from a camera-like video and the empty scene (`recon::video_masks`) against the masks
//! `synth` renders: the tabletop's drop (a body tumbling through the view, bouncing and coming to rest),
//! with a phone's drifting exposure, noise, JPEG and motion blur. The empty scene stands for the scene's
//! field rendered through the video's camera: the same video with the body far out of view, rendered clean
//! and blurred by a 3-pixel box as a field renders it.

use crate::common;
use pipeline::images::{read_mask, reference_frame};
use std::path::Path;
use synth::{preset, CameraLike, Scale, SynthScene};

const FRAMES: usize = 16;
const W: usize = 128;
const H: usize = 96;

fn scene(camera_like: Option<CameraLike>, body_away: bool) -> SynthScene {
    let mut s = preset("tabletop", Scale::Small).unwrap();
    s.cameras.width = W as u32;
    s.cameras.height = H as u32;
    s.cameras.views = 2;
    s.videos.retain(|v| v.name == "drop");
    s.videos[0].frames = FRAMES;
    if body_away {
        let b = &mut s.videos[0].bodies[0];
        b.t = [3.0, 3.0, 0.05];
        b.v = [0.0; 3];
        b.omega = [0.0; 3];
    }
    s.camera_like = camera_like;
    s
}

fn box_blur(img: &[[f32; 3]]) -> Vec<[f32; 3]> {
    (0..img.len())
        .map(|p| {
            let (x, y) = (p % W, p / W);
            let mut s = [0.0f32; 3];
            let mut n = 0.0;
            for yy in y.saturating_sub(1)..(y + 2).min(H) {
                for xx in x.saturating_sub(1)..(x + 2).min(W) {
                    let c = img[yy * W + xx];
                    (0..3).for_each(|i| s[i] += c[i]);
                    n += 1.0;
                }
            }
            s.map(|v| v / n)
        })
        .collect()
}

#[test]
fn masks_from_a_camera_like_video_and_the_empty_scene_match_the_true_ones() {
    let camera = CameraLike {
        exposure_drift: 0.12,
        ..CameraLike::default()
    };
    assert!(camera.noise > 0.0 && camera.jpeg_quality < 100 && camera.shutter > 0.0);
    let video = common::synth_into(&scene(Some(camera), false), "video_masks", "camera-like");
    let empty = common::synth_into(&scene(None, true), "video_masks", "empty");
    let file = |dir: &Path, sub: &str, k: usize| dir.join("drop").join(sub).join(synth::frame_name(k, FRAMES));
    let frames: Vec<Vec<[f32; 3]>> = (0..FRAMES)
        .map(|k| reference_frame(&file(&video, "image", k)).unwrap())
        .collect();
    let truth: Vec<Vec<bool>> = (0..FRAMES)
        .map(|k| read_mask(&file(&video, "mask", k)).unwrap())
        .collect();
    let rendered = box_blur(&reference_frame(&file(&empty, "image", 0)).unwrap());
    let refs: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.as_slice()).collect();
    let (masks, _) = recon::video_masks(&refs, &rendered, W, &recon::VideoMaskConfig::default());
    let mut scores = Vec::new();
    for (k, (m, t)) in masks.iter().zip(&truth).enumerate() {
        let area = t.iter().filter(|&&v| v).count();
        let iou = geom::coverage_iou(m, t);
        eprintln!("frame {k}: true area {area} px, IoU {iou:.3}");
        // The 200 pixels at 160 × 120, at this size.
        if area * 160 * 120 > 200 * W * H {
            scores.push(iou);
        }
    }
    assert!(
        scores.len() >= FRAMES / 2,
        "the body is seen in {} frames",
        scores.len()
    );
    let mean = scores.iter().sum::<f64>() / scores.len() as f64;
    let worst = scores.iter().copied().fold(1.0, f64::min);
    eprintln!("IoU mean {mean:.3}, worst {worst:.3}");
    // Measured 2026-12-06: mean 0.918, worst 0.862 (frame 3, the tumble before the first bounce, blurred;
    // 0.896 and 0.833 before the background's frames were grouped by mode); the bars guard that, short of
    // the 0.9 in every frame.
    assert!(mean > 0.9 && worst > 0.84, "mean {mean:.3}, worst {worst:.3}");
}
