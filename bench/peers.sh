#!/usr/bin/env bash
# Same-run speed ratios against the peers: each pair runs alternately on the same files in one session, and the
# medians and their ratio are printed (absolute times on a shared machine drift; the ratio is what to read).
#   polar end to end   jointspace run            vs  Klipper's polar, batch mode   (../shared/bench, 228,920 moves)
#   SCARA end to end   jointspace run, one core  vs  the FEKT-SCARA fork, one core (a Slic3r benchy, arcs, moved
#                                                    into the FEKT arm's workspace)
#   estimate           jointspace estimate      vs  klipper_estimator estimate (../shared/peers, MIT): the same
#                                                    Cartesian files (PrusaSlicer vase + plant sign, 5 copies, 4.3 MB)
#   plug-in overhead   Klipper + jointspace_polar (centre_slowdown: klipper: the same plan) vs Klipper's polar on
#                      the bench; the FEKT fork + jointspace_scara vs its own SCARA module on the benchy
# usage: bench/peers.sh [ROUNDS]      (default 3; needs ../shared; builds what it runs)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SHARED=$ROOT/../shared
ROUNDS=${1:-3}
export KLIP_DIR=${KLIP_DIR:-$ROOT/target/release/klipper-hosts}
"$SHARED/klipper/setup.sh" "$KLIP_DIR" >/dev/null
(cd "$ROOT" && cargo build --release -q -p cli -p klipper)
for tree in "$KLIP_DIR"/klipper "$KLIP_DIR"/kalico-fekt; do "$ROOT/klipper/install.sh" --host-dir "$tree" --no-build >/dev/null; done
JOINTSPACE=$ROOT/target/release/jointspace
WORK=$(mktemp -d); trap 'rm -rf "$WORK"' EXIT

# The polar bench, and the same machine with the plug-in planning as Klipper does.
BENCH_CFG=$SHARED/bench/polar-bench.cfg BENCH=$SHARED/bench/polar-bench20.gcode
sed 's/^kinematics: polar$/kinematics: jointspace_polar/; s/^max_angular_velocity: 5$/max_angular_velocity: 5\ncentre_slowdown: klipper/' \
  "$BENCH_CFG" > "$WORK/polar-plugin.cfg"; printf '\n[jointspace]\n' >> "$WORK/polar-plugin.cfg"
# The FEKT arm (the scara-fekt-cura-hex config: Z limits raised, which the fork ignores anyway) and a benchy moved
# into its workspace: XY shifted to centre the hull at (0, 130), homing replaced by the pose Klipper's tests use.
HEX_CFG=$SHARED/golden/scara-fekt-cura-hex/printer.cfg
sed 's/^max_z_velocity: .*/max_z_velocity: 300/; s/^max_z_accel: .*/max_z_accel: 3000/' "$HEX_CFG" > "$WORK/scara.cfg"
sed 's/^kinematics: scara$/kinematics: jointspace_scara/' "$WORK/scara.cfg" > "$WORK/scara-plugin.cfg"
printf '\n[jointspace]\n' >> "$WORK/scara-plugin.cfg"
python3 - "$SHARED/corpus/slic3r-prusa-1.33_benchy_arcwelder.gcode" "$WORK/benchy.gcode" <<'PY'
import re, sys
dx, dy = -97.807, 30.012
out = []
for line in open(sys.argv[1]):
    if line.startswith("G28 X0 Y200"):
        continue
    if line.startswith("G28"):
        out.append("SET_KINEMATIC_POSITION X=0 Y=130 Z=0.5\n")
        continue
    if re.match(r"G[0-3][ ;\n]", line):
        line = re.sub(r"X(-?[\d.]+)", lambda m: "X%.3f" % (float(m.group(1)) + dx), line)
        line = re.sub(r"Y(-?[\d.]+)", lambda m: "Y%.3f" % (float(m.group(1)) + dy), line)
    out.append(line)
open(sys.argv[2], "w").write("".join(out))
PY

# klipper_estimator (timed with --format json: its human output did not finish on these files in 10 minutes),
# built once from its pinned source (crates from the registry), with the Cartesian golden machine's
# limits in its own format (extruder limits as Klipper derives them: 5 mm² over 3.5 mm filament of max_velocity/accel).
KE_DIR=$ROOT/target/peers/klipper_estimator
if [ ! -x "$KE_DIR/target/release/klipper_estimator" ]; then
  mkdir -p "$ROOT/target/peers" && tar xzf "$SHARED/peers/klipper_estimator.tar.gz" -C "$ROOT/target/peers"
  (cd "$KE_DIR" && cargo build --release -q)
fi
KE=$KE_DIR/target/release/klipper_estimator
CART_CFG=$SHARED/golden/cartesian-prusa-minicube-arcs/printer.cfg
cat > "$WORK/ke.json" <<'JSON'
{ "max_velocity": 500, "max_acceleration": 3000, "minimum_cruise_ratio": 0.5, "square_corner_velocity": 5,
  "instant_corner_velocity": 1, "mm_per_arc_segment": 1.0,
  "move_checkers": [ {"axis_limiter": {"axis": [0, 0, 1], "max_velocity": 25, "max_accel": 30}},
                     {"extruder_limiter": {"max_velocity": 259.81, "max_accel": 1559.1}} ] }
JSON
for _ in 1 2 3 4 5; do
  cat "$SHARED/corpus/prusaslicer-2.7.4_spiral-vase.gcode" "$SHARED/corpus/prusaslicer-2.7.4_plant-sign_arcs.gcode"
done > "$WORK/cartesian.gcode"

seconds() { # command... -> wall seconds
  local start end
  start=$(date +%s.%N)
  "$@" >/dev/null 2>&1
  end=$(date +%s.%N)
  awk -v a="$start" -v b="$end" 'BEGIN { print b - a }'
}
batch() { "$SHARED/klipper/batch.sh" "$1" "$2" "$WORK/out" "$3"; }
median() { tr ' ' '\n' | grep . | sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }
# The fastest run: another tenant's load only ever adds time, so the fastest runs' ratio is the steadier reading on a
# shared machine (jointspace's two threads lose more to a busy second core than a one-threaded host does).
fastest() { tr ' ' '\n' | grep . | sort -g | head -1; }

# compare NAME "A label" "B label" -- command A -- command B: B/A is printed as "A is N× faster" when >1
compare() {
  local name=$1 label_a=$2 label_b=$3; shift 4
  local a=() b=() in_b=0
  for w in "$@"; do if [ "$w" = "--" ]; then in_b=1; elif [ $in_b = 0 ]; then a+=("$w"); else b+=("$w"); fi; done
  # Both must succeed (a failing run would time nothing).
  "${a[@]}" >/dev/null 2>"$WORK/err" || { echo "$name: ${a[*]} failed:"; tail -5 "$WORK/err"; exit 1; }
  "${b[@]}" >/dev/null 2>"$WORK/err" || { echo "$name: ${b[*]} failed:"; tail -5 "$WORK/err"; exit 1; }
  local ta="" tb=""
  for _ in $(seq "$ROUNDS"); do
    ta="$ta $(seconds "${a[@]}")"
    tb="$tb $(seconds "${b[@]}")"
  done
  local ma mb fa fb
  ma=$(echo "$ta" | median); mb=$(echo "$tb" | median)
  fa=$(echo "$ta" | fastest); fb=$(echo "$tb" | fastest)
  printf '%-22s %s %7.3f s | %s %7.3f s | ratio %s/%s = %.3f (fastest runs: %.3f)\n' "$name" "$label_a" "$ma" \
    "$label_b" "$mb" "$label_b" "$label_a" "$(awk -v a="$ma" -v b="$mb" 'BEGIN { print b / a }')" \
    "$(awk -v a="$fa" -v b="$fb" 'BEGIN { print b / a }')"
  printf '%-22s   runs: %s:%s; %s:%s\n' "" "$label_a" "$ta" "$label_b" "$tb"
}

echo "machine: $(nproc) cores, $(uname -m), $(date -u +%Y-%m-%dT%H:%MZ); jointspace $(git -C "$ROOT" rev-parse --short HEAD)," \
  "klipper $(cut -c1-12 "$KLIP_DIR/klipper/.commit"), kalico-fekt $(cut -c1-12 "$KLIP_DIR/kalico-fekt/.commit")"
compare "polar end to end" jointspace klipper -- "$JOINTSPACE" run -c "$BENCH_CFG" "$BENCH" -- batch "$BENCH_CFG" "$BENCH" klipper
compare "SCARA end to end 1core" jointspace fekt -- taskset -c 0 "$JOINTSPACE" run -c "$WORK/scara.cfg" "$WORK/benchy.gcode" \
  -- taskset -c 0 "$SHARED/klipper/batch.sh" "$WORK/scara.cfg" "$WORK/benchy.gcode" "$WORK/out" kalico-fekt
compare "estimate, Cartesian" jointspace klipper_estimator -- "$JOINTSPACE" estimate -c "$CART_CFG" "$WORK/cartesian.gcode" \
  -- "$KE" --config_file "$WORK/ke.json" estimate --format json "$WORK/cartesian.gcode"
printf '%-22s   planned: jointspace %s s, klipper_estimator %s s\n' "" \
  "$("$JOINTSPACE" estimate --json -c "$CART_CFG" "$WORK/cartesian.gcode" 2>/dev/null | python3 -c 'import json,sys; print(round(json.load(sys.stdin)["total"], 3))')" \
  "$("$KE" --config_file "$WORK/ke.json" estimate --format json "$WORK/cartesian.gcode" | python3 -c 'import json,sys; d=json.load(sys.stdin); print(round(sum(s["total_time"] for s in d["sequences"]), 3))')"
compare "plug-in, polar" builtin plugin -- batch "$BENCH_CFG" "$BENCH" klipper -- batch "$WORK/polar-plugin.cfg" "$BENCH" klipper
compare "plug-in, SCARA" builtin plugin -- batch "$WORK/scara.cfg" "$WORK/benchy.gcode" kalico-fekt \
  -- batch "$WORK/scara-plugin.cfg" "$WORK/benchy.gcode" kalico-fekt
