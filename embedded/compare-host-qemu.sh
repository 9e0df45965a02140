#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Copyright (c) obsynth authors
#
# Run the same closed-loop program natively (already built by CMake with the host compiler)
# and on a Cortex-M4F under QEMU (built by run-qemu.sh), and compare the trajectories.
#
#   embedded/compare-host-qemu.sh <host-executable> <source.cpp> <rtol> [qemu extra cxxflags
#                                 [extra include dirs for the QEMU build...]]
#
# Only lines "traj t x1 x2 xh1 xh2 ..." are compared (columns 2-6). The test is normwise: at
# every printed sample
#   |t_host - t_qemu| <= rtol * max|t|   and   |v_host - v_qemu| <= rtol * S  for v in x, xh,
# where S = max |x_i|, |xh_i| over the whole run (the inf-norm scale of the state). A component
# that passes near zero, or is computed with cancellation (seed 003: xh2 = z2^2/2 - z1 with
# z2^2/2 ~ 46 while xh2 ~ 0.3), is thus not judged on its last digits alone. The largest
# difference relative to each column's own scale is printed too, for information.
# rtol = 0 demands identical printed values and identical "hash" lines (a hash of the bit
# patterns of the states at every step).
# Both programs must also pass their own checks (exit status 0).
#
# Exit status: 0 match, 1 mismatch or a failing program, 77 toolchain/QEMU absent (skip).
set -uo pipefail

if [ $# -lt 3 ]; then
  echo "usage: $0 <host-executable> <source.cpp> <rtol> [qemu extra cxxflags [include dirs...]]" >&2
  exit 2
fi
host_exe="$1"
src="$2"
rtol="$3"
qemu_flags="${4:-}"
shift 3
[ $# -gt 0 ] && shift
# the rest: include directories for run-qemu.sh (e.g. generated/)
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
work="$(mktemp -d "${TMPDIR:-/tmp}/obsynth-cmp.XXXXXX")"
trap 'rm -rf "$work"' EXIT

echo "== host: $host_exe"
"$host_exe" >"$work/host.txt"
host_rc=$?
cat "$work/host.txt"
if [ $host_rc -ne 0 ]; then
  echo "FAIL: host program exited with status $host_rc"
  exit 1
fi

echo "== target (QEMU), extra flags: ${qemu_flags:-none}"
OBSYNTH_QEMU_CXXFLAGS="$qemu_flags" "$here/run-qemu.sh" "$src" "$@" >"$work/qemu.txt" 2>&1
qemu_rc=$?
cat "$work/qemu.txt"
if [ $qemu_rc -eq 77 ]; then
  echo "SKIP: cross toolchain or QEMU not installed"
  exit 77
fi
if [ $qemu_rc -ne 0 ]; then
  echo "FAIL: QEMU run failed with status $qemu_rc"
  exit 1
fi

grep '^traj ' "$work/host.txt" >"$work/host.traj"
grep '^traj ' "$work/qemu.txt" >"$work/qemu.traj"
echo "== compare (rtol $rtol, relative to each column's max |value|)"
awk -v rtol="$rtol" '
  function abs(v) { return v < 0 ? -v : v }
  NR == FNR { n1++; for (c = 2; c <= 6; c++) { h[n1, c] = $c; if (abs($c) > s[c]) s[c] = abs($c) } ; next }
  { n2++; for (c = 2; c <= 6; c++) { q[n2, c] = $c; if (abs($c) > s[c]) s[c] = abs($c) } }
  END {
    if (n1 == 0 || n1 != n2) { printf "FAIL: %d host lines vs %d target lines\n", n1, n2; exit 1 }
    split("t x1 x2 xh1 xh2", name, " ")
    S = 0; for (c = 3; c <= 6; c++) if (s[c] > S) S = s[c]
    printf "state scale S = max |x|, |xh| = %g\n", S
    bad = 0; worst = 0; worst_col = 0
    for (i = 1; i <= n1; i++) for (c = 2; c <= 6; c++) {
      d = abs(h[i, c] - q[i, c])
      scale = (c == 2) ? s[2] : S
      rel = (scale > 0) ? d / scale : d
      relc = (s[c] > 0) ? d / s[c] : d
      if (rel > worst) { worst = rel; wi = i; wc = c }
      if (relc > worst_col) { worst_col = relc; ci = i; cc = c }
      if (d > rtol * scale) {
        bad++
        if (bad <= 10) printf "  mismatch line %d %s: host %s target %s (|diff| %.3g = %.3g S)\n", i, name[c - 1], h[i, c], q[i, c], d, rel
      }
    }
    if (worst > 0) {
      printf "largest difference: %.3g of the state scale (line %d, %s)\n", worst, wi, name[wc - 1]
      printf "largest difference relative to its own column: %.3g (line %d, %s)\n", worst_col, ci, name[cc - 1]
    } else {
      print "host and target trajectories are identical to the printed digits"
    }
    if (bad > 0) { printf "FAIL: %d values differ by more than rtol %s\n", bad, rtol; exit 1 }
    print "trajectories match within rtol"
  }' "$work/host.traj" "$work/qemu.traj" || exit 1

if [ "$rtol" = "0" ]; then
  host_hash="$(grep '^hash ' "$work/host.txt" || true)"
  qemu_hash="$(grep '^hash ' "$work/qemu.txt" || true)"
  if [ -z "$host_hash" ] || [ "$host_hash" != "$qemu_hash" ]; then
    echo "FAIL: bit patterns differ: host '$host_hash' vs target '$qemu_hash'"
    exit 1
  fi
  echo "bit-identical states at every step: $host_hash"
fi
echo "PASS"
exit 0
