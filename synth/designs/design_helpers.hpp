// Small builders every design file uses: a generated function from its parts, and the text
// of an exact matrix for report rows.
#pragma once

#include <fmt/format.h>
#include <ginac/ginac.h>

#include <string>
#include <utility>
#include <vector>

#include "analysis/conditions.hpp"
#include "designs/registry.hpp"
#include "designs/spec.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

// A vector-valued generated function (out_rows = outputs.size(), one column).
inline GeneratedFunction make_function(const std::string& name, const std::string& doc,
                                       std::vector<FunctionArg> args, ExVec outputs,
                                       const std::string& out_type) {
  GeneratedFunction f;
  f.name = name;
  f.doc = doc;
  f.args = std::move(args);
  f.out_rows = outputs.size();
  f.outputs = std::move(outputs);
  f.out_type = out_type;
  return f;
}

// "[[a, b], [c, d]]", row by row.
inline std::string matrix_text(const GiNaC::matrix& M) {
  std::vector<std::string> rows;
  for (unsigned r = 0; r < M.rows(); ++r) {
    std::vector<std::string> row;
    for (unsigned c = 0; c < M.cols(); ++c) row.push_back(to_string(M(r, c)));
    rows.push_back(fmt::format("[{}]", fmt::join(row, ", ")));
  }
  return fmt::format("[{}]", fmt::join(rows, ", "));
}

// A key for caching a design's search between applies() and build(): the model's maps, its
// boxes, and its symbols' hashes (symbols compare by identity: a model loaded again has new ones).
// The observability matrix of a linear pair (A, c), c one row: rows c, c A, ..., c A^(n-1).
inline GiNaC::matrix linear_observability_matrix(const GiNaC::matrix& A, const GiNaC::matrix& c) {
  const unsigned n = A.rows();
  GiNaC::matrix O(n, n);
  GiNaC::matrix row = c;
  for (unsigned k = 0; k < n; ++k) {
    for (unsigned j = 0; j < n; ++j) O(k, j) = row(0, j);
    row = row.mul(A);
  }
  return O;
}

// A design exact by the observer canonical form: rigorous when the brackets, T and l(u, y) are
// proved symbolically; partial (numeric) when a zero among them is only numeric, with the list.
struct ExactnessClaim {
  std::string proved_lead;    // "<proved_lead>: <claim>"
  std::string unproven_lead;  // "<unproven_lead>, but unproven: <list>; <claim> only if these hold"
  std::string claim;
  std::string rigorous;  // the guarantee line when proved
  std::string partial;   // "<partial>, not proved: <list>"
};

inline void set_exactness(Verdict& v, const CanonicalForm& cf, const ExactnessClaim& c) {
  const std::vector<std::string> unproven = unproven_steps(cf);
  if (unproven.empty()) {
    v.reasons.push_back(c.proved_lead + ": " + c.claim);
    v.guarantee = Guarantee::rigorous;
    v.guarantee_text = c.rigorous;
    return;
  }
  const std::string list = fmt::format("{}", fmt::join(unproven, "; "));
  v.reasons.push_back(
      fmt::format("{}, but unproven: {}; {} only if these hold", c.unproven_lead, list, c.claim));
  v.guarantee = Guarantee::partial;
  v.guarantee_text = fmt::format("{}, not proved: {}", c.partial, list);
}

}  // namespace obsynth
