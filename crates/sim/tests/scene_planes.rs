//! A scene grid's planes made exact (`SdfGrid::with_planes`): on a reconstruction-like grid of the
//! tabletop's wall on the board (the foot rounded into a fillet, the faces rough by 0.3 mm), the planes are
//! found, the roughness and the fillet go, and what is not a plane or a fillet stays.
use crate::common;
use common::*;
use geom::Vec3;
use sim::sdf::{PlaneSettings, RoundedBox, SdfGrid, Shape};
use sim::BodyState;
use std::sync::Arc;

const SPACING: f64 = 0.0035;
const LO: [f64; 3] = [-0.16, -0.2, -0.02];
const HI: [f64; 3] = [0.32, 0.2, 0.1];
/// The wall's front face, x; the wall is 40 mm thick, 240 mm long and 70 mm tall.
const FACE: f64 = 0.2;

fn wall(p: Vec3<f64>) -> f64 {
    wall_of(0.02, p)
}

/// The wall with `half_thickness`, its front face at `FACE`.
fn wall_of(half_thickness: f64, p: Vec3<f64>) -> f64 {
    let (c, half) = ([FACE + half_thickness, 0.0, 0.035], [half_thickness, 0.12, 0.035]);
    let q: [f64; 3] = std::array::from_fn(|a| (p[a] - c[a]).abs() - half[a]);
    let outside = q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
    outside + q[0].max(q[1]).max(q[2]).min(0.0)
}

/// The true scene: the board (solid below z = 0) and the wall, with a sharp foot.
fn sharp(p: Vec3<f64>) -> f64 {
    p.z.min(wall(p))
}

/// As a reconstruction has it: the foot filled by a smooth minimum (its middle 4 mm off each face, the fillet
/// meeting the faces 16 mm from the corner), every surface rough by 0.3 mm.
fn reconstructed(p: Vec3<f64>) -> f64 {
    reconstructed_with(wall, p)
}

fn reconstructed_with(wall: impl Fn(Vec3<f64>) -> f64, p: Vec3<f64>) -> f64 {
    let (a, b, k) = (p.z, wall(p), 0.016);
    let blend = (k - (a - b).abs()).max(0.0) / k;
    let rough = 3e-4 * ((p.x * 700.0).sin() * (p.y * 530.0).sin() + (p.z * 610.0).sin() * (p.x * 410.0).cos());
    a.min(b) - blend * blend * k / 4.0 + rough
}

fn grid_of(f: impl Fn(Vec3<f64>) -> f64) -> SdfGrid {
    let dims: [usize; 3] = std::array::from_fn(|a| ((HI[a] - LO[a]) / SPACING).ceil() as usize + 1);
    let mut values = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = Vec3::new(
                    LO[0] + i as f64 * SPACING,
                    LO[1] + j as f64 * SPACING,
                    LO[2] + k as f64 * SPACING,
                );
                values.push(f(p) as f32);
            }
        }
    }
    SdfGrid::from_values(LO, SPACING, dims, values).unwrap()
}

/// Each node's position with its value in `g` and in `other` (a grid of the same dimensions).
fn nodes<'a>(g: &'a SdfGrid, other: &'a SdfGrid) -> impl Iterator<Item = (Vec3<f64>, f64, f64)> + 'a {
    let [nx, ny, _] = g.dims();
    g.values()
        .iter()
        .zip(other.values())
        .enumerate()
        .map(move |(idx, (&v, &w))| {
            let (i, j, k) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
            let p = Vec3::new(
                LO[0] + i as f64 * SPACING,
                LO[1] + j as f64 * SPACING,
                LO[2] + k as f64 * SPACING,
            );
            (p, v as f64, w as f64)
        })
}

/// The largest |grid − truth| over the nodes `which` picks.
fn worst(g: &SdfGrid, truth: impl Fn(Vec3<f64>) -> f64, which: impl Fn(Vec3<f64>) -> bool) -> f64 {
    nodes(g, g)
        .filter(|&(p, _, _)| which(p))
        .map(|(p, v, _)| (v - truth(p)).abs())
        .fold(0.0, f64::max)
}

/// In the wedge in front of the wall's foot, within 12 mm of it, away from the wall's ends.
fn at_the_foot(p: Vec3<f64>) -> bool {
    p.z > 0.0 && p.x < FACE && p.z.hypot(FACE - p.x) < 0.012 && p.y.abs() < 0.1
}

#[test]
fn a_filleted_rough_wall_foot_is_made_sharp_and_its_planes_exact() {
    let raw = grid_of(reconstructed);
    let (g, report) = raw.with_planes(&PlaneSettings::default(), 1.5);
    let has = |n: [f64; 3], offset: f64| {
        report
            .planes
            .iter()
            .any(|p| p.normal.dot(Vec3::cst(n)) > 0.999 && (p.offset - offset).abs() < 5e-4)
    };
    assert!(has([0.0, 0.0, 1.0], 0.0), "the board not found: {:?}", report.planes);
    assert!(
        has([-1.0, 0.0, 0.0], -FACE),
        "the wall's face not found: {:?}",
        report.planes
    );
    let foot = report
        .creases
        .iter()
        .find(|c| {
            c.planes
                .iter()
                .all(|&i| report.planes[i].normal.x < -0.99 || report.planes[i].normal.z > 0.99)
        })
        .expect("the wall's foot is a crease");
    assert!(foot.length > 0.2 && foot.blocked == 0.0, "{foot:?}");
    // The premise: the reconstruction, blurred as a bake does, is millimetres off at the foot.
    let before = worst(&raw.smoothed(1.5), sharp, at_the_foot);
    let after = worst(&g, sharp, at_the_foot);
    assert!(before > 3e-3, "the fillet is only {:.2} mm deep", before * 1e3);
    assert!(
        after < 5e-4,
        "the foot is {:.2} mm off after the planes (before {:.2})",
        after * 1e3,
        before * 1e3
    );
    // The board near the toy's path is its plane's distance again: the roughness gone.
    let board = |p: Vec3<f64>| p.z.abs() < 0.006 && p.x < 0.1 && p.x > -0.1 && p.y.abs() < 0.1;
    assert!(worst(&raw, sharp, board) > 2.5e-4, "the premise: a rough board");
    assert!(
        worst(&g, sharp, board) < 1e-4,
        "the board is {:.3} mm off",
        worst(&g, sharp, board) * 1e3
    );
}

/// A block standing in the corner is not a fillet: the corner is left alone where it stands (and sharpened
/// beside it), and a sphere resting on the board, curved, keeps the blurred field.
#[test]
fn what_stands_in_the_corner_and_what_is_curved_are_kept() {
    let block = |p: Vec3<f64>| {
        let (c, half) = ([FACE - 0.0125, 0.05, 0.0125], 0.0125);
        let q: [f64; 3] = std::array::from_fn(|a| (p[a] - c[a]).abs() - half);
        q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt() + q[0].max(q[1]).max(q[2]).min(0.0)
    };
    let ball = |p: Vec3<f64>| (p - Vec3::new(-0.05, 0.0, 0.03)).norm() - 0.03;
    let raw = grid_of(|p| reconstructed(p).min(block(p)).min(ball(p)));
    let (g, report) = raw.with_planes(&PlaneSettings::default(), 1.5);
    let foot = report
        .creases
        .iter()
        .find(|c| c.planes.iter().any(|&i| report.planes[i].normal.x < -0.99))
        .expect("the wall's foot is a crease");
    assert!(foot.blocked > 0.0 && foot.length > 0.15, "{foot:?}");
    let at = |p: [f64; 3]| {
        let [nx, ny, _] = g.dims();
        let ijk: [usize; 3] = std::array::from_fn(|a| ((p[a] - LO[a]) / SPACING).round() as usize);
        g.values()[ijk[0] + nx * (ijk[1] + ny * ijk[2])] as f64
    };
    // The block's inside stays solid, its corner nearest the wall's foot too.
    // The block stays as solid as the blur leaves it: no node inside it deeper than the snap's slack (twice
    // the tolerance: nearer the board, the board's plane decides) above the blurred field's value, and its
    // middle is the blurred field's.
    let blurred = raw.smoothed(1.5);
    let inside = |p: Vec3<f64>| block(p) < -2.5e-3;
    let opened = nodes(&g, &blurred).filter(|&(p, v, b)| inside(p) && v > b).count();
    assert_eq!(opened, 0, "nodes inside the block opened beyond the blur");
    let centre = [FACE - 0.0125, 0.05, 0.0125];
    assert_eq!(at(centre), {
        let [nx, ny, _] = blurred.dims();
        let ijk: [usize; 3] = std::array::from_fn(|a| ((centre[a] - LO[a]) / SPACING).round() as usize);
        blurred.values()[ijk[0] + nx * (ijk[1] + ny * ijk[2])] as f64
    });
    // Beside it the foot is sharp.
    let away = |p: Vec3<f64>| at_the_foot(p) && (p.y - 0.05).abs() > 0.04;
    assert!(
        worst(&g, sharp, away) < 5e-4,
        "the foot beside the block: {:.2} mm",
        worst(&g, sharp, away) * 1e3
    );
    // The ball, beyond the board's snapping band (three spacings), is the blurred field's, node for node;
    // nearer the board, its inside stays inside.
    let differ =
        |which: &dyn Fn(Vec3<f64>, f64, f64) -> bool| nodes(&g, &blurred).filter(|&(p, v, b)| which(p, v, b)).count();
    let on_ball = |p: Vec3<f64>| ball(p).abs() < 0.005 && p.z > 3.0 * SPACING;
    assert_eq!(differ(&|p, v, b| on_ball(p) && v != b), 0, "the ball changed");
    assert_eq!(
        differ(&|p, v, _| ball(p) < -1e-3 && v >= 0.0),
        0,
        "the ball's base opened"
    );
}

/// Nothing is made solid (deeper than the planes' tolerance) where both the reconstruction and the truth are
/// free space: beyond the ends of a
/// wall too thin for its ends to be planes (8 mm), where the foot's crease runs out and the board's nodes lie
/// behind the face's plane.
#[test]
fn no_solid_is_added_where_the_field_has_none() {
    // Shifted 2 mm along the crease, so one end falls 8 mm inside one of the crease's 10 mm stretches.
    let thin = |p: Vec3<f64>| wall_of(0.004, p - Vec3::new(0.0, 0.002, 0.0));
    let raw = grid_of(|p| reconstructed_with(thin, p));
    let sharp = |p: Vec3<f64>| p.z.min(thin(p));
    let (g, report) = raw.with_planes(&PlaneSettings::default(), 1.5);
    assert!(
        report.creases.iter().any(|c| c.length > 0.2),
        "the premise: the foot is a crease: {report}"
    );
    // Within the tolerance a plane may move the zero level (the snap): no more.
    let tolerance = PlaneSettings::default().tolerance;
    let added: Vec<_> = nodes(&g, &raw)
        .filter(|&(p, v, r)| r > 0.0 && sharp(p) > 0.0 && v < -tolerance)
        .collect();
    assert!(
        added.is_empty(),
        "{} nodes made solid, e.g. {:?}",
        added.len(),
        added.first()
    );
}

/// The point of it: a box (its edges rounded by 5 mm, as the tabletop's toy) sliding on the board into the
/// wall. In the reconstruction's grid (blurred, as a bake makes it) the fillet kicks it up and it does not
/// bounce as it does off the true scene; with the planes made exact it moves as in the true scene's grid.
#[test]
fn a_box_slides_into_the_sharpened_wall_as_into_the_true_one() {
    let half = [0.03, 0.022, 0.018];
    let run = |scene: SdfGrid| {
        let w = world_with(
            config_in(sim::ContactModel::MeanPoint, 30.0, 20, 20),
            Shape::Grid(Arc::new(scene)),
            vec![(
                sim::RigidBody::from_shape(
                    "toy",
                    &Shape::RoundedBox(RoundedBox { half, radius: 0.005 }),
                    sim::MassSpec::Mass(0.08),
                    sim::ContactSampling::Surface { count: 1000, seed: 7 },
                )
                .unwrap(),
                BodyState::new(
                    [FACE - half[0] - 0.06, 0.0, half[2]],
                    [1.0, 0.0, 0.0, 0.0],
                    [0.8, 0.0, 0.0],
                    [0.0; 3],
                ),
                contact(0.5, 0.25),
            )],
        );
        w.simulate(&w.params()).frames.iter().map(|f| f[0]).collect::<Vec<_>>()
    };
    let truth = run(grid_of(sharp));
    let raw = grid_of(reconstructed);
    let off = |states: &[BodyState<f64>]| {
        states
            .iter()
            .zip(&truth)
            .map(|(s, t)| (s.pose.t - t.pose.t).norm())
            .fold(0.0, f64::max)
    };
    assert!(
        truth.iter().any(|s| s.v.x < -0.1),
        "the premise: the box bounces off the true wall"
    );
    let blurred = off(&run(raw.smoothed(1.5)));
    let planes = off(&run(raw.with_planes(&PlaneSettings::default(), 1.5).0));
    assert!(
        blurred > 5e-3,
        "the premise: the fillet moves the box {:.2} mm",
        blurred * 1e3
    );
    assert!(
        planes < 1e-3,
        "with the planes the box is {:.2} mm off the truth's (blurred {:.2})",
        planes * 1e3,
        blurred * 1e3
    );
}

/// A grid with no plane in it (a ball floating in the air) is the blurred grid, node for node.
#[test]
fn a_grid_without_planes_is_only_blurred() {
    let raw = grid_of(|p| (p - Vec3::new(0.08, 0.0, 0.04)).norm() - 0.05);
    let (g, report) = raw.with_planes(&PlaneSettings::default(), 1.5);
    assert!(report.planes.is_empty(), "{report}");
    assert_eq!(g, raw.smoothed(1.5));
}

/// How far a textured board's squares stand proud as NeuS reads them: a checker of 20 mm squares, flat-topped
/// at 0 and 2 mm.
fn checker_relief(p: Vec3<f64>) -> f64 {
    let s = (p.x * std::f64::consts::PI / 0.02).sin() * (p.y * std::f64::consts::PI / 0.02).sin();
    1.0e-3 * (1.0 + (4.0 * s).tanh())
}

/// A board whose texture NeuS read as relief (flat-topped squares 2 mm proud, as a 1,500-step scene's board)
/// is one plane, not two, and flat: the squares are its relief, flattened by its snap (snapped to two planes
/// 1.7 mm apart, the board became steps; eased only part of the way, a body hopped on them).
#[test]
fn a_board_with_raised_squares_is_one_flat_plane() {
    let raw = grid_of(|p| reconstructed(p) - checker_relief(p));
    let (g, report) = raw.with_planes(&PlaneSettings::default(), 1.5);
    let boards: Vec<_> = report
        .planes
        .iter()
        .filter(|p| p.normal.z > 0.99 && p.offset.abs() < 0.01)
        .collect();
    assert_eq!(boards.len(), 1, "{report}");
    // The plane lies between the two levels, 1 mm from each (the roughness on top), and leans with the cut of
    // its points at the tolerance (measured 0.35°; the flatness below is against the plane found).
    assert!(boards[0].relief > 1e-3, "{report}");
    assert!(boards[0].normal.z > 1e-2f64.cos(), "leans more than 0.57°: {report}");
    // Over the board, away from the wall, the nodes within 8 mm of it hold the plane's distance.
    let (n, off) = (boards[0].normal, boards[0].offset);
    let plane = |p: Vec3<f64>| n.dot(p) - off;
    let near = |p: Vec3<f64>| p.z > -0.004 && p.z < 0.008 && p.x.abs() < 0.1 && p.y.abs() < 0.1;
    let (before, after) = (worst(&raw, plane, near), worst(&g, plane, near));
    assert!(
        before > 1.5e-3 && after < 1e-4,
        "the board {:.2} mm off its plane, the field {:.2}; {report}",
        after * 1e3,
        before * 1e3
    );
}

/// On that board a can standing upright keeps its base: the relief's squares beside it are flattened (the
/// field above the relief is free), the solid at its foot is not cut away (the field above the relief is
/// the can's solid), however near the board.
#[test]
fn a_can_standing_on_a_board_with_relief_keeps_its_base() {
    // 30 mm across, 60 mm tall, from 10 mm into the board (its field inside near the board is the distance to
    // its side, as a union's).
    let can = |p: Vec3<f64>| {
        let (r, h) = (
            Vec3::new(p.x + 0.05, p.y, 0.0).norm() - 0.015,
            (p.z - 0.025).abs() - 0.035,
        );
        r.max(h).min(0.0) + Vec3::new(r.max(0.0), h.max(0.0), 0.0).norm()
    };
    let raw = grid_of(|p| (reconstructed(p) - checker_relief(p)).min(can(p)));
    let (g, report) = raw.with_planes(&PlaneSettings::default(), 1.5);
    let board = report
        .planes
        .iter()
        .find(|p| p.normal.z > 0.99 && p.offset.abs() < 0.01)
        .expect("the board is a plane");
    assert!(board.relief > 1e-3, "{report}");
    // Within the tolerance a plane may move the zero level (the snap): no more.
    let tolerance = PlaneSettings::default().tolerance;
    let cut: Vec<_> = nodes(&g, &raw)
        .filter(|&(p, v, _)| can(p) < -tolerance && p.z < 0.01 && v >= 0.0)
        .collect();
    assert!(
        cut.is_empty(),
        "the can's foot cut at {} nodes, e.g. {:?}",
        cut.len(),
        cut.first()
    );
    // Beside it the board is flat.
    let (n, off) = (board.normal, board.offset);
    let beside = |p: Vec3<f64>| p.z.abs() < 0.004 && can(p) > 0.01 && p.x.abs() < 0.1 && p.y.abs() < 0.1;
    let flat = worst(&g, |p| n.dot(p) - off, beside);
    assert!(
        flat < 1e-4,
        "the board beside the can {:.2} mm off its plane",
        flat * 1e3
    );
}
