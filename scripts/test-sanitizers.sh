#!/usr/bin/env bash
# The tests of obsynth's own host code (unit tests, runtime, command line) under
# AddressSanitizer + UndefinedBehaviorSanitizer, in build-asan/. About 20 minutes on 2 cores.
# Not rebuilt here: the generated-observer matrix (~450 build steps of generated code, which
# scripts/test.sh compiles and runs), the fuzzer (its own instrumented binary), the QEMU runs
# (a cross build) and the package test (installs the normal build). -g1 keeps line tables for
# the sanitizers' stack traces at a fraction of full debug info's cost.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DOBSYNTH_SANITIZE=ON \
  -DOBSYNTH_BUILD_TESTS=ON -DOBSYNTH_BUILD_BENCH=OFF -DOBSYNTH_FULL_SUITE=OFF \
  -DOBSYNTH_STATIC_GINAC=OFF
cmake --build build-asan -j "$jobs"
(cd build-asan && ctest --output-on-failure -j "$jobs" --timeout 900)
