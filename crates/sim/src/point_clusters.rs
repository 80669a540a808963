//! A body's contact points grouped by place, so contact detection can rule out
//! a whole group with one query of the other surface: the other surface's
//! lower bound over the group's ball ([`crate::sdf::Sdf::lower_bound_in_ball`])
//! above the contact threshold means no point of the group is near. A body
//! resting on a board has most of its points well above it; without the groups
//! every point's distance was queried every substep, which was most of a
//! simulation's time.

use geom::Vec3;

/// Points per cluster at most: small enough that a cluster near the other surface holds few points that are
/// not, large enough that the clusters' own queries stay few (a 1,000-point body: about 64).
pub const CLUSTER_POINTS: usize = 16;

/// Points of a body (indices into its contact points) inside a ball (body frame).
#[derive(Clone, Debug)]
pub struct PointCluster {
    pub centre: Vec3<f64>,
    pub radius: f64,
    pub members: Vec<u32>,
}

/// `points` split in halves at the median of the widest side of their box, until each part holds at most
/// [`CLUSTER_POINTS`]; each part's ball is centred on its box.
pub fn cluster_points(points: &[Vec3<f64>]) -> Vec<PointCluster> {
    let mut clusters = Vec::new();
    let mut parts = vec![(0..points.len() as u32).collect::<Vec<u32>>()];
    while let Some(mut part) = parts.pop() {
        if part.is_empty() {
            continue;
        }
        let (lo, hi) = geom::bounding_box(part.iter().map(|&i| points[i as usize].to_array()));
        let (lo, hi) = (Vec3::cst(lo), Vec3::cst(hi));
        let centre = (lo + hi) * 0.5;
        if part.len() <= CLUSTER_POINTS {
            let radius = part
                .iter()
                .map(|&i| (points[i as usize] - centre).norm())
                .fold(0.0, f64::max);
            clusters.push(PointCluster {
                centre,
                radius,
                members: part,
            });
            continue;
        }
        let side = hi - lo;
        let axis = if side.x >= side.y && side.x >= side.z {
            0
        } else if side.y >= side.z {
            1
        } else {
            2
        };
        let half = part.len() / 2;
        part.select_nth_unstable_by(half, |&a, &b| {
            points[a as usize].to_array()[axis].total_cmp(&points[b as usize].to_array()[axis])
        });
        let upper = part.split_off(half);
        parts.push(part);
        parts.push(upper);
    }
    clusters
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_point_is_in_one_cluster_whose_ball_holds_it() {
        let mut rng = geom::SplitMix64::new(3);
        let points: Vec<Vec3<f64>> = (0..1000).map(|_| rng.in_box([0.0; 3], [0.06, 0.05, 0.04])).collect();
        let clusters = cluster_points(&points);
        let mut seen = vec![0; points.len()];
        for c in &clusters {
            assert!(!c.members.is_empty() && c.members.len() <= CLUSTER_POINTS);
            for &i in &c.members {
                seen[i as usize] += 1;
                assert!((points[i as usize] - c.centre).norm() <= c.radius);
            }
        }
        assert!(seen.iter().all(|&n| n == 1));
        assert!(clusters.len() <= 2 * points.len().div_ceil(CLUSTER_POINTS));
        assert!(cluster_points(&[]).is_empty());
    }

    /// Two boxes thrown spinning at each other over a baked scene whose values are not a distance (a board
    /// with a bump, the values scaled by 1.5): with the clusters, every frame and contact is what testing
    /// every point gives, bit for bit, for both contact models and through the dual numbers.
    #[test]
    fn detection_by_clusters_finds_what_every_point_finds() {
        use crate::sdf::{Cuboid, Plane, Sdf, SdfGrid, Shape, Sphere};
        use crate::{BodyState, ContactModel, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};
        use std::sync::Arc;
        let shapes = Shape::Union(vec![
            Shape::Plane(Plane {
                normal: [0.0, 0.0, 1.0],
                offset: 0.0,
            }),
            Shape::Sphere(Sphere { radius: 0.03 })
                .transformed(geom::Pose::from_translation(Vec3::new(0.1, 0.0, -0.015))),
        ]);
        let baked = SdfGrid::bake(&shapes, [-0.3, -0.3, -0.05], [0.4, 0.3, 0.1], 0.004).unwrap();
        let scaled = baked.values().iter().map(|v| 1.5 * v).collect();
        let scene = SdfGrid::from_values(baked.origin(), baked.spacing(), baked.dims(), scaled).unwrap();
        let body = |seed| {
            RigidBody::from_shape(
                "box",
                &Shape::Cuboid(Cuboid {
                    half: [0.03, 0.025, 0.02],
                }),
                MassSpec::Mass(0.2),
                ContactSampling::Surface { count: 400, seed },
            )
            .unwrap()
        };
        let c = ContactParams {
            restitution: 0.5,
            friction: 0.3,
        };
        for model in [ContactModel::MeanPoint, ContactModel::MultiPoint] {
            let mut w = World::new(
                SimConfig {
                    fps: 30.0,
                    frames: 25,
                    substeps: 10,
                    contact_model: model,
                    ..SimConfig::default()
                },
                Shape::Grid(Arc::new(scene.clone())),
            );
            let q = geom::Quat::exp(Vec3::new(0.3, 0.2, 0.1)).to_array_re();
            w.add_body(
                body(1),
                BodyState::new([-0.1, 0.0, 0.06], q, [1.2, 0.0, 0.3], [3.0, -2.0, 4.0]),
                c,
                c,
            );
            w.add_body(
                body(2),
                BodyState::new([0.15, 0.02, 0.03], [1.0, 0.0, 0.0, 0.0], [-0.6, 0.0, 0.0], [0.0; 3]),
                c,
                c,
            );
            let mut every_point = w.clone();
            for b in &mut every_point.bodies {
                b.point_clusters = vec![PointCluster {
                    centre: Vec3::zero(),
                    radius: 1e3,
                    members: (0..b.contact_points.len() as u32).collect(),
                }];
            }
            let p = w.params();
            let (a, b) = (w.simulate(&p), every_point.simulate(&p));
            assert_eq!(format!("{:?}", a.frames), format!("{:?}", b.frames), "{model:?}");
            assert_eq!(format!("{:?}", a.contacts), format!("{:?}", b.contacts), "{model:?}");
            assert!(
                a.contacts.iter().any(|f| f.scene.iter().any(|&s| s)),
                "{model:?}: no scene contact"
            );
            assert!(a.contacts.iter().any(|f| f.pairs[0]), "{model:?}: the boxes never met");
            let wrt: Vec<usize> = (0..p.len()).collect();
            let (ga, gb) = (
                crate::simulate_with_gradients(&w, &p, &wrt),
                crate::simulate_with_gradients(&every_point, &p, &wrt),
            );
            assert_eq!(format!("{ga:?}"), format!("{gb:?}"), "{model:?}: gradients");
            // The clusters did spare queries: at the end, the first box has clusters far from the scene.
            let t = a.frames.last().unwrap()[0].pose;
            let far = w.bodies[0]
                .point_clusters
                .iter()
                .filter(|k| {
                    let centre = t.transform_point(k.centre);
                    w.scene.lower_bound_in_ball(centre, k.radius) > w.config.contact_threshold
                })
                .count();
            assert!(far > 0, "{model:?}: no cluster was passed over");
        }
    }
}
