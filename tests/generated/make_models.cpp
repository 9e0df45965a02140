// Writes the constructed closed-loop test models (.sym) into a directory:
// chain<n>_stable (closed-form T^-1) and chain<n>_newton (T^-1 by runtime Newton).
#include <fstream>
#include <iostream>

#include "support/construct.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: make_models <dir>\n";
    return 2;
  }
  using namespace obsynth::testing;
  for (std::size_t n = 2; n <= 8; ++n)
    for (Flavor f : {Flavor::stable, Flavor::stable_newton}) {
      const Constructed c = linearizable_chain(n, f);
      std::ofstream out(std::string(argv[1]) + "/" + c.model.name + ".sym");
      out << to_sym(c.model);
      if (!out) return 1;
    }
  return 0;
}
