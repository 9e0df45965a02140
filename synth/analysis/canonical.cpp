#include "analysis/canonical.hpp"

#include <fmt/format.h>

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
  cf.y = fresh_symbol(m, "y");
  if (m.p() != 1) {
    cf.not_applicable = fmt::format(
        "the canonical-form stages (r, frame, brackets, T, l) are single-output for now; this "
        "model has {} outputs",
        m.p());
    return cf;
  }
  if (ob.generic_rank < n) {
    cf.not_applicable =
        fmt::format("C1 fails: the generic observability rank is {} < n = {}", ob.generic_rank, n);
    return cf;
  }
  cf.applicable = true;
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
