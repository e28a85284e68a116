#!/usr/bin/env bash
# Sweeps the launch-parameter overrides the library reads at device open (DUPLEXFIT_WG_SIZE,
# DUPLEXFIT_CHUNK) on one system and device, one duplexfit-bench run per setting, and prints the SpMV,
# per-kernel and CG tables of each run. Usage:
#   bench/sweep_launch.sh BUILD_DIR/bench/duplexfit-bench [--device=0:0] [--sizes=600k] [more bench options]
set -euo pipefail
bench=${1:?usage: sweep_launch.sh path/to/duplexfit-bench [bench options]}
shift
args=(--device=0:0 --sizes=600k --no-eigen --cg-trials=3 "$@")
run() {
  echo "### $1"
  env $1 "$bench" "${args[@]}"
}
run "DUPLEXFIT_SWEEP=default"
for wg in 64 256 1024; do run "DUPLEXFIT_WG_SIZE=$wg"; done
for chunk in 128 512 2048; do run "DUPLEXFIT_CHUNK=$chunk"; done
