// The C99 emitter: a header/source pair per model and design from the same ObserverSpec as
// the C++ emitter. Fixed-size arrays, a struct for the observer state, one scalar type
// (float or double by --precision), no heap, status as an enum, names prefixed
// <model>_<method>_. Supports the ode and linear_exact updates with identity or function
// init/estimate; the perfect observer (jets, Newton) is declined with a UserError.
#pragma once

#include "emit/emit_cxx.hpp"

namespace obsynth {

EmittedHeader emit_c_pair(const Analysis& a, const ObserverSpec& spec, const EmitOptions& opt);

}  // namespace obsynth
