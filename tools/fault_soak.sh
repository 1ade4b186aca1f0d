#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# An hour of faults (issue 49): both daemons on loopback with a pre-shared key, the desk frames'
# depth and both eyes, a recording on a small tmpfs and the view written as pictures, while faults
# are injected on a schedule. Afterwards tools/fault_soak_report.py writes OUTDIR/report.md.
#
# Usage: tools/fault_soak.sh [MINUTES=60] [OUTDIR=build/fault_soak]
# Env: BUILD (build dir, default build), PORT_BASE (47500; six ports from it), GAP_S (40: seconds
#      between faults after the first round; the first round uses 15), REC_MB (1536: the tmpfs).
# Needs: root (to mount the tmpfs), socat (the TCP relay that can be stopped: apt-get install
# socat), Debian's python3-rosbag for the report, the desk frames in ../shared/data/real/desk.
#
# The faults, in order, each started while the hand is pressing (the NatNet simulator holds the
# index tip 2 cm into the desk):
#   link_loss      the TCP relay and the UDP proxy stopped (SIGSTOP) for 5 s: nothing passes
#   loss20         the UDP proxy restarted with 20 % loss for 30 s
#   remote_kill    telex-remote killed (SIGKILL), restarted 2 s later
#   natnet_silent  the NatNet server stopped (SIGSTOP) for 3 s
#   display_closed the display's UDP port closed (telex-sim-display ended) for 2 s, then reopened
#   station_stop   telex-local stopped (SIGSTOP) for 1 s
#   disk_full      the recording's tmpfs filled (once, after the first round)
set -euo pipefail

minutes=${1:-60}
outdir=${2:-build/fault_soak}
build=${BUILD:-build}
base=${PORT_BASE:-47500}
gap_s=${GAP_S:-40}
rec_mb=${REC_MB:-1536}
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
desk=${DESK:-$here/../../shared/data/real/desk}

die() {
  echo "fault_soak.sh: $*" >&2
  exit 2
}
[[ "$minutes" =~ ^[0-9]+$ ]] || die "MINUTES must be a whole number, got '$minutes'"
for b in telex-remote telex-local telex-sim-impair telex-sim-natnet telex-sim-display telex; do
  [[ -x "$build/tools/$b" ]] || die "$build/tools/$b not built (cmake --build $build --target $b)"
done
command -v socat >/dev/null || die "socat not found (apt-get install socat): it is the TCP relay"
[[ -f "$desk/desk_0_depth_mm.png" ]] || die "no desk frames in $desk (set DESK=...)"
[[ $(id -u) == 0 ]] || die "needs root to mount the recording's tmpfs"

port_remote=$base relay=$((base + 1)) udp_port=$((base + 2)) proxy=$((base + 3))
natnet=$((base + 4)) display=$((base + 5))
duration_s=$((minutes * 60))
mkdir -p "$outdir"
outdir=$(cd "$outdir" && pwd)
bin=$outdir/bin rec=$outdir/rec
# The binaries are copied: a rebuild during the hour does not change what runs (the remote is
# started again mid-soak).
rm -rf "$bin" "$outdir/view" && mkdir -p "$bin" "$rec" "$outdir/view"
for b in telex-remote telex-local telex-sim-impair telex-sim-natnet telex-sim-display telex; do
  cp "$build/tools/$b" "$bin/"
done
mountpoint -q "$rec" && umount "$rec"
mount -t tmpfs -o "size=${rec_mb}m" tmpfs "$rec"
rm -f "$outdir/key" && "$bin/telex" keygen "$outdir/key" >/dev/null
echo "fault,start_ns,end_ns,pressing_before" >"$outdir/faults.csv"

pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -CONT -- "-$p" 2>/dev/null || kill -CONT "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done
  sleep 2
  for p in "${pids[@]}"; do kill -KILL -- "-$p" 2>/dev/null || kill -KILL "$p" 2>/dev/null || true; done
  if mountpoint -q "$rec"; then umount "$rec" 2>/dev/null || true; fi
}
trap cleanup EXIT
# CLOCK_REALTIME in ns without a fork (bash's EPOCHREALTIME, microseconds): `$(date +%s%N)`
# forks, and at load its stamp came 1.5 ms (up to 7 ms) before the next statement ran, which the
# fault's "to zero" would then include. The display simulator's arrivals are on the same clock.
stamp() { printf -v "$1" '%s000' "${EPOCHREALTIME/./}"; }
now_ns() { local t; stamp t; echo "$t"; }

start_remote() {
  "$bin/telex-remote" --listen "127.0.0.1:$port_remote" --psk "$outdir/key" \
    --source "files:$desk/desk_*_depth_mm.png,fps=30,loop" \
    --stereo "files:$desk/desk_*_rgb.png,$desk/desk_*_rgb.png,fps=30,loop" --head sim --no-stats \
    >>"$outdir/remote.out" 2>>"$outdir/remote.err" &
  remote_pid=$!
  pids+=("$remote_pid")
  echo "$(now_ns),$remote_pid" >>"$outdir/remote_pids.csv"
}
start_proxy() {  # [LOSS] [DURATION_S]
  "$bin/telex-sim-impair" --listen "127.0.0.1:$proxy" --forward "127.0.0.1:$udp_port" \
    --loss "${1:-0}" --seed "$RANDOM" --duration "${2:-0}" >>"$outdir/proxy.out" \
    2>>"$outdir/proxy.err" &
  proxy_pid=$!
  pids+=("$proxy_pid")
}
start_display() {
  "$bin/telex-sim-display" --listen "127.0.0.1:$display" --csv "$outdir/display.csv" --append \
    2>>"$outdir/display.err" &
  display_pid=$!
  pids+=("$display_pid")
}
# The relay runs in its own process group: SIGSTOP to the group stops every forked connection.
setsid socat "TCP-LISTEN:$relay,bind=127.0.0.1,reuseaddr,fork" "TCP:127.0.0.1:$port_remote" \
  2>>"$outdir/relay.err" &
relay_pid=$!
pids+=("$relay_pid")
"$bin/telex-sim-natnet" --command-port "$natnet" --duration 0 --motion hold --reach 0.85 \
  2>>"$outdir/natnet.err" &
natnet_pid=$!
pids+=("$natnet_pid")
rm -f "$outdir/display.csv"
start_display
start_remote
start_proxy
sleep 1
"$bin/telex-local" --connect "127.0.0.1:$relay" --psk "$outdir/key" --udp-port "$udp_port" \
  --udp-announce-port "$proxy" --hand "natnet:127.0.0.1,unicast,cmd=$natnet" \
  --haptics "udp:127.0.0.1:$display" --view "png:$outdir/view" --record "$rec/session.bag" \
  --duration "$duration_s" --json-summary --quiet >"$outdir/local.out" 2>"$outdir/local.err" &
local_pid=$!
pids+=("$local_pid")
start_s=$(date +%s)

# Resident memory (KiB) and open descriptors of the station and the remote, once a second.
sample() {
  local p=$1
  echo "$(awk '/^VmRSS:/ { print $2 }' "/proc/$p/status" 2>/dev/null),$(find "/proc/$p/fd" -mindepth 1 -maxdepth 1 2>/dev/null | wc -l)"
}
(
  echo "t_s,local_kb,local_fds,remote_pid,remote_kb,remote_fds"
  while kill -0 "$local_pid" 2>/dev/null; do
    rp=$(tail -n 1 "$outdir/remote_pids.csv" | cut -d, -f2)
    echo "$(($(date +%s) - start_s)),$(sample "$local_pid"),$rp,$(sample "$rp")"
    sleep 1
  done
) >"$outdir/resources.csv" &
pids+=("$!")

pressing() {  # the display's last commands hold force
  tail -n 20 "$outdir/display.csv" 2>/dev/null | awk -F, '$3 > 0.3 { n++ } END { exit !(n >= 10) }'
}
wait_for_press() {
  local i
  for ((i = 0; i < 150; ++i)); do
    pressing && return 0
    sleep 0.1
  done
  return 1
}
left_s() { echo $((duration_s - ($(date +%s) - start_s))); }
fault() {  # NAME then the action; the action sets fault_end_ns
  local name=$1 before=yes
  shift
  wait_for_press || before=no
  stamp fault_start_ns
  "$@"
  echo "$name,$fault_start_ns,$fault_end_ns,$before" >>"$outdir/faults.csv"
  echo "$(date +%T) $name (pressing before: $before)" >&2
}
link_loss() {
  kill -STOP -- "-$relay_pid"
  kill -STOP "$proxy_pid"
  sleep 5
  stamp fault_end_ns
  kill -CONT -- "-$relay_pid"
  kill -CONT "$proxy_pid"
}
loss20() {
  kill -INT "$proxy_pid"
  wait "$proxy_pid" 2>/dev/null || true
  start_proxy 0.2 30
  wait "$proxy_pid" 2>/dev/null || true
  stamp fault_end_ns
  start_proxy
}
remote_kill() {
  kill -KILL "$remote_pid"
  wait "$remote_pid" 2>/dev/null || true
  sleep 2
  stamp fault_end_ns
  start_remote
}
stop_for() {  # PID SECONDS: the process stopped (SIGSTOP), then resumed
  kill -STOP "$1"
  sleep "$2"
  stamp fault_end_ns
  kill -CONT "$1"
}
natnet_silent() { stop_for "$natnet_pid" 3; }
display_closed() {
  kill -INT "$display_pid"
  wait "$display_pid" 2>/dev/null || true
  sleep 2
  stamp fault_end_ns
  start_display
}
station_stop() { stop_for "$local_pid" 1; }
disk_full() {
  dd if=/dev/zero of="$rec/filler" bs=1M status=none 2>/dev/null || true
  stamp fault_end_ns
}

sleep 20
round=0
faults=(link_loss loss20 remote_kill natnet_silent display_closed station_stop)
while kill -0 "$local_pid" 2>/dev/null; do
  gap=$gap_s
  ((round == 0)) && gap=15
  for f in "${faults[@]}"; do
    (($(left_s) > gap + 45)) || break 2
    kill -0 "$local_pid" 2>/dev/null || break 2
    fault "$f" "$f"
    sleep "$gap"
  done
  if ((round == 0)); then
    fault disk_full disk_full
    sleep "$gap"
  fi
  round=$((round + 1))
done
echo "$(date +%T) schedule done after $round round(s); waiting for the station's end" >&2
local_rc=0
wait "$local_pid" || local_rc=$?
echo "$local_rc" >"$outdir/local.rc"
kill -INT "$display_pid" 2>/dev/null || true
wait "$display_pid" 2>/dev/null || true
cp "$rec/session.bag" "$outdir/session.bag" 2>/dev/null || true
python3=/usr/bin/python3
"$python3" "$here/fault_soak_report.py" "$outdir" | tee "$outdir/report.md"
