//! The scene file as a library: a world from TOML or JSON, and typed errors
//! that name the file and the field.

use scene_file::{SceneError, SceneFile};
use std::path::PathBuf;

fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("scene_file_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const GOOD: &str = r#"
name = "drop"
[sim]
fps = 30
frames = 12
[contact]
restitution = 0.4
friction = 0.3
[[scene]]
shape = "plane"
[[scene]]
shape = "box"
half = [0.05, 0.05, 0.02]
t = [0.2, 0.0, 0.02]
[[body]]
name = "a"
mass = 0.1
t = [0.0, 0.0, 0.1]
v = [0.5, 0.0, 0.0]
[body.shape]
shape = "sphere"
radius = 0.02
[[body]]
name = "b"
density = 500
t = [0.1, 0.0, 0.1]
[body.shape]
shape = "box"
half = [0.02, 0.02, 0.02]
[[pair]]
bodies = ["a", "b"]
restitution = 0.7
friction = 0.1
"#;

#[test]
fn a_scene_builds_its_world() {
    let loaded = SceneFile::load(&write("good.toml", GOOD)).unwrap();
    assert_eq!(loaded.name, "drop");
    let w = &loaded.world;
    assert_eq!(w.bodies.len(), 2);
    assert_eq!(w.config.frames, 12);
    assert_eq!(w.initial[0].v.to_array(), [0.5, 0.0, 0.0]);
    assert!((w.bodies[1].mass - 500.0 * 0.04f64.powi(3)).abs() < 1e-9);
    assert_eq!(w.pair_contact[0].restitution, 0.7);
    // The same scene as JSON.
    let value: toml::Value = toml::from_str(GOOD).unwrap();
    let json = write("good.json", &serde_json::to_string(&value).unwrap());
    let again = SceneFile::load(&json).unwrap();
    assert_eq!(again.world.params(), w.params());
}

#[test]
fn errors_are_typed_and_name_the_field() {
    let bad = write("bad.toml", &GOOD.replace("radius = 0.02", "radius = -1.0"));
    match SceneFile::load(&bad) {
        Err(SceneError::Field { path, field, msg }) => {
            assert_eq!(path, bad);
            assert_eq!(field, "body[0] (a).shape.radius");
            assert!(msg.contains("positive"), "{msg}");
        }
        other => panic!("{:?}", other.err()),
    }
    let unknown_pair = write(
        "pair.toml",
        &GOOD.replace("bodies = [\"a\", \"b\"]", "bodies = [\"a\", \"c\"]"),
    );
    let e = SceneFile::load(&unknown_pair).err().unwrap();
    assert!(e.to_string().contains("pair[0].bodies: no body named \"c\""), "{e}");
    let typo = write("typo.toml", &GOOD.replace("friction = 0.3", "fricton = 0.3"));
    assert!(matches!(SceneFile::load(&typo), Err(SceneError::Parse { .. })));
    let missing = std::env::temp_dir().join("no_such_scene_file.toml");
    assert!(matches!(SceneFile::load(&missing), Err(SceneError::Read { .. })));
    let no_mesh = write(
        "mesh.toml",
        &GOOD.replace("shape = \"plane\"", "shape = \"mesh\"\nfile = \"none.ply\""),
    );
    match SceneFile::load(&no_mesh) {
        Err(SceneError::Field { field, .. }) => assert_eq!(field, "scene[0].file"),
        other => panic!("{:?}", other.err()),
    }
}

/// The repository's scene files, mutated (numbers turned to nan, inf, huge or negative; bytes flipped,
/// lines cut): each is refused with an error or builds a world, never a panic.
#[test]
fn mutated_scene_files_are_refused_or_built_never_a_panic() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let seeds: Vec<Vec<u8>> = ["obstacle.toml", "tabletop.toml", "tabletop_guess.toml", "two_body.toml"]
        .iter()
        .map(|n| std::fs::read(root.join(n)).unwrap())
        .collect();
    let path = root.join("fuzzed.toml");
    let r = testkit::fuzz::fuzz("scene TOML", &seeds, 1500, 12, |b| {
        let Ok(text) = std::str::from_utf8(b) else { return false };
        let Ok(file) = toml::from_str::<SceneFile>(text) else {
            return false;
        };
        file.build(&path).is_ok()
    });
    println!("{r}");
    assert!(r.panics.is_empty(), "{r}: {:?}", &r.panics[..r.panics.len().min(5)]);
    assert!(r.accepted > 0 && r.accepted < r.cases, "{r}");
    assert!(r.slowest.as_secs_f64() < 2.0, "{r}");
}
