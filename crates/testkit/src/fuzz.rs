//! Mutation fuzzing on stable Rust, inside the test suite: valid files are mutated the ways real damage and
//! hostile headers look (truncation, bit flips, runs of 0xFF where counts live, inserted and deleted spans,
//! numbers in text replaced by `nan`, `inf` or huge values) and each mutant is handed to a parser, which must
//! return (an error is fine) without panicking. Deterministic: a seed gives the same cases.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};

/// Mutations drawn from a seeded generator.
pub struct Mutator {
    rng: geom::SplitMix64,
}

/// Text that replaces a number in a text format.
const NUMBERS: [&str; 9] = [
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e308",
    "4294967296",
    "99999999999999999999",
    "1.5",
];

impl Mutator {
    pub fn new(seed: u64) -> Self {
        Self {
            rng: geom::SplitMix64::new(seed),
        }
    }

    fn next(&mut self) -> u64 {
        self.rng.next_u64()
    }

    /// Uniform in `0..n` (0 when `n` is 0).
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }

    /// `input` with one to three mutations applied.
    pub fn mutate(&mut self, input: &[u8]) -> Vec<u8> {
        let mut b = input.to_vec();
        for _ in 0..1 + self.below(3) {
            self.mutate_once(&mut b);
        }
        b
    }

    fn mutate_once(&mut self, b: &mut Vec<u8>) {
        let len = b.len();
        match self.below(9) {
            0 => b.truncate(self.below(len + 1)),
            1 => {
                for _ in 0..1 + self.below(8) {
                    if len > 0 {
                        let i = self.below(len);
                        b[i] ^= 1 << self.below(8);
                    }
                }
            }
            2 if len > 0 => {
                let i = self.below(len);
                b[i] = [0x00, 0xFF, 0x7F, 0x80][self.below(4)];
            }
            3 if len > 0 => {
                // A run of 0xFF: a count or a size field becomes huge.
                let i = self.below(len);
                let n = (4 + self.below(5)).min(len - i);
                b[i..i + n].fill(0xFF);
            }
            4 => {
                let at = self.below(len + 1);
                let n = 1 + self.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| self.next() as u8).collect();
                b.splice(at..at, bytes);
            }
            5 if len > 0 => {
                let i = self.below(len);
                let n = 1 + self.below((len - i).min(64));
                b.drain(i..i + n);
            }
            6 if len > 0 => {
                let i = self.below(len);
                let n = 1 + self.below((len - i).min(64));
                let chunk = b[i..i + n].to_vec();
                let at = self.below(len + 1);
                b.splice(at..at, chunk);
            }
            7 => {
                // A number in text replaced by another, or by something that is not one.
                let starts: Vec<usize> = (0..len)
                    .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit()))
                    .collect();
                if !starts.is_empty() {
                    let s = starts[self.below(starts.len())];
                    let e = (s..len)
                        .find(|&i| !(b[i].is_ascii_digit() || b[i] == b'.'))
                        .unwrap_or(len);
                    let with = NUMBERS[self.below(NUMBERS.len())].as_bytes().to_vec();
                    b.splice(s..e, with);
                }
            }
            _ if len > 1 => {
                let (i, j) = (self.below(len), self.below(len));
                b.swap(i, j);
            }
            _ => b.push(self.next() as u8),
        }
    }
}

/// What a fuzz run found.
#[derive(Debug)]
pub struct FuzzReport {
    pub name: String,
    pub cases: usize,
    /// Cases the parser accepted (the rest returned an error).
    pub accepted: usize,
    /// The panics: case number and message.
    pub panics: Vec<(usize, String)>,
    pub elapsed: Duration,
    pub slowest: Duration,
}

impl std::fmt::Display for FuzzReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} cases in {:.2} s ({} accepted, {} panics, slowest case {:.1} ms)",
            self.name,
            self.cases,
            self.elapsed.as_secs_f64(),
            self.accepted,
            self.panics.len(),
            self.slowest.as_secs_f64() * 1e3
        )
    }
}

/// Hands `cases` mutants of the `seeds` (each a valid input) to `parse`, which returns whether it accepted
/// the input; catches and records panics.
pub fn fuzz(name: &str, seeds: &[Vec<u8>], cases: usize, seed: u64, parse: impl Fn(&[u8]) -> bool) -> FuzzReport {
    assert!(!seeds.is_empty(), "{name}: no seed inputs");
    let mut m = Mutator::new(seed);
    let mut report = FuzzReport {
        name: name.to_string(),
        cases,
        accepted: 0,
        panics: Vec::new(),
        elapsed: Duration::ZERO,
        slowest: Duration::ZERO,
    };
    let t0 = Instant::now();
    for case in 0..cases {
        let input = m.mutate(&seeds[case % seeds.len()]);
        let t = Instant::now();
        match catch_unwind(AssertUnwindSafe(|| parse(&input))) {
            Ok(accepted) => report.accepted += accepted as usize,
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                report.panics.push((case, msg));
            }
        }
        report.slowest = report.slowest.max(t.elapsed());
    }
    report.elapsed = t0.elapsed();
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutants_are_deterministic_and_varied() {
        let seed = b"ply\nelement vertex 3\n1.0 2.0 3.0\n".to_vec();
        let a: Vec<Vec<u8>> = {
            let mut m = Mutator::new(7);
            (0..200).map(|_| m.mutate(&seed)).collect()
        };
        let mut m = Mutator::new(7);
        assert!((0..200).all(|k| m.mutate(&seed) == a[k]));
        let distinct: std::collections::BTreeSet<&Vec<u8>> = a.iter().collect();
        assert!(distinct.len() > 150, "{}", distinct.len());
        assert!(a.iter().any(|x| x.len() < seed.len()) && a.iter().any(|x| x.len() > seed.len()));
        assert!(a.iter().any(|x| x.windows(3).any(|w| w == b"nan" || w == b"inf")));
    }

    #[test]
    fn panics_are_caught_and_counted() {
        let r = fuzz("toy", &[vec![1, 2, 3]], 100, 1, |b| {
            assert!(b.len() != 2, "two bytes");
            true
        });
        assert!(!r.panics.is_empty() && r.panics.iter().all(|(_, m)| m == "two bytes"));
        assert_eq!(r.accepted + r.panics.len(), 100);
    }
}
