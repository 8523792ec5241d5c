#!/usr/bin/python3
"""Renders an output folder of `dhfcast decompose` to a PNG: the parts exploded along their
removal directions, each in its own colour, and the two mold halves of the largest part opened
apart along its direction. A plain picture for documentation, not a viewer.

    scripts/render_preview.py OUTDIR PNG

Needs Debian's python3-matplotlib (run with /usr/bin/python3).
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

COLOURS = ["#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1",
           "#ff9da7", "#9c755f", "#bab0ac"]


def read_stl(path):
    """Triangles of a binary STL as an (n, 3, 3) array."""
    with open(path, "rb") as f:
        data = f.read()
    n = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0])
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
    return np.frombuffer(data, dtype=record, count=n, offset=84)["corners"].astype(float)


def shaded(triangles, colour, light=np.array([0.3, -0.5, 0.8])):
    """Face colours: the base colour dimmed by the angle to a light from the viewer's side."""
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    light = light / np.linalg.norm(light)
    lambert = 0.35 + 0.65 * np.clip(normals @ light, 0, 1)
    rgb = np.array(matplotlib.colors.to_rgb(colour))
    return np.clip(lambert[:, None] * rgb[None, :], 0, 1)


def draw(ax, meshes, title):
    points = np.concatenate([t.reshape(-1, 3) for t, _ in meshes])
    for triangles, colour in meshes:
        ax.add_collection3d(Poly3DCollection(triangles, facecolors=shaded(triangles, colour),
                                             linewidths=0))
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    for axis, c in zip("xyz", centre):
        getattr(ax, f"set_{axis}lim")(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=20, azim=-60)
    ax.set_axis_off()
    ax.set_title(title)


def motion(m):
    m = np.array(m, dtype=float)
    return m[:, :3], m[:, 3]


def main(outdir, png):
    d = json.load(open(f"{outdir}/decomposition.json"))
    parts = d["parts"]
    size = np.ptp(np.array(d["input"]["bbox_mm"], dtype=float), axis=0).max()
    fig = plt.figure(figsize=(12, 6), dpi=100)

    exploded = []
    for p in parts:
        triangles = read_stl(f"{outdir}/{p['mesh']}")
        away = np.array(p.get("removal_direction", p["direction"]), dtype=float)
        exploded.append((triangles + 0.25 * size * away, COLOURS[p["id"] % len(COLOURS)]))
    draw(fig.add_subplot(1, 2, 1, projection="3d"), exploded,
         f"{len(parts)} parts, exploded along their removal directions")

    with_molds = [p for p in parts if isinstance(p.get("molds"), dict) and "up" in p["molds"]]
    if with_molds:
        p = max(with_molds, key=lambda q: q["volume_mm3"])
        d_vec = np.array(p["direction"], dtype=float)
        meshes = [(read_stl(f"{outdir}/{p['mesh']}"), COLOURS[p["id"] % len(COLOURS)])]
        for half, sign, colour in (("up", 1, "#c8c8c8"), ("down", -1, "#8a8a8a")):
            rotation, translation = motion(p["molds"][f"{half}_to_model"])
            triangles = read_stl(f"{outdir}/{p['molds'][half]}") @ rotation.T + translation
            meshes.append((triangles + sign * 0.6 * size * d_vec, colour))
        draw(fig.add_subplot(1, 2, 2, projection="3d"), meshes,
             f"part {p['id']} and its two mold halves, opened along its direction")
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.93, wspace=0)
    fig.savefig(png)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
