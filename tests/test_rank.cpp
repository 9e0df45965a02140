// The generic rank without symbolic Lie derivatives (jets_rank.hpp) and the general
// (non-triangular) observability path with FLINT (flint_mpoly.hpp). Expected ranks come from
// an independent derivation: the symbolic path, a construction (a symmetry or a decoupled
// state makes a model unobservable; a diffeomorphism keeps the rank), or a hand computation.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "analysis/jets_rank.hpp"
#include "analysis/observability.hpp"
#include "app/report.hpp"
#include "front/parse.hpp"
#include "support/construct.hpp"

namespace obsynth {
namespace {

using GiNaC::ex;
using GiNaC::numeric;

std::string source(const std::string& rel) {
  return std::string(OBSYNTH_SOURCE_DIR) + "/" + rel;
}

Observability symbolic(const Model& m) {
  Budget budget;
  ObservabilityOptions opt;
  opt.rank_method = RankMethod::symbolic;
  return analyse_observability(m, budget, opt);
}

JetsRank jets(const Model& m, bool ball = false) {
  JetsOptions opt;
  opt.force_ball = ball;
  return jets_rank(m, opt);
}

// Every model of models/: the jets rank equals the symbolic rank, with and without inputs
// held constant (the symbolic O is the drift's), in both arithmetics where both apply.
TEST(JetsRank, EqualsSymbolicRankOnEveryModel) {
  for (const auto& entry : std::filesystem::directory_iterator(source("models"))) {
    if (entry.path().extension() != ".sym") continue;
    const Model m = load_model(entry.path().string());
    const Observability ob = symbolic(m);
    const JetsRank jr = jets(m);
    EXPECT_EQ(jr.rank, ob.generic_rank) << entry.path();
    EXPECT_EQ(jr.indices, ob.indices) << entry.path();
    EXPECT_GE(jr.rank_inputs, jr.rank) << entry.path();
    if (jr.arithmetic == JetsArithmetic::modular) {
      EXPECT_EQ(jets(m, true).rank, jr.rank) << entry.path() << " (balls)";
      EXPECT_EQ(jets(m, true).rank_inputs, jr.rank_inputs) << entry.path() << " (balls)";
    }
  }
}

// Linearizable by construction (T a diffeomorphism, canonical form observable): rank n.
TEST(JetsRank, ConstructedChainsHaveFullRank) {
  for (std::size_t n = 2; n <= 8; ++n)
    for (auto flavor : {testing::Flavor::polynomial, testing::Flavor::transcendental}) {
      const Model m = testing::linearizable_chain(n, flavor).model;
      const JetsRank jr = jets(m);
      EXPECT_EQ(jr.rank, n) << "n = " << n;
      EXPECT_EQ(jr.error_bound, 0.0);  // full rank is proven, in either arithmetic
      EXPECT_EQ(jr.arithmetic, flavor == testing::Flavor::polynomial ? JetsArithmetic::modular
                                                                     : JetsArithmetic::ball);
    }
}

// A chain x1' = x2, x2' = x3, x3' = -x1 read through y = x1 has O = I (by hand); a fourth
// state that nothing reads cannot be observed: rank 3 of 4, the fourth row dependent.
TEST(JetsRank, DecoupledStateGivesRankDeficit) {
  const Model m = parse_model(
      "model dec\nstates x1 x2 x3 x4\ninputs u\nf = [x2, x3, -x1, x4 + x1^2]\n"
      "g = [0, 0, u, u*x4]\nh = [x1]\n",
      "dec.sym");
  for (bool ball : {false, true}) {
    const JetsRank jr = jets(m, ball);
    EXPECT_EQ(jr.rank, 3u);
    EXPECT_EQ(jr.rank_inputs, 3u);
    EXPECT_EQ(jr.selected, (std::vector<std::size_t>{0, 1, 2}));
    if (!ball) {
      EXPECT_GT(jr.error_bound, 0.0);
      EXPECT_LT(jr.error_bound, 1e-20);
    }
  }
}

// An input can raise the rank: x2 enters the output's derivatives only through u*x2.
TEST(JetsRank, RankUnderConstantInputs) {
  const Model m = parse_model(
      "model inp\nstates x1 x2\ninputs u\nf = [0, -x2]\ng = [u*x2, 0]\nh = [x1]\n", "inp.sym");
  const JetsRank jr = jets(m);
  EXPECT_EQ(jr.rank, 1u);         // by hand: O = [[1, 0], [0, 0]] for u = 0
  EXPECT_EQ(jr.rank_inputs, 2u);  // d(u x2) = [0, u]
  EXPECT_EQ(symbolic(m).generic_rank, 1u);
}

// Identifiability-style models (tests/models/gen_identifiability.py): the plain model's
// symbolic rank carries over to the model seen through a diffeomorphism with rational powers
// and nested quotients, and the construction fixes the deficit (scaling symmetry, product of
// two parameters).
TEST(JetsRank, IdentifiabilityModels) {
  struct Case {
    const char* name;
    std::size_t expected_deficit;  // 0 when only the plain model's symbolic rank decides
  };
  for (const Case c : {Case{"ident_lv", 1}, Case{"ident_hiv", 0}, Case{"ident_mm", 1}}) {
    const Model plain = load_model(source(std::string("tests/models/") + c.name + "_plain.sym"));
    const Model seen = load_model(source(std::string("tests/models/") + c.name + ".sym"));
    ASSERT_EQ(plain.n(), seen.n());
    const JetsRank jr = jets(seen);
    EXPECT_EQ(jr.arithmetic, JetsArithmetic::ball) << c.name;  // rational powers
    EXPECT_EQ(jets(plain).rank, jr.rank) << c.name;
    EXPECT_EQ(jets(plain, true).rank, jr.rank) << c.name;
    if (c.expected_deficit) EXPECT_EQ(jr.rank, seen.n() - c.expected_deficit) << c.name;
    if (std::string(c.name) != "ident_mm")  // its plain symbolic chain alone takes minutes
      EXPECT_EQ(symbolic(plain).generic_rank, jr.rank) << c.name;
  }
}

// The command line: --rank-method jets on the identifiability models within 10 s, the report
// says how the rank was decided and what was skipped; two runs are byte-identical.
TEST(JetsRank, CheckWithJetsIsFastAndDeterministic) {
  for (const char* name : {"ident_lv", "ident_hiv", "ident_mm"}) {
    const std::string cmd = std::string(OBSYNTH_BINARY) + " check " +
                            source(std::string("tests/models/") + name + ".sym") +
                            " --rank-method jets --format json --no-timings";
    auto run = [&] {
      std::string out;
      FILE* p = popen(cmd.c_str(), "r");
      char buf[4096];
      while (std::size_t k = std::fread(buf, 1, sizeof buf, p)) out.append(buf, k);
      EXPECT_EQ(pclose(p), 0) << name;
      return out;
    };
    // The observability section (the printed model itself is GiNaC's business).
    auto section = [](const std::string& json) {
      return json.substr(json.find("\"observability\""));
    };
    const auto t0 = std::chrono::steady_clock::now();
    const std::string a = run();
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10.0);
    EXPECT_EQ(section(a), section(run())) << name;
    EXPECT_NE(a.find("\"rank_method\": \"jets\""), std::string::npos) << name;
    EXPECT_NE(a.find("\"arithmetic\": \"ball\""), std::string::npos) << name;
    EXPECT_NE(a.find("\"canonical_note\": \"skipped: the jets rank was requested"),
              std::string::npos)
        << name;
  }
}

// automatic: a symbolic chain over its budget hands over to the jets; symbolic: it stops.
TEST(JetsRank, AutomaticFallbackOnBudget) {
  const Model m = load_model(source("tests/models/ident_lv.sym"));
  AnalysisOptions opt;
  opt.budget.max_expression_size = 200;  // L_f^2 h of the obscured model is larger
  const Analysis a = analyse(m, opt);
  ASSERT_TRUE(a.observability.jets.has_value());
  EXPECT_EQ(a.observability.generic_rank, 5u);
  EXPECT_NE(a.observability.symbolic_skipped.find("exceeded their budget"), std::string::npos);
  EXPECT_FALSE(a.canonical.applicable);
  EXPECT_NE(a.canonical.not_applicable.find("skipped"), std::string::npos);
  for (auto format :
       {ReportFormat::text, ReportFormat::json, ReportFormat::markdown, ReportFormat::latex})
    EXPECT_NE(render_report(a, format, {}).find("jets"), std::string::npos);
  opt.observability.rank_method = RankMethod::symbolic;
  EXPECT_THROW(analyse(m, opt), UserError);
}

// Outside the ring one normal() can outlast any budget checked between calls (ident_mm: 21 s
// for L_f^2 h): the work budget interrupts it (counted allocations throw), whatever the time
// budget, and the jets decide the rank.
TEST(JetsRank, AutomaticFallbackFromAnUninterruptibleChain) {
  const Model m = load_model(source("tests/models/ident_mm.sym"));
  // The path is the same whatever the time budget (no timing here: the suite measures none).
  for (double stage_seconds : {120.0, 600.0}) {
    AnalysisOptions opt;
    opt.budget.stage_seconds = stage_seconds;
    opt.canonical_form = false;  // the rank is the subject
    const Analysis a = analyse(m, opt);
    ASSERT_TRUE(a.observability.jets.has_value());
    EXPECT_EQ(a.observability.generic_rank, m.n() - 1);  // q r: by construction
    EXPECT_NE(a.observability.symbolic_skipped.find("work budget"), std::string::npos)
        << a.observability.symbolic_skipped;
  }
}

// Deterministic: the same seed gives the same points, primes and results.
TEST(JetsRank, Deterministic) {
  const Model m = load_model(source("tests/models/ident_hiv_plain.sym"));
  const JetsRank a = jets(m), b = jets(m);
  EXPECT_EQ(a.primes, b.primes);
  EXPECT_EQ(a.selected, b.selected);
  EXPECT_EQ(a.method, b.method);
}

// mx seen through x = M w, M_ij = min(i, j) (det M = 1, M^-1 tridiagonal): O is dense.
struct DenseView {
  Model mw;
  GiNaC::exmap x_of_w;
};
DenseView dense_view(const Model& mx) {
  const std::size_t n = mx.n();
  DenseView d{mx, {}};
  d.mw.states.clear();
  for (std::size_t i = 0; i < n; ++i) d.mw.states.emplace_back("w" + std::to_string(i + 1));
  for (std::size_t i = 0; i < n; ++i) {
    ex xi = 0;
    for (std::size_t j = 0; j < n; ++j)
      xi += static_cast<long>(std::min(i, j) + 1) * d.mw.states[j];
    d.x_of_w[mx.states[i]] = xi;
  }
  // M^-1: 2 on the diagonal (1 in the last row), -1 beside it.
  auto pull = [&](const ExVec& v) {
    ExVec out(n);
    for (std::size_t i = 0; i < n; ++i) {
      ex s = (i + 1 < n ? 2 : 1) * v[i].subs(d.x_of_w);
      if (i > 0) s -= v[i - 1].subs(d.x_of_w);
      if (i + 1 < n) s -= v[i + 1].subs(d.x_of_w);
      out[i] = s;
    }
    return out;
  };
  d.mw.f = pull(mx.f);
  d.mw.g = pull(mx.g);
  for (auto& h : d.mw.h) h = h.subs(d.x_of_w);
  return d;
}

// x_i' = x_{i+1} (2 + x_i) + x_i^2 x_1, x_n' = -sum x_i^3, y = x1: O is lower triangular with
// diagonal prod_{i<k} (2 + x_i), so the rank drops on 2 + x_i = 0, i < n (by hand).
Model weighted_chain(std::size_t n) {
  std::string f;
  for (std::size_t i = 1; i < n; ++i)
    f += "x" + std::to_string(i + 1) + "*(2 + x" + std::to_string(i) + ") + x" + std::to_string(i) +
         "^2*x1, ";
  std::string cubes, states;
  for (std::size_t i = 1; i <= n; ++i) {
    cubes += (i > 1 ? " + x" : "x") + std::to_string(i) + "^3";
    states += " x" + std::to_string(i);
  }
  return parse_model("model wc\nstates" + states + "\nf = [" + f + "-(" + cubes + ")]\nh = [x1]\n",
                     "wc.sym");
}

// The general path with det and adj(O) e_n by fraction-free elimination in FLINT, r in lowest
// terms and the factors of det O. Independently: det O_w(w) = det O_x(M w) det M with det O_x
// from the triangular path of the x model; O adj(O) e_n = det O e_n and O r = e_n at exact
// random points; the rank-drop factors are those of the x model (by hand for weighted_chain)
// pulled back through M.
TEST(GeneralPath, DenseDeterminantCofactorsAndFactors) {
  for (std::size_t n = 2; n <= 5; ++n)
    for (bool weighted : {false, true}) {
      const Model mx = weighted ? weighted_chain(n)
                                : testing::linearizable_chain(n, testing::Flavor::polynomial).model;
      const auto [mw, x_of_w] = dense_view(mx);
      const Observability ox = symbolic(mx), ow = symbolic(mw);
      const std::string tag = (weighted ? "weighted n = " : "chain n = ") + std::to_string(n);
      ASSERT_TRUE(ox.triangular) << tag;
      ASSERT_FALSE(ow.triangular) << tag;
      ASSERT_EQ(ow.generic_rank, n) << tag;
      ASSERT_EQ(ow.r.size(), n) << tag;
      EXPECT_EQ(jets(mw).rank, n) << tag;
      EXPECT_TRUE(GiNaC::expand(ow.det - ox.det.subs(x_of_w)).is_zero()) << tag;
      for (int k = 1; k <= 3; ++k) {
        GiNaC::exmap pt;
        for (std::size_t i = 0; i < n; ++i) pt[mw.states[i]] = numeric(k * 7 + 3 * i, 11 + 2 * k);
        for (std::size_t r = 0; r < n; ++r) {
          ex acc = 0, acc_r = 0;
          for (std::size_t c = 0; c < n; ++c) {
            const ex o = ow.O[ow.selected[r]][c].subs(pt);
            acc += o * ow.last_row_cofactors[c].subs(pt);
            acc_r += o * ow.r[c].subs(pt);
          }
          EXPECT_EQ(acc, r + 1 == n ? ow.det.subs(pt) : ex(0)) << tag << " row " << r;
          EXPECT_EQ(acc_r, r + 1 == n ? 1 : 0) << tag << " row " << r;
        }
      }
      // Rank-drop set: 2 + x_i (i < n) in w, each once, up to a constant factor.
      const std::size_t expected = weighted ? n - 1 : 0;
      ASSERT_EQ(ow.rank_drop.size(), expected) << tag;
      for (std::size_t i = 1; i <= expected; ++i) {
        const ex form = GiNaC::expand(2 + ex(mx.states[i - 1]).subs(x_of_w));
        bool found = false;
        for (const auto& f : ow.rank_drop) {
          const ex q = GiNaC::normal(f / form);
          found |= GiNaC::is_a<numeric>(q);
        }
        EXPECT_TRUE(found) << tag << ": 2 + x" << i;
      }
    }
}

// ---------------------------------------------------------------------------------------------
// Published models from the STRIKE-GOLDD library (tests/models/strike_goldd/, each file cites
// its source): fractional powers and Hill functions, 4 to 8 states.

struct PublishedModel {
  const char* name;
  std::size_t rank;  // the header's derivation (a scaling symmetry bounds it from above)
};
const PublishedModel kPublished[] = {
    {"big_g_si", 3}, {"big_ins_si", 4}, {"goodwin_b", 4}, {"big_agcs", 6}, {"big_all", 6}};

Model published(const char* name) {
  return load_model(source(std::string("tests/models/strike_goldd/") + name + ".sym"));
}

// O at a point, independently of obsynth's rank code: the Lie derivatives by differentiation
// and products alone (no simplification, no zero test), evaluated to 60 digits at a rational
// point of the domain (its states and free parameters at 1/3 and 5/7 of their boxes, alternately).
std::vector<std::vector<numeric>> observability_matrix_at_point(const Model& m) {
  GiNaC::exmap pt;
  std::vector<GiNaC::symbol> syms(m.states);
  for (const auto& s : m.free_params()) syms.push_back(s);
  for (std::size_t i = 0; i < syms.size(); ++i) {
    const Interval b = m.box(syms[i]);
    pt[syms[i]] = b.lo + (b.hi - b.lo) * (i % 2 ? numeric(5, 7) : numeric(1, 3));
  }
  GiNaC::Digits = 60;
  std::vector<std::vector<numeric>> O;
  ex phi = m.h[0];
  for (std::size_t k = 0; k < m.n(); ++k) {
    std::vector<numeric> row;
    ex next = 0;
    for (std::size_t j = 0; j < m.n(); ++j) {
      const ex d = phi.diff(m.states[j]);
      row.push_back(GiNaC::ex_to<numeric>(GiNaC::evalf(d.subs(pt))));
      next += d * m.f[j];
    }
    O.push_back(std::move(row));
    phi = next;
  }
  return O;
}

// Rank by elimination with complete pivoting, rows scaled to unit max-norm first; a pivot
// counts above 1e-40 (the entries carry 60 digits; a rank-deficient O leaves pivots at the
// rounding level, about 1e-55 here).
std::size_t rank_by_elimination(std::vector<std::vector<numeric>> a) {
  for (auto& r : a) {
    numeric mx = 0;
    for (const auto& v : r) mx = std::max(mx, GiNaC::abs(v));
    if (!mx.is_zero())
      for (auto& v : r) v /= mx;
  }
  const std::size_t n = a.size(), cols = a[0].size();
  std::size_t rank = 0;
  for (; rank < n; ++rank) {
    std::size_t pr = rank, pc = 0;
    numeric best = -1;
    for (std::size_t r = rank; r < n; ++r)
      for (std::size_t c = 0; c < cols; ++c)
        if (GiNaC::abs(a[r][c]) > best) best = GiNaC::abs(a[r][c]), pr = r, pc = c;
    if (best < numeric(1, 10).power(40)) break;
    std::swap(a[pr], a[rank]);
    for (std::size_t r = rank + 1; r < n; ++r) {
      const numeric factor = a[r][pc] / a[rank][pc];
      for (std::size_t c = 0; c < cols; ++c) a[r][c] -= factor * a[rank][c];
    }
  }
  return rank;
}

// The expected ranks hold independently (the symmetry in each header bounds the rank above;
// a nonzero minor at a point bounds it below), and obsynth's automatic rank method finds them,
// as `check` would (the default budgets).
TEST(StrikeGoldd, ExpectedRanks) {
  for (const auto& c : kPublished) {
    const Model m = published(c.name);
    EXPECT_EQ(rank_by_elimination(observability_matrix_at_point(m)), c.rank) << c.name;
    Budget budget;
    const auto t0 = std::chrono::steady_clock::now();
    const Observability ob = analyse_observability(m, budget, ObservabilityOptions{});
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(ob.generic_rank, c.rank) << c.name;
    // Time is reported, not asserted (a timed test fails on a loaded machine): the path is a
    // pure function of the model (next test), and the README gives the measured times.
    std::printf("%s: rank %zu in %.2f s (%s)\n", c.name, ob.generic_rank, seconds,
                ob.jets ? "jets" : "symbolic");
  }
}

// The automatic rank method takes the same path for a model whatever the time budget (the
// machine's load only stretches time): symbolic or jets, and the same rank. On the wall-clock
// share this replaced, big_g_si went to the jets with a 3 s stage budget (its chain needed
// more than 0.75 s) and stayed symbolic with 30 s; big_ins_si went to the jets with 3 s and
// stalled in the observability stage, without a rank, with 30 s.
TEST(StrikeGoldd, PathIsAPureFunctionOfTheModel) {
  for (const char* name : {"big_g_si", "big_ins_si"}) {
    const Model m = published(name);
    auto run = [&](double stage_seconds) {
      BudgetLimits limits;
      limits.stage_seconds = stage_seconds;
      Budget budget(limits);
      return analyse_observability(m, budget, ObservabilityOptions{});
    };
    const Observability tight = run(3), loose = run(30);
    EXPECT_EQ(tight.jets.has_value(), loose.jets.has_value()) << name;
    EXPECT_EQ(tight.symbolic_skipped, loose.symbolic_skipped) << name;
    EXPECT_EQ(tight.generic_rank, loose.generic_rank) << name;
  }
}

// The work budget counts allocations on its own thread, throws past its limit (once, then
// every 16 allocations, so a swallowed exception cannot let the work run on), and nests.
TEST(WorkBudget, CountsThrowsAndNests) {
  // Allocations past the limit: each one throws (gtest's own allocations stay outside).
  std::vector<std::unique_ptr<int>> kept;  // escapes, so no allocation is elided
  kept.reserve(40);
  auto allocations_that_throw = [&](int tries) {
    int thrown = 0;
    for (int i = 0; i < tries; ++i) try {
        kept.push_back(std::make_unique<int>(i));
      } catch (const WorkBudgetExceeded&) {
        ++thrown;
      }
    return thrown;
  };
  std::uint64_t outer_used = 0;
  int thrown = 0;
  {
    WorkScope outer(1000);
    {
      WorkScope inner(10);
      thrown = allocations_that_throw(20);
    }
    outer_used = outer.used();
  }
  EXPECT_EQ(thrown, 1);
  EXPECT_EQ(outer_used, 20u);                // the inner scope's work is the outer's too
  EXPECT_EQ(allocations_that_throw(20), 0);  // no scope open: nothing counts
}

}  // namespace
}  // namespace obsynth
