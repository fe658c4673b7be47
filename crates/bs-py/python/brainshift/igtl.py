"""OpenIGTLink helpers for Python *clients* of ``brainshift serve`` (the server itself is
native: bs-igtl and bs-serve, in Rust).

pyigtl 0.3.4 cannot read POLYDATA (its ``PolyDataMessage._unpack_content`` does not run,
and its receiving thread then drops the connection): :func:`let_pyigtl_read_polydata`
registers a reader for the server's ``DeformedBrain`` (points and triangles).
:func:`crc64` is the protocol's checksum, native (pyigtl's crcmod is pure Python unless a
compiler built its extension).
"""

from __future__ import annotations

import struct

import numpy as np

from ._native import crc64

__all__ = ["crc64", "let_pyigtl_read_polydata", "polydata_triangles"]

_POLYDATA_HEADER = struct.Struct("> 10I")


def _content(header_version: int, body: bytes) -> bytes:
    """A body without the version-2 extended header and metadata."""
    if header_version < 2:
        return body
    ext, meta_header, meta_body, _ = struct.unpack("> H H I I", body[:12])
    return body[ext:len(body) - meta_header - meta_body]


def polydata_triangles(header_version: int, body: bytes):
    """Points (n, 3) float64 and triangles (m, 3) int64 of a POLYDATA body of triangle
    polygons (what the server sends as ``DeformedBrain``)."""
    c = _content(header_version, body)
    npts, _nv, sv, _nl, sl, npoly, spoly, _ns, _ss, _na = _POLYDATA_HEADER.unpack_from(c)
    at = _POLYDATA_HEADER.size
    points = np.frombuffer(c, ">f4", 3 * npts, at).reshape(-1, 3).astype(np.float64)
    at += 12 * npts + sv + sl
    cells = np.frombuffer(c, ">u4", spoly // 4, at).reshape(-1, 4)
    if len(cells) != npoly or not (cells[:, 0] == 3).all():
        raise ValueError("POLYDATA: expected triangle polygons only")
    return points, cells[:, 1:].astype(np.int64)


def let_pyigtl_read_polydata() -> None:
    """Makes pyigtl clients (0.3.4 and earlier) able to receive POLYDATA such as
    ``DeformedBrain``: registers a reader giving ``message.points`` (n, 3) and
    ``message.triangles`` (m, 3)."""
    import pyigtl

    class PolyDataMessage(pyigtl.PolyDataMessage):
        def unpack(self, header_fields, body):
            self.device_name = header_fields["device_name"]
            self.timestamp = header_fields["timestamp"]
            self.points, self.triangles = polydata_triangles(header_fields["header_version"], body)

    pyigtl.messages.message_type_to_class_constructor["POLYDATA"] = PolyDataMessage
