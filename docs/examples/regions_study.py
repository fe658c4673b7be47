"""How much model does a scene need? The full fixtures/mni152-regions model against three
simpler ones, each solved by `brainshift run` (docs/regions.md).

  full         parenchyma NH 3000 Pa, tumour NH 9000 Pa, ventricles SVK 100 Pa ν 0.1
  homogeneous  every element parenchyma (one material)
  holes        the ventricles' elements removed (their walls free, traction-free surfaces)
  no-tumour    the tumour's elements parenchyma (ventricles kept)

Every variant uses the fixture's mesh, loads, skull, element (t4) and solver; the holes
variant's mesh is brain.inp without the VENTRICLES elements (and the nodes only they used).
Measured against the full model: the displacement at the tumour's centre (interpolated in
the tet containing it), at the tumour's boundary nodes and at the ventricles' wall nodes
(max and mean of |u_variant − u_full|), over every node, and the Hausdorff distance between
the deformed ventricle surfaces (the full run's `surface-VENTRICLES.vtk`, and the same
triangles moved by each variant's displacements), sampled at the vertices, the edge
midpoints and 6 interior points per triangle of both surfaces (an approximation from below,
exact to within the sampling density). Solve time: report.json `solve_seconds` (median of
--repeat runs, one thread).

Run from the repository root after `cargo build --release -p bs-cli`:
    python3 docs/examples/regions_study.py [--repeat 3]
Writes docs/regions.csv, docs/regions.png and the table block of docs/regions.md.
"""

import argparse
import json
import os
import re
import subprocess
import sys

import numpy as np
from scipy.spatial import cKDTree

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
FIX = os.path.join(ROOT, "fixtures", "mni152-regions")
WORK = os.path.join(ROOT, "target", "regions-study")
BIN = os.path.join(ROOT, "target", "release", "brainshift")
TUMOUR_CENTRE = np.array([-12.0, -37.0, 50.0])  # fixtures/mni152-regions/make.py
NH = '{ model = "neo-hookean", youngs_modulus = 3000.0, poisson_ratio = 0.49, density = 1000.0 }'


def read_inp(path):
    """Nodes {id: xyz}, tets [(id, [4 node ids], elset)], node sets {name: [ids]}."""
    nodes, tets, nsets, elsets = {}, [], {}, {}
    mode, name = None, None
    for line in open(path):
        s = line.strip()
        if not s or s.startswith("**"):
            continue
        if s.startswith("*"):
            head = s.upper()
            mode = None
            if head.startswith("*NODE") and "PRINT" not in head:
                mode = "node"
            elif head.startswith("*ELEMENT"):
                found = re.search(r"ELSET=([^,\s]+)", s, re.I)
                mode, name = "elem", found.group(1) if found else None
            elif head.startswith("*ELSET"):
                mode, name = "elset", re.search(r"ELSET=([^,\s]+)", s, re.I).group(1)
            elif head.startswith("*NSET"):
                mode, name = "nset", re.search(r"NSET=([^,\s]+)", s, re.I).group(1)
                nsets.setdefault(name, [])
            continue
        f = [x for x in s.replace(",", " ").split()]
        if mode == "node":
            nodes[int(f[0])] = np.array([float(v) for v in f[1:4]])
        elif mode == "elem":
            tets.append((int(f[0]), [int(v) for v in f[1:5]], name))
        elif mode == "nset":
            nsets[name].extend(int(v) for v in f)
        elif mode == "elset":
            elsets.update((int(v), name) for v in f)
    tets = [(e, t, elsets.get(e, s)) for e, t, s in tets]
    assert all(s for _, _, s in tets), "an element in no element set"
    return nodes, tets, nsets


def write_inp(path, nodes, tets, nsets):
    used = sorted({n for _, t, _ in tets for n in t})
    with open(path, "w") as w:
        w.write("*NODE\n")
        for n in used:
            x = nodes[n]
            w.write(f"{n}, {float(x[0])!r}, {float(x[1])!r}, {float(x[2])!r}\n")
        sets = sorted({s for _, _, s in tets})
        for s in sets:
            w.write(f"*ELEMENT, TYPE=C3D4, ELSET={s}\n")
            for e, t, es in tets:
                if es == s:
                    w.write(f"{e}, {t[0]}, {t[1]}, {t[2]}, {t[3]}\n")
        keep = set(used)
        for name, ids in nsets.items():
            w.write(f"*NSET, NSET={name}\n")
            ids = [i for i in ids if i in keep]
            for k in range(0, len(ids), 12):
                w.write(", ".join(map(str, ids[k:k + 12])) + ",\n")


def scene(mesh, regions, surfaces):
    text = open(os.path.join(FIX, "scene.toml")).read()
    text = text.replace('file = "brain.inp"', f'file = "{mesh}"')
    text = text.replace('skull = "skull.off"', f'skull = "{os.path.join(FIX, "skull.off")}"')
    head, rest = text.split("[[region]]", 1)
    tail = rest[rest.index("# The brain stem"):]
    body = "".join(f'[[region]]\nelset = "{e}"\nmaterial = {m}\n\n' for e, m in regions)
    out = head + body + tail
    if surfaces:
        out += "\n[output]\nsurfaces = [" + ", ".join(f'"{s}"' for s in surfaces) + "]\n"
    return out


def full_regions():
    text = open(os.path.join(FIX, "scene.toml")).read()
    return re.findall(r'elset = "(\w+)"\nmaterial = (\{[^}]*\})', text)


def run(name, text, repeat):
    d = os.path.join(WORK, name)
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "scene.toml")
    open(path, "w").write(text)
    times = []
    for _ in range(repeat):
        done = subprocess.run([BIN, "run", path, "--out", os.path.join(d, "out"), "--threads", "1",
                               "--quiet"], capture_output=True, text=True)
        if done.returncode != 0:
            sys.exit(f"{name}: {done.stderr}")
        report = json.load(open(os.path.join(d, "out", "report.json")))
        times.append(report["solve_seconds"])
    u = {}
    for line in open(os.path.join(d, "out", "displacements.csv")).readlines()[1:]:
        f = line.split(",")
        u[int(f[0])] = np.array([float(v) for v in f[1:4]])
    return u, float(np.median(times)), report


def locate(nodes, tets, p):
    """The tet containing p and its barycentric weights."""
    ids = np.array([t for _, t, _ in tets])
    x = np.array([[nodes[n] for n in t] for t in ids])
    m = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    lam = np.linalg.solve(m, (p - x[:, 0])[:, :, None])[:, :, 0]
    bary = np.column_stack([1 - lam.sum(1), lam])
    k = int(np.argmax(bary.min(1)))
    assert bary[k].min() > -1e-9, "point outside the mesh"
    return ids[k], bary[k]


def boundary_nodes(tets, elset):
    faces = {}
    for _, t, s in tets:
        if s != elset:
            continue
        for f in ([t[0], t[1], t[2]], [t[0], t[1], t[3]], [t[0], t[2], t[3]], [t[1], t[2], t[3]]):
            key = tuple(sorted(f))
            faces[key] = faces.get(key, 0) + 1
    return sorted({n for f, c in faces.items() if c == 1 for n in f})


def read_vtk_surface(path):
    lines = open(path).read().splitlines()
    n = int(lines[4].split()[1])
    pts = np.array([[float(v) for v in l.split()] for l in lines[5:5 + n]])
    t = int(lines[5 + n].split()[1])
    tris = np.array([[int(v) for v in l.split()[1:]] for l in lines[6 + n:6 + n + t]])
    at = lines.index(f"node_id 1 {n} unsigned_long") + 1
    ids = [int(l) for l in lines[at:at + n]]
    return pts, tris, ids


def samples(pts, tris):
    a, b, c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
    out = [pts, (a + b) / 2, (b + c) / 2, (c + a) / 2]
    for w in ([1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6],
              [1 / 6, 1 / 6, 2 / 3], [0.5, 0.25, 0.25], [0.25, 0.5, 0.25]):
        out.append(w[0] * a + w[1] * b + w[2] * c)
    return np.vstack(out)


def hausdorff(p1, t1, p2, t2):
    s1, s2 = samples(p1, t1), samples(p2, t2)
    d12 = cKDTree(s2).query(s1)[0].max()
    d21 = cKDTree(s1).query(s2)[0].max()
    return float(max(d12, d21))


def main():
    global FIX, WORK
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--size", type=float, default=None,
                    help="re-mesh the fixture's labelmap at this size (mm) instead of using its 7 mm mesh")
    args = ap.parse_args()
    tag = ""
    if args.size is not None:
        tag = f"-{args.size:g}mm"
        WORK = WORK + tag
        mesh_dir = os.path.join(WORK, "mesh")
        done = subprocess.run([BIN, "mesh", os.path.join(FIX, "labels.nii.gz"), "--out", mesh_dir,
                               "--region", "ventricles=4", "--region", "tumour=5", "--size",
                               str(args.size), "--craniotomy"], capture_output=True, text=True)
        if done.returncode != 0:
            sys.exit(done.stderr)
        print("\n".join(l for l in done.stdout.splitlines() if "set " in l or "mesh at" in l))
        # The fixture's scene on the new mesh and skull (the same keys, materials, loads).
        open(os.path.join(mesh_dir, "scene.toml"), "w").write(open(os.path.join(FIX, "scene.toml")).read())
        FIX = mesh_dir
    nodes, tets, nsets = read_inp(os.path.join(FIX, "brain.inp"))
    os.makedirs(WORK, exist_ok=True)
    holes_mesh = os.path.join(WORK, "brain-holes.inp")
    write_inp(holes_mesh, nodes, [t for t in tets if t[2] != "VENTRICLES"], nsets)
    full = full_regions()
    mesh = os.path.join(FIX, "brain.inp")
    variants = [
        ("full", scene(mesh, full, ["VENTRICLES", "TUMOUR"])),
        ("homogeneous", scene(mesh, [("*", NH)], [])),
        ("holes", scene(holes_mesh, [r for r in full if r[0] != "VENTRICLES"], [])),
        ("no-tumour", scene(mesh, [(e, NH if e == "TUMOUR" else m) for e, m in full], [])),
    ]
    results = {name: run(name, text, args.repeat) for name, text in variants}
    tet, w = locate(nodes, tets, TUMOUR_CENTRE)
    tumour_wall = boundary_nodes(tets, "TUMOUR")
    ventricle_wall = boundary_nodes(tets, "VENTRICLES")
    pts, tris, ids = read_vtk_surface(os.path.join(WORK, "full", "out", "surface-VENTRICLES.vtk"))
    ref = np.array([nodes[i] for i in ids])
    u_full = results["full"][0]
    rows = []
    for name, (u, solve, report) in results.items():
        centre = sum(wk * u[n] for wk, n in zip(w, tet))
        centre_full = sum(wk * u_full[n] for wk, n in zip(w, tet))
        def diff(nodeset):
            d = np.array([np.linalg.norm(u[n] - u_full[n]) for n in nodeset])
            return d.max(), d.mean()
        common = [n for n in u_full if n in u]
        dt, dtm = diff(tumour_wall)
        dv, dvm = diff(ventricle_wall)
        da, dam = diff(common)
        moved = ref + np.array([u[i] for i in ids])
        rows.append({
            "variant": name,
            "elements": report["elements"],
            "u_tumour_centre_mm": float(np.linalg.norm(centre)),
            "d_tumour_centre_mm": float(np.linalg.norm(centre - centre_full)),
            "d_tumour_wall_max_mm": float(dt), "d_tumour_wall_mean_mm": float(dtm),
            "d_ventricle_wall_max_mm": float(dv), "d_ventricle_wall_mean_mm": float(dvm),
            "d_all_max_mm": float(da), "d_all_mean_mm": float(dam),
            "hausdorff_ventricles_mm": hausdorff(pts, tris, moved, tris),
            "u_ventricle_wall_max_mm": float(max(np.linalg.norm(u[n]) for n in ventricle_wall)),
            "solve_seconds": solve,
            "iterations": report["steps"],
            "nodes_in_contact": report["nodes_in_contact"],
        })
    keys = list(rows[0])
    with open(os.path.join(ROOT, "docs", f"regions{tag}.csv"), "w") as f:
        f.write(",".join(keys) + "\n")
        for r in rows:
            f.write(",".join(str(r[k]) for k in keys) + "\n")
    for r in rows:
        print(json.dumps(r))
    if not tag:
        figure(rows)
    table(rows, tag)


def table(rows, tag):
    """The Markdown table between the markers of docs/regions.md."""
    out = ["| model | elements | \\|u\\| tumour centre | Δ tumour centre | Δ tumour wall max / mean | "
           "Δ ventricle wall max / mean | Hausdorff ventricles | Δ whole brain max / mean | "
           "solve (1 thread) | Newton iterations |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(
            f"| {r['variant']} | {r['elements']} | {r['u_tumour_centre_mm']:.3f} mm | "
            f"{r['d_tumour_centre_mm']:.3f} mm | {r['d_tumour_wall_max_mm']:.3f} / "
            f"{r['d_tumour_wall_mean_mm']:.3f} mm | {r['d_ventricle_wall_max_mm']:.3f} / "
            f"{r['d_ventricle_wall_mean_mm']:.3f} mm | {r['hausdorff_ventricles_mm']:.3f} mm | "
            f"{r['d_all_max_mm']:.3f} / {r['d_all_mean_mm']:.4f} mm | {r['solve_seconds']:.2f} s | "
            f"{r['iterations']} |")
    path = os.path.join(ROOT, "docs", "regions.md")
    text = open(path).read()
    start = f"<!-- table{tag}: docs/examples/regions_study.py -->"
    end = f"<!-- /table{tag} -->"
    a, b = text.index(start) + len(start), text.index(end)
    open(path, "w").write(text[:a] + "\n" + "\n".join(out) + "\n" + text[b:])


def figure(rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [r["variant"] for r in rows[1:]]
    groups = [("tumour centre", "d_tumour_centre_mm"), ("tumour wall (max)", "d_tumour_wall_max_mm"),
              ("ventricle wall (max)", "d_ventricle_wall_max_mm"),
              ("ventricle Hausdorff", "hausdorff_ventricles_mm"), ("whole brain (max)", "d_all_max_mm")]
    fig, ax = plt.subplots(figsize=(8, 3.6), dpi=120)
    width = 0.8 / len(names)
    for k, name in enumerate(names):
        r = rows[1 + k]
        ax.bar([g + k * width for g in range(len(groups))], [r[key] for _, key in groups], width,
               label=name)
    ax.set_xticks([g + width * (len(names) - 1) / 2 for g in range(len(groups))])
    ax.set_xticklabels([g for g, _ in groups], fontsize=8)
    ax.set_ylabel("|u − u_full| [mm]")
    ax.set_title("MNI152 with ventricles and tumour: what each simplification changes", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(ROOT, "docs", "regions.png"))


if __name__ == "__main__":
    main()
