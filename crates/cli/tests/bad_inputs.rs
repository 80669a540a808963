//! A corpus of 23 damaged inputs made from the project's own capture and meshes (missing, NaN, singular and
//! misshapen cameras; truncated, mis-sized, empty and missing images and masks; broken PLY files, each through
//! `compare-mesh` on either side and `bake`; 29 command lines): every one
//! is refused with exit code 1 and a message naming the file (or the entry) at fault, never a panic, and
//! nothing is written. Meshes with a coordinate that is not a number are refused by every command that
//! reads meshes (`compare-mesh` used to panic on one).

use crate::common;
use common::{bin, copy_dir, not_refused, tabletop};
use pganeus_io::{write_npz, write_png, Image, NpyArray};
use std::path::{Path, PathBuf};

/// The commands that read a user's mesh, on `bad`: `compare-mesh` with it on either side of `good`, and
/// `bake` into `sdf`.
fn mesh_commands(bad: &Path, good: &Path, sdf: &Path) -> [Vec<String>; 3] {
    let s = |p: &Path| p.display().to_string();
    [
        vec!["compare-mesh".into(), s(bad), s(good)],
        vec!["compare-mesh".into(), s(good), s(bad)],
        vec!["bake".into(), s(bad), "--out".into(), s(sdf)],
    ]
}

/// A tetrahedron as ASCII PLY, its second vertex's x as given.
fn tetrahedron(x1: &str) -> String {
    format!(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         element face 4\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0\n{x1} 0 0\n0 0.01 0\n0 0 0.01\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    )
}

#[test]
fn a_nan_or_infinite_vertex_is_refused_by_name_not_a_panic() {
    let d = testkit::scratch_dir("cli", "bad_meshes");
    let good = d.join("good.ply");
    std::fs::write(&good, tetrahedron("0.01")).unwrap();
    for (name, x) in [("nan.ply", "nan"), ("inf.ply", "inf")] {
        let bad = d.join(name);
        std::fs::write(&bad, tetrahedron(x)).unwrap();
        for args in mesh_commands(&bad, &good, &d.join("x.sdf")) {
            let o = bin().args(&args).output().unwrap();
            if let Some(why) = not_refused(&o, &[name, "vertex 1"]) {
                panic!("{args:?}: {why}");
            }
        }
    }
    assert!(!d.join("x.sdf").exists());
    let _ = std::fs::remove_dir_all(&d);
}

/// The capture's cameras rewritten with `edit` applied to the list of (name, 4×4 array) entries.
fn edit_cameras(capture: &Path, edit: impl Fn(&mut Vec<(String, NpyArray)>)) {
    let path = capture.join("cameras_sphere.npz");
    let mut arrays = pganeus_io::read_npz(&path).unwrap();
    edit(&mut arrays);
    let refs: Vec<(&str, &NpyArray)> = arrays.iter().map(|(n, a)| (n.as_str(), a)).collect();
    write_npz(&path, &refs).unwrap();
}

/// Entry `name`'s elements with `f` applied.
fn edit_entry(arrays: &mut [(String, NpyArray)], name: &str, f: impl Fn(&mut Vec<f64>)) {
    let (_, a) = arrays.iter_mut().find(|(n, _)| n == name).unwrap();
    let mut v = a.as_f64();
    f(&mut v);
    *a = NpyArray::f64(a.shape.clone(), v);
}

/// The last line a command wrote to its error output (what it says when it refuses).
fn last_line(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr)
        .lines()
        .last()
        .unwrap_or("")
        .to_string()
}

fn truncate(path: &Path, keep: usize) {
    let b = std::fs::read(path).unwrap();
    std::fs::write(path, &b[..keep.min(b.len())]).unwrap();
}

/// One damaged capture: how it is damaged, and what the refusal must name.
struct Case {
    name: &'static str,
    damage: fn(&Path),
    names: &'static str,
}

fn capture_cases() -> Vec<Case> {
    vec![
        Case {
            name: "cameras file missing",
            damage: |c| std::fs::remove_file(c.join("cameras_sphere.npz")).unwrap(),
            names: "cameras_sphere.npz",
        },
        Case {
            name: "cameras file truncated",
            damage: |c| truncate(&c.join("cameras_sphere.npz"), 700),
            names: "cameras_sphere.npz",
        },
        Case {
            name: "cameras file not an archive",
            damage: |c| std::fs::write(c.join("cameras_sphere.npz"), "world_mat_0 = identity\n").unwrap(),
            names: "cameras_sphere.npz",
        },
        Case {
            name: "a camera missing",
            damage: |c| edit_cameras(c, |a| a.retain(|(n, _)| n != "world_mat_3")),
            names: "world_mat_3",
        },
        Case {
            name: "a camera with NaN",
            damage: |c| edit_cameras(c, |a| edit_entry(a, "world_mat_2", |v| v[5] = f64::NAN)),
            names: "world_mat_2",
        },
        Case {
            name: "a camera with infinity",
            damage: |c| edit_cameras(c, |a| edit_entry(a, "world_mat_4", |v| v[0] = f64::INFINITY)),
            names: "world_mat_4",
        },
        Case {
            name: "a singular camera",
            damage: |c| edit_cameras(c, |a| edit_entry(a, "world_mat_3", |v| v[4..8].fill(0.0))),
            names: "world_mat_3",
        },
        Case {
            name: "a singular scale_mat",
            damage: |c| {
                edit_cameras(c, |a| {
                    for k in 0..6 {
                        edit_entry(a, &format!("scale_mat_{k}"), |v| v[0] = 0.0)
                    }
                })
            },
            names: "scale_mat_0",
        },
        Case {
            name: "a camera of the wrong shape",
            damage: |c| {
                edit_cameras(c, |a| {
                    let (_, m) = a.iter_mut().find(|(n, _)| n == "world_mat_0").unwrap();
                    *m = NpyArray::f64(vec![3, 4], m.as_f64()[..12].to_vec());
                })
            },
            names: "world_mat_0",
        },
        Case {
            name: "an image truncated",
            damage: |c| truncate(&c.join("image/001.png"), 100),
            names: "001.png",
        },
        Case {
            name: "an image of another size",
            damage: |c| write_png(&c.join("image/002.png"), &Image::new(20, 10, 3)).unwrap(),
            names: "002.png",
        },
        Case {
            name: "an image that is not an image",
            damage: |c| std::fs::write(c.join("image/003.png"), "not a picture").unwrap(),
            names: "003.png",
        },
        Case {
            name: "an empty image file",
            damage: |c| std::fs::write(c.join("image/004.png"), "").unwrap(),
            names: "004.png",
        },
        Case {
            name: "the image folder missing",
            damage: |c| std::fs::remove_dir_all(c.join("image")).unwrap(),
            names: "image",
        },
        Case {
            name: "an image missing",
            damage: |c| std::fs::remove_file(c.join("image/005.png")).unwrap(),
            names: "mask",
        },
        Case {
            // Without mask/ an object capture's masks are computed from its photos; photos of nothing
            // (one flat colour) leave no object to find.
            name: "the mask folder missing and no object in the photos",
            damage: |c| {
                std::fs::remove_dir_all(c.join("mask")).unwrap();
                let mut flat = Image::new(48, 36, 3);
                flat.data.fill(128);
                for k in 0..6 {
                    write_png(&c.join(format!("image/{k:03}.png")), &flat).unwrap();
                }
            },
            names: "no object stands out",
        },
        Case {
            name: "a mask of another size",
            damage: |c| write_png(&c.join("mask/002.png"), &Image::new(10, 10, 1)).unwrap(),
            names: "002.png",
        },
        Case {
            name: "a mask truncated",
            damage: |c| truncate(&c.join("mask/001.png"), 60),
            names: "001.png",
        },
        Case {
            name: "a mask missing",
            damage: |c| std::fs::remove_file(c.join("mask/004.png")).unwrap(),
            names: "mask",
        },
        Case {
            name: "every mask empty",
            damage: |c| {
                for k in 0..6 {
                    write_png(&c.join(format!("mask/{k:03}.png")), &Image::new(48, 36, 1)).unwrap();
                }
            },
            names: "mask",
        },
    ]
}

/// A binary PLY of the tetrahedron with its header edited by `header` and its body cut by `cut` bytes.
fn binary_ply(d: &Path, name: &str, header: impl Fn(&str) -> String, cut: usize) -> PathBuf {
    let mesh = pganeus_io::read_ply_bytes(tetrahedron("0.01").as_bytes(), Path::new("t.ply")).unwrap();
    let bytes = pganeus_io::write_ply_bytes(&mesh, pganeus_io::PlyEncoding::BinaryLittleEndian);
    let end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let head = header(std::str::from_utf8(&bytes[..end]).unwrap());
    let mut out = head.into_bytes();
    out.extend_from_slice(&bytes[end..bytes.len() - cut]);
    let path = d.join(name);
    std::fs::write(&path, out).unwrap();
    path
}

#[test]
fn a_corpus_of_damaged_captures_and_meshes_is_refused_by_name() {
    let d = testkit::scratch_dir("cli", "bad_inputs");
    let pristine = tabletop(&d, (48, 36), 6, 1, &[]).join("toy_a");
    let mut refused = 0;
    let mut failures = Vec::new();
    let cases = capture_cases();
    for (k, case) in cases.iter().enumerate() {
        let capture = d.join(format!("case{k}"));
        copy_dir(&pristine, &capture);
        (case.damage)(&capture);
        let run = d.join(format!("run{k}"));
        let o = bin()
            .arg("train")
            .arg(&capture)
            .arg("--out")
            .arg(&run)
            .args(["--kind", "object", "--iterations", "2", "--no-preview"])
            .output()
            .unwrap();
        println!("{}: {}", case.name, last_line(&o));
        match not_refused(&o, &[case.names]) {
            None if !run.join("checkpoint.safetensors").exists() => refused += 1,
            None => failures.push(format!("{}: refused, but a checkpoint was written", case.name)),
            Some(why) => failures.push(format!("{}: {why}", case.name)),
        }
    }
    // Broken meshes, through the two commands that read meshes from users.
    let good = d.join("good.ply");
    std::fs::write(&good, tetrahedron("0.01")).unwrap();
    let meshes = [
        (binary_ply(&d, "short.ply", str::to_string, 7), "short.ply"),
        (
            binary_ply(
                &d,
                "huge.ply",
                |h| h.replace("element vertex 4", "element vertex 1000000000"),
                0,
            ),
            "huge.ply",
        ),
        (
            binary_ply(&d, "index.ply", str::to_string, 0),
            "index.ply", // made bad below
        ),
    ];
    {
        // The last face's last index out of range.
        let mut b = std::fs::read(&meshes[2].0).unwrap();
        let n = b.len();
        b[n - 4..].copy_from_slice(&99i32.to_le_bytes());
        std::fs::write(&meshes[2].0, b).unwrap();
    }
    for (path, name) in &meshes {
        for args in mesh_commands(path, &good, &d.join("x.sdf")) {
            let o = bin().args(&args).output().unwrap();
            println!("{}: {}", args[0], last_line(&o));
            match not_refused(&o, &[name]) {
                None => refused += 1,
                Some(why) => failures.push(format!("{args:?}: {why}")),
            }
        }
    }
    let total = cases.len() + 3 * meshes.len();
    println!("{refused} of {total} command lines on damaged inputs refused");
    assert!(
        failures.is_empty(),
        "{} of {total} not refused cleanly:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(!d.join("x.sdf").exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn masks_refuse_a_mask_folder_in_place_and_a_missing_scene_run_by_name() {
    let d = testkit::scratch_dir("cli", "bad_masks");
    let data = tabletop(&d, (48, 36), 2, 3, &[]);
    let slide = data.join("slide");
    // The video's own masks are not overwritten: without --out the default folder exists.
    let o = bin()
        .args(["masks"])
        .arg(&slide)
        .args(["--scene", "no-such-run", "--body", "toy"])
        .output()
        .unwrap();
    if let Some(why) = not_refused(&o, &["mask_toy", "exists", "--out"]) {
        panic!("{why}");
    }
    // A scene run that is not there is named; nothing is written.
    let out = d.join("computed").join("mask_toy");
    let o = bin()
        .args(["masks"])
        .arg(&slide)
        .args(["--scene", "no-such-run", "--body", "toy", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    if let Some(why) = not_refused(&o, &["--scene no-such-run"]) {
        panic!("{why}");
    }
    assert!(!out.exists() && !d.join("computed").exists());
    let _ = std::fs::remove_dir_all(&d);
}
