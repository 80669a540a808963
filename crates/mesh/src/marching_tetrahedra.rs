//! The zero level of a scalar field sampled on a regular grid, by marching
//! tetrahedra.
//!
//! Each grid cube is split into the 6 tetrahedra of the Kuhn (Freudenthal)
//! triangulation, which share the cube's main diagonal from its lowest to its
//! highest corner. Translated copies of that split agree on every shared cube
//! face, so the surface closes up across cubes. Inside a tetrahedron the field
//! is taken as linear: each edge whose ends differ in sign (negative = inside,
//! zero and above = outside) carries one vertex at the linear crossing, shared
//! by every triangle that uses that grid edge, and the tetrahedron emits one
//! triangle (one corner apart) or a quad split along its shorter diagonal
//! (two and two). Triangles are oriented by the tetrahedron's parity, never by
//! the interpolated positions, so their normals point towards positive values
//! (outward for a signed distance) even where vertices coincide.
//!
//! Vertices coincide where the field is exactly zero at a grid point (a box
//! whose faces lie on grid planes, say): every edge from a negative neighbour
//! puts its vertex on that point. Such zero-length edges are collapsed
//! afterwards wherever the collapse keeps the surface a manifold (the link
//! condition, `collapse_coincident.rs`), which removes the zero-area
//! triangles without opening the mesh. Where the negative region touches
//! itself at a zero grid point, welding would pinch the surface, and the
//! zero-area triangles there stay (the mesh stays closed).
//!
//! Work is split into slabs of cube layers along z, run in parallel; vertices
//! on the planes between slabs are merged by grid edge. The split depends on
//! the grid size only, so the output is the same for any number of threads.

use std::collections::HashMap;

use geom::TriMesh;
use rayon::prelude::*;

use crate::collapse_coincident::collapse_coincident_vertices;

/// A scalar field sampled at the points `origin + spacing · (i, j, k)`,
/// `0 ≤ i < dims[0]` and so on.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarGrid {
    /// The position of grid point `(0, 0, 0)`.
    pub origin: [f64; 3],
    /// Distance between neighbouring grid points, the same on every axis.
    pub spacing: f64,
    /// Number of grid points along x, y and z.
    pub dims: [usize; 3],
    /// The samples, x fastest: point `(i, j, k)` is at `i + dims[0] · (j + dims[1] · k)`.
    pub values: Vec<f32>,
}

/// Why a [`ScalarGrid`] cannot be built from its parts.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The number of values is not the number of grid points.
    #[error("{found} values for a grid of {dims:?} points (expected {expected})")]
    ValueCount {
        /// Grid points along x, y, z.
        dims: [usize; 3],
        /// `dims[0] · dims[1] · dims[2]`, or `usize::MAX` on overflow.
        expected: usize,
        /// The number of values given.
        found: usize,
    },
    /// The spacing is zero, negative or not finite.
    #[error("grid spacing {0} is not a positive finite number")]
    Spacing(f64),
    /// The origin has a NaN or infinite coordinate.
    #[error("grid origin {0:?} is not finite")]
    Origin([f64; 3]),
}

impl ScalarGrid {
    /// A grid from its parts, checked: as many values as points, a positive
    /// finite spacing and a finite origin.
    pub fn new(origin: [f64; 3], spacing: f64, dims: [usize; 3], values: Vec<f32>) -> Result<Self, GridError> {
        let grid = Self {
            origin,
            spacing,
            dims,
            values,
        };
        let expected = grid.point_count().unwrap_or(usize::MAX);
        if expected != grid.values.len() {
            return Err(GridError::ValueCount {
                dims,
                expected,
                found: grid.values.len(),
            });
        }
        if !(spacing > 0.0 && spacing.is_finite()) {
            return Err(GridError::Spacing(spacing));
        }
        if origin.iter().any(|c| !c.is_finite()) {
            return Err(GridError::Origin(origin));
        }
        Ok(grid)
    }

    /// The position of grid point `(i, j, k)`. Every part of this crate
    /// computes grid positions here, so equal points give equal bits.
    pub fn point(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.origin[0] + i as f64 * self.spacing,
            self.origin[1] + j as f64 * self.spacing,
            self.origin[2] + k as f64 * self.spacing,
        ]
    }

    /// The value at grid point `(i, j, k)`.
    pub fn value(&self, i: usize, j: usize, k: usize) -> f32 {
        self.values[self.index(i, j, k)]
    }

    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// The grid point count the dims ask for (`None` on overflow).
    fn point_count(&self) -> Option<usize> {
        self.dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d))
    }
}

/// Cube corner `c` (bits: x = 1, y = 2, z = 4) as an offset.
const fn corner_offset(c: usize) -> [usize; 3] {
    [c & 1, (c >> 1) & 1, (c >> 2) & 1]
}

/// The 6 tetrahedra of a cube, as cube corners. Each is a chain from corner 0
/// to corner 7 through one, then two axes (the permutation `(a, b, c)`); for
/// odd permutations the last two corners are swapped so that every
/// tetrahedron is positively oriented (checked by a unit test).
const TETS: [[usize; 4]; 6] = [
    [0, 1, 3, 7], // x, y, z (even)
    [0, 2, 6, 7], // y, z, x (even)
    [0, 4, 5, 7], // z, x, y (even)
    [0, 1, 7, 5], // x, z, y (odd)
    [0, 2, 7, 3], // y, x, z (odd)
    [0, 4, 7, 6], // z, y, x (odd)
];

/// The triangles one tetrahedron emits for each sign pattern, as edges
/// `(a, b)` between tetrahedron corners `0..4` (`a` negative, `b` not).
#[derive(Clone, Copy, Debug, Default)]
struct TetCase {
    /// 0, 1 (a triangle) or 2 (a quad, in cyclic order).
    kind: u8,
    edges: [(u8, u8); 4],
}

/// Whether `(p[0], p[1], p[2], p[3])` is an even permutation of `(0, 1, 2, 3)`.
fn is_even(p: [usize; 4]) -> bool {
    let mut inversions = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            inversions += usize::from(p[i] > p[j]);
        }
    }
    inversions % 2 == 0
}

/// The case table over the 16 sign patterns (bit `i` set: corner `i` negative).
///
/// For a positively oriented tetrahedron `(i, j, k, l)` (an even permutation
/// of its corners), the triangle on edges `ij, ik, il` has its normal pointing
/// away from `i`; the quad on `ik, il, jl, jk` has its normal pointing from
/// the edge `ij` to the edge `kl`. Those two facts give every case.
fn tet_cases() -> [TetCase; 16] {
    let mut cases = [TetCase::default(); 16];
    for (mask, case) in cases.iter_mut().enumerate() {
        let neg: Vec<usize> = (0..4).filter(|&c| mask & (1 << c) != 0).collect();
        let pos: Vec<usize> = (0..4).filter(|&c| mask & (1 << c) == 0).collect();
        let e = |a: usize, b: usize| (a as u8, b as u8);
        // The other three corners after `i`, in an order that makes the permutation even.
        let rest = |i: usize| {
            let mut r: Vec<usize> = (0..4).filter(|&c| c != i).collect();
            if !is_even([i, r[0], r[1], r[2]]) {
                r.swap(1, 2);
            }
            r
        };
        match neg.len() {
            1 => {
                let i = neg[0];
                let r = rest(i);
                // Normal away from the negative corner.
                *case = TetCase {
                    kind: 1,
                    edges: [e(i, r[0]), e(i, r[1]), e(i, r[2]), (0, 0)],
                };
            }
            3 => {
                let i = pos[0];
                let r = rest(i);
                // Normal towards the positive corner: the reversed triangle.
                *case = TetCase {
                    kind: 1,
                    edges: [e(r[0], i), e(r[2], i), e(r[1], i), (0, 0)],
                };
            }
            2 => {
                let (i, j) = (neg[0], neg[1]);
                let (mut k, mut l) = (pos[0], pos[1]);
                if !is_even([i, j, k, l]) {
                    std::mem::swap(&mut k, &mut l);
                }
                *case = TetCase {
                    kind: 2,
                    edges: [e(i, k), e(i, l), e(j, l), e(j, k)],
                };
            }
            _ => {}
        }
    }
    cases
}

/// Number of cube layers per slab. Fixed by the grid alone (never by the
/// thread count), so the output does not depend on the machine.
fn slab_layers(grid: &ScalarGrid) -> usize {
    // About 64k cubes per slab, and at least 2 layers.
    let layer = (grid.dims[0] - 1) * (grid.dims[1] - 1);
    (65_536 / layer.max(1)).max(2)
}

/// The zero level of `grid` as a triangle mesh (see the module docs), with
/// normals pointing towards positive values. Values below zero are inside;
/// zero, positive and NaN values are outside. A grid with no sign change, or
/// fewer than 2 points along an axis, gives an empty mesh. Where the zero
/// level reaches the edge of the grid the mesh is open there; elsewhere it is
/// closed and consistently oriented. Zero-area triangles are left only where
/// the field is exactly 0 at a grid point and removing them would pinch the
/// surface (module docs).
///
/// # Panics
/// If `values.len()` is not `dims[0] · dims[1] · dims[2]`, or the mesh would
/// have more than `u32::MAX` vertices.
pub fn extract_zero_level(grid: &ScalarGrid) -> TriMesh {
    assert_eq!(
        grid.point_count(),
        Some(grid.values.len()),
        "extract_zero_level: {} values for a grid of {:?} points",
        grid.values.len(),
        grid.dims
    );
    if grid.dims.iter().any(|&d| d < 2) {
        return TriMesh::default();
    }
    let cases = tet_cases();
    let cube_layers = grid.dims[2] - 1;
    let per_slab = slab_layers(grid);
    let slabs: Vec<(usize, usize)> = (0..cube_layers)
        .step_by(per_slab)
        .map(|z0| (z0, (z0 + per_slab).min(cube_layers)))
        .collect();
    let parts: Vec<SlabMesh> = slabs
        .par_iter()
        .map(|&(z0, z1)| extract_slab(grid, &cases, z0, z1))
        .collect();
    let (mut vertices, mut faces) = merge_slabs(grid, parts);
    collapse_coincident_vertices(&mut vertices, &mut faces);
    TriMesh::new(vertices, faces)
}

/// The surface of one slab of cube layers, with vertices keyed by grid edge.
struct SlabMesh {
    /// Grid edge of each vertex: `base point index · 8 + direction` (the
    /// direction as corner bits, 1..=7).
    keys: Vec<u64>,
    vertices: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    /// The grid plane `z` at the top of the slab, shared with the next slab.
    top: u64,
}

/// The vertex of grid edge `(a, b)` with `a` negative and `b` not: the linear
/// crossing, written `(1 − t) a + t b` so that `t = 1` lands exactly on `b`.
fn crossing(pa: [f64; 3], va: f32, pb: [f64; 3], vb: f32) -> [f64; 3] {
    let (va, vb) = (va as f64, vb as f64);
    let t = va / (va - vb);
    // Infinite values give NaN; put those crossings half way.
    let t = if t.is_nan() { 0.5 } else { t.clamp(0.0, 1.0) };
    [0, 1, 2].map(|c| (1.0 - t) * pa[c] + t * pb[c])
}

fn extract_slab(grid: &ScalarGrid, cases: &[TetCase; 16], z0: usize, z1: usize) -> SlabMesh {
    let [nx, ny, _] = grid.dims;
    let mut out = SlabMesh {
        keys: Vec::new(),
        vertices: Vec::new(),
        faces: Vec::new(),
        top: z1 as u64,
    };
    let mut by_edge: HashMap<u64, u32> = HashMap::new();
    // Grid point index of each cube corner relative to the cube's base.
    let corner_delta: [usize; 8] = std::array::from_fn(|c| {
        let [dx, dy, dz] = corner_offset(c);
        dx + nx * (dy + ny * dz)
    });
    for k in z0..z1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let base = grid.index(i, j, k);
                let v: [f32; 8] = std::array::from_fn(|c| grid.values[base + corner_delta[c]]);
                let neg = v.iter().filter(|&&x| x < 0.0).count();
                if neg == 0 || neg == 8 {
                    continue;
                }
                for tet in &TETS {
                    let mask = (0..4).fold(0usize, |m, t| m | (usize::from(v[tet[t]] < 0.0) << t));
                    let case = &cases[mask];
                    if case.kind == 0 {
                        continue;
                    }
                    let n = if case.kind == 1 { 3 } else { 4 };
                    let mut ids = [0u32; 4];
                    for (slot, &(a, b)) in case.edges[..n].iter().enumerate() {
                        let (ca, cb) = (tet[a as usize], tet[b as usize]);
                        // The grid edge runs from the lower corner (a subset of the other's bits).
                        let (lo, hi) = if ca & cb == ca { (ca, cb) } else { (cb, ca) };
                        let key = ((base + corner_delta[lo]) as u64) << 3 | (hi ^ lo) as u64;
                        ids[slot] = *by_edge.entry(key).or_insert_with(|| {
                            let at = |c: usize| {
                                let [dx, dy, dz] = corner_offset(c);
                                grid.point(i + dx, j + dy, k + dz)
                            };
                            out.keys.push(key);
                            out.vertices.push(crossing(at(ca), v[ca], at(cb), v[cb]));
                            (out.vertices.len() - 1) as u32
                        });
                    }
                    if n == 3 {
                        out.faces.push([ids[0], ids[1], ids[2]]);
                    } else {
                        // Split the quad along its shorter diagonal.
                        let p = |s: usize| out.vertices[ids[s] as usize];
                        if dist_sq(p(0), p(2)) <= dist_sq(p(1), p(3)) {
                            out.faces.push([ids[0], ids[1], ids[2]]);
                            out.faces.push([ids[0], ids[2], ids[3]]);
                        } else {
                            out.faces.push([ids[0], ids[1], ids[3]]);
                            out.faces.push([ids[1], ids[2], ids[3]]);
                        }
                    }
                }
            }
        }
    }
    out
}

fn dist_sq(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).powi(2)).sum()
}

/// Concatenates the slabs in z order. A vertex on a grid edge that an earlier
/// slab already has (edges in the plane between two slabs) takes that slab's
/// index, so each grid edge keeps one vertex.
fn merge_slabs(grid: &ScalarGrid, parts: Vec<SlabMesh>) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let plane = (grid.dims[0] * grid.dims[1]) as u64;
    let total_v: usize = parts.iter().map(|p| p.vertices.len()).sum();
    let total_f: usize = parts.iter().map(|p| p.faces.len()).sum();
    assert!(
        total_v <= u32::MAX as usize,
        "extract_zero_level: {total_v} vertices do not fit u32 indices"
    );
    let mut vertices = Vec::with_capacity(total_v);
    let mut faces = Vec::with_capacity(total_f);
    // Vertices of the previous slab on its top plane, by grid edge.
    let mut top_prev: HashMap<u64, u32> = HashMap::new();
    for part in parts {
        let mut remap = Vec::with_capacity(part.vertices.len());
        let mut top: HashMap<u64, u32> = HashMap::new();
        for (&key, &p) in part.keys.iter().zip(&part.vertices) {
            let id = match top_prev.get(&key) {
                Some(&id) => id,
                None => {
                    vertices.push(p);
                    (vertices.len() - 1) as u32
                }
            };
            // An edge lies in the top plane when its base is there and it does not go up in z.
            if (key >> 3) / plane == part.top && key & 4 == 0 {
                top.insert(key, id);
            }
            remap.push(id);
        }
        faces.extend(part.faces.iter().map(|f| f.map(|v| remap[v as usize])));
        top_prev = top;
    }
    (vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(o: [[f64; 3]; 4]) -> f64 {
        let a = [0, 1, 2].map(|c| o[1][c] - o[0][c]);
        let b = [0, 1, 2].map(|c| o[2][c] - o[0][c]);
        let d = [0, 1, 2].map(|c| o[3][c] - o[0][c]);
        a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0]) + a[2] * (b[0] * d[1] - b[1] * d[0])
    }

    #[test]
    fn tetrahedra_are_positively_oriented_and_fill_the_cube() {
        let mut volume = 0.0;
        for t in TETS {
            let d = det(t.map(|c| corner_offset(c).map(|x| x as f64)));
            assert!(d > 0.0, "{t:?}");
            volume += d / 6.0;
        }
        assert!((volume - 1.0).abs() < 1e-12);
    }

    /// Each case's triangles point from negative to positive corners, checked
    /// geometrically on a regular tetrahedron with crossings at edge midpoints.
    #[test]
    fn case_table_orients_towards_positive() {
        let corners = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(det(corners) > 0.0);
        for (mask, case) in tet_cases().iter().enumerate() {
            let n = match case.kind {
                0 => continue,
                1 => 3,
                _ => 4,
            };
            let mid = |(a, b): (u8, u8)| {
                let (p, q) = (corners[a as usize], corners[b as usize]);
                [0, 1, 2].map(|c| 0.5 * (p[c] + q[c]))
            };
            let pts: Vec<[f64; 3]> = case.edges[..n].iter().map(|&e| mid(e)).collect();
            let (mut neg, mut pos) = ([0.0; 3], [0.0; 3]);
            for c in 0..4 {
                let target = if mask & (1 << c) != 0 { &mut neg } else { &mut pos };
                for a in 0..3 {
                    target[a] += corners[c][a];
                }
            }
            let k = (mask as u32).count_ones() as f64;
            let dir: Vec<f64> = (0..3).map(|a| pos[a] / (4.0 - k) - neg[a] / k).collect();
            let e1 = [0, 1, 2].map(|c| pts[1][c] - pts[0][c]);
            let e2 = [0, 1, 2].map(|c| pts[2][c] - pts[0][c]);
            let nrm = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let dot: f64 = (0..3).map(|a| nrm[a] * dir[a]).sum();
            assert!(dot > 0.0, "mask {mask:04b}: {case:?}");
        }
    }

    /// A sphere cut into slabs of 1, 2, 3 or all layers gives the same surface.
    #[test]
    fn slab_split_does_not_change_the_surface() {
        let n = 12;
        let grid = ScalarGrid {
            origin: [-1.0; 3],
            spacing: 2.0 / (n - 1) as f64,
            dims: [n, n, n],
            values: (0..n * n * n)
                .map(|i| {
                    let p = [i % n, (i / n) % n, i / (n * n)].map(|x| -1.0 + x as f64 * 2.0 / (n - 1) as f64);
                    ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.7) as f32
                })
                .collect(),
        };
        let cases = tet_cases();
        let canonical = |per: usize| {
            let slabs: Vec<SlabMesh> = (0..n - 1)
                .step_by(per)
                .map(|z0| extract_slab(&grid, &cases, z0, (z0 + per).min(n - 1)))
                .collect();
            let (v, f) = merge_slabs(&grid, slabs);
            let mut tris: Vec<[[u64; 3]; 3]> = f
                .iter()
                .map(|t| {
                    let mut c = t.map(|i| v[i as usize].map(f64::to_bits));
                    // Rotate so the smallest corner is first (keeps the winding).
                    let m = (0..3).min_by_key(|&s| c[s]).unwrap();
                    c.rotate_left(m);
                    c
                })
                .collect();
            tris.sort_unstable();
            (v.len(), tris)
        };
        let whole = canonical(n);
        for per in [1, 2, 3] {
            assert_eq!(canonical(per), whole, "slabs of {per}");
        }
    }
}
