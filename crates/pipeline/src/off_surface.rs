//! Whether a trained scene's SDF is a distance off its surface, where the simulator reads it: at heights of
//! a few millimetres to centimetres over the free board (no other surface nearer than the board), the field's
//! value against the height and its gradient against the board's normal. A field trained only near its zero
//! level can keep the zero level right and still tilt a centimetre above it (profile notebook, 2026-12-07), and a
//! body simulated against that tilt starts off; Chamfer and PSNR do not see it.

use crate::surfaces::SceneRegion;
use geom::{TriMesh, Vec3};
use neus::NeusField;
use serde::Serialize;
use sim::sdf::MeshDistance;

/// The field over the free board at one height.
#[derive(Clone, Debug, Serialize)]
pub struct OffSurface {
    pub height_mm: f64,
    /// Points over the free board at this height (a grid over the region, inside the unit sphere).
    pub points: usize,
    /// Mean and worst |SDF − height|.
    pub sdf_error_mm: f64,
    pub worst_sdf_error_mm: f64,
    /// Mean length of the SDF's gradient (1 for a distance).
    pub gradient_length: f64,
    /// Mean and worst angle between the gradient and the board's normal.
    pub tilt_deg: f64,
    pub worst_tilt_deg: f64,
}

/// Grid points a side over the region.
const GRID: usize = 24;

/// A column over the free board: this high over it, the nearest true surface is still the board beneath (no
/// wall or obstacle within about this distance, and the point is not inside one).
pub const FREE_HEIGHT: f64 = 0.03;

fn free_column(md: &MeshDistance, x: f64, y: f64) -> bool {
    let (d, c) = md.closest_point(Vec3::new(x, y, FREE_HEIGHT));
    (d - FREE_HEIGHT).abs() < 1e-4 && c.z.abs() < 1e-4
}

/// The field over the free board at each of `heights` (metres): a grid of points over the middle 80 % of
/// `region` at that height, kept over the free board ([`FREE_HEIGHT`]) and well inside the unit sphere
/// (`centre`, `radius`). Heights up to [`FREE_HEIGHT`].
pub fn off_surface(
    field: &NeusField,
    levels: usize,
    centre: Vec3<f64>,
    radius: f64,
    truth: &TriMesh,
    region: &SceneRegion,
    heights: &[f64],
) -> Vec<OffSurface> {
    let Ok(md) = MeshDistance::new(truth) else {
        return Vec::new();
    };
    let sdf = |ps: &[Vec3<f64>]| -> Vec<f64> {
        let unit: Vec<f32> = ps
            .iter()
            .flat_map(|p| ((*p - centre) * (1.0 / radius)).to_array().map(|v| v as f32))
            .collect();
        field
            .sdf_values(&unit, levels)
            .iter()
            .map(|&s| s as f64 * radius)
            .collect()
    };
    heights
        .iter()
        .map(|&h| {
            let mut pts = Vec::new();
            for i in 0..GRID {
                for j in 0..GRID {
                    let f = |k: usize, a: usize| {
                        let u = 0.1 + 0.8 * (a as f64 + 0.5) / GRID as f64;
                        region.lo[k] + u * (region.hi[k] - region.lo[k])
                    };
                    let p = Vec3::new(f(0, i), f(1, j), h);
                    let inside = (p - centre).norm() < 0.9 * radius;
                    if inside && free_column(&md, p.x, p.y) {
                        pts.push(p);
                    }
                }
            }
            let (values, grads) = mesh::values_and_gradients(&sdf, &pts, 1e-3);
            let n = pts.len().max(1) as f64;
            let errors: Vec<f64> = values.iter().map(|v| (v - h).abs()).collect();
            let tilts: Vec<f64> = grads
                .iter()
                .map(|g| (g.z / g.norm().max(1e-12)).clamp(-1.0, 1.0).acos().to_degrees())
                .collect();
            let max = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max);
            OffSurface {
                height_mm: h * 1e3,
                points: pts.len(),
                sdf_error_mm: errors.iter().sum::<f64>() / n * 1e3,
                worst_sdf_error_mm: max(&errors) * 1e3,
                gradient_length: grads.iter().map(|g| g.norm()).sum::<f64>() / n,
                tilt_deg: tilts.iter().sum::<f64>() / n,
                worst_tilt_deg: max(&tilts),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use neus::{FieldConfig, FieldInit};

    /// The board `[-0.3, 0.3]²` at z = 0 and, if asked, a wall `x ∈ [0.1, 0.14]` standing 70 mm on it (its
    /// faces wound outward; the board's top up).
    fn truth(wall: bool) -> TriMesh {
        let mut v = vec![[-0.3, -0.3, 0.0], [0.3, -0.3, 0.0], [0.3, 0.3, 0.0], [-0.3, 0.3, 0.0]];
        let mut f = vec![[0, 1, 2], [0, 2, 3]];
        if wall {
            let (x0, x1, y0, y1, z1) = (0.1, 0.14, -0.3, 0.3, 0.07);
            let b = v.len() as u32;
            for z in [0.0, z1] {
                v.extend([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]);
            }
            let quads = [[4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]];
            for q in quads {
                f.push([b + q[0], b + q[1], b + q[2]]);
                f.push([b + q[0], b + q[2], b + q[3]]);
            }
        }
        TriMesh::new(v, f)
    }

    /// A scene field at its start (the board's exact plane, its normal `normal`) over a unit sphere of radius
    /// 0.4 m centred 5 cm over the board.
    fn plane_field(normal: [f32; 3]) -> (NeusField, Vec3<f64>, f64) {
        let (centre, radius) = (Vec3::new(0.0, 0.0, 0.05), 0.4);
        let config = FieldConfig {
            init: FieldInit::Board,
            ..FieldConfig::default()
        };
        let board = (-centre.z / radius) as f32;
        let mut field = NeusField::new(&config, 3, board);
        let mut rng = geom::SplitMix64::new(9);
        // Through the board's centre under the sphere's: n · (0, 0, board) = offset.
        field
            .sdf
            .init_geometric_plane(&mut field.sdf_params, &mut rng, normal, normal[2] * board);
        (field, centre, radius)
    }

    #[test]
    fn the_boards_exact_plane_is_a_distance_and_a_tilted_one_shows_its_tilt() {
        let region = SceneRegion {
            lo: [-0.3, -0.3],
            hi: [0.3, 0.3],
        };
        let heights = [0.005, 0.01, 0.02];
        let (field, centre, radius) = plane_field([0.0, 0.0, 1.0]);
        let levels = field.grid.levels();
        let board = off_surface(&field, levels, centre, radius, &truth(false), &region, &heights);
        for o in &board {
            assert!(o.points > 300, "{o:?}");
            assert!(o.worst_sdf_error_mm < 0.05, "{o:?}");
            assert!((o.gradient_length - 1.0).abs() < 1e-3, "{o:?}");
            assert!(o.worst_tilt_deg < 0.1, "{o:?}");
        }
        // The wall's columns, and those within 3 cm of it, are not the free board.
        let walled = off_surface(&field, levels, centre, radius, &truth(true), &region, &heights);
        let band = (0.14 + 0.03 - (0.1 - 0.03)) / 0.6 / 0.8;
        let expected = board[0].points as f64 * (1.0 - band);
        assert!(
            (walled[0].points as f64 - expected).abs() < 0.1 * expected,
            "{} points beside the wall, {} without it (expected about {expected:.0})",
            walled[0].points,
            board[0].points
        );
        // A plane tilted 5° about x: the gradient's tilt is read, and the height error grows with the offset
        // from the board's centre.
        let a = 5f32.to_radians();
        let (tilted, ..) = plane_field([0.0, a.sin(), a.cos()]);
        for o in off_surface(&tilted, levels, centre, radius, &truth(false), &region, &heights) {
            assert!((o.tilt_deg - 5.0).abs() < 0.05, "{o:?}");
            assert!(o.sdf_error_mm > 1.0, "{o:?}");
        }
    }
}
