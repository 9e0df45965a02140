#!/usr/bin/env bash
# Builds and runs the whole test suite: once normally, once under AddressSanitizer +
# UndefinedBehaviorSanitizer. Installs missing packages first.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)

# Release (as scripts/setup.sh, so the two share one build): no debug info, which costs a
# third of the compile time of the Eigen-heavy tests.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DOBSYNTH_BUILD_TESTS=ON -DOBSYNTH_BUILD_BENCH=ON
cmake --build build -j "$jobs"
(cd build && ctest --output-on-failure -j "$jobs" --timeout 600)

# Sanitizers: the tests of obsynth's own host code (unit tests, runtime, command line). Not
# rebuilt here: the generated-observer matrix (~550 build steps of generated code, which the
# Release pass compiles and runs), the fuzzer (its own instrumented binary), the QEMU runs
# (a cross build) and the package test (installs the normal build). -g1 keeps line tables for
# the sanitizers' stack traces at a fraction of full debug info's cost.
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DOBSYNTH_SANITIZE=ON \
  -DOBSYNTH_BUILD_TESTS=ON -DOBSYNTH_BUILD_BENCH=OFF -DOBSYNTH_CONTRACT_CHECKS=OFF -DOBSYNTH_FULL_SUITE=OFF
cmake --build build-asan -j "$jobs"
(cd build-asan && ctest --output-on-failure -j "$jobs" --timeout 900)
