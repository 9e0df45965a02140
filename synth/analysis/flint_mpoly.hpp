// FLINT's fmpq_mpoly as the engine for the heavy polynomial products and exact divisions of
// the observability stages (Lie chains of dense polynomial fields, fraction-free elimination).
// The polynomial ring (symbolic/poly.hpp) stays the interface: its Poly values are converted
// in and out, its derivative rules (atoms) are reused. On a dense 8-state model FLINT's
// multiplication is about 100x faster than the ring's hash map of rationals.
#pragma once

#include <flint/fmpq_mpoly.h>

#include <memory>
#include <optional>
#include <vector>

#include "symbolic/poly.hpp"

namespace obsynth {

class MPolyContext;

// An fmpq_mpoly bound to its context (move-only).
class MPoly {
 public:
  explicit MPoly(const MPolyContext& ctx);
  MPoly(MPoly&& o) noexcept;
  MPoly& operator=(MPoly&& o) noexcept;
  MPoly(const MPoly&) = delete;
  MPoly& operator=(const MPoly&) = delete;
  ~MPoly();
  fmpq_mpoly_struct* get() { return p_; }
  const fmpq_mpoly_struct* get() const { return p_; }
  bool is_zero() const;
  std::size_t length() const;

 private:
  const MPolyContext* ctx_;
  fmpq_mpoly_struct* p_;
};

// The ring variables a computation touches, mapped to consecutive FLINT variables.
class MPolyContext {
 public:
  // A context for `polys` and every derivative of them (atoms' derivatives bring their
  // companions), or nullopt when some exponent is negative (Laurent exp bases stay in the ring).
  static std::unique_ptr<MPolyContext> for_polys(const PolyRing& ring,
                                                 const std::vector<const Poly*>& polys);
  ~MPolyContext();
  MPolyContext(const MPolyContext&) = delete;
  MPolyContext& operator=(const MPolyContext&) = delete;

  MPoly to_flint(const Poly& p) const;    // throws PolyOverflow on a variable outside the map
  Poly from_flint(const MPoly& p) const;  // throws PolyOverflow on an exponent > 127
  // FLINT's context, created on first use: a small model whose products all stay in the ring
  // (kFlintProductWork) never loads FLINT (the executable loads it lazily).
  const fmpq_mpoly_ctx_struct* ctx() const;

 private:
  MPolyContext() = default;
  mutable fmpq_mpoly_ctx_struct* ctx_ = nullptr;
  std::vector<std::size_t> ring_var_;  // FLINT variable -> ring variable
  std::vector<long> flint_var_;        // ring variable -> FLINT variable, -1 when unused
};

// Below this many term pairs (sum over the products of |a| |b|) a sum of products is computed
// in the ring: FLINT's conversions cost as much there, and a model whose products all stay
// below it never pays FLINT's load (1-1.5 ms of a 5 ms check). Exact either way, so both
// engines give the same polynomial.
constexpr std::size_t kFlintProductWork = 2048;
inline std::size_t product_work(const std::vector<Poly>& a, const std::vector<Poly>& b) {
  std::size_t w = 0;
  for (std::size_t j = 0; j < a.size() && j < b.size(); ++j)
    w += a[j].terms.size() * b[j].terms.size();
  return w;
}

// L_f phi = sum_j (d phi / d x_j) f_j with the products in FLINT.
Poly lie_derivative_flint(const PolyRing& ring, const MPolyContext& ctx, const Poly& phi,
                          const std::vector<MPoly>& field);

// det A and the cofactors of A's last row (adj(A) e_n), by fraction-free (Bareiss) elimination
// of [A | e_n] with exact divisions; nullopt when det A is the zero polynomial.
struct DetCofactors {
  MPoly det;
  std::vector<MPoly> cofactors;
};
std::optional<DetCofactors> det_and_last_row_cofactors(const MPolyContext& ctx,
                                                       std::vector<std::vector<MPoly>> a);

// The distinct non-constant irreducible factors of p (FLINT's multivariate factorisation), each
// scaled to integer coefficients with content 1; nullopt when FLINT cannot factor it.
std::optional<std::vector<MPoly>> irreducible_factors(const MPolyContext& ctx, const MPoly& p);

// a / b in lowest terms: num / den with gcd 1, den with integer coefficients, content 1 and a
// positive leading coefficient. b must be nonzero.
struct Quotient {
  MPoly num, den;
};
Quotient reduced_quotient(const MPolyContext& ctx, const MPoly& a, const MPoly& b);

}  // namespace obsynth
