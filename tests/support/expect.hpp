// Test helpers: an independent oracle for identities between expressions, and parsing expected
// answers.
//
// The oracle shares no code with obsynth: it never calls obsynth's zero test, simplifier or
// evaluators, only GiNaC's own expand and CLN's arbitrary-precision evaluation. a == b holds
// when the expanded difference is the number zero, or when at every one of kOraclePoints exact
// rational points |a - b| <= 1e-40 (1 + |a| + |b|), evaluated to 50 digits. Points lie in a box
// per symbol: the model's domain box when one is given, else [1/5, 9/5] (positive, away from 0
// and 1, so that roots and logarithms of plain symbols stay real). A point where either side
// cannot be evaluated (a pole) is skipped; fewer than kOracleMinPoints evaluated points fail.
#pragma once

#include <ginac/ginac.h>
#include <gtest/gtest.h>

#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "front/model.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth::testing {

constexpr int kOraclePoints = 5;
constexpr int kOracleMinPoints = 3;

/// A closed interval [lo, hi] of exact rationals per symbol name.
using OracleBox = std::map<std::string, std::pair<GiNaC::numeric, GiNaC::numeric>>;

/// The domain box of a model's states, inputs and free parameters, by name.
inline OracleBox oracle_box(const Model& m) {
  OracleBox box;
  for (const auto& s : m.all_symbols()) {
    const Interval iv = m.box(s);
    box[s.get_name()] = {iv.lo, iv.hi};
  }
  return box;
}

namespace detail {

// The symbols of e by name (GiNaC traversal, sorted so that points do not depend on hashing).
inline void collect_symbols(const GiNaC::ex& e, std::map<std::string, GiNaC::ex>& out) {
  if (GiNaC::is_a<GiNaC::symbol>(e)) {
    out.emplace(GiNaC::ex_to<GiNaC::symbol>(e).get_name(), e);
    return;
  }
  for (std::size_t i = 0; i < e.nops(); ++i) collect_symbols(e.op(i), out);
}

// Point k: symbol i at lo + t (hi - lo), t = ((37 i + 53 k + 11) mod 97 + 1) / 99 in (0, 1).
inline GiNaC::exmap oracle_point(const std::map<std::string, GiNaC::ex>& symbols,
                                 const OracleBox& box, int k) {
  GiNaC::exmap at;
  long i = 0;
  for (const auto& [name, sym] : symbols) {
    const auto it = box.find(name);
    const GiNaC::numeric lo = it != box.end() ? it->second.first : GiNaC::numeric(1, 5);
    const GiNaC::numeric hi = it != box.end() ? it->second.second : GiNaC::numeric(9, 5);
    const GiNaC::numeric t((37 * i++ + 53 * k + 11) % 97 + 1, 99);
    at[sym] = lo + t * (hi - lo);
  }
  return at;
}

// 50-digit value of e at the point; false when it is not a number there (a pole).
inline bool value_at(const GiNaC::ex& e, const GiNaC::exmap& at, GiNaC::numeric& out) {
  try {
    const GiNaC::ex v = GiNaC::evalf(e.subs(at));
    if (!GiNaC::is_a<GiNaC::numeric>(v)) return false;
    out = GiNaC::ex_to<GiNaC::numeric>(v);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

inline std::string point_text(const GiNaC::exmap& at) {
  std::ostringstream out;
  for (const auto& [sym, value] : at) out << sym << " = " << value << "; ";
  return out.str();
}

}  // namespace detail

/// a == b as functions, judged independently of obsynth (see the file comment).
inline ::testing::AssertionResult same(const GiNaC::ex& a, const GiNaC::ex& b,
                                       const OracleBox& box = {}) {
  if (GiNaC::expand(a - b).is_zero()) return ::testing::AssertionSuccess();
  std::map<std::string, GiNaC::ex> symbols;
  detail::collect_symbols(a, symbols);
  detail::collect_symbols(b, symbols);
  const long saved = GiNaC::Digits;
  GiNaC::Digits = 50;
  const GiNaC::numeric tolerance("1e-40");
  int evaluated = 0;
  ::testing::AssertionResult result = ::testing::AssertionSuccess();
  for (int k = 0; k < kOraclePoints && result; ++k) {
    const GiNaC::exmap at = detail::oracle_point(symbols, box, k);
    GiNaC::numeric av, bv;
    if (!detail::value_at(a, at, av) || !detail::value_at(b, at, bv)) continue;
    ++evaluated;
    const GiNaC::numeric gap = GiNaC::abs(av - bv) / (1 + GiNaC::abs(av) + GiNaC::abs(bv));
    if (gap > tolerance)
      result = ::testing::AssertionFailure() << to_string(a) << " != " << to_string(b) << ": " << av
                                             << " vs " << bv << " at " << detail::point_text(at);
  }
  GiNaC::Digits = saved;
  if (result && evaluated < kOracleMinPoints)
    return ::testing::AssertionFailure()
           << to_string(a) << " vs " << to_string(b) << ": evaluated at only " << evaluated
           << " of " << kOraclePoints << " points";
  return result;
}

inline ::testing::AssertionResult same(const ExVec& a, const ExVec& b, const OracleBox& box = {}) {
  if (a.size() != b.size())
    return ::testing::AssertionFailure() << "sizes " << a.size() << " vs " << b.size();
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto r = same(a[i], b[i], box);
    if (!r) return r << " (component " << i + 1 << ")";
  }
  return ::testing::AssertionSuccess();
}

/// The derivative of e along the vector field v, sum_i de/dx_i v_i, by GiNaC's diff alone
/// (independent of obsynth's Lie derivatives, for oracles).
inline GiNaC::ex derivative_along(const GiNaC::ex& e, const ExVec& v,
                                  const std::vector<GiNaC::symbol>& x) {
  GiNaC::ex sum = 0;
  for (std::size_t i = 0; i < x.size(); ++i) sum += e.diff(x[i]) * v[i];
  return sum;
}

// Parses an expression with GiNaC's parser over the given symbols (strict: unknown names fail).
inline GiNaC::ex parse_with(const std::string& text, const std::vector<GiNaC::symbol>& syms) {
  GiNaC::symtab table;
  for (const auto& s : syms) table[s.get_name()] = s;
  GiNaC::parser reader(table, true);
  return reader(text);
}

}  // namespace obsynth::testing
