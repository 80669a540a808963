//! NumPy `.npy` arrays and `.npz` archives (`cameras_sphere.npz` of a capture,
//! reference values of tests).
//!
//! `.npy` (NumPy's "format.py"): the magic `\x93NUMPY`, a version byte pair,
//! the header length (`u16` in version 1.0, `u32` in 2.0 and 3.0), a header
//! that is a Python dict literal such as
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (4, 4), }`, then the raw
//! data. Reading accepts versions 1.0 to 3.0, either byte order, C or Fortran
//! order (Fortran arrays are transposed to C order), and the dtypes
//! `f8 f4 i8 i4 u1 b1`, plus `i2 i1 u2` (widened to `i32`) and `u4` (widened
//! to `i64`). Bytes after the data are ignored, as NumPy does. Writing gives
//! version 1.0 (2.0 only for a header longer than 65535 bytes), little-endian,
//! C order, with the header padded so the data starts at a multiple of 64.
//!
//! `.npz` (`np.savez`): a ZIP archive holding one `<name>.npy` per array,
//! read and written through the `zip` crate. The writer stores entries
//! uncompressed with fixed timestamps (1980-01-01 00:00), so its output is
//! deterministic. The reader takes entries stored or DEFLATE-compressed
//! (`np.savez_compressed`), ZIP64 included, checks their CRC-32 and sizes,
//! and skips entries whose names do not end in `.npy` (NumPy would return
//! them as raw bytes). Names are UTF-8 when flagged so, else CP437, as
//! NumPy's `zipfile` reads them.

use std::path::Path;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};

/// The elements of an array, in C order.
#[derive(Clone, Debug, PartialEq)]
pub enum NpyData {
    /// `float64` (`<f8`).
    F64(Vec<f64>),
    /// `float32` (`<f4`).
    F32(Vec<f32>),
    /// `int64` (`<i8`).
    I64(Vec<i64>),
    /// `int32` (`<i4`).
    I32(Vec<i32>),
    /// `uint8` (`|u1`).
    U8(Vec<u8>),
    /// `bool` (`|b1`).
    Bool(Vec<bool>),
}

impl NpyData {
    /// Number of elements.
    pub fn len(&self) -> usize {
        match self {
            NpyData::F64(v) => v.len(),
            NpyData::F32(v) => v.len(),
            NpyData::I64(v) => v.len(),
            NpyData::I32(v) => v.len(),
            NpyData::U8(v) => v.len(),
            NpyData::Bool(v) => v.len(),
        }
    }

    /// `true` if there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The NumPy dtype this data is written as, e.g. `<f8`.
    pub fn descr(&self) -> &'static str {
        match self {
            NpyData::F64(_) => "<f8",
            NpyData::F32(_) => "<f4",
            NpyData::I64(_) => "<i8",
            NpyData::I32(_) => "<i4",
            NpyData::U8(_) => "|u1",
            NpyData::Bool(_) => "|b1",
        }
    }
}

/// An n-dimensional array: its shape and its elements in C (row-major) order.
/// A shape `[]` is a 0-d array holding one element.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// Size along each axis.
    pub shape: Vec<usize>,
    /// The elements, `shape.iter().product()` of them.
    pub data: NpyData,
}

impl NpyArray {
    /// An array of the given shape and elements.
    ///
    /// # Panics
    /// If the number of elements is not the product of `shape`.
    pub fn new(shape: Vec<usize>, data: NpyData) -> Self {
        let n = element_count(&shape);
        assert_eq!(
            n,
            Some(data.len()),
            "NpyArray::new: shape {shape:?} needs {n:?} elements, data has {}",
            data.len()
        );
        Self { shape, data }
    }

    /// A `float64` array; panics as [`NpyArray::new`] does.
    pub fn f64(shape: Vec<usize>, data: Vec<f64>) -> Self {
        Self::new(shape, NpyData::F64(data))
    }

    /// The elements as `f64`, whatever the dtype (`true` is 1, `false` 0;
    /// 64-bit integers beyond 2^53 are rounded).
    pub fn as_f64(&self) -> Vec<f64> {
        match &self.data {
            NpyData::F64(v) => v.clone(),
            NpyData::F32(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::I64(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::I32(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::U8(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::Bool(v) => v.iter().map(|&x| if x { 1.0 } else { 0.0 }).collect(),
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// `true` if the array has no elements (some axis has size 0).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
}

fn element_count(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d))
}

// ---------------------------------------------------------------------------
// .npy
// ---------------------------------------------------------------------------

const NPY_MAGIC: &[u8; 6] = b"\x93NUMPY";
/// NumPy aligns the data of arrays it writes to this many bytes.
const NPY_ALIGN: usize = 64;

/// Reads a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray> {
    read_npy_bytes(&read_file(path)?, path)
}

/// [`read_npy`] from bytes already in memory; `path` is only used in errors.
pub fn read_npy_bytes(bytes: &[u8], path: &Path) -> Result<NpyArray> {
    parse_npy(bytes).map_err(|msg| IoError::Npz {
        path: path.to_path_buf(),
        msg,
    })
}

/// Writes `array` as a `.npy` file (version 1.0), atomically.
pub fn write_npy(path: &Path, array: &NpyArray) -> Result<()> {
    check_array(array).map_err(|msg| IoError::Npz {
        path: path.to_path_buf(),
        msg,
    })?;
    write_atomic(path, &npy_bytes(array))
}

/// `array` as the bytes of a `.npy` file (version 1.0, little-endian, C order;
/// the data starts at a multiple of 64 bytes).
///
/// # Panics
/// If the number of elements is not the product of the shape.
pub fn npy_bytes(array: &NpyArray) -> Vec<u8> {
    if let Err(msg) = check_array(array) {
        panic!("npy_bytes: {msg}");
    }
    let shape = match array.shape.len() {
        0 => "()".to_string(),
        1 => format!("({},)", array.shape[0]),
        _ => {
            let dims: Vec<String> = array.shape.iter().map(|d| d.to_string()).collect();
            format!("({})", dims.join(", "))
        }
    };
    let mut header = format!(
        "{{'descr': '{}', 'fortran_order': False, 'shape': {shape}, }}",
        array.data.descr()
    );
    // Version 1.0 stores the header length in a u16; beyond that, 2.0 and a u32.
    let (version, prefix) = if header.len() + 1 + NPY_ALIGN + 10 <= u16::MAX as usize {
        (1u8, 10)
    } else {
        (2u8, 12)
    };
    let pad = (NPY_ALIGN - (prefix + header.len() + 1) % NPY_ALIGN) % NPY_ALIGN;
    header.push_str(&" ".repeat(pad));
    header.push('\n');

    let item = item_size(&array.data);
    let mut out = Vec::with_capacity(prefix + header.len() + array.len() * item);
    out.extend_from_slice(NPY_MAGIC);
    out.extend_from_slice(&[version, 0]);
    if version == 1 {
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    } else {
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(header.as_bytes());
    match &array.data {
        NpyData::F64(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
        NpyData::F32(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
        NpyData::I64(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
        NpyData::I32(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
        NpyData::U8(v) => out.extend_from_slice(v),
        NpyData::Bool(v) => out.extend(v.iter().map(|&b| b as u8)),
    }
    out
}

fn item_size(data: &NpyData) -> usize {
    match data {
        NpyData::F64(_) | NpyData::I64(_) => 8,
        NpyData::F32(_) | NpyData::I32(_) => 4,
        NpyData::U8(_) | NpyData::Bool(_) => 1,
    }
}

fn check_array(array: &NpyArray) -> std::result::Result<(), String> {
    match element_count(&array.shape) {
        Some(n) if n == array.len() => Ok(()),
        n => Err(format!(
            "shape {:?} needs {} elements, data has {}",
            array.shape,
            n.map_or("too many".to_string(), |n| n.to_string()),
            array.len()
        )),
    }
}

/// The element types the reader knows, before widening to an [`NpyData`].
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    F8,
    F4,
    I8,
    I4,
    I2,
    I1,
    U4,
    U2,
    U1,
    B1,
}

impl Kind {
    fn size(self) -> usize {
        match self {
            Kind::F8 | Kind::I8 => 8,
            Kind::F4 | Kind::I4 | Kind::U4 => 4,
            Kind::I2 | Kind::U2 => 2,
            Kind::I1 | Kind::U1 | Kind::B1 => 1,
        }
    }
}

/// Parses a dtype string such as `<f8`, `>i4`, `|u1` or `|b1`: (kind, little-endian).
fn parse_descr(descr: &str) -> std::result::Result<(Kind, bool), String> {
    let unsupported =
        || format!("dtype '{descr}' is not supported (only float64/32, int64/32/16/8, uint32/16/8 and bool)");
    let mut chars = descr.chars();
    let (order, rest) = match chars.next() {
        Some(c @ ('<' | '>' | '|' | '=')) => (c, chars.as_str()),
        _ => ('|', descr),
    };
    let kind = match rest {
        "f8" => Kind::F8,
        "f4" => Kind::F4,
        "i8" => Kind::I8,
        "i4" => Kind::I4,
        "i2" => Kind::I2,
        "i1" => Kind::I1,
        "u4" => Kind::U4,
        "u2" => Kind::U2,
        "u1" => Kind::U1,
        "b1" | "?" => Kind::B1,
        _ => return Err(unsupported()),
    };
    let little = match order {
        '<' => true,
        '>' => false,
        '=' => cfg!(target_endian = "little"),
        // '|' (not applicable) is only right for one-byte types.
        _ if kind.size() == 1 => true,
        _ => return Err(format!("dtype '{descr}' has no byte order")),
    };
    Ok((kind, little))
}

fn parse_npy(bytes: &[u8]) -> std::result::Result<NpyArray, String> {
    if bytes.len() < 10 || &bytes[..6] != NPY_MAGIC {
        return Err(if bytes.len() >= 6 && &bytes[..6] != NPY_MAGIC {
            "not a .npy array (bad magic)".to_string()
        } else {
            format!("truncated: {} bytes", bytes.len())
        });
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let (header_len, start): (usize, usize) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            let b = bytes.get(8..12).ok_or("truncated header")?;
            (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize, 12)
        }
        _ => {
            return Err(format!(
                ".npy format version {major}.{minor} is not supported (1.0 to 3.0 are)"
            ))
        }
    };
    let end = start
        .checked_add(header_len)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| format!("truncated: the header needs {header_len} bytes"))?;
    // Version 1.0 and 2.0 headers are latin-1, 3.0 UTF-8; the keys and values
    // read here are ASCII either way.
    let header = std::str::from_utf8(&bytes[start..end]).map_err(|_| "header is not text".to_string())?;
    let header = parse_header(header)?;

    let (kind, little) = parse_descr(&header.descr)?;
    let count = element_count(&header.shape).ok_or_else(|| format!("shape {:?} is too large", header.shape))?;
    let body = &bytes[end..];
    let need = count
        .checked_mul(kind.size())
        .filter(|&n| n <= body.len())
        .ok_or_else(|| {
            format!(
                "truncated: shape {:?} of {} needs {} bytes of data, the file has {}",
                header.shape,
                header.descr,
                count.saturating_mul(kind.size()),
                body.len()
            )
        })?;
    let body = &body[..need];

    let mut data = decode_elements(body, kind, little);
    if header.fortran_order && header.shape.len() > 1 {
        data = fortran_to_c(&data, &header.shape);
    }
    Ok(NpyArray {
        shape: header.shape,
        data,
    })
}

fn decode_elements(body: &[u8], kind: Kind, little: bool) -> NpyData {
    fn words<const N: usize>(body: &[u8], little: bool) -> impl Iterator<Item = [u8; N]> + '_ {
        body.chunks_exact(N).map(move |c| {
            let mut w = [0u8; N];
            w.copy_from_slice(c);
            if !little {
                w.reverse();
            }
            w
        })
    }
    match kind {
        Kind::F8 => NpyData::F64(words::<8>(body, little).map(f64::from_le_bytes).collect()),
        Kind::F4 => NpyData::F32(words::<4>(body, little).map(f32::from_le_bytes).collect()),
        Kind::I8 => NpyData::I64(words::<8>(body, little).map(i64::from_le_bytes).collect()),
        Kind::I4 => NpyData::I32(words::<4>(body, little).map(i32::from_le_bytes).collect()),
        Kind::U4 => NpyData::I64(words::<4>(body, little).map(|w| u32::from_le_bytes(w) as i64).collect()),
        Kind::I2 => NpyData::I32(words::<2>(body, little).map(|w| i16::from_le_bytes(w) as i32).collect()),
        Kind::U2 => NpyData::I32(words::<2>(body, little).map(|w| u16::from_le_bytes(w) as i32).collect()),
        Kind::I1 => NpyData::I32(body.iter().map(|&b| b as i8 as i32).collect()),
        Kind::U1 => NpyData::U8(body.to_vec()),
        Kind::B1 => NpyData::Bool(body.iter().map(|&b| b != 0).collect()),
    }
}

/// Reorders elements stored in Fortran (column-major) order into C order.
fn fortran_to_c(data: &NpyData, shape: &[usize]) -> NpyData {
    // Fortran strides: the first axis is contiguous.
    let mut strides = vec![1usize; shape.len()];
    for k in 1..shape.len() {
        strides[k] = strides[k - 1] * shape[k - 1];
    }
    let n = data.len();
    let mut order = Vec::with_capacity(n);
    let mut index = vec![0usize; shape.len()];
    for _ in 0..n {
        order.push(index.iter().zip(&strides).map(|(i, s)| i * s).sum::<usize>());
        // Advance the C-order multi-index: the last axis fastest.
        for k in (0..shape.len()).rev() {
            index[k] += 1;
            if index[k] < shape[k] {
                break;
            }
            index[k] = 0;
        }
    }
    fn pick<T: Copy>(v: &[T], order: &[usize]) -> Vec<T> {
        order.iter().map(|&i| v[i]).collect()
    }
    match data {
        NpyData::F64(v) => NpyData::F64(pick(v, &order)),
        NpyData::F32(v) => NpyData::F32(pick(v, &order)),
        NpyData::I64(v) => NpyData::I64(pick(v, &order)),
        NpyData::I32(v) => NpyData::I32(pick(v, &order)),
        NpyData::U8(v) => NpyData::U8(pick(v, &order)),
        NpyData::Bool(v) => NpyData::Bool(pick(v, &order)),
    }
}

struct Header {
    descr: String,
    fortran_order: bool,
    shape: Vec<usize>,
}

/// A value of the header's dict literal.
enum PyValue {
    Str(String),
    Bool(bool),
    Tuple(Vec<usize>),
}

/// Parses the subset of Python literals an `.npy` header uses: a dict of
/// string keys to strings, `True`/`False` and tuples of integers.
fn parse_header(text: &str) -> std::result::Result<Header, String> {
    let bad = |what: &str| format!("bad header ({what}): {}", text.trim_end());
    let mut p = Lexer {
        s: text.as_bytes(),
        i: 0,
    };
    if !p.eat(b'{') {
        return Err(bad("expected a dict"));
    }
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    loop {
        if p.eat(b'}') {
            break;
        }
        let key = p.string().ok_or_else(|| bad("expected a quoted key"))?;
        if !p.eat(b':') {
            return Err(bad("expected ':'"));
        }
        let value = p
            .value()
            .ok_or_else(|| bad(&format!("cannot read the value of '{key}'")))?;
        match (key.as_str(), value) {
            ("descr", PyValue::Str(s)) => descr = Some(s),
            ("fortran_order", PyValue::Bool(b)) => fortran = Some(b),
            ("shape", PyValue::Tuple(t)) => shape = Some(t),
            ("descr" | "fortran_order" | "shape", _) => return Err(bad(&format!("'{key}' has the wrong type"))),
            _ => {}
        }
        if !p.eat(b',') {
            if p.eat(b'}') {
                break;
            }
            return Err(bad("expected ',' or '}'"));
        }
    }
    Ok(Header {
        descr: descr.ok_or_else(|| bad("no 'descr'"))?,
        fortran_order: fortran.ok_or_else(|| bad("no 'fortran_order'"))?,
        shape: shape.ok_or_else(|| bad("no 'shape'"))?,
    })
}

struct Lexer<'a> {
    s: &'a [u8],
    i: usize,
}

impl Lexer<'_> {
    fn skip_ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn eat(&mut self, c: u8) -> bool {
        self.skip_ws();
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn string(&mut self) -> Option<String> {
        self.skip_ws();
        let quote = *self.s.get(self.i)?;
        if quote != b'\'' && quote != b'"' {
            return None;
        }
        let start = self.i + 1;
        let len = self.s[start..].iter().position(|&c| c == quote)?;
        self.i = start + len + 1;
        String::from_utf8(self.s[start..start + len].to_vec()).ok()
    }

    fn word(&mut self) -> &[u8] {
        self.skip_ws();
        let start = self.i;
        while self.i < self.s.len() && self.s[self.i].is_ascii_alphanumeric() {
            self.i += 1;
        }
        &self.s[start..self.i]
    }

    fn value(&mut self) -> Option<PyValue> {
        self.skip_ws();
        match *self.s.get(self.i)? {
            b'\'' | b'"' => self.string().map(PyValue::Str),
            b'(' => {
                self.i += 1;
                let mut dims = Vec::new();
                loop {
                    if self.eat(b')') {
                        break;
                    }
                    let w = std::str::from_utf8(self.word()).ok()?;
                    // Python 2 wrote long integers as `3L`.
                    dims.push(w.strip_suffix('L').unwrap_or(w).parse().ok()?);
                    if !self.eat(b',') {
                        if self.eat(b')') {
                            break;
                        }
                        return None;
                    }
                }
                Some(PyValue::Tuple(dims))
            }
            _ => match self.word() {
                b"True" => Some(PyValue::Bool(true)),
                b"False" => Some(PyValue::Bool(false)),
                _ => None,
            },
        }
    }
}

// ---------------------------------------------------------------------------
// .npz = ZIP (the container through the `zip` crate)
// ---------------------------------------------------------------------------

/// Reads every array of a `.npz` archive, in archive order, named without
/// their `.npy` suffix.
pub fn read_npz(path: &Path) -> Result<Vec<(String, NpyArray)>> {
    read_npz_bytes(&read_file(path)?, path)
}

/// [`read_npz`] from bytes already in memory; `path` is only used in errors.
pub fn read_npz_bytes(bytes: &[u8], path: &Path) -> Result<Vec<(String, NpyArray)>> {
    let err = |msg: String| IoError::Npz {
        path: path.to_path_buf(),
        msg,
    };
    let entries = read_zip(bytes).map_err(err)?;
    let mut arrays = Vec::with_capacity(entries.len());
    for (name, data) in entries {
        let Some(stem) = name.strip_suffix(".npy") else {
            continue;
        };
        let array = parse_npy(&data).map_err(|msg| err(format!("entry {name}: {msg}")))?;
        arrays.push((stem.to_string(), array));
    }
    Ok(arrays)
}

/// Writes `arrays` as a `.npz` archive (what `np.savez` makes), atomically.
/// Each array becomes the entry `<name>.npy`.
pub fn write_npz(path: &Path, arrays: &[(&str, &NpyArray)]) -> Result<()> {
    let bytes = try_npz_bytes(arrays).map_err(|msg| IoError::Npz {
        path: path.to_path_buf(),
        msg: format!("cannot write: {msg}"),
    })?;
    write_atomic(path, &bytes)
}

/// `arrays` as the bytes of a `.npz` archive: entries stored uncompressed, in
/// the given order, with fixed timestamps, so the bytes depend only on the arrays.
///
/// # Panics
/// If an array's shape does not match its data, two arrays share a name, or a
/// name is empty.
/// [`write_npz`] returns these as errors instead.
pub fn npz_bytes(arrays: &[(&str, &NpyArray)]) -> Vec<u8> {
    try_npz_bytes(arrays).unwrap_or_else(|msg| panic!("npz_bytes: {msg}"))
}

fn try_npz_bytes(arrays: &[(&str, &NpyArray)]) -> std::result::Result<Vec<u8>, String> {
    let mut entries = Vec::with_capacity(arrays.len());
    for (i, (name, array)) in arrays.iter().enumerate() {
        if name.is_empty() {
            return Err(format!("array {i} has an empty name"));
        }
        if arrays[..i].iter().any(|(other, _)| other == name) {
            return Err(format!("two arrays are named '{name}'"));
        }
        check_array(array).map_err(|msg| format!("array '{name}': {msg}"))?;
        entries.push((format!("{name}.npy"), npy_bytes(array)));
    }
    write_zip(&entries)
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })
}

/// Reads the entries of a ZIP archive: (name, uncompressed data), directories left out.
fn read_zip(b: &[u8]) -> std::result::Result<Vec<(String, Vec<u8>)>, String> {
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(b)).map_err(|e| {
        if b.starts_with(b"PK\x03\x04") {
            format!("truncated or damaged ZIP archive (it begins as one): {e}")
        } else {
            format!("not a ZIP archive: {e}")
        }
    })?;
    let mut entries = Vec::with_capacity(archive.len().min(1 << 16));
    for k in 0..archive.len() {
        let label = archive.name_for_index(k).map_or(format!("{k}"), str::to_string);
        let mut entry = archive.by_index(k).map_err(|e| format!("entry {label}: {e}"))?;
        if entry.is_dir() {
            continue;
        }
        let name = entry.name().to_string();
        let size = entry.size();
        // Grown as it is read (a damaged directory may claim any size), and no further than it claims.
        let mut data = Vec::new();
        std::io::Read::read_to_end(&mut std::io::Read::take(&mut entry, size.saturating_add(1)), &mut data)
            .map_err(|e| format!("entry {name}: {e}"))?;
        if data.len() as u64 != size {
            return Err(format!(
                "entry {name}: holds {} bytes, the directory says {size}",
                data.len()
            ));
        }
        entries.push((name, data));
    }
    Ok(entries)
}

/// Writes a ZIP archive of stored entries dated 1980-01-01 00:00, so the bytes depend only on the entries.
fn write_zip(entries: &[(String, Vec<u8>)]) -> std::result::Result<Vec<u8>, String> {
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .last_modified_time(zip::DateTime::default())
        .large_file(entries.iter().any(|(_, d)| d.len() as u64 >= u32::MAX as u64));
    for (name, data) in entries {
        zip.start_file(name.as_str(), options)
            .map_err(|e| format!("entry {name}: {e}"))?;
        std::io::Write::write_all(&mut zip, data).map_err(|e| format!("entry {name}: {e}"))?;
    }
    Ok(zip.finish().map_err(|e| e.to_string())?.into_inner())
}
