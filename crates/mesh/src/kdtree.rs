//! A k-d tree over 3-D points for nearest-neighbour queries (ICP's
//! correspondences). Built once by median splits into an implicit layout.

use geom::Vec3;

type V = Vec3<f64>;

/// Nearest-neighbour search over a fixed point set.
pub struct KdTree {
    /// The points in tree order: node `[lo, hi)` has its split point at the middle. Held in this order (with
    /// each split's axis and the point's index beside it) so that a search reads memory near where it was:
    /// ICP's searches through an index array took four fifths of a merge's time.
    nodes: Vec<Node>,
    /// Each point's position in `nodes`.
    position: Vec<u32>,
}

#[derive(Clone, Copy)]
struct Node {
    p: [f64; 3],
    /// The index of the point in the set the tree was built from.
    index: u32,
    /// The split axis at this middle position.
    axis: u8,
}

impl KdTree {
    pub fn new(points: &[V]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut axis = vec![0u8; points.len()];
        build(points, &mut order, &mut axis, 0, points.len());
        let nodes = order
            .iter()
            .zip(&axis)
            .map(|(&i, &a)| Node {
                p: points[i as usize].to_array(),
                index: i,
                axis: a,
            })
            .collect();
        let mut position = vec![0u32; points.len()];
        for (k, &i) in order.iter().enumerate() {
            position[i as usize] = k as u32;
        }
        Self { nodes, position }
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Index and squared distance of the point nearest `q`.
    pub fn nearest(&self, q: V) -> Option<(usize, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best = (usize::MAX, f64::INFINITY);
        self.search(q.to_array(), 0, self.nodes.len(), &mut best);
        Some((self.nodes[best.0].index as usize, best.1))
    }

    /// [`Self::nearest`], starting from point `hint` as the nearest so far: where the answer is near the
    /// hint (ICP's next iteration, whose points moved little), the search skips almost every branch. The
    /// same point as without the hint, but where several lie at exactly the same distance.
    pub fn nearest_from(&self, q: V, hint: usize) -> Option<(usize, f64)> {
        let Some(&at) = self.position.get(hint) else {
            return self.nearest(q);
        };
        let q = q.to_array();
        let mut best = (at as usize, dist2(self.nodes[at as usize].p, q));
        self.search(q, 0, self.nodes.len(), &mut best);
        Some((self.nodes[best.0].index as usize, best.1))
    }

    /// `best`: the tree position of the nearest point so far and its squared distance.
    fn search(&self, q: [f64; 3], lo: usize, hi: usize, best: &mut (usize, f64)) {
        if lo >= hi {
            return;
        }
        let mid = (lo + hi) / 2;
        let node = &self.nodes[mid];
        let p = node.p;
        let d2 = dist2(p, q);
        if d2 < best.1 {
            *best = (mid, d2);
        }
        if hi - lo == 1 {
            return;
        }
        let a = node.axis as usize;
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

/// Squared distance, summed in the order of `Vec3::norm_sq`.
fn dist2(p: [f64; 3], q: [f64; 3]) -> f64 {
    (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2])
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
