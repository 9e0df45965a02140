#include "analysis/flint_mpoly.hpp"

#include <flint/fmpq.h>
#include <flint/fmpq_mpoly_factor.h>

#include <cln/integer.h>
#include <cln/integer_io.h>
#include <set>
#include <sstream>

namespace obsynth {

namespace {

void set_fmpz(fmpz_t z, const cln::cl_I& v) {
  if (cln::integer_length(v) < 63) {
    fmpz_set_si(z, cln::cl_I_to_Q(v));
    return;
  }
  std::ostringstream s;
  s << v;
  fmpz_set_str(z, s.str().c_str(), 10);
}

cln::cl_RA get_rational(const fmpq_t c) {
  if (fmpz_fits_si(fmpq_numref(c)) && fmpz_fits_si(fmpq_denref(c)))
    return cln::cl_RA(cln::cl_I(fmpz_get_si(fmpq_numref(c)))) /
           cln::cl_I(fmpz_get_si(fmpq_denref(c)));
  char* s = fmpq_get_str(nullptr, 10, c);
  const cln::cl_RA r(s);
  flint_free(s);
  return r;
}

Poly single_variable(std::size_t v) {
  Poly p;
  Monomial m;
  m.e[v] = 1;
  p.terms.emplace(m, cln::cl_RA(1));
  return p;
}

}  // namespace

MPoly::MPoly(const MPolyContext& ctx) : ctx_(&ctx), p_(new fmpq_mpoly_struct) {
  fmpq_mpoly_init(p_, ctx_->ctx());
}
MPoly::MPoly(MPoly&& o) noexcept : ctx_(o.ctx_), p_(o.p_) {
  o.p_ = nullptr;
}
MPoly& MPoly::operator=(MPoly&& o) noexcept {
  std::swap(ctx_, o.ctx_);
  std::swap(p_, o.p_);
  return *this;
}
MPoly::~MPoly() {
  if (!p_) return;
  fmpq_mpoly_clear(p_, ctx_->ctx());
  delete p_;
}
bool MPoly::is_zero() const {
  return fmpq_mpoly_is_zero(p_, ctx_->ctx());
}
std::size_t MPoly::length() const {
  return static_cast<std::size_t>(fmpq_mpoly_length(p_, ctx_->ctx()));
}

std::unique_ptr<MPolyContext> MPolyContext::for_polys(const PolyRing& ring,
                                                      const std::vector<const Poly*>& polys) {
  // Variables used, closed under differentiation (d sin = cos d(arg), ...).
  std::set<std::size_t> used;
  for (std::size_t j = 0; j < ring.states(); ++j) used.insert(j);
  std::vector<std::size_t> todo;
  auto scan = [&](const Poly& p) {
    for (const auto& [m, c] : p.terms)
      for (std::size_t v = 0; v < kMaxPolyVariables; ++v) {
        if (static_cast<std::int8_t>(m.e[v]) < 0) return false;
        if (m.e[v] > 0 && used.insert(v).second) todo.push_back(v);
      }
    return true;
  };
  for (const Poly* p : polys)
    if (!scan(*p)) return nullptr;
  while (!todo.empty()) {
    const std::size_t v = todo.back();
    todo.pop_back();
    if (v < ring.states()) continue;
    for (std::size_t j = 0; j < ring.states(); ++j)
      if (!scan(ring.derivative(single_variable(v), j))) return nullptr;
  }
  std::unique_ptr<MPolyContext> c(new MPolyContext);
  c->flint_var_.assign(kMaxPolyVariables, -1);
  for (std::size_t v : used) {
    c->flint_var_[v] = static_cast<long>(c->ring_var_.size());
    c->ring_var_.push_back(v);
  }
  return c;
}

const fmpq_mpoly_ctx_struct* MPolyContext::ctx() const {
  if (!ctx_) {
    ctx_ = new fmpq_mpoly_ctx_struct;
    fmpq_mpoly_ctx_init(ctx_, static_cast<slong>(ring_var_.size()), ORD_DEGREVLEX);
  }
  return ctx_;
}

MPolyContext::~MPolyContext() {
  if (!ctx_) return;
  fmpq_mpoly_ctx_clear(ctx_);
  delete ctx_;
}

MPoly MPolyContext::to_flint(const Poly& p) const {
  MPoly out(*this);
  std::vector<ulong> e(ring_var_.size());
  fmpq_t c;
  fmpq_init(c);
  for (const auto& [m, k] : p.terms) {
    std::fill(e.begin(), e.end(), 0);
    for (std::size_t v = 0; v < kMaxPolyVariables; ++v) {
      if (m.e[v] == 0) continue;
      if (static_cast<std::int8_t>(m.e[v]) < 0 || flint_var_[v] < 0) {
        fmpq_clear(c);
        throw PolyOverflow{};
      }
      e[static_cast<std::size_t>(flint_var_[v])] = static_cast<ulong>(m.e[v]);
    }
    set_fmpz(fmpq_numref(c), cln::numerator(k));
    set_fmpz(fmpq_denref(c), cln::denominator(k));
    fmpq_mpoly_push_term_fmpq_ui(out.get(), c, e.data(), ctx_);
  }
  fmpq_clear(c);
  fmpq_mpoly_sort_terms(out.get(), ctx_);
  fmpq_mpoly_combine_like_terms(out.get(), ctx_);
  return out;
}

Poly MPolyContext::from_flint(const MPoly& p) const {
  Poly out;
  const slong len = fmpq_mpoly_length(p.get(), ctx_);
  out.terms.reserve(static_cast<std::size_t>(len));
  std::vector<ulong> e(ring_var_.size());
  fmpq_t c;
  fmpq_init(c);
  for (slong i = 0; i < len; ++i) {
    fmpq_mpoly_get_term_coeff_fmpq(c, p.get(), i, ctx_);
    if (!fmpq_mpoly_term_exp_fits_ui(p.get(), i, ctx_)) {
      fmpq_clear(c);
      throw PolyOverflow{};
    }
    fmpq_mpoly_get_term_exp_ui(e.data(), p.get(), i, ctx_);
    Monomial m;
    for (std::size_t v = 0; v < e.size(); ++v) {
      if (e[v] > 127) {
        fmpq_clear(c);
        throw PolyOverflow{};
      }
      m.e[ring_var_[v]] = static_cast<std::int8_t>(e[v]);
    }
    out.terms.emplace(m, get_rational(c));
  }
  fmpq_clear(c);
  return out;
}

Poly lie_derivative_flint(const PolyRing& ring, const MPolyContext& ctx, const Poly& phi,
                          const std::vector<MPoly>& field) {
  MPoly acc(ctx), term(ctx);
  for (std::size_t j = 0; j < field.size(); ++j) {
    if (field[j].is_zero()) continue;
    const Poly d = ring.derivative(phi, j);
    if (d.is_zero()) continue;
    const MPoly dj = ctx.to_flint(d);
    fmpq_mpoly_mul(term.get(), dj.get(), field[j].get(), ctx.ctx());
    fmpq_mpoly_add(acc.get(), acc.get(), term.get(), ctx.ctx());
  }
  return ctx.from_flint(acc);
}

namespace {

// a := (p * a - q * b) / d, exactly.
void bareiss_update(const MPolyContext& ctx, MPoly& a, const MPoly& p, const MPoly& q,
                    const MPoly& b, const MPoly& d) {
  const auto* c = ctx.ctx();
  MPoly t(ctx), u(ctx);
  fmpq_mpoly_mul(t.get(), p.get(), a.get(), c);
  fmpq_mpoly_mul(u.get(), q.get(), b.get(), c);
  fmpq_mpoly_sub(t.get(), t.get(), u.get(), c);
  if (!fmpq_mpoly_divides(a.get(), t.get(), d.get(), c))
    throw std::logic_error("fraction-free elimination: inexact division");
}

}  // namespace

std::optional<DetCofactors> det_and_last_row_cofactors(const MPolyContext& ctx,
                                                       std::vector<std::vector<MPoly>> a) {
  const std::size_t n = a.size();
  const auto* c = ctx.ctx();
  // Augment with e_n.
  for (std::size_t i = 0; i < n; ++i) {
    a[i].emplace_back(ctx);
    if (i + 1 == n) fmpq_mpoly_one(a[i].back().get(), c);
  }
  int sign = 1;
  MPoly prev(ctx);
  fmpq_mpoly_one(prev.get(), c);
  for (std::size_t k = 0; k < n; ++k) {
    // The shortest nonzero pivot keeps the products small.
    std::optional<std::size_t> piv;
    for (std::size_t i = k; i < n; ++i)
      if (!a[i][k].is_zero() && (!piv || a[i][k].length() < a[*piv][k].length())) piv = i;
    if (!piv) return std::nullopt;
    if (*piv != k) {
      std::swap(a[*piv], a[k]);
      sign = -sign;
    }
    for (std::size_t i = k + 1; i < n; ++i) {
      for (std::size_t j = k + 1; j <= n; ++j)
        bareiss_update(ctx, a[i][j], a[k][k], a[i][k], a[k][j], prev);
      fmpq_mpoly_zero(a[i][k].get(), c);
    }
    fmpq_mpoly_set(prev.get(), a[k][k].get(), c);
  }
  // Back substitution: y_i = D x_i with D = a[n-1][n-1] = det(PA); exact by Cramer's rule.
  const MPoly& D = a[n - 1][n - 1];
  std::vector<MPoly> y;
  for (std::size_t i = 0; i < n; ++i) y.emplace_back(ctx);
  for (std::size_t i = n; i-- > 0;) {
    MPoly acc(ctx), t(ctx);
    fmpq_mpoly_mul(acc.get(), D.get(), a[i][n].get(), c);
    for (std::size_t j = i + 1; j < n; ++j) {
      fmpq_mpoly_mul(t.get(), a[i][j].get(), y[j].get(), c);
      fmpq_mpoly_sub(acc.get(), acc.get(), t.get(), c);
    }
    if (!fmpq_mpoly_divides(y[i].get(), acc.get(), a[i][i].get(), c))
      throw std::logic_error("fraction-free back substitution: inexact division");
  }
  DetCofactors out{MPoly(ctx), {}};
  fmpq_mpoly_set(out.det.get(), D.get(), c);
  if (sign < 0) fmpq_mpoly_neg(out.det.get(), out.det.get(), c);
  for (auto& v : y) {
    if (sign < 0) fmpq_mpoly_neg(v.get(), v.get(), c);
    out.cofactors.push_back(std::move(v));
  }
  return out;
}

namespace {

// p / content(p), its leading coefficient made positive.
void make_primitive(const MPolyContext& ctx, MPoly& p) {
  const auto* c = ctx.ctx();
  if (p.is_zero()) return;
  fmpq_t g;
  fmpq_init(g);
  fmpq_mpoly_content(g, p.get(), c);
  fmpq_mpoly_scalar_div_fmpq(p.get(), p.get(), g, c);
  fmpq_mpoly_get_term_coeff_fmpq(g, p.get(), 0, c);
  if (fmpq_sgn(g) < 0) fmpq_mpoly_neg(p.get(), p.get(), c);
  fmpq_clear(g);
}

}  // namespace

std::optional<std::vector<MPoly>> irreducible_factors(const MPolyContext& ctx, const MPoly& p) {
  const auto* c = ctx.ctx();
  fmpq_mpoly_factor_t f;
  fmpq_mpoly_factor_init(f, c);
  std::optional<std::vector<MPoly>> out;
  if (fmpq_mpoly_factor(f, p.get(), c)) {
    out.emplace();
    for (slong i = 0; i < fmpq_mpoly_factor_length(f, c); ++i) {
      MPoly b(ctx);
      fmpq_mpoly_factor_get_base(b.get(), f, i, c);
      if (fmpq_mpoly_is_fmpq(b.get(), c)) continue;
      make_primitive(ctx, b);
      out->push_back(std::move(b));
    }
  }
  fmpq_mpoly_factor_clear(f, c);
  return out;
}

Quotient reduced_quotient(const MPolyContext& ctx, const MPoly& a, const MPoly& b) {
  const auto* c = ctx.ctx();
  Quotient q{MPoly(ctx), MPoly(ctx)};
  MPoly g(ctx);
  if (!fmpq_mpoly_gcd(g.get(), a.get(), b.get(), c) || g.is_zero()) fmpq_mpoly_one(g.get(), c);
  if (!fmpq_mpoly_divides(q.num.get(), a.get(), g.get(), c) ||
      !fmpq_mpoly_divides(q.den.get(), b.get(), g.get(), c))
    throw std::logic_error("reduced quotient: the gcd does not divide");
  // Scale so that den is primitive with a positive leading coefficient.
  fmpq_t k, lead;
  fmpq_init(k);
  fmpq_init(lead);
  fmpq_mpoly_content(k, q.den.get(), c);
  fmpq_mpoly_get_term_coeff_fmpq(lead, q.den.get(), 0, c);
  if (fmpq_sgn(lead) < 0) fmpq_neg(k, k);
  fmpq_mpoly_scalar_div_fmpq(q.num.get(), q.num.get(), k, c);
  fmpq_mpoly_scalar_div_fmpq(q.den.get(), q.den.get(), k, c);
  fmpq_clear(k);
  fmpq_clear(lead);
  return q;
}

}  // namespace obsynth
