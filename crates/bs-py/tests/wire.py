"""Raw OpenIGTLink over a socket for the server tests: what pyigtl's client cannot do
(send mutated, truncated or oversize bytes; read every reply of a connection the server
closes). Headers are parsed and bodies unpacked by pyigtl itself."""

import socket
import struct

import pyigtl

HEADER_SIZE = 58


def recv_exactly(sock, n):
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return bytes(buf)


def read_message(sock):
    """(header fields, body) of the next message, or None when the peer closed."""
    raw = recv_exactly(sock, HEADER_SIZE)
    if raw is None:
        return None
    h = pyigtl.MessageBase.parse_header(raw)
    body = recv_exactly(sock, h["body_size"]) if h["body_size"] else b""
    if body is None:
        return None
    return h, body


def unpack(h, body):
    """The reply as a pyigtl message."""
    m = pyigtl.MessageBase.create_message(h["message_type"])
    m.unpack(h, body)
    return m


def raw(port, data, shut=True, timeout=30):
    """Sends bytes on a fresh connection; the messages the server sends back until it
    closes (or `timeout`)."""
    s = socket.create_connection(("127.0.0.1", port))
    s.settimeout(timeout)
    try:
        s.sendall(data)
        if shut:
            s.shutdown(socket.SHUT_WR)
    except OSError:
        pass  # the server answered a bad header and closed before all was sent
    out = []
    try:
        while True:
            m = read_message(s)
            if m is None:
                break
            out.append(m)
    except OSError:
        pass
    s.close()
    return out


def error_text(h, body):
    assert (h["message_type"], h["device_name"]) == ("STRING", "Error"), h
    return unpack(h, body).string


def with_header(data, device=None, body_size=None, crc=None):
    """`data` (a packed message) with its header's device name field (20 bytes, given
    raw), body size or CRC replaced."""
    b = bytearray(data)
    if device is not None:
        b[14:34] = device.ljust(20, b"\0")[:20]
    if body_size is not None:
        b[42:50] = struct.pack(">Q", body_size)
    if crc is not None:
        b[50:58] = struct.pack(">Q", crc)
    return bytes(b)
