#!/usr/bin/env bash
# Regenerates generated/ from models/ with the obsynth binary given (default build/synth/obsynth).
# Every bundled model listed gets a header for every registered design that applies to it.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build/synth/obsynth}
out=${2:-generated}
models=(slawinski17 triangular4 flexible_joint pendulum pendulum_params vanderpol two_block
        jamesbaras_sin lorenz rayleigh cart_pendulum dufour4 cstr)
mkdir -p "$out"
cp runtime/LICENSE "$out/LICENSE"
for m in "${models[@]}"; do
  "$bin" "models/$m.sym" -o "$out" --method all >/dev/null
done
# Seed 004's example (14), finite-time observer: a coarse variant (17 x 17 grid, dt = 0.01; the
# bound also covers the example's input ramps, slope 2; without the slope tables, as the
# embedded closed loop that runs it was derived) whose
# tables (~32k entries, 124 KiB: --precision float stores them as float) fit a microcontroller; the paper's 161 x 161 grid gives
# 2.85 M entries (10.9 MiB as float), see tests/test_finite_time.cpp.
"$bin" models/garcia14.sym -o "$out" --method finite-time --window 0.5 \
  --filter-poles=-0.01,-0.05,-0.1,-0.5,-1,-1.5,-2,-4,-8,-16 --grid-step 0.125 --input-step 1 \
  --kernel-epsilon 0.3 --weight-power 4 --sample-period 0.01 --input-rate 2 --precision float \
  --input-slope ignore >/dev/null
