//! Grid sampling: the grid's geometry (spacing from the longest side, centred
//! on the box, covering it), the x-fastest layout, batches of whole z-layers.

use std::sync::Mutex;

use mesh::sample_sdf_grid;

#[test]
fn cube_box_grid_ends_on_the_corners() {
    let g = sample_sdf_grid(
        &|p: &[[f64; 3]]| vec![0.0; p.len()],
        [-1.0, 0.0, 2.0],
        [1.0, 2.0, 4.0],
        33,
    );
    assert_eq!(g.dims, [33; 3]);
    assert!((g.spacing - 2.0 / 32.0).abs() < 1e-15);
    assert_eq!(g.origin, [-1.0, 0.0, 2.0]);
    let last = g.point(32, 32, 32);
    for a in 0..3 {
        assert!((last[a] - [1.0, 2.0, 4.0][a]).abs() < 1e-12);
    }
}

#[test]
fn other_sides_are_covered_and_centred() {
    let (min, max) = ([0.0, -0.3, 5.0], [2.0, 0.3, 5.05]);
    let g = sample_sdf_grid(&|p: &[[f64; 3]]| vec![0.0; p.len()], min, max, 21);
    assert_eq!(g.dims[0], 21);
    assert!((g.spacing - 0.1).abs() < 1e-15);
    assert_eq!(g.dims[1], 7); // 0.6 / 0.1 = 6 intervals (not 7 through rounding)
    assert_eq!(g.dims[2], 2);
    let hi = g.point(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1);
    for a in 0..3 {
        assert!(g.origin[a] <= min[a] + 1e-12 && hi[a] >= max[a] - 1e-12, "axis {a}");
        let centre = 0.5 * (g.origin[a] + hi[a]);
        assert!((centre - 0.5 * (min[a] + max[a])).abs() < 1e-12, "axis {a}");
    }
}

#[test]
fn values_are_laid_out_x_fastest_in_layer_batches() {
    let calls = Mutex::new(Vec::new());
    let f = |pts: &[[f64; 3]]| {
        calls.lock().unwrap().push(pts.len());
        pts.iter().map(|p| (p[0] + 10.0 * p[1] + 100.0 * p[2]) as f32).collect()
    };
    let g = sample_sdf_grid(&f, [0.0; 3], [1.0, 1.0, 2.0], 301);
    let [nx, ny, nz] = g.dims;
    assert_eq!([nx, ny, nz], [151, 151, 301]);
    for (i, j, k) in [(0, 0, 0), (150, 0, 0), (3, 7, 11), (150, 150, 300)] {
        let p = g.point(i, j, k);
        assert_eq!(
            g.values[i + nx * (j + ny * k)],
            (p[0] + 10.0 * p[1] + 100.0 * p[2]) as f32
        );
    }
    let calls = calls.into_inner().unwrap();
    assert_eq!(calls.iter().sum::<usize>(), nx * ny * nz);
    // Whole layers per call, and large batches (here two layers of 151²).
    assert!(calls.iter().all(|&n| n % (nx * ny) == 0));
    assert!(calls.len() < nz, "{} calls", calls.len());
}

#[test]
#[should_panic(expected = "returned 1 values")]
fn a_field_returning_the_wrong_count_panics() {
    sample_sdf_grid(&|_: &[[f64; 3]]| vec![0.0], [0.0; 3], [1.0; 3], 4);
}
