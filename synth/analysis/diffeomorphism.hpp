// The diffeomorphism stage of the canonical form: T with dT/dx [tau] = I and T(x0) = 0, and
// the output injection l_i = L_{f+g} T_i - T_{i-1} as a function of (u, y). Built in the
// polynomial ring when f, g, h and the frame live in it (GiNaC otherwise); every result is
// verified by substitution.
#pragma once

#include <optional>

#include "analysis/canonical.hpp"
#include "analysis/frame.hpp"
#include "front/model.hpp"

namespace obsynth {

// Fills cf.base_point, cf.T (and its kind, note, verdict) and cf.l; returns the polynomials
// of T when they were built in the ring.
void build_diffeomorphism(const Model& m, const FrameRing& fr, Budget& budget,
                          const CanonicalOptions& opt, CanonicalForm& cf);

// Base point: the origin (coordinate-wise, where the box holds 0), else the box centre, else a
// point of the box, where f, g, h and also_defined (the frame) are defined.
ExVec choose_base_point(const Model& m, const std::vector<ExVec>& also_defined = {});

}  // namespace obsynth
