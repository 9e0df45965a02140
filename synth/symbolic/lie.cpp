#include "symbolic/lie.hpp"

#include "symbolic/symbolic.hpp"

namespace obsynth {

ExMatrix jacobian(const ExVec& field, const Symbols& x) {
  ExMatrix J(field.size(), ExVec(x.size()));
  for (std::size_t i = 0; i < field.size(); ++i)
    for (std::size_t j = 0; j < x.size(); ++j) J[i][j] = field[i].diff(x[j]);
  return J;
}

GiNaC::ex lie_derivative(const GiNaC::ex& phi, const ExVec& field, const Symbols& x) {
  GiNaC::ex acc = 0;
  for (std::size_t j = 0; j < x.size(); ++j) {
    if (field[j].is_zero()) continue;
    const GiNaC::ex d = phi.diff(x[j]);
    if (!d.is_zero()) acc += d * field[j];
  }
  return simplify(acc);
}

ExVec lie_bracket(const ExVec& a, const ExMatrix& da, const ExVec& b, const ExMatrix& db) {
  const std::size_t n = a.size();
  ExVec out(n);
  for (std::size_t i = 0; i < n; ++i) {
    GiNaC::ex acc = 0;
    for (std::size_t j = 0; j < n; ++j) {
      if (!db[i][j].is_zero() && !a[j].is_zero()) acc += db[i][j] * a[j];
      if (!da[i][j].is_zero() && !b[j].is_zero()) acc -= da[i][j] * b[j];
    }
    out[i] = simplify(acc);
  }
  return out;
}

ExVec lie_bracket(const ExVec& a, const ExVec& b, const Symbols& x) {
  return lie_bracket(a, jacobian(a, x), b, jacobian(b, x));
}

LieChain lie_chain_with_gradients(const GiNaC::ex& h, const ExVec& f, const Symbols& x,
                                  std::size_t count, const Budget* budget) {
  LieChain out;
  if (count == 0) return out;
  out.derivatives.push_back(h);
  for (std::size_t k = 0; k < count; ++k) {
    ExVec row = gradient(out.derivatives[k], x);
    for (auto& e : row) e = simplify(e);
    if (k + 1 < count) {
      GiNaC::ex next = 0;
      for (std::size_t j = 0; j < x.size(); ++j)
        if (!row[j].is_zero() && !f[j].is_zero()) next += row[j] * f[j];
      out.derivatives.push_back(simplify(next));
      if (budget) budget->check(expression_size(out.derivatives.back()));
    }
    out.gradients.push_back(std::move(row));
  }
  return out;
}

ExVec simplified(const ExVec& v) {
  ExVec out;
  out.reserve(v.size());
  for (const auto& e : v) out.push_back(simplify(e));
  return out;
}

}  // namespace obsynth
