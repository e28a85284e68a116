#!/usr/bin/env python3
"""Fits an oriented point cloud with duplexfit and writes the zero-level and offset meshes and the field.

    PYTHONPATH=build/python /usr/bin/python3 python/examples/fit_sphere.py \\
        ../shared/data/clouds/sphere_10k.ply --offset 0.05 -o out-python

writes out-python/zero.ply (the surface), out-python/offset.ply (the surface moved 0.05 inward) and
out-python/field.dpxf, and prints how far the meshes' vertices are from the centre of the cloud's box
(for sphere_10k, radius 0.5: about 0.5 and 0.45).
"""

import argparse
import os
import sys
import time

import numpy as np

import duplexfit


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cloud", help="oriented point cloud (PLY or XYZ with normals)")
    parser.add_argument("--offset", type=float, default=0.05, help="offset delta, > 0 inward (default 0.05)")
    parser.add_argument("--device", default=None, help="device spec: cpu, gpu, ref, P:D (default: the default)")
    parser.add_argument("-o", "--out", default="out-python", help="output folder (default out-python)")
    args = parser.parse_args()

    points, normals = duplexfit.read_point_cloud(args.cloud)
    print(f"{args.cloud}: {len(points)} points")

    def progress(stage, fraction, message):
        # One line per level (and the stages around the levels); returning False would cancel.
        if stage in ("hierarchy", "constraints") and message:
            done = "" if fraction is None else f" {100 * fraction:3.0f}%"
            print(f"  {stage}{done} {message}", file=sys.stderr)
        return True

    start = time.perf_counter()
    field = duplexfit.fit(points, normals, offsets=[args.offset], device=args.device, progress=progress)
    report = field.report
    print(f"fit: {report['levels']} levels, {field.centres} centres, E0 {report['e0']:.2e}, "
          f"converged {report['converged']}, {time.perf_counter() - start:.1f} s on {report['device']}")

    os.makedirs(args.out, exist_ok=True)
    lo, hi = field.bounds
    centre = 0.5 * (lo + hi)
    for name, iso in (("zero", 0.0), ("offset", args.offset)):
        start = time.perf_counter()
        vertices, faces = field.mesh(iso)
        path = os.path.join(args.out, name + ".ply")
        duplexfit.write_mesh(path, vertices, faces)
        radius = np.linalg.norm(vertices - centre, axis=1)
        topology = duplexfit.mesh_topology(vertices, faces)
        print(f"{path}: iso {iso}, {len(faces)} triangles, {topology['components']} component(s), "
              f"{'watertight' if topology['watertight'] else 'NOT watertight'}, distance from the box centre "
              f"{radius.min():.4f} .. {radius.max():.4f}, {time.perf_counter() - start:.1f} s")
    field.save(os.path.join(args.out, "field.dpxf"))
    print(f"{os.path.join(args.out, 'field.dpxf')}: f at the box centre {field.value([centre])[0]:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
