// Test helpers: exact comparison of expressions and parsing expected answers.
#pragma once

#include <ginac/ginac.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "front/model.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth::testing {

// a == b as functions (symbolic proof, or the numeric verdict for transcendental identities).
inline ::testing::AssertionResult same(const GiNaC::ex& a, const GiNaC::ex& b) {
  const GiNaC::ex d = a - b;
  if (zero_test(d, SampleBoxes{}) != ZeroVerdict::nonzero) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << to_string(a) << " != " << to_string(b);
}

inline ::testing::AssertionResult same(const ExVec& a, const ExVec& b) {
  if (a.size() != b.size())
    return ::testing::AssertionFailure() << "sizes " << a.size() << " vs " << b.size();
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto r = same(a[i], b[i]);
    if (!r) return r << " (component " << i + 1 << ")";
  }
  return ::testing::AssertionSuccess();
}

// Parses an expression with GiNaC's parser over the given symbols (strict: unknown names fail).
inline GiNaC::ex parse_with(const std::string& text, const std::vector<GiNaC::symbol>& syms) {
  GiNaC::symtab table;
  for (const auto& s : syms) table[s.get_name()] = s;
  GiNaC::parser reader(table, true);
  return reader(text);
}

}  // namespace obsynth::testing
