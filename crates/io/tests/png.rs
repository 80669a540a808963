//! PNG reading and writing: exact round trips, deterministic bytes, the
//! conversions of other PNG layouts (palette, 16-bit, gray + alpha, low bit
//! depths) built with the png crate's own encoder, and clean errors (never a
//! panic) on truncated or corrupt files.

use std::path::{Path, PathBuf};

use pganeus_io::{encode_png, read_png, read_png_bytes, read_png_size, write_png, Image, IoError};

const P: &str = "mem.png";

/// A deterministic pattern with every sample different from its neighbours.
fn pattern(width: u32, height: u32, channels: u8) -> Image {
    let mut img = Image::new(width, height, channels);
    for y in 0..height {
        for x in 0..width {
            for (c, s) in img.pixel_mut(x, y).iter_mut().enumerate() {
                *s = ((x * 37 + y * 101 + c as u32 * 59) % 256) as u8;
            }
        }
    }
    img
}

/// Encodes raw samples with the png crate directly, in any layout.
fn encode_raw(
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    palette: Option<(&[u8], Option<&[u8]>)>,
    data: &[u8],
) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(color);
    enc.set_depth(depth);
    if let Some((plte, trns)) = palette {
        enc.set_palette(plte.to_vec());
        if let Some(t) = trns {
            enc.set_trns(t.to_vec());
        }
    }
    let mut w = enc.write_header().unwrap();
    w.write_image_data(data).unwrap();
    w.finish().unwrap();
    out
}

struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let d = std::env::temp_dir().join(format!("pganeus_io_png_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        TempDir(d)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn round_trip_gray_rgb_rgba_exact() {
    for channels in [1u8, 3, 4] {
        let img = pattern(13, 7, channels);
        let bytes = encode_png(&img);
        let back = read_png_bytes(&bytes, Path::new(P)).unwrap();
        assert_eq!(back, img, "{channels} channels");
    }
}

#[test]
fn round_trip_through_a_file() {
    let dir = TempDir::new("file");
    let path = dir.0.join("sub/000.png");
    let img = pattern(31, 17, 3);
    write_png(&path, &img).unwrap();
    assert_eq!(read_png(&path).unwrap(), img);
    assert_eq!(read_png_size(&path).unwrap(), (31, 17));
}

#[test]
fn encoding_is_deterministic() {
    let img = pattern(64, 48, 4);
    let a = encode_png(&img);
    let b = encode_png(&img.clone());
    assert_eq!(a, b);
    let mut other = img.clone();
    other.pixel_mut(5, 5)[0] ^= 1;
    assert_ne!(encode_png(&other), a, "a different image must give different bytes");
}

#[test]
fn pixel_access_and_conversions() {
    let mut img = Image::new(3, 2, 4);
    img.pixel_mut(2, 1).copy_from_slice(&[10, 20, 30, 40]);
    assert_eq!(img.pixel(2, 1), &[10, 20, 30, 40]);
    assert_eq!(
        &img.data[(3 + 2) * 4..(3 + 2) * 4 + 4],
        &[10, 20, 30, 40],
        "row-major layout"
    );

    let rgb = img.to_rgb();
    assert_eq!(rgb.channels, 3);
    assert_eq!(rgb.pixel(2, 1), &[10, 20, 30]);
    rgb.check().unwrap();

    let gray = Image {
        width: 2,
        height: 1,
        channels: 1,
        data: vec![7, 200],
    };
    assert_eq!(gray.to_rgb().data, vec![7, 7, 7, 200, 200, 200]);
    assert_eq!(gray.to_gray(), gray);

    // Luma, rounded; black and white stay exact so masks threshold the same.
    let colours = Image {
        width: 4,
        height: 1,
        channels: 3,
        data: vec![0, 0, 0, 255, 255, 255, 255, 0, 0, 10, 20, 30],
    };
    let g = colours.to_gray();
    assert_eq!(g.channels, 1);
    // 0.299*255 = 76.245 → 76; 0.299*10 + 0.587*20 + 0.114*30 = 18.15 → 18.
    assert_eq!(g.data, vec![0, 255, 76, 18]);
    let mut rgba = colours.clone();
    rgba.channels = 4;
    rgba.data = colours.data.chunks(3).flat_map(|p| [p[0], p[1], p[2], 9]).collect();
    assert_eq!(rgba.to_gray(), g, "alpha is ignored");
}

#[test]
fn check_reports_bad_lengths() {
    let mut img = Image::new(4, 4, 3);
    img.check().unwrap();
    img.data.pop();
    assert!(img.check().unwrap_err().contains("48"));
    let err = write_png(Path::new("never_written.png"), &img).unwrap_err();
    assert!(matches!(err, IoError::Png { .. }), "{err}");
    assert!(!Path::new("never_written.png").exists());
    img.channels = 2;
    img.data = vec![0; 32];
    assert!(img.check().is_err());
}

#[test]
fn palette_is_expanded() {
    let plte = [255, 0, 0, 0, 255, 0, 0, 0, 255, 9, 8, 7];
    // 2-bit indices: 4 pixels per byte; a 5x2 image has 2 bytes per row.
    let indices = [[0u8, 1, 2, 3, 1], [3, 2, 1, 0, 0]];
    let pack = |row: &[u8; 5]| {
        let mut bytes = [0u8; 2];
        for (i, &v) in row.iter().enumerate() {
            bytes[i / 4] |= v << (6 - 2 * (i % 4));
        }
        bytes
    };
    let data: Vec<u8> = indices.iter().flat_map(pack).collect();
    let bytes = encode_raw(
        5,
        2,
        png::ColorType::Indexed,
        png::BitDepth::Two,
        Some((&plte, None)),
        &data,
    );
    let img = read_png_bytes(&bytes, Path::new(P)).unwrap();
    assert_eq!((img.width, img.height, img.channels), (5, 2, 3));
    for (y, row) in indices.iter().enumerate() {
        for (x, &i) in row.iter().enumerate() {
            let i = i as usize;
            assert_eq!(img.pixel(x as u32, y as u32), &plte[3 * i..3 * i + 3], "({x}, {y})");
        }
    }

    // With tRNS the palette gives RGBA; entries past the tRNS list are opaque.
    let data8 = [0u8, 1, 2, 3];
    let bytes = encode_raw(
        2,
        2,
        png::ColorType::Indexed,
        png::BitDepth::Eight,
        Some((&plte, Some(&[0, 128]))),
        &data8,
    );
    let img = read_png_bytes(&bytes, Path::new(P)).unwrap();
    assert_eq!(img.channels, 4);
    assert_eq!(
        img.data,
        vec![255, 0, 0, 0, 0, 255, 0, 128, 0, 0, 255, 255, 9, 8, 7, 255]
    );
}

#[test]
fn sixteen_bit_keeps_the_high_byte() {
    // RGB16, big-endian samples: 0x1234 → 0x12.
    let samples: [u16; 6] = [0x1234, 0xffff, 0x0001, 0x8000, 0x7fff, 0x00ff];
    let data: Vec<u8> = samples.iter().flat_map(|s| s.to_be_bytes()).collect();
    let bytes = encode_raw(2, 1, png::ColorType::Rgb, png::BitDepth::Sixteen, None, &data);
    let img = read_png_bytes(&bytes, Path::new(P)).unwrap();
    assert_eq!(img.channels, 3);
    assert_eq!(img.data, vec![0x12, 0xff, 0x00, 0x80, 0x7f, 0x00]);

    let bytes = encode_raw(
        3,
        1,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        None,
        &data[..6],
    );
    let img = read_png_bytes(&bytes, Path::new(P)).unwrap();
    assert_eq!((img.channels, img.data.clone()), (1, vec![0x12, 0xff, 0x00]));

    let bytes = encode_raw(1, 1, png::ColorType::Rgba, png::BitDepth::Sixteen, None, &data[..8]);
    assert_eq!(
        read_png_bytes(&bytes, Path::new(P)).unwrap().data,
        vec![0x12, 0xff, 0x00, 0x80]
    );
}

#[test]
fn gray_alpha_becomes_rgba_and_low_bit_gray_is_scaled() {
    let bytes = encode_raw(
        2,
        1,
        png::ColorType::GrayscaleAlpha,
        png::BitDepth::Eight,
        None,
        &[10, 20, 250, 0],
    );
    let img = read_png_bytes(&bytes, Path::new(P)).unwrap();
    assert_eq!(img.channels, 4);
    assert_eq!(img.data, vec![10, 10, 10, 20, 250, 250, 250, 0]);

    // 1-bit gray: 0 → 0, 1 → 255.
    let bytes = encode_raw(
        3,
        1,
        png::ColorType::Grayscale,
        png::BitDepth::One,
        None,
        &[0b1010_0000],
    );
    let img = read_png_bytes(&bytes, Path::new(P)).unwrap();
    assert_eq!((img.channels, img.data.clone()), (1, vec![255, 0, 255]));
}

#[test]
fn truncated_files_are_errors_not_panics() {
    let bytes = encode_png(&pattern(16, 16, 3));
    for len in 0..bytes.len() {
        let err = read_png_bytes(&bytes[..len], Path::new("cut.png")).expect_err(&format!("cut at {len}"));
        match &err {
            IoError::Png { path, msg } => {
                assert_eq!(path, Path::new("cut.png"));
                assert!(!msg.is_empty());
            }
            e => panic!("cut at {len}: unexpected error {e}"),
        }
    }
    let msg = read_png_bytes(&bytes[..bytes.len() / 2], Path::new("cut.png"))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("cut.png") && msg.contains("truncated"), "{msg}");
}

#[test]
fn not_a_png() {
    let msg = read_png_bytes(b"GIF89a.......", Path::new("x.png"))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("x.png") && msg.contains("not a PNG"), "{msg}");
    let dir = TempDir::new("notpng");
    let path = dir.0.join("fake.png");
    std::fs::write(&path, b"hello, I am text").unwrap();
    let msg = read_png_size(&path).unwrap_err().to_string();
    assert!(msg.contains("fake.png") && msg.contains("not a PNG"), "{msg}");
    assert!(matches!(read_png(&dir.0.join("absent.png")), Err(IoError::Open { .. })));
}

#[test]
fn corrupt_bytes_are_errors_not_panics() {
    let good = encode_png(&pattern(20, 12, 4));
    // Deterministic pseudo-random corruptions (xorshift).
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut errors = 0;
    for _ in 0..2000 {
        let mut bytes = good.clone();
        for _ in 0..1 + next() % 4 {
            let i = (next() % bytes.len() as u64) as usize;
            bytes[i] = next() as u8;
        }
        // Either a clean error or a consistent image; never a panic.
        match read_png_bytes(&bytes, Path::new(P)) {
            Ok(img) => img.check().unwrap(),
            Err(IoError::Png { .. }) => errors += 1,
            Err(e) => panic!("unexpected error {e}"),
        }
    }
    assert!(errors > 1000, "CRCs should catch most corruptions, caught {errors}");

    // A header claiming a huge image in a tiny file is refused before allocating.
    let mut bytes = encode_png(&pattern(1, 1, 1));
    bytes[16..24].copy_from_slice(&[0, 1, 0, 0, 0, 1, 0, 0]); // 65536 x 65536
    let ihdr_crc = crc32(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&ihdr_crc.to_be_bytes());
    let msg = read_png_bytes(&bytes, Path::new(P)).unwrap_err().to_string();
    assert!(msg.contains("65536x65536"), "{msg}");
}

/// Bitwise CRC-32 (the PNG/ZIP polynomial), to forge a valid IHDR.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Every frame of an APNG, drawn over the one before as its frame control says.
fn decode_apng(bytes: &[u8]) -> Vec<Vec<u8>> {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
    let (w, h) = (reader.info().width as usize, reader.info().height as usize);
    let n = reader.info().animation_control.unwrap().num_frames;
    let mut canvas = vec![0u8; w * h * 3];
    let mut out = Vec::new();
    for _ in 0..n {
        let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
        reader.next_frame(&mut buf).unwrap();
        let fc = reader.info().frame_control.unwrap();
        assert_eq!(fc.blend_op, png::BlendOp::Source);
        let (x0, y0, fw) = (fc.x_offset as usize, fc.y_offset as usize, fc.width as usize);
        for y in 0..fc.height as usize {
            let dst = ((y0 + y) * w + x0) * 3;
            canvas[dst..dst + fw * 3].copy_from_slice(&buf[y * fw * 3..(y + 1) * fw * 3]);
        }
        out.push(canvas.clone());
    }
    out
}

#[test]
fn an_animation_stores_only_what_changed_and_plays_back_every_frame() {
    // A still 64×48 background with a 6×5 square moving across it, and one repeated frame.
    let frame = |k: usize| {
        let mut img = Image::new(64, 48, 3);
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = ((i * 7919) % 251) as u8;
        }
        for y in 10..15 {
            for x in 4 + 5 * k..10 + 5 * k {
                img.data[(y * 64 + x) * 3..(y * 64 + x) * 3 + 3].copy_from_slice(&[255, 0, 0]);
            }
        }
        img
    };
    let mut frames: Vec<Image> = (0..8).map(frame).collect();
    frames.push(frames[7].clone());
    let d = std::env::temp_dir().join(format!("pganeus_io_apng_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let path = d.join("a.png");
    pganeus_io::write_apng(&path, &frames, 30.0).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let back = decode_apng(&bytes);
    assert_eq!(back.len(), frames.len());
    for (k, (b, f)) in back.iter().zip(&frames).enumerate() {
        assert!(b == &f.data, "frame {k} differs after playback");
    }
    // The noisy background is stored once: nine whole frames would not compress below 8 × 9 kB.
    assert!(bytes.len() < 9216 + 8 * 600, "{} bytes", bytes.len());
    // Viewers without APNG support read the first frame.
    assert_eq!(pganeus_io::read_png(&path).unwrap(), frames[0]);
    let _ = std::fs::remove_dir_all(&d);
}
