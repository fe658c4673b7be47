"""``python -m brainshift.serve``: brain shift over OpenIGTLink, for 3D Slicer and
navigation systems.

The server prepares a live :class:`brainshift.Session` of a scene and reads the
pre-operative image once, then listens. Each intra-operative measurement a client sends
is solved warm from the last good state and answered, to that client, with:

* IMAGE ``WarpedImage``: the pre-operative image warped into the new configuration, on
  its own grid (float32, IJK-to-RAS matrix);
* IMAGE ``DisplacementField``: d(y) = X(y) − y on that grid, 3 components, RAS mm (a grid
  transform's displacement: where each intra-operative voxel came from);
* POLYDATA ``DeformedBrain``: the deformed brain surface, RAS mm;
* STRING ``Report``: the run's report as JSON (the keys of report.json, and ``serve``: the
  solve and image seconds and ``outside``, what the map does between brain and skull).

Measurements (geometry in RAS, mm, Slicer's world frame; converted to the scene's frame
and unit):

* POLYDATA ``IntraopSurface``: the measured exposed brain surface (triangles), as the
  scene's ``surface`` load: each node of the boundary moves to its closest point on it;
* POINT ``PreopLandmarks`` then POINT ``IntraopLandmarks``: landmark pairs (paired by name
  when both lists carry the same unique names, else by order), as a ``landmarks`` load;
  the pre-operative list is kept for later intra-operative ones;
* STRING ``Displacements``: CSV ``node_id,ux,uy,uz`` with a header line, one row per node
  of the set, in the scene's frame and unit, as ``displacement_file``;
* STRING ``Gravity``: ``x,y,z``, gravity's new direction in RAS (the head repositioned);
  the scene's ``[gravity]`` is turned and the brain solved again;
* STRING ``Resect``: the element set of a region; its elements leave the model (the
  cavity's walls free) and the brain is solved again warm;
* POINT or POLYDATA ``IntraopPoints``: a new scan (its points; triangles, if any, ignored)
  of the scene's ``[[measurement]]`` with points, *fitted* as that measurement is
  (docs/fit.md); the Report's ``measurements`` say how (inliers, residual RMS and max). A
  scene whose only intra-operative data are measurements needs no ``--set``.

A refused message, a load the solver cannot carry, or a result that fails verification is
answered with STRING ``Error`` (the text the command line prints) and the session stays at
its last good state. A stream that cannot be read on (bad header, oversize or truncated
body) is answered, then that connection is closed; the server goes on.
"""

from __future__ import annotations

import argparse
import json
import signal
import socket
import sys
import threading
import time
from typing import Callable, Dict, Iterable, Iterator, List, Optional

import numpy as np

from . import igtl
from ._native import BrainshiftError, Scene, Session, read_image

DEFAULT_PORT = 18944
UNIT_MM = {"mm": 1.0, "m": 1000.0}


def keep_large_buffers() -> bool:
    """Keeps freed large buffers in the process's heap (glibc malloc) instead of returning
    them to the kernel. Every update allocates image-sized arrays (35 MB each for the 8.7 M
    voxels of the MNI152 T1: the voxel owners, the warped image, the field); by default
    glibc maps each one anew and the kernel zero-fills it page by page on first touch.
    Measured with the same settings through the environment (``MALLOC_MMAP_THRESHOLD_``,
    ``MALLOC_TRIM_THRESHOLD_``) on ``cargo xtask bench update``: the warped T1 after an
    update 0.177 and 0.191 s → 0.161 and 0.154 s (two alternated pairs), peak memory the
    same (603 MiB). Returns whether the setting took (glibc only; elsewhere a no-op)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3
    return bool(mallopt(m_mmap_threshold, 1 << 30)) and bool(mallopt(m_trim_threshold, (1 << 31) - 1))


def _pyigtl():
    try:
        import pyigtl
    except ImportError:
        sys.exit(
            "brainshift serve needs pyigtl (the OpenIGTLink library): "
            "pip install 'brainshift[serve]' or pip install pyigtl"
        )
    return pyigtl


class Frame:
    """RAS millimetres (the wire) to and from the scene's frame and unit."""

    def __init__(self, space: str, units: str):
        self.flip = np.array([-1.0, -1.0, 1.0]) if space == "LPS" else np.ones(3)
        self.mm = UNIT_MM[units]

    def to_scene(self, ras_mm: np.ndarray) -> np.ndarray:
        return ras_mm * self.flip / self.mm

    def to_ras(self, scene: np.ndarray) -> np.ndarray:
        return scene * self.mm * self.flip


class Brainshift:
    """The session, the image, and what a measurement becomes: one update at a time."""

    def __init__(self, scene: str, image: str, set_name: Optional[str], threads: Optional[int],
                 field: bool = True, log: Callable[[str], None] = print, verbose: bool = False,
                 surface: bool = True):
        self.log = log
        started = time.perf_counter()
        s = Scene.from_toml(scene)
        self.frame = Frame(s.space, s.units)
        self.session = Session(s, threads=threads)
        self.image = read_image(image)
        sets = self.session.prescribed_sets()
        self.measured = self.session.measured_sets()
        if set_name is None:
            if len(sets) == 1:
                set_name = sets[0]
            elif sets or not self.measured:
                raise BrainshiftError(
                    f"{scene}: the scene prescribes {len(sets)} node sets ({', '.join(sets) or 'none'}); "
                    "name the one measurements move with --set"
                )
        elif set_name not in sets:
            raise BrainshiftError(
                f"{scene}: --set {set_name}: not a prescribed node set of the scene "
                f"(prescribed: {', '.join(sets) or 'none'})"
            )
        self.set_name = set_name
        ids = self.session.set_nodes(set_name) if set_name is not None else []
        self.set_ids = np.asarray(ids, dtype=np.int64)
        self.field = field
        self.verbose = verbose
        self.surface = surface
        self.preop_landmarks: Dict[int, tuple] = {}
        self.lock = threading.Lock()
        self.prepare_seconds = time.perf_counter() - started

    # -- measurements ------------------------------------------------------------------
    def measurement(self, client: int, h: igtl.Header, body: bytes) -> Optional[dict]:
        """The update a message asks for (keyword arguments of Session.update), None for a
        message that only stores something; raises MessageError."""
        pyigtl = _pyigtl()
        key = (h.type, h.device)
        if key in (("POINT", "IntraopPoints"), ("POLYDATA", "IntraopPoints")):
            if not self.measured:
                raise igtl.MessageError(
                    f"{h}: the scene has no [[measurement]] with points to fit (IntraopSurface imposes a surface)"
                )
            if h.type == "POINT":
                points = igtl.points_of(igtl.unpack_with(pyigtl.PointMessage, h, body), h)
            else:
                points, _ = igtl.unpack_polydata(h, body, triangles=False)
            self.log(f"  {h}: {len(points)} scanned points for {self.measured[0]}")
            return {"points": {self.measured[0]: self.frame.to_scene(points)}}
        if key == ("STRING", "Resect"):
            m = igtl.unpack_with(pyigtl.StringMessage, h, body)
            region = m.string.strip()
            if region not in self.session.regions():
                raise igtl.MessageError(
                    f"{h}: {region!r} is not a region still in the model; the regions are: "
                    f"{', '.join(self.session.regions())}"
                )
            self.log(f"  {h}: resecting {region}")
            return {"resect": region}
        if key == ("STRING", "Gravity"):
            m = igtl.unpack_with(pyigtl.StringMessage, h, body)
            direction = gravity_of(m.string, h)
            if self.session.gravity() is None:
                raise igtl.MessageError(f"{h}: the scene has no [gravity] to turn")
            self.log(f"  {h}: gravity turned to RAS ({', '.join(f'{c:g}' for c in direction)})")
            return {"gravity": list(direction * self.frame.flip)}
        if self.set_name is None:
            raise igtl.MessageError(
                f"{h}: the scene prescribes no node set to move; it takes POINT or POLYDATA "
                "'IntraopPoints' (or STRING 'Gravity')"
            )
        if key == ("POLYDATA", "IntraopSurface"):
            points, tris = igtl.unpack_polydata(h, body)
            self.log(f"  {h}: {len(points)} points, {len(tris)} triangles")
            return {"surface": {self.set_name: (self.frame.to_scene(points), tris)}}
        if key == ("POINT", "PreopLandmarks"):
            m = igtl.unpack_with(pyigtl.PointMessage, h, body)
            self.preop_landmarks[client] = (igtl.points_of(m, h), list(m.names))
            self.log(f"  {h}: {len(m.names)} pre-operative landmarks kept")
            return None
        if key == ("POINT", "IntraopLandmarks"):
            m = igtl.unpack_with(pyigtl.PointMessage, h, body)
            intra, names = igtl.points_of(m, h), list(m.names)
            if client not in self.preop_landmarks:
                raise igtl.MessageError(f"{h}: send POINT 'PreopLandmarks' first (the pairs' pre-operative positions)")
            pre, pre_names = self.preop_landmarks[client]
            pre, intra = pair_landmarks(pre, pre_names, intra, names, h)
            self.log(f"  {h}: {len(intra)} landmark pairs")
            return {"landmarks": {self.set_name: (self.frame.to_scene(pre), self.frame.to_scene(intra))}}
        if key == ("STRING", "Displacements"):
            m = igtl.unpack_with(pyigtl.StringMessage, h, body)
            d = displacements_of_csv(m.string, self.set_ids, h)
            self.log(f"  {h}: {len(d)} node displacements")
            return {"displacements": {self.set_name: d}}
        raise igtl.MessageError(
            f"{h}: not a measurement this server takes; it takes POLYDATA 'IntraopSurface', "
            "POINT 'PreopLandmarks' + 'IntraopLandmarks', STRING 'Displacements', POINT/POLYDATA "
            "'IntraopPoints' (a scan to fit), STRING 'Gravity' (x,y,z in RAS) or STRING 'Resect' (a region)"
        )

    def _progress(self, p: dict) -> None:
        self.log(
            f"    iteration {p['step']}: load {p['load_factor']:.3f}, error estimate "
            f"{p['error_estimate']:.2e}, max displacement {p['max_displacement']:.3f}, "
            f"{p['nodes_in_contact']} nodes in contact"
        )

    def update(self, loads: dict) -> Iterator[bytes]:
        """Solves (one update at a time), then yields the replies as buffers to send in
        order, each message computed just before it is sent: WarpedImage first (what the
        surgeon waits for), then DisplacementField, DeformedBrain and Report. Raises
        BrainshiftError before the first reply (the session keeps its last good state)."""
        t0 = time.perf_counter()
        progress = self._progress if self.verbose else None
        with self.lock:
            if "resect" in loads:
                r = self.session.resect(loads["resect"], progress=progress)
            else:
                r = self.session.update(**loads, progress=progress)
        solved = time.perf_counter()

        def replies():
            m = r.inverse_map(self.image)
            warped = m.warp(self.image)
            ras = m.affine  # voxel index -> RAS (mm)
            yield from igtl.image_parts(warped.T, ras, "WarpedImage")
            t_image = time.perf_counter()
            if self.field:
                yield from igtl.image_parts(m.field().transpose(2, 1, 0, 3), ras, "DisplacementField")
            if self.surface:
                points, tris, _ = r.surface()
                yield igtl.pack(igtl.TriangleMesh(self.frame.to_ras(points), tris, "DeformedBrain"))
            outside = m.outside
            report = dict(
                r.report,
                serve={"solve_seconds": solved - t0, "image_seconds": t_image - solved, "outside": outside},
            )
            yield igtl.string_message(json.dumps(report), "Report")
            self.log(
                f"  solved in {solved - t0:.2f} s ({report['steps']} Newton, {report['linear_iterations']} GMRES, "
                f"max displacement {report['max_displacement']:.2f} {report['units']}); WarpedImage packed "
                f"{t_image - solved:.2f} s later ({m.extension_iterations} extension iterations)"
            )
            if outside and outside["folding_voxels"] > 0:
                at = outside["min_det_at"]
                where = f" near RAS ({at[0]:.1f}, {at[1]:.1f}, {at[2]:.1f}) mm" if at else ""
                self.log(
                    f"  warning: the map between brain and skull folds at {outside['folding_voxels']} voxels{where} "
                    f"(det(I + grad d) min {outside['min_det']:.3f}): there the warped image repeats tissue"
                )

        return replies()


def gravity_of(text: str, h) -> np.ndarray:
    """Gravity's direction from ``x,y,z`` (RAS; any length but zero)."""
    try:
        d = np.array([float(c) for c in text.replace(" ", "").split(",")])
    except ValueError:
        d = np.array([])
    if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.any(d != 0.0):
        raise igtl.MessageError(
            f"{h}: {text!r} is not a direction: send three numbers x,y,z in RAS, not all zero "
            "(a supine patient: 0,-1,0)"
        )
    return d


def pair_landmarks(pre, pre_names, intra, names, h):
    """Landmark pairs: by name when both lists have the same unique non-empty names, else
    by order (then the counts must agree)."""
    if all(pre_names) and all(names) and len(set(names)) == len(names) and set(names) == set(pre_names) \
            and len(set(pre_names)) == len(pre_names):
        order = [pre_names.index(n) for n in names]
        return pre[order], intra
    if len(pre) != len(intra):
        raise igtl.MessageError(
            f"{h}: {len(intra)} intra-operative landmarks for {len(pre)} pre-operative ones "
            "(pairs are matched by name when both lists have the same names, else by order)"
        )
    return pre, intra


def displacements_of_csv(text: str, set_ids: np.ndarray, h) -> np.ndarray:
    """(n, 3) displacements in set order from CSV rows ``node_id,ux,uy,uz`` (header line
    first), one per node of the set."""
    index = {int(i): k for k, i in enumerate(set_ids)}
    d = np.full((len(set_ids), 3), np.nan)
    for line_no, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if line_no == 1 or not line:
            continue
        f = [x.strip() for x in line.split(",")]
        try:
            if len(f) != 4:
                raise ValueError
            node, u = int(f[0]), [float(x) for x in f[1:]]
            if not np.isfinite(u).all():
                raise ValueError
        except ValueError:
            raise igtl.MessageError(f"{h} line {line_no}: expected node_id,ux,uy,uz with numbers, found '{line}'") from None
        if node not in index:
            raise igtl.MessageError(f"{h} line {line_no}: node {node} is not in the measured node set")
        d[index[node]] = u
    missing = np.flatnonzero(np.isnan(d[:, 0]))
    if len(missing):
        raise igtl.MessageError(
            f"{h}: {len(missing)} nodes of the set have no row (first: node {int(set_ids[missing[0]])}); "
            "every node of the set needs one"
        )
    return d


class Server:
    """The listening socket and one thread per client; updates one at a time."""

    def __init__(self, brainshift: Brainshift, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 max_message_bytes: int = 64 << 20, log: Callable[[str], None] = print,
                 stall_seconds: float = 30.0, max_clients: int = 16):
        self.bs = brainshift
        self.log = log
        self.max_body = max_message_bytes
        self.stall = stall_seconds
        self.max_clients = max_clients
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.address = self.sock.getsockname()
        self.stopping = threading.Event()
        self.clients: Dict[int, socket.socket] = {}
        self.threads: List[threading.Thread] = []
        self.next_client = 1

    def serve_forever(self) -> None:
        while not self.stopping.is_set():
            try:
                conn, peer = self.sock.accept()
            except socket.timeout:
                continue
            except OSError:
                break
            if len(self.clients) >= self.max_clients:
                self.log(f"refused {peer[0]}:{peer[1]}: {self.max_clients} clients already connected")
                self._error(conn, f"the server already serves {self.max_clients} clients; try again later")
                conn.close()
                continue
            k = self.next_client
            self.next_client += 1
            self.clients[k] = conn
            t = threading.Thread(target=self._client, args=(k, conn, peer), daemon=True)
            self.threads.append(t)
            t.start()

    def stop(self) -> None:
        self.stopping.set()
        self.sock.close()
        for c in list(self.clients.values()):
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        for t in self.threads:
            t.join(timeout=30)

    def _client(self, k: int, conn: socket.socket, peer) -> None:
        name = f"client {k} ({peer[0]}:{peer[1]})"
        self.log(f"{name} connected")
        conn.settimeout(None)
        try:
            self._serve(k, conn, name)
        finally:
            self.clients.pop(k, None)
            self.bs.preop_landmarks.pop(k, None)
            conn.close()
            self.log(f"{name} disconnected")

    def _send(self, conn: socket.socket, data: Iterable[bytes]) -> bool:
        try:
            for d in data:
                conn.sendall(d)
            return True
        except OSError as e:
            self.log(f"  could not send the reply ({e}); the client is gone")
            return False
        except Exception as e:  # a reply that cannot be made: say so, keep serving
            return self._error(conn, f"could not make the reply: {e}")

    def _error(self, conn: socket.socket, text: str) -> bool:
        self.log(f"  error: {text}")
        return self._send(conn, [igtl.string_message(text, "Error")])

    def _serve(self, k: int, conn: socket.socket, name: str) -> None:
        while not self.stopping.is_set():
            try:
                msg = igtl.read_message(conn, self.max_body, self.stall)
            except igtl.ProtocolError as e:
                self._error(conn, f"{e}; closing the connection")
                return
            except OSError:
                return
            if msg is None:
                return
            h, body = msg
            started = time.perf_counter()
            self.log(f"{name}: {h.type} '{h.device}', {h.body_size} bytes")
            try:
                igtl.check_crc(h, body)
                if h.type.startswith(("GET_", "STT_", "STP_", "RTS_")) or h.type == "STATUS":
                    self.log("  query or status message: nothing to do")
                    continue
                loads = self.bs.measurement(k, h, body)
                if loads is None:
                    continue
                replies = self.bs.update(loads)
            except igtl.MessageError as e:
                if not self._error(conn, str(e)):
                    return
                continue
            except BrainshiftError as e:
                if not self._error(conn, f"{e}; the session keeps its last good state"):
                    return
                continue
            except Exception as e:  # never die on input: report and go on
                if not self._error(conn, f"internal error on {h}: {type(e).__name__}: {e}"):
                    return
                continue
            if not self._send(conn, replies):
                return
            self.log(f"  replied in {time.perf_counter() - started:.2f} s")


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(
        prog="brainshift serve",
        description="Serve brain-shift updates over OpenIGTLink (3D Slicer's OpenIGTLinkIF, "
        "PLUS, navigation systems): each intra-operative measurement is solved warm from the "
        "last one and answered with the warped image, the displacement field, the deformed "
        "brain surface and the report. Geometry on the wire is RAS, mm.",
    )
    p.add_argument("scene", help="scene file (.toml), e.g. fixtures/mni152/scene.toml")
    p.add_argument("--image", required=True, help="pre-operative image to warp (.nii, .nii.gz, .nrrd)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1, this machine only)")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"TCP port (default {DEFAULT_PORT}, OpenIGTLink's)")
    p.add_argument("--set", dest="set_name", help="node set the measurements move (default: the scene's only prescribed one)")
    p.add_argument("--threads", type=int, help="solver threads (default: all cores)")
    p.add_argument("--no-field", action="store_true", help="do not send the DisplacementField image")
    p.add_argument("--no-surface", action="store_true",
                   help="do not send the DeformedBrain surface (pyigtl 0.3.4 clients cannot read POLYDATA "
                        "unless they call brainshift.igtl.let_pyigtl_read_polydata())")
    p.add_argument("--verbose", action="store_true", help="print every solver iteration")
    p.add_argument("--max-message-mb", type=float, default=64.0, help="largest message accepted (default 64 MB)")
    p.add_argument("--stall-seconds", type=float, default=30.0,
                   help="close a connection silent this long in the middle of a message (default 30)")
    p.add_argument("--max-clients", type=int, default=16, help="clients served at once (default 16)")
    a = p.parse_args(argv)
    log = lambda s: print(s, flush=True)  # noqa: E731
    _pyigtl()
    keep_large_buffers()
    log(f"preparing {a.scene} and reading {a.image} ...")
    try:
        bs = Brainshift(a.scene, a.image, a.set_name, a.threads, field=not a.no_field, log=log,
                        verbose=a.verbose, surface=not a.no_surface)
        server = Server(bs, a.host, a.port, int(a.max_message_mb * (1 << 20)), log=log,
                        stall_seconds=a.stall_seconds, max_clients=a.max_clients)
    except (BrainshiftError, ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    log(
        f"prepared in {bs.prepare_seconds:.2f} s: {bs.image.shape[0]}x{bs.image.shape[1]}x{bs.image.shape[2]} "
        f"image, measurements move node set {bs.set_name} ({len(bs.set_ids)} nodes)"
    )
    log(f"listening on {server.address[0]}:{server.address[1]} (OpenIGTLink); Ctrl-C stops")
    # Ctrl-C stops the server even when the shell started it with SIGINT ignored.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, lambda *_: server.stopping.set())
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    log("stopping ...")
    server.stop()
    log("stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
