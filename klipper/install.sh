#!/usr/bin/env bash
# Install jointspace's kinematics (jointspace_polar, jointspace_scara) into a Klipper or Kalico tree.
# usage: klipper/install.sh [--host-dir DIR] [--uninstall] [--no-build]
#   --host-dir DIR  the Klipper or Kalico checkout (default: ~/klipper)
#   --uninstall     remove what install put there (the tree is left as it was)
#   --no-build      skip `cargo build --release -p klipper` (the library must already be built)
# Klipper: klippy/extras/jointspace.py and the jointspace_*.py modules it loads are symlinks to this folder's files,
# listed in the tree's .git/info/exclude so Moonraker does not report the repository as dirty. Kalico:
# klippy/plugins/.
# The module finds libjointspace_klipper.so in this repository's target/release/.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/.." && pwd)
HOST_DIR=$HOME/klipper
UNINSTALL=0
BUILD=1
while [ $# -gt 0 ]; do
  case "$1" in
    --host-dir) HOST_DIR=${2:?--host-dir needs a directory}; shift 2 ;;
    --uninstall) UNINSTALL=1; shift ;;
    --no-build) BUILD=0; shift ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) echo "install.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -f "$HOST_DIR/klippy/klippy.py" ] || { echo "install.sh: $HOST_DIR is not a Klipper or Kalico tree (no klippy/klippy.py)" >&2; exit 2; }
HOST_DIR=$(cd "$HOST_DIR" && pwd)
if [ -d "$HOST_DIR/klippy/plugins" ]; then DEST=klippy/plugins; else DEST=klippy/extras; fi
# The modules Klipper loads: jointspace.py (from [jointspace]) and the helpers it loads from beside its real path
# (linked too, so the host's folder shows the whole plug-in, and uninstall finds every link it made).
MODULES=(jointspace.py jointspace_library.py jointspace_kinematics.py jointspace_splitter.py jointspace_commands.py
         jointspace_scan.py)
EXCLUDE_LINES=()
for module in "${MODULES[@]}"; do
  EXCLUDE_LINES+=("$DEST/$module" "$DEST/__pycache__/${module%.py}.*")
done
# The kinematics names, for a printer.cfg without [jointspace]: a clear error saying to add it (with the section,
# jointspace.py registers the real kinematics first and these files are never imported).
KINEMATICS=(jointspace_polar.py jointspace_scara.py)
for module in "${KINEMATICS[@]}"; do
  EXCLUDE_LINES+=("klippy/kinematics/$module" "klippy/kinematics/__pycache__/${module%.py}.*")
done

exclude_file() {
  # The tree's own exclude list, if it is a git checkout (a worktree's .git is a file naming the real one).
  git -C "$HOST_DIR" rev-parse --git-path info/exclude 2>/dev/null | sed "s|^\([^/]\)|$HOST_DIR/\1|"
}

if [ $UNINSTALL = 1 ]; then
  for module in "${MODULES[@]}"; do
    rm -f "$HOST_DIR/$DEST/$module" "$HOST_DIR/$DEST/__pycache__/${module%.py}".*
  done
  rmdir "$HOST_DIR/$DEST/__pycache__" 2>/dev/null || true
  for module in "${KINEMATICS[@]}"; do
    rm -f "$HOST_DIR/klippy/kinematics/$module" "$HOST_DIR/klippy/kinematics/__pycache__/${module%.py}".*
  done
  if ex=$(exclude_file) && [ -f "$ex" ]; then
    for line in "${EXCLUDE_LINES[@]}"; do
      grep -vxF -- "$line" "$ex" > "$ex.tmp" || true
      mv "$ex.tmp" "$ex"
    done
  fi
  echo "jointspace removed from $HOST_DIR"
  exit 0
fi

if [ $BUILD = 1 ]; then
  (cd "$REPO" && cargo build --release -p klipper)
fi
LIBRARY=${CARGO_TARGET_DIR:-$REPO/target}/release/libjointspace_klipper.so
[ -f "$LIBRARY" ] || { echo "install.sh: $LIBRARY is missing (run without --no-build)" >&2; exit 1; }
if [ "$(realpath "$LIBRARY")" != "$(realpath -m "$REPO/target/release/libjointspace_klipper.so")" ]; then
  echo "note: the library is outside this repository's target/: add 'library: $LIBRARY' to [jointspace]"
fi
for module in "${MODULES[@]}"; do
  ln -sfn "$HERE/$module" "$HOST_DIR/$DEST/$module"
done
for module in "${KINEMATICS[@]}"; do
  ln -sfn "$HERE/jointspace_missing_section.py" "$HOST_DIR/klippy/kinematics/$module"
done
if ex=$(exclude_file); then
  mkdir -p "$(dirname "$ex")"
  touch "$ex"
  for line in "${EXCLUDE_LINES[@]}"; do
    grep -qxF -- "$line" "$ex" || echo "$line" >> "$ex"
  done
fi
echo "jointspace installed into $HOST_DIR/$DEST; add [jointspace] to printer.cfg and restart Klipper"
