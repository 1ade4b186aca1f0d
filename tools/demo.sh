#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Quick-start command 1: install what is missing, build, then run both nodes on loopback with the
# built-in synthetic room (depth and both eyes' video: a plank floor, plaster walls, a table with a
# book, a box, a mug and a ball) and a scripted hand that presses and strokes the book, printing fingertip
# forces live and writing the operator's view once a second to demo_view/ (TELEX_DEMO_VIEW=DIR
# elsewhere): the stereo pair left.png, right.png, sbs.png and the overview view.png. Ctrl-C stops
# both. Extra arguments go to telex-local (e.g. --hand script:press).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
t0=$SECONDS
# Only the two daemons and what they link: the tests build in tools/test.sh.
TELEX_BUILD_TARGETS="telex-remote telex-local" "$root/tools/build.sh"
echo "demo: built in $((SECONDS - t0)) s; both nodes start now" >&2
t_run=$SECONDS
bin="${TELEX_BUILD_DIR:-$root/build}/tools"
duration="${TELEX_DEMO_SECONDS:-20}"
port="${TELEX_DEMO_PORT:-7300}"
view="${TELEX_DEMO_VIEW:-$root/demo_view}"

"$bin/telex-remote" --listen "127.0.0.1:$port" --source synthetic:room --stereo synthetic:room \
  --duration $((duration + 5)) \
  --no-stats &
remote=$!
trap 'kill -INT $remote 2>/dev/null; wait $remote 2>/dev/null' EXIT INT TERM

# The station's defaults: it filters and builds normals only around the fingertips and the remote
# sends those tiles first, the lowest-latency path (docs/BENCHMARKS.md, "Defaults").
"$bin/telex-local" --connect "127.0.0.1:$port" --hand script:stroke --repeat --duration "$duration" \
  --haptics sim --print-forces 10 --view "png:$view" "$@"
echo "demo: ran $((SECONDS - t_run)) s; the operator's view is in $view/sbs.png (both eyes), left.png, right.png and view.png"
