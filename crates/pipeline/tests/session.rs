//! `import` on raw sessions laid out wrongly: each refused before any work, naming what is missing.

use pganeus_io::{write_png, Image};
use pipeline::import_session::{run, ImportSessionArgs};
use pipeline::Quiet;
use std::path::Path;

/// A session folder with `folders` of two tiny photos each, and a board file.
fn session(name: &str, folders: &[&str]) -> std::path::PathBuf {
    let dir = testkit::scratch_dir("session", name);
    std::fs::write(dir.join("board.toml"), "kind = \"aruco_grid\"\n").unwrap();
    for f in folders {
        for k in 0..2 {
            let p = dir.join(f).join(format!("{k:04}.png"));
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            write_png(&p, &Image::new(8, 6, 3)).unwrap();
        }
    }
    dir
}

fn refusal(dir: &Path) -> String {
    let out = dir.with_file_name(format!("{}-data", dir.file_name().unwrap().to_string_lossy()));
    let e = match run(&ImportSessionArgs::new(dir, &out), &Quiet) {
        Ok(_) => panic!("{}: imported", dir.display()),
        Err(e) => e.to_string(),
    };
    assert!(!out.exists(), "{}: written on a refusal", out.display());
    e
}

#[test]
fn a_session_missing_a_capture_is_refused_by_name() {
    let e = refusal(&session("no_background", &["toy_a", "toy_b", "slide"]));
    assert!(e.contains("no background/"), "{e}");
    let e = refusal(&session("lone_half", &["background", "toy_a", "slide"]));
    assert!(e.contains("toy_a") && e.contains("no toy_b/"), "{e}");
    let e = refusal(&session("other_half", &["background", "toy_b", "slide"]));
    assert!(e.contains("no toy_a/"), "{e}");
    // An object never seen apart from the scene.
    let e = refusal(&session("no_objects", &["background", "slide"]));
    assert!(e.contains("no object captures"), "{e}");
    let dir = session("no_board", &["background", "toy_a", "toy_b"]);
    std::fs::remove_file(dir.join("board.toml")).unwrap();
    let e = refusal(&dir);
    assert!(e.contains("board.toml"), "{e}");
}

#[test]
fn a_second_camera_or_an_unreadable_video_file_is_refused_by_name() {
    let dir = session("second_camera", &["background", "toy_a", "toy_b", "slide"]);
    std::fs::write(dir.join("slide/camera.json"), "{}").unwrap();
    let e = refusal(&dir);
    assert!(e.contains("camera.json") && e.contains("second camera"), "{e}");
    // A video file: without ffmpeg the error says the command that cuts it; with it, ffmpeg's complaint
    // about a file that is no video. Either names the file.
    let dir = session("video_file", &["background", "toy_a", "toy_b"]);
    std::fs::write(dir.join("drop.mp4"), b"not a video").unwrap();
    let e = refusal(&dir);
    assert!(e.contains("drop.mp4"), "{e}");
    assert!(e.contains("ffmpeg -i") || e.contains("ffmpeg could not read it"), "{e}");
}
