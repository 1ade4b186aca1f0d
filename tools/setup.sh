#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs every Debian package the project builds, tests and benchmarks with.
# Idempotent: quiet and quick when everything is already present.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libopenni2-dev libopenni2-0
  libv4l-dev
  libopencv-dev libopencv-contrib-dev
  zlib1g-dev libzstd-dev libpng-dev
  libboost-dev libboost-system-dev
  libglm-dev
  libavcodec-dev libavutil-dev libswscale-dev
  libepoxy-dev libegl-dev libegl1 libegl-mesa0 libgl1-mesa-dri
  libglfw3-dev libxrandr2 libx11-dev xvfb
  libopenxr-dev libopenxr-loader1 openxr-layer-corevalidation
  libhidapi-dev libusb-1.0-0-dev libfreenect-dev libfreenect-bin
  libssl-dev rt-tests
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev
  librosbag-storage-dev libsensor-msgs-dev libgeometry-msgs-dev libtf2-msgs-dev libstd-msgs-dev
  pluginlib-dev libclass-loader-dev librcpputils-dev librcutils-dev libament-index-cpp-dev
  python3-rosbag
  iproute2 procps
)

# One dpkg-query for all of them (one a package took 17 s on a loaded 2-core machine).
installed="$(dpkg-query -W -f='${Package} ${Status}\n' "${PACKAGES[@]}" 2>/dev/null |
  awk '$NF == "installed" && $(NF-1) == "ok" { sub(/:.*/, "", $1); print $1 }' || true)"
missing=()
for p in "${PACKAGES[@]}"; do
  grep -qxF "$p" <<< "$installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  SUDO="sudo"
fi
echo "setup: installing ${#missing[@]} missing package(s): ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q >/dev/null
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done" >&2
