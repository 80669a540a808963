//! An object capture's masks computed from its calibrated photos ([`mod@recon::object_masks`]): the board
//! the photos agree on is each view's background, and the views agree on what stands on it. `train` uses
//! them for an object capture without `mask/`, `masks` writes them for inspection.

use geom::Vec3;
use neus::Dataset;

use crate::error::fail;
use crate::Result;

/// How high above the board's plane (metres) parallax and colour cannot tell an object's base from the
/// board: the points below take the verdict of the point at this height.
const BASE_BAND: f64 = 0.002;

/// The masks of the object in every view of `data` (its cameras in the capture's unit frame; the board's
/// printed face is the world's `z = 0`), with what was measured. An error names the capture where the
/// object stands out in too few views to be found.
pub fn compute(data: &Dataset) -> Result<(Vec<Vec<bool>>, recon::object_masks::ObjectMaskStats)> {
    let images: Vec<&[[f32; 3]]> = data.views.iter().map(|v| v.rgb.as_slice()).collect();
    let cameras: Vec<geom::Camera<f64>> = data.views.iter().map(|v| v.camera).collect();
    let board = recon::object_masks::BoardPlane {
        z: -data.centre.z / data.radius,
        band: BASE_BAND / data.radius,
    };
    if board.z <= -1.0 {
        fail!(
            Input,
            "{}: the capture's region (centre z {:.3} m, radius {:.3} m) lies wholly above the board's plane z = 0: \
             an object capture's region holds the object resting on the board",
            data.dir.display(),
            data.centre.z,
            data.radius
        );
    }
    let (masks, stats) = recon::object_masks::object_masks(
        &images,
        &cameras,
        (Vec3::new(0.0, 0.0, 0.0), 1.0),
        board,
        &recon::object_masks::ObjectMaskConfig::default(),
    );
    let empty: Vec<&str> = data
        .views
        .iter()
        .zip(&masks)
        .filter(|(_, m)| !m.iter().any(|&x| x))
        .map(|(v, _)| v.name.as_str())
        .collect();
    if empty.len() * 2 > masks.len() {
        fail!(
            Input,
            "{}: no object stands out from the board in {} of {} views ({}): is the object in the photos, \
             resting on the board inside the capture's region?",
            data.dir.display(),
            empty.len(),
            masks.len(),
            empty.join(", ")
        );
    }
    if !empty.is_empty() {
        tracing::warn!("{}: no object found in views {}", data.dir.display(), empty.join(", "));
    }
    Ok((masks, stats))
}
