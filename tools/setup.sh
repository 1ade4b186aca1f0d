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

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
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
