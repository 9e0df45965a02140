// A small SVG plotter for simulation results: true vs estimated states, and the estimation
// error on a logarithmic scale.
#pragma once

#include <string>
#include <vector>

namespace obsynth {

struct TrajectoryPlot {
  std::string title;
  std::vector<std::string> names;  // state names
  std::vector<double> t;
  std::vector<std::vector<double>> x, xh;  // [sample][state]
};

std::string render_svg(const TrajectoryPlot& p);

}  // namespace obsynth
