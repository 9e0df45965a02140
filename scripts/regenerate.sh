#!/usr/bin/env bash
# Regenerates generated/ from models/ with the obsynth binary given (default build/synth/obsynth).
# Every bundled model that admits the canonical and perfect designs gets both headers.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build/synth/obsynth}
out=${2:-generated}
models=(slawinski17 triangular4 flexible_joint pendulum vanderpol)
mkdir -p "$out"
cp runtime/LICENSE "$out/LICENSE"
for m in "${models[@]}"; do
  "$bin" "models/$m.sym" -o "$out" --method canonical,perfect >/dev/null
done
