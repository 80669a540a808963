//! Captures named as published datasets name them train as the project's own: DTU as NeuS preprocessed it
//! (`image/000000.png` with `mask/000.png`, `camera_mat_i` entries in the npz) and a BlendedMVS-style
//! folder of JPEG images (`00000000.jpg`) with PNG masks. Both are also committed, small
//! (`tests/data/dtu_scan_tiny`, `tests/data/blendedmvs_tiny`: four views of 64×48 of the tabletop toy),
//! and trained from as they are; `PGANEUS_WRITE_FIXTURES=1` writes them anew from the renamed captures
//! (with `--test-threads=1`, so the test that reads them does not run while they are rewritten).

use pganeus_io::{read_image, read_npz, Image};
use std::path::{Path, PathBuf};

use crate::common;
use common::{bin, copy_dir, tabletop, text};

/// The tabletop preset's toy_a capture at 64×48 with four views.
fn toy_capture(d: &Path) -> PathBuf {
    tabletop(d, (64, 48), 4, 2, &[]).join("toy_a")
}

/// `src` copied to `dst` with its images renamed by `image_name(i)` (and written as JPEG when the name ends
/// so) and its masks by `mask_name(i)`; the cameras as they are, capture.json left out (as published).
fn renamed(src: &Path, dst: &Path, image_name: impl Fn(usize) -> String, mask_name: impl Fn(usize) -> String) {
    for sub in ["image", "mask"] {
        std::fs::create_dir_all(dst.join(sub)).unwrap();
    }
    std::fs::copy(src.join("cameras_sphere.npz"), dst.join("cameras_sphere.npz")).unwrap();
    let mut images: Vec<PathBuf> = std::fs::read_dir(src.join("image"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    images.sort();
    for (i, img) in images.iter().enumerate() {
        let name = image_name(i);
        let to = dst.join("image").join(&name);
        if name.ends_with(".jpg") {
            let rgb = read_image(img).unwrap().to_rgb();
            std::fs::write(&to, testkit::jpeg_bytes(&rgb.data, rgb.width, rgb.height, 3, 92)).unwrap();
        } else {
            std::fs::copy(img, &to).unwrap();
        }
        let mask = src.join("mask").join(img.file_name().unwrap());
        std::fs::copy(mask, dst.join("mask").join(mask_name(i))).unwrap();
    }
}

/// The committed fixtures' folder.
fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

/// The sorted file names in `capture/sub`.
fn names_in(capture: &Path, sub: &str) -> Vec<String> {
    testkit::sorted_file_names(&capture.join(sub))
}

#[test]
fn committed_dtu_and_blendedmvs_fixtures_train_as_they_are() {
    let d = testkit::scratch_dir("cli", "fixtures");
    let dtu = fixtures().join("dtu_scan_tiny");
    assert_eq!(names_in(&dtu, "image")[0], "000000.png");
    assert_eq!(names_in(&dtu, "mask")[0], "000.png");
    let npz = read_npz(&dtu.join("cameras_sphere.npz")).unwrap();
    assert!(
        npz.iter().any(|(k, _)| k == "camera_mat_0"),
        "DTU's npz has camera_mat entries"
    );
    train_a_few_steps(&dtu, &d.join("run_dtu"));
    let bmvs = fixtures().join("blendedmvs_tiny");
    assert_eq!(names_in(&bmvs, "image")[0], "00000000.jpg");
    train_a_few_steps(&bmvs, &d.join("run_bmvs"));
    let _ = std::fs::remove_dir_all(&d);
}

fn train_a_few_steps(capture: &Path, run: &Path) {
    let o = bin()
        .arg("train")
        .arg(capture)
        .arg("--out")
        .arg(run)
        .args(["--iterations", "4", "--kind", "object"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}: {}", capture.display(), text(&o));
    assert!(run.join("checkpoint.safetensors").is_file(), "{}", text(&o));
}

#[test]
fn dtu_and_blendedmvs_style_captures_load_and_train() {
    let d = testkit::scratch_dir("cli", "captures");
    let toy = toy_capture(&d);
    // The npz has NeuS's camera_mat entries, as DTU's does.
    let npz = read_npz(&toy.join("cameras_sphere.npz")).unwrap();
    let keys: Vec<&str> = npz.iter().map(|(k, _)| k.as_str()).collect();
    assert!(keys.iter().any(|k| k.starts_with("camera_mat_")), "{keys:?}");

    let dtu = d.join("dtu_scan");
    renamed(&toy, &dtu, |i| format!("{i:06}.png"), |i| format!("{i:03}.png"));
    train_a_few_steps(&dtu, &d.join("run_dtu"));

    let bmvs = d.join("bmvs");
    renamed(&toy, &bmvs, |i| format!("{i:08}.jpg"), |i| format!("{i:03}.png"));
    train_a_few_steps(&bmvs, &d.join("run_bmvs"));
    if std::env::var_os("PGANEUS_WRITE_FIXTURES").is_some() {
        for (from, name) in [(&dtu, "dtu_scan_tiny"), (&bmvs, "blendedmvs_tiny")] {
            let to = fixtures().join(name);
            let _ = std::fs::remove_dir_all(&to);
            copy_dir(from, &to);
        }
    }

    // A mask short: refused, naming the counts.
    std::fs::remove_file(dtu.join("mask").join("003.png")).unwrap();
    let o = bin()
        .arg("train")
        .arg(&dtu)
        .arg("--out")
        .arg(d.join("run_short"))
        .args(["--iterations", "4"])
        .output()
        .unwrap();
    assert!(
        !o.status.success() && text(&o).contains("3 masks for 4 images"),
        "{}",
        text(&o)
    );

    // Masks that mark nothing in any view: an object capture refused before training, naming the folder.
    for e in std::fs::read_dir(bmvs.join("mask")).unwrap() {
        let p = e.unwrap().path();
        let m = read_image(&p).unwrap();
        pganeus_io::write_png(&p, &Image::new(m.width, m.height, 1)).unwrap();
    }
    let o = bin()
        .arg("train")
        .arg(&bmvs)
        .arg("--out")
        .arg(d.join("run_empty"))
        .args(["--iterations", "4", "--kind", "object"])
        .output()
        .unwrap();
    let t = text(&o);
    assert!(!o.status.success() && t.contains("every mask is empty"), "{t}");
    assert!(t.contains(&bmvs.join("mask").display().to_string()), "{t}");
    assert!(!d.join("run_empty").join("checkpoint.safetensors").exists());
    let _ = std::fs::remove_dir_all(&d);
}
