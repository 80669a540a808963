//! NPY and NPZ: round trips of every dtype, the header layout NumPy expects,
//! hand-built headers (old 16-byte alignment, Fortran order, big-endian,
//! versions 2.0 and 3.0), ZIP archives with DEFLATE entries, comments and
//! damage, and files written by NumPy itself (`tests/data/`, made by
//! `tests/data/gen_npz.py`).

use std::path::{Path, PathBuf};

use pganeus_io::{
    npy_bytes, npz_bytes, read_npy, read_npy_bytes, read_npz, read_npz_bytes, write_npz, IoError, NpyArray, NpyData,
};

const P: &str = "mem.npz";

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

fn get<'a>(entries: &'a [(String, NpyArray)], name: &str) -> &'a NpyArray {
    &entries
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no {name}"))
        .1
}

fn sample_arrays() -> Vec<(&'static str, NpyArray)> {
    let m: Vec<f64> = (0..16).map(|i| i as f64 * 0.1 - 0.7).collect();
    vec![
        ("mat", NpyArray::f64(vec![4, 4], m)),
        (
            "vec32",
            NpyArray::new(vec![5], NpyData::F32(vec![0.1, -2.5, 3e-8, f32::MAX, 0.0])),
        ),
        (
            "bytes",
            NpyArray::new(vec![2, 3], NpyData::U8(vec![0, 1, 127, 128, 254, 255])),
        ),
        ("flags", NpyArray::new(vec![3], NpyData::Bool(vec![true, false, true]))),
        (
            "ints",
            NpyArray::new(vec![2, 2], NpyData::I64(vec![i64::MIN, -1, 0, i64::MAX])),
        ),
        ("i32", NpyArray::new(vec![3], NpyData::I32(vec![i32::MIN, 5, i32::MAX]))),
        ("scalar", NpyArray::f64(vec![], vec![std::f64::consts::PI])),
        ("empty", NpyArray::f64(vec![0, 3], vec![])),
    ]
}

/// Builds a `.npy` v1.0 file by hand with the given header text (unpadded)
/// padded so the data starts at a multiple of `align`.
fn hand_npy(header: &str, align: usize, data: &[u8]) -> Vec<u8> {
    let mut h = header.to_string();
    let pad = (align - (10 + h.len() + 1) % align) % align;
    h.push_str(&" ".repeat(pad));
    h.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(h.len() as u16).to_le_bytes());
    out.extend_from_slice(h.as_bytes());
    out.extend_from_slice(data);
    out
}

/// A minimal ZIP writer for tests: entries given as (name, method, stored bytes,
/// crc, uncompressed size), with an optional archive comment.
fn hand_zip(entries: &[(&str, u16, Vec<u8>, u32, usize)], comment: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut cd = Vec::new();
    for (name, method, data, crc, size) in entries {
        let offset = out.len() as u32;
        let fields = |v: &mut Vec<u8>| {
            v.extend_from_slice(&20u16.to_le_bytes());
            v.extend_from_slice(&0u16.to_le_bytes());
            v.extend_from_slice(&method.to_le_bytes());
            v.extend_from_slice(&[0, 0, 0x21, 0]);
            v.extend_from_slice(&crc.to_le_bytes());
            v.extend_from_slice(&(data.len() as u32).to_le_bytes());
            v.extend_from_slice(&(*size as u32).to_le_bytes());
            v.extend_from_slice(&(name.len() as u16).to_le_bytes());
            v.extend_from_slice(&0u16.to_le_bytes());
        };
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        fields(&mut out);
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(data);
        cd.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        cd.extend_from_slice(&20u16.to_le_bytes());
        fields(&mut cd);
        cd.extend_from_slice(&[0; 10]);
        cd.extend_from_slice(&offset.to_le_bytes());
        cd.extend_from_slice(name.as_bytes());
    }
    let cd_offset = out.len() as u32;
    out.extend_from_slice(&cd);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    out.extend_from_slice(&[0; 4]);
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    out.extend_from_slice(&(cd.len() as u32).to_le_bytes());
    out.extend_from_slice(&cd_offset.to_le_bytes());
    out.extend_from_slice(&(comment.len() as u16).to_le_bytes());
    out.extend_from_slice(comment);
    out
}

fn npz_err(bytes: &[u8]) -> String {
    match read_npz_bytes(bytes, Path::new(P)) {
        Err(e @ IoError::Npz { .. }) => e.to_string(),
        Err(e) => panic!("wrong error variant: {e}"),
        Ok(_) => panic!("damaged archive was accepted"),
    }
}

#[test]
fn npz_round_trip_of_every_dtype() {
    let arrays = sample_arrays();
    let refs: Vec<(&str, &NpyArray)> = arrays.iter().map(|(n, a)| (*n, a)).collect();
    let bytes = npz_bytes(&refs);
    let back = read_npz_bytes(&bytes, Path::new(P)).unwrap();
    assert_eq!(back.len(), arrays.len());
    for ((name, a), (name2, b)) in arrays.iter().zip(&back) {
        assert_eq!(name, name2, "archive order is kept");
        assert_eq!(a, b, "{name}");
    }
    assert_eq!(npz_bytes(&refs), bytes, "deterministic bytes");
}

#[test]
fn npz_round_trip_through_a_file() {
    let dir = std::env::temp_dir().join(format!("pganeus_io_npz_file_{}", std::process::id()));
    let path = dir.join("a.npz");
    let arrays = sample_arrays();
    let refs: Vec<(&str, &NpyArray)> = arrays.iter().map(|(n, a)| (*n, a)).collect();
    write_npz(&path, &refs).unwrap();
    let back = read_npz(&path).unwrap();
    assert_eq!(
        back.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(),
        refs.iter().map(|r| r.0).collect::<Vec<_>>()
    );
    // Duplicate names are refused and nothing is written.
    let dup = dir.join("dup.npz");
    let err = write_npz(&dup, &[("a", refs[0].1), ("a", refs[1].1)]).unwrap_err();
    assert!(err.to_string().contains("two arrays are named 'a'"), "{err}");
    assert!(!dup.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn npy_header_is_numpy_style_and_64_aligned() {
    for (name, a) in sample_arrays() {
        let bytes = npy_bytes(&a);
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00", "{name}: version 1.0");
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0, "{name}: data offset {} not 64-aligned", 10 + hlen);
        let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
        assert!(header.ends_with('\n'), "{name}");
        assert_eq!(bytes.len(), 10 + hlen + a.len() * header_item_size(header), "{name}");
        assert_eq!(read_npy_bytes(&bytes, Path::new("x.npy")).unwrap(), a, "{name}");
    }
    let m = NpyArray::f64(vec![4, 4], vec![0.0; 16]);
    let bytes = npy_bytes(&m);
    let header = std::str::from_utf8(&bytes[10..128]).unwrap();
    assert_eq!(
        header.trim_end(),
        "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 4), }"
    );
    let v = npy_bytes(&NpyArray::f64(vec![3], vec![0.0; 3]));
    assert!(std::str::from_utf8(&v[10..64]).unwrap().contains("'shape': (3,)"));
    let s = npy_bytes(&NpyArray::f64(vec![], vec![1.0]));
    assert!(std::str::from_utf8(&s[10..64]).unwrap().contains("'shape': ()"));
}

fn header_item_size(header: &str) -> usize {
    ["f8", "f4", "i8", "i4", "u1", "b1"]
        .iter()
        .find(|d| header.contains(*d))
        .map(|d| d[1..].parse().unwrap())
        .unwrap()
}

#[test]
fn hand_built_v1_header_with_old_16_byte_alignment() {
    let data: Vec<u8> = [1.5f64, -2.0, 0.25, 8.0, 1e-3, 7.0]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    // Old NumPy aligned to 16; also double quotes and no trailing comma.
    let bytes = hand_npy(
        "{\"descr\": \"<f8\", \"fortran_order\": False, \"shape\": (2, 3)}",
        16,
        &data,
    );
    assert_eq!(bytes.len() % 16, 0);
    assert_ne!(
        (bytes.len() - data.len()) % 64,
        0,
        "the test must not be 64-aligned by accident"
    );
    let a = read_npy_bytes(&bytes, Path::new("old.npy")).unwrap();
    assert_eq!(a, NpyArray::f64(vec![2, 3], vec![1.5, -2.0, 0.25, 8.0, 1e-3, 7.0]));

    // Keys in another order, Python 2 long integers, bytes after the data ignored.
    let mut data4: Vec<u8> = [3i32, -4].iter().flat_map(|x| x.to_le_bytes()).collect();
    data4.extend_from_slice(b"trailing");
    let bytes = hand_npy("{'shape': (2L,), 'fortran_order': False, 'descr': '<i4'}", 16, &data4);
    let a = read_npy_bytes(&bytes, Path::new("py2.npy")).unwrap();
    assert_eq!(a, NpyArray::new(vec![2], NpyData::I32(vec![3, -4])));
}

#[test]
fn fortran_order_is_transposed_to_c_order() {
    // A 2x3 array [[0, 1, 2], [3, 4, 5]] stored column by column: 0 3 1 4 2 5.
    let col_major = [0.0f64, 3.0, 1.0, 4.0, 2.0, 5.0];
    let data: Vec<u8> = col_major.iter().flat_map(|x| x.to_le_bytes()).collect();
    let bytes = hand_npy("{'descr': '<f8', 'fortran_order': True, 'shape': (2, 3), }", 64, &data);
    let a = read_npy_bytes(&bytes, Path::new("f.npy")).unwrap();
    assert_eq!(a, NpyArray::f64(vec![2, 3], vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]));

    // 3-d: element (i, j, k) = 100 i + 10 j + k, shape (2, 3, 4), stored with i fastest.
    let (n0, n1, n2) = (2, 3, 4);
    let mut stored = Vec::new();
    for k in 0..n2 {
        for j in 0..n1 {
            for i in 0..n0 {
                stored.push((100 * i + 10 * j + k) as i64);
            }
        }
    }
    let data: Vec<u8> = stored.iter().flat_map(|x| x.to_le_bytes()).collect();
    let bytes = hand_npy(
        "{'descr': '<i8', 'fortran_order': True, 'shape': (2, 3, 4), }",
        64,
        &data,
    );
    let a = read_npy_bytes(&bytes, Path::new("f3.npy")).unwrap();
    let mut expected = Vec::new();
    for i in 0..n0 {
        for j in 0..n1 {
            for k in 0..n2 {
                expected.push((100 * i + 10 * j + k) as i64);
            }
        }
    }
    assert_eq!(a, NpyArray::new(vec![2, 3, 4], NpyData::I64(expected)));
}

#[test]
fn big_endian_dtypes() {
    let data: Vec<u8> = [1.25f64, -3.5].iter().flat_map(|x| x.to_be_bytes()).collect();
    let a = read_npy_bytes(
        &hand_npy("{'descr': '>f8', 'fortran_order': False, 'shape': (2,), }", 64, &data),
        Path::new("be.npy"),
    )
    .unwrap();
    assert_eq!(a, NpyArray::f64(vec![2], vec![1.25, -3.5]));

    let data: Vec<u8> = [0.5f32, 7.0].iter().flat_map(|x| x.to_be_bytes()).collect();
    let a = read_npy_bytes(
        &hand_npy("{'descr': '>f4', 'fortran_order': False, 'shape': (2,), }", 64, &data),
        Path::new("be.npy"),
    )
    .unwrap();
    assert_eq!(a.data, NpyData::F32(vec![0.5, 7.0]));

    let data: Vec<u8> = [-2i64, 1 << 40].iter().flat_map(|x| x.to_be_bytes()).collect();
    let a = read_npy_bytes(
        &hand_npy("{'descr': '>i8', 'fortran_order': False, 'shape': (2,), }", 64, &data),
        Path::new("be.npy"),
    )
    .unwrap();
    assert_eq!(a.data, NpyData::I64(vec![-2, 1 << 40]));

    // Widened types: uint16 big-endian → i32.
    let a = read_npy_bytes(
        &hand_npy(
            "{'descr': '>u2', 'fortran_order': False, 'shape': (2,), }",
            64,
            &[0xff, 0xfe, 0, 1],
        ),
        Path::new("be.npy"),
    )
    .unwrap();
    assert_eq!(a.data, NpyData::I32(vec![0xfffe, 1]));
    assert_eq!(a.as_f64(), vec![65534.0, 1.0]);
}

#[test]
fn versions_2_and_3_are_read() {
    for major in [2u8, 3] {
        let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }          \n";
        let mut bytes = vec![0x93, b'N', b'U', b'M', b'P', b'Y', major, 0];
        bytes.extend_from_slice(&(header.len() as u32).to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        bytes.extend_from_slice(&1.0f32.to_le_bytes());
        bytes.extend_from_slice(&2.0f32.to_le_bytes());
        let a = read_npy_bytes(&bytes, Path::new("v.npy")).unwrap();
        assert_eq!(a.data, NpyData::F32(vec![1.0, 2.0]), "version {major}");
    }
    let mut bytes = npy_bytes(&NpyArray::f64(vec![1], vec![1.0]));
    bytes[6] = 4;
    let msg = read_npy_bytes(&bytes, Path::new("v4.npy")).unwrap_err().to_string();
    assert!(msg.contains("v4.npy") && msg.contains("version 4.0"), "{msg}");
}

#[test]
fn bad_npy_files_are_errors() {
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"PK\x03\x04 not npy".to_vec(), "bad magic"),
        (b"\x93NUMPY\x01".to_vec(), "truncated"),
        (
            hand_npy(
                "{'descr': '<c16', 'fortran_order': False, 'shape': (1,), }",
                64,
                &[0; 16],
            ),
            "'<c16' is not supported",
        ),
        (
            hand_npy(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }",
                64,
                &[0; 16],
            ),
            "truncated",
        ),
        (
            hand_npy("{'descr': '<f8', 'shape': (1,), }", 64, &[0; 8]),
            "no 'fortran_order'",
        ),
        (
            hand_npy(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (1, x), }",
                64,
                &[0; 8],
            ),
            "bad header",
        ),
        (hand_npy("[1, 2]", 64, &[]), "expected a dict"),
        (
            hand_npy("{'descr': '<f8', 'fortran_order': 'no', 'shape': (1,), }", 64, &[0; 8]),
            "wrong type",
        ),
        (
            hand_npy(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (100000000000, 100000000000, 100000000000), }",
                64,
                &[],
            ),
            "too large",
        ),
    ];
    for (bytes, want) in cases {
        let msg = read_npy_bytes(&bytes, Path::new("bad.npy")).unwrap_err().to_string();
        assert!(
            msg.contains("bad.npy") && msg.contains(want),
            "expected '{want}' in: {msg}"
        );
    }
    // Every truncation of a good file is an error, never a panic.
    let good = npy_bytes(&NpyArray::f64(vec![2, 2], vec![1.0, 2.0, 3.0, 4.0]));
    for len in 0..good.len() {
        assert!(
            read_npy_bytes(&good[..len], Path::new("cut.npy")).is_err(),
            "cut at {len}"
        );
    }
}

#[test]
fn deflate_entry_is_inflated() {
    let a = NpyArray::f64(vec![8, 8], (0..64).map(|i| (i % 5) as f64).collect());
    let raw = npy_bytes(&a);
    let deflated = miniz_oxide::deflate::compress_to_vec(&raw, 6);
    assert!(deflated.len() < raw.len());
    let b = NpyArray::new(vec![2], NpyData::U8(vec![4, 2]));
    let raw_b = npy_bytes(&b);
    let zip = hand_zip(
        &[
            ("a.npy", 8, deflated, crc32fast::hash(&raw), raw.len()),
            ("b.npy", 0, raw_b.clone(), crc32fast::hash(&raw_b), raw_b.len()),
            ("readme.txt", 0, b"hi".to_vec(), crc32fast::hash(b"hi"), 2),
        ],
        b"",
    );
    let entries = read_npz_bytes(&zip, Path::new(P)).unwrap();
    assert_eq!(entries.len(), 2, "non-.npy entries are skipped");
    assert_eq!(get(&entries, "a"), &a);
    assert_eq!(get(&entries, "b"), &b);
}

#[test]
fn archive_comment_is_accepted() {
    let a = NpyArray::f64(vec![1], vec![9.0]);
    let raw = npy_bytes(&a);
    // The comment even contains an end-of-central-directory signature.
    let zip = hand_zip(
        &[("a.npy", 0, raw.clone(), crc32fast::hash(&raw), raw.len())],
        b"note PK\x05\x06 inside",
    );
    let entries = read_npz_bytes(&zip, Path::new(P)).unwrap();
    assert_eq!(entries, vec![("a".to_string(), a)]);
}

#[test]
fn bad_crc_is_an_error() {
    let a = NpyArray::f64(vec![2], vec![1.0, 2.0]);
    let mut bytes = npz_bytes(&[("a", &a)]);
    // Flip one bit of the data: the last byte of the last float, in the entry.
    let at = bytes.windows(8).position(|w| w == 2.0f64.to_le_bytes()).unwrap() + 7;
    bytes[at] ^= 0x01;
    let msg = npz_err(&bytes);
    assert!(
        msg.contains("mem.npz") && msg.contains("a.npy") && msg.contains("checksum"),
        "{msg}"
    );

    // A deflate entry whose stored CRC is wrong.
    let raw = npy_bytes(&a);
    let zip = hand_zip(
        &[(
            "a.npy",
            8,
            miniz_oxide::deflate::compress_to_vec(&raw, 1),
            0x1234_5678,
            raw.len(),
        )],
        b"",
    );
    assert!(npz_err(&zip).contains("checksum"));
}

#[test]
fn truncated_or_damaged_zip_is_an_error() {
    let arrays = sample_arrays();
    let refs: Vec<(&str, &NpyArray)> = arrays.iter().map(|(n, a)| (*n, a)).collect();
    let bytes = npz_bytes(&refs);
    for len in [0, 3, 30, bytes.len() / 2, bytes.len() - 23, bytes.len() - 1] {
        let msg = npz_err(&bytes[..len]);
        assert!(msg.contains("mem.npz"), "{msg}");
    }
    assert!(npz_err(&bytes[..bytes.len() / 2]).contains("truncated"));
    // Every truncation: error or (never) panic.
    for len in 0..bytes.len() {
        assert!(read_npz_bytes(&bytes[..len], Path::new(P)).is_err(), "cut at {len}");
    }
    // Missing EOCD.
    assert!(npz_err(b"just some bytes that are long enough to scan").contains("not a ZIP archive"));
    // Central directory offset pointing outside the file.
    let mut bad = bytes.clone();
    let n = bad.len();
    bad[n - 6..n - 2].copy_from_slice(&u32::MAX.wrapping_sub(7).to_le_bytes());
    assert!(npz_err(&bad).contains("Invalid CDFH offset in EOCD"));
    // Unsupported compression method.
    let raw = npy_bytes(&arrays[0].1);
    let zip = hand_zip(&[("a.npy", 12, raw.clone(), crc32fast::hash(&raw), raw.len())], b"");
    assert!(npz_err(&zip).contains("entry a.npy: unsupported Zip archive: Compression method not supported"));
    // Garbage DEFLATE data.
    let zip = hand_zip(&[("a.npy", 8, vec![0xff; 40], 0, raw.len())], b"");
    assert!(npz_err(&zip).contains("entry a.npy: corrupt deflate stream"));
    // A bad .npy inside names the entry.
    let zip = hand_zip(&[("x.npy", 0, b"nope".to_vec(), crc32fast::hash(b"nope"), 4)], b"");
    assert!(npz_err(&zip).contains("entry x.npy"));
}

#[test]
fn as_f64_converts_every_dtype() {
    assert_eq!(
        NpyArray::new(vec![2], NpyData::Bool(vec![true, false])).as_f64(),
        vec![1.0, 0.0]
    );
    assert_eq!(
        NpyArray::new(vec![2], NpyData::U8(vec![3, 255])).as_f64(),
        vec![3.0, 255.0]
    );
    assert_eq!(NpyArray::new(vec![1], NpyData::I64(vec![-7])).as_f64(), vec![-7.0]);
    assert_eq!(NpyArray::new(vec![1], NpyData::F32(vec![0.5])).as_f64(), vec![0.5]);
    let s = NpyArray::f64(vec![], vec![2.0]);
    assert_eq!((s.len(), s.is_empty()), (1, false));
    assert!(NpyArray::f64(vec![3, 0], vec![]).is_empty());
}

#[test]
#[should_panic(expected = "needs")]
fn shape_mismatch_panics_in_the_constructor() {
    let _ = NpyArray::f64(vec![2, 2], vec![1.0; 3]);
}

// ---- files written by NumPy (tests/data/gen_npz.py) ----

#[test]
fn numpy_savez_cameras_fixture() {
    let entries = read_npz(&data_dir().join("cameras_sphere.npz")).unwrap();
    assert_eq!(entries.len(), 18);
    let k = [[100.0, 0.0, 32.0], [0.0, 100.0, 24.0], [0.0, 0.0, 1.0]];
    for i in 0..3 {
        let (c, s) = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0)][i];
        let r = [[c, -s, 0.0], [0.0, 0.0, -1.0], [s, c, 0.0]];
        let t = [0.0, 0.0, 4.0];
        let mut expected = vec![0.0; 16];
        for row in 0..3 {
            for col in 0..3 {
                expected[4 * row + col] = (0..3).map(|m| k[row][m] * r[m][col]).sum();
            }
            expected[4 * row + 3] = (0..3).map(|m| k[row][m] * t[m]).sum();
        }
        expected[15] = 1.0;
        let w = get(&entries, &format!("world_mat_{i}"));
        assert_eq!(w, &NpyArray::f64(vec![4, 4], expected.clone()), "world_mat_{i}");
        let s = get(&entries, &format!("scale_mat_{i}"));
        let scale = vec![
            0.5, 0.0, 0.0, 0.25, 0.0, 0.5, 0.0, -0.125, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0, 0.0, 1.0,
        ];
        assert_eq!(s, &NpyArray::f64(vec![4, 4], scale), "scale_mat_{i}");
        // world_mat_inv_i @ world_mat_i = I.
        let inv = get(&entries, &format!("world_mat_inv_{i}")).as_f64();
        for row in 0..4 {
            for col in 0..4 {
                let x: f64 = (0..4).map(|m| inv[4 * row + m] * expected[4 * m + col]).sum();
                assert!((x - (row == col) as u8 as f64).abs() < 1e-12);
            }
        }
        assert_eq!(get(&entries, &format!("camera_mat_{i}")).shape, vec![4, 4]);
    }
}

#[test]
fn numpy_savez_compressed_fixture() {
    let e = read_npz(&data_dir().join("compressed.npz")).unwrap();
    assert_eq!(e.len(), 11);
    assert_eq!(
        get(&e, "f8"),
        &NpyArray::f64(vec![3, 4], (0..12).map(|i| i as f64 * 0.5).collect())
    );
    assert_eq!(
        get(&e, "f4").data,
        NpyData::F32((0..7).map(|i| i as f32 * 0.25).collect())
    );
    assert_eq!(
        get(&e, "i8"),
        &NpyArray::new(vec![2, 2], NpyData::I64(vec![-3, 1 << 40, 7, -(1 << 50)]))
    );
    assert_eq!(get(&e, "i4").data, NpyData::I32(vec![1, -2, 3]));
    assert_eq!(get(&e, "u1").data, NpyData::U8((0..=255).collect()));
    assert_eq!(get(&e, "b1").data, NpyData::Bool(vec![true, false, true, true]));
    assert_eq!(get(&e, "scalar"), &NpyArray::f64(vec![], vec![2.5]));
    assert_eq!(get(&e, "big"), &NpyArray::f64(vec![3], vec![1.5, -2.25, 1e300]));
    assert_eq!(
        get(&e, "big_i4"),
        &NpyArray::new(vec![2, 2], NpyData::I32(vec![1, -2, 65536, 7]))
    );
    assert_eq!(
        get(&e, "fortran"),
        &NpyArray::f64(vec![2, 3, 4], (0..24).map(|i| i as f64).collect())
    );
    assert_eq!(get(&e, "empty"), &NpyArray::f64(vec![0, 3], vec![]));
}

#[test]
fn numpy_save_fortran_fixture() {
    let a = read_npy(&data_dir().join("fortran.npy")).unwrap();
    assert_eq!(a, NpyArray::new(vec![2, 3], NpyData::I32(vec![0, 1, 2, 3, 4, 5])));
}
