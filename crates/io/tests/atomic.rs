//! `write_atomic`: the whole file or the old one, parent folders created,
//! no temporary file left behind on success or failure.

use std::path::{Path, PathBuf};

use pganeus_io::{write_atomic, IoError};

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pganeus_io_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn writes_replaces_and_leaves_no_temp_file() {
    let dir = tempdir("atomic_ok");
    let path = dir.join("a/b/c.txt");
    write_atomic(&path, b"first").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"first");
    write_atomic(&path, b"second, longer").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"second, longer");
    write_atomic(&path, b"").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"");
    assert_eq!(testkit::sorted_file_names(&dir.join("a/b")), vec!["c.txt"]);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn failed_rename_removes_temp_file() {
    let dir = tempdir("atomic_fail");
    // A non-empty folder where the file should go: the rename must fail.
    let target = dir.join("taken");
    std::fs::create_dir_all(target.join("inside")).unwrap();
    let err = write_atomic(&target, b"data").unwrap_err();
    assert!(matches!(err, IoError::Write { .. }), "{err:?}");
    assert!(err.to_string().contains("taken"), "{err}");
    assert_eq!(testkit::sorted_file_names(&dir), vec!["taken"]);
    assert!(target.join("inside").is_dir());
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn path_without_file_name_is_an_error() {
    let err = write_atomic(Path::new("/"), b"x").unwrap_err();
    assert!(matches!(err, IoError::Write { .. }), "{err:?}");
}

#[test]
fn concurrent_writers_to_one_target_never_mix() {
    let dir = tempdir("atomic_threads");
    let path = dir.join("shared.bin");
    std::thread::scope(|s| {
        for k in 0..4u8 {
            let path = &path;
            s.spawn(move || {
                for _ in 0..20 {
                    write_atomic(path, &[k; 4096]).unwrap();
                }
            });
        }
    });
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes.len(), 4096);
    assert!(bytes.iter().all(|&b| b == bytes[0]), "mixed contents");
    assert_eq!(testkit::sorted_file_names(&dir), vec!["shared.bin"]);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_staged_folder_replaces_its_target_only_when_committed() {
    let dir = tempdir("staged");
    let target = dir.join("out");
    std::fs::create_dir_all(&target).unwrap();
    std::fs::write(target.join("old.txt"), "old").unwrap();
    // Dropped half-written: the old folder stays whole and the partial one is gone.
    {
        let staged = pganeus_io::StagedDir::new(&target).unwrap();
        std::fs::write(staged.path().join("new.txt"), "new").unwrap();
    }
    assert_eq!(testkit::sorted_file_names(&target), ["old.txt"]);
    assert_eq!(testkit::sorted_file_names(&dir), ["out"]);
    // Committed: the new contents replace the old.
    let staged = pganeus_io::StagedDir::new(&target).unwrap();
    std::fs::write(staged.path().join("new.txt"), "new").unwrap();
    staged.commit().unwrap();
    assert_eq!(testkit::sorted_file_names(&target), ["new.txt"]);
    assert_eq!(testkit::sorted_file_names(&dir), ["out"]);
    // A target that did not exist is created.
    let fresh = dir.join("fresh");
    let staged = pganeus_io::StagedDir::new(&fresh).unwrap();
    std::fs::write(staged.path().join("a"), "a").unwrap();
    staged.commit().unwrap();
    assert_eq!(testkit::sorted_file_names(&fresh), ["a"]);
    let _ = std::fs::remove_dir_all(&dir);
}
