#!/usr/bin/python3
"""Outputs check (the print-workflow targets): the default fit of a cloud at one or more offsets, its meshes
written as float32 STL, then read back by tools a user's chain would run on them.

For every delta:
  1. `duplexfit fit CLOUD --offset D --format stl --shell --deviation-samples 0 -o TMP --quiet`
     (every vertex and face centre in the level-set deviation);
  2. per mesh (zero, offset, shell): triangles, the deviation's max as a fraction of the largest side
     (report.json), admesh's summary (degenerate facets, edges fixed, facets removed/added, backwards edges,
     parts) and Open3D's checks after welding the STL's float32 vertices (edge-manifold, vertex-manifold,
     orientable, Euler characteristic);
  3. the shell's volume against the zero mesh's minus the offset's (signed volumes of the STL triangles);
  4. `duplexfit slice FIELD --cusp C -o TMP/slices` (placed on the plate by default): the lowest `$$LAYER`
     height of the .cli file.
Prints a markdown table on stdout and the raw figures as JSON (--json FILE).

usage: /usr/bin/python3 bench/outputs_check.py [--cloud data/maxplanck_12k.ply] [--deltas 0.02,0.005]
           [--duplexfit build/cli/duplexfit] [--cusp 0.01] [--json FILE] [--keep DIR]
Needs numpy, admesh (Debian package admesh) and python3-open3d; a missing tool's columns say "n/a".
"""
import argparse
import json
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import time

try:
    import numpy as np
except ImportError:  # pragma: no cover
    sys.exit("outputs_check.py needs numpy (python3-numpy)")


def log(msg):
    print("[outputs %s] %s" % (time.strftime("%H:%M:%S"), msg), file=sys.stderr, flush=True)


def read_stl(path):
    """Triangles of a binary STL as a (n, 3, 3) float32 array."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 84:
        raise ValueError("%s: too short for a binary STL" % path)
    n = struct.unpack_from("<I", data, 80)[0]
    if len(data) != 84 + 50 * n:
        raise ValueError("%s: %d bytes for %d triangles (not a binary STL)" % (path, len(data), n))
    rec = np.frombuffer(data, dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), count=n,
                        offset=84)
    return rec["v"].astype(np.float64)


def signed_volume(tris):
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def admesh_summary(path):
    exe = shutil.which("admesh")
    if exe is None:
        return None
    out = subprocess.run([exe, path], capture_output=True, check=False).stdout.decode("utf-8", "replace")
    keys = {"degenerate": r"Degenerate facets\s*:\s*(\d+)", "edges_fixed": r"Edges fixed\s*:\s*(\d+)",
            "facets_removed": r"Facets removed\s*:\s*(\d+)", "facets_added": r"Facets added\s*:\s*(\d+)",
            "facets_reversed": r"Facets reversed\s*:\s*(\d+)", "backwards_edges": r"Backwards edges\s*:\s*(\d+)",
            "normals_fixed": r"Normals fixed\s*:\s*(\d+)", "parts": r"Number of parts\s*:\s*(\d+)"}
    res = {}
    for k, rx in keys.items():
        m = re.search(rx, out)
        res[k] = int(m.group(1)) if m else None
    res["clean"] = all(res[k] == 0 for k in ("degenerate", "edges_fixed", "facets_removed", "facets_added",
                                             "facets_reversed", "backwards_edges", "normals_fixed"))
    return res


def open3d_summary(path):
    try:
        import open3d as o3d  # noqa: F401
    except ImportError:
        return None
    import open3d as o3d
    m = o3d.io.read_triangle_mesh(path)
    m.remove_duplicated_vertices()
    v, e = len(m.vertices), None
    f = len(m.triangles)
    t = np.asarray(m.triangles)
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    e = len(np.unique(edges, axis=0))
    return {"vertices": v, "faces": f, "edge_manifold": bool(m.is_edge_manifold(allow_boundary_edges=False)),
            "vertex_manifold": bool(m.is_vertex_manifold()), "orientable": bool(m.is_orientable()),
            "euler": v - e + f}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap.add_argument("--cloud", default=os.path.join(root, "data", "maxplanck_12k.ply"))
    ap.add_argument("--deltas", default="0.02,0.005")
    ap.add_argument("--duplexfit", default=os.path.join(root, "build", "cli", "duplexfit"))
    ap.add_argument("--cusp", type=float, default=0.01)
    ap.add_argument("--json")
    ap.add_argument("--keep", help="folder to keep the outputs in (default: a temporary one, removed)")
    a = ap.parse_args()
    work = a.keep or tempfile.mkdtemp(prefix="duplexfit-outputs-")
    os.makedirs(work, exist_ok=True)
    rows = []
    try:
        for d in [float(x) for x in a.deltas.split(",")]:
            out = os.path.join(work, "d%g" % d)
            shutil.rmtree(out, ignore_errors=True)
            log("fit %s --offset %g" % (os.path.basename(a.cloud), d))
            t0 = time.time()
            subprocess.run([a.duplexfit, "fit", a.cloud, "--offset", str(d), "--format", "stl", "--shell",
                            "--deviation-samples", "0", "-o", out, "--quiet"], check=True, stdout=subprocess.DEVNULL)
            seconds = time.time() - t0
            rep = json.load(open(os.path.join(out, "report.json")))
            devs = {os.path.splitext(m["file"])[0]: m for m in rep["meshes"]}
            volumes = {}
            for name in ("zero", "offset1", "shell"):
                path = os.path.join(out, name + ".stl")
                tris = read_stl(path)
                volumes[name] = signed_volume(tris)
                dev = devs.get(name, {}).get("level_set_deviation", {})
                log("  %s: %d triangles; admesh, Open3D" % (name, len(tris)))
                rows.append({"delta": d, "mesh": name, "triangles": int(len(tris)), "fit_seconds": seconds,
                             "deviation_max_relative": dev.get("max_relative"),
                             "deviation_p99_relative": dev.get("p99_relative"), "admesh": admesh_summary(path),
                             "open3d": open3d_summary(path), "volume": volumes[name]})
            expected = volumes["zero"] - volumes["offset1"]
            rows[-1]["volume_expected"] = expected
            rows[-1]["volume_error"] = (volumes["shell"] - expected) / expected
            sl = os.path.join(out, "slices")
            subprocess.run([a.duplexfit, "slice", os.path.join(out, "field.dpxf"), "--cusp", str(a.cusp), "-o", sl,
                            "--quiet"], check=True, stdout=subprocess.DEVNULL)
            clis = [f for f in os.listdir(sl) if f.endswith(".cli")]
            heights = []
            for f in clis:
                for line in open(os.path.join(sl, f), errors="replace"):
                    m = re.match(r"\$\$LAYER/([-0-9.eE+]+)", line.strip())
                    if m:
                        heights.append(float(m.group(1)))
            rows[-1]["cli_layers"] = len(heights)
            rows[-1]["cli_lowest_layer"] = min(heights) if heights else None
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)

    def fmt(x, spec):
        return "n/a" if x is None else format(x, spec)

    print("| δ | mesh | triangles | deviation max / p99 (% of side) | admesh | Open3D (edge-, vertex-manifold, "
          "orientable, χ) | shell volume vs zero − offset | lowest .cli layer |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        adm = r["admesh"]
        adm_s = "n/a" if adm is None else ("clean" if adm["clean"] else
                                          "; ".join("%s %s" % (k, v) for k, v in adm.items() if v))
        if adm is not None:
            adm_s += ", %s part(s)" % adm["parts"]
        o = r["open3d"]
        o_s = "n/a" if o is None else "%s, %s, %s, %d" % (
            "yes" if o["edge_manifold"] else "NO", "yes" if o["vertex_manifold"] else "NO",
            "yes" if o["orientable"] else "NO", o["euler"])
        dev = "n/a" if r["deviation_max_relative"] is None else "%.3f / %.4f" % (
            100 * r["deviation_max_relative"], 100 * r["deviation_p99_relative"])
        vol = "%+.3f%%" % (100 * r["volume_error"]) if "volume_error" in r else ""
        low = "%s (%d layers)" % (fmt(r.get("cli_lowest_layer"), ".4g"), r["cli_layers"]) if "cli_layers" in r else ""
        print("| %g | %s | %s | %s | %s | %s | %s | %s |" % (r["delta"], r["mesh"], format(r["triangles"], ","), dev,
                                                            adm_s, o_s, vol, low))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
