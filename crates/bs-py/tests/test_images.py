"""Result.warp and Result.field against `brainshift warp` and `brainshift field` of the
same result, read back with nibabel: the same library calls, so the field is bit-identical
and the warped image equal up to the NIfTI's storage (the CLI keeps the input's int16
datatype, rounding each value: within half a unit)."""

import nibabel
import numpy as np

from brainshift import BrainshiftError, Scene

import pytest


@pytest.fixture(scope="module")
def ellipsoid_result(request):
    from conftest import FIXTURES

    return Scene.from_toml(FIXTURES / "ellipsoid" / "scene.toml").run()


def test_warp_and_field_equal_the_cli(ellipsoid_result, fixtures, cli, tmp_path):
    result = ellipsoid_result
    run = tmp_path / "run"
    result.write(run)
    preop = fixtures / "registration" / "preop.nii.gz"

    o = cli("warp", "--image", preop, "--result", run, "--out", tmp_path / "w.nii.gz")
    assert o.returncode == 0, o.stderr
    img = nibabel.load(tmp_path / "w.nii.gz")
    warped, affine = result.warp(preop)
    assert warped.dtype == np.float32 and warped.shape == img.shape
    assert np.allclose(affine, img.affine, atol=1e-4)
    assert np.abs(warped - img.get_fdata()).max() <= 0.5 + 1e-3
    # The warp did something: the brain moved 10 mm.
    pre = nibabel.load(preop).get_fdata()
    assert np.abs(warped - pre).max() > 50

    o = cli("field", "--reference", preop, "--result", run, "--out", tmp_path / "f.nii.gz")
    assert o.returncode == 0, o.stderr
    f = np.asarray(nibabel.load(tmp_path / "f.nii.gz").dataobj).reshape(warped.shape + (3,))
    field, affine_f = result.field(preop)
    assert field.dtype == np.float32 and field.shape == warped.shape + (3,)
    assert np.array_equal(field, f)
    assert np.array_equal(affine_f, affine)
    # Inside the deformed brain the inverse of the FE map: about the 10 mm push. In the gap
    # beyond the skin a voxel may point at the pre-operative gap's nearest voxel centre (up
    # to 15 mm on these 4 mm voxels; fixtures/registration/README.md).
    norm = np.linalg.norm(field, axis=-1)
    inside = result.inverse_map(preop).inside
    assert 5.0 < norm[inside].max() < 12.0
    assert norm.max() <= norm[inside].max() + 12 * 4.0 * np.sqrt(3) + 1e-3


def test_a_missing_image_is_refused(ellipsoid_result, tmp_path):
    with pytest.raises(BrainshiftError, match="missing.nii.gz"):
        ellipsoid_result.warp(tmp_path / "missing.nii.gz")
