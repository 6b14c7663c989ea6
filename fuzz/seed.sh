#!/usr/bin/env bash
# Seeds the fuzz corpora from real inputs: snippets of ../shared/corpus (the slicer G-code beside the
# repository) for the G-code targets, and the example and golden printer.cfg files for `config`.
# Usage: fuzz/seed.sh   (idempotent; writes fuzz/corpus/<target>/)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
shared="$here/../../shared"
corpus="$here/corpus"
mkdir -p "$corpus"/{lexer,config,pipeline,convert,includes}

# Classic edge cases every G-code target starts from, whether or not ../shared is present.
printf 'G28\nG1 X10 Y10 F3000\nG1 X20 E1\n' >"$corpus/lexer/basic"
printf 'N1 G1 X1*40\nG2 X10 Y0 I5 J0\nG91\nG1 X-1e308\n' >"$corpus/lexer/edges"
printf 'SET_VELOCITY_LIMIT VELOCITY=100 ACCEL=500\nM204 S1000\nG92 E0\nG4 P10\n' >"$corpus/lexer/klipper"
cp "$corpus"/lexer/* "$corpus/pipeline/"
cp "$corpus"/lexer/* "$corpus/convert/"
# Include trees: a chain, a cycle, a diamond and a glob (files separated by NUL bytes, f0.cfg first).
printf '[include f1.cfg]\n\0[include f2.cfg]\n\0[printer]\nkinematics: cartesian\n' >"$corpus/includes/chain"
printf '[include f1.cfg]\n\0[include f0.cfg]\n' >"$corpus/includes/cycle"
printf '[include f1.cfg]\n[include f2.cfg]\n\0[include f3.cfg]\n\0[include f3.cfg]\n\0\n' >"$corpus/includes/diamond"
printf '[include f*.cfg]\n\0[include /dev/null]\n' >"$corpus/includes/glob"

if [ -d "$shared/corpus" ]; then
  # 40-line snippets at a few places of every corpus file: headers, layer changes, arcs, retractions.
  for file in "$shared"/corpus/*.gcode; do
    name=$(basename "$file" .gcode)
    total=$(wc -l <"$file")
    for part in 0 1 2 3 4 5 6 7; do
      start=$((total * part / 8 + 1))
      sed -n "${start},$((start + 39))p" "$file" >"$corpus/lexer/${name}_$part"
    done
  done
  # The planner and converter targets are slower: fewer, shorter snippets from the middle of prints.
  for file in "$shared"/corpus/*.gcode; do
    name=$(basename "$file" .gcode)
    total=$(wc -l <"$file")
    for part in 2 5; do
      start=$((total * part / 8 + 1))
      snippet=$(sed -n "${start},$((start + 24))p" "$file")
      printf 'G28\nG90\nG1 X110 Y110 Z1 F3000\n%s\n' "$snippet" >"$corpus/pipeline/${name}_$part"
      printf 'G28\nG90\nG1 X10 Y10 Z1 F3000\n%s\n' "$snippet" >"$corpus/convert/${name}_$part"
    done
  done
  for cfg in "$shared"/golden/*/printer.cfg; do
    cp "$cfg" "$corpus/config/$(basename "$(dirname "$cfg")").cfg"
  done
else
  echo "seed.sh: $shared is absent: seeding from built-in snippets only" >&2
fi
cp "$here"/../examples/machines/*.cfg "$corpus/config/"
echo "seeded: $(for t in lexer config pipeline convert; do printf '%s=%s ' $t "$(ls "$corpus/$t" | wc -l)"; done)"
