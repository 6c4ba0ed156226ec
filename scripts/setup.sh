#!/usr/bin/env bash
# Shared by demo.sh and test.sh: install missing Debian packages, configure and build Release into build/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Open MPI: `mpirun -np N relume fit` and its tests; relume builds without it too.
PACKAGES=(cmake g++ make pkg-config libembree-dev libtbb-dev libeigen3-dev libopenimageio-dev
  libopenmpi-dev openmpi-bin libopenexr-dev nlohmann-json3-dev libcli11-dev libfmt-dev libspdlog-dev libtinygltf-dev
  libtinyobjloader-dev libgtest-dev)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  if [[ $(id -u) -eq 0 ]]; then
    echo "relume: installing ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
  else
    echo "relume: missing packages; run: sudo apt-get install -y ${missing[*]}" >&2
    exit 1
  fi
fi
cmake -S "$ROOT" -B "$ROOT/build" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$ROOT/build" -j "$(nproc)"
