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
  libflann-dev liblz4-dev              # FLANN k-d tree (neighbour queries); lz4 is linked by its headers
  doctest-dev                          # unit tests
  libpng-dev                           # PNG output (section pictures, slice masks)
  nlohmann-json3-dev                   # JSON: report.json and --json output, parsed by the tests (header-only)
  libcli11-dev                         # command-line parsing of the duplexfit tool, header-only
  clinfo                               # device diagnostics
)
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages are installed"
  exit 0
fi

if [ "$(id -u)" -ne 0 ]; then
  echo "install-deps: missing Debian packages: ${missing[*]}" >&2
  echo "install them as root with:" >&2
  echo "  apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
  exit 1
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"
