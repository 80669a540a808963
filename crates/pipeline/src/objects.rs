//! The `--object NAME=DIR` arguments of `fit` and `render --trajectory`: parsed, and each object folder
//! loaded once however many bodies share it (several identical balls are one object: its zero level is
//! extracted once, not once per body).

use crate::error::{err, fail, Context};
use crate::Result;
use neus::object_model::ObjectModel;
use std::path::PathBuf;
use std::sync::Arc;

/// The `--object NAME=DIR` entries, in order (names unique).
pub fn parse_objects(list: &[String]) -> Result<Vec<(String, PathBuf)>> {
    if list.is_empty() {
        fail!(Stage, "give the body with --object NAME=DIR");
    }
    let mut out: Vec<(String, PathBuf)> = Vec::new();
    for one in list {
        let (n, d) = one.split_once('=').ok_or_else(|| {
            err!(
                Settings,
                "--object {one:?}: expected NAME=DIR (a merge output or a run folder)"
            )
        })?;
        if n.is_empty() {
            fail!(Settings, "--object {one:?}: the name is empty");
        }
        if out.iter().any(|(o, _)| o == n) {
            fail!(Settings, "--object {one:?}: body {n:?} is given twice");
        }
        out.push((n.to_string(), PathBuf::from(d)));
    }
    Ok(out)
}

/// Each named body's object, every distinct folder loaded once (errors name the body), its geometry baked
/// `bake` lattice steps a cell of its occupancy grid (0: not baked; [`ObjectModel::bake`]).
pub fn load_objects(named: &[(String, PathBuf)], bake: usize) -> Result<Vec<(String, Arc<ObjectModel>)>> {
    let mut loaded: Vec<(PathBuf, Arc<ObjectModel>)> = Vec::new();
    let mut out = Vec::with_capacity(named.len());
    for (name, dir) in named {
        let model = match loaded.iter().find(|(d, _)| d == dir) {
            Some((_, m)) => m.clone(),
            None => {
                let mut m = ObjectModel::load(dir).with_context(|| format!("--object {name}"))?;
                m.bake(bake).with_context(|| format!("--object {name}"))?;
                let m = Arc::new(m);
                loaded.push((dir.clone(), m.clone()));
                m
            }
        };
        out.push((name.clone(), model));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_must_be_given_once_and_dirs_named() {
        let list = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let ok = parse_objects(&list(&["a=x", "b=x"])).unwrap();
        assert_eq!(ok, vec![("a".into(), "x".into()), ("b".into(), "x".into())]);
        for (bad, needle) in [
            (list(&[]), "--object NAME=DIR"),
            (list(&["a=x", "a=y"]), "given twice"),
            (list(&["ax"]), "expected NAME=DIR"),
            (list(&["=x"]), "name is empty"),
        ] {
            let e = parse_objects(&bad).unwrap_err().to_string();
            assert!(e.contains(needle), "{bad:?}: {e}");
        }
    }
}
