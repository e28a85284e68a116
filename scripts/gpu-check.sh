#!/bin/bash
# The GPU check, run on a lent device machine from the repository root after scripts/gpu-bundle.sh here
# (device tool: carry [".gpu"], command "bash scripts/gpu-check.sh", timeout_s about 540). It registers the
# NVIDIA OpenCL driver with the ICD loader by hand (the image has no ICD file), runs the device suites on
# the GPU against their C++ twins, then fits fandisk_50k and fandisk_550k on the GPU with the level matrices
# assembled on the device and on the host (--assembly), alternated, and leaves in $OUT: check.log (every
# step's output), summary.json (each fit's wall time and stages from report.json) and the report.json of
# the last fandisk_550k fit of each kind. DUPLEXFIT_CHECK_DEVICE=cpu runs the same on a CPU device (a dry
# run of this script on a machine without a GPU).
set -uo pipefail
out=${OUT:-/tmp/duplexfit-gpu-check}
mkdir -p "$out"
log="$out/check.log"
: >"$log"
say() { echo "== $*" | tee -a "$log"; }
export LD_LIBRARY_PATH="$PWD/.gpu/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
bin=.gpu/bin
device=${DUPLEXFIT_CHECK_DEVICE:-gpu}
[ -x "$bin/duplexfit" ] || { echo "gpu-check: no .gpu/bin/duplexfit (run scripts/gpu-bundle.sh, carry .gpu)" >&2; exit 1; }
# GCC's runtime from the bundle only where the machine's own does not load the binaries.
if ! "$bin/duplexfit" --version >/dev/null 2>>"$log"; then
  export LD_LIBRARY_PATH="$PWD/.gpu/lib-runtime:$LD_LIBRARY_PATH"
  "$bin/duplexfit" --version >/dev/null 2>>"$log" || { echo "gpu-check: the binaries do not load" | tee -a "$log" >&2; exit 1; }
  echo "== with the bundle's libstdc++" >>"$log"
fi
say "bundle of git $(cat .gpu/commit 2>/dev/null), device $device, $(date -u +%FT%TZ)"

if [ "$device" = gpu ] && ! ls /etc/OpenCL/vendors/*.icd >/dev/null 2>&1; then
  icd=$(ldconfig -p 2>/dev/null | awk '/libnvidia-opencl\.so\.1/ {print $NF; exit}')
  [ -n "$icd" ] || icd=$(find / -xdev -name 'libnvidia-opencl.so.1' 2>/dev/null | head -1)
  if [ -n "$icd" ]; then
    mkdir -p /etc/OpenCL/vendors && echo "$icd" >/etc/OpenCL/vendors/nvidia.icd
    say "registered $icd"
  else
    say "no libnvidia-opencl.so.1 found"
  fi
fi
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv >>"$log" 2>&1
"$bin/duplexfit" devices >>"$log" 2>&1

# The suites whose kernels have C++ twins; the shared-data cases skip (no shared data travels).
for suite in device linalg field fit polygonize; do
  say "suite $suite"
  DUPLEXFIT_DEVICE=$device DUPLEXFIT_SHARED_DATA=/nonexistent timeout 150 "$bin/duplexfit_tests" -ts="$suite" \
    >"$out/suite.txt" 2>&1
  echo "exit $?" >>"$log"
  grep -E "ERROR|FAILED|test cases:|assertions:|Status" "$out/suite.txt" | head -40 >>"$log"
done
rm -f "$out/suite.txt"

runs="$out/runs.txt"
: >"$runs"
for cloud in fandisk_50k fandisk_550k; do
  for round in 1 2; do
    for where in device host; do
      dir=/tmp/duplexfit-gpu-$cloud-$where-$round
      rm -rf "$dir"
      start=$(date +%s.%N)
      "$bin/duplexfit" fit ".gpu/data/clouds/$cloud.ply" --offset 0.025 --device "$device" --assembly "$where" \
        -o "$dir" --quiet >>"$log" 2>&1
      status=$?
      end=$(date +%s.%N)
      echo "$cloud $where $round $status $start $end $dir" >>"$runs"
      say "fit $cloud --assembly $where (round $round): exit $status"
      [ "$cloud" = fandisk_550k ] && [ -f "$dir/report.json" ] && cp "$dir/report.json" "$out/report-$where.json"
      [ "$where" = host ] && cmp -s "/tmp/duplexfit-gpu-$cloud-device-$round/field.dpxf" "$dir/field.dpxf" &&
        say "$cloud: the same field.dpxf from both assemblies"
    done
  done
done

python3 - "$runs" "$out/summary.json" <<'EOF' >>"$log" 2>&1
import json, sys
rows = []
for line in open(sys.argv[1]):
    cloud, where, rnd, status, start, end, d = line.split()
    row = {"cloud": cloud, "assembly": where, "round": int(rnd), "exit": int(status),
           "wall_s": round(float(end) - float(start), 3)}
    try:
        r = json.load(open(d + "/report.json"))
        lv = r["level_reports"]
        row.update(device=r["device"], assembled=r.get("assembly"), stages=r["seconds"],
                   constraints=sum(l["seconds"]["constraints"] for l in lv),
                   residual=sum(l["seconds"]["residual"] for l in lv),
                   assembly_s=sum(l["seconds"]["assembly"] for l in lv),
                   solve=sum(l["seconds"]["solve"] for l in lv), E0=r["E0"])
    except (OSError, KeyError, ValueError) as e:
        row["error"] = str(e)
    rows.append(row)
    print(json.dumps(row))
json.dump(rows, open(sys.argv[2], "w"), indent=1)
EOF
say "done $(date -u +%FT%TZ)"
