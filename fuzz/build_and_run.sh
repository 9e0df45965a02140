#!/usr/bin/env bash
# Build the libFuzzer target for the .sym parser with clang++ and run it.
#
#   fuzz/build_and_run.sh [SECONDS] [extra libFuzzer flags...]   fuzz for SECONDS (default 30)
#   fuzz/build_and_run.sh repro FILE...                           re-run saved inputs once
#   fuzz/build_and_run.sh build                                   only build
#
# Exit status: 0 = no finding, non-zero = a finding (crash, sanitizer report, uncaught
# exception other than UserError, leak, timeout, out of memory) or a build failure,
# 125 = skipped because clang++/pkg-config is missing.
#
# Environment:
#   CXX_FUZZ                 clang++ to use (default: clang++)
#   OBSYNTH_FUZZ_BUILD_DIR   where objects and the binary go
#                            (default: ${TMPDIR:-/tmp}/obsynth-fuzz-$UID)
#   OBSYNTH_FUZZ_CORPUS      keep the grown corpus in this directory instead of a temp dir
#   OBSYNTH_FUZZ_ARTIFACTS   where crashing inputs are written (default: fuzz/artifacts/)
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
cxx="${CXX_FUZZ:-clang++}"
build="${OBSYNTH_FUZZ_BUILD_DIR:-${TMPDIR:-/tmp}/obsynth-fuzz-$(id -u)}"
artifacts="${OBSYNTH_FUZZ_ARTIFACTS:-$here/artifacts}"
bin="$build/fuzz_parse"

if ! command -v "$cxx" >/dev/null 2>&1 || ! command -v pkg-config >/dev/null 2>&1; then
  echo "fuzz: $cxx or pkg-config not found; skipping" >&2
  exit 125
fi

# ---- build -------------------------------------------------------------------------------
# The synth/*/*.cpp files the parser needs: the include closure of synth/front/parse.cpp
# (each '#include "dir/x.hpp"' pulls in synth/dir/x.cpp when it exists), so new dependencies
# are picked up.
sources() {
  local -a todo=("$root/synth/front/parse.cpp") seen=()
  while ((${#todo[@]})); do
    local f="${todo[0]}"
    todo=("${todo[@]:1}")
    [[ " ${seen[*]-} " == *" $f "* ]] && continue
    seen+=("$f")
    local inc
    for inc in $(sed -n 's/^#include "\([A-Za-z0-9_/]*\)\.hpp".*/\1/p' "$f" "${f%.cpp}.hpp" 2>/dev/null | sort -u); do
      [[ -f "$root/synth/$inc.cpp" ]] && todo+=("$root/synth/$inc.cpp")
      [[ -f "$root/synth/$inc.hpp" && ! -f "$root/synth/$inc.cpp" ]] && todo+=("$root/synth/$inc.hpp")
    done
  done
  local s
  for s in "${seen[@]}"; do [[ "$s" == *.cpp ]] && echo "$s"; done
}

build_fuzzer() {
  mkdir -p "$build"
  local -a srcs
  mapfile -t srcs < <(sources)
  srcs+=("$here/fuzz_parse.cpp")
  # Rebuild when any input is newer than the binary.
  if [[ -x "$bin" ]] && [[ -z "$(find "${srcs[@]}" "$root"/synth/*/*.hpp "$0" -newer "$bin" 2>/dev/null | head -1)" ]]; then
    return 0
  fi
  local -a deps
  read -r -a deps <<<"$(pkg-config --cflags ginac cln fmt)"
  local -a libs
  read -r -a libs <<<"$(pkg-config --libs ginac cln fmt)"
  local -a flags=(-std=c++17 -g -O1 -fno-omit-frame-pointer
                  -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all
                  -I"$root/synth" "${deps[@]}")
  echo "fuzz: compiling ${#srcs[@]} files with $cxx into $build" >&2
  local -a objs=() pids=()
  local s o
  for s in "${srcs[@]}"; do
    o="$build/$(basename "${s%.cpp}").o"
    objs+=("$o")
    "$cxx" "${flags[@]}" -c "$s" -o "$o" &
    pids+=($!)
  done
  local ok=1 p
  for p in "${pids[@]}"; do wait "$p" || ok=0; done
  ((ok)) || { echo "fuzz: compilation failed" >&2; exit 1; }
  "$cxx" -fsanitize=fuzzer,address,undefined "${objs[@]}" "${libs[@]}" -o "$bin.tmp"
  mv "$bin.tmp" "$bin"
}

build_fuzzer

export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
# Leaks are checked after every input that allocated more than it freed (libFuzzer's
# -detect_leaks=1, the default) and at exit; lsan.supp lists known leaks in GiNaC/CLN.
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$here/lsan.supp:print_suppressions=0}"
common=(-max_len=4096 -timeout=10 -rss_limit_mb=4096)

case "${1:-}" in
  build) echo "$bin"; exit 0 ;;
  repro)
    shift
    (($#)) || { echo "usage: $0 repro FILE..." >&2; exit 2; }
    # One pass over the given inputs, with full stacks for allocations (slower, clearer).
    export ASAN_OPTIONS="${ASAN_OPTIONS:-fast_unwind_on_malloc=0}"
    exec "$bin" "${common[@]}" "$@"
    ;;
esac

seconds="${1:-30}"
[[ "$seconds" =~ ^[0-9]+$ ]] || { echo "usage: $0 [SECONDS] [libFuzzer flags...]" >&2; exit 2; }
shift || true

# ---- corpus: the models plus hand-written seeds, copied so the checkout stays clean -------
if [[ -n "${OBSYNTH_FUZZ_CORPUS:-}" ]]; then
  corpus="$OBSYNTH_FUZZ_CORPUS"
  mkdir -p "$corpus"
else
  corpus="$(mktemp -d "${TMPDIR:-/tmp}/obsynth-fuzz-corpus.XXXXXX")"
  trap 'rm -rf "$corpus"' EXIT
fi
cp "$root"/models/*.sym "$corpus"/ 2>/dev/null || true
cp "$here"/seeds/* "$corpus"/ 2>/dev/null || true
mkdir -p "$artifacts"

echo "fuzz: running $bin for ${seconds}s on $(ls "$corpus" | wc -l) corpus files" >&2
status=0
"$bin" "${common[@]}" -max_total_time="$seconds" -dict="$here/sym.dict" \
  -artifact_prefix="$artifacts/" -print_final_stats=1 "$@" "$corpus" || status=$?
if ((status != 0)); then
  echo "fuzz: FINDING (libFuzzer exit status $status); inputs saved under $artifacts/" >&2
  echo "fuzz: reproduce with: $0 repro $artifacts/<crash|leak|timeout|oom>-<sha1>" >&2
fi
exit "$status"
