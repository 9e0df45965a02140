// Sums of products of ring elements computed with FLINT's fmpq_mpoly (sparse multivariate
// polynomials over Q with packed exponents and fast multiplication). On the dense-O family
// the frame recursion's products are 10-30x faster than the ring's hash map (measured with
// the dense family, bench/README.md). Ring variables (states, symbols, atoms) map one to one
// to FLINT variables; derivatives stay in the ring, which knows the atoms' chain rule.
#pragma once

#include <memory>
#include <vector>

#include "symbolic/poly.hpp"

namespace obsynth {

class FlintProducts {
 public:
  // For polynomials in the first `variables` ring variables.
  explicit FlintProducts(std::size_t variables);
  ~FlintProducts();
  FlintProducts(const FlintProducts&) = delete;
  FlintProducts& operator=(const FlintProducts&) = delete;

  // A handle to a converted polynomial (owned by this object).
  using Handle = std::size_t;
  Handle add(const Poly& p);
  // sum_j a[j] * b[j] - sum_j c[j] * d[j] (the component of a Lie bracket).
  Poly dot_difference(const std::vector<Handle>& a, const std::vector<Handle>& b,
                      const std::vector<Handle>& c, const std::vector<Handle>& d);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace obsynth
