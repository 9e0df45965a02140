// Reference derivatives of the generated high-gain and Kalman-like theta observers, computed by
// GiNaC (exact rationals at rational points, printed via evalf at 30 digits) straight from
// seed 002, independently of synth/designs, the DAG, CSE and the printers:
//   high-gain:    xh' = F(xh, u) + O(xh)^-1 Delta_theta K (y - h(xh)), O = d(h, L_f h, ...)/dx
//                 (Lie derivatives and K recomputed here; the solve by GiNaC's exact lsolve);
//   kalman-theta: zh' = F(zh, u) + S^-1 e1 (y - zh1), S' = -theta S - A^T S - S A + e1 e1^T,
//                 A(u) = the superdiagonal d F_i / d x_{i+1}, when the model is in seed 002's
//                 form in x (y = x1, every d F_i / d x_{i+1} free of x, F_i free of x_{i+2..n});
//                 otherwise in z = Z(x) = (h, L_f h, ..., L_f^{n-1} h) (Lie derivatives written
//                 out here): at w = (Z(x), S), zh' = DZ(x) F(x, u) + S^-1 e1 (y - h(x)) by the
//                 chain rule (no inverse map), A the upper shift (ones).
// The design defaults are used (theta = 5; poles -2, -5/2, ...), as the generated headers.
// usage: hgkt_reference <model.sym> <high-gain|kalman-theta> <out.hpp>
#include <fmt/format.h>

#include <fstream>
#include <iostream>

#include "front/parse.hpp"
#include "reference_value.hpp"

using namespace obsynth;
using GiNaC::ex;
using GiNaC::numeric;

namespace {

constexpr int kPoints = 5;
const numeric kTheta(5);

// Deterministic rational point in [lo, hi].
numeric at(const Interval& b, int k, int i) {
  const numeric frac((k * 7 + i * 3) % 11 + 1, 13);  // in (0, 1)
  return b.lo + (b.hi - b.lo) * frac;
}

std::string row(const ExVec& v, const GiNaC::exmap& pt) {
  std::vector<std::string> s;
  for (const auto& e : v) s.push_back(testing::reference_value(e, pt));
  if (s.empty()) s.push_back("0.0");
  return fmt::format("{{{}}}", fmt::join(s, ", "));
}

ExVec high_gain(const Model& m, const GiNaC::symbol& y) {
  const std::size_t n = m.n();
  // Lie derivatives of h along the drift, written out here.
  ExVec L = {m.h[0]};
  for (std::size_t k = 1; k < n; ++k) {
    ex d = 0;
    for (std::size_t j = 0; j < n; ++j) d += L.back().diff(m.states[j]) * m.f[j];
    L.push_back(d);
  }
  GiNaC::matrix O(n, n);
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = 0; c < n; ++c) O(r, c) = L[r].diff(m.states[c]);
  // prod (s - p_k), p_k = -2 - k/2; K_i = coefficient of s^{n-i}.
  GiNaC::symbol s("s");
  ex poly = 1;
  for (std::size_t k = 0; k < n; ++k) poly *= s + 2 + numeric(static_cast<long>(k), 2);
  poly = GiNaC::expand(poly);
  GiNaC::matrix v(n, 1);
  numeric th = 1;
  for (std::size_t i = 1; i <= n; ++i) {
    th *= kTheta;
    v(i - 1, 0) = th * poly.coeff(s, static_cast<int>(n - i)) * (y - m.h[0]);
  }
  std::vector<GiNaC::symbol> unknowns;
  GiNaC::matrix X(n, 1);
  for (std::size_t i = 0; i < n; ++i) {
    unknowns.emplace_back(fmt::format("q{}", i));
    X(i, 0) = unknowns.back();
  }
  const GiNaC::matrix solved = O.solve(X, v, GiNaC::solve_algo::gauss);
  ExVec out;
  for (std::size_t i = 0; i < n; ++i) out.push_back(m.f[i] + m.g[i] + solved(i, 0));
  return out;
}

// Seed 002's form directly in x (checked here, not by synth/): y = x1, the superdiagonal
// coefficients free of x, row i free of x_{i+2}..x_n.
bool form_in_x(const Model& m) {
  const std::size_t n = m.n();
  if (!(m.h[0] - m.states[0]).is_zero()) return false;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const ex Fi = m.f[i] + m.g[i];
    const ex a = GiNaC::normal(Fi.diff(m.states[i + 1]));
    for (const auto& x : m.states)
      if (a.has(x)) return false;
    for (std::size_t j = i + 2; j < n; ++j)
      if (!GiNaC::normal(Fi.diff(m.states[j])).is_zero()) return false;
  }
  return true;
}

// Z(x) = (h, L_f h, ..., L_f^{n-1} h), the drift's Lie derivatives written out here.
ExVec lie_coordinates(const Model& m) {
  ExVec L = {m.h[0]};
  for (std::size_t k = 1; k < m.n(); ++k) {
    ex d = 0;
    for (std::size_t j = 0; j < m.n(); ++j) d += L.back().diff(m.states[j]) * m.f[j];
    L.push_back(d);
  }
  return L;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: hgkt_reference <model.sym> <high-gain|kalman-theta> <out.hpp>\n";
    return 2;
  }
  try {
    const Model m = load_model(argv[1]);
    const std::string method = argv[2];
    const std::size_t n = m.n();
    const GiNaC::symbol y("y");
    std::vector<GiNaC::symbol> wsyms(m.states.begin(), m.states.end());
    ExVec rhs;
    std::vector<std::vector<ex>> S(n, std::vector<ex>(n));
    bool in_x = true;
    ExVec Z;  // out of x: the coordinates z = Z(x) the observer runs in
    if (method == "high-gain") {
      rhs = high_gain(m, y);
    } else {
      in_x = form_in_x(m);
      if (!in_x) Z = lie_coordinates(m);
      for (std::size_t r = 0; r < n; ++r)
        for (std::size_t c = r; c < n; ++c) {
          wsyms.emplace_back(fmt::format("S{}{}", r, c));
          S[r][c] = S[c][r] = wsyms.back();
        }
      GiNaC::matrix Sm(n, n), A(n, n), e1y(n, 1);
      for (std::size_t r = 0; r < n; ++r)
        for (std::size_t c = 0; c < n; ++c) Sm(r, c) = S[r][c];
      for (std::size_t i = 0; i + 1 < n; ++i)
        A(i, i + 1) = in_x ? (m.f[i] + m.g[i]).diff(m.states[i + 1]) : ex(1);
      e1y(0, 0) = y - (in_x ? ex(m.states[0]) : Z[0]);
      GiNaC::matrix X(n, 1);
      for (std::size_t i = 0; i < n; ++i) X(i, 0) = GiNaC::symbol(fmt::format("q{}", i));
      const GiNaC::matrix gain = Sm.solve(X, e1y, GiNaC::solve_algo::gauss);
      for (std::size_t i = 0; i < n; ++i) {
        ex zdot = 0;  // in x: F_i; in z: d/dt Z_i(x) = DZ_i(x) F(x, u)
        if (in_x)
          zdot = m.f[i] + m.g[i];
        else
          for (std::size_t j = 0; j < n; ++j) zdot += Z[i].diff(m.states[j]) * (m.f[j] + m.g[j]);
        rhs.push_back(zdot + gain(i, 0));
      }
      const GiNaC::matrix dS = Sm.mul_scalar(-kTheta).sub(A.transpose().mul(Sm)).sub(Sm.mul(A));
      for (std::size_t r = 0; r < n; ++r)
        for (std::size_t c = r; c < n; ++c) rhs.push_back(dS(r, c) + (r == 0 && c == 0 ? 1 : 0));
    }
    std::string W, U, Y, D;
    for (int k = 0; k < kPoints; ++k) {
      GiNaC::exmap pt;
      ExVec wv, uv, yv{y};
      for (std::size_t i = 0; i < n; ++i)
        pt[m.states[i]] = at(m.box(m.states[i]), k, static_cast<int>(i));
      for (std::size_t r = 0; r < n && method != "high-gain"; ++r)
        for (std::size_t c = r; c < n; ++c)  // diagonally dominant: positive definite
          pt[GiNaC::ex(S[r][c])] =
              r == c ? numeric(2 + static_cast<long>(r) + k) : numeric(1, 4 + k);
      for (std::size_t j = 0; j < m.m(); ++j)
        pt[m.inputs[j]] = at(m.box(m.inputs[j]), k, 5 + static_cast<int>(j));
      pt[y] = numeric(k - 2, 3);
      for (std::size_t i = 0; i < wsyms.size(); ++i)  // out of x, w starts with Z(x)
        wv.push_back(!in_x && i < n ? Z[i] : ex(wsyms[i]));
      for (const auto& s : m.inputs) uv.push_back(s);
      W += "    " + row(wv, pt) + ",\n";
      U += "    " + row(uv, pt) + ",\n";
      Y += "    " + row(yv, pt) + ",\n";
      D += "    " + row(rhs, pt) + ",\n";
    }
    const std::size_t nw = wsyms.size(), mm = std::max<std::size_t>(m.m(), 1);
    std::ofstream out(argv[3]);
    out << "// generated by hgkt_reference — reference derivatives for tests\n#pragma once\n"
        << "namespace ref {\n"
        << fmt::format("inline constexpr int kPoints = {};\n", kPoints)
        << fmt::format("inline constexpr double w[{}][{}] = {{\n{}}};\n", kPoints, nw, W)
        << fmt::format("inline constexpr double u[{}][{}] = {{\n{}}};\n", kPoints, mm, U)
        << fmt::format("inline constexpr double y[{}][1] = {{\n{}}};\n", kPoints, Y)
        << fmt::format("inline constexpr double dw[{}][{}] = {{\n{}}};\n", kPoints, nw, D)
        << "}  // namespace ref\n";
    return out ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "hgkt_reference: " << e.what() << "\n";
    return 1;
  }
}
