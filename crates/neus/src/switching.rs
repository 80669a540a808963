//! Switching render (Sec. 3.2, Eq. 3–4, Fig. 2a): two fields of one object,
//! each trained in its own capture's frame (board at z = 0), and seen only
//! from above that board. A camera placed in the primary field's frame
//! renders with the primary field when it is above the board,
//! `z(p_cam) ≥ 0`; below, each of its rays `r₁ = p_cam + r·d` is moved into
//! the other field's frame, `r₂ = R₁→₂ r₁ + T₁→₂` (Eq. 3), where that side of
//! the object was seen, and the other field renders it (Eq. 4). All rays of a
//! camera share `p_cam`, so the choice is per camera, and moving every ray is
//! the same as moving the camera.

use geom::{Camera, Pose};

/// Which field renders a camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Route {
    /// The primary field, with the camera as given.
    Primary,
    /// The other field, with the camera moved into its frame.
    Other(Camera<f64>),
}

/// Eq. 4's choice for `camera` (in the primary field's frame), with
/// `primary_to_other` the rigid map `p₂ = R₁→₂ p₁ + T₁→₂` of Eq. 3.
pub fn route(camera: &Camera<f64>, primary_to_other: &Pose<f64>) -> Route {
    if camera.center().z >= 0.0 {
        Route::Primary
    } else {
        let mut moved = *camera;
        // x_cam = W(p₁) = W(P⁻¹(p₂)): the camera's world-to-camera map in frame 2.
        moved.world_to_cam = camera.world_to_cam.compose(&primary_to_other.inverse());
        Route::Other(moved)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geom::{Quat, Vec3};

    fn camera_at(eye: Vec3<f64>) -> Camera<f64> {
        let k = geom::Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 32.0,
            cy: 24.0,
            skew: 0.0,
        };
        Camera::look_at(eye, Vec3::new(0.0, 0.0, 0.02), Vec3::new(0.0, 0.0, 1.0), k, 64, 48)
    }

    #[test]
    fn cameras_above_stay_and_cameras_below_move_by_eq_3() {
        let p = Pose::new(Quat::exp(Vec3::new(3.0, 0.2, -0.1)), Vec3::new(0.01, -0.02, 0.04));
        assert_eq!(route(&camera_at(Vec3::new(0.2, 0.1, 0.15)), &p), Route::Primary);
        let below = camera_at(Vec3::new(0.2, 0.1, -0.15));
        let Route::Other(moved) = route(&below, &p) else {
            panic!("a camera below the board must switch");
        };
        // Eq. 3 for every ray: origin p_cam ↦ R p_cam + T, and the ray through
        // a pixel in frame 1 is the moved ray through the same pixel.
        assert!((moved.center() - p.transform_point(below.center())).norm() < 1e-12);
        for (u, v) in [(0.5, 0.5), (31.5, 20.0), (63.5, 47.5)] {
            let (r1, r2) = (below.ray(u, v), moved.ray(u, v));
            for s in [0.05, 0.2, 0.4] {
                assert!((r2.at(s) - p.transform_point(r1.at(s))).norm() < 1e-12);
            }
        }
    }
}
