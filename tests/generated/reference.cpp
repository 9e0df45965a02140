// Reference values for a generated canonical observer header, computed by GiNaC (evalf, 30
// digits) from the analysis' symbolic maps, independently of obsynth's designs, DAG, CSE and
// C++ printer: the gains K, the offset y0, the step constant c = l + K (y - y0), the
// x-realisation field and the exact discretisation (Phi, Gamma) are derived here again from
// design.md §1, not taken from synth/designs.
// usage: reference <model.sym> <out.hpp>
#include <fmt/format.h>

#include <fstream>
#include <iostream>

#include "analysis/analysis.hpp"
#include "designs/spec.hpp"
#include "front/parse.hpp"
#include "reference_value.hpp"
#include "symbolic/zero_test.hpp"

using namespace obsynth;
using GiNaC::ex;

namespace {

constexpr int kPoints = 6;
constexpr int kParamSets = 3;
const double kStepDt = 0.05;  // dt of the reference discretisation (1/20 below)

std::string value(const ex& e, const GiNaC::exmap& at) {
  return testing::reference_value(e, at);
}

using Table = std::vector<std::vector<std::string>>;

std::string array(const std::string& name, const Table& rows) {
  std::size_t width = 1;
  for (const auto& r : rows) width = std::max(width, r.size());
  std::string s = fmt::format("inline constexpr double {}[{}][{}] = {{\n", name,
                              std::max<std::size_t>(rows.size(), 1), width);
  for (const auto& r : rows)
    s += fmt::format("    {{{}}},\n",
                     r.empty() ? std::string("0.0") : fmt::format("{}", fmt::join(r, ", ")));
  if (rows.empty()) s += "    {0.0},\n";
  return s + "};\n";
}

// Coefficients c_0..c_{k-1} of prod (s - pole) = s^k + c_{k-1} s^{k-1} + ... + c_0, by
// repeated multiplication of the coefficient vector (design.md §1: K_i = c_{i-1}).
std::vector<GiNaC::numeric> characteristic_coefficients(const std::vector<GiNaC::numeric>& poles) {
  std::vector<GiNaC::numeric> c = {1};  // low degree first
  for (const auto& pole : poles) {
    std::vector<GiNaC::numeric> next(c.size() + 1, 0);
    for (std::size_t i = 0; i < c.size(); ++i) {
      next[i + 1] += c[i];
      next[i] -= pole * c[i];
    }
    c = next;
  }
  c.pop_back();  // the monic s^k
  return c;
}

// Phi = V diag(e^{p dt}) V^-1 and Gamma = V diag((e^{p dt} - 1) / p) V^-1 of one block from
// the eigenvectors of its companion matrix (distinct poles p; v_k = 1 and v_{i-1} = p v_i +
// c_i from (A_cl v)_i = v_{i-1} - c_i v_k), in exact arithmetic up to the exponentials:
// independent of the runtime's scaling and squaring and of simulate's Pade. Written into the
// diagonal block at `at` of Phi and Gamma.
void exact_discretisation(const std::vector<GiNaC::numeric>& poles, const GiNaC::numeric& dt,
                          unsigned at, GiNaC::matrix& Phi, GiNaC::matrix& Gamma) {
  const auto c = characteristic_coefficients(poles);
  const unsigned n = static_cast<unsigned>(c.size());
  GiNaC::matrix V(n, n), E(n, n), D(n, n);
  for (unsigned k = 0; k < n; ++k) {
    const GiNaC::numeric p = poles[k];
    ex v = 1;
    V(n - 1, k) = 1;
    for (unsigned i = n - 1; i >= 1; --i) {
      v = p * v + c[i];
      V(i - 1, k) = v;
    }
    E(k, k) = GiNaC::exp(p * dt);
    D(k, k) = (GiNaC::exp(p * dt) - 1) / p;
  }
  const GiNaC::matrix Vi = V.inverse();
  const GiNaC::matrix P = V.mul(E).mul(Vi), G = V.mul(D).mul(Vi);
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = 0; j < n; ++j) {
      Phi(at + i, at + j) = P(i, j);
      Gamma(at + i, at + j) = G(i, j);
    }
}

std::string class_name(const std::string& model) {
  return pascal_case(model);
}

struct Points {
  std::vector<GiNaC::exmap> at;  // states, inputs, parameters
  std::vector<std::vector<GiNaC::numeric>> params;
};

Points sample(const Model& m) {
  SampleBoxes boxes = m.sample_boxes();
  for (const auto& s : m.states) {
    const Interval b = m.box(s);  // stay well inside the domain
    boxes.by_name[s.get_name()] = {b.lo + (b.hi - b.lo) / 4, b.hi - (b.hi - b.lo) / 4};
  }
  std::vector<GiNaC::symbol> syms(m.states);
  for (const auto& u : m.inputs) syms.push_back(u);
  Points p;
  p.at = sample_points(syms, boxes, kPoints, 0xC0DE);
  // Parameter sets: the box centre (the generated default) and two other points of the box.
  const auto free = m.free_params();
  for (int k = 0; k < kParamSets; ++k) {
    std::vector<GiNaC::numeric> set;
    for (const auto& q : free) {
      const Interval b = m.box(q);
      const GiNaC::numeric w = k == 0 ? GiNaC::numeric(1, 2) : GiNaC::numeric(k == 1 ? 1 : 7, 8);
      set.push_back(b.lo + (b.hi - b.lo) * w);
    }
    p.params.push_back(set);
  }
  for (int k = 0; k < kPoints; ++k)
    for (std::size_t q = 0; q < free.size(); ++q)
      p.at[static_cast<std::size_t>(k)][free[q]] = p.params[k % kParamSets][q];
  return p;
}

std::string params_setter(const Model& m, const Points& p) {
  std::string s = "template <class P>\ninline void set_params(P& prm, int set) {\n";
  const auto free = m.free_params();
  if (free.empty()) return s + "  (void)prm;\n  (void)set;\n}\n";
  for (int k = 0; k < kParamSets; ++k) {
    s += fmt::format("  if (set == {}) {{\n", k);
    for (std::size_t q = 0; q < free.size(); ++q)
      s += fmt::format("    prm.{} = static_cast<decltype(prm.{})>({:.17e});\n", free[q].get_name(),
                       free[q].get_name(), p.params[k][q].to_double());
    s += "  }\n";
  }
  return s + "}\n";
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
    const std::size_t n = m.n();
    const bool has_T = cf.T_kind == Availability::symbolic;
    const bool has_Tinv = cf.T_inverse_kind == Availability::symbolic;
    const bool z_real = has_T && has_Tinv;
    // The poles the design is given, -(2 + k/2) in state order, taken block by block; each
    // block is a companion matrix of its own poles (ones on the subdiagonal, -c in the last
    // column), its output the block's last coordinate.
    const unsigned un = static_cast<unsigned>(n);
    std::vector<GiNaC::numeric> c(n);  // K, block by block
    std::vector<std::size_t> output_of(n);
    GiNaC::matrix Acl(un, un), Phi(un, un), Gamma(un, un);
    for (std::size_t b = 0, start = 0; b < cf.blocks.size(); start += cf.blocks[b++]) {
      std::vector<GiNaC::numeric> poles;
      for (std::size_t k = 0; k < cf.blocks[b]; ++k)
        poles.push_back(-2 - GiNaC::numeric(static_cast<long>(start + k), 2));
      const auto cb = characteristic_coefficients(poles);
      const std::size_t end = start + cf.blocks[b] - 1;
      for (std::size_t k = 0; k < cf.blocks[b]; ++k) {
        const unsigned i = static_cast<unsigned>(start + k);
        c[start + k] = cb[k];
        output_of[start + k] = b;
        if (k > 0) Acl(i, i - 1) = 1;
        Acl(i, static_cast<unsigned>(end)) = Acl(i, static_cast<unsigned>(end)) - cb[k];
      }
      exact_discretisation(poles, GiNaC::numeric(1, 20), static_cast<unsigned>(start), Phi, Gamma);
    }
    GiNaC::exmap at_x0;
    for (std::size_t i = 0; i < n; ++i) at_x0[m.states[i]] = cf.base_point[i];
    ExVec y0;
    for (const auto& h : m.h) y0.push_back(h.subs(at_x0));

    const Points pts = sample(m);
    Table X, U, F, G, H, T, Z, Tinv, L, FR, C, ZR, XR, STEP, STEP_SCALE;
    for (const auto& pt : pts.at) {
      std::vector<std::string> x, u, f, g, t, z, ti, l, fr, cc, zr, xr, st;
      double scale = 0;  // sum of |terms| of Phi z + Gamma c: the size rounding acts on
      for (const auto& s : m.states) x.push_back(value(s, pt));
      for (const auto& s : m.inputs) u.push_back(value(s, pt));
      for (const auto& e : m.f) f.push_back(value(e, pt));
      for (const auto& e : m.g) g.push_back(value(e, pt));
      std::vector<std::string> hv;
      GiNaC::exmap ypt(pt);
      for (std::size_t q = 0; q < m.p(); ++q) {
        hv.push_back(value(m.h[q], pt));
        ypt[cf.y[q]] = m.h[q].subs(pt);
      }
      H.push_back(hv);
      ExVec cval;
      for (std::size_t i = 0; i < n; ++i) {
        l.push_back(value(cf.l[i], ypt));
        const ex ci = cf.l[i] + c[i] * (cf.y[output_of[i]] - y0[output_of[i]]);
        cc.push_back(value(ci, ypt));
        DigitsGuard dg(30);
        cval.push_back(GiNaC::evalf(ci.subs(ypt)));
      }
      if (has_T) {
        GiNaC::exmap zpt(pt);
        ExVec zv;
        for (std::size_t i = 0; i < n; ++i) {
          t.push_back(value(cf.T[i], pt));
          zpt[cf.z[i]] = cf.T[i].subs(pt);
          zv.push_back(cf.T[i].subs(pt));
        }
        z = t;
        if (has_Tinv)
          for (const auto& e : cf.T_inverse) ti.push_back(value(e, zpt));
        // z' = A_cl z + c at z = T(x), and one exact step of length kStepDt.
        for (std::size_t i = 0; i < n; ++i) {
          ex acc = cval[i], next = 0, size = 0;
          for (std::size_t k = 0; k < n; ++k) {
            const auto ui = static_cast<unsigned>(i), uk = static_cast<unsigned>(k);
            acc += Acl(ui, uk) * zv[k];
            next += Phi(ui, uk) * zv[k] + Gamma(ui, uk) * cval[k];
            size += GiNaC::abs(Phi(ui, uk) * zv[k]) + GiNaC::abs(Gamma(ui, uk) * cval[k]);
          }
          zr.push_back(value(acc, {}));
          st.push_back(value(next, {}));
          scale = std::max(scale, std::stod(value(size, {})));
        }
      }
      for (std::size_t k = 0; k < n; ++k)
        for (std::size_t r = 0; r < n; ++r) fr.push_back(value(cf.frame[k][r], pt));
      // x realisation at (x, u, y = h(x) + 1/10): f + g + [tau] (l(u,y) - l(u,h) + K (y - h)).
      GiNaC::exmap ypx(pt), yh(pt);
      for (std::size_t q = 0; q < m.p(); ++q) {
        ypx[cf.y[q]] = m.h[q].subs(pt) + GiNaC::numeric(1, 10);
        yh[cf.y[q]] = m.h[q].subs(pt);
      }
      for (std::size_t r = 0; r < n; ++r) {
        ex acc = m.field()[r].subs(pt);
        for (std::size_t k = 0; k < n; ++k)
          acc += cf.frame[k][r].subs(pt) *
                 (cf.l[k].subs(ypx) - cf.l[k].subs(yh) + c[k] * GiNaC::numeric(1, 10));
        xr.push_back(value(acc, {}));
      }
      X.push_back(x);
      U.push_back(u);
      F.push_back(f);
      G.push_back(g);
      T.push_back(t);
      Z.push_back(z);
      Tinv.push_back(ti);
      L.push_back(l);
      FR.push_back(fr);
      C.push_back(cc);
      ZR.push_back(zr);
      XR.push_back(xr);
      STEP.push_back(st);
      STEP_SCALE.push_back({fmt::format("{:.17e}", scale)});
    }
    const std::string cls = class_name(m.name);
    std::string s =
        fmt::format("// reference values computed by GiNaC for {}\n#pragma once\n", m.name);
    s += fmt::format(
        "#define OBSYNTH_NS {}\n#define OBSYNTH_CLASS {}Canonical\n#define OBSYNTH_NAME \"{}\"\n",
        m.name, cls, m.name);
    s += fmt::format("#define OBSYNTH_HAS_T {}\n#define OBSYNTH_HAS_TINV {}\n", has_T ? 1 : 0,
                     has_Tinv ? 1 : 0);
    s += fmt::format("#define OBSYNTH_Z_REALISATION {}\n#define OBSYNTH_HAS_FRAME {}\n",
                     z_real ? 1 : 0, z_real ? 0 : 1);
    s += fmt::format("#define OBSYNTH_HAS_PARAMS {}\n", m.free_params().empty() ? 0 : 1);
    // Horizon: the slowest pole (-2) brings a unit error below 1e-8 in ~9 s; larger n has
    // more nearby poles (polynomial factors), so allow one more second per state.
    s += fmt::format("#define OBSYNTH_T_END {}.0\n#define OBSYNTH_INPUT_AMPLITUDE 0.5\n", 10 + n);
    s += fmt::format("namespace ref {{\ninline constexpr int kPoints = {};\n", kPoints);
    s += fmt::format("inline constexpr int kParamSets = {};\n", kParamSets);
    s += fmt::format("inline constexpr double kStepDt = {:.17e};\n", kStepDt);
    s += "inline constexpr double kSlowestPole = -2.0;\n";
    s += array("x", X) + array("u", U) + array("f", F) + array("g", G) + array("h", H) +
         array("T", T) + array("z", Z) + array("Tinv", Tinv) + array("l", L) + array("frame", FR) +
         array("step_constant", C) + array("z_rhs", ZR) + array("x_rhs", XR) +
         array("exact_step", STEP) + array("exact_step_scale", STEP_SCALE);
    // ||A_cl dt||_1: scaling and squaring loses about this factor times the unit roundoff.
    double norm = 0;
    for (unsigned col = 0; col < n; ++col) {
      double sum = 0;
      for (unsigned r = 0; r < n; ++r) sum += std::fabs(std::stod(value(Acl(r, col), {})));
      norm = std::max(norm, sum * kStepDt);
    }
    s += fmt::format("inline constexpr double kAclNormDt = {:.17e};\n", norm);
    s += params_setter(m, pts);
    s += "}  // namespace ref\n";
    std::ofstream(argv[2]) << s;
  } catch (const std::exception& e) {
    std::cerr << "reference: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
