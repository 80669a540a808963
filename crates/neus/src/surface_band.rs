//! Training samples near the surface only. The occupancy grid keeps whole cells within reach of the
//! surface: a band of a cell and a half either side of the zero level plus the density's width, about
//! fifteen samples of a scene's slanted ray of which the NeuS density weighs a handful. The SDF values the
//! grid's refresh reads at the cells' centres, interpolated between centres, place the surface inside a
//! cell; samples further from it than the density reaches (a few 1/s) and a margin for the values' age
//! and the interpolation's error are left out of a training step: in front of the surface they are
//! transparent, behind it hidden.

/// The SDF at the centres of an occupancy grid's `res³` cells (x fastest), as its refresh read it; NaN
/// where no refresh has read it yet.
#[derive(Clone, Debug)]
pub struct CentreSdf {
    res: usize,
    values: Vec<f32>,
}

impl CentreSdf {
    /// Nothing read yet.
    pub fn unknown(res: usize) -> Self {
        Self {
            res,
            values: vec![f32::NAN; res * res * res],
        }
    }

    /// Values kept from an earlier run (a checkpoint), `res³` of them.
    pub fn from_values(res: usize, values: Vec<f32>) -> Option<Self> {
        (values.len() == res * res * res).then_some(Self { res, values })
    }

    pub fn res(&self) -> usize {
        self.res
    }

    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Keep what a refresh read: `sdf[k]` at the centre of cell `indices[k]`.
    pub fn record(&mut self, indices: &[usize], sdf: &[f32]) {
        for (&i, &s) in indices.iter().zip(sdf) {
            self.values[i] = s;
        }
    }

    /// The SDF at `p` (unit coordinates), interpolated trilinearly between the eight nearest centres;
    /// `None` outside the lattice of centres or where one of them is unread.
    #[inline]
    pub fn at(&self, p: [f32; 3]) -> Option<f32> {
        let r = self.res;
        let mut base = [0usize; 3];
        let mut frac = [0f32; 3];
        for k in 0..3 {
            // Centre i sits at -1 + (i + ½)·2/r.
            let g = (p[k] + 1.0) * 0.5 * r as f32 - 0.5;
            if !(g >= 0.0 && g < (r - 1) as f32) {
                return None;
            }
            base[k] = g as usize;
            frac[k] = g - base[k] as f32;
        }
        let idx = |i: usize, j: usize, k: usize| ((base[2] + k) * r + base[1] + j) * r + base[0] + i;
        let mut s = 0.0f32;
        for c in 0..8 {
            let (i, j, k) = (c & 1, (c >> 1) & 1, c >> 2);
            let v = self.values[idx(i, j, k)];
            let w = [i, j, k]
                .iter()
                .zip(&frac)
                .map(|(&b, &f)| if b == 1 { f } else { 1.0 - f })
                .product::<f32>();
            s += w * v;
        }
        // An unread centre (NaN) makes the sum NaN.
        s.is_finite().then_some(s)
    }

    /// Drop the samples `t[from..]` (with their `dt`) of the ray `o + t d` whose interpolated SDF lies further
    /// than `reach` from zero, telling `dropped` where each lies along the ray and its interpolated SDF (in
    /// order); samples where it is unknown stay.
    #[allow(clippy::too_many_arguments)]
    pub fn keep_near_surface(
        &self,
        o: [f32; 3],
        d: [f32; 3],
        reach: f32,
        from: usize,
        t: &mut Vec<f32>,
        dt: &mut Vec<f32>,
        mut dropped: impl FnMut(f32, f32),
    ) {
        let mut kept = from;
        for s in from..t.len() {
            let p = [o[0] + t[s] * d[0], o[1] + t[s] * d[1], o[2] + t[s] * d[2]];
            match self.at(p) {
                Some(v) if v.abs() > reach => dropped(t[s], v),
                _ => {
                    t[kept] = t[s];
                    dt[kept] = dt[s];
                    kept += 1;
                }
            }
        }
        t.truncate(kept);
        dt.truncate(kept);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(res: usize, height: f32) -> CentreSdf {
        let grid = crate::occupancy::OccupancyGrid::full(res);
        let mut c = CentreSdf::unknown(res);
        let idx: Vec<usize> = (0..res * res * res).collect();
        let sdf: Vec<f32> = idx.iter().map(|&i| grid.centre(i)[2] - height).collect();
        c.record(&idx, &sdf);
        c
    }

    /// Trilinear interpolation is exact for a plane's SDF (a linear function) between the centres, and
    /// there is no value outside them or where a centre is unread.
    #[test]
    fn a_planes_sdf_is_read_exactly_between_centres_and_not_outside() {
        let c = plane(16, 0.1);
        for p in [[0.0, 0.0, 0.0], [0.31, -0.52, 0.77], [-0.9, 0.9, -0.9]] {
            let v = c.at(p).expect("inside the centres");
            assert!((v - (p[2] - 0.1)).abs() < 1e-5, "{p:?}: {v}");
        }
        // The first centre sits at -1 + 1/16: the rim outside it has no value.
        assert_eq!(c.at([-0.97, 0.0, 0.0]), None);
        assert_eq!(c.at([0.0, 0.0, 1.5]), None);
        let mut partly = c.clone();
        let near = (8 * 16 + 8) * 16 + 8;
        partly.values[near] = f32::NAN;
        assert_eq!(partly.at([0.05, 0.05, 0.05]), None);
        assert!(CentreSdf::unknown(4).at([0.0; 3]).is_none());
    }

    /// A ray down through a plane keeps the samples within reach of it and those with no value, in order, and
    /// tells where the others lay.
    #[test]
    fn a_ray_keeps_its_samples_within_reach_of_the_surface() {
        let c = plane(32, 0.0);
        let (o, d) = ([0.0, 0.0, 2.0], [0.0, 0.0, -1.0]);
        // Heights 1.2 (outside the centres: kept), then 0.5, 0.05, 0.01, -0.02, -0.3.
        let mut t = vec![0.8, 1.5, 1.95, 1.99, 2.02, 2.3];
        let mut dt = vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
        let (mut t0, mut dt0) = (vec![7.0], vec![7.0]);
        t0.extend(&t);
        dt0.extend(&dt);
        let mut dropped = Vec::new();
        c.keep_near_surface(o, d, 0.03, 1, &mut t0, &mut dt0, |t, _| dropped.push(t));
        assert_eq!(t0, vec![7.0, 0.8, 1.99, 2.02]);
        assert_eq!(dt0, vec![7.0, 0.1, 0.4, 0.5]);
        assert_eq!(dropped, vec![1.5, 1.95, 2.3], "the others, in order");
        c.keep_near_surface(o, d, 1.0, 0, &mut t, &mut dt, |_, _| panic!("nothing is dropped"));
        assert_eq!(t.len(), 6, "everything within a unit of the plane stays");
    }
}
