#include "designs/riccati.hpp"

#include <fmt/format.h>

#include <set>

#include "certify/riccati_certificate.hpp"
#include "designs/design_helpers.hpp"
#include "designs/options.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

GiNaC::matrix identity(std::size_t d) {
  GiNaC::matrix I(static_cast<unsigned>(d), static_cast<unsigned>(d));
  for (unsigned i = 0; i < d; ++i) I(i, i) = 1;
  return I;
}

// n values: diagonal; n*n values: row-major; one value: c I; none: I.
GiNaC::matrix matrix_option(const DesignOptions& o, const std::string& name, std::size_t d,
                            const std::string& what, bool& given) {
  const std::vector<numeric> v = real_list_option(o, name);
  given = !v.empty();
  if (v.empty()) return identity(d);
  GiNaC::matrix M(static_cast<unsigned>(d), static_cast<unsigned>(d));
  if (v.size() == d * d && d > 1) {
    for (unsigned r = 0; r < d; ++r)
      for (unsigned c = 0; c < d; ++c) M(r, c) = v[r * d + c];
  } else if (v.size() == d) {
    for (unsigned i = 0; i < d; ++i) M(i, i) = v[i];
  } else if (v.size() == 1) {
    for (unsigned i = 0; i < d; ++i) M(i, i) = v[0];
  } else {
    throw UserError(SourceLoc{},
                    fmt::format("--{}: {} values given; {} is {} x {}: give 1 value (a multiple "
                                "of I), {} (the diagonal) or {} (row-major)",
                                name, v.size(), what, d, d, d, d * d));
  }
  return M;
}

// Lambda of the detectability test (3.3), n x p: n*p values (row-major); none: 0.
GiNaC::matrix lambda_option(const DesignOptions& o, std::size_t n, std::size_t p) {
  const std::vector<numeric> v = real_list_option(o, "Lambda");
  GiNaC::matrix L(static_cast<unsigned>(n), static_cast<unsigned>(p));
  if (v.empty()) return L;
  if (v.size() != n * p)
    throw UserError(SourceLoc{},
                    fmt::format("--Lambda: {} values given; Lambda is n x p = {} x {}: "
                                "give {} values (row-major)",
                                v.size(), n, p, n * p));
  for (unsigned r = 0; r < n; ++r)
    for (unsigned c = 0; c < p; ++c) L(r, c) = v[r * p + c];
  return L;
}

void require_symmetric_pd(const GiNaC::matrix& M, const std::string& name) {
  for (unsigned r = 0; r < M.rows(); ++r)
    for (unsigned c = r + 1; c < M.cols(); ++c)
      if (!(M(r, c) - M(c, r)).is_zero())
        throw UserError(
            SourceLoc{},
            fmt::format("--{}: not symmetric (entry ({}, {}) = {} but ({}, {}) = {})", name, r + 1,
                        c + 1, to_string(M(r, c)), c + 1, r + 1, to_string(M(c, r))));
  if (!exact_positive_definite(M))
    throw UserError(
        SourceLoc{},
        fmt::format("--{}: not positive definite (a leading principal minor is <= 0)", name));
}

std::vector<numeric> row_major(const GiNaC::matrix& M) {
  std::vector<numeric> v;
  for (unsigned r = 0; r < M.rows(); ++r)
    for (unsigned c = 0; c < M.cols(); ++c) v.push_back(GiNaC::ex_to<numeric>(M(r, c)));
  return v;
}

// Symbol names unique against the model's names and each other (functions bind arguments
// and let-definitions by name).
class Names {
 public:
  explicit Names(const Model& m) {
    for (const auto& s : m.all_symbols()) used_.insert(s.get_name());
    for (const auto& p : m.params) used_.insert(p.name);
  }
  GiNaC::symbol make(const std::string& stem) {
    std::string name = stem;
    while (used_.count(name)) name += "_";
    used_.insert(name);
    return GiNaC::symbol(name);
  }

 private:
  std::set<std::string> used_;
};

Verdict applies(const Analysis& a) {
  Verdict v;
  const std::size_t n = a.model.n(), r = a.observability.generic_rank;
  if (!a.completed("observability")) {
    v.reasons.push_back("the observability stage did not complete");
    return v;
  }
  if (r < n) {
    v.reasons.push_back(fmt::format(
        "the observability rank (at u = 0) is {} < n = {}: the Riccati observer needs the pair "
        "(H, A) uniformly detectable (seed 000 (3.3)); --method riccati still builds it",
        r, n));
    return v;
  }
  v.applies = true;
  v.reasons.push_back(
      "it needs only the Jacobians of f + g and h (no canonical form); convergence for "
      "an initial error below rho (Theorem 2.1) or globally when delta > 0 (Corollary 2.1) under "
      "uniform "
      "detectability");
  return v;
}

using ExMatrix = std::vector<std::vector<ex>>;

// The observer's symbols. Their creation order fixes GiNaC's term order in the output, so
// it must not change: Q's entries first, then the outputs.
struct RiccatiSymbols {
  // w = (m, Q packed): m uses the model's own state symbols, so f, g, h and their Jacobians
  // apply unchanged; then Q's upper triangle row by row.
  std::vector<GiNaC::symbol> w;
  ExMatrix Q;  // n x n, symmetric, entries from w
  std::vector<GiNaC::symbol> y;
};

RiccatiSymbols riccati_symbols(const Model& m, Names& names) {
  const std::size_t n = m.n(), p = m.p();
  RiccatiSymbols sym;
  sym.w.assign(m.states.begin(), m.states.end());
  sym.Q.assign(n, std::vector<ex>(n));
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r; c < n; ++c) {
      const GiNaC::symbol q = names.make(fmt::format("Q_{}_{}", r + 1, c + 1));
      sym.w.push_back(q);
      sym.Q[r][c] = sym.Q[c][r] = q;
    }
  for (std::size_t k = 0; k < p; ++k)
    sym.y.push_back(names.make(p == 1 ? std::string("y") : fmt::format("y{}", k + 1)));
  return sym;
}

// A let of f named after stem holding value, so that the emitted code computes it once; a
// symbol or number needs none and is returned as is.
ex bind_let(GeneratedFunction& f, Names& names, const std::string& stem, const ex& value) {
  if (GiNaC::is_a<GiNaC::symbol>(value) || GiNaC::is_a<numeric>(value)) return value;
  const GiNaC::symbol s = names.make(stem);
  f.lets.push_back({s, value});
  return s;
}

// The innovation e = y - h(m), one let per output.
std::vector<ex> bind_innovation(GeneratedFunction& f, Names& names, const Model& m,
                                const std::vector<GiNaC::symbol>& y) {
  std::vector<ex> e(m.p());
  for (std::size_t k = 0; k < m.p(); ++k) {
    const GiNaC::symbol s = names.make(fmt::format("innovation_{}", k + 1));
    f.lets.push_back({s, y[k] - m.h[k]});
    e[k] = s;
  }
  return e;
}

// G = Q Dh^T (n x p) and the gain Gw = G W, W = R^-2; both appear in m' and in Q'.
struct RiccatiGain {
  ExMatrix G, Gw;
};

RiccatiGain bind_gain(GeneratedFunction& f, Names& names, const Model& m, const ExMatrix& Q,
                      const GiNaC::matrix& W) {
  const std::size_t n = m.n(), p = m.p();
  RiccatiGain g{ExMatrix(n, std::vector<ex>(p)), ExMatrix(n, std::vector<ex>(p))};
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < p; ++k) {
      ex acc = 0;
      for (std::size_t j = 0; j < n; ++j) acc += Q[i][j] * m.h[k].diff(m.states[j]);
      g.G[i][k] = bind_let(f, names, fmt::format("G_{}_{}", i + 1, k + 1), acc);
    }
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < p; ++k) {
      ex acc = 0;
      for (std::size_t l = 0; l < p; ++l)
        acc += g.G[i][l] * W(static_cast<unsigned>(l), static_cast<unsigned>(k));
      g.Gw[i][k] = bind_let(f, names, fmt::format("GW_{}_{}", i + 1, k + 1), acc);
    }
  return g;
}

// A = D_x(f + g), n x n.
ExMatrix field_jacobian(const Model& m, const ExVec& F) {
  const std::size_t n = m.n();
  ExMatrix A(n, std::vector<ex>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) A[i][j] = F[i].diff(m.states[j]);
  return A;
}

// The packed upper triangle of Q' = A Q + Q A^T - Gw G^T + N N^T, row by row.
void push_riccati_rows(GeneratedFunction& f, Names& names, const ExMatrix& A, const ExMatrix& Q,
                       const RiccatiGain& g, const GiNaC::matrix& NNt) {
  const std::size_t n = Q.size(), p = g.G.empty() ? 0 : g.G[0].size();
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r; c < n; ++c) {
      ex acc = NNt(static_cast<unsigned>(r), static_cast<unsigned>(c));
      if (r == c) {
        // (A Q + Q A^T)_rr = 2 (A Q)_rr: bound once, so that the factor 2 is one product
        // instead of being distributed over the sum's terms.
        ex aq = 0;
        for (std::size_t k = 0; k < n; ++k) aq += A[r][k] * Q[k][r];
        acc += 2 * bind_let(f, names, fmt::format("AQ_{}_{}", r + 1, r + 1), aq);
      } else {
        for (std::size_t k = 0; k < n; ++k) acc += A[r][k] * Q[k][c] + Q[r][k] * A[c][k];
      }
      for (std::size_t k = 0; k < p; ++k) acc -= g.Gw[r][k] * g.G[c][k];
      f.outputs.push_back(acc);
    }
}

// The right-hand side d/dt (m, Q), and A = D_x(f + g) for the report.
struct RiccatiRhs {
  GeneratedFunction f;
  ExMatrix A;
};

RiccatiRhs riccati_rhs(const Model& m, const RiccatiSymbols& sym, const GiNaC::matrix& W,
                       const GiNaC::matrix& NNt, Names& names) {
  const ExVec F = m.field();
  RiccatiRhs out;
  GeneratedFunction& rhs = out.f;
  rhs.name = "riccati_rhs";
  rhs.doc =
      "d/dt (m, Q): m' = f + g + G R^-2 (y - h), Q' = A Q + Q A^T - G R^-2 G^T + N N^T "
      "(upper triangle), G = Q Dh^T.";
  rhs.args = {vector_arg("w", "ObserverState", sym.w, FunctionArg::Kind::observer_state),
              input_arg(m), output_arg(sym.y)};
  rhs.out_type = "ObserverState";
  rhs.out_rows = sym.w.size();

  const std::vector<ex> e = bind_innovation(rhs, names, m, sym.y);
  const RiccatiGain g = bind_gain(rhs, names, m, sym.Q, W);
  out.A = field_jacobian(m, F);
  // m' = f + g + Gw e
  for (std::size_t i = 0; i < m.n(); ++i) {
    ex acc = F[i];
    for (std::size_t k = 0; k < m.p(); ++k) acc += g.Gw[i][k] * e[k];
    rhs.outputs.push_back(acc);
  }
  push_riccati_rows(rhs, names, out.A, sym.Q, g, NNt);
  return out;
}

// The spec without its texts: state layout, functions (init, rhs, estimate) and their roles.
ObserverSpec riccati_skeleton(const Model& m, const RiccatiParameters& prm,
                              const RiccatiSymbols& sym, GeneratedFunction rhs) {
  const std::size_t n = m.n();
  SymmetricBlock Q;
  Q.name = "Q";
  Q.offset = n;
  Q.dim = n;
  Q.keep_positive_definite = true;

  ObserverSpec s;
  s.method = "riccati";
  s.class_suffix = "Riccati";
  s.state_size = sym.w.size();
  s.state_name = "w";
  s.state_doc = fmt::format(
      "w = (m, Q): the estimate m (rows 0..{}) and Q as its packed upper triangle, row by row "
      "(rows {}..{})",
      n - 1, n, sym.w.size() - 1);
  s.params = runtime_params(m);
  s.functions = model_functions(m);

  ExVec init(m.states.begin(), m.states.end());
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r; c < n; ++c)
      init.push_back(prm.Q0(static_cast<unsigned>(r), static_cast<unsigned>(c)));
  s.functions.push_back(make_function("riccati_init", "w = (xh0, Q0 packed upper triangle).",
                                      {state_arg(m)}, init, "ObserverState"));
  s.functions.push_back(std::move(rhs));
  s.functions.push_back(
      make_function("riccati_estimate", "The estimate m: the first n entries of w.",
                    {vector_arg("w", "ObserverState", sym.w, FunctionArg::Kind::observer_state)},
                    ExVec(m.states.begin(), m.states.end()), "State"));
  s.init = InitKind::function;
  s.roles.init = "riccati_init";
  s.update = UpdateKind::ode;
  s.roles.rhs = "riccati_rhs";
  s.estimate = EstimateKind::function;
  s.roles.estimate = "riccati_estimate";
  s.symmetric_blocks = {Q};
  return s;
}

// Title, description, class documentation and the constants of the generated class.
void describe_riccati(ObserverSpec& s, const RiccatiParameters& prm) {
  s.title = "James-Baras Riccati observer (seed 000, eq. 2.1-2.2)";
  s.description = {
      "Observer: James-Baras Riccati observer (seed 000, eq. 2.1-2.2)",
      fmt::format("Q0 = {}{}; N = {}{}; R = {}{}", matrix_text(prm.Q0),
                  prm.Q0_given ? "" : " (default)", matrix_text(prm.N),
                  prm.N_given ? "" : " (default)", matrix_text(prm.R),
                  prm.R_given ? "" : " (default)"),
      "Integrator: RK4 of (m, Q) jointly with u, y held over a step; a step that leaves Q "
      "without a Cholesky factor is rejected (Status::singular)"};
  s.class_doc = {
      "  m' = f(m, u) + g(m, u) + Q H^T R^-1 (y - h(m))",
      "  Q' = A Q + Q A^T - Q H^T H Q + N N^T,  Q(0) = Q0",
      "with A = D_x(f + g)(m, u) and H = R^-1 Dh(m): R acts as a standard deviation (the gain is",
      "Q Dh^T R^-2). Q is stored as its packed upper triangle in w; only the upper triangle of",
      "Q' is computed. A step after which Q has no Cholesky factor is rejected (state kept,",
      "Status::singular), never a NaN."};
  s.constants.push_back({"Q0", row_major(prm.Q0), "initial Q (row-major), symmetric > 0"});
  s.constants.push_back({"N", row_major(prm.N), "N (row-major); N N^T drives Q"});
  s.constants.push_back({"R", row_major(prm.R), "R (row-major), acts as a standard deviation"});
}

// "[[a, b], [c, d]]" of the rows given.
std::string rows_text(const ExMatrix& M) {
  std::vector<std::string> rows;
  for (const auto& r : M) {
    std::vector<std::string> row;
    for (const auto& e : r) row.push_back(to_string(e));
    rows.push_back(fmt::format("[{}]", fmt::join(row, ", ")));
  }
  return fmt::format("[{}]", fmt::join(rows, ", "));
}

// Dh, p x n.
ExMatrix output_jacobian(const Model& m) {
  ExMatrix Dh(m.p(), std::vector<ex>(m.n()));
  for (std::size_t k = 0; k < m.p(); ++k)
    for (std::size_t j = 0; j < m.n(); ++j) Dh[k][j] = m.h[k].diff(m.states[j]);
  return Dh;
}

// The report rows: equations, A, Dh, the parameters, warnings, then the certificate of
// Theorem 2.1 / Corollary 2.1 over the domain box (rigorous or sampled, each number labelled).
void report_riccati(ObserverSpec& s, const Analysis& a, const DesignOptions& o,
                    const RiccatiParameters& prm, const ExMatrix& A, const GiNaC::matrix& W) {
  const Model& m = a.model;
  const std::size_t n = m.n(), p = m.p();
  s.report = {
      {"equations",
       "m' = f(m,u) + Q H^T R^-1 (y - h(m)), Q' = A Q + Q A^T - Q H^T H Q + N N^T "
       "(seed 000 eq. 2.1-2.2)"},
      {"convention", "A = D_x(f+g)(m,u), H = R^-1 Dh(m): R acts as a standard deviation"},
      {"A = D_x(f+g)", rows_text(A)},
      {"Dh", rows_text(output_jacobian(m))},
      {"Q0", matrix_text(prm.Q0) + (prm.Q0_given ? " (--Q0)" : " (default: I)")},
      {"N", matrix_text(prm.N) + (prm.N_given ? " (--N)" : " (default: I)")},
      {"R", matrix_text(prm.R) + (prm.R_given ? " (--R)" : " (default: I)")},
      {"R^-2", matrix_text(W) + " (exact)"},
      {"integrator",
       "RK4 of (m, Q) with u, y held; Q kept symmetric positive definite (after each step its "
       "L D L^T pivots must be finite and > 0, i.e. Q has a Cholesky factor; otherwise the step "
       "is rejected: Status::singular)"}};
  if (prm.N.rank() < n)
    s.report.push_back({"warning", fmt::format("rank N = {} < n = {}: seed 000 assumes rank N = n "
                                               "(N N^T >= r0 I, r0 > 0)",
                                               prm.N.rank(), n)});
  const Verdict v = applies(a);
  if (!v.applies) s.report.push_back({"warning", v.text()});
  const certify::RiccatiCertificate cert = certify::riccati_certificate(
      m, certify::RiccatiParameters{prm.Q0, prm.N, prm.R, lambda_option(o, n, p)});
  for (auto& row : certify::riccati_certificate_rows(cert)) s.report.push_back(std::move(row));
}

ObserverSpec build(const Analysis& a, const DesignOptions& o) {
  const Model& m = a.model;
  const RiccatiParameters prm = riccati_parameters(m.n(), m.p(), o);
  Names names(m);

  // W = R^-1 R^-1 = R^-2 (R symmetric): H^T R^-1 = Dh^T R^-2 and H^T H = Dh^T R^-2 Dh.
  const GiNaC::matrix Rinv = prm.R.inverse();
  const GiNaC::matrix W = Rinv.mul(Rinv);
  const GiNaC::matrix NNt = prm.N.mul(prm.N.transpose());

  const RiccatiSymbols sym = riccati_symbols(m, names);
  RiccatiRhs rhs = riccati_rhs(m, sym, W, NNt, names);
  ObserverSpec s = riccati_skeleton(m, prm, sym, std::move(rhs.f));
  describe_riccati(s, prm);
  report_riccati(s, a, o, prm, rhs.A, W);
  s.summary = fmt::format(
      "James-Baras Riccati observer (seed 000): RK4 of (m, Q) with Q packed and kept positive "
      "definite; Q0 = {}, N = {}, R = {}",
      matrix_text(prm.Q0), matrix_text(prm.N), matrix_text(prm.R));
  return s;
}

}  // namespace

bool exact_positive_definite(const GiNaC::matrix& M) {
  for (unsigned k = 1; k <= M.rows(); ++k) {
    GiNaC::matrix L(k, k);
    for (unsigned r = 0; r < k; ++r)
      for (unsigned c = 0; c < k; ++c) L(r, c) = M(r, c);
    const ex d = L.determinant();
    if (!GiNaC::is_a<numeric>(d) || !GiNaC::ex_to<numeric>(d).is_positive()) return false;
  }
  return true;
}

RiccatiParameters riccati_parameters(std::size_t n, std::size_t p, const DesignOptions& o) {
  RiccatiParameters r;
  r.Q0 = matrix_option(o, "Q0", n, "Q0", r.Q0_given);
  r.N = matrix_option(o, "N", n, "N", r.N_given);
  r.R = matrix_option(o, "R", p, "R (one row per output)", r.R_given);
  require_symmetric_pd(r.Q0, "Q0");
  require_symmetric_pd(r.R, "R");
  return r;
}

Design riccati_design() {
  Design d;
  d.name = "riccati";
  d.summary = "James-Baras Riccati observer (seed 000; Jacobians only, Q kept positive definite)";
  d.options = {
      {"Q0",
       "riccati: initial Q, symmetric positive definite: n values (diagonal), n*n (row-major) "
       "or 1 (multiple of I)",
       "I"},
      {"N", "riccati: N of Q' = ... + N N^T, n x n: n values (diagonal), n*n or 1", "I"},
      {"R",
       "riccati: R (a standard deviation: gain Q Dh^T R^-2), p x p symmetric positive definite: "
       "p values (diagonal), p*p or 1",
       "I"},
      {"Lambda",
       "riccati: Lambda of the detectability test (3.3), n x p: n*p values (row-major); "
       "certificate only",
       "0"}};
  d.needs_canonical_form = false;
  d.applies = applies;
  d.build = build;
  return d;
}

}  // namespace obsynth
