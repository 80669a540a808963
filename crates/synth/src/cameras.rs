//! Where the cameras of each capture stand, and the unit-sphere normalisation
//! (`scale_mat`) of each capture's region of interest.

use geom::{Camera, Intrinsics, Vec3};

/// Square-pixel intrinsics for a vertical field of view.
pub fn intrinsics(width: u32, height: u32, fov_deg: f64) -> Intrinsics {
    let fy = 0.5 * height as f64 / (0.5 * fov_deg.to_radians()).tan();
    Intrinsics {
        fx: fy,
        fy,
        cx: 0.5 * width as f64,
        cy: 0.5 * height as f64,
        skew: 0.0,
    }
}

/// A camera on a sphere about `centre`, looking at it, z up.
pub fn orbit(
    centre: Vec3<f64>,
    distance: f64,
    elevation_deg: f64,
    azimuth_deg: f64,
    k: Intrinsics,
    w: u32,
    h: u32,
) -> Camera<f64> {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    let eye = centre + Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin()) * distance;
    Camera::look_at(eye, centre, Vec3::new(0.0, 0.0, 1.0), k, w, h)
}

/// The distance at which a ball of `radius` fills the narrower field of view,
/// with `margin` (> 1 leaves room around it).
pub fn framing_distance(radius: f64, k: &Intrinsics, w: u32, h: u32, margin: f64) -> f64 {
    let half_v = (0.5 * h as f64 / k.fy).atan();
    let half_h = (0.5 * w as f64 / k.fx).atan();
    radius * margin / half_v.min(half_h).sin()
}

/// A camera on an orbit about `centre` (as [`orbit`]) at the distance where
/// every point of `content` projects inside the image with `border` (a
/// fraction of each side) to spare: a scene capture fills the frame with its
/// board and obstacles, as a person walking round a table does, instead of
/// framing the whole region's ball from every side.
#[allow(clippy::too_many_arguments)]
pub fn framed_orbit(
    centre: Vec3<f64>,
    content: &[Vec3<f64>],
    elevation_deg: f64,
    azimuth_deg: f64,
    border: f64,
    k: Intrinsics,
    w: u32,
    h: u32,
) -> Camera<f64> {
    let reach = content.iter().map(|p| (*p - centre).norm()).fold(1e-6, f64::max);
    let fits = |d: f64| {
        let cam = orbit(centre, d, elevation_deg, azimuth_deg, k, w, h);
        let (bw, bh) = (border * w as f64, border * h as f64);
        content.iter().all(|p| {
            let (u, v, z) = cam.project(*p);
            z > 0.0 && u >= bw && u <= w as f64 - bw && v >= bh && v <= h as f64 - bh
        })
    };
    // Far enough always fits (the content shrinks to the image centre);
    // bisect down to the nearest distance that does.
    let (mut near, mut far) = (reach, 2.0 * reach);
    while !fits(far) {
        far *= 2.0;
    }
    for _ in 0..40 {
        let mid = 0.5 * (near + far);
        if fits(mid) {
            far = mid;
        } else {
            near = mid;
        }
    }
    orbit(centre, far, elevation_deg, azimuth_deg, k, w, h)
}

/// `n` views spread over azimuth (golden angle) and elevation `[lo, hi]` degrees.
pub fn hemisphere_views(n: usize, elevation: [f64; 2]) -> Vec<(f64, f64)> {
    let golden = 180.0 * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let f = (i as f64 + 0.5) / n as f64;
            (
                elevation[0] + (elevation[1] - elevation[0]) * f,
                (i as f64 * golden).rem_euclid(360.0),
            )
        })
        .collect()
}

/// `scale_mat` mapping the unit sphere onto the ball (`centre`, `radius`).
pub fn scale_mat(centre: Vec3<f64>, radius: f64) -> [[f64; 4]; 4] {
    [
        [radius, 0.0, 0.0, centre.x],
        [0.0, radius, 0.0, centre.y],
        [0.0, 0.0, radius, centre.z],
        [0.0, 0.0, 0.0, 1.0],
    ]
}
