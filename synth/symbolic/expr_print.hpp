// Deterministic printing of expressions. GiNaC's own output order depends on hash values
// that change between runs, so operands are ordered here by their printed text.
// The plain form reads back through GiNaC's parser to the same expression.
#pragma once

#include <ginac/ginac.h>

#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace obsynth {

std::string to_string(const GiNaC::ex& e);
std::string to_latex(const GiNaC::ex& e);
std::vector<std::string> to_strings(const std::vector<GiNaC::ex>& v);

// While a PrintCache is in use (PrintCache::Use, scoped), to_string and to_latex remember the
// text of each expression object they print: a report rendered again (the checkpoints of a
// partial analysis, then the final report) prints each expression once. The cache holds the
// expressions, so no address is reused while it is cached.
class PrintCache {
 public:
  class Use {
   public:
    explicit Use(PrintCache& cache);
    ~Use();
    Use(const Use&) = delete;
    Use& operator=(const Use&) = delete;

   private:
    PrintCache* previous_;
  };

 private:
  friend std::string to_string(const GiNaC::ex& e);
  friend std::string to_latex(const GiNaC::ex& e);
  std::unordered_map<const GiNaC::basic*, std::pair<GiNaC::ex, std::string>> plain_, latex_;
};

}  // namespace obsynth
