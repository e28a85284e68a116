#!/usr/bin/env bash
# Sweeps the launch-parameter overrides the library reads at device open (DUPLEXFIT_WG_SIZE,
# DUPLEXFIT_CHUNK; optionally PoCL's own POCL_WORK_GROUP_METHOD) on one system and device: one
# duplexfit-bench --csv run per setting, settings interleaved over ROUNDS rounds so that load from other
# processes spreads over all of them, then a summary (best over rounds) of the SpMV, per-operation and
# CG figures. Usage:
#   [ROUNDS=2] [OUT=dir] [SETTINGS="default VAR=value ..."] bench/sweep_launch.sh BUILD/bench/duplexfit-bench [bench options]
# ROUNDS=0 with OUT=dir of an earlier sweep only prints its summary again.
# Defaults: --device=0:0 --sizes=600k --no-eigen --cg-trials=3 (extra options override them).
set -euo pipefail
bench=${1:?usage: sweep_launch.sh path/to/duplexfit-bench [bench options]}
shift
rounds=${ROUNDS:-2}
out=${OUT:-$(mktemp -d /tmp/duplexfit-sweep.XXXXXX)}
mkdir -p "$out"
args=(--device=0:0 --sizes=600k --no-eigen --cg-trials=3 --csv "$@")
settings=("default" "DUPLEXFIT_WG_SIZE=256" "DUPLEXFIT_WG_SIZE=1024" "DUPLEXFIT_CHUNK=128"
          "DUPLEXFIT_CHUNK=2048" "POCL_WORK_GROUP_METHOD=cbs")
[[ -n "${SETTINGS:-}" ]] && read -r -a settings <<<"$SETTINGS"
for r in $(seq 1 "$rounds"); do
  for s in "${settings[@]}"; do
    echo "round $r: $s" >&2
    if [[ $s == default ]]; then env_args=(); else env_args=("$s"); fi
    env "${env_args[@]}" "$bench" "${args[@]}" >"$out/$s.$r.csv" 2>"$out/$s.$r.log"
  done
done
echo "raw output: $out" >&2
command -v python3 >/dev/null || exit 0
SWEEP_ORDER="${settings[*]}" python3 - "$out" <<'PY'
import csv, glob, io, os, sys
from collections import defaultdict
best = defaultdict(dict)   # (setting, precision) -> metric -> best value over rounds (min ms / max GB/s)
def keep(key, name, value, larger=False):
    old = best[key].get(name)
    if old is None or (value > old if larger else value < old):
        best[key][name] = value
for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.csv"))):
    setting = os.path.basename(path).rsplit(".", 2)[0]
    sections = open(path).read().split("\n# ")
    for sec in sections:
        title, _, body = sec.partition("\n")
        rows = list(csv.DictReader(io.StringIO(body)))
        for row in rows:
            if title.startswith("STREAM") and row.get("where", "").startswith("device"):
                keep((setting, row["precision"]), "triad GB/s", float(row["best GB/s"]), True)
            elif title.startswith("SpMV") and row["kernel"] == "row-per-item":
                keep((setting, row["precision"]), "spmv ms", float(row["min ms"]))
            elif title.startswith("SpMV") and row["kernel"] == "row-per-group":
                keep((setting, row["precision"]), "group ms", float(row["min ms"]))
            elif title.startswith("CG iteration"):
                op = row["operation"]
                if op in ("spmvDot", "cgUpdate", "cgDirection", "sum: one iteration"):
                    keep((setting, row["precision"]), op.split(":")[0] + " ms", float(row["min ms"]))
            elif title.startswith("CG from") and row["solver"] == "duplexfit":
                keep((setting, row["precision"]), "cg ms/it", float(row["min ms/it"]))
cols = ["triad GB/s", "spmv ms", "group ms", "spmvDot ms", "cgUpdate ms", "cgDirection ms",
        "sum ms", "cg ms/it"]
print("best over rounds (ms: min, GB/s: max); triad: the device's own; spmv: row-per-item, group: row-per-group")
w = max([len(k[0]) for k in best] + [7])
print("%-*s %-9s" % (w, "setting", "precision") + "".join("%15s" % c for c in cols))
order = os.environ.get("SWEEP_ORDER", "").split()
rank = lambda s: order.index(s) if s in order else len(order)
for key in sorted(best, key=lambda k: (k[1], rank(k[0]), k[0])):
    print("%-*s %-9s" % (w, key[0], key[1]) + "".join("%15.3f" % best[key][c] if c in best[key] else "%15s" % "-" for c in cols))
PY
