//! A signed distance sampled on a dense grid: trilinear value and its exact
//! (piecewise bilinear) gradient, so the simulator never calls a network.
//!
//! File layout (little endian): magic `PGASDF01`, `u32 nx, ny, nz`,
//! `f64 origin[3]`, `f64 spacing`, then `nx·ny·nz` `f32` values, x fastest.

use super::Sdf;
use geom::{Real, Vec3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const MAGIC: &[u8; 8] = b"PGASDF01";

#[derive(Debug, thiserror::Error)]
pub enum GridError {
    #[error("{path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error("{path}: not a pganeus SDF grid: {msg}")]
    Format { path: PathBuf, msg: String },
    #[error("grid bounds are invalid: {0}")]
    Bounds(String),
    #[error(transparent)]
    Mesh(#[from] super::MeshSdfError),
}

#[derive(Clone, Debug)]
pub struct SdfGrid {
    /// Position of node (0, 0, 0).
    origin: [f64; 3],
    /// Distance between neighbouring nodes (the same on every axis).
    spacing: f64,
    /// Node counts, each ≥ 2.
    dims: [usize; 3],
    /// Values, x fastest then y then z.
    values: Vec<f32>,
    /// The far corner (every distance query clamps to it).
    hi: [f64; 3],
    /// Bounds of the gradient's length per block of cells, built on the first [`Sdf::lower_bound_in_ball`].
    slopes: OnceLock<BlockSlopes>,
}

impl PartialEq for SdfGrid {
    fn eq(&self, other: &Self) -> bool {
        (self.origin, self.spacing, self.dims) == (other.origin, other.spacing, other.dims)
            && self.values == other.values
    }
}

/// Cells per block side of [`BlockSlopes`]: a contact cluster (a centimetre or two) spans a few blocks of a
/// reconstructed scene's 3–4 mm cells.
const SLOPE_BLOCK: usize = 4;

/// For each block of `SLOPE_BLOCK`³ cells, a bound on the length of the trilinear interpolant's gradient
/// over it: along each axis the largest difference between neighbouring nodes on the cells' edges (the
/// derivative along an axis interpolates those differences), over the spacing. A baked reconstruction is not
/// an exact distance (its gradient's length strays from 1 away from the surface), so a ball's bound needs
/// the slope of the part of the grid it covers.
#[derive(Clone, Debug)]
struct BlockSlopes {
    blocks: [usize; 3],
    slope: Vec<f64>,
}

impl BlockSlopes {
    fn of(grid: &SdfGrid) -> Self {
        let [nx, ny, nz] = grid.dims;
        let cells = [nx - 1, ny - 1, nz - 1];
        let blocks: [usize; 3] = std::array::from_fn(|a| cells[a].div_ceil(SLOPE_BLOCK));
        let inv_h = 1.0 / grid.spacing;
        // One z-layer of blocks per task; each cell's bound from its twelve edges.
        let slope = (0..blocks[2])
            .into_par_iter()
            .flat_map_iter(|bk| {
                let mut layer = vec![0.0f64; blocks[0] * blocks[1]];
                for k in bk * SLOPE_BLOCK..((bk + 1) * SLOPE_BLOCK).min(cells[2]) {
                    for j in 0..cells[1] {
                        for i in 0..cells[0] {
                            let c = |di, dj, dk| grid.at(i + di, j + dj, k + dk);
                            let mut edge = [0.0f64; 3];
                            for (u, w) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                                edge[0] = edge[0].max((c(1, u, w) - c(0, u, w)).abs());
                                edge[1] = edge[1].max((c(u, 1, w) - c(u, 0, w)).abs());
                                edge[2] = edge[2].max((c(u, w, 1) - c(u, w, 0)).abs());
                            }
                            let cell = (edge[0] * edge[0] + edge[1] * edge[1] + edge[2] * edge[2]).sqrt() * inv_h;
                            let b = &mut layer[i / SLOPE_BLOCK + blocks[0] * (j / SLOPE_BLOCK)];
                            *b = b.max(cell);
                        }
                    }
                }
                layer
            })
            .collect();
        Self { blocks, slope }
    }

    /// The largest bound over the blocks holding the cells `lo..=hi` (cell indices per axis).
    fn max_over(&self, lo: [usize; 3], hi: [usize; 3]) -> f64 {
        let [bx, by, _] = self.blocks;
        let mut m = 0.0f64;
        for k in lo[2] / SLOPE_BLOCK..=hi[2] / SLOPE_BLOCK {
            for j in lo[1] / SLOPE_BLOCK..=hi[1] / SLOPE_BLOCK {
                for i in lo[0] / SLOPE_BLOCK..=hi[0] / SLOPE_BLOCK {
                    m = m.max(self.slope[i + bx * (j + by * k)]);
                }
            }
        }
        m
    }
}

impl SdfGrid {
    /// Sample `sdf` on a grid covering `[min, max]` with node spacing `spacing`.
    pub fn bake(sdf: &(impl Sdf + ?Sized), min: [f64; 3], max: [f64; 3], spacing: f64) -> Result<Self, GridError> {
        let dims = grid_dims(min, max, spacing)?;
        let [nx, ny, _] = dims;
        let values = (0..dims.iter().product::<usize>())
            .into_par_iter()
            .map(|idx| {
                let (i, j, k) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
                let p = [
                    min[0] + i as f64 * spacing,
                    min[1] + j as f64 * spacing,
                    min[2] + k as f64 * spacing,
                ];
                sdf.distance_local(Vec3::<f64>::cst(p)) as f32
            })
            .collect();
        Ok(Self::with(min, spacing, dims, values))
    }

    /// The signed distance of a closed mesh (sign by winding number), on a
    /// grid of `cells` cells along the mesh's longest side, padded by
    /// `pad_cells` cells all round.
    pub fn from_mesh(mesh: &geom::TriMesh, cells: usize, pad_cells: f64) -> Result<Self, GridError> {
        let dist = super::MeshDistance::new(mesh)?;
        let (lo, hi) = mesh.bounds();
        let h = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max) / cells.max(1) as f64;
        let pad = pad_cells * h;
        Self::bake(&dist, lo.map(|v| v - pad), hi.map(|v| v + pad), h)
    }

    /// Build from values computed elsewhere (checks the length).
    pub fn from_values(origin: [f64; 3], spacing: f64, dims: [usize; 3], values: Vec<f32>) -> Result<Self, GridError> {
        if dims.iter().any(|&n| n < 2)
            || values.len() != dims.iter().product::<usize>()
            || !spacing.is_finite()
            || spacing <= 0.0
        {
            return Err(GridError::Bounds(format!(
                "dims {dims:?} with spacing {spacing} do not match {} values",
                values.len()
            )));
        }
        Ok(Self::with(origin, spacing, dims, values))
    }

    /// The grid of checked parts.
    fn with(origin: [f64; 3], spacing: f64, dims: [usize; 3], values: Vec<f32>) -> Self {
        Self {
            origin,
            spacing,
            dims,
            values,
            hi: std::array::from_fn(|a| origin[a] + (dims[a] - 1) as f64 * spacing),
            slopes: OnceLock::new(),
        }
    }

    /// Position of node (0, 0, 0).
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Distance between neighbouring nodes (the same on every axis).
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Node counts, each ≥ 2.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Values, x fastest then y then z.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// The grid blurred by a Gaussian of `sigma` node spacings along each axis (separable). Beyond the
    /// border, values continue linearly (odd reflection about the border node), so a plane's distance, a
    /// linear function, is kept exactly everywhere; detail finer than `sigma` (a reconstruction's
    /// sub-pixel roughness, which tilts contact normals by degrees) is averaged away, and edges round off
    /// over about `sigma`.
    pub fn smoothed(&self, sigma: f64) -> Self {
        if !(sigma > 0.0) {
            return self.clone();
        }
        let radius = (3.0 * sigma).ceil() as isize;
        let kernel: Vec<f64> = (-radius..=radius)
            .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
            .collect();
        let total: f64 = kernel.iter().sum();
        let kernel: Vec<f64> = kernel.iter().map(|w| w / total).collect();
        let mut values: Vec<f64> = self.values.iter().map(|&v| v as f64).collect();
        let [nx, ny, nz] = self.dims;
        let strides = [1, nx, nx * ny];
        for axis in 0..3 {
            let n = self.dims[axis] as isize;
            let stride = strides[axis];
            let lines: Vec<usize> = (0..nx * ny * nz)
                .filter(|&idx| (idx / stride) % self.dims[axis] == 0)
                .collect();
            let src = values.clone();
            let out: Vec<(usize, Vec<f64>)> = lines
                .par_iter()
                .map(|&start| {
                    let at = |i: isize| src[start + i as usize * stride];
                    // Odd reflection: v(−i) = 2 v(0) − v(i), v(n − 1 + i) = 2 v(n − 1) − v(n − 1 − i).
                    let ext = |i: isize| {
                        if i < 0 {
                            2.0 * at(0) - at((-i).min(n - 1))
                        } else if i >= n {
                            2.0 * at(n - 1) - at((2 * (n - 1) - i).max(0))
                        } else {
                            at(i)
                        }
                    };
                    let line = (0..n)
                        .map(|i| {
                            kernel
                                .iter()
                                .enumerate()
                                .map(|(k, w)| w * ext(i + k as isize - radius))
                                .sum()
                        })
                        .collect();
                    (start, line)
                })
                .collect();
            for (start, line) in out {
                for (i, v) in line.into_iter().enumerate() {
                    values[start + i * stride] = v;
                }
            }
        }
        Self::with(
            self.origin,
            self.spacing,
            self.dims,
            values.into_iter().map(|v| v as f32).collect(),
        )
    }

    /// The far corner.
    pub fn max_corner(&self) -> [f64; 3] {
        self.hi
    }

    #[inline]
    fn at(&self, i: usize, j: usize, k: usize) -> f64 {
        self.values[i + self.dims[0] * (j + self.dims[1] * k)] as f64
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(8 + 12 + 32 + 4 * self.values.len());
        b.extend_from_slice(MAGIC);
        for &n in &self.dims {
            b.extend_from_slice(&(n as u32).to_le_bytes());
        }
        for &o in &self.origin {
            b.extend_from_slice(&o.to_le_bytes());
        }
        b.extend_from_slice(&self.spacing.to_le_bytes());
        for &v in &self.values {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b
    }

    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, GridError> {
        let err = |msg: String| GridError::Format {
            path: path.to_path_buf(),
            msg,
        };
        if bytes.len() < 52 || &bytes[..8] != MAGIC {
            return Err(err("missing PGASDF01 header".into()));
        }
        let u = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes")) as usize;
        let f = |o: usize| f64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
        let dims = [u(8), u(12), u(16)];
        let origin = [f(20), f(28), f(36)];
        let spacing = f(44);
        let need = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .and_then(|n| n.checked_mul(4))
            .and_then(|b| b.checked_add(52));
        if need != Some(bytes.len()) {
            return Err(err(format!(
                "dims {dims:?} do not match the file's {} bytes",
                bytes.len()
            )));
        }
        let values: Vec<f32> = bytes[52..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect();
        if values.iter().any(|v| !v.is_finite()) || origin.iter().any(|v| !v.is_finite()) {
            return Err(err("non-finite values".into()));
        }
        Self::from_values(origin, spacing, dims, values).map_err(|e| err(e.to_string()))
    }

    pub fn load(path: &Path) -> Result<Self, GridError> {
        let bytes = std::fs::read(path).map_err(|source| GridError::Io {
            path: path.to_path_buf(),
            cause: source,
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// Write to a temporary file beside `path`, then rename over it.
    pub fn save(&self, path: &Path) -> Result<(), GridError> {
        let io = |source| GridError::Io {
            path: path.to_path_buf(),
            cause: source,
        };
        let tmp = path.with_extension("sdf.tmp");
        std::fs::write(&tmp, self.to_bytes()).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }
}

fn grid_dims(min: [f64; 3], max: [f64; 3], spacing: f64) -> Result<[usize; 3], GridError> {
    if !spacing.is_finite() || spacing <= 0.0 || min.iter().chain(&max).any(|v| !v.is_finite()) {
        return Err(GridError::Bounds(format!("spacing {spacing}, bounds {min:?}..{max:?}")));
    }
    let mut dims = [0; 3];
    for a in 0..3 {
        let ext = max[a] - min[a];
        if ext.is_nan() || ext <= 0.0 {
            return Err(GridError::Bounds(format!("max {max:?} is not above min {min:?}")));
        }
        dims[a] = (ext / spacing).ceil() as usize + 1;
    }
    if dims.iter().product::<usize>() > 512 * 512 * 512 {
        return Err(GridError::Bounds(format!("{dims:?} nodes is more than 512³")));
    }
    Ok(dims)
}

impl Sdf for SdfGrid {
    /// Trilinear interpolation inside the grid; outside, the value at the
    /// nearest point of the grid box plus the distance to it.
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        let hi = self.hi;
        let pa = p.to_array();
        let mut clamped = pa;
        for a in 0..3 {
            clamped[a] = pa[a].clamp(self.origin[a], hi[a]);
        }
        let outside = Vec3::from_array(pa) - Vec3::from_array(clamped);
        let inv_h = 1.0 / self.spacing;
        let mut cell = [0usize; 3];
        let mut u = [S::zero(); 3];
        for a in 0..3 {
            let f = (clamped[a] - self.origin[a]) * inv_h;
            // `f` ≥ 0 (clamped), so the cast is the floor.
            let i = (f.re().max(0.0) as usize).min(self.dims[a] - 2);
            cell[a] = i;
            u[a] = f - i as f64;
        }
        let [i, j, k] = cell;
        let c = |di, dj, dk| self.at(i + di, j + dj, k + dk);
        let (c000, c100, c010, c110) = (c(0, 0, 0), c(1, 0, 0), c(0, 1, 0), c(1, 1, 0));
        let (c001, c101, c011, c111) = (c(0, 0, 1), c(1, 0, 1), c(0, 1, 1), c(1, 1, 1));
        let [x, y, z] = u;
        let one = S::one();
        // Interpolate along x, then y, then z, keeping the pieces for the gradient.
        let lerp = |a: f64, b: f64, t: S| t * (b - a) + a;
        let x00 = lerp(c000, c100, x);
        let x10 = lerp(c010, c110, x);
        let x01 = lerp(c001, c101, x);
        let x11 = lerp(c011, c111, x);
        let y0 = (x10 - x00) * y + x00;
        let y1 = (x11 - x01) * y + x01;
        let d = (y1 - y0) * z + y0;
        let (ym, zm) = (one - y, one - z);
        let dx =
            ((ym * zm) * (c100 - c000) + (y * zm) * (c110 - c010) + (ym * z) * (c101 - c001) + (y * z) * (c111 - c011))
                * inv_h;
        let dy = (zm * (x10 - x00) + z * (x11 - x01)) * inv_h;
        let dz = (y1 - y0) * inv_h;
        let grad = Vec3::new(dx, dy, dz);
        let out_len = outside.norm_sq();
        if out_len.re() > 0.0 {
            // d(clamp(p)) + |p − clamp(p)|: along a clamped axis only the
            // second term changes, along the others only the first.
            let l = out_len.sqrt();
            let mut g = grad;
            for (a, gc) in [&mut g.x, &mut g.y, &mut g.z].into_iter().enumerate() {
                if pa[a].re() < self.origin[a] || pa[a].re() > hi[a] {
                    *gc = S::zero();
                }
            }
            (d + l, g + outside * l.recip())
        } else {
            (d, grad)
        }
    }

    /// The value at the centre less the ball's radius times the steepest slope of the blocks of cells the
    /// ball's clamped box overlaps; where the ball leaves the grid, one more radius for the distance added
    /// outside (that term is 1-Lipschitz, and the clamp moves no point farther than it moves the centre).
    fn lower_bound_in_ball(&self, centre: Vec3<f64>, radius: f64) -> f64 {
        let c = centre.to_array();
        let slopes = self.slopes.get_or_init(|| BlockSlopes::of(self));
        let inside = (0..3).all(|a| c[a] - radius >= self.origin[a] && c[a] + radius <= self.hi[a]);
        let cell = |x: f64, a: usize| {
            let f = (x.clamp(self.origin[a], self.hi[a]) - self.origin[a]) / self.spacing;
            (f.max(0.0) as usize).min(self.dims[a] - 2)
        };
        let lo: [usize; 3] = std::array::from_fn(|a| cell(c[a] - radius, a));
        let hi: [usize; 3] = std::array::from_fn(|a| cell(c[a] + radius, a));
        let slope = slopes.max_over(lo, hi) + if inside { 0.0 } else { 1.0 };
        self.distance_local(centre) - slope * radius
    }
}
