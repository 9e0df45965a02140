#include "construct.hpp"

#include <fmt/format.h>

namespace obsynth::testing {

using GiNaC::ex;

ExVec pull_back(const ExVec& T, const std::vector<GiNaC::symbol>& x, const ExVec& w) {
  // Row T_{n-k} (0-based index n-1-k) = x_{k+1} + psi_k(x_1..x_k): solve for v_{k} in order.
  const std::size_t n = x.size();
  ExVec v(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t row = n - 1 - k;
    ex acc = w[row];
    for (std::size_t j = 0; j < k; ++j) acc -= T[row].diff(x[j]) * v[j];
    v[k] = GiNaC::normal(acc);  // coefficient of x_{k+1} in T[row] is 1
  }
  return v;
}

Constructed linearizable_chain(std::size_t n, Flavor flavor, const Perturbation& extra_f,
                               const Perturbation& extra_g) {
  Constructed c;
  Model& m = c.model;
  m.name = fmt::format("chain{}_{}", n, flavor == Flavor::polynomial ? "poly" : "trans");
  m.file = m.name + ".sym";
  for (std::size_t i = 0; i < n; ++i) m.states.push_back(GiNaC::symbol(fmt::format("x{}", i + 1)));
  GiNaC::symbol u("u");
  m.inputs.push_back(u);
  c.y = GiNaC::symbol("y");
  for (std::size_t i = 0; i < n; ++i) c.z.push_back(GiNaC::symbol(fmt::format("z{}", i + 1)));
  const auto& x = m.states;

  // psi_k(x_1..x_k), each zero at the origin.
  auto psi = [&](std::size_t k) -> ex {  // k = 1..n-1
    const ex a = x[k - 1], b = x[0];
    if (flavor == Flavor::polynomial) {
      switch (k % 3) {
        case 0: return a * a / 2;
        case 1: return a * b;
        default: return a * a * b / 3 + a;
      }
    }
    switch (k % 3) {
      case 0: return GiNaC::exp(a) - 1;
      case 1: return GiNaC::sin(b) * a;
      default: return GiNaC::atan(a);
    }
  };
  c.T.assign(n, 0);
  c.T[n - 1] = x[0];
  for (std::size_t k = 1; k < n; ++k) c.T[n - 1 - k] = x[k] + psi(k);
  // Inverse: x1 = zn, x_{k+1} = z_{n-k} - psi_k(x_1..x_k) with the earlier x substituted.
  ExVec xs(n);
  xs[0] = c.z[n - 1];
  for (std::size_t k = 1; k < n; ++k) {
    GiNaC::exmap sub;
    for (std::size_t j = 0; j < k; ++j) sub[x[j]] = xs[j];
    xs[k] = c.z[n - 1 - k] - psi(k).subs(sub);
  }
  c.T_inverse = xs;
  // l(u, y): nonlinear in y, one input term.
  c.l.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const ex yy = c.y;
    switch (i % 3) {
      case 0: c.l[i] = -yy / 2 + (flavor == Flavor::polynomial ? yy * yy * yy / 6 : GiNaC::sin(yy)); break;
      case 1: c.l[i] = yy * yy / 4; break;
      default: c.l[i] = (flavor == Flavor::polynomial ? -yy : -GiNaC::atan(yy)); break;
    }
  }
  c.l[0] += u * (1 + c.y * c.y);
  // Drift and input field in z coordinates, then pulled back.
  GiNaC::exmap z_of_x, y_of_x, u0;
  for (std::size_t i = 0; i < n; ++i) z_of_x[c.z[i]] = c.T[i];
  y_of_x[c.y] = x[0];
  u0[u] = 0;
  const ExVec extra_f_z = extra_f ? extra_f(c.z, u) : ExVec{};
  const ExVec extra_g_z = extra_g ? extra_g(c.z, u) : ExVec{};
  ExVec wf(n), wg(n);
  for (std::size_t i = 0; i < n; ++i) {
    const ex Az = i == 0 ? ex(0) : c.T[i - 1];
    const ex li = c.l[i].subs(y_of_x);
    wf[i] = Az + li.subs(u0);
    wg[i] = li - li.subs(u0);
    if (i < extra_f_z.size()) wf[i] += extra_f_z[i].subs(z_of_x);
    if (i < extra_g_z.size()) wg[i] += extra_g_z[i].subs(z_of_x).subs(y_of_x);
  }
  m.f = pull_back(c.T, x, wf);
  m.g = pull_back(c.T, x, wg);
  m.h = {x[0]};
  if (flavor == Flavor::transcendental)
    for (const auto& s : x) m.domain[s.get_name()] = Interval{GiNaC::numeric(-1), GiNaC::numeric(1)};
  return c;
}

}  // namespace obsynth::testing
