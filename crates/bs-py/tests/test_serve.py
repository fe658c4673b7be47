"""The native OpenIGTLink server (`python -m brainshift.serve`, which runs the same Rust
server as `brainshift serve`) driven over loopback by an independent OpenIGTLink client
(pyigtl, the Perk Lab's library) and by raw sockets for what pyigtl cannot send (mutated,
truncated, oversize messages, and the bytes the C++ library and 3D Slicer send).

The server runs as its own process on the ellipsoid scene (coarse mesh, 0.2 s per
update) with fixtures/registration/preop.nii.gz as the pre-operative image. Expectations
come from the same update solved in this process (a Session's first update starts from the
reference state, as the server's does: the same library calls, so the same numbers), from
`brainshift run` and `brainshift warp` of that update read back with nibabel and meshio,
and from result.vtu's boundary found here with numpy."""

import os
import signal
import socket
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

pyigtl = pytest.importorskip("pyigtl")

from brainshift import Scene, Session, igtl, read_image, read_mesh  # noqa: E402
from wire import error_text, raw, read_message, unpack, with_header  # noqa: E402

SCENE = "ellipsoid/scene.toml"
IMAGE = "registration/preop.nii.gz"


class _PolyData(pyigtl.PolyDataMessage):
    """pyigtl 0.3.4 cannot unpack POLYDATA (its ``_unpack_content`` indexes a Struct):
    points and triangle polygons read here, from the OpenIGTLink 2 specification."""

    def _unpack_content(self, content):
        n = struct.unpack_from(">10I", content)
        self.points = np.frombuffer(content, ">f4", 3 * n[0], 40).reshape(-1, 3).astype(float)
        at = 40 + 12 * n[0] + n[2] + n[4]
        cells = np.frombuffer(content, ">u4", n[6] // 4, at).reshape(-1, 4)
        assert (cells[:, 0] == 3).all()
        self.polygons = cells[:, 1:].astype(np.int64)


pyigtl.messages.message_type_to_class_constructor["POLYDATA"] = _PolyData


def boundary_faces(tets):
    """Faces (sorted node triples) that belong to one tetrahedron only."""
    f = np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]], tets[:, [1, 2, 3]]])
    f = np.sort(f, axis=1)
    u, count = np.unique(f, axis=0, return_counts=True)
    return u[count == 1]


@pytest.fixture(scope="module")
def ellipsoid():
    from conftest import FIXTURES

    m = read_mesh(FIXTURES / "ellipsoid" / "brain-coarse.inp")
    crani = set(m["node_sets"]["CRANIOTOMY"].tolist())
    faces = boundary_faces(m["elements"])
    patch = faces[[all(v in crani for v in f) for f in faces]]
    used, tris = np.unique(patch, return_inverse=True)
    m["patch"] = (m["nodes"][used], tris.reshape(-1, 3))  # the craniotomy's exposed surface
    return m


def surface_message(ellipsoid, dz):
    """The exposed surface moved dz mm along z (RAS; the scene is RAS, mm)."""
    pts, tris = ellipsoid["patch"]
    flat = np.hstack([np.full((len(tris), 1), 3), tris]).ravel()
    return pyigtl.PolyDataMessage(points=pts + [0.0, 0.0, dz], polygons=flat, device_name="IntraopSurface")


class ServerProcess:
    def __init__(self, fixtures, *extra, program=(sys.executable, "-m", "brainshift.serve"), scene=SCENE,
                 image=IMAGE):
        cmd = [*program, str(fixtures / scene), "--image", str(fixtures / image), "--port", "0",
               "--threads", "1", *extra]
        self.p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines = []
        while True:
            line = self.p.stdout.readline()
            assert line, "server exited: " + "".join(self.lines)
            self.lines.append(line)
            if line.startswith("listening on "):
                self.port = int(line.split()[2].split(":")[1])
                break
        import threading

        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self):
        for line in self.p.stdout:
            self.lines.append(line)

    def alive(self):
        return self.p.poll() is None

    def stop(self):
        if self.alive():
            self.p.send_signal(signal.SIGINT)
            return self.p.wait(timeout=60)
        return self.p.returncode


@pytest.fixture(scope="module")
def server():
    from conftest import FIXTURES

    s = ServerProcess(FIXTURES)
    yield s
    s.stop()


def client(port):
    c = pyigtl.OpenIGTLinkClient("127.0.0.1", port)
    t = time.time()
    while not c.is_connected():
        assert time.time() - t < 10, "no connection"
        time.sleep(0.01)
    return c


def replies(c, names=("WarpedImage", "DisplacementField", "DeformedBrain", "Report"), timeout=60):
    return {n: c.wait_for_message(n, timeout=timeout) for n in names}


def test_the_native_checksum_equals_pyigtls_crcmod():
    from pyigtl.messages import CRC64

    data = np.random.default_rng(4).integers(0, 256, size=100_003, dtype=np.uint8)
    assert igtl.crc64(b"123456789") == 0x6C40DF5F0B497347  # CRC-64/ECMA-182's check value
    assert igtl.crc64(data) == CRC64(data.tobytes())
    assert igtl.crc64(data[50_000:], igtl.crc64(data[:50_000].tobytes())) == CRC64(data.tobytes())
    # Above 8 MB the native sum runs in parallel pieces joined algebraically: it equals the
    # same bytes summed one piece after another, and crcmod's on a prefix.
    big = np.random.default_rng(5).integers(0, 256, size=9_000_011, dtype=np.uint8)
    chained = 0
    for k in range(0, big.size, 1 << 20):
        chained = igtl.crc64(big[k:k + (1 << 20)], chained)
    assert igtl.crc64(big) == chained
    assert igtl.crc64(big[: 8_400_000]) == CRC64(big[: 8_400_000].tobytes())


def test_a_surface_measurement_returns_the_warped_image_field_surface_and_report(
        server, ellipsoid, fixtures, cli, tmp_path):
    import meshio
    import nibabel

    c = client(server.port)
    c.send_message(surface_message(ellipsoid, -4.0), wait=True)
    got = replies(c)
    c.stop()
    assert all(got.values()), server.lines

    # The same measurement solved here, from the reference state as the server's first
    # (the points as the wire carries them: float32).
    pts, tris = ellipsoid["patch"]
    session = Session(Scene.from_toml(fixtures / SCENE), threads=1)
    sent = (pts + [0.0, 0.0, -4.0]).astype(np.float32).astype(np.float64)
    r = session.update(surface={"CRANIOTOMY": (sent, tris)})
    report = got["Report"]
    import json

    rep = json.loads(report.string)
    assert rep["converged"] and rep["max_displacement"] == r.report["max_displacement"]

    # WarpedImage: the warp of this result (bit-identical), and `brainshift warp` of it
    # (the CLI writes int16 like its input: within half a unit).
    expected, affine = r.warp(fixtures / IMAGE)
    w = got["WarpedImage"]
    assert w.world_coordinate_system == "ras"
    assert np.array_equal(w.image, expected.T)
    assert np.allclose(w.ijk_to_world_matrix, affine, atol=1e-4)  # float32 matrix on the wire
    r.write(tmp_path / "run")
    o = cli("warp", "--image", fixtures / IMAGE, "--result", tmp_path / "run", "--out", tmp_path / "w.nii.gz")
    assert o.returncode == 0, o.stderr
    img = nibabel.load(tmp_path / "w.nii.gz")
    assert np.abs(w.image.T - img.get_fdata()).max() <= 0.5 + 1e-3
    assert np.allclose(w.ijk_to_world_matrix, img.affine, atol=1e-4)
    assert np.abs(w.image.T - nibabel.load(fixtures / IMAGE).get_fdata()).max() > 50  # it moved

    # The report's account of the map between brain and skull: the numbers of `brainshift
    # warp`'s "outside the brain" line for the same result.
    import re

    out = rep["serve"]["outside"]
    line = re.search(
        r"outside the brain: (\d+) gap voxels extended harmonically \(zero at the skull; (\d+) iterations, "
        r"residual ([0-9.e+-]+)\); det\(I \+ grad d\) min ([0-9.-]+).*, (\d+) voxels <= 0",
        o.stdout + o.stderr,
    )
    assert line, o.stdout + o.stderr
    assert out["boundary"] == "skull" and out["gap_voxels"] == int(line[1]) > 0
    assert out["iterations"] == int(line[2]) and out["folding_voxels"] == int(line[5])
    assert abs(out["min_det"] - float(line[4])) <= 5e-4 and out["residual"] == pytest.approx(float(line[3]), rel=0.06)

    field, _ = r.field(fixtures / IMAGE)
    f = got["DisplacementField"]
    assert f.image.shape == expected.T.shape + (3,)
    assert np.array_equal(f.image, field.transpose(2, 1, 0, 3))
    # Inside the deformed brain the field is the FE map's inverse: as long as the motion.
    # Beyond the skin a gap voxel whose trilinear cell reaches outside the pre-operative gap
    # points at that gap's nearest voxel centre (on these 4 mm voxels up to a few voxels
    # away): within the search radius of the harmonic point, itself within the motion.
    norm = np.linalg.norm(field, axis=-1)
    inside = r.inverse_map(fixtures / IMAGE).inside
    assert inside.shape == norm.shape and 1000 < inside.sum() < inside.size
    assert 3.0 < norm[inside].max() < 6.0
    assert norm.max() <= norm[inside].max() + 12 * 4.0 * np.sqrt(3) + 1e-3

    # DeformedBrain: the deformed boundary of the result mesh (float32 on the wire), outward.
    vtu = meshio.read(tmp_path / "run" / "result.vtk")  # meshio 5.3.5 rejects the .vtu's String array
    x = vtu.points + vtu.point_data["displacement"]
    tets = vtu.cells_dict["tetra"]
    b = got["DeformedBrain"]
    node = np.array([np.argmin(np.linalg.norm(x - p, axis=1)) for p in b.points])
    assert np.abs(x[node] - b.points).max() < 1e-4
    assert {tuple(t) for t in np.sort(node[b.polygons], axis=1)} == {tuple(t) for t in boundary_faces(tets)}
    p0, p1, p2 = (b.points[b.polygons[:, k]] for k in range(3))
    enclosed = np.einsum("ij,ij->", p0, np.cross(p1, p2)) / 6.0
    a, bb, cc, d = (x[tets[:, k]] for k in range(4))
    volume = np.abs(np.einsum("ij,ij->i", bb - a, np.cross(cc - a, d - a))).sum() / 6.0
    assert enclosed == pytest.approx(volume, rel=1e-5)


def test_landmarks_are_fitted_as_the_cli_fits_them_and_displacements_imposed(server, ellipsoid, fixtures, cli,
                                                                              tmp_path):
    """Landmarks on the craniotomy are fitted through it (sigma 1 mm), as `brainshift run`
    fits the scene with that [[boundary]] replaced by a landmark [[measurement]] of the same
    pairs; a Displacements message after them imposes its values again."""
    import meshio

    c = client(server.port)
    rng = np.random.default_rng(3)
    # Inside the brain under the craniotomy (the ellipsoid's top pole at z = 55).
    pre = np.array([[0, 0, 50], [12, 6, 47], [-12, -5, 46], [6, -14, 44], [-6, 14, 45], [0, 0, 38]], float)
    intra = pre + [0.3, 0.0, -2.0] + rng.normal(scale=0.1, size=pre.shape)
    names = [f"L{k}" for k in range(len(pre))]
    c.send_message(pyigtl.PointMessage(pre, names=names, device_name="PreopLandmarks"), wait=True)
    order = rng.permutation(len(pre))  # sent in another order: paired by name
    c.send_message(pyigtl.PointMessage(intra[order], names=[names[k] for k in order],
                                       device_name="IntraopLandmarks"), wait=True)
    b = c.wait_for_message("DeformedBrain", timeout=120)
    assert b is not None, "".join(server.lines[-10:])

    # The same pairs (as the wire carries them: float32) in a scene, run by the CLI.
    f32 = lambda a: a.astype(np.float32).astype(np.float64)  # noqa: E731
    rows = "".join(",".join(repr(float(v)) for v in np.r_[p, q]) + "\n" for p, q in zip(f32(pre), f32(intra)))
    (tmp_path / "pairs.csv").write_text("x,y,z,x2,y2,z2\n" + rows)
    text = (fixtures / SCENE).read_text()
    old = '[[boundary]]\nnset = "CRANIOTOMY"\ndisplacement = { x = 0.0, y = 0.0, z = -10.0 }\n'
    assert old in text
    text = text.replace(old, '[[measurement]]\nnset = "CRANIOTOMY"\nlandmarks = "pairs.csv"\nsigma = 1.0\n')
    d = fixtures / "ellipsoid"
    text = text.replace('file = "brain-coarse.inp"', f'file = "{d / "brain-coarse.inp"}"')
    text = text.replace('skull = "skull.off"', f'skull = "{d / "skull.off"}"')
    (tmp_path / "scene.toml").write_text(text)
    o = cli("run", tmp_path / "scene.toml", "--out", tmp_path / "run", "--quiet")
    assert o.returncode == 0, o.stderr
    vtu = meshio.read(tmp_path / "run" / "result.vtk")
    x = vtu.points + vtu.point_data["displacement"]
    nearest = np.array([np.linalg.norm(x - p, axis=1).min() for p in b.points])
    assert nearest.max() < 1e-3, nearest.max()  # float32 points, the solver's tolerance

    session = Session(Scene.from_toml(fixtures / SCENE), threads=1)
    expected = session.update(displacements={"CRANIOTOMY": [0.0, 0.0, -2.0]}).surface()[0]
    crani = ellipsoid["node_ids"][ellipsoid["node_sets"]["CRANIOTOMY"]]
    csv = "node_id,ux,uy,uz\n" + "".join(f"{i},0,0,-2\n" for i in crani[::-1])
    c.send_message(pyigtl.StringMessage(csv, device_name="Displacements"), wait=True)
    b = c.wait_for_message("DeformedBrain", timeout=60)
    c.stop()
    assert np.abs(b.points - expected).max() < 1e-3


def test_refused_measurements_are_answered_and_the_session_keeps_its_state(server, ellipsoid):
    c = client(server.port)
    c.send_message(surface_message(ellipsoid, -3.0), wait=True)
    good = c.wait_for_message("DeformedBrain", timeout=60)
    assert good is not None

    bad = [
        (surface_message(ellipsoid, -40.0), "max_distance"),  # farther than the scene allows
        (pyigtl.PointMessage([[0, 0, 0]] * 3, device_name="IntraopLandmarks"), "'PreopLandmarks' first"),
        (pyigtl.StringMessage("node_id,ux,uy,uz\n1,0,0,x\n", device_name="Displacements"), "line 2"),
        (pyigtl.TransformMessage(np.eye(4), device_name="Tool"), "not a measurement"),
        (pyigtl.PointMessage([[0, 0, 0]] * 3, device_name="IntraopPoints"), "no [[measurement]]"),
        (pyigtl.StringMessage("0,0,0", device_name="Gravity"), "not a direction"),
        (pyigtl.StringMessage("0,-1,0", device_name="Gravity"), "no [gravity] to turn"),
        (pyigtl.StringMessage("TUMOUR", device_name="Resect"), "not a region still in the model"),
    ]
    for message, text in bad:
        c.send_message(message, wait=True)
        e = c.wait_for_message("Error", timeout=60)
        assert e is not None and text in e.string, (text, e and e.string)

    # The same measurement again: already at that state, the same surface comes back.
    c.send_message(surface_message(ellipsoid, -3.0), wait=True)
    again = c.wait_for_message("DeformedBrain", timeout=60)
    c.stop()
    assert np.abs(again.points - good.points).max() < 1e-3
    assert server.alive()


def pack(m):
    return m.pack()


def test_fuzzed_streams_never_stop_the_server(server, ellipsoid):
    valid = pack(surface_message(ellipsoid, -1.0))
    text = pack(pyigtl.StringMessage("node_id,ux,uy,uz\n", device_name="Displacements"))
    rng = np.random.default_rng(7)
    answered = 0
    for k in range(60):
        data = bytearray(valid if (k // 6) % 2 else text)  # each kind on both messages
        kind = k % 6
        if kind == 0:  # flipped bytes anywhere (header or body)
            for i in rng.integers(0, len(data), size=3):
                data[i] ^= int(rng.integers(1, 256))
        elif kind == 1:  # truncated
            data = data[: int(rng.integers(1, len(data)))]
        elif kind == 2:  # the body changed, the checksum fixed: the content reader's turn
            body = bytearray(data[58:])
            for i in rng.integers(0, len(body), size=2):
                body[i] = int(rng.integers(0, 256))
            data = data[:50] + struct.pack(">Q", igtl.crc64(bytes(body))) + body
        elif kind == 3:  # an unknown type
            data[2:14] = b"FOO\0\0\0\0\0\0\0\0\0"
        elif kind == 4:  # an oversize body announced
            data[42:50] = struct.pack(">Q", 1 << 40)
        else:  # garbage
            data = bytearray(rng.integers(0, 256, size=int(rng.integers(1, 200)), dtype=np.uint8).tobytes())
        out = raw(server.port, bytes(data))
        answered += len(out)
        assert server.alive(), f"mutation {k} ({kind}) stopped the server:\n" + "".join(server.lines[-20:])
    assert answered >= 30  # most mutations get an Error (a truncated header gets none)

    # Two valid messages back to back on one connection still work after all that.
    out = raw(server.port, pack(surface_message(ellipsoid, -1.0)) + pack(surface_message(ellipsoid, -2.0)))
    assert [h["device_name"] for h, _ in out].count("WarpedImage") == 2


def test_openigtlink_3_messages_with_metadata_are_read_and_answered_in_version_2(server, ellipsoid):
    """OpenIGTLink 3 (Slicer 5) sends header version 2: an extended header and metadata
    (keys the server does not know among them) around the content; packed here by pyigtl
    itself (its own CRC). The replies come in version 2 too, then in version 1 again after
    a version-1 message."""
    m = surface_message(ellipsoid, -2.0)
    m.header_version = 2
    m.metadata = {"Sender": "test", "Frame": "RAS", "x-unknown-key": "ignored"}
    s = pyigtl.StringMessage("node_id,ux,uy,uz\n", device_name="Displacements")
    s.header_version = 2
    s.metadata = {"Sender": "test"}
    v1 = pyigtl.StringMessage("node_id,ux,uy,uz\n", device_name="Displacements")
    out = raw(server.port, m.pack() + s.pack() + v1.pack())
    devices = [h["device_name"] for h, _ in out]
    assert devices[:4] == ["WarpedImage", "DisplacementField", "DeformedBrain", "Report"], devices
    assert [h["header_version"] for h, _ in out] == [2, 2, 2, 2, 2, 1]
    assert unpack(*out[0]).image.shape == (36, 44, 50)  # pyigtl reads the version-2 image
    assert "nodes of the set have no row" in error_text(*out[4])
    assert "nodes of the set have no row" in error_text(*out[5])


def test_what_the_cpp_library_and_slicer_send_is_answered_and_the_server_stays_up(server, ellipsoid):
    """A device name ending at a NUL with bytes after it (read, as the C++ library reads it,
    up to the NUL), Slicer's STATUS with an empty device name on connecting (nothing to
    answer), and a body larger than its header says (its checksum fails: answered; the
    bytes after it are no header: answered, that connection closed)."""
    text = pack(pyigtl.StringMessage("node_id,ux,uy,uz\n", device_name="Displacements"))
    junk = with_header(text, device=b"Displacements\0junk!")
    from conftest import FIXTURES

    status = (FIXTURES / "igtl" / "status.igtl").read_bytes()  # the C++ library's, name ""
    out = raw(server.port, status + junk)
    assert len(out) == 1 and "nodes of the set have no row" in error_text(*out[0])

    longer = with_header(text, body_size=len(text) - 58 - 6)  # 6 bytes more than claimed
    out = raw(server.port, longer)
    texts = [error_text(*o) for o in out]
    assert "CRC-64" in texts[0] and "closing the connection" in texts[1], texts
    # A STRING whose length field says less than its content holds (checksum right).
    body = struct.pack(">HH", 3, 3) + b"0,-1,0"
    h = pyigtl.StringMessage("x", device_name="Gravity").pack()[:58]
    out = raw(server.port, with_header(h, body_size=len(body), crc=igtl.crc64(body)) + body)
    assert "after its last field" in error_text(*out[0])
    assert server.alive()


def test_24_clients_at_once_are_served(fixtures, ellipsoid):
    """24 simultaneous connections (the cap raised to 24), each sending a message: the
    refused ones answered, the updates among them queued one at a time and answered."""
    import threading

    s = ServerProcess(fixtures, "--max-clients", "24", "--no-field")
    try:
        good = pack(surface_message(ellipsoid, -1.5))
        bad = pack(pyigtl.StringMessage("node_id,ux,uy,uz\n", device_name="Displacements"))
        results = [None] * 24

        def one(k):
            results[k] = raw(s.port, good if k % 6 == 0 else bad, timeout=300)

        threads = [threading.Thread(target=one, args=(k,)) for k in range(24)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        for k, out in enumerate(results):
            devices = [h["device_name"] for h, _ in out]
            assert devices == (["WarpedImage", "DeformedBrain", "Report"] if k % 6 == 0 else ["Error"]), (k, devices)
        assert s.alive()
    finally:
        assert s.stop() == 0


def test_a_client_leaving_mid_update_and_two_clients_at_once(server, ellipsoid):
    s = socket.create_connection(("127.0.0.1", server.port))
    s.sendall(pack(surface_message(ellipsoid, -2.5)))
    s.close()  # gone before the answer
    a, b = client(server.port), client(server.port)
    a.send_message(surface_message(ellipsoid, -3.5), wait=False)
    b.send_message(surface_message(ellipsoid, -1.5), wait=False)
    ra = a.wait_for_message("WarpedImage", timeout=120)
    rb = b.wait_for_message("WarpedImage", timeout=120)
    a.stop()
    b.stop()
    assert ra is not None and rb is not None
    assert server.alive()


def test_a_client_stalled_mid_message_is_closed_and_too_many_are_refused(fixtures, ellipsoid):
    s = ServerProcess(fixtures, "--stall-seconds", "0.5", "--max-clients", "2")
    try:
        data = pack(surface_message(ellipsoid, -1.0))
        stalled = socket.create_connection(("127.0.0.1", s.port))
        stalled.sendall(data[:100])  # header and part of the body, then nothing
        stalled.settimeout(10)
        h, body = read_message(stalled)
        assert "no byte for 0.5 s in the middle of a message" in error_text(h, body)
        stalled.close()
        held = [socket.create_connection(("127.0.0.1", s.port)) for _ in range(2)]
        for _ in range(50):  # until the server has accepted both (and let the stalled go)
            extra = raw(s.port, b"", timeout=5)
            if extra:
                break
            time.sleep(0.1)
        assert extra and "already serves 2 clients" in error_text(*extra[0]), "".join(s.lines)
        for c in held:
            c.close()
        time.sleep(0.3)
        out = raw(s.port, data)
        assert [h["device_name"] for h, _ in out][0] == "WarpedImage"
    finally:
        assert s.stop() == 0


def test_pyigtl_clients_can_be_made_to_read_polydata_and_no_surface_leaves_it_out(fixtures, server, ellipsoid):
    """brainshift.igtl.let_pyigtl_read_polydata() on the server's own DeformedBrain against
    this file's reader, and --no-surface: the other replies only."""
    s = ServerProcess(fixtures, "--no-surface")
    try:
        out = raw(s.port, pack(surface_message(ellipsoid, -2.0)))
        assert [h["device_name"] for h, _ in out] == ["WarpedImage", "DisplacementField", "Report"]
    finally:
        s.stop()
    out = raw(server.port, pack(surface_message(ellipsoid, -2.0)))
    h, body = next((h, b) for h, b in out if h["device_name"] == "DeformedBrain")
    theirs = unpack(h, body)
    try:
        igtl.let_pyigtl_read_polydata()
        m = pyigtl.MessageBase.create_message("POLYDATA")
        m.unpack(h, body)
        assert np.array_equal(m.points, theirs.points) and np.array_equal(m.triangles, theirs.polygons)
    finally:
        pyigtl.messages.message_type_to_class_constructor["POLYDATA"] = _PolyData


def test_ctrl_c_stops_the_server_cleanly(fixtures, ellipsoid):
    s = ServerProcess(fixtures)
    c = client(s.port)  # a client still connected
    assert s.stop() == 0
    c.stop()
    time.sleep(0.2)
    assert any(line.startswith("stopped") for line in s.lines), s.lines


def test_brainshift_serve_is_the_same_server(fixtures, cli, ellipsoid):
    s = ServerProcess(fixtures, "--verbose", program=(cli.path, "serve"))
    assert any(line.startswith("prepared in ") for line in s.lines)
    c = client(s.port)
    c.send_message(surface_message(ellipsoid, -2.0), wait=True)
    assert c.wait_for_message("WarpedImage", timeout=60) is not None
    c.stop()
    assert s.stop() == 0
    assert any(line.startswith("    iteration 1: load") for line in s.lines), s.lines


def test_a_scene_without_the_set_or_image_is_refused_before_listening(fixtures, tmp_path):
    base = [sys.executable, "-m", "brainshift.serve", str(fixtures / SCENE)]
    o = subprocess.run(base + ["--image", str(tmp_path / "none.nii.gz")], capture_output=True, text=True)
    assert o.returncode == 1 and "none.nii.gz" in o.stderr, o.stderr
    o = subprocess.run(base + ["--image", str(fixtures / IMAGE), "--set", "FIXED"], capture_output=True, text=True)
    assert o.returncode == 1 and "--set FIXED" in o.stderr and "CRANIOTOMY" in o.stderr, o.stderr


def test_image_read_once_warps_as_the_file(fixtures):
    session = Session(Scene.from_toml(fixtures / SCENE), threads=1)
    r = session.update(displacements={"CRANIOTOMY": [0.0, 0.0, -3.0]})
    image = read_image(fixtures / IMAGE)
    a, affine_a = r.warp(image)
    b, affine_b = r.warp(fixtures / IMAGE)
    assert np.array_equal(a, b) and np.array_equal(affine_a, affine_b)
    m = r.inverse_map(image)
    assert np.array_equal(m.warp(image), a) and np.array_equal(m.field(), r.field(image)[0])
    assert image.shape == a.shape and np.array_equal(image.affine, m.affine)
    # The next update's map reuses the pre-operative gap the image keeps from the first
    # (same reference mesh and skull): the same warp as the file read afresh.
    r2 = session.update(displacements={"CRANIOTOMY": [0.0, 0.0, -5.0]})
    b2, _ = r2.warp(fixtures / IMAGE)
    assert not np.array_equal(b2, a)
    assert np.array_equal(r2.inverse_map(image).warp(image), b2)
    assert np.array_equal(r2.warp(image)[0], b2)
    # A map's field without a warp before it (the gap located on its grid, not taken from
    # an image): the same as the field from the file.
    f2, _ = r2.field(fixtures / IMAGE)
    assert np.array_equal(r2.inverse_map(fixtures / IMAGE).field(), f2)


def test_intraop_points_are_fitted_and_the_report_says_how(fixtures):
    """fixtures/fit (its craniotomy measured, nothing prescribed: no --set needed): a scan
    sent as POINT 'IntraopPoints' is fitted; the Report's measurements count its points and
    inliers as a session's update does. Boundary messages are refused there."""
    import json

    s = ServerProcess(fixtures, scene="fit/scene.toml", image="mni152/t1.nii.gz")
    try:
        c = client(s.port)
        scan = np.loadtxt(fixtures / "fit" / "scan.csv", delimiter=",", skiprows=1)
        c.send_message(pyigtl.PointMessage(scan, device_name="IntraopPoints"), wait=True)
        r = c.wait_for_message("Report", timeout=180)
        assert r is not None, "".join(s.lines[-10:])
        m = json.loads(r.string)["measurements"][0]
        assert m["kind"] == "points" and m["points"] == len(scan), m
        assert m["inliers"] > 0.9 * len(scan), m
        c.send_message(pyigtl.StringMessage("node_id,ux,uy,uz\n", device_name="Displacements"), wait=True)
        e = c.wait_for_message("Error", timeout=60)
        assert e is not None and "prescribes no node set" in e.string, e and e.string
        c.stop()
    finally:
        s.stop()


def test_the_uncertainty_image_is_what_run_writes_on_the_same_grid(fixtures, cli, tmp_path):
    """`--uncertainty 8` on fixtures/fit: its own scan sent as POINT 'IntraopPoints' is
    answered with IMAGE 'Uncertainty' right after the WarpedImage (read by pyigtl), the
    total σ on the pre-operative image's grid; against `brainshift run --uncertainty 8
    --uncertainty-grid` of the same scene read with nibabel. The scan crosses the wire as
    float32 and each response is a GMRES solve to 1e-2, so the two agree to a few per cent,
    not to the digit."""
    import json

    nib = pytest.importorskip("nibabel")
    s = ServerProcess(fixtures, "--uncertainty", "8", "--no-field", "--no-surface", scene="fit/scene.toml",
                      image="mni152/t1.nii.gz")
    try:
        c = client(s.port)
        scan = np.loadtxt(fixtures / "fit" / "scan.csv", delimiter=",", skiprows=1)
        c.send_message(pyigtl.PointMessage(scan, device_name="IntraopPoints"), wait=True)
        u = c.wait_for_message("Uncertainty", timeout=240)
        r = c.wait_for_message("Report", timeout=60)
        assert u is not None and r is not None, "".join(s.lines[-10:])
        c.stop()
    finally:
        s.stop()
    report = json.loads(r.string)["uncertainty"]
    assert report["samples"] == 8, report
    o = cli("run", fixtures / "fit" / "scene.toml", "--out", tmp_path, "--uncertainty", "8",
            "--uncertainty-grid", fixtures / "mni152" / "t1.nii.gz", "--quiet")
    assert o.returncode == 0, o.stderr
    ref = nib.load(tmp_path / "uncertainty.nii.gz")
    expected = np.asarray(ref.dataobj, dtype=np.float32)
    got = np.asarray(u.image, dtype=np.float32)
    if got.shape != expected.shape:  # pyigtl holds voxels k, j, i
        got = got.transpose(2, 1, 0)
    assert got.shape == expected.shape
    assert np.allclose(u.ijk_to_world_matrix, ref.affine, atol=1e-4), (u.ijk_to_world_matrix, ref.affine)
    top = expected.max()
    assert top > 0.1, top
    assert abs(got.max() - top) < 0.05 * top, (got.max(), top)
    # The same voxels inside the deformed brain (float32 points move its boundary by
    # micrometres: a voxel centre on it may flip).
    assert np.mean((got > 0) != (expected > 0)) < 1e-4
    assert np.allclose(got, expected, rtol=0.05, atol=0.02 * top)
