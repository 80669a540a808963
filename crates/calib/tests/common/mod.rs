//! OpenCV as the independent reference of the slow tests: `tests/opencv/reference.py` run by the Python
//! in `PGANEUS_OPENCV_PYTHON` (else `python3`) with opencv-contrib-python-headless, as `.ci/run` installs it.

use std::path::Path;
use std::process::Command;

/// Runs `reference.py COMMAND INPUT OUTPUT` and returns what it printed (OpenCV's version and a summary);
/// panics with OpenCV's error when it fails.
pub fn opencv_reference(command: &str, input: &Path, output: &Path) -> String {
    let python = std::env::var("PGANEUS_OPENCV_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(python)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/opencv/reference.py"))
        .args([command, &input.to_string_lossy(), &output.to_string_lossy()])
        .output()
        .expect("run Python; set PGANEUS_OPENCV_PYTHON to a Python with opencv-contrib-python-headless");
    assert!(
        out.status.success(),
        "OpenCV's reference ({command}) failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}
