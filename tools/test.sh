#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Quick-start command 2: install what is missing, build, run the whole test suite (ctest).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/tools/build.sh"
build="${TELEX_BUILD_DIR:-$root/build}"
cd "$build"
ctest --output-on-failure -j "${TELEX_JOBS:-$(nproc)}" --timeout 600
