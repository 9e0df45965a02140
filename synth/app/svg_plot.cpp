#include "app/svg_plot.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace obsynth {

namespace {

const char* const kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd",
                               "#ff7f0e", "#8c564b", "#e377c2", "#17becf"};

struct Panel {
  double x0, y0, w, h;  // pixel box
  double tmin, tmax, vmin, vmax;
  double px(double t) const { return x0 + (t - tmin) / (tmax - tmin) * w; }
  double py(double v) const { return y0 + h - (v - vmin) / (vmax - vmin) * h; }
};

std::string escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<')
      o += "&lt;";
    else if (c == '>')
      o += "&gt;";
    else if (c == '&')
      o += "&amp;";
    else
      o += c;
  }
  return o;
}

// "Nice" tick values covering [lo, hi].
std::vector<double> ticks(double lo, double hi, int target) {
  const double span = hi - lo;
  if (!(span > 0)) return {lo};
  const double raw = span / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  std::vector<double> out;
  for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * span; v += step)
    out.push_back(std::fabs(v) < 1e-12 * span ? 0.0 : v);
  return out;
}

std::string axes(const Panel& p, const std::string& ylabel, bool log_y) {
  std::string s = fmt::format(
      "<rect x='{:.1f}' y='{:.1f}' width='{:.1f}' height='{:.1f}' fill='white' stroke='#444'/>\n",
      p.x0, p.y0, p.w, p.h);
  for (double t : ticks(p.tmin, p.tmax, 8)) {
    s += fmt::format("<line x1='{0:.1f}' y1='{1:.1f}' x2='{0:.1f}' y2='{2:.1f}' stroke='#ddd'/>\n",
                     p.px(t), p.y0, p.y0 + p.h);
    s +=
        fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='11' text-anchor='middle'>{:g}</text>\n",
                    p.px(t), p.y0 + p.h + 14, t);
  }
  if (log_y) {
    for (int e = static_cast<int>(std::ceil(p.vmin)); e <= static_cast<int>(std::floor(p.vmax));
         ++e) {
      s +=
          fmt::format("<line x1='{0:.1f}' y1='{1:.1f}' x2='{2:.1f}' y2='{1:.1f}' stroke='#ddd'/>\n",
                      p.x0, p.py(e), p.x0 + p.w);
      s += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='11' text-anchor='end'>1e{}</text>\n",
                       p.x0 - 4, p.py(e) + 4, e);
    }
  } else {
    for (double v : ticks(p.vmin, p.vmax, 6)) {
      s +=
          fmt::format("<line x1='{0:.1f}' y1='{1:.1f}' x2='{2:.1f}' y2='{1:.1f}' stroke='#ddd'/>\n",
                      p.x0, p.py(v), p.x0 + p.w);
      s += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='11' text-anchor='end'>{:g}</text>\n",
                       p.x0 - 4, p.py(v) + 4, v);
    }
  }
  s += fmt::format(
      "<text x='{:.1f}' y='{:.1f}' font-size='12' text-anchor='middle' transform='rotate(-90 "
      "{:.1f} {:.1f})'>{}</text>\n",
      p.x0 - 48, p.y0 + p.h / 2, p.x0 - 48, p.y0 + p.h / 2, escape(ylabel));
  s += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='12' text-anchor='middle'>t</text>\n",
                   p.x0 + p.w / 2, p.y0 + p.h + 30);
  return s;
}

std::string polyline(const Panel& p, const std::vector<double>& t, const std::vector<double>& v,
                     const char* color, bool dashed) {
  std::string pts;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (!std::isfinite(v[i])) continue;
    const double y = std::clamp(v[i], p.vmin, p.vmax);
    pts += fmt::format("{:.1f},{:.1f} ", p.px(t[i]), p.py(y));
  }
  return fmt::format("<polyline fill='none' stroke='{}' stroke-width='1.6'{} points='{}'/>\n",
                     color, dashed ? " stroke-dasharray='6 4'" : "", pts);
}

// The sample indices plotted: at most ~1500 per curve, always the last one.
std::vector<std::size_t> plotted_indices(std::size_t N) {
  const std::size_t stride = std::max<std::size_t>(1, N / 1500);
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < N; i += stride) idx.push_back(i);
  if (N && idx.back() != N - 1) idx.push_back(N - 1);
  return idx;
}

// The panels' value ranges: the states (both curves, padded later) and log10 of the error,
// 16 decades at most below its ceiling.
struct Ranges {
  double vmin = 1e300, vmax = -1e300, emin = 0, emax = -1e300;
};

Ranges value_ranges(const TrajectoryPlot& p, const std::vector<std::size_t>& idx) {
  Ranges r;
  const std::size_t n = p.names.size();
  for (auto i : idx)
    for (std::size_t k = 0; k < n; ++k) {
      for (double v : {p.x[i][k], p.xh[i][k]})
        if (std::isfinite(v)) {
          r.vmin = std::min(r.vmin, v);
          r.vmax = std::max(r.vmax, v);
        }
      const double e = std::fabs(p.x[i][k] - p.xh[i][k]);
      if (e > 0 && std::isfinite(e)) r.emax = std::max(r.emax, std::log10(e));
    }
  if (!(r.vmax > r.vmin)) {
    r.vmin -= 1;
    r.vmax += 1;
  }
  r.emax = std::ceil(std::max(r.emax, -15.0) + 0.5);
  r.emin = std::max(r.emax - 16.0, -17.0);
  return r;
}

// State k's curves (true solid, estimate dashed; the error below) and its legend entry.
std::string state_curves(const TrajectoryPlot& p, std::size_t k,
                         const std::vector<std::size_t>& idx, const std::vector<double>& t,
                         const Panel& top, const Panel& bottom, double emin, double W) {
  const char* c = kColors[k % 8];
  std::vector<double> xv, hv, ev;
  for (auto i : idx) {
    xv.push_back(p.x[i][k]);
    hv.push_back(p.xh[i][k]);
    const double e = std::fabs(p.x[i][k] - p.xh[i][k]);
    ev.push_back(e > 0 ? std::log10(e) : emin);
  }
  std::string s = polyline(top, t, xv, c, false);
  s += polyline(top, t, hv, c, true);
  s += polyline(bottom, t, ev, c, false);
  const double ly = 70 + 22.0 * static_cast<double>(k);
  s += fmt::format("<line x1='{}' y1='{:.1f}' x2='{}' y2='{:.1f}' stroke='{}' stroke-width='2'/>",
                   W - 145, ly, W - 120, ly, c);
  s += fmt::format(
      "<line x1='{}' y1='{:.1f}' x2='{}' y2='{:.1f}' stroke='{}' stroke-width='2' "
      "stroke-dasharray='6 4'/>",
      W - 115, ly, W - 90, ly, c);
  s += fmt::format("<text x='{}' y='{:.1f}' font-size='12'>{}</text>\n", W - 84, ly + 4,
                   escape(p.names[k]));
  return s;
}

}  // namespace

std::string render_svg(const TrajectoryPlot& p) {
  const double W = 960, H = 720;
  const std::vector<std::size_t> idx = plotted_indices(p.t.size());
  std::vector<double> t;
  for (auto i : idx) t.push_back(p.t[i]);
  const std::size_t n = p.names.size();
  const Ranges r = value_ranges(p, idx);
  const double pad = 0.05 * (r.vmax - r.vmin);
  const double tmax = t.empty() ? 1 : std::max(t.back(), t.front() + 1e-12);
  Panel top{80, 50, W - 240, 280, t.empty() ? 0 : t.front(), tmax, r.vmin - pad, r.vmax + pad};
  Panel bottom{80, 390, W - 240, 270, top.tmin, tmax, r.emin, r.emax};

  std::string s = fmt::format(
      "<svg xmlns='http://www.w3.org/2000/svg' width='{}' height='{}' viewBox='0 0 {} {}' "
      "font-family='sans-serif'>\n",
      W, H, W, H);
  s += fmt::format(
      "<rect width='100%' height='100%' fill='#fafafa'/>\n<text x='{}' y='28' font-size='16' "
      "text-anchor='middle'>{}</text>\n",
      W / 2, escape(p.title));
  s += axes(top, "state", false);
  s += axes(bottom, "|x - x_hat| (log scale)", true);
  for (std::size_t k = 0; k < n; ++k) s += state_curves(p, k, idx, t, top, bottom, r.emin, W);
  s += fmt::format("<text x='{}' y='{}' font-size='11' fill='#555'>solid: true</text>\n", W - 145,
                   60 + 22 * n + 20);
  s += fmt::format("<text x='{}' y='{}' font-size='11' fill='#555'>dashed: estimate</text>\n",
                   W - 145, 60 + 22 * n + 36);
  s += "</svg>\n";
  return s;
}

}  // namespace obsynth
