//! Paths written into one output that name another: relative to the file's own folder, so that a tree of
//! outputs can be moved or read from any working directory.

use std::path::{Component, Path, PathBuf};

/// `target` as a path relative to the folder `from` (both must exist: they are made absolute through the
/// file system). Falls back to `target` made absolute, or as given, when either cannot be resolved.
pub fn path_relative_to(from: &Path, target: &Path) -> PathBuf {
    let (Ok(from), Ok(target)) = (from.canonicalize(), target.canonicalize()) else {
        return std::path::absolute(target).unwrap_or_else(|_| target.to_path_buf());
    };
    let (f, t): (Vec<Component>, Vec<Component>) = (from.components().collect(), target.components().collect());
    let common = f.iter().zip(&t).take_while(|(a, b)| a == b).count();
    // Different roots (another drive): only an absolute path names it.
    if common == 0 {
        return target;
    }
    let mut out: PathBuf = std::iter::repeat_n(Component::ParentDir, f.len() - common).collect();
    out.extend(&t[common..]);
    if out.as_os_str().is_empty() {
        out.push(".");
    }
    out
}

/// A path read from a file in `folder`: relative to that folder (as [`path_relative_to`] writes it); for
/// files written before that rule, a relative path that exists from the working directory is taken as it is.
pub fn resolve_from(folder: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        return p.to_path_buf();
    }
    let inside = folder.join(p);
    if inside.exists() || !p.exists() {
        inside
    } else {
        p.to_path_buf()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_relative_path_leads_from_the_folder_to_the_target_from_any_working_directory() {
        let root = std::env::temp_dir().join(format!("pganeus-paths-{}", std::process::id()));
        let (out, run) = (root.join("merged/toy"), root.join("runs/toy_a"));
        std::fs::create_dir_all(&out).unwrap();
        std::fs::create_dir_all(&run).unwrap();
        let rel = path_relative_to(&out, &run);
        assert_eq!(rel, Path::new("../../runs/toy_a"));
        assert_eq!(
            resolve_from(&out, &rel).canonicalize().unwrap(),
            run.canonicalize().unwrap()
        );
        assert_eq!(path_relative_to(&out, &out), Path::new("."));
        // A target that does not exist is written absolute.
        let missing = path_relative_to(&out, Path::new("no/such/run"));
        assert!(missing.is_absolute() && missing.ends_with("no/such/run"));
        std::fs::remove_dir_all(&root).unwrap();
    }
}
