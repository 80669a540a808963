//! Camera-like captures (`[camera_like]`) are the clean captures as a camera records them: each effect
//! alone, against the clean render of the same scene — a gain per photo within its jitter, a video's gain
//! drifting smoothly, noise of the stated size, motion blur only where bodies move, and the truth (masks,
//! cameras) unchanged.

use std::path::{Path, PathBuf};
use synth::{preset, CameraLike, Scale, SynthScene};

const FRAMES: usize = 12;
/// Pixels around a body's mask that its blur may reach (96 × 72 frames, a 1/60 s shutter).
const NEAR: i64 = 5;

fn scene(camera_like: Option<CameraLike>) -> SynthScene {
    let mut s = preset("tabletop", Scale::Small).unwrap();
    s.cameras.width = 96;
    s.cameras.height = 72;
    s.cameras.views = 4;
    s.videos.truncate(1);
    s.videos[0].frames = FRAMES;
    s.camera_like = camera_like;
    s
}

/// Only the effects named: everything else off.
fn only(f: impl FnOnce(&mut CameraLike)) -> CameraLike {
    let mut c = CameraLike {
        noise: 0.0,
        jpeg_quality: 100,
        exposure_jitter: 0.0,
        white_balance_jitter: 0.0,
        exposure_drift: 0.0,
        shutter: 0.0,
        blur_samples: 1,
        sensor_scale: 1,
        seed: 3,
    };
    f(&mut c);
    c
}

fn generate(scene: &SynthScene, name: &str) -> PathBuf {
    let dir = testkit::scratch_dir("synth", name);
    let _ = std::fs::remove_dir_all(&dir);
    synth::generate(scene, Path::new("."), &dir, &mut |_, _, _| {}).unwrap();
    dir
}

/// The image's pixels as linear light (the sRGB encoding undone), 0–1.
fn linear(path: &Path) -> Vec<f64> {
    let img = pganeus_io::read_png(path).unwrap();
    img.data
        .iter()
        .map(|&v| {
            let s = v as f64 / 255.0;
            if s <= 0.04045 {
                s / 12.92
            } else {
                ((s + 0.055) / 1.055).powf(2.4)
            }
        })
        .collect()
}

fn image(dir: &Path, capture: &str, i: usize, n: usize) -> PathBuf {
    dir.join(capture).join("image").join(synth::frame_name(i, n))
}

/// The gain of `b` over `a`: least squares on pixels neither dark nor near white.
fn gain(a: &[f64], b: &[f64]) -> f64 {
    let (mut ab, mut aa) = (0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        if *x > 0.05 && *x < 0.7 && *y < 0.95 {
            ab += x * y;
            aa += x * x;
        }
    }
    ab / aa
}

#[test]
fn each_effect_is_what_its_setting_says_and_the_truth_is_kept() {
    let clean = generate(&scene(None), "camera-like-clean");
    let n_static = 4;

    // Exposure per photo and a drifting video, nothing else.
    let gains = generate(
        &scene(Some(only(|c| {
            c.exposure_jitter = 0.1;
            c.exposure_drift = 0.08;
        }))),
        "camera-like-gain",
    );
    let photo: Vec<f64> = (0..n_static)
        .map(|i| {
            gain(
                &linear(&image(&clean, "background", i, n_static)),
                &linear(&image(&gains, "background", i, n_static)),
            )
        })
        .collect();
    eprintln!("photos' gains {photo:.4?}");
    assert!(photo.iter().all(|g| (g - 1.0).abs() < 0.105), "{photo:?}");
    let spread =
        photo.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - photo.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(spread > 0.02, "the photos' exposures differ: {photo:?}");
    let video = &scene(None).videos[0].name;
    let frames: Vec<f64> = (0..FRAMES)
        .map(|i| {
            gain(
                &linear(&image(&clean, video, i, FRAMES)),
                &linear(&image(&gains, video, i, FRAMES)),
            )
        })
        .collect();
    eprintln!("video's gains {frames:.4?}");
    let swing =
        frames.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - frames.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(swing > 0.01, "the video's exposure drifts: {frames:?}");
    for w in frames.windows(2) {
        assert!((w[1] - w[0]).abs() < 0.05, "a slow drift, not a flicker: {frames:?}");
    }
    // The truth keeps the gain each image was developed with (`image_gains`), which is the one measured.
    let read_truth = |dir: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap()
    };
    assert!(
        read_truth(&clean).get(synth::IMAGE_GAINS).is_none(),
        "clean footage has no gains"
    );
    let truth = read_truth(&gains);
    let kept = |capture: &str| -> Vec<f64> {
        let per_image = truth[synth::IMAGE_GAINS][capture]
            .as_array()
            .expect("gains of every capture");
        per_image
            .iter()
            .map(|g| g.as_array().unwrap().iter().map(|c| c.as_f64().unwrap()).sum::<f64>() / 3.0)
            .collect()
    };
    for (measured, capture) in [(&photo, "background"), (&frames, video.as_str())] {
        let kept = kept(capture);
        assert_eq!(measured.len(), kept.len(), "{capture}: one gain per image");
        for (m, k) in measured.iter().zip(&kept) {
            assert!(
                (m / k - 1.0).abs() < 0.01,
                "{capture}: measured {measured:?}, kept {kept:?}"
            );
        }
    }

    // Noise only: the difference has about the size asked for (0.01 linear at mid grey).
    let noisy = generate(&scene(Some(only(|c| c.noise = 0.01))), "camera-like-noise");
    let (a, b) = (
        linear(&image(&clean, "background", 0, n_static)),
        linear(&image(&noisy, "background", 0, n_static)),
    );
    let (mut sum, mut count) = (0.0, 0);
    for (x, y) in a.iter().zip(&b) {
        if *x > 0.15 && *x < 0.5 {
            sum += (y - x).powi(2) / ((x + 0.02) / 0.52);
            count += 1;
        }
    }
    let sigma = (sum / count as f64).sqrt();
    eprintln!("noise {sigma:.4} at mid grey over {count} values");
    assert!(sigma > 0.007 && sigma < 0.014, "noise {sigma}");

    // Motion blur only: photos unchanged, a video's frames blurred where the body moves, masks the same.
    let blurred = generate(
        &scene(Some(only(|c| {
            c.shutter = 1.0 / 60.0;
            c.blur_samples = 7;
        }))),
        "camera-like-blur",
    );
    // (JPEG at quality 100 still rounds colour edges: the mean, not the largest, difference.)
    let mean_diff = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| (p - q).abs()).sum::<f64>() / x.len() as f64;
    let photo_diff = mean_diff(
        &linear(&image(&clean, "background", 1, n_static)),
        &linear(&image(&blurred, "background", 1, n_static)),
    );
    assert!(photo_diff < 0.003, "a photo has nothing to blur: {photo_diff}");
    let info = pganeus_io::read_capture_info(&blurred.join(video).join("capture.json")).unwrap();
    assert_eq!(info.shutter, Some(1.0 / 60.0));
    assert_eq!(
        pganeus_io::read_capture_info(&clean.join(video).join("capture.json"))
            .unwrap()
            .shutter,
        None
    );
    // Against the same sampling with the shutter closed to a microsecond, what changes is near the body:
    // within a few pixels of where its frame's mask puts it.
    let still = generate(
        &scene(Some(only(|c| {
            c.shutter = 1e-6;
            c.blur_samples = 7;
        }))),
        "camera-like-still",
    );
    let mut most = 0usize;
    for i in 0..FRAMES {
        let name = synth::frame_name(i, FRAMES);
        for masks in ["mask", "mask_toy"] {
            assert_eq!(
                std::fs::read(clean.join(video).join(masks).join(&name)).unwrap(),
                std::fs::read(blurred.join(video).join(masks).join(&name)).unwrap(),
                "frame {i}: the masks are the frame's instant"
            );
        }
        let mask = pganeus_io::read_png(&clean.join(video).join("mask").join(&name)).unwrap();
        let (w, h) = (mask.width as i64, mask.height as i64);
        let near = |x: i64, y: i64| {
            (-NEAR..=NEAR).any(|dy| {
                (-NEAR..=NEAR).any(|dx| {
                    let (u, v) = (x + dx, y + dy);
                    u >= 0 && v >= 0 && u < w && v < h && mask.data[(v * w + u) as usize] > 127
                })
            })
        };
        let (x, y) = (
            linear(&image(&still, video, i, FRAMES)),
            linear(&image(&blurred, video, i, FRAMES)),
        );
        let (mut changed, mut away) = (0usize, 0usize);
        for p in 0..(w * h) as usize {
            let moved = (0..3).any(|c| (x[3 * p + c] - y[3 * p + c]).abs() > 0.03);
            if moved {
                changed += 1;
                if !near(p as i64 % w, p as i64 / w) {
                    away += 1;
                }
            }
        }
        assert!(
            away * 100 <= (w * h) as usize,
            "frame {i}: {away} pixels changed away from the moving body"
        );
        most = most.max(changed);
    }
    eprintln!("blur changes up to {most} pixels of a frame");
    assert!(most > 20, "a moving body blurs: {most} pixels changed at most");

    // JPEG made at a sensor three times the capture's size and shrunk, as a phone's photo is: nearer the
    // clean render than JPEG at the capture's size, and the masks exactly the clean capture's.
    let jpeg = |sensor_scale: u32, name: &str| {
        let mut s = scene(Some(only(|c| {
            c.jpeg_quality = 85;
            c.sensor_scale = sensor_scale;
        })));
        s.videos[0].frames = 1; // the photos are compared
        generate(&s, name)
    };
    let (small, large) = (jpeg(1, "camera-like-jpeg1"), jpeg(3, "camera-like-jpeg3"));
    let off = |d: &Path| {
        (0..n_static)
            .map(|i| {
                mean_diff(
                    &linear(&image(&clean, "toy_a", i, n_static)),
                    &linear(&image(d, "toy_a", i, n_static)),
                )
            })
            .sum::<f64>()
            / n_static as f64
    };
    let (at_capture, at_sensor) = (off(&small), off(&large));
    eprintln!(
        "JPEG q85 against the clean render: {at_capture:.4} at the capture's size, {at_sensor:.4} from a 3x sensor"
    );
    assert!(at_sensor < 0.8 * at_capture, "{at_sensor} {at_capture}");
    for i in 0..n_static {
        let name = synth::frame_name(i, n_static);
        assert_eq!(
            std::fs::read(clean.join("toy_a/mask").join(&name)).unwrap(),
            std::fs::read(large.join("toy_a/mask").join(&name)).unwrap(),
            "toy_a {i}: a capture pixel's mask is its centre's"
        );
    }

    // Everything on (the defaults) keeps the cameras.
    let all = generate(&scene(Some(CameraLike::default())), "camera-like-all");
    for capture in ["background", video.as_str()] {
        assert_eq!(
            std::fs::read(clean.join(capture).join("cameras_sphere.npz")).unwrap(),
            std::fs::read(all.join(capture).join("cameras_sphere.npz")).unwrap()
        );
    }
    for d in [clean, gains, noisy, blurred, still, small, large, all] {
        let _ = std::fs::remove_dir_all(d);
    }
}
