#!/usr/bin/env bash
# Installs the Debian 12 packages duplexfit needs to build, test and run (apt-get, as root), or, when not
# root, prints exactly which packages are missing and the command that installs them.
set -euo pipefail

packages=(
  g++ make cmake                        # toolchain
  opencl-headers                       # OpenCL C headers + C++ bindings (opencl-c-headers, opencl-clhpp-headers)
  ocl-icd-opencl-dev                   # the OpenCL ICD loader (libOpenCL)
  pocl-opencl-icd                      # PoCL: the CPU OpenCL device the tests run on
  libeigen3-dev                        # Eigen: host linear algebra and the reference solver
  doctest-dev                          # unit tests
  libpng-dev                           # PNG output (section pictures, slice masks)
  nlohmann-json3-dev                   # JSON: report.json and --json output, parsed by the tests (header-only)
  libcli11-dev                         # command-line parsing of the duplexfit tool, header-only
  clinfo                               # device diagnostics
)
# Optional: the build works without them (CMake finds them when present).
optional=(
  libmeshoptimizer-dev                 # mesh simplification: fit/mesh --max-triangles, --max-error
  pybind11-dev python3-dev             # the Python package duplexfit (python/, import duplexfit)
  python3-numpy                        # its arrays and its tests
  doxygen                              # the API documentation (share/doc/duplexfit/html)
  lib3mf-dev                           # 3MF meshes (fit --format 3mf, mesh -o part.3mf, check/measure of .3mf)
  libzip-dev                           # SLA packages: slice --sl1 (PrusaSlicer's SL1 zip)
  pkg-config                           # how CMake finds lib3mf and libzip
  libopenmpi-dev openmpi-bin           # the distributed fit: mpirun -np P duplexfit fit ... (DUPLEXFIT_WITH_MPI)
)
installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
missing=()
for p in "${packages[@]}"; do
  installed "$p" || missing+=("$p")
done
missing_optional=()
for p in "${optional[@]}"; do
  installed "$p" || missing_optional+=("$p")
done

if [ ${#missing[@]} -eq 0 ] && [ ${#missing_optional[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages (and ${#optional[@]} optional) are installed"
  exit 0
fi

if [ "$(id -u)" -ne 0 ]; then
  if [ ${#missing_optional[@]} -gt 0 ]; then
    echo "install-deps: optional packages not installed: ${missing_optional[*]}" \
         "(apt-get install -y --no-install-recommends ${missing_optional[*]})" >&2
  fi
  if [ ${#missing[@]} -eq 0 ]; then
    echo "install-deps: all ${#packages[@]} required packages are installed"
    exit 0
  fi
  echo "install-deps: missing Debian packages: ${missing[*]}" >&2
  echo "install them as root with:" >&2
  echo "  apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
  exit 1
fi

export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if [ ${#missing_optional[@]} -gt 0 ]; then
  echo "install-deps: installing the optional ${missing_optional[*]}"
  apt-get install -y -qq --no-install-recommends "${missing_optional[@]}" ||
    echo "install-deps: could not install ${missing_optional[*]} (optional; the build works without it)" >&2
fi
