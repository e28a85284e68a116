#!/bin/bash
# Packs what a lent GPU machine needs for scripts/gpu-check.sh into .gpu/ (ignored by git; the device
# tool carries it: carry [".gpu"]): a Release build without MPI and Python (build-gpu/), its binaries, the
# shared libraries they load except the C library's own (the device machine's image is not Debian and
# reaches no package registry), and the clouds the check fits. About 37 MB with fandisk_550k. The binaries
# need glibc 2.35 there.
#   bash scripts/gpu-bundle.sh [DATA]      DATA: the shared data folder (default ../shared/data)
# Then run there: bash scripts/gpu-check.sh (docs/benchmarks.md, "GPU check").
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-../shared/data}
[ -f "$data/clouds/fandisk_550k.ply" ] || { echo "gpu-bundle: no $data/clouds/fandisk_550k.ply" >&2; exit 1; }
cmake -S . -B build-gpu -DCMAKE_BUILD_TYPE=Release -DDUPLEXFIT_WITH_MPI=OFF -DDUPLEXFIT_BUILD_PYTHON=OFF \
  -DDUPLEXFIT_BUILD_DOCS=OFF >/dev/null
cmake --build build-gpu -j"$(nproc)" --target duplexfit_cli duplexfit_tests duplexfit_bench
rm -rf .gpu
mkdir -p .gpu/bin .gpu/lib .gpu/lib-runtime .gpu/data/clouds
cp build-gpu/cli/duplexfit build-gpu/test/duplexfit_tests build-gpu/bench/duplexfit-bench .gpu/bin/
for b in .gpu/bin/*; do ldd "$b"; done | awk '$2 == "=>" && $3 ~ /^\// {print $3}' | sort -u |
  while read -r lib; do
    case "$(basename "$lib")" in
      libc.so* | libm.so* | libpthread.so* | libdl.so* | librt.so* | ld-linux*) ;;
      # GCC's runtime needs this glibc (Debian 12's libstdc++ asks for 2.36): used there only when the
      # machine's own is missing or too old (gpu-check.sh tries without it first).
      libstdc++.so* | libgcc_s.so*) cp -L "$lib" .gpu/lib-runtime/ ;;
      *) cp -L "$lib" .gpu/lib/ ;;
    esac
  done
for c in fandisk_8k fandisk_50k fandisk_550k; do cp "$data/clouds/$c.ply" .gpu/data/clouds/; done
git rev-parse --short HEAD > .gpu/commit
grep -qx '/.gpu/' .git/info/exclude 2>/dev/null || echo '/.gpu/' >> .git/info/exclude
du -sh .gpu
