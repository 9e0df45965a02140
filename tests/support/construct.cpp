#include "construct.hpp"

#include <fmt/format.h>

#include "symbolic/expr_print.hpp"

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
    v[k] = GiNaC::normal(acc / T[row].diff(x[k]));  // dT_row/dx_{k+1}: 1, or 1 + x^2 (newton)
  }
  return v;
}

Constructed linearizable_chain(std::size_t n, Flavor flavor, const Perturbation& extra_f,
                               const Perturbation& extra_g) {
  Constructed c;
  Model& m = c.model;
  static const char* const flavor_names[] = {"poly", "trans", "stable", "newton"};
  m.name = fmt::format("chain{}_{}", n, flavor_names[static_cast<int>(flavor)]);
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
    if (flavor != Flavor::transcendental) {
      switch (k % 3) {
        case 0:
          return a * a / 2;
        case 1:
          return a * b;
        default:
          return a * a * b / 3 + a;
      }
    }
    switch (k % 3) {
      case 0:
        return GiNaC::exp(a) - 1;
      case 1:
        return GiNaC::sin(b) * a;
      default:
        return GiNaC::atan(a);
    }
  };
  const bool newton = flavor == Flavor::stable_newton;
  c.T.assign(n, 0);
  c.T[n - 1] = x[0];
  for (std::size_t k = 1; k < n; ++k)
    c.T[n - 1 - k] = x[k] + (newton && k == n - 1 ? GiNaC::pow(x[k], 3) / 3 : ex(0)) + psi(k);
  // Inverse: x1 = zn, x_{k+1} = z_{n-k} - psi_k(x_1..x_k) with the earlier x substituted.
  ExVec xs(n);
  xs[0] = c.z[n - 1];
  for (std::size_t k = 1; k < n; ++k) {
    GiNaC::exmap sub;
    for (std::size_t j = 0; j < k; ++j) sub[x[j]] = xs[j];
    xs[k] = c.z[n - 1 - k] - psi(k).subs(sub);
  }
  c.T_inverse = newton ? ExVec{} : xs;  // no closed form with the cubic terms
  // l(u, y): nonlinear in y, one input term.
  c.l.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const ex yy = c.y;
    switch (i % 3) {
      case 0:
        c.l[i] = -yy / 2 + (flavor == Flavor::polynomial ? yy * yy * yy / 6 : GiNaC::sin(yy));
        break;
      case 1:
        c.l[i] = yy * yy / 4;
        break;
      default:
        c.l[i] = (flavor == Flavor::polynomial ? -yy : -GiNaC::atan(yy));
        break;
    }
  }
  if (flavor == Flavor::stable || newton) {
    // Hurwitz: prod (s + 1 + k/2) gives a_i; the z-system is A - a e_n^T plus bounded terms.
    std::vector<GiNaC::numeric> poles;
    for (std::size_t k = 0; k < n; ++k)
      poles.push_back(-1 - GiNaC::numeric(static_cast<long>(k), 2));
    GiNaC::symbol s("s");
    ex poly = 1;
    for (const auto& q : poles) poly *= (s - q);
    poly = GiNaC::expand(poly);
    for (std::size_t i = 0; i < n; ++i) {
      const ex a = poly.coeff(s, static_cast<int>(i));
      c.l[i] = -a * c.y + (i % 2 == 0 ? GiNaC::sin(c.y) / 4 : c.y * c.y / (4 * (1 + c.y * c.y)));
    }
    c.l[0] += u * GiNaC::cos(c.y);
    for (const auto& s2 : x)
      m.domain[s2.get_name()] = Interval{GiNaC::numeric(-1), GiNaC::numeric(1)};
  } else {
    c.l[0] += u * (1 + c.y * c.y);
  }
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
    for (const auto& s : x)
      m.domain[s.get_name()] = Interval{GiNaC::numeric(-1), GiNaC::numeric(1)};
  return c;
}

namespace {

struct FamilyParts {
  std::function<ex(std::size_t k)> scale;  // s_k(x1), dT_{n-k}/dx_{k+1}
  std::function<ex(std::size_t k)> psi;    // psi_k(x_1..x_k), zero at the origin
  std::function<ex(std::size_t i)> l;      // l_{i+1}(0, y)
};

FamilyParts family_parts(Family family, const std::vector<GiNaC::symbol>& x, const ex& y) {
  const ex b = x[0];
  auto xk = [&x](std::size_t k) { return ex(x[k - 1]); };
  switch (family) {
    case Family::tanh_friction:
      return {[](std::size_t) { return ex(1); },
              [=](std::size_t k) { return k % 2 ? xk(k) * GiNaC::tanh(b) : xk(k) * xk(k) / 2; },
              [=](std::size_t i) {
                const ex terms[] = {-y / 2 - 3 * GiNaC::tanh(2 * y), y * y / 4 + GiNaC::tanh(y) / 2,
                                    -y * GiNaC::tanh(y)};
                return terms[i % 3];
              }};
    case Family::exp_cancel:
      return {[=](std::size_t k) { return GiNaC::exp(ex(1 + k % 2) * b); },
              [=](std::size_t k) { return k % 2 ? xk(k) * GiNaC::exp(-b) : ex(0); },
              [=](std::size_t i) {
                const ex terms[] = {-y / 2 + y * GiNaC::exp(-y), GiNaC::exp(2 * y) / 4,
                                    GiNaC::sin(y) - y * y * GiNaC::exp(-y) / 2};
                return terms[i % 3];
              }};
    case Family::poly_exp:
      return {[](std::size_t) { return ex(1); },
              [=](std::size_t k) { return b * b * GiNaC::exp(b) * xk(k); },
              [=](std::size_t i) {
                const ex terms[] = {-y / 2 + y * y * GiNaC::exp(y), y * GiNaC::exp(y) / 4,
                                    -y * GiNaC::exp(-y)};
                return terms[i % 3];
              }};
    case Family::poly_sin:
      return {[](std::size_t) { return ex(1); },
              [=](std::size_t k) { return b * GiNaC::sin(b) * xk(k); },
              [=](std::size_t i) {
                const ex terms[] = {-y / 2 + y * GiNaC::sin(y), y * y * GiNaC::cos(y) / 4,
                                    -GiNaC::exp(2 * y) * GiNaC::cos(y)};
                return terms[i % 3];
              }};
    case Family::atan:
      return {[](std::size_t) { return ex(1); },
              [=](std::size_t k) { return k % 2 ? GiNaC::atan(xk(k)) : xk(k) * GiNaC::atan(b); },
              [=](std::size_t i) {
                const ex terms[] = {-y / 2 + y * GiNaC::atan(y), GiNaC::atan(y) / 4,
                                    -y * y / (1 + y * y)};
                return terms[i % 3];
              }};
  }
  return {};
}

}  // namespace

const char* family_name(Family f) {
  static const char* const names[] = {"tanh_friction", "exp_cancel", "poly_exp", "poly_sin",
                                      "atan"};
  return names[static_cast<int>(f)];
}

Constructed linearizable_family(std::size_t n, Family family) {
  Constructed c;
  Model& m = c.model;
  m.name = fmt::format("{}{}", family_name(family), n);
  m.file = m.name + ".sym";
  for (std::size_t i = 0; i < n; ++i) m.states.push_back(GiNaC::symbol(fmt::format("x{}", i + 1)));
  GiNaC::symbol u("u");
  m.inputs.push_back(u);
  c.y = GiNaC::symbol("y");
  for (std::size_t i = 0; i < n; ++i) c.z.push_back(GiNaC::symbol(fmt::format("z{}", i + 1)));
  const auto& x = m.states;
  const FamilyParts parts = family_parts(family, x, c.y);
  c.T.assign(n, 0);
  c.T[n - 1] = x[0];
  for (std::size_t k = 1; k < n; ++k) c.T[n - 1 - k] = parts.scale(k) * x[k] + parts.psi(k);
  // Inverse: x1 = zn, x_{k+1} = (z_{n-k} - psi_k) / s_k with the earlier x substituted.
  ExVec xs(n);
  xs[0] = c.z[n - 1];
  for (std::size_t k = 1; k < n; ++k) {
    GiNaC::exmap sub;
    for (std::size_t j = 0; j < k; ++j) sub[x[j]] = xs[j];
    xs[k] = ((c.z[n - 1 - k] - parts.psi(k)) / parts.scale(k)).subs(sub);
  }
  c.T_inverse = xs;
  for (std::size_t i = 0; i < n; ++i) c.l.push_back(parts.l(i));
  c.l[0] += u * (1 + c.y * c.y);
  GiNaC::exmap y_of_x{{c.y, x[0]}}, u0{{u, 0}};
  ExVec wf(n), wg(n);
  for (std::size_t i = 0; i < n; ++i) {
    const ex li = c.l[i].subs(y_of_x);
    wf[i] = (i == 0 ? ex(0) : c.T[i - 1]) + li.subs(u0);
    wg[i] = li - li.subs(u0);
  }
  m.f = pull_back(c.T, x, wf);
  m.g = pull_back(c.T, x, wg);
  m.h = {x[0]};
  for (const auto& s : x) m.domain[s.get_name()] = Interval{GiNaC::numeric(-1), GiNaC::numeric(1)};
  return c;
}

std::string to_sym(const Model& m) {
  std::vector<std::string> xs, us;
  for (const auto& s : m.states) xs.push_back(s.get_name());
  for (const auto& s : m.inputs) us.push_back(s.get_name());
  std::string out = fmt::format("# constructed by the obsynth test suite\nmodel {}\nstates {}\n",
                                m.name, fmt::join(xs, " "));
  if (!us.empty()) out += fmt::format("inputs {}\n", fmt::join(us, " "));
  out += fmt::format("f = [\n  {}\n]\n", fmt::join(to_strings(m.f), ",\n  "));
  out += fmt::format("g = [\n  {}\n]\n", fmt::join(to_strings(m.g), ",\n  "));
  out += fmt::format("h = [ {} ]\n", fmt::join(to_strings(m.h), ", "));
  std::vector<std::string> dom;
  for (const auto& [name, box] : m.domain)
    dom.push_back(fmt::format("{} in [{}, {}]", name, to_string(box.lo), to_string(box.hi)));
  if (!dom.empty()) out += fmt::format("domain {}\n", fmt::join(dom, ", "));
  return out;
}

}  // namespace obsynth::testing
