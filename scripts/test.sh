#!/usr/bin/env bash
# Builds and runs the whole test suite: once normally, once under AddressSanitizer +
# UndefinedBehaviorSanitizer. Installs missing packages first.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOBSYNTH_BUILD_TESTS=ON -DOBSYNTH_BUILD_BENCH=ON
cmake --build build -j "$jobs"
(cd build && ctest --output-on-failure -j "$jobs" --timeout 600)

# Sanitizers: the same tests except those that are not about our host code (the fuzzer
# builds its own instrumented binary, the QEMU run is a cross build).
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DOBSYNTH_SANITIZE=ON \
  -DOBSYNTH_BUILD_TESTS=ON -DOBSYNTH_BUILD_BENCH=OFF
cmake --build build-asan -j "$jobs"
(cd build-asan && ctest --output-on-failure -j "$jobs" --timeout 900 -LE 'fuzz|embedded|package')
