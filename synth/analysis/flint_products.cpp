#include "analysis/flint_products.hpp"

#include <flint/fmpq_mpoly.h>

#include <cln/integer.h>
#include <cln/rational.h>

#include <algorithm>
#include <array>
#include <deque>

#include "analysis/flint_mpoly.hpp"

namespace obsynth {

namespace {

void set_fmpz(fmpz_t out, const cln::cl_I& v) {
  if (cln::integer_length(v) < 63) {
    fmpz_set_si(out, cln::cl_I_to_Q(v));
    return;
  }
  // Large values limb by limb: |v| = sum of 32-bit digits.
  const cln::cl_I a = cln::abs(v);
  fmpz_zero(out);
  for (uintL bit = cln::integer_length(a); bit > 0;) {
    const uintL take = bit >= 32 ? 32 : bit;
    bit -= take;
    fmpz_mul_2exp(out, out, take);
    fmpz_add_ui(out, out, cln::cl_I_to_UQ(cln::ldb(a, cln::cl_byte(take, bit))));
  }
  if (cln::minusp(v)) fmpz_neg(out, out);
}

cln::cl_I to_cl_I(const fmpz_t v) {
  if (fmpz_fits_si(v)) {
    const slong s = fmpz_get_si(v);
    // Built from the magnitude: CLN's inline constructors shift negative values.
    const cln::cl_I mag = cln::cl_I(static_cast<unsigned long>(s < 0 ? -(s + 1) : s)) +
                          (s < 0 ? cln::cl_I(1UL) : cln::cl_I(0UL));
    return s < 0 ? -mag : mag;
  }
  fmpz_t a, digit;
  fmpz_init(a);
  fmpz_init(digit);
  fmpz_abs(a, v);
  cln::cl_I out = 0UL;
  const slong bits = static_cast<slong>(fmpz_bits(a));
  for (slong bit = ((bits + 31) / 32) * 32; bit > 0;) {
    bit -= 32;
    fmpz_fdiv_q_2exp(digit, a, static_cast<ulong>(bit));
    fmpz_fdiv_r_2exp(digit, digit, 32);
    out = out * cln::cl_I(4294967296UL) + cln::cl_I(fmpz_get_ui(digit));
  }
  if (fmpz_sgn(v) < 0) out = -out;
  fmpz_clear(a);
  fmpz_clear(digit);
  return out;
}

}  // namespace

// Every added polynomial is kept in the ring; its FLINT copy (and FLINT's context) is made at
// the first product large enough for FLINT (kFlintProductWork).
struct FlintProducts::Impl {
  std::size_t variables;
  std::vector<Poly> ring;
  std::deque<fmpq_mpoly_struct> polys;  // FLINT copies, by handle (empty until needed)
  std::vector<bool> converted;
  bool ctx_ready = false;
  fmpq_mpoly_ctx_t ctx;
  explicit Impl(std::size_t v) : variables(std::max<std::size_t>(v, 1)) {}
  ~Impl() {
    if (!ctx_ready) return;
    for (std::size_t h = 0; h < polys.size(); ++h)
      if (converted[h]) fmpq_mpoly_clear(&polys[h], ctx);
    fmpq_mpoly_ctx_clear(ctx);
  }
  const fmpq_mpoly_struct* flint(Handle h);
  std::size_t work(const std::vector<Handle>& a, const std::vector<Handle>& b) const {
    std::size_t w = 0;
    for (std::size_t j = 0; j < a.size(); ++j)
      w += ring[a[j]].terms.size() * ring[b[j]].terms.size();
    return w;
  }
};

FlintProducts::FlintProducts(std::size_t variables) : impl_(std::make_unique<Impl>(variables)) {}
FlintProducts::~FlintProducts() = default;

constexpr long kExponentBias = 128;

FlintProducts::Handle FlintProducts::add(const Poly& p) {
  impl_->ring.push_back(p);
  return impl_->ring.size() - 1;
}

const fmpq_mpoly_struct* FlintProducts::Impl::flint(Handle h) {
  if (!ctx_ready) {
    fmpq_mpoly_ctx_init(ctx, static_cast<slong>(variables), ORD_LEX);
    ctx_ready = true;
  }
  while (polys.size() < ring.size()) {
    polys.emplace_back();
    converted.push_back(false);
  }
  fmpq_mpoly_struct* out = &polys[h];
  if (converted[h]) return out;
  fmpq_mpoly_init(out, ctx);
  converted[h] = true;
  std::array<ulong, kMaxPolyVariables> exps{};
  fmpq_t c;
  fmpq_init(c);
  for (const auto& [m, coeff] : ring[h].terms) {
    // Ring exponents are signed (exp bases are Laurent): biased to be FLINT's unsigned ones.
    for (std::size_t i = 0; i < variables; ++i)
      exps[i] = static_cast<ulong>(int{m.e[i]} + kExponentBias);
    set_fmpz(fmpq_numref(c), cln::numerator(coeff));
    set_fmpz(fmpq_denref(c), cln::denominator(coeff));
    fmpq_mpoly_push_term_fmpq_ui(out, c, exps.data(), ctx);
  }
  fmpq_clear(c);
  fmpq_mpoly_sort_terms(out, ctx);
  fmpq_mpoly_combine_like_terms(out, ctx);
  return out;
}

Poly FlintProducts::dot_difference(const std::vector<Handle>& a, const std::vector<Handle>& b,
                                   const std::vector<Handle>& c, const std::vector<Handle>& d) {
  Impl& im = *impl_;
  if (im.work(a, b) + im.work(c, d) < kFlintProductWork) {
    auto dot = [&](const std::vector<Handle>& u, const std::vector<Handle>& v) {
      Poly out;
      for (std::size_t j = 0; j < u.size(); ++j)
        PolyRing::add_to(out, PolyRing::product(im.ring[u[j]], im.ring[v[j]]));
      return out;
    };
    Poly out = dot(a, b);
    PolyRing::subtract_from(out, dot(c, d));
    return out;
  }
  fmpq_mpoly_t acc, term;
  for (const std::vector<Handle>* hs : {&a, &b, &c, &d})  // convert once, without copies
    for (Handle h : *hs) im.flint(h);
  const auto ctx = im.ctx;
  fmpq_mpoly_init(acc, ctx);
  fmpq_mpoly_init(term, ctx);
  for (std::size_t j = 0; j < a.size(); ++j) {
    fmpq_mpoly_mul(term, &im.polys[a[j]], &im.polys[b[j]], ctx);
    fmpq_mpoly_add(acc, acc, term, ctx);
  }
  for (std::size_t j = 0; j < c.size(); ++j) {
    fmpq_mpoly_mul(term, &im.polys[c[j]], &im.polys[d[j]], ctx);
    fmpq_mpoly_sub(acc, acc, term, ctx);
  }
  Poly out;
  std::array<ulong, kMaxPolyVariables> exps{};
  fmpq_t q;
  fmpq_init(q);
  for (slong i = 0; i < fmpq_mpoly_length(acc, ctx); ++i) {
    fmpq_mpoly_get_term_coeff_fmpq(q, acc, i, ctx);
    fmpq_mpoly_get_term_exp_ui(exps.data(), acc, i, ctx);
    Monomial m;
    for (std::size_t v = 0; v < impl_->variables; ++v) {
      // Each term is a product of two biased operands: twice the bias.
      const long e = static_cast<long>(exps[v]) - 2 * kExponentBias;
      if (e < -128 || e > 127) throw PolyOverflow{};
      m.e[v] = static_cast<std::int8_t>(e);
    }
    out.terms.emplace(m, cln::cl_RA(to_cl_I(fmpq_numref(q))) / to_cl_I(fmpq_denref(q)));
  }
  fmpq_clear(q);
  fmpq_mpoly_clear(acc, ctx);
  fmpq_mpoly_clear(term, ctx);
  return out;
}

}  // namespace obsynth
