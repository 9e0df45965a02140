// The frame stage of the canonical form: r = adj(O) e_n / det O and
// tau_1 = r, tau_{k+1} = [-f, tau_k] (design.md §1), in the polynomial ring when f, g and r
// live in it, else with GiNaC.
#pragma once

#include <optional>
#include <vector>

#include "analysis/canonical.hpp"
#include "analysis/observability.hpp"
#include "foundation/budget.hpp"
#include "front/model.hpp"
#include "symbolic/poly.hpp"

namespace obsynth {

// The frame's fields as ring elements, shared by the later stages (conditions append g; the
// diffeomorphism reads tau_n). `ring` is empty when the model is outside the ring.
struct FrameRing {
  std::optional<PolyRing> ring;
  std::vector<std::vector<Poly>> fields;                  // tau_1..tau_n (then g)
  std::vector<std::vector<std::vector<Poly>>> jacobians;  // their Jacobians
  std::vector<std::vector<Poly>> jacobian(const std::vector<Poly>& v) const;
  void add_field(std::vector<Poly> v);
};

// Fills cf.r and cf.frame; returns the ring data (empty ring on the GiNaC path).
FrameRing compute_frame(const Model& m, const Observability& ob, Budget& budget, CanonicalForm& cf);

}  // namespace obsynth
