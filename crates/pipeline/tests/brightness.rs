//! The brightness drift a fit reads off the scene (`recon::brightness_drift`) against the drift a camera-like
//! video was developed with (`truth.json`'s `image_gains`): a phone's auto exposure swinging over the video,
//! with noise, JPEG and motion blur on top. The scene behind the body is its clean render, as a trained
//! scene field renders it.

use pipeline::images::{read_mask, reference_frame};
use std::path::{Path, PathBuf};
use synth::{preset, CameraLike, Scale, SynthScene};

const FRAMES: usize = 12;

fn scene(camera_like: Option<CameraLike>) -> SynthScene {
    let mut s = preset("tabletop", Scale::Small).unwrap();
    s.cameras.width = 96;
    s.cameras.height = 72;
    s.cameras.views = 2;
    // The drop: a body tumbling through the view, its blur reaching past its mask.
    s.videos.remove(0);
    s.videos[0].frames = FRAMES;
    s.camera_like = camera_like;
    s
}

fn generate(scene: &SynthScene, name: &str) -> PathBuf {
    let dir = testkit::scratch_dir("brightness", name);
    synth::generate(scene, Path::new("."), &dir, &mut |_, _, _| {}).unwrap();
    dir
}

#[test]
fn a_drifting_auto_exposure_is_read_off_the_scene_within_half_a_percent() {
    let clean = generate(&scene(None), "clean");
    let camera = CameraLike {
        exposure_drift: 0.12,
        ..CameraLike::default()
    };
    assert!(camera.noise > 0.0 && camera.jpeg_quality < 100 && camera.shutter > 0.0);
    let raw = generate(&scene(Some(camera)), "camera-like");
    let video = scene(None).videos[0].name.clone();
    let file = |dir: &Path, sub: &str, k: usize| dir.join(&video).join(sub).join(synth::frame_name(k, FRAMES));

    let frames: Vec<Vec<[f32; 3]>> = (0..FRAMES)
        .map(|k| reference_frame(&file(&raw, "image", k)).unwrap())
        .collect();
    let masks: Vec<Vec<bool>> = (0..FRAMES)
        .map(|k| read_mask(&file(&raw, "mask", k)).unwrap())
        .collect();
    // The clean first frame stands for the empty scene: its body's pixels are left out of every frame.
    let backdrop = reference_frame(&file(&clean, "image", 0)).unwrap();
    let bodies: Vec<Vec<bool>> = masks
        .iter()
        .map(|m| m.iter().zip(&masks[0]).map(|(a, b)| *a || *b).collect())
        .collect();
    let rgb: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.as_slice()).collect();
    let measured = recon::brightness_drift(&rgb, &bodies, &backdrop, 96);

    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(raw.join("truth.json")).unwrap()).unwrap();
    let gains: Vec<[f64; 3]> = serde_json::from_value(truth[synth::IMAGE_GAINS][&video].clone()).unwrap();
    let level = |g: &[f64; 3]| g.iter().sum::<f64>() / 3.0;
    // On the stored (sRGB) values a gain g on the light is about g^(1/2.2), as eval carries it.
    let expected: Vec<f64> = gains
        .iter()
        .map(|g| (level(g) / level(&gains[0])).powf(1.0 / 2.2))
        .collect();
    eprintln!("measured {measured:.4?}\nexpected {expected:.4?}");
    let swing = expected.iter().cloned().fold(0.0f64, |m, e| m.max((e - 1.0).abs()));
    assert!(swing > 0.02, "the video drifts enough to measure: {expected:?}");
    for (k, (m, e)) in measured.iter().zip(&expected).enumerate() {
        assert!(
            (m / e - 1.0).abs() < 0.005,
            "frame {k}: measured {m:.4}, the truth's {e:.4}"
        );
    }
}
