"""brainshift.Session: a live session's updates against the command line. A session's
first solve, and any update after reset(), starts from the reference state exactly as
`brainshift run` does: bit-identical. A warm update (from the last state) agrees with the
cold CLI run to the solver tolerance of the scene (1e-10 mm; asserted at 1e-8 mm)."""

import numpy as np
import pytest

from brainshift import BrainshiftError, Scene, Session

from test_bindings import read_csv

CUBE = "cube/uniaxial-t4.toml"


def scene_with_top(fixtures, tmp_path, dz):
    """The cube scene with its top face (ZMAX) pushed dz instead of -0.1."""
    text = (fixtures / CUBE).read_text()
    text = text.replace('"../basic/cube-t4.msh"', repr(str(fixtures / "basic" / "cube-t4.msh")).replace("'", '"'))
    text = text.replace("displacement = { z = -0.1 }", f"displacement = {{ z = {dz!r} }}")
    path = tmp_path / f"cube-{dz}.toml"
    path.write_text(text)
    return path


def cli_displacements(cli, scene, out):
    o = cli("run", scene, "--out", out, "--quiet")
    assert o.returncode == 0, o.stderr
    return read_csv(out / "displacements.csv")[1]


def test_session_matches_the_cli_cold_bit_for_bit_and_warm_to_the_tolerance(fixtures, cli, tmp_path):
    session = Session(Scene.from_toml(fixtures / CUBE))
    first = session.update()  # the scene's own load, from the reference state
    u_cli = cli_displacements(cli, fixtures / CUBE, tmp_path / "a")
    assert np.array_equal(first.displacements.view(np.uint64), u_cli.view(np.uint64))

    u_cli = cli_displacements(cli, scene_with_top(fixtures, tmp_path, -0.2), tmp_path / "b")
    steps = []
    warm = session.update(displacements={"ZMAX": [0.0, 0.0, -0.2]}, progress=steps.append)
    assert len(steps) == warm.report["steps"] and steps[-1]["load_factor"] == 1.0
    # The counts so far, per iteration: the last ones are the report's.
    assert steps[-1]["linear_iterations"] == warm.report["linear_iterations"]
    assert steps[-1]["force_evaluations"] <= warm.report["force_evaluations"]
    assert np.abs(warm.displacements - u_cli).max() < 1e-8
    assert warm.report["converged"] and warm.report["max_displacement"] > 0.2

    session.reset()
    cold = session.update(displacements={"ZMAX": [0.0, 0.0, -0.2]})
    assert np.array_equal(cold.displacements.view(np.uint64), u_cli.view(np.uint64))


def test_per_node_displacements_follow_set_nodes(fixtures):
    session = Session(Scene.from_toml(fixtures / CUBE))
    ids = session.set_nodes("ZMAX")
    per_node = np.zeros((len(ids), 3))
    per_node[:, 2] = -0.15
    a = session.update(displacements={"ZMAX": per_node})
    rows = {int(i): k for k, i in enumerate(a.node_ids)}
    assert np.all(a.displacements[[rows[i] for i in ids], 2] == -0.15)
    b = session.update(displacements={"ZMAX": [0.0, 0.0, -0.15]})
    assert np.abs(a.displacements - b.displacements).max() < 1e-8


def test_a_refused_update_keeps_the_session(fixtures):
    session = Session(Scene.from_toml(fixtures / CUBE))
    good = session.update(displacements={"ZMAX": [0.0, 0.0, -0.05]}).displacements
    with pytest.raises(BrainshiftError, match="prescribed node sets are: ZMAX"):
        session.update(displacements={"TOP": [0.0, 0.0, -0.1]})
    with pytest.raises(BrainshiftError, match="leaves this component free"):
        session.update(displacements={"ZMAX": [0.1, 0.0, -0.1]})
    with pytest.raises(BrainshiftError, match="2 displacements for"):
        session.update(displacements={"ZMAX": np.zeros((2, 3))})
    # Still at the last good state: an update with the same load returns it unchanged.
    again = session.update(displacements={"ZMAX": [0.0, 0.0, -0.05]}).displacements
    assert np.abs(again - good).max() < 1e-8


def test_surface_and_landmarks_given_as_arrays(fixtures):
    session = Session(Scene.from_toml(fixtures / CUBE))
    plane = (np.array([[-1.0, -1.0, 0.9], [2.0, -1.0, 0.9], [2.0, 2.0, 0.9], [-1.0, 2.0, 0.9]]),
             np.array([[0, 1, 2], [0, 2, 3]]))
    # The arrays reach the scene's surface loader; ZMAX prescribes only z, and a measured
    # surface moves all three components, which an update may not change.
    with pytest.raises(BrainshiftError, match="other components"):
        session.update(surface={"ZMAX": plane})
    with pytest.raises(ValueError, match="give pairs"):
        session.update(landmarks={"ZMAX": (np.zeros((4, 3)), np.zeros((3, 3)))})
    with pytest.raises(ValueError, match="file path or a pair of arrays"):
        session.update(surface={"ZMAX": 3})
    assert session.update().report["converged"]


def test_a_new_scan_is_fitted_warm(fixtures):
    """fixtures/fit: a session's first solve fits the scene's scan; the same scan given as
    an array lands at the same answer (a new scan is fitted from the reference state, as a
    cold run is; 1e-9 mm is rounding), a deeper scan moves the window deeper, and bad scans
    are refused."""
    fit = fixtures / "fit"
    session = Session(Scene.from_toml(fit / "scene.toml"))
    assert session.measured_sets() == ["CRANIOTOMY"]
    first = session.update()
    scan = np.loadtxt(fit / "scan.csv", delimiter=",", skiprows=1)
    again = session.update(points={"CRANIOTOMY": scan})
    assert np.abs(again.displacements - first.displacements).max() < 1e-9
    m = again.report["measurements"][0]
    assert m["points"] == len(scan) and m["inliers"] > 0.9 * len(scan)
    deeper = session.update(points={"CRANIOTOMY": scan - [0.0, 0.0, 1.0]})
    assert deeper.report["measurements"][0]["mean_pull"] > m["mean_pull"] + 0.5
    with pytest.raises(BrainshiftError, match="scanned node sets are: CRANIOTOMY"):
        session.update(points={"TOP": scan})
    with pytest.raises(BrainshiftError, match="none of its"):
        session.update(points={"CRANIOTOMY": scan * 1e-3})
    with pytest.raises(ValueError, match="in one call, not two"):
        session.update(points={"CRANIOTOMY": scan}, displacements={"FIXED": [0.0, 0.0, 0.0]})


def test_new_landmarks_of_a_measurement_are_fitted_as_the_cli_fits_them(fixtures, cli, tmp_path):
    """A landmark [[measurement]] on the cube's top (ZMAX, fitted through it): new pairs
    given to update(landmarks=...) on that node set are fitted from the reference state with
    the session's preparation, as `brainshift run` fits a scene holding those pairs (on a
    boundary's node set they are fitted through it: test_serve's landmark test)."""
    rng = np.random.default_rng(7)
    pre = 0.2 + 0.6 * rng.random((10, 3))
    first = pre + np.outer(pre[:, 2], [0.0, 0.0, -0.05])
    second = pre + np.outer(pre[:, 2], [0.02, 0.0, -0.08])

    def scene(name, intra):
        rows = "\n".join(",".join(repr(float(v)) for v in np.r_[a, b]) for a, b in zip(pre, intra))
        (tmp_path / f"{name}.csv").write_text("x,y,z,x2,y2,z2\n" + rows + "\n")
        mesh = str(fixtures / "basic" / "cube-t4.msh")
        text = (
            f'units = "mm"\n[mesh]\nfile = "{mesh}"\nelement = "t4"\n[[region]]\nelset = "*"\n'
            'material = { model = "neo-hookean", youngs_modulus = 3000.0, poisson_ratio = 0.3 }\n'
            '[[boundary]]\nnset = "ZMIN"\nfix = ["x", "y", "z"]\n'
            f'[[measurement]]\nlandmarks = "{name}.csv"\nnset = "ZMAX"\nsigma = 0.001\n'
            "[solver]\ntolerance = 1e-9\n"
        )
        path = tmp_path / f"{name}.toml"
        path.write_text(text)
        return path

    session = Session(Scene.from_toml(scene("first", first)))
    assert session.landmark_sets() == ["ZMAX"] and session.measured_sets() == []
    session.update()
    u_cli = cli_displacements(cli, scene("second", second), tmp_path / "second")
    r = session.update(landmarks={"ZMAX": (pre, second)})
    assert np.abs(r.displacements - u_cli).max() < 1e-8
    assert r.report["measurements"][0]["kind"] == "landmarks"
    again = session.update(landmarks={"ZMAX": tmp_path / "second.csv"})
    assert np.abs(again.displacements - r.displacements).max() < 1e-12
    with pytest.raises(ValueError, match="in one call, not two"):
        session.update(landmarks={"ZMAX": (pre, first)}, displacements={"ZMIN": [0.0, 0.0, 0.0]})


def test_gravity_turned_in_a_session_agrees_with_the_cli_run_of_that_direction(fixtures, cli, tmp_path):
    """fixtures/column (a confined column under its weight, its lower half in fluid): the
    weight turned upwards (the column hangs from its base) in the session, against a cold
    `brainshift run` of the scene with that direction (both at the scene's 1e-6 mm
    tolerance; asserted at 1e-5 mm)."""
    scene = fixtures / "column" / "scene.toml"
    session = Session(Scene.from_toml(scene))
    assert session.gravity() == [0.0, 0.0, -1.0]
    down = session.update()
    assert down.displacements[:, 2].min() < -2.0  # it settles
    up = session.update(gravity=[0.0, 0.0, 2.0])
    text = scene.read_text().replace("direction = [0.0, 0.0, -1.0]", "direction = [0.0, 0.0, 1.0]")
    text = text.replace('"column-h8-16.inp"', f'"{fixtures / "column" / "column-h8-16.inp"}"')
    (tmp_path / "up.toml").write_text(text)
    u_cli = cli_displacements(cli, tmp_path / "up.toml", tmp_path / "up")
    # Now it hangs from its base, stretched (the fluid is below the level along gravity: the
    # upper half is the buoyed one now).
    assert up.displacements[:, 2].max() > 0.5
    assert np.abs(up.displacements - u_cli).max() < 1e-5
    assert session.gravity() == [0.0, 0.0, 2.0]
    with pytest.raises(BrainshiftError, match="non-zero"):
        session.update(gravity=[0.0, 0.0, 0.0])
    assert session.gravity() == [0.0, 0.0, 2.0]
    with pytest.raises(BrainshiftError, match="no \\[gravity\\] to turn"):
        Session(Scene.from_toml(fixtures / CUBE)).update(gravity=[0.0, 0.0, -1.0])


def test_a_tumour_resected_in_a_session_agrees_with_the_cli_run_of_the_resected_scene(fixtures, cli, tmp_path):
    """fixtures/mni152-regions: the tumour resected in a live session after the scene's own
    push, against a cold `brainshift run` of the scene with `resected = true`. The two land
    on the same contact equilibrium within 0.01 mm (warm and cold paths may settle held
    contact nodes a few micrometres apart; both at the 1e-3 mm tolerance)."""
    scene = fixtures / "mni152-regions" / "scene.toml"
    session = Session(Scene.from_toml(scene))
    intact = session.update()
    assert session.regions() == ["BRAIN", "TUMOUR", "VENTRICLES"]
    with pytest.raises(BrainshiftError, match="not a region of the scene still in the model"):
        session.resect("TUMOR")
    r = session.resect("TUMOUR")
    assert r.report["resected"]["regions"] == ["TUMOUR"] and r.report["resected"]["elements"] == 109
    assert session.regions() == ["BRAIN", "VENTRICLES"]
    text = scene.read_text().replace(
        'elset = "TUMOUR"\n', 'elset = "TUMOUR"\nresected = true\n'
    )
    for name in ("brain.inp", "skull.off"):
        text = text.replace(f'"{name}"', f'"{fixtures / "mni152-regions" / name}"')
    (tmp_path / "resected.toml").write_text(text)
    u_cli = cli_displacements(cli, tmp_path / "resected.toml", tmp_path / "r")
    assert np.abs(r.displacements - u_cli).max() < 0.01
    # Without the stiffer tumour the tissue under the craniotomy gives: the answers differ.
    assert np.abs(r.displacements - intact.displacements).max() > 0.1
    # The warped T1 shows the cavity as the fluid around the brain (0 in this skull-stripped
    # template), where the pre-operative image has the tumour's tissue.
    import nibabel

    t1 = fixtures / "mni152" / "t1.nii.gz"
    warped, _ = r.warp(t1)
    assert nibabel.load(t1).get_fdata()[86, 97, 122] > 100 and warped[86, 97, 122] == 0.0
    # The warped labelmap: the tumour's label 5 there becomes background, or the label named
    # for the cavity; nothing else changes.
    labels = fixtures / "mni152-regions" / "labels.nii.gz"
    plain, _ = r.warp(labels, labels=True)
    named, _ = r.warp(labels, labels=True, cavity_label=6)
    assert plain[86, 97, 122] == 0 and named[86, 97, 122] == 6
    changed = plain != named
    assert changed.any() and (plain[changed] == 0).all() and (named[changed] == 6).all()
