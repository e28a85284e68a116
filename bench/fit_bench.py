#!/usr/bin/env python3
"""Fit benchmark: runs `duplexfit fit` on the paper's models (shared clouds) with one inward offset on
every device (or those given with --device) and prints per-stage seconds, CG iterations per level,
E0/E_delta, peak memory, and the paper's Table 2 times beside ours.

usage: bench/fit_bench.py [--duplexfit build/cli/duplexfit] [--data ../shared/data] [--device SPEC ...]
                          [--clouds fandisk_8k,igea_72k,...] [--offset 0.025] [--markdown]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

# The paper's Table 2 (docs/method.md section 11.1): points, levels, CPU time, GPU time (seconds).
PAPER = {
    "fandisk_8k": ("Fandisk (lr)", 8030, 6, 6.4, 3.0),
    "fandisk_550k": ("Fandisk (hr)", 550340, 9, 940.1, 150.8),
    "wheel_29k": ("Hub (lr)", 29426, 6, 88.7, 28.5),
    "wheel_118k": ("Hub (hr)", 118566, 7, 352.7, 100.5),
    "eight_110k": ("Eight-shape", 110628, 7, 81.54, 20.26),
    "igea_72k": ("Igea", 72545, 7, 78.86, 13.12),
    "maxplanck_40k": ("Moai", 40002, 7, 37.6, 7.12),
    "pinion_53k": ("Gear", 53816, 7, 91.68, 24.5),
}
DEFAULT_CLOUDS = "fandisk_8k,igea_72k,eight_110k,wheel_118k,fandisk_550k"


def run(args, cloud, device):
    path = os.path.join(args.data, "clouds", cloud + ".ply")
    with tempfile.TemporaryDirectory() as out:
        cmd = [args.duplexfit, "fit", path, "--offset", str(args.offset), "--device", device, "-o", out, "--quiet"]
        print("running:", " ".join(cmd), file=sys.stderr, flush=True)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        with open(os.path.join(out, "report.json")) as f:
            return json.load(f)


def stage_sums(report):
    sums = {"constraints": 0.0, "residual": 0.0, "assembly": 0.0, "solve": 0.0}
    for level in report["level_reports"]:
        for key in sums:
            sums[key] += level["seconds"][key]
    return sums


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    p.add_argument("--duplexfit", default=os.path.join(here, "..", "build", "cli", "duplexfit"))
    p.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data"))
    p.add_argument("--device", action="append", help="device spec (repeatable); default: every device")
    p.add_argument("--clouds", default=DEFAULT_CLOUDS)
    p.add_argument("--offset", type=float, default=0.025)
    args = p.parse_args()

    devices = args.device
    if not devices:
        listing = json.loads(subprocess.run([args.duplexfit, "devices", "--json"], check=True,
                                            capture_output=True, text=True).stdout)
        devices = [d["spec"] for d in listing["devices"]]

    rows = []
    for device in devices:
        for cloud in args.clouds.split(","):
            r = run(args, cloud, device)
            rows.append((device, cloud, r))

    header = ("| device | cloud | points | M | offsets kept (finest) | constraints | residual | assembly | solve | "
              "polygonize | total s | CG iterations per level | E0 | E_delta | peak MiB | paper CPU s | paper GPU s |")
    print(header)
    print("|" + "|".join(["---"] * (header.count("|") - 1)) + "|")
    for device, cloud, r in rows:
        s = stage_sums(r)
        finest = r["level_reports"][-1]
        kept = "%d/%d" % (finest["offset_kept"][0], finest["offset_candidates"][0]) if finest["offset_kept"] else "-"
        its = " ".join(str(level["cg"]["iterations"]) for level in r["level_reports"])
        paper = PAPER.get(cloud)
        print("| %s | %s | %d | %d | %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %s | %.1e | %.1e | %.0f | %s | %s |" % (
            device, cloud, r["points"], r["levels"], kept, s["constraints"], s["residual"], s["assembly"],
            s["solve"], r["seconds"]["polygonize"], r["seconds"]["total"], its, r["E0"],
            max(r["Edelta"]) if r["Edelta"] else 0.0, r["peak_rss_mib"],
            "%.1f" % paper[3] if paper else "-", "%.1f" % paper[4] if paper else "-"))
        print("device %s: %s" % (device, r["device"]), file=sys.stderr)


if __name__ == "__main__":
    main()
