//! The region a capture's cameras look at, which becomes its `scale_mat` (the field's unit sphere).
//!
//! Two rules. An object's ([`looked_at_region`]): the centre is the point nearest every camera's optical
//! axis (least squares), not below the board; the radius is what the cameras frame there, the median over
//! cameras of their distance to the centre times the tangent of half their narrower field of view. A
//! scene's ([`seen_table_region`]): the part of the board's plane that at least three quarters of the
//! cameras see, where the bodies will move, not only the spot the cameras aim at.

use geom::Vec3;

/// A camera for the rule: where it is, where it looks (unit), and the tangent of half its narrower field
/// of view.
#[derive(Clone, Copy, Debug)]
pub struct Looking {
    pub centre: Vec3<f64>,
    pub forward: Vec3<f64>,
    pub half_fov_tan: f64,
}

impl Looking {
    /// The camera of a world-to-camera pose (OpenCV's axes: it looks along its +z).
    pub fn from_pose(world_to_cam: &geom::Pose<f64>, half_fov_tan: f64) -> Looking {
        let c2w = world_to_cam.inverse();
        Looking {
            centre: c2w.t,
            forward: c2w.transform_vector(Vec3::new(0.0, 0.0, 1.0)),
            half_fov_tan,
        }
    }

    /// A camera with its intrinsics and image size.
    pub fn from_camera(camera: &geom::Camera<f64>) -> Looking {
        let tan = (0.5 * camera.width as f64 / camera.k.fx).min(0.5 * camera.height as f64 / camera.k.fy);
        Looking::from_pose(&camera.world_to_cam, tan)
    }
}

/// The point nearest a set of lines (each an origin and a unit direction) in least squares,
/// `Σ (I − d dᵀ) p = Σ (I − d dᵀ) c`, with that system's matrix; `None` when it is singular.
pub fn nearest_point_to_lines(lines: &[(Vec3<f64>, Vec3<f64>)]) -> Option<(Vec3<f64>, [[f64; 3]; 3])> {
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for (c, d) in lines {
        let (c, d) = (c.to_array(), d.to_array());
        for i in 0..3 {
            for j in 0..3 {
                let m = if i == j { 1.0 } else { 0.0 } - d[i] * d[j];
                a[i][j] += m;
                b[i] += m * c[j];
            }
        }
    }
    let inv = crate::homography::invert3(&a)?;
    let p = Vec3::new(
        (0..3).map(|j| inv[0][j] * b[j]).sum(),
        (0..3).map(|j| inv[1][j] * b[j]).sum(),
        (0..3).map(|j| inv[2][j] * b[j]).sum(),
    );
    Some((p, a))
}

/// The ball (centre, radius) the cameras look at; `None` when the axes are parallel (one camera, or a
/// video) and none meets the board: then the region must be given.
pub fn looked_at_region(cameras: &[Looking]) -> Option<(Vec3<f64>, f64)> {
    if cameras.is_empty() {
        return None;
    }
    let axes: Vec<(Vec3<f64>, Vec3<f64>)> = cameras.iter().map(|c| (c.centre, c.forward)).collect();
    let centre = match nearest_point_to_lines(&axes) {
        Some((p, a)) if cameras.len() > 1 && condition_ok(&a) => p,
        _ => {
            // One camera (or parallel axes): where the mean axis meets the board.
            let n = cameras.len() as f64;
            let c = cameras.iter().fold(Vec3::zero(), |s, k| s + k.centre) * (1.0 / n);
            let d = cameras.iter().fold(Vec3::zero(), |s, k| s + k.forward) * (1.0 / n);
            if d.z >= -1e-6 {
                return None;
            }
            c + d * (-c.z / d.z)
        }
    };
    let centre = Vec3::new(centre.x, centre.y, centre.z.max(0.0));
    let mut radii: Vec<f64> = cameras
        .iter()
        .map(|k| (k.centre - centre).norm() * k.half_fov_tan)
        .collect();
    radii.sort_by(f64::total_cmp);
    Some((centre, radii[radii.len() / 2]))
}

/// The share of a scene's photos that must see a point of the table for it to be in the region.
///
/// A point few photos see is reconstructed from thin evidence and only widens the ball (fewer samples
/// per millimetre everywhere). Half let in the table's far edges, seen from across the table only: on
/// synth's four handheld layouts (tabletop seeds 1–3, backdrop seed 1) a ball a quarter wider than the table's
/// (0.53–0.59 m against 0.45 m), which cost the scene's Chamfer 13 %; three quarters gives
/// 0.43–0.46 m.
pub const SCENE_QUORUM: f64 = 0.75;

/// A scene's ball: around the part of the plane z = 0 that at least [`SCENE_QUORUM`] of `cameras` see
/// (inside the image, in front), its centre on the plane, its radius reaching that part's farthest
/// point; `None` when the cameras do not look at the plane or no part of it is seen by that many.
pub fn seen_table_region(cameras: &[geom::Camera<f64>]) -> Option<(Vec3<f64>, f64)> {
    let looking: Vec<Looking> = cameras.iter().map(Looking::from_camera).collect();
    let (aim, framed) = looked_at_region(&looking)?;
    // A grid over the plane around where the cameras aim, wide enough for what a camera sees beside it.
    const CELLS: usize = 160;
    let half = 6.0 * framed;
    let cell = 2.0 * half / CELLS as f64;
    let needed = ((SCENE_QUORUM * cameras.len() as f64).ceil() as usize).max(1);
    let mut seen = Vec::new();
    for j in 0..=CELLS {
        for i in 0..=CELLS {
            let p = Vec3::new(aim.x - half + i as f64 * cell, aim.y - half + j as f64 * cell, 0.0);
            if views_seeing(cameras, p) >= needed {
                seen.push(p);
            }
        }
    }
    if seen.is_empty() {
        return None;
    }
    let (lo, hi) = seen.iter().fold(
        (
            Vec3::new(f64::INFINITY, f64::INFINITY, 0.0),
            Vec3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, 0.0),
        ),
        |(lo, hi), p| {
            (
                Vec3::new(lo.x.min(p.x), lo.y.min(p.y), 0.0),
                Vec3::new(hi.x.max(p.x), hi.y.max(p.y), 0.0),
            )
        },
    );
    let centre = (lo + hi) * 0.5;
    let radius = seen.iter().map(|p| (*p - centre).norm()).fold(0.0, f64::max) + cell;
    Some((centre, radius))
}

/// How many of `cameras` see the point `p`: in front of them and inside their image.
fn views_seeing(cameras: &[geom::Camera<f64>], p: Vec3<f64>) -> usize {
    cameras
        .iter()
        .filter(|c| {
            let (u, v, depth) = c.project(p);
            depth > 0.0 && (0.0..=c.width as f64).contains(&u) && (0.0..=c.height as f64).contains(&v)
        })
        .count()
}

/// Whether the axes constrain the point in every direction (not all parallel).
fn condition_ok(a: &[[f64; 3]; 3]) -> bool {
    let (values, _) = geom::symmetric_eigen(*a);
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    lo > 1e-3 * hi
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cameras_around_a_point_look_at_it() {
        let target = Vec3::new(0.05, -0.02, 0.03);
        let cams: Vec<Looking> = (0..8)
            .map(|k| {
                let a = k as f64 * 0.8;
                let centre = target + Vec3::new(a.cos() * 0.4, a.sin() * 0.4, 0.3);
                Looking {
                    centre,
                    forward: (target - centre) * (1.0 / (target - centre).norm()),
                    half_fov_tan: 0.4,
                }
            })
            .collect();
        let (c, r) = looked_at_region(&cams).unwrap();
        assert!((c - target).norm() < 1e-9);
        assert!((r - 0.5 * 0.4).abs() < 1e-9);
        let one = looked_at_region(&cams[..1]).unwrap();
        assert!(one.0.z.abs() < 1e-12, "one camera: where its axis meets the board");
    }

    /// Cameras all round a table, each aimed at a point of a 0.3 × 0.2 m rectangle near its own side: they
    /// aim near the middle, but what three quarters of them see is the rectangle and a margin, which the scene's
    /// rule holds and the object's rule (what they frame at the aim point) does not.
    #[test]
    fn a_scene_region_holds_the_table_most_cameras_see() {
        let k = geom::Intrinsics::centred(400.0, 320, 240);
        let cams: Vec<geom::Camera<f64>> = (0..12)
            .map(|n| {
                let a = n as f64 * std::f64::consts::TAU / 12.0;
                let target = Vec3::new(0.15 * a.cos(), 0.1 * a.sin(), 0.0);
                let eye = Vec3::new(0.45 * a.cos(), 0.45 * a.sin(), 0.4);
                geom::Camera::look_at(eye, target, Vec3::new(0.0, 0.0, 1.0), k, 320, 240)
            })
            .collect();
        let (centre, radius) = seen_table_region(&cams).unwrap();
        assert!(centre.norm() < 0.02, "centred on the table: {centre:?}");
        assert!(radius > 0.2 && radius < 0.45, "the rectangle and a margin: {radius}");
        let looking: Vec<Looking> = cams.iter().map(Looking::from_camera).collect();
        let (_, framed) = looked_at_region(&looking).unwrap();
        assert!(
            radius > 1.2 * framed,
            "the scene's region is wider than what the cameras frame: {radius} {framed}"
        );
        // Every point of the rectangle lies in the ball.
        for (x, y) in [(0.15, 0.1), (-0.15, 0.1), (0.15, -0.1), (-0.15, -0.1)] {
            assert!((Vec3::new(x, y, 0.0) - centre).norm() < radius);
        }
        // The table's far edge that only half of them see (from across the table) is left out.
        let edge = (0..2000)
            .map(|i| Vec3::new(i as f64 * 1e-3, 0.0, 0.0))
            .take_while(|p| views_seeing(&cams, *p) >= cams.len() / 2)
            .last()
            .unwrap();
        let quorum = (SCENE_QUORUM * cams.len() as f64).ceil() as usize;
        let seen = views_seeing(&cams, edge);
        assert!(
            seen < quorum,
            "seen by half, not by the quorum: {seen} of {}",
            cams.len()
        );
        assert!((edge - centre).norm() > radius, "{edge:?} outside {radius}");
        let away: Vec<geom::Camera<f64>> = cams
            .iter()
            .map(|c| geom::Camera::look_at(c.center(), c.center() * 2.0, Vec3::new(0.0, 0.0, 1.0), k, 320, 240))
            .collect();
        assert!(
            seen_table_region(&away).is_none(),
            "cameras looking away from the table"
        );
    }
}
