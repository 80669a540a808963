//! Points on the zero level of a field, with normals: start points (samples
//! of the extracted mesh, or grid points near the surface) moved along the
//! field's gradient by Newton steps, `x ← x − f(x) ∇f / |∇f|²`. Marching
//! leaves its vertices off the true level by O(h²) where the surface curves;
//! the projection removes that, and the gradient gives the field's own normal
//! rather than a facet's.

use geom::Vec3;

type V = Vec3<f64>;

/// Signed distances at a batch of points (negative inside).
pub type BatchSdf<'a> = dyn Fn(&[V]) -> Vec<f64> + Sync + 'a;

/// Values and central-difference gradients of `sdf` at `points`, in one batch
/// of 7 points per point.
pub fn values_and_gradients(sdf: &BatchSdf, points: &[V], step: f64) -> (Vec<f64>, Vec<V>) {
    let axes = [V::new(1.0, 0.0, 0.0), V::new(0.0, 1.0, 0.0), V::new(0.0, 0.0, 1.0)];
    let mut batch = Vec::with_capacity(points.len() * 7);
    for &p in points {
        batch.push(p);
        for a in axes {
            batch.push(p + a * step);
            batch.push(p - a * step);
        }
    }
    let f = sdf(&batch);
    assert_eq!(f.len(), batch.len(), "the field returned the wrong number of values");
    let values = f.chunks_exact(7).map(|c| c[0]).collect();
    let grads = f
        .chunks_exact(7)
        .map(|c| V::new(c[1] - c[2], c[3] - c[4], c[5] - c[6]) * (0.5 / step))
        .collect();
    (values, grads)
}

/// Moves `points` onto the zero level of `sdf` (`iterations` Newton steps,
/// gradients by central differences of width `2·step`) and returns the
/// points that land within `tolerance` of it, with unit normals (the
/// normalised gradient, outward for a signed distance).
pub fn zero_level_points(
    sdf: &BatchSdf,
    points: &[V],
    step: f64,
    iterations: usize,
    tolerance: f64,
) -> (Vec<V>, Vec<V>) {
    let mut x = points.to_vec();
    for _ in 0..iterations {
        let (f, g) = values_and_gradients(sdf, &x, step);
        for ((xi, fi), gi) in x.iter_mut().zip(&f).zip(&g) {
            let g2 = gi.dot(*gi);
            if g2 > 1e-12 {
                *xi -= *gi * (fi / g2);
            }
        }
    }
    let (f, g) = values_and_gradients(sdf, &x, step);
    x.into_iter()
        .zip(f)
        .zip(g)
        .filter(|((_, fi), gi)| fi.abs() <= tolerance && gi.norm() > 1e-6)
        .map(|((xi, _), gi)| (xi, gi * (1.0 / gi.norm())))
        .unzip()
}
