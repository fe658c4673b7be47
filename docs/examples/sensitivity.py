#!/usr/bin/env python3
"""Sensitivity of brain shift at a deep target to the brain's Young's modulus E, its
Poisson's ratio nu and the craniotomy displacement: the MNI152 case
(fixtures/mni152/scene.toml) on a 3 x 3 x 3 grid (27 runs), run through Dask on a
LocalCluster, collected into one table and plotted.

    pip install ./crates/bs-py matplotlib "dask[distributed]"
    python docs/examples/sensitivity.py [--workers 2] [--runs target/sensitivity]

Writes docs/sensitivity.csv and docs/sensitivity.png (the run folders, with every
result.vtu, stay under --runs).
"""

import argparse
import csv
import time
from pathlib import Path

import numpy as np

import brainshift
from brainshift import sweep

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "fixtures/mni152/scene.toml"

E = [1500.0, 3750.0, 6000.0]          # Pa
NU = [0.45, 0.47, 0.49]
PUSH = [-4.0, -8.0, -12.0]            # mm along z (the craniotomy's displacement)
KEYS = {
    "region.material.youngs_modulus": ("Young's modulus E [Pa]", E),
    "region.material.poisson_ratio": ("Poisson's ratio ν", NU),
    "boundary.1.displacement.z": ("craniotomy displacement [mm]", PUSH),
}


def deep_target():
    """The mesh's node centroid: a point deep in the brain, far from every boundary."""
    mesh = brainshift.read_mesh(ROOT / "fixtures/mni152/brain.inp")
    return tuple(float(round(x, 1)) for x in mesh["nodes"].mean(axis=0))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--threads", type=int, default=1, help="threads per run")
    ap.add_argument("--runs", default=str(ROOT / "target/sensitivity"))
    ap.add_argument("--out", default=str(ROOT / "docs"))
    args = ap.parse_args()

    runs = Path(args.runs)
    runs.mkdir(parents=True, exist_ok=True)
    sweep_file = runs / "sweep.toml"
    axes = "".join(
        f'[[axis]]\nkey = "{k}"\nvalues = {[float(v) for v in vals]}\n'
        for k, (_, vals) in KEYS.items()
    )
    sweep_file.write_text(f'base = "{SCENE}"\n{axes}')
    sweep.plan(sweep_file, runs / "sweep")
    target = deep_target()

    from dask.distributed import Client, LocalCluster

    started = time.perf_counter()
    with LocalCluster(n_workers=args.workers, threads_per_worker=1,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        rows = sweep.run_dask(runs / "sweep", client, threads=args.threads,
                              points={"target": target})
    wall = time.perf_counter() - started
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"{len(rows)} runs in {wall:.1f} s on {args.workers} workers; "
          f"{len(failed)} not ok; target {target} mm")
    for r in failed:
        print(f"  row {r['index']}: {r['status']}: {r['error']}")

    out = Path(args.out)
    cols = ["index", *KEYS, "target_umag", "target_ux", "target_uy", "target_uz",
            "max_displacement", "nodes_in_contact", "solve_seconds", "status"]
    with open(out / "sensitivity.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["index", "youngs_modulus_pa", "poisson_ratio", "craniotomy_z_mm",
                    "target_umag_mm", "target_ux_mm", "target_uy_mm", "target_uz_mm",
                    "max_displacement_mm", "nodes_in_contact", "solve_seconds", "status"])
        for r in rows:
            w.writerow([r[c] if r[c] is not None else "" for c in cols])

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r["status"] == "ok"]
    fig, axs = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, (k, (label, vals)) in zip(axs, KEYS.items()):
        x = np.array([r[k] for r in ok])
        y = np.array([r["target_umag"] for r in ok])
        ax.scatter(x, y, s=18, alpha=0.6, color="tab:blue", label="each run")
        means = [y[x == v].mean() for v in vals]
        ax.plot(vals, means, "o-", color="tab:red", label="mean over the other two")
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axs[0].set_ylabel(f"|u| at the deep target {target} [mm]")
    axs[0].legend(fontsize=8)
    fig.suptitle("MNI152 brain shift at a deep target: 27 runs (3 × 3 × 3 grid) on Dask")
    fig.tight_layout()
    fig.savefig(out / "sensitivity.png", dpi=110)
    print(f"wrote {out / 'sensitivity.csv'} and {out / 'sensitivity.png'}")


if __name__ == "__main__":
    main()
