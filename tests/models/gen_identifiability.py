#!/usr/bin/env python3
"""Writes the identifiability-style test models (tests/test_rank.cpp).

Each <name>_plain.sym is a small published-style model with its parameters appended as constant
states (p' = 0); its rank is decided by obsynth's symbolic path. <name>.sym is the same model
seen through the triangular diffeomorphism x1 = s1 (the output), x_i = s_i + phi_i(s1) for
the other physical states (parameters unchanged), with rational powers and nested quotients in
phi_i. The generic rank is invariant under a diffeomorphism, so both files have the same rank,
while the Lie derivatives of <name>.sym swell. Run: python3 gen_identifiability.py (needs sympy).
"""
import sympy as sp

s1 = sp.Symbol("s1", positive=True)
PHI = [
    s1 ** sp.Rational(17, 2) / (1 + s1 / (1 + s1 ** 2)),
    1 / (1 + 1 / (1 + s1 ** sp.Rational(3, 2))) + s1 ** sp.Rational(5, 3) / (2 + s1),
    s1 ** sp.Rational(7, 2) / (1 + s1 ** 2 / (3 + s1 / (1 + s1))),
]


def text(e):
    return sp.sstr(e).replace("**", "^")


def write(name, comment, physical, params, f, extra=""):
    """physical: names, the output first; params: names; f: dict name -> sympy expr."""
    syms = {n: sp.Symbol(n) for n in physical + params}
    header = "".join(f"# {line}\n" for line in comment.strip().splitlines())
    dom = f"domain {physical[0]} in [1/2, 2]" + extra
    plain = [header, f"model {name}_plain\n", "states " + " ".join(physical + params) + "\n"]
    plain.append("f = [\n  " + ",\n  ".join(text(f[n]) for n in physical) +
                 "".join(",\n  0" for _ in params) + "\n]\n")
    plain.append(f"h = [ {physical[0]} ]\n{dom}\n")
    open(f"{name}_plain.sym", "w").write("".join(plain))
    # x = Phi(s): s1 = x1, s_i = x_i - phi_i(x1).
    x = {n: sp.Symbol(n) for n in physical}
    out = physical[0]
    back = {syms[out]: x[out]}
    for i, n in enumerate(physical[1:]):
        back[syms[n]] = x[n] - PHI[i].subs(s1, x[out])
    F1 = f[out].subs(back, simultaneous=True)
    rows = [text(F1)]
    for i, n in enumerate(physical[1:]):
        dphi = sp.diff(PHI[i], s1).subs(s1, x[out])
        rows.append(f"({text(f[n].subs(back, simultaneous=True))}) + ({text(dphi)})*({text(F1)})")
    body = [header, "# Seen through x_i = s_i + phi_i(x1) (gen_identifiability.py).\n",
            f"model {name}\n", "states " + " ".join(physical + params) + "\n",
            "f = [\n  " + ",\n  ".join(rows) + "".join(",\n  0" for _ in params) + "\n]\n",
            f"h = [ {out} ]\n{dom}\n"]
    open(f"{name}.sym", "w").write("".join(body))


def lotka_volterra():
    x1, x2, a, b, c, d = sp.symbols("x1 x2 a b c d")
    write("ident_lv", """Lotka-Volterra with y = prey, parameters a, b, c, d as constant states.
Scaling symmetry (x2, b) -> (l x2, b / l): unobservable, rank n - 1 = 5.""",
          ["x1", "x2"], ["a", "b", "c", "d"],
          {"x1": a * x1 - b * x1 * x2, "x2": -c * x2 + d * x1 * x2})


def hiv():
    V, T, Y, s, dd, beta, delta, p, c = sp.symbols("V T Y s dd beta delta p c")
    write("ident_hiv", """HIV dynamics (Perelson): T' = s - dd T - beta T V, Y' = beta T V - delta Y,
V' = p Y - c V, y = V (Y: infected cells); the six parameters as constant states (n = 9).""",
          ["V", "T", "Y"], ["s", "dd", "beta", "delta", "p", "c"],
          {"V": p * Y - c * V, "T": s - dd * T - beta * T * V, "Y": beta * T * V - delta * Y},
          ", T in [1/2, 2], Y in [1/2, 2]")


def michaelis_menten():
    x1, x2, x3, vm, km, k, q, r = sp.symbols("x1 x2 x3 vm km k q r")
    write("ident_mm", """Michaelis-Menten elimination with a nested quotient and a transfer
compartment; the rate appears only as the product q*r of two constant states, so the map
(q, r) -> q r makes it unobservable: rank at most n - 1 = 7 (equal when the model in q r is
observable, which its plain counterpart's symbolic rank confirms).""",
          ["x1", "x2", "x3"], ["vm", "km", "k", "q", "r"],
          {"x1": -vm * x1 / (km + x1 / (1 + x2 ** 2)) + k * x2,
           "x2": -k * x2 + q * r * x3, "x3": -q * r * x3 + x1 / (1 + x1)},
          ", km in [1/2, 2]")


lotka_volterra()
hiv()
michaelis_menten()
