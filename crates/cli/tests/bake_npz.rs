//! `bake --out x.npz` writes the same grid as `bake --out x.sdf`, as a NumPy archive: `sdf` [nz, ny, nx]
//! float32, `origin`, `spacing`.

use pganeus_io::{read_npz, NpyData};
use std::path::Path;
use std::process::Command;

#[test]
fn a_grid_baked_to_npz_holds_the_same_values_as_the_grid_file() {
    let d = testkit::scratch_dir("cli", "bake_npz");
    let cup = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cup_house.obj");
    for out in ["cup.sdf", "cup.npz"] {
        let o = Command::new(env!("CARGO_BIN_EXE_pganeus"))
            .arg("bake")
            .arg(&cup)
            .args(["--res", "20", "--out"])
            .arg(d.join(out))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let grid = sim::sdf::SdfGrid::load(&d.join("cup.sdf")).unwrap();
    let npz = read_npz(&d.join("cup.npz")).unwrap();
    let get = |name: &str| &npz.iter().find(|(k, _)| k == name).unwrap().1;
    let sdf = get("sdf");
    let [nx, ny, nz] = grid.dims();
    assert_eq!(sdf.shape, vec![nz, ny, nx]);
    match &sdf.data {
        NpyData::F32(v) => assert!(v == grid.values()),
        other => panic!("sdf is not float32: {other:?}"),
    }
    match (&get("origin").data, &get("spacing").data) {
        (NpyData::F64(o), NpyData::F64(s)) => {
            assert_eq!(o[..], grid.origin()[..]);
            assert_eq!(s[..], [grid.spacing()]);
        }
        other => panic!("{other:?}"),
    }
    // Inside the cup's solid wall the distance is negative: index [k][j][i] is node (i, j, k).
    assert!(grid.values().iter().any(|&v| v < 0.0));
    let _ = std::fs::remove_dir_all(&d);
}
