//! Safetensors checkpoints (the format of Hugging Face's `safetensors`
//! package): named n-dimensional tensors plus a string-to-string metadata map.
//!
//! Layout: an 8-byte little-endian `u64` N, then N bytes of UTF-8 JSON
//! `{"__metadata__": {string: string}, "<name>": {"dtype": "F32", "shape":
//! [..], "data_offsets": [begin, end]}, ...}` padded with spaces to a multiple
//! of 8, then the byte buffer. Offsets count from the start of the buffer;
//! elements are little-endian, C (row-major) order.
//!
//! Reading checks everything and turns any damage into
//! [`IoError::Safetensors`] with a plain message, never a panic: the header
//! length against the file size, the JSON, the dtype (`F32 F64 U8 I64 U32`),
//! the shape, that the offsets lie in the buffer, do not overlap and leave no
//! gap or trailing byte (as the official reader demands), and that each
//! tensor's byte length is its element count times the dtype's size.
//!
//! Writing is deterministic: `__metadata__` first (left out when empty), then
//! the tensors in buffer order. That order is the official writer's: by dtype
//! (`I64 F64 F32 U32 U8`, wider first), then by name. So every tensor starts
//! at a multiple of its element size (the buffer itself starts at a multiple
//! of 8) and a zero-copy reader can use it in place; and with at most one
//! metadata entry the bytes are exactly those of the official package.

use std::collections::BTreeMap;
use std::path::Path;

use serde_json::Value;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};

/// The elements of a tensor, in C order.
#[derive(Clone, Debug, PartialEq)]
pub enum TensorData {
    /// `F32`.
    F32(Vec<f32>),
    /// `F64`.
    F64(Vec<f64>),
    /// `U8`.
    U8(Vec<u8>),
    /// `I64`.
    I64(Vec<i64>),
    /// `U32`.
    U32(Vec<u32>),
}

impl TensorData {
    /// Number of elements.
    pub fn len(&self) -> usize {
        match self {
            TensorData::F32(v) => v.len(),
            TensorData::F64(v) => v.len(),
            TensorData::U8(v) => v.len(),
            TensorData::I64(v) => v.len(),
            TensorData::U32(v) => v.len(),
        }
    }

    /// `true` if there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The dtype as written in the header, e.g. `F32`.
    pub fn dtype(&self) -> &'static str {
        match self {
            TensorData::F32(_) => "F32",
            TensorData::F64(_) => "F64",
            TensorData::U8(_) => "U8",
            TensorData::I64(_) => "I64",
            TensorData::U32(_) => "U32",
        }
    }

    /// Rank of the dtype in the official writer's buffer order (higher first).
    fn write_rank(&self) -> u8 {
        match self {
            TensorData::I64(_) => 4,
            TensorData::F64(_) => 3,
            TensorData::F32(_) => 2,
            TensorData::U32(_) => 1,
            TensorData::U8(_) => 0,
        }
    }

    /// Bytes per element.
    pub fn element_size(&self) -> usize {
        match self {
            TensorData::F32(_) | TensorData::U32(_) => 4,
            TensorData::F64(_) | TensorData::I64(_) => 8,
            TensorData::U8(_) => 1,
        }
    }

    /// Appends the elements to `out` as little-endian bytes (the file's buffer layout).
    pub fn extend_le_bytes(&self, out: &mut Vec<u8>) {
        match self {
            TensorData::F32(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
            TensorData::F64(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
            TensorData::U8(v) => out.extend_from_slice(v),
            TensorData::I64(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
            TensorData::U32(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
        }
    }
}

/// A tensor: its shape and its elements in C order. A shape `[]` holds one
/// element.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// Size of each dimension.
    pub shape: Vec<usize>,
    /// The elements; their number is the product of `shape`.
    pub data: TensorData,
}

impl Tensor {
    /// A tensor from its parts (not checked here; writing checks it).
    pub fn new(shape: Vec<usize>, data: TensorData) -> Self {
        Self { shape, data }
    }

    /// An `F32` tensor.
    pub fn f32(shape: Vec<usize>, data: Vec<f32>) -> Self {
        Self::new(shape, TensorData::F32(data))
    }

    /// An `F64` tensor.
    pub fn f64(shape: Vec<usize>, data: Vec<f64>) -> Self {
        Self::new(shape, TensorData::F64(data))
    }

    /// Number of elements the shape asks for (`None` on overflow).
    fn shape_len(&self) -> Option<usize> {
        self.shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d))
    }
}

/// Why a tensor asked for by name is not there in the expected form.
/// [`TensorError::at`] turns it into an [`IoError`] naming the file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TensorError {
    /// No tensor of that name.
    #[error("no tensor `{name}`")]
    Missing {
        /// The tensor asked for.
        name: String,
    },
    /// The tensor has another dtype.
    #[error("tensor `{name}` is {found}, expected {expected}")]
    Dtype {
        /// The tensor.
        name: String,
        /// The dtype asked for, e.g. `F32`.
        expected: &'static str,
        /// The dtype it has.
        found: &'static str,
    },
    /// The tensor has another shape.
    #[error("tensor `{name}` has shape {found:?}, expected {expected:?}")]
    Shape {
        /// The tensor.
        name: String,
        /// The shape asked for.
        expected: Vec<usize>,
        /// The shape it has.
        found: Vec<usize>,
    },
}

impl TensorError {
    /// This error as [`IoError::Safetensors`] about the file at `path`.
    pub fn at(self, path: &Path) -> IoError {
        IoError::Safetensors {
            path: path.to_path_buf(),
            msg: self.to_string(),
        }
    }
}

/// A whole safetensors file: metadata and tensors, both ordered by name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SafeTensors {
    /// The `__metadata__` map (empty when the file has none).
    pub metadata: BTreeMap<String, String>,
    /// The tensors by name.
    pub tensors: BTreeMap<String, Tensor>,
}

macro_rules! typed_getter {
    ($(#[$doc:meta])* $fn:ident, $variant:ident, $t:ty) => {
        $(#[$doc])*
        pub fn $fn(&self, name: &str) -> std::result::Result<&[$t], TensorError> {
            match &self.get(name)?.data {
                TensorData::$variant(v) => Ok(v),
                other => Err(TensorError::Dtype {
                    name: name.to_string(),
                    expected: stringify!($variant),
                    found: other.dtype(),
                }),
            }
        }
    };
}

impl SafeTensors {
    /// No metadata, no tensors.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds (or replaces) the tensor `name`.
    pub fn insert(&mut self, name: impl Into<String>, tensor: Tensor) {
        self.tensors.insert(name.into(), tensor);
    }

    /// The tensor `name`.
    pub fn get(&self, name: &str) -> std::result::Result<&Tensor, TensorError> {
        self.tensors
            .get(name)
            .ok_or_else(|| TensorError::Missing { name: name.to_string() })
    }

    /// The shape of tensor `name`.
    pub fn shape(&self, name: &str) -> std::result::Result<&[usize], TensorError> {
        Ok(&self.get(name)?.shape)
    }

    /// The tensor `name`, checked to have exactly `shape`.
    pub fn get_shaped(&self, name: &str, shape: &[usize]) -> std::result::Result<&Tensor, TensorError> {
        let t = self.get(name)?;
        if t.shape != shape {
            return Err(TensorError::Shape {
                name: name.to_string(),
                expected: shape.to_vec(),
                found: t.shape.clone(),
            });
        }
        Ok(t)
    }

    typed_getter!(
        /// The elements of `F32` tensor `name`.
        get_f32, F32, f32
    );
    typed_getter!(
        /// The elements of `F64` tensor `name`.
        get_f64, F64, f64
    );
    typed_getter!(
        /// The elements of `U8` tensor `name`.
        get_u8, U8, u8
    );
    typed_getter!(
        /// The elements of `I64` tensor `name`.
        get_i64, I64, i64
    );
    typed_getter!(
        /// The elements of `U32` tensor `name`.
        get_u32, U32, u32
    );
}

/// Reads a safetensors file.
pub fn read_safetensors(path: &Path) -> Result<SafeTensors> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })?;
    read_safetensors_bytes(&bytes, path)
}

/// [`read_safetensors`] from bytes already in memory; `path` is only used in errors.
pub fn read_safetensors_bytes(bytes: &[u8], path: &Path) -> Result<SafeTensors> {
    parse(bytes).map_err(|msg| IoError::Safetensors {
        path: path.to_path_buf(),
        msg,
    })
}

/// Writes `st` as a safetensors file, atomically.
pub fn write_safetensors(path: &Path, st: &SafeTensors) -> Result<()> {
    check(st).map_err(|msg| IoError::Safetensors {
        path: path.to_path_buf(),
        msg,
    })?;
    write_atomic(path, &safetensors_bytes(st))
}

/// `st` as the bytes of a safetensors file (layout in the module docs).
///
/// # Panics
/// If a tensor's element count is not the product of its shape, or a tensor
/// is named `__metadata__` ([`write_safetensors`] reports these as errors).
pub fn safetensors_bytes(st: &SafeTensors) -> Vec<u8> {
    if let Err(msg) = check(st) {
        panic!("safetensors_bytes: {msg}");
    }
    let mut order: Vec<(&String, &Tensor)> = st.tensors.iter().collect();
    order.sort_by(|(na, a), (nb, b)| b.data.write_rank().cmp(&a.data.write_rank()).then_with(|| na.cmp(nb)));

    // serde_json escapes the strings; the rest is laid out by hand to keep
    // the field order of the official writer (dtype, shape, data_offsets).
    let json_str = |s: &str| serde_json::to_string(s).expect("a string always serialises");
    let mut header = String::from("{");
    let mut first = true;
    if !st.metadata.is_empty() {
        header.push_str("\"__metadata__\":{");
        let entries: Vec<String> = st
            .metadata
            .iter()
            .map(|(k, v)| format!("{}:{}", json_str(k), json_str(v)))
            .collect();
        header.push_str(&entries.join(","));
        header.push('}');
        first = false;
    }
    let mut offset = 0usize;
    for (name, t) in &order {
        let len = t.data.len() * t.data.element_size();
        let shape: Vec<String> = t.shape.iter().map(|d| d.to_string()).collect();
        if !first {
            header.push(',');
        }
        first = false;
        header.push_str(&format!(
            "{}:{{\"dtype\":\"{}\",\"shape\":[{}],\"data_offsets\":[{},{}]}}",
            json_str(name),
            t.data.dtype(),
            shape.join(","),
            offset,
            offset + len
        ));
        offset += len;
    }
    header.push('}');
    let pad = (8 - header.len() % 8) % 8;
    header.push_str(&" ".repeat(pad));

    let mut out = Vec::with_capacity(8 + header.len() + offset);
    out.extend_from_slice(&(header.len() as u64).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for (_, t) in &order {
        t.data.extend_le_bytes(&mut out);
    }
    out
}

/// The checks writing needs: names and element counts.
fn check(st: &SafeTensors) -> std::result::Result<(), String> {
    for (name, t) in &st.tensors {
        if name == METADATA_KEY {
            return Err(format!("a tensor cannot be named `{METADATA_KEY}`"));
        }
        match t.shape_len() {
            Some(n) if n == t.data.len() => {}
            _ => {
                return Err(format!(
                    "tensor `{name}`: shape {:?} does not hold its {} elements",
                    t.shape,
                    t.data.len()
                ))
            }
        }
    }
    Ok(())
}

const METADATA_KEY: &str = "__metadata__";

/// Refuse headers larger than this (the official reader's limit), so a
/// corrupt length cannot make the parser chew through a huge file as JSON.
const MAX_HEADER: u64 = 100_000_000;

fn parse(bytes: &[u8]) -> std::result::Result<SafeTensors, String> {
    if bytes.len() < 8 {
        return Err(format!(
            "truncated: {} bytes, shorter than the 8-byte header length",
            bytes.len()
        ));
    }
    let n = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes"));
    let available = (bytes.len() - 8) as u64;
    if n > MAX_HEADER {
        return Err(format!(
            "header length {n} is over the {MAX_HEADER}-byte limit (corrupt file?)"
        ));
    }
    if n > available {
        return Err(format!(
            "truncated: header says {n} bytes of JSON, file has {available} after the length"
        ));
    }
    let n = n as usize;
    let header = &bytes[8..8 + n];
    let buffer = &bytes[8 + n..];
    let value: Value = serde_json::from_slice(header).map_err(|e| format!("header is not valid JSON: {e}"))?;
    let Value::Object(map) = value else {
        return Err("header is not a JSON object".to_string());
    };

    let mut st = SafeTensors::new();
    // (begin, end, name, dtype, shape) of every tensor, checked as a whole below.
    let mut entries: Vec<(usize, usize, String, &'static str, Vec<usize>)> = Vec::with_capacity(map.len());
    for (name, v) in &map {
        if name == METADATA_KEY {
            st.metadata = parse_metadata(v)?;
            continue;
        }
        let (dtype, shape, begin, end) = parse_entry(name, v)?;
        entries.push((begin, end, name.clone(), dtype, shape));
    }

    // The offsets must tile the buffer exactly: sorted, each begins where the
    // previous ended, the last ends at the end of the buffer.
    entries.sort_by(|a, b| (a.0, a.1, &a.2).cmp(&(b.0, b.1, &b.2)));
    let mut pos = 0usize;
    let mut prev: Option<&str> = None;
    for (begin, end, name, _, _) in &entries {
        if *begin < pos {
            return Err(format!(
                "tensor `{name}` (bytes {begin}..{end}) overlaps tensor `{}` (ending at {pos})",
                prev.unwrap_or("?")
            ));
        }
        if *begin > pos {
            return Err(format!(
                "gap in the buffer: bytes {pos}..{begin} (before tensor `{name}`) belong to no tensor"
            ));
        }
        pos = *end;
        prev = Some(name);
    }
    if pos > buffer.len() {
        return Err(format!(
            "truncated: header says {pos} bytes of tensors, file has {}",
            buffer.len()
        ));
    }
    if pos < buffer.len() {
        return Err(format!(
            "{} bytes after the last tensor (header says {pos} bytes of tensors, file has {})",
            buffer.len() - pos,
            buffer.len()
        ));
    }

    for (begin, end, name, dtype, shape) in entries {
        let data = decode(dtype, &buffer[begin..end]);
        st.tensors.insert(name, Tensor { shape, data });
    }
    Ok(st)
}

fn parse_metadata(v: &Value) -> std::result::Result<BTreeMap<String, String>, String> {
    let Value::Object(m) = v else {
        return Err(format!("`{METADATA_KEY}` is not a JSON object"));
    };
    m.iter()
        .map(|(k, v)| match v {
            Value::String(s) => Ok((k.clone(), s.clone())),
            _ => Err(format!("`{METADATA_KEY}` value of `{k}` is not a string")),
        })
        .collect()
}

/// Element size of the dtypes this reader knows.
fn dtype_size(dtype: &str) -> Option<(&'static str, usize)> {
    Some(match dtype {
        "F32" => ("F32", 4),
        "F64" => ("F64", 8),
        "U8" => ("U8", 1),
        "I64" => ("I64", 8),
        "U32" => ("U32", 4),
        _ => return None,
    })
}

/// One tensor's header entry, checked on its own: dtype, shape, offsets and
/// that the byte length matches the element count.
fn parse_entry(name: &str, v: &Value) -> std::result::Result<(&'static str, Vec<usize>, usize, usize), String> {
    let Value::Object(m) = v else {
        return Err(format!("tensor `{name}`: header entry is not a JSON object"));
    };
    let field = |key: &str| {
        m.get(key)
            .ok_or_else(|| format!("tensor `{name}`: header entry has no `{key}`"))
    };
    let dtype = match field("dtype")? {
        Value::String(s) => s.as_str(),
        _ => return Err(format!("tensor `{name}`: `dtype` is not a string")),
    };
    let (dtype, size) = dtype_size(dtype)
        .ok_or_else(|| format!("tensor `{name}`: dtype {dtype} is not supported (only F32, F64, U8, I64, U32)"))?;
    let shape = usize_list(field("shape")?)
        .ok_or_else(|| format!("tensor `{name}`: `shape` is not a list of non-negative integers"))?;
    let offsets = usize_list(field("data_offsets")?)
        .filter(|o| o.len() == 2)
        .ok_or_else(|| format!("tensor `{name}`: `data_offsets` is not a pair of non-negative integers"))?;
    let (begin, end) = (offsets[0], offsets[1]);
    if end < begin {
        return Err(format!(
            "tensor `{name}`: data_offsets [{begin}, {end}] end before they begin"
        ));
    }
    let count = shape
        .iter()
        .try_fold(1usize, |n, &d| n.checked_mul(d))
        .ok_or_else(|| format!("tensor `{name}`: shape {shape:?} has too many elements"))?;
    let expected = count.checked_mul(size);
    if expected != Some(end - begin) {
        return Err(format!(
            "tensor `{name}`: shape {shape:?} of {dtype} needs {} bytes, data_offsets [{begin}, {end}] give {}",
            expected.map_or("too many".to_string(), |e| e.to_string()),
            end - begin
        ));
    }
    Ok((dtype, shape, begin, end))
}

fn usize_list(v: &Value) -> Option<Vec<usize>> {
    v.as_array()?
        .iter()
        .map(|x| x.as_u64().and_then(|u| usize::try_from(u).ok()))
        .collect()
}

/// Little-endian elements of `dtype` (already checked: `bytes.len()` is a
/// multiple of the element size).
fn decode(dtype: &str, bytes: &[u8]) -> TensorData {
    fn chunks<const N: usize, T>(bytes: &[u8], f: fn([u8; N]) -> T) -> Vec<T> {
        bytes
            .chunks_exact(N)
            .map(|c| f(c.try_into().expect("exact chunk")))
            .collect()
    }
    match dtype {
        "F32" => TensorData::F32(chunks(bytes, f32::from_le_bytes)),
        "F64" => TensorData::F64(chunks(bytes, f64::from_le_bytes)),
        "I64" => TensorData::I64(chunks(bytes, i64::from_le_bytes)),
        "U32" => TensorData::U32(chunks(bytes, u32::from_le_bytes)),
        _ => TensorData::U8(bytes.to_vec()),
    }
}
