//! The two-pose object (Sec. 3.2, Fig. 2b): an object reconstructed upright
//! (A) and turned over (B), each closed but guessed underneath where it stood
//! on the board. Keep from each only what its cameras could see (above the
//! board plane z = 0 of its capture, with a margin), align A to B by ICP on
//! those parts, and make one closed surface: the zero level of a fused SDF
//! that takes B's distance where B was seen, A's where only A was seen, and
//! blends across the seam.
//!
//! Each part is a [`PartialSurface`]: a signed distance evaluated in batches
//! (a trained field's own SDF, or a closed mesh's) and its zero-level mesh,
//! cut down to its largest piece (the object, without floaters). The fused
//! SDF uses the distances themselves, so the merged surface is as good as the
//! fields, not as their meshes; its largest piece is the result. "Seen" is
//! above the board's margin and, when a part knows its capture's cameras, also
//! seen by enough of them ([`Visibility`]). How the alignment is chosen
//! (several starts, two refinements, B's board in the target, a preference
//! for the turned-over pose on symmetric objects) is told at `align` (below).

use crate::components::largest_component;
use crate::icp::{icp, icp_evaluate, icp_hypotheses, inlier_fraction, IcpConfig, IcpResult, IcpTarget};
use crate::marching_tetrahedra::{extract_zero_level, ScalarGrid};
use crate::visibility::Visibility;
use crate::zero_level_points::{zero_level_points, BatchSdf};
use geom::{Camera, Pose, TriMesh, Vec3};
use rayon::prelude::*;
use sim::sdf::MeshDistance;

type V = Vec3<f64>;

/// A part's colour at surface points seen head-on (points and outward normals in its capture's frame), RGB.
pub type ColourFn<'a> = dyn Fn(&[V], &[V]) -> Vec<[f64; 3]> + Sync + 'a;

/// A's samples compared by colour with B under an alignment: at most this many.
const COLOUR_SAMPLES: usize = 2000;

#[derive(Clone, Debug, PartialEq)]
pub struct MergeConfig {
    /// Parts within this height of a capture's board (z ≤ margin) were not seen. Default 3 mm.
    pub board_margin: f64,
    /// Width of the blend between the two SDFs across the seam, m. Default 3 mm.
    pub blend: f64,
    /// Grid points along the longest side of the merged object's box. Default 128.
    pub resolution: usize,
    /// Points per cloud given to ICP. Default 20 000.
    pub icp_points: usize,
    /// Refuse the result when ICP's RMS point-to-plane residual is above this, m. Default 1 mm.
    pub max_residual: f64,
    /// Finite-difference step of a field's gradient when ICP samples are projected onto its zero level, m. Default 0.2 mm.
    pub fd_step: f64,
    /// Where A lies in B's frame, if known (`p_B = start · p_A`, e.g. from
    /// markers): ICP starts there instead of searching. Default none.
    pub start: Option<Pose<f64>>,
    /// Refine `start` by ICP (else it is used as given, and only measured). Default true.
    pub refine: bool,
    /// Pairs kept by the second ICP pass (the first keeps `icp.keep_fraction`). Default 0.95.
    pub refine_keep_fraction: f64,
    /// A's samples within this of B's count as landing on it, when the two passes are compared, m. Default 0.5 mm.
    pub inlier_distance: f64,
    /// Refuse an alignment whose [`IcpResult::conditioning`] is below this. Default 1e-3.
    pub min_conditioning: f64,
    /// With cameras: a point is fully seen when at least this many cameras see it. Default 3.
    pub min_cameras: usize,
    /// With cameras: nodes along the longest side of the grid the visibility test traces through. Default 96.
    pub visibility_resolution: usize,
    pub icp: IcpConfig,
}

impl Default for MergeConfig {
    fn default() -> Self {
        Self {
            board_margin: 3e-3,
            blend: 3e-3,
            resolution: 128,
            icp_points: 20000,
            max_residual: 1e-3,
            fd_step: 2e-4,
            start: None,
            refine: true,
            refine_keep_fraction: 0.95,
            inlier_distance: 5e-4,
            min_conditioning: 1e-3,
            min_cameras: 3,
            visibility_resolution: 96,
            icp: IcpConfig {
                keep_fraction: 0.7,
                ..IcpConfig::default()
            },
        }
    }
}

/// Why a mesh or a field cannot be a part of a merge.
#[derive(Debug, thiserror::Error)]
pub enum PartError {
    #[error("the mesh has no faces")]
    NoFaces,
    #[error("{0}")]
    NotClosed(sim::MeshCheckError),
    #[error("{0}")]
    Distance(sim::sdf::MeshSdfError),
    #[error("the field has no zero level")]
    NoZeroLevel,
}

#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("mesh {0} has nothing above its board plane (z > {1} m): was it reconstructed in its capture's frame?")]
    NothingVisible(char, f64),
    #[error("ICP did not converge: RMS residual {residual:.3e} m is above {limit:.1e} m (the two parts may not overlap enough, or be different objects)")]
    NoConvergence { residual: f64, limit: f64 },
    #[error("the alignment is not pinned down (conditioning {conditioning:.1e} < {limit:.0e}): the surfaces both parts show leave a direction free, e.g. only parallel walls; capture more of the object in both poses")]
    IllConditioned { conditioning: f64, limit: f64 },
    #[error("the fused SDF has no zero level")]
    Empty,
    #[error("part {0}: the signed distance returned {1} values for {2} points")]
    ValueCount(char, usize, usize),
}

/// One partial reconstruction, in its capture's frame (board at z = 0).
pub struct PartialSurface<'a> {
    /// The zero level's largest piece.
    mesh: TriMesh,
    sdf: Box<BatchSdf<'a>>,
    /// Whether ICP samples taken on `mesh` are projected onto the SDF's zero
    /// level (a field's mesh is only a marching approximation of it).
    project: bool,
    /// The capture's cameras (its frame), if known: then "seen" also means
    /// seen by them, not only "above the board".
    cameras: Vec<Camera<f64>>,
    /// Its colour, if known: it tells apart the alignments a symmetric shape allows.
    colour: Option<Box<ColourFn<'a>>>,
}

impl<'a> PartialSurface<'a> {
    /// A closed mesh: its distance by the generalized winding number.
    pub fn from_mesh(mesh: TriMesh) -> Result<PartialSurface<'static>, PartError> {
        if mesh.faces.is_empty() {
            return Err(PartError::NoFaces);
        }
        sim::check_closed_mesh(&mesh).map_err(PartError::NotClosed)?;
        let dist = MeshDistance::new(&mesh).map_err(PartError::Distance)?;
        Ok(PartialSurface {
            mesh: largest_component(&mesh),
            sdf: Box::new(move |pts: &[V]| pts.iter().map(|p| dist.signed_distance(*p).0).collect()),
            project: false,
            cameras: Vec::new(),
            colour: None,
        })
    }

    /// A field: its signed distance in metres (`sdf`, batched) and its
    /// extracted zero level, of which the largest piece is kept.
    pub fn from_field(zero_level: &TriMesh, sdf: impl Fn(&[V]) -> Vec<f64> + Sync + 'a) -> Result<Self, PartError> {
        let mesh = largest_component(zero_level);
        if mesh.faces.is_empty() {
            return Err(PartError::NoZeroLevel);
        }
        Ok(Self {
            mesh,
            sdf: Box::new(sdf),
            project: true,
            cameras: Vec::new(),
            colour: None,
        })
    }

    /// The cameras of the part's capture (world frame of that capture), for
    /// a visibility test: parts hidden from every camera (an overhang, the
    /// side the object stands on) are taken from the other pose.
    pub fn with_cameras(mut self, cameras: Vec<Camera<f64>>) -> Self {
        self.cameras = cameras;
        self
    }

    /// The part's colour (a field's, rendered head-on at surface points): of the alignments a symmetric shape
    /// allows equally well (a box turned over about x or about y), the one whose colours agree wins.
    pub fn with_colour(mut self, colour: impl Fn(&[V], &[V]) -> Vec<[f64; 3]> + Sync + 'a) -> Self {
        self.colour = Some(Box::new(colour));
        self
    }

    /// The part's box, padded by a tenth of its size.
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let (lo, hi) = self.mesh.bounds();
        let pad = 0.1 * (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        (lo.map(|v| v - pad), hi.map(|v| v + pad))
    }

    /// The visibility test of this part, if it has cameras.
    fn visibility(&self, resolution: usize) -> Option<Visibility> {
        if self.cameras.is_empty() {
            return None;
        }
        let (lo, hi) = self.bounds();
        Some(Visibility::new(&*self.sdf, lo, hi, resolution, self.cameras.clone()))
    }

    /// The object's zero-level mesh (largest piece).
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// Signed distances at `points`, checked for count.
    fn distances(&self, name: char, points: &[V]) -> Result<Vec<f64>, MergeError> {
        let d = (self.sdf)(points);
        if d.len() != points.len() {
            return Err(MergeError::ValueCount(name, d.len(), points.len()));
        }
        Ok(d)
    }

    /// Points (spread by area) with normals on the part above `z_min`.
    /// Samples of the whole surface are cut, not faces: a large face that
    /// reaches down to the board still counts above it.
    fn visible_cloud(&self, z_min: f64, count: usize, fd_step: f64, seed: u64) -> (Vec<V>, Vec<V>) {
        let above = |pts: Vec<V>| -> Vec<V> { pts.into_iter().filter(|p| p.z > z_min).collect() };
        let mut pts = above(sim::sample_surface::sample_surface(&self.mesh, count, seed));
        if !pts.is_empty() && pts.len() < count {
            // Sample again, densely enough for `count` above the cut.
            let more = (count as f64 * count as f64 / pts.len() as f64).min(20.0 * count as f64) as usize;
            pts = above(sim::sample_surface::sample_surface(&self.mesh, more, seed + 1));
            pts.truncate(count);
        }
        if pts.is_empty() {
            return (vec![], vec![]);
        }
        if self.project {
            let (p, n) = zero_level_points(&*self.sdf, &pts, fd_step, 2, fd_step);
            p.into_iter().zip(n).filter(|(p, _)| p.z > z_min).unzip()
        } else {
            let md = MeshDistance::new(&self.mesh).expect("a partial surface has faces");
            let normals = pts
                .iter()
                .map(|p| md.face_normal(md.closest_point_triangle(*p).2))
                .collect();
            (pts, normals)
        }
    }
}

/// What a merge produced.
pub struct Merged {
    /// The whole object, in B's frame.
    pub mesh: TriMesh,
    /// `p_B = a_to_b · p_A`.
    pub a_to_b: Pose<f64>,
    pub icp: IcpResult,
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Merge `a` (upright) and `b` (turned over), each in its own capture's
/// frame (board at z = 0).
pub fn merge_two_poses(a: &PartialSurface, b: &PartialSurface, cfg: &MergeConfig) -> Result<Merged, MergeError> {
    merge_two_poses_reporting(a, b, cfg, &|_| {})
}

/// The merge's stages, in order, as [`merge_two_poses_reporting`] reports them done.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MergeStage {
    /// What each part's cameras saw.
    Visibility,
    /// The point clouds ICP aligns (samples on each part, projected onto its zero level).
    Clouds,
    /// The alignment: ICP from several starts, refined, one chosen.
    Alignment,
    /// The cameras' share of the fused SDF's weights.
    Weights,
    /// The fused SDF on the narrow band around the surface.
    FusedSdf,
    /// Its zero level.
    ZeroLevel,
}

impl MergeStage {
    pub const ALL: [MergeStage; 6] = [
        Self::Visibility,
        Self::Clouds,
        Self::Alignment,
        Self::Weights,
        Self::FusedSdf,
        Self::ZeroLevel,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::Visibility => "visibility",
            Self::Clouds => "ICP clouds",
            Self::Alignment => "alignment",
            Self::Weights => "camera weights",
            Self::FusedSdf => "fused SDF",
            Self::ZeroLevel => "zero level",
        }
    }
}

/// [`merge_two_poses`], telling `done` each stage as it ends (for a progress
/// bar), and logging each stage's time at debug level.
pub fn merge_two_poses_reporting(
    a: &PartialSurface,
    b: &PartialSurface,
    cfg: &MergeConfig,
    done: &dyn Fn(MergeStage),
) -> Result<Merged, MergeError> {
    let clock = std::cell::Cell::new(std::time::Instant::now());
    let stage_done = |stage: MergeStage| {
        tracing::debug!(
            "merge: {} in {:.2} s",
            stage.name(),
            clock.get().elapsed().as_secs_f64()
        );
        clock.set(std::time::Instant::now());
        done(stage);
    };
    let (vis_a, vis_b) = (
        a.visibility(cfg.visibility_resolution),
        b.visibility(cfg.visibility_resolution),
    );
    // How surely a part saw the surface near x (its own frame): above the
    // board's margin, and by enough of its cameras when they are known.
    let by_cameras = |vis: &Option<Visibility>, x: V| -> f64 {
        vis.as_ref().map_or(1.0, |v| {
            smoothstep(
                0.0,
                cfg.min_cameras as f64 / v.cameras().max(1) as f64,
                v.seen_fraction(x),
            )
        })
    };
    let above_board = |x: V| smoothstep(cfg.board_margin, cfg.board_margin + cfg.blend, x.z);
    // ICP aligns what lies above each board. Cutting its clouds down to what
    // the cameras saw would, on boxy objects, leave little more than parallel
    // walls, which do not fix the pose; the guesses above the board are close
    // (masks carve them) and trimming drops the pairs that disagree.
    stage_done(MergeStage::Visibility);
    let (pa, na) = a.visible_cloud(cfg.board_margin, cfg.icp_points, cfg.fd_step, 1);
    let (pb, nb) = b.visible_cloud(cfg.board_margin, cfg.icp_points, cfg.fd_step, 2);
    tracing::debug!(
        "merge: ICP clouds of {} (A) and {} (B) points above the board",
        pa.len(),
        pb.len()
    );
    if pa.is_empty() {
        return Err(MergeError::NothingVisible('A', cfg.board_margin));
    }
    if pb.is_empty() {
        return Err(MergeError::NothingVisible('B', cfg.board_margin));
    }
    // B's board is a seen surface too, and where B stands on it lies what A
    // shows on top: it holds A at the right height when the walls both see
    // leave that free.
    let (mut pb, mut nb) = (pb, nb);
    let board = board_patch(&b.mesh, cfg.board_margin, cfg.icp_points / 4);
    let footprint = Footprint::of(&board);
    nb.extend(std::iter::repeat_n(V::new(0.0, 0.0, 1.0), board.len()));
    pb.extend(board);
    let target = IcpTarget::new(pb, nb);
    stage_done(MergeStage::Clouds);
    // What A could not see (on its board), to tell symmetric alignments apart.
    let a_hidden: Vec<V> = sim::sample_surface::sample_surface(&a.mesh, cfg.icp_points / 4, 3)
        .into_iter()
        .filter(|p| p.z <= cfg.board_margin)
        .collect();
    // With both parts' colours: how much A's colours disagree with B's where an alignment puts A on what B
    // saw (mean L1 over RGB; none where it puts nothing there).
    let colour_gap = match (&a.colour, &b.colour) {
        (Some(ca), Some(cb)) => {
            let every = pa.len().div_ceil(COLOUR_SAMPLES).max(1);
            let (sa, sn): (Vec<V>, Vec<V>) = pa.iter().zip(&na).step_by(every).map(|(p, n)| (*p, *n)).unzip();
            let col_a = ca(&sa, &sn);
            let judge = move |t: &Pose<f64>| -> Option<f64> {
                let moved: Vec<V> = sa.iter().map(|p| t.transform_point(*p)).collect();
                let dist = (b.sdf)(&moved);
                let keep: Vec<usize> = (0..moved.len())
                    .filter(|&i| {
                        moved[i].z > cfg.board_margin + cfg.blend && dist[i].abs() <= 2.0 * cfg.inlier_distance
                    })
                    .collect();
                if keep.is_empty() {
                    return None;
                }
                let pts: Vec<V> = keep.iter().map(|&i| moved[i]).collect();
                let nrm: Vec<V> = keep.iter().map(|&i| t.transform_vector(sn[i])).collect();
                let col_b = cb(&pts, &nrm);
                let gap: f64 = keep
                    .iter()
                    .zip(&col_b)
                    .map(|(&i, cb)| (0..3).map(|k| (col_a[i][k] - cb[k]).abs()).sum::<f64>() / 3.0)
                    .sum();
                Some(gap / keep.len() as f64)
            };
            Some(judge)
        }
        _ => None,
    };
    let fit = align(
        &pa,
        &target,
        &a_hidden,
        footprint,
        cfg,
        colour_gap.as_ref().map(|f| f as &ColourGap<'_>),
    );
    if !(fit.residual <= cfg.max_residual) {
        return Err(MergeError::NoConvergence {
            residual: fit.residual,
            limit: cfg.max_residual,
        });
    }
    if !(fit.conditioning >= cfg.min_conditioning) {
        return Err(MergeError::IllConditioned {
            conditioning: fit.conditioning,
            limit: cfg.min_conditioning,
        });
    }
    tracing::debug!(
        "merge: chose rotation {:?}, translation {:?} m, rms {:.3} mm, conditioning {:.2e}, {} ICP iterations",
        fit.transform.q.to_array_re(),
        fit.transform.t.to_array(),
        fit.rms_distance * 1e3,
        fit.conditioning,
        fit.iterations
    );
    stage_done(MergeStage::Alignment);
    let a_to_b = fit.transform;
    let b_to_a = a_to_b.inverse();
    // The box of the object in B's frame: B's box and A's moved into it.
    let moved_a = a
        .mesh
        .vertices
        .iter()
        .map(|v| a_to_b.transform_point(V::cst(*v)).to_array());
    let (lo, hi) = geom::bounding_box(b.mesh.vertices.iter().copied().chain(moved_a));
    let longest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let h = longest / (cfg.resolution.max(8) - 1) as f64;
    let pad = 3.0 * h;
    let origin = lo.map(|v| v - pad);
    let dims: [usize; 3] = std::array::from_fn(|k| ((hi[k] - lo[k] + 2.0 * pad) / h).ceil() as usize + 1);
    // The cameras' share of the weights, on the narrow band's coarse grid
    // (it changes slowly, and tracing every fine point would cost 64 times more).
    let coarse = CoarseGrid::new(origin, h * NARROW_BAND_COARSENING as f64, dims);
    let camera_weights: Vec<(f64, f64)> = if vis_a.is_none() && vis_b.is_none() {
        Vec::new()
    } else {
        (0..coarse.len())
            .into_par_iter()
            .map(|i| {
                let x = coarse.point(i);
                (by_cameras(&vis_a, b_to_a.transform_point(x)), by_cameras(&vis_b, x))
            })
            .collect()
    };
    stage_done(MergeStage::Weights);
    // The fused SDF in B's frame: B where B saw, else A.
    let fused = |xs: &[V]| -> Result<Vec<f64>, MergeError> {
        let xa: Vec<V> = xs.iter().map(|x| b_to_a.transform_point(*x)).collect();
        let sb = b.distances('B', xs)?;
        let sa = a.distances('A', &xa)?;
        Ok((0..xs.len())
            .map(|i| {
                let (ca, cb) = coarse.interpolate(&camera_weights, xs[i]).unwrap_or((1.0, 1.0));
                let (wb, wa) = (above_board(xs[i]) * cb, above_board(xa[i]) * ca);
                if wa + wb <= 0.0 {
                    // Seen by neither (only in a thin sliver at both boards): the nearer guess.
                    if sa[i].abs() < sb[i].abs() {
                        sa[i]
                    } else {
                        sb[i]
                    }
                } else {
                    // Prefer B where B saw it; A fills where only A saw.
                    let w = wb / (wb + wa * (1.0 - wb));
                    w * sb[i] + (1.0 - w) * sa[i]
                }
            })
            .collect())
    };
    let values = narrow_band(&fused, &coarse, origin, h, dims)?;
    tracing::debug!(
        "merge: fused SDF on a {}×{}×{} grid of {:.2} mm",
        dims[0],
        dims[1],
        dims[2],
        h * 1e3
    );
    stage_done(MergeStage::FusedSdf);
    let grid = ScalarGrid {
        origin,
        spacing: h,
        dims,
        values,
    };
    let mesh = largest_component(&extract_zero_level(&grid));
    if mesh.faces.is_empty() {
        return Err(MergeError::Empty);
    }
    stage_done(MergeStage::ZeroLevel);
    Ok(Merged { mesh, a_to_b, icp: fit })
}

/// Points on the board plane z = 0 under and around where `m` stands on it
/// (its footprint, within `margin` of the board, padded by 5 mm), about
/// `count` of them on a square lattice.
fn board_patch(m: &TriMesh, margin: f64, count: usize) -> Vec<V> {
    let (lo, hi) = geom::bounding_box(m.vertices.iter().copied().filter(|v| v[2] <= margin));
    let (lo, hi) = ([lo[0] - 5e-3, lo[1] - 5e-3], [hi[0] + 5e-3, hi[1] + 5e-3]);
    if !(lo[0] < hi[0] && lo[1] < hi[1]) || count == 0 {
        return Vec::new();
    }
    let step = ((hi[0] - lo[0]) * (hi[1] - lo[1]) / count as f64).sqrt();
    let n = [0, 1].map(|k| ((hi[k] - lo[k]) / step).ceil() as usize);
    (0..n[0] * n[1])
        .map(|i| V::new(lo[0] + (i % n[0]) as f64 * step, lo[1] + (i / n[0]) as f64 * step, 0.0))
        .collect()
}

/// Where B stands on its board: the box, in the board's plane, of [`board_patch`]'s points.
#[derive(Clone, Copy, Debug)]
struct Footprint {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Footprint {
    fn of(patch: &[V]) -> Self {
        let (lo, hi) = geom::bounding_box(patch.iter().map(|p| p.to_array()));
        Self {
            lo: [lo[0], lo[1]],
            hi: [hi[0], hi[1]],
        }
    }

    fn holds(&self, p: V) -> bool {
        (self.lo[0]..=self.hi[0]).contains(&p.x) && (self.lo[1]..=self.hi[1]).contains(&p.y)
    }
}

/// How well A's samples `pa` moved by `transform` land on B (`target`: B's seen surface and its board under
/// `footprint`): of those it puts where B saw, the share within `cfg.inlier_distance` of B's surface; 0 when
/// it puts under a quarter of A there. Where B saw is clear of its board, and over its footprint the board
/// itself: B cannot see under itself, but it stands there, so what A shows on top must land on it. Without
/// the board, walls that leave the height free (a box's) would land as well with A a few millimetres too
/// high, and a trimmed ICP pass, which drops the pairs on the board as the farthest, would stay there
/// (the two-body scene's block merged 37.8 mm tall instead of 40).
fn landing_share(pa: &[V], target: &IcpTarget, footprint: Footprint, transform: Pose<f64>, cfg: &MergeConfig) -> f64 {
    let seen_by_b = |p: V| p.z > cfg.board_margin + cfg.blend || footprint.holds(p);
    let (share, counted) = inlier_fraction(pa, target, transform, cfg.inlier_distance, &seen_by_b);
    if 4 * counted >= pa.len() {
        share
    } else {
        0.0
    }
}

/// The mean colour difference between A's surface placed by a transform and B's, where it can be told.
type ColourGap<'a> = dyn Fn(&Pose<f64>) -> Option<f64> + 'a;

/// An alignment shows A's hidden side when it moves at least this share of it up into B's view.
const SHOWS_HIDDEN: f64 = 0.5;

/// An alignment whose ICP residual is within this factor of the tightest one fits as well.
const TIGHT_AS: f64 = 1.25;

/// Hypotheses of the automatic start refined in full: a box on a square footprint (the two-body scene's
/// block) goes onto itself eight ways, and its four upright ones fit before any turned-over one, so with
/// four it was never turned over and both guessed undersides stayed (merged 50 mm tall instead of 40).
const HYPOTHESES_REFINED: usize = 8;

/// Rigid alignment of A's samples onto B's.
///
/// Each start is refined twice: trimmed ICP (robust to the parts' different
/// extents and to wrong guesses), then a pass that keeps nearly every pair,
/// since trimming alone can let a shape slide along a weakly held direction
/// (a box's walls) and drop the pairs that would object, while keeping every
/// pair lets wrong guesses pull. Of the two, the one under which more of A
/// lands on B (of what it puts where B saw, B's board under it included:
/// [`landing_share`]) wins. Without a given start, the [`HYPOTHESES_REFINED`] best
/// distinct hypotheses of the automatic start are refined (a symmetric object has several good ones) and
/// [`pick_alignment`] chooses: the second pose is there to show what the first hid, so those that show most
/// of A's hidden side within the residual bar come first; of them, those that make about as much of A land
/// on B (within 5 %) or fit as tightly (ICP residual within [`TIGHT_AS`] of the tightest), then the one that
/// shows most; a box turned over about x or about y shows as much: with both parts' colours
/// (`colour_gap`), of those within 5 % of the most shown, the one whose colours agree best with B's wins.
fn align(
    pa: &[V],
    target: &IcpTarget,
    a_hidden: &[V],
    footprint: Footprint,
    cfg: &MergeConfig,
    colour_gap: Option<&ColourGap<'_>>,
) -> IcpResult {
    let lands = |r: &IcpResult| landing_share(pa, target, footprint, r.transform, cfg);
    let refine = |start: Pose<f64>| -> IcpResult {
        let first = icp(pa, target, start, &cfg.icp, cfg.icp.iterations);
        let fine = IcpConfig {
            keep_fraction: cfg.refine_keep_fraction,
            ..cfg.icp.clone()
        };
        let second = icp(pa, target, first.transform, &fine, cfg.icp.iterations);
        if lands(&second) > lands(&first) {
            second
        } else {
            first
        }
    };
    match cfg.start {
        Some(start) if !cfg.refine => icp_evaluate(pa, target, start, &cfg.icp),
        Some(start) => refine(start),
        None => {
            let hypotheses = icp_hypotheses(pa, target, &cfg.icp);
            let shown = |r: &IcpResult| {
                let up = cfg.board_margin + cfg.blend;
                let n = a_hidden
                    .iter()
                    .filter(|p| r.transform.transform_point(**p).z > up)
                    .count();
                n as f64 / a_hidden.len().max(1) as f64
            };
            let scored: Vec<(IcpResult, f64, f64)> = hypotheses
                .iter()
                .take(HYPOTHESES_REFINED)
                .map(|h| {
                    let r = refine(h.transform);
                    (r, lands(&r), shown(&r))
                })
                .collect();
            for (r, lands, shown) in &scored {
                tracing::debug!(
                    "merge hypothesis: rotation {:?}, rms {:.2} mm, residual {:.2} mm, lands {lands:.3}, hidden side shown {shown:.3}, colour gap {:?}",
                    r.transform.q.to_array_re().map(|x| (x * 1e3).round() / 1e3),
                    r.rms_distance * 1e3,
                    r.residual * 1e3,
                    colour_gap.and_then(|g| g(&r.transform))
                );
            }
            pick_alignment(scored, cfg.max_residual, colour_gap)
        }
    }
}

/// Of refined alignments `(fit, share of A landing on B, share of A's hidden side shown)`, the one to keep.
/// The second capture is there to show what the first hid, so the alignments that show most of A's hidden
/// side ([`SHOWS_HIDDEN`]) and fit within the merge's own residual bar (`max_residual`) are the candidates,
/// and only when there are none do those that show nothing compete: on a symmetric shape, leaving A as it
/// is always fits tighter than the true turn (both captures share what a field makes of the band by its
/// board, and their shading: the lights do not turn with the object), and keeping it keeps both guessed
/// undersides (the two-body scene's block merged 50 mm tall instead of 40, its 0.47 mm fit against the
/// turn's 0.82). Of the candidates, those geometrically as good as the best, then those showing most of A's
/// hidden side, and of those within 5 % of it, the one whose colours agree best with B's (when colours
/// are known).
fn pick_alignment(
    scored: Vec<(IcpResult, f64, f64)>,
    max_residual: f64,
    colour_gap: Option<&ColourGap<'_>>,
) -> IcpResult {
    let showing = |s: &(IcpResult, f64, f64)| s.2 >= SHOWS_HIDDEN && s.0.residual <= max_residual;
    let scored = if scored.iter().any(showing) {
        scored.into_iter().filter(showing).collect()
    } else {
        scored
    };
    // Geometrically as good: about as much of A lands on B, or the fit is as tight as the tightest
    // (the share that lands is taken over what each alignment puts where B saw, which differs between
    // alignments: a turned-over box puts A's well-seen top where B saw nothing, and on a briefly trained
    // field's surfaces its walls alone land less often than top on top: 0.79 vs 0.86 on the demo's toy).
    let most = scored.iter().map(|s| s.1).fold(0.0, f64::max);
    let tightest = scored.iter().map(|s| s.0.rms_distance).fold(f64::INFINITY, f64::min);
    let landing: Vec<(IcpResult, f64, f64)> = scored
        .into_iter()
        .filter(|s| s.1 >= most - 0.05 || (s.1 > 0.0 && s.0.rms_distance <= TIGHT_AS * tightest))
        .collect();
    let most_shown = landing.iter().map(|s| s.2).fold(0.0, f64::max);
    let by_colour = colour_gap.and_then(|gap| {
        landing
            .iter()
            .filter(|s| s.2 >= most_shown - 0.05)
            .filter_map(|s| gap(&s.0.transform).map(|g| (s.0, g)))
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .map(|(r, _)| r)
    });
    by_colour.unwrap_or_else(|| {
        landing
            .into_iter()
            .max_by(|x, y| x.2.total_cmp(&y.2).then(x.1.total_cmp(&y.1)))
            .expect("the best hypothesis passes")
            .0
    })
}

/// The fused SDF at a batch of points.
type FusedSdf<'a> = dyn Fn(&[V]) -> Result<Vec<f64>, MergeError> + Sync + 'a;

/// Points per call of the fused SDF.
const BATCH: usize = 1 << 14;

/// `f` at every point, in parallel batches.
fn eval_batched(f: &FusedSdf, points: &[V]) -> Result<Vec<f64>, MergeError> {
    let parts: Vec<Vec<f64>> = points.par_chunks(BATCH).map(f).collect::<Result<_, _>>()?;
    Ok(parts.concat())
}

/// Sample `f` on the fine grid, exactly only near its zero level: a grid four
/// times coarser first; a fine point whose coarse cell has every corner
/// farther from the surface than the cell's diagonal takes the coarse
/// interpolation (its sign, all marching needs there, is right).
/// The coarse grid of [`narrow_band`], over the fine grid's box.
struct CoarseGrid {
    origin: [f64; 3],
    step: f64,
    dims: [usize; 3],
}

impl CoarseGrid {
    fn new(origin: [f64; 3], step: f64, fine_dims: [usize; 3]) -> Self {
        let k = NARROW_BAND_COARSENING;
        let dims = std::array::from_fn(|a| (fine_dims[a] - 1).div_ceil(k) + 1);
        Self { origin, step, dims }
    }
    fn len(&self) -> usize {
        self.dims.iter().product()
    }
    fn point(&self, idx: usize) -> V {
        let d = self.dims;
        let ijk = [idx % d[0], (idx / d[0]) % d[1], idx / (d[0] * d[1])];
        V::new(
            self.origin[0] + ijk[0] as f64 * self.step,
            self.origin[1] + ijk[1] as f64 * self.step,
            self.origin[2] + ijk[2] as f64 * self.step,
        )
    }
    /// Trilinear interpolation of per-node pairs at `x` (clamped to the grid); `None` without values.
    fn interpolate(&self, values: &[(f64, f64)], x: V) -> Option<(f64, f64)> {
        if values.is_empty() {
            return None;
        }
        let d = self.dims;
        let mut base = [0usize; 3];
        let mut frac = [0.0; 3];
        for a in 0..3 {
            let t = ((x.to_array()[a] - self.origin[a]) / self.step).clamp(0.0, (d[a] - 1) as f64);
            base[a] = (t.floor() as usize).min(d[a] - 2);
            frac[a] = t - base[a] as f64;
        }
        let mut out = (0.0, 0.0);
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, corner >> 2];
            let w: f64 = (0..3)
                .map(|a| if o[a] == 1 { frac[a] } else { 1.0 - frac[a] })
                .product();
            let v = values[(base[0] + o[0]) + d[0] * ((base[1] + o[1]) + d[1] * (base[2] + o[2]))];
            out.0 += w * v.0;
            out.1 += w * v.1;
        }
        Some(out)
    }
}

/// How much coarser the first pass of [`narrow_band`] is.
const NARROW_BAND_COARSENING: usize = 4;

fn narrow_band(
    f: &FusedSdf,
    grid: &CoarseGrid,
    origin: [f64; 3],
    h: f64,
    dims: [usize; 3],
) -> Result<Vec<f32>, MergeError> {
    const K: usize = NARROW_BAND_COARSENING;
    let cd = grid.dims;
    let coarse_points: Vec<V> = (0..grid.len()).map(|idx| grid.point(idx)).collect();
    let coarse = eval_batched(f, &coarse_points)?;
    let far = 1.8 * (K as f64) * h;
    let c = |i: usize, j: usize, k: usize| coarse[i + cd[0] * (j + cd[1] * k)];
    let mut exact = Vec::new();
    let mut values: Vec<f32> = (0..dims.iter().product::<usize>())
        .map(|idx| {
            let (i, j, k) = (idx % dims[0], (idx / dims[0]) % dims[1], idx / (dims[0] * dims[1]));
            let (ci, cj, ck) = ((i / K).min(cd[0] - 2), (j / K).min(cd[1] - 2), (k / K).min(cd[2] - 2));
            let corners = [
                c(ci, cj, ck),
                c(ci + 1, cj, ck),
                c(ci, cj + 1, ck),
                c(ci + 1, cj + 1, ck),
                c(ci, cj, ck + 1),
                c(ci + 1, cj, ck + 1),
                c(ci, cj + 1, ck + 1),
                c(ci + 1, cj + 1, ck + 1),
            ];
            if corners.iter().all(|v| *v > far) || corners.iter().all(|v| *v < -far) {
                let t = |n: usize, cn: usize| (n as f64 - (cn * K) as f64) / K as f64;
                let (u, v, w) = (t(i, ci), t(j, cj), t(k, ck));
                let lerp = |a: f64, b: f64, s: f64| a + (b - a) * s;
                let x0 = lerp(lerp(corners[0], corners[1], u), lerp(corners[2], corners[3], u), v);
                let x1 = lerp(lerp(corners[4], corners[5], u), lerp(corners[6], corners[7], u), v);
                lerp(x0, x1, w) as f32
            } else {
                exact.push(idx);
                0.0
            }
        })
        .collect();
    let exact_points: Vec<V> = exact
        .iter()
        .map(|&idx| {
            let (i, j, k) = (idx % dims[0], (idx / dims[0]) % dims[1], idx / (dims[0] * dims[1]));
            V::new(
                origin[0] + i as f64 * h,
                origin[1] + j as f64 * h,
                origin[2] + k as f64 * h,
            )
        })
        .collect();
    for (idx, v) in exact.iter().zip(eval_batched(f, &exact_points)?) {
        values[*idx] = v as f32;
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points and outward normals on the faces of a box `[lo, hi]` about `step` apart, where `keep` holds.
    fn box_cloud(lo: [f64; 3], hi: [f64; 3], step: f64, keep: impl Fn(V) -> bool) -> (Vec<V>, Vec<V>) {
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        for axis in 0..3 {
            let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
            let n = |k: usize| ((hi[k] - lo[k]) / step).round() as usize;
            for side in [-1.0, 1.0] {
                for i in 0..=n(u) {
                    for j in 0..=n(w) {
                        let mut p = [0.0; 3];
                        p[axis] = if side > 0.0 { hi[axis] } else { lo[axis] };
                        p[u] = lo[u] + (hi[u] - lo[u]) * i as f64 / n(u) as f64;
                        p[w] = lo[w] + (hi[w] - lo[w]) * j as f64 / n(w) as f64;
                        let mut nrm = [0.0; 3];
                        nrm[axis] = side;
                        if keep(V::cst(p)) {
                            points.push(V::cst(p));
                            normals.push(V::cst(nrm));
                        }
                    }
                }
            }
        }
        (points, normals)
    }

    /// A box turned over: its walls land as well with A 3 mm too high, its top on B's board only in place.
    #[test]
    fn a_turned_over_box_lands_in_place_only_with_its_top_on_the_board() {
        let cfg = MergeConfig::default();
        let (lo, hi) = ([-0.025, -0.025, 0.0], [0.025, 0.025, 0.04]);
        let seen = |p: V| p.z > cfg.board_margin;
        let (pa, _) = box_cloud(lo, hi, 1e-3, seen);
        let (mut pb, mut nb) = box_cloud(lo, hi, 1e-3, seen);
        // B's underside's corners: where it stands.
        let under = TriMesh::new(vec![lo, [hi[0], hi[1], 0.0]], Vec::new());
        let board = board_patch(&under, cfg.board_margin, 2000);
        let footprint = Footprint::of(&board);
        nb.extend(std::iter::repeat_n(V::new(0.0, 0.0, 1.0), board.len()));
        pb.extend(board);
        let target = IcpTarget::new(pb, nb);
        let turned = Pose::new(
            geom::Quat::exp(V::new(std::f64::consts::PI, 0.0, 0.0)),
            V::new(0.0, 0.0, 0.04),
        );
        let high = Pose::from_translation(V::new(0.0, 0.0, 3e-3)).compose(&turned);
        let (in_place, too_high) = (
            landing_share(&pa, &target, footprint, turned, &cfg),
            landing_share(&pa, &target, footprint, high, &cfg),
        );
        assert!(in_place > 0.95, "{in_place}");
        assert!(
            too_high < in_place - 0.15,
            "3 mm too high: {too_high} against {in_place}"
        );
    }

    /// A colour judge that gives each hypothesis of `scored` (told by its turn) its measured gap.
    fn colour_gaps<const N: usize>(
        scored: &[(IcpResult, f64, f64)],
        gaps: [f64; N],
    ) -> impl Fn(&Pose<f64>) -> Option<f64> {
        let turns: Vec<geom::Quat<f64>> = scored.iter().map(|s| s.0.transform.q).collect();
        move |t: &Pose<f64>| {
            turns
                .iter()
                .position(|q| geom::rotation_distance(*q, t.q) < 1e-6)
                .map(|i| gaps[i])
        }
    }

    fn fit(q: [f64; 4], rms_mm: f64) -> IcpResult {
        IcpResult {
            transform: Pose::new(geom::Quat::cst(q).normalize_or_identity(), V::zero()),
            residual: rms_mm * 1e-3,
            rms_distance: rms_mm * 1e-3,
            iterations: 10,
            conditioning: 0.2,
        }
    }

    /// The four hypotheses measured on the demo's toy (160×120 captures, 1,000 steps; B is A turned over
    /// about x): left as is, more of A lands on B (0.86) than turned over (0.79), but the turns fit as
    /// tightly (0.52 vs 0.47 mm), show A's hidden side, and the turn about x agrees in colour.
    #[test]
    fn a_turn_that_fits_as_tightly_is_weighed_by_colour() {
        let scored = vec![
            (fit([0.0, 0.0, 1.0, 0.0], 0.52), 0.789, 1.0),
            (fit([0.0, 1.0, 0.0, 0.0], 0.53), 0.786, 1.0),
            (fit([1.0, 0.0, 0.0, 0.0], 0.47), 0.863, 0.0),
            (fit([0.0, 0.0, 0.0, 1.0], 0.48), 0.848, 0.0),
        ];
        let gaps = [0.135, 0.080, 0.135, 0.168];
        let gap = colour_gaps(&scored, gaps);
        let max_residual = MergeConfig::default().max_residual;
        let chosen = pick_alignment(scored.clone(), max_residual, Some(&gap));
        assert_eq!(chosen, scored[1].0, "the turn about x");
        // A turn whose fit is beyond the merge's residual bar (a wrong face on a wrong face) is not admitted
        // however well it shows.
        let mut loose = scored.clone();
        for s in &mut loose[..2] {
            s.0.residual = 1.2e-3;
            s.0.rms_distance = 1.5e-3;
        }
        let chosen = pick_alignment(loose, max_residual, Some(&gap));
        assert_eq!(chosen.transform.q, geom::Quat::identity(), "left as is");
    }

    /// The eight hypotheses measured on the two-body scene's block (a 50 × 50 × 40 mm box with a solid
    /// checker, 160 × 120 captures, 1,000 steps; B is A turned over about x): left as is fits tightest
    /// (0.47 mm), lands most (0.90) and agrees best in colour (0.027: the same faces lit the same way), but
    /// shows none of A's underside; the turns show all of it within the residual bar, and of them the turn
    /// about x agrees best in colour.
    #[test]
    fn the_turn_that_shows_the_hidden_side_wins_over_a_tighter_fit_that_shows_none() {
        let h = |q: [f64; 4], rms: f64, residual: f64, lands: f64, shown: f64| {
            let mut f = fit(q, rms);
            f.residual = residual * 1e-3;
            (f, lands, shown)
        };
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let scored = vec![
            h([1.0, 0.0, 0.0, 0.0], 0.47, 0.25, 0.902, 0.0),
            h([0.0, s, s, 0.0], 0.68, 0.54, 0.644, 1.0),
            h([0.0, -s, s, 0.0], 0.68, 0.54, 0.641, 1.0),
            h([0.0, -1.0, 0.0, 0.0], 0.82, 0.69, 0.579, 1.0),
            h([0.0, 0.0, 0.0, 1.0], 0.65, 0.50, 0.679, 0.0),
            h([0.0, 0.0, 1.0, 0.0], 0.82, 0.69, 0.536, 1.0),
            h([s, 0.0, 0.0, s], 0.81, 0.69, 0.522, 0.0),
            h([s, 0.0, 0.0, -s], 0.79, 0.68, 0.531, 0.0),
        ];
        let gaps = [0.027, 0.216, 0.182, 0.073, 0.096, 0.114, 0.239, 0.241];
        let gap = colour_gaps(&scored, gaps);
        let max_residual = MergeConfig::default().max_residual;
        let chosen = pick_alignment(scored.clone(), max_residual, Some(&gap));
        assert_eq!(chosen, scored[3].0, "the turn about x");
        // Without colours, the turn that lands most of those showing the underside.
        let chosen = pick_alignment(scored.clone(), max_residual, None);
        assert_eq!(chosen, scored[1].0, "a turn about a diagonal");
    }
}
