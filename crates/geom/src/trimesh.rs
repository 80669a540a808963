//! A triangle mesh as plain arrays: the one mesh type every crate passes around.

/// Indexed triangle mesh. Faces are counter-clockwise seen from outside
/// (outward normals by the right-hand rule) when the mesh is closed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<[f64; 3]>,
    pub faces: Vec<[u32; 3]>,
}

impl TriMesh {
    pub fn new(vertices: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Self {
        Self { vertices, faces }
    }

    /// The smallest axis-aligned box holding every vertex: `(min, max)`
    /// (infinite and inverted for a mesh without vertices).
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        bounding_box(self.vertices.iter().copied())
    }

    /// The three corners of face `f`.
    pub fn triangle(&self, f: usize) -> [[f64; 3]; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// The area of face `f`.
    pub fn triangle_area(&self, f: usize) -> f64 {
        let [a, b, c] = self.triangle(f).map(crate::Vec3::<f64>::cst);
        0.5 * (b - a).cross(c - a).norm()
    }

    /// The surface area (every face's).
    pub fn area(&self) -> f64 {
        (0..self.faces.len()).map(|f| self.triangle_area(f)).sum()
    }
}

/// The smallest axis-aligned box holding `points`: `(min, max)` (infinite and
/// inverted when there are none).
pub fn bounding_box(points: impl IntoIterator<Item = [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}
