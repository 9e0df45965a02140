#include "symbolic/symbolic.hpp"

#include <algorithm>
#include <set>

namespace obsynth {

namespace {
void collect(const GiNaC::ex& e, std::vector<GiNaC::symbol>& out, std::set<std::string>& seen) {
  if (GiNaC::is_a<GiNaC::symbol>(e)) {
    const auto& s = GiNaC::ex_to<GiNaC::symbol>(e);
    if (seen.insert(s.get_name()).second) out.push_back(s);
    return;
  }
  for (std::size_t i = 0; i < e.nops(); ++i) collect(e.op(i), out, seen);
}
}  // namespace

std::vector<GiNaC::symbol> symbols_in(const GiNaC::ex& e) {
  std::vector<GiNaC::symbol> out;
  std::set<std::string> seen;
  collect(e, out, seen);
  std::sort(out.begin(), out.end(), [](const GiNaC::symbol& a, const GiNaC::symbol& b) {
    return a.get_name() < b.get_name();
  });
  return out;
}

bool depends_on(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& syms) {
  for (const auto& s : syms)
    if (e.has(s)) return true;
  return false;
}

std::size_t expression_size(const GiNaC::ex& e) {
  std::size_t n = 1;
  for (std::size_t i = 0; i < e.nops(); ++i) n += expression_size(e.op(i));
  return n;
}

bool has_transcendental(const GiNaC::ex& e) {
  if (GiNaC::is_a<GiNaC::function>(e)) return true;
  if (GiNaC::is_a<GiNaC::power>(e)) {
    const GiNaC::ex ex = e.op(1);
    if (!(GiNaC::is_a<GiNaC::numeric>(ex) && GiNaC::ex_to<GiNaC::numeric>(ex).is_integer()))
      return true;
  }
  for (std::size_t i = 0; i < e.nops(); ++i)
    if (has_transcendental(e.op(i))) return true;
  return false;
}

namespace {
// A negative power (or tan = sin/cos) whose base `matters`, anywhere in e.
template <class Matters>
bool has_denominator(const GiNaC::ex& e, const Matters& matters) {
  if (GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<GiNaC::numeric>(e.op(1)) &&
      GiNaC::ex_to<GiNaC::numeric>(e.op(1)).is_negative() && matters(e.op(0)))
    return true;
  if (GiNaC::is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == "tan" &&
      matters(e))
    return true;
  for (std::size_t i = 0; i < e.nops(); ++i)
    if (has_denominator(e.op(i), matters)) return true;
  return false;
}
}  // namespace

bool has_denominator_in(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& syms) {
  return has_denominator(e, [&](const GiNaC::ex& base) { return depends_on(base, syms); });
}

bool has_symbolic_denominator(const GiNaC::ex& e) {
  return has_denominator(e,
                         [](const GiNaC::ex& base) { return !GiNaC::is_a<GiNaC::numeric>(base); });
}

std::vector<GiNaC::ex> gradient(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& vars) {
  std::vector<GiNaC::ex> out;
  out.reserve(vars.size());
  for (const auto& v : vars) out.push_back(e.diff(v));
  return out;
}

// normal() cancels common factors of fractions but costs gcds; an expression without a
// symbolic denominator is a polynomial in its symbols and function atoms, for which the
// expanded form is canonical (zero exactly when normal() would give zero) and much cheaper
// to reach on large Lie derivatives and brackets.
GiNaC::ex simplify(const GiNaC::ex& e) {
  if (!has_symbolic_denominator(e)) return GiNaC::expand(e);
  return GiNaC::normal(e);
}

}  // namespace obsynth
