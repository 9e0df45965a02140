#!/usr/bin/env bash
# Command-line behaviour: exit codes, gcc-style diagnostics, budgets, determinism.
# usage: run_cli_tests.sh <obsynth binary> <source dir>
set -u
bin=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0
fail=0
check() {  # name, condition (a command)
  local name=$1
  shift
  if "$@"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: $name"; fi
}

# 0: a good model, every format.
for fmt in text json markdown latex; do
  "$bin" check "$src/models/slawinski17.sym" --format "$fmt" >"$tmp/out.$fmt" 2>"$tmp/err"
  check "check --format $fmt exits 0" test $? -eq 0
  check "check --format $fmt prints something" test -s "$tmp/out.$fmt"
done
check "text report shows T" grep -q "T = \[x1^2/2-x2, x1\]" "$tmp/out.text"

# 1: user errors print file:line:col: error: and exit 1.
printf 'model bad\nstates x1 x2\nf = [ -x2, x3 ]\nh = [x1]\n' >"$tmp/bad.sym"
"$bin" check "$tmp/bad.sym" >"$tmp/out" 2>"$tmp/err"
check "unknown symbol exits 1" test $? -eq 1
check "unknown symbol diagnostic has position" grep -q "bad.sym:3:12: error: unknown symbol 'x3'" "$tmp/err"
"$bin" check "$tmp/missing.sym" >"$tmp/out" 2>"$tmp/err"
check "missing file exits 1" test $? -eq 1
check "missing file is named" grep -q "missing.sym: error: cannot open" "$tmp/err"
"$bin" check "$src/models/slawinski17.sym" --format yaml >"$tmp/out" 2>"$tmp/err"
check "bad option exits 1" test $? -eq 1
"$bin" --version >"$tmp/out"
check "--version" grep -q "^obsynth [0-9]" "$tmp/out"
"$bin" --help >"$tmp/out"
check "--help lists check" grep -q "check" "$tmp/out"

# Budget: a stage that runs past its time budget ends with a diagnostic naming it.
{
  echo "model heavy"
  echo "states $(seq -f 'x%g' -s ' ' 1 12)"
  printf 'f = ['
  for i in $(seq 1 11); do printf 'x%d + x%d^2*x1, ' $((i + 1)) "$i"; done
  printf -- '-('; for i in $(seq 1 12); do printf 'x%d^3' "$i"; [ "$i" -lt 12 ] && printf '+'; done; echo ') ]'
  echo "h = [x1]"
} >"$tmp/heavy.sym"
start=$(date +%s)
"$bin" check "$tmp/heavy.sym" --stage-seconds 1 >"$tmp/out" 2>"$tmp/err"
code=$?
elapsed=$(( $(date +%s) - start ))
check "budget exit code 1" test $code -eq 1
check "budget diagnostic names the stage" grep -Eq "stage '[a-z]+' exceeded its (time|expression-size) budget" "$tmp/err"
check "budget stops promptly (${elapsed}s)" test $elapsed -le 10
"$bin" check "$tmp/heavy.sym" --max-expression-size 2000 --rank-method symbolic >"$tmp/out" 2>"$tmp/err"
check "size budget exit code 1" test $? -eq 1
check "size budget diagnostic" grep -q "exceeded its expression-size budget" "$tmp/err"

# Determinism: byte-identical JSON between runs.
for m in slawinski17 triangular4 cstr lorenz flexible_joint; do
  "$bin" check "$src/models/$m.sym" --format json --no-timings >"$tmp/a.json"
  "$bin" check "$src/models/$m.sym" --format json --no-timings >"$tmp/b.json"
  check "deterministic JSON for $m" cmp -s "$tmp/a.json" "$tmp/b.json"
done

echo "cli: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
