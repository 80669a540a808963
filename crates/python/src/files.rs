//! Readers of the project's files whose format is its own or whose meaning is its code's: meshes (PLY, OBJ),
//! SDF grids, and a capture's cameras split into `K` and world-to-camera (`cameras_sphere.npz` holds their
//! product with NeuS's normalisation).

use crate::errors;
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// A mesh as numpy arrays: vertices `float64[N,3]` and faces `uint32[M,3]`.
pub type MeshArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<u32>>);

/// `(vertices float64[N,3], faces uint32[M,3])` of a mesh file (`.ply` or `.obj`).
#[pyfunction]
pub fn read_mesh(py: Python<'_>, path: PathBuf) -> PyResult<MeshArrays<'_>> {
    let mesh = pganeus_io::read_mesh(&path).map_err(errors::input)?;
    Ok(mesh_arrays(py, &mesh))
}

pub fn mesh_arrays<'py>(
    py: Python<'py>,
    mesh: &geom::TriMesh,
) -> (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<u32>>) {
    let v: Vec<f64> = mesh.vertices.iter().flatten().copied().collect();
    let f: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    let v = Array2::from_shape_vec((mesh.vertices.len(), 3), v).expect("three coordinates a vertex");
    let f = Array2::from_shape_vec((mesh.faces.len(), 3), f).expect("three corners a face");
    (v.into_pyarray(py), f.into_pyarray(py))
}

/// A baked SDF grid (`bake`'s `.sdf`): `{"values": float32[nx, ny, nz], "origin": (x, y, z), "spacing": h}`,
/// node `(i, j, k)` at `origin + h (i, j, k)`, metres.
#[pyfunction]
pub fn read_sdf_grid(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyDict>> {
    let grid = sim::sdf::SdfGrid::load(&path).map_err(errors::input)?;
    let [nx, ny, nz] = grid.dims();
    // Stored x fastest: as C-ordered [z][y][x], then viewed as [x][y][z].
    let values = Array3::from_shape_vec((nz, ny, nx), grid.values().to_vec())
        .expect("dims match the values")
        .reversed_axes();
    let d = PyDict::new(py);
    d.set_item("values", values.into_pyarray(py))?;
    d.set_item("origin", grid.origin())?;
    d.set_item("spacing", grid.spacing())?;
    Ok(d)
}

/// A capture's cameras (`image/`, `cameras_sphere.npz`): `{"names": [...], "K": float64[N,3,3], "W2C":
/// float64[N,4,4], "width": w, "height": h}`, OpenCV's convention (x right, y down, z forward), in the
/// capture's world frame (metres, z up).
#[pyfunction]
pub fn read_cameras(py: Python<'_>, capture: PathBuf) -> PyResult<Bound<'_, PyDict>> {
    let index = pganeus_io::open_capture(&capture).map_err(errors::input)?;
    let cameras = pipeline::cameras::world_cameras(&index).map_err(|e| errors::to_py(&e))?;
    let n = cameras.len();
    let mut k = Vec::with_capacity(9 * n);
    let mut w2c = Vec::with_capacity(16 * n);
    for c in &cameras {
        let i = c.k;
        k.extend([i.fx, i.skew, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0]);
        w2c.extend(c.world_to_cam.to_matrix().iter().flatten());
    }
    let names: Vec<String> = index
        .images
        .iter()
        .map(|p| {
            p.file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .collect();
    let d = PyDict::new(py);
    d.set_item("names", names)?;
    let k: Bound<'_, PyArray3<f64>> = Array3::from_shape_vec((n, 3, 3), k).expect("3x3").into_pyarray(py);
    let w2c: Bound<'_, PyArray3<f64>> = Array3::from_shape_vec((n, 4, 4), w2c).expect("4x4").into_pyarray(py);
    d.set_item("K", k)?;
    d.set_item("W2C", w2c)?;
    d.set_item("width", index.width)?;
    d.set_item("height", index.height)?;
    Ok(d)
}
