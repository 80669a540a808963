//! Every parser of user files, fed mutants of valid files (testkit's mutation fuzzer): none may panic, and
//! no case may allocate more than 256 MiB (a header claiming 10⁹ vertices must not reserve them before they
//! are read) or take more than a second. `PGANEUS_FUZZ_CASES=N` sets the cases per parser (default 20,000);
//! the long run: `PGANEUS_FUZZ_CASES=200000 cargo test --release -p pganeus-io --test suite fuzz:: -- --nocapture`.

use pganeus_io::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use testkit::fuzz::{fuzz, FuzzReport};

/// The system allocator, recording the largest single request and refusing any above 1 GiB (the process
/// then aborts: a failed test, not a machine out of memory).
struct Capped;

static LARGEST: AtomicUsize = AtomicUsize::new(0);
const REFUSED_ABOVE: usize = 1 << 30;

unsafe impl GlobalAlloc for Capped {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > REFUSED_ABOVE {
            return std::ptr::null_mut();
        }
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > REFUSED_ABOVE {
            return std::ptr::null_mut();
        }
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > REFUSED_ABOVE {
            return std::ptr::null_mut();
        }
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOC: Capped = Capped;

const P: &str = "fuzzed";

fn cases() -> usize {
    std::env::var("PGANEUS_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000)
}

/// `png` with every whole chunk's CRC recomputed, so that a mutant reaches past the checksum into the
/// chunk's contents.
fn with_fixed_crcs(png: &[u8]) -> Vec<u8> {
    let mut b = png.to_vec();
    let mut at = 8;
    while at + 12 <= b.len() {
        let len = u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize;
        let Some(end) = at.checked_add(12 + len).filter(|&e| e <= b.len()) else {
            break;
        };
        let crc = crc32fast::hash(&b[at + 4..end - 4]);
        b[end - 4..end].copy_from_slice(&crc.to_be_bytes());
        at = end;
    }
    b
}

fn pattern(w: u32, h: u32, channels: u8) -> Image {
    let mut img = Image::new(w, h, channels);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = (i * 37 % 251) as u8;
    }
    img
}

fn tetrahedron() -> PlyMesh {
    PlyMesh {
        mesh: geom::TriMesh::new(
            vec![[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        ),
        colors: Some(vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [9, 9, 9]]),
        normals: None,
    }
}

fn data(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)).unwrap()
}

#[test]
fn every_parser_survives_mutated_files() {
    let n = cases();
    let path = Path::new(P);
    let truth_text = data("truth_example.json");
    let truth = read_truth_bytes(&truth_text, path).unwrap();
    let mut apng = Vec::new();
    {
        let d = std::env::temp_dir().join(format!("pganeus_fuzz_{}.png", std::process::id()));
        write_apng(&d, &[pattern(6, 5, 3), pattern(6, 5, 3)], 10.0).unwrap();
        apng.extend(std::fs::read(&d).unwrap());
        let _ = std::fs::remove_file(&d);
    }
    let ply = tetrahedron();
    let npy = NpyArray {
        shape: vec![2, 3],
        data: NpyData::F64(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
    };
    let reports: Vec<FuzzReport> = vec![
        fuzz(
            "PNG",
            &[
                encode_png(&pattern(7, 5, 1)),
                encode_png(&pattern(7, 5, 3)),
                encode_png(&pattern(4, 9, 4)),
                apng,
            ],
            n,
            1,
            |b| {
                let raw = read_png_bytes(b, path).is_ok();
                read_png_bytes(&with_fixed_crcs(b), path).is_ok() || raw
            },
        ),
        fuzz(
            "JPEG",
            &[
                testkit::jpeg_bytes(&pattern(16, 8, 3).data, 16, 8, 3, 80),
                testkit::jpeg_bytes(&pattern(8, 8, 1).data, 8, 8, 1, 80),
            ],
            n,
            2,
            |b| read_jpeg_bytes(b, path).is_ok(),
        ),
        fuzz("NPY", &[npy_bytes(&npy), data("fortran.npy")], n, 3, |b| {
            read_npy_bytes(b, path).is_ok()
        }),
        fuzz(
            "NPZ",
            &[
                npz_bytes(&[("a", &npy)]),
                data("cameras_sphere.npz"),
                data("compressed.npz"),
            ],
            n,
            4,
            |b| read_npz_bytes(b, path).is_ok(),
        ),
        fuzz(
            "PLY",
            &[
                write_ply_bytes(&ply, PlyEncoding::Ascii),
                write_ply_bytes(&ply, PlyEncoding::BinaryLittleEndian),
            ],
            n,
            5,
            |b| read_ply_bytes(b, path).is_ok(),
        ),
        fuzz(
            "OBJ",
            &[b"v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nvn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\nf 1 3 2\n".to_vec()],
            n,
            6,
            |b| read_obj_bytes(b, path).is_ok(),
        ),
        fuzz("safetensors", &[data("official.safetensors")], n, 7, |b| {
            read_safetensors_bytes(b, path).is_ok()
        }),
        fuzz("truth.json", std::slice::from_ref(&truth_text), n, 8, |b| {
            read_truth_bytes(b, path).is_ok()
        }),
        fuzz(
            "trajectory.json",
            &[write_trajectory_bytes(&truth.videos[0], path).unwrap()],
            n,
            9,
            |b| read_trajectory_bytes(b, path).is_ok(),
        ),
    ];
    let largest = LARGEST.load(Ordering::Relaxed);
    for r in &reports {
        println!("{r}");
    }
    println!(
        "largest single allocation: {:.1} MiB",
        largest as f64 / (1 << 20) as f64
    );
    for r in &reports {
        assert!(r.panics.is_empty(), "{r}: {:?}", &r.panics[..r.panics.len().min(5)]);
        assert!(r.slowest.as_secs_f64() < 1.0, "{r}");
        // Mutants are mostly broken, but not all: the fuzzer reaches past the first check.
        assert!(r.accepted > 0 && r.accepted < r.cases, "{r}");
    }
    assert!(largest < 256 << 20, "an allocation of {largest} bytes");
}
