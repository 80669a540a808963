//! What the CLI's end-to-end tests share: the binary, its output as text, the repository, and small
//! synthetic tabletop datasets. Each test file uses its own subset.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pganeus"))
}

/// A command's stdout and stderr, for assertion messages.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The tabletop preset's description at `width`×`height`, `views` per static capture, `frames` per video.
pub fn tabletop_toml(width: u32, height: u32, views: usize, frames: usize) -> String {
    let printed = bin().args(["synth", "--print-preset", "tabletop"]).output().unwrap();
    assert!(printed.status.success(), "{}", text(&printed));
    String::from_utf8(printed.stdout)
        .unwrap()
        .replacen("width = 160", &format!("width = {width}"), 1)
        .replacen("height = 120", &format!("height = {height}"), 1)
        .replacen("views = 24", &format!("views = {views}"), 1)
        .replace("frames = 30", &format!("frames = {frames}"))
}

/// [`tabletop_toml`] rendered by `synth` into `d/data` (its description in `d/scene.toml`), with `extra`
/// arguments; the dataset's folder.
pub fn tabletop(d: &Path, (width, height): (u32, u32), views: usize, frames: usize, extra: &[&str]) -> PathBuf {
    std::fs::write(d.join("scene.toml"), tabletop_toml(width, height, views, frames)).unwrap();
    let o = bin()
        .args(["synth", "--scene"])
        .arg(d.join("scene.toml"))
        .arg("--out")
        .arg(d.join("data"))
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    d.join("data")
}

#[allow(unused_imports)]
pub use testkit::copy_dir;

/// Why a command's outcome is not a clean refusal (exit code 1, every needle in its error output, no
/// panic), or `None` when it is one.
pub fn not_refused(o: &Output, needles: &[&str]) -> Option<String> {
    let err = String::from_utf8_lossy(&o.stderr);
    let clean = o.status.code() == Some(1) && needles.iter().all(|n| err.contains(n)) && !err.contains("panicked");
    (!clean).then(|| format!("exit {:?}, wanted {needles:?}: {}", o.status.code(), text(o)))
}

/// A trajectory body's `flight` as `fit` writes it (the launch fitted to the flight alone, 4 frames, bent),
/// 3 cm/s faster along x than `video`'s first body's true launch.
pub fn flight_3_cm_s_fast(video: &serde_json::Value) -> serde_json::Value {
    let initial = &video["bodies"][0]["initial"];
    let mut v = initial["v"].clone();
    v[0] = serde_json::json!(v[0].as_f64().unwrap() + 0.03);
    serde_json::json!({"frames": 4, "bent": true, "v0": v, "omega0": initial["omega"], "statistic": 40.0, "critical": 26.2})
}
