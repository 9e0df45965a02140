#!/usr/bin/env python3
"""Random 20-state models of about 9 kB (12 physical states, 8 parameters as constant states,
rational powers, nested quotients, sin, exp, tanh) for the jets rank target of issue 6: any
model of <= 20 states and <= 10 kB decides its rank within 10 s.

  python3 bench/jets_stress.py OUT_DIR        # writes stress_s3.sym, stress_s4.sym, stress_s3_deficit.sym
  obsynth check OUT_DIR/stress_s3.sym --rank-method jets

stress_s3_deficit.sym replaces the parameter k8 by the product k7*k6 in f (k8 then enters
nothing), so its rank is at most 19.
"""
import os
import random
import sys

NPHYS, NPAR, TERMS = 12, 8, 40
X = [f"x{i + 1}" for i in range(NPHYS)]
P = [f"k{i + 1}" for i in range(NPAR)]


def model(seed):
    rnd = random.Random(seed)

    def atom():
        return rnd.choice(X + P)

    def term(depth=0):
        r = rnd.random()
        if depth > 2 or r < 0.3:
            return atom()
        if r < 0.45:
            return f"{atom()}^({rnd.choice(['17/2', '3/2', '5/3', '2', '3'])})"
        if r < 0.6:
            return f"{term(depth + 1)}/(1+{term(depth + 1)}^2)"
        if r < 0.7:
            return f"sin({term(depth + 1)})"
        if r < 0.78:
            return f"exp(-1/(1+{term(depth + 1)}^2))"
        if r < 0.85:
            return f"tanh({term(depth + 1)})"
        return f"{term(depth + 1)}*{term(depth + 1)}"

    f = [" - ".join([f"{P[i % NPAR]}*{X[(i + 1) % NPHYS]}"] + [term() for _ in range(TERMS)])
         for i in range(NPHYS)]
    return f, f"u*(1+{X[0]}^2)"


def text(name, f, g0):
    return (f"model {name}\nstates {' '.join(X + P)}\ninputs u\n"
            f"f = [\n  " + ",\n  ".join(f + ["0"] * NPAR) + "\n]\n"
            f"g = [\n  " + ",\n  ".join([g0] + ["0"] * (NPHYS + NPAR - 1)) + "\n]\nh = [ x1 ]\n"
            "domain " + ", ".join(f"{s} in [1/2, 2]" for s in X + P) + ", u in [1/2, 1]\n")


out = sys.argv[1]
os.makedirs(out, exist_ok=True)
for seed in (3, 4):
    f, g0 = model(seed)
    open(os.path.join(out, f"stress_s{seed}.sym"), "w").write(text(f"stress_s{seed}", f, g0))
    if seed == 3:
        fd = [e.replace("k8", "(k7*k6)") for e in f]
        open(os.path.join(out, "stress_s3_deficit.sym"), "w").write(
            text("stress_s3_deficit", fd, g0))
