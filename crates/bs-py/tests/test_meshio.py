"""The mesh outputs of `brainshift run` and `brainshift mesh` open in meshio 5.3.5 (the
mesh library of SlicerCBM and most Python pipelines): the legacy VTK copies (result.vtk,
brain.vtk) carry the displacement, ids, node and element sets as point and cell data, and
the frame as `SPACE=` in their title line, as 3D Slicer reads it. (The .vtu files carry the
frame as a `SPACE` String field-data array, which Slicer reads from XML files and meshio
5.3 refuses: "Illegal data type 'String'".)
"""

import csv

import meshio
import numpy as np


def title_line(path):
    with open(path, "rb") as f:
        f.readline()
        return f.readline().decode().strip()


def test_run_writes_a_result_meshio_reads_with_displacements_and_sets(fixtures, cli, tmp_path):
    out = tmp_path / "run"
    o = cli("run", fixtures / "sphere-shell/scene.toml", "--out", out, "--quiet")
    assert o.returncode == 0, o.stderr
    m = meshio.read(out / "result.vtk")
    assert title_line(out / "result.vtk").endswith("SPACE=RAS")
    ref = meshio.read(fixtures / "sphere-shell/brain.inp")
    assert m.points.shape == ref.points.shape
    np.testing.assert_array_equal(m.points, ref.points)
    assert sum(len(c.data) for c in m.cells) == sum(len(c.data) for c in ref.cells)
    # Displacements: bit for bit those of displacements.csv, row by node id.
    with open(out / "displacements.csv") as f:
        rows = {int(r["node_id"]): [float(r[k]) for k in ("ux", "uy", "uz")]
                for r in csv.DictReader(f)}
    ids = m.point_data["node_id"].astype(np.int64)
    u = m.point_data["displacement"]
    assert u.shape == (len(ids), 3)
    np.testing.assert_array_equal(u, np.array([rows[i] for i in ids]))
    assert np.abs(u).max() > 5.0  # the craniotomy moved 10 mm in
    # Node sets as 0/1 point data, the same nodes as the Abaqus deck's *NSET.
    for name in ("FIXED", "CRANIOTOMY"):
        flags = m.point_data[f"nset:{name}"]
        members = np.flatnonzero(flags)
        np.testing.assert_array_equal(np.sort(members), np.sort(ref.point_sets[name]))
    # Element sets and the per-element results as cell data.
    assert all(np.all(b == 1) for b in m.cell_data["elset:BRAIN"])
    assert all(np.all(b > 0) for b in m.cell_data["J"])
    assert "von_mises" in m.cell_data and "in_contact" in m.point_data


def test_mesh_writes_a_brain_meshio_reads_with_its_sets(fixtures, cli, tmp_path):
    out = tmp_path / "model"
    o = cli("mesh", fixtures / "mni152/mask.nii.gz", "--out", out, "--size", "10",
            "--craniotomy")
    assert o.returncode == 0, o.stderr
    m = meshio.read(out / "brain.vtk")
    assert title_line(out / "brain.vtk").endswith("SPACE=RAS")
    ref = meshio.read(out / "brain.inp")
    np.testing.assert_array_equal(m.points, ref.points)
    assert [len(c.data) for c in m.cells] == [len(c.data) for c in ref.cells]
    for name in ("FIXED", "CRANIOTOMY"):
        members = np.flatnonzero(m.point_data[f"nset:{name}"])
        assert len(members) > 0
        np.testing.assert_array_equal(np.sort(members), np.sort(ref.point_sets[name]))
    # The brain lies in the MNI152 head (RAS mm).
    lo, hi = m.points.min(axis=0), m.points.max(axis=0)
    assert (hi - lo).min() > 100 and (hi - lo).max() < 200
    # The mesh's last line names what the scene still needs (here: nothing; it runs).
    assert "next:" not in o.stdout.strip().splitlines()[-1]
    o = cli("mesh", fixtures / "mni152/mask.nii.gz", "--out", tmp_path / "bare", "--size", "10")
    assert o.returncode == 0, o.stderr
    assert "CRANIOTOMY" in o.stdout.strip().splitlines()[-1]
