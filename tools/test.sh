#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Quick-start command 2: install what is missing, build, run the whole test suite (ctest), then say
# how many tests skipped and why (a clone without ../shared skips the real-frame tests; CI runs
# with TELEX_NO_SKIPS=1, which turns any skip into a failure).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
t0=$SECONDS
"$root/tools/build.sh"
t_build=$((SECONDS - t0))
build="${TELEX_BUILD_DIR:-$root/build}"
cd "$build"
set +e
ctest --output-on-failure --schedule-random -j "${TELEX_JOBS:-$(nproc)}" --timeout 600 2>&1 | tee ctest.out
rc=${PIPESTATUS[0]}
set -e
# The phases: build.sh's line above splits the first into install, configure and build.
echo "test.sh: install + configure + build ${t_build} s, tests $((SECONDS - t0 - t_build)) s"
skipped="$(sed -nE 's/^[[:space:]]+[0-9]+ - (.*) \(Skipped\)$/\1/p' ctest.out)"
count=0
[ -n "$skipped" ] && count="$(printf '%s\n' "$skipped" | wc -l)"
echo "test.sh: ${count} test(s) skipped${TELEX_NO_SKIPS:+ (TELEX_NO_SKIPS is set: a skip fails instead)}"
if [ "$count" -gt 0 ]; then
  # The reason is the line gtest prints after "Skipped" in the test's output.
  while IFS= read -r name; do
    reason="$(awk -v t="Testing: $name" '
      index($0, t) { on = 1; next }
      on && /Testing: / { exit }
      on && seen { print; exit }
      on && /: Skipped$/ { seen = 1 }' Testing/Temporary/LastTest.log)"
    echo "  skipped: $name: ${reason:-reason not found in Testing/Temporary/LastTest.log}"
  done <<< "$skipped"
fi
exit "$rc"
