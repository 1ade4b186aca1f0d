#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Regenerates docs/images from the real desk frames (shared/data/real/desk: depth and colour of a
# PrimeSense-class sensor): both nodes on loopback, the remote playing the frames as depth and as
# both eyes' video, the station pressing the laptop lid with the scripted index finger (the
# `press` script) and writing the operator's view at the moment of contact with the Fig. 7 layout:
#   docs/images/desk_left.png, desk_right.png  each eye as the operator sees it
#   docs/images/desk_sbs.png                   both eyes side by side
#   docs/images/desk_fig7.png                  the right eye beside the normal map, touch vector
# Usage: tools/make_images.sh [OUT_DIR]  (default docs/images). Needs telex-remote and
# telex-local built (TELEX_BUILD_DIR, default build/); TELEX_DESK_DIR overrides where the frames
# are; extra station flags in TELEX_IMAGES_FLAGS (e.g. "--eye-size 1280x720").
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${TELEX_BUILD_DIR:-$root/build}/tools"
desk="${TELEX_DESK_DIR:-$root/../shared/data/real/desk}"
out="${1:-$root/docs/images}"
port="${TELEX_IMAGES_PORT:-7391}"

if [[ ! -f "$desk/desk_0_depth_mm.png" ]]; then
  echo "make_images: no desk frames in $desk (set TELEX_DESK_DIR)" >&2
  exit 2
fi
for b in telex-remote telex-local; do
  if [[ ! -x "$bin/$b" ]]; then
    echo "make_images: $bin/$b is not built (ninja -C build telex-remote telex-local)" >&2
    exit 2
  fi
done
mkdir -p "$out"
view="$(mktemp -d)"

"$bin/telex-remote" --listen "127.0.0.1:$port" \
  --source "files:$desk/desk_*_depth_mm.png,units=mm,fps=5,loop" \
  --stereo "files:$desk/desk_*_rgb.png,$desk/desk_*_rgb.png,fps=5,loop" \
  --duration 40 --no-stats &
remote=$!
trap 'kill -INT $remote 2>/dev/null; wait $remote 2>/dev/null; rm -rf "$view"' EXIT INT TERM

# The press script reaches the surface 3.1 s after it starts and holds 1 s: the view is written
# 3.6 s in, with the finger pressing. No head teleoperation: the frames are fixed.
# shellcheck disable=SC2086
"$bin/telex-local" --connect "127.0.0.1:$port" --hand script:press --haptics sim --no-head \
  --duration 6 --view "png:$view" --view-at 3.6 --view-layout fig7 --quiet \
  ${TELEX_IMAGES_FLAGS:-}

for name in left right sbs fig7; do
  if [[ ! -s "$view/$name.png" ]]; then
    echo "make_images: the station wrote no $name.png" >&2
    exit 1
  fi
  cp "$view/$name.png" "$out/desk_$name.png"
done
echo "make_images: wrote $out/desk_{left,right,sbs,fig7}.png"
