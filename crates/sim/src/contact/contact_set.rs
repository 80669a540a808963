//! Colliding points grouped into contact patches by their surface normal (a
//! corner on the board and a face against a wall are two patches; plain
//! numbers: the choice is discrete, its derivative zero). The mean-point model
//! averages each patch; the multi-point model reduces each to at most four
//! points that span its support polygon, as engines reduce a contact manifold:
//! the deepest point, the one farthest from it, the one farthest from their
//! line, and the one that adds the most area. A body then rests on its support
//! polygon, rocks about an edge and tips over one, which a single averaged
//! point cannot.

use geom::Vec3;

/// A colliding contact point: its index among the body's points near the other surface
/// ([`super::support_point::Near`]), its distance to the other surface and that
/// surface's unit normal there (plain numbers).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Colliding {
    pub index: usize,
    pub distance: f64,
    pub normal: Vec3<f64>,
    /// Where it is (world frame).
    pub at: Vec3<f64>,
}

/// Normals within this angle share a patch (cos 30°).
const SAME_PATCH_COS: f64 = 0.866;
/// At most this many patches per body pair (the rest are rare and tiny).
const MAX_PATCHES: usize = 3;

/// The colliding points grouped into patches, deepest first, as indices into `points` (each in their
/// order there): a patch is the points whose normals lie within 30° of its deepest point's, the deepest
/// point left over seeds the next, at most [`MAX_PATCHES`] (the rest are rare and tiny).
pub(crate) fn patches(points: &[Colliding]) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    let mut left: Vec<usize> = (0..points.len()).collect();
    while out.len() < MAX_PATCHES {
        let Some(seed) = deepest(points, &left) else {
            break;
        };
        let n0 = points[seed].normal;
        let (patch, rest): (Vec<usize>, Vec<usize>) =
            left.iter().partition(|&&i| points[i].normal.dot(n0) >= SAME_PATCH_COS);
        out.push(patch);
        left = rest;
    }
    out
}

/// The points to solve, as indices into `points`: at most four per patch.
pub(crate) fn select_contacts(points: &[Colliding], out: &mut Vec<usize>) {
    out.clear();
    for patch in patches(points) {
        if let Some(seed) = deepest(points, &patch) {
            reduce_patch(points, &patch, seed, out);
        }
    }
}

/// The deepest of `among` (the first of equals, so a patch's deepest is the point that seeded it).
fn deepest(points: &[Colliding], among: &[usize]) -> Option<usize> {
    among
        .iter()
        .copied()
        .min_by(|&a, &b| points[a].distance.total_cmp(&points[b].distance))
}

/// Up to four points of one patch spanning its support polygon (`seed`: the deepest).
fn reduce_patch(points: &[Colliding], patch: &[usize], seed: usize, out: &mut Vec<usize>) {
    let at = |i: usize| points[i].at;
    out.push(seed);
    let far = |score: &dyn Fn(Vec3<f64>) -> f64| {
        patch
            .iter()
            .copied()
            .map(|i| (i, score(at(i))))
            .filter(|(_, s)| *s > 1e-12)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    };
    let p1 = at(seed);
    let Some(i2) = far(&|x| (x - p1).norm_sq()) else { return };
    out.push(i2);
    let p2 = at(i2);
    let area = |a: Vec3<f64>, b: Vec3<f64>, c: Vec3<f64>| (b - a).cross(c - a).norm();
    let Some(i3) = far(&|x| area(p1, p2, x)) else { return };
    out.push(i3);
    let p3 = at(i3);
    // What a fourth point adds to the triangle: positive only outside it.
    let base = area(p1, p2, p3);
    if let Some(i4) = far(&|x| area(p1, p2, x) + area(p2, p3, x) + area(p3, p1, x) - base - 1e-9 * base) {
        out.push(i4);
    }
}
