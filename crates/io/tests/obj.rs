//! OBJ reading: every face-corner form, relative indices, fan triangulation,
//! ignored statements, and errors with line numbers.

use std::path::Path;

use pganeus_io::{read_obj, read_obj_bytes, IoError};

fn obj_err(text: &str) -> String {
    match read_obj_bytes(text.as_bytes(), Path::new("m.obj")) {
        Err(e @ IoError::Obj { .. }) => e.to_string(),
        other => panic!("expected an OBJ error, got {other:?}"),
    }
}

#[test]
fn corner_forms_negative_indices_and_polygons() {
    let text = "# a comment\n\
mtllib m.mtl\n\
o thing\n\
g part\n\
s 1\n\
usemtl red\n\
v 0 0 0\n\
v 1 0 0 1.0\n\
v 1 1 0 0.5 0.5 0.5\n\
v 0 1 0\n\
vt 0 0\n\
vt 1 0\n\
vt 1 1\n\
vn 0 0 1\n\
f 1/1/1 2/2/1 3/3/1\n\
f 1//1 3//1 4//1  # trailing comment\n\
f -4/1 -3/2 -2/3 -1/1\n\
v 2 0 0\n\
f -1 2 3\n\
f 1 2 3 4 5\n";
    let m = read_obj_bytes(text.as_bytes(), Path::new("m.obj")).unwrap();
    assert_eq!(
        m.vertices,
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0]
        ]
    );
    assert_eq!(
        m.faces,
        vec![
            [0, 1, 2],
            [0, 2, 3],
            // quad from relative indices, fan-triangulated
            [0, 1, 2],
            [0, 2, 3],
            // -1 is the vertex just read, not the 4th
            [4, 1, 2],
            // pentagon
            [0, 1, 2],
            [0, 2, 3],
            [0, 3, 4]
        ]
    );
}

#[test]
fn crlf_and_forward_reference_read() {
    let text = "f 1 2 3\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\n";
    let m = read_obj_bytes(text.as_bytes(), Path::new("m.obj")).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2]]);
    assert_eq!(m.vertices[2], [0.0, 1.0, 0.0]);
}

#[test]
fn errors_name_file_and_line() {
    let msg = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    assert!(
        msg.contains("m.obj") && msg.contains("line 4") && msg.contains("out of range"),
        "{msg}"
    );

    let msg = obj_err("v 0 0 0\nv 1 0 0\nf -1 -2 -3\n");
    assert!(msg.contains("line 3") && msg.contains("-3"), "{msg}");

    let msg = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 0 1 2\n");
    assert!(msg.contains("line 5") && msg.contains("index 0"), "{msg}");

    let msg = obj_err("v 0 0\n");
    assert!(msg.contains("line 1") && msg.contains("3 coordinates"), "{msg}");

    let msg = obj_err("v 0 zero 0\n");
    assert!(msg.contains("`zero`"), "{msg}");

    let msg = obj_err("v 0 0 0\nv 1 0 0\nf 1 2\n");
    assert!(msg.contains("line 3") && msg.contains("at least 3"), "{msg}");

    let msg = obj_err("v 0 0 0\nf 1 a/2 1\n");
    assert!(msg.contains("`a/2`"), "{msg}");
}

#[test]
fn read_from_file_and_missing_file() {
    let dir = std::env::temp_dir().join(format!("pganeus_io_obj_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("tri.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let m = read_obj(&path).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2]]);
    let err = read_obj(&dir.join("missing.obj")).unwrap_err();
    assert!(matches!(err, IoError::Open { .. }), "{err:?}");
    assert!(err.to_string().contains("missing.obj"));
    std::fs::remove_dir_all(&dir).unwrap();
}
