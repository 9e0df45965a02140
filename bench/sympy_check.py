#!/usr/bin/env python3
"""A straightforward SymPy script of the `obsynth check` pipeline, for side-by-side timing
(bench/run_check_bench.sh). Not part of the test suite.

    python3 bench/sympy_check.py MODEL.sym [--timeout SECONDS] [--verbose]

Stages, with the conventions of design.md section 1:
  lie            L_f^k h, k = 0..n-1 (expanded)
  observability  O = d(L_f^k h)/dx, generic rank at a random rational point, det O
  frame          r = O^-1 e_n, tau_1 = r, tau_{k+1} = [-f, tau_k]
  conditions     [tau_i, tau_j] = 0 (C2), [g, tau_j] = 0 (C3)
  diffeomorphism T by integration (z_n = h - h(x0), z_{i-1} = L_f z_i - a_i(y) with
                 a_i'(y) = L_{tau_n} L_f z_i), check dT/dx [tau] = I, l_i = L_{f+g} T_i - T_{i-1}
                 in (u, y), T^-1 as an elimination sequence solved equation by equation
                 (never composed or expanded when T is triangular; when no equation has a
                 single unknown, earlier solutions are substituted and expanded)

Prints one line: `result <verdict> <stage ms ...>` (JSON). Exit 0 when the pipeline
finished, 3 on timeout.
"""
import argparse
import json
import random
import re
import signal
import sys
import time

import sympy as sp


class Timeout(Exception):
    pass


def on_alarm(signum, frame):
    raise Timeout()


def read_model(path):
    """Minimal reader of the .sym format: model, states, inputs, params (with values), f, g, h."""
    text = open(path).read()
    lines = [re.sub(r"#.*", "", ln) for ln in text.splitlines()]
    body = "\n".join(lines)
    spec = {"states": [], "inputs": [], "params": {}, "f": None, "g": None, "h": None}
    for m in re.finditer(r"^\s*(states|inputs)\s+(.*)$", body, re.M):
        spec[m.group(1)] = m.group(2).split()
    for m in re.finditer(r"^\s*params\s+(.*)$", body, re.M):
        for item in m.group(1).split(","):
            name, _, value = item.partition("=")
            spec["params"][name.strip()] = value.strip() or None
    for key in ("f", "g", "h"):
        m = re.search(r"^\s*%s\s*=\s*\[(.*?)\]" % key, body, re.M | re.S)
        if m:
            spec[key] = [e.strip() for e in m.group(1).split(",") if e.strip()]
    names = spec["states"] + spec["inputs"] + list(spec["params"])
    syms = {s: sp.Symbol(s) for s in names}
    env = dict(syms)

    def parse(e):
        return sp.sympify(e.replace("^", "**"), locals=env, rational=True)

    x = [syms[s] for s in spec["states"]]
    u = [syms[s] for s in spec["inputs"]]
    f = [parse(e) for e in spec["f"]]
    g = [parse(e) for e in spec["g"]] if spec["g"] else [sp.Integer(0)] * len(x)
    h = [parse(e) for e in spec["h"]]
    values = {syms[k]: parse(v) for k, v in spec["params"].items() if v}
    f = [e.subs(values) for e in f]
    g = [e.subs(values) for e in g]
    h = [e.subs(values) for e in h]
    return x, u, f, g, h


def lie(phi, field, x):
    return sum(sp.diff(phi, xj) * fj for xj, fj in zip(x, field))


def simp(e):
    """Simplify for storage: expand polynomials, cancel rational functions."""
    e = sp.expand(e)
    return sp.cancel(e) if e.is_rational_function() and not e.is_polynomial() else e


def bracket(a, b, x):
    """[a, b] = (db/dx) a - (da/dx) b."""
    return [simp(lie(bi, a, x) - lie(ai, b, x)) for ai, bi in zip(a, b)]


def is_zero(e):
    e = simp(e)
    return e == 0 or sp.simplify(e) == 0


def random_point(symbols, rng):
    return {s: sp.Rational(rng.randint(-1000, 1000), 1009) for s in symbols}


def express_in_output(e, h, x, y):
    """e(x) as a function of y = h(x), or None."""
    for xi in x:
        if h.has(xi) and sp.diff(h, xi).free_symbols.isdisjoint({xi}):
            sol = sp.solve(sp.Eq(h, y), xi)
            if len(sol) == 1:
                r = simp(e.subs(xi, sol[0]))
                if r.free_symbols.isdisjoint(set(x)):
                    return r
                return None
    return None


def analyse(path, timings):
    x, u, f, g, h = read_model(path)
    n = len(x)
    y = sp.Symbol("y")
    stage = ["lie", time.perf_counter()]

    def next_stage(name):
        now = time.perf_counter()
        timings[stage[0]] = round((now - stage[1]) * 1000, 1)
        stage[0], stage[1] = name, now

    hh = h[0]
    L = [hh]
    for _ in range(1, n):
        L.append(simp(lie(L[-1], f, x)))
    next_stage("observability")
    O = sp.Matrix([[sp.diff(Lk, xj) for xj in x] for Lk in L])
    rng = random.Random(5)
    rank = O.subs(random_point(x + u, rng)).rank()
    if rank < n:
        next_stage("end")
        return "rank %d < %d" % (rank, n)
    det = sp.factor(O.det(method="berkowitz"))
    next_stage("frame")
    r = [simp(e) for e in O.LUsolve(sp.Matrix([0] * (n - 1) + [1]))]
    minus_f = [-e for e in f]
    frame = [r]
    for _ in range(1, n):
        frame.append(bracket(minus_f, frame[-1], x))
    next_stage("conditions")
    ok = True
    for i in range(n):
        for j in range(i + 1, n):
            ok &= all(is_zero(e) for e in bracket(frame[i], frame[j], x))
    for j in range(n - 1):
        ok &= all(is_zero(e) for e in bracket(g, frame[j], x))
    if not ok:
        next_stage("end")
        return "not linearizable"
    next_stage("diffeomorphism")
    x0 = {xi: 0 for xi in x}
    y0 = hh.subs(x0)
    tau_n = frame[-1]
    T = [None] * n
    T[n - 1] = simp(hh - y0)
    for i in range(n - 1, 0, -1):
        LfTi = simp(lie(T[i], f, x))
        a = express_in_output(simp(lie(LfTi, tau_n, x)), hh, x, y)
        if a is None:
            next_stage("end")
            return "T numeric (a_%d not a function of y)" % (i + 1)
        A = sp.integrate(a, y)
        T[i - 1] = simp(LfTi - (A.subs(y, hh) - A.subs(y, y0)) - LfTi.subs(x0))
    for i in range(n):
        grad = [sp.diff(T[i], xk) for xk in x]
        for j in range(n):
            assert is_zero(sum(gk * tk for gk, tk in zip(grad, frame[j])) - (1 if i == j else 0))
    F = [fi + gi for fi, gi in zip(f, g)]
    l = []
    for i in range(n):
        li = express_in_output(simp(lie(T[i], F, x) - (T[i - 1] if i else 0)), hh, x, y)
        assert li is not None, "l_%d is not a function of (u, y)" % (i + 1)
        l.append(li)
    z = sp.symbols("z1:%d" % (n + 1))
    eqs = [T[i] - z[i] for i in range(n)]
    solved, steps, used = {}, [], set()
    while len(steps) < n:
        pick = None
        for i, eq in enumerate(eqs):
            unknown = [xk for xk in x if xk not in solved and eq.has(xk)]
            if i not in used and len(unknown) == 1 and sp.degree(eq, unknown[0]) == 1:
                pick = (i, unknown[0])
                break
        if pick is None:
            # No triangular order: substitute the solutions so far and expand.
            eqs = [simp(eq.subs(solved)) for eq in eqs]
            for i, eq in enumerate(eqs):
                unknown = [xk for xk in x if xk not in solved and eq.has(xk)]
                if i not in used and unknown and sp.degree(eq, unknown[0]) == 1:
                    pick = (i, unknown[0])
                    break
            if pick is None:
                next_stage("end")
                return "T^-1 numeric"
        i, xk = pick
        value = sp.solve(eqs[i], xk)[0]
        # Step check: the step solves its own equation.
        assert simp(eqs[i].subs(xk, value)) == 0
        used.add(i)
        solved[xk] = value
        steps.append((xk, value))
    next_stage("end")
    return "linearizable"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--timeout", type=float, default=0)
    args = ap.parse_args()
    timings = {}
    signal.signal(signal.SIGALRM, on_alarm)
    if args.timeout > 0:
        signal.setitimer(signal.ITIMER_REAL, args.timeout)
    start = time.perf_counter()
    try:
        result = analyse(args.model, timings)
        code = 0
    except Timeout:
        result = "timeout"
        code = 3
    signal.setitimer(signal.ITIMER_REAL, 0)
    print(json.dumps({"result": result, "seconds": round(time.perf_counter() - start, 3),
                      "timings_ms": timings}))
    sys.exit(code)


if __name__ == "__main__":
    main()
