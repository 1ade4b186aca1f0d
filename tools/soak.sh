#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Soak: both daemons through telex-sim-impair at 5 % loss for N minutes, RSS sampled once a second.
#
# Usage: tools/soak.sh [MINUTES=10] [OUTDIR=build/soak]
# Env: BUILD (build dir, default build), LOSS (0.05), WARMUP_S (60), GRACE_S (120), PORT/UDP_PORT/PROXY_PORT,
#      REMOTE_ARGS (default: --transport udp --source synthetic:plane), LOCAL_ARGS (extra flags).
# Writes OUTDIR/rss.csv (t_s,remote_kb,local_kb,proxy_kb), the daemons' logs, and summary.txt.
set -euo pipefail

minutes=${1:-10}
outdir=${2:-build/soak}
build=${BUILD:-build}
loss=${LOSS:-0.05}
warmup_s=${WARMUP_S:-60}
grace_s=${GRACE_S:-120}
port=${PORT:-47300}
udp_port=${UDP_PORT:-47310}
proxy_port=${PROXY_PORT:-47311}
remote_args=${REMOTE_ARGS:---transport udp --source synthetic:plane}
local_args=${LOCAL_ARGS:-}

if ! [[ "$minutes" =~ ^[0-9]+([.][0-9]+)?$ ]]; then
  echo "soak.sh: MINUTES must be a number, got '$minutes'" >&2
  exit 2
fi
for b in telex-remote telex-local telex-sim-impair; do
  if [[ ! -x "$build/tools/$b" ]]; then
    echo "soak.sh: $build/tools/$b not built (cmake --build $build --target $b)" >&2
    exit 2
  fi
done
duration_s=$(awk -v m="$minutes" 'BEGIN { printf "%d", m * 60 }')
mkdir -p "$outdir"

pids=()
# shellcheck disable=SC2317  # called by the EXIT trap
cleanup() {
  for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done
  sleep 1
  for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
}
trap cleanup EXIT

# shellcheck disable=SC2086  # the *_args strings are word lists on purpose
"$build/tools/telex-remote" --listen "127.0.0.1:$port" $remote_args \
  >"$outdir/remote.out" 2>"$outdir/remote.err" &
remote_pid=$!
pids+=("$remote_pid")
"$build/tools/telex-sim-impair" --listen "127.0.0.1:$proxy_port" --forward "127.0.0.1:$udp_port" \
  --loss "$loss" --seed 1 --duration $((duration_s + 20)) --stats-every 60 --json-summary \
  >"$outdir/proxy.out" 2>"$outdir/proxy.err" &
proxy_pid=$!
pids+=("$proxy_pid")
sleep 1
# shellcheck disable=SC2086
"$build/tools/telex-local" --connect "127.0.0.1:$port" --udp-port "$udp_port" \
  --udp-announce-port "$proxy_port" --hand script:press --repeat --haptics sim --no-realtime \
  --quiet --duration "$duration_s" --json-summary $local_args \
  >"$outdir/local.out" 2>"$outdir/local.err" &
local_pid=$!
pids+=("$local_pid")

rss_kb() { awk '/^VmRSS:/ { print $2; f = 1 } END { if (!f) print "" }' "/proc/$1/status" 2>/dev/null || echo ""; }

echo "t_s,remote_kb,local_kb,proxy_kb" >"$outdir/rss.csv"
start=$(date +%s)
while kill -0 "$local_pid" 2>/dev/null; do
  t=$(($(date +%s) - start))
  echo "$t,$(rss_kb "$remote_pid"),$(rss_kb "$local_pid"),$(rss_kb "$proxy_pid")" >>"$outdir/rss.csv"
  # telex-local's --duration starts at its first surface: bound the whole run regardless.
  if ((t > duration_s + grace_s)); then
    echo "soak.sh: telex-local still running ${t} s in; stopping it" >&2
    kill -INT "$local_pid" 2>/dev/null || true
    break
  fi
  if ! kill -0 "$remote_pid" 2>/dev/null; then
    echo "soak.sh: telex-remote exited during the soak (see $outdir/remote.err)" >&2
    break
  fi
  sleep 1
done
local_rc=0
wait "$local_pid" || local_rc=$?
kill -INT "$proxy_pid" 2>/dev/null || true
wait "$proxy_pid" 2>/dev/null || true
remote_alive=no
kill -0 "$remote_pid" 2>/dev/null && remote_alive=yes

{
  echo "soak: ${minutes} min, loss $loss, telex-local exit $local_rc, telex-remote alive at end: $remote_alive"
  # Max RSS and least-squares slope after the warm-up, per daemon, in MiB and KiB/min. The last
  # 3 s are left out of the slope: telex-local is shutting down then and frees its buffers.
  end_t=$(tail -n 1 "$outdir/rss.csv" | cut -d, -f1)
  awk -F, -v w="$warmup_s" -v e="$((end_t - 3))" '
    NR == 1 { next }
    {
      for (c = 2; c <= 4; ++c) if ($c != "") { if ($c > mx[c]) mx[c] = $c }
      if ($1 >= w && $1 <= e) for (c = 2; c <= 4; ++c) if ($c != "") {
        n[c]++; sx[c] += $1; sy[c] += $c; sxx[c] += $1 * $1; sxy[c] += $1 * $c
        if (!(c in first)) first[c] = $c; last[c] = $c
      }
    }
    END {
      split("remote local proxy", name, " ")
      for (c = 2; c <= 4; ++c) {
        slope = "n/a"
        d = n[c] * sxx[c] - sx[c] * sx[c]
        if (n[c] > 2 && d > 0) slope = sprintf("%.1f", 60 * (n[c] * sxy[c] - sx[c] * sy[c]) / d)
        printf "%-6s max RSS %.1f MiB, after %d s warm-up: %s -> %s KiB, slope %s KiB/min (%d samples)\n",
          name[c-1], mx[c] / 1024, w, first[c], last[c], slope, n[c]
      }
    }' "$outdir/rss.csv"
  echo "telex-local summary: $(tail -n 1 "$outdir/local.out")"
  echo "proxy counters: $(tail -n 1 "$outdir/proxy.out")"
  echo "telex-local last stderr lines:"
  tail -n 3 "$outdir/local.err"
} | tee "$outdir/summary.txt"
exit "$local_rc"
