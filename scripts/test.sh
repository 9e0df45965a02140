#!/usr/bin/env bash
# Builds and runs the whole test suite (Release). Installs missing packages first.
# The same tests under AddressSanitizer + UndefinedBehaviorSanitizer: scripts/test-sanitizers.sh
# (not part of this command, to keep CI well under 20 minutes on 2 cores; the parser's fuzz
# test, fuzz_parse_short, runs here under ASan + UBSan).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)

# Release (as scripts/setup.sh, so the two share one build): no debug info, which costs a
# third of the compile time of the Eigen-heavy tests.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DOBSYNTH_BUILD_TESTS=ON -DOBSYNTH_BUILD_BENCH=ON
cmake --build build -j "$jobs"
(cd build && ctest --output-on-failure -j "$jobs" --timeout 600)
