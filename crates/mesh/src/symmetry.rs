//! The proper symmetries of a closed surface: the rigid motions of its own
//! frame that map it onto itself (a box on a square footprint has eight, a
//! brick four, a shape without symmetry only the identity). A pose of a
//! symmetric body is right up to them: the body turned a quarter about its
//! square face shows the same surface, and a rotation error should be able to
//! say so. Found by aligning the surface to itself from every pairing of its
//! principal axes ([`icp_hypotheses`]) and keeping the alignments that fit as
//! well as two samples of the same surface fit each other. A body of
//! revolution (a ball, a can) has infinitely many: at most 60 are kept, so its
//! rotation error up to them is an upper bound (ADD-S is the measure for it).

use crate::icp::{icp, icp_hypotheses, IcpConfig, IcpTarget};
use geom::{rotation_distance, Pose, TriMesh, Vec3};
use sim::sample_surface::{sample_surface, sample_surface_with_normals};

/// A self-alignment is a symmetry when its point-to-plane residual is within this factor of the
/// identity's: two independent samples of one surface do not fit each other exactly either (points near
/// an edge find their nearest neighbour across it), and a true symmetry maps one sample onto another just
/// as good. A near-symmetry (a 50 × 50 × 40 mm box turned onto its 40 mm side) misses by millimetres.
const RESIDUAL_FACTOR: f64 = 1.5;

/// Below this share of the surface's size the residual is rounding, not shape.
const RESIDUAL_FLOOR: f64 = 1e-4;

/// Two alignments closer than this are the same symmetry.
const SAME_ANGLE_RAD: f64 = 0.035;

/// The largest finite group of rotations a closed body can have (an icosahedron's): closing the found set
/// under composition stops here whatever it found.
const LARGEST_GROUP: usize = 60;

/// The surface's proper symmetries, the identity first, each as the rigid motion `S` of the body frame
/// with `S(surface) = surface` (a rotation about the surface's centre: its translation is
/// `c − R c`). Found from `count` points sampled with `seed`.
pub fn proper_symmetries(mesh: &TriMesh, count: usize, seed: u64) -> Vec<Pose<f64>> {
    let mut found = vec![Pose::identity()];
    if mesh.faces.is_empty() || count < 3 {
        return found;
    }
    let (points, normals): (Vec<Vec3<f64>>, Vec<Vec3<f64>>) =
        sample_surface_with_normals(mesh, count, seed).into_iter().unzip();
    let centre = points.iter().fold(Vec3::zero(), |a, p| a + *p) * (1.0 / points.len() as f64);
    let size = points.iter().map(|p| (*p - centre).norm()).fold(0.0, f64::max);
    let target = IcpTarget::new(points, normals);
    let source = sample_surface(mesh, count, seed.wrapping_add(0x9e37_79b9));
    // Every pair counts: a trimmed fit would forgive the part of a near-symmetry that misses.
    let cfg = IcpConfig {
        keep_fraction: 1.0,
        ..IcpConfig::default()
    };
    let own = icp(&source, &target, Pose::identity(), &cfg, cfg.iterations).residual;
    let limit = (RESIDUAL_FACTOR * own).max(RESIDUAL_FLOOR * size);
    let add = |found: &mut Vec<Pose<f64>>, s: Pose<f64>| {
        let new = !found.iter().any(|f| rotation_distance(f.q, s.q) < SAME_ANGLE_RAD);
        if new {
            found.push(s);
        }
        new
    };
    for start in icp_hypotheses(&source, &target, &cfg) {
        let fit = icp(&source, &target, start.transform, &cfg, cfg.iterations);
        if fit.residual <= limit {
            add(&mut found, fit.transform);
        }
    }
    // Where the principal axes are arbitrary (a cube's, a square box's in its square) the starts miss
    // some symmetries; they form a group, so the products of those found give the rest.
    let mut grew = true;
    while grew && found.len() < LARGEST_GROUP {
        grew = false;
        for i in 0..found.len() {
            for j in 0..found.len() {
                let product = found[i].compose(&found[j]);
                grew |= add(&mut found, product);
            }
        }
    }
    found.truncate(LARGEST_GROUP);
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::sdf::{Cuboid, RoundedBox, Wedge};
    use sim::tessellate::{cuboid_mesh, rounded_box_mesh, wedge_mesh};

    #[test]
    fn boxes_have_the_symmetries_of_their_sides_and_a_wedge_none() {
        let cube = cuboid_mesh(&Cuboid { half: [0.02; 3] }, 1);
        let square = cuboid_mesh(
            &Cuboid {
                half: [0.025, 0.025, 0.02],
            },
            1,
        );
        let brick = rounded_box_mesh(
            &RoundedBox {
                half: [0.03, 0.022, 0.018],
                radius: 0.005,
            },
            8,
        );
        let wedge = wedge_mesh(&Wedge {
            half: [0.06, 0.05, 0.02],
        });
        for (name, mesh, expected) in [
            ("cube", &cube, 24),
            ("square", &square, 8),
            ("brick", &brick, 4),
            ("wedge", &wedge, 1),
        ] {
            let found = proper_symmetries(mesh, 2000, 7);
            assert_eq!(found.len(), expected, "{name}: {found:?}");
            for s in &found {
                // A rotation about the centre (every shape here is centred at its origin) …
                assert!(s.t.norm() < 1e-4, "{name}: {s:?}");
                // … that maps corners onto corners (the brick's rounded corners: a half turn about an axis).
                if name == "brick" {
                    let angle = rotation_distance(s.q, Pose::<f64>::identity().q);
                    assert!(
                        angle < 0.01 || (angle - std::f64::consts::PI).abs() < 0.01,
                        "{name}: {s:?}"
                    );
                    continue;
                }
                for v in &mesh.vertices {
                    let moved = s.transform_point(Vec3::cst(*v));
                    let nearest = mesh
                        .vertices
                        .iter()
                        .map(|w| (Vec3::cst(*w) - moved).norm())
                        .fold(f64::INFINITY, f64::min);
                    assert!(nearest < 1e-3, "{name}: {s:?} moves {v:?} {nearest} m from any vertex");
                }
            }
        }
    }
}
