// profile_check: breaks the `obsynth check` pipeline into its GiNaC sub-steps and times each
// one, to find where a slow stage spends its time. It re-runs the steps of analyse()
// (synth/observability.cpp, synth/canonical.cpp) through the public synth API, in the same
// order and with the same simplifications, and prints one line per sub-step:
//
//   stage  step  cpu-ms  calls  largest-expression(nodes)  terms
//
// Times are process CPU time (not wall time), so they stay meaningful on a loaded machine.
//
// With --alternatives it also times candidate replacements for the dominant steps (expand()
// instead of normal() on polynomial-in-atoms expressions, differentiation with the
// transcendental atoms replaced by symbols, triangular solve for r), checking that each
// alternative gives the same result.
//
//   profile_check FAMILY N [--alternatives] [--upto STAGE] [--skip-det] [--max-brackets K]
//   [--reverse] profile_check --file model.sym [...]
#include <fmt/format.h>

#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "canonical.hpp"
#include "families.hpp"
#include "lie.hpp"
#include "observability.hpp"
#include "parse.hpp"
#include "symbolic.hpp"
#include "zero_test.hpp"

namespace {

using namespace obsynth;
using GiNaC::ex;
using GiNaC::numeric;

struct Row {
  std::string stage, step;
  double ms = 0;
  std::size_t calls = 0, max_size = 0, max_terms = 0;
};

double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

class Profile {
 public:
  // Times fn(), attributing it to (stage, step).
  template <class F>
  auto time(const std::string& stage, const std::string& step, F&& fn) {
    const double t0 = cpu_ms();
    if constexpr (std::is_void_v<decltype(fn())>) {
      fn();
      add(stage, step, t0);
    } else {
      auto r = fn();
      add(stage, step, t0);
      return r;
    }
  }
  void note_size(const std::string& stage, const std::string& step, const ex& e) {
    Row& r = row(stage, step);
    r.max_size = std::max(r.max_size, expression_size(e));
    r.max_terms = std::max(r.max_terms, GiNaC::is_a<GiNaC::add>(e) ? e.nops() : std::size_t(1));
  }
  void print() const {
    std::printf("%-15s %-44s %10s %7s %10s %7s\n", "stage", "step", "cpu ms", "calls", "max nodes",
                "terms");
    for (const auto& r : rows_)
      std::printf("%-15s %-44s %10.1f %7zu %10zu %7zu\n", r.stage.c_str(), r.step.c_str(), r.ms,
                  r.calls, r.max_size, r.max_terms);
  }

 private:
  std::vector<Row> rows_;
  Row& row(const std::string& stage, const std::string& step) {
    for (auto& r : rows_)
      if (r.stage == stage && r.step == step) return r;
    rows_.push_back({stage, step});
    return rows_.back();
  }
  void add(const std::string& stage, const std::string& step, double t0) {
    Row& r = row(stage, step);
    const double dt = cpu_ms() - t0;
    r.ms += dt;
    ++r.calls;
    if (dt > 1000)
      std::fprintf(stderr, "  [%s] %s: %.0f cpu ms\n", stage.c_str(), step.c_str(), dt);
  }
};

// ---- alternatives ------------------------------------------------------------------------

// Transcendental atoms (function calls) of e whose argument depends on x.
void collect_atoms(const ex& e, const Symbols& x, std::vector<ex>& atoms) {
  if (GiNaC::is_a<GiNaC::function>(e) && depends_on(e, x)) {
    for (const auto& a : atoms)
      if (a.is_equal(e)) return;
    atoms.push_back(e);
  }
  for (std::size_t i = 0; i < e.nops(); ++i) collect_atoms(e.op(i), x, atoms);
}

// Differentiation with function atoms frozen as symbols: d/dx = d/dx|_atoms + sum_a
// (d/da) (da/dx). Avoids GiNaC's function::derivative, which throws and catches an
// exception (expl_derivative) for every sin/cos it meets.
struct AtomDiff {
  Symbols x;
  std::vector<ex> atoms;               // sin(x1), cos(x1), ...
  std::vector<GiNaC::symbol> syms;     // their stand-ins
  std::vector<std::vector<ex>> datom;  // datom[a][j] = d atom_a / d x_j, in stand-ins
  GiNaC::exmap to_sym, to_atom;

  AtomDiff(const Symbols& xs, const std::vector<ex>& exprs) : x(xs) {
    for (const auto& e : exprs) collect_atoms(e, x, atoms);
    // Close under differentiation (sin -> cos -> sin): a few rounds suffice here.
    for (std::size_t k = 0; k < atoms.size(); ++k)
      for (const auto& s : x) collect_atoms(atoms[k].diff(s), x, atoms);
    for (std::size_t a = 0; a < atoms.size(); ++a) {
      syms.emplace_back(fmt::format("atom{}", a));
      to_sym[atoms[a]] = syms[a];
      to_atom[syms[a]] = atoms[a];
    }
    for (std::size_t a = 0; a < atoms.size(); ++a) {
      std::vector<ex> row;
      for (const auto& s : x) row.push_back(freeze(atoms[a].diff(s)));
      datom.push_back(row);
    }
  }
  ex freeze(const ex& e) const { return e.subs(to_sym, GiNaC::subs_options::no_pattern); }
  ex thaw(const ex& e) const { return e.subs(to_atom, GiNaC::subs_options::no_pattern); }
  // e in stand-ins.
  ex diff(const ex& e, std::size_t j) const {
    ex d = e.diff(x[j]);
    for (std::size_t a = 0; a < syms.size(); ++a)
      if (!datom[a][j].is_zero() && e.has(syms[a])) d += e.diff(syms[a]) * datom[a][j];
    return d;
  }
};

bool same(const ex& a, const ex& b) {
  return GiNaC::normal(a - b).is_zero();
}

// ---- the pipeline ------------------------------------------------------------------------

struct Options {
  bool alternatives = false;
  bool skip_det = false;
  std::size_t max_brackets = 1000000;  // symbolic drift brackets to profile
  bool reverse = false;                // profile the brackets from [tau_{n-1}, tau_n] down
  std::string upto = "diffeomorphism";
};

int run(const Model& m, const Options& opt) {
  Profile P;
  const Symbols& x = m.states;
  const std::size_t n = m.n();
  const ex h = m.h.at(0);
  // lie
  ExVec lie;
  lie.push_back(h);
  for (std::size_t k = 1; k < n; ++k) {
    const ex& phi = lie.back();
    ex acc = P.time("lie", "diff + multiply (L_f phi)", [&] {
      ex a = 0;
      for (std::size_t j = 0; j < n; ++j) {
        if (m.f[j].is_zero()) continue;
        const ex d = phi.diff(x[j]);
        if (!d.is_zero()) a += d * m.f[j];
      }
      return a;
    });
    ex s = P.time("lie", "normal(L_f phi)", [&] { return simplify(acc); });
    P.note_size("lie", "normal(L_f phi)", s);
    lie.push_back(s);
  }
  if (opt.alternatives) {
    ExVec alt{h};
    P.time("lie*", "alt: diff + expand (no normal)", [&] {
      for (std::size_t k = 1; k < n; ++k) {
        ex a = 0;
        for (std::size_t j = 0; j < n; ++j) a += alt.back().diff(x[j]) * m.f[j];
        alt.push_back(GiNaC::expand(a));
      }
    });
    bool ok = true;
    for (std::size_t k = 0; k < n; ++k) ok &= same(alt[k], lie[k]);
    std::printf("alt lie chain (expand) agrees with normal(): %s\n", ok ? "yes" : "NO");
    AtomDiff ad(x, m.f);
    ExVec fz;
    for (const auto& e : m.f) fz.push_back(ad.freeze(e));
    ExVec alt2{ad.freeze(h)};
    P.time("lie*", "alt: atoms as symbols, diff + expand", [&] {
      for (std::size_t k = 1; k < n; ++k) {
        ex a = 0;
        for (std::size_t j = 0; j < n; ++j) a += ad.diff(alt2.back(), j) * fz[j];
        alt2.push_back(GiNaC::expand(a));
      }
    });
    ok = true;
    for (std::size_t k = 0; k < n; ++k) ok &= same(ad.thaw(alt2[k]), lie[k]);
    std::printf("alt lie chain (atoms as symbols) agrees: %s (%zu atoms)\n", ok ? "yes" : "NO",
                ad.atoms.size());
  }
  if (opt.alternatives) {
    // Lie chain and O rows together: the gradient of L_f^k h is row k of O and also what
    // L_f^{k+1} h = sum_j row_k[j] f_j needs, so compute it once; differentiate only by the
    // states the expression contains; atoms (sin x1, ...) frozen as symbols; one add() built
    // from a vector and expanded once instead of acc += ... followed by normal().
    AtomDiff ad(x, m.f);
    ExVec fz;
    for (const auto& e : m.f) fz.push_back(ad.freeze(e));
    ExVec L{ad.freeze(h)};
    ExMatrix rows;
    P.time("lie+obs*", "alt: fused lie chain + O rows (expand)", [&] {
      for (std::size_t k = 0; k < n; ++k) {
        ExVec row(n, 0);
        for (std::size_t j = 0; j < n; ++j) {
          bool needed = L[k].has(x[j]);
          for (std::size_t a = 0; a < ad.syms.size() && !needed; ++a)
            needed = !ad.datom[a][j].is_zero() && L[k].has(ad.syms[a]);
          if (!needed) continue;
          row[j] = GiNaC::expand(ad.diff(L[k], j));
        }
        rows.push_back(row);
        if (k + 1 < n) {
          GiNaC::exvector terms;
          for (std::size_t j = 0; j < n; ++j)
            if (!row[j].is_zero() && !fz[j].is_zero()) terms.push_back(row[j] * fz[j]);
          L.push_back(GiNaC::expand(GiNaC::add(terms)));
        }
      }
    });
    bool ok = true;
    for (std::size_t k = 0; k < n; ++k) ok &= same(ad.thaw(L[k]), lie[k]);
    std::printf("alt fused lie chain agrees: %s\n", ok ? "yes" : "NO");
    // Evaluate O at a point with atoms frozen: atoms evaluated once, then a numeric subs.
    const SampleBoxes b0 = SampleBoxes::from_model(m);
    const auto pts = sample_points(x, b0, 1, 0x0b5e7);
    P.time("lie+obs*", "alt: O at one point, atoms evaluated once (60 digits)", [&] {
      DigitsGuard digits(60);
      GiNaC::exmap pt = pts[0];
      for (std::size_t a = 0; a < ad.syms.size(); ++a) {
        numeric v;
        evaluate_real(ad.atoms[a], pts[0], 60, v);
        pt[ad.syms[a]] = v;
      }
      for (const auto& r : rows)
        for (const auto& e : r) (void)e.subs(pt);
    });
  }
  if (opt.upto == "lie") return P.print(), 0;

  // observability: O rows
  ExMatrix O;
  for (std::size_t k = 0; k < n; ++k) {
    ExVec row = P.time("observability", "gradient (diff)", [&] { return gradient(lie[k], x); });
    for (auto& e : row) {
      e = P.time("observability", "normal(O entries)", [&] { return simplify(e); });
      P.note_size("observability", "normal(O entries)", e);
    }
    O.push_back(row);
  }
  bool exact = true;
  P.time("observability", "has_transcendental", [&] {
    for (const auto& r : O)
      for (const auto& e : r) exact &= !has_transcendental(e);
  });
  const SampleBoxes boxes = SampleBoxes::from_model(m);
  const auto points = sample_points(x, boxes, 3, 0x0b5e7);
  std::size_t rank = 0;
  for (const auto& pt : points) {
    std::vector<std::vector<numeric>> a;
    P.time("observability",
           exact ? "evaluate O at point (exact subs)" : "evaluate O at point (evalf, 60 digits)",
           [&] {
             for (const auto& r : O) {
               std::vector<numeric> row;
               for (const auto& e : r) {
                 numeric v;
                 if (exact)
                   v = GiNaC::ex_to<numeric>(e.subs(pt));
                 else
                   evaluate_real(e, pt, 60, v);
                 row.push_back(v);
               }
               a.push_back(row);
             }
           });
    rank = std::max(
        rank, P.time("observability", "numeric_rank", [&] { return numeric_rank(a, exact); }));
  }
  P.time("observability", "denominators: normal+factor per entry", [&] {
    for (const auto& r : O)
      for (const auto& e : r) (void)dependent_factors(GiNaC::denom(GiNaC::normal(e)), x);
  });
  std::printf("generic rank %zu of %zu (%s)\n", rank, n, exact ? "exact" : "floating");
  if (rank < n || opt.upto == "observability" || opt.skip_det) return P.print(), 0;
  // cofactors of the last row (selected rows = 0..n-1 when rank is full and p = 1)
  ExVec cof(n);
  ex det = 0;
  for (std::size_t c = 0; c < n; ++c) {
    GiNaC::matrix minor(n - 1, n - 1);
    std::size_t zero_cols = 0;
    for (std::size_t r = 0; r + 1 < n; ++r)
      for (std::size_t cc = 0, k = 0; cc < n; ++cc) {
        if (cc == c) continue;
        minor(r, k++) = O[r][cc];
      }
    for (std::size_t k = 0; k + 1 < n; ++k) {
      bool z = true;
      for (std::size_t r = 0; r + 1 < n; ++r) z &= minor(r, k).is_zero();
      zero_cols += z;
    }
    const ex md = P.time("observability",
                         zero_cols ? "determinant(minor with a zero column)" : "determinant(minor)",
                         [&] { return n == 1 ? ex(1) : minor.determinant(); });
    const ex cf = ((n - 1 + c) % 2 == 0 ? 1 : -1) * md;
    cof[c] = P.time("observability", "normal(cofactor)", [&] { return simplify(cf); });
    P.note_size("observability", "normal(cofactor)", cof[c]);
    det += O[n - 1][c] * cf;
  }
  det = P.time("observability", "normal(det)", [&] { return simplify(det); });
  P.note_size("observability", "normal(det)", det);
  P.time("observability", "dependent_factors(det) (normal+factor)",
         [&] { (void)dependent_factors(det, x); });
  if (opt.alternatives) {
    // Lower-triangular O (row k free of x_{k+2}..x_n): det = product of the diagonal and
    // r = e_n / O[n-1][n-1] -- no determinant at all.
    bool lower = true;
    for (std::size_t r = 0; r < n; ++r)
      for (std::size_t c = r + 1; c < n; ++c) lower &= O[r][c].is_zero();
    if (lower) {
      ex d2 = P.time("observability*", "alt: triangular det = prod(diag)", [&] {
        ex d = 1;
        for (std::size_t k = 0; k < n; ++k) d *= O[k][k];
        return simplify(d);
      });
      std::printf("alt triangular det agrees: %s\n", same(d2, det) ? "yes" : "NO");
    } else {
      std::printf("O is not lower triangular\n");
    }
  }
  if (opt.upto == "observability") return P.print(), 0;

  // frame
  ExVec r;
  for (std::size_t i = 0; i < n; ++i)
    r.push_back(P.time("frame", "normal(cofactor / det)", [&] { return simplify(cof[i] / det); }));
  ExVec minus_f;
  for (const auto& e : m.f) minus_f.push_back(-e);
  const ExMatrix Jmf = jacobian(minus_f, x);
  std::vector<ExVec> frame{r};
  for (std::size_t k = 1; k < n; ++k) {
    const ExMatrix Jt =
        P.time("frame", "jacobian(tau_k) (diff)", [&] { return jacobian(frame.back(), x); });
    frame.push_back(P.time("frame", "lie_bracket (mul + normal)",
                           [&] { return lie_bracket(minus_f, Jmf, frame.back(), Jt); }));
    for (const auto& e : frame.back()) P.note_size("frame", "lie_bracket (mul + normal)", e);
  }
  if (opt.upto == "frame") return P.print(), 0;

  // conditions
  std::vector<ExMatrix> J;
  for (const auto& t : frame)
    J.push_back(P.time("conditions", "jacobian(tau_k) (diff)", [&] { return jacobian(t, x); }));
  std::size_t failing = 0, total = 0;
  ZeroTestOptions zopt;
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
  if (opt.reverse) std::reverse(pairs.begin(), pairs.end());
  for (const auto& [i, j] : pairs) {
    {
      if (total >= opt.max_brackets) break;
      const ExVec b = P.time("conditions", "[tau_i,tau_j] (mul + normal)", [&, i = i, j = j] {
        return lie_bracket(frame[i], J[i], frame[j], J[j]);
      });
      for (const auto& e : b) P.note_size("conditions", "[tau_i,tau_j] (mul + normal)", e);
      ZeroVerdict v = ZeroVerdict::proved;
      P.time("conditions", "zero_test(bracket components)", [&] {
        for (const auto& e : b) {
          const ZeroVerdict w = zero_test(e, boxes, zopt);
          if (static_cast<int>(w) > static_cast<int>(v)) v = w;
          if (v == ZeroVerdict::nonzero) break;
        }
      });
      ++total;
      failing += v == ZeroVerdict::nonzero;
    }
  }
  if (opt.alternatives && n >= 2) {
    // Decide C2 numerically first: evaluate the unsimplified bracket at one point.
    const auto pts = sample_points(x, boxes, 1, 0x5eed0b5);
    std::size_t failing_fast = 0;
    // Evaluate every tau_k and its Jacobian once at the point (exact rationals when the model
    // is rational, else 40 digits), then form all brackets in numbers:
    // [tau_i, tau_j](p) = J_j(p) tau_i(p) - J_i(p) tau_j(p).
    P.time("conditions*", "alt: all [tau_i,tau_j] from tau(p), J(p) numbers", [&] {
      std::vector<std::vector<numeric>> tv(n, std::vector<numeric>(n));
      std::vector<std::vector<std::vector<numeric>>> Jv(
          n, std::vector<std::vector<numeric>>(n, std::vector<numeric>(n)));
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t c = 0; c < n; ++c) {
          evaluate_real(frame[i][c], pts[0], 40, tv[i][c]);
          for (std::size_t k = 0; k < n; ++k) evaluate_real(J[i][c][k], pts[0], 40, Jv[i][c][k]);
        }
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = i + 1; j < n; ++j) {
          bool nz = false;
          for (std::size_t c = 0; c < n && !nz; ++c) {
            numeric acc = 0, scale = 1;
            for (std::size_t k = 0; k < n; ++k) {
              const numeric a = Jv[j][c][k] * tv[i][k], b = Jv[i][c][k] * tv[j][k];
              acc += a - b;
              scale = std::max(scale, std::max(GiNaC::abs(a), GiNaC::abs(b)));
            }
            if (GiNaC::abs(acc) > scale * numeric(1, 1000000000)) nz = true;
          }
          failing_fast += nz;
        }
    });
    std::printf(
        "alt numeric bracket screen: %zu failing of %zu (symbolic, of the first %zu: %zu)\n",
        failing_fast, n * (n - 1) / 2, total, failing);
  }
  const ExMatrix Jg = jacobian(m.g, x);
  for (std::size_t j = 0; j + 1 < n; ++j) {
    const ExVec b = P.time("conditions", "[g,tau_j] (mul + normal)",
                           [&] { return lie_bracket(m.g, Jg, frame[j], J[j]); });
    P.time("conditions", "zero_test(bracket components)", [&] {
      for (const auto& e : b)
        if (zero_test(e, boxes, zopt) == ZeroVerdict::nonzero) break;
    });
  }
  P.time("conditions", "classify_completeness", [&] {
    for (const auto& t : frame) {
      std::string why;
      (void)classify_completeness(t, x, why);
    }
  });
  std::printf("C2: %zu of %zu drift brackets fail\n", failing, total);
  P.print();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  std::string file, family;
  int n = 0;
  std::vector<std::string> pos;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--alternatives")
      opt.alternatives = true;
    else if (a == "--skip-det")
      opt.skip_det = true;
    else if (a == "--upto" && i + 1 < argc)
      opt.upto = argv[++i];
    else if (a == "--reverse")
      opt.reverse = true;
    else if (a == "--max-brackets" && i + 1 < argc)
      opt.max_brackets = std::strtoul(argv[++i], nullptr, 10);
    else if (a == "--file" && i + 1 < argc)
      file = argv[++i];
    else
      pos.push_back(a);
  }
  try {
    Model m;
    if (!file.empty()) {
      m = load_model(file);
    } else {
      if (pos.size() != 2 || !obsynth::bench::parse_family(pos[0])) {
        std::fprintf(stderr,
                     "usage: profile_check FAMILY N [--alternatives] [--upto STAGE] [--skip-det]\n"
                     "       profile_check --file model.sym [...]\n");
        return 1;
      }
      n = std::atoi(pos[1].c_str());
      const auto f = *obsynth::bench::parse_family(pos[0]);
      m = parse_model(obsynth::bench::family_model(f, n), obsynth::bench::model_file_name(f, n));
    }
    return run(m, opt);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "profile_check: %s\n", e.what());
    return 1;
  }
}
