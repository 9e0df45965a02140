#!/usr/bin/env bash
# Regenerates generated/ from models/ with the obsynth binary given (default build/synth/obsynth).
# Every bundled model listed gets a header for every registered design that applies to it.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build/synth/obsynth}
out=${2:-generated}
models=(slawinski17 triangular4 flexible_joint pendulum pendulum_params vanderpol
        jamesbaras_sin lorenz rayleigh cstr cart_pendulum dufour4)
mkdir -p "$out"
cp runtime/LICENSE "$out/LICENSE"
for m in "${models[@]}"; do
  "$bin" "models/$m.sym" -o "$out" --method all >/dev/null
done
