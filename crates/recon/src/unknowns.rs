//! The values a physics fit moves and the simulator parameters they set. Each value sets its parameters
//! linearly: one parameter (a launch component), several tied to one value (one board's friction for
//! every body), or a direction in parameter space (a launch kept in the plane of the surface the body
//! starts on, where the images cannot tell a slide from a slow hop and the physics says the normal part is
//! zero). Jacobians over the parameters become Jacobians over the values by the same coefficients.

use serde::{Deserialize, Serialize};

/// One value: the parameters it sets, `p[columns[c]] = Σ coef · x` over the values that share it.
#[derive(Clone, Debug)]
struct Unknown {
    terms: Vec<(usize, f64)>,
    /// The pattern search's (or trust region's) scale of this value.
    probe: f64,
    /// Kept within the contact values' range (0, 1).
    bounded: bool,
}

/// The values of a fit, in order, and the parameters they set.
#[derive(Clone, Debug, Default)]
pub(crate) struct Unknowns {
    list: Vec<Unknown>,
    /// Every parameter some value sets (the simulator's derivative columns), each once.
    columns: Vec<usize>,
    /// What each column holds before the values are added (0 but for a position kept in a plane: its
    /// part along the normal).
    base: Vec<f64>,
}

impl Unknowns {
    fn column(&mut self, param: usize) -> usize {
        match self.columns.iter().position(|&c| c == param) {
            Some(c) => c,
            None => {
                self.columns.push(param);
                self.base.push(0.0);
                self.columns.len() - 1
            }
        }
    }

    /// A value that sets `Σ coef · x` into each of its `(parameter, coef)` terms.
    pub fn push(&mut self, terms: &[(usize, f64)], probe: f64, bounded: bool) {
        let terms = terms.iter().map(|&(m, c)| (self.column(m), c)).collect();
        self.list.push(Unknown { terms, probe, bounded });
    }

    /// A value that is one parameter.
    pub fn push_param(&mut self, param: usize, probe: f64, bounded: bool) {
        self.push(&[(param, 1.0)], probe, bounded);
    }

    /// A velocity (parameters `first..first + 3`) kept in the plane normal to `normal`: two values along
    /// an orthonormal basis of that plane (the probe applies to each).
    pub fn push_in_plane(&mut self, first: usize, normal: [f64; 3], probe: f64) {
        for axis in tangent_basis(normal) {
            let terms: Vec<(usize, f64)> = (0..3).map(|i| (first + i, axis[i])).collect();
            self.push(&terms, probe, false);
        }
    }

    /// A position (parameters `first..first + 3`) that moves in the plane through `at` normal to `normal`
    /// only: two values as [`Self::push_in_plane`], the part along the normal kept at `at`'s (a body resting
    /// on a face slides along the scene, it does not sink into it).
    pub fn push_in_plane_at(&mut self, first: usize, normal: [f64; 3], at: [f64; 3], probe: f64) {
        self.push_in_plane(first, normal, probe);
        let len = normal.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
        let n = normal.map(|v| v / len);
        let height: f64 = (0..3).map(|i| n[i] * at[i]).sum();
        for i in 0..3 {
            let c = self.column(first + i);
            self.base[c] = n[i] * height;
        }
    }

    /// A vector (parameters `first..first + 3`) kept along `axis`: one value, its length along the unit axis.
    pub fn push_along(&mut self, first: usize, axis: [f64; 3], probe: f64) {
        let len = axis.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
        let terms: Vec<(usize, f64)> = (0..3).map(|i| (first + i, axis[i] / len)).collect();
        self.push(&terms, probe, false);
    }

    /// A body's launch (v0 at parameters `first..first + 3`, ω0 after it) as its start on the scene allows;
    /// `velocity`, `spin`: whether each is fitted at all.
    pub fn push_launch(&mut self, first: usize, start: StartContact, velocity: bool, spin: bool) {
        let (v, w) = (first, first + 3);
        if let StartContact::Rest { .. } = start {
            return;
        }
        match start {
            StartContact::Touching { normal } | StartContact::Face { normal } if velocity => {
                self.push_in_plane(v, normal, probe_scale(6))
            }
            _ if velocity => (0..3).for_each(|i| self.push_param(v + i, probe_scale(6), false)),
            _ => {}
        }
        match start {
            StartContact::Face { normal } if spin => self.push_along(w, normal, probe_scale(9)),
            _ if spin => (0..3).for_each(|i| self.push_param(w + i, probe_scale(9), false)),
            _ => {}
        }
    }

    pub fn len(&self) -> usize {
        self.list.len()
    }

    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The parameters the values set, each once: the columns of the simulator's Jacobian.
    pub fn columns(&self) -> &[usize] {
        &self.columns
    }

    /// These values but the `i`-th, whose parameters are left as they are: for a value whose parameters no
    /// other value sets, as a contact value's (a tangent of a vector kept in a plane shares its parameters
    /// with the other tangent, and [`Self::set`] rewrites them).
    pub fn without(&self, i: usize) -> Unknowns {
        let mut out = Unknowns::default();
        for (j, u) in self.list.iter().enumerate() {
            if j != i {
                let terms: Vec<(usize, f64)> = u.terms.iter().map(|&(c, k)| (self.columns[c], k)).collect();
                out.push(&terms, u.probe, u.bounded);
            }
        }
        for (c, &m) in out.columns.iter().enumerate() {
            if let Some(k) = self.columns.iter().position(|&x| x == m) {
                out.base[c] = self.base[k];
            }
        }
        out
    }

    pub fn probe(&self, i: usize) -> f64 {
        self.list[i].probe
    }

    pub fn bounded(&self, i: usize) -> bool {
        self.list[i].bounded
    }

    /// The values that best reproduce parameters `p`: each value's projection `Σ c p / Σ c²` (exact for
    /// parameters [`Self::set`] wrote, as the directions are orthogonal; the mean of tied parameters).
    pub fn values(&self, p: &[f64]) -> Vec<f64> {
        self.list
            .iter()
            .map(|u| {
                let (num, den) = u
                    .terms
                    .iter()
                    .fold((0.0, 0.0), |(n, d), &(c, k)| (n + k * p[self.columns[c]], d + k * k));
                num / den.max(1e-300)
            })
            .collect()
    }

    /// Parameters `p` with the values `x` in place: every parameter a value sets is rewritten (a velocity
    /// kept in a plane loses its normal part; a position kept in a plane keeps its base's).
    pub fn set(&self, p: &mut [f64], x: &[f64]) {
        for (&m, &b) in self.columns.iter().zip(&self.base) {
            p[m] = b;
        }
        for (u, v) in self.list.iter().zip(x) {
            for &(c, k) in &u.terms {
                p[self.columns[c]] += k * v;
            }
        }
    }

    /// A row of derivatives over [`Self::columns`] as derivatives over the values.
    pub fn chain(&self, row: &[f64]) -> Vec<f64> {
        self.list
            .iter()
            .map(|u| u.terms.iter().map(|&(c, k)| k * row[c]).sum())
            .collect()
    }
}

/// Two unit vectors orthogonal to `normal` and to each other.
pub(crate) fn tangent_basis(normal: [f64; 3]) -> [[f64; 3]; 2] {
    let len = normal.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
    let n = normal.map(|v| v / len);
    // Cross with the world axis least aligned with the normal: never degenerate.
    let least = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap_or(0);
    let mut e = [0.0; 3];
    e[least] = 1.0;
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let t1 = cross(n, e);
    let l1 = t1.iter().map(|v| v * v).sum::<f64>().sqrt();
    let t1 = t1.map(|v| v / l1);
    [t1, cross(n, t1)]
}

/// How a body touches the scene in the first frame, which decides how its launch is fitted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum StartContact {
    /// Off the scene (a toss, a drop): v0 and ω0 are free.
    #[default]
    Free,
    /// On the scene at a point or along an edge (a ball, a rocking body): v0 in the plane normal to the
    /// scene there, ω0 free (a ball rolls, a body rocks). One view cannot tell a slide from a slow hop (from
    /// a camera above, up and forward look alike), and a body pressed on a surface does not leave it at
    /// the start.
    Touching { normal: [f64; 3] },
    /// Resting on a face: v0 in the plane, ω0 about the normal only. A turn about an axis in the face digs
    /// one side of it into the scene, which stops it within a substep, so the video cannot tell it (a
    /// sliding box's fit took a spin of 11 rad/s about such an axis and lost the slide).
    Face { normal: [f64; 3] },
    /// At rest on the scene from the start until something moves it ([`mod@crate::resting_start`]): no launch
    /// (v0 = ω0 = 0), from its resting pose (refitted with the others' where a fit moves the initial poses,
    /// on its face only: along the scene and about its normal; held there, the error of its pose on a
    /// reconstructed scene went into the body that strikes it, 12 mm at the three balls' first frame).
    Rest { normal: [f64; 3] },
}

/// The pattern search's first step for a parameter: 2 mm and 0.02 rad of initial pose, 5 cm/s, 0.5 rad/s,
/// 0.1 of restitution and friction. Where contacts make the loss rugged (a landing on an edge, a tumble),
/// Levenberg–Marquardt's local model may not point downhill at any damping; probing each parameter at
/// these scales (then at halves of them) still finds a lower loss, and the gradient steps resume from there.
pub(crate) fn probe_scale(k: usize) -> f64 {
    match k {
        0..=2 => 0.002,
        3..=5 => 0.02,
        6..=8 => 0.05,
        9..=11 => 0.5,
        _ => 0.1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_velocity_in_a_plane_keeps_its_tangent_part_and_chains_its_derivatives() {
        let normal = [0.1, -0.2, 1.0];
        let mut u = Unknowns::default();
        u.push_param(13, 0.1, true);
        u.push_in_plane(6, normal, 0.05);
        u.push(&[(12, 1.0), (26, 1.0)], 0.1, true);
        assert_eq!(u.len(), 4);
        assert_eq!(u.columns(), &[13, 6, 7, 8, 12, 26]);
        let mut p = vec![0.0; 30];
        p[6..9].copy_from_slice(&[1.2, 0.3, 0.4]);
        p[13] = 0.25;
        p[12] = 0.4;
        p[26] = 0.6;
        let x = u.values(&p);
        u.set(&mut p, &x);
        // The velocity lost its normal part only.
        let len = normal.iter().map(|v| v * v).sum::<f64>().sqrt();
        let along: f64 = (0..3).map(|i| p[6 + i] * normal[i] / len).sum();
        assert!(along.abs() < 1e-12, "{along}");
        let v0 = [1.2, 0.3, 0.4];
        let n_part: f64 = (0..3).map(|i| v0[i] * normal[i] / len).sum();
        for i in 0..3 {
            assert!((p[6 + i] - (v0[i] - n_part * normal[i] / len)).abs() < 1e-12);
        }
        // Tied values meet at their mean; a single one is itself.
        assert!((p[12] - 0.5).abs() < 1e-12 && (p[26] - 0.5).abs() < 1e-12);
        assert_eq!(p[13], 0.25);
        // Values read back are the values written.
        let again = u.values(&p);
        for (a, b) in again.iter().zip(&x) {
            assert!((a - b).abs() < 1e-12);
        }
        // The chain rule by the same coefficients: a function of the parameters, differentiated by finite
        // differences in the values.
        let f = |p: &[f64]| p[6] * p[6] + 3.0 * p[7] - p[8] * p[13] + p[12] * p[26];
        let row: Vec<f64> = u
            .columns()
            .iter()
            .map(|&m| match m {
                6 => 2.0 * p[6],
                7 => 3.0,
                8 => -p[13],
                13 => -p[8],
                12 => p[26],
                26 => p[12],
                _ => 0.0,
            })
            .collect();
        let chained = u.chain(&row);
        for j in 0..u.len() {
            let h = 1e-6;
            let (mut a, mut b) = (x.clone(), x.clone());
            a[j] += h;
            b[j] -= h;
            let (mut pa, mut pb) = (p.clone(), p.clone());
            u.set(&mut pa, &a);
            u.set(&mut pb, &b);
            let fd = (f(&pa) - f(&pb)) / (2.0 * h);
            assert!((fd - chained[j]).abs() < 1e-6, "value {j}: {fd} vs {}", chained[j]);
        }
    }

    #[test]
    fn a_start_allows_the_launch_its_values_can_reach() {
        let (v, w) = ([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]);
        let close = |a: [f64; 3], b: [f64; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12);
        assert_eq!(StartContact::Free.allowed_launch(v, w), (v, w));
        let up = [0.0, 0.0, 1.0];
        let (tv, tw) = StartContact::Touching { normal: up }.allowed_launch(v, w);
        assert!(close(tv, [1.0, 2.0, 0.0]) && close(tw, w), "{tv:?} {tw:?}");
        let (fv, fw) = StartContact::Face { normal: up }.allowed_launch(v, w);
        assert!(
            close(fv, [1.0, 2.0, 0.0]) && close(fw, [0.0, 0.0, 6.0]),
            "{fv:?} {fw:?}"
        );
    }

    #[test]
    fn the_tangent_basis_is_orthonormal_for_any_normal() {
        for n in [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.3, -0.9, 0.2], [0.0, 0.0, -2.0]] {
            let [a, b] = tangent_basis(n);
            let dot = |x: [f64; 3], y: [f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
            assert!((dot(a, a) - 1.0).abs() < 1e-12 && (dot(b, b) - 1.0).abs() < 1e-12);
            assert!(dot(a, b).abs() < 1e-12 && dot(a, n).abs() < 1e-12 && dot(b, n).abs() < 1e-12);
        }
    }

    #[test]
    fn a_position_in_a_plane_moves_along_it_and_keeps_its_height() {
        let normal = [0.0, 0.2, 1.0];
        let at = [0.05, 0.02, 0.021];
        let mut u = Unknowns::default();
        u.push_in_plane_at(0, normal, at, 0.002);
        u.push_along(3, normal, 0.02);
        let mut p = vec![0.0; 12];
        p[..3].copy_from_slice(&at);
        let x = u.values(&p);
        let mut q = p.clone();
        u.set(&mut q, &x);
        for i in 0..3 {
            assert!((q[i] - at[i]).abs() < 1e-15, "read back and written: {:?}", &q[..3]);
        }
        // Moved by the values: along the plane only, its height along the normal kept.
        let moved: Vec<f64> = x.iter().enumerate().map(|(i, v)| v + 0.01 * (i + 1) as f64).collect();
        u.set(&mut q, &moved);
        let len = normal.iter().map(|v| v * v).sum::<f64>().sqrt();
        let height = |t: &[f64]| (0..3).map(|i| t[i] * normal[i] / len).sum::<f64>();
        assert!((height(&q[..3]) - height(&at)).abs() < 1e-15);
        assert!((0..3).map(|i| (q[i] - at[i]).powi(2)).sum::<f64>().sqrt() > 0.01);
        // The turn about the normal only, and a value left out keeps the height too.
        let turn = &q[3..6];
        let cross = [
            turn[1] * normal[2] - turn[2] * normal[1],
            turn[2] * normal[0] - turn[0] * normal[2],
            turn[0] * normal[1] - turn[1] * normal[0],
        ];
        assert!(cross.iter().all(|c| c.abs() < 1e-15), "{turn:?}");
        let w = u.without(2);
        let mut r = p.clone();
        w.set(&mut r, &x[..2]);
        assert!((height(&r[..3]) - height(&at)).abs() < 1e-15);
    }
}
