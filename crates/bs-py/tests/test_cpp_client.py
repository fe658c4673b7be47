"""The native server driven by a client built on the reference C++ library (Debian's
libopenigtlink 1.11, `cpp/igtl_client.cpp`, built by .ci/python.sh into
BRAINSHIFT_IGTL_CLIENT): every message type the server takes, packed by the library, and
every reply unpacked by it with its CRC check. The answers must be the same update solved
here (a Session's first update from the reference state, as the server's) and warped
here, the C++ library's reading of the IMAGE matrix (the volume's centre) giving the
image's IJK-to-RAS matrix."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from brainshift import Scene, Session

pytest.importorskip("pyigtl")  # test_serve's fixtures
from test_serve import IMAGE, SCENE, ServerProcess, boundary_faces  # noqa: E402

CLIENT = os.environ.get("BRAINSHIFT_IGTL_CLIENT")
pytestmark = pytest.mark.skipif(not CLIENT, reason="BRAINSHIFT_IGTL_CLIENT (the C++ client) not built")


@pytest.fixture(scope="module")
def server():
    from conftest import FIXTURES

    s = ServerProcess(FIXTURES)
    yield s
    assert s.stop() == 0


def send(server, out: Path, replies: int, kind: str, device: str, *args):
    """Runs the C++ client; its replies as dicts (the fields it wrote), in order."""
    out.mkdir(parents=True, exist_ok=True)
    o = subprocess.run([CLIENT, "127.0.0.1", str(server.port), str(out), str(replies), kind, device, *map(str, args)],
                       capture_output=True, text=True, timeout=300)
    assert o.returncode == 0, o.stderr
    got = []
    for k in range(replies):
        (txt,) = out.glob(f"{k}-*.txt")
        fields = {}
        for line in txt.read_text().splitlines():
            key, _, value = line.partition(" ")
            fields[key] = value
        fields["path"] = txt.with_suffix("")
        got.append(fields)
    assert all(g["crc"] == "ok" for g in got), got
    return got


def image_of(reply):
    """Voxels and IJK-to-RAS from the C++ library's reading: unit directions, the spacing
    apart, and the volume's centre as the matrix's translation."""
    size = [int(x) for x in reply["size"].split()]
    c = int(reply["components"])
    assert reply["scalar"] == "10" and reply["frame"] == "1"  # float32, RAS
    dtype = "<f4" if reply["endian"] == "2" else ">f4"
    v = np.fromfile(str(reply["path"]) + ".raw", dtype=dtype)
    v = v.reshape(size[2], size[1], size[0], c) if c > 1 else v.reshape(size[2], size[1], size[0])
    m = np.array([float(x) for x in reply["matrix"].split()]).reshape(4, 4)
    spacing = np.array([float(x) for x in reply["spacing"].split()])
    affine = m.copy()
    affine[:3, :3] = m[:3, :3] * spacing
    affine[:3, 3] = m[:3, 3] - affine[:3, :3] @ ((np.array(size) - 1) / 2.0)
    return v, affine


def test_statuses_and_queries_are_taken_silently(server, tmp_path):
    send(server, tmp_path / "status", 0, "status", "")
    send(server, tmp_path / "get", 0, "get", "WarpedImage")
    import time

    for _ in range(100):  # the client closes at once; the server logs when it has read
        if sum("nothing to do" in line for line in server.lines) >= 2:
            break
        time.sleep(0.05)
    assert sum("nothing to do" in line for line in server.lines) >= 2, server.lines
    assert server.alive()


def test_a_surface_from_the_cpp_library_is_answered_as_the_session_and_warp_answer_it(server, fixtures, tmp_path):
    from brainshift import read_mesh

    m = read_mesh(fixtures / "ellipsoid" / "brain-coarse.inp")
    crani = set(m["node_sets"]["CRANIOTOMY"].tolist())
    faces = boundary_faces(m["elements"])
    patch = faces[[all(v in crani for v in f) for f in faces]]
    used, tris = np.unique(patch, return_inverse=True)
    pts = m["nodes"][used] + [0.0, 0.0, -4.0]
    np.savetxt(tmp_path / "points.csv", pts, delimiter=",", fmt="%.9g")
    np.savetxt(tmp_path / "tris.csv", tris.reshape(-1, 3), delimiter=",", fmt="%d")
    got = send(server, tmp_path / "surface", 4, "polydata", "IntraopSurface", tmp_path / "points.csv",
               tmp_path / "tris.csv")
    assert [g["device"] for g in got] == ["WarpedImage", "DisplacementField", "DeformedBrain", "Report"]

    session = Session(Scene.from_toml(fixtures / SCENE), threads=1)
    sent = np.loadtxt(tmp_path / "points.csv", delimiter=",").astype(np.float32).astype(np.float64)
    r = session.update(surface={"CRANIOTOMY": (sent, tris.reshape(-1, 3))})
    expected, affine = r.warp(fixtures / IMAGE)
    warped, their_affine = image_of(got[0])
    assert np.array_equal(warped, expected.T)
    assert np.allclose(their_affine, affine, atol=1e-4)
    field, _ = r.field(fixtures / IMAGE)
    f, _ = image_of(got[1])
    assert np.array_equal(f, field.transpose(2, 1, 0, 3))
    points = np.loadtxt(str(got[2]["path"]) + ".csv", delimiter=",")
    assert np.abs(points - r.surface()[0]).max() < 1e-4
    report = json.loads(got[3]["text"])
    assert report["converged"] and report["max_displacement"] == r.report["max_displacement"]


def test_landmarks_displacements_and_refusals_from_the_cpp_library(server, fixtures, tmp_path):
    session = Session(Scene.from_toml(fixtures / SCENE), threads=1)
    expected = session.update(displacements={"CRANIOTOMY": [0.0, 0.0, -2.0]}).surface()[0]
    ids = session.set_nodes("CRANIOTOMY")
    csv = "node_id,ux,uy,uz\n" + "".join(f"{i},0,0,-2\n" for i in ids)
    got = send(server, tmp_path / "d", 4, "string", "Displacements", csv)
    points = np.loadtxt(str(got[2]["path"]) + ".csv", delimiter=",")
    assert np.abs(points - expected).max() < 1e-3

    pre = np.array([[0, 0, 50], [12, 6, 47], [-12, -5, 46], [6, -14, 44], [-6, 14, 45], [0, 0, 38]], float)
    for name, p in (("pre", pre), ("intra", pre + [0.0, 0.0, -1.5])):
        (tmp_path / f"{name}.csv").write_text("".join(f"L{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(p)))
    got = send(server, tmp_path / "l", 4, "landmarks", "-", tmp_path / "pre.csv", tmp_path / "intra.csv")
    assert json.loads(got[3]["text"])["measurements"][0]["kind"] == "landmarks"

    for device, text, expect in [("Gravity", "0,-1,0", "no [gravity] to turn"),
                                 ("Resect", "TUMOUR", "not a region still in the model"),
                                 ("Displacements", "node_id,ux,uy,uz\n1,0,0,x\n", "line 2")]:
        (err,) = send(server, tmp_path / device, 1, "string", device, text)
        assert err["device"] == "Error" and expect in err["text"], err
    (err,) = send(server, tmp_path / "points", 1, "points", "IntraopPoints", tmp_path / "pre.csv")
    assert "no [[measurement]]" in err["text"]
    assert server.alive()
