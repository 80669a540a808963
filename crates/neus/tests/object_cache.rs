//! A run used as an object extracts its zero level once: the mesh is kept beside the checkpoint under the
//! checkpoint's digest, read back exactly on the next load, and made again when the checkpoint changes.

use geom::Vec3;
use neus::checkpoint::save_field;
use neus::untrained_field::untrained_field;
use neus::{FieldInit, ObjectModel};

/// Coarser than a fit's 192³: the cache, not the mesh, is under test.
const RES: usize = 64;

#[test]
fn a_runs_zero_level_is_cached_beside_its_checkpoint() {
    let d = testkit::scratch_dir("neus", "object_cache");
    let ckpt = d.join("checkpoint.safetensors");
    save_field(
        &untrained_field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.06, 3),
        &ckpt,
    )
    .unwrap();
    let t = std::time::Instant::now();
    let first = ObjectModel::load_with_mesh_res(&d, RES).unwrap();
    let extracted = t.elapsed();
    assert!(d.join("object_mesh.ply").exists() && d.join("object_mesh.json").exists());
    let t = std::time::Instant::now();
    let second = ObjectModel::load_with_mesh_res(&d, RES).unwrap();
    let cached = t.elapsed();
    println!("first load {extracted:?}, cached {cached:?}");
    // The very same mesh (double-precision positions), so every later stage sees the same body.
    assert_eq!(first.mesh.vertices, second.mesh.vertices);
    assert_eq!(first.mesh.faces, second.mesh.faces);
    assert_eq!(first.volume, second.volume);
    assert!(
        cached < extracted,
        "the cache was not used: {cached:?} vs {extracted:?}"
    );

    // Another checkpoint in the same place: its own zero level, not the cached one.
    save_field(
        &untrained_field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.04, 3),
        &ckpt,
    )
    .unwrap();
    let other = ObjectModel::load_with_mesh_res(&d, RES).unwrap();
    assert!(
        other.volume < 0.5 * first.volume,
        "{} vs {}",
        other.volume,
        first.volume
    );
    // A damaged cache is made again, not trusted.
    std::fs::write(d.join("object_mesh.ply"), b"ply\ngarbage").unwrap();
    let again = ObjectModel::load_with_mesh_res(&d, RES).unwrap();
    assert_eq!(again.mesh.vertices, other.mesh.vertices);
    let _ = std::fs::remove_dir_all(&d);
}
