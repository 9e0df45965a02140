// Property tests built by construction: canonical forms pulled back through known
// diffeomorphisms must give back T, l and T^-1; unobservable constructions must have rank < n;
// deliberate perturbations must fail exactly the predicted bracket conditions.
#include <gtest/gtest.h>

#include <set>

#include "analysis/analysis.hpp"
#include "support/construct.hpp"
#include "support/expect.hpp"
#include "symbolic/lie.hpp"

using namespace obsynth;
using namespace obsynth::testing;
using GiNaC::ex;

namespace {

struct ChainCase {
  std::size_t n;
  Flavor flavor;
};

std::string case_name(const ::testing::TestParamInfo<ChainCase>& info) {
  return std::string(info.param.flavor == Flavor::polynomial ? "poly" : "trans") + "_n" +
         std::to_string(info.param.n);
}

class Chain : public ::testing::TestWithParam<ChainCase> {};

TEST_P(Chain, RecoversTLAndInverse) {
  const auto [n, flavor] = GetParam();
  const Constructed c = linearizable_chain(n, flavor);
  // The construction itself: dT/dx f = A T + l(0, h) (independent of the pipeline).
  const auto& x = c.model.states;
  GiNaC::exmap y_is_h{{c.y, x[0]}}, u0{{c.model.inputs[0], 0}};
  for (std::size_t i = 0; i < n; ++i)
    ASSERT_TRUE(same(lie_derivative(c.T[i], c.model.f, x),
                     (i ? c.T[i - 1] : ex(0)) + c.l[i].subs(u0).subs(y_is_h)));

  const Analysis a = analyse(c.model);
  EXPECT_EQ(a.observability.generic_rank, n);
  const CanonicalForm& cf = a.canonical;
  ASSERT_TRUE(cf.applicable) << cf.not_applicable;
  for (const auto& b : cf.drift) EXPECT_TRUE(b.holds()) << "[tau_" << b.i << ", tau_" << b.j << "]";
  for (const auto& b : cf.input) EXPECT_TRUE(b.holds()) << "[g, tau_" << b.j << "]";
  ASSERT_TRUE(cf.linearizable);
  // T is unique up to constants; both vanish at the origin.
  ASSERT_EQ(cf.T_kind, Availability::symbolic) << cf.T_note;
  EXPECT_TRUE(same(cf.T, c.T));
  // The frame is dual to dT: check with the constructed T (not the pipeline's).
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      EXPECT_TRUE(same(lie_derivative(c.T[i], cf.frame[j], x), ex(i == j ? 1 : 0)));
  ASSERT_EQ(cf.l_kind, Availability::symbolic) << cf.l_note;
  GiNaC::exmap rename{{c.y, cf.y}};
  ExVec expected_l;
  for (const auto& li : c.l) expected_l.push_back(li.subs(rename));
  EXPECT_TRUE(same(cf.l, expected_l));
  ASSERT_EQ(cf.T_inverse_kind, Availability::symbolic) << cf.T_inverse_note;
  GiNaC::exmap zr;
  for (std::size_t i = 0; i < n; ++i) zr[c.z[i]] = cf.z[i];
  ExVec expected_inv;
  for (const auto& e : c.T_inverse) expected_inv.push_back(e.subs(zr));
  EXPECT_TRUE(same(cf.T_inverse, expected_inv));
}

std::vector<ChainCase> chain_cases() {
  std::vector<ChainCase> v;
  for (std::size_t n = 2; n <= 8; ++n) {
    v.push_back({n, Flavor::polynomial});
    v.push_back({n, Flavor::transcendental});
  }
  return v;
}

INSTANTIATE_TEST_SUITE_P(ByConstruction, Chain, ::testing::ValuesIn(chain_cases()), case_name);

class Unobservable : public ::testing::TestWithParam<std::size_t> {};

TEST_P(Unobservable, RankIsBelowN) {
  const std::size_t n = GetParam();
  // w1 never reaches the output: w1' = -w1 + w2^2, w2' = l2(y) (no w1), w_i' = w_{i-1} + l_i.
  const Perturbation drop_w1 = [n](const std::vector<GiNaC::symbol>& z, const GiNaC::symbol&) {
    ExVec e(n, 0);
    e[0] = -z[0] + z[1] * z[1];
    e[1] = -z[0];  // cancels the A z coupling of w1 into w2
    return e;
  };
  const Constructed c = linearizable_chain(n, Flavor::polynomial, drop_w1);
  const Analysis a = analyse(c.model);
  EXPECT_EQ(a.observability.generic_rank, n - 1);
  EXPECT_FALSE(a.canonical.applicable);
  EXPECT_NE(a.canonical.not_applicable.find("C1 fails"), std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(ByConstruction, Unobservable, ::testing::Values(2, 3, 4, 5, 6));

class InputBracket : public ::testing::TestWithParam<std::pair<std::size_t, std::size_t>> {};

TEST_P(InputBracket, FailsExactlyAtTheCoupledCoordinate) {
  // In z coordinates [g, d/dz_j] = -dg/dz_j: adding u*z_k to g breaks C3 at j = k only.
  const auto [n, k] = GetParam();
  const Perturbation couple = [n, k = k](const std::vector<GiNaC::symbol>& z,
                                         const GiNaC::symbol& u) {
    ExVec e(n, 0);
    e[n - 1] = u * z[k - 1];
    return e;
  };
  const Constructed c = linearizable_chain(n, Flavor::polynomial, {}, couple);
  const Analysis a = analyse(c.model);
  const CanonicalForm& cf = a.canonical;
  ASSERT_TRUE(cf.applicable);
  for (const auto& b : cf.drift) EXPECT_TRUE(b.holds());
  for (const auto& b : cf.input) EXPECT_EQ(b.holds(), b.j != k) << "j = " << b.j;
  EXPECT_FALSE(cf.linearizable);
}

INSTANTIATE_TEST_SUITE_P(ByConstruction, InputBracket,
                         ::testing::Values(std::make_pair(2u, 1u), std::make_pair(3u, 1u),
                                           std::make_pair(3u, 2u), std::make_pair(4u, 3u),
                                           std::make_pair(5u, 2u), std::make_pair(6u, 4u)));

TEST(DriftBracket, QuadraticTermInZ1FailsTheFirstPair) {
  // z coordinates, n = 2: f = [l1 + z1^2, z1 + l2]: tau_1 = e1, tau_2 = [2 z1, 1],
  // [tau_1, tau_2] = [2, 0] != 0; [g, tau_1] = -dg/dz1 = 0 still holds.
  const Perturbation quad = [](const std::vector<GiNaC::symbol>& z, const GiNaC::symbol&) {
    return ExVec{z[0] * z[0], 0};
  };
  const Analysis a = analyse(linearizable_chain(2, Flavor::polynomial, quad).model);
  const CanonicalForm& cf = a.canonical;
  ASSERT_EQ(cf.drift.size(), 1u);
  EXPECT_FALSE(cf.drift[0].holds());
  ASSERT_EQ(cf.input.size(), 1u);
  EXPECT_TRUE(cf.input[0].holds());
  EXPECT_FALSE(cf.linearizable);
}

TEST(DriftBracket, QuadraticTermInZ1ForThreeStates) {
  // n = 3, by hand in z: tau_1 = e1, tau_2 = [2 z1, 1, 0], tau_3 = [2 z1^2 - 2 l1, 2 z1, 1];
  // [tau_1,tau_2] = [2,0,0], [tau_1,tau_3] = [4 z1, 2, 0], [tau_2,tau_3] = [4 z1^2 + 4 l1, 4 z1, 0]
  // all nonzero; [g, tau_1] = 0 holds, [g, tau_2] = [2 g1, 0, 0] fails (g1 = u (1 + y^2)).
  const Perturbation quad = [](const std::vector<GiNaC::symbol>& z, const GiNaC::symbol&) {
    return ExVec{z[0] * z[0], 0, 0};
  };
  const Analysis a = analyse(linearizable_chain(3, Flavor::polynomial, quad).model);
  const CanonicalForm& cf = a.canonical;
  ASSERT_EQ(cf.drift.size(), 3u);
  for (const auto& b : cf.drift) EXPECT_FALSE(b.holds()) << b.i << "," << b.j;
  ASSERT_EQ(cf.input.size(), 2u);
  EXPECT_TRUE(cf.input[0].holds());
  EXPECT_FALSE(cf.input[1].holds());
}

TEST(SeveralOutputs, IndicesAndRankButCanonicalFormDeclines) {
  // Two decoupled double integrators with y = (x1, x3): indices (2, 2), rank 4.
  Model m;
  m.name = "two_outputs";
  for (int i = 1; i <= 4; ++i) m.states.push_back(GiNaC::symbol("x" + std::to_string(i)));
  const auto& x = m.states;
  m.f = {x[1], -sin(x[0]), x[3], -x[2] * x[2] * x[2]};
  m.g = {0, 0, 0, 0};
  m.h = {x[0], x[2]};
  const Analysis a = analyse(m);
  EXPECT_EQ(a.observability.generic_rank, 4u);
  EXPECT_EQ(a.observability.indices, (std::vector<std::size_t>{2, 2}));
  EXPECT_FALSE(a.canonical.applicable);
  EXPECT_NE(a.canonical.not_applicable.find("single-output"), std::string::npos);
}

TEST(RankDrop, ProductOutputDropsOnTheAxes) {
  // y = x1 x2 with x' = (x2, -x1) ... O = [[x2, x1], [d(x2^2 - x1^2)]] -> det = -2 (x1^2 + x2^2)?
  // Derivation: L_f h = x2*x2 + x1*(-x1) = x2^2 - x1^2, d = [-2 x1, 2 x2],
  // det [[x2, x1], [-2 x1, 2 x2]] = 2 x2^2 + 2 x1^2: drops only at the origin.
  Model m;
  m.name = "product_output";
  GiNaC::symbol x1("x1"), x2("x2");
  m.states = {x1, x2};
  m.f = {x2, -x1};
  m.g = {0, 0};
  m.h = {x1 * x2};
  const Analysis a = analyse(m);
  EXPECT_EQ(a.observability.generic_rank, 2u);
  EXPECT_TRUE(same(a.observability.det, 2 * x1 * x1 + 2 * x2 * x2));
  ASSERT_EQ(a.observability.rank_drop.size(), 1u);
  EXPECT_TRUE(same(a.observability.rank_drop[0], x1 * x1 + x2 * x2));
}

}  // namespace
