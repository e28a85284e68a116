#!/usr/bin/env python3
"""Where a fitted zero level's topology differs from the truth's: voxel solids compared on one grid.

Usage: bench/topology_diff.py FIELD.dpxf TRUTH_MESH.ply [--cell H] [--margin M] [--json OUT]

Samples the fitted field (f > 0 inside) and the truth mesh's inside (ray parity along +z, exact for a
closed mesh) at the nodes of one grid of spacing H over the truth's box, and reports for each solid its
Euler characteristic as a union of closed voxels (b0 - b1 + b2: 1 - genus for one solid component without
cavities), the characteristics with only the missing solid added and with only the extra solid removed,
and every connected cluster of differing voxels whose flip changes the characteristic (so a handle or a
tunnel that one solid has and the other has not): its centre, its extent, and its extra and missing voxels.
Sample the grid finer than the features whose topology you ask about: a neck thinner than H can vanish.

Needs numpy, scipy, open3d (reading the mesh) and the duplexfit Python module (PYTHONPATH=build/python).
The truth's parity is a numpy loop over its triangles: about 30 s for a 56k-triangle mesh at H = 0.002 of
a unit box (26M nodes); memory about 60 bytes a node.
"""
import argparse
import json
import sys

import numpy as np


def truth_inside(vertices, faces, xs, ys, zs):
    """Inside test of a closed mesh at every grid node: the parity of the crossings of the vertical line
    through (x, y) below z. Half-open barycentric tests count a line through a shared edge once."""
    nx, ny = len(xs), len(ys)
    x0, hx = xs[0], xs[1] - xs[0]
    y0, hy = ys[0], ys[1] - ys[0]
    a_all, b_all, c_all = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    columns, heights = [], []
    for a, b, c in zip(a_all, b_all, c_all):
        lo = np.minimum(np.minimum(a, b), c)
        hi = np.maximum(np.maximum(a, b), c)
        i0, i1 = max(0, int(np.ceil((lo[0] - x0) / hx))), min(nx - 1, int(np.floor((hi[0] - x0) / hx)))
        j0, j1 = max(0, int(np.ceil((lo[1] - y0) / hy))), min(ny - 1, int(np.floor((hi[1] - y0) / hy)))
        if i1 < i0 or j1 < j0:
            continue
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if det == 0:
            continue  # vertical triangle: no vertical line crosses it
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
        ii, jj = ii.ravel(), jj.ravel()
        px, py = x0 + ii * hx, y0 + jj * hy
        w1 = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det
        w2 = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det
        w0 = 1.0 - w1 - w2
        hit = ((w0 >= 0) & (w1 > 0) & (w2 > 0)) | ((w0 > 0) & (w1 >= 0) & (w2 > 0)) | ((w0 > 0) & (w1 > 0) & (w2 >= 0))
        if hit.any():
            columns.append(ii[hit] * ny + jj[hit])
            heights.append(w0[hit] * a[2] + w1[hit] * b[2] + w2[hit] * c[2])
    inside = np.zeros((nx * ny, len(zs)), bool)
    if not columns:
        return inside.reshape(nx, ny, len(zs))
    columns, heights = np.concatenate(columns), np.concatenate(heights)
    order = np.lexsort((heights, columns))
    columns, heights = columns[order], heights[order]
    keys = np.arange(nx * ny)
    starts, ends = np.searchsorted(columns, keys), np.searchsorted(columns, keys, "right")
    for col in np.nonzero(ends > starts)[0]:
        inside[col] = np.searchsorted(heights[starts[col]:ends[col]], zs) % 2 == 1
    return inside.reshape(nx, ny, len(zs))


def euler(solid):
    """Euler characteristic of the union of closed voxels: vertices - edges + squares - cubes."""
    v = np.pad(solid.astype(bool), 1)

    def grown(axes):  # cells of the complex touched by a voxel, along the given axes
        out = v.copy()
        for axis in axes:
            shifted = out.copy()
            dst = [slice(None)] * 3
            src = [slice(None)] * 3
            dst[axis], src[axis] = slice(1, None), slice(0, -1)
            shifted[tuple(dst)] |= out[tuple(src)]
            out = shifted
        return out

    v = np.pad(v, ((0, 1), (0, 1), (0, 1)))
    cubes = int(v.sum())
    squares = sum(int(grown([a]).sum()) for a in range(3))
    edges = sum(int(grown(pair).sum()) for pair in ((0, 1), (0, 2), (1, 2)))
    vertices = int(grown([0, 1, 2]).sum())
    return vertices - edges + squares - cubes


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("field")
    p.add_argument("truth")
    p.add_argument("--cell", type=float, default=0.002, help="grid spacing (input units)")
    p.add_argument("--margin", type=float, default=0.01, help="grid beyond the truth's box (input units)")
    p.add_argument("--json", help="write the figures here")
    args = p.parse_args()
    try:
        import duplexfit
        import open3d as o3d
        from scipy import ndimage
    except ImportError as e:
        sys.exit("topology_diff.py: %s (PYTHONPATH=build/python for duplexfit; python3-open3d, python3-scipy)" % e)

    mesh = o3d.io.read_triangle_mesh(args.truth)
    vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    if len(faces) == 0:
        sys.exit("topology_diff.py: %s has no triangles" % args.truth)
    lo, hi = vertices.min(0) - args.margin, vertices.max(0) + args.margin
    # Nodes offset by a third of a cell from the box's corner, so that axis-aligned faces of a CAD truth do
    # not lie on a grid plane (where the two samplings would disagree by rounding alone).
    xs = [np.arange(lo[a] + args.cell / 3.0, hi[a], args.cell) for a in range(3)]
    shape = tuple(len(x) for x in xs)
    gx, gy, gz = np.meshgrid(*xs, indexing="ij")
    nodes = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], 1)
    del gx, gy, gz
    field = duplexfit.load_field(args.field)
    ours = np.empty(len(nodes), bool)
    for i in range(0, len(nodes), 1 << 22):
        ours[i:i + (1 << 22)] = np.asarray(field.value(nodes[i:i + (1 << 22)])) > 0.0
    ours = ours.reshape(shape)
    del nodes
    truth = truth_inside(vertices, faces, *xs)

    result = {"cell": args.cell, "grid": list(shape), "ours_voxels": int(ours.sum()), "truth_voxels": int(truth.sum()),
              "chi_ours": euler(ours), "chi_truth": euler(truth), "chi_ours_plus_missing": euler(ours | truth),
              "chi_ours_minus_extra": euler(ours & truth), "clusters": []}
    differ = ours != truth
    labels, count = ndimage.label(differ, structure=np.ones((3, 3, 3)))
    boxes = ndimage.find_objects(labels)
    for i, box in enumerate(boxes):
        grown = tuple(slice(max(0, s.start - 2), s.stop + 2) for s in box)
        here = labels[grown] == i + 1
        before = ours[grown]
        after = before.copy()
        after[here] = truth[grown][here]
        change = euler(after) - euler(before)
        if change != 0:
            centre = lo + args.cell / 3.0 + np.array(ndimage.center_of_mass(here)) * args.cell + \
                np.array([s.start for s in grown]) * args.cell
            result["clusters"].append({
                "chi_change": int(change), "centre": [round(float(c), 5) for c in centre],
                "extent": [round((s.stop - s.start) * args.cell, 5) for s in box],
                "extra_voxels": int((here & before).sum()), "missing_voxels": int((here & ~before).sum())})
    result["clusters"].sort(key=lambda c: (-abs(c["chi_change"]), c["centre"]))
    result["differing_clusters"] = int(count)

    print("grid %s at cell %g: ours %d voxels, truth %d" % (shape, args.cell, result["ours_voxels"], result["truth_voxels"]))
    print("Euler characteristic of the voxel solids: ours %d, truth %d; ours with the missing solid added %d, "
          "with the extra solid removed %d" % (result["chi_ours"], result["chi_truth"], result["chi_ours_plus_missing"],
                                               result["chi_ours_minus_extra"]))
    print("%d clusters of differing voxels; those whose flip changes the characteristic:" % count)
    for c in result["clusters"]:
        print("  %+d at %s, extent %s, %d extra and %d missing voxels" % (c["chi_change"], c["centre"], c["extent"],
                                                                         c["extra_voxels"], c["missing_voxels"]))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
