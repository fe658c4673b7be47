"""OpenIGTLink messages on the wire, for :mod:`brainshift.serve`.

The message layouts are pyigtl's (the Perk Lab's OpenIGTLink library, used with 3D Slicer
and PLUS): incoming POINT and STRING are unpacked by its ``PointMessage`` and
``StringMessage``, and the replies written here are the bytes its ``pack()`` writes
(tested). What is done here instead, because pyigtl 0.3.4 cannot do it for a server that
must not die on its input or must answer fast:

* reading a message off a socket, with the header checked (version 1 or 2, printable
  ASCII type and device name), the body size bounded, the body read in full into one
  buffer, a client silent mid-message closed, and its CRC-64 verified (pyigtl's own reader
  does none of these);
* the checksum itself, computed natively (``brainshift._native.crc64``; pyigtl's crcmod is
  pure Python unless a compiler built its extension);
* unpacking POLYDATA (pyigtl's ``PolyDataMessage._unpack_content`` does not run);
* packing IMAGE without copying the voxels, STRING in UTF-8 when the text is not ASCII
  (pyigtl's encoder raises), POLYDATA with numpy.

Frames: OpenIGTLink geometry here is RAS, millimetres (3D Slicer's world frame); images
carry the RAS flag of the IMAGE header.
"""

from __future__ import annotations

import socket
import struct
import sys
import time
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from ._native import crc64

HEADER = struct.Struct("> H 12s 20s I I Q Q")
HEADER_SIZE = HEADER.size  # 58
POLYDATA_HEADER = struct.Struct("> 10I")


class ProtocolError(Exception):
    """The byte stream cannot be read on (a bad header, an oversize or truncated body):
    the connection is answered and closed."""


class MessageError(Exception):
    """One message that is refused (bad checksum, content or device): it is answered and
    the connection goes on."""


@dataclass
class Header:
    version: int
    type: str
    device: str
    timestamp: float
    body_size: int
    crc: int

    def fields(self) -> dict:
        """The header as pyigtl's ``MessageBase.unpack`` takes it."""
        return {
            "header_version": self.version,
            "message_type": self.type,
            "device_name": self.device,
            "timestamp": self.timestamp,
            "body_size": self.body_size,
        }

    def __str__(self) -> str:
        return f"{self.type} '{self.device}'"


def _name(raw: bytes, what: str) -> str:
    text = raw.rstrip(b"\0")
    if b"\0" in text or any(c < 0x20 or c > 0x7E for c in text):
        raise ProtocolError(
            f"the header's {what} {raw!r} is not printable ASCII: this is not an "
            "OpenIGTLink stream (or it lost its framing)"
        )
    return text.decode("ascii").strip()


def parse_header(raw: bytes) -> Header:
    version, typ, device, seconds, fraction, size, crc = HEADER.unpack(raw)
    if version not in (1, 2):
        raise ProtocolError(
            f"header version {version}: OpenIGTLink 1 and 2 use 1, version 3 uses 2"
        )
    t = _name(typ, "message type")
    if not t:
        raise ProtocolError("the header's message type is empty")
    return Header(version, t, _name(device, "device name"), seconds + fraction / 2**32, size, crc)


def _recv_exactly(sock: socket.socket, n: int, what: str, started: bool = False,
                  offset: int = 0) -> Optional[bytearray]:
    """``n`` bytes; None if the peer closed before the first one of an item not yet
    ``started``, else a ProtocolError naming the truncation (``offset`` bytes of the item
    came before these)."""
    buf = bytearray(n)
    view = memoryview(buf)
    got = 0
    while got < n:
        k = sock.recv_into(view[got:], n - got)
        if k == 0:
            if got == 0 and not started:
                return None
            raise ProtocolError(
                f"{what} truncated: {offset + got} of {offset + n} bytes, then the client closed"
            )
        got += k
    return buf


def read_message(sock: socket.socket, max_body: int,
                 stall: Optional[float] = None) -> Optional[Tuple[Header, bytes]]:
    """The next message (header, body) on ``sock``; None when the client closed between
    messages. Between messages the wait is unbounded; once a message has begun, more than
    ``stall`` seconds without a byte is a ProtocolError (a client that stopped mid-message
    would otherwise hold its connection forever). Raises ProtocolError (framing lost) or
    socket errors."""
    first = _recv_exactly(sock, 1, "header")
    if first is None:
        return None
    previous = sock.gettimeout()
    sock.settimeout(stall)
    try:
        raw = first + _recv_exactly(sock, HEADER_SIZE - 1, "header", started=True, offset=1)
        h = parse_header(bytes(raw))
        if h.body_size > max_body:
            raise ProtocolError(
                f"{h}: a body of {h.body_size} bytes exceeds the server's limit of {max_body} "
                "bytes (--max-message-mb)"
            )
        body = _recv_exactly(sock, h.body_size, f"{h} body", started=True) if h.body_size else bytearray()
    except socket.timeout:
        raise ProtocolError(f"no byte for {stall:g} s in the middle of a message") from None
    finally:
        sock.settimeout(previous)
    return h, bytes(body)


def check_crc(h: Header, body: bytes) -> None:
    c = crc64(body)
    if c != h.crc:
        raise MessageError(
            f"{h}: CRC-64 of the body is {c:#018x}, the header says {h.crc:#018x} "
            "(corrupted in transit?); message ignored"
        )


def content(h: Header, body: bytes) -> bytes:
    """The message content: the body without the version-2 extended header and
    metadata."""
    if h.version == 1:
        return body
    if len(body) < 12:
        raise MessageError(f"{h}: a version-2 body needs its 12-byte extended header")
    ext, meta_header, meta_body, _ = struct.unpack("> H H I I", body[:12])
    end = len(body) - meta_header - meta_body
    if ext < 12 or end < ext:
        raise MessageError(
            f"{h}: extended header of {ext} bytes and metadata of {meta_header + meta_body} "
            f"bytes do not fit a body of {len(body)} bytes"
        )
    return body[ext:end]


def unpack_with(cls, h: Header, body: bytes):
    """``body`` unpacked by the pyigtl message class ``cls``."""
    m = cls()
    try:
        m.unpack(h.fields(), body)
    except Exception as e:  # pyigtl raises struct, Unicode, value errors on bad bytes
        raise MessageError(f"{h}: the body cannot be read as {h.type} ({e})") from None
    return m


def points_of(m, h: Header) -> np.ndarray:
    """The positions of a pyigtl PointMessage as an (n, 3) float64 array."""
    p = np.asarray(m.positions, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        raise MessageError(f"{h}: no points")
    if not np.isfinite(p).all():
        raise MessageError(f"{h}: point {int(np.flatnonzero(~np.isfinite(p).all(1))[0]) + 1} is not finite")
    return p


def _cells(raw: bytes, count: int, what: str, h: Header) -> list:
    """Cells (lists of point indices) of a POLYDATA cell array: each a count N, then N
    indices (uint32, big-endian)."""
    a = np.frombuffer(raw, dtype=">u4")
    cells = []
    i = 0
    while i < len(a):
        n = int(a[i])
        if i + 1 + n > len(a):
            raise MessageError(f"{h}: {what} cell {len(cells) + 1} runs past its array")
        cells.append(a[i + 1 : i + 1 + n])
        i += 1 + n
    if len(cells) != count:
        raise MessageError(f"{h}: {what}: the header says {count} cells, the array holds {len(cells)}")
    return cells


def unpack_polydata(h: Header, body: bytes, triangles: bool = True) -> Tuple[np.ndarray, np.ndarray]:
    """Points (n, 3) float64 and triangles (m, 3) int64 of a POLYDATA message: polygons
    fanned into triangles, triangle strips split; vertices, lines and attributes ignored.
    With ``triangles=False`` a point cloud: the points, and whatever triangles there are
    (none is not an error)."""
    c = content(h, body)
    if len(c) < POLYDATA_HEADER.size:
        raise MessageError(f"{h}: shorter than the 40-byte POLYDATA header")
    npts, _nv, sv, _nl, sl, npoly, spoly, nstrip, sstrip, _na = POLYDATA_HEADER.unpack_from(c)
    at = POLYDATA_HEADER.size
    need = at + 12 * npts + sv + sl + spoly + sstrip
    if need > len(c):
        raise MessageError(
            f"{h}: the header announces {need} bytes of points and cells, the body has {len(c)}"
        )
    points = np.frombuffer(c, dtype=">f4", count=3 * npts, offset=at).reshape(-1, 3)
    points = points.astype(np.float64)
    at += 12 * npts + sv + sl
    tris = []
    flat = np.frombuffer(c[at : at + spoly], dtype=">u4")
    if spoly == 16 * npoly and (flat[0::4] == 3).all():  # triangles only (Slicer's models)
        tris.append(flat.reshape(-1, 4)[:, 1:].astype(np.int64))
    else:
        for cell in _cells(c[at : at + spoly], npoly, "polygons", h):
            tris.append([(cell[0], cell[k], cell[k + 1]) for k in range(1, len(cell) - 1)])
    at += spoly
    for cell in _cells(c[at : at + sstrip], nstrip, "triangle strips", h):
        tris.append(
            [
                (cell[k], cell[k + 1], cell[k + 2]) if k % 2 == 0 else (cell[k + 1], cell[k], cell[k + 2])
                for k in range(len(cell) - 2)
            ]
        )
    t = np.concatenate([np.asarray(x, dtype=np.int64).reshape(-1, 3) for x in tris] or [np.zeros((0, 3), np.int64)])
    if len(t) == 0 and triangles:
        raise MessageError(f"{h}: no triangles (polygons or triangle strips) to measure with")
    if npts == 0:
        raise MessageError(f"{h}: no points")
    if len(t) and t.max() >= npts:
        raise MessageError(f"{h}: a cell refers to point {int(t.max())}, there are {npts}")
    if not np.isfinite(points).all():
        raise MessageError(f"{h}: a point is not finite")
    return points, t


IANA_ASCII, IANA_UTF8 = 3, 106


def string_message(text: str, device: str, timestamp: Optional[float] = None) -> bytes:
    """A STRING message: ASCII when the text is, else UTF-8 (pyigtl 0.3.4's encoder fails
    on non-ASCII text: it catches the wrong exception). The length field is 16 bits: text
    beyond 65535 bytes is cut, with a note saying so."""
    try:
        data, encoding = text.encode("ascii"), IANA_ASCII
    except UnicodeEncodeError:
        data, encoding = text.encode("utf-8"), IANA_UTF8
    if len(data) > 0xFFFF:
        note = b" ... (cut: longer than a STRING message holds)"
        data = data[: 0xFFFF - len(note)].decode("utf-8", "ignore").encode("utf-8") + note
    body = struct.pack("> H H", encoding, len(data)) + data
    return _header("STRING", device, len(body), crc64(body), timestamp) + body


SCALAR_TYPES = {np.dtype(np.int8): 2, np.dtype(np.uint8): 3, np.dtype(np.int16): 4,
                np.dtype(np.uint16): 5, np.dtype(np.int32): 6, np.dtype(np.uint32): 7,
                np.dtype(np.float32): 10, np.dtype(np.float64): 11}


def _header(message_type: str, device: str, body_size: int, crc: int, timestamp: Optional[float]) -> bytes:
    t = time.time() if timestamp is None else timestamp
    seconds = int(t)
    fraction = min(int((t - seconds) * 2**32), 2**32 - 1)
    return HEADER.pack(1, message_type.encode("ascii"), device.encode("ascii"), seconds, fraction,
                       body_size, crc)


def image_parts(image: np.ndarray, ijk_to_ras: np.ndarray, device: str,
                timestamp: Optional[float] = None) -> list:
    """An IMAGE message (header version 1, RAS) as a list of buffers to send in order,
    the voxels not copied: ``image`` is C-contiguous (k, j, i) or (k, j, i, components),
    as pyigtl's ``ImageMessage`` takes it, and the bytes are the ones its ``pack()`` writes
    (the same float32 matrix and image centre)."""
    a = np.ascontiguousarray(image)
    if a.ndim == 3:
        a = a[..., np.newaxis]
    nk, nj, ni, components = a.shape
    size = np.array([ni, nj, nk])
    m = np.asarray(ijk_to_ras, dtype=np.float32)
    centre = m.dot(np.array([(ni - 1) / 2.0, (nj - 1) / 2.0, (nk - 1) / 2.0, 1.0]))
    little = a.dtype.byteorder == "<" or (a.dtype.byteorder == "=" and sys.byteorder == "little")
    head = struct.pack("> H B B B B H H H", 1, components, SCALAR_TYPES[a.dtype.newbyteorder("=")],
                       2 if little or a.dtype.byteorder == "|" else 1, 1, *size)
    head += struct.pack("> 12f", *m[0:3, 0], *m[0:3, 1], *m[0:3, 2], *centre[0:3])
    head += struct.pack("> 6H", 0, 0, 0, *size)
    data = a.reshape(-1).view(np.uint8)
    crc = crc64(data, crc64(head))
    return [_header("IMAGE", device, len(head) + data.nbytes, crc, timestamp), head, data]


def pack(message, timestamp: Optional[float] = None) -> bytes:
    """A pyigtl message as OpenIGTLink bytes (header version 1), as ``message.pack()``
    writes them, with the native checksum."""
    body = message._pack_content()
    return _header(message.message_type, message.device_name, len(body), crc64(body), timestamp) + body


class TriangleMesh:
    """An outgoing POLYDATA message of triangles (no vertices, lines, strips or
    attributes), packed with numpy (pyigtl's ``PolyDataMessage`` counts cells in a Python
    loop; the bytes are the same)."""

    message_type = "POLYDATA"

    def __init__(self, points: np.ndarray, triangles: np.ndarray, device_name: str):
        self.points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        self.device_name = device_name

    def _pack_content(self) -> bytes:
        t = self.triangles
        cells = np.empty((len(t), 4), dtype=">u4")
        cells[:, 0] = 3
        cells[:, 1:] = t
        n = len(self.points)
        head = POLYDATA_HEADER.pack(n, 0, 0, 0, 0, len(t), 16 * len(t), 0, 0, 0)
        return head + np.ascontiguousarray(self.points, dtype=">f4").tobytes() + cells.tobytes()


def let_pyigtl_read_polydata() -> None:
    """Makes pyigtl clients (0.3.4 and earlier) able to receive POLYDATA such as
    ``DeformedBrain``: pyigtl's own reader fails in its receiving thread, which then drops
    the connection. Registers a reader built on :func:`unpack_polydata` (points (n, 3) and
    triangles (m, 3) as ``message.points`` and ``message.triangles``)."""
    import pyigtl

    class PolyDataMessage(pyigtl.PolyDataMessage):
        def unpack(self, header_fields, body):
            h = Header(header_fields["header_version"], header_fields["message_type"],
                       header_fields["device_name"], header_fields["timestamp"],
                       header_fields["body_size"], 0)
            self.device_name, self.timestamp = h.device, h.timestamp
            self.points, self.triangles = unpack_polydata(h, body)

    pyigtl.messages.message_type_to_class_constructor["POLYDATA"] = PolyDataMessage
