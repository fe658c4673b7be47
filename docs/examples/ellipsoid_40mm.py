"""Draw docs/ellipsoid-40mm.svg: the paper's ellipsoid pushed 40 mm, the material plane
Y = 0 in its deformed place, each element's piece coloured by its volume ratio J, for the
coarse tetrahedral mesh (Newton-Krylov) and the hexahedral mesh (Dynamic Relaxation), with
the skull's section. Where the tets under the craniotomy flatten (J -> 0), the hexahedra
stay near 0.8.

    brainshift run fixtures/ellipsoid/scene-40mm.toml --out tet40
    brainshift run fixtures/ellipsoid/scene-40mm-dr.toml --out hex40
    python3 docs/examples/ellipsoid_40mm.py tet40/result.vtk hex40/result.vtk docs/ellipsoid-40mm.svg

Needs meshio and numpy only (the SVG is written as text; docs/ellipsoid-40mm.png is the
same picture rasterised, e.g. `rsvg-convert -o ellipsoid-40mm.png ellipsoid-40mm.svg` (Debian librsvg2-bin)).
"""

import sys

import meshio
import numpy as np

# A hexahedron (VTK order) as six tetrahedra around its 0-6 diagonal.
HEX_TETS = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]
TET_EDGES = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
J_MAX = 1.2  # the colour scale: 0 (flat) .. J_MAX
# viridis at 0, 0.25, 0.5, 0.75, 1 (interpolated linearly between)
STOPS = [(68, 1, 84), (59, 82, 139), (33, 145, 140), (94, 201, 98), (253, 231, 37)]
SCALE = 3.0  # px per mm
PANEL_W, PANEL_H = 190 * SCALE, 140 * SCALE


def colour(j):
    t = min(max(j / J_MAX, 0.0), 1.0) * (len(STOPS) - 1)
    i = min(int(t), len(STOPS) - 2)
    f = t - i
    c = [round(a + f * (b - a)) for a, b in zip(STOPS[i], STOPS[i + 1])]
    return f"rgb({c[0]},{c[1]},{c[2]})"


def plane_pieces(points, u, cells, j):
    """The polygons where the reference plane Y = 0 cuts each tetrahedron (hexahedra split
    into six), placed at their deformed positions (x, z), with the J of their element."""
    if cells.shape[1] == 8:
        tets = np.concatenate([cells[:, list(t)] for t in HEX_TETS])
        owner = np.tile(np.arange(len(cells)), len(HEX_TETS))
    else:
        tets, owner = cells, np.arange(len(cells))
    # 1 µm off Y = 0: the hexahedral grid has faces on Y = 0 itself.
    y = points[tets, 1] - 1e-3
    cut = (y.min(1) < 0) & (y.max(1) > 0)
    by_owner = {}
    for t, e in zip(tets[cut], owner[cut]):
        pts = []
        for a, b in TET_EDGES:
            ya, yb = points[t[a], 1] - 1e-3, points[t[b], 1] - 1e-3
            if (ya < 0) != (yb < 0):
                s = ya / (ya - yb)
                x = (1 - s) * (points[t[a]] + u[t[a]]) + s * (points[t[b]] + u[t[b]])
                pts.append(x[[0, 2]])
        by_owner.setdefault(e, []).extend(pts)
    # One polygon per element (a hexahedron's six tets' pieces joined), corners by angle.
    pieces = []
    for e, pts in by_owner.items():
        pts = np.unique(np.round(np.array(pts), 9), axis=0)
        if len(pts) >= 3:
            c = pts.mean(0)
            pts = pts[np.argsort(np.arctan2(pts[:, 1] - c[1], pts[:, 0] - c[0]))]
            pieces.append((pts, float(j[e])))
    return pieces


def panel(path, title, left):
    """SVG of one panel whose left edge is at `left` px."""
    m = meshio.read(path)
    pieces = plane_pieces(m.points, m.point_data["displacement"], m.cells[0].data, m.cell_data["J"][0])
    cx, cy = left + PANEL_W / 2, 40 + PANEL_H / 2

    def xy(p):
        return f"{cx + SCALE * p[0]:.1f},{cy - SCALE * p[1]:.1f}"

    out = [f'<text x="{cx:.0f}" y="18" text-anchor="middle" font-size="14">{title}</text>']
    smallest = min(v for _, v in pieces)
    out.append(f'<text x="{cx:.0f}" y="34" text-anchor="middle" font-size="12">smallest J in the plane {smallest:.4f}</text>')
    for pts, v in pieces:
        out.append(f'<polygon points="{" ".join(xy(p) for p in pts)}" fill="{colour(v)}" stroke="black" stroke-width="0.3"/>')
    t = np.linspace(0, 2 * np.pi, 200)
    skull = " ".join(xy((83 * np.cos(a), 58 * np.sin(a))) for a in t)
    out.append(f'<polygon points="{skull}" fill="none" stroke="grey" stroke-width="1.5"/>')
    out.append(f'<text x="{cx:.0f}" y="{40 + PANEL_H + 14:.0f}" text-anchor="middle" font-size="11">x (mm) across, z (mm) up; grey: the skull in the plane Y = 0</text>')
    return out


def legend(left):
    out = []
    n = 60
    for i in range(n):
        j = J_MAX * i / (n - 1)
        y = 40 + PANEL_H - (i + 1) * PANEL_H / n
        out.append(f'<rect x="{left}" y="{y:.1f}" width="18" height="{PANEL_H / n + 0.5:.1f}" fill="{colour(j)}"/>')
    for j in (0.0, 0.4, 0.8, 1.2):
        y = 40 + PANEL_H - j / J_MAX * PANEL_H
        out.append(f'<text x="{left + 24}" y="{y + 4:.0f}" font-size="11">{j:.1f}</text>')
    out.append(f'<text x="{left}" y="34" font-size="11">J</text>')
    return out


def main():
    tet, hexa, out = sys.argv[1:4]
    width, height = 2 * PANEL_W + 70, PANEL_H + 60
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" font-family="DejaVu Sans, sans-serif">',
             f'<rect width="{width:.0f}" height="{height:.0f}" fill="white"/>']
    parts += panel(tet, "coarse tetrahedra (T4ANP), Newton-Krylov, 40 mm", 0)
    parts += panel(hexa, "hexahedra (H8), Dynamic Relaxation, 40 mm", PANEL_W)
    parts += legend(2 * PANEL_W + 15)
    parts.append("</svg>")
    with open(out, "w") as f:
        f.write("\n".join(parts) + "\n")


if __name__ == "__main__":
    main()
