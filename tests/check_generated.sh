#!/usr/bin/env bash
# generated/ must be exactly what the current obsynth emits for models/.
# usage: check_generated.sh <obsynth binary> <source dir>
set -u
bin=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$src" || exit 1
bash scripts/regenerate.sh "$bin" "$tmp/generated" || { echo "regeneration failed"; exit 1; }
if diff -ru generated "$tmp/generated" >"$tmp/diff"; then
  echo "generated: 1 passed, 0 failed"
  exit 0
fi
cat "$tmp/diff"
echo
echo "generated/ is out of date; refresh it with: bash scripts/regenerate.sh build/synth/obsynth"
echo "generated: 0 passed, 1 failed"
exit 1
