//! The seeded mutator: byte-level mutations for every input, token-level ones
//! for text formats.
//!
//! Every draw comes from a [`vtsm_core::rng::Rng`] positioned by the caller, so
//! one (seed, target, iteration) always gives the same input. One call applies
//! a short stack of mutations (1 to 8, occasionally up to 32) and cuts the
//! result to the target's size cap.

use vtsm_core::rng::Rng;

/// Bytes with a special meaning to parsers (limits, signs, ASCII classes).
const INTERESTING_U8: &[u8] = &[
    0, 1, 2, 0x7f, 0x80, 0xff, b'0', b'9', b'-', b'.', b'e', b' ', b'\n', b'\r', b'\t', b'#', b'/',
    b'"', b'{', b'}', b'[', b']', b',', b':', b'\\',
];

/// 32-bit values that sit on boundaries (sizes, counts, signed limits).
const INTERESTING_U32: &[u32] = &[
    0,
    1,
    2,
    3,
    0x7f,
    0x80,
    0xff,
    0x100,
    0x7fff,
    0x8000,
    0xffff,
    0x1_0000,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
    8192,
    8193,
    16383,
    65535,
    1 << 20,
    1 << 24,
];

/// f32 bit patterns: NaN, infinities, −0, denormals, huge and tiny values.
const INTERESTING_F32: &[f32] = &[
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    -0.0,
    0.0,
    1.0,
    -1.0,
    f32::MAX,
    f32::MIN,
    f32::MIN_POSITIVE,
    1.0e-45,
    1.0e30,
    -1.0e30,
    3.0e38,
    0.5,
    1.0e6,
    1.0e-6,
];

/// Replacements for a number token of a text format.
const NUMBER_TOKENS: &[&str] = &[
    "1e300",
    "-1e300",
    "1e-320",
    "1e39",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "Infinity",
    "-0",
    "0",
    "-1",
    "1",
    "2",
    "3",
    "0.5",
    "1.0000001",
    "99999999999999999999999",
    "-99999999999999999999999",
    "4294967295",
    "4294967296",
    "18446744073709551616",
    "2147483647",
    "2147483648",
    "-2147483648",
    "-2147483649",
    "65535",
    "65536",
    "8192",
    "8193",
    "1e",
    ".",
    "-",
    "0x10",
    "1_000",
    "",
];

/// Fixed draws of the mutator for one input.
pub struct Mutator<'c> {
    rng: Rng,
    /// Other inputs to splice from (the target's corpus and pool).
    pool: &'c [Vec<u8>],
    /// Tokens of the target's format (keywords, punctuation).
    dict: &'c [&'c str],
    text: bool,
    max_len: usize,
}

impl<'c> Mutator<'c> {
    /// A mutator drawing from `rng`, splicing from `pool`, inserting tokens of
    /// `dict`, with token-level mutations when `text`, cutting at `max_len`.
    pub fn new(
        rng: Rng,
        pool: &'c [Vec<u8>],
        dict: &'c [&'c str],
        text: bool,
        max_len: usize,
    ) -> Self {
        Self {
            rng,
            pool,
            dict,
            text,
            max_len,
        }
    }

    fn below(&mut self, n: usize) -> usize {
        self.rng.below(n.min(u32::MAX as usize) as u32) as usize
    }

    fn chance(&mut self, one_in: u32) -> bool {
        self.rng.below(one_in) == 0
    }

    /// Mutate `data` in place.
    pub fn mutate(&mut self, data: &mut Vec<u8>) {
        let stack = if self.chance(16) {
            1 + self.below(32)
        } else if self.text {
            1 + self.below(4)
        } else {
            1 + self.below(8)
        };
        for _ in 0..stack {
            // Text formats: byte-level operations (0..=10) a third of the time,
            // so most inputs stay text and reach past the UTF-8 check.
            let op = if self.text && !self.chance(3) {
                11 + self.below(5)
            } else {
                self.below(11)
            };
            self.apply(op, data);
        }
        data.truncate(self.max_len);
    }

    fn apply(&mut self, op: usize, d: &mut Vec<u8>) {
        match op {
            0 => {
                if !d.is_empty() {
                    let i = self.below(d.len());
                    d[i] ^= 1 << self.below(8);
                }
            }
            1 => {
                if !d.is_empty() {
                    let i = self.below(d.len());
                    let b = self.rng.next_u32() as u8;
                    // Text formats: mostly printable ASCII.
                    d[i] = if self.text && !self.chance(8) {
                        b' ' + b % 95
                    } else {
                        b
                    };
                }
            }
            2 => {
                if !d.is_empty() {
                    let i = self.below(d.len());
                    d[i] = INTERESTING_U8[self.below(INTERESTING_U8.len())];
                }
            }
            3 => {
                let at = self.below(d.len() + 1);
                let n = 1 + self.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| self.rng.next_u32() as u8).collect();
                d.splice(at..at, bytes);
            }
            4 => {
                if !d.is_empty() {
                    let at = self.below(d.len());
                    let n = 1 + self.below((d.len() - at).min(64));
                    d.drain(at..at + n);
                }
            }
            5 => {
                // Copy a range of the input over or into another place.
                if !d.is_empty() {
                    let from = self.below(d.len());
                    let n = 1 + self.below((d.len() - from).min(256));
                    let chunk: Vec<u8> = d[from..from + n].to_vec();
                    let at = self.below(d.len() + 1);
                    if self.chance(2) {
                        d.splice(at..at, chunk);
                    } else {
                        let end = (at + n).min(d.len());
                        d.splice(at..end, chunk);
                    }
                }
            }
            6 => self.splice(d),
            7 => {
                if !d.is_empty() {
                    let n = self.below(d.len());
                    d.truncate(n);
                }
            }
            8 => {
                // An interesting integer or float, little or big endian.
                let bytes: Vec<u8> = match self.below(4) {
                    0 => {
                        let v = INTERESTING_U32[self.below(INTERESTING_U32.len())];
                        if self.chance(2) {
                            v.to_le_bytes().to_vec()
                        } else {
                            v.to_be_bytes().to_vec()
                        }
                    }
                    1 => {
                        let v = INTERESTING_U32[self.below(INTERESTING_U32.len())] as u16;
                        v.to_le_bytes().to_vec()
                    }
                    2 => {
                        let v = INTERESTING_F32[self.below(INTERESTING_F32.len())];
                        if self.chance(2) {
                            v.to_le_bytes().to_vec()
                        } else {
                            v.to_be_bytes().to_vec()
                        }
                    }
                    _ => {
                        let v = [i64::MAX, i64::MIN, -1, 1 << 40][self.below(4)];
                        v.to_le_bytes().to_vec()
                    }
                };
                self.overwrite(d, &bytes);
            }
            9 => {
                // Small arithmetic on one byte.
                if !d.is_empty() {
                    let i = self.below(d.len());
                    let delta = 1 + self.below(16) as u8;
                    d[i] = if self.chance(2) {
                        d[i].wrapping_add(delta)
                    } else {
                        d[i].wrapping_sub(delta)
                    };
                }
            }
            10 => self.insert_token(d),
            // Text formats only.
            11 | 12 => self.replace_number(d),
            13 => self.line_op(d),
            14 => self.insert_token(d),
            _ => self.number_from_elsewhere(d),
        }
    }

    fn overwrite(&mut self, d: &mut Vec<u8>, bytes: &[u8]) {
        if d.len() < bytes.len() {
            d.extend_from_slice(bytes);
            return;
        }
        let at = self.below(d.len() - bytes.len() + 1);
        d[at..at + bytes.len()].copy_from_slice(bytes);
    }

    fn splice(&mut self, d: &mut Vec<u8>) {
        if self.pool.is_empty() {
            return;
        }
        let other = &self.pool[self.below(self.pool.len())];
        if other.is_empty() {
            return;
        }
        let from = self.below(other.len());
        let n = 1 + self.below(other.len() - from);
        let chunk = other[from..from + n].to_vec();
        let at = self.below(d.len() + 1);
        if self.chance(2) {
            // Crossover: keep our head, take the other's tail.
            d.truncate(at);
            d.extend_from_slice(&chunk);
        } else {
            d.splice(at..at, chunk);
        }
    }

    fn insert_token(&mut self, d: &mut Vec<u8>) {
        if self.dict.is_empty() {
            return;
        }
        let tok = self.dict[self.below(self.dict.len())].as_bytes().to_vec();
        // At a line start (text) or anywhere.
        let at = if self.text && self.chance(2) {
            let starts = line_starts(d);
            starts[self.below(starts.len())]
        } else {
            self.below(d.len() + 1)
        };
        let mut tok = tok;
        if self.text {
            tok.push(if self.chance(2) { b' ' } else { b'\n' });
        }
        d.splice(at..at, tok);
    }

    fn replace_number(&mut self, d: &mut Vec<u8>) {
        let spans = number_spans(d);
        if spans.is_empty() {
            return self.insert_token(d);
        }
        let (a, b) = spans[self.below(spans.len())];
        let rep: Vec<u8> = if self.chance(4) {
            // A random integer of random width and sign.
            let v = self.rng.next_u64() >> self.below(64);
            let s = if self.chance(2) {
                format!("-{v}")
            } else {
                v.to_string()
            };
            s.into_bytes()
        } else {
            NUMBER_TOKENS[self.below(NUMBER_TOKENS.len())]
                .as_bytes()
                .to_vec()
        };
        d.splice(a..b, rep);
    }

    fn number_from_elsewhere(&mut self, d: &mut Vec<u8>) {
        let spans = number_spans(d);
        if spans.len() < 2 {
            return self.replace_number(d);
        }
        let (a, b) = spans[self.below(spans.len())];
        let (c, e) = spans[self.below(spans.len())];
        let rep = d[c..e].to_vec();
        d.splice(a..b, rep);
    }

    fn line_op(&mut self, d: &mut Vec<u8>) {
        let starts = line_starts(d);
        let line = |k: usize| -> (usize, usize) {
            let a = starts[k];
            let b = starts.get(k + 1).copied().unwrap_or(d.len());
            (a, b)
        };
        let k = self.below(starts.len());
        let (a, b) = line(k);
        match self.below(4) {
            0 => {
                let l = d[a..b].to_vec();
                d.splice(a..a, l);
            }
            1 => {
                d.drain(a..b);
            }
            2 => {
                let j = self.below(starts.len());
                let (c, e) = line(j);
                let l = d[c..e].to_vec();
                d.splice(a..a, l);
            }
            _ => {
                // Many copies of one line (element counts, long lists).
                let l = d[a..b].to_vec();
                let n = 1 + self.below(64);
                for _ in 0..n {
                    d.splice(a..a, l.iter().copied());
                }
            }
        }
    }
}

/// Offsets at which lines start (always includes 0).
fn line_starts(d: &[u8]) -> Vec<usize> {
    let mut v = vec![0];
    v.extend(
        d.iter()
            .enumerate()
            .filter(|(_, &c)| c == b'\n')
            .map(|(i, _)| i + 1)
            .filter(|&i| i < d.len()),
    );
    v
}

/// Byte ranges of number-like tokens: a run of `[0-9.eE+-]` holding a digit.
fn number_spans(d: &[u8]) -> Vec<(usize, usize)> {
    let numch = |c: u8| c.is_ascii_digit() || matches!(c, b'.' | b'e' | b'E' | b'+' | b'-');
    let mut out = Vec::new();
    let mut i = 0;
    while i < d.len() {
        if numch(d[i]) && (i == 0 || !d[i - 1].is_ascii_alphanumeric()) {
            let a = i;
            while i < d.len() && numch(d[i]) {
                i += 1;
            }
            if d[a..i].iter().any(u8::is_ascii_digit) {
                out.push((a, i));
            }
        } else {
            i += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_number_tokens() {
        let d = b"v 1.5 -2e3 x9 abc\nf 1/2";
        let s = number_spans(d);
        let toks: Vec<&[u8]> = s.iter().map(|&(a, b)| &d[a..b]).collect();
        assert_eq!(
            toks,
            [&b"1.5"[..], &b"-2e3"[..], &b"1"[..], &b"2"[..]].to_vec()
        );
    }

    #[test]
    fn same_rng_same_mutation() {
        let pool = vec![b"v 1 2 3\nf 1 2 3\n".to_vec()];
        let run = |seed| {
            let mut d = pool[0].clone();
            Mutator::new(Rng::new(seed), &pool, &["v", "f"], true, 1 << 16).mutate(&mut d);
            d
        };
        assert_eq!(run(7), run(7));
        assert!((0..20).any(|s| run(s) != pool[0]));
    }
}
