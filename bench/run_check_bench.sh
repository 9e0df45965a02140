#!/usr/bin/env bash
# Runs `obsynth check --format json` on every generated benchmark model (bench/families.hpp:
# chain, cubic, sine at n = 2, 4, 8, 12, 16) under a per-stage time budget, measures wall
# time, CPU time and peak memory with /usr/bin/time, and prints a markdown table.
#
#   bench/run_check_bench.sh [--build DIR] [--stage-seconds S] [--families "chain cubic sine"]
#                            [--sizes "2 4 8 12 16"] [--mem-limit-mib M] [--out DIR]
#   bench/run_check_bench.sh --compare [--families "nested dense"] [--sizes "2 4 8 12 16"]
#                            [--repeats R] [--sympy-repeats R] [--sympy-timeout S] [...]
#
# --compare: obsynth check and bench/sympy_check.py (a straightforward SymPy script of the
# same pipeline) side by side on the issue 6 families (nested: the chain family; dense: the
# same through x = M w), each under bench/timed_run: median wall time and median peak RSS
# over the repeats (defaults 3 for obsynth, 1 for SymPy), and the ratio SymPy / obsynth.
# SymPy runs under --sympy-timeout (default 300 s) per model; a timeout shows as "> S".
#
# Defaults: --build build, --stage-seconds 30, --mem-limit-mib 8192 (address-space limit per
# run, so a runaway expression swell fails cleanly instead of exhausting the machine),
# --out <build>/bench/results (raw JSON reports and stderr of every run).
#
# Budget arithmetic: a run stops at the first stage that exceeds S seconds, so a model costs
# at most 5*S (five stages each just under S); in practice the models that miss their
# budget do so in one stage. With S = 30 the whole table takes about 4 minutes on this 2-core
# machine (5 models stop at the budget); S = 60 takes about 7.
#
# The issue's targets: chain n = 16 under 2 s; cubic and sine n = 8 under 5 s; cubic and sine
# n = 12, 16 finish within the budget or stop with a clear budget diagnostic.
#
# Times are wall times; the per-stage times come from the report (steady clock in the
# worker). The load average is printed, since other jobs on the machine inflate wall time;
# the "cpu s" column (user + sys) is the load-independent figure.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
build="$root/build"
stage_seconds=30
families="chain cubic sine"
sizes="2 4 8 12 16"
mem_limit_mib=8192
out=""
compare=0
repeats=3
sympy_repeats=1
sympy_timeout=300

while [ $# -gt 0 ]; do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --stage-seconds) stage_seconds="$2"; shift 2 ;;
    --families) families="$2"; shift 2 ;;
    --sizes) sizes="$2"; shift 2 ;;
    --mem-limit-mib) mem_limit_mib="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --compare) compare=1; shift ;;
    --repeats) repeats="$2"; shift 2 ;;
    --sympy-repeats) sympy_repeats="$2"; shift 2 ;;
    --sympy-timeout) sympy_timeout="$2"; shift 2 ;;
    -h|--help) sed -n '2,36p' "$0"; exit 0 ;;
    *) echo "run_check_bench.sh: unknown argument '$1'" >&2; exit 1 ;;
  esac
done
case "$build" in /*) ;; *) build="$PWD/$build" ;; esac
[ -n "$out" ] || out="$build/bench/results"

obsynth="$build/synth/obsynth"
summary="$build/bench/check_summary"
gen="$build/bench/gen_family"
timed_run="$build/bench/timed_run"
models="$build/bench/models"
timebin=/usr/bin/time
for tool in "$obsynth" "$summary" "$gen" "$timed_run"; do
  if [ ! -x "$tool" ]; then
    echo "run_check_bench.sh: $tool not found; build first: cmake -S . -B build -G Ninja && ninja -C build" >&2
    exit 1
  fi
done
if [ ! -x "$timebin" ]; then
  echo "run_check_bench.sh: $timebin missing (apt-get install time, or scripts/install-deps.sh)" >&2
  exit 1
fi
mkdir -p "$out"
"$gen" "$models"

# timed TIME_FILE OUT_FILE ERR_FILE COMMAND...: runs the command under bench/timed_run (the
# address-space limit, wall time from fork to reaping, peak RSS from wait4); prints
# "<wall s> <peak RSS MiB> <exit status>" and keeps that line in TIME_FILE. A shell subshell
# with ulimit and /usr/bin/time -v cost 3-4 ms per run itself, most of a small check.
timed() {
  local tfile="$1" ofile="$2" efile="$3"; shift 3
  "$timed_run" "$mem_limit_mib" "$ofile" "$efile" "$@" | tee "$tfile"
}

median() {  # numbers on stdin -> their median
  sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "-"; else if (NR % 2) print v[(NR + 1) / 2]; else printf "%.3f\n", (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}

if [ "$compare" = 1 ]; then
  [ "$families" = "chain cubic sine" ] && families="nested dense"
  sympy_script="$here/sympy_check.py"
  echo "## obsynth check vs SymPy (bench/sympy_check.py)"
  echo
  echo "- $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "- medians over $repeats obsynth runs and $sympy_repeats SymPy runs; SymPy timeout ${sympy_timeout} s per model; obsynth --stage-seconds $stage_seconds"
  echo
  echo "| family | n | obsynth s | obsynth RSS MiB | obsynth result | SymPy s | SymPy RSS MiB | SymPy result | SymPy / obsynth |"
  echo "|---|---:|---:|---:|---|---:|---:|---|---:|"
  for f in $families; do
    for n in $sizes; do
      model="$models/${f}_n${n}.sym"
      [ -f "$model" ] || "$gen" "$models" "$f" "$n"
      walls=(); rsss=(); rc=0
      for ((r = 0; r < repeats; ++r)); do
        read -r w m rc < <(timed "$out/${f}_n${n}.otime" "$out/${f}_n${n}.json" \
          "$out/${f}_n${n}.stderr" "$obsynth" check "$model" --format json \
          --stage-seconds "$stage_seconds")
        walls+=("$w"); rsss+=("$m")
      done
      ow=$(printf '%s\n' "${walls[@]}" | median); orss=$(printf '%s\n' "${rsss[@]}" | median)
      if [ "$rc" = 0 ]; then
        oresult=$("$summary" "$out/${f}_n${n}.json" | cut -f1)
      else
        oresult="exit $rc: $(head -n 1 "$out/${f}_n${n}.stderr" | cut -c1-80)"
      fi
      walls=(); rsss=(); src=0
      for ((r = 0; r < sympy_repeats; ++r)); do
        read -r w m src < <(timed "$out/${f}_n${n}.stime" "$out/${f}_n${n}.sympy" \
          "$out/${f}_n${n}.sympy_stderr" timeout "$((sympy_timeout + 10))" \
          python3 "$sympy_script" "$model" --timeout "$sympy_timeout")
        walls+=("$w"); rsss+=("$m")
      done
      sw=$(printf '%s\n' "${walls[@]}" | median); srss=$(printf '%s\n' "${rsss[@]}" | median)
      sresult=$(sed -n 's/.*"result": "\([^"]*\)".*/\1/p' "$out/${f}_n${n}.sympy" | head -n 1)
      [ -n "$sresult" ] || sresult="exit $src"
      if [ "$src" = 0 ]; then
        ratio=$(awk -v s="$sw" -v o="$ow" 'BEGIN { if (o > 0) printf "%.0fx", s / o; else print "-" }')
      else
        sw="> $sympy_timeout"
        ratio=$(awk -v s="$sympy_timeout" -v o="$ow" 'BEGIN { if (o > 0) printf "> %.0fx", s / o; else print "-" }')
      fi
      echo "| $f | $n | $ow | $orss | $oresult | $sw | $srss | $sresult | $ratio |"
    done
  done
  echo
  echo "- load average at end: $(cut -d' ' -f1-3 /proc/loadavg); raw output in $out"
  exit 0
fi

target_for() {  # family n -> target description and limit in seconds ("" = no time target)
  local f="$1" n="$2"
  if [ "$f" = chain ] && [ "$n" = 16 ]; then echo "< 2 s|2"; return; fi
  if [ "$f" != chain ] && [ "$n" = 8 ]; then echo "< 5 s|5"; return; fi
  if [ "$f" != chain ] && { [ "$n" = 12 ] || [ "$n" = 16 ]; }; then echo "finish or budget diagnostic|"; return; fi
  echo "-|"
}

stages="lie observability frame conditions diffeomorphism"
started=$(date +%s)
echo "## obsynth check benchmark"
echo
echo "- $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "- per-stage budget: --stage-seconds $stage_seconds; address-space limit ${mem_limit_mib} MiB per run"
echo "- command: obsynth check MODEL --format json --stage-seconds $stage_seconds (models in $models)"
echo
echo "| family | n | total s | cpu s | lie ms | observability ms | frame ms | conditions ms | diffeomorphism ms | peak RSS MiB | result | target |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|"
for f in $families; do
  for n in $sizes; do
    model="$models/${f}_n${n}.sym"
    if [ ! -f "$model" ]; then
      "$gen" "$models" "$f" "$n"
    fi
    json="$out/${f}_n${n}.json"
    err="$out/${f}_n${n}.stderr"
    tfile="$out/${f}_n${n}.time"
    set +e
    (
      ulimit -v $((mem_limit_mib * 1024))
      exec "$timebin" -f "%e %U %S %M" -o "$tfile" \
        "$obsynth" check "$model" --format json --stage-seconds "$stage_seconds" >"$json" 2>"$err"
    )
    rc=$?
    set -e
    read -r wall user sys maxrss_kib < <(tail -n 1 "$tfile")
    cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')
    rss=$(awk -v k="$maxrss_kib" 'BEGIN { printf "%.0f", k / 1024 }')
    declare -A ms=()
    for s in $stages; do ms[$s]="-"; done
    if [ "$rc" -eq 0 ]; then
      IFS=$'\t' read -r result t_lie t_obs t_frame t_cond t_diff < <("$summary" "$json")
      ms[lie]=$t_lie; ms[observability]=$t_obs; ms[frame]=$t_frame
      ms[conditions]=$t_cond; ms[diffeomorphism]=$t_diff
    else
      stage=$(sed -n "s/.*stage '\([a-z]*\)' exceeded its time budget.*/\1/p" "$err" | head -n 1)
      sized=$(sed -n "s/.*stage '\([a-z]*\)' exceeded its expression-size budget.*/\1/p" "$err" | head -n 1)
      if [ -n "$stage" ]; then
        result="budget exceeded in stage $stage (${stage_seconds} s)"
        ms[$stage]="> $((stage_seconds * 1000))"
      elif [ -n "$sized" ]; then
        result="expression-size budget exceeded in stage $sized"
      elif grep -q "bad_alloc" "$err"; then
        result="out of memory (${mem_limit_mib} MiB limit)"
      else
        result="error (exit $rc): $(head -n 1 "$err" | cut -c1-120)"
      fi
    fi
    IFS='|' read -r target limit < <(target_for "$f" "$n")
    verdict="$target"
    if [ -n "$limit" ]; then
      if [ "$rc" -eq 0 ] && awk -v w="$wall" -v l="$limit" 'BEGIN { exit !(w < l) }'; then
        verdict="$target: met"
      else
        verdict="$target: **missed**"
      fi
    elif [ "$target" != "-" ]; then
      if [ "$rc" -eq 0 ] || [ -n "${stage:-}" ] || [ -n "${sized:-}" ]; then verdict="$target: met"; else verdict="$target: **missed**"; fi
    fi
    echo "| $f | $n | $wall | $cpu | ${ms[lie]} | ${ms[observability]} | ${ms[frame]} | ${ms[conditions]} | ${ms[diffeomorphism]} | $rss | $result | $verdict |"
    unset ms stage sized
  done
done
echo
echo "- load average at end: $(cut -d' ' -f1-3 /proc/loadavg); whole run $(( $(date +%s) - started )) s; raw reports in $out"
