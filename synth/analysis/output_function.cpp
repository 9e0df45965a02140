#include "analysis/output_function.hpp"

#include "analysis/inverse.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;

namespace {

// x_k = value(y, other states) with h(x) = y, for a state not in `used`: a state h equals,
// else the first one h solves for (linear in it or in one invertible atom of it).
std::optional<std::pair<std::size_t, ex>> solve_output(const ex& h, const Symbols& x,
                                                       const GiNaC::symbol& y,
                                                       const std::vector<bool>& used) {
  for (std::size_t i = 0; i < x.size(); ++i)
    if (!used[i] && h.is_equal(x[i])) return std::make_pair(i, ex(y));
  for (std::size_t i = 0; i < x.size(); ++i)
    if (!used[i])
      if (const auto s = solve_for(h - y, x[i])) return std::make_pair(i, *s);
  return std::nullopt;
}

}  // namespace

std::optional<ex> express_in_outputs(const ex& e, const ExVec& h, const Symbols& x,
                                     const std::vector<GiNaC::symbol>& y, const ExVec& base_point,
                                     const SampleBoxes& boxes) {
  // Solve h_1 = y_1, h_2 = y_2, ... in turn, each for a new state, the earlier solutions
  // substituted into the later outputs.
  std::vector<bool> used(x.size(), false);
  GiNaC::exmap solution;
  for (std::size_t q = 0; q < h.size(); ++q) {
    const auto s = solve_output(simplify(h[q].subs(solution)), x, y[q], used);
    if (!s) return std::nullopt;
    used[s->first] = true;
    for (auto& [state, value] : solution) value = simplify(value.subs(x[s->first] == s->second));
    solution[x[s->first]] = s->second;
  }
  ex r = simplify(e.subs(solution));
  Symbols others;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (!used[i] && r.has(x[i])) others.push_back(x[i]);
  if (others.empty()) return r;
  // Remaining dependence must vanish identically (e.g. sin^2 + cos^2 left by normal()).
  for (const auto& s : others)
    if (zero_test(r.diff(s), boxes) == ZeroVerdict::nonzero) return std::nullopt;
  GiNaC::exmap at;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (!used[i]) at[x[i]] = base_point[i];
  return simplify(r.subs(at));
}

std::optional<ex> express_in_output(const ex& e, const ex& h, const Symbols& x,
                                    const GiNaC::symbol& y, const ExVec& base_point,
                                    const SampleBoxes& boxes) {
  return express_in_outputs(e, {h}, x, {y}, base_point, boxes);
}

OutputFunction::OutputFunction(const PolyRing& ring, const ex& h, const Symbols& x, GiNaC::symbol y,
                               ExVec base_point, SampleBoxes boxes, ZeroTestOptions zero)
    : ring_(ring),
      h_(h),
      x_(x),
      y_(std::move(y)),
      base_point_(std::move(base_point)),
      boxes_(std::move(boxes)),
      zero_(zero) {
  const ex he = GiNaC::expand(h);
  for (std::size_t k = 0; k < x.size() && !line_; ++k) {
    const ex c = he.diff(x[k]);
    if (!GiNaC::is_a<GiNaC::numeric>(c) || c.is_zero()) continue;
    GiNaC::exmap at;
    for (std::size_t j = 0; j < x.size(); ++j)
      if (j != k) at[x[j]] = base_point_[j];
    const ex b0 = (he - c * x[k]).subs(at);
    if (b0.has(x[k])) continue;
    at[x[k]] = (y_ - b0) / c;
    line_ = at;
  }
}

std::optional<OutputFunction::Result> OutputFunction::operator()(const Poly& p) const {
  const ex e = ring_.to_ex(p);
  Result r;
  if (!line_) {
    const auto v = express_in_output(e, h_, x_, y_, base_point_, boxes_);
    if (!v) return std::nullopt;
    r.value = *v;
    r.verdict = zero_test(simplify(v->subs(y_ == h_) - e), boxes_, zero_);
    if (r.verdict == ZeroVerdict::nonzero) return std::nullopt;
    return r;
  }
  r.value = simplify(e.subs(*line_));
  // p = A(h(x)): exactly in the ring when A(h) converts, else by the zero test.
  const ex back = r.value.subs(y_ == h_);
  if (const auto q = ring_.from_ex(back)) {
    Poly d = *q;
    PolyRing::subtract_from(d, p);
    if (d.is_zero()) return r;
    r.verdict = zero_test(ring_.to_ex(d), boxes_, zero_);
  } else {
    r.verdict = zero_test(simplify(back - e), boxes_, zero_);
  }
  if (r.verdict == ZeroVerdict::nonzero) return std::nullopt;
  return r;
}

}  // namespace obsynth
