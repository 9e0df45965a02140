// Symbols for a stage's own use (the measured output y, canonical coordinates z1..zn, jets),
// named so that they never take a name of the model. Stages bind, sample and print symbols by
// name, and a user may well call a state y or z1: the model keeps its names, the stage's
// symbols give way (stem, stem_, stem__, ...). Defined in model.cpp.
#pragma once

#include <string>
#include <vector>

#include "front/model.hpp"

namespace obsynth {

// A state, an input or a parameter (free or fixed) of the model has this name.
bool has_name(const Model& m, const std::string& name);
// stem, with '_' appended while it is a name of the model.
GiNaC::symbol fresh_symbol(const Model& m, std::string stem);
// stem<first>..stem<first+count-1>, with '_' appended to the stem while any of them is a name
// of the model (z1, z2 or z_1, z_2: never a mixture).
std::vector<GiNaC::symbol> fresh_symbols(const Model& m, std::string stem, std::size_t count,
                                         std::size_t first = 1);
// The measured outputs: y (one output) or y1..yp.
std::vector<GiNaC::symbol> measurement_symbols(const Model& m);

}  // namespace obsynth
