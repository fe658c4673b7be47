//! The checksum of OpenIGTLink messages: CRC-64 with the ECMA-182 polynomial
//! (0x42F0E1EBA9EA3693, not reflected, initial value 0, no final xor), as the C++ library
//! and pyigtl compute it. Native because the server checks every message it receives and
//! sums every image it sends (tens of MB); slicing by eight (eight table lookups per 8
//! bytes), and from twice [`PARALLEL_BYTES`] in pieces summed in parallel and joined: the CRC is
//! linear, `crc(A B, c) = crc(B, 0) ⊕ crc(A, c) · x^(8|B|) mod P`.

use pyo3::prelude::*;
use rayon::prelude::*;

const POLY: u64 = 0x42F0_E1EB_A9EA_3693;

/// Inputs of at least twice this are summed in pieces of this size, in parallel (an
/// 8.7 M-voxel float image is 35 MB: 0.017 s on one core, 0.009 s on two).
const PARALLEL_BYTES: usize = 4 << 20;

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

/// CRC-64/ECMA-182 of `data` on one core, continuing from `crc` (the checksum of what came
/// before; 0 to start).
fn crc64_serial(data: &[u8], crc: u64) -> u64 {
    let t = &*TABLES;
    let mut crc = crc;
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

/// CRC-64/ECMA-182 of `data`, continuing from `crc` (the checksum of what came before; 0
/// to start): in parallel pieces for long inputs, joined by [`shift`].
pub(crate) fn crc64_of(data: &[u8], crc: u64) -> u64 {
    if data.len() < 2 * PARALLEL_BYTES {
        return crc64_serial(data, crc);
    }
    let pieces: Vec<(u64, usize)> =
        data.par_chunks(PARALLEL_BYTES).map(|c| (crc64_serial(c, 0), c.len())).collect();
    pieces.iter().fold(crc, |acc, &(c, len)| shift(acc, len) ^ c)
}

/// `crc · x^(8 bytes) mod P`: the checksum `crc` carried over `bytes` zero bytes.
fn shift(crc: u64, bytes: usize) -> u64 {
    // x^(8 bytes) by squaring, from x (the bit 1).
    let (mut power, mut base, mut e) = (1u64, 2u64, 8 * bytes as u128);
    while e > 0 {
        if e & 1 == 1 {
            power = mul_mod(power, base);
        }
        base = mul_mod(base, base);
        e >>= 1;
    }
    mul_mod(crc, power)
}

/// `a · b mod P` over GF(2) (bit `i` the coefficient of `x^i`).
fn mul_mod(a: u64, b: u64) -> u64 {
    let mut r = 0u64;
    for i in (0..64).rev() {
        r = if r >> 63 == 1 { (r << 1) ^ POLY } else { r << 1 };
        if b >> i & 1 == 1 {
            r ^= a;
        }
    }
    r
}

/// The OpenIGTLink checksum (CRC-64/ECMA-182) of `data` (bytes, bytearray, or a
/// contiguous one-dimensional uint8 numpy array, e.g. an image's `.reshape(-1).view(uint8)`),
/// continuing from `crc` (the checksum of the bytes before it, so that a body sent in parts
/// is summed without joining them), computed with the GIL released.
#[pyfunction]
#[pyo3(signature = (data, crc=0))]
pub(crate) fn crc64(py: Python<'_>, data: &Bound<'_, PyAny>, crc: u64) -> PyResult<u64> {
    if let Ok(b) = data.extract::<pyo3::pybacked::PyBackedBytes>() {
        return Ok(py.detach(|| crc64_of(&b, crc)));
    }
    let a: numpy::PyReadonlyArray1<'_, u8> = data.extract().map_err(|_| {
        pyo3::exceptions::PyValueError::new_err(
            "crc64: bytes, a bytearray or a one-dimensional uint8 numpy array",
        )
    })?;
    let bytes = a.as_slice().map_err(|_| {
        pyo3::exceptions::PyValueError::new_err("crc64: the array must be contiguous")
    })?;
    Ok(py.detach(|| crc64_of(bytes, crc)))
}
