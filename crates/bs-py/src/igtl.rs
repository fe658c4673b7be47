//! The checksum of OpenIGTLink messages: CRC-64 with the ECMA-182 polynomial
//! (0x42F0E1EBA9EA3693, not reflected, initial value 0, no final xor), as the C++ library
//! and pyigtl compute it. Native because the server checks every message it receives and
//! sums every image it sends (tens of MB); slicing by eight (eight table lookups per 8
//! bytes).

use pyo3::prelude::*;

const POLY: u64 = 0x42F0_E1EB_A9EA_3693;

/// `TABLES[k][b]`: the CRC of byte `b` followed by `k` zero bytes.
static TABLES: std::sync::LazyLock<[[u64; 256]; 8]> = std::sync::LazyLock::new(|| {
    let mut t = [[0u64; 256]; 8];
    for (b, entry) in t[0].iter_mut().enumerate() {
        let mut c = (b as u64) << 56;
        for _ in 0..8 {
            c = if c & (1 << 63) != 0 { (c << 1) ^ POLY } else { c << 1 };
        }
        *entry = c;
    }
    for k in 1..8 {
        for b in 0..256 {
            let prev = t[k - 1][b];
            t[k][b] = (prev << 8) ^ t[0][(prev >> 56) as usize];
        }
    }
    t
});

/// CRC-64/ECMA-182 of `data`.
pub(crate) fn crc64_of(data: &[u8]) -> u64 {
    let t = &*TABLES;
    let mut crc = 0u64;
    let mut chunks = data.chunks_exact(8);
    for c in &mut chunks {
        let x = crc ^ u64::from_be_bytes(c.try_into().expect("8 bytes"));
        crc = (0..8).fold(0, |acc, i| acc ^ t[7 - i][((x >> (56 - 8 * i)) & 0xff) as usize]);
    }
    for &b in chunks.remainder() {
        crc = (crc << 8) ^ t[0][((crc >> 56) as u8 ^ b) as usize];
    }
    crc
}

/// The OpenIGTLink checksum (CRC-64/ECMA-182) of `bytes` (or a bytearray), computed with
/// the GIL released.
#[pyfunction]
pub(crate) fn crc64(py: Python<'_>, data: pyo3::pybacked::PyBackedBytes) -> u64 {
    py.detach(|| crc64_of(&data))
}
