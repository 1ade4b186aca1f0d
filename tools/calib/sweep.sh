#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Calibration accuracy over seeds: for each, `telex calibrate render` a board set with known
# answers, run `calibrate stereo` then `calibrate depth-eye` on the files, and print the errors
# against truth.json. Usage: tools/calib/sweep.sh [SEEDS...] (default 1-8); TELEX=path/to/telex,
# RENDER_FLAGS="--noise 6 --blur-px 1.5" for harsher images.
set -euo pipefail
T=${TELEX:-build/tools/telex}
seeds=("$@")
[ ${#seeds[@]} -eq 0 ] && seeds=(1 2 3 4 5 6 7 8)
for s in "${seeds[@]}"; do
  d=$(mktemp -d)
  trap 'rm -rf "$d"' EXIT
  # shellcheck disable=SC2086
  "$T" calibrate render --out "$d/b" --seed "$s" ${RENDER_FLAGS:-} >/dev/null
  "$T" calibrate stereo --left "$d/b/left_*.png" --right "$d/b/right_*.png" --board 9x6 \
    --square-mm 30 --out "$d/rig.json" --json >"$d/stereo.json"
  depth=$(python3 -c 'import json, sys; k = json.load(open(sys.argv[1]))["truth"]["depth"]
print(",".join(str(k[n]) for n in ("fx_px", "fy_px", "cx_px", "cy_px", "width", "height")))' \
    "$d/b/truth.json")
  "$T" calibrate depth-eye --ir "$d/b/ir_*.png" --right "$d/b/right_*.png" \
    --depth "$d/b/depth_*.png" --board 9x6 --square-mm 30 --rig "$d/rig.json" \
    --depth-intrinsics "$depth" --json >"$d/depth_eye.json"
  python3 - "$d" "$s" <<'PY'
import json, math, sys
d, seed = sys.argv[1], sys.argv[2]
truth = json.load(open(d + "/b/truth.json"))["truth"]
st = json.load(open(d + "/stereo.json"))
de = json.load(open(d + "/depth_eye.json"))
rig = json.load(open(d + "/rig.json"))
pc = lambda got, want: 100.0 * (got - want) / want
def angle_deg(a, b):
    trace = sum(a[i][j] * b[i][j] for i in range(3) for j in range(3))
    return math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0))))
eyes, x = truth["eyes"], truth["extrinsics"]
b_true = math.hypot(*x["right_eye_from_left_eye"]["translation_m"])
dt = x["right_eye_from_depth"]
print(f"seed {seed}: pairs {st['views_used']}/{st['views']}, RMS {st['rms_px']:.3f} px; "
      f"fx L {pc(st['left']['fx_px'], eyes['left']['fx_px']):+.3f}% "
      f"R {pc(st['right']['fx_px'], eyes['right']['fx_px']):+.3f}%; "
      f"fy L {pc(st['left']['fy_px'], eyes['left']['fy_px']):+.3f}% "
      f"R {pc(st['right']['fy_px'], eyes['right']['fy_px']):+.3f}%; "
      f"baseline {pc(st['baseline_m'], b_true):+.3f}% | depth-eye: "
      f"t off {1e3 * math.dist(de['translation_m'], dt['translation_m']):.2f} mm, "
      f"rotation off {angle_deg(rig['extrinsics']['right_eye_from_depth']['rotation'], dt['rotation']):.3f} deg, "
      f"residual {de['residual_mm']:.2f} mm")
PY
  rm -rf "$d"
  trap - EXIT
done
