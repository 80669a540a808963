//! Safetensors: round trips of every dtype with metadata, the byte layout of
//! the spec (hand-built files, header padding, alignment), damage of every
//! kind (truncation at every length, bad JSON, overlapping offsets, gaps,
//! wrong lengths) giving `IoError::Safetensors` and never a panic, and a file
//! written by the official Python package (`tests/data/official.safetensors`,
//! made by `tests/data/gen_safetensors.py`).

use std::path::{Path, PathBuf};

use pganeus_io::{
    read_safetensors, read_safetensors_bytes, safetensors_bytes, write_safetensors, IoError, SafeTensors, Tensor,
    TensorData, TensorError,
};

const P: &str = "mem.safetensors";

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

fn sample() -> SafeTensors {
    let mut st = SafeTensors::new();
    st.metadata.insert("format".into(), "pganeus".into());
    st.metadata
        .insert("config".into(), "{\"lr\": 0.01, \"quote\": \"\\\"\"}".into());
    st.metadata.insert("ünïcode".into(), "ok ✓".into());
    st.insert(
        "a.weight",
        Tensor::f32(vec![2, 3], vec![0.1, -2.5, 3e-8, f32::MAX, 0.0, -0.0]),
    );
    st.insert(
        "b.bias",
        Tensor::f64(vec![3], vec![std::f64::consts::PI, f64::MIN_POSITIVE, -1e300]),
    );
    st.insert("mask", Tensor::new(vec![2, 2, 1], TensorData::U8(vec![0, 1, 128, 255])));
    st.insert("step", Tensor::new(vec![], TensorData::I64(vec![i64::MIN])));
    st.insert(
        "counts",
        Tensor::new(vec![4], TensorData::I64(vec![-1, 0, 1, i64::MAX])),
    );
    st.insert("index", Tensor::new(vec![3], TensorData::U32(vec![0, 7, u32::MAX])));
    st.insert("odd", Tensor::new(vec![3], TensorData::U8(vec![9, 8, 7])));
    st.insert("empty", Tensor::f32(vec![0, 4], vec![]));
    st
}

/// A file from its header text (padded here with spaces to a multiple of 8) and buffer.
fn hand_file(header: &str, buffer: &[u8]) -> Vec<u8> {
    let mut h = header.to_string();
    let pad = (8 - h.len() % 8) % 8;
    h.push_str(&" ".repeat(pad));
    let mut out = (h.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(h.as_bytes());
    out.extend_from_slice(buffer);
    out
}

/// The message of an `IoError::Safetensors` about `P`; panics on any other outcome.
fn err_msg(bytes: &[u8]) -> String {
    match read_safetensors_bytes(bytes, Path::new(P)) {
        Err(IoError::Safetensors { path, msg }) => {
            assert_eq!(path, Path::new(P));
            msg
        }
        other => panic!("expected a safetensors error, got {other:?}"),
    }
}

#[test]
fn round_trip_every_dtype_and_metadata() {
    let st = sample();
    let bytes = safetensors_bytes(&st);
    let back = read_safetensors_bytes(&bytes, Path::new(P)).unwrap();
    // -0.0 == 0.0, so compare bit patterns of the floats too.
    assert_eq!(back, st);
    let bits = |s: &SafeTensors| {
        s.get_f32("a.weight")
            .unwrap()
            .iter()
            .map(|x| x.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&back), bits(&st));

    let dir = std::env::temp_dir().join(format!("pganeus-safetensors-{}", std::process::id()));
    let path = dir.join("sub/ckpt.safetensors");
    write_safetensors(&path, &st).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
    assert_eq!(read_safetensors(&path).unwrap(), st);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn layout_follows_the_spec() {
    let bytes = safetensors_bytes(&sample());
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    assert_eq!(n % 8, 0, "header padded to a multiple of 8");
    let header = std::str::from_utf8(&bytes[8..8 + n]).unwrap();
    assert!(header.starts_with("{\"__metadata__\":{"), "{header}");
    let json: serde_json::Value = serde_json::from_str(header).unwrap();
    // Every tensor starts at a multiple of its element size, wide dtypes first.
    let mut spans = Vec::new();
    for (name, v) in json.as_object().unwrap() {
        if name == "__metadata__" {
            continue;
        }
        let size = match v["dtype"].as_str().unwrap() {
            "F64" | "I64" => 8,
            "F32" | "U32" => 4,
            _ => 1,
        };
        let b = v["data_offsets"][0].as_u64().unwrap();
        let e = v["data_offsets"][1].as_u64().unwrap();
        assert_eq!(b % size, 0, "{name} misaligned at {b}");
        spans.push((b, e));
    }
    spans.sort();
    assert_eq!(spans.last().unwrap().1 as usize, bytes.len() - 8 - n);
}

#[test]
fn writing_is_deterministic_whatever_the_insertion_order() {
    let a = sample();
    let mut b = SafeTensors::new();
    for (k, v) in a.metadata.iter().rev() {
        b.metadata.insert(k.clone(), v.clone());
    }
    for (k, v) in a.tensors.iter().rev() {
        b.insert(k.clone(), v.clone());
    }
    assert_eq!(safetensors_bytes(&a), safetensors_bytes(&b));
}

#[test]
fn empty_file_without_metadata() {
    let st = SafeTensors::new();
    let bytes = safetensors_bytes(&st);
    assert_eq!(&bytes[8..], b"{}      ");
    assert_eq!(read_safetensors_bytes(&bytes, Path::new(P)).unwrap(), st);
}

#[test]
fn hand_crafted_file_reads() {
    let mut buffer = Vec::new();
    for x in [1.0f64, -2.0] {
        buffer.extend_from_slice(&x.to_le_bytes());
    }
    for x in [0.5f32, 1.5, -3.0, 4.0] {
        buffer.extend_from_slice(&x.to_le_bytes());
    }
    buffer.extend_from_slice(&42u32.to_le_bytes());
    buffer.extend_from_slice(&[5u8, 6]);
    // Keys in any order, whitespace, offsets not in key order.
    let header = r#"{ "w": {"shape": [2, 2], "dtype": "F32", "data_offsets": [16, 32]},
        "__metadata__": {"k": "v"},
        "d": {"dtype": "F64", "shape": [2], "data_offsets": [0, 16]},
        "u": {"dtype": "U32", "shape": [], "data_offsets": [32, 36]},
        "b": {"dtype": "U8", "shape": [1, 2], "data_offsets": [36, 38]} }"#;
    let st = read_safetensors_bytes(&hand_file(header, &buffer), Path::new(P)).unwrap();
    assert_eq!(st.metadata.get("k").map(String::as_str), Some("v"));
    assert_eq!(st.get_f64("d").unwrap(), &[1.0, -2.0]);
    assert_eq!(st.get_f32("w").unwrap(), &[0.5, 1.5, -3.0, 4.0]);
    assert_eq!(st.shape("w").unwrap(), &[2, 2]);
    assert_eq!(st.get_u32("u").unwrap(), &[42]);
    assert_eq!(st.get_u8("b").unwrap(), &[5, 6]);
    // An unpadded header and no metadata are fine too.
    let mut raw = 2u64.to_le_bytes().to_vec();
    raw.extend_from_slice(b"{}");
    assert!(read_safetensors_bytes(&raw, Path::new(P)).unwrap().tensors.is_empty());
}

#[test]
fn official_package_file_reads_and_matches_our_bytes() {
    let path = data_dir().join("official.safetensors");
    let st = read_safetensors(&path).unwrap();
    assert_eq!(st.metadata.len(), 1);
    assert_eq!(st.metadata["format"], "pt");
    let w: Vec<f32> = (0..12).map(|i| i as f32 * 0.25 - 1.0).collect();
    assert_eq!(st.get_shaped("weights", &[3, 4]).unwrap().data, TensorData::F32(w));
    assert_eq!(st.get_f64("bias").unwrap(), &[0.5, -1.5, 1e-3]);
    assert_eq!(
        st.get_shaped("mask", &[2, 3]).unwrap().data,
        TensorData::U8(vec![0, 1, 255, 128, 7, 3])
    );
    assert_eq!(st.shape("step").unwrap(), &[] as &[usize]);
    assert_eq!(st.get_i64("step").unwrap(), &[123456789012]);
    assert_eq!(st.get_u32("index").unwrap(), &[0, 1, u32::MAX]);
    assert_eq!(st.get_shaped("empty", &[0, 3]).unwrap().data, TensorData::F32(vec![]));
    // Our writer lays the file out exactly as the official one.
    assert_eq!(safetensors_bytes(&st), std::fs::read(&path).unwrap());
}

#[test]
fn getters_name_the_tensor() {
    let st = sample();
    let missing = st.get_f32("nope").unwrap_err();
    assert_eq!(missing, TensorError::Missing { name: "nope".into() });
    let wrong = st.get_f32("b.bias").unwrap_err();
    assert_eq!(wrong.to_string(), "tensor `b.bias` is F64, expected F32");
    let shape = st.get_shaped("a.weight", &[3, 2]).unwrap_err();
    assert_eq!(shape.to_string(), "tensor `a.weight` has shape [2, 3], expected [3, 2]");
    let e = missing.at(Path::new("ckpt.safetensors"));
    assert_eq!(e.path(), Path::new("ckpt.safetensors"));
    assert_eq!(
        e.to_string(),
        "ckpt.safetensors: bad safetensors file: no tensor `nope`"
    );
    assert!(st.get_i64("step").is_ok() && st.get_u8("mask").is_ok() && st.get_u32("index").is_ok());
}

#[test]
fn truncation_at_every_length_errors() {
    let bytes = safetensors_bytes(&sample());
    for len in 0..bytes.len() {
        let msg = err_msg(&bytes[..len]);
        assert!(!msg.is_empty());
    }
    // The message says how much is missing.
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let total = bytes.len() - 8 - n;
    let msg = err_msg(&bytes[..bytes.len() - 10]);
    assert_eq!(
        msg,
        format!(
            "truncated: header says {total} bytes of tensors, file has {}",
            total - 10
        )
    );
    assert!(
        err_msg(&bytes[..20]).starts_with("truncated: header says"),
        "{}",
        err_msg(&bytes[..20])
    );
    assert!(err_msg(&bytes[..3]).starts_with("truncated: 3 bytes"));
}

#[test]
fn trailing_bytes_error() {
    let mut bytes = safetensors_bytes(&sample());
    bytes.push(0);
    assert!(err_msg(&bytes).contains("1 bytes after the last tensor"));
}

#[test]
fn corrupt_json_errors() {
    let f = |h: &str| err_msg(&hand_file(h, &[]));
    assert!(f("{\"a\": {").starts_with("header is not valid JSON"));
    assert!(f("[1, 2]").contains("not a JSON object"));
    assert!(f("\u{0}\u{1}garbage").starts_with("header is not valid JSON"));
    // Invalid UTF-8 in the header.
    let mut raw = 8u64.to_le_bytes().to_vec();
    raw.extend_from_slice(b"{\"\xff\":1}  ");
    assert!(err_msg(&raw).starts_with("header is not valid JSON"));
    // Flip every byte of a valid header in turn: errors or reads, never panics.
    let good = safetensors_bytes(&sample());
    let n = u64::from_le_bytes(good[..8].try_into().unwrap()) as usize;
    for i in 0..8 + n {
        let mut bad = good.clone();
        bad[i] ^= 0x5a;
        let _ = read_safetensors_bytes(&bad, Path::new(P));
    }
}

#[test]
fn bad_entries_error_naming_the_tensor() {
    let f = |h: &str, buf: &[u8]| err_msg(&hand_file(h, buf));
    let b8 = [0u8; 8];
    assert!(
        f(r#"{"x": {"dtype": "BF16", "shape": [4], "data_offsets": [0, 8]}}"#, &b8)
            .contains("tensor `x`: dtype BF16 is not supported")
    );
    assert!(
        f(r#"{"x": {"shape": [2], "data_offsets": [0, 8]}}"#, &b8).contains("tensor `x`: header entry has no `dtype`")
    );
    assert!(f(r#"{"x": {"dtype": "F32", "shape": [-2], "data_offsets": [0, 8]}}"#, &b8).contains("`shape`"));
    assert!(f(r#"{"x": {"dtype": "F32", "shape": [2], "data_offsets": [0]}}"#, &b8).contains("`data_offsets`"));
    assert!(f(r#"{"x": {"dtype": "F32", "shape": [2], "data_offsets": [8, 0]}}"#, &b8).contains("end before"));
    assert_eq!(
        f(r#"{"x": {"dtype": "F32", "shape": [3], "data_offsets": [0, 8]}}"#, &b8),
        "tensor `x`: shape [3] of F32 needs 12 bytes, data_offsets [0, 8] give 8"
    );
    assert!(f(
        r#"{"x": {"dtype": "U8", "shape": [4294967296, 4294967296, 4294967296], "data_offsets": [0, 8]}}"#,
        &b8
    )
    .contains("too many elements"));
    assert!(f(r#"{"x": 3}"#, &b8).contains("tensor `x`: header entry is not a JSON object"));
    assert!(f(r#"{"__metadata__": {"a": 1}}"#, &[]).contains("value of `a` is not a string"));
    assert!(f(r#"{"__metadata__": []}"#, &[]).contains("`__metadata__` is not a JSON object"));
    // Offsets far past the end of the file.
    assert!(f(r#"{"x": {"dtype": "U8", "shape": [8], "data_offsets": [0, 8]}, "y": {"dtype": "U8", "shape": [1], "data_offsets": [18446744073709551614, 18446744073709551615]}}"#, &b8)
        .contains("gap in the buffer"));
}

#[test]
fn overlapping_offsets_error() {
    let h = r#"{"a": {"dtype": "F32", "shape": [2], "data_offsets": [0, 8]},
                "b": {"dtype": "F32", "shape": [2], "data_offsets": [4, 12]}}"#;
    assert_eq!(
        err_msg(&hand_file(h, &[0u8; 12])),
        "tensor `b` (bytes 4..12) overlaps tensor `a` (ending at 8)"
    );
    // The same range twice.
    let h = r#"{"a": {"dtype": "U8", "shape": [4], "data_offsets": [0, 4]},
                "b": {"dtype": "U8", "shape": [4], "data_offsets": [0, 4]}}"#;
    assert!(err_msg(&hand_file(h, &[0u8; 4])).contains("overlaps"));
}

#[test]
fn gaps_in_the_buffer_error() {
    let h = r#"{"a": {"dtype": "U8", "shape": [2], "data_offsets": [0, 2]},
                "b": {"dtype": "U8", "shape": [2], "data_offsets": [4, 6]}}"#;
    assert_eq!(
        err_msg(&hand_file(h, &[0u8; 6])),
        "gap in the buffer: bytes 2..4 (before tensor `b`) belong to no tensor"
    );
}

#[test]
fn absurd_header_length_errors() {
    let mut raw = u64::MAX.to_le_bytes().to_vec();
    raw.extend_from_slice(b"{}");
    assert!(err_msg(&raw).contains("over the"));
    let mut raw = 1000u64.to_le_bytes().to_vec();
    raw.extend_from_slice(b"{}");
    assert_eq!(
        err_msg(&raw),
        "truncated: header says 1000 bytes of JSON, file has 2 after the length"
    );
}

#[test]
fn writing_inconsistent_tensors_errors_and_leaves_no_file() {
    let dir = std::env::temp_dir().join(format!("pganeus-safetensors-bad-{}", std::process::id()));
    let path = dir.join("bad.safetensors");
    let mut st = SafeTensors::new();
    st.insert("x", Tensor::f32(vec![2, 2], vec![1.0; 3]));
    let e = write_safetensors(&path, &st).unwrap_err();
    assert!(
        matches!(&e, IoError::Safetensors { msg, .. } if msg.contains("tensor `x`")),
        "{e}"
    );
    let mut st = SafeTensors::new();
    st.insert("__metadata__", Tensor::f32(vec![1], vec![1.0]));
    assert!(write_safetensors(&path, &st).is_err());
    assert!(!path.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn reading_a_missing_file_names_it() {
    let path = data_dir().join("no-such.safetensors");
    let e = read_safetensors(&path).unwrap_err();
    assert!(matches!(e, IoError::Open { .. }));
    assert_eq!(e.path(), path);
}
