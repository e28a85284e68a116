#!/usr/bin/env python3
"""Slicing benchmark: `duplexfit fit` then `duplexfit slice` (adaptive, both modes) on the paper's head and
on a torus, on every device `duplexfit devices --json` lists (the reference path included). Prints layers,
layers/s and contour vertices/s per device and mode, with the layer counts of the paper's Fig. 21.

Settings (docs/method.md §10.6, §11): τ = 0.01, t_min = τ/4, t_max = 5τ; grid 0.005 for the head and 0.01
for the torus (Fig. 21). The paper scales each model to unit *width*; the clouds here have their longest
side 1, so the head (maxplanck_40k: x 0.70, y 0.90, z 1.00) is sliced with every length divided by the
scale s = 1/width (the count of a field scaled by s at τ equals that of the unscaled field at τ/s), and its
inward offset is δ = 0.025 (the paper's Moai, Fig. 7's middle value) in those units. The torus is
torus_10k (R = 0.35, r = 0.15, unit width) stood upright by slicing along y, with δ = 0.1 as in §10.6.

    python3 bench/slice_bench.py [--cli build/cli/duplexfit] [--devices ref,0:0] [--fit-device SPEC]
                                 [--width-axis x|y] [--work DIR] [--cusp-rule geometric|paper]
"""
import argparse
import json
import os
import struct
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
CLOUDS = os.path.join(ROOT, "..", "shared", "data", "clouds")

# Fig. 21: head 88 layers (zero-level only) and 114 (both); torus 67 and 75; τ = 0.01.
PAPER = {"head": {"zero": 88, "shell": 114}, "torus": {"zero": 67, "shell": 75}}


def ply_bounds(path):
    """Axis-aligned bounds of a binary little-endian PLY with float x, y, z first."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii", "replace").splitlines()
    n = int(next(l for l in header if l.startswith("element vertex")).split()[2])
    props = [l.split()[1] for l in header if l.startswith("property")]
    fmt = "<" + "".join({"float": "f", "double": "d", "uchar": "B", "int": "i"}[t] for t in props)
    size = struct.calcsize(fmt)
    lo, hi = [float("inf")] * 3, [float("-inf")] * 3
    for i in range(n):
        v = struct.unpack_from(fmt, data, end + i * size)
        for k in range(3):
            lo[k] = min(lo[k], v[k])
            hi[k] = max(hi[k], v[k])
    return lo, hi


def run(cmd, quiet=True):
    t = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        sys.stderr.write("failed (%d): %s\n%s\n" % (p.returncode, " ".join(cmd), p.stderr[-4000:]))
        raise SystemExit(1)
    return p.stdout, time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default=None, help="the duplexfit binary (default: build*/cli/duplexfit)")
    ap.add_argument("--devices", default=None, help="comma-separated specs (default: all listed, ref included)")
    ap.add_argument("--fit-device", default=None, help="device of the fits (default: the default device)")
    ap.add_argument("--width-axis", default="x", choices=["x", "y"], help="the head's 'width' (default x)")
    ap.add_argument("--cusp-rule", default="geometric", choices=["geometric", "paper"])
    ap.add_argument("--work", default=None, help="folder for fields and slices (default: a temporary one)")
    ap.add_argument("--models", default="head,torus")
    args = ap.parse_args()

    cli = args.cli
    if cli is None:
        for cand in ("build/cli/duplexfit", "build-slice/cli/duplexfit"):
            if os.path.exists(os.path.join(ROOT, cand)):
                cli = os.path.join(ROOT, cand)
                break
    if cli is None or not os.path.exists(cli):
        sys.exit("duplexfit binary not found; pass --cli")
    listed = json.loads(run([cli, "devices", "--json"])[0])
    specs = [d["spec"] for d in listed["devices"]]
    names = {d["spec"]: d["name"] for d in listed["devices"]}
    if args.devices:
        specs = args.devices.split(",")
    fit_device = args.fit_device or listed["default"]
    work = args.work or tempfile.mkdtemp(prefix="duplexfit-slice-bench-")
    os.makedirs(work, exist_ok=True)

    head_path = os.path.join(CLOUDS, "maxplanck_40k.ply")
    lo, hi = ply_bounds(head_path)
    width = hi["xy".index(args.width_axis)] - lo["xy".index(args.width_axis)]
    s = 1.0 / width  # unit width: lengths of the unit-width model = s × lengths here
    tau = 0.01
    models = {
        # name: cloud, δ (cloud units), axis, grid, τ (cloud units)
        "head": (head_path, 0.025 / s, "z", 0.005 / s, tau / s),
        "torus": (os.path.join(CLOUDS, "torus_10k.ply"), 0.1, "y", 0.01, tau),
    }
    print("# duplexfit slice benchmark: fits on %s, cusp rule %s, work folder %s" % (fit_device, args.cusp_rule, work))
    print("# head: maxplanck_40k scaled to unit width along %s (width %.4f, height %.4f in unit-width units), "
          "delta 0.025, grid 0.005; torus: torus_10k upright (sliced along y), delta 0.1, grid 0.01; tau 0.01"
          % (args.width_axis, width, (hi[2] - lo[2]) * s))
    rows = []
    for name in args.models.split(","):
        cloud, delta, axis, grid, tau_here = models[name]
        fit_dir = os.path.join(work, name + "-fit")
        out, secs = run([cli, "fit", cloud, "--offset", "%.9g" % delta, "--device", fit_device, "--quiet", "-o", fit_dir])
        print("# fit %s: %s (%.1f s)" % (name, out.strip().splitlines()[0], secs))
        field = os.path.join(fit_dir, "field.dpxf")
        for spec in specs:
            for mode in ("zero", "shell"):
                out_dir = os.path.join(work, "%s-%s-%s" % (name, spec.replace(":", "_"), mode))
                _, wall = run([cli, "slice", field, "--cusp", "%.9g" % tau_here, "--grid", "%.9g" % grid, "--axis", axis,
                               "--mode", mode, "--cusp-rule", args.cusp_rule, "--device", spec, "--quiet", "-o", out_dir])
                with open(os.path.join(out_dir, "slices.json")) as f:
                    rep = json.load(f)
                sl = rep["seconds"]["slice"]
                rows.append((name, spec, names.get(spec, spec), mode, rep["layer_count"], PAPER[name][mode], sl,
                             rep["layer_count"] / sl, rep["vertices"] / sl, rep["vertices"], wall,
                             rep["thickness"]["min"] * (s if name == "head" else 1),
                             rep["thickness"]["mean"] * (s if name == "head" else 1),
                             rep["thickness"]["max"] * (s if name == "head" else 1)))
                r = rows[-1]
                sys.stderr.write("%s %s %s: %d layers, %.2f s\n" % (name, spec, mode, r[4], sl))

    hdr = ("model", "device", "mode", "layers", "Fig.21", "slice s", "layers/s", "vertices/s", "vertices",
           "t min", "t mean", "t max")
    print("| " + " | ".join(hdr) + " |")
    print("|" + "---|" * len(hdr))
    for r in rows:
        print("| %s | %s (%s) | %s | %d | %d | %.2f | %.1f | %.0f | %d | %.4f | %.4f | %.4f |"
              % (r[0], r[1], r[2][:28], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[11], r[12], r[13]))
    print("# thickness in unit-width units; layers/s and vertices/s over the slicing itself (no file output)")


if __name__ == "__main__":
    main()
