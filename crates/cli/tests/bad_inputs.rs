//! Meshes with a coordinate that is not a number are refused by every command that reads meshes, naming
//! the file and the vertex (`compare-mesh` used to panic on one).

mod common;
use common::bin;

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
        let runs: Vec<Vec<String>> = vec![
            vec![
                "compare-mesh".into(),
                bad.display().to_string(),
                good.display().to_string(),
            ],
            vec![
                "compare-mesh".into(),
                good.display().to_string(),
                bad.display().to_string(),
            ],
            vec![
                "bake".into(),
                bad.display().to_string(),
                "--out".into(),
                d.join("x.sdf").display().to_string(),
            ],
        ];
        for args in runs {
            let o = bin().args(&args).output().unwrap();
            let text = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {text}");
            assert!(text.contains(name) && text.contains("vertex 1"), "{args:?}: {text}");
            assert!(!text.contains("panicked"), "{text}");
        }
    }
    assert!(!d.join("x.sdf").exists());
    let _ = std::fs::remove_dir_all(&d);
}
