//! PLY meshes and point clouds (Turk's format, as written by Blender, MeshLab,
//! Open3D and trimesh).
//!
//! Reading accepts ASCII and binary of either byte order, elements in any
//! order, and skips elements and properties it does not use, lists included.
//! Writing produces `float` positions (optionally `double`), optional `uchar`
//! colours and `float` normals, and `uchar`-count `int`-index faces.

use std::path::Path;

use geom::TriMesh;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};

/// A mesh (or point cloud, when `faces` is empty) with optional per-vertex data.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyMesh {
    /// Positions and triangles. Polygons in the file are fan-triangulated.
    pub mesh: TriMesh,
    /// Per-vertex colour, one per vertex, if the file has `red`, `green`, `blue`.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Per-vertex normal, one per vertex, if the file has `nx`, `ny`, `nz`.
    pub normals: Option<Vec<[f32; 3]>>,
}

impl PlyMesh {
    /// A mesh without colours or normals.
    pub fn from_mesh(mesh: TriMesh) -> Self {
        Self {
            mesh,
            colors: None,
            normals: None,
        }
    }
}

/// How a PLY file's body is encoded when writing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `binary_little_endian`: compact and exact for `float`; the project default.
    #[default]
    BinaryLittleEndian,
    /// `ascii`: readable, larger.
    Ascii,
}

/// Options of [`write_ply_with`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlyWriteOptions {
    /// Body encoding. Default: binary little-endian.
    pub encoding: PlyEncoding,
    /// Write positions as `double` instead of `float`. Default: `false`, since
    /// `float` is what most PLY readers expect.
    pub positions_f64: bool,
}

/// Reads a PLY file. See [`read_ply_bytes`].
pub fn read_ply(path: &Path) -> Result<PlyMesh> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })?;
    read_ply_bytes(&bytes, path)
}

/// Parses a PLY file already in memory; `path` is only used in errors.
///
/// Vertices need `x`, `y`, `z` of any scalar type. Faces are read from a list
/// property named `vertex_indices` or `vertex_index`; faces with fewer than
/// three corners are dropped. A file without a `face` element is a point cloud.
pub fn read_ply_bytes(bytes: &[u8], path: &Path) -> Result<PlyMesh> {
    let ply = parse(bytes).map_err(|msg| IoError::Ply {
        path: path.to_path_buf(),
        msg,
    })?;
    super::mesh_file::check_finite_vertices(&ply.mesh, path)?;
    Ok(ply)
}

/// Writes `mesh` to `path` atomically, with default options but `encoding`.
pub fn write_ply(path: &Path, mesh: &PlyMesh, encoding: PlyEncoding) -> Result<()> {
    let opts = PlyWriteOptions {
        encoding,
        ..Default::default()
    };
    write_ply_with(path, mesh, &opts)
}

/// Writes `mesh` to `path` atomically. Checks first that colours and normals
/// have one entry per vertex and that faces index existing vertices.
pub fn write_ply_with(path: &Path, mesh: &PlyMesh, opts: &PlyWriteOptions) -> Result<()> {
    check_for_writing(mesh).map_err(|(field, msg)| IoError::Invalid {
        path: path.to_path_buf(),
        field: field.to_string(),
        msg,
    })?;
    write_atomic(path, &write_ply_bytes_with(mesh, opts))
}

/// Encodes `mesh` as a PLY file with `float` positions.
///
/// # Panics
/// If `colors` or `normals` is present with a length other than the vertex count.
pub fn write_ply_bytes(mesh: &PlyMesh, encoding: PlyEncoding) -> Vec<u8> {
    let opts = PlyWriteOptions {
        encoding,
        ..Default::default()
    };
    write_ply_bytes_with(mesh, &opts)
}

/// Encodes `mesh` as a PLY file.
///
/// # Panics
/// If `colors` or `normals` is present with a length other than the vertex count.
pub fn write_ply_bytes_with(mesh: &PlyMesh, opts: &PlyWriteOptions) -> Vec<u8> {
    let n = mesh.mesh.vertices.len();
    let colors = mesh.colors.as_deref();
    let normals = mesh.normals.as_deref();
    if let Some(c) = colors {
        assert_eq!(c.len(), n, "PlyMesh has {} colours for {n} vertices", c.len());
    }
    if let Some(nr) = normals {
        assert_eq!(nr.len(), n, "PlyMesh has {} normals for {n} vertices", nr.len());
    }

    let ascii = opts.encoding == PlyEncoding::Ascii;
    let pos_type = if opts.positions_f64 { "double" } else { "float" };
    let mut h = String::from("ply\n");
    h += if ascii {
        "format ascii 1.0\n"
    } else {
        "format binary_little_endian 1.0\n"
    };
    h += "comment written by pganeus\n";
    h += &format!("element vertex {n}\n");
    for c in ["x", "y", "z"] {
        h += &format!("property {pos_type} {c}\n");
    }
    if normals.is_some() {
        h += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if colors.is_some() {
        h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    // No face element at all for a point cloud, which is what point-cloud tools expect.
    let faces = &mesh.mesh.faces;
    if !faces.is_empty() {
        h += &format!("element face {}\n", faces.len());
        h += "property list uchar int vertex_indices\n";
    }
    h += "end_header\n";

    let mut out = h.into_bytes();
    if ascii {
        use std::fmt::Write;
        let mut s = String::new();
        for (i, p) in mesh.mesh.vertices.iter().enumerate() {
            if opts.positions_f64 {
                let _ = write!(s, "{} {} {}", p[0], p[1], p[2]);
            } else {
                let _ = write!(s, "{} {} {}", p[0] as f32, p[1] as f32, p[2] as f32);
            }
            if let Some(nr) = normals {
                let [a, b, c] = nr[i];
                let _ = write!(s, " {a} {b} {c}");
            }
            if let Some(col) = colors {
                let [r, g, b] = col[i];
                let _ = write!(s, " {r} {g} {b}");
            }
            s.push('\n');
        }
        for [a, b, c] in faces {
            let _ = writeln!(s, "3 {a} {b} {c}");
        }
        out.extend_from_slice(s.as_bytes());
    } else {
        let stride = if opts.positions_f64 { 24 } else { 12 }
            + if normals.is_some() { 12 } else { 0 }
            + if colors.is_some() { 3 } else { 0 };
        out.reserve(n * stride + faces.len() * 13);
        for (i, p) in mesh.mesh.vertices.iter().enumerate() {
            for &x in p {
                if opts.positions_f64 {
                    out.extend_from_slice(&x.to_le_bytes());
                } else {
                    out.extend_from_slice(&(x as f32).to_le_bytes());
                }
            }
            if let Some(nr) = normals {
                for x in nr[i] {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
            if let Some(col) = colors {
                out.extend_from_slice(&col[i]);
            }
        }
        for f in faces {
            out.push(3);
            for &v in f {
                // `int` indices: checked < vertex count, which fits in i32 in practice.
                out.extend_from_slice(&(v as i32).to_le_bytes());
            }
        }
    }
    out
}

/// `(field, message)` of the first problem that would make the file wrong.
fn check_for_writing(mesh: &PlyMesh) -> std::result::Result<(), (&'static str, String)> {
    let n = mesh.mesh.vertices.len();
    if let Some(c) = &mesh.colors {
        if c.len() != n {
            return Err(("colors", format!("{} colours for {n} vertices", c.len())));
        }
    }
    if let Some(nr) = &mesh.normals {
        if nr.len() != n {
            return Err(("normals", format!("{} normals for {n} vertices", nr.len())));
        }
    }
    if n > i32::MAX as usize {
        return Err(("vertices", format!("{n} vertices do not fit PLY `int` indices")));
    }
    for (f, face) in mesh.mesh.faces.iter().enumerate() {
        if let Some(&v) = face.iter().find(|&&v| v as usize >= n) {
            return Err((
                "faces",
                format!("face {f} refers to vertex {v} but there are {n} vertices"),
            ));
        }
    }
    Ok(())
}

// ---------------------------------------------------------------- header

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Self::F32 | Self::F64)
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

impl Element {
    fn find(&self, names: &[&str]) -> Option<usize> {
        self.props.iter().position(|p| names.contains(&p.name.as_str()))
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    BinaryLe,
    BinaryBe,
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Offset of the first byte after `end_header`'s line end.
    body_start: usize,
}

fn parse_header(bytes: &[u8]) -> std::result::Result<Header, String> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(if line_no == 0 {
                "empty file, or no line end after the first line".into()
            } else {
                "the header has no `end_header` line (file truncated, or not PLY)".into()
            });
        };
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        line_no += 1;
        let line = std::str::from_utf8(raw)
            .map_err(|_| format!("header line {line_no} is not text"))?
            .trim_end_matches('\r');
        let words: Vec<&str> = line.split_whitespace().collect();
        if line_no == 1 {
            if line.trim() != "ply" {
                return Err("not a PLY file: the first line is not `ply`".into());
            }
            continue;
        }
        let bad = |what: &str| format!("header line {line_no} `{line}`: {what}");
        match words.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                format = Some(match words.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::BinaryLe,
                    Some("binary_big_endian") => Format::BinaryBe,
                    _ => return Err(bad("unknown format")),
                });
            }
            Some("element") => {
                let [_, name, count] = words[..] else {
                    return Err(bad("expected `element <name> <count>`"));
                };
                let count = count
                    .parse()
                    .map_err(|_| bad("the count is not a non-negative integer"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let kind;
                let name;
                if words.get(1) == Some(&"list") {
                    let [_, _, ct, it, n] = words[..] else {
                        return Err(bad("expected `property list <count type> <type> <name>`"));
                    };
                    let count = Scalar::parse(ct).ok_or_else(|| bad("unknown count type"))?;
                    if count.is_float() {
                        return Err(bad("a list count must have an integer type"));
                    }
                    let item = Scalar::parse(it).ok_or_else(|| bad("unknown item type"))?;
                    kind = Kind::List { count, item };
                    name = n;
                } else {
                    let [_, t, n] = words[..] else {
                        return Err(bad("expected `property <type> <name>`"));
                    };
                    kind = Kind::Scalar(Scalar::parse(t).ok_or_else(|| bad("unknown type"))?);
                    name = n;
                }
                let el = elements
                    .last_mut()
                    .ok_or_else(|| bad("a property before any element"))?;
                el.props.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            Some("end_header") => break,
            Some(_) => return Err(bad("unknown keyword")),
        }
    }
    let format = format.ok_or("the header has no `format` line")?;
    Ok(Header {
        format,
        elements,
        body_start: pos,
    })
}

// ---------------------------------------------------------------- body

/// A stream of numbers, whatever the encoding.
trait Values {
    fn next(&mut self, t: Scalar) -> std::result::Result<f64, String>;

    fn skip(&mut self, t: Scalar, n: usize) -> std::result::Result<(), String> {
        for _ in 0..n {
            self.next(t)?;
        }
        Ok(())
    }

    /// Bytes left, to bound allocations made from header counts.
    fn remaining(&self) -> usize;
}

struct AsciiValues<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Values for AsciiValues<'_> {
    fn next(&mut self, t: Scalar) -> std::result::Result<f64, String> {
        let b = self.bytes;
        while self.pos < b.len() && b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < b.len() && !b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err("the file ends early".into());
        }
        let tok = std::str::from_utf8(&b[start..self.pos]).unwrap_or("?");
        let bad = || format!("`{tok}` is not a number");
        if t == Scalar::F32 {
            // Parsed as f32 directly: going through f64 could round twice.
            tok.parse::<f32>().map(f64::from).map_err(|_| bad())
        } else if t == Scalar::F64 {
            tok.parse::<f64>().map_err(|_| bad())
        } else {
            // Some writers put `1.0` in integer columns; accept it when it is integral.
            match tok.parse::<i64>() {
                Ok(i) => Ok(i as f64),
                Err(_) => tok.parse::<f64>().ok().filter(|x| x.fract() == 0.0).ok_or_else(bad),
            }
        }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

struct BinaryValues<'a> {
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl BinaryValues<'_> {
    fn take<const N: usize>(&mut self) -> std::result::Result<[u8; N], String> {
        let end = self.pos + N;
        let s = self.bytes.get(self.pos..end).ok_or("the file ends early")?;
        self.pos = end;
        let mut a: [u8; N] = s.try_into().expect("slice of length N");
        if self.big_endian {
            a.reverse();
        }
        Ok(a)
    }
}

impl Values for BinaryValues<'_> {
    fn next(&mut self, t: Scalar) -> std::result::Result<f64, String> {
        // `take` has turned the bytes little-endian.
        Ok(match t {
            Scalar::I8 => i8::from_le_bytes(self.take()?) as f64,
            Scalar::U8 => u8::from_le_bytes(self.take()?) as f64,
            Scalar::I16 => i16::from_le_bytes(self.take()?) as f64,
            Scalar::U16 => u16::from_le_bytes(self.take()?) as f64,
            Scalar::I32 => i32::from_le_bytes(self.take()?) as f64,
            Scalar::U32 => u32::from_le_bytes(self.take()?) as f64,
            Scalar::F32 => f32::from_le_bytes(self.take()?) as f64,
            Scalar::F64 => f64::from_le_bytes(self.take()?),
        })
    }

    fn skip(&mut self, t: Scalar, n: usize) -> std::result::Result<(), String> {
        let end = n
            .checked_mul(t.size())
            .and_then(|len| self.pos.checked_add(len))
            .filter(|&end| end <= self.bytes.len())
            .ok_or("the file ends early")?;
        self.pos = end;
        Ok(())
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

fn parse(bytes: &[u8]) -> std::result::Result<PlyMesh, String> {
    let header = parse_header(bytes)?;
    let body = &bytes[header.body_start..];
    match header.format {
        Format::Ascii => read_body(&header, AsciiValues { bytes: body, pos: 0 }),
        Format::BinaryLe | Format::BinaryBe => read_body(
            &header,
            BinaryValues {
                bytes: body,
                pos: 0,
                big_endian: header.format == Format::BinaryBe,
            },
        ),
    }
}

/// Where the vertex element keeps what we read.
struct VertexLayout {
    xyz: [usize; 3],
    normal: Option<[usize; 3]>,
    color: Option<([usize; 3], Scalar)>,
}

fn vertex_layout(el: &Element) -> std::result::Result<VertexLayout, String> {
    let scalar = |name: &str| -> std::result::Result<Option<(usize, Scalar)>, String> {
        match el.find(&[name]) {
            None => Ok(None),
            Some(i) => match el.props[i].kind {
                Kind::Scalar(t) => Ok(Some((i, t))),
                Kind::List { .. } => Err(format!("vertex property `{name}` is a list")),
            },
        }
    };
    let three = |names: [&str; 3]| -> std::result::Result<Option<[(usize, Scalar); 3]>, String> {
        match (scalar(names[0])?, scalar(names[1])?, scalar(names[2])?) {
            (Some(a), Some(b), Some(c)) => Ok(Some([a, b, c])),
            _ => Ok(None),
        }
    };
    let mut xyz = [0; 3];
    for (k, name) in ["x", "y", "z"].into_iter().enumerate() {
        xyz[k] = scalar(name)?
            .ok_or_else(|| format!("the vertex element has no `{name}` property"))?
            .0;
    }
    let normal = three(["nx", "ny", "nz"])?.map(|a| a.map(|(i, _)| i));
    let color = three(["red", "green", "blue"])?.map(|a| (a.map(|(i, _)| i), a[0].1));
    Ok(VertexLayout { xyz, normal, color })
}

/// A colour channel of any type to 0..=255: floats are in [0, 1], `ushort` in 0..=65535.
fn color_channel(x: f64, t: Scalar) -> u8 {
    let v = match t {
        Scalar::F32 | Scalar::F64 => x * 255.0,
        Scalar::U16 => x / 257.0,
        _ => x,
    };
    v.round().clamp(0.0, 255.0) as u8
}

fn read_body<V: Values>(header: &Header, mut src: V) -> std::result::Result<PlyMesh, String> {
    let mut vertex_el = None;
    let mut face_el = None;
    for (i, el) in header.elements.iter().enumerate() {
        let slot = match el.name.as_str() {
            "vertex" => &mut vertex_el,
            "face" => &mut face_el,
            _ => continue,
        };
        if slot.is_some() {
            return Err(format!("two `{}` elements", el.name));
        }
        *slot = Some(i);
    }
    let vertex_el = vertex_el.ok_or("no `vertex` element")?;
    let n_vertices = header.elements[vertex_el].count;
    let layout = vertex_layout(&header.elements[vertex_el])?;
    let face_prop = match face_el {
        None => None,
        Some(f) => {
            let el = &header.elements[f];
            let p = el
                .find(&["vertex_indices", "vertex_index"])
                .ok_or("the face element has no `vertex_indices` list")?;
            let Kind::List { .. } = el.props[p].kind else {
                return Err("the face property `vertex_indices` is not a list".into());
            };
            if n_vertices > u32::MAX as usize {
                return Err(format!("{n_vertices} vertices do not fit 32-bit face indices"));
            }
            Some(p)
        }
    };

    let mut vertices = Vec::new();
    let mut normals = Vec::new();
    let mut colors = Vec::new();
    let mut faces = Vec::new();
    let mut scalars: Vec<f64> = Vec::new();
    let mut corners: Vec<u32> = Vec::new();

    for (e, el) in header.elements.iter().enumerate() {
        if el.props.is_empty() {
            // Nothing to read, however large the count.
            continue;
        }
        let is_vertex = e == vertex_el;
        let is_face = Some(e) == face_el;
        // Each instance takes at least one byte, so this bounds the reservation.
        let reserve = el.count.min(src.remaining());
        if is_vertex {
            vertices.reserve(reserve);
            if layout.normal.is_some() {
                normals.reserve(reserve);
            }
            if layout.color.is_some() {
                colors.reserve(reserve);
            }
        } else if is_face {
            faces.reserve(reserve);
        }
        scalars.resize(el.props.len(), 0.0);
        for k in 0..el.count {
            let at = || format!("element `{}` #{k} (of {})", el.name, el.count);
            for (p, prop) in el.props.iter().enumerate() {
                match prop.kind {
                    Kind::Scalar(t) => {
                        scalars[p] = src
                            .next(t)
                            .map_err(|m| format!("{}, property `{}`: {m}", at(), prop.name))?;
                    }
                    Kind::List { count, item } => {
                        let err = |m: String| format!("{}, list `{}`: {m}", at(), prop.name);
                        let c = src.next(count).map_err(err)?;
                        if c < 0.0 {
                            return Err(err(format!("negative count {c}")));
                        }
                        let c = c as usize;
                        if is_face && Some(p) == face_prop {
                            corners.clear();
                            for _ in 0..c {
                                let v = src.next(item).map_err(err)?;
                                if !(v >= 0.0 && v < n_vertices as f64 && v.fract() == 0.0) {
                                    return Err(err(format!(
                                        "vertex index {v} out of range: the file has \
                                         {n_vertices} vertices"
                                    )));
                                }
                                corners.push(v as u32);
                            }
                            // Fan triangulation; faces with < 3 corners give nothing.
                            for j in 1..c.saturating_sub(1) {
                                faces.push([corners[0], corners[j], corners[j + 1]]);
                            }
                        } else {
                            src.skip(item, c).map_err(err)?;
                        }
                    }
                }
            }
            if is_vertex {
                let [x, y, z] = layout.xyz;
                vertices.push([scalars[x], scalars[y], scalars[z]]);
                if let Some([a, b, c]) = layout.normal {
                    normals.push([scalars[a] as f32, scalars[b] as f32, scalars[c] as f32]);
                }
                if let Some(([r, g, b], t)) = layout.color {
                    colors.push([
                        color_channel(scalars[r], t),
                        color_channel(scalars[g], t),
                        color_channel(scalars[b], t),
                    ]);
                }
            }
        }
    }
    Ok(PlyMesh {
        mesh: TriMesh { vertices, faces },
        colors: layout.color.map(|_| colors),
        normals: layout.normal.map(|_| normals),
    })
}
