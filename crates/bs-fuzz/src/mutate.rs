//! The mutations: bit flips, byte insertions and deletions, truncation, splicing two files,
//! numbers replaced by hostile counts (2000000000, -1, nan, ...), binary words overwritten
//! with such counts, lines duplicated or dropped. Deterministic for a seed.

/// The workspace's one seeded generator: the same inputs for a seed.
pub type Rng = bs_mesh::rng::SplitMix64;

/// Numbers a hostile file puts where a count or coordinate belongs.
const HOSTILE_NUMBERS: [&str; 16] = [
    "2000000000",
    "-1",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "0",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "-2147483648",
    "9223372036854775807",
    "1e308",
    "-0",
    "99999999999999999999999",
    "1e-320",
];

/// Binary words a hostile file puts where a count or size belongs (little-endian).
const HOSTILE_WORDS: [u64; 8] = [
    2_000_000_000,
    u32::MAX as u64,
    0x8000_0000,
    0x7FFF_FFFF,
    u64::MAX,
    0x7FF8_0000_0000_0000, // NaN as f64
    0,
    1 << 40,
];

const INTERESTING_BYTES: &[u8] = b"\n\r \t-+.,0189eE*<>\"/=#$\0\xff";

/// One random mutation of `data`; `other` is another seed of the same reader (splicing).
pub fn mutate_once(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    match rng.below(10) {
        // Bit flips.
        0 => {
            if !data.is_empty() {
                for _ in 0..=rng.below(4) {
                    let i = rng.below(data.len());
                    data[i] ^= 1 << rng.below(8);
                }
            }
        }
        // Insert bytes.
        1 => {
            let at = rng.below(data.len() + 1);
            let n = 1 + rng.below(8);
            for _ in 0..n {
                let b = if rng.below(2) == 0 {
                    *rng.pick(INTERESTING_BYTES)
                } else {
                    rng.next_u64() as u8
                };
                data.insert(at, b);
            }
        }
        // Delete a range.
        2 => {
            if !data.is_empty() {
                let at = rng.below(data.len());
                let longest = if rng.below(4) == 0 { 256 } else { 8 };
                let n = (1 + rng.below(longest)).min(data.len() - at);
                data.drain(at..at + n);
            }
        }
        // Truncate.
        3 => {
            let at = rng.below(data.len() + 1);
            data.truncate(at);
        }
        // Splice: a prefix of this file and a suffix of the other.
        4 => {
            if !other.is_empty() {
                let a = rng.below(data.len() + 1);
                let b = rng.below(other.len());
                data.truncate(a);
                data.extend_from_slice(&other[b..]);
            }
        }
        // Replace a number by a hostile one.
        5 | 6 => {
            let spans = number_spans(data);
            if !spans.is_empty() {
                let (a, b) = *rng.pick(&spans);
                let n = rng.pick(&HOSTILE_NUMBERS).as_bytes();
                data.splice(a..b, n.iter().copied());
            }
        }
        // Duplicate or drop a line.
        7 => {
            let starts = line_starts(data);
            let k = rng.below(starts.len());
            let (a, b) = (starts[k], starts.get(k + 1).copied().unwrap_or(data.len()));
            if rng.below(3) == 0 {
                data.drain(a..b);
            } else {
                let line = data[a..b].to_vec();
                let times = if rng.below(4) == 0 { 1 + rng.below(50) } else { 1 };
                for _ in 0..times {
                    data.splice(b..b, line.iter().copied());
                }
            }
        }
        // Overwrite a binary word with a hostile count.
        8 => {
            let width = if rng.below(2) == 0 { 4 } else { 8 };
            if data.len() >= width {
                let at = rng.below(data.len() - width + 1);
                let word = rng.pick(&HOSTILE_WORDS).to_le_bytes();
                data[at..at + width].copy_from_slice(&word[..width]);
            }
        }
        // Overwrite a byte with an interesting one.
        _ => {
            if !data.is_empty() {
                let i = rng.below(data.len());
                data[i] = *rng.pick(INTERESTING_BYTES);
            }
        }
    }
}

/// Byte ranges of the decimal numbers (digits with sign, point, exponent) in `data`.
fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if data[i].is_ascii_digit() {
            let mut a = i;
            if a > 0 && data[a - 1] == b'-' {
                a -= 1;
            }
            while i < data.len() && (data[i].is_ascii_digit() || b".eE+-".contains(&data[i])) {
                i += 1;
            }
            spans.push((a, i));
        } else {
            i += 1;
        }
    }
    spans
}

fn line_starts(data: &[u8]) -> Vec<usize> {
    std::iter::once(0)
        .chain(data.iter().enumerate().filter(|&(_, &b)| b == b'\n').map(|(i, _)| i + 1))
        .filter(|&i| i < data.len() || i == 0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_are_deterministic_and_change_the_input() {
        let seed = b"*NODE\n1, 0.0, 1.5, 2\n2, 3, 4, 5\n".to_vec();
        let run = |s| {
            let mut rng = Rng::new(s);
            (0..200)
                .map(|_| {
                    let mut d = seed.clone();
                    mutate_once(&mut rng, &mut d, b"other file\n");
                    d
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(run(3), run(3));
        assert!(run(3).iter().filter(|d| **d != seed).count() > 150);
        assert_eq!(number_spans(b"a -12.5e3 7"), vec![(2, 9), (10, 11)]);
    }
}
