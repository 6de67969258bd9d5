//! Console lines assembled without `core::fmt`.
//!
//! `core::fmt` is precompiled with bounds checks whose panic paths the linker
//! keeps, so an image that formats through it can never pass the panic-freedom
//! check (`--features panic-check`). The report needs only text, unsigned
//! decimals and fixed-width hexadecimal, which this module writes into a fixed
//! line buffer: a line longer than the buffer is cut, never an error.

/// One output line, printed by [`Line::end`].
pub struct Line {
    buf: [u8; 192],
    len: usize,
}

impl Line {
    /// An empty line.
    pub fn new() -> Self {
        Self {
            buf: [0; 192],
            len: 0,
        }
    }

    /// Appends bytes, cutting what does not fit.
    fn bytes(mut self, bytes: &[u8]) -> Self {
        let mut written = 0usize;
        if let Some(free) = self.buf.get_mut(self.len..) {
            for (dst, &src) in free.iter_mut().zip(bytes) {
                *dst = src;
                written = written.wrapping_add(1);
            }
        }
        self.len = self.len.wrapping_add(written).min(self.buf.len());
        self
    }

    /// Appends text.
    pub fn s(self, text: &str) -> Self {
        self.bytes(text.as_bytes())
    }

    /// Appends `v` in decimal.
    pub fn u(self, mut v: u64) -> Self {
        let mut digits = [0u8; 20];
        let mut n = 0usize;
        for slot in digits.iter_mut().rev() {
            // `v % 10` < 10: the cast and the addition cannot overflow.
            *slot = b'0'.wrapping_add((v % 10) as u8);
            v /= 10;
            n = n.wrapping_add(1);
            if v == 0 {
                break;
            }
        }
        let start = digits.len().saturating_sub(n);
        self.bytes(digits.get(start..).unwrap_or(&[]))
    }

    /// Appends the low `width` hexadecimal digits of `v` (at most 16), zero-padded.
    pub fn hex(self, v: u64, width: u32) -> Self {
        const HEX: &[u8; 16] = b"0123456789abcdef";
        let width = width.min(16);
        let mut digits = [0u8; 16];
        for (i, slot) in digits.iter_mut().take(width as usize).enumerate() {
            // i < width ≤ 16, so the shift is below 64.
            let shift = 4 * (width as usize).wrapping_sub(1).wrapping_sub(i);
            let nibble = (v >> (shift & 63)) & 0xF;
            *slot = HEX.get(nibble as usize).copied().unwrap_or(b'?');
        }
        self.bytes(digits.get(..width as usize).unwrap_or(&[]))
    }

    /// Ends the line with a newline and prints it.
    pub fn end(mut self) {
        // A cut line still ends with its newline.
        self.len = self.len.min(self.buf.len().saturating_sub(1));
        let line = self.bytes(b"\n");
        crate::start::print(line.buf.get(..line.len).unwrap_or(&[]));
    }
}
