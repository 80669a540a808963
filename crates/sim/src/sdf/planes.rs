//! A scene grid's planes, made exact. A tabletop is mostly planes (the board,
//! a wall's faces, a box's top), and a NeuS reconstruction is wrong on them
//! exactly where bodies touch them: rough by a fraction of a millimetre (which
//! tilts contact normals by degrees), and rounded into a fillet 10–15 mm wide
//! where two planes meet in a concave crease (the foot of a wall on the
//! board), which kicks a body sliding into the corner up off it instead of
//! letting it meet the wall. Blurring the grid takes the roughness away but
//! rounds the crease further.
//!
//! So the planes are found on the grid's zero level (RANSAC on oriented
//! points: each point's own normal proposes a plane), and
//! - near each plane, over its footprint, where the field agrees with the
//!   plane to within its relief (how far the zero level stands off it: the
//!   roughness, or a textured board's squares that NeuS reads as a millimetre
//!   or two of relief), the value is the plane's distance (snapped);
//! - along a concave crease between two planes, in the wedge of free space
//!   between them, the value is at least the sharp corner's distance
//!   `min(d_a, d_b)` (the fillet taken away), in each stretch of the crease
//!   that both planes reach and where nothing but a fillet stands in the
//!   corner;
//! - every other node keeps the field, blurred (curved surfaces keep the
//!   blur's smoothing).
//!
//! A prior of man-made scenes, as plane priors in indoor reconstruction
//! (e.g. Manhattan-SDF, Guo et al., CVPR 2022); `bake --no-planes` turns it off.

use super::{Sdf, SdfGrid};
use geom::{symmetric_eigen, SplitMix64, Vec3};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};

type V = Vec3<f64>;

/// What counts as a plane, and how far a crease's fillet reaches.
#[derive(Clone, Debug)]
pub struct PlaneSettings {
    /// Largest distance of a surface point from its plane, m (a reconstruction's roughness).
    pub tolerance: f64,
    /// Largest angle between a surface point's normal and its plane's, degrees.
    pub max_angle_deg: f64,
    /// Smallest plane kept, m² of surface.
    pub min_area: f64,
    /// Narrowest plane kept, m (the width of a uniform strip with its points' spread across): a fillet's
    /// flattest band is a strip 10–16 mm wide, and taken for a plane it would make a chamfer.
    pub min_width: f64,
    /// How far from a concave crease the field is made sharp, m: wider than the fillet NeuS leaves there
    /// (10–15 mm measured on the tabletop's wall).
    pub crease_reach: f64,
}

impl Default for PlaneSettings {
    fn default() -> Self {
        Self {
            tolerance: 1.2e-3,
            max_angle_deg: 12.0,
            min_area: 25e-4,
            min_width: 0.025,
            crease_reach: 0.02,
        }
    }
}

/// A plane found in the grid: `normal · x = offset`, the normal pointing into free space.
#[derive(Clone, Debug, PartialEq)]
pub struct ScenePlane {
    pub normal: V,
    pub offset: f64,
    /// Surface points on it.
    pub points: usize,
    /// How far the zero level stands off it over its footprint, m (at most three tolerances: what stands higher
    /// is something on it): the reconstruction's roughness, or the relief NeuS reads into a textured board; the
    /// snap flattens this much.
    pub relief: f64,
}

/// A concave crease between two planes, made sharp.
#[derive(Clone, Debug, PartialEq)]
pub struct Crease {
    /// Indices into [`PlaneReport::planes`].
    pub planes: [usize; 2],
    /// Length of the crease made sharp, m.
    pub length: f64,
    /// Length left as it was because something other than a fillet stands in the corner there, m.
    pub blocked: f64,
}

/// What [`SdfGrid::with_planes`] found and changed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlaneReport {
    pub planes: Vec<ScenePlane>,
    pub creases: Vec<Crease>,
    /// Nodes set to a plane's distance.
    pub snapped: usize,
    /// Nodes raised in a crease's wedge.
    pub sharpened: usize,
    /// The largest raise there, m.
    pub largest_raise: f64,
}

/// A point of the zero level with the field's unit normal there.
#[derive(Clone, Copy, Debug)]
struct Oriented {
    p: V,
    n: V,
}

/// A plane with the surface points on it and their footprint.
struct Found {
    normal: V,
    offset: f64,
    members: Vec<usize>,
    footprint: Footprint,
    /// As [`ScenePlane::relief`].
    relief: f64,
}

impl Found {
    fn distance(&self, x: V) -> f64 {
        self.normal.dot(x) - self.offset
    }
}

/// The cells of a plane (in its own 2-D basis) that its surface points cover, grown by one cell.
struct Footprint {
    origin: V,
    e1: V,
    e2: V,
    lo: [f64; 2],
    cell: f64,
    dims: [usize; 2],
    covered: Vec<bool>,
}

impl Footprint {
    fn of(normal: V, points: &[V], cell: f64) -> Self {
        let origin = points[0];
        let helper = if normal.x.abs() < 0.9 {
            V::new(1.0, 0.0, 0.0)
        } else {
            V::new(0.0, 1.0, 0.0)
        };
        let e1 = normal.cross(helper).normalize_or(V::new(1.0, 0.0, 0.0));
        let e2 = normal.cross(e1);
        let uv: Vec<[f64; 2]> = points
            .iter()
            .map(|&p| [(p - origin).dot(e1), (p - origin).dot(e2)])
            .collect();
        let lo = [0, 1].map(|a| uv.iter().map(|c| c[a]).fold(f64::INFINITY, f64::min) - 2.0 * cell);
        let hi = [0, 1].map(|a| uv.iter().map(|c| c[a]).fold(f64::NEG_INFINITY, f64::max) + 2.0 * cell);
        let dims = [0, 1].map(|a| ((hi[a] - lo[a]) / cell).ceil() as usize + 1);
        let mut covered = vec![false; dims[0] * dims[1]];
        for c in &uv {
            let (i, j) = (((c[0] - lo[0]) / cell) as usize, ((c[1] - lo[1]) / cell) as usize);
            for dj in 0..3 {
                for di in 0..3 {
                    // One cell all round (the points sit a node apart; the footprint closes the gaps).
                    let (ii, jj) = ((i + di).saturating_sub(1), (j + dj).saturating_sub(1));
                    if ii < dims[0] && jj < dims[1] {
                        covered[ii + dims[0] * jj] = true;
                    }
                }
            }
        }
        Self {
            origin,
            e1,
            e2,
            lo,
            cell,
            dims,
            covered,
        }
    }

    fn contains(&self, x: V) -> bool {
        let d = x - self.origin;
        let (u, v) = (
            (d.dot(self.e1) - self.lo[0]) / self.cell,
            (d.dot(self.e2) - self.lo[1]) / self.cell,
        );
        u >= 0.0
            && v >= 0.0
            && (u as usize) < self.dims[0]
            && (v as usize) < self.dims[1]
            && self.covered[u as usize + self.dims[0] * v as usize]
    }
}

/// How near a parallel plane found earlier (larger) a plane may lie, in tolerances, and still be only that
/// plane's relief: NeuS raises a textured board's squares by up to 1.5–2 mm (a 1,500-step scene's board
/// measured 0–1.4 mm, found as a second plane 1.7 mm up); a real step (a book, a mat) stands higher.
const RELIEF: f64 = 3.0;

/// How far from both planes, in crease reaches, the zero level or the solid may stand in a crease's wedge
/// and still be the reconstruction's rounding: a fillet's middle stands 0.29 of its radius off each plane, a
/// 45° chamfer's half its leg, and the reach is the largest (a 1,500-step scene's wall leans out over its
/// lowest 10–15 mm, its zero level 8 mm off both planes in places).
const STANDING: f64 = 0.5;

/// A concave crease's line, and the stretches of it (bins along the line) to make sharp.
struct CreaseLine {
    planes: [usize; 2],
    point: V,
    direction: V,
    bin: f64,
    bins: BTreeSet<i64>,
    blocked: usize,
}

impl CreaseLine {
    /// For each stretch, the run of consecutive stretches it is in: where the run starts and ends along the line.
    fn runs(&self) -> BTreeMap<i64, (f64, f64)> {
        let mut out = BTreeMap::new();
        let bins: Vec<i64> = self.bins.iter().copied().collect();
        let mut start = 0;
        for i in 0..bins.len() {
            if i + 1 == bins.len() || bins[i + 1] != bins[i] + 1 {
                let span = (bins[start] as f64 * self.bin, (bins[i] + 1) as f64 * self.bin);
                for &k in &bins[start..=i] {
                    out.insert(k, span);
                }
                start = i + 1;
            }
        }
        out
    }

    /// Position along the line and distance from it.
    fn coordinates(&self, x: V) -> (f64, f64) {
        let q = x - self.point;
        let t = q.dot(self.direction);
        (t, (q - self.direction * t).norm())
    }
}

impl SdfGrid {
    /// This grid with its planes snapped and their concave creases made sharp, and every node no plane
    /// claims blurred by a Gaussian of `blur` spacings (as [`SdfGrid::smoothed`]); see the module's text.
    pub fn with_planes(&self, settings: &PlaneSettings, blur: f64) -> (SdfGrid, PlaneReport) {
        let h = self.spacing();
        let points = surface_points(self);
        let found = find_planes(&points, settings, h);
        let raw: Vec<f64> = self.values().iter().map(|&v| v as f64).collect();
        let blurred: Vec<f64> = self.smoothed(blur).values().iter().map(|&v| v as f64).collect();
        let mut report = PlaneReport {
            planes: found
                .iter()
                .map(|f| ScenePlane {
                    normal: f.normal,
                    offset: f.offset,
                    points: f.members.len(),
                    relief: f.relief,
                })
                .collect(),
            ..Default::default()
        };

        // Snap: within three spacings of a plane, over its footprint, where the field is within its relief and
        // a tolerance of it (the nearest such plane when several are), the blurred field eased into the
        // plane's distance, all of the way where the field is within the relief (at least the tolerance): the
        // board is flat, its relief and roughness gone. Where the field and the plane disagree on the side by
        // more than the tolerance, only if the field beyond the relief (its height and a tolerance off the
        // plane, on the node's side of it) agrees with the plane: a square of relief is flattened, the base of
        // a body standing on the plane (solid above the relief too) is not cut.
        let (band, tol) = (3.0 * h, settings.tolerance);
        let slack = 2.0 * tol;
        let flat = |k: usize| found[k].relief.max(tol);
        let snapped_to: Vec<Option<usize>> = (0..raw.len())
            .into_par_iter()
            .map(|idx| {
                let (x, v) = (self.node(idx), raw[idx]);
                found
                    .iter()
                    .enumerate()
                    .map(|(k, f)| (k, f.distance(x)))
                    .filter(|&(k, d)| {
                        let f = &found[k];
                        let relief_only = || {
                            let beyond = x + f.normal * ((flat(k) + tol).copysign(d) - d);
                            self.distance_local(beyond) * d > 0.0
                        };
                        d.abs() < band
                            && (v - d).abs() < flat(k) + tol
                            && f.footprint.contains(x)
                            && (v * d >= 0.0 || v.abs().max(d.abs()) <= tol || relief_only())
                    })
                    .min_by(|a, b| (v - a.1).abs().total_cmp(&(v - b.1).abs()))
                    .map(|(k, _)| k)
            })
            .collect();
        let base: Vec<f64> = (0..raw.len())
            .into_par_iter()
            .map(|idx| match snapped_to[idx] {
                Some(k) => {
                    let d = found[k].distance(self.node(idx));
                    let weight = ((flat(k) + tol - (raw[idx] - d).abs()) / tol).clamp(0.0, 1.0);
                    blurred[idx] + weight * (d - blurred[idx])
                }
                None => blurred[idx],
            })
            .collect();
        report.snapped = snapped_to.iter().filter(|k| k.is_some()).count();

        // Sharpen each concave crease, from the snapped field (so the order of the creases does not matter):
        // in the wedge (both distances above minus a spacing), within the reach, at least the corner's
        // distance, eased in over the reach's outer quarter and over half a stretch at the ends of a run of
        // stretches. The raises combine by their maximum; then a node snapped to one of a crease's planes is
        // capped at the other plane's distance (which may be nearer than its own), unless the field has free
        // space behind that plane there (its end, an overhang): no solid is added where the field has none.
        let reach = settings.crease_reach;
        let mut values = base.clone();
        let mut capped = vec![f64::INFINITY; raw.len()];
        for mut line in concave_creases(&found, &points, settings) {
            let (a, b) = (&found[line.planes[0]], &found[line.planes[1]]);
            // Where the snapped field holds solid in the wedge further from both planes than a fillet's middle
            // stands (0.29 of its radius; the reach is the largest fillet), or beyond the reach at all (a mat,
            // a cable along the corner: no fillet reaches there), something stands in the corner: its stretch is
            // left alone.
            let standing: BTreeSet<i64> = self
                .nodes_near(&line, 1.5 * reach)
                .into_iter()
                .filter_map(|idx| {
                    let x = self.node(idx);
                    let (t, r) = line.coordinates(x);
                    let corner = a.distance(x).min(b.distance(x));
                    let fills = if r < reach {
                        corner > STANDING * reach
                    } else {
                        corner > slack
                    };
                    (base[idx] < 0.0 && fills).then_some((t / line.bin).floor() as i64)
                })
                .collect();
            let before = line.bins.len();
            line.bins.retain(|k| !standing.contains(k));
            line.blocked += before - line.bins.len();
            let runs = line.runs();
            let changes: Vec<(usize, f64, Option<f64>)> = self
                .nodes_near(&line, reach)
                .into_par_iter()
                .filter_map(|idx| {
                    let x = self.node(idx);
                    let (t, r) = line.coordinates(x);
                    let (da, db) = (a.distance(x), b.distance(x));
                    let run = runs.get(&((t / line.bin).floor() as i64))?;
                    if r >= reach || da <= -h || db <= -h {
                        return None;
                    }
                    let along = ((t - run.0).min(run.1 - t) / (0.5 * line.bin)).clamp(0.0, 1.0);
                    let weight = ((reach - r) / (0.25 * reach)).clamp(0.0, 1.0) * along;
                    let v = base[idx];
                    let other = match snapped_to[idx] {
                        Some(k) if k == line.planes[0] => Some(db),
                        Some(k) if k == line.planes[1] => Some(da),
                        _ => None,
                    };
                    let raised = v.max(da.min(db));
                    let cap = other
                        .filter(|&d| !(d < 0.0 && raw[idx] > 0.0))
                        .map(|d| v + weight * (raised.min(d) - v));
                    Some((idx, v + weight * (raised - v), cap))
                })
                .collect();
            for (idx, raise, cap) in changes {
                values[idx] = values[idx].max(raise);
                if let Some(c) = cap {
                    capped[idx] = capped[idx].min(c);
                }
            }
            report.creases.push(Crease {
                planes: line.planes,
                length: line.bins.len() as f64 * line.bin,
                blocked: line.blocked as f64 * line.bin,
            });
        }
        for ((v, &c), &b) in values.iter_mut().zip(&capped).zip(&base) {
            *v = v.min(c);
            if *v > b + 1e-9 {
                report.sharpened += 1;
                report.largest_raise = report.largest_raise.max(*v - b);
            }
        }
        let out = values.into_iter().map(|v| v as f32).collect();
        let grid = SdfGrid::from_values(self.origin(), h, self.dims(), out).expect("the same grid's dimensions");
        (grid, report)
    }

    /// The nodes within `radius` of a crease's stretches (of the box around them).
    fn nodes_near(&self, line: &CreaseLine, radius: f64) -> Vec<usize> {
        let (Some(&first), Some(&last)) = (line.bins.first(), line.bins.last()) else {
            return Vec::new();
        };
        let ends = [first as f64 * line.bin, (last + 1) as f64 * line.bin].map(|t| line.point + line.direction * t);
        let ([nx, ny, nz], o, h) = (self.dims(), self.origin(), self.spacing());
        let range = |axis: usize, n: usize| {
            let (p, q) = (ends[0][axis], ends[1][axis]);
            let lo = ((p.min(q) - radius - o[axis]) / h).floor().max(0.0) as usize;
            let hi = (((p.max(q) + radius - o[axis]) / h).ceil().max(0.0) as usize).min(n - 1);
            lo..=hi
        };
        let (ri, rj, rk) = (range(0, nx), range(1, ny), range(2, nz));
        let mut out = Vec::new();
        for k in rk {
            for j in rj.clone() {
                for i in ri.clone() {
                    out.push(i + nx * (j + ny * k));
                }
            }
        }
        out
    }

    /// The position of node `idx` (x fastest).
    fn node(&self, idx: usize) -> V {
        let ([nx, ny, _], o, h) = (self.dims(), self.origin(), self.spacing());
        let (i, j, k) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
        V::new(o[0] + i as f64 * h, o[1] + j as f64 * h, o[2] + k as f64 * h)
    }
}

/// The zero level's points: each node within 0.75 spacings of it moved along the grid's gradient (central
/// differences) onto it, with the unit gradient as normal. Nodes where the gradient is short (under 0.5; the
/// field is no distance there) give none.
fn surface_points(g: &SdfGrid) -> Vec<Oriented> {
    let ([nx, ny, nz], h) = (g.dims(), g.spacing());
    let value = |i: usize, j: usize, k: usize| g.values()[i + nx * (j + ny * k)] as f64;
    let slope = |lo: f64, hi: f64, steps: usize| (hi - lo) / (steps as f64 * h);
    (0..nz)
        .into_par_iter()
        .flat_map_iter(|k| {
            let mut out = Vec::new();
            for j in 0..ny {
                for i in 0..nx {
                    let v = value(i, j, k);
                    if !(v.abs() < 0.75 * h) {
                        continue;
                    }
                    let axis = |idx: usize, n: usize, at: &dyn Fn(usize) -> f64| {
                        let (lo, hi) = (idx.saturating_sub(1), (idx + 1).min(n - 1));
                        slope(at(lo), at(hi), hi - lo)
                    };
                    let gr = V::new(
                        axis(i, nx, &|a| value(a, j, k)),
                        axis(j, ny, &|a| value(i, a, k)),
                        axis(k, nz, &|a| value(i, j, a)),
                    );
                    let len = gr.norm();
                    if len < 0.5 {
                        continue;
                    }
                    let n = gr * (1.0 / len);
                    let x = g.node(i + nx * (j + ny * k));
                    out.push(Oriented {
                        p: x - n * (v / len),
                        n,
                    });
                }
            }
            out
        })
        .collect()
}

/// The centre of `members` and the covariance of their offsets from it, each offset first mapped by `map`.
fn scatter(points: &[Oriented], members: &[usize], map: impl Fn(V) -> V) -> (V, [[f64; 3]; 3]) {
    let m = members.len() as f64;
    let centre = members.iter().fold(V::zero(), |s, &i| s + points[i].p) * (1.0 / m);
    let mut cov = [[0.0; 3]; 3];
    for &i in members {
        let d = map(points[i].p - centre).to_array();
        for (r, row) in cov.iter_mut().enumerate() {
            for (c, e) in row.iter_mut().enumerate() {
                *e += d[r] * d[c] / m;
            }
        }
    }
    (centre, cov)
}

/// The least-squares plane through `members` (the normal oriented with their mean normal).
fn fit_plane(points: &[Oriented], members: &[usize]) -> (V, f64) {
    let (centre, cov) = scatter(points, members, |d| d);
    let mean_normal = members.iter().fold(V::zero(), |s, &i| s + points[i].n);
    let (values, vectors) = symmetric_eigen(cov);
    let smallest = (0..3).min_by(|&a, &b| values[a].total_cmp(&values[b])).unwrap_or(0);
    let mut normal = V::new(vectors[0][smallest], vectors[1][smallest], vectors[2][smallest]);
    if normal.dot(mean_normal) < 0.0 {
        normal = -normal;
    }
    (normal, normal.dot(centre))
}

/// The width across the plane of `members` (normal `normal`): of the uniform strip with their spread
/// (√12 standard deviations) along the in-plane direction they spread least.
fn narrowest_width(points: &[Oriented], members: &[usize], normal: V) -> f64 {
    let (_, cov) = scatter(points, members, |d| d - normal * d.dot(normal));
    // The in-plane spread: the two largest eigenvalues (the third, along the normal, is zero).
    let (mut values, _) = symmetric_eigen(cov);
    values.sort_by(f64::total_cmp);
    (12.0 * values[1].max(0.0)).sqrt()
}

/// Planes by RANSAC on oriented points: each round, 300 of the points left each propose the plane through
/// them with their normal; the one with the most points within the tolerance and angle (counted on a sample
/// of 20,000 of the points left) wins, is refitted by least squares until its points stop changing, and its
/// points leave; it is kept if it is at least the narrowest width across and not a larger plane's relief.
/// Until the best covers less than the smallest area.
fn find_planes(points: &[Oriented], s: &PlaneSettings, h: f64) -> Vec<Found> {
    const PROPOSALS: usize = 300;
    /// Points each proposal is scored on (the winner's points are then counted over all of them).
    const SCORED: usize = 20_000;
    /// Enough for a room's worth of faces; a reconstruction's fog beyond the board can make dozens of facets.
    const MAX_PLANES: usize = 64;
    let cos_max = s.max_angle_deg.to_radians().cos();
    // About one and a half surface points per spacing² of surface (the nodes within 0.75 spacings of it).
    let min_points = ((1.5 * s.min_area / (h * h)).ceil() as usize).max(16);
    let mut left: Vec<usize> = (0..points.len()).collect();
    let mut rng = SplitMix64::new(0x504c_414e_4553);
    let mut found = Vec::new();
    let on = |normal: V, offset: f64, i: usize| {
        let q = points[i];
        (normal.dot(q.p) - offset).abs() < s.tolerance && normal.dot(q.n) > cos_max
    };
    // Rounds whose winner is a strip make no plane: a bound on them too (a curved surface is all strips).
    let mut rounds = 0;
    while left.len() >= min_points && found.len() < MAX_PLANES && rounds < 4 * MAX_PLANES {
        rounds += 1;
        let mut pick = || left[(rng.next_u64() % left.len() as u64) as usize];
        let proposals: Vec<usize> = (0..PROPOSALS).map(|_| pick()).collect();
        let scored: Vec<usize> = if left.len() <= SCORED {
            left.clone()
        } else {
            (0..SCORED).map(|_| pick()).collect()
        };
        let Some((_, seed)) = proposals
            .par_iter()
            .map(|&c| {
                let (n, o) = (points[c].n, points[c].n.dot(points[c].p));
                (scored.iter().filter(|&&i| on(n, o, i)).count(), c)
            })
            .max_by_key(|&(count, c)| (count, std::cmp::Reverse(c)))
        else {
            break;
        };
        let (mut normal, mut offset) = (points[seed].n, points[seed].n.dot(points[seed].p));
        let mut members: Vec<usize> = left.iter().copied().filter(|&i| on(normal, offset, i)).collect();
        // Refit until the points on it stop changing (the plane then no longer depends on its proposal).
        for _ in 0..8 {
            if members.len() < 3 {
                break;
            }
            (normal, offset) = fit_plane(points, &members);
            let again: Vec<usize> = left.iter().copied().filter(|&i| on(normal, offset, i)).collect();
            if again == members {
                break;
            }
            members = again;
        }
        if members.len() < min_points {
            break;
        }
        let taken: BTreeSet<usize> = members.iter().copied().collect();
        left.retain(|i| !taken.contains(i));
        if narrowest_width(points, &members, normal) < s.min_width {
            // A strip (a fillet's flattest band, a cylinder's side): its points leave, no plane is made.
            continue;
        }
        if found
            .iter()
            .any(|f: &Found| f.normal.dot(normal) > cos_max && (f.offset - offset).abs() < RELIEF * s.tolerance)
        {
            // A plane's relief, not a plane of its own (a textured board's squares reconstructed a millimetre or
            // two proud): its points leave, and the larger plane's snap flattens them where they are near it.
            continue;
        }
        let on_plane: Vec<V> = members.iter().map(|&i| points[i].p).collect();
        found.push(Found {
            normal,
            offset,
            footprint: Footprint::of(normal, &on_plane, h),
            members,
            relief: 0.0,
        });
    }
    // Each plane's relief: the points parallel to it and near it (within RELIEF tolerances, over its footprint
    // coarsened to cells of four spacings, as a relief's squares make holes in it), its own and those of its
    // relief, make its footprint and say how far they stand off it. Its normal and level stay its own points'
    // (refitted to all of these, a wall's normal leans with the rounding at its foot: 1.5° on a 1,500-step
    // scene).
    for f in &mut found {
        let own: Vec<V> = f.members.iter().map(|&i| points[i].p).collect();
        let coarse = Footprint::of(f.normal, &own, 4.0 * h);
        let wide: Vec<V> = points
            .par_iter()
            .filter(|q| {
                f.normal.dot(q.n) > cos_max && f.distance(q.p).abs() < RELIEF * s.tolerance && coarse.contains(q.p)
            })
            .map(|q| q.p)
            .collect();
        f.relief = wide.iter().map(|&p| f.distance(p).abs()).fold(0.0, f64::max);
        f.footprint = Footprint::of(f.normal, &wide, h);
    }
    found
}

/// The concave creases between the planes: pairs at least 30° apart whose points each lie, near the line
/// where the planes meet, on the other's free side (a convex edge has them behind), with the stretches of the
/// line (bins of half the reach) where both planes have points within 4 reaches of it (a plane's points stop
/// where the fillet or a face's lean begins, which on a 1,500-step scene's wall was more than 30 mm up in
/// places; the raise is the corner's distance, a lower bound of the true one where the two planes are the
/// nearest solid, so a generous window costs nothing). A stretch where the
/// zero level in the wedge stands further than [`STANDING`] reaches from both planes holds something other
/// than a fillet and is left alone.
fn concave_creases(found: &[Found], points: &[Oriented], s: &PlaneSettings) -> Vec<CreaseLine> {
    let reach = s.crease_reach;
    let bin = 0.5 * reach;
    let mut lines = Vec::new();
    for ia in 0..found.len() {
        for ib in ia + 1..found.len() {
            let (a, b) = (&found[ia], &found[ib]);
            if a.normal.dot(b.normal).abs() > 30f64.to_radians().cos() {
                continue;
            }
            let direction = a.normal.cross(b.normal).normalize_or(V::new(1.0, 0.0, 0.0));
            // The point of the line nearest the origin: on both planes and on `direction · x = 0`.
            let denom = a.normal.dot(b.normal.cross(direction));
            let point = (b.normal.cross(direction) * a.offset + direction.cross(a.normal) * b.offset) * (1.0 / denom);
            let mut line = CreaseLine {
                planes: [ia, ib],
                point,
                direction,
                bin,
                bins: BTreeSet::new(),
                blocked: 0,
            };
            // Each plane's points near the line: the stretches they cover, and how far those within 1.5 reaches
            // stand on the other's side.
            let near = |f: &Found, other: &Found| -> (BTreeSet<i64>, Vec<f64>) {
                let mut bins = BTreeSet::new();
                let mut sides = Vec::new();
                for &i in &f.members {
                    let (t, r) = line.coordinates(points[i].p);
                    if r < 4.0 * reach {
                        bins.insert((t / bin).floor() as i64);
                    }
                    if r < 1.5 * reach {
                        sides.push(other.distance(points[i].p));
                    }
                }
                (bins, sides)
            };
            let ((bins_a, mut side_a), (bins_b, mut side_b)) = (near(a, b), near(b, a));
            if side_a.len() < 4 || side_b.len() < 4 || median(&mut side_a) <= 0.0 || median(&mut side_b) <= 0.0 {
                continue;
            }
            let mut bins: BTreeSet<i64> = bins_a.intersection(&bins_b).copied().collect();
            // What stands in the wedge, per stretch.
            let mut standing: BTreeMap<i64, f64> = BTreeMap::new();
            for q in points {
                let (t, r) = line.coordinates(q.p);
                let (da, db) = (a.distance(q.p), b.distance(q.p));
                if r < reach && da > s.tolerance && db > s.tolerance {
                    let e = standing.entry((t / bin).floor() as i64).or_insert(0.0);
                    *e = e.max(da.min(db));
                }
            }
            let before = bins.len();
            bins.retain(|k| standing.get(k).is_none_or(|&d| d <= STANDING * reach));
            line.blocked = before - bins.len();
            if !bins.is_empty() || line.blocked > 0 {
                line.bins = bins;
                lines.push(line);
            }
        }
    }
    lines
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

impl std::fmt::Display for PlaneReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} found", self.planes.len())?;
        // The largest few (a fog's facets can make dozens).
        const SHOWN: usize = 8;
        for p in self.planes.iter().take(SHOWN) {
            let [x, y, z] = p.normal.to_array();
            write!(
                f,
                "; ({x:.3}, {y:.3}, {z:.3})·x = {:.4} m, {} points, relief {:.1} mm",
                p.offset,
                p.points,
                p.relief * 1e3
            )?;
        }
        if self.planes.len() > SHOWN {
            write!(f, "; {} more", self.planes.len() - SHOWN)?;
        }
        let length: f64 = self.creases.iter().map(|c| c.length).sum();
        let blocked: f64 = self.creases.iter().map(|c| c.blocked).sum();
        write!(
            f,
            "; {} concave creases made sharp over {:.2} m ({:.2} m left: something stands in the corner); {} nodes \
             snapped to a plane, {} raised at a crease by up to {:.2} mm",
            self.creases.len(),
            length,
            blocked,
            self.snapped,
            self.sharpened,
            self.largest_raise * 1e3
        )
    }
}
