//! `mesh`, `bake`, `compare-mesh` and `merge`: the zero level of a trained field, SDF grids for the
//! simulator (a scene's with its planes made exact: [`bake_scene`]), mesh metrics, and one object from its
//! reconstructions in two poses (Sec. 3.2, Fig. 2b).

use crate::cameras::world_cameras;
use crate::error::{err, fail, Context};
use crate::run_folder::checkpoint_of;
use crate::Result;
use crate::{note, Observer, Task};
use geom::Vec3;
use neus::checkpoint::load_field;
use pganeus_io::read_mesh;
use sim::sdf::{MeshDistance, PlaneSettings, SdfGrid};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus mesh runs/toy_a --out toy_a.ply
  pganeus mesh runs/toy_a --out toy_a.ply --res 256 --largest-piece --faces 5000")
)]
pub struct MeshArgs {
    /// A run folder (from `pganeus train`) or its checkpoint.
    pub run: PathBuf,
    /// The PLY to write (world coordinates).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// Grid points along each side of the unit cube.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 256))]
    pub res: usize,
    /// Simplify to at most this many faces by quadric edge collapses (a light mesh for the
    /// simulator's contact points: `shape = "mesh"` with `contact_vertices = true`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub faces: Option<usize>,
    /// Also write points on the zero level with the field's normals (a PLY point cloud):
    /// samples of the mesh moved onto the field's zero level along its gradient.
    #[cfg_attr(feature = "clap", arg(long))]
    pub points: Option<PathBuf>,
    /// Keep only the largest connected piece (the object; NeuS leaves floaters and bits of
    /// background near the unit cube's edge).
    #[cfg_attr(feature = "clap", arg(long))]
    pub largest_piece: bool,
    /// How many points `--points` writes (at most: points that do not settle are dropped).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 100_000))]
    pub point_count: usize,
}

pub fn mesh(a: &MeshArgs, observer: &dyn Observer) -> Result<()> {
    let l = load_field(&checkpoint_of(&a.run))?;
    let t0 = std::time::Instant::now();
    let mut m = zero_level_mesh(
        &l.field,
        l.config.field.grid.levels,
        l.centre,
        l.radius,
        a.res,
        observer,
    );
    if m.faces.is_empty() {
        fail!(
            Input,
            "{}: the field has no zero level inside its unit sphere's cube (nothing to mesh)",
            a.run.display()
        );
    }
    if a.largest_piece {
        m = mesh::largest_component(&m);
    }
    if let Some(path) = &a.points {
        let levels = l.config.field.grid.levels;
        // One finest-level cell as the finite-difference step and the tolerance.
        let step = 2.0 * l.radius / l.config.field.grid.max_resolution as f64;
        let start = sim::sample_surface::sample_surface(&m, a.point_count, 1);
        let (pts, normals) =
            mesh::zero_level_points(&|p: &[Vec3<f64>]| field_distances(&l, levels, p), &start, step, 3, step);
        let cloud = pganeus_io::PlyMesh {
            mesh: geom::TriMesh::new(pts.iter().map(|p| p.to_array()).collect(), vec![]),
            colors: None,
            normals: Some(normals.iter().map(|n| n.to_array().map(|v| v as f32)).collect()),
        };
        pganeus_io::write_ply(path, &cloud, pganeus_io::PlyEncoding::BinaryLittleEndian)?;
        note(
            observer,
            format!(
                "{} of {} points on the zero level, with normals; wrote {}",
                pts.len(),
                start.len(),
                path.display()
            ),
        );
    }
    if let Some(n) = a.faces {
        m = mesh::decimate(&m, n);
    }
    if let Err(e) = sim::check_closed_mesh(&m) {
        tracing::warn!(
            "{}: the zero level reaches the edge of the unit cube, so the mesh is open ({e})",
            a.run.display()
        );
    }
    pganeus_io::write_ply(
        &a.out,
        &pganeus_io::PlyMesh::from_mesh(m.clone()),
        pganeus_io::PlyEncoding::BinaryLittleEndian,
    )?;
    note(
        observer,
        format!(
            "{} vertices, {} faces at {}³ in {:.2} s; wrote {}",
            m.vertices.len(),
            m.faces.len(),
            a.res,
            t0.elapsed().as_secs_f64(),
            a.out.display()
        ),
    );
    Ok(())
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus bake runs/scene --out scene.sdf
  pganeus bake toy.ply --out toy.sdf
  pganeus bake toy.ply --out toy.npz")
)]
pub struct BakeArgs {
    /// A run folder / checkpoint (its field) or a closed mesh (.ply, .obj).
    pub source: PathBuf,
    /// The grid file to write (read by scene files' `shape = "grid"` and `fit --scene-grid`); with `.npz`, a
    /// NumPy archive instead: `sdf` (float32, shape [nz, ny, nx], metres, negative inside), `origin` (the
    /// node [0, 0, 0], m) and `spacing` (m).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// Nodes along the longest side. Default 256 for scene fields (as `fit` bakes a scene: 3.5 mm on a 0.9 m
    /// board; at 128 a wall's foot leans by degrees), 128 for objects and meshes.
    #[cfg_attr(feature = "clap", arg(long))]
    pub res: Option<usize>,
    /// Bounds "xmin,ymin,zmin,xmax,ymax,zmax" in metres (default: an object field's unit-sphere cube; a scene
    /// field's board region: the unit sphere's square in x and y, from 10 % of its radius below the board to as
    /// far above its highest surface; a mesh's box padded by 5 %).
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ',', allow_hyphen_values = true))]
    pub bounds: Option<Vec<f64>>,
    /// Height of the floor, m: everything below it is solid (the grid takes the union of the field with that
    /// half-space), so the sign is right under the board however little the cameras saw there. Default for
    /// scene fields 0 (captures are calibrated on the board, the plane z = 0); none for objects and meshes.
    #[cfg_attr(feature = "clap", arg(long, allow_hyphen_values = true, conflicts_with = "no_floor"))]
    pub floor: Option<f64>,
    /// No floor, also for a scene field.
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_floor: bool,
    /// Blur the grid by a Gaussian of this many node spacings (planes stay exact; detail finer than
    /// this, such as a reconstruction's sub-pixel roughness that tilts contact normals, is averaged away).
    /// Default 1.5 for scene fields, 0 for objects and meshes.
    #[cfg_attr(feature = "clap", arg(long))]
    pub smooth: Option<f64>,
    /// Make the grid's planes exact: the planes found on its zero level snapped (their relief and roughness
    /// flattened), their concave creases made sharp, only the other nodes blurred (docs/commands/bake.md,
    /// "The scene's planes"). Default for scene fields; this flag asks for it on objects and meshes too.
    #[cfg_attr(feature = "clap", arg(long, conflicts_with = "no_planes"))]
    pub planes: bool,
    /// Only blur, also for a scene field.
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_planes: bool,
    /// How far from a concave crease between two planes the field is made sharp, m: wider than the fillet
    /// NeuS leaves there (10–15 mm measured at the tabletop wall's foot).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = PlaneSettings::default().crease_reach))]
    pub crease_reach: f64,
}

impl BakeArgs {
    /// A bake of `source` into `out` with the command's defaults.
    pub fn new(source: PathBuf, out: PathBuf) -> BakeArgs {
        BakeArgs {
            source,
            out,
            res: None,
            bounds: None,
            floor: None,
            no_floor: false,
            smooth: None,
            planes: false,
            no_planes: false,
            crease_reach: PlaneSettings::default().crease_reach,
        }
    }
}

/// The board region of a scene field: the unit sphere's square in x and y; in z, from 10 % of its radius below
/// the board (z = 0) to as far above the highest point of its zero level.
fn scene_box(l: &neus::checkpoint::LoadedField, observer: &dyn Observer) -> ([f64; 3], [f64; 3]) {
    let (c, r) = (l.centre.to_array(), l.radius);
    let m = zero_level_mesh(&l.field, l.config.field.grid.levels, l.centre, r, 96, observer);
    let top = m.vertices.iter().map(|v| v[2]).fold(0.0, f64::max);
    let z_hi = (top + 0.1 * r).min(c[2] + r);
    ([c[0] - r, c[1] - r, -0.1 * r], [c[0] + r, c[1] + r, z_hi])
}

/// A field's SDF in metres sampled on the nodes of `bounds` (`res` along the longest side), united with the
/// solid below `floor` when given.
fn field_grid(
    l: &neus::checkpoint::LoadedField,
    source: &Path,
    (lo, hi): ([f64; 3], [f64; 3]),
    res: usize,
    floor: Option<f64>,
    observer: &dyn Observer,
) -> Result<SdfGrid> {
    let (c, r) = (l.centre.to_array(), l.radius);
    let h = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max) / (res - 1) as f64;
    let dims: [usize; 3] = std::array::from_fn(|k| ((hi[k] - lo[k]) / h).ceil() as usize + 1);
    let mut pts = Vec::with_capacity(dims.iter().product::<usize>() * 3);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let w = [lo[0] + x as f64 * h, lo[1] + y as f64 * h, lo[2] + z as f64 * h];
                pts.extend((0..3).map(|k| ((w[k] - c[k]) / r) as f32));
            }
        }
    }
    // In slices (each still parallel inside), for the progress bar.
    const SLICE: usize = 1 << 18;
    let pb = Task::start(observer, "sampling the field", (pts.len() / 3) as u64);
    let mut sdf = Vec::with_capacity(pts.len() / 3);
    for chunk in pts.chunks(3 * SLICE) {
        sdf.extend(l.field.sdf_values(chunk, l.config.field.grid.levels));
        pb.inc((chunk.len() / 3) as u64);
    }
    pb.finish();
    if !sdf.iter().any(|v| *v < 0.0) || !sdf.iter().any(|v| *v > 0.0) {
        fail!(
            Input,
            "{}: the field has no zero level inside the bounds",
            source.display()
        );
    }
    // Unit-sphere distances to metres, united with the solid below the floor.
    let values = sdf
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let d = v * r as f32;
            match floor {
                Some(f) => d.min((lo[2] + (i / (dims[0] * dims[1])) as f64 * h - f) as f32),
                None => d,
            }
        })
        .collect();
    Ok(SdfGrid::from_values(lo, h, dims, values)?)
}

/// Nodes along a scene grid's longest side by default (3.5 mm on a 0.9 m board; at 128 a wall's foot leans by
/// degrees).
const SCENE_RES: usize = 256;

/// A scene run's grid for the simulator, as `bake` makes it by default (the board region, 256 nodes along
/// its longest side, the solid below z = 0, its planes made exact, the rest smoothed over 1.5 spacings).
pub fn bake_scene(l: &neus::checkpoint::LoadedField, source: &Path, observer: &dyn Observer) -> Result<SdfGrid> {
    let grid = field_grid(l, source, scene_box(l, observer), SCENE_RES, Some(0.0), observer)?;
    let (grid, planes) = grid.with_planes(&PlaneSettings::default(), 1.5);
    tracing::info!("the scene's planes: {planes}");
    Ok(grid)
}

pub fn bake(a: &BakeArgs, observer: &dyn Observer) -> Result<()> {
    if a.res.is_some_and(|r| r < 2) {
        fail!(Settings, "--res must be at least 2");
    }
    let is_mesh = a
        .source
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply") || e.eq_ignore_ascii_case("obj"));
    let t0 = std::time::Instant::now();
    let bounds = |lo: [f64; 3], hi: [f64; 3]| -> Result<([f64; 3], [f64; 3])> {
        match &a.bounds {
            None => Ok((lo, hi)),
            Some(b) if b.len() == 6 && b.iter().all(|v| v.is_finite()) && (0..3).all(|k| b[k] < b[k + 3]) => {
                Ok(([b[0], b[1], b[2]], [b[3], b[4], b[5]]))
            }
            Some(b) => fail!(Settings, "--bounds: give six numbers with min < max, got {b:?}"),
        }
    };
    let mut scene_field = false;
    let grid = if is_mesh {
        let m = read_mesh(&a.source)?;
        sim::check_closed_mesh(&m).with_context(|| format!("{}", a.source.display()))?;
        let (lo, hi) = m.bounds();
        let pad = 0.05 * (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let (lo, hi) = bounds(lo.map(|v| v - pad), hi.map(|v| v + pad))?;
        let h = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max) / (a.res.unwrap_or(128) - 1) as f64;
        let dist = MeshDistance::new(&m)?;
        SdfGrid::bake(&dist, lo, hi, h)?
    } else {
        let l = load_field(&checkpoint_of(&a.source))?;
        let scene = l.config.kind == neus::CaptureSubject::Scene;
        scene_field = scene;
        let (c, r) = (l.centre.to_array(), l.radius);
        let (lo, hi) = if scene {
            let (lo, hi) = scene_box(&l, observer);
            bounds(lo, hi)?
        } else {
            bounds([0, 1, 2].map(|k| c[k] - r), [0, 1, 2].map(|k| c[k] + r))?
        };
        let floor = match (a.floor, a.no_floor) {
            (_, true) => None,
            (Some(z), _) => Some(z),
            (None, false) => scene.then_some(0.0),
        };
        let res = a.res.unwrap_or(if scene { SCENE_RES } else { 128 });
        field_grid(&l, &a.source, (lo, hi), res, floor, observer)?
    };
    let smooth = a.smooth.unwrap_or(if scene_field { 1.5 } else { 0.0 });
    if !(smooth.is_finite() && smooth >= 0.0) {
        fail!(
            Settings,
            "--smooth must be a non-negative number of node spacings, got {smooth}"
        );
    }
    if !(a.crease_reach.is_finite() && a.crease_reach > 0.0) {
        fail!(
            Settings,
            "--crease-reach must be a positive length in metres, got {}",
            a.crease_reach
        );
    }
    let (grid, planes) = if a.planes || (scene_field && !a.no_planes) {
        let settings = PlaneSettings {
            crease_reach: a.crease_reach,
            ..Default::default()
        };
        let (g, report) = grid.with_planes(&settings, smooth);
        (g, Some(report))
    } else {
        (grid.smoothed(smooth), None)
    };
    if a.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("npz")) {
        write_grid_npz(&grid, &a.out)?;
    } else {
        grid.save(&a.out)?;
    }
    note(
        observer,
        format!(
            "baked {:?} nodes, spacing {:.3} mm{}, in {:.2} s; wrote {}",
            grid.dims(),
            grid.spacing() * 1e3,
            if smooth > 0.0 {
                format!(", smoothed over {smooth} spacings")
            } else {
                String::new()
            },
            t0.elapsed().as_secs_f64(),
            a.out.display()
        ),
    );
    if let Some(p) = planes {
        note(observer, format!("planes: {p}"));
    }
    Ok(())
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus compare-mesh toy_a.ply data/tabletop/toy.ply
  pganeus compare-mesh toy_a.ply --truth data/tabletop/truth.json --capture toy_a")
)]
pub struct CompareMeshArgs {
    pub a: PathBuf,
    /// The mesh to compare with (or give `--truth` and `--capture`).
    #[cfg_attr(feature = "clap", arg(required_unless_present = "truth", conflicts_with = "truth"))]
    pub b: Option<PathBuf>,
    /// Compare with the true mesh of a synthetic dataset's body ...
    #[cfg_attr(feature = "clap", arg(long, requires = "capture"))]
    pub truth: Option<PathBuf>,
    /// ... posed as in this static capture (e.g. `toy_b`): `a` is in that capture's frame. With the
    /// background capture (e.g. `background`), the true scene: both are cropped to its footprint on the board.
    #[cfg_attr(feature = "clap", arg(long, requires = "truth"))]
    pub capture: Option<String>,
    /// Surface samples per mesh (Chamfer, normals) and points for the volume IoU (×10).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 20000))]
    pub samples: usize,
}

/// The part of a scene that a comparison covers: the true scene's footprint on the board (its xy box).
#[derive(Clone, Copy, Debug)]
pub struct SceneRegion {
    pub lo: [f64; 2],
    pub hi: [f64; 2],
}

impl SceneRegion {
    /// The faces of `m` whose centroid lies over the region.
    pub fn crop(&self, m: &geom::TriMesh) -> geom::TriMesh {
        mesh::faces_where(m, |[a, b, c]| {
            (0..2).all(|k| {
                let x = (a[k] + b[k] + c[k]) / 3.0;
                x >= self.lo[k] && x <= self.hi[k]
            })
        })
    }
}

/// The true mesh of `capture` in `truth.json` (read once): the body captured there, posed as it was, or, for
/// the background capture, the part of the true scene a camera above the board can see (faces turned down,
/// such as the board's underside lying on the table, are left out) and its footprint, the region to crop a
/// reconstruction to.
pub fn capture_truth(truth: &Path, capture: &str) -> Result<(geom::TriMesh, PathBuf, Option<SceneRegion>)> {
    let t = pganeus_io::read_truth(truth)?;
    let dir = truth.parent().unwrap_or(Path::new("."));
    if let Some(bg) = t.background.as_ref().filter(|b| b.capture == capture) {
        let path = dir.join(&bg.mesh);
        let m = read_mesh(&path)?;
        let (lo, hi) = m.bounds();
        let up = mesh::faces_where(&m, |[a, b, c]| {
            let [a, b, c] = [a, b, c].map(Vec3::cst);
            (b - a).cross(c - a).normalize_or(Vec3::new(0.0, 0.0, 1.0)).z > -0.5
        });
        let region = SceneRegion {
            lo: [lo[0], lo[1]],
            hi: [hi[0], hi[1]],
        };
        return Ok((up, path, Some(region)));
    }
    let (m, p) = posed_truth(&t, truth, capture)?;
    Ok((m, p, None))
}

/// The true mesh of the body captured in `capture`, posed as it was there (`truth`: the file `t` was read
/// from, for the message and its folder).
fn posed_truth(t: &pganeus_io::Truth, truth: &Path, capture: &str) -> Result<(geom::TriMesh, PathBuf)> {
    let (body, stat) = t
        .bodies
        .iter()
        .find_map(|b| b.static_captures.iter().find(|s| s.capture == capture).map(|s| (b, s)))
        .ok_or_else(|| {
            err!(
                Input,
                "{}: no body has a static capture named {capture:?}",
                truth.display()
            )
        })?;
    let path = truth.parent().unwrap_or(Path::new(".")).join(&body.mesh);
    let mut m = read_mesh(&path)?;
    let pose = geom::Pose::new(geom::Quat::<f64>::cst(stat.pose.q), Vec3::cst(stat.pose.t));
    for v in &mut m.vertices {
        *v = pose.transform_point(Vec3::cst(*v)).to_array();
    }
    Ok((m, path))
}

pub fn compare_mesh(a: &CompareMeshArgs, observer: &dyn Observer) -> Result<()> {
    let mut ma = read_mesh(&a.a)?;
    let (mb, b_path) = match (&a.b, &a.truth, &a.capture) {
        (Some(b), _, _) => (read_mesh(b)?, b.clone()),
        (None, Some(truth), Some(capture)) => {
            let (m, p, region) = capture_truth(truth, capture)?;
            if let Some(r) = region {
                // A scene: compare over the true scene's footprint only (the table beyond is not scene).
                ma = r.crop(&ma);
            }
            (m, p)
        }
        _ => fail!(Stage, "give a second mesh, or --truth and --capture"),
    };
    for (m, p) in [(&ma, &a.a), (&mb, &b_path)] {
        if m.faces.is_empty() {
            fail!(Input, "{}: the mesh has no faces", p.display());
        }
    }
    let c = mesh::chamfer(&ma, &mb, a.samples, 1);
    let nc = mesh::normal_consistency(&ma, &mb, a.samples, 2);
    // Volume needs inside and outside: say which mesh is not closed, and why.
    let open: Vec<String> = [(&ma, &a.a), (&mb, &b_path)]
        .iter()
        .filter_map(|(m, p)| sim::check_closed_mesh(m).err().map(|e| format!("{}: {e}", p.display())))
        .collect();
    let iou = open.is_empty().then(|| mesh::volume_iou(&ma, &mb, a.samples * 10, 3));
    note(
        observer,
        serde_json::to_string_pretty(&serde_json::json!({
            "a": a.a, "b": b_path, "capture": a.capture,
            "chamfer_mean": c.mean, "chamfer_p95": c.p95, "chamfer_max": c.max,
            "normal_consistency": nc,
            "volume_iou": iou,
            "note": if open.is_empty() { String::new() } else { format!("no volume_iou: {}", open.join("; ")) },
        }))?,
    );
    Ok(())
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus merge runs/toy_a runs/toy_b --out merged/toy --capture-a data/tabletop/toy_a --capture-b data/tabletop/toy_b
  pganeus merge cup_a.ply cup_b.ply --out merged/cup")
)]
pub struct MergeArgs {
    /// The object upright: a run folder (from `pganeus train`) or a closed mesh in its capture's frame.
    pub a: PathBuf,
    /// The object turned over: the same.
    pub b: PathBuf,
    /// Output folder: merged.ply (in B's frame) and transform.json.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// Grid resolution of each field's zero level, used for ICP samples and the box (runs only).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 192))]
    pub field_res: usize,
    /// Grid resolution of the merged surface.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 128))]
    pub res: usize,
    /// Height above each board (z = 0) that its cameras could not see, m.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 3e-3))]
    pub board_margin: f64,
    /// Refuse an alignment whose RMS point-to-plane residual is above this, m.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 1e-3))]
    pub max_residual: f64,
    /// Simplify the merged mesh to at most this many faces (quadric edge collapses).
    #[cfg_attr(feature = "clap", arg(long))]
    pub faces: Option<usize>,
    /// A's capture (NeuS layout): its cameras decide what A saw, so parts hidden
    /// from every camera (an overhang, a roof the object stands on) come from B.
    /// Without it, "seen" is "above the board's margin".
    #[cfg_attr(feature = "clap", arg(long))]
    pub capture_a: Option<PathBuf>,
    /// B's capture, likewise.
    #[cfg_attr(feature = "clap", arg(long))]
    pub capture_b: Option<PathBuf>,
    /// Start ICP from a known transform (`q_1to2`, `T_1to2` as in `transform.json`, e.g. from
    /// markers) instead of the automatic search.
    #[cfg_attr(feature = "clap", arg(long))]
    pub start: Option<PathBuf>,
    /// Use `--start` as given: no ICP refinement (its residual is still checked).
    #[cfg_attr(feature = "clap", arg(long, requires = "start"))]
    pub no_refine: bool,
}

impl MergeArgs {
    /// The merge of `a` (upright) and `b` (turned over) into `out` with the command's defaults.
    pub fn new(a: PathBuf, b: PathBuf, out: PathBuf) -> MergeArgs {
        MergeArgs {
            a,
            b,
            out,
            field_res: 192,
            res: 128,
            board_margin: 3e-3,
            max_residual: 1e-3,
            faces: None,
            capture_a: None,
            capture_b: None,
            start: None,
            no_refine: false,
        }
    }
}

/// The cameras of a capture, in its world frame.
fn capture_cameras(dir: &Path) -> Result<Vec<geom::Camera<f64>>> {
    world_cameras(&pganeus_io::open_capture(dir)?)
}

/// A grid as a NumPy archive: x fastest in the file's order is C order for the shape [nz, ny, nx].
fn write_grid_npz(grid: &sim::sdf::SdfGrid, path: &Path) -> Result<()> {
    use pganeus_io::{NpyArray, NpyData};
    let [nx, ny, nz] = grid.dims();
    let sdf = NpyArray {
        shape: vec![nz, ny, nx],
        data: NpyData::F32(grid.values().to_vec()),
    };
    let origin = NpyArray {
        shape: vec![3],
        data: NpyData::F64(grid.origin().to_vec()),
    };
    let spacing = NpyArray {
        shape: vec![],
        data: NpyData::F64(vec![grid.spacing()]),
    };
    pganeus_io::write_npz(path, &[("sdf", &sdf), ("origin", &origin), ("spacing", &spacing)])?;
    Ok(())
}

/// A run's field (its SDF in metres and its zero level), or a closed mesh
/// file, in its capture's world frame.
fn partial_surface(p: &Path, res: usize, observer: &dyn Observer) -> Result<mesh::PartialSurface<'static>> {
    if p.is_dir() || p.extension().is_some_and(|e| e == "safetensors") {
        let l = std::sync::Arc::new(load_field(&checkpoint_of(p))?);
        let levels = l.config.field.grid.levels;
        let zero = zero_level_mesh(&l.field, levels, l.centre, l.radius, res, observer);
        let lc = l.clone();
        let sdf = move |pts: &[Vec3<f64>]| field_distances(&l, levels, pts);
        Ok(mesh::PartialSurface::from_field(&zero, sdf)
            .with_context(|| format!("{}", p.display()))?
            .with_colour(move |pts, normals| field_colour(&lc, pts, normals)))
    } else {
        mesh::PartialSurface::from_mesh(read_mesh(p)?).with_context(|| format!("{}", p.display()))
    }
}

/// A field's colour at surface points (world) seen head-on: rendered along the inward normal from 5 mm out.
fn field_colour(l: &neus::checkpoint::LoadedField, pts: &[Vec3<f64>], normals: &[Vec3<f64>]) -> Vec<[f64; 3]> {
    let set = neus::render_view::RenderSettings::of(l);
    let mut scratch = neus::render_view::RenderScratch::default();
    let unit = |p: Vec3<f64>| ((p - l.centre) * (1.0 / l.radius)).to_array().map(|v| v as f32);
    let mut out = Vec::with_capacity(pts.len());
    for (p, n) in pts.chunks(2048).zip(normals.chunks(2048)) {
        let o: Vec<[f32; 3]> = p.iter().zip(n).map(|(p, n)| unit(*p + *n * 0.005)).collect();
        let d: Vec<[f32; 3]> = n.iter().map(|n| (-*n).to_array().map(|v| v as f32)).collect();
        let rays = neus::render_view::render_rays(&l.field, &l.occupancy, &set, &o, &d, &mut scratch);
        out.extend(rays.iter().map(|(r, _)| r.rgb.map(f64::from)));
    }
    out
}

/// A field's signed distance at world points, in metres. The field is only
/// defined inside its unit sphere; beyond 0.98 of it the value is the
/// distance to that sphere (or the field's, if larger) at the nearest point inside.
fn field_distances(l: &neus::checkpoint::LoadedField, levels: usize, pts: &[Vec3<f64>]) -> Vec<f64> {
    const LIMIT: f64 = 0.98;
    let mut flat = Vec::with_capacity(pts.len() * 3);
    let mut beyond = Vec::with_capacity(pts.len());
    for p in pts {
        let u = (*p - l.centre) * (1.0 / l.radius);
        let n = u.norm();
        let (u, e) = if n > LIMIT {
            (u * (LIMIT / n), Some(n - LIMIT))
        } else {
            (u, None)
        };
        flat.extend(u.to_array().map(|v| v as f32));
        beyond.push(e);
    }
    let f = l.field.sdf_values(&flat, levels);
    f.iter()
        .zip(beyond)
        .map(|(v, e)| e.map_or(*v as f64, |e| (*v as f64).max(e)) * l.radius)
        .collect()
}

pub fn merge(a: &MergeArgs, observer: &dyn Observer) -> Result<()> {
    let t0 = std::time::Instant::now();
    let mut pa = partial_surface(&a.a, a.field_res, observer)?;
    let mut pb = partial_surface(&a.b, a.field_res, observer)?;
    if let Some(dir) = &a.capture_a {
        pa = pa.with_cameras(capture_cameras(dir)?);
    }
    if let Some(dir) = &a.capture_b {
        pb = pb.with_cameras(capture_cameras(dir)?);
    }
    let cfg = mesh::MergeConfig {
        board_margin: a.board_margin,
        resolution: a.res,
        max_residual: a.max_residual,
        start: a.start.as_deref().map(crate::cameras::read_transform).transpose()?,
        refine: !a.no_refine,
        ..mesh::MergeConfig::default()
    };
    let pb_merge = Task::start(observer, "merge", mesh::MergeStage::ALL.len() as u64);
    let mut merged = mesh::merge_two_poses_reporting(&pa, &pb, &cfg, &|stage| {
        pb_merge.inc(1);
        pb_merge.set_status(&format!("merge: {} done", stage.name()));
    })
    .with_context(|| format!("merging {} into {}", a.a.display(), a.b.display()))?;
    pb_merge.finish();
    if let Some(n) = a.faces {
        merged.mesh = mesh::decimate(&merged.mesh, n);
    }
    std::fs::create_dir_all(&a.out)?;
    pganeus_io::write_ply(
        &a.out.join("merged.ply"),
        &pganeus_io::PlyMesh::from_mesh(merged.mesh.clone()),
        pganeus_io::PlyEncoding::BinaryLittleEndian,
    )?;
    let r = merged.a_to_b.q.to_mat().m;
    let body = sim::mass_properties(&merged.mesh, 1.0);
    let doc = serde_json::json!({
        "R_1to2": r, "T_1to2": merged.a_to_b.t.to_array(), "q_1to2": merged.a_to_b.q.to_array_re(),
        "residual": merged.icp.residual, "rms_distance": merged.icp.rms_distance, "icp_iterations": merged.icp.iterations,
        "icp_conditioning": merged.icp.conditioning,
        "reference": "b", "a": pganeus_io::path_relative_to(&a.out, &a.a), "b": pganeus_io::path_relative_to(&a.out, &a.b),
        "board_margin": a.board_margin,
        "object": {
            "note": "the merged object in b's capture frame; the simulator's body frame has its origin at the centre of mass (uniform density)",
            "volume_m3": body.volume, "centre_of_mass": body.center_of_mass.to_array(),
        },
        "capture_a": a.capture_a, "capture_b": a.capture_b,
        "note": "p_b = R_1to2 · p_a + T_1to2; merged.ply is in b's capture frame",
    });
    pganeus_io::write_atomic(
        &a.out.join("transform.json"),
        serde_json::to_string_pretty(&doc)?.as_bytes(),
    )?;
    note(
        observer,
        format!(
            "merged: {} vertices, {} faces; ICP residual {:.3} mm; {:.1} s; wrote {}",
            merged.mesh.vertices.len(),
            merged.mesh.faces.len(),
            merged.icp.residual * 1e3,
            t0.elapsed().as_secs_f64(),
            a.out.display()
        ),
    );
    Ok(())
}

/// A field's zero level (`neus::surface::zero_level_mesh`) with progress over the points sampled.
pub fn zero_level_mesh(
    field: &neus::NeusField,
    levels: usize,
    centre: geom::Vec3<f64>,
    radius: f64,
    res: usize,
    observer: &dyn Observer,
) -> geom::TriMesh {
    let pb = Task::start(observer, &format!("zero level at {res}³"), (res * res * res) as u64);
    let m = neus::surface::zero_level_mesh_reporting(field, levels, centre, radius, res, &|n| pb.inc(n as u64));
    pb.finish();
    m
}
