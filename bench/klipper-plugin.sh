#!/usr/bin/env bash
# Wall time of Klipper-family hosts in batch mode with their own kinematics and with jointspace's plug-in, run
# alternately on the same files in one session, and the ratios (plug-in / built-in; 1.00 = as fast).
#   polar: ../shared/bench (228,920 moves) on Klipper: built-in polar vs jointspace_polar (centre_slowdown: klipper,
#          so both plan the same moves)
#   SCARA: the scara-fekt-cura-hex golden case on the FEKT-SCARA fork: its scara module vs jointspace_scara
# usage: bench/klipper-plugin.sh [ROUNDS]      (default 5; needs ../shared/klipper and a release build)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SHARED=$ROOT/../shared
ROUNDS=${1:-5}
export KLIP_DIR=${KLIP_DIR:-$ROOT/target/release/klipper-hosts}
"$SHARED/klipper/setup.sh" "$KLIP_DIR" >/dev/null
(cd "$ROOT" && cargo build --release -p klipper -q)
for tree in "$KLIP_DIR"/klipper "$KLIP_DIR"/kalico-fekt; do "$ROOT/klipper/install.sh" --host-dir "$tree" --no-build >/dev/null; done
WORK=$(mktemp -d); trap 'rm -rf "$WORK"' EXIT

sed 's/^kinematics: polar$/kinematics: jointspace_polar/; s/^max_angular_velocity: 5$/max_angular_velocity: 5\ncentre_slowdown: klipper/' \
  "$SHARED/bench/polar-bench.cfg" > "$WORK/polar.cfg"; printf '\n[jointspace]\n' >> "$WORK/polar.cfg"
HEX=$SHARED/golden/scara-fekt-cura-hex
sed 's/^kinematics: scara$/kinematics: jointspace_scara/; s/^max_z_velocity: .*/max_z_velocity: 300/; s/^max_z_accel: .*/max_z_accel: 3000/' \
  "$HEX/printer.cfg" > "$WORK/scara.cfg"; printf '\n[jointspace]\n' >> "$WORK/scara.cfg"
sed 's/^max_z_velocity: .*/max_z_velocity: 300/; s/^max_z_accel: .*/max_z_accel: 3000/' "$HEX/printer.cfg" > "$WORK/scara-builtin.cfg"

seconds() { # CFG GCODE HOST -> wall seconds of one batch run
  local start end
  start=$(date +%s.%N)
  "$SHARED/klipper/batch.sh" "$1" "$2" "$WORK/out" "$3" >/dev/null 2>&1
  end=$(date +%s.%N)
  awk -v a="$start" -v b="$end" 'BEGIN { print b - a }'
}
median() { tr ' ' '\n' | grep . | sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }

compare() { # NAME HOST BUILTIN_CFG PLUGIN_CFG GCODE
  local builtin="" plugin=""
  for _ in $(seq "$ROUNDS"); do
    builtin="$builtin $(seconds "$3" "$5" "$2")"
    plugin="$plugin $(seconds "$4" "$5" "$2")"
  done
  local b p
  b=$(echo "$builtin" | median); p=$(echo "$plugin" | median)
  printf '%-6s %-12s built-in %6.2f s  jointspace %6.2f s  ratio %.3f   (runs: built-in%s; plug-in%s)\n' \
    "$1" "$2" "$b" "$p" "$(awk -v p="$p" -v b="$b" 'BEGIN { print p / b }')" "$builtin" "$plugin"
}
echo "machine: $(nproc) cores, $(uname -m), $(date -u +%Y-%m-%dT%H:%MZ); klipper $(cat "$KLIP_DIR/klipper/.commit" | cut -c1-12), kalico-fekt $(cat "$KLIP_DIR/kalico-fekt/.commit" | cut -c1-12)"
compare polar klipper "$SHARED/bench/polar-bench.cfg" "$WORK/polar.cfg" "$SHARED/bench/polar-bench20.gcode"
compare scara kalico-fekt "$WORK/scara-builtin.cfg" "$WORK/scara.cfg" "$HEX/input.gcode"
