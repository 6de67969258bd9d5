//! CRC-32 (IEEE 802.3, reflected, the zlib checksum) of the map product,
//! slicing by eight with tables built at compile time.
//!
//! Input: any byte slice; output: its CRC-32. O(len), no allocation.

// ---- CRC-32 (IEEE 802.3, reflected, poly 0xEDB88320) ------------------------

// Const evaluation: `i < 256` is the loop bound, so `t[i]` is in range (and an
// out-of-range index would fail the build, not the flight code).
#[allow(clippy::indexing_slicing)]
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "table index i < 256 and bit counter k < 8: the increments and the cast are exact"
)]
pub(super) const fn crc_table() -> [u32; 256] {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
}

/// The slicing-by-8 tables: `CRC_TABLES[0]` is the bytewise table,
/// `CRC_TABLES[k][i]` the CRC state after byte `i` followed by `k` zero bytes.
#[allow(
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects,
    reason = "const evaluation over fixed 8 × 256 bounds: k < 8, i < 256, the index (c & 0xFF) < 256"
)]
pub(super) const fn crc_tables() -> [[u32; 256]; 8] {
    let mut t = [[0u32; 256]; 8];
    t[0] = crc_table();
    let mut k = 1;
    while k < 8 {
        let mut i = 0;
        while i < 256 {
            let c = t[k - 1][i];
            t[k][i] = t[0][(c & 0xFF) as usize] ^ (c >> 8);
            i += 1;
        }
        k += 1;
    }
    t
}

pub(super) static CRC_TABLES: [[u32; 256]; 8] = crc_tables();

/// CRC-32 (IEEE 802.3, the zlib/PNG one) of `bytes`. `crc32(b"123456789") == 0xCBF43926`.
///
/// Slicing-by-8: eight bytes per step through eight 256-entry tables (8 KiB of
/// constant data), the same value as the bytewise recurrence (checked against
/// it in the map tests) at several times its speed; the map check reads the
/// whole product through it.
pub fn crc32(bytes: &[u8]) -> u32 {
    let [t0, t1, t2, t3, t4, t5, t6, t7] = &CRC_TABLES;
    // Every index below is a byte (`& 0xFF` or `>> 24`), so `get` never fails.
    let g = |t: &[u32; 256], i: u32| t.get((i & 0xFF) as usize).copied().unwrap_or(0);
    let mut c = 0xFFFF_FFFFu32;
    let mut chunks = bytes.chunks_exact(8);
    for ch in &mut chunks {
        let Some((lo, hi)) = ch.split_first_chunk::<4>() else {
            break;
        };
        let a = c ^ u32::from_le_bytes(*lo);
        let b = hi.first_chunk::<4>().map_or(0, |h| u32::from_le_bytes(*h));
        c = g(t7, a)
            ^ g(t6, a >> 8)
            ^ g(t5, a >> 16)
            ^ g(t4, a >> 24)
            ^ g(t3, b)
            ^ g(t2, b >> 8)
            ^ g(t1, b >> 16)
            ^ g(t0, b >> 24);
    }
    for b in chunks.remainder() {
        c = g(t0, c ^ u32::from(*b)) ^ (c >> 8);
    }
    !c
}
