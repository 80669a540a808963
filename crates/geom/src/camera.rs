//! Pinhole cameras with OpenCV axes (x right, y down, z forward), pixel
//! centres at integer + 0.5, and the decomposition of a NeuS `world_mat`.

use crate::{Mat3, Pose, Quat, Real, Vec3};

/// Intrinsics in pixels (zero skew is not assumed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub skew: f64,
}

impl Intrinsics {
    /// A square-pixel camera of focal length `focal` px with its principal point at the image centre.
    pub fn centred(focal: f64, width: u32, height: u32) -> Self {
        Self {
            fx: focal,
            fy: focal,
            cx: 0.5 * width as f64,
            cy: 0.5 * height as f64,
            skew: 0.0,
        }
    }
    pub fn matrix(&self) -> Mat3<f64> {
        Mat3::from_rows([[self.fx, self.skew, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])
    }
    pub fn from_matrix(k: &Mat3<f64>) -> Self {
        let s = k.m[2][2];
        Self {
            fx: k.m[0][0] / s,
            fy: k.m[1][1] / s,
            cx: k.m[0][2] / s,
            cy: k.m[1][2] / s,
            skew: k.m[0][1] / s,
        }
    }
}

/// A ray `origin + s · dir`, `dir` unit length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray<S> {
    pub origin: Vec3<S>,
    pub dir: Vec3<S>,
}

impl<S: Real> Ray<S> {
    pub fn at(&self, s: S) -> Vec3<S> {
        self.origin + self.dir * s
    }
}

/// A pinhole camera: intrinsics, the world-to-camera pose and the image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera<S> {
    pub k: Intrinsics,
    /// World to camera: `p_cam = world_to_cam.transform_point(p_world)`.
    pub world_to_cam: Pose<S>,
    pub width: u32,
    pub height: u32,
}

/// Why a projection matrix could not be split into `K [R | t]`.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraError {
    NotFinite,
    Singular,
    LastRowNotAffine,
}

impl std::fmt::Display for CameraError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CameraError::NotFinite => write!(f, "the matrix has NaN or infinite entries"),
            CameraError::Singular => write!(f, "the left 3x3 block is singular (not a camera)"),
            CameraError::LastRowNotAffine => write!(f, "the last row of a 4x4 world_mat must be [0, 0, 0, 1]"),
        }
    }
}
impl std::error::Error for CameraError {}

impl<S: Real> Camera<S> {
    /// Camera centre in the world.
    pub fn center(&self) -> Vec3<S> {
        self.world_to_cam.inverse().t
    }
    /// Pixel coordinates and depth of a world point.
    pub fn project(&self, p_world: Vec3<S>) -> (S, S, S) {
        let p = self.world_to_cam.transform_point(p_world);
        let u = (p.x * self.k.fx + p.y * self.k.skew) / p.z + self.k.cx;
        let v = p.y * self.k.fy / p.z + self.k.cy;
        (u, v, p.z)
    }
    /// The world ray through pixel coordinates `(u, v)`; the centre of pixel
    /// `(i, j)` is `(i + 0.5, j + 0.5)`.
    pub fn ray(&self, u: f64, v: f64) -> Ray<S> {
        let y = (v - self.k.cy) / self.k.fy;
        let x = (u - self.k.cx - self.k.skew * y) / self.k.fx;
        let d_cam = Vec3::<S>::cst([x, y, 1.0]);
        let c2w = self.world_to_cam.inverse();
        Ray {
            origin: c2w.t,
            dir: c2w.transform_vector(d_cam).normalize_or(Vec3::cst([0.0, 0.0, 1.0])),
        }
    }
}

impl Camera<f64> {
    /// The 4×4 NeuS `world_mat = [[K, 0], [0, 1]] @ W2C`, row-major.
    pub fn world_mat(&self) -> [[f64; 4]; 4] {
        let k = self.k.matrix();
        let w2c = self.world_to_cam.to_matrix();
        let mut p = [[0.0; 4]; 4];
        for (i, row) in p.iter_mut().take(3).enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3).map(|l| k.m[i][l] * w2c[l][j]).sum();
            }
        }
        p[3] = [0.0, 0.0, 0.0, 1.0];
        p
    }

    /// The same camera seen from a unit frame placed at `centre` with scale
    /// `radius` (`p_world = centre + radius · p_unit`): a field's frame, as
    /// NeuS's `scale_mat` defines it.
    pub fn in_unit_frame(&self, centre: Vec3<f64>, radius: f64) -> Self {
        let mut c = *self;
        c.world_to_cam.t = (self.world_to_cam.t + self.world_to_cam.q.rotate(centre)) * (1.0 / radius);
        c
    }

    /// The inverse of [`Camera::in_unit_frame`]: a camera of the unit frame back in the world.
    pub fn from_unit_frame(&self, centre: Vec3<f64>, radius: f64) -> Self {
        let mut c = *self;
        c.world_to_cam.t = self.world_to_cam.t * radius - self.world_to_cam.q.rotate(centre);
        c
    }

    /// Split a NeuS `world_mat` (`P = K [R | t]`, any overall scale) into
    /// intrinsics and the world-to-camera pose, by an RQ decomposition.
    pub fn from_world_mat(p: &[[f64; 4]; 4], width: u32, height: u32) -> Result<Self, CameraError> {
        if p.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        let last = p[3];
        if last[0].abs() > 1e-9 || last[1].abs() > 1e-9 || last[2].abs() > 1e-9 || (last[3] - 1.0).abs() > 1e-9 {
            return Err(CameraError::LastRowNotAffine);
        }
        let mut m = Mat3::from_rows([
            [p[0][0], p[0][1], p[0][2]],
            [p[1][0], p[1][1], p[1][2]],
            [p[2][0], p[2][1], p[2][2]],
        ]);
        let mut p4 = Vec3::new(p[0][3], p[1][3], p[2][3]);
        let det = m.det();
        // Singular relative to the rows' size: P has an arbitrary overall scale.
        let scale = m.row(0).norm() * m.row(1).norm() * m.row(2).norm();
        if !(scale > 0.0) || det.abs() < 1e-12 * scale {
            return Err(CameraError::Singular);
        }
        // P is defined up to scale; a negative scale would flip R to det −1.
        if det < 0.0 {
            m = m.scale(-1.0);
            p4 = -p4;
        }
        let (m1, m2, m3) = (m.row(0), m.row(1), m.row(2));
        let k33 = m3.norm();
        let r3 = m3 * (1.0 / k33);
        let k23 = m2.dot(r3);
        let u2 = m2 - r3 * k23;
        let k22 = u2.norm();
        let r2 = u2 * (1.0 / k22);
        let k13 = m1.dot(r3);
        let k12 = m1.dot(r2);
        let u1 = m1 - r2 * k12 - r3 * k13;
        let k11 = u1.norm();
        if k11 < 1e-12 * k33 || k22 < 1e-12 * k33 {
            return Err(CameraError::Singular);
        }
        let r1 = u1 * (1.0 / k11);
        let kmat = Mat3::from_rows([[k11, k12, k13], [0.0, k22, k23], [0.0, 0.0, k33]]);
        let kinv = kmat.try_inverse().ok_or(CameraError::Singular)?;
        let t = kinv.mul_vec(p4);
        let r = Mat3::from_rows([r1.to_array(), r2.to_array(), r3.to_array()]);
        Ok(Self {
            k: Intrinsics::from_matrix(&kmat),
            world_to_cam: Pose::new(Quat::from_mat(&r), t),
            width,
            height,
        })
    }

    /// A camera at `eye` looking at `target`, with world `up` pointing up in
    /// the image (OpenCV axes).
    pub fn look_at(eye: Vec3<f64>, target: Vec3<f64>, up: Vec3<f64>, k: Intrinsics, width: u32, height: u32) -> Self {
        let z = (target - eye).normalize_or(Vec3::new(0.0, 0.0, 1.0));
        let x = z
            .cross(up)
            .try_normalize()
            .unwrap_or_else(|| z.cross(Vec3::new(1.0, 0.0, 0.0)).normalize_or(Vec3::new(0.0, 1.0, 0.0)));
        let y = z.cross(x);
        let r = Mat3::from_rows([x.to_array(), y.to_array(), z.to_array()]);
        let q = Quat::from_mat(&r);
        let t = -r.mul_vec(eye);
        Self {
            k,
            world_to_cam: Pose::new(q, t),
            width,
            height,
        }
    }
}
