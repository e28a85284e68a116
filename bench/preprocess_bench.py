#!/usr/bin/env python3
"""Pre-processing benchmark: runs `duplexfit denoise` (bilateral filter, docs/method.md section 9) and
`duplexfit normals` (PCA normals with spanning-tree and outward orientation) with --json on the shared
clouds, for every device of `duplexfit devices --json` (the reference path included) or those given with
--device, and prints the seconds and points per second of each stage.

The normals benchmark ignores the normals stored in the clouds (it estimates new ones) and reports the
share of estimated normals that agree in sign with the stored ones.

usage: bench/preprocess_bench.py [--duplexfit build/cli/duplexfit] [--data ../shared/data] [--device SPEC ...]
                                 [--denoise-clouds ...] [--normals-clouds ...] [--precision float|double]
                                 [--repeat N]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

DENOISE_CLOUDS = "fandisk_50k_noise0.5pct,fandisk_550k"
NORMALS_CLOUDS = "fandisk_50k_noise0.5pct,fandisk_550k"
DENOISE_STAGES = ("neighbors", "filter", "denoise")
NORMALS_STAGES = ("neighbors", "pca", "orient", "normals")


def run_json(cmd):
    print("running:", " ".join(cmd), file=sys.stderr, flush=True)
    done = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True)
    return json.loads(done.stdout)


def best_of(args, cmd, stages):
    """Runs cmd args.repeat times; returns the last summary with each stage's minimum seconds."""
    best = None
    for _ in range(args.repeat):
        summary = run_json(cmd)
        if best is None:
            best = summary
        else:
            for s in stages:
                best["seconds"][s] = min(best["seconds"][s], summary["seconds"][s])
    return best


def rate(points, seconds):
    return points / seconds if seconds > 0 else float("inf")


def fmt_rate(r):
    if r == float("inf"):
        return "-"
    if r >= 1e6:
        return "%.2fM" % (r / 1e6)
    return "%.0fk" % (r / 1e3)


def table(title, stages, rows, extra_name):
    print("\n" + title)
    head = "%-26s %-6s %9s" % ("cloud", "device", "points")
    for s in stages:
        head += " %18s" % (s + " s (pts/s)")
    head += " %12s %s" % ("build s", extra_name)
    print(head)
    print("-" * len(head))
    for cloud, device, summary, extra in rows:
        n = summary["points"]
        line = "%-26s %-6s %9d" % (cloud, device, n)
        for s in stages:
            sec = summary["seconds"][s]
            line += " %18s" % ("%.3f (%s)" % (sec, fmt_rate(rate(n, sec))))
        line += " %12.3f %s" % (summary["seconds"].get("kernel_build", 0.0), extra)
        print(line)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    p.add_argument("--duplexfit", default=os.path.join(here, "..", "build", "cli", "duplexfit"))
    p.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data"))
    p.add_argument("--device", action="append", help="device spec (repeatable); default: every device and ref")
    p.add_argument("--denoise-clouds", default=DENOISE_CLOUDS)
    p.add_argument("--normals-clouds", default=NORMALS_CLOUDS)
    p.add_argument("--precision", default="float", choices=("float", "double"))
    p.add_argument("--repeat", type=int, default=1, help="runs per measurement; the minimum per stage is shown")
    args = p.parse_args()

    devices = args.device
    if not devices:
        listing = json.loads(subprocess.run([args.duplexfit, "devices", "--json"], check=True,
                                            stdout=subprocess.PIPE, text=True).stdout)
        devices = [d["spec"] for d in listing["devices"]]
        if "ref" not in devices:
            devices.append("ref")

    denoise_rows, normals_rows = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out.ply")
        for device in devices:
            for cloud in filter(None, args.denoise_clouds.split(",")):
                path = os.path.join(args.data, "clouds", cloud + ".ply")
                cmd = [args.duplexfit, "denoise", path, "-o", out, "--device", device, "--precision",
                       args.precision, "--json", "--quiet"]
                s = best_of(args, cmd, DENOISE_STAGES)
                extra = "%.1f nbrs, mean move %.2e" % (s["mean_neighbors"], s["mean_displacement"])
                denoise_rows.append((cloud, device, s, extra))
            for cloud in filter(None, args.normals_clouds.split(",")):
                path = os.path.join(args.data, "clouds", cloud + ".ply")
                cmd = [args.duplexfit, "normals", path, "-o", out, "--device", device, "--precision",
                       args.precision, "--json", "--quiet"]
                s = best_of(args, cmd, NORMALS_STAGES)
                agree = s.get("agree_with_input_normals")
                extra = "k %d, %d comp, agree %s" % (s["k"], s["components"],
                                                      "%.6f" % agree if agree is not None else "-")
                normals_rows.append((cloud, device, s, extra))

    print("duplexfit pre-processing benchmark (precision %s, best of %d)" % (args.precision, args.repeat))
    table("denoise (bilateral filter, one pass; 'neighbors' = the k-d tree on the host, 'filter' = weighted sums "
          "incl. transfers)", DENOISE_STAGES, denoise_rows, "notes")
    table("normals (k = 15; 'neighbors' = k-d tree kNN, 'pca' = covariances on the device + host eigenvectors, "
          "'orient' = graph, MST, outward test)", NORMALS_STAGES, normals_rows, "notes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
