//! The capture folder (FORMATS.md, "A capture"): a valid capture opens with
//! its images, masks, cameras and capture.json; each broken variant fails with
//! an `IoError::Capture` naming the offending file.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use pganeus_io::{
    open_capture, read_cameras_npz, read_capture_info, read_npz, write_cameras_npz, write_capture_info, write_npz,
    write_png, CameraMats, CaptureInfo, CaptureKind, Image, IoError, NpyArray,
};
use serde_json::{json, Map};

/// A fresh folder under the system temp dir, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let d = std::env::temp_dir().join(format!("pganeus_io_neus_{name}_{}_{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        TempDir(d)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn camera(i: usize) -> CameraMats {
    let f = 100.0 + i as f64;
    CameraMats {
        world_mat: [
            [f, 0.0, 16.0, 0.5 * i as f64],
            [0.0, f, 12.0, -0.25],
            [0.0, 0.0, 1.0, 4.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
        scale_mat: [
            [0.5, 0.0, 0.0, 0.1],
            [0.0, 0.5, 0.0, -0.2],
            [0.0, 0.0, 0.5, 0.3],
            [0.0, 0.0, 0.0, 1.0],
        ],
    }
}

/// A valid capture of `n` 8x6 RGB images with masks, cameras and capture.json.
fn make_capture(name: &str, n: usize) -> TempDir {
    let dir = TempDir::new(name);
    for i in 0..n {
        let mut img = Image::new(8, 6, 3);
        img.data.iter_mut().for_each(|s| *s = (i * 40) as u8);
        write_png(&dir.0.join(format!("image/{i:03}.png")), &img).unwrap();
        let mut mask = Image::new(8, 6, 1);
        mask.pixel_mut(3, 3)[0] = 255;
        write_png(&dir.0.join(format!("mask/{i:03}.png")), &mask).unwrap();
    }
    let cams: Vec<CameraMats> = (0..n).map(camera).collect();
    write_cameras_npz(&dir.0.join("cameras_sphere.npz"), &cams).unwrap();
    let info = CaptureInfo {
        kind: CaptureKind::Video,
        subject: None,
        fps: Some(30.0),
        shutter: None,
        extra: Map::new(),
    };
    write_capture_info(&dir.0.join("capture.json"), &info).unwrap();
    dir
}

/// The error of opening `dir`, which must be an `IoError::Capture`: (path, message).
fn capture_err(dir: &Path) -> (PathBuf, String) {
    match open_capture(dir) {
        Err(IoError::Capture { path, msg }) => (path, msg),
        Err(e) => panic!("expected IoError::Capture, got {e}"),
        Ok(_) => panic!("a broken capture opened"),
    }
}

#[test]
fn happy_path() {
    let dir = make_capture("happy", 3);
    // Extra mask folder, a stray note and a hidden file, which are ignored.
    for i in 0..3 {
        write_png(&dir.0.join(format!("mask_toy/{i:03}.png")), &Image::new(8, 6, 1)).unwrap();
    }
    std::fs::write(dir.0.join("image/notes.txt"), "ignored").unwrap();
    std::fs::write(dir.0.join("image/.DS_Store"), "ignored").unwrap();

    let cap = open_capture(&dir.0).unwrap();
    assert_eq!(cap.dir, dir.0);
    assert_eq!(cap.len(), 3);
    assert_eq!((cap.width, cap.height), (8, 6));
    let names: Vec<String> = cap
        .images
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["000.png", "001.png", "002.png"]);
    let masks = cap.masks.as_ref().unwrap();
    for (img, mask) in cap.images.iter().zip(masks) {
        assert_eq!(img.file_name(), mask.file_name());
        assert_eq!(mask.parent().unwrap(), dir.0.join("mask"));
    }
    assert_eq!(cap.extra_masks.len(), 1);
    assert_eq!(cap.extra_masks[0].0, "toy");
    assert_eq!(cap.extra_masks[0].1.len(), 3);
    assert_eq!(cap.cameras, (0..3).map(camera).collect::<Vec<_>>());
    let info = cap.info.unwrap();
    assert_eq!((info.kind, info.fps), (CaptureKind::Video, Some(30.0)));
}

#[test]
fn images_are_sorted_by_file_name_and_masks_are_optional() {
    let dir = TempDir::new("sorted");
    for name in ["b10", "a", "b2"] {
        write_png(&dir.0.join(format!("image/{name}.png")), &Image::new(2, 2, 4)).unwrap();
    }
    write_cameras_npz(
        &dir.0.join("cameras_sphere.npz"),
        &(0..3).map(camera).collect::<Vec<_>>(),
    )
    .unwrap();
    let cap = open_capture(&dir.0).unwrap();
    let names: Vec<_> = cap
        .images
        .iter()
        .map(|p| p.file_stem().unwrap().to_str().unwrap().to_string())
        .collect();
    assert_eq!(names, ["a", "b10", "b2"]);
    assert!(cap.masks.is_none() && cap.extra_masks.is_empty() && cap.info.is_none());
}

#[test]
fn missing_npz_entry_names_world_mat_2() {
    let dir = make_capture("missing_entry", 3);
    // Rewrite the cameras without world_mat_2.
    let npz = dir.0.join("cameras_sphere.npz");
    let entries = read_npz(&npz).unwrap();
    let kept: Vec<(&str, &NpyArray)> = entries
        .iter()
        .filter(|(n, _)| n != "world_mat_2")
        .map(|(n, a)| (n.as_str(), a))
        .collect();
    write_npz(&npz, &kept).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, npz);
    assert!(
        msg.contains("no entry world_mat_2") && msg.contains("3 images"),
        "{msg}"
    );
}

#[test]
fn misshapen_or_non_finite_cameras() {
    let dir = make_capture("bad_cam", 2);
    let npz = dir.0.join("cameras_sphere.npz");
    let entries = read_npz(&npz).unwrap();
    let small = NpyArray::f64(vec![3, 4], vec![1.0; 12]);
    let mut nan = NpyArray::f64(vec![4, 4], vec![1.0; 16]);
    if let pganeus_io::NpyData::F64(v) = &mut nan.data {
        v[6] = f64::NAN;
    }
    for (key, bad, want) in [
        ("scale_mat_1", &small, "scale_mat_1 has shape (3, 4), expected (4, 4)"),
        ("world_mat_0", &nan, "world_mat_0[1][2] is not finite"),
    ] {
        let arrays: Vec<(&str, &NpyArray)> = entries
            .iter()
            .map(|(n, a)| (n.as_str(), if n == key { bad } else { a }))
            .collect();
        write_npz(&npz, &arrays).unwrap();
        let (path, msg) = capture_err(&dir.0);
        assert_eq!(path, npz);
        assert!(msg.contains(want), "{msg}");
    }
}

#[test]
fn mask_size_mismatch_names_the_mask() {
    let dir = make_capture("mask_size", 3);
    let bad = dir.0.join("mask/001.png");
    write_png(&bad, &Image::new(8, 7, 1)).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, bad);
    assert!(
        msg.contains("8x7") && msg.contains("8x6") && msg.contains("001.png"),
        "{msg}"
    );
}

#[test]
fn image_size_mismatch_is_an_error() {
    let dir = make_capture("image_size", 3);
    let bad = dir.0.join("image/002.png");
    write_png(&bad, &Image::new(9, 6, 3)).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, bad);
    assert!(
        msg.contains("9x6") && msg.contains("000.png") && msg.contains("8x6"),
        "{msg}"
    );
}

#[test]
fn missing_mask_names_it() {
    let dir = make_capture("missing_mask", 3);
    let gone = dir.0.join("mask/001.png");
    std::fs::remove_file(&gone).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, gone);
    assert!(
        msg.contains(&dir.0.join("image/001.png").display().to_string()),
        "{msg}"
    );
}

#[test]
fn extra_mask_names_both_paths() {
    let dir = make_capture("extra_mask", 2);
    let extra = dir.0.join("mask/007.png");
    write_png(&extra, &Image::new(8, 6, 1)).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, extra);
    assert!(
        msg.contains(&dir.0.join("image/007.png").display().to_string()),
        "{msg}"
    );
}

#[test]
fn empty_or_missing_image_folder_is_an_error() {
    let dir = make_capture("empty", 2);
    for i in 0..2 {
        std::fs::remove_file(dir.0.join(format!("image/{i:03}.png"))).unwrap();
    }
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, dir.0.join("image"));
    assert!(msg.contains("no images (PNG or JPEG)"), "{msg}");

    std::fs::remove_dir_all(dir.0.join("image")).unwrap();
    let (path, _) = capture_err(&dir.0);
    assert_eq!(path, dir.0.join("image"));

    let (path, _) = capture_err(&dir.0.join("does_not_exist"));
    assert_eq!(path, dir.0.join("does_not_exist"));
}

#[test]
fn missing_npz_corrupt_png_jpeg_and_bad_capture_json() {
    let dir = make_capture("misc", 2);
    let npz = dir.0.join("cameras_sphere.npz");
    std::fs::rename(&npz, dir.0.join("elsewhere.npz")).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, npz);
    assert!(msg.contains("missing"), "{msg}");
    std::fs::rename(dir.0.join("elsewhere.npz"), &npz).unwrap();
    open_capture(&dir.0).unwrap();

    let info = dir.0.join("capture.json");
    std::fs::write(&info, r#"{"kind": "video", "fps": -1}"#).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, info);
    assert!(msg.contains("fps"), "{msg}");
    std::fs::write(&info, r#"{"kind": "panorama"}"#).unwrap();
    assert_eq!(capture_err(&dir.0).0, info);
    std::fs::remove_file(&info).unwrap();

    let bad = dir.0.join("image/001.png");
    std::fs::write(&bad, b"\x89PNG\r\n\x1a\n").unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, bad);
    assert!(msg.contains("PNG"), "{msg}");

    write_png(&bad, &Image::new(8, 6, 3)).unwrap();
    // A JPEG is read, so a broken one is an error naming it.
    let jpg = dir.0.join("image/002.jpg");
    std::fs::write(&jpg, b"\xff\xd8\xff").unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, jpg);
    assert!(msg.contains("JPEG"), "{msg}");
}

#[test]
fn dtu_naming_pairs_masks_by_order_and_different_counts_are_refused() {
    // DTU as NeuS publishes it: image/000000.png with mask/000.png.
    let dir = make_capture("dtu", 3);
    for i in 0..3 {
        std::fs::rename(
            dir.0.join(format!("image/{i:03}.png")),
            dir.0.join(format!("image/{i:06}.png")),
        )
        .unwrap();
    }
    let cap = open_capture(&dir.0).unwrap();
    let masks = cap.masks.as_ref().unwrap();
    for (i, (img, mask)) in cap.images.iter().zip(masks).enumerate() {
        assert_eq!(img.file_name().unwrap().to_string_lossy(), format!("{i:06}.png"));
        assert_eq!(mask.file_name().unwrap().to_string_lossy(), format!("{i:03}.png"));
    }
    // One mask short: neither the names nor the order pair them.
    std::fs::remove_file(dir.0.join("mask/002.png")).unwrap();
    let (path, msg) = capture_err(&dir.0);
    assert_eq!(path, dir.0.join("mask/000000.png"));
    assert!(msg.contains("2 masks for 3 images"), "{msg}");
}

#[test]
fn jpeg_images_and_masks_open_and_read_like_png() {
    let dir = make_capture("jpeg", 3);
    let mut colour = Image::new(8, 6, 3);
    for (k, v) in colour.data.iter_mut().enumerate() {
        *v = [200u8, 90, 30][k % 3];
    }
    let mut mask = Image::new(8, 6, 1);
    for y in 0..6 {
        for x in 0..4 {
            mask.pixel_mut(x, y)[0] = 255;
        }
    }
    for i in 0..3 {
        std::fs::remove_file(dir.0.join(format!("image/{i:03}.png"))).unwrap();
        std::fs::write(
            dir.0.join(format!("image/{i:03}.jpg")),
            testkit::jpeg_bytes(&colour.data, 8, 6, 3, 95),
        )
        .unwrap();
        std::fs::remove_file(dir.0.join(format!("mask/{i:03}.png"))).unwrap();
        std::fs::write(
            dir.0.join(format!("mask/{i:03}.JPEG")),
            testkit::jpeg_bytes(&mask.data, 8, 6, 1, 95),
        )
        .unwrap();
    }
    let cap = open_capture(&dir.0).unwrap();
    assert_eq!((cap.width, cap.height), (8, 6));
    let img = pganeus_io::read_image(&cap.images[1]).unwrap();
    assert_eq!((img.width, img.height, img.channels), (8, 6, 3));
    // Lossy, but close: a flat colour comes back within a few levels.
    for p in img.data.chunks(3) {
        for (got, want) in p.iter().zip([200u8, 90, 30]) {
            assert!((*got as i32 - want as i32).abs() <= 4, "{p:?}");
        }
    }
    let m = pganeus_io::read_image(&cap.masks.as_ref().unwrap()[1]).unwrap();
    assert_eq!(m.channels, 1);
    assert!(m.data[0] > 200 && m.data[7] < 50, "{:?}", &m.data[..8]);
    assert_eq!(pganeus_io::read_image_size(&cap.images[0]).unwrap(), (8, 6));
    // Not an image this tool reads.
    assert!(pganeus_io::read_image(&dir.0.join("capture.json")).is_err());
}

#[test]
fn camera_npz_round_trip_and_neus_keys() {
    let dir = TempDir::new("cams");
    let path = dir.0.join("cameras_sphere.npz");
    let cams: Vec<CameraMats> = (0..4).map(camera).collect();
    write_cameras_npz(&path, &cams).unwrap();
    assert_eq!(read_cameras_npz(&path, 4).unwrap(), cams);
    assert_eq!(read_cameras_npz(&path, 2).unwrap(), cams[..2].to_vec());

    let entries = read_npz(&path).unwrap();
    assert_eq!(entries.len(), 4 * 6);
    for (name, a) in &entries {
        assert_eq!(a.shape, [4, 4], "{name}");
        assert!(matches!(a.data, pganeus_io::NpyData::F64(_)), "{name} must be float64");
    }
    let find = |k: &str| entries.iter().find(|(n, _)| n == k).unwrap().1.as_f64();
    let eye: Vec<f64> = (0..16).map(|k| if k % 5 == 0 { 1.0 } else { 0.0 }).collect();
    assert_eq!(find("camera_mat_3"), eye);
    assert_eq!(find("camera_mat_inv_3"), eye);
    // The stored inverses are inverses.
    for stem in ["world_mat", "scale_mat"] {
        let m = find(&format!("{stem}_2"));
        let inv = find(&format!("{stem}_inv_2"));
        for r in 0..4 {
            for c in 0..4 {
                let x: f64 = (0..4).map(|k| m[4 * r + k] * inv[4 * k + c]).sum();
                assert!((x - eye[4 * r + c]).abs() < 1e-12, "{stem}: {x} at ({r}, {c})");
            }
        }
    }

    let msg = read_cameras_npz(&path, 5).unwrap_err().to_string();
    assert!(msg.contains("cameras_sphere.npz") && msg.contains("no entry world_mat_4 (the capture has 5 images)"));

    // Non-finite or singular matrices are refused on writing.
    let mut bad = cams.clone();
    bad[1].world_mat[0][3] = f64::INFINITY;
    let err = write_cameras_npz(&dir.0.join("bad.npz"), &bad).unwrap_err();
    assert!(err.to_string().contains("world_mat_1[0][3]"), "{err}");
    bad[1].world_mat[0][3] = 0.0;
    bad[1].scale_mat = [[0.0; 4]; 4];
    let err = write_cameras_npz(&dir.0.join("bad.npz"), &bad).unwrap_err();
    assert!(
        err.to_string().contains("scale_mat_1") && err.to_string().contains("singular"),
        "{err}"
    );
    assert!(!dir.0.join("bad.npz").exists());
}

#[test]
fn capture_info_round_trips_extra_keys() {
    let dir = TempDir::new("info");
    let path = dir.0.join("capture.json");
    std::fs::write(&path, r#"{"kind": "static", "note": {"by": "synth", "seed": 3}}"#).unwrap();
    let info = read_capture_info(&path).unwrap();
    assert_eq!((info.kind, info.fps), (CaptureKind::Static, None));
    assert_eq!(info.extra["note"], json!({"by": "synth", "seed": 3}));
    write_capture_info(&path, &info).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(!text.contains("fps"), "{text}");
    assert_eq!(read_capture_info(&path).unwrap(), info);

    let video = CaptureInfo {
        kind: CaptureKind::Video,
        subject: None,
        fps: Some(f64::NAN),
        shutter: None,
        extra: Map::new(),
    };
    assert!(matches!(
        write_capture_info(&path, &video),
        Err(IoError::Invalid { .. })
    ));
    assert_eq!(
        read_capture_info(&path).unwrap(),
        info,
        "a failed write leaves the old file"
    );
    // A shutter longer than a frame is refused; one within it reads back.
    let blurred = CaptureInfo {
        fps: Some(30.0),
        shutter: Some(0.05),
        ..video.clone()
    };
    let e = write_capture_info(&path, &blurred).unwrap_err().to_string();
    assert!(e.contains("shutter") && e.contains("longer than a frame"), "{e}");
    let blurred = CaptureInfo {
        shutter: Some(1.0 / 60.0),
        ..blurred
    };
    write_capture_info(&path, &blurred).unwrap();
    assert_eq!(read_capture_info(&path).unwrap(), blurred);
}
