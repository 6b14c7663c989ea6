#!/usr/bin/env bash
# Install jointspace's kinematics (jointspace_polar, jointspace_scara) into a Klipper or Kalico tree.
# usage: klipper/install.sh [--host-dir DIR] [--uninstall] [--no-build]
#   --host-dir DIR  the Klipper or Kalico checkout (default: ~/klipper)
#   --uninstall     remove what install put there: links to this folder's files, and its block in the exclude list
#   --no-build      skip `cargo build --release -p klipper` (the library must already be built)
# Klipper: klippy/extras/jointspace.py and the jointspace_*.py modules it loads are symlinks to this folder's files,
# listed in a marked block of the tree's own .git/info/exclude so Moonraker does not report the repository as dirty
# (only when DIR is the top level of its own git repository). Kalico: klippy/plugins/. A file of the same name that is
# not a link to this folder is never replaced or removed.
# The module finds libjointspace_klipper.so in this repository's target/release/.
set -euo pipefail
HERE=$(cd -- "$(dirname -- "$0")" && pwd -P)
REPO=$(cd -- "$HERE/.." && pwd -P)
HOST_DIR=$HOME/klipper
UNINSTALL=0
BUILD=1
while [ $# -gt 0 ]; do
  case "$1" in
    --host-dir) HOST_DIR=${2:?--host-dir needs a directory}; shift 2 ;;
    --uninstall) UNINSTALL=1; shift ;;
    --no-build) BUILD=0; shift ;;
    -h|--help) sed -n '2,11p' -- "$0"; exit 0 ;;
    *) printf 'install.sh: unknown argument %s (see --help)\n' "$1" >&2; exit 2 ;;
  esac
done
if [ ! -f "$HOST_DIR/klippy/klippy.py" ]; then
  printf 'install.sh: %s is not a Klipper or Kalico tree (no klippy/klippy.py)\n' "$HOST_DIR" >&2
  exit 2
fi
HOST_DIR=$(cd -- "$HOST_DIR" && pwd -P)
if [ -d "$HOST_DIR/klippy/plugins" ]; then DEST=klippy/plugins; else DEST=klippy/extras; fi
# The modules Klipper loads: jointspace.py (from [jointspace]) and the helpers it loads from beside its real path
# (linked too, so the host's folder shows the whole plug-in, and uninstall finds every link it made).
MODULES=(jointspace.py jointspace_library.py jointspace_kinematics.py jointspace_splitter.py jointspace_commands.py
         jointspace_scan.py)
# The kinematics names, for a printer.cfg without [jointspace]: a clear error saying to add it (with the section,
# jointspace.py registers the real kinematics first and these files are never imported).
KINEMATICS=(jointspace_polar.py jointspace_scara.py)
# LINKS[i] in the host tree links to TARGETS[i] in this folder.
LINKS=()
TARGETS=()
for module in "${MODULES[@]}"; do
  LINKS+=("$DEST/$module"); TARGETS+=("$HERE/$module")
done
for module in "${KINEMATICS[@]}"; do
  LINKS+=("klippy/kinematics/$module"); TARGETS+=("$HERE/jointspace_missing_section.py")
done
EXCLUDE_BEGIN="# jointspace (klipper/install.sh): begin"
EXCLUDE_END="# jointspace (klipper/install.sh): end"

is_ours() {
  # $1 (in the host tree) is a link to $2 (this folder's file): only such a file is install's to replace or remove.
  [ -L "$1" ] && [ "$(readlink -f -- "$1")" = "$(readlink -f -- "$2")" ]
}

own_exclude_file() {
  # The exclude list of the host tree's own repository (a worktree's .git is a file naming the real one). None
  # unless the tree is the top level of its repository: a tree inside another repository is not that repository's
  # to ignore files for.
  local top path
  top=$(git -C "$HOST_DIR" rev-parse --show-toplevel 2>/dev/null) || return 1
  [ "$top" = "$HOST_DIR" ] || return 1
  path=$(git -C "$HOST_DIR" rev-parse --git-path info/exclude 2>/dev/null) || return 1
  case $path in
    /*) printf '%s\n' "$path" ;;
    *) printf '%s\n' "$HOST_DIR/$path" ;;
  esac
}

exclude_lines() {
  # Our exclude lines, each prefixed by $1 ("/": anchored at the tree's top; "": as earlier versions wrote them).
  local link
  for link in "${LINKS[@]}"; do
    printf '%s%s\n%s%s/__pycache__/%s.*\n' "$1" "$link" "$1" "$(dirname -- "$link")" "$(basename -- "$link" .py)"
  done
}

without_our_block() {
  # The exclude list on stdin, without the block install wrote, nor the unmarked lines earlier versions wrote (the
  # markers and lines are fixed text, never a path).
  awk -v begin="$EXCLUDE_BEGIN" -v end="$EXCLUDE_END" -v legacy="$(exclude_lines "")" '
    BEGIN { n = split(legacy, lines, "\n"); for (i = 1; i <= n; i++) old[lines[i]] = 1 }
    $0 == begin { inside = 1; next }
    $0 == end { inside = 0; next }
    !inside && !($0 in old) { print }'
}

our_block() {
  printf '%s\n' "$EXCLUDE_BEGIN"
  exclude_lines /
  printf '%s\n' "$EXCLUDE_END"
}

rewrite_exclude() {
  # $1: "add" or "remove" our block, in the host's own exclude list only.
  local ex
  if ! ex=$(own_exclude_file); then
    printf 'note: %s is not the top level of its own git repository: no exclude list edited\n' "$HOST_DIR"
    return 0
  fi
  mkdir -p -- "$(dirname -- "$ex")"
  touch -- "$ex"
  { without_our_block < "$ex"; if [ "$1" = add ]; then our_block; fi; } > "$ex.jointspace-tmp"
  mv -f -- "$ex.jointspace-tmp" "$ex"
}

uninstall() {
  local i link
  for i in "${!LINKS[@]}"; do
    link=$HOST_DIR/${LINKS[$i]}
    if is_ours "$link" "${TARGETS[$i]}"; then
      rm -f -- "$link" "$(dirname -- "$link")/__pycache__/$(basename -- "$link" .py)".*
      rmdir -- "$(dirname -- "$link")/__pycache__" 2>/dev/null || true
    elif [ -e "$link" ] || [ -L "$link" ]; then
      printf 'note: left %s: not a link to this plug-in\n' "$link"
    fi
  done
  rewrite_exclude remove
  printf 'jointspace removed from %s\n' "$HOST_DIR"
}

check_nothing_foreign() {
  # Before any link is made: a file in the way that is not ours stays, and install stops.
  local i link
  for i in "${!LINKS[@]}"; do
    link=$HOST_DIR/${LINKS[$i]}
    if { [ -e "$link" ] || [ -L "$link" ]; } && ! is_ours "$link" "${TARGETS[$i]}"; then
      printf 'install.sh: %s exists and is not a link to this plug-in: move it away (or uninstall what put it there) and run again\n' "$link" >&2
      exit 1
    fi
  done
}

install() {
  local i library
  if [ $BUILD = 1 ]; then
    (cd -- "$REPO" && cargo build --release -p klipper)
  fi
  library=${CARGO_TARGET_DIR:-$REPO/target}/release/libjointspace_klipper.so
  if [ ! -f "$library" ]; then
    printf 'install.sh: %s is missing (run without --no-build)\n' "$library" >&2
    exit 1
  fi
  if [ "$(realpath -- "$library")" != "$(realpath -m -- "$REPO/target/release/libjointspace_klipper.so")" ]; then
    printf "note: the library is outside this repository's target/: add 'library: %s' to [jointspace]\n" "$library"
  fi
  check_nothing_foreign
  for i in "${!LINKS[@]}"; do
    ln -sfn -- "${TARGETS[$i]}" "$HOST_DIR/${LINKS[$i]}"
  done
  rewrite_exclude add
  printf 'jointspace installed into %s/%s; add [jointspace] to printer.cfg and restart Klipper\n' "$HOST_DIR" "$DEST"
}

if [ $UNINSTALL = 1 ]; then uninstall; else install; fi
