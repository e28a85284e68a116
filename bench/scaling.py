#!/usr/bin/env python3
"""Scaling benchmark (docs/benchmarks.md, "Scaling"; issue 12).

Two parts, each optional:
  ranks   `mpirun -np P duplexfit fit CLOUD` for P in --ranks (default 1,2,3,4; local mode), and the same cloud
          with `--blocks B` in one process for B in --blocks: wall time, peak RSS (of the process tree, from
          /usr/bin/time when installed, else report.json's peak of rank 0), E_0, E_delta and the per-rank /
          per-block counts of report.json (points, halo points, unknowns, non-zeros, CG iterations, bytes).
  big     a synthetic cloud of --big-points samples of a shared mesh (bench's duplexfit-sample-cloud; written
          to a temporary folder, never committed), fitted with `--blocks --big-blocks`: time, peak memory,
          and fidelity against the same mesh (duplexfit measure: zero mesh vs the mesh, Metro distances).

usage: bench/scaling.py [--duplexfit build/cli/duplexfit] [--sampler build/bench/duplexfit-sample-cloud]
                        [--data ../shared/data] [--cloud fandisk_550k] [--ranks 1,2,3,4] [--blocks 4,16]
                        [--big-mesh fandisk] [--big-points 20000000] [--big-blocks 16] [--offset 0.025]
                        [--resolution 256] [--fit-args="..."] [--skip-ranks] [--skip-big] [--json FILE]
Markdown tables to stdout, progress to stderr. Set OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
to run mpirun as root.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def timed(cmd, env=None, stderr_to=None):
    """Runs cmd; returns (wall seconds, peak RSS in MB or None, completed process). With stderr_to (an open
    file), the command's stderr (its progress) goes there instead of being captured."""
    time_bin = shutil.which("time") or ("/usr/bin/time" if os.path.exists("/usr/bin/time") else None)
    rss_file = None
    if time_bin:
        fd, rss_file = tempfile.mkstemp(suffix=".rss")
        os.close(fd)
        cmd = [time_bin, "-f", "%M", "-o", rss_file] + cmd
    start = time.monotonic()
    proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=stderr_to or subprocess.PIPE, text=True)
    wall = time.monotonic() - start
    rss = None
    if rss_file:
        try:
            with open(rss_file) as f:
                rss = int(f.read().strip().splitlines()[-1]) / 1024.0
        except (ValueError, IndexError, OSError):
            rss = None
        os.unlink(rss_file)
    if proc.returncode != 0:
        raise RuntimeError(" ".join(cmd) + " failed:\n" + proc.stdout[-2000:] + (proc.stderr or "")[-2000:])
    return wall, rss, proc


def mpirun_prefix(ranks):
    return ["mpirun", "--oversubscribe", "-np", str(ranks), "-x", "POCL_MAX_PTHREAD_COUNT", "-x", "OMP_NUM_THREADS"]


def fit_row(label, wall, rss, report):
    d = report.get("distributed") or {}
    row = {
        "run": label,
        "wall_s": wall,
        "fit_s": report["seconds"]["fit"] if "seconds" in report and "fit" in report["seconds"] else None,
        "peak_rss_mb": rss if rss is not None else report.get("peak_rss_mib"),
        "e0": report.get("E0"),
        "e_delta": (report.get("Edelta") or [None])[0],
        "blocks": d.get("per_block", []),
        "ranks": d.get("per_rank", []),
    }
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duplexfit", default=os.path.join(ROOT, "build", "cli", "duplexfit"))
    ap.add_argument("--sampler", default=os.path.join(ROOT, "build", "bench", "duplexfit-sample-cloud"))
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "data"))
    ap.add_argument("--cloud", default="fandisk_550k")
    ap.add_argument("--ranks", default="1,2,3,4")
    ap.add_argument("--blocks", default="4,16")
    ap.add_argument("--big-mesh", default="fandisk")
    ap.add_argument("--big-points", type=int, default=20_000_000)
    ap.add_argument("--big-blocks", type=int, default=16)
    ap.add_argument("--offset", type=float, default=0.025)
    ap.add_argument("--resolution", type=int, default=256, help="mesh grid of the big cloud's fit")
    ap.add_argument("--fit-args", default="", help="more options for every fit, e.g. '--resolution 64 --no-project'")
    ap.add_argument("--skip-ranks", action="store_true")
    ap.add_argument("--skip-big", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    env = dict(os.environ, POCL_MAX_PTHREAD_COUNT=os.environ.get("POCL_MAX_PTHREAD_COUNT", "1"),
               OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    results = {"ranks": [], "big": None}
    work = tempfile.mkdtemp(prefix="duplexfit-scaling-")
    try:
        if not args.skip_ranks:
            cloud = os.path.join(args.data, "clouds", args.cloud + ".ply")
            runs = [("P = %d" % p, mpirun_prefix(p), []) for p in (int(x) for x in args.ranks.split(",") if x)]
            runs += [("blocks = %d" % b, [], ["--blocks", str(b)]) for b in (int(x) for x in args.blocks.split(",") if x)]
            for label, prefix, extra in runs:
                out = os.path.join(work, label.replace(" ", "").replace("=", "_"))
                cmd = prefix + [args.duplexfit, "fit", cloud, "--offset", str(args.offset), "--distributed", "local",
                                "--quiet", "-o", out] + extra + args.fit_args.split()
                log("scaling: " + label)
                wall, rss, _ = timed(cmd, env)
                with open(os.path.join(out, "report.json")) as f:
                    results["ranks"].append(fit_row(label, wall, rss, json.load(f)))
                shutil.rmtree(out, ignore_errors=True)
            print("| run | wall s | peak RSS MB | E_0 | E_delta | block: points, halo (max level), unknowns, non-zeros, CG |")
            print("|---|---|---|---|---|---|")
            for r in results["ranks"]:
                parts = ["%d: %d, %d, %d, %.2fM, %d" % (b["block"], b["points"], b["halo_points"], b["unknowns"],
                                                      b["non_zeros"] / 1e6, b["cg_iterations"]) for b in r["blocks"]]
                print("| %s | %.1f | %s | %.2g | %.2g | %s |" % (
                    r["run"], r["wall_s"], "%.0f" % r["peak_rss_mb"] if r["peak_rss_mb"] else "?", r["e0"] or 0,
                    r["e_delta"] or 0, "; ".join(parts)))
        if not args.skip_big:
            mesh = os.path.join(args.data, "meshes", args.big_mesh + ".ply")
            big = os.path.join(work, "big.ply")
            log("big: sampling %d points of %s" % (args.big_points, mesh))
            sample_s, sample_rss, _ = timed([args.sampler, mesh, str(args.big_points), big])
            out = os.path.join(work, "big_fit")
            log("big: fitting with --blocks %d (its progress follows)" % args.big_blocks)
            # One process: it gets every core (the one-thread limits above are for the ranks sharing them),
            # unless the caller set the limits.
            big_env = dict(os.environ)
            wall, rss, _ = timed([args.duplexfit, "fit", big, "--offset", str(args.offset), "--blocks", str(args.big_blocks),
                                  "--resolution", str(args.resolution), "-o", out] + args.fit_args.split(), big_env,
                                 stderr_to=sys.stderr)
            with open(os.path.join(out, "report.json")) as f:
                report = json.load(f)
            log("big: measuring the zero mesh against " + mesh)
            _, _, m = timed([args.duplexfit, "measure", os.path.join(out, "zero.ply"), mesh, "--json"])
            measured = json.loads(m.stdout)
            row = fit_row("big", wall, rss, report)
            row.update({"points": args.big_points, "mesh": args.big_mesh, "sample_s": sample_s, "measure": measured,
                        "levels": report.get("levels"), "seconds": report.get("seconds")})
            results["big"] = row
            print()
            print("| cloud | blocks | wall s | peak RSS MB | E_0 | E_delta | zero mesh vs %s (measure) |" % args.big_mesh)
            print("|---|---|---|---|---|---|---|")
            print("| %d samples of %s | %d | %.0f | %s | %.2g | %.2g | %s |" % (
                args.big_points, args.big_mesh, args.big_blocks, wall, "%.0f" % row["peak_rss_mb"] if row["peak_rss_mb"] else "?",
                row["e0"] or 0, row["e_delta"] or 0, json.dumps(measured.get("distance", measured))[:300]))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
