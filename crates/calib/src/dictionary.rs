//! OpenCV's predefined marker dictionaries: each marker's inner bits, and the identification of a read bit
//! grid (any of four rotations) with the dictionary's error correction.
//!
//! The bit tables are data (`data/dictionaries.txt`), extracted once from OpenCV by
//! `data/extract_dictionaries.py`; the tables of one marker size (`_50` … `_1000`) are prefixes of one.

use std::sync::OnceLock;

/// One predefined dictionary: `count` markers of `marker_size` × `marker_size` inner bits.
#[derive(Debug)]
pub struct Dictionary {
    /// OpenCV's name, e.g. `DICT_5X5_1000`.
    pub name: &'static str,
    /// Inner bits per side (the black border not counted).
    pub marker_size: usize,
    /// The bits a read marker may differ from its code and still be that marker (OpenCV's `maxCorrectionBits`).
    pub max_correction_bits: u32,
    /// Each marker's bits at rotation 0, row by row from the top-left, the first bit the most significant.
    codes: &'static [u64],
}

/// Bits of black border around a marker's inner bits (OpenCV's default `borderBits`).
pub const BORDER_BITS: usize = 1;

static SOURCE: &str = include_str!("../data/dictionaries.txt");

struct Tables {
    dictionaries: Vec<Dictionary>,
}

fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(|| parse_tables(SOURCE))
}

/// Parses the embedded data file; it is part of the build, so a malformed line is a bug, not an input error.
fn parse_tables(source: &'static str) -> Tables {
    let mut tables: Vec<(&'static str, usize, &'static [u64])> = Vec::new();
    let mut dictionaries = Vec::new();
    let mut lines = source.lines().filter(|l| !l.starts_with('#')).peekable();
    while let Some(line) = lines.next() {
        let words: Vec<&'static str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["table", name, "marker_size", size, "count", count] => {
                let size: usize = size.parse().expect("marker size");
                let count: usize = count.parse().expect("count");
                let mut codes = Vec::with_capacity(count);
                while codes.len() < count {
                    let row = lines.next().expect("a table's codes");
                    codes.extend(
                        row.split_whitespace()
                            .map(|h| u64::from_str_radix(h, 16).expect("hex code")),
                    );
                }
                assert_eq!(codes.len(), count, "table {name}");
                tables.push((name, size, Box::leak(codes.into_boxed_slice())));
            }
            ["dictionary", name, "table", table, "count", count, "max_correction_bits", bits] => {
                let (_, size, codes) = tables
                    .iter()
                    .find(|t| t.0 == *table)
                    .expect("table before its dictionaries");
                let count: usize = count.parse().expect("count");
                dictionaries.push(Dictionary {
                    name,
                    marker_size: *size,
                    max_correction_bits: bits.parse().expect("correction bits"),
                    codes: &codes[..count],
                });
            }
            _ => panic!("dictionaries.txt: unexpected line {line:?}"),
        }
    }
    Tables { dictionaries }
}

/// The names of every dictionary, OpenCV's spelling.
pub fn names() -> Vec<&'static str> {
    tables().dictionaries.iter().map(|d| d.name).collect()
}

/// The dictionary OpenCV calls `name` (case does not matter: `DICT_APRILTAG_36h11` is `DICT_APRILTAG_36H11`).
pub fn by_name(name: &str) -> Option<&'static Dictionary> {
    tables().dictionaries.iter().find(|d| d.name.eq_ignore_ascii_case(name))
}

/// A read marker matched to the dictionary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identified {
    /// The marker's id.
    pub id: usize,
    /// Quarter turns clockwise that take the read grid to the marker's rotation-0 bits: the read grid's
    /// top-left corner is the marker's corner `rotation` (0 top-left, 1 top-right, 2 bottom-right, 3 bottom-left).
    pub rotation: usize,
    /// Bits that differ.
    pub distance: u32,
}

impl Dictionary {
    /// Markers in the dictionary.
    pub fn len(&self) -> usize {
        self.codes.len()
    }

    /// Whether the dictionary has no markers (never, for a predefined one).
    pub fn is_empty(&self) -> bool {
        self.codes.is_empty()
    }

    /// Marker `id`'s inner bits, row by row from the top-left (`true` is white).
    pub fn bits(&self, id: usize) -> Vec<bool> {
        (0..self.marker_size * self.marker_size)
            .map(|i| self.bit(id, i))
            .collect()
    }

    /// Bit `index` (row by row from the top-left) of marker `id`: `true` is white.
    pub fn bit(&self, id: usize, index: usize) -> bool {
        let n = self.marker_size * self.marker_size;
        (self.codes[id] >> (n - 1 - index)) & 1 == 1
    }

    /// The marker a read grid of bits is (row by row, `true` white), at the rotation with the fewest
    /// differing bits, if that is within `max_errors`.
    pub fn identify(&self, read: &[bool], max_errors: u32) -> Option<Identified> {
        let n = self.marker_size;
        assert_eq!(read.len(), n * n, "a read marker of {n} x {n} bits");
        let mut rotated = [0u64; 4];
        for (r, code) in rotated.iter_mut().enumerate() {
            *code = pack(&rotate_quarter_turns(read, n, r));
        }
        let mut best: Option<Identified> = None;
        for (id, &code) in self.codes.iter().enumerate() {
            for (rotation, read_code) in rotated.iter().enumerate() {
                let distance = (code ^ read_code).count_ones();
                if distance <= max_errors && best.is_none_or(|b| distance < b.distance) {
                    best = Some(Identified { id, rotation, distance });
                    if distance == 0 {
                        return best;
                    }
                }
            }
        }
        best
    }
}

/// Packs bits row by row, the first the most significant.
fn pack(bits: &[bool]) -> u64 {
    bits.iter().fold(0, |acc, &b| (acc << 1) | b as u64)
}

/// The grid turned `quarter_turns` times clockwise.
pub(crate) fn rotate_quarter_turns(bits: &[bool], n: usize, quarter_turns: usize) -> Vec<bool> {
    let mut out = bits.to_vec();
    for _ in 0..quarter_turns % 4 {
        let prev = out.clone();
        for row in 0..n {
            for col in 0..n {
                // Clockwise: the new row `row` is the old column `row` read bottom to top.
                out[row * n + col] = prev[(n - 1 - col) * n + row];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_dictionary_the_issue_names_is_there_with_its_size() {
        for (name, size, count) in [
            ("DICT_4X4_50", 4, 50),
            ("DICT_4X4_1000", 4, 1000),
            ("DICT_5X5_100", 5, 100),
            ("DICT_5X5_1000", 5, 1000),
            ("DICT_6X6_250", 6, 250),
            ("DICT_6X6_1000", 6, 1000),
            ("DICT_ARUCO_ORIGINAL", 5, 1024),
            ("DICT_APRILTAG_36h11", 6, 587),
        ] {
            let d = by_name(name).unwrap_or_else(|| panic!("{name}"));
            assert_eq!((d.marker_size, d.len()), (size, count), "{name}");
        }
        assert!(by_name("DICT_3X3_10").is_none());
    }

    #[test]
    fn the_first_marker_of_4x4_is_opencvs() {
        // cv2.aruco.Dictionary.getBitsFromByteList(DICT_4X4_50.bytesList[0:1], 4)
        let d = by_name("DICT_4X4_50").unwrap();
        let want = [1, 0, 1, 1, 0, 1, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0].map(|b| b == 1);
        assert_eq!(d.bits(0), want);
    }

    #[test]
    fn identify_finds_each_rotation_and_corrects_errors() {
        let d = by_name("DICT_5X5_1000").unwrap();
        for id in [0, 17, 999] {
            let bits = d.bits(id);
            for turns in 0..4 {
                // Seen turned `turns` clockwise; a clockwise turn of the view by `rotation` brings it back.
                let seen = rotate_quarter_turns(&bits, 5, (4 - turns) % 4);
                let found = d.identify(&seen, 0).unwrap();
                assert_eq!((found.id, found.rotation, found.distance), (id, turns, 0));
                let mut flipped = seen.clone();
                flipped[7] = !flipped[7];
                flipped[18] = !flipped[18];
                let found = d.identify(&flipped, d.max_correction_bits).unwrap();
                assert_eq!((found.id, found.distance), (id, 2));
                assert!(d.identify(&flipped, 1).is_none_or(|f| f.id != id || f.distance <= 1));
            }
        }
    }
}
