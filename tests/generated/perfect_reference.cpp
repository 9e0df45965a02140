// Exact output jets for a generated perfect observer, computed by GiNaC independently of
// obsynth's Lie functions and designs: with the input held constant, y^(k) = L_F^k h with
// F = f + g(x, u), each Lie derivative taken here with GiNaC's diff. Writes a header with
// points x, inputs u and the jets, so that a test can check reconstruct(jets) = x.
// usage: perfect_reference <model.sym> <out.hpp>
#include <fmt/format.h>

#include <fstream>
#include <iostream>

#include "designs/spec.hpp"
#include "front/parse.hpp"
#include "reference_value.hpp"
#include "symbolic/zero_test.hpp"

using namespace obsynth;
using GiNaC::ex;

namespace {

std::string value(const ex& e, const GiNaC::exmap& at) {
  return testing::reference_value(e, at);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: perfect_reference <model.sym> <out.hpp>\n";
    return 2;
  }
  try {
    const Model m = load_model(argv[1]);
    const std::size_t n = m.n();
    ExVec F(n);
    for (std::size_t i = 0; i < n; ++i) F[i] = m.f[i] + m.g[i];
    std::vector<ex> jets{m.h[0]};
    for (std::size_t k = 1; k < n; ++k) {
      ex next = 0;
      for (std::size_t j = 0; j < n; ++j) next += jets.back().diff(m.states[j]) * F[j];
      jets.push_back(next);
    }
    SampleBoxes boxes = m.sample_boxes();
    for (const auto& s : m.states) {
      const Interval b = m.box(s);
      boxes.by_name[s.get_name()] = {b.lo / 2, b.hi / 2};
    }
    std::vector<GiNaC::symbol> syms(m.states);
    for (const auto& u : m.inputs) syms.push_back(u);
    const int points = 5;
    const auto pts = sample_points(syms, boxes, points, 0xBEEF);
    std::string X, U, Y;
    for (const auto& pt : pts) {
      std::vector<std::string> x, u, y;
      for (const auto& s : m.states) x.push_back(value(s, pt));
      for (const auto& s : m.inputs) u.push_back(value(s, pt));
      for (const auto& e : jets) y.push_back(value(e, pt));
      X += fmt::format("    {{{}}},\n", fmt::join(x, ", "));
      U += fmt::format("    {{{}}},\n", u.empty() ? "0.0" : fmt::format("{}", fmt::join(u, ", ")));
      Y += fmt::format("    {{{}}},\n", fmt::join(y, ", "));
    }
    const std::string cls = pascal_case(m.name);
    std::ofstream out(argv[2]);
    out << fmt::format(
        "// exact output jets computed by GiNaC for {}\n#pragma once\n#define OBSYNTH_NS {}\n"
        "#define OBSYNTH_CLASS {}Perfect\n#define OBSYNTH_NAME \"{}\"\nnamespace ref {{\n"
        "inline constexpr int kPoints = {};\ninline constexpr int kInputs = {};\n"
        "inline constexpr double x[{}][{}] = {{\n{}}};\ninline constexpr double u[{}][{}] = "
        "{{\n{}}};\ninline constexpr double yjet[{}][{}] = {{\n{}}};\n}}  // namespace ref\n",
        m.name, m.name, cls, m.name, points, m.m(), points, n, X, points,
        std::max<std::size_t>(m.m(), 1), U, points, n, Y);
  } catch (const std::exception& e) {
    std::cerr << "perfect_reference: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
