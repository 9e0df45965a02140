#!/usr/bin/env bash
# Fresh machine to first observer: installs the Debian packages, builds obsynth, and runs it
# on a bundled model (seed 003's worked example).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DOBSYNTH_BUILD_TESTS=OFF -DOBSYNTH_BUILD_BENCH=OFF
cmake --build build --target obsynth
./build/synth/obsynth check models/slawinski17.sym
