//! A k-d tree over 3-D points for nearest-neighbour queries (ICP's
//! correspondences). Built once by median splits into an implicit layout.

use geom::Vec3;

type V = Vec3<f64>;

/// Nearest-neighbour search over a fixed point set.
pub struct KdTree {
    points: Vec<V>,
    /// Point indices in tree order: node `[lo, hi)` has its split at the middle.
    order: Vec<u32>,
    /// Split axis of each middle position.
    axis: Vec<u8>,
}

impl KdTree {
    pub fn new(points: &[V]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut axis = vec![0u8; points.len()];
        build(points, &mut order, &mut axis, 0, points.len());
        Self {
            points: points.to_vec(),
            order,
            axis,
        }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Index and squared distance of the point nearest `q`.
    pub fn nearest(&self, q: V) -> Option<(usize, f64)> {
        if self.points.is_empty() {
            return None;
        }
        let mut best = (usize::MAX, f64::INFINITY);
        self.search(q, 0, self.points.len(), &mut best);
        Some(best)
    }

    fn search(&self, q: V, lo: usize, hi: usize, best: &mut (usize, f64)) {
        if lo >= hi {
            return;
        }
        let mid = (lo + hi) / 2;
        let i = self.order[mid] as usize;
        let p = self.points[i];
        let d2 = (p - q).norm_sq();
        if d2 < best.1 {
            *best = (i, d2);
        }
        if hi - lo == 1 {
            return;
        }
        let a = self.axis[mid] as usize;
        let diff = q[a] - p[a];
        let (near, far) = if diff < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(q, near.0, near.1, best);
        if diff * diff < best.1 {
            self.search(q, far.0, far.1, best);
        }
    }
}

fn build(points: &[V], order: &mut [u32], axis: &mut [u8], lo: usize, hi: usize) {
    if hi - lo <= 1 {
        return;
    }
    // Split on the axis of largest extent.
    let (mut min, mut max) = (V::splat(f64::INFINITY), V::splat(f64::NEG_INFINITY));
    for &i in &order[lo..hi] {
        let p = points[i as usize];
        min = V::new(min.x.min(p.x), min.y.min(p.y), min.z.min(p.z));
        max = V::new(max.x.max(p.x), max.y.max(p.y), max.z.max(p.z));
    }
    let ext = max - min;
    let a = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = (lo + hi) / 2;
    order[lo..hi].select_nth_unstable_by(mid - lo, |&i, &j| {
        points[i as usize][a].total_cmp(&points[j as usize][a])
    });
    axis[mid] = a as u8;
    build(points, order, axis, lo, mid);
    build(points, order, axis, mid + 1, hi);
}
