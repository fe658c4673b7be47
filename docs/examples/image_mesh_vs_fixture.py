"""The MNI152 brain meshed from its labelmap by `brainshift mesh` against the bundled
fixture mesh (fixtures/mni152, gmsh), under the same loads: issue 15's real-labelmap check.

The fixture's brain is cut flat at z = -66 mm and its craniotomy is the boundary within
30 mm of a fixed centre; to compare like with like the labelmap is cut at the same height
and the meshed scene selects its craniotomy with a `sphere` at that centre. Both scenes are
solved; the image mesh's displacement is interpolated (linear) at the fixture's nodes.

    python3 docs/examples/image_mesh_vs_fixture.py target/release/brainshift [SIZE_MM ...]

Needs numpy, scipy, nibabel and meshio. Prints mean / median / max differences in mm.
"""

import os
import re
import subprocess
import sys
import tempfile

import meshio
import nibabel as nib
import numpy as np
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import cKDTree

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CENTRE = [-12.381930144908935, -36.77234985549018, 81.80078394948251]  # PROVENANCE.txt
Z_CUT = -66.0


def result(folder):
    """Points and displacements of a result.vtu (meshio does not read VTK String field
    data, so the SPACE string is dropped from a copy first)."""
    text = open(os.path.join(folder, "result.vtu"), "rb").read()
    text = re.sub(rb"<FieldData>.*?</FieldData>\n", b"", text, flags=re.S)
    copy = os.path.join(folder, "result-nofielddata.vtu")
    open(copy, "wb").write(text)
    m = meshio.read(copy)
    return m.points, m.point_data["displacement"]


def main():
    exe = os.path.abspath(sys.argv[1])
    sizes = [float(s) for s in sys.argv[2:]] or [7.0]
    work = tempfile.mkdtemp(prefix="bs-image-vs-fixture-")
    subprocess.run([exe, "run", os.path.join(ROOT, "fixtures/mni152/scene.toml"), "--out",
                    os.path.join(work, "fixture"), "--quiet"], check=True)
    ref_p, ref_u = result(os.path.join(work, "fixture"))
    mask = nib.load(os.path.join(ROOT, "fixtures/mni152/mask.nii.gz"))
    a = np.asanyarray(mask.dataobj).copy()
    k_cut = int(round(np.linalg.solve(mask.affine, [0, 0, Z_CUT, 1])[2]))
    a[:, :, :k_cut] = 0
    cut = os.path.join(work, "mask-cut.nii.gz")
    nib.save(nib.Nifti1Image(a, mask.affine, mask.header), cut)
    for size in sizes:
        d = os.path.join(work, f"image-{size:g}")
        subprocess.run([exe, "mesh", cut, "--out", d, "--size", str(size), "--craniotomy"],
                       check=True, stdout=subprocess.DEVNULL)
        scene = os.path.join(d, "scene.toml")
        text = open(scene).read().replace(
            'nset = "CRANIOTOMY"', f"sphere = {{ centre = {CENTRE}, radius = 30.0 }}")
        open(scene, "w").write(text)
        subprocess.run([exe, "run", scene, "--out", os.path.join(d, "out"), "--quiet"],
                       check=True)
        p, u = result(os.path.join(d, "out"))
        v = LinearNDInterpolator(p, u)(ref_p)
        outside = np.isnan(v[:, 0])
        if outside.any():
            v[outside] = u[cKDTree(p).query(ref_p[outside])[1]]
        diff = np.linalg.norm(v - ref_u, axis=1)
        print(f"image mesh {size:g} mm ({len(p)} nodes) vs fixture ({len(ref_p)} nodes): "
              f"mean {diff.mean():.3f} mm, median {np.median(diff):.3f}, max {diff.max():.2f} "
              f"({outside.sum()} fixture nodes outside the image mesh, nearest node used)")


if __name__ == "__main__":
    main()
