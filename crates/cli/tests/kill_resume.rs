//! `train` killed with SIGKILL at several moments (as its first checkpoint lands, and part way through two
//! resumed runs), and killed half-way through writing a checkpoint, and resumed each time ends with the same
//! checkpoint, byte for byte, as a training that was
//! never interrupted: checkpoints are written to a temporary file and renamed (`pganeus_io::write_atomic`:
//! a kill leaves the old file or the new one under the final name, never part of one), and hold the step,
//! the random state and the optimiser's moments.

use std::path::Path;
use std::process::Command;

use crate::common;
use common::{bin, tabletop, text};
use std::time::{Duration, Instant};

fn train(d: &Path, out: &str, extra: &[&str]) -> Command {
    let mut c = bin();
    c.current_dir(d)
        .args([
            "train",
            "data/toy_a",
            "--out",
            out,
            "--config",
            "train.toml",
            "--iterations",
            "60",
            // The preview mesh is not compared: only the checkpoints are.
            "--no-preview",
        ])
        .args(extra);
    c
}

#[test]
#[ignore = "slow: a training killed three times and resumed ends with the uninterrupted checkpoint, ~24 s"]
fn a_killed_training_resumes_to_the_same_checkpoint() {
    let d = testkit::scratch_dir("cli", "kill_resume");
    tabletop(&d, (64, 48), 4, 2, &[]);
    // A checkpoint every 10 steps; a table small enough that the whole run takes seconds.
    std::fs::write(
        d.join("train.toml"),
        "checkpoint_every = 10\n\n[field.grid]\nlog2_table_size = 15\n",
    )
    .unwrap();

    let o = train(&d, "whole", &[]).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let whole = std::fs::read(d.join("whole/checkpoint.safetensors")).unwrap();

    // Killed three times: as soon as the first checkpoint appears, then 1.5 s and 3 s into two resumed runs;
    // each time resumed from what is on disk.
    let ckpt = d.join("cut/checkpoint.safetensors");
    let mut kills = 0;
    for (attempt, delay_ms) in [0u64, 1500, 3000].into_iter().enumerate() {
        let first = attempt == 0;
        let mut child = if first {
            train(&d, "cut", &[]).spawn().unwrap()
        } else {
            train(&d, "cut", &["--resume"]).spawn().unwrap()
        };
        let t0 = Instant::now();
        while !ckpt.exists() && t0.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(5));
        }
        std::thread::sleep(Duration::from_millis(delay_ms));
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            kills += 1;
            println!("killed {attempt}: {delay_ms} ms after the checkpoint was there");
        }
        child.wait().unwrap();
        // Whatever is under the final name is a whole checkpoint: the resume below reads it.
        assert!(ckpt.exists());
    }
    assert!(kills >= 1, "the training ended before any kill");
    let o = train(&d, "cut", &["--resume"]).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let cut = std::fs::read(&ckpt).unwrap();
    assert!(
        cut == whole,
        "the resumed training's checkpoint differs from the uninterrupted one"
    );
    killed_while_writing_its_checkpoint(&d, &whole);
    let _ = std::fs::remove_dir_all(&d);
}

/// Killed in the middle of writing its second checkpoint (half of it in the temporary file, through the
/// `PGANEUS_DIE_WRITING` fault of `write_atomic`): the final name still holds the first checkpoint, whole,
/// and the resumed training ends with the uninterrupted one's bytes (`whole`, trained in `d` as here).
fn killed_while_writing_its_checkpoint(d: &Path, whole: &[u8]) {
    let o = train(d, "cut_mid_write", &[])
        .env("PGANEUS_DIE_WRITING", "checkpoint.safetensors:2")
        .output()
        .unwrap();
    assert!(!o.status.success(), "the fault did not fire: {}", text(&o));
    let ckpt = d.join("cut_mid_write/checkpoint.safetensors");
    let first = std::fs::read(&ckpt).expect("the first checkpoint is under its name");
    let st = pganeus_io::read_safetensors_bytes(&first, &ckpt).expect("and it is whole");
    assert_eq!(
        st.metadata.get("step").map(String::as_str),
        Some("10"),
        "{:?}",
        st.metadata
    );
    let partial: Vec<_> = std::fs::read_dir(d.join("cut_mid_write"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with(".checkpoint.safetensors.tmp")
        })
        .collect();
    assert_eq!(
        partial.len(),
        1,
        "the half-written checkpoint is left aside under a temporary name"
    );

    let o = train(d, "cut_mid_write", &["--resume"]).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        std::fs::read(&ckpt).unwrap() == whole,
        "the resumed training's checkpoint differs from the uninterrupted one"
    );
}
