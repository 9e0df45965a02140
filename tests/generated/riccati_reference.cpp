// Reference values for a generated Riccati observer (seed 000 eq. 2.1-2.2), computed by GiNaC
// (evalf, 30 digits) from the model's maps with dense matrices, independently of
// synth/designs/riccati.cpp, the DAG, CSE and the printers:
//   m' = f + g + Q C^T W (y - h),  Q' = A Q + Q A^T - Q C^T W C Q + N N^T,
//   A = d(f + g)/dx,  C = dh/dx,  W = R^-1 R^-1 (H = R^-1 C: R acts as a standard deviation).
// usage: riccati_reference <model.sym> <out.hpp> <Q0> <N> <R>
// Q0, N, R: comma-separated rationals, d values (diagonal) or d*d (row-major).
#include <fmt/format.h>

#include <fstream>
#include <iostream>
#include <sstream>

#include "front/parse.hpp"
#include "reference_value.hpp"

using namespace obsynth;
using GiNaC::ex;

namespace {

constexpr int kPoints = 6;
constexpr int kParamSets = 3;

GiNaC::matrix matrix_arg(const std::string& text, unsigned d) {
  std::vector<GiNaC::numeric> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) v.emplace_back(item.c_str());
  GiNaC::matrix M(d, d);
  if (v.size() == d * d) {
    for (unsigned r = 0; r < d; ++r)
      for (unsigned c = 0; c < d; ++c) M(r, c) = v[r * d + c];
  } else if (v.size() == d) {
    for (unsigned i = 0; i < d; ++i) M(i, i) = v[i];
  } else {
    throw std::runtime_error("riccati_reference: bad matrix argument " + text);
  }
  return M;
}

// Deterministic rationals in [lo, hi].
struct Lcg {
  std::uint64_t s = 0x5eed1234abcdULL;
  GiNaC::numeric next(const GiNaC::numeric& lo, const GiNaC::numeric& hi) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    const long k = static_cast<long>((s >> 33) % 1000);
    return lo + (hi - lo) * GiNaC::numeric(k, 999);
  }
};

using Row = std::vector<std::string>;

std::string array(const std::string& name, const std::vector<Row>& rows) {
  std::size_t width = 1;
  for (const auto& r : rows) width = std::max(width, r.size());
  std::string s =
      fmt::format("inline constexpr double {}[{}][{}] = {{\n", name, rows.size(), width);
  for (const auto& r : rows)
    s += fmt::format("    {{{}}},\n",
                     r.empty() ? std::string("0.0") : fmt::format("{}", fmt::join(r, ", ")));
  return s + "};\n";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 6) {
    std::cerr << "usage: riccati_reference <model.sym> <out.hpp> <Q0> <N> <R>\n";
    return 2;
  }
  try {
    const Model m = load_model(argv[1]);
    const unsigned n = static_cast<unsigned>(m.n()), p = static_cast<unsigned>(m.p());
    const GiNaC::matrix Q0 = matrix_arg(argv[3], n), N = matrix_arg(argv[4], n),
                        R = matrix_arg(argv[5], p);
    const GiNaC::matrix Rinv = R.inverse();
    const GiNaC::matrix W = Rinv.mul(Rinv);
    const GiNaC::matrix NNt = N.mul(N.transpose());
    GiNaC::matrix F(n, 1), Hm(p, 1), A(n, n), C(p, n);
    for (unsigned i = 0; i < n; ++i) F(i, 0) = m.f[i] + m.g[i];
    for (unsigned k = 0; k < p; ++k) Hm(k, 0) = m.h[k];
    for (unsigned i = 0; i < n; ++i)
      for (unsigned j = 0; j < n; ++j) A(i, j) = F(i, 0).diff(m.states[j]);
    for (unsigned k = 0; k < p; ++k)
      for (unsigned j = 0; j < n; ++j) C(k, j) = Hm(k, 0).diff(m.states[j]);

    Lcg rng;
    const auto free = m.free_params();
    std::vector<std::vector<GiNaC::numeric>> sets;
    for (int k = 0; k < kParamSets; ++k) {
      std::vector<GiNaC::numeric> set;
      for (const auto& q : free) {
        const Interval b = m.box(q);
        set.push_back(b.lo + (b.hi - b.lo) * (k == 0 ? GiNaC::numeric(1, 2)
                                                     : GiNaC::numeric(k == 1 ? 1 : 7, 8)));
      }
      sets.push_back(set);
    }
    std::vector<Row> xs, Qs, us, ys, dms, dQs;
    for (int k = 0; k < kPoints; ++k) {
      GiNaC::exmap at;
      Row xr, ur, yr, Qr, dmr, dQr;
      for (const auto& s : m.states) {
        const Interval b = m.box(s);
        const GiNaC::numeric v = rng.next(b.lo + (b.hi - b.lo) / 4, b.hi - (b.hi - b.lo) / 4);
        at[s] = v;
        xr.push_back(fmt::format("{:.17e}", v.to_double()));
      }
      for (const auto& s : m.inputs) {
        const Interval b = m.box(s);
        const GiNaC::numeric v = rng.next(b.lo, b.hi);
        at[s] = v;
        ur.push_back(fmt::format("{:.17e}", v.to_double()));
      }
      for (std::size_t q = 0; q < free.size(); ++q) at[free[q]] = sets[k % kParamSets][q];
      // Q = L L^T + I/2 with L lower triangular, entries in [-1, 1]: symmetric > 0.
      GiNaC::matrix L(n, n);
      for (unsigned r = 0; r < n; ++r)
        for (unsigned c = 0; c <= r; ++c) L(r, c) = rng.next(-1, 1);
      GiNaC::matrix Q = L.mul(L.transpose());
      for (unsigned i = 0; i < n; ++i) Q(i, i) += GiNaC::numeric(1, 2);
      GiNaC::matrix y(p, 1);
      for (unsigned j = 0; j < p; ++j) {
        y(j, 0) = rng.next(-2, 2);
        yr.push_back(fmt::format("{:.17e}", GiNaC::ex_to<GiNaC::numeric>(y(j, 0)).to_double()));
      }
      GiNaC::matrix Ax(n, n), Cx(p, n), Fx(n, 1), e(p, 1);
      for (unsigned i = 0; i < n; ++i) {
        Fx(i, 0) = F(i, 0).subs(at);
        for (unsigned j = 0; j < n; ++j) Ax(i, j) = A(i, j).subs(at);
      }
      for (unsigned j = 0; j < p; ++j) {
        e(j, 0) = y(j, 0) - Hm(j, 0).subs(at);
        for (unsigned c = 0; c < n; ++c) Cx(j, c) = C(j, c).subs(at);
      }
      const GiNaC::matrix dm = Fx.add(Q.mul(Cx.transpose()).mul(W).mul(e));
      const GiNaC::matrix dQ = Ax.mul(Q)
                                   .add(Q.mul(Ax.transpose()))
                                   .sub(Q.mul(Cx.transpose()).mul(W).mul(Cx).mul(Q))
                                   .add(NNt);
      const GiNaC::exmap none;
      for (unsigned i = 0; i < n; ++i) dmr.push_back(testing::reference_value(dm(i, 0), none));
      for (unsigned r = 0; r < n; ++r)
        for (unsigned c = 0; c < n; ++c) {
          Qr.push_back(testing::reference_value(Q(r, c), none));
          dQr.push_back(testing::reference_value(dQ(r, c), none));
        }
      xs.push_back(xr), us.push_back(ur), ys.push_back(yr), Qs.push_back(Qr);
      dms.push_back(dmr), dQs.push_back(dQr);
    }
    std::string s = fmt::format(
        "// riccati_reference: GiNaC reference values for {} (do not edit)\n#pragma once\n"
        "#define OBSYNTH_HAS_PARAMS {}\nnamespace ref {{\n"
        "inline constexpr int kPoints = {};\ninline constexpr int kParamSets = {};\n",
        m.name, free.empty() ? 0 : 1, kPoints, kParamSets);
    s += array("x", xs) + array("u", us) + array("y", ys) + array("Q", Qs) + array("dm", dms) +
         array("dQ", dQs);
    Row q0;
    for (unsigned r = 0; r < n; ++r)
      for (unsigned c = 0; c < n; ++c) q0.push_back(testing::reference_value(Q0(r, c), {}));
    s += array("Q0", {q0});
    s += "template <class P>\ninline void set_params(P& prm, int set) {\n";
    if (free.empty()) s += "  (void)prm;\n  (void)set;\n";
    for (int k = 0; k < kParamSets && !free.empty(); ++k) {
      s += fmt::format("  if (set == {}) {{\n", k);
      for (std::size_t q = 0; q < free.size(); ++q)
        s += fmt::format("    prm.{0} = static_cast<decltype(prm.{0})>({1:.17e});\n",
                         free[q].get_name(), sets[k][q].to_double());
      s += "  }\n";
    }
    s += "}\n}  // namespace ref\n";
    std::ofstream(argv[2]) << s;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "riccati_reference: " << e.what() << "\n";
    return 1;
  }
}
