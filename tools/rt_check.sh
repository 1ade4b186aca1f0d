#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The 1 kHz loop at the machine's limit: both nodes on loopback with everything on (depth, both
# eyes' video, the stereo view written as pictures) while cyclictest (Debian: rt-tests) measures
# the machine's own scheduling latency at the haptic thread's priority in the same run. Prints the
# station's rate, missed ticks and wake-up latency beside cyclictest's, and their ratio.
#
#   tools/rt_check.sh [synthetic|desk] [SECONDS] [extra telex-local flags...]
#
# desk: the real desk frames from ../shared/data/real/desk (depth and both eyes). Needs root (or
# CAP_SYS_NICE and an unlimited RLIMIT_MEMLOCK) for SCHED_FIFO and mlockall; says so otherwise.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${TELEX_BUILD_DIR:-$root/build}/tools"
scene="${1:-synthetic}"
seconds="${2:-20}"
shift $(($# > 2 ? 2 : $#))
port="${TELEX_RT_PORT:-7390}"
out="$(mktemp -d)"
trap 'kill -INT ${remote:-} ${cyc:-} 2>/dev/null; wait 2>/dev/null; rm -rf "$out"' EXIT

command -v cyclictest >/dev/null || { echo "rt_check: cyclictest not found (apt-get install rt-tests)" >&2; exit 2; }
case "$scene" in
  synthetic) source=(--source synthetic:plane --stereo synthetic:plane) ;;
  desk)
    desk="$root/../shared/data/real/desk"
    [[ -d "$desk" ]] || { echo "rt_check: $desk not found (the real frames beside the clone)" >&2; exit 2; }
    source=(--source "files:$desk/desk_*_depth_mm.png,fps=30,loop"
            --stereo "files:$desk/desk_*_rgb.png,$desk/desk_*_rgb.png,fps=30,loop") ;;
  *) echo "rt_check: scene must be synthetic or desk, got '$scene'" >&2; exit 2 ;;
esac

"$bin/telex-remote" --listen "127.0.0.1:$port" "${source[@]}" --duration $((seconds + 8)) \
  --no-stats 2>"$out/remote.log" &
remote=$!
# The haptic thread's priority (telex/base/periodic.h kHapticPriority), one thread, 1 ms interval,
# memory locked, a histogram in microseconds.
cyclictest -m -p 80 -t1 -i 1000 -D "$((seconds + 2))s" -q -h 20000 >"$out/cyclictest.txt" 2>&1 &
cyc=$!
"$bin/telex-local" --connect "127.0.0.1:$port" --hand script:stroke --repeat --duration "$seconds" \
  --haptics sim --view "png:$out/view" --quiet --json-summary "$@" >"$out/summary.json" \
  2>"$out/local.log"
wait "$cyc" || true

# cyclictest's histogram: "NNNNNN CCCCCC" per microsecond bin, then "# Total:", "# Max Latencies:".
read -r cyc_count cyc_p99 cyc_max < <(awk '
  /^[0-9]+[ \t]+[0-9]+/ { n[$1 + 0] = $2; total += $2 }
  /# Max Latencies:/ { max = $4 }
  END {
    target = 0.99 * total; seen = 0
    for (us = 0; us < 20000; ++us) { seen += n[us]; if (seen >= target) { p = us; break } }
    print total, p, max
  }' "$out/cyclictest.txt")
python3 - "$out/summary.json" "$cyc_count" "$cyc_p99" "$cyc_max" "$scene" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
cyc_n, cyc_p99, cyc_max = int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
ticks, missed = s["ticks"], s["missed_ticks"]
wake = s["wake_latency_p99_us"]
print(f"scene {sys.argv[5]}: haptic {s['haptic_rate_hz']:.1f} Hz, {ticks} ticks, "
      f"{missed} missed ({100.0 * missed / max(ticks + missed, 1):.3f} %), "
      f"period jitter p99 {s['period_p99_jitter_us']:.0f} us")
print(f"  haptic wake-up latency p50 {s['wake_latency_median_us']:.1f} us, "
      f"p99 {wake:.1f} us, max {s['wake_latency_max_us']:.0f} us; {s['scheduling']}; "
      f"{s['memory_lock']}")
print(f"  cyclictest (SCHED_FIFO 80, 1 ms, same run): {cyc_n} samples, p99 {cyc_p99:.0f} us, "
      f"max {cyc_max} us")
print(f"  ratio haptic p99 / cyclictest p99: {wake / max(cyc_p99, 1.0):.2f} (goal <= 1.5)")
PY
