#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Copyright (c) obsynth authors
#
# Cross-compile a C++ test program for a Cortex-M4F and run it under QEMU (mps2-an386) with
# newlib semihosting; print its stdout, the .text size and the stack usage of the observer code.
#
#   embedded/run-qemu.sh <source.cpp> [extra include dirs...]
#
# Exit status: the program's exit status (0 = pass); 124 if QEMU timed out; 2 on a build
# failure or bad usage; 77 if arm-none-eabi-g++ or qemu-system-arm is not installed
# (CTest treats 77 as "skipped").
#
# Environment:
#   OBSYNTH_QEMU_TIMEOUT     seconds before QEMU is killed (default 60)
#   OBSYNTH_QEMU_CXXFLAGS    extra compiler flags (appended; e.g. -g to map a fault's PC with
#                            arm-none-eabi-addr2line, -DNDEBUG, -ffp-contract=off)
#   OBSYNTH_QEMU_STACK_REGEX extended regex selecting the "observer functions" in the .su
#                            and symbol reports (default: observer|obsynth, case-insensitive)
#   OBSYNTH_QEMU_WORKDIR     keep build products in this directory (default: a temporary one,
#                            removed on exit)
#
# The program is compiled with the flags obsynth promises generated code works with,
#   -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -Os -fno-exceptions -fno-rtti
# plus -fstack-usage, -ffunction-sections/-fdata-sections with --gc-sections, and
# -Wall -Wextra -Wconversion -Wdouble-promotion -Werror (the generated-code contract), against
# full newlib (printf of floating point works without -u _printf_float).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(dirname "$here")"

if [ $# -lt 1 ]; then
  echo "usage: $0 <source.cpp> [extra include dirs...]" >&2
  exit 2
fi
src="$1"
shift
if [ ! -f "$src" ]; then
  echo "run-qemu.sh: no such source file: $src" >&2
  exit 2
fi

CXX="${OBSYNTH_ARM_CXX:-arm-none-eabi-g++}"
SIZE="${OBSYNTH_ARM_SIZE:-arm-none-eabi-size}"
NM="${OBSYNTH_ARM_NM:-arm-none-eabi-nm}"
QEMU="${OBSYNTH_QEMU:-qemu-system-arm}"
for tool in "$CXX" "$SIZE" "$NM" "$QEMU"; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "run-qemu.sh: SKIP: '$tool' not found (install gcc-arm-none-eabi, libnewlib-arm-none-eabi," \
         "libstdc++-arm-none-eabi-newlib and qemu-system-arm)" >&2
    exit 77
  fi
done
# The compiler alone is not enough: newlib (rdimon semihosting specs) and the newlib build of
# libstdc++ come in separate packages.
arch_probe=(-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -mthumb)
for f in rdimon.specs libstdc++.a; do
  found="$("$CXX" "${arch_probe[@]}" -print-file-name="$f" 2>/dev/null || true)"
  if [ "$found" = "$f" ] || [ ! -e "$found" ]; then
    echo "run-qemu.sh: SKIP: $f not found for $CXX (install libnewlib-arm-none-eabi and" \
         "libstdc++-arm-none-eabi-newlib)" >&2
    exit 77
  fi
done
if ! command -v timeout >/dev/null 2>&1; then
  echo "run-qemu.sh: 'timeout' (coreutils) not found" >&2
  exit 2
fi

eigen_dir="${OBSYNTH_EIGEN_DIR:-/usr/include/eigen3}"
timeout_s="${OBSYNTH_QEMU_TIMEOUT:-60}"
regex="${OBSYNTH_QEMU_STACK_REGEX:-observer|obsynth}"

if [ -n "${OBSYNTH_QEMU_WORKDIR:-}" ]; then
  work="$OBSYNTH_QEMU_WORKDIR"
  mkdir -p "$work"
else
  work="$(mktemp -d "${TMPDIR:-/tmp}/obsynth-qemu.XXXXXX")"
  trap 'rm -rf "$work"' EXIT
fi

arch=(-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -mthumb)
cxxflags=("${arch[@]}" -Os -std=c++17 -fno-exceptions -fno-rtti -fstack-usage -fcallgraph-info=su
          -ffunction-sections -fdata-sections
          -Wall -Wextra -Wconversion -Wdouble-promotion -Werror)
incs=(-I "$root/runtime" -I "$eigen_dir")
# C programs (<source>.c, e.g. the C99 back end's): further .c arguments are compiled with it
# as C99 under the same strict flags (-pedantic added) and linked.
c_sources=()
for d in "$@"; do
  case "$d" in
    *.c) c_sources+=("$d") ;;
    *) incs+=(-I "$d") ;;
  esac
done
case "$src" in
  *.c)
    CC="${OBSYNTH_ARM_CC:-arm-none-eabi-gcc}"
    c_sources=("$src" "${c_sources[@]}")
    cflags=("${arch[@]}" -Os -std=c99 -pedantic -fstack-usage -fcallgraph-info=su
            -ffunction-sections -fdata-sections
            -Wall -Wextra -Wconversion -Wdouble-promotion -Werror)
    ;;
esac
# shellcheck disable=SC2206
extra=(${OBSYNTH_QEMU_CXXFLAGS:-})

name="$(basename "${src%.*}")"
elf="$work/$name.elf"

echo "== build: $CXX ${arch[*]} -Os -fno-exceptions -fno-rtti -fstack-usage ${extra[*]:-} $src"
objs=()
if [ "${#c_sources[@]}" -gt 0 ] && [ -n "${CC:-}" ]; then
  for c in "${c_sources[@]}"; do
    o="$work/$(basename "${c%.*}").o"
    echo "== build (C): $CC ${cflags[*]} ${extra[*]:-} $c"
    "$CC" "${cflags[@]}" "${incs[@]}" "${extra[@]}" -c "$c" -o "$o" || { echo "run-qemu.sh: build failed" >&2; exit 2; }
    objs+=("$o")
  done
fi
if [ "${#objs[@]}" -eq 0 ] && ! "$CXX" "${cxxflags[@]}" "${incs[@]}" "${extra[@]}" -c "$src" -o "$work/$name.o"; then
  echo "run-qemu.sh: build failed" >&2
  exit 2
fi
[ "${#objs[@]}" -gt 0 ] || objs=("$work/$name.o")
if
   ! "$CXX" "${arch[@]}" -Os -std=c++17 -fno-exceptions -fno-rtti -fstack-usage \
       -ffunction-sections -fdata-sections -Wall -Wextra -Werror \
       -c "$here/startup.cpp" -o "$work/startup.o" ||
   ! "$CXX" "${arch[@]}" --specs=rdimon.specs -T "$here/mps2-an386.ld" -Wl,--gc-sections \
       -Wl,-Map="$work/$name.map" "${objs[@]}" "$work/startup.o" -lm -o "$elf"; then
  echo "run-qemu.sh: build failed" >&2
  exit 2
fi

echo "== run: timeout $timeout_s $QEMU -M mps2-an386 -nographic -semihosting-config enable=on,target=native -kernel $(basename "$elf")"
set +e
timeout "$timeout_s" "$QEMU" -M mps2-an386 -nographic -monitor none \
  -semihosting-config enable=on,target=native -kernel "$elf" </dev/null
rc=$?
set -e

echo "== size"
text_size="$("$SIZE" -A "$elf" | awk '$1 == ".text" { print $2 }')"
vec_size="$("$SIZE" -A "$elf" | awk '$1 == ".vectors" { print $2 }')"
echo ".text: ${text_size} bytes (whole program incl. newlib printf; .vectors ${vec_size})"
# (portable awk: no gawk extensions such as strtonum or IGNORECASE)
obs_text="$("$NM" -C -S --size-sort "$elf" | awk -v re="$regex" '
  function hex(s,   i, v) {
    v = 0; s = tolower(s)
    for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(s, i, 1)) - 1
    return v
  }
  BEGIN { re = tolower(re) }
  ($3 == "T" || $3 == "t" || $3 == "W" || $3 == "w") {
    name = $0; sub(/^[^ ]+ [^ ]+ [^ ]+ /, "", name)
    if (tolower(name) ~ re) { total += hex($2); n++ }
  }
  END { printf "%d bytes in %d functions", total, n }')"
echo "observer code (symbols matching /$regex/): $obs_text"

echo "== stack usage (-fstack-usage: own frame of each function matching /$regex/)"
su_file="$work/$name.su"
if [ -e "$su_file" ]; then
  awk -F'\t' -v re="$regex" '
    BEGIN { re = tolower(re); max = 0 }
    {
      fn = $1; sub(/^[^:]*:[0-9]+:[0-9]+:/, "", fn)
      if (tolower(fn) ~ re) {
        printf "  %6d  %-8s %s\n", $2, $3, fn
        if ($2 + 0 > max) { max = $2 + 0; maxfn = fn }
        n++
      }
    }
    END {
      if (n == 0) print "  (no matching functions: everything was inlined into callers)"
      else printf "max observer stack frame: %d bytes (%s)\n", max, maxfn
    }' "$su_file"
fi

# Worst case over call chains inside this translation unit, from -fcallgraph-info=su (VCG):
# for each matching function, its own frame plus the deepest chain of callees (Eigen kernels,
# lambdas, ...). Calls leaving the unit (libm, libc) have unknown frames and are listed.
ci_file="$work/$name.ci"
if [ -e "$ci_file" ]; then
  echo "== stack usage including callees (-fcallgraph-info=su, worst call chain in this unit)"
  awk -v re="$regex" '
    function field(line, key,   i, rest) {
      i = index(line, key ": \"")
      if (i == 0) return ""
      rest = substr(line, i + length(key) + 3)
      return substr(rest, 1, index(rest, "\"") - 1)
    }
    function depth(t,   e, d, best, c) {
      if (t in memo) return memo[t]
      if (t in busy) { recursive = 1; return 0 }
      busy[t] = 1
      best = 0
      for (e = 1; e <= nedge[t]; e++) {
        c = edge[t, e]
        if (!(c in bytes)) { unknown[c] = 1; continue }
        d = depth(c)
        if (d > best) best = d
      }
      delete busy[t]
      memo[t] = bytes[t] + best
      return memo[t]
    }
    /^node:/ {
      t = field($0, "title"); lab = field($0, "label")
      name[t] = lab; sub(/\\n.*/, "", name[t])
      if (match(lab, /\\n[0-9]+ bytes/)) {
        b = substr(lab, RSTART + 2, RLENGTH - 2); sub(/ bytes/, "", b); bytes[t] = b + 0
      }
    }
    /^edge:/ { s = field($0, "sourcename"); d = field($0, "targetname"); nedge[s]++; edge[s, nedge[s]] = d }
    END {
      re = tolower(re); max = -1
      for (t in bytes) if (tolower(name[t]) ~ re) {
        v = depth(t)
        if (v > max) { max = v; maxfn = name[t] }
      }
      if (max < 0) { print "  (no matching functions)"; exit }
      printf "max observer stack incl. callees: %d bytes (root: %s)\n", max, maxfn
      n = 0; for (u in unknown) { lst = lst (n++ ? ", " : "") name[u] }
      if (n) printf "  not included (outside this unit): %s\n", lst
      if (recursive) print "  warning: recursion in the call graph; the figure is a lower bound"
    }' "$ci_file"
fi

# Code size of the observer including everything it calls in this unit: the functions matching
# the regex (by their name in the call graph) plus the closure of their callees (outlined Eigen
# kernels, lambdas, helpers such as obsynth::all_finite), summed over the ELF's symbol sizes
# (after --gc-sections). Calls leaving the unit (libm, libgcc) are listed, not counted.
if [ -e "$ci_file" ]; then
  echo "== observer code including callees (-fcallgraph-info=su closure, symbol sizes from the ELF)"
  "$NM" -S "$elf" | awk -v re="$regex" '
    function hex(s,   i, v) {
      v = 0; s = tolower(s)
      for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(s, i, 1)) - 1
      return v
    }
    function field(line, key,   i, rest) {
      i = index(line, key ": \"")
      if (i == 0) return ""
      rest = substr(line, i + length(key) + 3)
      return substr(rest, 1, index(rest, "\"") - 1)
    }
    function sym(t,   s) { s = t; sub(/^.*:/, "", s); return s }
    function visit(t,   e) {
      if (t in seen) return
      seen[t] = 1
      for (e = 1; e <= nedge[t]; e++) visit(edge[t, e])
    }
    FILENAME == "-" {
      if (NF >= 4 && ($3 == "T" || $3 == "t" || $3 == "W" || $3 == "w")) size[$4] = hex($2)
      next
    }
    /^node:/ { t = field($0, "title"); name[t] = field($0, "label"); sub(/\\n.*/, "", name[t]); node[t] = 1 }
    /^edge:/ { s = field($0, "sourcename"); d = field($0, "targetname"); nedge[s]++; edge[s, nedge[s]] = d }
    END {
      re = tolower(re)
      for (t in node) if (tolower(name[t]) ~ re) { visit(t); roots++ }
      if (roots == 0) { print "  (no matching functions)"; exit }
      for (t in seen) {
        k = sym(t)
        if (k in size) { total += size[k]; n++ }
        else if (!(t in nedge) && index(t, ":") == 0) { ext = ext (m++ ? ", " : "") k }
      }
      printf "observer code incl. callees: %d bytes in %d functions (%d roots)\n", total, n, roots
      if (m) printf "  not included (outside this unit): %s\n", ext
    }' - "$ci_file"
fi

case $rc in
  0) echo "== PASS" ;;
  124) echo "== FAIL: QEMU timed out after ${timeout_s}s" >&2 ;;
  *) echo "== FAIL: program exited with status $rc" >&2 ;;
esac
exit "$rc"
