#include "analysis/canonical.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <functional>

#include "analysis/conditions.hpp"
#include "analysis/diffeomorphism.hpp"
#include "analysis/frame.hpp"
#include "analysis/inverse.hpp"
#include "front/fresh_names.hpp"

namespace obsynth {

const char* completeness_name(Completeness c) {
  switch (c) {
    case Completeness::global:
      return "global";
    case Completeness::local:
      return "local";
    case Completeness::unknown:
      return "unknown";
  }
  return "unknown";
}

const char* availability_name(Availability a) {
  switch (a) {
    case Availability::symbolic:
      return "symbolic";
    case Availability::numeric:
      return "numeric";
    case Availability::none:
      return "none";
  }
  return "none";
}

std::size_t CanonicalForm::block_start(std::size_t i) const {
  std::size_t k = 0;
  for (std::size_t b = 0; b < i; ++b) k += blocks[b];
  return k;
}

std::size_t CanonicalForm::block_end(std::size_t i) const {
  return block_start(i) + blocks[i] - 1;
}

std::size_t CanonicalForm::block_of(std::size_t k) const {
  std::size_t i = 0;
  for (std::size_t end = blocks.empty() ? 0 : blocks[0]; k >= end && i + 1 < blocks.size();)
    end += blocks[++i];
  return i;
}

std::string CanonicalForm::tau_name(std::size_t k) const {
  if (blocks.size() <= 1) return fmt::format("tau_{}", k + 1);
  const std::size_t i = block_of(k);
  return fmt::format("tau_{{{},{}}}", i + 1, k - block_start(i) + 1);
}

ExVec frame_column_major(const CanonicalForm& cf) {
  ExVec flat;
  for (const auto& t : cf.frame) flat.insert(flat.end(), t.begin(), t.end());
  return flat;
}

CanonicalForm analyse_canonical(const Model& m, const Observability& ob, Budget& budget,
                                const CanonicalOptions& opt, CanonicalForm* progress) {
  CanonicalForm local;
  CanonicalForm& cf = progress ? *progress : local;
  const std::size_t n = m.n();
  cf.z = fresh_symbols(m, "z", n);
  cf.y = measurement_symbols(m);
  if (ob.generic_rank < n || ob.selected.size() != n) {
    cf.not_applicable =
        fmt::format("C1 fails: the generic observability rank is {} < n = {}", ob.generic_rank, n);
    return cf;
  }
  cf.blocks = m.p() == 1 ? std::vector<std::size_t>{n} : ob.indices;
  for (std::size_t i = 0; i < cf.blocks.size(); ++i)
    if (cf.blocks[i] == 0) {
      cf.not_applicable = fmt::format(
          "output {} adds nothing to the observability rank (index 0): the block observer "
          "canonical form needs every output to start a block; drop it or measure another state",
          i + 1);
      return cf;
    }
  cf.applicable = true;
  if (std::adjacent_find(cf.blocks.begin(), cf.blocks.end(), std::not_equal_to<>()) !=
      cf.blocks.end())
    cf.frame_note = fmt::format(
        "the observability indices differ ({}): r_i is the dual field O r_i = e_(i, k_i - 1); a "
        "frame corrected along the longer blocks by functions of y (Krener-Respondek) is not "
        "searched, so a failing condition refutes this frame only",
        fmt::join(cf.blocks, ", "));
  FrameRing fr = compute_frame(m, ob, budget, cf);
  check_conditions(m, fr, budget, opt, cf);
  if (!cf.linearizable) {
    cf.T_note = cf.T_inverse_note = cf.l_note =
        "not computed: the bracket conditions fail, no observer canonical form exists";
    return cf;
  }
  StageScope stage(budget, "diffeomorphism");
  build_diffeomorphism(m, fr, budget, opt, cf);
  if (cf.T_kind == Availability::symbolic) {
    build_inverse(m, budget, opt, cf);
  } else {
    cf.T_inverse_kind = Availability::numeric;
    cf.T_inverse_note = "runtime Newton solve with [tau] as inverse Jacobian";
  }
  return cf;
}

}  // namespace obsynth
