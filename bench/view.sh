#!/usr/bin/env bash
# `jointspace view` on large prints: G-code files of about SIZE MB (default 100) made by repeating the golden
# PrusaSlicer mini cube (arcs; each copy homes and starts over): on the Cartesian golden machine (no motor limits: a
# typical print), and centred on the polar golden machine with its bed limited to 5 rad/s and 200 rad/s² (the
# estimate plans three times, and the bed's limits hold most moves: nearly every segment is a limit hit, the worst
# case for merging). Prints the time and peak memory of `jointspace view`, the page's size, and the page's load in
# headless Chromium: the time from navigation until the page's script has drawn everything (its own
# `performance.now()`, written into the page as data-load-ms), for the layer view and the 3D view, and the browser's
# whole run (which includes writing out the page's tens of MB of DOM). Not part of `cargo test`.
# usage: bench/view.sh [SIZE_MB] [polar]   (needs ../shared and Debian's chromium; builds what it runs; `polar`: that
#        case only)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SHARED=$ROOT/../shared
SIZE_MB=${1:-100}
(cd "$ROOT" && cargo build --release -q -p cli)
JOINTSPACE=${CARGO_TARGET_DIR:-$ROOT/target}/release/jointspace
WORK=$(mktemp -d); trap 'rm -rf "$WORK"' EXIT

chromium_run() {
  local profile; profile=$(mktemp -d)
  chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking \
    --disable-component-update --disable-sync --enable-unsafe-swiftshader --use-angle=swiftshader \
    --user-data-dir="$profile" --window-size=1300,1000 "$@" 2>/dev/null
  rm -rf "$profile"
}

one_case() {  # name, case folder, config
  local name=$1 case=$2 config=$3
  local one copies
  one=$(stat -c %s "$case/input.gcode")
  copies=$(( SIZE_MB * 1000000 / one + 1 ))
  for _ in $(seq "$copies"); do cat "$case/input.gcode"; done > "$WORK/big.gcode"
  echo "== $name: $copies copies of $(basename "$case")/input.gcode, $(( $(stat -c %s "$WORK/big.gcode") / 1000000 )) MB"
  /usr/bin/time -f "view: %e s wall, %M KB peak memory" \
    "$JOINTSPACE" view -c "$config" "$WORK/big.gcode" -o "$WORK/big.html" 2>&1 | grep -v warning
  echo "page: $(( $(stat -c %s "$WORK/big.html") / 1000 )) kB"
  for view in layer 3d; do
    local start end dom
    start=$(date +%s.%N)
    dom=$(chromium_run --dump-dom "file://$WORK/big.html#view=$view" | grep -o 'data-ready="[a-z]*"\|data-load-ms="[0-9]*"' | tr '\n' ' ')
    end=$(date +%s.%N)
    echo "chromium, $view view: $dom; browser start to exit $(python3 -c "print(round($end - $start, 1))") s"
  done
}

if [ "${2:-}" != polar ]; then
  one_case "Cartesian, no motor limits" "$SHARED/golden/cartesian-prusa-minicube-arcs" \
    "$SHARED/golden/cartesian-prusa-minicube-arcs/printer.cfg"
fi
sed 's/^kinematics: polar$/kinematics: polar\nmax_angular_velocity: 5\nmax_angular_accel: 200/' \
  "$SHARED/golden/polar-prusa-minicube-arcs/printer.cfg" > "$WORK/polar.cfg"
one_case "polar, bed limited to 5 rad/s" "$SHARED/golden/polar-prusa-minicube-arcs" "$WORK/polar.cfg"
