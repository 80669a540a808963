//! The composed renderer: a posed object renders as its own field from the
//! inversely moved camera (Eq. 7), and its pose gradients (colour, depth,
//! opacity; translation and rotation; both fields of a two-pose object) match
//! central differences.

use geom::{Camera, Intrinsics, Pose, Quat, SplitMix64, Vec3};
use neus::checkpoint::LoadedField;
use neus::compose::{
    prerender_scene, render_composed, Behind, ComposedRay, Composer, FixedSamples, Layer, RayGradient,
};
use neus::occupancy::OccupancyGrid;
use neus::render_view::{render_view, RenderSettings};
use neus::FieldInit;

fn field(init: FieldInit, centre: Vec3<f64>, radius: f64, seed: u64) -> LoadedField {
    neus::untrained_field::untrained_field(init, centre, radius, seed)
}

/// Every sample of the sphere and no cap: samples stay put while the pose moves (no stride changes, no
/// occupancy borders).
fn fine(l: &LoadedField) -> RenderSettings {
    RenderSettings {
        steps_per_ray: 160,
        max_samples_per_ray: 100_000,
        // Every sample: no ray stops where a pose change could move the stop.
        stop_transmittance: 0.0,
        ..RenderSettings::of(l)
    }
}

fn camera(eye: Vec3<f64>, target: Vec3<f64>, w: u32, h: u32) -> Camera<f64> {
    let k = Intrinsics::centred(1.1 * w as f64, w, h);
    Camera::look_at(eye, target, Vec3::new(0.0, 0.0, 1.0), k, w, h)
}

/// The object (a toy 6 cm across, its capture's centre 2 cm above its body origin) and the scene.
struct Rig {
    object: LoadedField,
    scene: LoadedField,
    capture_from_body: Pose<f64>,
}

fn rig() -> Rig {
    Rig {
        object: field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.06, 3),
        scene: field(FieldInit::Board, Vec3::new(0.0, 0.0, 0.05), 0.3, 7),
        // The body's origin sits off the field's centre, so turning the body also moves its surface.
        capture_from_body: Pose::new(Quat::exp(Vec3::new(0.1, -0.2, 0.3)), Vec3::new(0.008, -0.005, 0.02)),
    }
}

/// Σ over rays of the weighted outputs; `which` picks colour (0), depth (1) or the object's opacity (2).
fn loss_and_grads(n: usize, which: usize, seed: u64) -> Vec<RayGradient> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            let mut g = RayGradient {
                object_opacity: vec![0.0],
                ..RayGradient::default()
            };
            match which {
                0 => g.rgb = [0; 3].map(|_| rng.range(-1.0, 1.0) as f32),
                1 => g.depth = rng.range(-1.0, 1.0) as f32 * 10.0,
                _ => g.object_opacity[0] = rng.range(-1.0, 1.0) as f32,
            }
            g
        })
        .collect()
}

/// What a render leaves for [`value`]: each ray's outputs and the object's opacity.
struct Rendered {
    out: Vec<ComposedRay>,
    object_opacity: Vec<f32>,
}

impl From<&Composer> for Rendered {
    fn from(c: &Composer) -> Self {
        Self {
            out: c.out.clone(),
            object_opacity: c.object_opacity.clone(),
        }
    }
}

fn value(c: &Rendered, g: &[RayGradient]) -> f64 {
    c.out
        .iter()
        .zip(g)
        .enumerate()
        .map(|(i, (o, g))| {
            (0..3).map(|k| o.rgb[k] as f64 * g.rgb[k] as f64).sum::<f64>()
                + o.depth as f64 * g.depth as f64
                + c.object_opacity[i] as f64 * g.object_opacity[0] as f64
        })
        .sum()
}

fn rays(cam: &Camera<f64>) -> (Vec<Vec3<f64>>, Vec<Vec3<f64>>) {
    let mut o = Vec::new();
    let mut d = Vec::new();
    for y in 0..cam.height {
        for x in 0..cam.width {
            let r = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
            o.push(r.origin);
            d.push(r.dir);
        }
    }
    (o, d)
}

/// Analytic vs central differences of the pose gradient, for each output kind, with the scene behind.
fn check_pose_gradients(
    r: &Rig,
    object: &LoadedField,
    capture_from_body: &Pose<f64>,
    cam: &Camera<f64>,
    pose: Pose<f64>,
    fast: bool,
) {
    let silhouette = true;
    check_pose_gradients_in(r, object, capture_from_body, cam, pose, fast, silhouette);
}

/// As [`check_pose_gradients`]; `silhouette`: the object's outline is in view (else it fills the view).
fn check_pose_gradients_in(
    r: &Rig,
    object: &LoadedField,
    capture_from_body: &Pose<f64>,
    cam: &Camera<f64>,
    pose: Pose<f64>,
    fast: bool,
    silhouette: bool,
) {
    let (o, d) = rays(cam);
    let layers_at = |p: &Pose<f64>| {
        let mut obj = Layer::object(object, capture_from_body, p, 0);
        obj.settings = fine(object);
        let mut scene = Layer::scene(&r.scene);
        scene.settings = fine(&r.scene);
        if fast {
            vec![obj]
        } else {
            vec![scene, obj]
        }
    };
    // The fast path: the scene pre-rendered once, behind the object.
    let pre = fast.then(|| {
        let mut scene = Layer::scene(&r.scene);
        scene.settings = fine(&r.scene);
        let mut c = Composer::default();
        c.forward(&[scene], 0, Behind::Colour([0.0; 3]), &o, &d);
        c.out.clone()
    });
    let behind = match &pre {
        Some(p) => Behind::Scene(p),
        None => Behind::Colour([0.0; 3]),
    };
    let grads: Vec<Vec<RayGradient>> = (0..3)
        .map(|which| loss_and_grads(o.len(), which, 11 + which as u64))
        .collect();
    let analytic: Vec<[f64; 6]> = grads
        .iter()
        .map(|grads| {
            let mut c = Composer::default();
            let layers = layers_at(&pose);
            c.forward(&layers, 1, behind, &o, &d);
            let covered = c.object_opacity.iter().filter(|&&a| a > 0.5).count();
            let expected = if silhouette {
                covered > 10 && covered < o.len() - 10
            } else {
                covered == o.len()
            };
            assert!(expected, "the object covers {covered} of {} pixels", o.len());
            c.backward(&layers, grads)[0]
        })
        .collect();
    // Central differences: the least-squares slope over six evenly spaced offsets (f32 rendering noise
    // averages out), at steps of `base` for colour and opacity and twice that for depth. Every offset is then a
    // multiple of `base` (±1, ±2, ±3, ±4, ±6), so each moved pose is rendered once for all three outputs.
    let multiples = [-6, -4, -3, -2, -1, 1, 2, 3, 4, 6];
    let offsets = [-3.0, -2.0, -1.0, 1.0, 2.0, 3.0];
    let mut fd = [[0.0f64; 6]; 3];
    // One composer for every render: its buffers are reused rather than allocated anew each time.
    let mut c = Composer::default();
    for k in 0..6 {
        let base = if k < 3 { 1e-5 } else { 2e-4 };
        let renders: Vec<Rendered> = multiples
            .iter()
            .map(|&m| {
                let mut e = [0.0; 6];
                e[k] = m as f64 * base;
                let rot = Quat::exp(Vec3::new(e[3], e[4], e[5]));
                let p = Pose::new(rot * pose.q, pose.t + Vec3::new(e[0], e[1], e[2]));
                c.forward(&layers_at(&p), 1, behind, &o, &d);
                Rendered::from(&c)
            })
            .collect();
        for (which, grads) in grads.iter().enumerate() {
            let factor = if which == 1 { 2 } else { 1 };
            let h = base * factor as f64;
            let moved = |s: f64| {
                let m = s as i32 * factor;
                value(&renders[multiples.iter().position(|&x| x == m).unwrap()], grads)
            };
            fd[which][k] =
                offsets.iter().map(|&s| s * moved(s)).sum::<f64>() / (h * offsets.iter().map(|s| s * s).sum::<f64>());
        }
    }
    for which in 0..3 {
        for k in 0..6 {
            let fd = fd[which][k];
            let block = if k < 3 { 0..3 } else { 3..6 };
            let scale = analytic[which][block].iter().map(|v| v * v).sum::<f64>().sqrt();
            let err = (analytic[which][k] - fd).abs() / scale.max(1e-9);
            eprintln!(
                "output {which} component {k}: analytic {:.5e} differences {fd:.5e} error {err:.2e}",
                analytic[which][k]
            );
            // NeuS's section opacity has a kink where a ray grazes the surface (cos = 0, `iter_cos`), right
            // at the silhouette where depth jumps from the object to the scene: differences over a window
            // that holds such samples stray by up to ~2 % for depth (colour and opacity stay within 0.6 %).
            // Without a silhouette in view, depth is held to 1 % like the rest.
            let tolerance = if which == 1 && silhouette { 3e-2 } else { 1e-2 };
            assert!(
                err <= tolerance,
                "output {which}, component {k}: analytic {:.6e}, differences {fd:.6e} (relative to the block's norm {scale:.3e}: {err:.2e})",
                analytic[which][k]
            );
        }
    }
}

#[test]
fn pose_gradients_match_central_differences() {
    let r = rig();
    let cam = camera(Vec3::new(0.2, -0.12, 0.12), Vec3::new(0.02, 0.0, 0.03), 24, 18);
    let pose = Pose::new(Quat::exp(Vec3::new(0.2, 0.1, -0.4)), Vec3::new(0.02, 0.01, 0.01));
    check_pose_gradients(&r, &r.object, &r.capture_from_body, &cam, pose, false);
}

#[test]
fn pose_gradients_of_a_baked_object_match_central_differences() {
    // The object's geometry baked (neus::baked_geometry): the fit's path, three lattice steps a cell of its
    // occupancy (every cell: no occupancy border moves samples as the pose moves).
    let mut r = rig();
    r.object.bake(3).unwrap();
    let cam = camera(Vec3::new(0.2, -0.12, 0.12), Vec3::new(0.02, 0.0, 0.03), 24, 18);
    let pose = Pose::new(Quat::exp(Vec3::new(0.2, 0.1, -0.4)), Vec3::new(0.02, 0.01, 0.01));
    check_pose_gradients(&r, &r.object, &r.capture_from_body, &cam, pose, true);
}

#[test]
fn a_bake_of_one_step_a_cell_is_refused_and_zero_drops_a_bake() {
    let mut r = rig();
    let one = r.object.bake(1).unwrap_err();
    assert!(one.contains("at least 2"), "{one}");
    assert!(r.object.baked().is_none());
    r.object.bake(2).unwrap();
    assert_eq!(r.object.bake_steps(), 2);
    assert!(r.object.baked().is_some_and(|b| b.bricks() > 0));
    r.object.bake(0).unwrap();
    assert!(r.object.baked().is_none());
    // A grid not yet refined (every cell occupied) would bake 33 M points: the network is read instead.
    r.object.occupancy = OccupancyGrid::full(64);
    r.object.bake(4).unwrap();
    assert!(r.object.baked().is_none());
    r.object.occupancy = OccupancyGrid::full(16);
    r.object.bake(4).unwrap();
    assert!(r.object.baked().is_some());
}

#[test]
fn a_baked_object_renders_as_its_network() {
    let mut r = rig();
    r.object.occupancy = ball_occupancy(16, 0.6);
    let pose = Pose::new(Quat::exp(Vec3::new(0.3, -0.5, 1.2)), Vec3::new(0.1, -0.05, 0.04));
    let cam = camera(pose.t + Vec3::new(0.11, 0.04, 0.07), pose.t, 40, 30);
    let render = |object: &LoadedField| {
        let layer = Layer::object(object, &r.capture_from_body, &pose, 0);
        render_composed(&[layer], 1, Behind::Colour([0.0; 3]), &cam, &mut Composer::default())
    };
    let network = render(&r.object);
    r.object.bake(4).unwrap();
    let baked = render(&r.object);
    let (mut worst, mut sq) = (0.0f32, 0.0f64);
    for (a, b) in baked.rgb.iter().zip(&network.rgb) {
        for k in 0..3 {
            worst = worst.max((a[k] - b[k]).abs());
            sq += ((a[k] - b[k]) as f64).powi(2);
        }
    }
    let psnr = -10.0 * (sq / (3 * baked.rgb.len()) as f64).log10();
    let opacity = baked
        .object_opacity
        .iter()
        .zip(&network.object_opacity)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    let covered = network.object_opacity.iter().filter(|&&a| a > 0.5).count();
    assert!(covered > 100, "the object covers {covered} pixels");
    // The untrained field's finest hash levels add detail far under a lattice step; the sphere itself is
    // smooth at it.
    assert!(
        psnr > 40.0 && worst < 0.05 && opacity < 0.05,
        "PSNR {psnr:.1} dB, worst colour {worst}, opacity {opacity}"
    );
}

#[test]
fn pose_gradients_match_central_differences_inside_the_silhouette() {
    // The camera close to a sharper object, which fills the view: no ray grazes its surface, so depth
    // has no kink within the differences' window.
    let mut r = rig();
    r.object.field.extra[0] = 300f32.ln() / 10.0;
    let pose = Pose::new(Quat::exp(Vec3::new(0.2, 0.1, -0.4)), Vec3::new(0.02, 0.01, 0.04));
    let centre = pose.transform_point(r.capture_from_body.inverse_transform_point(r.object.centre));
    let cam = camera(centre + Vec3::new(0.035, -0.02, 0.025), centre, 16, 12);
    check_pose_gradients_in(&r, &r.object, &r.capture_from_body, &cam, pose, false, false);
}

#[test]
fn pose_gradients_of_the_other_field_below_the_board() {
    // A two-pose object seen from below the primary field's board: the other field renders (Eq. 4) and its
    // rays cross the primary frame's z = 0 seam; the gradient flows through the other field and the merge
    // transform.
    let r = rig();
    let other = field(FieldInit::Sphere, Vec3::new(0.01, 0.0, 0.028), 0.065, 5);
    let flip = Pose::new(Quat::exp(Vec3::new(3.1, 0.05, 0.0)), Vec3::new(0.0, 0.0, 0.05));
    let other_from_body = flip.compose(&r.capture_from_body);
    // Turned over by the pose, the body shows its primary frame's underside to a camera above the table.
    let pose = Pose::new(Quat::exp(Vec3::new(3.0, 0.2, 0.1)), Vec3::new(0.0, 0.01, 0.03));
    let cam = camera(Vec3::new(0.18, 0.1, 0.15), Vec3::new(0.0, 0.01, 0.03), 24, 18);
    // The camera is below the board in the primary frame.
    let in_primary = r
        .capture_from_body
        .compose(&pose.inverse())
        .transform_point(cam.center());
    assert!(
        in_primary.z < 0.0,
        "the camera must sit below the primary board: {in_primary:?}"
    );
    check_pose_gradients(&r, &other, &other_from_body, &cam, pose, false);
}

#[test]
fn a_posed_object_renders_as_its_field_from_the_inversely_moved_camera() {
    let mut r = rig();
    // Cells near the sphere only, so pixels whose rays miss them are culled (and must still match).
    r.object.occupancy = ball_occupancy(16, 0.6);
    let pose = Pose::new(Quat::exp(Vec3::new(0.3, -0.5, 1.2)), Vec3::new(0.1, -0.05, 0.04));
    let cam = camera(pose.t + Vec3::new(0.11, 0.04, 0.07), pose.t, 40, 30);
    let mut layer = Layer::object(&r.object, &r.capture_from_body, &pose, 0);
    // Every sample, in both renderers.
    layer.settings.stop_transmittance = 0.0;
    let set = layer.settings;
    let bg = r.object.field.background();
    let img = render_composed(&[layer], 1, Behind::Colour(bg), &cam, &mut Composer::default());
    // Eq. 7: the camera moved by H⁻¹ into the body frame, then into the field's capture and unit frame.
    let capture_from_world = r.capture_from_body.compose(&pose.inverse());
    let mut moved = cam;
    moved.world_to_cam = cam.world_to_cam.compose(&capture_from_world.inverse());
    let (c, rad) = (r.object.centre, r.object.radius);
    moved.world_to_cam.t = (moved.world_to_cam.t + moved.world_to_cam.q.rotate(c)) * (1.0 / rad);
    let own = render_view(&r.object.field, &r.object.occupancy, &set, &moved);
    let mut hit = 0;
    for i in 0..img.rgb.len() {
        for k in 0..3 {
            assert!(
                (img.rgb[i][k] - own.rgb[i][k]).abs() < 2e-4,
                "pixel {i}: {:?} vs {:?}",
                img.rgb[i],
                own.rgb[i]
            );
        }
        assert!(
            (img.object_opacity[i] - own.opacity[i]).abs() < 2e-4,
            "pixel {i} opacity"
        );
        assert!(
            (img.depth[i] as f64 - own.depth[i] as f64 * rad).abs() < 1e-5,
            "pixel {i} depth"
        );
        hit += usize::from(own.opacity[i] > 0.5);
    }
    assert!(hit > 50 && hit < img.rgb.len() - 50, "the object covers {hit} pixels");
    assert!(
        img.traced < img.rgb.len() * 3 / 4,
        "{} of {} pixels traced: rays that miss the occupied cells must be culled",
        img.traced,
        img.rgb.len()
    );
}

/// Cells whose centres lie within `radius` of the unit frame's origin.
fn ball_occupancy(res: usize, radius: f32) -> OccupancyGrid {
    let full = OccupancyGrid::full(res);
    let cells = (0..res * res * res)
        .map(|i| u8::from(full.centre(i).iter().map(|v| v * v).sum::<f32>() <= radius * radius))
        .collect();
    OccupancyGrid::from_cells(res, cells)
}

/// The object half sunk into a sharp board (a trained scene's surface is a few millimetres thick), seen
/// by a fixed camera: the scene pre-rendered once with the object composited over it, hidden below the
/// scene's surface.
fn sunk_rig() -> (Rig, Camera<f64>, Pose<f64>) {
    let mut r = rig();
    // inv_s = 1000 per unit (radius 0.3 m): the board's opacity rises over about a millimetre.
    r.scene.field.extra[0] = 1000f32.ln() / 10.0;
    let cam = camera(Vec3::new(0.2, -0.12, 0.12), Vec3::new(0.02, 0.0, 0.0), 40, 30);
    let pose = Pose::new(Quat::exp(Vec3::new(0.2, 0.1, -0.4)), Vec3::new(0.02, 0.01, -0.01));
    (r, cam, pose)
}

#[test]
fn the_fixed_camera_fast_path_matches_the_reference() {
    let (mut r, cam, pose) = sunk_rig();
    // Cells near the sphere only, so pixels whose rays miss them are culled.
    r.object.occupancy = ball_occupancy(16, 0.6);
    let object = Layer::object(&r.object, &r.capture_from_body, &pose, 0);
    let scene = Layer::scene(&r.scene);
    let mut c = Composer::default();
    let reference = render_composed(&[scene, object], 1, Behind::Colour([0.0; 3]), &cam, &mut c);
    let pre = prerender_scene(&r.scene, &cam, &mut c);
    let object = Layer::object(&r.object, &r.capture_from_body, &pose, 0);
    let fast = render_composed(&[object], 1, Behind::Scene(&pre), &cam, &mut c);
    let n = reference.rgb.len();
    assert!(fast.traced < n / 2, "{} of {n} pixels traced", fast.traced);
    let object = Layer::object(&r.object, &r.capture_from_body, &pose, 0);
    let alone = render_composed(&[object], 1, Behind::Colour([0.0; 3]), &cam, &mut c);
    // Where the object (its mean depth) is within a centimetre of the scene's (the line where it enters the
    // board), the reference blends the two soft surfaces and the fast path cuts the object at the scene's:
    // they may differ there. Everywhere else they must agree.
    let near_contact = |p: usize| {
        let a = alone.object_opacity[p];
        a > 0.01 && (alone.depth[p] / a - pre[p].surface).abs() < 0.01
    };
    let (mut worst, mut sum, mut contact_line, mut seen, mut hidden) = (0.0f32, 0.0f32, 0, 0, 0);
    for p in 0..n {
        let e = (0..3)
            .map(|k| (reference.rgb[p][k] - fast.rgb[p][k]).abs())
            .chain([
                (reference.object_opacity[p] - fast.object_opacity[p]).abs(),
                (reference.depth[p] - fast.depth[p]).abs() * 10.0,
            ])
            .fold(0.0, f32::max);
        sum += e;
        if near_contact(p) {
            contact_line += 1;
        } else {
            worst = worst.max(e);
        }
        seen += usize::from(fast.object_opacity[p] > 0.5);
        // Where the object is below the board, the board hides it.
        hidden += usize::from(alone.object_opacity[p] > 0.5 && fast.object_opacity[p] < 0.1);
    }
    eprintln!(
        "fast vs reference (colour, object opacity, depth in decimetres): mean {:.2e}, worst {worst:.2e} away from the {contact_line} pixels of the contact line; object seen in {seen} pixels, hidden in {hidden}",
        sum / n as f32
    );
    assert!(
        seen > 30 && hidden >= 5,
        "the object is seen in {seen} pixels and hidden by the board in {hidden}"
    );
    // The test's object is soft (its surface a few millimetres thick, a trained one's is sharper), so
    // its faint rim a little in front of the board still differs by about 1 %.
    assert!(worst < 0.02 && sum / (n as f32) < 1e-3 && contact_line < n / 20);
}

#[test]
fn rays_stopped_early_change_the_image_by_less_than_the_threshold() {
    let (mut r, cam, pose) = sunk_rig();
    // A sharper object, so rays through it become opaque.
    r.object.field.extra[0] = 300f32.ln() / 10.0;
    let render = |stop: f32| {
        let mut object = Layer::object(&r.object, &r.capture_from_body, &pose, 0);
        let mut scene = Layer::scene(&r.scene);
        object.settings.stop_transmittance = stop;
        scene.settings.stop_transmittance = stop;
        render_composed(
            &[scene, object],
            1,
            Behind::Colour([0.0; 3]),
            &cam,
            &mut Composer::default(),
        )
    };
    let (all, stopped) = (render(0.0), render(1e-3));
    let mut worst = 0.0f32;
    for p in 0..all.rgb.len() {
        for k in 0..3 {
            worst = worst.max((all.rgb[p][k] - stopped.rgb[p][k]).abs());
        }
        worst = worst.max((all.object_opacity[p] - stopped.object_opacity[p]).abs());
    }
    eprintln!(
        "samples {} -> {}, worst change {worst:.2e}",
        all.samples, stopped.samples
    );
    // Each of the two fields may leave out at most 1e-3 of the ray's weight.
    assert!(worst <= 2e-3, "worst change {worst}");
    assert!(
        stopped.samples * 10 < all.samples * 8,
        "{} of {} samples",
        stopped.samples,
        all.samples
    );
}

#[test]
fn a_view_whose_rays_stop_early_changes_by_less_than_the_threshold() {
    let (r, cam, _) = sunk_rig();
    // The camera in the scene field's unit frame.
    let mut unit = cam;
    let (c, rad) = (r.scene.centre, r.scene.radius);
    unit.world_to_cam.t = (unit.world_to_cam.t + unit.world_to_cam.q.rotate(c)) * (1.0 / rad);
    let render = |stop: f32| {
        let set = RenderSettings {
            stop_transmittance: stop,
            ..RenderSettings::of(&r.scene)
        };
        render_view(&r.scene.field, &r.scene.occupancy, &set, &unit)
    };
    let (all, stopped) = (render(0.0), render(1e-3));
    // Colour, opacity and the normal (Σ w n, unit normals) move by at most the weight left out; the depth
    // (Σ w t) by at most that times the farthest sample's distance.
    let far = (unit.world_to_cam.t.norm() + 1.0) as f32;
    let (mut worst, mut worst_depth) = (0.0f32, 0.0f32);
    for p in 0..all.rgb.len() {
        for k in 0..3 {
            worst = worst.max((all.rgb[p][k] - stopped.rgb[p][k]).abs());
            worst = worst.max((all.normal[p][k] - stopped.normal[p][k]).abs());
        }
        worst = worst.max((all.opacity[p] - stopped.opacity[p]).abs());
        worst_depth = worst_depth.max((all.depth[p] - stopped.depth[p]).abs());
    }
    eprintln!(
        "samples {} -> {}, worst change {worst:.2e}, depth {worst_depth:.2e} (farthest {far:.2})",
        all.samples, stopped.samples
    );
    assert!(worst <= 1e-3, "worst change {worst}");
    assert!(worst_depth <= 1e-3 * far, "worst depth change {worst_depth}");
    // The board is opaque: the samples under it (past the round in which the ray became opaque) are never
    // evaluated.
    assert!(
        stopped.samples * 10 < all.samples * 8,
        "{} of {} samples",
        stopped.samples,
        all.samples
    );
}

#[test]
fn pose_gradients_of_the_fast_path_match_central_differences() {
    let (r, cam, pose) = sunk_rig();
    check_pose_gradients(&r, &r.object, &r.capture_from_body, &cam, pose, true);
}

/// Random gradients of every output of `n` rays through two bodies.
fn two_body_grads(n: usize, seed: u64) -> Vec<RayGradient> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| RayGradient {
            rgb: [0; 3].map(|_| rng.range(-1.0, 1.0) as f32),
            depth: rng.range(-1.0, 1.0) as f32,
            object_opacity: vec![rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32],
        })
        .collect()
}

/// Two bodies, one in front of the other: the gradient of one alone (`backward_of`) is, bit for bit, its
/// entry of the full backward, and the body not wanted gets zero.
#[test]
fn the_gradient_of_one_body_alone_is_its_entry_of_all() {
    let r = rig();
    let cam = camera(Vec3::new(0.25, -0.2, 0.15), Vec3::new(0.0, 0.0, 0.03), 24, 18);
    let (o, d) = rays(&cam);
    let near = Pose::new(Quat::exp(Vec3::new(0.0, 0.0, 0.4)), Vec3::new(0.03, -0.02, 0.0));
    let far = Pose::new(Quat::exp(Vec3::new(0.2, 0.0, -0.3)), Vec3::new(-0.02, 0.02, 0.0));
    let layers = vec![
        Layer::object(&r.object, &r.capture_from_body, &near, 0),
        Layer::object(&r.object, &r.capture_from_body, &far, 1),
    ];
    let grads = two_body_grads(o.len(), 5);
    let mut c = Composer::default();
    c.forward(&layers, 2, Behind::Colour([0.2; 3]), &o, &d);
    let both: Vec<f64> = (0..o.len())
        .map(|i| c.object_opacity[2 * i].min(c.object_opacity[2 * i + 1]) as f64)
        .collect();
    assert!(both.iter().any(|&a| a > 0.01), "the bodies overlap in the view");
    let all = c.backward(&layers, &grads);
    assert!(
        all.iter().all(|g| g.iter().any(|&x| x != 0.0)),
        "both bodies have a gradient: {all:?}"
    );
    for wanted in 0..2 {
        let one = c.backward_of(&layers, &grads, |object| object == wanted);
        assert_eq!(one[wanted], all[wanted], "body {wanted}");
        assert_eq!(one[1 - wanted], [0.0; 6], "the body not wanted");
    }
}

/// A body held fixed (its samples drawn once, [`FixedSamples`]) renders, bit for bit, as its layer drawn
/// again: colour, depth, opacity, both bodies' opacities and the other body's pose gradient, over a
/// pre-rendered scene that hides part of both.
#[test]
fn a_body_held_fixed_renders_as_its_layer_drawn_again() {
    let (r, cam, _) = sunk_rig();
    let (o, d) = rays(&cam);
    let pre = prerender_scene(&r.scene, &cam, &mut Composer::default());
    let near = Pose::new(Quat::exp(Vec3::new(0.0, 0.0, 0.4)), Vec3::new(0.03, -0.02, -0.01));
    let far = Pose::new(Quat::exp(Vec3::new(0.2, 0.0, -0.3)), Vec3::new(-0.01, 0.02, 0.0));
    let layers = vec![
        Layer::object(&r.object, &r.capture_from_body, &near, 0),
        Layer::object(&r.object, &r.capture_from_body, &far, 1),
    ];
    let grads = two_body_grads(o.len(), 9);
    let mut both = Composer::default();
    both.forward(&layers, 2, Behind::Scene(&pre), &o, &d);
    let want = both.backward_of(&layers, &grads, |object| object == 0)[0];
    // The far body alone, its samples kept; then the near one over them.
    let mut c = Composer::default();
    c.forward(&layers[1..], 2, Behind::Colour([0.0; 3]), &o, &d);
    let fixed = c.samples_as_fixed(&layers[1..]);
    assert!(fixed.samples() > 0, "the far body is in view");
    // Through a cache: the rays copied one by one, as a frame's fit assembles them.
    let mut copied = FixedSamples::default();
    for i in 0..fixed.rays() {
        copied.push_ray_of(&fixed, i);
    }
    c.forward_over(&layers[..1], 2, Behind::Scene(&pre), &o, &d, Some(&copied));
    assert_eq!(c.out, both.out);
    assert_eq!(c.object_opacity, both.object_opacity);
    assert!(
        (0..o.len()).any(|i| both.object_opacity[2 * i] > 0.01 && both.object_opacity[2 * i + 1] > 0.01),
        "the bodies overlap in the view"
    );
    let got = c.backward_of(&layers[..1], &grads, |object| object == 0)[0];
    assert_eq!(got, want);
    assert!(got.iter().any(|&x| x != 0.0));
}

/// A frame of more chunks than threads renders the same bits on one thread and on three (the chunks side by
/// side, a composer each; a scene layer and a posed object over a pre-rendered scene).
#[test]
fn a_many_chunk_frame_renders_the_same_on_any_number_of_threads() {
    let r = rig();
    let pose = Pose::new(Quat::exp(Vec3::new(0.2, 0.1, -0.4)), Vec3::new(0.0, 0.0, 0.03));
    // 96 × 72 = 6,912 rays: four chunks of 2,048, the last one short.
    let cam = camera(Vec3::new(0.25, -0.2, 0.2), Vec3::new(0.0, 0.0, 0.03), 96, 72);
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let pre = prerender_scene(&r.scene, &cam, &mut Composer::default());
            let object = Layer::object(&r.object, &r.capture_from_body, &pose, 0);
            let img = render_composed(&[object], 1, Behind::Scene(&pre), &cam, &mut Composer::default());
            (pre, img.rgb, img.depth, img.object_opacity, img.traced, img.samples)
        })
    };
    let one = render(1);
    let three = render(3);
    assert_eq!(one.0.len(), 96 * 72);
    assert!(one.4 > 2048, "more than one chunk traced: {}", one.4);
    assert!(one.0 == three.0, "the pre-rendered scene differs with the thread count");
    assert!(
        one.1 == three.1 && one.2 == three.2 && one.3 == three.3,
        "the frame differs with the thread count"
    );
    assert_eq!((one.4, one.5), (three.4, three.5));
}
