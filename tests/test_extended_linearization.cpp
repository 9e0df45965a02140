// Extended linearization (Baumann-Rugh, seed 001 §5). Oracles written here, independently of
// synth/designs/extended_linearization.cpp:
//  - the injections and families derived by hand in models/pendulum.sym (below) and
//    models/cart_pendulum.sym (in its comments), compared exactly (normal(a - b) == 0) or through
//    GiNaC's own Taylor series of the hand formulas;
//  - the eigenvalues of the linearized error dynamics, from the generated right-hand side
//    differentiated by GiNaC and evaluated at the exact (hand) equilibria, by Eigen;
//  - closed-loop convergence with `simulate`.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>

#include "analysis/analysis.hpp"
#include "app/simulate.hpp"
#include "app/synthesize.hpp"
#include "designs/extended_linearization.hpp"
#include "designs/registry.hpp"
#include "front/parse.hpp"
#include "support/construct.hpp"

using namespace obsynth;
using GiNaC::ex;

namespace {

Model load(const std::string& name) {
  return load_model(std::string(OBSYNTH_SOURCE_DIR) + "/models/" + name + ".sym");
}

Model model_text(const char* text) {
  return parse_model(text, "t.sym");
}

DesignOptions opts(std::map<std::string, std::string> v) {
  DesignOptions o;
  o.values = std::move(v);
  return o;
}

// Taylor polynomial of e in y up to y^order, by GiNaC's series.
ex taylor_of(const ex& e, const GiNaC::symbol& y, int order) {
  return GiNaC::series_to_poly(e.series(y == 0, order + 1));
}

bool exactly_equal(const ex& a, const ex& b) {
  return GiNaC::normal(GiNaC::expand(a - b)).is_zero();
}

// Pendulum, by hand: family x = (e, 0), u = sin e; A = [[0, 1], [-cos e, -1/4]], H = [1, 0];
// det(lambda I - A + c H) = lambda^2 + (c1 + 1/4) lambda + c1/4 + cos e + c2 = (lambda+1)(lambda+2)
// => c1 = 11/4, c2 = 21/16 - cos e; k(y) = [11/4 y, 21/16 y - sin y].
ExVec pendulum_k(const GiNaC::symbol& y) {
  return {GiNaC::numeric(11, 4) * y, GiNaC::numeric(21, 16) * y - GiNaC::sin(y)};
}
// Cart pendulum, by hand (models/cart_pendulum.sym): k(y) = [3 asin y, 2 asin y + atanh y].
ExVec cart_k(const GiNaC::symbol& y) {
  return {3 * GiNaC::asin(y), 2 * GiNaC::asin(y) + GiNaC::atanh(y)};
}

// Eigenvalues (sorted by real part) of d rhs / d xh at xh = x, y = h(x), u given: the
// linearized error dynamics of e = x - xh.
std::vector<std::complex<double>> error_eigenvalues(const Model& m, const ObserverSpec& s,
                                                    const std::vector<double>& x, double u,
                                                    const GiNaC::exmap& params = {}) {
  const GeneratedFunction* rhs = s.function(s.roles.rhs);
  EXPECT_NE(rhs, nullptr);
  GiNaC::exmap lets;
  ExVec out = rhs->outputs;
  for (auto it = rhs->lets.rbegin(); it != rhs->lets.rend(); ++it)
    for (auto& e : out) e = e.subs(it->symbol == it->value);
  GiNaC::exmap pt = params;
  for (std::size_t i = 0; i < m.n(); ++i) pt[m.states[i]] = x[i];
  pt[m.inputs[0]] = u;
  // The output argument y = h(x), every output.
  const auto& yarg = rhs->args[2];
  GiNaC::exmap y_at;
  for (std::size_t l = 0; l < m.p(); ++l) y_at[yarg.symbols[l]] = GiNaC::evalf(m.h[l].subs(pt));
  const std::size_t n = m.n();
  Eigen::MatrixXd J(n, n);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      ex d = out[i].diff(m.states[j]).subs(y_at).subs(pt);
      J(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) =
          GiNaC::ex_to<GiNaC::numeric>(GiNaC::evalf(d)).to_double();
    }
  Eigen::EigenSolver<Eigen::MatrixXd> es(J);
  std::vector<std::complex<double>> ev;
  for (Eigen::Index k = 0; k < es.eigenvalues().size(); ++k) ev.push_back(es.eigenvalues()(k));
  std::sort(ev.begin(), ev.end(), [](auto a, auto b) { return a.real() < b.real(); });
  return ev;
}

double deviation(const std::vector<std::complex<double>>& ev, const std::vector<double>& want) {
  double d = 0;
  for (std::size_t k = 0; k < ev.size(); ++k) d = std::max(d, std::abs(ev[k] - want[k]));
  return d;
}

TEST(ExtendedLinearization, RegisteredAndListed) {
  ASSERT_NE(find_design("extended-linearization"), nullptr);
  const auto& planned = planned_methods();
  EXPECT_EQ(std::count(planned.begin(), planned.end(), "extended-linearization"), 0);
}

TEST(ExtendedLinearization, PendulumClosedForm) {
  const Model m = load("pendulum");
  const auto& r = extended_linearization(m, {});
  ASSERT_TRUE(r.failures.empty()) << r.failures[0];
  EXPECT_TRUE(r.family_closed);
  EXPECT_TRUE(r.injection_closed);
  ASSERT_EQ(r.x_eps.size(), 2u);
  EXPECT_TRUE(exactly_equal(r.x_eps[0], r.eps));
  EXPECT_TRUE(exactly_equal(r.x_eps[1], 0));
  EXPECT_TRUE(exactly_equal(r.u_eps, GiNaC::sin(r.eps)));
  EXPECT_DOUBLE_EQ(r.det_A0, 1);   // det [[0, 1], [-1, -1/4]]
  EXPECT_DOUBLE_EQ(r.dy_deps, 1);  // -[1 0] A0^-1 [0 1]^T
  const ExVec k = pendulum_k(r.y[0]);
  ASSERT_EQ(r.injection.size(), 2u);
  for (int i = 0; i < 2; ++i) EXPECT_TRUE(exactly_equal(r.injection[i], k[i])) << r.injection[i];
}

// The series injection (eq. 42-45) equals the Taylor polynomial of the closed form to order m.
TEST(ExtendedLinearization, PendulumSeriesAgreesWithClosedForm) {
  const Model m = load("pendulum");
  for (int order : {3, 6, 9}) {
    const auto& r = extended_linearization(
        m, opts({{"el-injection", "series"}, {"el-order", std::to_string(order)}}));
    ASSERT_TRUE(r.failures.empty());
    EXPECT_FALSE(r.injection_closed);
    EXPECT_EQ(r.injection_order, order);
    const ExVec k = pendulum_k(r.y[0]);
    for (int i = 0; i < 2; ++i)
      EXPECT_TRUE(exactly_equal(r.injection[i], taylor_of(k[i], r.y[0], order)))
          << "order " << order << ": " << r.injection[i];
  }
}

TEST(ExtendedLinearization, CartPendulumSeriesFamilyAndInjection) {
  const Model m = load("cart_pendulum");
  const auto& r = extended_linearization(m, {});
  ASSERT_TRUE(r.failures.empty()) << r.failures[0];
  EXPECT_FALSE(r.family_closed);  // asin is not found by elimination
  EXPECT_FALSE(r.injection_closed);
  const int N = r.family_order, M = r.injection_order;
  EXPECT_EQ(M, 6);
  // Family: x1 = asin(eps), x2 = 0, u = eps / sqrt(1 - eps^2).
  EXPECT_TRUE(exactly_equal(r.x_eps[0], taylor_of(GiNaC::asin(r.eps), r.eps, N)));
  EXPECT_TRUE(exactly_equal(r.x_eps[1], 0));
  EXPECT_TRUE(exactly_equal(r.u_eps, taylor_of(r.eps / GiNaC::sqrt(1 - r.eps * r.eps), r.eps, N)));
  const ExVec k = cart_k(r.y[0]);
  for (int i = 0; i < 2; ++i)
    EXPECT_TRUE(exactly_equal(r.injection[i], taylor_of(k[i], r.y[0], M))) << r.injection[i];
  // A longer series agrees too (order 9).
  const auto& r9 = extended_linearization(m, opts({{"el-order", "9"}}));
  ASSERT_TRUE(r9.failures.empty());
  const ExVec k9 = cart_k(r9.y[0]);  // each result has its own symbol y
  for (int i = 0; i < 2; ++i)
    EXPECT_TRUE(exactly_equal(r9.injection[i], taylor_of(k9[i], r9.y[0], 9))) << r9.injection[i];
}

// Eigenvalues of the linearized error at points of the family: exactly the poles for the closed
// form (pendulum, far from the base point too); for the series injection of order m the
// deviation is O(eps^m) (cart pendulum, m = 6: leading error term eps^6).
TEST(ExtendedLinearization, EigenvaluesInvariantAlongFamily) {
  {
    const Model m = load("pendulum");
    const Analysis a = analyse(m);
    for (const auto& poles : {std::string(""), std::string("-3,-0.5")}) {
      const ObserverSpec s =
          build_design(a, "extended-linearization",
                       poles.empty() ? DesignOptions{} : opts({{"el-poles", poles}}));
      const std::vector<double> want =
          poles.empty() ? std::vector<double>{-2, -1} : std::vector<double>{-3, -0.5};
      for (double e : {-2.0, -0.7, 0.0, 0.3, 1.0, 2.5}) {
        const auto ev = error_eigenvalues(m, s, {e, 0}, std::sin(e));
        EXPECT_LT(deviation(ev, want), 1e-9) << "eps = " << e;
      }
    }
  }
  {
    const Model m = load("cart_pendulum");
    const Analysis a = analyse(m);
    const ObserverSpec s = build_design(a, "extended-linearization", {});
    auto dev = [&](double e) {
      const double x1 = std::asin(e);
      return deviation(error_eigenvalues(m, s, {x1, 0}, std::tan(x1)), {-2, -1});
    };
    EXPECT_LT(dev(0), 1e-12);
    const double d1 = dev(0.2), d2 = dev(0.1), d3 = dev(0.05);
    std::printf(
        "cart pendulum, series injection m = 6: eigenvalue deviation %.3g, %.3g, %.3g at "
        "eps = 0.2, 0.1, 0.05\n",
        d1, d2, d3);
    EXPECT_GT(d1, 0);
    // Order 6: halving eps divides the deviation by about 2^6.
    EXPECT_GT(d2 / d3, 40) << d2 << " " << d3;
    EXPECT_LT(d2 / d3, 100) << d2 << " " << d3;
    EXPECT_GT(d1 / d2, 30) << d1 << " " << d2;
    EXPECT_LT(d2, 1e-4);
  }
}

// Free parameters stay symbolic: the eigenvalues are the poles at every parameter value.
// pendulum_params by hand: family x = (e, 0), u = mgl sin e.
TEST(ExtendedLinearization, RuntimeParametersKeepEigenvalues) {
  const Model m = load("pendulum_params");
  const ObserverSpec s = build_design(analyse(m), "extended-linearization", {});
  EXPECT_EQ(s.params.size(), 3u);
  for (const auto& prm :
       std::vector<std::array<double, 3>>{{0.5, 0.1, 0.5}, {2, 0.5, 1.5}, {1.2, 0.3, 0.7}}) {
    GiNaC::exmap pv;
    for (const auto& p : m.params)
      pv[p.symbol] = p.name == "mgl" ? prm[0] : p.name == "b" ? prm[1] : prm[2];
    for (double e : {-1.0, 0.2, 1.5}) {
      const auto ev = error_eigenvalues(m, s, {e, 0}, prm[0] * std::sin(e), pv);
      EXPECT_LT(deviation(ev, {-2, -1}), 1e-9) << "eps = " << e << ", mgl = " << prm[0];
    }
  }
}

// A base equilibrium away from the origin, given with --el-base (x1 = 1, x2 = 0, u = 0).
TEST(ExtendedLinearization, BaseEquilibriumOption) {
  const Model m = model_text(
      "model sh\nstates x1 x2\ninputs u\nf = [x2, -(x1 - 1)^3 - (x1 - 1) - x2]\ng = [0, u]\nh = "
      "[x1]\n");
  const Analysis a = analyse(m);
  const Verdict v = find_design("extended-linearization")->applies(a);
  EXPECT_FALSE(v.applies);
  EXPECT_NE(v.text().find("is not an equilibrium: f(x0) + g(x0, u0) = [0, 2]"), std::string::npos)
      << v.text();
  EXPECT_THROW(build_design(a, "extended-linearization", opts({{"el-base", "1,0"}})), UserError);
  const ObserverSpec s = build_design(a, "extended-linearization", opts({{"el-base", "1,0,0"}}));
  // Family by hand: x1 = 1 + e, x2 = 0, u = e^3 + e.
  for (double e : {-0.5, 0.0, 0.4, 1.0}) {
    const auto ev = error_eigenvalues(m, s, {1 + e, 0}, e * e * e + e);
    EXPECT_LT(deviation(ev, {-2, -1}), 1e-9) << "eps = " << e;
  }
}

double final_error(const SimulationResult& r) {
  double e = 0;
  for (size_t i = 0; i < r.names.size(); ++i)
    e = std::max(e, std::abs(r.x.back()[i] - r.xh.back()[i]));
  return e;
}

TEST(ExtendedLinearization, ClosedLoopConvergesNearFamily) {
  {
    SimulationOptions o;
    o.method = "extended-linearization";
    o.u_text = "sin(1/2) + 1/5*sin(t)";
    o.x0 = {0.5, 0};
    o.xhat0 = {0.8, -0.4};
    o.t_end = 15;
    o.dt = 1e-3;
    const auto r = simulate(analyse(load("pendulum")), o);
    EXPECT_TRUE(r.diverged.empty()) << r.diverged;
    EXPECT_LT(final_error(r), 1e-5);
  }
  {
    // At the equilibrium x1 = asin(1/5), u = tan(x1) of the (open-loop unstable) cart pendulum.
    SimulationOptions o;
    o.method = "extended-linearization";
    o.u_text = "1/5/sqrt(24/25)";
    o.x0 = {std::asin(0.2), 0};
    o.xhat0 = {std::asin(0.2) + 0.05, -0.05};
    o.t_end = 10;
    o.dt = 1e-3;
    const auto r = simulate(analyse(load("cart_pendulum")), o);
    EXPECT_TRUE(r.diverged.empty()) << r.diverged;
    const double e0 = 0.05;
    EXPECT_LT(final_error(r), 1e-3 * e0);
    EXPECT_LT(std::abs(r.x.back()[0] - std::asin(0.2)), 1e-6);  // the plant stayed there
  }
}

TEST(ExtendedLinearization, ConstraintsReportedWithNumbers) {
  // (i): the double integrator has det A0 = 0.
  const Model di =
      model_text("model di\nstates x1 x2\ninputs u\nf = [x2, 0]\ng = [0, u]\nh = [x1]\n");
  const Verdict v1 = find_design("extended-linearization")->applies(analyse(di));
  EXPECT_FALSE(v1.applies);
  EXPECT_NE(v1.text().find("constraint (i) fails: det(d(f+g)/dx) at the base point = 0"),
            std::string::npos)
      << v1.text();
  // (iii): the input enters bilinearly, B0 = 0, dy/deps = 0.
  const Model bl = model_text(
      "model bl\nstates x1 x2\ninputs u\nf = [-x1 + x2, -x2]\ng = [0, u*x1]\nh = [x1]\n");
  const Verdict v3 = find_design("extended-linearization")->applies(analyse(bl));
  EXPECT_FALSE(v3.applies);
  EXPECT_NE(v3.text().find("constraint (iii) fails: dy_eps/deps = -H0 A0^-1 B0 = 0"),
            std::string::npos)
      << v3.text();
  // (ii): x2 invisible in the linearisation.
  const Model un =
      model_text("model un\nstates x1 x2\ninputs u\nf = [-x1 + x2^2, -x2]\ng = [0, u]\nh = [x1]\n");
  const Verdict v2 = find_design("extended-linearization")->applies(analyse(un));
  EXPECT_FALSE(v2.applies);
  EXPECT_NE(v2.text().find("constraint (ii) fails"), std::string::npos) << v2.text();
  // No input: no family.
  const Model ni = model_text("model ni\nstates x1 x2\nf = [x2, -x1]\nh = [x1]\n");
  EXPECT_FALSE(find_design("extended-linearization")->applies(analyse(ni)).applies);
  // Not an equilibrium at the origin.
  const Model ne =
      model_text("model ne\nstates x1 x2\ninputs u\nf = [x2, 1 - x1]\ng = [0, u]\nh = [x1]\n");
  const Verdict v4 = find_design("extended-linearization")->applies(analyse(ne));
  EXPECT_FALSE(v4.applies);
  EXPECT_NE(v4.text().find("not an equilibrium"), std::string::npos) << v4.text();
  // The pendulum: applies, with the constraint numbers.
  const Verdict vp = find_design("extended-linearization")->applies(analyse(load("pendulum")));
  EXPECT_TRUE(vp.applies) << vp.text();
  EXPECT_NE(vp.text().find("det A0 = 1"), std::string::npos) << vp.text();
}

TEST(ExtendedLinearization, BadOptionsAreDiagnosed) {
  const Analysis a = analyse(load("pendulum"));
  EXPECT_THROW(build_design(a, "extended-linearization", opts({{"el-poles", "-1"}})), UserError);
  EXPECT_THROW(build_design(a, "extended-linearization", opts({{"el-poles", "-1,2"}})), UserError);
  EXPECT_THROW(build_design(a, "extended-linearization", opts({{"el-order", "0"}})), UserError);
  EXPECT_THROW(build_design(a, "extended-linearization", opts({{"el-injection", "magic"}})),
               UserError);
  // Closed form demanded where the integrals do not close: the cart pendulum's family is a series.
  EXPECT_THROW(build_design(analyse(load("cart_pendulum")), "extended-linearization",
                            opts({{"el-injection", "closed"}})),
               UserError);
}

// Odd and larger n (5, 7, 8): chain x_i' = x_{i+1} - x_i, x_n' = -x_n + sin(x1)/5 + u, y = x1.
// By hand: the family is x_i = eps for every i, u = eps - sin(eps)/5. The eigenvalues of the
// linearized error (GiNaC derivative of the emitted rhs, Eigen) are the default poles
// -1, ..., -n at points along it (odd n were refused before: the self-check's sign), and the
// closed loop converges near the family.
std::string el_chain(int n) {
  std::string states, f, g;
  for (int i = 1; i <= n; ++i) {
    states += " x" + std::to_string(i);
    f += i < n ? "x" + std::to_string(i + 1) + " - x" + std::to_string(i) + ", "
               : "-x" + std::to_string(n) + " + sin(x1)/5";
    g += i < n ? "0, " : "u";
  }
  return "model elchain" + std::to_string(n) + "\nstates" + states + "\ninputs u\nf = [ " + f +
         " ]\ng = [ " + g + " ]\nh = [ x1 ]\n";
}

TEST(ExtendedLinearization, ChainsOfFiveToEightStates) {
  for (int n : {5, 7, 8}) {
    const Model m = model_text(el_chain(n).c_str());
    const auto& r = extended_linearization(m, {});
    ASSERT_TRUE(r.failures.empty()) << "n = " << n << ": " << r.failures[0];
    EXPECT_TRUE(r.family_closed);
    for (int i = 0; i < n; ++i) EXPECT_TRUE(exactly_equal(r.x_eps[i], r.eps));
    EXPECT_TRUE(exactly_equal(r.u_eps, r.eps - GiNaC::sin(r.eps) / 5));
    const Analysis a = analyse(m);
    const ObserverSpec s = build_design(a, "extended-linearization", {});
    std::vector<double> want;
    for (int k = n; k >= 1; --k) want.push_back(-k);
    for (double e : {-1.5, -0.4, 0.0, 0.6, 1.7}) {
      const auto ev = error_eigenvalues(m, s, std::vector<double>(n, e), e - std::sin(e) / 5);
      EXPECT_LT(deviation(ev, want), 1e-7) << "n = " << n << ", eps = " << e;
    }
    SimulationOptions o;
    o.method = "extended-linearization";
    o.u_text = "1/2 - sin(1/2)/5 + 1/10*sin(t)";
    o.x0.assign(n, 0.5);
    o.xhat0.assign(n, 0.5);
    o.xhat0[0] = 0.8;
    o.xhat0[n - 1] = 0.1;
    o.t_end = 20;
    o.dt = 1e-3;
    const auto sim = simulate(a, o);
    EXPECT_TRUE(sim.diverged.empty()) << sim.diverged;
    EXPECT_LT(final_error(sim), 1e-5) << "n = " << n;
  }
}

// A constructed 7-state rational chain: the closed-form family outgrows its budget (series
// instead), and the symbolic gain schedule is not attempted, with the sizes in the message;
// it returns in seconds (it took minutes without the budgets).
TEST(ExtendedLinearization, ExpressionBudgetStopsLargeConstructions) {
  const Model m = obsynth::testing::linearizable_chain(7, obsynth::testing::Flavor::stable).model;
  const auto& r = extended_linearization(m, {});
  ASSERT_FALSE(r.failures.empty());
  EXPECT_NE(r.failures[0].find("gain schedule is not attempted"), std::string::npos)
      << r.failures[0];
  EXPECT_NE(r.failures[0].find("past the budget of 20000"), std::string::npos) << r.failures[0];
  bool abandoned = false;
  for (const auto& note : r.notes)
    abandoned =
        abandoned || note.find("closed-form equilibrium family was abandoned") != std::string::npos;
  EXPECT_TRUE(abandoned);
}

// An 8-state chain with a sine in every equation: the closed-form family nests sines 8 deep,
// past the nesting budget, so the family and the injection are series (they took minutes as
// closed forms). The linearized error has the prescribed eigenvalues at the base point and,
// along the series family, up to its truncation (order 6).
TEST(ExtendedLinearization, NestedFunctionsTakeTheSeries) {
  const int n = 8;
  std::string f;
  for (int i = 1; i < n; ++i)
    f += "x" + std::to_string(i + 1) + " - x" + std::to_string(i) + " + sin(x" + std::to_string(i) +
         ")/10, ";
  f += "-x8 + sin(x1)/5";
  const Model m = model_text(("model dense8\nstates x1 x2 x3 x4 x5 x6 x7 x8\ninputs u\nf = [ " + f +
                              " ]\ng = [ 0, 0, 0, 0, 0, 0, 0, u ]\nh = [ x1 ]\n")
                                 .c_str());
  const auto& r = extended_linearization(m, {});
  ASSERT_TRUE(r.failures.empty()) << r.failures[0];
  EXPECT_FALSE(r.family_closed);
  EXPECT_FALSE(r.injection_closed);
  bool noted = false;
  for (const auto& note : r.notes)
    noted = noted || note.find("nests functions") != std::string::npos;
  EXPECT_TRUE(noted);
  const ObserverSpec s = build_design(analyse(m), "extended-linearization", {});
  auto dev = [&](double e) {
    GiNaC::exmap at;
    at[r.eps] = e;
    std::vector<double> x;
    for (const auto& xi : r.x_eps)
      x.push_back(GiNaC::ex_to<GiNaC::numeric>(GiNaC::evalf(xi.subs(at))).to_double());
    const double u = GiNaC::ex_to<GiNaC::numeric>(GiNaC::evalf(r.u_eps.subs(at))).to_double();
    return deviation(error_eigenvalues(m, s, x, u), {-8, -7, -6, -5, -4, -3, -2, -1});
  };
  EXPECT_LT(dev(0), 1e-8);
  EXPECT_LT(dev(0.05), 1e-4);
}

}  // namespace

// Two outputs (seed 001 eq. 35-41). Hand derivations:
// (a) x1' = x2, x2' = -sin x1 - x2/2 + u, x3' = -x3 + x1^2/2, y = (x1, x3): equilibria x2 = 0,
//     u = sin x1, x3 = x1^2/2, so with eps = y1 the family is x = (e, 0, e^2/2), u = sin e.
//     A0 = [[0, 1, 0], [-1, -1/2, 0], [0, 0, -1]]: y1 alone does not see x3 and y2 alone does
//     not see (x1, x2) at the base point, their sum does (det O = 3/2), so w = (1, 1), L0 = 0.
// (b) x1' = -x1 + u, x2' = -x2 + x1^2, y = (x1, x2): A0 = -I is not cyclic, no combination of
//     the outputs observes it alone: a pre-gain L0 is needed; family x = (e, e^2), u = e.
// Oracle: the eigenvalues of the generated rhs's Jacobian at xh = x on the hand family (every
// output at y = h(x)), by Eigen, against the default poles -1, -2, -3 (-1, -2).
const char* kTwoOutputSum = R"(model el2a
states x1 x2 x3
inputs u
f = [ x2, -sin(x1) - x2/2, -x3 + x1^2/2 ]
g = [ 0, u, 0 ]
h = [ x1, x3 ]
domain x1 in [-1, 1], x2 in [-1, 1], x3 in [-1, 1], u in [-2, 2]
)";
const char* kTwoOutputNotCyclic = R"(model el2b
states x1 x2
inputs u
f = [ -x1, -x2 + x1^2 ]
g = [ u, 0 ]
h = [ x1, x2 ]
domain x1 in [-1, 1], x2 in [-1, 1], u in [-2, 2]
)";

TEST(ExtendedLinearization, TwoOutputsPlaceTheEigenvaluesAlongTheHandFamily) {
  {
    const Model m = model_text(kTwoOutputSum);
    const auto r = extended_linearization(m, {});
    ASSERT_TRUE(r.failures.empty()) << r.failures[0];
    EXPECT_EQ(r.level_output, 0u);
    ASSERT_EQ(r.combination.size(), 2u);
    EXPECT_EQ(r.combination[0], 1);
    EXPECT_EQ(r.combination[1], 1);
    const GiNaC::symbol& e = r.eps;
    EXPECT_TRUE(exactly_equal(r.x_eps[0], e));
    EXPECT_TRUE(exactly_equal(r.x_eps[1], 0));
    EXPECT_TRUE(exactly_equal(r.x_eps[2], e * e / 2));
    EXPECT_TRUE(exactly_equal(r.u_eps, GiNaC::sin(e)));
    // c(eps) is rational in eps and cos(eps): no closed-form antiderivative, the series
    // injection of order 6 (eq. 42-45), exact at eps = 0 and O(eps^6) along the family.
    EXPECT_FALSE(r.injection_closed);
    const ObserverSpec s = build_design(analyse(m), "extended-linearization", {});
    auto dev = [&](double v) {
      return deviation(error_eigenvalues(m, s, {v, 0, v * v / 2}, std::sin(v)), {-3, -2, -1});
    };
    EXPECT_LT(dev(0), 1e-12);
    const double d1 = dev(0.2), d2 = dev(0.1), d3 = dev(0.05), d4 = dev(-0.05);
    EXPECT_GT(d2 / d3, 40) << d2 << " " << d3;
    EXPECT_LT(d2 / d3, 100) << d2 << " " << d3;
    EXPECT_GT(d1 / d2, 30) << d1 << " " << d2;
    EXPECT_LT(d3, 1e-6);
    EXPECT_LT(d4, 1e-6);
  }
  {
    const Model m = model_text(kTwoOutputNotCyclic);
    const auto r = extended_linearization(m, {});
    ASSERT_TRUE(r.failures.empty()) << r.failures[0];
    bool nonzero = false;
    for (const auto& row : r.pre_gain)
      for (const auto& x : row) nonzero = nonzero || !x.is_zero();
    EXPECT_TRUE(nonzero) << "A0 = -I needs a pre-gain";
    const ObserverSpec s = build_design(analyse(m), "extended-linearization", {});
    for (double v : {-0.8, -0.3, 0.0, 0.4, 0.9}) {
      const auto ev = error_eigenvalues(m, s, {v, v * v}, v);
      EXPECT_LT(deviation(ev, {-2, -1}), 1e-9) << "eps = " << v;
    }
  }
}

// The two-output observer converges in closed loop near the family, from a 0.15 error.
TEST(ExtendedLinearization, TwoOutputsClosedLoopConverges) {
  SimulationOptions o;
  o.method = "extended-linearization";
  o.u_text = "sin(1/2) + 1/5*sin(t)";
  o.x0 = {0.5, 0, 0.125};
  o.xhat0 = {0.65, -0.15, 0.275};
  o.t_end = 15;
  o.dt = 1e-3;
  const auto r = simulate(analyse(model_text(kTwoOutputSum)), o);
  EXPECT_TRUE(r.diverged.empty()) << r.diverged;
  EXPECT_LT(final_error(r), 1e-5);
}

// Where the outputs do not move with the family, constraint (iii) names the slopes of all.
TEST(ExtendedLinearization, TwoOutputsWithFlatLevelsFailConstraintThree) {
  const Model m = model_text(R"(model el2c
states x1 x2
inputs u
f = [ -x1 + x2, -x2 ]
g = [ 0, u ]
h = [ x1 - x2, x2 - x1 ]
domain x1 in [-1, 1], x2 in [-1, 1], u in [-1, 1]
)");
  const auto r = extended_linearization(m, {});
  ASSERT_FALSE(r.failures.empty());
  // By hand: x_eps = (u, u) for u = eps, so y = (0, 0) along it: dy/deps = (0, 0).
  EXPECT_NE(r.failures[0].find("constraint (iii) fails: dy_eps/deps = -H0 A0^-1 B0 = [0, 0]"),
            std::string::npos)
      << r.failures[0];
}
