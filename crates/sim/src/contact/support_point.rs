//! Where a curved body really touches. A body's contact points are samples
//! of its surface, and a curved surface meets the other one between them:
//! rolling over samples is rolling a polygon, which knocks at every sample and
//! loses speed, and the samples just ahead of a rolling contact turn toward
//! the other surface, so they look like an impact and bounce the body.
//!
//! A sample near the other surface is slid along the body's own surface (its
//! SDF) to where that surface faces the other one (the body's normal opposite
//! the other's normal: the support point, where a smooth body touches), by
//! Newton steps on the normal with the surface's curvature (its shape
//! operator, by differences of the SDF's normal between surface points; a
//! baked grid's normal from central differences of its values, which turn
//! continuously where its trilinear gradient jumps). Where the surface does
//! not curve (a flat face) there is no such place, and where it lies beyond
//! the sample's share of the surface (it belongs to other samples) or sliding
//! there lifts the point (a corner is already the support), the sample stays:
//! a face still rests on its spread of points and a box still lands on its
//! corners.
//!
//! Derivatives: the support point moves with the pose (a ball's contact stays
//! under its centre however it turns). One Newton step taken again in the
//! generic scalar from the converged point ([`Touch::local`]) carries that
//! motion into the dual numbers (exactly for a sphere).
//!
//! Cost: each sample's start (its place on the SDF's surface and the
//! curvature there) is found once per body, so flat samples and those by a
//! sharp edge never search; per substep only the samples near the lowest
//! search, deepest first, sharing the supports found, and a run of searches
//! that find nothing ends the searching (a box costs nothing, the synth toy
//! about three times its simulation without supports).

use super::contact_set::Colliding;
use super::sequential_impulses::tangents;
use super::Detection;
use crate::sdf::{Sdf, Shape};
use crate::RigidBody;
use geom::{Mat3, Real, Vec3};

/// Newton steps per sample.
const STEPS: usize = 6;
/// Steps stop when the next one is shorter than this fraction of the reach (or stalls there): converged to
/// rounding, so the point does not wobble with the sample it came from.
const STEP_DONE: f64 = 1e-14;
/// A support is kept when the step still to go after the last one is shorter than this fraction of the
/// reach. Only the curved directions count: on a cylinder tilted against the other surface the sample
/// slides round to the lowest line and stays at its place along the axis (where no point faces exactly).
const STEP_CLOSE: f64 = 1e-6;
/// Curvatures below this fraction of 1/reach count as flat (1/m · reach).
const FLAT_CURVATURE: f64 = 1e-3;

/// A slide that rises more than this fraction of its length is off a corner, not toward a support.
const UPHILL: f64 = 0.05;

/// Normals that turn by more than this (cos 10°) between a surface point and just inside it meet at a crease.
const CREASE_COS: f64 = 0.985;

/// Searches in a row that find no support before the rest of a substep's samples keep their places.
const MAX_MISSES: usize = 8;

/// A cluster is passed over when its bound exceeds the threshold by more than this (m): the bound and the
/// points' distances are rounded differently.
const CULL_MARGIN: f64 = 1e-9;

/// How far a sample may slide, in contact-point spacings.
const REACH_SPACINGS: f64 = 4.0;

/// A body's point near the other surface (body frame): where it is (at its support if it slid there), the
/// other surface's distance there and its unit normal.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Touch {
    pub point: Vec3<f64>,
    pub distance: f64,
    pub normal: Vec3<f64>,
    /// Which of the body's contact points it is (or slid from).
    sample: usize,
    support: Option<SurfacePoint>,
}

impl Touch {
    /// The point with its derivatives. `facing(x)`: the body-frame unit vector opposite the other
    /// surface's normal at the body-frame point `x`, in the generic scalar. A support moves with the pose:
    /// one Newton step taken again in `S` from it carries that (its value is the point's residual, below
    /// the tolerance, and is dropped so the value is the point itself).
    pub fn local<S: Real>(&self, facing: impl Fn(Vec3<S>) -> Vec3<S>) -> Vec3<S> {
        let point = Vec3::lift(self.point);
        match &self.support {
            Some(s) => {
                let step = s.surface.step(facing(point));
                point + step - Vec3::lift(step.re())
            }
            None => point,
        }
    }
}

/// A point of the body's surface with the surface around it (body frame): a sample's start, found once
/// per body, or the support it slid to.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SurfacePoint {
    at: Vec3<f64>,
    surface: Local,
}

/// Where a sample's search starts, found once per body (the surface is the body's own). `None` where the
/// surface is flat there or meets a sharp edge (the sample never moves, and costs nothing per substep) or
/// the search cannot start.
#[derive(Clone, Debug)]
pub(crate) struct SampleStart(Option<SurfacePoint>);

impl SampleStart {
    /// The starts of `points` on `body` (body frame), for contact points `spacing` apart.
    pub fn of_samples(body: &Shape, points: &[Vec3<f64>], spacing: f64) -> Vec<Self> {
        let Lengths { probe, flat, .. } = Lengths::of(body, spacing);
        points
            .iter()
            .map(|&r| {
                let at = project(body, r);
                SampleStart(
                    at.and_then(|at| Local::at(body, at, probe, flat).map(|surface| SurfacePoint { at, surface }))
                        .filter(|p| !p.surface.is_flat() && !near_crease(body, p.at, &p.surface, probe)),
                )
            })
            .collect()
    }
}

/// A body's points within the contact threshold of the other surface, the nearest slid to their supports.
pub(crate) struct Near {
    pub touches: Vec<Touch>,
}

impl Near {
    /// `speed`: the fastest any point of the body moves (m/s); `other(x)`: the other surface's distance and
    /// unit normal at the body-frame point `x`; `other_bound(c, r)`: a lower bound of its distance over the
    /// ball of radius `r` about the body-frame point `c` (a cluster of points whose bound is above the
    /// threshold has none near, [`crate::point_clusters`]).
    pub fn find(
        body: &RigidBody,
        det: &Detection,
        speed: f64,
        other: impl Fn(Vec3<f64>) -> (f64, Vec3<f64>),
        other_bound: impl Fn(Vec3<f64>, f64) -> f64,
    ) -> Self {
        // The samples of the clusters that may be near, in the points' own order (the solvers' sums run in
        // it): indices are sorted, not touches (a touch with its support is a few hundred bytes; moving them
        // in the sort and the growing vector was a tenth of a fit's time).
        let mut candidates: Vec<u32> = body
            .point_clusters
            .iter()
            .filter(|c| other_bound(c.centre, c.radius) <= det.delta + CULL_MARGIN)
            .flat_map(|c| c.members.iter().copied())
            .collect();
        candidates.sort_unstable();
        let mut touches: Vec<Touch> = Vec::with_capacity(candidates.len());
        touches.extend(candidates.iter().filter_map(|&i| {
            let sample = i as usize;
            let point = body.contact_points[sample];
            let (distance, normal) = other(point);
            (distance <= det.delta).then_some(Touch {
                point,
                distance,
                normal,
                sample,
                support: None,
            })
        }));
        if det.supports && !touches.is_empty() {
            slide_to_supports(body, det, speed, &other, &mut touches);
        }
        Self { touches }
    }

    /// The touches that collide (Eq. 8 with the speculative rule) as the contact solvers take them: `to_world`
    /// maps a body-frame offset to world axes, `origin` is the body's centre (world), `velocity(x)` the
    /// velocity of the world point `x` relative to the other surface.
    pub fn colliding(
        &self,
        det: &Detection,
        to_world: &Mat3<f64>,
        origin: Vec3<f64>,
        velocity: impl Fn(Vec3<f64>) -> Vec3<f64>,
    ) -> Vec<Colliding> {
        self.touches
            .iter()
            .enumerate()
            .filter_map(|(index, touch)| {
                let at = origin + to_world.mul_vec(touch.point);
                let normal = to_world.mul_vec(touch.normal);
                det.collides(touch.distance, velocity(at).dot(normal))
                    .then_some(Colliding {
                        index,
                        distance: touch.distance,
                        normal,
                        at,
                    })
            })
            .collect()
    }

    /// The mean of the colliding points (body frame) with their derivatives (`local` of each touch).
    pub fn mean<S: Real>(&self, colliding: &[Colliding], local: impl Fn(&Touch) -> Vec3<S>) -> Vec3<S> {
        colliding
            .iter()
            .fold(Vec3::<S>::zero(), |acc, c| acc + local(&self.touches[c.index]))
            * S::cst(1.0 / colliding.len() as f64)
    }

    /// RMS distance of the colliding points from their mean (body frame), about the first point: the spread
    /// of points slid to one support is zero, not rounding noise.
    pub fn patch_radius(&self, colliding: &[Colliding]) -> f64 {
        let Some(first) = colliding.first().map(|c| self.touches[c.index].point) else {
            return 0.0;
        };
        let (sum, sum_sq) = colliding.iter().fold((Vec3::<f64>::zero(), 0.0), |(sum, sq), c| {
            let r = self.touches[c.index].point - first;
            (sum + r, sq + r.norm_sq())
        });
        let n = colliding.len() as f64;
        (sum_sq / n - (sum * (1.0 / n)).norm_sq()).max(0.0).sqrt()
    }

    /// The deepest point below the other surface, if any.
    pub fn deepest(&self) -> Option<&Touch> {
        self.touches
            .iter()
            .filter(|t| t.distance < 0.0)
            .min_by(|a, b| a.distance.total_cmp(&b.distance))
    }
}

/// Slide the touches that may collide to their supports (the module's docs). Only samples that may reach
/// the surface within the substep (or the skin without the speculative rule), and a quarter spacing higher:
/// the support is found from the samples nearest it, which on a surface curved at radii above two spacings
/// lie within that of its height. Deepest first: a sample within a spacing of a support already found
/// shares it (a ball's samples round its lowest point all slide there), and after a few searches in a row
/// that find nothing (samples of a rounded edge by a face that nearly faces the other surface), the rest
/// keep their places.
fn slide_to_supports(
    body: &RigidBody,
    det: &Detection,
    speed: f64,
    other: &dyn Fn(Vec3<f64>) -> (f64, Vec3<f64>),
    touches: &mut [Touch],
) {
    let nearest = touches.iter().map(|t| t.distance).fold(f64::INFINITY, f64::min);
    let band = det.speculative_dt.map_or(det.delta, |dt| dt * speed) + 0.25 * body.contact_spacing;
    let lengths = Lengths::of(&body.sdf, body.contact_spacing);
    let mut order: Vec<usize> = (0..touches.len())
        .filter(|&k| touches[k].distance <= nearest + band && body.sample_starts[touches[k].sample].0.is_some())
        .collect();
    order.sort_by(|&a, &b| touches[a].distance.total_cmp(&touches[b].distance));
    let mut found: Vec<Touch> = Vec::new();
    let mut misses = 0;
    for k in order {
        let touch = &mut touches[k];
        let SampleStart(Some(start)) = &body.sample_starts[touch.sample] else {
            continue;
        };
        if let Some(shared) = found
            .iter()
            .find(|f| (f.point - start.at).norm() < body.contact_spacing)
        {
            *touch = Touch {
                sample: touch.sample,
                ..*shared
            };
            continue;
        }
        if misses == MAX_MISSES {
            continue;
        }
        match support_point(&body.sdf, start, lengths, other) {
            Some(support) => {
                let (distance, normal) = other(support.at);
                *touch = Touch {
                    point: support.at,
                    distance,
                    normal,
                    sample: touch.sample,
                    support: Some(support),
                };
                found.push(*touch);
                misses = 0;
            }
            None => misses += 1,
        }
    }
}

/// Slide a sample (body frame) from its `start` along `body`'s surface to its support against the other
/// surface, moving at most `lengths.reach`. `other(x)` is the other surface's distance and unit normal at
/// the body-frame point `x`. `None`: the sample stays where it is.
fn support_point(
    body: &Shape,
    start: &SurfacePoint,
    lengths: Lengths,
    other: &dyn Fn(Vec3<f64>) -> (f64, Vec3<f64>),
) -> Option<SurfacePoint> {
    let Lengths { reach, probe, flat } = lengths;
    // The start is on the SDF's own surface (a mesh's samples lie a little off a grid's level set), so the
    // steps' descent is measured on one surface.
    let mut x = start.at;
    let d_start = other(x).0;
    let mut moved = 0.0;
    let mut last = f64::INFINITY;
    for steps in 0..=STEPS {
        let surface = if steps == 0 {
            start.surface
        } else {
            Local::at(body, x, probe, flat)?
        };
        if surface.is_flat() {
            // Slid off the curved part onto a flat one (a face by a rounded edge, nearly facing): the face's
            // own samples stand for it.
            return None;
        }
        let step = surface.step(-other(x).1);
        let length = step.norm();
        // Stop when converged to rounding, stalled (Newton's steps shrink fast toward a support; they creep
        // where the curvature ends before the facing place, as at a face's border), out of steps, or when
        // the facing place is another sample's.
        let stalled = length > 0.5 * last;
        last = length;
        let mut stop = length < STEP_DONE * reach || stalled || steps == STEPS || moved + length > reach;
        let mut to = x;
        if !stop {
            to = project(body, x + step)?;
            // Sliding off a corner (already the support) lifts the point: stay. Measured from the start, as
            // the last steps near a support gain little and a grid's level set is rough at 1e-7 m.
            stop = other(to).0 > d_start + UPHILL * (moved + length);
        }
        if stop {
            return (moved > 0.0 && length < STEP_CLOSE * reach).then_some(SurfacePoint { at: x, surface });
        }
        (x, moved) = (to, moved + length);
    }
    None // not reached: the last pass stops
}

/// The lengths of a body's search.
#[derive(Clone, Copy, Debug)]
struct Lengths {
    /// How far a sample may slide.
    reach: f64,
    /// The step of the differences that give the surface's curvature: a tenth of a spacing (the curvature
    /// at the sample, not smeared over its neighbours': a face's sample by a rounded edge is flat), or a
    /// grid's cell where the SDF is a grid (below it a grid has no curvature of its own).
    probe: f64,
    /// Curvatures below this are flat, 1/m.
    flat: f64,
}

impl Lengths {
    fn of(body: &Shape, spacing: f64) -> Self {
        let reach = REACH_SPACINGS * spacing;
        Self {
            reach,
            probe: (0.1 * spacing).max(grid_cell(body)),
            flat: FLAT_CURVATURE / reach,
        }
    }
}

/// The cell of a grid SDF (placed or not), 0 for an analytic one.
fn grid_cell(body: &Shape) -> f64 {
    match body {
        Shape::Grid(grid) => grid.spacing(),
        Shape::Transformed { shape, .. } => grid_cell(shape),
        _ => 0.0,
    }
}

/// The body's surface around a point: a tangent basis and the inverse of the shape operator in it (zero
/// along flat directions).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Local {
    basis: [Vec3<f64>; 2],
    inverse: [[f64; 2]; 2],
}

impl Local {
    /// No direction curves here (no step moves the point).
    fn is_flat(&self) -> bool {
        self.inverse == [[0.0; 2]; 2]
    }

    /// The Newton step toward where the normal is `facing` (a unit vector; any scalar): the shape
    /// operator's inverse on the part of `facing` the normal lacks in the tangent plane.
    fn step<S: Real>(&self, facing: Vec3<S>) -> Vec3<S> {
        let [e1, e2] = self.basis.map(Vec3::lift);
        let (a, b) = (facing.dot(e1), facing.dot(e2));
        let inv = &self.inverse;
        e1 * (a * inv[0][0] + b * inv[0][1]) + e2 * (a * inv[1][0] + b * inv[1][1])
    }

    fn at(body: &Shape, x: Vec3<f64>, eps: f64, flat: f64) -> Option<Self> {
        let normal = surface_normal(body, x)?.1;
        let (e1, e2) = tangents(normal);
        let basis = [e1, e2];
        // Shape operator W[i][j] = e_i · ∂n/∂s_j: the normal's change between the surface points found from
        // x ± eps e_j (projected along the SDF's gradient, whose normal they share) over their distance
        // along e_j, exact on a sphere.
        let mut w = [[0.0; 2]; 2];
        for j in 0..2 {
            let at = |s: f64| {
                let y = x + basis[j] * s;
                surface_normal(body, y).map(|(d, n)| (y - n * d, n))
            };
            let ((p_plus, n_plus), (p_minus, n_minus)) = (at(eps)?, at(-eps)?);
            let run = basis[j].dot(p_plus - p_minus);
            if run.abs() < 1e-12 {
                return None;
            }
            for i in 0..2 {
                w[i][j] = basis[i].dot(n_plus - n_minus) / run;
            }
        }
        Some(Self {
            basis,
            inverse: pseudo_inverse(w, flat),
        })
    }
}

/// Whether a sharp edge lies within `eps` of `x` (a box's): there the normal jumps, no point faces the
/// other surface exactly and the search would only wander. Off a crease the SDF's gradient is the same
/// just inside the surface as on it; past a crease, the points a probe lands on (the edge) have one
/// normal outside (diagonal) and another just inside (a face's).
fn near_crease(body: &Shape, x: Vec3<f64>, local: &Local, eps: f64) -> bool {
    let inside = eps;
    local.basis.iter().any(|&e| {
        [eps, -eps].iter().any(|&s| {
            let y = x + e * s;
            surface_normal(body, y).is_none_or(|(d, n)| {
                let p = y - n * d;
                surface_normal(body, p - n * inside).is_none_or(|(_, n_in)| n_in.dot(n) < CREASE_COS)
            })
        })
    })
}

/// The inverse of the symmetric part of `w` on its convex directions (eigenvalues above `flat`); flat and
/// concave directions get zero (no step along them).
fn pseudo_inverse(w: [[f64; 2]; 2], flat: f64) -> [[f64; 2]; 2] {
    let (a, b, c) = (w[0][0], 0.5 * (w[0][1] + w[1][0]), w[1][1]);
    let invert = |lambda: f64| if lambda > flat { 1.0 / lambda } else { 0.0 };
    if b.abs() <= 1e-12 * (a.abs() + c.abs()) {
        // Diagonal already (a sphere's, whatever the basis).
        return [[invert(a), 0.0], [0.0, invert(c)]];
    }
    let mean = 0.5 * (a + c);
    let spread = (0.25 * (a - c).powi(2) + b * b).sqrt();
    let mut inv = [[0.0; 2]; 2];
    for lambda in [mean + spread, mean - spread] {
        // Eigenvector of [[a, b], [b, c]] for lambda (b ≠ 0, so the two are distinct and orthogonal).
        let v = [lambda - c, b];
        let len2 = v[0] * v[0] + v[1] * v[1];
        for i in 0..2 {
            for j in 0..2 {
                inv[i][j] += v[i] * v[j] / len2 * invert(lambda);
            }
        }
    }
    inv
}

/// The nearest point of the body's surface to `x` (one projection along the SDF's gradient).
fn project(body: &Shape, x: Vec3<f64>) -> Option<Vec3<f64>> {
    let (d, n) = surface_normal(body, x)?;
    Some(x - n * d)
}

/// The body's distance and unit normal at `x` for the search. A grid's trilinear gradient jumps from cell
/// to cell, so no point of it may face the other surface exactly; its normal here is the central
/// difference of its (continuous) values a cell apart, which turns continuously.
fn surface_normal(body: &Shape, x: Vec3<f64>) -> Option<(f64, Vec3<f64>)> {
    match body {
        Shape::Grid(grid) => {
            let h = grid.spacing();
            let at = |dx: f64, dy: f64, dz: f64| grid.distance_local(x + Vec3::new(dx, dy, dz));
            let g = Vec3::new(
                at(h, 0.0, 0.0) - at(-h, 0.0, 0.0),
                at(0.0, h, 0.0) - at(0.0, -h, 0.0),
                at(0.0, 0.0, h) - at(0.0, 0.0, -h),
            );
            Some((grid.distance_local(x), g.try_normalize()?))
        }
        Shape::Transformed { pose, shape } => {
            let (d, n) = surface_normal(shape, pose.inverse_transform_point(x))?;
            Some((d, pose.transform_vector(n)))
        }
        _ => {
            let (d, g) = body.distance_grad_local(x);
            Some((d, g.try_normalize()?))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sdf::{Cuboid, Sphere};
    use geom::Dual;

    /// The search from a raw sample (its start found as a body's are).
    fn slide(
        body: &Shape,
        r: Vec3<f64>,
        reach: f64,
        other: &dyn Fn(Vec3<f64>) -> (f64, Vec3<f64>),
    ) -> Option<SurfacePoint> {
        let spacing = reach / REACH_SPACINGS;
        let start = SampleStart::of_samples(body, &[r], spacing).remove(0);
        support_point(body, start.0.as_ref()?, Lengths::of(body, spacing), other)
    }

    fn plane_below(x: Vec3<f64>) -> (f64, Vec3<f64>) {
        (x.z + 0.02, Vec3::new(0.0, 0.0, 1.0))
    }

    #[test]
    fn a_sample_on_a_ball_slides_to_the_bottom() {
        let ball = Shape::Sphere(Sphere { radius: 0.02 });
        let angle: f64 = 0.1;
        let r = Vec3::new(0.02 * angle.sin(), 0.0, -0.02 * angle.cos());
        let s = slide(&ball, r, 0.006, &plane_below).expect("moves");
        assert!((s.at - Vec3::new(0.0, 0.0, -0.02)).norm() < 1e-12, "{:?}", s.at);
        // Beyond its reach it stays.
        let far = Vec3::new(0.02 * 0.5f64.sin(), 0.0, -0.02 * 0.5f64.cos());
        assert!(slide(&ball, far, 0.006, &plane_below).is_none());
    }

    #[test]
    fn samples_on_a_face_and_at_a_corner_stay() {
        let cube = Shape::Cuboid(Cuboid { half: [0.02; 3] });
        let tilted = |x: Vec3<f64>| (x.z + 0.03, Vec3::new(0.1, 0.0, 1.0).normalize_or(Vec3::zero()));
        assert!(slide(&cube, Vec3::new(0.005, 0.003, -0.02), 0.006, &tilted).is_none());
        assert!(slide(&cube, Vec3::new(0.02, 0.02, -0.02), 0.006, &tilted).is_none());
    }

    #[test]
    fn the_lifted_support_of_a_ball_moves_as_the_facing_turns() {
        // A ball's support against a surface with normal −f is radius · f: as f turns, so does the point.
        let ball = Shape::Sphere(Sphere { radius: 0.02 });
        let r = Vec3::new(0.001, 0.0005, -0.02).normalize_or(Vec3::zero()) * 0.02;
        let s = slide(&ball, r, 0.006, &plane_below).unwrap();
        let (ax, ay) = (Dual::<2>::var(0.0, 0), Dual::<2>::var(0.0, 1));
        let facing = Vec3::new(ax, ay, Dual::new(-1.0));
        let touch = Touch {
            point: s.at,
            distance: 0.0,
            normal: Vec3::new(0.0, 0.0, 1.0),
            sample: 0,
            support: Some(s),
        };
        let lifted = touch.local(|_| facing);
        assert!(
            (lifted.re() - Vec3::new(0.0, 0.0, -0.02)).norm() < 1e-12,
            "{:?}",
            lifted.re()
        );
        for (slot, axis) in [(0, 0usize), (1, 1)] {
            let d = [lifted.x.eps[slot], lifted.y.eps[slot], lifted.z.eps[slot]];
            for (k, dk) in d.iter().enumerate() {
                let want = if k == axis { 0.02 } else { 0.0 };
                assert!(
                    (dk - want).abs() < 1e-9 * 0.02,
                    "d point[{k}] / d facing[{axis}] = {dk}, want {want}"
                );
            }
        }
    }
}
