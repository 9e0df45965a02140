// Reference values for a generated Thau or Kou observer: the observer field
// F(x, u) + L (h(x) - y) evaluated by GiNaC (evalf, 30 digits) straight from the model's f, g, h,
// independently of obsynth's DAG, CSE and printers. Only the gain L, the Lyapunov matrix P and
// the certified rate and region are taken from the design: they are what the generated code is
// tested against (the exactness of L and P is tested in tests/test_lyapunov_designs.cpp).
// usage: lyapunov_reference <model.sym> <thau|kou> <out.hpp>
#include <fmt/format.h>

#include <fstream>
#include <iostream>

#include "analysis/analysis.hpp"
#include "designs/kou.hpp"
#include "designs/thau.hpp"
#include "front/parse.hpp"
#include "reference_value.hpp"

using namespace obsynth;
using GiNaC::ex;

namespace {

constexpr int kPoints = 8;

std::string row(const std::vector<std::string>& v) {
  return fmt::format("{{{}}}",
                     v.empty() ? std::string("0.0") : fmt::format("{}", fmt::join(v, ", ")));
}

std::string table(const std::string& name, const std::vector<std::vector<std::string>>& rows,
                  std::size_t width) {
  std::string s = fmt::format("inline constexpr double {}[{}][{}] = {{\n", name, rows.size(),
                              std::max<std::size_t>(width, 1));
  for (const auto& r : rows) s += "    " + row(r) + ",\n";
  return s + "};\n";
}

std::string vec(const std::string& name, const std::vector<double>& v) {
  std::vector<std::string> s;
  for (double d : v) s.push_back(fmt::format("{:.17e}", d));
  return fmt::format("inline constexpr double {}[{}] = {};\n", name,
                     std::max<std::size_t>(v.size(), 1), row(s));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: lyapunov_reference <model.sym> <thau|kou> <out.hpp>\n";
    return 2;
  }
  try {
    const Model m = load_model(argv[1]);
    const std::string method = argv[2];
    const std::size_t n = m.n(), p = m.p();
    // L (n x p), P, the certified decay rate of V = e' P e and the region.
    std::vector<double> L(n * p, 0), P;
    std::vector<double> lo, hi;
    double v_rate = 0;
    if (method == "thau") {
      const ThauCertificate c = thau_certificate(m);
      if (!c.holds) throw std::runtime_error("thau does not apply");
      for (std::size_t i = 0; i < n; ++i) L[i * p + c.output] = c.L[i];
      for (const auto& r : c.region) lo.push_back(r.first), hi.push_back(r.second);
      v_rate = 2 * c.margin_region;  // V' <= -2 (sigma_min(Q) - M sigma_max(P)) |e|^2
      // P of the Lyapunov argument is in the spec; the rate is stated for P/sigma_max(P) alike.
      const ObserverSpec s = find_design("thau")->build(analyse(m), {});
      for (const auto& c2 : s.constants)
        if (c2.name == "P")
          for (const auto& v : c2.values) P.push_back(v.to_double());
    } else if (method == "kou") {
      const KouCertificate c = kou_certificate(m);
      if (!c.holds) throw std::runtime_error("kou does not apply");
      L = c.L;
      P = c.P;
      for (const auto& x : m.states) {
        const Interval b = m.box(x);
        lo.push_back(b.lo.to_double());
        hi.push_back(b.hi.to_double());
      }
      v_rate = -2 * c.max_eigenvalue_bound / c.sigma_max_P;
    } else {
      throw std::runtime_error("unknown method " + method);
    }
    // Free parameters at their box centre (the generated classes' defaults).
    GiNaC::exmap params;
    for (const auto& q : m.free_params()) {
      const Interval b = m.box(q);
      params[q] = (b.lo + b.hi) / 2;
    }
    const ExVec F = m.field();
    std::vector<std::vector<std::string>> xs, us, ys, fs, gs, hs, rhs;
    for (int k = 0; k < kPoints; ++k) {
      GiNaC::exmap at = params;
      std::vector<std::string> xr, ur, yr, fr, gr, hr, rr;
      for (std::size_t i = 0; i < n; ++i) {
        // Golden-ratio sequence over the middle half of the region, exact rationals.
        const double t = 0.25 + 0.5 * std::fmod(0.5 + (k + 1) * 0.6180339887498949 * (i + 1), 1.0);
        const GiNaC::numeric v =
            GiNaC::numeric(static_cast<long>(std::round((lo[i] + t * (hi[i] - lo[i])) * 1024))) /
            1024;
        at[m.states[i]] = v;
        xr.push_back(fmt::format("{:.17e}", v.to_double()));
      }
      for (std::size_t j = 0; j < m.m(); ++j) {
        const Interval b = m.box(m.inputs[j]);
        const GiNaC::numeric v = b.lo + (b.hi - b.lo) * GiNaC::numeric(k + 1, kPoints + 2);
        at[m.inputs[j]] = v;
        ur.push_back(fmt::format("{:.17e}", v.to_double()));
      }
      std::vector<ex> y;
      for (std::size_t i = 0; i < p; ++i) {
        // A measurement that differs from h(x), so that the injection term is exercised.
        y.push_back(m.h[i].subs(at) + GiNaC::numeric(3 - k, 8));
        yr.push_back(testing::reference_value(y.back(), at));
        hr.push_back(testing::reference_value(m.h[i], at));
      }
      for (std::size_t i = 0; i < n; ++i) {
        fr.push_back(testing::reference_value(m.f[i], at));
        gr.push_back(testing::reference_value(m.g[i], at));
        ex e = F[i];
        for (std::size_t q = 0; q < p; ++q)
          e += GiNaC::numeric(GiNaC::numeric(L[i * p + q]).to_double()) * (m.h[q] - y[q]);
        rr.push_back(testing::reference_value(e, at));
      }
      xs.push_back(xr), us.push_back(ur), ys.push_back(yr), fs.push_back(fr), gs.push_back(gr),
          hs.push_back(hr), rhs.push_back(rr);
    }
    std::string out = fmt::format(
        "// Reference values for the {} observer of {}, generated by lyapunov_reference.\n"
        "#pragma once\n#define OBSYNTH_NS {}\n#define OBSYNTH_CLASS {}{}\n"
        "#define OBSYNTH_FUNCTIONS {}Functions\n#define OBSYNTH_NAME \"{}_{}\"\n"
        "#define OBSYNTH_HAS_PARAMS {}\n#define OBSYNTH_INPUT_AMPLITUDE 0.1\n"
        "namespace ref {{\ninline constexpr int kPoints = {};\n"
        "inline constexpr double kVRate = {:.17e};  // V = e' P e decays at least as e^(-kVRate "
        "t)\n",
        method, m.name, m.name, pascal_case(m.name), pascal_case(method), pascal_case(method),
        m.name, method, m.free_params().empty() ? 0 : 1, kPoints, v_rate);
    out += table("x", xs, n) + table("u", us, m.m()) + table("y", ys, p) + table("f", fs, n) +
           table("g", gs, n) + table("h", hs, p) + table("rhs", rhs, n);
    out += vec("P", P) + vec("region_lo", lo) + vec("region_hi", hi) + vec("L", L);
    out += "}  // namespace ref\n";
    std::ofstream(argv[3]) << out;
  } catch (const std::exception& e) {
    std::cerr << "lyapunov_reference: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
