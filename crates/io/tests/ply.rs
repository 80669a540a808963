//! PLY reading and writing: round trips, hand-written files in every encoding,
//! unknown elements and properties, and clean errors on broken files.

use std::path::Path;

use geom::TriMesh;
use pganeus_io::{
    read_ply, read_ply_bytes, write_ply, write_ply_bytes, write_ply_bytes_with, IoError, PlyEncoding, PlyMesh,
    PlyWriteOptions,
};

const P: &str = "mem.ply";

fn sample() -> PlyMesh {
    // Values that f32 cannot hold exactly, so the tolerance is exercised.
    let vertices = vec![
        [0.1, -0.2, 0.3],
        [1.0 / 3.0, 2.0 / 3.0, -1e-7],
        [123.456789, -0.000123, 7.0],
        [-5.5, 0.0, 1e3],
    ];
    PlyMesh {
        mesh: TriMesh::new(vertices, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]),
        colors: Some(vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [12, 34, 56]]),
        normals: Some(vec![
            [0.0, 0.0, 1.0],
            [0.6, 0.8, 0.0],
            [-1.0, 0.0, 0.0],
            [0.267_261_24, 0.534_522_5, 0.801_783_7],
        ]),
    }
}

fn assert_close_f32(a: &PlyMesh, b: &PlyMesh) {
    assert_eq!(a.mesh.vertices.len(), b.mesh.vertices.len());
    for (p, q) in a.mesh.vertices.iter().zip(&b.mesh.vertices) {
        for k in 0..3 {
            let tol = 1e-7 * p[k].abs().max(1e-30);
            assert!((p[k] - q[k]).abs() <= tol, "{p:?} vs {q:?}: beyond f32 precision");
        }
    }
    assert_eq!(a.mesh.faces, b.mesh.faces);
    assert_eq!(a.colors, b.colors);
    assert_eq!(a.normals, b.normals);
}

fn ply_err(r: pganeus_io::Result<PlyMesh>) -> String {
    match r {
        Err(e @ IoError::Ply { .. }) => e.to_string(),
        other => panic!("expected a PLY error, got {other:?}"),
    }
}

#[test]
fn round_trip_binary() {
    let m = sample();
    let bytes = write_ply_bytes(&m, PlyEncoding::BinaryLittleEndian);
    assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    let back = read_ply_bytes(&bytes, Path::new(P)).unwrap();
    assert_close_f32(&m, &back);
}

#[test]
fn round_trip_ascii() {
    let m = sample();
    let bytes = write_ply_bytes(&m, PlyEncoding::Ascii);
    assert!(bytes.starts_with(b"ply\nformat ascii 1.0\n"));
    let back = read_ply_bytes(&bytes, Path::new(P)).unwrap();
    assert_close_f32(&m, &back);
}

#[test]
fn round_trip_f64_positions_is_exact() {
    let m = sample();
    for encoding in [PlyEncoding::BinaryLittleEndian, PlyEncoding::Ascii] {
        let opts = PlyWriteOptions {
            encoding,
            positions_f64: true,
        };
        let bytes = write_ply_bytes_with(&m, &opts);
        let back = read_ply_bytes(&bytes, Path::new(P)).unwrap();
        assert_eq!(back, m, "{encoding:?}");
    }
}

#[test]
fn round_trip_plain_mesh_and_point_cloud() {
    let mesh = PlyMesh::from_mesh(sample().mesh);
    let back = read_ply_bytes(&write_ply_bytes(&mesh, PlyEncoding::BinaryLittleEndian), Path::new(P)).unwrap();
    assert_eq!(back.colors, None);
    assert_eq!(back.normals, None);
    assert_eq!(back.mesh.faces, mesh.mesh.faces);

    let mut cloud = sample();
    cloud.mesh.faces.clear();
    let bytes = write_ply_bytes(&cloud, PlyEncoding::Ascii);
    let text = String::from_utf8(bytes.clone()).unwrap();
    assert!(!text.contains("element face"), "{text}");
    let back = read_ply_bytes(&bytes, Path::new(P)).unwrap();
    assert!(back.mesh.faces.is_empty());
    assert_eq!(back.mesh.vertices.len(), 4);
}

#[test]
fn write_and_read_file() {
    let dir = tempdir("ply_file");
    let path = dir.join("sub/mesh.ply");
    let m = sample();
    write_ply(&path, &m, PlyEncoding::BinaryLittleEndian).unwrap();
    assert_close_f32(&m, &read_ply(&path).unwrap());

    // Mismatched colours are refused before anything is written.
    let mut bad = m.clone();
    bad.colors.as_mut().unwrap().pop();
    let before = std::fs::read(&path).unwrap();
    let err = write_ply(&path, &bad, PlyEncoding::Ascii).unwrap_err();
    assert!(matches!(err, IoError::Invalid { ref field, .. } if field == "colors"));
    assert_eq!(std::fs::read(&path).unwrap(), before);

    let missing = dir.join("nope.ply");
    let err = read_ply(&missing).unwrap_err();
    assert!(matches!(err, IoError::Open { .. }));
    assert!(err.to_string().contains("nope.ply"), "{err}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn ascii_quad_with_unknown_element_and_list() {
    let text = "ply\r\n\
format ascii 1.0\r\n\
comment made by hand\r\n\
obj_info nothing useful\r\n\
element vertex 4\r\n\
property float x\r\n\
property float y\r\n\
property float z\r\n\
property float confidence\r\n\
property uchar red\r\n\
property uchar green\r\n\
property uchar blue\r\n\
element edge 2\r\n\
property list uchar int vertex_pair\r\n\
property uchar flags\r\n\
element face 1\r\n\
property list uchar int vertex_index\r\n\
property list uchar float texcoord\r\n\
end_header\r\n\
0 0 0 0.5 10 20 30\r\n\
1 0 0 0.5 40 50 60\r\n\
1 1 0 0.5 70 80 90\r\n\
0 1 0 0.5 100 110 120\r\n\
2 0 1 7\r\n\
3 1 2 3 9\r\n\
4 0 1 2 3 8 0 0 1 0 1 1 0 1\r\n";
    let m = read_ply_bytes(text.as_bytes(), Path::new(P)).unwrap();
    assert_eq!(
        m.mesh.vertices,
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]
    );
    assert_eq!(m.mesh.faces, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.colors.unwrap()[3], [100, 110, 120]);
    assert_eq!(m.normals, None);
}

#[test]
fn big_endian_by_hand_faces_first_mixed_types() {
    // Faces before vertices; x double, y float, z short; an unknown scalar
    // and an unknown list on both elements; float colours; uint indices; one quad.
    let header = "ply\n\
format binary_big_endian 1.0\n\
element face 2\n\
property uint16 material\n\
property list uint8 uint32 vertex_indices\n\
property list int16 double weights\n\
element vertex 4\n\
property double x\n\
property float32 y\n\
property int16 z\n\
property list uchar int neighbours\n\
property float nx\n\
property float ny\n\
property float nz\n\
property float red\n\
property float green\n\
property float blue\n\
end_header\n";
    let mut b = header.as_bytes().to_vec();
    // face 0: triangle 2 1 0, one weight
    b.extend(7u16.to_be_bytes());
    b.push(3);
    for i in [2u32, 1, 0] {
        b.extend(i.to_be_bytes());
    }
    b.extend(1i16.to_be_bytes());
    b.extend(0.25f64.to_be_bytes());
    // face 1: quad 0 1 2 3, no weights
    b.extend(8u16.to_be_bytes());
    b.push(4);
    for i in [0u32, 1, 2, 3] {
        b.extend(i.to_be_bytes());
    }
    b.extend(0i16.to_be_bytes());
    let verts: [(f64, f32, i16); 4] = [(0.5, -1.5, 3), (1e-3, 2.25, -4), (-7.0, 0.0, 0), (3.0, 3.0, 300)];
    for (k, (x, y, z)) in verts.iter().enumerate() {
        b.extend(x.to_be_bytes());
        b.extend(y.to_be_bytes());
        b.extend(z.to_be_bytes());
        b.push(k as u8); // neighbour count
        for j in 0..k as i32 {
            b.extend(j.to_be_bytes());
        }
        for n in [0.0f32, 0.0, 1.0] {
            b.extend(n.to_be_bytes());
        }
        for c in [1.0f32, 0.5, 0.0] {
            b.extend(c.to_be_bytes());
        }
    }
    let m = read_ply_bytes(&b, Path::new(P)).unwrap();
    assert_eq!(
        m.mesh.vertices,
        vec![
            [0.5, -1.5, 3.0],
            [1e-3, 2.25, -4.0],
            [-7.0, 0.0, 0.0],
            [3.0, 3.0, 300.0]
        ]
    );
    assert_eq!(m.mesh.faces, vec![[2, 1, 0], [0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.normals.unwrap(), vec![[0.0, 0.0, 1.0]; 4]);
    assert_eq!(m.colors.unwrap(), vec![[255, 128, 0]; 4]);
}

#[test]
fn all_scalar_type_names_little_endian() {
    // One vertex per pair of names; x has the type, y and z are float.
    let types: [(&str, Vec<u8>); 16] = [
        ("char", (-5i8).to_le_bytes().to_vec()),
        ("int8", (-5i8).to_le_bytes().to_vec()),
        ("uchar", 5u8.to_le_bytes().to_vec()),
        ("uint8", 5u8.to_le_bytes().to_vec()),
        ("short", (-500i16).to_le_bytes().to_vec()),
        ("int16", (-500i16).to_le_bytes().to_vec()),
        ("ushort", 50000u16.to_le_bytes().to_vec()),
        ("uint16", 50000u16.to_le_bytes().to_vec()),
        ("int", (-70000i32).to_le_bytes().to_vec()),
        ("int32", (-70000i32).to_le_bytes().to_vec()),
        ("uint", 3_000_000_000u32.to_le_bytes().to_vec()),
        ("uint32", 3_000_000_000u32.to_le_bytes().to_vec()),
        ("float", 0.5f32.to_le_bytes().to_vec()),
        ("float32", 0.5f32.to_le_bytes().to_vec()),
        ("double", 0.1f64.to_le_bytes().to_vec()),
        ("float64", 0.1f64.to_le_bytes().to_vec()),
    ];
    let expect = [
        -5.0, -5.0, 5.0, 5.0, -500.0, -500.0, 50000.0, 50000.0, -70000.0, -70000.0, 3e9, 3e9, 0.5, 0.5, 0.1, 0.1,
    ];
    for ((name, bytes), want) in types.iter().zip(expect) {
        let mut b = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex 1\n\
             property {name} x\nproperty float y\nproperty float z\nend_header\n"
        )
        .into_bytes();
        b.extend(bytes);
        b.extend(1.0f32.to_le_bytes());
        b.extend(2.0f32.to_le_bytes());
        let m = read_ply_bytes(&b, Path::new(P)).unwrap();
        assert_eq!(m.mesh.vertices, vec![[want, 1.0, 2.0]], "type {name}");
        assert!(m.mesh.faces.is_empty());
    }
}

#[test]
fn truncated_binary_is_an_error_at_every_length() {
    let bytes = write_ply_bytes(&sample(), PlyEncoding::BinaryLittleEndian);
    for len in 0..bytes.len() {
        let r = read_ply_bytes(&bytes[..len], Path::new("cut.ply"));
        let msg = ply_err(r);
        assert!(msg.contains("cut.ply"), "{msg}");
    }
    let body = bytes.len() - 5;
    let msg = ply_err(read_ply_bytes(&bytes[..body], Path::new("cut.ply")));
    assert!(msg.contains("ends early") && msg.contains("face"), "{msg}");
}

#[test]
fn truncated_ascii_is_an_error() {
    let bytes = write_ply_bytes(&sample(), PlyEncoding::Ascii);
    let text = String::from_utf8(bytes).unwrap();
    let cut = text.trim_end().rsplit_once(' ').unwrap().0;
    let msg = ply_err(read_ply_bytes(cut.as_bytes(), Path::new(P)));
    assert!(msg.contains("ends early"), "{msg}");
}

#[test]
fn bad_headers_are_errors() {
    let cases: [(&str, &str); 7] = [
        ("plx\nformat ascii 1.0\nend_header\n", "first line"),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
            "end_header",
        ),
        (
            "ply\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
            "format",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
            "unknown type",
        ),
        ("ply\nformat ascii 1.0\nelement vertex lots\nend_header\n", "count"),
        (
            "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
            "before any element",
        ),
        ("ply\nformat utf9 1.0\nend_header\n", "unknown format"),
    ];
    for (text, want) in cases {
        let msg = ply_err(read_ply_bytes(text.as_bytes(), Path::new(P)));
        assert!(msg.contains(want), "{want:?} not in {msg:?}");
    }
}

#[test]
fn missing_coordinate_and_bad_index_are_errors() {
    let no_z = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n";
    let msg = ply_err(read_ply_bytes(no_z.as_bytes(), Path::new(P)));
    assert!(msg.contains("`z`"), "{msg}");

    let out_of_range =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n";
    let msg = ply_err(read_ply_bytes(out_of_range.as_bytes(), Path::new(P)));
    assert!(msg.contains("out of range") && msg.contains("face"), "{msg}");

    let negative = out_of_range.replace("3 0 1 3", "3 0 1 -1");
    let msg = ply_err(read_ply_bytes(negative.as_bytes(), Path::new(P)));
    assert!(msg.contains("out of range"), "{msg}");

    let not_a_number = out_of_range.replace("1 0 0\n", "1 zero 0\n");
    let msg = ply_err(read_ply_bytes(not_a_number.as_bytes(), Path::new(P)));
    assert!(msg.contains("`zero` is not a number"), "{msg}");
}

#[test]
fn huge_counts_in_a_short_file_fail_without_allocating() {
    let text = "ply\nformat binary_little_endian 1.0\nelement vertex 4294967295\n\
property float x\nproperty float y\nproperty float z\nelement face 18446744073709551615\n\
property list uint uint vertex_indices\nend_header\n\x01\x02";
    let msg = ply_err(read_ply_bytes(text.as_bytes(), Path::new(P)));
    assert!(msg.contains("ends early"), "{msg}");

    let too_many = text.replace("vertex 4294967295", "vertex 18446744073709551615");
    let msg = ply_err(read_ply_bytes(too_many.as_bytes(), Path::new(P)));
    assert!(msg.contains("32-bit"), "{msg}");
}

fn tempdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("pganeus_io_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn a_vertex_that_is_not_finite_is_refused_by_name_in_ply_and_obj() {
    let ply = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\nnan 0 0\n";
    match pganeus_io::read_ply_bytes(ply, std::path::Path::new("p.ply")) {
        Err(pganeus_io::IoError::Invalid { field, .. }) => assert_eq!(field, "vertex 1"),
        other => panic!("{other:?}"),
    }
    match pganeus_io::read_obj_bytes(b"v 0 0 0\nv 0 inf 0\nv 0 0 1\nf 1 2 3\n", std::path::Path::new("o.obj")) {
        Err(pganeus_io::IoError::Invalid { field, .. }) => assert_eq!(field, "vertex 1"),
        other => panic!("{other:?}"),
    }
}
