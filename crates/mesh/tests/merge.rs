//! Merging two partial reconstructions (the visible upper parts of one object
//! in two poses, each with a wrong guess underneath) gives a closed mesh
//! within 1 % of the object's diameter of the whole object, and recovers the
//! transform between the poses.
use crate::common;

use geom::{rotation_distance, Pose, Quat, TriMesh, Vec3};
use mesh::{
    chamfer, components, extract_zero_level, largest_component, merge_two_poses, sample_sdf_grid, MergeConfig,
    PartialSurface,
};
use sim::sdf::{Cuboid, Sdf, Shape};

/// An L-shaped block (no rotational symmetry), body frame.
fn l_shape() -> Shape {
    let base = Shape::Cuboid(Cuboid {
        half: [0.03, 0.02, 0.01],
    });
    let post = Shape::Cuboid(Cuboid {
        half: [0.01, 0.02, 0.015],
    })
    .transformed(Pose::from_translation(Vec3::new(0.02, 0.0, 0.02)));
    Shape::Union(vec![base, post])
}

/// [`l_shape`] meshed from its SDF.
fn l_block() -> TriMesh {
    let shape = l_shape();
    extract_zero_level(&common::grid_of(
        &shape,
        [-0.045, -0.035, -0.025],
        [0.045, 0.035, 0.05],
        150,
    ))
}

/// The merge with 6,000 points per cloud for ICP instead of 20,000 (`MergeConfig::default`): the nearest-point
/// searches are most of a merge's time, and these shapes are aligned as tightly with fewer.
fn small() -> MergeConfig {
    MergeConfig {
        icp_points: 6000,
        ..MergeConfig::default()
    }
}

/// The body resting on the board with orientation `q` (lowest point at z = 0).
fn rest(body: &TriMesh, q: Quat<f64>, xy: [f64; 2]) -> Pose<f64> {
    let low = body
        .vertices
        .iter()
        .map(|v| q.rotate(Vec3::cst(*v)).z)
        .fold(f64::INFINITY, f64::min);
    Pose::new(q, Vec3::new(xy[0], xy[1], -low))
}

fn posed(m: &TriMesh, p: &Pose<f64>) -> TriMesh {
    TriMesh::new(
        m.vertices
            .iter()
            .map(|v| p.transform_point(Vec3::cst(*v)).to_array())
            .collect(),
        m.faces.clone(),
    )
}

/// What NeuS gives for the unseen underside: a guess. Here: everything
/// within 4 mm of the board sags 3 mm through it.
fn wrong_underside(m: &TriMesh) -> TriMesh {
    let mut out = m.clone();
    for v in &mut out.vertices {
        if v[2] < 0.004 {
            v[2] -= 0.003;
        }
    }
    out
}

#[test]
fn merging_two_poses_gives_the_whole_object() {
    let body = l_block();
    sim::check_closed_mesh(&body).unwrap();
    let pose_a = rest(&body, Quat::identity(), [0.01, -0.02]);
    let pose_b = rest(
        &body,
        Quat::exp(Vec3::new(std::f64::consts::PI, 0.0, 0.0)) * Quat::exp(Vec3::new(0.0, 0.0, 0.5)),
        [0.03, 0.01],
    );
    let (true_a, true_b) = (posed(&body, &pose_a), posed(&body, &pose_b));
    let (rec_a, rec_b) = (wrong_underside(&true_a), wrong_underside(&true_b));
    let merged = merge_two_poses(
        &PartialSurface::from_mesh(rec_a).unwrap(),
        &PartialSurface::from_mesh(rec_b.clone()).unwrap(),
        &small(),
    )
    .unwrap();
    // The transform between the poses.
    let truth = pose_b.compose(&pose_a.inverse());
    let angle = rotation_distance(merged.a_to_b.q, truth.q).to_degrees();
    assert!(angle < 0.2, "rotation A→B off by {angle}°");
    assert!(
        (merged.a_to_b.t - truth.t).norm() < 3e-4,
        "translation A→B off by {:?}",
        merged.a_to_b.t - truth.t
    );
    // One closed mesh, close to the whole object (in B's frame).
    sim::check_closed_mesh(&merged.mesh).unwrap();
    let diameter = 2.0 * body.vertices.iter().map(|v| Vec3::cst(*v).norm()).fold(0.0, f64::max);
    let c = chamfer(&merged.mesh, &true_b, 20000, 1);
    assert!(
        c.mean < 0.01 * diameter,
        "Chamfer {:.3} mm vs 1 % of the diameter {:.3} mm",
        c.mean * 1e3,
        diameter * 10.0
    );
    // Each input alone is wrong underneath by more than the merge is.
    let alone = chamfer(&rec_b, &true_b, 20000, 1);
    assert!(
        alone.p95 > c.p95,
        "merge p95 {} should beat B alone {}",
        c.p95,
        alone.p95
    );
}

#[test]
fn unrelated_meshes_do_not_merge_silently() {
    let body = l_block();
    let a = posed(&body, &rest(&body, Quat::identity(), [0.0, 0.0]));
    let other = posed(
        &sim::tessellate::sphere_mesh(&sim::sdf::Sphere { radius: 0.05 }, 16),
        &Pose::from_translation(Vec3::new(0.0, 0.0, 0.05)),
    );
    let cfg = MergeConfig {
        max_residual: 2e-4,
        icp_points: 4000,
        ..small()
    };
    let err = merge_two_poses(
        &PartialSurface::from_mesh(a).unwrap(),
        &PartialSurface::from_mesh(other).unwrap(),
        &cfg,
    )
    .err()
    .expect("a block and a ball must not merge");
    assert!(err.to_string().contains("ICP did not converge"), "{err}");
}

/// A "field" of the object posed by `pose`: its exact distance, a wrong
/// underside (a slab filling the box's footprint up to 4 mm above the board,
/// as a visual hull from above would) and a floater in the L's notch.
fn guessed_field(
    shape: &Shape,
    pose: Pose<f64>,
    footprint: ([f64; 2], [f64; 2]),
) -> impl Fn(&[Vec3<f64>]) -> Vec<f64> + Sync {
    let (lo, hi) = footprint;
    let slab = Shape::Cuboid(Cuboid {
        half: [0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]), 0.0035],
    })
    .transformed(Pose::from_translation(Vec3::new(
        0.5 * (lo[0] + hi[0]),
        0.5 * (lo[1] + hi[1]),
        0.0005,
    )));
    let floater = Shape::Sphere(sim::sdf::Sphere { radius: 0.004 })
        .transformed(pose.compose(&Pose::from_translation(Vec3::new(-0.015, 0.0, 0.025))));
    let object = shape.clone().transformed(pose);
    move |pts: &[Vec3<f64>]| {
        pts.iter()
            .map(|p| {
                object
                    .distance_local(*p)
                    .min(slab.distance_local(*p))
                    .min(floater.distance_local(*p))
            })
            .collect()
    }
}

fn footprint(m: &TriMesh) -> ([f64; 2], [f64; 2]) {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for v in &m.vertices {
        for k in 0..2 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    (lo, hi)
}

#[test]
fn merging_two_fields_uses_their_distances_and_drops_floaters() {
    let body = l_block();
    let shape = l_shape();
    let pose_a = rest(&body, Quat::identity(), [0.0, 0.01]);
    let pose_b = rest(
        &body,
        Quat::exp(Vec3::new(std::f64::consts::PI, 0.0, 0.0)) * Quat::exp(Vec3::new(0.0, 0.0, -0.7)),
        [-0.02, 0.0],
    );
    let (true_a, true_b) = (posed(&body, &pose_a), posed(&body, &pose_b));
    let field_a = guessed_field(&shape, pose_a, footprint(&true_a));
    let field_b = guessed_field(&shape, pose_b, footprint(&true_b));
    let zero_level = |f: &(dyn Fn(&[Vec3<f64>]) -> Vec<f64> + Sync)| {
        let grid = sample_sdf_grid(
            &|pts: &[[f64; 3]]| {
                let v: Vec<Vec3<f64>> = pts.iter().map(|p| Vec3::cst(*p)).collect();
                f(&v).iter().map(|d| *d as f32).collect()
            },
            [-0.1, -0.1, -0.02],
            [0.1, 0.1, 0.08],
            96,
        );
        extract_zero_level(&grid)
    };
    let (zero_a, zero_b) = (zero_level(&field_a), zero_level(&field_b));
    assert!(
        components(&zero_b).len() >= 2,
        "the field's zero level should have the floater"
    );
    let merged = merge_two_poses(
        &PartialSurface::from_field(&zero_a, field_a).unwrap(),
        &PartialSurface::from_field(&zero_b, field_b).unwrap(),
        &small(),
    )
    .unwrap();
    let truth = pose_b.compose(&pose_a.inverse());
    let angle = rotation_distance(merged.a_to_b.q, truth.q).to_degrees();
    assert!(angle < 0.2, "rotation A→B off by {angle}°");
    assert!((merged.a_to_b.t - truth.t).norm() < 3e-4);
    sim::check_closed_mesh(&merged.mesh).unwrap();
    assert_eq!(components(&merged.mesh).len(), 1, "the floater should be gone");
    let diameter = 2.0 * body.vertices.iter().map(|v| Vec3::cst(*v).norm()).fold(0.0, f64::max);
    let c = chamfer(&merged.mesh, &true_b, 20000, 1);
    assert!(
        c.mean < 0.01 * diameter && c.p95 < 0.02 * diameter,
        "Chamfer mean {:.3} mm, p95 {:.3} mm (diameter {:.1} mm)",
        c.mean * 1e3,
        c.p95 * 1e3,
        diameter * 1e3
    );
    // B's field alone (its object piece) keeps the slab underneath.
    let alone = chamfer(&largest_component(&zero_b), &true_b, 20000, 1);
    assert!(alone.p95 > 2.0 * c.p95, "merge p95 {} vs B alone {}", c.p95, alone.p95);
}

/// Cameras around `look_at` from above the board, as a capture's.
fn ring_of_cameras(look_at: Vec3<f64>, count: usize) -> Vec<geom::Camera<f64>> {
    let k = geom::Intrinsics {
        fx: 300.0,
        fy: 300.0,
        cx: 160.0,
        cy: 120.0,
        skew: 0.0,
    };
    (0..count)
        .map(|i| {
            let elevation = [30.0f64, 50.0, 70.0][i % 3].to_radians();
            let azimuth = i as f64 * std::f64::consts::TAU / count as f64;
            let eye = look_at
                + Vec3::new(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                ) * 0.3;
            geom::Camera::look_at(eye, look_at, Vec3::new(0.0, 0.0, 1.0), k, 320, 240)
        })
        .collect()
}

/// A T-shaped post on the board (a stem with a wide cap at the top), seen by
/// cameras from above: the cap's top is seen by all, its underside (an
/// overhang high above the board) and the stem just under it by none, the
/// stem's foot and the cap's sides by some.
#[test]
fn cameras_see_the_top_but_not_under_an_overhang() {
    let stem = Shape::Cuboid(Cuboid {
        half: [0.005, 0.005, 0.02],
    })
    .transformed(Pose::from_translation(Vec3::new(0.0, 0.0, 0.02)));
    let cap = Shape::Cuboid(Cuboid {
        half: [0.025, 0.025, 0.004],
    })
    .transformed(Pose::from_translation(Vec3::new(0.0, 0.0, 0.04)));
    let t = Shape::Union(vec![stem, cap]);
    let sdf = |pts: &[Vec3<f64>]| -> Vec<f64> { pts.iter().map(|p| t.distance_local(*p)).collect() };
    let vis = mesh::visibility::Visibility::new(
        &sdf,
        [-0.04, -0.04, -0.005],
        [0.04, 0.04, 0.055],
        96,
        ring_of_cameras(Vec3::new(0.0, 0.0, 0.02), 24),
    );
    let seen = |x: [f64; 3]| vis.seen_fraction(Vec3::cst(x));
    assert_eq!(seen([0.01, 0.005, 0.044]), 1.0, "the cap's top");
    assert_eq!(seen([0.015, 0.01, 0.036]), 0.0, "under the cap, 3.6 cm above the board");
    assert_eq!(seen([0.005, 0.0, 0.03]), 0.0, "the stem just under the cap");
    let foot = seen([0.005, 0.0, 0.002]);
    assert!(
        foot > 0.0 && foot < 0.5,
        "the stem's foot, seen by low cameras only: {foot}"
    );
    let side = seen([0.025, 0.0, 0.04]);
    assert!(side > 0.1 && side < 0.9, "the cap's side: {side}");
    // The board hides what is below it.
    assert_eq!(seen([0.0, 0.0, -0.001]), 0.0);
}

/// A box is the same shape upright and turned over, so ICP fits A to B as
/// well unturned: then both guessed undersides would meet and stay. The merge
/// picks the alignment that brings A's hidden side into B's view. A box on a
/// square footprint (the two-body scene's block) fits upright four ways, each
/// better than any turned-over one: those must be tried too.
#[test]
fn a_symmetric_box_is_turned_over_not_left_as_is() {
    for half in [[0.03, 0.022, 0.018], [0.025, 0.025, 0.02]] {
        box_turned_over(half);
    }
}

fn box_turned_over(half: [f64; 3]) {
    let shape = Shape::Cuboid(Cuboid { half });
    // A margin of about a fifth of each side around the box (a finer grid along the short sides).
    let pad = [0.01, 0.008, 0.007];
    let body = extract_zero_level(&common::grid_of(
        &shape,
        [0, 1, 2].map(|k| -half[k] - pad[k]),
        [0, 1, 2].map(|k| half[k] + pad[k]),
        120,
    ));
    let pose_a = rest(&body, Quat::identity(), [0.0, 0.0]);
    let pose_b = rest(&body, Quat::exp(Vec3::new(std::f64::consts::PI, 0.0, 0.0)), [0.0, 0.0]);
    let (true_a, true_b) = (posed(&body, &pose_a), posed(&body, &pose_b));
    let (rec_a, rec_b) = (wrong_underside(&true_a), wrong_underside(&true_b));
    let merged = merge_two_poses(
        &PartialSurface::from_mesh(rec_a).unwrap(),
        &PartialSurface::from_mesh(rec_b.clone()).unwrap(),
        &MergeConfig {
            resolution: 96,
            ..small()
        },
    )
    .unwrap();
    let r = merged.a_to_b.q.to_mat();
    assert!(
        r.m[2][2] < -0.99,
        "{half:?}: A should be turned over onto B: R = {:?}",
        r.m
    );
    let (c, alone) = (
        chamfer(&merged.mesh, &true_b, 20000, 1),
        chamfer(&rec_b, &true_b, 20000, 1),
    );
    assert!(
        c.p95 < 0.5 * alone.p95,
        "{half:?}: merged p95 {:.3} mm vs B alone {:.3} mm",
        c.p95 * 1e3,
        alone.p95 * 1e3
    );
}

/// Turned over about x or about y, a box shows the same shape: only its
/// colours tell which. Each part paints the box by body coordinates (a
/// pattern no half-turn maps onto itself); the merge must find each pose's
/// own turn, however B was turned.
#[test]
fn a_symmetric_box_is_turned_over_the_way_its_colours_agree() {
    let shape = Shape::Cuboid(Cuboid {
        half: [0.03, 0.022, 0.018],
    });
    let body = extract_zero_level(&common::grid_of(
        &shape,
        [-0.04, -0.03, -0.025],
        [0.04, 0.03, 0.025],
        120,
    ));
    let paint = |p: Vec3<f64>| {
        [
            0.5 + 0.5 * (60.0 * p.x).sin(),
            0.5 + 0.5 * (45.0 * p.y + 0.7).sin(),
            0.5 + 10.0 * p.x * p.y,
        ]
    };
    let pose_a = rest(&body, Quat::identity(), [0.0, 0.0]);
    for axis in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)] {
        let pose_b = rest(&body, Quat::exp(axis * std::f64::consts::PI), [0.0, 0.0]);
        let (rec_a, rec_b) = (
            wrong_underside(&posed(&body, &pose_a)),
            wrong_underside(&posed(&body, &pose_b)),
        );
        let colour_of = |pose: Pose<f64>| {
            move |pts: &[Vec3<f64>], _: &[Vec3<f64>]| -> Vec<[f64; 3]> {
                pts.iter().map(|p| paint(pose.inverse_transform_point(*p))).collect()
            }
        };
        let merged = merge_two_poses(
            &PartialSurface::from_mesh(rec_a).unwrap().with_colour(colour_of(pose_a)),
            &PartialSurface::from_mesh(rec_b).unwrap().with_colour(colour_of(pose_b)),
            &MergeConfig {
                resolution: 64,
                ..small()
            },
        )
        .unwrap();
        let truth = pose_b.compose(&pose_a.inverse());
        let off = rotation_distance(merged.a_to_b.q, truth.q).to_degrees();
        assert!(
            off < 2.0,
            "turned about {axis:?}: the merge's turn is {off:.1}° from the truth"
        );
    }
}
