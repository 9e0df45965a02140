#!/usr/bin/env bash
# ns/step (Google Benchmark) and instructions/step (callgrind) of the generated vs the
# hand-written seed 003 canonical observer, in double and float; with --chains also of the
# generated observers of the constructed chains, n = 2..8: chain<n>_stable (z realisation,
# closed-form T^-1), chain<n>_newton (obsynth's default for it: x realisation) and
# chain<n>_newton_z (--realisation z: T^-1 by runtime Newton).
#
#   bench/observer/instructions.sh [--chains] [BUILD_DIR]       (BUILD_DIR default: build)
#
# Environment: N (steps for callgrind; runs N and 2N, default 20000), REPS (benchmark
# repetitions, default 10), MIN_TIME (seconds per repetition, default 0.1).
#
# Instructions per step = (Ir(2N) - Ir(N)) / N from two callgrind runs of count_steps, so the
# setup (plant simulation, sample conversion, process start) cancels. ns/step is the median
# over REPS repetitions (randomly interleaved) of the CPU time per iteration reported by
# bench_observer. Results (JSON, callgrind totals, the table) go to BUILD_DIR/bench/observer/results.
set -euo pipefail

chains=0
if [[ "${1:-}" == "--chains" ]]; then
  chains=1
  shift
fi
src_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${1:-${src_dir}/build}"
N="${N:-20000}"
REPS="${REPS:-10}"
MIN_TIME="${MIN_TIME:-0.1}"
command -v valgrind >/dev/null || { echo "valgrind not found" >&2; exit 1; }
command -v python3 >/dev/null || { echo "python3 not found" >&2; exit 1; }

if [[ ! -f "${build}/build.ninja" ]]; then
  cmake -S "${src_dir}" -B "${build}" -G Ninja >/dev/null
fi
if (( chains )); then
  bench=bench_observer_chains
  count=count_steps_chains
else
  bench=bench_observer
  count=count_steps
fi
ninja -C "${build}" "${bench}" "${count}" >&2
bin="${build}/bench/observer"
out="${bin}/results"
mkdir -p "${out}"

# ---- time ------------------------------------------------------------------------------------
echo "running ${bench} (${REPS} repetitions x ${MIN_TIME} s)..." >&2
"${bin}/${bench}" --benchmark_repetitions="${REPS}" --benchmark_min_time="${MIN_TIME}" \
  --benchmark_enable_random_interleaving=true --benchmark_report_aggregates_only=true \
  --benchmark_out="${out}/${bench}.json" --benchmark_out_format=json >&2

# ---- instructions ----------------------------------------------------------------------------
observers=(generated handwritten expert)
if (( chains )); then
  for n in 2 3 4 5 6 7 8; do observers+=("chain${n}_stable" "chain${n}_newton" "chain${n}_newton_z"); done
fi
ir() {  # ir OBSERVER SCALAR STEPS -> total instructions executed (and STEPS, failed steps in .stdout)
  local f="${out}/callgrind.$1.$2.$3.out"
  valgrind --tool=callgrind --callgrind-out-file="${f}" "${bin}/${count}" "$1" "$2" "$3" >"${f}.stdout" 2>"${f}.log" ||
    { echo "count_steps $1 $2 $3 failed (see ${f}.log)" >&2; return 1; }
  awk '/^(summary|totals):/ { print $2; exit }' "${f}"
}
: >"${out}/instructions.tsv"
for o in "${observers[@]}"; do
  for s in double float; do
    a=$(ir "${o}" "${s}" "${N}")
    b=$(ir "${o}" "${s}" $((2 * N)))
    fails=$(sed -n 's/.*failures=\([0-9]*\).*/\1/p' "${out}/callgrind.${o}.${s}.$((2 * N)).out.stdout")
    printf '%s\t%s\t%s\t%s\t%s\t%s\n' "${o}" "${s}" "${N}" "${a}" "${b}" "${fails}" >>"${out}/instructions.tsv"
    echo "callgrind ${o} ${s}: Ir(N)=${a} Ir(2N)=${b} failed steps in 2N: ${fails}" >&2
  done
done

# ---- table -----------------------------------------------------------------------------------
python3 - "${out}/${bench}.json" "${out}/instructions.tsv" <<'EOF' | tee "${out}/table.md"
import json, sys
bench = json.load(open(sys.argv[1]))
ns = {}
for b in bench["benchmarks"]:
    if b.get("aggregate_name") == "median":
        assert b["time_unit"] == "ns"
        ns[b["run_name"]] = b["cpu_time"]
ins = {}
fails = {}
for line in open(sys.argv[2]):
    o, s, n, a, b, f = line.split()
    ins[(o, s)] = (int(b) - int(a)) / int(n)
    if int(f):
        fails[(o, s)] = (int(f), 2 * int(n))

def key(o, s):
    return f"seed003/{o}/{s}" if o in ("generated", "handwritten", "expert") else f"{o}/{s}"

ctx = bench["context"]
print(f"Flags: {ctx.get('compile_flags', '?')}; CPU time, median of the repetitions; "
      f"{ctx.get('num_cpus')} x {ctx.get('mhz_per_cpu')} MHz; load average {ctx.get('load_avg')}")
print()
print("| observer | scalar | ns/step | instructions/step | ratio generated/expert (ns) | ratio (instructions) |")
print("|---|---|---:|---:|---:|---:|")
for o in ["generated", "handwritten", "expert"] + sorted({o for o, _ in ins if o.startswith("chain")},
                                                key=lambda c: (int(c[5:].split("_")[0]), c)):
    for s in ("double", "float"):
        if (o, s) not in ins:
            continue
        t = ns.get(key(o, s), float("nan"))
        r_ns = r_in = ""
        if o == "generated":
            r_ns = f"{t / ns[key('expert', s)]:.2f}"
            r_in = f"{ins[(o, s)] / ins[('expert', s)]:.2f}"
        name = f"seed003 {o}" if o in ("generated", "handwritten", "expert") else f"{o} (generated)"
        print(f"| {name} | {s} | {t:.1f} | {ins[(o, s)]:.1f} | {r_ns} | {r_in} |")

for (o, s), (f, steps) in sorted(fails.items()):
    print(f"\n{o} {s}: {f} of {steps} steps returned a status other than ok")

chains = sorted({int(o[5:].split("_")[0]) for o, _ in ins if o.startswith("chain")})
if chains:
    flavors = [f for f in ("stable", "newton", "newton_z") if any((f"chain{n}_{f}", "double") in ins for n in chains)]
    print()
    print("Growth with n (ns/step, instructions/step in parentheses):")
    print()
    print("| n | " + " | ".join(f"{f} {s}" for s in ("double", "float") for f in flavors) + " |")
    print("|---:|" + "---:|" * (2 * len(flavors)))
    for n in chains:
        cells = []
        for s in ("double", "float"):
            for f in flavors:
                o = f"chain{n}_{f}"
                cells.append(f"{ns.get(key(o, s), float('nan')):.0f} ({ins[(o, s)]:.0f})" if (o, s) in ins else "")
        print(f"| {n} | " + " | ".join(cells) + " |")
EOF
