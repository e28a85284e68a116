#!/usr/bin/env bash
# Builds the libFuzzer targets (test/fuzz, DUPLEXFIT_FUZZ=ON) with clang in build-fuzz and runs each for a
# bounded time, starting from the committed seed corpora (test/fuzz/corpus/<target>, never modified: new
# inputs go to build-fuzz/corpus/<target>). Fails when any target finds a crash, a sanitizer report, a leak,
# a timeout or an out-of-memory; the reproducers land in build-fuzz/artifacts/.
#   scripts/fuzz.sh [SECONDS per target, default 60] [TARGET...]   (default: all targets)
# Environment: CXX (default clang++), DUPLEXFIT_FUZZ_BUILD (default build-fuzz), DUPLEXFIT_FUZZ_JOBS (-j, 2).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
[ $# -gt 0 ] && shift
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_point_cloud fuzz_mesh fuzz_field fuzz_check_measure fuzz_cli_file)
build="${DUPLEXFIT_FUZZ_BUILD:-build-fuzz}"
cxx="${CXX:-clang++}"
case "$cxx" in *clang*) ;; *) cxx=clang++ ;; esac

cmake -S . -B "$build" -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDUPLEXFIT_FUZZ=ON \
  -DDUPLEXFIT_BUILD_TESTS=OFF -DDUPLEXFIT_BUILD_BENCH=OFF -DDUPLEXFIT_BUILD_CLI=OFF \
  -DDUPLEXFIT_WARNINGS_AS_ERRORS="${DUPLEXFIT_FUZZ_WERROR:-OFF}" >/dev/null
cmake --build "$build" --target "${targets[@]}" -j"${DUPLEXFIT_FUZZ_JOBS:-2}"

# One thread: the measure code's OpenMP regions are tiny here, and one thread keeps runs reproducible.
export OMP_NUM_THREADS=1
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
mkdir -p "$build/artifacts" "$build/logs"
failed=()
summary=()
for t in "${targets[@]}"; do
  corpus="$build/corpus/$t"
  mkdir -p "$corpus"
  log="$build/logs/$t.log"
  echo "== $t: $seconds s"
  status=0
  "$build/test/fuzz/$t" -max_total_time="$seconds" -timeout=20 -rss_limit_mb=2048 -max_len=65536 \
    -print_final_stats=1 -artifact_prefix="$build/artifacts/$t-" "$corpus" "test/fuzz/corpus/$t" \
    >"$log" 2>&1 || status=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  if [ "$status" -ne 0 ]; then
    failed+=("$t")
    tail -n 60 "$log"
    summary+=("$t: FAILED (exit $status) after ${execs:-?} executions; log $log")
  else
    summary+=("$t: ok, ${execs:-?} executions in $seconds s, corpus $(ls "$corpus" | wc -l) files")
  fi
done
printf '%s\n' "== fuzz summary" "${summary[@]}"
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzzing found problems in: ${failed[*]} (reproducers: $build/artifacts/)" >&2
  exit 1
fi
