#!/usr/bin/python3
"""Fidelity benchmark: duplexfit (one field, surface = 0-level, offset = delta-level) against the two-step
pipeline a user would otherwise chain, Open3D screened Poisson reconstruction followed by an exact
distance-field offset of its mesh with OpenVDB (bench/peer.py).

For every shared cloud with ground truth and every delta (positive = inward, as in `duplexfit fit`):
  1. `duplexfit fit CLOUD --offset=D -o TMP --quiet [--duplexfit-args]`, timed (wall clock);
  2. the peer: Poisson once per cloud, then the VDB offset of its mesh at D, each step timed;
  3. the exact offset of the ground-truth mesh the same way (VDB), for its components and as the floor of
     the offset step's own discretisation error; analytic clouds get a fine mesh of their exact surface
     from the JSON sidecar (sphere, torus) or the exact box meshes (cube, notched cube);
  4. `duplexfit measure ZERO TRUTH --json` (Metro: mean, Hausdorff) for both zero levels and
     `duplexfit measure OFFSET --offset-of TRUTH --delta D --json` (|d - |D|| / |D|: mean, p99, max) for
     ours, the peer's and the truth's offset; connected components (faces sharing a vertex) of every mesh,
     significant when >= 1 % of that mesh's area, tiny when < 0.1 %, and the genus of the significant ones
     (against the truth mesh's and its exact offset's);
  5. writes a markdown table (--out, default docs/fidelity.md) and all raw numbers as JSON beside it.

usage: /usr/bin/python3 bench/fidelity.py [--models a,b] [--deltas 0.025,0.05] [--out docs/fidelity.md]
           [--duplexfit build/cli/duplexfit] [--duplexfit-args "--side-test"] [--no-peer] [--with-550k]
           [--poisson-depth 9] [--vdb-voxel H] [--jobs 1] [--keep]
Negative deltas: write --deltas=0.02,-0.02 (with '=').
Needs numpy; the peer needs python3-open3d and python3-openvdb (Debian packages, system /usr/bin/python3).
"""
import argparse
import concurrent.futures
import datetime
import json
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import peer  # noqa: E402  (numpy check happens there)

MESH_MODELS = ["fandisk_8k", "fandisk_50k", "eight_110k", "maxplanck_40k", "igea_72k", "wheel_118k",
               "pinion_53k", "bunny_35k", "armadillo_43k", "rocker_arm_40k", "joint_40k"]
SLOW_MODELS = ["fandisk_550k"]
ANALYTIC_MODELS = ["sphere_10k", "torus_10k", "thin_torus_20k", "cube_24k", "notched_cube_24k"]
MESH_DELTAS = [0.025, 0.05]
ANALYTIC_DELTAS = [0.02, -0.02]
SIGNIFICANT = 0.01   # a component is significant at >= 1 % of its mesh's area
TINY = 0.001         # and tiny below 0.1 %

_print_lock = threading.Lock()


def log(msg):
    with _print_lock:
        print("[fidelity %s] %s" % (time.strftime("%H:%M:%S"), msg), file=sys.stderr, flush=True)


class StepError(RuntimeError):
    pass


def run_cmd(cmd, timeout, what):
    """Runs a command; returns (stdout, wall seconds). Raises StepError with the tail of stderr on failure."""
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise StepError("%s: timed out after %.0f s" % (what, timeout))
    except OSError as e:
        raise StepError("%s: cannot run %s: %s" % (what, cmd[0], e))
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        tail = " | ".join((p.stderr or p.stdout or "").strip().splitlines()[-3:])
        raise StepError("%s: exit status %d: %s" % (what, p.returncode, tail[-400:]))
    return p.stdout, wall


def last_json(text):
    """The JSON object a command printed (pretty-printed by duplexfit, one line by peer.py)."""
    try:
        return json.loads(text)
    except ValueError:
        start = text.find("{")
        if start < 0:
            raise StepError("no JSON in the output: %r" % text[-200:])
        return json.loads(text[start:])


# ------------------------------------------------------------------------------------------- config

def resolve_truth(cfg, model, workdir):
    """(truth mesh path, kind, description) for a cloud name; analytic surfaces are meshed into workdir."""
    data = cfg.data
    cloud = os.path.join(data, "clouds", model + ".ply")
    if not os.path.exists(cloud):
        raise StepError("no cloud %s" % cloud)
    sidecar = os.path.join(data, "clouds", model + ".json")
    if os.path.exists(sidecar):
        with open(sidecar) as f:
            sc = json.load(f)
        surface = sc.get("surface", "")
        if "mesh" in sc:
            path = os.path.join(data, sc["mesh"].split()[0])
            if not os.path.exists(path):
                raise StepError("sidecar mesh %s missing" % path)
            return path, "analytic", "exact mesh %s" % sc["mesh"].split()[0]
        out = os.path.join(workdir, "truth.ply")
        if surface == "sphere":
            v, f = peer.sphere_mesh(sc["radius"], sc.get("center", (0, 0, 0)), tol=cfg.truth_tol)
            desc = "icosphere r=%g, %d faces" % (sc["radius"], len(f))
        elif surface == "torus":
            if [abs(x) for x in sc.get("axis", [0, 0, 1])] != [0.0, 0.0, 1.0]:
                raise StepError("torus sidecar with an axis other than z is not supported")
            v, f = peer.torus_mesh(sc["R"], sc["r"], sc.get("center", (0, 0, 0)), tol=cfg.truth_tol)
            desc = "torus grid R=%g r=%g, %d faces" % (sc["R"], sc["r"], len(f))
        else:
            raise StepError("sidecar surface %r has no mesh and no generator" % surface)
        peer.write_mesh(out, v, f)
        return out, "analytic", desc
    base = re.sub(r"_\d+k(_.*)?$", "", model)
    path = os.path.join(data, "meshes", base + ".ply")
    if not os.path.exists(path):
        raise StepError("no ground-truth mesh for %s (looked for %s)" % (model, path))
    return path, "mesh", "meshes/%s.ply" % base


def default_deltas(model, data):
    return ANALYTIC_DELTAS if os.path.exists(os.path.join(data, "clouds", model + ".json")) else MESH_DELTAS


# --------------------------------------------------------------------------------------------- steps

def measure_distance(cfg, a, b):
    out, _ = run_cmd([cfg.duplexfit, "measure", a, b, "--json", "--quiet", "--samples", str(cfg.samples)],
                     cfg.timeout, "measure %s" % os.path.basename(a))
    j = last_json(out)
    fw, bw = j["forward"], j["backward"]
    return {"mean": 0.5 * (fw["mean"] + bw["mean"]), "forward_mean": fw["mean"], "backward_mean": bw["mean"],
            "forward_rms": fw["rms"], "backward_rms": bw["rms"], "forward_max": fw["max"], "backward_max": bw["max"],
            "hausdorff": j["hausdorff"], "hausdorff_rel": j["hausdorff_rel"], "diagonal_b": j["diagonal_b"],
            "raw": j}


def face_count(path):
    return int(len(peer.read_mesh(path)[1]))


def measure_offset(cfg, mesh, truth, delta):
    if face_count(mesh) == 0:  # no offset surface at all (e.g. a part thinner than 2|D| everywhere)
        return {"empty": True, "mean_pct": None, "p99_pct": None, "max_pct": None, "rms_pct": None,
                "wrong_side_share": None, "components": 0, "off_offset_components": 0}
    out, _ = run_cmd([cfg.duplexfit, "measure", mesh, "--offset-of", truth, "--delta=%r" % delta, "--json",
                      "--quiet", "--samples", str(cfg.samples)], cfg.timeout, "measure offset %s" % os.path.basename(mesh))
    j = last_json(out)
    rd = j["relative_deviation"]
    return {"mean_pct": 100.0 * rd["mean"], "p99_pct": 100.0 * rd["p99"], "max_pct": 100.0 * rd["max"],
            "rms_pct": 100.0 * rd["rms"], "wrong_side_share": j["wrong_side_share"], "components": j["components"],
            "off_offset_components": j["off_offset_components"], "raw": j}


def mesh_components(path):
    v, f = peer.read_mesh(path)
    if len(f) == 0:
        return {"components": 0, "significant": 0, "tiny": 0, "area": 0.0, "shares": [], "faces": 0, "empty": True}
    s = peer.component_summary(peer.components(v, f), SIGNIFICANT, TINY)
    s["faces"] = int(len(f))
    return s


def peer_step(cfg, args, what):
    out, wall = run_cmd([sys.executable, os.path.join(HERE, "peer.py")] + args, cfg.timeout, what)
    j = last_json(out)
    j["wall_seconds"] = wall
    return j


def guarded(errors, what, fn, *a):
    try:
        return fn(*a)
    except Exception as e:  # a failing step becomes an error entry; the run continues
        msg = "%s: %s" % (what, e) if not isinstance(e, StepError) else str(e)
        if not isinstance(e, (StepError, OSError, ValueError, KeyError)):
            msg += " (" + traceback.format_exc().strip().splitlines()[-1] + ")"
        errors.append(msg)
        log("  error: " + msg)
        return None


def run_model(cfg, model, deltas, index, total):
    """All deltas of one model. Returns a list of row dicts (one per delta)."""
    t_model = time.perf_counter()
    workdir = tempfile.mkdtemp(prefix=model + "-", dir=cfg.tmp)
    rows = []
    common_errors = []
    log("[%d/%d] %s: deltas %s" % (index, total, model, ", ".join("%g" % d for d in deltas)))
    truth = guarded(common_errors, "truth", resolve_truth, cfg, model, workdir)
    cloud = os.path.join(cfg.data, "clouds", model + ".ply")
    info = {"model": model, "cloud": cloud}
    truth_comps = peer_zero = peer_zero_m = peer_zero_c = None
    if truth:
        info["truth"], info["kind"], info["truth_desc"] = truth
        truth_comps = guarded(common_errors, "truth components", mesh_components, truth[0])
        if not cfg.no_peer:
            log("  %s: Open3D Poisson (depth %d) ..." % (model, cfg.poisson_depth))
            pz = os.path.join(workdir, "peer_zero.ply")
            pargs = ["poisson", cloud, "-o", pz, "--depth", str(cfg.poisson_depth), "--scale", str(cfg.poisson_scale),
                     "--trim", str(cfg.poisson_trim), "--threads", str(cfg.poisson_threads)]
            if cfg.poisson_linear_fit:
                pargs.append("--linear-fit")
            peer_zero = guarded(common_errors, "peer Poisson", peer_step, cfg, pargs, "peer Poisson %s" % model)
            if peer_zero:
                log("  %s: Poisson %.2f s, %d faces" % (model, peer_zero["seconds"], peer_zero["faces"]))
                peer_zero_m = guarded(common_errors, "peer zero measure", measure_distance, cfg, pz, truth[0])
                peer_zero_c = guarded(common_errors, "peer zero components", mesh_components, pz)
    for delta in deltas:
        row = dict(info, delta=delta, errors=list(common_errors), ours={}, peer={}, truth_offset={})
        t_row = time.perf_counter()
        rows.append(row)
        if not truth:
            row["status"] = "error"
            continue
        tpath = truth[0]
        # 1. ours
        od = os.path.join(workdir, "ours_%g" % delta)
        os.makedirs(od, exist_ok=True)
        cmd = [cfg.duplexfit, "fit", cloud, "--offset=%r" % delta, "-o", od, "--quiet"] + cfg.extra
        row["ours"]["command"] = " ".join(shlex.quote(c) for c in cmd)
        log("  %s d=%g: duplexfit fit ..." % (model, delta))
        res = guarded(row["errors"], "duplexfit fit", run_cmd, cmd, cfg.timeout, "duplexfit fit %s" % model)
        if res:
            row["ours"]["wall_seconds"] = res[1]
            rep = guarded(row["errors"], "report.json", lambda: json.load(open(os.path.join(od, "report.json"))))
            zero = os.path.join(od, "zero.ply")
            off = os.path.join(od, "offset1.ply")
            if rep:
                row["ours"]["report_seconds"] = rep.get("seconds")
                row["ours"]["levels"] = rep.get("levels")
                row["ours"]["grid_cell"] = rep.get("grid", {}).get("cell")
                row["ours"]["E0"] = rep.get("E0")
                row["ours"]["Edelta"] = rep.get("Edelta")
                meshes = rep.get("meshes", [])
                if len(meshes) >= 2:
                    zero, off = os.path.join(od, meshes[0]["file"]), os.path.join(od, meshes[1]["file"])
            log("  %s d=%g: fit %.2f s; measuring ..." % (model, delta, res[1]))
            row["ours"]["zero"] = guarded(row["errors"], "ours zero measure", measure_distance, cfg, zero, tpath)
            row["ours"]["zero_components"] = guarded(row["errors"], "ours zero components", mesh_components, zero)
            row["ours"]["offset"] = guarded(row["errors"], "ours offset measure", measure_offset, cfg, off, tpath, delta)
            row["ours"]["offset_components"] = guarded(row["errors"], "ours offset components", mesh_components, off)
        # 2. peer
        vox = ["--voxel", repr(cfg.vdb_voxel)] if cfg.vdb_voxel else []
        if peer_zero:
            row["peer"]["poisson"] = peer_zero
            row["peer"]["zero"] = peer_zero_m
            row["peer"]["zero_components"] = peer_zero_c
            po = os.path.join(workdir, "peer_offset_%g.ply" % delta)
            log("  %s d=%g: OpenVDB offset of the Poisson mesh ..." % (model, delta))
            vo = guarded(row["errors"], "peer VDB offset", peer_step, cfg,
                         ["offset", os.path.join(workdir, "peer_zero.ply"), "--delta=%r" % delta, "-o", po,
                          "--margin", str(cfg.vdb_margin)] + vox, "peer VDB offset %s" % model)
            if vo:
                row["peer"]["vdb"] = vo
                row["peer"]["seconds"] = peer_zero["seconds"] + vo["seconds"]
                log("  %s d=%g: VDB %.2f s (voxel %g, %d faces); measuring ..." % (model, delta, vo["seconds"],
                                                                                   vo["voxel"], vo["faces"]))
                row["peer"]["offset"] = guarded(row["errors"], "peer offset measure", measure_offset, cfg, po, tpath,
                                                delta)
                row["peer"]["offset_components"] = guarded(row["errors"], "peer offset components", mesh_components,
                                                           po)
        # 3. truth offset (VDB of the ground truth)
        if cfg.vdb_available:
            to = os.path.join(workdir, "truth_offset_%g.ply" % delta)
            log("  %s d=%g: OpenVDB offset of the truth ..." % (model, delta))
            tv = guarded(row["errors"], "truth VDB offset", peer_step, cfg,
                         ["offset", tpath, "--delta=%r" % delta, "-o", to, "--margin", str(cfg.vdb_margin)] + vox,
                         "truth VDB offset %s" % model)
            if tv:
                row["truth_offset"]["vdb"] = tv
                row["truth_offset"]["offset"] = guarded(row["errors"], "truth offset measure", measure_offset, cfg, to,
                                                        tpath, delta)
                row["truth_offset"]["offset_components"] = guarded(row["errors"], "truth offset components",
                                                                   mesh_components, to)
        row["truth_components"] = truth_comps
        row["row_seconds"] = time.perf_counter() - t_row
        row["status"] = "ok" if not row["errors"] else ("error" if not row["ours"].get("offset") else "partial")
        o = row["ours"].get("offset") or {}
        p = row["peer"].get("offset") or {}
        log("  %s d=%g done in %.0f s: offset mean %s%% ours, %s%% peer%s" % (
            model, delta, row["row_seconds"], fmt(o.get("mean_pct"), 3), fmt(p.get("mean_pct"), 3),
            "" if not row["errors"] else " (%d error(s))" % len(row["errors"])))
        if not cfg.keep:
            shutil.rmtree(od, ignore_errors=True)
    if not cfg.keep:
        shutil.rmtree(workdir, ignore_errors=True)
    seconds = time.perf_counter() - t_model
    for r in rows:
        r["model_seconds"] = seconds
    log("[%d/%d] %s finished in %.0f s" % (index, total, model, seconds))
    return rows


# -------------------------------------------------------------------------------------------- report

def fmt(v, digits=2):
    if v is None:
        return "-"
    if isinstance(v, (int,)) and not isinstance(v, bool):
        return str(v)
    av = abs(v)
    if av != 0 and (av < 10 ** -(digits + 1) or av >= 1e5):
        return "%.*e" % (max(digits - 1, 1), v)
    return "%.*f" % (digits, v) if av < 100 else "%.0f" % v


def get(d, *keys):
    for k in keys:
        if not isinstance(d, dict) or d.get(k) is None:
            return None
        d = d[k]
    return d


def cell(*vals, digits=2, scale=1.0):
    return " / ".join(fmt(v * scale if isinstance(v, float) else v, digits) if v is not None else "-" for v in vals)


def markdown(doc, cfg):
    rows = doc["runs"]
    lines = ["# Fidelity: duplexfit against Poisson + exact offset", "",
             "Generated by `bench/fidelity.py` on %s (%s)." % (doc["date"], doc["machine"]), "",
             "```", doc["command"], "```", "",
             "* **ours**: `%s fit CLOUD --offset=D -o DIR --quiet%s` (duplexfit %s): one field, the surface its "
             "0-level, the offset its D-level." % (os.path.basename(cfg.duplexfit), (" " + " ".join(cfg.extra)) if cfg.extra else "",
                                                doc["duplexfit_version"].replace("duplexfit ", "")),
             ]
    if cfg.show_peer:
        lines += ["* **peer**: Open3D %s screened Poisson (`create_from_point_cloud_poisson`, depth %d, scale %g, "
                  "linear_fit %s, density trim %s, n_threads %d), then the exact offset of its mesh with OpenVDB %s "
                  "(`createLevelSetFromPolygons`, voxel %s, half width ceil(|D|/voxel) + %d voxels; "
                  "`convertToPolygons` at isovalue -D, adaptivity 0)." % (
                      doc["versions"].get("open3d"), cfg.poisson_depth, cfg.poisson_scale, cfg.poisson_linear_fit,
                      cfg.poisson_trim or "none", cfg.poisson_threads, doc["versions"].get("openvdb"),
                      ("%g" % cfg.vdb_voxel) if cfg.vdb_voxel else "min(%g, |D|/%g)" % (
                          peer.VDB_VOXEL_MAX, peer.VDB_VOXELS_PER_DELTA), cfg.vdb_margin)]
    lines += [
        "* **truth**: the ground-truth mesh (`meshes/`; analytic shapes: a fine mesh of the exact surface), and "
        "for offsets its exact offset by the same OpenVDB step (its error is the floor of the offset step's own "
        "discretisation).",
        "* **time**: ours = wall clock of `duplexfit fit` (process start, read, fit, polygonize, write); "
        "peer = Poisson call + VDB offset call (inside Python, file I/O and imports excluded).",
        "* **zero level** vs truth by `duplexfit measure ZERO TRUTH` (%d samples/face + vertices): mean = average of "
        "the forward and backward mean distances, Hausdorff symmetric; in units of 1e-3 of the unit box." % cfg.samples,
        "* **offset** by `duplexfit measure OFFSET --offset-of TRUTH --delta D`: |dist to truth - |D|| / |D| in %, "
        "mean / p99 / max over the samples; columns are ours / peer / truth-offset.",
        "* **components**: faces sharing a vertex (coincident vertices welded); significant = at least 1 % of "
        "that mesh's area, tiny = below 0.1 %. Zero-level column: all components.",
        "* **genus**: handles of the significant components, summed ((2 - V + E - F) / 2 a component, vertices "
        "welded); the truth columns are the ground-truth mesh's and its exact (OpenVDB) offset's.",
        "* D > 0 is inward, D < 0 outward (duplexfit's sign convention).", "",
    ]
    head = ("| model | D | time s ours / peer | zero mean e-3 ours / peer | zero Hausdorff e-3 ours / peer | "
            "zero comps ours / peer / truth | offset mean % ours / peer / truth | offset p99 % ours / peer / truth | "
            "offset max % ours / peer / truth | "
            "offset comps >= 1 % ours / peer / truth | offset comps < 0.1 % ours / peer / truth | "
            "zero genus ours / peer / truth | offset genus ours / peer / truth |")
    lines += [head, "|" + "|".join(["---"] * (head.count("|") - 1)) + "|"]
    win_off = win_zero = n_off = n_zero = n_genus = 0
    genus_off = []
    for r in rows:
        o, p, t = r.get("ours", {}), r.get("peer", {}), r.get("truth_offset", {})
        if r.get("status") == "error" and not o.get("offset"):
            lines.append("| %s | %g | error: %s | | | | | | | | | | |" % (r["model"], r["delta"],
                                                                   "; ".join(r["errors"]).replace("|", "/")[:300]))
            continue
        pt = None
        if get(p, "poisson", "seconds") is not None and get(p, "vdb", "seconds") is not None:
            pt = "%s (%s+%s)" % (fmt(p["seconds"], 1), fmt(p["poisson"]["seconds"], 1), fmt(p["vdb"]["seconds"], 1))
        time_cell = "%s / %s" % (fmt(o.get("wall_seconds"), 1), pt or "-")
        zc_truth = get(r, "truth_components", "components")
        row = [r["model"], "%g" % r["delta"], time_cell,
               cell(get(o, "zero", "mean"), get(p, "zero", "mean"), scale=1e3, digits=3),
               cell(get(o, "zero", "hausdorff"), get(p, "zero", "hausdorff"), scale=1e3, digits=2),
               cell(get(o, "zero_components", "components"), get(p, "zero_components", "components"), zc_truth),
               cell(get(o, "offset", "mean_pct"), get(p, "offset", "mean_pct"), get(t, "offset", "mean_pct")),
               cell(get(o, "offset", "p99_pct"), get(p, "offset", "p99_pct"), get(t, "offset", "p99_pct")),
               cell(get(o, "offset", "max_pct"), get(p, "offset", "max_pct"), get(t, "offset", "max_pct"), digits=1),
               cell(get(o, "offset_components", "significant"), get(p, "offset_components", "significant"),
                    get(t, "offset_components", "significant")),
               cell(get(o, "offset_components", "tiny"), get(p, "offset_components", "tiny"),
                    get(t, "offset_components", "tiny")),
               cell(get(o, "zero_components", "genus"), get(p, "zero_components", "genus"),
                    get(r, "truth_components", "genus")),
               cell(get(o, "offset_components", "genus"), get(p, "offset_components", "genus"),
                    get(t, "offset_components", "genus"))]
        if r.get("errors"):
            row[0] += " (errors: %s)" % "; ".join(r["errors"]).replace("|", "/")[:200]
        lines.append("| " + " | ".join(row) + " |")
        a, b = get(o, "offset", "mean_pct"), get(p, "offset", "mean_pct")
        if a is not None and b is not None:
            n_off += 1
            win_off += a <= b
        a, b = get(o, "zero", "mean"), get(p, "zero", "mean")
        if a is not None and b is not None:
            n_zero += 1
            win_zero += a <= b
        a, b = get(o, "offset_components", "genus"), get(t, "offset_components", "genus")
        if a is not None and b is not None:
            n_genus += 1
            if a != b:
                genus_off.append("%s D=%g (%g vs %g)" % (r["model"], r["delta"], a, b))
    lines.append("")
    if cfg.show_peer:
        lines.append("**Summary: ours <= peer offset mean on %d of %d pairs; ours <= peer zero-level mean on %d of "
                     "%d pairs.**" % (win_off, n_off, win_zero, n_zero))
        doc["summary"] = {"offset_mean_ours_le_peer": win_off, "offset_pairs": n_off,
                          "zero_mean_ours_le_peer": win_zero, "zero_pairs": n_zero}
    if n_genus:
        lines.append("")
        lines.append("**Offset genus = the exact offset's on %d of %d pairs**%s" % (
            n_genus - len(genus_off), n_genus, (": differs on " + ", ".join(genus_off) + ".") if genus_off else "."))
        doc["offset_genus_differs"] = genus_off
    errors = [r for r in rows if r.get("errors")]
    per_model = {}
    for r in rows:
        if r.get("model_seconds") is not None:
            per_model[r["model"]] = r["model_seconds"]
    if per_model:
        lines.append("")
        lines.append("Wall time per model (all its deltas, with the measuring): " +
                     ", ".join("%s %.0f s" % (m, s) for m, s in per_model.items()) + ".")
    lines.append("")
    lines.append("%d runs, %d with errors; total %.0f s. Raw numbers: `%s`." % (
        len(rows), len(errors), doc.get("total_seconds", 0.0), os.path.basename(cfg.json_out)))
    return "\n".join(lines) + "\n"


GENERATED_MARK = "<!-- everything below is generated by bench/fidelity.py; the text above is kept -->"


def write_outputs(doc, cfg):
    text = markdown(doc, cfg)
    # A hand-written analysis above the marker survives a rerun.
    try:
        old = open(cfg.out).read()
        if GENERATED_MARK in old:
            text = old.split(GENERATED_MARK)[0] + GENERATED_MARK + "\n\n" + text
    except OSError:
        pass
    for path, content in ((cfg.out, text), (cfg.json_out, json.dumps(doc, indent=1, default=str) + "\n")):
        d = os.path.dirname(os.path.abspath(path))
        os.makedirs(d, exist_ok=True)
        tmp = path + ".tmp"
        with open(tmp, "w") as f:
            f.write(content)
        os.replace(tmp, path)


# ---------------------------------------------------------------------------------------------- main

def parse_deltas(text):
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError("--deltas wants numbers like 0.025,0.05 (negative: --deltas=-0.02)")
    if not vals or any(v == 0 for v in vals):
        raise argparse.ArgumentTypeError("--deltas needs non-zero values")
    return vals


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return "%s, %d CPU threads, %s" % (cpu, os.cpu_count() or 0, platform.platform())


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    root = os.path.normpath(os.path.join(HERE, ".."))
    p.add_argument("--duplexfit", default=os.path.join(root, "build", "cli", "duplexfit"), help="duplexfit binary")
    p.add_argument("--duplexfit-args", default="", help='extra arguments for `duplexfit fit`, e.g. "--side-test"')
    p.add_argument("--data", default=os.path.normpath(os.path.join(root, "..", "shared", "data")))
    p.add_argument("--models", default="", help="comma-separated cloud names (default: every model with truth)")
    p.add_argument("--with-550k", action="store_true", help="also run fandisk_550k (slow)")
    p.add_argument("--deltas", type=parse_deltas, default=None,
                   help="deltas for every model (default: 0.025,0.05 for mesh clouds, 0.02,-0.02 for analytic)")
    p.add_argument("--out", default=os.path.join(root, "docs", "fidelity.md"), help="markdown output")
    p.add_argument("--json-out", default="", help="JSON output (default: --out with .json)")
    p.add_argument("--no-peer", action="store_true", help="skip the Poisson + OpenVDB peer columns")
    p.add_argument("--peer-from", help="take the peer and truth-offset results of every (model, D) from this earlier "
                   "fidelity JSON instead of recomputing them (they do not depend on duplexfit)")
    p.add_argument("--poisson-depth", type=int, default=peer.POISSON_DEPTH)
    p.add_argument("--poisson-scale", type=float, default=peer.POISSON_SCALE)
    p.add_argument("--poisson-linear-fit", action="store_true", default=peer.POISSON_LINEAR_FIT)
    p.add_argument("--poisson-trim", type=float, default=0.0, help="drop vertices below this density quantile")
    p.add_argument("--poisson-threads", type=int, default=-1)
    p.add_argument("--vdb-voxel", type=float, default=0.0,
                   help="VDB voxel size (default min(%g, |D|/%g))" % (peer.VDB_VOXEL_MAX, peer.VDB_VOXELS_PER_DELTA))
    p.add_argument("--vdb-margin", type=int, default=peer.VDB_MARGIN, help="narrow-band voxels beyond |D|")
    p.add_argument("--samples", type=float, default=10, help="measure samples per face (duplexfit measure)")
    p.add_argument("--truth-tol", type=float, default=1e-5, help="chord error of generated analytic truth meshes")
    p.add_argument("--timeout", type=float, default=3600, help="seconds per external step")
    p.add_argument("--jobs", type=int, default=1, help="models run concurrently (timings then interfere)")
    p.add_argument("--tmp", default=None, help="folder for temporary outputs (default: system temp)")
    p.add_argument("--keep", action="store_true", help="keep the temporary outputs")
    argv = list(sys.argv[1:])
    for i, a in enumerate(argv[:-1]):  # its value usually starts with "--", which argparse would refuse
        if a == "--duplexfit-args":
            argv[i:i + 2] = ["--duplexfit-args=" + argv[i + 1]]
            break
    cfg = p.parse_args(argv)
    cfg.extra = shlex.split(cfg.duplexfit_args)
    cfg.json_out = cfg.json_out or os.path.splitext(cfg.out)[0] + ".json"
    cfg.duplexfit = os.path.abspath(cfg.duplexfit)
    if not (os.path.isfile(cfg.duplexfit) and os.access(cfg.duplexfit, os.X_OK)):
        print("fidelity.py: no duplexfit binary at %s (build it, or pass --duplexfit)" % cfg.duplexfit, file=sys.stderr)
        return 2
    try:
        version = subprocess.run([cfg.duplexfit, "--version"], capture_output=True, text=True, timeout=60).stdout.strip()
    except (OSError, subprocess.TimeoutExpired) as e:
        print("fidelity.py: cannot run %s: %s" % (cfg.duplexfit, e), file=sys.stderr)
        return 2
    versions = {}
    def load_peer_rows():
        rows = {}
        try:
            old = json.load(open(cfg.peer_from))
        except (OSError, ValueError):
            return {}, {}
        for r in old.get("runs", []):
            if r.get("peer") or r.get("truth_offset"):
                rows[(r["model"], float(r["delta"]))] = r
        return rows, old.get("versions", {})

    if cfg.peer_from:
        _, versions = load_peer_rows()
        cfg.no_peer = True
    cfg.show_peer = not cfg.no_peer or bool(cfg.peer_from)
    if cfg.peer_from:
        cfg.vdb_available = False
    elif not cfg.no_peer:
        try:
            versions = peer.versions()
        except peer.PeerMissing as e:
            print("fidelity.py: the peer pipeline is unavailable: %s\n(or run with --no-peer to skip the peer "
                  "columns)" % e, file=sys.stderr)
            return 3
        cfg.vdb_available = True
    else:
        try:
            peer.import_openvdb()
            cfg.vdb_available = True
        except peer.PeerMissing as e:
            log("note: %s; the truth offsets are skipped" % e)
            cfg.vdb_available = False

    if cfg.models:
        models = [m.strip() for m in cfg.models.split(",") if m.strip()]
    else:
        models = MESH_MODELS + (SLOW_MODELS if cfg.with_550k else []) + ANALYTIC_MODELS
    plan = [(m, cfg.deltas or default_deltas(m, cfg.data)) for m in models]
    tmp_root = tempfile.mkdtemp(prefix="fidelity-", dir=cfg.tmp)
    cfg.tmp = tmp_root
    script = os.path.abspath(sys.argv[0])
    script = os.path.relpath(script, root) if script.startswith(root + os.sep) else script
    command = " ".join(shlex.quote(a) for a in [sys.executable, script] + sys.argv[1:])
    doc = {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
           "command": command,
           "machine": machine(), "duplexfit": cfg.duplexfit, "duplexfit_version": version,
           "duplexfit_args": cfg.extra, "python": sys.executable, "versions": versions,
           "settings": {"poisson_depth": cfg.poisson_depth, "poisson_scale": cfg.poisson_scale,
                        "poisson_linear_fit": cfg.poisson_linear_fit, "poisson_trim": cfg.poisson_trim,
                        "poisson_threads": cfg.poisson_threads,
                        "vdb_voxel": cfg.vdb_voxel or "min(%g, |D|/%g)" % (peer.VDB_VOXEL_MAX, peer.VDB_VOXELS_PER_DELTA),
                        "vdb_margin_voxels": cfg.vdb_margin, "measure_samples_per_face": cfg.samples,
                        "significant_share": SIGNIFICANT, "tiny_share": TINY, "truth_tol": cfg.truth_tol,
                        "no_peer": cfg.no_peer, "peer_from": cfg.peer_from},
           "runs": []}
    log("%d models, %d runs; temporary outputs in %s" % (len(plan), sum(len(d) for _, d in plan), tmp_root))
    t0 = time.perf_counter()
    results = {}
    lock = threading.Lock()

    def one(i, model, deltas):
        try:
            rows = run_model(cfg, model, deltas, i + 1, len(plan))
        except Exception as e:  # never lose the other models
            log("%s failed: %s" % (model, e))
            rows = [{"model": model, "delta": d, "status": "error", "errors": ["%s: %s" % (type(e).__name__, e)],
                     "ours": {}, "peer": {}, "truth_offset": {}} for d in deltas]
        # The peer's and the truth's numbers from the earlier (or a still running) run: waits up to an hour
        # for that run to reach this model.
        peer_rows = {}
        if cfg.peer_from:
            for _ in range(120):
                peer_rows, _v = load_peer_rows()
                if all((r["model"], float(r["delta"])) in peer_rows for r in rows):
                    break
                time.sleep(30)
        for r in rows:
            old = peer_rows.get((r["model"], float(r["delta"])))
            if old:
                r["peer"], r["truth_offset"] = old.get("peer", {}), old.get("truth_offset", {})
                r["peer_from"] = cfg.peer_from
        with lock:
            results[i] = rows
            doc["runs"] = [r for k in sorted(results) for r in results[k]]
            doc["total_seconds"] = time.perf_counter() - t0
            write_outputs(doc, cfg)

    try:
        with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, cfg.jobs)) as ex:
            futures = [ex.submit(one, i, m, d) for i, (m, d) in enumerate(plan)]
            for f in futures:
                f.result()
    finally:
        if not cfg.keep:
            shutil.rmtree(tmp_root, ignore_errors=True)
        else:
            log("kept temporary outputs in %s" % tmp_root)
    doc["total_seconds"] = time.perf_counter() - t0
    write_outputs(doc, cfg)
    log("wrote %s and %s (%.0f s)" % (cfg.out, cfg.json_out, doc["total_seconds"]))
    if "summary" in doc:
        s = doc["summary"]
        log("ours <= peer offset mean on %d of %d pairs" % (s["offset_mean_ours_le_peer"], s["offset_pairs"]))
    return 0 if all(not r.get("errors") for r in doc["runs"]) else 1


if __name__ == "__main__":
    sys.exit(main())
