#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# One run of both daemons with the depth path through telex-sim-impair (docs/BENCHMARKS.md, "Repair
# of lost tiles" and "Latency with no tuning flags"). Prints the station's --json-summary line.
#   tools/loss_run.sh LOSS DELAY_MS SOURCE [telex-local flags...]
# LOSS 0 and DELAY_MS 0 skip the proxy. SOURCE is a telex-remote --source, e.g.
#   'files:/path/to/desk_*_depth_mm.png,fps=30,loop' or synthetic:plane,noise=off.
# TELEX_RUN_SECONDS (default 30) is the station's duration; TELEX_REMOTE_FLAGS (split on spaces)
# adds telex-remote flags. Needs a build (tools/build.sh).
set -euo pipefail
if [[ $# -lt 3 ]]; then
  echo "usage: tools/loss_run.sh LOSS DELAY_MS SOURCE [telex-local flags...]" >&2
  exit 2
fi
loss="$1" delay="$2" source="$3"
shift 3
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${TELEX_BUILD_DIR:-$root/build}/tools"
seconds="${TELEX_RUN_SECONDS:-30}"
log="$(mktemp -d)"
port=$((20000 + RANDOM % 20000))
udp=$((port + 1)) proxy=$((port + 2))

"$bin/telex-remote" --listen "127.0.0.1:$port" --transport udp --duration $((seconds + 10)) \
  --source "$source" ${TELEX_REMOTE_FLAGS:-} >"$log/remote.out" 2>"$log/remote.err" &
remote=$!
pids=("$remote")
udp_flags=()
if [[ "$loss" != 0 || "$delay" != 0 ]]; then
  "$bin/telex-sim-impair" --listen "127.0.0.1:$proxy" --forward "127.0.0.1:$udp" --loss "$loss" \
    --delay-ms "$delay" --seed 7 >"$log/proxy.out" 2>"$log/proxy.err" &
  pids+=("$!")
  udp_flags=(--udp-port "$udp" --udp-announce-port "$proxy")
fi
trap 'kill -INT "${pids[@]}" 2>/dev/null; wait 2>/dev/null' EXIT INT TERM
sleep 1
"$bin/telex-local" --connect "127.0.0.1:$port" "${udp_flags[@]}" --hand script:press --repeat \
  --duration "$seconds" --haptics sim --json-summary --quiet "$@" 2>"$log/local.err" | tail -1
sleep 1.5  # the remote's next stats line
grep -o 'key-requests.*' "$log/remote.err" | tail -1 >&2 || true
# The remote's CPU so far (user + system, all threads) and the frames it sent: CPU per frame.
if [[ -r /proc/$remote/stat ]]; then
  ticks="$(awk '{print $14 + $15}' "/proc/$remote/stat")"
  frames="$(grep -o 'frames-sent [0-9]*' "$log/remote.err" | tail -1 | awk '{print $2}')"
  awk -v t="$ticks" -v hz="$(getconf CLK_TCK)" -v f="${frames:-0}" 'BEGIN {
    printf "loss_run: remote CPU %.2f s for %d frames sent: %.3f ms per frame\n", t / hz, f,
      (f > 0 ? 1000 * t / hz / f : 0) }' >&2
fi
echo "loss_run: logs in $log" >&2
