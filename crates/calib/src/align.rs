//! A reconstruction's world put onto the board's metric world (gravity along −z): from the board's corners
//! seen in its images, or, without a board, from the dominant plane of its sparse points and a known scale.

use std::collections::BTreeMap;

use geom::{Quat, Similarity, SplitMix64, Vec3};

use crate::board::Board;
use crate::calibrate::ViewPoints;
use crate::reconstruction::Reconstruction;

/// How the board put a reconstruction into its world.
#[derive(Clone, Debug)]
pub struct BoardAlignment {
    /// Reconstruction world → board world (metres).
    pub similarity: Similarity,
    /// Board points triangulated from two or more images and kept.
    pub points: usize,
    /// Board points left out (seen once, rays too parallel, or off the others).
    pub rejected: usize,
    /// Images whose board points were used.
    pub images: usize,
    /// RMS and largest distance of the kept points from the board's, after the similarity: metres.
    pub rms: f64,
    pub worst: f64,
}

/// Why a reconstruction could not be aligned.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct AlignError(pub String);

/// One image's sighting of a board point: the image and the point's normalised ray (z = 1).
type Sighting = (usize, [f64; 2]);

/// The smallest angle between the rays that triangulate a kept point: thinner angles leave its depth loose.
const MIN_RAY_ANGLE_DEG: f64 = 2.0;

/// Aligns by the board: each board point seen in two or more images (`sightings`: image index and its board
/// points, raw pixels) is triangulated in the reconstruction's world, and the similarity taking those points
/// onto the board's is fitted, points far off the others dropped (a misdetected corner, a bad camera).
pub fn align_to_board(
    rec: &Reconstruction,
    sightings: &[(usize, ViewPoints)],
    board: &Board,
) -> Result<BoardAlignment, AlignError> {
    // Board point (its board coordinates, exactly as the board gives them) → (image, normalised ray).
    let mut seen: BTreeMap<(u64, u64), Vec<Sighting>> = BTreeMap::new();
    for (image, points) in sightings {
        let lens = &rec.images[*image].lens;
        for (b, i) in points.board.iter().zip(&points.image) {
            seen.entry((b[0].to_bits(), b[1].to_bits()))
                .or_default()
                .push((*image, lens.undistort(i[0], i[1])));
        }
    }
    let images_seeing = sightings.iter().filter(|(_, p)| !p.board.is_empty()).count();
    if images_seeing < 3 {
        return Err(AlignError(format!(
            "the board is seen in {images_seeing} of the {} registered images; aligning to it needs 3 or more",
            rec.images.len()
        )));
    }
    let mut from = Vec::new();
    let mut to = Vec::new();
    let mut used_images = std::collections::BTreeSet::new();
    let mut rejected = 0;
    for ((bx, by), obs) in &seen {
        match triangulate(rec, obs) {
            Some(p) => {
                from.push(p);
                to.push(Vec3::from_array(
                    board.to_world([f64::from_bits(*bx), f64::from_bits(*by)]),
                ));
                used_images.extend(obs.iter().map(|o| o.0));
            }
            None => rejected += 1,
        }
    }
    let mut keep = vec![true; from.len()];
    let mut fit = None;
    for _ in 0..4 {
        let (f, t): (Vec<Vec3<f64>>, Vec<Vec3<f64>>) = from
            .iter()
            .zip(&to)
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|((f, t), _)| (*f, *t))
            .unzip();
        let s = Similarity::fit(&f, &t).ok_or_else(|| {
            AlignError(format!(
                "{} board points triangulated from two or more images, on one line or fewer than 3: photograph more of the board from more directions",
                f.len()
            ))
        })?;
        let errors: Vec<f64> = from.iter().zip(&to).map(|(f, t)| (s.apply(*f) - *t).norm()).collect();
        let mut kept: Vec<f64> = errors.iter().zip(&keep).filter(|(_, k)| **k).map(|(e, _)| *e).collect();
        kept.sort_by(f64::total_cmp);
        // A point 3 times the median off (and over half a millimetre) is not the board's.
        let limit = (3.0 * kept[kept.len() / 2]).max(5e-4);
        let next: Vec<bool> = errors.iter().map(|e| *e <= limit).collect();
        fit = Some(s);
        if next == keep {
            break;
        }
        keep = next;
    }
    let similarity = fit.expect("fitted at least once");
    let kept: Vec<f64> = from
        .iter()
        .zip(&to)
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|((f, t), _)| (similarity.apply(*f) - *t).norm())
        .collect();
    if kept.len() < 6 {
        return Err(AlignError(format!("only {} board points agree with each other: is the board file the printed board, and did the reconstruction register these images right?", kept.len())));
    }
    let rms = (kept.iter().map(|e| e * e).sum::<f64>() / kept.len() as f64).sqrt();
    Ok(BoardAlignment {
        similarity,
        points: kept.len(),
        rejected: rejected + keep.iter().filter(|k| !**k).count(),
        images: used_images.len(),
        rms,
        worst: kept.iter().copied().fold(0.0, f64::max),
    })
}

/// The point nearest the rays of its observations (the midpoint, in least squares), `None` when the rays
/// are too near parallel or the point is behind a camera.
fn triangulate(rec: &Reconstruction, obs: &[Sighting]) -> Option<Vec3<f64>> {
    if obs.len() < 2 {
        return None;
    }
    let rays: Vec<(Vec3<f64>, Vec3<f64>)> = obs
        .iter()
        .map(|(i, [x, y])| {
            let c2w = rec.images[*i].pose.inverse();
            let d = c2w.transform_vector(Vec3::new(*x, *y, 1.0));
            (c2w.t, d * (1.0 / d.norm()))
        })
        .collect();
    let widest = rays
        .iter()
        .flat_map(|a| rays.iter().map(move |b| a.1.dot(b.1)))
        .fold(1.0, f64::min);
    if widest > MIN_RAY_ANGLE_DEG.to_radians().cos() {
        return None;
    }
    let (p, _) = crate::region::nearest_point_to_lines(&rays)?;
    rays.iter().all(|(c, d)| (p - *c).dot(*d) > 0.0).then_some(p)
}

/// A plane `normal · p = offset` and the points near it.
#[derive(Clone, Debug)]
pub struct Plane {
    pub normal: Vec3<f64>,
    pub offset: f64,
    pub inliers: usize,
    /// RMS distance of the inliers from it (the reconstruction's units).
    pub rms: f64,
}

/// The plane most sparse points lie on (a table, a floor): RANSAC over point triples, then least squares on
/// the points within 1 % of the cloud's median radius of it; the normal turned toward the cameras.
pub fn dominant_plane(rec: &Reconstruction) -> Result<Plane, AlignError> {
    let pts = &rec.points;
    if pts.len() < 20 {
        return Err(AlignError(format!(
            "{} sparse points: finding the table's plane needs the reconstruction's points (20 or more)",
            pts.len()
        )));
    }
    let centroid = pts.iter().fold(Vec3::zero(), |s, &p| s + p) * (1.0 / pts.len() as f64);
    let mut radii: Vec<f64> = pts.iter().map(|p| (*p - centroid).norm()).collect();
    radii.sort_by(f64::total_cmp);
    let tolerance = 0.01 * radii[radii.len() / 2];
    let mut rng = SplitMix64::new(67);
    let mut best: Option<(usize, Vec3<f64>, f64)> = None;
    for _ in 0..500 {
        let pick = |r: &mut SplitMix64| pts[(r.next_u64() % pts.len() as u64) as usize];
        let (a, b, c) = (pick(&mut rng), pick(&mut rng), pick(&mut rng));
        let n = (b - a).cross(c - a);
        if n.norm() < 1e-12 {
            continue;
        }
        let n = n * (1.0 / n.norm());
        let d = n.dot(a);
        let count = pts.iter().filter(|p| (n.dot(**p) - d).abs() < tolerance).count();
        if best.as_ref().is_none_or(|b| count > b.0) {
            best = Some((count, n, d));
        }
    }
    let (_, mut normal, mut offset) = best.ok_or_else(|| AlignError("the sparse points are all on one line".into()))?;
    // Least squares on the inliers: the smallest direction of their scatter.
    let mut inliers: Vec<Vec3<f64>> = Vec::new();
    for _ in 0..3 {
        inliers = pts
            .iter()
            .copied()
            .filter(|p| (normal.dot(*p) - offset).abs() < tolerance)
            .collect();
        let mean = inliers.iter().fold(Vec3::zero(), |s, &p| s + p) * (1.0 / inliers.len() as f64);
        let mut m = [[0.0; 3]; 3];
        for p in &inliers {
            let q = (*p - mean).to_array();
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += q[i] * q[j];
                }
            }
        }
        let (values, vectors) = geom::symmetric_eigen(m);
        let k = (0..3).min_by(|&i, &j| values[i].total_cmp(&values[j])).expect("three");
        let n = Vec3::new(vectors[0][k], vectors[1][k], vectors[2][k]);
        normal = n * (1.0 / n.norm());
        offset = normal.dot(mean);
    }
    // The cameras are above the table.
    let above = rec
        .images
        .iter()
        .filter(|i| normal.dot(i.pose.inverse().t) > offset)
        .count();
    if 2 * above < rec.images.len() {
        normal = normal * -1.0;
        offset = -offset;
    }
    let rms = (inliers.iter().map(|p| (normal.dot(*p) - offset).powi(2)).sum::<f64>() / inliers.len() as f64).sqrt();
    Ok(Plane {
        normal,
        offset,
        inliers: inliers.len(),
        rms,
    })
}

impl Plane {
    /// Where the ray from `origin` along `direction` meets the plane, if ahead.
    pub fn meet(&self, origin: Vec3<f64>, direction: Vec3<f64>) -> Option<Vec3<f64>> {
        let along = self.normal.dot(direction);
        if along.abs() < 1e-12 {
            return None;
        }
        let t = (self.offset - self.normal.dot(origin)) / along;
        (t > 0.0).then(|| origin + direction * t)
    }

    /// The similarity putting this plane at z = 0 (normal +z), `centre` (a point of the reconstruction's
    /// world) over the origin, `x_hint`'s direction along the plane as +x, and `scale` metres per unit.
    pub fn world(&self, centre: Vec3<f64>, x_hint: Vec3<f64>, scale: f64) -> Similarity {
        let z = self.normal;
        let x = x_hint - z * z.dot(x_hint);
        let x = if x.norm() < 1e-9 {
            // Any direction in the plane.
            let a = if z.x.abs() < 0.9 {
                Vec3::new(1.0, 0.0, 0.0)
            } else {
                Vec3::new(0.0, 1.0, 0.0)
            };
            a - z * z.dot(a)
        } else {
            x
        };
        let x = x * (1.0 / x.norm());
        let y = z.cross(x);
        // Rows x, y, z: the new axes in the old world; the rotation old → new.
        let rotation = Quat::from_mat(&geom::Mat3::from_rows([x.to_array(), y.to_array(), z.to_array()])).unit();
        let on_plane = centre - z * (z.dot(centre) - self.offset);
        Similarity {
            scale,
            rotation,
            translation: rotation.rotate(on_plane) * -scale,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lens::Lens;
    use crate::reconstruction::RegisteredImage;
    use geom::Pose;

    /// A board seen by cameras in a world moved by a known similarity: aligning gives that similarity's
    /// inverse back, and a table of points gives its plane.
    #[test]
    fn board_and_plane_alignments_undo_a_known_similarity() {
        let board = Board::new(crate::BoardSpec {
            kind: crate::BoardKind::ArucoGrid,
            dictionary: "DICT_5X5_1000".into(),
            size: [4, 3],
            marker_length: 0.04,
            marker_separation: Some(0.01),
            square_length: None,
            legacy: false,
            first_id: 0,
        })
        .unwrap();
        let lens = Lens {
            fx: 600.0,
            fy: 600.0,
            cx: 319.5,
            cy: 239.5,
            distortion: [-0.2, 0.05, 0.001, -0.0005, 0.0],
        };
        let truth: Vec<Pose<f64>> = (0..5)
            .map(|i| {
                let a = i as f64 * 1.2;
                let eye = Vec3::new(0.4 * a.cos(), 0.4 * a.sin(), 0.35);
                let k = geom::Intrinsics::centred(600.0, 640, 480);
                geom::Camera::look_at(eye, Vec3::zero(), Vec3::new(0.0, 0.0, 1.0), k, 640, 480).world_to_cam
            })
            .collect();
        let secret = Similarity {
            scale: 7.3,
            rotation: Quat::exp(Vec3::new(0.4, 2.0, -1.1)),
            translation: Vec3::new(3.0, -2.0, 11.0),
        };
        let truth_rec = Reconstruction {
            images: truth
                .iter()
                .enumerate()
                .map(|(i, p)| RegisteredImage {
                    name: format!("{i}.png"),
                    width: 640,
                    height: 480,
                    lens,
                    pose: *p,
                })
                .collect(),
            points: (0..400)
                .map(|i| {
                    let (u, v) = ((i % 20) as f64 / 20.0 - 0.5, (i / 20) as f64 / 20.0 - 0.5);
                    // Three quarters on the table, the rest above it.
                    Vec3::new(0.6 * u, 0.6 * v, if i % 4 == 3 { 0.05 + 0.1 * u.abs() } else { 0.0 })
                })
                .collect(),
        };
        let rec = truth_rec.transformed(&inverse(&secret));
        let sightings: Vec<(usize, ViewPoints)> = truth
            .iter()
            .enumerate()
            .map(|(i, pose)| {
                let mut v = ViewPoints::default();
                for m in &board.markers {
                    for c in &m.corners {
                        let w = Vec3::from_array(board.to_world(*c));
                        v.board.push(*c);
                        v.image.push(lens.project(pose.transform_point(w)));
                    }
                }
                (i, v)
            })
            .collect();
        let a = align_to_board(&rec, &sightings, &board).unwrap();
        assert!(a.worst < 1e-9, "{a:?}");
        assert_eq!(a.points, 4 * board.markers.len());
        for (found, t) in rec.transformed(&a.similarity).images.iter().zip(&truth) {
            assert!((found.pose.inverse().t - t.inverse().t).norm() < 1e-9);
            assert!(geom::rotation_distance(found.pose.q, t.q) < 1e-9);
        }
        // Two views are not enough.
        assert!(align_to_board(&rec, &sightings[..2], &board).is_err());

        let plane = dominant_plane(&rec).unwrap();
        assert_eq!(plane.inliers, 300);
        // The reconstruction's world is the truth's moved by the secret's inverse.
        let back = inverse(&secret);
        let s = plane.world(
            back.apply(Vec3::zero()),
            back.rotation.rotate(Vec3::new(1.0, 0.0, 0.0)),
            secret.scale,
        );
        for (p, t) in rec.points.iter().zip(&truth_rec.points) {
            assert!((s.apply(*p) - *t).norm() < 1e-9, "{:?} {t:?}", s.apply(*p));
        }
    }

    fn inverse(s: &Similarity) -> Similarity {
        let r = s.rotation.conj();
        Similarity {
            scale: 1.0 / s.scale,
            rotation: r,
            translation: r.rotate(s.translation) * (-1.0 / s.scale),
        }
    }
}
