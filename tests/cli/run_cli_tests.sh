#!/usr/bin/env bash
# Command-line behaviour: exit codes, gcc-style diagnostics, budgets, determinism.
# usage: run_cli_tests.sh <obsynth binary> <source dir>
set -u
bin=$1
src=$2
. "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
# Which stage a time budget stops first depends on the binary's speed: under the sanitizers
# (5-20x slower) an earlier stage stops first. Those checks run in the Release pass only.
sanitized=0
if ldd "$bin" 2>/dev/null | grep -q libasan; then sanitized=1; fi
timed_check() {
  if [ $sanitized -eq 1 ]; then echo "skipped under the sanitizers: $1"; else check "$@"; fi
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

# FLINT and Arb load on first use (cmake/lazy_library_stubs.sh): a check of a small model never
# maps them; one that needs them (--certify: Arb's balls) loads them and gives the same answer.
if ! ldd "$bin" 2>/dev/null | grep -q libflint; then
  LD_DEBUG=files "$bin" check "$src/models/slawinski17.sym" >"$tmp/out" 2>"$tmp/err"
  check "small check exits 0" test $? -eq 0
  check "small check does not load FLINT" sh -c "! grep -q 'file=libflint' '$tmp/err'"
  check "small check still reports T" grep -q "T = \[x1^2/2-x2, x1\]" "$tmp/out"
  LD_DEBUG=files "$bin" check "$src/models/slawinski17.sym" --certify >"$tmp/out" 2>"$tmp/err"
  check "certify exits 0" test $? -eq 0
  check "certify loads Arb on first use" grep -q "file=libflint-arb.so.* dynamically loaded" "$tmp/err"
  check "certify report is complete" grep -q "T = \[x1^2/2-x2, x1\]" "$tmp/out"
fi

# Budget: a stage that runs past its time budget ends with a diagnostic naming it.
{
  echo "model heavy"
  echo "states $(seq -f 'x%g' -s ' ' 1 12)"
  printf 'f = ['
  for i in $(seq 1 11); do printf 'x%d + x%d^2*x1, ' $((i + 1)) "$i"; done
  printf -- '-('; for i in $(seq 1 12); do printf 'x%d^3' "$i"; [ "$i" -lt 12 ] && printf '+'; done; echo ') ]'
  echo "h = [x1]"
} >"$tmp/heavy.sym"
# --rank-method symbolic: with the automatic method, a loaded machine can run the Lie chain out
# of its share of the budget, fall back to jets and complete (exit 0); an idle one stops later.
start=$(date +%s)
"$bin" check "$tmp/heavy.sym" --stage-seconds 1 --rank-method symbolic >"$tmp/out" 2>"$tmp/err"
code=$?
elapsed=$(( $(date +%s) - start ))
timed_check "budget exit code 1" test $code -eq 1
timed_check "budget diagnostic names the stage" grep -Eq "stage '[a-z]+' exceeded its (time|expression-size) budget" "$tmp/err"
check "budget stops promptly (${elapsed}s)" test $elapsed -le 10
"$bin" check "$tmp/heavy.sym" --max-expression-size 2000 --rank-method symbolic >"$tmp/out" 2>"$tmp/err"
check "size budget exit code 1" test $? -eq 1
check "size budget diagnostic" grep -q "exceeded its expression-size budget" "$tmp/err"

# A stop keeps what the completed stages found: the frame stage exceeds the size budget, and
# the rank (decided in the observability stage) is still reported, in text and JSON.
"$bin" check "$tmp/heavy.sym" --max-expression-size 100000 >"$tmp/out" 2>"$tmp/err"
check "frame stop exit code 1" test $? -eq 1
check "frame stop diagnostic" grep -q "stage 'frame' exceeded its expression-size budget" "$tmp/err"
check "frame stop keeps the rank (text)" grep -q "generic rank 12 of n = 12" "$tmp/out"
check "frame stop marks the stage (text)" grep -q "frame: stopped: exceeded its expression-size" "$tmp/out"
check "later stages not run (text)" grep -q "diffeomorphism: not run" "$tmp/out"
"$bin" check "$tmp/heavy.sym" --max-expression-size 100000 --format json >"$tmp/out.json" 2>"$tmp/err"
check "frame stop exit code 1 (json)" test $? -eq 1
check "frame stop keeps the rank (json)" grep -q '"generic_rank": 12' "$tmp/out.json"
check "json says incomplete" grep -q '^  "complete": false' "$tmp/out.json"
check "json stage statuses" sh -c "grep -A1 '\"name\": \"observability\"' '$tmp/out.json' | grep -q '\"status\": \"completed\"' && grep -A1 '\"name\": \"frame\"' '$tmp/out.json' | grep -q '\"status\": \"stopped\"' && grep -A1 '\"name\": \"conditions\"' '$tmp/out.json' | grep -q '\"status\": \"not run\"'"
for fmt in markdown latex; do
  "$bin" check "$tmp/heavy.sym" --max-expression-size 100000 --format $fmt >"$tmp/out" 2>/dev/null
  check "frame stop keeps the rank ($fmt)" grep -Eq "generic rank \*\*12\*\*|rank\} O &= 12" "$tmp/out"
done

# A stage killed by the watchdog (one GiNaC call longer than the budget) still prints the
# stages before it, from the worker's checkpoint.
{
  echo "model expchain"
  echo "states $(seq -f 'x%g' -s ' ' 1 8)"
  printf 'f = ['
  for i in $(seq 1 7); do printf 'x%d + exp(x%d)*x1^2, ' $((i + 1)) "$i"; done
  echo '-x1*x8/(1+x1^2) ]'
  echo "h = [x1]"
} >"$tmp/expchain.sym"
"$bin" check "$tmp/expchain.sym" --stage-seconds 1 --rank-method symbolic >"$tmp/out" 2>"$tmp/err"
check "watchdog stop exit code 1" test $? -eq 1
timed_check "watchdog stop diagnostic" grep -q "stage 'frame' exceeded its time budget of 1 s" "$tmp/err"
timed_check "watchdog stop keeps the rank" grep -q "generic rank 8 of n = 8" "$tmp/out"
timed_check "watchdog stop marks the stage" grep -q "frame: stopped: exceeded its time budget of 1 s" "$tmp/out"

# The total time budget ends the whole run within it, whatever the stages' own budgets, with
# the completed stages' results; it is checked by the watchdog thread (check) and the forked
# worker (the main job, where it admits no fallback rerun).
start=$(date +%s)
"$bin" check "$tmp/expchain.sym" --total-seconds 2 --rank-method symbolic >"$tmp/out" 2>"$tmp/err"
code=$?
elapsed=$(( $(date +%s) - start ))
check "total budget exit code 1" test $code -eq 1
timed_check "total budget diagnostic" grep -q "stage 'frame' exceeded the total time budget of 2 s (raise it with --total-seconds)" "$tmp/err"
check "total budget ends the run within it (${elapsed}s)" test $elapsed -le 3
timed_check "total budget stop keeps the rank" grep -q "generic rank 8 of n = 8" "$tmp/out"
start=$(date +%s)
"$bin" "$tmp/expchain.sym" -o "$tmp/job_total" --total-seconds 2 >"$tmp/out" 2>"$tmp/err"
code=$?
elapsed=$(( $(date +%s) - start ))
check "main job total budget exit code 1" test $code -eq 1
check "main job total budget diagnostic" grep -q "exceeded the total time budget of 2 s" "$tmp/err"
check "main job total budget: no fallback rerun" sh -c "! grep -q 'note:' '$tmp/err'"
check "main job total budget within it (${elapsed}s)" test $elapsed -le 3
check "main job total budget writes nothing" test ! -e "$tmp/job_total"

# Memory budget: an exploding model ends with the memory diagnostic and exit 1, promptly, in
# the worker and in-process, with the completed stages' results.
start=$(date +%s)
"$bin" check "$tmp/heavy.sym" --max-memory 256M >"$tmp/out" 2>"$tmp/err"
code=$?
elapsed=$(( $(date +%s) - start ))
check "memory budget exit code 1" test $code -eq 1
check "memory budget diagnostic" grep -Eq "^obsynth: error: stage '[a-z]+' exceeded its memory budget of 256 MiB" "$tmp/err"
# Wall time, so generous: the suite runs tests in parallel on 2 cores, where 30 s may be exceeded.
check "memory budget stops promptly (${elapsed}s)" test $elapsed -le 90
timed_check "memory stop keeps the rank" grep -q "generic rank 12 of n = 12" "$tmp/out"
# In-process the budget is the address-space limit, which AddressSanitizer's shadow memory
# rules out (synth/app/worker.cpp): skipped for a sanitized binary.
if [ $sanitized -eq 0 ]; then
  "$bin" check "$tmp/heavy.sym" --max-memory 256M --in-process --format json >"$tmp/out.json" 2>"$tmp/err"
  check "memory budget in-process exit code 1" test $? -eq 1
  check "memory budget in-process diagnostic" grep -q "exceeded its memory budget of 256 MiB" "$tmp/err"
  check "memory stop json incomplete" grep -q '"complete": false' "$tmp/out.json"
fi
for bad in 12X 1.2.3G -1G; do
  "$bin" check "$src/models/lorenz.sym" --max-memory=$bad >"$tmp/out" 2>"$tmp/err"
  check "malformed --max-memory $bad exits 1" test $? -eq 1
  check "malformed --max-memory $bad diagnostic" grep -q "^--max-memory: '$bad' is not a memory size" "$tmp/err"
done
"$bin" check "$src/models/lorenz.sym" --max-memory 512 >"$tmp/out" 2>"$tmp/err"
check "tiny --max-memory diagnostic" grep -q "'512' is 512 bytes, below the minimum of 32 MiB" "$tmp/err"
"$bin" check "$src/models/lorenz.sym" --max-memory 1G >"$tmp/out" 2>"$tmp/err"
check "--max-memory 1G runs" test $? -eq 0

# The main job is atomic: a budget stop leaves no output directory.
"$bin" "$tmp/heavy.sym" -o "$tmp/job_size" --max-expression-size 100000 --method canonical >"$tmp/out" 2>"$tmp/err"
check "main job size stop exits 1" test $? -eq 1
check "main job size stop diagnostic" grep -q "^obsynth: error: stage 'frame' exceeded its expression-size" "$tmp/err"
check "main job size stop writes nothing" test ! -e "$tmp/job_size"
"$bin" "$tmp/heavy.sym" -o "$tmp/job_mem" --max-memory 256M --method canonical >"$tmp/out" 2>"$tmp/err"
check "main job memory stop exits 1" test $? -eq 1
check "main job memory stop diagnostic" grep -q "exceeded its memory budget of 256 MiB" "$tmp/err"
check "main job memory stop writes nothing" test ! -e "$tmp/job_mem"
# auto may choose a design that needs no canonical form: a stop in the canonical-form stages
# (frame, conditions, diffeomorphism) skips them, says so, and the job goes on. heavy6: the
# 6-state version of heavy.sym, whose frame exceeds 2000 nodes (high-gain applies).
{
  echo "model heavy6"
  echo "states x1 x2 x3 x4 x5 x6"
  echo "f = [x2 + x1^2*x1, x3 + x2^2*x1, x4 + x3^2*x1, x5 + x4^2*x1, x6 + x5^2*x1, -(x1^3+x2^3+x3^3+x4^3+x5^3+x6^3)]"
  echo "h = [x1]"
} >"$tmp/heavy6.sym"
"$bin" "$tmp/heavy6.sym" -o "$tmp/job_auto_size" --max-expression-size 2000 >"$tmp/out" 2>"$tmp/err"
check "auto after a frame size stop exits 0" test $? -eq 0
check "auto after a frame size stop: note" grep -q "^obsynth: note: stage 'frame' exceeded its expression-size budget.*; continuing without the canonical form" "$tmp/err"
check "auto after a frame size stop: report says why" grep -q "not analysed: stage 'frame' exceeded its expression-size budget" "$tmp/job_auto_size/heavy6_report.md"
check "auto after a frame size stop: an observer" test -s "$tmp/job_auto_size/heavy6_auto.hpp"
# auto after a time stop in its chosen design's build: the next design that applies. heavy8: an
# 8-state model whose high-gain build (the Lipschitz bound of phi over the box: 36 entries, each
# a branch and bound up to its work cap) takes several seconds, every stage before it well
# under one.
{
  echo "model heavy8"
  echo "states $(seq -f 'x%g' -s ' ' 1 8)"
  printf 'f = ['
  for i in $(seq 1 7); do printf 'x%d + x%d^3*x1^2/10, ' $((i + 1)) "$i"; done
  printf -- '-('; for i in $(seq 1 8); do printf 'x%d^3' "$i"; [ "$i" -lt 8 ] && printf '+'; done; echo ') ]'
  echo "h = [x1]"
} >"$tmp/heavy8.sym"
"$bin" "$tmp/heavy8.sym" -o "$tmp/job_auto_next" --stage-seconds 2 >"$tmp/out" 2>"$tmp/err"
timed_check "auto after a design-build time stop exits 0" test $? -eq 0
# The stop may come in a design's certificate (its verdict, for auto's ranking) or its build:
# either way auto passes over that design and says so.
timed_check "auto after a design-build time stop: note" grep -Eq "^obsynth: note: stage '[a-z-]+ (verdict|design)' exceeded its time budget of 2 s.*; auto tries the next design" "$tmp/err"
timed_check "auto after a design-build time stop: report says why" grep -Eq "[a-z-]+: (its verdict stopped|it applies, but its build stopped): stage '[a-z-]+ (verdict|design)' exceeded its time budget" "$tmp/job_auto_next/heavy8_report.md"
timed_check "auto after a design-build time stop: another observer" test -s "$tmp/job_auto_next/heavy8_auto.hpp"
stopped_design=$(sed -nE "s/^obsynth: note: stage '([a-z-]+) (verdict|design)' exceeded.*/\1/p" "$tmp/err" | head -1)
timed_check "auto after a design-build time stop: no header of the design passed over" test -n "$stopped_design" -a ! -e "$tmp/job_auto_next/heavy8_${stopped_design}.hpp"
"$bin" "$tmp/heavy6.sym" -o "$tmp/job_named_size" --max-expression-size 2000 --method canonical >"$tmp/out" 2>"$tmp/err"
check "canonical after a frame size stop exits 1" test $? -eq 1
check "canonical after a frame size stop writes nothing" test ! -e "$tmp/job_named_size"
# --method canonical: auto would fall back to a design that does not need the stopped stage
# (kalman-theta here, when the Lie chain's share of the budget runs out first).
"$bin" "$tmp/expchain.sym" -o "$tmp/job_time" --stage-seconds 1 --method canonical \
  --rank-method symbolic >"$tmp/out" 2>"$tmp/err"
check "main job time stop exits 1" test $? -eq 1
timed_check "main job time stop diagnostic" grep -q "stage 'frame' exceeded its time budget of 1 s" "$tmp/err"
check "main job time stop writes nothing" test ! -e "$tmp/job_time"
# finite-time on a model that escapes in backward time: a diagnostic, not an internal error.
"$bin" "$src/models/vanderpol.sym" -o "$tmp/vdp_ft" --method finite-time >"$tmp/out" 2>"$tmp/err"
check "finite-time backward escape exits 1" test $? -eq 1
check "finite-time backward escape diagnostic" grep -q "backward simulation over the window T = [0-9.]* from the grid point x = (.*) at u = .* leaves the finite numbers" "$tmp/err"
# check runs the costly verdicts (thau, kou: certificate searches; extended-linearization: the
# symbolic design) only with --certify.
"$bin" check "$src/models/pendulum.sym" >"$tmp/out" 2>"$tmp/err"
check "check leaves the searches out" grep -q "^  thau  *not evaluated: its verdict is a certificate search" "$tmp/out"
check "check leaves the symbolic extended linearization out" grep -q "^  extended-linearization  *not evaluated: its verdict is a certificate search or a symbolic construction" "$tmp/out"
"$bin" check "$src/models/pendulum.sym" --certify >"$tmp/out" 2>"$tmp/err"
check "check --certify runs thau's search" grep -q "^  thau  *applies: " "$tmp/out"
check "check --certify runs kou's search" grep -q "^  kou  *applies: .*(rigorous" "$tmp/out"
check "check --certify builds extended linearization" grep -q "^  extended-linearization  *applies: constraints (i)-(iii) hold" "$tmp/out"
# A named method's report evaluates only that design; the others say so.
"$bin" "$src/models/pendulum.sym" -o "$tmp/named" --method high-gain >"$tmp/out" 2>"$tmp/err"
check "named method report marks the others" grep -q '| `thau` | not evaluated | only --method high-gain was requested (`obsynth check --certify` evaluates every design)' "$tmp/named/pendulum_report.md"
check "named method report has its verdict" grep -q '| `high-gain` | applies |' "$tmp/named/pendulum_report.md"

# The design registry: --list-methods, auto's explanation, all, unknown and planned methods.
"$bin" --list-methods >"$tmp/out" 2>&1
check "--list-methods lists canonical" grep -q "^canonical " "$tmp/out"
check "--list-methods lists perfect" grep -q "^perfect " "$tmp/out"
check "--list-methods lists riccati" grep -q "^riccati " "$tmp/out"
check "--list-methods lists high-gain" grep -q "^high-gain " "$tmp/out"
planned=$(awk '/planned/ {print $1; exit}' "$tmp/out")  # a registered-but-planned method, if any
"$bin" "$src/models/slawinski17.sym" -o "$tmp/auto" >"$tmp/out" 2>"$tmp/err"
check "auto explains its choice" grep -q "auto: chose 'canonical' (guarantee rigorous.*because the bracket conditions hold" "$tmp/out"
check "auto writes the alias header" grep -q "using AutoObserver = Slawinski17Canonical<Scalar...>;" "$tmp/auto/slawinski17_auto.hpp"
"$bin" "$src/models/slawinski17.sym" -o "$tmp/all" --method all >"$tmp/out" 2>"$tmp/err"
check "--method all writes canonical and perfect" test -e "$tmp/all/slawinski17_canonical.hpp" -a -e "$tmp/all/slawinski17_perfect.hpp"
"$bin" "$src/models/stuart_landau.sym" -o "$tmp/sl" >"$tmp/out" 2>"$tmp/err"
check "auto on an unobservable model exits 1" test $? -eq 1
check "auto names why canonical does not apply" grep -q "canonical: C1 fails" "$tmp/err"
check "auto failure writes nothing" test ! -e "$tmp/sl"
"$bin" "$src/models/slawinski17.sym" -o "$tmp/x" --method nonsense >"$tmp/out" 2>"$tmp/err"
check "unknown method diagnostic" grep -q "unknown method 'nonsense' (known: auto, all, canonical, perfect" "$tmp/err"

# Run-time parameters and --param.
"$bin" "$src/models/pendulum_params.sym" -o "$tmp/prm" --method canonical >"$tmp/out" 2>"$tmp/err"
check "free parameters become Params fields" grep -q "Scalar J = Scalar(1);  ///< default: centre of its box" "$tmp/prm/pendulum_params_canonical.hpp"
"$bin" "$src/models/pendulum_params.sym" -o "$tmp/prm_bound" --method canonical --param J=1.2 >"$tmp/out" 2>"$tmp/err"
check "--param binds: J is no longer a field" sh -c "! grep -q 'Scalar J = ' '$tmp/prm_bound/pendulum_params_canonical.hpp'"
check "--param binds: mgl stays a field" grep -q "Scalar mgl = " "$tmp/prm_bound/pendulum_params_canonical.hpp"
"$bin" check "$src/models/pendulum_params.sym" --param K=1 >"$tmp/out" 2>"$tmp/err"
check "--param unknown name" grep -q "the model has no parameter 'K'" "$tmp/err"
"$bin" check "$src/models/pendulum_params.sym" --param J=7 >"$tmp/out" 2>"$tmp/err"
check "--param outside the box" grep -q "outside its domain \[1/2, 3/2\]" "$tmp/err"
"$bin" check "$src/models/pendulum_params.sym" --param J=abc >"$tmp/out" 2>"$tmp/err"
check "--param malformed value" grep -q "is not a real number" "$tmp/err"
"$bin" check "$src/models/pendulum_params.sym" >"$tmp/out" 2>"$tmp/err"
check "check states the parameter box" grep -q "Free parameters mgl in \[1/2, 2\], b in \[1/10, 1/2\], J in \[1/2, 3/2\]" "$tmp/out"

# The usage example of the report compiles under the contract flags and runs.
if command -v python3 >/dev/null 2>&1 && command -v c++ >/dev/null 2>&1; then
  for m in slawinski17 pendulum_params; do
    dir=$tmp/auto
    [ "$m" = pendulum_params ] && dir=$tmp/prm
    python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['generated'][0]['usage_example'])" \
      "$dir/${m}_report.json" >"$tmp/usage_$m.cpp"
    c++ -std=c++17 -O1 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -fno-exceptions \
      -fno-rtti -I"$dir" -I"$src/runtime" -I/usr/include/eigen3 "$tmp/usage_$m.cpp" -o "$tmp/usage_$m" 2>"$tmp/err"
    check "usage example of $m compiles under the contract flags" test $? -eq 0
    "$tmp/usage_$m" >"$tmp/out" 2>&1
    check "usage example of $m runs" test $? -eq 0
  done
fi

# simulate: convergence, and a run that leaves the finite numbers stops with a diagnostic.
"$bin" simulate "$src/models/slawinski17.sym" --method canonical --u "sin(t)" --x0 0.5,-0.3 \
  --xhat0 0,0 --t-end 12 --dt 1e-3 -o "$tmp/sim" >"$tmp/out" 2>"$tmp/err"
check "simulate exits 0" test $? -eq 0
check "simulate CSV header" sh -c "head -1 '$tmp/sim/slawinski17_canonical.csv' | grep -qx 't,x1,x2,x1_hat,x2_hat'"
check "simulate converges" sh -c "tail -1 '$tmp/sim/slawinski17_canonical.csv' | awk -F, '{d1=\$2-\$4; d2=\$3-\$5; if (d1<0) d1=-d1; if (d2<0) d2=-d2; exit !(d1<1e-6 && d2<1e-6)}'"
"$bin" simulate "$src/models/slawinski17.sym" --method canonical --u "20 - 2*sqrt((t-5)^2)" \
  --x0 0.5,-0.3 --xhat0 0,0 --t-end 5 --dt 1e-3 -o "$tmp/simnan" >"$tmp/out" 2>"$tmp/err"
check "simulate divergence exits 1" test $? -eq 1
check "simulate divergence names system and time" grep -Eq "the (plant|observer) left the finite numbers at t = 0\.[67]" "$tmp/err"
check "simulate divergence keeps the CSV up to there" sh -c "test \$(wc -l < '$tmp/simnan/slawinski17_canonical.csv') -gt 100 && ! grep -qi nan '$tmp/simnan/slawinski17_canonical.csv'"
"$bin" simulate "$src/models/slawinski17.sym" --method canonical --u "sin(t)" --x0 0.5,-0.3 \
  --xhat0 0,0 --t-end 2 --dt 1e-3 -o "$tmp/sim2" >"$tmp/out" 2>"$tmp/err"
"$bin" simulate "$src/models/slawinski17.sym" --method canonical --u "sin(t)" --x0 0.5,-0.3 \
  --xhat0 0,0 --t-end 2 --dt 1e-3 -o "$tmp/sim3" >"$tmp/out" 2>"$tmp/err"
check "simulate SVG is deterministic" cmp -s "$tmp/sim2/slawinski17_canonical.svg" "$tmp/sim3/slawinski17_canonical.svg"
if command -v python3 >/dev/null 2>&1; then
  check "simulate SVG is well-formed XML" python3 -c "import sys, xml.dom.minidom; xml.dom.minidom.parse(sys.argv[1])" "$tmp/sim2/slawinski17_canonical.svg"
fi

# Determinism: byte-identical JSON between runs.
for m in slawinski17 triangular4 cstr lorenz flexible_joint; do
  "$bin" check "$src/models/$m.sym" --format json --no-timings >"$tmp/a.json"
  "$bin" check "$src/models/$m.sym" --format json --no-timings >"$tmp/b.json"
  check "deterministic JSON for $m" cmp -s "$tmp/a.json" "$tmp/b.json"
done
# ident_mm: GiNaC gives a squared sum either sign from run to run ((-a+b)^2 or (a-b)^2); the
# report prints one (half of the runs differed before the printer normalised it), in the model
# echo. --rank-method jets: the symbolic Lie chain would run into its 15 s budget on every run.
"$bin" check "$src/tests/models/ident_mm.sym" --no-timings --rank-method jets >"$tmp/a.txt" 2>&1
same=1
for run in 1 2 3 4 5 6; do
  "$bin" check "$src/tests/models/ident_mm.sym" --no-timings --rank-method jets >"$tmp/b.txt" 2>&1
  cmp -s "$tmp/a.txt" "$tmp/b.txt" || same=0
done
check "deterministic report for ident_mm (7 runs)" test $same -eq 1
# The main job over every design, twice, on a model whose Riccati header once differed.
"$bin" "$src/models/cstr.sym" -o "$tmp/cstr1" --method all >/dev/null 2>&1
"$bin" "$src/models/cstr.sym" -o "$tmp/cstr2" --method all >/dev/null 2>&1
check "deterministic main job for cstr" diff -r "$tmp/cstr1" "$tmp/cstr2"

# simulate: a converging run writes a CSV with the documented header and a well-formed,
# deterministic SVG.
for run in 1 2; do
  "$bin" simulate "$src/models/slawinski17.sym" --u "sin(t)" --x0 0.5,-0.5 --xhat0 0,0 \
    --t-end 5 --dt 0.01 -o "$tmp/sim$run" >"$tmp/out" 2>"$tmp/err"
  check "simulate run $run exits 0" test $? -eq 0
done
check "simulate CSV header" test "$(head -1 "$tmp/sim1/slawinski17_canonical.csv")" = "t,x1,x2,x1_hat,x2_hat"
check "simulate CSV is deterministic" cmp -s "$tmp/sim1/slawinski17_canonical.csv" "$tmp/sim2/slawinski17_canonical.csv"
check "simulate SVG is deterministic" cmp -s "$tmp/sim1/slawinski17_canonical.svg" "$tmp/sim2/slawinski17_canonical.svg"
check "simulate SVG has an svg root" grep -q "<svg" "$tmp/sim1/slawinski17_canonical.svg"
if command -v xmllint >/dev/null; then
  check "simulate SVG is well-formed XML" xmllint --noout "$tmp/sim1/slawinski17_canonical.svg"
fi

# simulate: the issue's divergence case stops with a message naming the time and the system,
# keeps the CSV up to the last finite sample and exits 1.
"$bin" simulate "$src/models/slawinski17.sym" --u "20 - 2*sqrt((t-5)^2)" --x0 0.5,-0.5 \
  --xhat0 0,0 --t-end 10 --dt 0.001 -o "$tmp/div" >"$tmp/out" 2>"$tmp/err"
check "diverging simulate exits 1" test $? -eq 1
check "diverging simulate names system and time" \
  grep -Eq "^obsynth: error: simulate: the (plant|observer[^ ]*) left the finite numbers at t = 0\.[67]" "$tmp/err"
check "diverging simulate keeps the CSV" test -s "$tmp/div/slawinski17_canonical.csv"
check "diverging simulate CSV is finite" \
  sh -c "! grep -Eqi 'nan|inf' '$tmp/div/slawinski17_canonical.csv'"
check "diverging simulate CSV ends before t = 1" \
  awk -F, 'END { exit !($1 > 0.5 && $1 < 1) }' "$tmp/div/slawinski17_canonical.csv"
check "diverging simulate summary has no false maximum at t = 1" \
  sh -c "! grep -q 'at t = 1$' '$tmp/out'"

# Methods: the registry is listed; auto refuses a non-linearizable model naming every design;
# unknown and planned methods have distinct diagnostics.
"$bin" --list-methods >"$tmp/out" 2>"$tmp/err"
check "--list-methods exits 0" test $? -eq 0
for m in canonical perfect riccati high-gain; do
  check "--list-methods names $m" grep -q "$m" "$tmp/out"
done
"$bin" "$src/models/stuart_landau.sym" -o "$tmp/lorenz_out" >"$tmp/out" 2>"$tmp/err"
check "auto on stuart_landau exits 1" test $? -eq 1
check "auto on stuart_landau names canonical" grep -q "canonical:" "$tmp/err"
check "auto on stuart_landau names perfect" grep -q "perfect:" "$tmp/err"
check "auto on stuart_landau names high-gain" grep -q "high-gain:" "$tmp/err"
check "auto on stuart_landau names kalman-theta" grep -q "kalman-theta:" "$tmp/err"
check "auto on stuart_landau names riccati" grep -q "riccati:" "$tmp/err"
check "auto on stuart_landau writes nothing" test ! -e "$tmp/lorenz_out"
# Lorenz (y = x1) is uniformly observable, but phi has no finite Lipschitz bound on the box
# (the denominator x1 of z = (h, L_f h, L_f^2 h)): high-gain's certificate withdraws it, and the
# report says why; auto takes another design.
"$bin" "$src/models/lorenz.sym" -o "$tmp/lorenz_hg" >"$tmp/out" 2>"$tmp/err"
check "auto on lorenz does not take high-gain" test ! -e "$tmp/lorenz_hg/lorenz_high-gain.hpp"
check "auto on lorenz writes an observer" test -s "$tmp/lorenz_hg/lorenz_auto.hpp"
check "lorenz report: high-gain withdrawn, theta* infinite" grep -q "high-gain.*theta\* = inf" "$tmp/lorenz_hg/lorenz_report.md"
# Strong persistence (seed 002): --input/--horizon in every format; JSON key "persistence".
"$bin" check "$src/models/dufour4.sym" --input "sin(t)" --horizon 20 --format json >"$tmp/p.json" 2>"$tmp/err"
check "persistence json exits 0" test $? -eq 0
check "persistence: sin t is strongly persistent" test "$(jq '.persistence.strongly_persistent' "$tmp/p.json")" = true
"$bin" check "$src/models/dufour4.sym" --input "0" --horizon 20 --format json >"$tmp/p0.json" 2>"$tmp/err"
check "persistence: u = 0 is not" test "$(jq '.persistence.strongly_persistent' "$tmp/p0.json")" = false
for fmt in text markdown latex; do
  "$bin" check "$src/models/dufour4.sym" --input "0" --horizon 20 --format $fmt >"$tmp/p.$fmt" 2>"$tmp/err"
  check "persistence in $fmt" grep -q "not strongly persistent" "$tmp/p.$fmt"
done
"$bin" check "$src/models/dufour4.sym" --input "sin(t), t" --horizon 20 >"$tmp/out" 2>"$tmp/err"
check "persistence: wrong input count exits 1" test $? -eq 1
check "persistence: wrong input count diagnostic" grep -q "\-\-input needs 1 expression in t" "$tmp/err"
for m in high-gain kalman-theta; do
  "$bin" simulate "$src/models/vanderpol.sym" --method $m --u "0.5*sin(t)" --x0 1,0 --xhat0 0,0.5 --t-end 5 -o "$tmp/sim_$m" >"$tmp/out" 2>"$tmp/err"
  check "simulate --method $m exits 0" test $? -eq 0
  check "simulate --method $m writes the csv" test -s "$tmp/sim_$m/vanderpol_$m.csv"
done
"$bin" "$src/models/slawinski17.sym" -o "$tmp/m1" --method bogus >"$tmp/out" 2>"$tmp/err"
check "unknown method exits 1" test $? -eq 1
check "unknown method diagnostic" grep -q "unknown method 'bogus' (known: auto, all, " "$tmp/err"
if [ -n "$planned" ]; then
  "$bin" "$src/models/slawinski17.sym" -o "$tmp/m2" --method "$planned" >"$tmp/out" 2>"$tmp/err"
  check "planned method exits 1" test $? -eq 1
  check "planned method diagnostic" grep -q "method '$planned' is not implemented in this version" "$tmp/err"
fi
"$bin" "$src/models/slawinski17.sym" -o "$tmp/m3" --method riccati --Q0 1,2,3,1 >"$tmp/out" 2>"$tmp/err"
check "riccati: non-symmetric --Q0 exits 1" test $? -eq 1
check "riccati: --Q0 diagnostic" grep -q -- "--Q0: not symmetric" "$tmp/err"
"$bin" "$src/models/lorenz.sym" -o "$tmp/ric" --method riccati >"$tmp/out" 2>"$tmp/err"
check "riccati alone exits 0" test $? -eq 0
check "riccati alone writes its header" test -e "$tmp/ric/lorenz_riccati.hpp"
check "riccati alone skips the canonical stages" grep -q "not analysed: the methods asked for do not need the canonical form" "$tmp/ric/lorenz_report.md"
"$bin" "$src/models/slawinski17.sym" -o "$tmp/all" --method all >"$tmp/out" 2>"$tmp/err"
check "--method all exits 0" test $? -eq 0
check "--method all writes canonical" test -s "$tmp/all/slawinski17_canonical.hpp"
check "--method all writes perfect" test -s "$tmp/all/slawinski17_perfect.hpp"

# --param binds at synthesis: the bound field leaves Params, the others stay.
"$bin" "$src/models/pendulum_params.sym" -o "$tmp/pp" --method canonical --param mgl=1 \
  >"$tmp/out" 2>"$tmp/err"
check "--param mgl=1 exits 0" test $? -eq 0
check "--param mgl=1 removes the field" sh -c "! grep -q 'Scalar mgl =' '$tmp/pp/pendulum_params_canonical.hpp'"
check "--param mgl=1 keeps b" grep -q "Scalar b =" "$tmp/pp/pendulum_params_canonical.hpp"
"$bin" "$src/models/pendulum_params.sym" -o "$tmp/pq" --param nope=1 >"$tmp/out" 2>"$tmp/err"
check "--param unknown name exits 1" test $? -eq 1
check "--param unknown name diagnostic" grep -q "the model has no parameter 'nope'" "$tmp/err"
"$bin" "$src/models/pendulum_params.sym" -o "$tmp/pq" --param mgl=7 >"$tmp/out" 2>"$tmp/err"
check "--param outside box exits 1" test $? -eq 1
check "--param outside box diagnostic" grep -q "mgl=7: outside its domain \[1/2, 2\]" "$tmp/err"
for bad in mgl=abc mgl= =1 mgl; do
  "$bin" "$src/models/pendulum_params.sym" -o "$tmp/pq" --param "$bad" >"$tmp/out" 2>"$tmp/err"
  check "--param '$bad' exits 1" test $? -eq 1
  check "--param '$bad' has a diagnostic" grep -q "error: --param" "$tmp/err"
done
check "--param failures write nothing" test ! -e "$tmp/pq"

# The report's usage example is a complete program: it compiles under the contract flags and
# runs (exit 0), for a model without and one with run-time parameters.
cxx=${CXX:-c++}
eigen=$(pkg-config --cflags eigen3 2>/dev/null || echo -I/usr/include/eigen3)
for m in slawinski17 pendulum_params; do
  "$bin" "$src/models/$m.sym" -o "$tmp/use_$m" --method canonical >"$tmp/out" 2>"$tmp/err"
  check "usage: $m generates" test $? -eq 0
  jq -r '.generated[0].usage_example' "$tmp/use_$m/${m}_report.json" >"$tmp/use_$m/main.cpp"
  check "usage: $m example is non-empty" grep -q "int main()" "$tmp/use_$m/main.cpp"
  # shellcheck disable=SC2086
  "$cxx" -std=c++17 -O1 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic \
    -fno-exceptions -fno-rtti -I"$tmp/use_$m" -I"$src/runtime" $eigen \
    "$tmp/use_$m/main.cpp" -o "$tmp/use_$m/main" 2>"$tmp/err"
  check "usage: $m example compiles under the contract flags" test $? -eq 0
  check "usage: $m example runs" "$tmp/use_$m/main"
done

# simulate --method auto names the design it ran (a stderr note, the summary, the file names);
# --plant-param sets a free parameter in the plant alone, and refuses other names (issue 17).
"$bin" simulate "$src/models/slawinski17.sym" --method auto --u "sin(t)" --x0 0.5,-0.5 \
  --xhat0 0,0 --t-end 1 --dt 0.01 -o "$tmp/simauto" >"$tmp/out" 2>"$tmp/err"
check "simulate auto exits 0" test $? -eq 0
chosen=$(sed -n "s/^obsynth: note: auto: chose '\([a-z-]*\)'.*/\1/p" "$tmp/err")
check "simulate auto names the design on stderr" test -n "$chosen"
check "simulate auto names the design in the summary" \
  grep -q "^observer: $chosen (auto: chose '$chosen'" "$tmp/out"
check "simulate auto CSV carries the design's name" test -s "$tmp/simauto/slawinski17_$chosen.csv"
check "simulate auto SVG carries the design's name" test -s "$tmp/simauto/slawinski17_$chosen.svg"
check "simulate auto writes no _auto files" test ! -e "$tmp/simauto/slawinski17_auto.csv"
"$bin" simulate "$src/models/pendulum_params.sym" --method canonical --x0 1,0 --xhat0 0,0 \
  --t-end 1 --dt 0.01 -o "$tmp/simpp" --param mgl=1 --plant-param mgl=1.9 --plant-param J=1.2 \
  >"$tmp/out" 2>"$tmp/err"
check "simulate --plant-param exits 0" test $? -eq 0
check "simulate --plant-param names plant and observer values" \
  grep -q "plant parameters: mgl = 1.9 (observer: 1); J = 1.2 (observer: 1)" "$tmp/out"
plant_param_fails() {  # name, model, state count, --plant-param value, expected diagnostic
  local x0
  x0=$(printf '0%.0s,' $(seq "$3"))
  "$bin" simulate "$src/models/$2.sym" --method canonical --x0 "${x0%,}" --xhat0 "${x0%,}" \
    --t-end 0.1 -o "$tmp/simbad" --plant-param "$4" >"$tmp/out" 2>"$tmp/err"
  check "simulate --plant-param $1 exits 1" test $? -eq 1
  check "simulate --plant-param $1 diagnostic" grep -qF "error: --plant-param $5" "$tmp/err"
}
plant_param_fails "unknown name" pendulum_params 2 nope=1 \
  "nope: the model has no parameter 'nope' (its free parameters: mgl, b, J)"
plant_param_fails "fixed parameter" stuart_landau 2 mu=2 "mu: 'mu' is not a free parameter"
plant_param_fails "bad value" pendulum_params 2 mgl=abc "mgl=abc"
plant_param_fails "no value" pendulum_params 2 mgl "'mgl': expected name=value"
check "simulate --plant-param failures write nothing" test ! -e "$tmp/simbad"
# Names engineers write (issue 17 item 7): a dilution rate D, a pump current I, a state y, and a
# domain wrapped after its commas. Oracle: the same model with neutral names (Dil, v, b) must
# give the same trajectories; the generated code compiles under the contract flags, C and C++.
cat >"$tmp/bio.sym" <<'SYM'
# chemostat: substrate S, biomass y (measured), feed driven by the pump current I
model bioreactor
states S y
inputs I
params D, mu = 1, K = 1, Yield = 1/2
f = [ -D*S - mu*S/(K + S)*y/Yield, mu*S/(K + S)*y - D*y ]
g = [ I, 0 ]
h = [ y ]
domain S in [0.05, 4],   # substrate
       y in [0.05, 2],
       I in [0, 2], D in [0.2, 0.4]
SYM
sed -e 's/\bD\b/Dil/g; s/\by\b/b/g; s/\bI\b/v/g' "$tmp/bio.sym" >"$tmp/bio_plain.sym"
"$bin" check "$tmp/bio.sym" >"$tmp/bio_check" 2>"$tmp/err"
check "names D, I, y: check exits 0" test $? -eq 0
check "names D, I, y: check keeps the user's names" grep -q "states: S, y; m = 1 inputs: I" "$tmp/bio_check"
check "names D, I, y: the domain continues after ','" grep -q "Free parameters D in \[1/5, 2/5\]" "$tmp/bio_check"
for lang in cpp c; do
  rm -rf "$tmp/bio_$lang"
  "$bin" "$tmp/bio.sym" -o "$tmp/bio_$lang" --method auto,riccati --language "$lang" >"$tmp/out" 2>"$tmp/err"
  check "names D, I, y: main job ($lang) exits 0" test $? -eq 0
  check "names D, I, y: main job ($lang) writes bioreactor_report.md" test -s "$tmp/bio_$lang/bioreactor_report.md"
done
check "names D, I, y: C++ accessors keep the names" grep -q "constexpr int y = 1;" "$tmp/bio_cpp/bioreactor_riccati.hpp"
check "names D, I, y: C++ parameter field D" grep -q "Scalar D = " "$tmp/bio_cpp/bioreactor_riccati.hpp"
check "names D, I, y: C parameter field D" grep -q "_scalar D;" "$tmp/bio_c/bioreactor_riccati.h"
for hpp in "$tmp"/bio_cpp/*.hpp; do
  printf '#include "%s"\nint main() { return 0; }\n' "$(basename "$hpp")" >"$tmp/bio_inc.cpp"
  # shellcheck disable=SC2086
  "$cxx" -std=c++17 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -fno-exceptions \
    -fno-rtti -I"$tmp/bio_cpp" -I"$src/runtime" $eigen -c "$tmp/bio_inc.cpp" -o "$tmp/bio_inc.o" 2>"$tmp/err"
  check "names D, I, y: $(basename "$hpp") compiles under the contract flags" test $? -eq 0
done
jq -r '.generated[0].usage_example' "$tmp/bio_cpp/bioreactor_report.json" >"$tmp/bio_cpp/main.cpp"
# shellcheck disable=SC2086
"$cxx" -std=c++17 -O1 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -fno-exceptions \
  -fno-rtti -I"$tmp/bio_cpp" -I"$src/runtime" $eigen "$tmp/bio_cpp/main.cpp" -o "$tmp/bio_cpp/main" 2>"$tmp/err"
check "names D, I, y: C++ usage example compiles" test $? -eq 0
if command -v cc >/dev/null 2>&1; then
  jq -r '.generated[0].usage_example' "$tmp/bio_c/bioreactor_report.json" >"$tmp/bio_main.c"
  cc -std=c99 -O1 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -I"$tmp/bio_c" -I"$src/runtime" \
    "$tmp/bio_main.c" "$tmp"/bio_c/*.c -lm -o "$tmp/bio_main" 2>"$tmp/err"
  check "names D, I, y: C sources and usage example compile" test $? -eq 0
fi
for method in riccati kou; do
  for m in bio bio_plain; do
    "$bin" simulate "$tmp/$m.sym" --method "$method" --u "1" --x0 0.5,1.2 --xhat0 0.6,1.0 \
      --t-end 20 --dt 1e-3 -o "$tmp/sim_$m" >"$tmp/out" 2>"$tmp/err"
    check "names D, I, y: simulate $method ($m) exits 0" test $? -eq 0
  done
  check "names D, I, y: simulate CSV header keeps the names" \
    sh -c "head -1 '$tmp/sim_bio/bioreactor_$method.csv' | grep -qx 't,S,y,S_hat,y_hat'"
  # Same trajectories as with neutral names (to 1e-9: GiNaC orders terms by name), converged.
  check "names D, I, y: simulate $method equals the neutral-name run and converges" \
    awk -F, 'NR == FNR { a[FNR] = $0; next }
             FNR > 1 { split(a[FNR], p, ","); for (i = 1; i <= NF; ++i) { d = p[i] - $i; if (d < 0) d = -d; if (d > 1e-9) bad = 1 } }
             END { d1 = $2 - $4; d2 = $3 - $5; if (d1 < 0) d1 = -d1; if (d2 < 0) d2 = -d2; exit bad || d1 > 1e-6 || d2 > 1e-6 || NR != 2 * FNR }' \
      "$tmp/sim_bio/bioreactor_$method.csv" "$tmp/sim_bio_plain/bioreactor_$method.csv"
done

# States named y and z1 (the names of the measured output and of the canonical coordinates):
# slawinski17 with x1 -> y, x2 -> z1, u -> I runs canonical, perfect and kalman-theta like the
# original, and its canonical header compiles.
sed -e 's/\bx1\b/y/g; s/\bx2\b/z1/g; s/\bu\b/I/g' "$src/models/slawinski17.sym" >"$tmp/slaw_yz.sym"
"$bin" "$tmp/slaw_yz.sym" -o "$tmp/slaw_yz" --method canonical,perfect >"$tmp/out" 2>"$tmp/err"
check "states y, z1: main job exits 0" test $? -eq 0
"$bin" check "$tmp/slaw_yz.sym" >"$tmp/out" 2>"$tmp/err"
check "states y, z1: canonical coordinates and output give way" grep -q "^  y_ = z_2 + h(x0)" "$tmp/out"
check "states y, z1: T^-1 names the state z1" grep -q "z1 = y^2/2-z_1   (from T_1 = z_1)" "$tmp/out"
printf '#include "slawinski17_canonical.hpp"\nint main() { obsynth_gen::slawinski17::Slawinski17Canonical<float> o; return o.step(0.01f, {}, {}) == obsynth::Status::ok ? 0 : 1; }\n' >"$tmp/slaw_yz.cpp"
# shellcheck disable=SC2086
"$cxx" -std=c++17 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -fno-exceptions \
  -fno-rtti -I"$tmp/slaw_yz" -I"$src/runtime" $eigen "$tmp/slaw_yz.cpp" -o "$tmp/slaw_yz_main" 2>"$tmp/err"
check "states y, z1: canonical header compiles under the contract flags" test $? -eq 0
for method in canonical perfect kalman-theta; do
  for m in "$src/models/slawinski17.sym" "$tmp/slaw_yz.sym"; do
    "$bin" simulate "$m" --method "$method" --u "sin(t)" --x0 0.5,-0.3 --xhat0 0,0 --t-end 6 \
      --dt 1e-3 -o "$tmp/sim_$(basename "$m" .sym)" >"$tmp/out" 2>"$tmp/err"
    check "states y, z1: simulate $method ($(basename "$m")) exits 0" test $? -eq 0
  done
  check "states y, z1: simulate $method equals the original" \
    awk -F, 'NR == FNR { a[FNR] = $0; next }
             FNR > 1 { split(a[FNR], p, ","); for (i = 1; i <= NF; ++i) { d = p[i] - $i; if (d < 0) d = -d; if (d > 1e-9) bad = 1 } }
             END { exit bad || NR != 2 * FNR }' \
      "$tmp/sim_slawinski17/slawinski17_$method.csv" "$tmp/sim_slaw_yz/slawinski17_$method.csv"
done

# Two outputs (issue 18): two_block, linearizable in the block canonical form. The main job with
# no options takes canonical; every design that handles p = 2 emits a C++ header and a C99
# source that compile under the contract flags, and simulate converges with each.
"$bin" "$src/models/two_block.sym" -o "$tmp/two_block" >"$tmp/out" 2>"$tmp/err"
check "two outputs: main job exits 0" test $? -eq 0
check "two outputs: auto chose canonical with a rigorous guarantee" \
  grep -q "auto: chose 'canonical' (guarantee rigorous" "$tmp/out"
"$bin" check "$src/models/two_block.sym" >"$tmp/out" 2>"$tmp/err"
check "two outputs: check prints the blocks" grep -q "^  blocks k = (2, 2)" "$tmp/out"
check "two outputs: check prints l with both outputs" grep -q "^  y2 = z4 + h2(x0)" "$tmp/out"
for method in canonical perfect high-gain kalman-theta riccati; do
  "$bin" "$src/models/two_block.sym" -o "$tmp/two_$method" --method "$method" >"$tmp/out" 2>"$tmp/err"
  check "two outputs: $method emits (exit 0)" test $? -eq 0
  "$bin" "$src/models/two_block.sym" -o "$tmp/two_${method}_c" --method "$method" --language c \
    >"$tmp/out" 2>"$tmp/err"
  check "two outputs: $method emits C99 (exit 0)" test $? -eq 0
  cls=$(grep -o "class TwoBlock[A-Za-z]*" "$tmp/two_$method/two_block_$method.hpp" | head -1 | cut -d' ' -f2)
  printf '#include "two_block_%s.hpp"\nint main() { obsynth_gen::two_block::%s<float> o; obsynth_gen::two_block::%s<float>::Output y; y << 0.1f, -0.2f; return o.step(0.01f, {}, y) == obsynth::Status::ok ? 0 : 1; }\n' \
    "$method" "$cls" "$cls" >"$tmp/two_$method.cpp"
  # shellcheck disable=SC2086
  "$cxx" -std=c++17 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -fno-exceptions \
    -fno-rtti -I"$tmp/two_$method" -I"$src/runtime" $eigen "$tmp/two_$method.cpp" \
    -o "$tmp/two_${method}_main" 2>"$tmp/err"
  check "two outputs: $method header compiles and steps" "$tmp/two_${method}_main"
  cc -std=c99 -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -I"$src/runtime" \
    -c "$tmp/two_${method}_c/"*.c -o "$tmp/two_$method.o" 2>"$tmp/err"
  check "two outputs: $method C99 compiles under the strict flags" test $? -eq 0
  "$bin" simulate "$src/models/two_block.sym" --method "$method" --u "0.5*sin(t)" \
    --x0 0.5,-0.3,0.2,0.1 --xhat0 0.3,-0.1,0,0.3 --t-end 15 --dt 1e-3 -o "$tmp/sim_two" \
    >"$tmp/out" 2>"$tmp/err"
  check "two outputs: simulate $method exits 0" test $? -eq 0
  check "two outputs: simulate $method converges (final error < 1e-3)" \
    awk -F, 'END { e = 0; for (i = 2; i <= 5; ++i) { d = $i - $(i + 4); if (d < 0) d = -d; if (d > e) e = d } exit !(e < 1e-3) }' \
    "$tmp/sim_two/two_block_$method.csv"
done

echo "cli: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
