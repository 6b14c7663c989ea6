#!/usr/bin/env bash
# Install jointspace's kinematics (jointspace_polar, jointspace_scara, jointspace_fivebar) into a Klipper or Kalico
# host.
# usage: klipper/install.sh [--host-dir DIR] [--venv DIR] [--wheel PATH] [--uninstall]
#        klipper/install.sh --dev [--no-build] [--host-dir DIR] [--uninstall]
#   --host-dir DIR  the Klipper or Kalico checkout (default: ~/klipper)
#   --venv DIR      the host's Python virtualenv (default: ~/klippy-env)
#   --wheel PATH    install from this wheel file, or from the folder of wheels PATH (the one that fits this host),
#                   instead of from the package index (PyPI)
#   --uninstall     remove what install put there: the package, the loader, and its block in the exclude list
#   --dev           developer mode, from this source tree: build the library (cargo build --release -p klipper) and
#                   link the plug-in's modules into the host tree instead of installing the package
#   --no-build      developer mode without the build (the library must already be built)
# Package mode: pip installs jointspace-klipper (the Python modules and libjointspace_klipper.so) into the
# virtualenv, then copies its loader to klippy/extras/jointspace.py (Kalico: klippy/plugins/, never both) and the
# stand-ins to klippy/kinematics/jointspace_{polar,scara,fivebar}.py. The files install puts into the host tree are
# listed in a marked block of the tree's own .git/info/exclude so Moonraker does not report the repository as dirty
# (only when DIR is the top level of its own git repository). A file of the same name that install did not put there (not a
# link to this folder, no install.sh marker line) is never replaced or removed.
set -euo pipefail
HERE=$(cd -- "$(dirname -- "$0")" && pwd -P)
REPO=$(cd -- "$HERE/.." && pwd -P)
PLUGIN=$HERE/jointspace_klipper
HOST_DIR=$HOME/klipper
VENV=$HOME/klippy-env
WHEEL=
UNINSTALL=0
DEV=0
BUILD=1
while [ $# -gt 0 ]; do
  case "$1" in
    --host-dir) HOST_DIR=${2:?--host-dir needs a directory}; shift 2 ;;
    --venv) VENV=${2:?--venv needs a directory}; shift 2 ;;
    --wheel) WHEEL=${2:?--wheel needs a wheel file or a folder of wheels}; shift 2 ;;
    --uninstall) UNINSTALL=1; shift ;;
    --dev) DEV=1; shift ;;
    --no-build) DEV=1; BUILD=0; shift ;;
    -h|--help) sed -n '2,18p' -- "$0"; exit 0 ;;
    *) printf 'install.sh: unknown argument %s (see --help)\n' "$1" >&2; exit 2 ;;
  esac
done
if [ ! -f "$HOST_DIR/klippy/klippy.py" ]; then
  printf 'install.sh: %s is not a Klipper or Kalico tree (no klippy/klippy.py)\n' "$HOST_DIR" >&2
  exit 2
fi
HOST_DIR=$(cd -- "$HOST_DIR" && pwd -P)
# Kalico loads klippy/plugins/ as klippy/extras/ and refuses to start when both hold a module of the same name.
if [ -d "$HOST_DIR/klippy/plugins" ]; then DEST=klippy/plugins; OTHER=klippy/extras
else DEST=klippy/extras; OTHER=; fi
PACKAGE=jointspace-klipper
# The oldest Python the package supports (pyproject.toml's requires-python).
MIN_PYTHON=3.8
# The line that marks a file install copied into the host tree (the loader, the stand-ins).
MARKER="# jointspace-klipper: written by install.sh"
# The modules Klipper loads: jointspace.py (from [jointspace]; the loader in package mode) and, in developer mode,
# the helpers it loads from beside its real path (linked too, so uninstall finds every link it made).
MODULES=(jointspace.py jointspace_library.py jointspace_kinematics.py jointspace_splitter.py jointspace_commands.py
         jointspace_scan.py)
# The kinematics names, for a printer.cfg without [jointspace]: a clear error saying to add it (with the section,
# jointspace.py registers the real kinematics first and these files are never imported).
KINEMATICS=(jointspace_polar.py jointspace_scara.py jointspace_fivebar.py)
# LINKS[i] in the host tree links to (developer mode) or is a copy of SOURCES[i].
LINKS=()
SOURCES=()
for module in "${MODULES[@]}"; do
  LINKS+=("$DEST/$module"); SOURCES+=("$PLUGIN/$module")
done
for module in "${KINEMATICS[@]}"; do
  LINKS+=("klippy/kinematics/$module"); SOURCES+=("$PLUGIN/jointspace_missing_section.py")
done
EXCLUDE_BEGIN="# jointspace (klipper/install.sh): begin"
EXCLUDE_END="# jointspace (klipper/install.sh): end"

is_ours() {
  # $1 (in the host tree) is install's to replace or remove: a link to $2 (this folder's file, or where earlier
  # versions kept it: klipper/ itself), or a regular file install copied (it holds the marker line).
  local target
  if [ -L "$1" ]; then
    target=$(readlink -f -- "$1")
    [ "$target" = "$(readlink -f -- "$2")" ] || [ "$target" = "$HERE/$(basename -- "$2")" ]
  else
    [ -f "$1" ] && grep -qxF -- "$MARKER" "$1"
  fi
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

venv_python() {
  # The virtualenv's interpreter, run isolated (-I: neither the current folder nor PYTHON* variables on its path).
  "$VENV/bin/python" -I "$@"
}

package_installed() {
  [ -x "$VENV/bin/python" ] && venv_python -m pip show -q "$PACKAGE" >/dev/null 2>&1
}

remove_host_files() {
  local i link
  for i in "${!LINKS[@]}"; do
    link=$HOST_DIR/${LINKS[$i]}
    if is_ours "$link" "${SOURCES[$i]}"; then
      rm -f -- "$link" "$(dirname -- "$link")/__pycache__/$(basename -- "$link" .py)".*
      rmdir -- "$(dirname -- "$link")/__pycache__" 2>/dev/null || true
    elif [ -e "$link" ] || [ -L "$link" ]; then
      printf 'note: left %s: install.sh did not put it there\n' "$link"
    fi
  done
}

uninstall() {
  remove_host_files
  rewrite_exclude remove
  if [ $DEV = 0 ] && package_installed; then
    venv_python -m pip uninstall -y -q "$PACKAGE"
    printf '%s removed from %s\n' "$PACKAGE" "$VENV"
  fi
  printf 'jointspace removed from %s\n' "$HOST_DIR"
}

check_nothing_foreign() {
  # Before anything is written: a file in the way that install did not put there stays, and install stops.
  local i link
  for i in "${!LINKS[@]}"; do
    link=$HOST_DIR/${LINKS[$i]}
    if { [ -e "$link" ] || [ -L "$link" ]; } && ! is_ours "$link" "${SOURCES[$i]}"; then
      printf 'install.sh: %s exists and install.sh did not put it there: move it away (or uninstall what put it there) and run again\n' "$link" >&2
      exit 1
    fi
  done
  if [ -n "$OTHER" ] && { [ -e "$HOST_DIR/$OTHER/jointspace.py" ] || [ -L "$HOST_DIR/$OTHER/jointspace.py" ]; }; then
    printf 'install.sh: %s/%s/jointspace.py exists: Kalico refuses to start with jointspace.py in both %s and %s; remove it and run again\n' \
      "$HOST_DIR" "$OTHER" "$OTHER" "$DEST" >&2
    exit 1
  fi
}

python_version() {
  # The virtualenv's Python as MAJOR.MINOR (-E, not -I: Python 2 knows no -I), or "unknown".
  "$VENV/bin/python" -E -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || echo unknown
}

check_python() {
  # The virtualenv exists and its Python is one the package supports (a clear message, before pip's own).
  local version
  if [ ! -x "$VENV/bin/python" ]; then
    printf 'install.sh: %s/bin/python is missing: name the virtualenv Klipper runs in with --venv DIR\n' "$VENV" >&2
    exit 2
  fi
  version=$(python_version)
  case $version in
    unknown) ;;
    *) if printf '%s\n%s\n' "$MIN_PYTHON" "$version" | sort -C -V; then return 0; fi ;;
  esac
  printf 'install.sh: %s runs Python %s; %s needs Python %s or newer: recreate the virtualenv with a newer Python 3 (e.g. reinstall Klipper with KIAUH) and run again\n' \
    "$VENV" "$version" "$PACKAGE" "$MIN_PYTHON" >&2
  exit 2
}

pip_install() {
  # From the index, or from the given wheel(s) as a local index: either way pip records no direct URL, so Moonraker's
  # `type: python` updater updates the package from the index afterwards.
  local links status=0
  if [ -z "$WHEEL" ]; then
    venv_python -m pip install --upgrade --no-deps "$PACKAGE"
    return
  fi
  if [ -d "$WHEEL" ]; then
    links=$(cd -- "$WHEEL" && pwd -P)
    venv_python -m pip install --no-index --find-links "$links" --force-reinstall --no-deps "$PACKAGE" || status=$?
  elif [ -f "$WHEEL" ]; then
    links=$(mktemp -d)
    ln -s -- "$(cd -- "$(dirname -- "$WHEEL")" && pwd -P)/$(basename -- "$WHEEL")" "$links/"
    venv_python -m pip install --no-index --find-links "$links" --force-reinstall --no-deps "$PACKAGE" || status=$?
    rm -rf -- "$links"
  else
    printf 'install.sh: %s is neither a wheel file nor a folder of wheels\n' "$WHEEL" >&2
    exit 2
  fi
  if [ $status != 0 ]; then
    printf 'install.sh: no wheel in %s fits this host (%s, Python %s)\n' "$WHEEL" "$(uname -m)" "$(python_version)" >&2
    exit 1
  fi
}

copy_into_host() {
  # $1: the file in the installed package, $2: its place in the host tree (written whole, then renamed).
  cp -- "$1" "$2.jointspace-tmp"
  mv -f -- "$2.jointspace-tmp" "$2"
}

install_package() {
  local loader missing i
  check_python
  check_nothing_foreign
  pip_install
  loader=$(venv_python -c 'import jointspace_klipper; print(jointspace_klipper.LOADER)')
  missing=$(venv_python -c 'import jointspace_klipper; print(jointspace_klipper.MISSING_SECTION)')
  # A developer-mode install before this one: its links give way to the loader.
  remove_host_files >/dev/null
  copy_into_host "$loader" "$HOST_DIR/$DEST/jointspace.py"
  for i in "${!LINKS[@]}"; do
    case ${LINKS[$i]} in klippy/kinematics/*) copy_into_host "$missing" "$HOST_DIR/${LINKS[$i]}" ;; esac
  done
  rewrite_exclude add
  printf 'jointspace %s installed into %s, its loader into %s/%s; add [jointspace] to printer.cfg and restart Klipper\n' \
    "$(venv_python -m pip show "$PACKAGE" | sed -n 's/^Version: //p')" "$VENV" "$HOST_DIR" "$DEST"
}

install_dev() {
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
  remove_host_files >/dev/null
  for i in "${!LINKS[@]}"; do
    ln -sfn -- "${SOURCES[$i]}" "$HOST_DIR/${LINKS[$i]}"
  done
  rewrite_exclude add
  printf 'jointspace (developer mode, from %s) linked into %s/%s; add [jointspace] to printer.cfg and restart Klipper\n' \
    "$PLUGIN" "$HOST_DIR" "$DEST"
}

if [ $UNINSTALL = 1 ]; then uninstall
elif [ $DEV = 1 ]; then install_dev
else install_package; fi
