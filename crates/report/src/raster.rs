//! A small z-buffered rasteriser for pictures of meshes: flat shading from a key light and the view, opaque
//! meshes first, then translucent ones blended over what they are in front of (the truth as a ghost over
//! the fit). Pixel centres sit at integer + 0.5, as in the cameras of the captures.

use geom::{Camera, Intrinsics, Pose, TriMesh, Vec3};
use pganeus_io::Image;

/// A picture being drawn through one camera.
pub struct Raster {
    camera: Camera<f64>,
    /// Inverse depth of the nearest opaque surface per pixel (0: nothing).
    inv_depth: Vec<f64>,
    rgb: Vec<[f64; 3]>,
}

/// How a mesh is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Paint {
    pub color: [f64; 3],
    /// 1: opaque; below 1: blended over the opaque surfaces behind (only the mesh's nearest surface).
    pub alpha: f64,
    /// Leave out faces turned away from the camera (walls seen from outside a room).
    pub cull_back: bool,
}

impl Paint {
    pub fn solid(color: [f64; 3]) -> Self {
        Self {
            color,
            alpha: 1.0,
            cull_back: false,
        }
    }

    pub fn ghost(color: [f64; 3], alpha: f64) -> Self {
        Self {
            color,
            alpha,
            cull_back: false,
        }
    }

    pub fn front_faces(self) -> Self {
        Self {
            cull_back: true,
            ..self
        }
    }
}

/// Turns `mesh`'s faces around when most of its area faces away from `eye`, so that its front faces are
/// the ones a camera there sees (extracted surfaces may wind either way).
pub fn face_towards(mesh: &mut TriMesh, eye: Vec3<f64>) {
    let mut facing = 0.0;
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| Vec3::cst(mesh.vertices[i as usize]));
        let n = (b - a).cross(c - a);
        facing += n.dot(eye - a).signum() * n.norm();
    }
    if facing < 0.0 {
        for f in &mut mesh.faces {
            f.swap(1, 2);
        }
    }
}

/// Towards the key light (world, z up).
const LIGHT: [f64; 3] = [0.35, -0.45, 0.82];

impl Raster {
    /// An empty picture: `background` at the top fading to a lighter tone at the bottom.
    pub fn new(camera: Camera<f64>, background: [f64; 3]) -> Self {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let mut rgb = Vec::with_capacity(w * h);
        for y in 0..h {
            let s = 0.85 + 0.15 * y as f64 / h.max(1) as f64;
            rgb.extend(std::iter::repeat_n(background.map(|c| (c * s).min(1.0)), w));
        }
        Self {
            camera,
            inv_depth: vec![0.0; w * h],
            rgb,
        }
    }

    pub fn camera(&self) -> &Camera<f64> {
        &self.camera
    }

    /// Shade of a face with world normal `n` seen along `view` (unit, camera → face).
    fn shade(n: Vec3<f64>, view: Vec3<f64>, color: [f64; 3]) -> [f64; 3] {
        let l = Vec3::cst(LIGHT).normalize_or(Vec3::new(0.0, 0.0, 1.0));
        // Two-sided: a face's back is shaded as if it faced the camera.
        let n = if n.dot(view) > 0.0 { n.scale(-1.0) } else { n };
        let k = 0.28 + 0.52 * n.dot(l).max(0.0) + 0.2 * (-n.dot(view)).max(0.0);
        color.map(|c| (c * k).min(1.0))
    }

    /// Draws `mesh` (body frame) placed by `pose`.
    pub fn draw(&mut self, mesh: &TriMesh, pose: &Pose<f64>, paint: Paint) {
        let Paint {
            color,
            alpha,
            cull_back,
        } = paint;
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        let world: Vec<Vec3<f64>> = mesh
            .vertices
            .iter()
            .map(|p| pose.transform_point(Vec3::cst(*p)))
            .collect();
        let uvz: Vec<(f64, f64, f64)> = world.iter().map(|&p| self.camera.project(p)).collect();
        let eye = self.camera.center();
        let opaque = alpha >= 1.0;
        // A translucent mesh keeps its own nearest surface, then blends once.
        let mut own = if opaque {
            Vec::new()
        } else {
            vec![(0.0f64, [0.0f64; 3]); w * h]
        };
        for f in &mesh.faces {
            let [ia, ib, ic] = f.map(|i| i as usize);
            let (a, b, c) = (uvz[ia], uvz[ib], uvz[ic]);
            if !(a.2 > 1e-6 && b.2 > 1e-6 && c.2 > 1e-6) {
                continue;
            }
            let n = (world[ib] - world[ia]).cross(world[ic] - world[ia]);
            let Some(n) = n.try_normalize() else { continue };
            let centre = (world[ia] + world[ib] + world[ic]).scale(1.0 / 3.0);
            let view = (centre - eye).normalize_or(Vec3::new(0.0, 0.0, 1.0));
            if cull_back && n.dot(view) > 0.0 {
                continue;
            }
            let shaded = Self::shade(n, view, color);
            let area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
            if area.abs() < 1e-12 {
                continue;
            }
            let x0 = (a.0.min(b.0).min(c.0) - 0.5).ceil().max(0.0) as usize;
            let x1 = ((a.0.max(b.0).max(c.0) - 0.5).floor() + 1.0).clamp(0.0, w as f64) as usize;
            let y0 = (a.1.min(b.1).min(c.1) - 0.5).ceil().max(0.0) as usize;
            let y1 = ((a.1.max(b.1).max(c.1) - 0.5).floor() + 1.0).clamp(0.0, h as f64) as usize;
            let (ia_z, ib_z, ic_z) = (1.0 / a.2, 1.0 / b.2, 1.0 / c.2);
            for y in y0..y1 {
                for x in x0..x1 {
                    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                    let wa = ((b.0 - px) * (c.1 - py) - (b.1 - py) * (c.0 - px)) / area;
                    let wb = ((c.0 - px) * (a.1 - py) - (c.1 - py) * (a.0 - px)) / area;
                    let wc = 1.0 - wa - wb;
                    if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                        continue;
                    }
                    // Inverse depth is affine in screen space.
                    let inv = wa * ia_z + wb * ib_z + wc * ic_z;
                    let i = y * w + x;
                    if opaque {
                        if inv > self.inv_depth[i] {
                            self.inv_depth[i] = inv;
                            self.rgb[i] = shaded;
                        }
                    } else if inv > own[i].0 && inv > self.inv_depth[i] {
                        own[i] = (inv, shaded);
                    }
                }
            }
        }
        for (i, (inv, c)) in own.into_iter().enumerate() {
            if inv > 0.0 {
                let p = &mut self.rgb[i];
                *p = [0, 1, 2].map(|k| (1.0 - alpha) * p[k] + alpha * c[k]);
            }
        }
    }

    /// The picture as 8-bit RGB (the shades are display values already).
    pub fn image(&self) -> Image {
        Image {
            width: self.camera.width,
            height: self.camera.height,
            channels: 3,
            data: self
                .rgb
                .iter()
                .flat_map(|p| p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
                .collect(),
        }
    }
}

/// `views` pictures of `mesh` (`size` pixels square) from cameras circling its centre at 25° elevation,
/// side by side in one strip.
pub fn turntable(mesh: &TriMesh, views: usize, size: u32, color: [f64; 3]) -> Image {
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for v in &mesh.vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let centre = Vec3::new(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2]));
    let radius = mesh
        .vertices
        .iter()
        .map(|v| (Vec3::cst(*v) - centre).norm())
        .fold(1e-6, f64::max);
    let views = views.max(1);
    let mut strip = Image::new(size * views as u32, size, 3);
    // A 30° field of view framing the bounding ball.
    let f = 0.5 * size as f64 / (15f64).to_radians().tan();
    let distance = radius / (14f64).to_radians().sin();
    let k = Intrinsics {
        fx: f,
        fy: f,
        cx: 0.5 * size as f64,
        cy: 0.5 * size as f64,
        skew: 0.0,
    };
    let elevation = 25f64.to_radians();
    for v in 0..views {
        let az = std::f64::consts::TAU * v as f64 / views as f64 - std::f64::consts::FRAC_PI_2;
        let dir = Vec3::new(elevation.cos() * az.cos(), elevation.cos() * az.sin(), elevation.sin());
        let cam = Camera::look_at(
            centre + dir.scale(distance),
            centre,
            Vec3::new(0.0, 0.0, 1.0),
            k,
            size,
            size,
        );
        let mut r = Raster::new(cam, [0.93, 0.94, 0.96]);
        r.draw(mesh, &Pose::identity(), Paint::solid(color));
        let img = r.image();
        for y in 0..size as usize {
            let row = &img.data[y * size as usize * 3..(y + 1) * size as usize * 3];
            let at = (y * strip.width as usize + v * size as usize) * 3;
            strip.data[at..at + row.len()].copy_from_slice(row);
        }
    }
    strip
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube centred at the origin, its faces wound to face inwards (as a room's walls do).
    fn cube() -> TriMesh {
        let v: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    (i & 1) as f64 - 0.5,
                    ((i >> 1) & 1) as f64 - 0.5,
                    ((i >> 2) & 1) as f64 - 0.5,
                ]
            })
            .collect();
        let quads = [
            [0, 1, 3, 2],
            [4, 6, 7, 5],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ];
        let faces = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriMesh::new(v, faces)
    }

    fn camera() -> Camera<f64> {
        let k = Intrinsics {
            fx: 60.0,
            fy: 60.0,
            cx: 32.0,
            cy: 24.0,
            skew: 0.0,
        };
        Camera::look_at(
            Vec3::new(0.0, -5.0, 0.0),
            Vec3::zero(),
            Vec3::new(0.0, 0.0, 1.0),
            k,
            64,
            48,
        )
    }

    #[test]
    fn the_nearest_surface_wins_and_a_ghost_tints_what_it_covers() {
        let mut r = Raster::new(camera(), [1.0, 1.0, 1.0]);
        let red = [1.0, 0.0, 0.0];
        let blue = [0.0, 0.0, 1.0];
        // A red cube in front of a blue one (drawn first): the centre pixel is red.
        r.draw(
            &cube(),
            &Pose::new(geom::Quat::identity(), Vec3::new(0.0, 1.0, 0.0)),
            Paint::solid(blue),
        );
        r.draw(&cube(), &Pose::identity(), Paint::solid(red));
        let img = r.image();
        let centre = (24 * 64 + 32) * 3;
        assert!(
            img.data[centre] > 50 && img.data[centre + 2] == 0,
            "{:?}",
            &img.data[centre..centre + 3]
        );
        // The cube covers 12 px across at 60 px focal length, 4.5 away (its near face): ±6.7 px.
        assert_eq!(
            img.data[(24 * 64 + 2) * 3],
            img.data[(24 * 64 + 1) * 3],
            "background far left"
        );
        // A green ghost behind the red cube leaves it alone; one in front tints it.
        let before = img.data[centre..centre + 3].to_vec();
        let green = [0.0, 1.0, 0.0];
        r.draw(
            &cube(),
            &Pose::new(geom::Quat::identity(), Vec3::new(0.0, 2.0, 0.0)),
            Paint::ghost(green, 0.5),
        );
        assert_eq!(r.image().data[centre..centre + 3], before[..]);
        r.draw(
            &cube(),
            &Pose::new(geom::Quat::identity(), Vec3::new(0.0, -2.0, 0.0)),
            Paint::ghost(green, 0.5),
        );
        let after = &r.image().data[centre..centre + 3];
        assert!(after[1] > 50 && after[0] < before[0], "{after:?} {before:?}");
    }

    #[test]
    fn culling_drops_the_faces_turned_away_and_face_towards_turns_a_room_to_its_camera() {
        let mut room = cube();
        for v in &mut room.vertices {
            *v = v.map(|x| x * 20.0);
        }
        let red = |img: &Image| img.data.chunks(3).filter(|p| p[0] as i32 > p[2] as i32 + 50).count();
        // Seen from inside, every wall faces the camera: all of them are drawn.
        let mut r = Raster::new(camera(), [1.0, 1.0, 1.0]);
        r.draw(&room, &Pose::identity(), Paint::solid([1.0, 0.0, 0.0]).front_faces());
        assert_eq!(red(&r.image()), 64 * 48);
        // Wound the other way, the walls face out and are culled, until face_towards turns them round.
        let mut outward = room.clone();
        for f in &mut outward.faces {
            f.swap(1, 2);
        }
        let mut r = Raster::new(camera(), [1.0, 1.0, 1.0]);
        r.draw(&outward, &Pose::identity(), Paint::solid([1.0, 0.0, 0.0]).front_faces());
        assert_eq!(red(&r.image()), 0);
        face_towards(&mut outward, r.camera().center());
        assert!(outward.faces == room.faces);
    }

    #[test]
    fn a_turntable_shows_the_mesh_in_every_view() {
        let strip = turntable(&cube(), 4, 48, [0.9, 0.5, 0.2]);
        assert_eq!((strip.width, strip.height), (192, 48));
        for v in 0..4 {
            let at = (24 * 192 + v * 48 + 24) * 3;
            let p = &strip.data[at..at + 3];
            assert!(p[0] as i32 > p[2] as i32 + 30, "view {v}: {p:?}");
        }
    }
}
