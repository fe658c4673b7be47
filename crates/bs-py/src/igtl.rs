//! `brainshift._native.crc64`: the OpenIGTLink checksum (CRC-64/ECMA-182) of bs-igtl, for
//! Python clients that pack their own messages (pyigtl's crcmod is pure Python unless a
//! compiler built its extension).

use pyo3::prelude::*;

/// The OpenIGTLink checksum (CRC-64/ECMA-182) of `data` (bytes, bytearray, or a
/// contiguous one-dimensional uint8 numpy array), continuing from `crc` (the checksum of
/// the bytes before it, so that a body in parts is summed without joining them), computed
/// with the GIL released.
#[pyfunction]
#[pyo3(signature = (data, crc=0))]
pub(crate) fn crc64(py: Python<'_>, data: &Bound<'_, PyAny>, crc: u64) -> PyResult<u64> {
    if let Ok(b) = data.extract::<pyo3::pybacked::PyBackedBytes>() {
        return Ok(py.detach(|| bs_igtl::crc::crc64(&b, crc)));
    }
    let a: numpy::PyReadonlyArray1<'_, u8> = data.extract().map_err(|_| {
        pyo3::exceptions::PyValueError::new_err(
            "crc64: bytes, a bytearray or a one-dimensional uint8 numpy array",
        )
    })?;
    let bytes = a.as_slice().map_err(|_| {
        pyo3::exceptions::PyValueError::new_err("crc64: the array must be contiguous")
    })?;
    Ok(py.detach(|| bs_igtl::crc::crc64(bytes, crc)))
}
