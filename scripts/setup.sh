#!/usr/bin/env bash
# Fresh machine to first observer: installs the Debian packages, builds obsynth, analyses a
# bundled model (seed 003's worked example) and generates its observer into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DOBSYNTH_BUILD_TESTS=OFF -DOBSYNTH_BUILD_BENCH=OFF
cmake --build build --target obsynth
./build/synth/obsynth check models/slawinski17.sym
./build/synth/obsynth models/slawinski17.sym -o out/
echo
echo "The observer header is out/slawinski17_canonical.hpp (include it together with runtime/;"
echo "out/slawinski17_report.md explains the design and shows a usage example)."
