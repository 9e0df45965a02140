// The canonical-form stages after the split: T^-1 as an elimination sequence (issue 6),
// checked against independent derivations: seed 003 by hand, the nested chain family of
// issue 6 by its own construction (exact evaluation at random rational points), the same
// family through a dense linear change of coordinates, the emitter's DAG on the unexpanded
// composition, and byte-identical JSON.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>

#include "analysis/analysis.hpp"
#include "analysis/flint_mpoly.hpp"
#include "analysis/flint_products.hpp"
#include "app/report.hpp"
#include "designs/registry.hpp"
#include "front/parse.hpp"
#include "support/expect.hpp"
#include "symbolic/dag.hpp"
#include "symbolic/poly.hpp"

using namespace obsynth;
using GiNaC::ex;
using GiNaC::numeric;

namespace {

std::string model_path(const std::string& name) {
  return std::string(OBSYNTH_SOURCE_DIR) + "/models/" + name + ".sym";
}

// The nested chain family of issue 6, written here independently of bench/families:
// z_n = x1, z_{n-k} = x_k^2/2 - x_{k+1}; f_1 = z_{n-1} + l_n(0, x1),
// f_k = -(z_{n-k} + l_{n+1-k}(0, x1)) + x_{k-1} f_{k-1}; g likewise with the u-parts.
struct Nested {
  int n;
  std::string zx(int j) const {
    if (j == 0) return "0";
    if (j == n) return "x1";
    return fmt::format("(x{}^2/2 - x{})", n - j, n - j + 1);
  }
  std::string l0(int i) const {
    if (i == 1) return "(-sin(x1))";
    if (i == n) return "(-x1^2/2)";
    return fmt::format("(x1^2/{})", i);
  }
  std::string lu(int i) const {
    if (i == 1) return "((x1^2 + x1 - 1)*u)";
    if (i == n) return "((1 + x1)*u)";
    return "0";
  }
  std::vector<std::string> f() const {
    std::vector<std::string> out{zx(n - 1) + " + " + l0(n)};
    for (int k = 2; k <= n; ++k)
      out.push_back(
          fmt::format("-({} + {}) + x{}*({})", zx(n - k), l0(n + 1 - k), k - 1, out.back()));
    return out;
  }
  std::vector<std::string> g() const {
    std::vector<std::string> out{lu(n)};
    for (int k = 2; k <= n; ++k)
      out.push_back(fmt::format("-{} + x{}*({})", lu(n + 1 - k), k - 1, out.back()));
    return out;
  }
  // T_i(x), i = 1..n, and l_i(u, y).
  ex T(const Model& m, int i) const {
    const auto& x = m.states;
    if (i == n) return x[0];
    const int k = n - i;
    return GiNaC::pow(x[k - 1], 2) / 2 - x[k];
  }
  ex l(int i, const ex& u, const ex& y) const {
    if (i == 1) return -GiNaC::sin(y) + (y * y + y - 1) * u;
    if (i == n) return -y * y / 2 + (1 + y) * u;
    return y * y / i;
  }
  std::string text() const {
    std::string s = fmt::format("model nested{}\nstates", n);
    for (int i = 1; i <= n; ++i) s += fmt::format(" x{}", i);
    s += "\ninputs u\nf = [" + fmt::format("{}", fmt::join(f(), ",\n")) + "]\n";
    s += "g = [" + fmt::format("{}", fmt::join(g(), ",\n")) + "]\nh = [ x1 ]\n";
    return s;
  }
};

// Deterministic rationals in [-1/2, 1/2] with a large prime denominator.
numeric random_rational(std::uint64_t& state) {
  state = state * 6364136223846793005ULL + 1442695040888963407ULL;
  const long p = static_cast<long>((state >> 33) % 1000003ULL) - 500001;
  return numeric(p, 1000003);
}

// Runs the elimination sequence at z exactly: every value must evaluate to a rational.
std::vector<numeric> run_steps(const CanonicalForm& cf, const Model& m,
                               const std::vector<numeric>& z) {
  GiNaC::exmap at;
  for (std::size_t i = 0; i < z.size(); ++i) at[cf.z[i]] = z[i];
  std::vector<numeric> x(z.size());
  for (const auto& s : cf.T_inverse_steps) {
    const ex v = s.value.subs(at);
    EXPECT_TRUE(GiNaC::is_a<numeric>(v)) << to_string(s.value);
    x[s.state] = GiNaC::ex_to<numeric>(v);
    at[m.states[s.state]] = x[s.state];
  }
  return x;
}

TEST(InverseSteps, Seed003ByHand) {
  const Analysis a = analyse(load_model(model_path("slawinski17")));
  const CanonicalForm& cf = a.canonical;
  const auto& x = a.model.states;
  ASSERT_EQ(cf.T_inverse_kind, Availability::symbolic) << cf.T_inverse_note;
  ASSERT_EQ(cf.T_inverse_steps.size(), 2u);
  // x1 = z2 from T_2 = x1; then x2 = x1^2/2 - z1 from T_1 = x1^2/2 - x2 (seed 003 eq. 29).
  const auto& s1 = cf.T_inverse_steps[0];
  const auto& s2 = cf.T_inverse_steps[1];
  EXPECT_EQ(s1.state, 0u);
  EXPECT_EQ(s1.equation, 1u);
  EXPECT_TRUE(GiNaC::normal(s1.value - cf.z[1]).is_zero()) << to_string(s1.value);
  EXPECT_EQ(s2.state, 1u);
  EXPECT_EQ(s2.equation, 0u);
  EXPECT_TRUE(GiNaC::normal(s2.value - (x[0] * x[0] / 2 - cf.z[0])).is_zero())
      << to_string(s2.value);
  // By substitution in the hand-derived T = [x1^2/2 - x2, x1].
  const ExVec T{x[0] * x[0] / 2 - x[1], x[0]};
  for (const auto& s : cf.T_inverse_steps)
    EXPECT_TRUE(
        GiNaC::normal(T[s.equation].subs(x[s.state] == s.value) - cf.z[s.equation]).is_zero());
  // The composition is T^-1(z) = [z2, z2^2/2 - z1].
  EXPECT_TRUE(GiNaC::normal(cf.T_inverse[1] - (cf.z[1] * cf.z[1] / 2 - cf.z[0])).is_zero());
}

class NestedChain : public ::testing::TestWithParam<int> {};

TEST_P(NestedChain, StepsInvertTheConstructedT) {
  const Nested c{GetParam()};
  const int n = c.n;
  const Model m = parse_model(c.text(), "nested.sym");
  const Analysis a = analyse(m);
  const CanonicalForm& cf = a.canonical;
  ASSERT_TRUE(cf.linearizable);
  ASSERT_EQ(cf.T_kind, Availability::symbolic) << cf.T_note;
  ASSERT_EQ(cf.T_inverse_kind, Availability::symbolic) << cf.T_inverse_note;
  ASSERT_EQ(cf.T_inverse_steps.size(), static_cast<std::size_t>(n));
  // T(x0) = 0 at the origin fixes T: it is the constructed one, and so is l.
  for (int i = 1; i <= n; ++i)
    EXPECT_TRUE(GiNaC::expand(cf.T[i - 1] - c.T(m, i)).is_zero()) << to_string(cf.T[i - 1]);
  ASSERT_EQ(cf.l_kind, Availability::symbolic) << cf.l_note;
  for (int i = 1; i <= n; ++i)
    EXPECT_TRUE(GiNaC::expand(cf.l[i - 1] - c.l(i, m.inputs[0], cf.y[0])).is_zero())
        << to_string(cf.l[i - 1]);
  // T(T^-1(z)) = z at random rational points, exactly, with the constructed T.
  std::uint64_t state = 0x1234567 + static_cast<std::uint64_t>(n);
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<numeric> z;
    for (int i = 0; i < n; ++i) z.push_back(random_rational(state));
    const auto x = run_steps(cf, m, z);
    GiNaC::exmap at;
    for (int i = 0; i < n; ++i) at[m.states[i]] = x[i];
    for (int i = 1; i <= n; ++i) EXPECT_EQ(c.T(m, i).subs(at), ex(z[i - 1])) << "T_" << i;
  }
}

INSTANTIATE_TEST_SUITE_P(N2to8, NestedChain, ::testing::Range(2, 9));

TEST(NestedChain, DagOfTheCompositionIsLinearInN) {
  const int n = 16;
  const Model m = parse_model(Nested{n}.text(), "nested.sym");
  const Analysis a = analyse(m);
  const CanonicalForm& cf = a.canonical;
  ASSERT_EQ(cf.T_inverse_kind, Availability::symbolic) << cf.T_inverse_note;
  // x_n has degree 2^15 in z once expanded; the DAG has a few nodes per step.
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::string> z_names;
  for (const auto& s : cf.z) z_names.push_back(s.get_name());
  const NumericFunction fn(cf.T_inverse, z_names);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 1.0);
  Dag dag;
  for (const auto& e : cf.T_inverse) dag.add(e);
  EXPECT_LT(dag.size(), 20u * n);
  // Same values as the recursion x1 = z_n, x_k = -z_{n+1-k} + x_{k-1}^2/2, up to depth 10
  // (beyond, GiNaC's content factors 2^(+-2^k) leave the double range: canonical.hpp).
  std::vector<double> z;
  for (int i = 0; i < n; ++i) z.push_back(0.3 * std::sin(1.0 + i));
  const auto x = fn(z);
  double xk = z[n - 1];
  EXPECT_DOUBLE_EQ(x[0], xk);
  for (int k = 2; k <= 10; ++k) {
    xk = -z[n - k] + xk * xk / 2;
    EXPECT_NEAR(x[k - 1], xk, 1e-14) << k;
  }
}

// The family seen through x = M w (M_ij = min(i, j)): no equation has a single unknown.
TEST(DenseChain, EliminationWithSubstitutionInvertsT) {
  const int n = 3;
  const Nested c{n};
  auto through_M = [&](std::string s) {
    for (int i = n; i >= 1; --i) {
      std::string lin;
      for (int j = 1; j <= n; ++j)
        lin += fmt::format("{}{}*w{}", j > 1 ? "+" : "", std::min(i, j), j);
      std::string::size_type p;
      while ((p = s.find(fmt::format("x{}", i))) != std::string::npos)
        s.replace(p, 2, "(" + lin + ")");
    }
    return s;
  };
  const auto F = c.f(), G = c.g();
  auto row = [&](const std::vector<std::string>& v, int i) {  // (M^-1 v)_i, M^-1 tridiagonal
    std::string s = fmt::format("{}*({})", i < n ? 2 : 1, v[i - 1]);
    if (i > 1) s += " - (" + v[i - 2] + ")";
    if (i < n) s += " - (" + v[i] + ")";
    return through_M(s);
  };
  std::string text = "model dense3\nstates w1 w2 w3\ninputs u\nf = [";
  for (int i = 1; i <= n; ++i) text += row(F, i) + (i < n ? ",\n" : "]\n");
  text += "g = [";
  for (int i = 1; i <= n; ++i) text += row(G, i) + (i < n ? ",\n" : "]\n");
  text += "h = [ " + through_M("x1") + " ]\n";
  const Model m = parse_model(text, "dense.sym");
  const Analysis a = analyse(m);
  const CanonicalForm& cf = a.canonical;
  ASSERT_TRUE(cf.linearizable);
  ASSERT_EQ(cf.T_inverse_kind, Availability::symbolic) << cf.T_inverse_note;
  std::uint64_t state = 99;
  std::vector<numeric> z;
  for (int i = 0; i < n; ++i) z.push_back(random_rational(state));
  const auto w = run_steps(cf, m, z);
  // x = M w, then the constructed T.
  const Model mx = parse_model(Nested{n}.text(), "nested.sym");
  GiNaC::exmap at;
  for (int i = 1; i <= n; ++i) {
    numeric xi = 0;
    for (int j = 1; j <= n; ++j) xi += std::min(i, j) * w[j - 1];
    at[mx.states[i - 1]] = xi;
  }
  for (int i = 1; i <= n; ++i) EXPECT_EQ(c.T(mx, i).subs(at), ex(z[i - 1])) << "T_" << i;
}

std::string nested_json(int n) {
  const Analysis a = analyse(parse_model(Nested{n}.text(), "nested.sym"));
  ReportOptions ro;
  ro.timings = false;
  return render_report(a, ReportFormat::json, ro);
}

TEST(InverseSteps, JsonListsTheStepsAndIsByteIdentical) {
  const std::string first = nested_json(6);
  // Unrelated symbols shift GiNaC's hash seeds and term order.
  std::vector<GiNaC::symbol> noise;
  for (int i = 0; i < 300; ++i) noise.emplace_back("noise" + std::to_string(i));
  ex junk = 0;
  for (const auto& s : noise) junk += GiNaC::pow(s, 3) * GiNaC::exp(s);
  (void)GiNaC::expand(junk * junk);
  EXPECT_EQ(nested_json(6), first);
  const auto j = nlohmann::json::parse(first);
  EXPECT_EQ(j["schema"], 2);
  ASSERT_EQ(j["T_inverse"].size(), 6u);
  EXPECT_EQ(j["T_inverse"][0]["state"], "x1");
  EXPECT_EQ(j["T_inverse"][0]["equation"], 6);
  EXPECT_EQ(j["T_inverse"][0]["value"], "z6");
  EXPECT_EQ(j["T_inverse"][1]["state"], "x2");
  EXPECT_EQ(j["T_inverse"][1]["equation"], 5);
  EXPECT_EQ(j["T_inverse"][1]["value"], "x1^2/2-z5");
}

// FLINT's products agree with GiNaC's expand, with coefficients far beyond 64 bits (both signs)
// and atoms as ring variables.
TEST(FlintProducts, DotDifferenceMatchesExpand) {
  GiNaC::symbol x1("x1"), x2("x2"), k("k");
  const Symbols x{x1, x2};
  const ex big = GiNaC::pow(numeric(2), 100) / GiNaC::pow(numeric(3), 41);
  const ex a = big * x1 * x1 - GiNaC::sin(x1 + x2) * x2 + numeric(-7, 5) * k;
  const ex b = -big * big * x2 + GiNaC::cos(x1 + x2) + 1;
  const ex c = x1 * GiNaC::sin(x1 + x2) - numeric(123456789012345LL) * numeric(98765432109LL);
  const ex d = GiNaC::pow(x1 + x2 + big, 3);
  const auto ring = PolyRing::for_expressions({a, b, c, d}, x);
  ASSERT_TRUE(ring);
  FlintProducts flint(ring->variables());
  auto handle = [&](const ex& e) { return flint.add(*ring->from_ex(e)); };
  const Poly r = flint.dot_difference({handle(a), handle(c)}, {handle(b), handle(d)}, {handle(d)},
                                      {handle(a)});
  const ex expected = GiNaC::expand(a * b + c * d - d * a);
  EXPECT_TRUE(GiNaC::expand(ring->to_ex(r) - expected).is_zero()) << to_string(ring->to_ex(r));
}

// The same above FLINT's threshold (the operands' term pairs exceed kFlintProductWork, so the
// products run in FLINT rather than in the ring), with signed (Laurent) exponents of exp.
TEST(FlintProducts, LargeProductsInFlintMatchExpand) {
  GiNaC::symbol x1("x1"), x2("x2"), x3("x3");
  const Symbols x{x1, x2, x3};
  const ex a = GiNaC::pow(x1 + 2 * x2 - x3 + numeric(1, 3), 7);
  const ex b = GiNaC::pow(x1 - x2 + 3 * x3 * GiNaC::exp(-x1) + 5, 7);
  const ex c = GiNaC::pow(x2 + x3 + 1, 9);
  const auto ring = PolyRing::for_expressions({a, b, c}, x);
  ASSERT_TRUE(ring);
  const Poly pa = *ring->from_ex(a), pb = *ring->from_ex(b), pc = *ring->from_ex(c);
  ASSERT_GT(pa.terms.size() * pb.terms.size() + pc.terms.size() * pa.terms.size(),
            kFlintProductWork);
  FlintProducts flint(ring->variables());
  const auto ha = flint.add(pa), hb = flint.add(pb), hc = flint.add(pc);
  const Poly r = flint.dot_difference({ha}, {hb}, {hc}, {ha});
  const ex expected = GiNaC::expand(a * b - c * a);
  EXPECT_TRUE(GiNaC::expand(ring->to_ex(r) - expected).is_zero());
}

// Issue 17 item 6: a numeric verdict is never taken for a proof.

std::string text_report(const Analysis& a) {
  ReportOptions ro;
  ro.timings = false;
  return render_report(a, ReportFormat::text, ro);
}

// Evaluates e at the point with GiNaC's evalf at 50 digits (not obsynth's zero test).
double evalf_at(const ex& e, const GiNaC::exmap& at) {
  const long saved = GiNaC::Digits;
  GiNaC::Digits = 50;
  const ex v = GiNaC::evalf(e.subs(at));
  GiNaC::Digits = saved;
  return GiNaC::ex_to<numeric>(v).to_double();
}

// C2 of the DC motor with friction tanh(100 w), w in [-800, 800], is (5000/9) tanh(100 w)
// sech^2(100 w) (hand derivation in the model's header): zero within rounding on all but
// 0.03 % of the box, 201.906 at w = 0.005. It fails, with a witness point.
TEST(NumericVerdicts, SteepFrictionBracketFailsWithAWitness) {
  const Analysis a =
      analyse(load_model(std::string(OBSYNTH_SOURCE_DIR) + "/tests/models/dc_motor_tanh.sym"));
  const CanonicalForm& cf = a.canonical;
  const GiNaC::symbol w = a.model.states[1];
  const ex th = GiNaC::tanh(100 * w);
  const ex hand = numeric(5000, 9) * th * (1 - th * th);
  EXPECT_NEAR(evalf_at(hand, {{w, numeric(1, 200)}}), 201.906, 1e-3);
  ASSERT_EQ(cf.drift.size(), 1u);
  const BracketCheck& c2 = cf.drift[0];
  ASSERT_EQ(c2.verdict, ZeroVerdict::nonzero);
  EXPECT_FALSE(cf.linearizable);
  // The residual is the hand-derived bracket: [0, hand] at w = 0.005 and at the witness.
  ASSERT_EQ(c2.residual.size(), 2u);
  EXPECT_NEAR(evalf_at(c2.residual[1], {{w, numeric(1, 200)}}), 201.906, 1e-3);
  EXPECT_NEAR(evalf_at(c2.residual[0], {{w, numeric(1, 200)}}), 0, 1e-12);
  ASSERT_EQ(c2.witness.count(w), 1u);
  const double at_witness = evalf_at(hand, c2.witness);
  EXPECT_GT(std::abs(at_witness), 1e-6);
  EXPECT_NEAR(evalf_at(c2.residual[1], c2.witness), at_witness, 1e-9 * std::abs(at_witness));
  const std::string text = text_report(a);
  EXPECT_NE(text.find("FAILS (nonzero)"), std::string::npos) << text;
  EXPECT_NE(text.find("=> NOT linearizable"), std::string::npos) << text;
  EXPECT_NE(text.find("nonzero at w = "), std::string::npos) << text;
  EXPECT_FALSE(find_design("canonical")->applies(a).applies);
}

// C2 = [0, d^2 phi / dx2^2] for f = [x2, phi] and h = x1; with
// phi = -x1 - x2 + x2^2 (atan(e^x2) + atan(e^-x2) - pi/2) it is zero (the bracket is 0 for
// every x2, as atan e^a + atan e^-a = pi/2), but no rewrite proves it: numeric only.
TEST(NumericVerdicts, NumericZeroNeverConcludesLinearizable) {
  const Model m = parse_model(
      "model atan_identity\nstates x1 x2\n"
      "f = [ x2, -x1 - x2 + x2^2*(atan(exp(x2)) + atan(exp(-x2)) - 2*atan(1)) ]\n"
      "h = [ x1 ]\ndomain x1 in [-2, 2], x2 in [-2, 2]\n",
      "atan_identity.sym");
  const Analysis a = analyse(m);
  const CanonicalForm& cf = a.canonical;
  ASSERT_EQ(cf.drift.size(), 1u);
  // Independent oracle: the residual vanishes at a hand-chosen point, by evalf.
  ASSERT_EQ(cf.drift[0].residual.size(), 2u);
  const GiNaC::exmap at{{m.states[0], numeric(3, 7)}, {m.states[1], numeric(-5, 4)}};
  EXPECT_NEAR(evalf_at(cf.drift[0].residual[1], at), 0, 1e-30);
  EXPECT_EQ(cf.drift[0].verdict, ZeroVerdict::numeric);
  EXPECT_GT(cf.drift[0].zero_points, 0);
  const std::string text = text_report(a);
  EXPECT_NE(
      text.find(fmt::format("unproven (numerically zero at {} points)", cf.drift[0].zero_points)),
      std::string::npos)
      << text;
  EXPECT_EQ(text.find("=> linearizable"), std::string::npos) << text;
  EXPECT_EQ(text.find("holds (numeric)"), std::string::npos) << text;
  ReportOptions ro;
  ro.timings = false;
  const auto j = nlohmann::json::parse(render_report(a, ReportFormat::json, ro));
  EXPECT_FALSE(j["linearizable"].get<bool>());
  EXPECT_EQ(j["linearizability"], "unproven");
  for (const char* method : {"canonical", "perfect"}) {
    const Verdict v = find_design(method)->applies(a);
    EXPECT_NE(v.guarantee, Guarantee::rigorous) << method;
  }
}

// The designs read the verdicts as given: seed 003 with every condition proved is rigorous;
// the same analysis with C2 only numerically zero is offered, partial, and says so.
TEST(NumericVerdicts, CanonicalDesignsAreRigorousOnlyWhenProved) {
  Analysis a = analyse(load_model(model_path("slawinski17")));
  for (const char* method : {"canonical", "perfect"}) {
    const Verdict v = find_design(method)->applies(a);
    EXPECT_TRUE(v.applies) << method;
    EXPECT_EQ(v.guarantee, Guarantee::rigorous) << method << ": " << v.guarantee_text;
  }
  EXPECT_NE(text_report(a).find("=> linearizable by output injection"), std::string::npos);
  ASSERT_EQ(a.canonical.drift.size(), 1u);
  a.canonical.drift[0].verdict = ZeroVerdict::numeric;
  a.canonical.drift[0].zero_points = 23;
  for (const char* method : {"canonical", "perfect"}) {
    const Verdict v = find_design(method)->applies(a);
    EXPECT_TRUE(v.applies) << method;
    EXPECT_EQ(v.guarantee, Guarantee::partial) << method;
    EXPECT_NE(v.guarantee_text.find("numeric"), std::string::npos) << v.guarantee_text;
    EXPECT_NE(v.text().find("[tau_1, tau_2] = 0 (numerically zero at 23 points)"),
              std::string::npos)
        << v.text();
  }
  const std::string text = text_report(a);
  EXPECT_NE(text.find("unproven (numerically zero at 23 points)"), std::string::npos) << text;
  EXPECT_EQ(text.find("=> linearizable"), std::string::npos) << text;
}

}  // namespace
