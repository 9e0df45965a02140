// Reference values for a generated observer header, computed by GiNaC (evalf, 30 digits)
// from the symbolic expressions, independently of obsynth's DAG, CSE and C++ printer.
// usage: reference <model.sym> <out.hpp>
#include <fmt/format.h>

#include <fstream>
#include <iostream>

#include "analysis/analysis.hpp"
#include "designs/observers.hpp"
#include "front/parse.hpp"
#include "symbolic/zero_test.hpp"

using namespace obsynth;
using GiNaC::ex;

namespace {

std::string value(const ex& e, const GiNaC::exmap& at) {
  DigitsGuard g(30);
  const ex v = GiNaC::evalf(e.subs(at));
  if (!GiNaC::is_a<GiNaC::numeric>(v)) throw std::runtime_error("reference: value not numeric");
  return fmt::format("{:.17e}", GiNaC::ex_to<GiNaC::numeric>(v).to_double());
}

std::string array(const std::string& name, const std::vector<std::vector<std::string>>& rows) {
  std::string s = fmt::format("inline constexpr double {}[kPoints][{}] = {{\n", name,
                              rows.empty() ? 1 : std::max<std::size_t>(1, rows[0].size()));
  for (const auto& r : rows)
    s += fmt::format("    {{{}}},\n",
                     r.empty() ? std::string("0.0") : fmt::format("{}", fmt::join(r, ", ")));
  return s + "};\n";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: reference <model.sym> <out.hpp>\n";
    return 2;
  }
  try {
    const Model m = load_model(argv[1]);
    const Analysis a = analyse(m);
    const CanonicalForm& cf = a.canonical;
    const CanonicalDesign d = design_canonical(a, {});
    const std::size_t n = m.n();
    SampleBoxes boxes = SampleBoxes::from_model(m);
    for (const auto& s : m.states) {
      const Interval b = m.box(s);  // stay well inside the domain
      boxes.by_name[s.get_name()] = {b.lo + (b.hi - b.lo) / 4, b.hi - (b.hi - b.lo) / 4};
    }
    std::vector<GiNaC::symbol> syms(m.states);
    for (const auto& u : m.inputs) syms.push_back(u);
    const int kPoints = 6;
    const auto points = sample_points(syms, boxes, kPoints, 0xC0DE);
    std::vector<std::vector<std::string>> X, U, Y, F, G, H, T, Tinv, Z, L, FR, C, ZR, XR;
    for (const auto& pt : points) {
      std::vector<std::string> x, u, f, g, t, z, l, fr, c, zr, xr;
      for (const auto& s : m.states) x.push_back(value(s, pt));
      for (const auto& s : m.inputs) u.push_back(value(s, pt));
      for (const auto& e : m.f) f.push_back(value(e, pt));
      for (const auto& e : m.g) g.push_back(value(e, pt));
      H.push_back({value(m.h[0], pt)});
      GiNaC::exmap ypt(pt);
      ypt[cf.y] = m.h[0].subs(pt);
      for (const auto& e : cf.l) l.push_back(value(e, ypt));
      ExVec cval;
      for (std::size_t i = 0; i < n; ++i) {
        const ex ci = cf.l[i] + d.K[i] * (cf.y - d.y0);
        c.push_back(value(ci, ypt));
        cval.push_back(GiNaC::evalf(ci.subs(ypt)));
      }
      if (cf.T_kind == Availability::symbolic) {
        GiNaC::exmap zpt;
        for (std::size_t i = 0; i < n; ++i) {
          t.push_back(value(cf.T[i], pt));
          zpt[cf.z[i]] = cf.T[i].subs(pt);
        }
        for (std::size_t i = 0; i < n; ++i) z.push_back(value(cf.z[i], zpt));
        if (cf.T_inverse_kind == Availability::symbolic) {
          std::vector<std::string> ti;
          for (const auto& e : cf.T_inverse) ti.push_back(value(e, zpt));
          Tinv.push_back(ti);
        }
        // z_rhs at zh = T(x) with c from above.
        GiNaC::exmap zc;
        for (std::size_t i = 0; i < n; ++i) {
          zc[d.zh[i]] = cf.T[i].subs(pt);
          zc[d.c[i]] = cval[i];
        }
        for (const auto& e : d.z_rhs) zr.push_back(value(e, zc));
      }
      for (std::size_t k = 0; k < n; ++k)
        for (std::size_t r = 0; r < n; ++r)
          fr.push_back(value(cf.frame[k][r], pt));  // column-major
      X.push_back(x);
      U.push_back(u);
      F.push_back(f);
      G.push_back(g);
      T.push_back(t);
      Z.push_back(z);
      L.push_back(l);
      FR.push_back(fr);
      C.push_back(c);
      ZR.push_back(zr);
    }
    // x_rhs for the x realisation, at (x, u, y = h(x) + 0.1): exercises the injection terms.
    const CanonicalDesign dx = design_canonical(a, {{}, Realisation::x});
    for (const auto& pt : points) {
      GiNaC::exmap ypt(pt);
      ypt[cf.y] = m.h[0].subs(pt) + GiNaC::numeric(1, 10);
      std::vector<std::string> xr;
      for (const auto& e : dx.x_rhs) xr.push_back(value(e, ypt));
      XR.push_back(xr);
    }
    std::string cls;
    bool up = true;
    for (char ch : m.name) {
      if (ch == '_') {
        up = true;
        continue;
      }
      cls += up ? static_cast<char>(std::toupper(static_cast<unsigned char>(ch))) : ch;
      up = false;
    }
    std::string s =
        fmt::format("// reference values computed by GiNaC for {}\n#pragma once\n", m.name);
    s += fmt::format(
        "#define OBSYNTH_NS {}\n#define OBSYNTH_CLASS {}Canonical\n#define OBSYNTH_NAME \"{}\"\n",
        m.name, cls, m.name);
    s += fmt::format("#define OBSYNTH_HAS_T {}\n#define OBSYNTH_HAS_TINV {}\n",
                     cf.T_kind == Availability::symbolic ? 1 : 0,
                     cf.T_inverse_kind == Availability::symbolic ? 1 : 0);
    s += fmt::format("#define OBSYNTH_Z_REALISATION {}\n#define OBSYNTH_HAS_FRAME {}\n",
                     d.realisation == Realisation::z ? 1 : 0,
                     (d.realisation == Realisation::x || d.newton_inverse) ? 1 : 0);
    // Horizon: the slowest pole (-2) brings a unit error below 1e-8 in ~9 s; larger n has
    // more nearby poles (polynomial factors), so allow one more second per state.
    s += fmt::format("#define OBSYNTH_T_END {}.0\n#define OBSYNTH_INPUT_AMPLITUDE 0.5\n", 10 + n);
    s += fmt::format("namespace ref {{\ninline constexpr int kPoints = {};\n", kPoints);
    s += fmt::format("inline constexpr bool kHasT = {};\ninline constexpr bool kHasTinv = {};\n",
                     cf.T_kind == Availability::symbolic,
                     cf.T_inverse_kind == Availability::symbolic);
    std::vector<std::string> poles, ks;
    for (const auto& q : d.poles) poles.push_back(fmt::format("{:.17e}", q.to_double()));
    s += fmt::format("inline constexpr double kSlowestPole = {};\n", poles.front());
    s += array("x", X) + array("u", U) + array("f", F) + array("g", G) + array("h", H) +
         array("T", T) + array("z", Z);
    s += array("Tinv", Tinv.empty() ? std::vector<std::vector<std::string>>(kPoints) : Tinv);
    s += array("l", L) + array("frame", FR) + array("step_constant", C) + array("z_rhs", ZR) +
         array("x_rhs", XR);
    s += "}  // namespace ref\n";
    std::ofstream(argv[2]) << s;
  } catch (const std::exception& e) {
    std::cerr << "reference: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
