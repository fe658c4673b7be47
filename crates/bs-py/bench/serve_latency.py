"""Latency of `brainshift serve` (what `cargo xtask bench serve` runs).

Starts the server on the MNI152 demo scene with the T1 template as the pre-operative
image, then sends eight intra-operative surfaces over one OpenIGTLink connection, as
POLYDATA `IntraopSurface`: the exposed brain surface (the craniotomy's boundary faces and
three rings around them) as a cold solve with the craniotomy moved 1, 2, ... 8 mm along -z
deforms it, made here beforehand (what a surface scanner would see); then, on a fresh
server, the same eight loads as STRING `Displacements` (the craniotomy's nodes moved k mm,
the sequence of `cargo xtask bench update`). For each it measures, on this side of the
socket, the time from the last byte sent to the last byte of IMAGE `WarpedImage`
received, and to the whole answer; each answer is verified: the report says converged and
verified, the warped image has the template's grid and differs from the last one, and the
deformed surface has the mesh's boundary.

Usage: python crates/bs-py/bench/serve_latency.py [--scene S] [--image I] [--threads N]
(needs the `brainshift` package and pyigtl in that interpreter).
"""

import argparse
import json
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pyigtl

from brainshift import Scene, Session, igtl, read_mesh

ROOT = Path(__file__).resolve().parents[3]


def patch_nodes(mesh_file, set_name, rings=3):
    """Node mask of `set_name` grown by `rings` rings of neighbouring boundary faces (so
    that the rim's nodes find their closest point inside the measured surface, not on its
    edge), and the number of boundary faces of the mesh."""
    m = read_mesh(mesh_file)
    tets = m["elements"]
    f = np.sort(np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]], tets[:, [1, 2, 3]]]), axis=1)
    u, count = np.unique(f, axis=0, return_counts=True)
    faces = u[count == 1]
    inside = np.zeros(len(m["nodes"]), bool)
    inside[m["node_sets"][set_name]] = True
    for _ in range(rings):
        inside[faces[inside[faces].any(axis=1)]] = True
    return inside, len(faces)


def measured_surfaces(args, inside):
    """The intra-operative surfaces: for each k, the deformed brain surface around the
    craniotomy of a cold solve with the craniotomy moved k mm along -z (what a surface
    scanner would see)."""
    out = []
    for k in range(1, 9):
        session = Session(Scene.from_toml(args.scene), threads=args.threads)
        r = session.update(displacements={args.set: [0.0, 0.0, -float(k)]})
        points, tris, node = r.surface()
        keep = inside[node[tris]].all(axis=1)
        used, t = np.unique(tris[keep], return_inverse=True)
        out.append((points[used], t.reshape(-1, 3)))
    return out


def start_server(args):
    cmd = [sys.executable, "-m", "brainshift.serve", str(args.scene), "--image", str(args.image), "--port", "0"]
    if args.threads:
        cmd += ["--threads", str(args.threads)]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    while True:
        line = p.stdout.readline()
        if not line:
            sys.exit("the server did not start:\n" + "".join(lines))
        lines.append(line)
        print("  server: " + line, end="")
        if line.startswith("listening on "):
            port = int(line.split()[2].split(":")[1])
            break
    log = []
    threading.Thread(target=lambda: log.extend(p.stdout), daemon=True).start()
    return p, port, log


def main():
    a = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    a.add_argument("--scene", type=Path, default=ROOT / "fixtures/mni152/scene.toml")
    a.add_argument("--image", type=Path, default=ROOT / "fixtures/mni152/t1.nii.gz")
    a.add_argument("--mesh", type=Path, default=ROOT / "fixtures/mni152/brain.inp")
    a.add_argument("--set", default="CRANIOTOMY")
    a.add_argument("--threads", type=int)
    args = a.parse_args()

    inside, boundary = patch_nodes(args.mesh, args.set)
    surfaces = measured_surfaces(args, inside)
    print(f"measured surfaces: {len(surfaces[0][0])} points, {len(surfaces[0][1])} triangles (around {args.set})")
    sequences = {
        "POLYDATA IntraopSurface (closest-point surface load)": [
            igtl.pack(pyigtl.PolyDataMessage(points=p, polygons=np.hstack([np.full((len(t), 1), 3), t]).ravel(),
                                             device_name="IntraopSurface"))
            for p, t in surfaces
        ],
        "STRING Displacements (the craniotomy's nodes moved k mm, as `bench update`)": [
            igtl.pack(pyigtl.StringMessage(displacement_csv(args, k), device_name="Displacements"))
            for k in range(1, 9)
        ],
    }
    for name, messages in sequences.items():
        print(f"\n== {name}")
        rows = run_sequence(args, messages, boundary)
        summarise(rows)


def displacement_csv(args, k):
    ids = Session(Scene.from_toml(args.scene), threads=1).set_nodes(args.set)
    return "node_id,ux,uy,uz\n" + "".join(f"{i},0,0,{-float(k)!r}\n" for i in ids)


def run_sequence(args, messages, boundary):
    server, port, log = start_server(args)
    s = socket.create_connection(("127.0.0.1", port))
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    rows, last = [], None
    print(f"{'mm':>3} {'latency':>8} {'all s':>7} {'solve s':>8} {'image s':>8} {'Newton':>6} {'GMRES':>6} {'max u':>6}")
    try:
        for k, msg in enumerate(messages, start=1):
            s.sendall(msg)
            sent = time.perf_counter()
            got, t_image, error = {}, None, None
            while len(got) < 4 and error is None:
                m = igtl.read_message(s, 1 << 31)
                if m is None:
                    sys.exit("the server closed the connection:\n" + "".join(log))
                h, body = m
                if h.device == "WarpedImage":
                    t_image = time.perf_counter() - sent
                if h.device == "Error":
                    error = igtl.unpack_with(pyigtl.StringMessage, h, body).string
                got[h.device] = (h, body)
            t_all = time.perf_counter() - sent
            if error is not None:
                print(f"{k:3d} {'':8} {t_all:7.3f}  refused: {error}")
                rows.append((k, None, t_all, None))
                continue
            igtl.check_crc(*got["WarpedImage"])
            image = igtl.unpack_with(pyigtl.ImageMessage, *got["WarpedImage"]).image
            report = json.loads(igtl.unpack_with(pyigtl.StringMessage, *got["Report"]).string)
            _, surf_tris = igtl.unpack_polydata(*got["DeformedBrain"])
            assert report["converged"] and report["equilibrium_residual"] <= report["equilibrium_bound"], report
            assert len(surf_tris) == boundary, (len(surf_tris), boundary)
            assert last is None or (image.shape == last.shape and np.abs(image - last).max() > 0)
            last = image
            rows.append((k, t_image, t_all, report))
            print(f"{k:3d} {t_image:8.3f} {t_all:7.3f} {report['serve']['solve_seconds']:8.3f} "
                  f"{report['serve']['image_seconds']:8.3f} {report['steps']:6d} {report['linear_iterations']:6d} "
                  f"{report['max_displacement']:6.2f}")
    finally:
        s.close()
        server.terminate()
        server.wait(timeout=60)
    if last is not None:
        print(f"image {last.shape[2]}x{last.shape[1]}x{last.shape[0]} ({last.size / 1e6:.1f} M voxels); "
              f"deformed surface {boundary} triangles")
    return rows


def summarise(rows):
    ok = [r for r in rows if r[3] is not None]
    if not ok:
        print("no update answered")
        return
    lat = [r[1] for r in ok]
    solve = [r[3]["serve"]["solve_seconds"] for r in ok]
    print(f"{len(ok)} of {len(rows)} answered with a verified result, {len(rows) - len(ok)} refused (an Error reply)")
    print(f"last byte sent -> WarpedImage received: median {statistics.median(lat):.3f} s, max {max(lat):.3f} s "
          f"(target: median <= 0.5 s); the solve alone: median {statistics.median(solve):.3f} s; "
          f"the rest: median {statistics.median([a - b for a, b in zip(lat, solve)]):.3f} s")


if __name__ == "__main__":
    main()
