// A small SVG plotter for simulation results: one panel per state (true vs estimated, its own
// y-axis, the domain box marked), and the relative estimation error of every state on a
// logarithmic scale. Deterministic and self-contained (no scripts, no external resources).
#pragma once

#include <string>
#include <vector>

namespace obsynth {

// A state's domain box: drawn when declared; its width scales the relative error either way.
struct StateBox {
  double lo = -2, hi = 2;
  bool declared = false;
};

struct TrajectoryPlot {
  std::string title;
  std::string note;                // a line under the title (e.g. the plant's own parameters)
  std::vector<std::string> names;  // state names
  std::vector<double> t;
  std::vector<std::vector<double>> x, xh;  // [sample][state]
  // One per state; empty: the error is scaled by the range of the true state.
  std::vector<StateBox> boxes;
  // Why the run ended early (e.g. "the observer left the finite numbers at t = 0.71"); marked
  // at the last sample. A non-finite sample in x or xh also ends the plotted history there.
  std::string stopped;
};

std::string render_svg(const TrajectoryPlot& p);

}  // namespace obsynth
