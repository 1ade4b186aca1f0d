#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs missing dependencies and builds into build/ (or $TELEX_BUILD_DIR). Extra args go to cmake.
# TELEX_BUILD_TARGETS="a b": build only those targets (and what they link), not the whole tree.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
t0=$SECONDS
"$root/tools/setup.sh"
t_setup=$((SECONDS - t0))
build="${TELEX_BUILD_DIR:-$root/build}"
jobs="${TELEX_JOBS:-$(nproc)}"
if [ ! -f "$build/build.ninja" ]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
elif [ $# -gt 0 ]; then
  cmake "$build" "$@" >/dev/null
fi
t_configure=$((SECONDS - t0 - t_setup))
targets=()
[ -n "${TELEX_BUILD_TARGETS:-}" ] && read -r -a targets <<< "$TELEX_BUILD_TARGETS"
cmake --build "$build" -j "$jobs" ${targets[@]:+--target "${targets[@]}"}
# How long each phase took (build/.ninja_log has each translation unit's own time).
echo "build.sh: install ${t_setup} s, configure ${t_configure} s, build $((SECONDS - t0 - t_setup - t_configure)) s${targets[*]:+ (${targets[*]})}" >&2
