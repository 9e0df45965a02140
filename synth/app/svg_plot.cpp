#include "app/svg_plot.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace obsynth {

namespace {

const char* const kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd",
                               "#ff7f0e", "#8c564b", "#e377c2", "#17becf"};

// Layout (pixels).
constexpr double kWidth = 960, kLeft = 96, kRight = 150, kTop = 64;
constexpr double kGap = 34, kErrorHeight = 230;
// A state panel's axis extends at most this many reference widths beyond the true trajectory
// and the domain box: a peaking or diverging estimate is clipped there (and said so) instead of
// flattening the true curve.
constexpr double kClipWidths = 3;
// The relative error axis ends at 10^kLogCap box widths (a diverging run is clipped there, so
// the history below stays readable), and spans at most kLogSpan decades.
constexpr double kLogCap = 3, kLogSpan = 16;
constexpr std::size_t kMaxPlotted = 1200;

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
    else if (c == '\'')
      o += "&apos;";
    else
      o += c;
  }
  return o;
}

// "Nice" tick values covering [lo, hi] (integer multiples of the step: no drift).
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
  for (double k = std::ceil(lo / step); k * step <= hi + 1e-9 * span; k += 1)
    out.push_back(std::fabs(k * step) < 1e-12 * span ? 0.0 : k * step);
  return out;
}

// The samples drawn: the history up to the first non-finite one, at most ~kMaxPlotted of them,
// always the last finite one.
struct Samples {
  std::vector<std::size_t> idx;
  bool cut = false;  // a non-finite sample ended the history
};

bool finite_row(const std::vector<double>& a, const std::vector<double>& b) {
  return std::all_of(a.begin(), a.end(), [](double v) { return std::isfinite(v); }) &&
         std::all_of(b.begin(), b.end(), [](double v) { return std::isfinite(v); });
}

Samples plotted_samples(const TrajectoryPlot& p) {
  Samples s;
  std::size_t end = 0;
  while (end < p.t.size() && std::isfinite(p.t[end]) && finite_row(p.x[end], p.xh[end])) ++end;
  s.cut = end < p.t.size();
  const std::size_t stride = std::max<std::size_t>(1, end / kMaxPlotted);
  for (std::size_t i = 0; i < end; i += stride) s.idx.push_back(i);
  if (end && s.idx.back() != end - 1) s.idx.push_back(end - 1);
  return s;
}

// A state's reference interval: its declared box joined with the bulk of the true trajectory
// (the 5 % to 95 % quantiles over time, so that a plant that blows up in its last samples does
// not set the scale); `scale` is the width the relative error is divided by.
struct StateScale {
  double lo, hi, scale;
  bool declared;
};

StateScale state_scale(const TrajectoryPlot& p, const Samples& s, std::size_t k) {
  std::vector<double> v;
  for (auto i : s.idx) v.push_back(p.x[i][k]);
  std::sort(v.begin(), v.end());
  double lo = v.empty() ? 0 : v[v.size() / 20],
         hi = v.empty() ? 0 : v[v.size() - 1 - v.size() / 20];
  const bool has_box = p.boxes.size() == p.names.size();
  const StateBox box = has_box ? p.boxes[k] : StateBox{lo, hi, false};
  double scale = box.hi - box.lo;
  if (box.declared) {
    lo = std::min(lo, box.lo);
    hi = std::max(hi, box.hi);
  }
  if (!(scale > 0)) scale = hi > lo ? hi - lo : std::max(1.0, std::fabs(lo));
  return {lo, hi, scale, box.declared};
}

std::string num(double v) {
  return fmt::format("{:.4g}", v);
}

std::string time_axis(const Panel& p, bool labels) {
  std::string s;
  for (double t : ticks(p.tmin, p.tmax, 8)) {
    s += fmt::format(
        "<line x1='{0:.1f}' y1='{1:.1f}' x2='{0:.1f}' y2='{2:.1f}' stroke='#e4e4e4'/>\n", p.px(t),
        p.y0, p.y0 + p.h);
    if (labels)
      s +=
          fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='11' text-anchor='middle'>{}</text>\n",
                      p.px(t), p.y0 + p.h + 14, num(t));
  }
  return s;
}

// A horizontal grid line with its label; data-value holds the axis value (log10 on a log axis).
std::string value_tick(const Panel& p, double v, const std::string& label) {
  return fmt::format(
      "<line class='ygrid' data-value='{:.6g}' x1='{:.1f}' y1='{:.1f}' x2='{:.1f}' y2='{:.1f}' "
      "stroke='#e4e4e4'/>\n<text x='{:.1f}' y='{:.1f}' font-size='11' "
      "text-anchor='end'>{}</text>\n",
      v, p.x0, p.py(v), p.x0 + p.w, p.py(v), p.x0 - 4, p.py(v) + 4, label);
}

std::string rotated_label(const Panel& p, const std::string& text, const char* color) {
  const double x = p.x0 - 62, y = p.y0 + p.h / 2;
  return fmt::format(
      "<text x='{0:.1f}' y='{1:.1f}' font-size='13' fill='{3}' text-anchor='middle' "
      "transform='rotate(-90 {0:.1f} {1:.1f})'>{2}</text>\n",
      x, y, escape(text), color);
}

std::string polyline(const Panel& p, const std::vector<double>& t, const std::vector<double>& v,
                     const char* cls, const char* color, bool dashed) {
  std::string pts;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double y = std::isnan(v[i]) ? p.vmin : std::clamp(v[i], p.vmin, p.vmax);
    pts += fmt::format("{:.1f},{:.1f} ", p.px(t[i]), p.py(y));
  }
  if (!pts.empty()) pts.pop_back();
  return fmt::format(
      "<polyline class='{}' fill='none' stroke='{}' stroke-width='1.6'{} points='{}'/>\n", cls,
      color, dashed ? " stroke-dasharray='6 4'" : "", pts);
}

// The end of a run that stopped early: a vertical line at the last sample, labelled.
std::string stop_marker(const Panel& p, const std::string& why, bool label) {
  const double x = p.px(p.tmax);
  std::string s = fmt::format(
      "<line class='diverged' x1='{0:.1f}' y1='{1:.1f}' x2='{0:.1f}' y2='{2:.1f}' "
      "stroke='#c00000' stroke-width='2' stroke-dasharray='3 3'/>\n",
      x, p.y0, p.y0 + p.h);
  if (label)
    s += fmt::format(
        "<text x='{:.1f}' y='{:.1f}' font-size='11' fill='#c00000' text-anchor='end'>{}</text>\n",
        x - 8, p.y0 + p.h - 8, escape(why));
  return s;
}

// The linear axis of state k's panel: the true curve, the box and the estimate, with the
// estimate clipped kClipWidths reference widths beyond the true curve and the box.
struct StateAxis {
  double vmin, vmax, peak;  // peak: the largest |value| cut off (0: none)
};

StateAxis state_axis(const TrajectoryPlot& p, const Samples& s, std::size_t k,
                     const StateScale& r) {
  const double ref = r.hi > r.lo ? r.hi - r.lo : r.scale;
  const double lo_cap = r.lo - kClipWidths * ref, hi_cap = r.hi + kClipWidths * ref;
  StateAxis a{r.lo, r.hi, 0};
  for (auto i : s.idx)
    for (double v : {p.x[i][k], p.xh[i][k]}) {
      if (v < lo_cap || v > hi_cap) a.peak = std::max(a.peak, std::fabs(v));
      a.vmin = std::min(a.vmin, std::max(v, lo_cap));
      a.vmax = std::max(a.vmax, std::min(v, hi_cap));
    }
  if (!(a.vmax > a.vmin)) {
    a.vmin -= r.scale / 2;
    a.vmax += r.scale / 2;
  }
  const double pad = 0.05 * (a.vmax - a.vmin);
  return {a.vmin - pad, a.vmax + pad, a.peak};
}

std::string domain_marks(const Panel& p, const StateBox& box) {
  const double top = p.py(std::min(box.hi, p.vmax)), bottom = p.py(std::max(box.lo, p.vmin));
  std::string s;
  if (bottom > top)
    s += fmt::format(
        "<rect class='domain-band' x='{:.1f}' y='{:.1f}' width='{:.1f}' height='{:.1f}' "
        "fill='#e9f2e4'/>\n",
        p.x0, top, p.w, bottom - top);
  for (double v : {box.lo, box.hi})
    if (v >= p.vmin && v <= p.vmax)
      s += fmt::format(
          "<line class='domain' data-value='{:.6g}' x1='{:.1f}' y1='{:.1f}' x2='{:.1f}' "
          "y2='{:.1f}' stroke='#5a8f3c' stroke-width='1.2' stroke-dasharray='8 3 2 3'/>\n",
          v, p.x0, p.py(v), p.x0 + p.w, p.py(v));
  return s;
}

std::string state_panel(const TrajectoryPlot& p, const Samples& s, const std::vector<double>& t,
                        std::size_t k, const Panel& frame) {
  const StateScale r = state_scale(p, s, k);
  const StateAxis a = state_axis(p, s, k, r);
  Panel pn = frame;
  pn.vmin = a.vmin;
  pn.vmax = a.vmax;
  const char* c = kColors[k % 8];
  std::string g = fmt::format("<g class='state-panel' data-state='{}'>\n", escape(p.names[k]));
  g += fmt::format(
      "<rect x='{:.1f}' y='{:.1f}' width='{:.1f}' height='{:.1f}' fill='white' stroke='none'/>\n",
      pn.x0, pn.y0, pn.w, pn.h);
  const bool boxed = r.declared && p.boxes.size() == p.names.size();
  if (boxed) g += domain_marks(pn, p.boxes[k]);
  g += time_axis(pn, true);
  for (double v : ticks(pn.vmin, pn.vmax, 5)) g += value_tick(pn, v, num(v));
  std::vector<double> xv, hv;
  for (auto i : s.idx) {
    xv.push_back(p.x[i][k]);
    hv.push_back(p.xh[i][k]);
  }
  g += polyline(pn, t, xv, "true", c, false);
  g += polyline(pn, t, hv, "estimate", c, true);
  g += fmt::format(
      "<rect x='{:.1f}' y='{:.1f}' width='{:.1f}' height='{:.1f}' fill='none' stroke='#444'/>\n",
      pn.x0, pn.y0, pn.w, pn.h);
  g += rotated_label(pn, p.names[k], c);
  const double lx = pn.x0 + pn.w + 10;
  g += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='12' fill='{}'>{}</text>\n", lx,
                   pn.y0 + 14, c, escape(p.names[k]));
  if (boxed)
    g += fmt::format(
        "<text x='{:.1f}' y='{:.1f}' font-size='11' fill='#5a8f3c'>domain [{}, {}]</text>\n", lx,
        pn.y0 + 30, num(p.boxes[k].lo), num(p.boxes[k].hi));
  if (a.peak > 0)
    g += fmt::format(
        "<text class='clipped' x='{:.1f}' y='{:.1f}' font-size='11' fill='#c00000'>axis clipped: "
        "|{}| reaches {}</text>\n",
        pn.x0 + 6, pn.y0 + 14, escape(p.names[k]), num(a.peak));
  if (!p.stopped.empty() || s.cut) g += stop_marker(pn, "", false);
  return g + "</g>\n";
}

// log10 of the relative error of state k at sample i; +inf when it overflowed, -inf at zero.
double log_relative_error(const TrajectoryPlot& p, std::size_t i, std::size_t k, double scale) {
  const double e = std::fabs(p.x[i][k] - p.xh[i][k]) / scale;
  return e > 0 ? std::log10(e) : -std::numeric_limits<double>::infinity();
}

// The log axis: up to kLogCap decades above the box width, kLogSpan decades at most, down to
// the smallest error drawn.
std::pair<double, double> log_range(const std::vector<std::vector<double>>& logs) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& series : logs)
    for (double v : series)
      if (std::isfinite(v)) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      } else if (v > 0) {
        hi = std::max(hi, kLogCap);
      }
  if (!(hi >= lo)) return {-kLogSpan + 1, 1};
  const double top = std::min(std::ceil(hi + 0.05), kLogCap);
  const double bottom = std::max({std::floor(lo), top - kLogSpan, -17.0});
  return {std::min(bottom, top - 2), top};
}

// Where a curve first leaves the top of the log axis: a marker there.
std::string clip_mark(const Panel& p, const std::vector<double>& t, const std::vector<double>& v,
                      const char* color) {
  for (std::size_t i = 0; i < v.size(); ++i)
    if (v[i] > p.vmax)
      return fmt::format(
          "<path class='clip' d='M{0:.1f},{1:.1f} l-5,9 h10 z' fill='{2}' stroke='#c00000'/>\n",
          p.px(t[i]), p.y0, color);
  return "";
}

std::string error_panel(const TrajectoryPlot& p, const Samples& s, const std::vector<double>& t,
                        const Panel& frame) {
  const std::size_t n = p.names.size();
  std::vector<std::vector<double>> logs(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double scale = state_scale(p, s, k).scale;
    for (auto i : s.idx) logs[k].push_back(log_relative_error(p, i, k, scale));
  }
  const auto [bottom, top] = log_range(logs);
  Panel pn = frame;
  pn.vmin = bottom;
  pn.vmax = top;
  std::string g = "<g class='error-panel'>\n";
  g += fmt::format(
      "<rect x='{:.1f}' y='{:.1f}' width='{:.1f}' height='{:.1f}' fill='white' stroke='none'/>\n",
      pn.x0, pn.y0, pn.w, pn.h);
  g += time_axis(pn, true);
  const int step = top - bottom > 8 ? 2 : 1;
  for (int e = static_cast<int>(top); e >= static_cast<int>(bottom); e -= step)
    g += value_tick(pn, e, fmt::format("1e{}", e));
  for (std::size_t k = 0; k < n; ++k) {
    g += polyline(pn, t, logs[k], "error", kColors[k % 8], false);
    g += clip_mark(pn, t, logs[k], kColors[k % 8]);
    g += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='12' fill='{}'>{}</text>\n",
                     pn.x0 + pn.w + 10, pn.y0 + 14 + 18.0 * static_cast<double>(k), kColors[k % 8],
                     escape(p.names[k]));
  }
  g += fmt::format(
      "<rect x='{:.1f}' y='{:.1f}' width='{:.1f}' height='{:.1f}' fill='none' stroke='#444'/>\n",
      pn.x0, pn.y0, pn.w, pn.h);
  g += rotated_label(pn, "|x - x_hat| / box width", "#222");
  g += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='12' text-anchor='middle'>t</text>\n",
                   pn.x0 + pn.w / 2, pn.y0 + pn.h + 30);
  const std::string why = !p.stopped.empty() ? p.stopped
                          : s.cut            ? "non-finite values after this sample"
                                             : "";
  if (!why.empty()) g += stop_marker(pn, why, true);
  return g + "</g>\n";
}

std::string legend(const std::string& note) {
  std::string s;
  if (!note.empty())
    s += fmt::format("<text x='{}' y='44' font-size='12' text-anchor='middle'>{}</text>\n",
                     kWidth / 2, escape(note));
  return s + fmt::format(
                 "<text x='{}' y='{}' font-size='11' fill='#555'>solid: true; dashed: estimate; "
                 "green band: domain box; bottom: |x - x_hat| / box width, log scale (triangle: "
                 "leaves the axis)</text>\n",
                 kLeft, note.empty() ? 48 : 62);
}

}  // namespace

std::string render_svg(const TrajectoryPlot& p) {
  const std::size_t n = p.names.size();
  const double ph = n <= 3 ? 150 : n <= 6 ? 120 : 96;
  const double top = p.note.empty() ? kTop : kTop + 14;
  const double H = top + static_cast<double>(n) * (ph + kGap) + kErrorHeight + 50;
  const Samples s = plotted_samples(p);
  std::vector<double> t;
  for (auto i : s.idx) t.push_back(p.t[i]);
  const double tmin = t.empty() ? 0 : t.front();
  const double tmax = t.empty() ? 1 : std::max(t.back(), tmin + 1e-12);
  const double pw = kWidth - kLeft - kRight;

  std::string svg = fmt::format(
      "<svg xmlns='http://www.w3.org/2000/svg' width='{0}' height='{1}' viewBox='0 0 {0} {1}' "
      "font-family='sans-serif'>\n",
      kWidth, H);
  svg += fmt::format(
      "<rect width='100%' height='100%' fill='#fafafa'/>\n<text x='{}' y='26' font-size='16' "
      "text-anchor='middle'>{}</text>\n",
      kWidth / 2, escape(p.title));
  svg += legend(p.note);
  for (std::size_t k = 0; k < n; ++k) {
    const Panel frame{kLeft, top + static_cast<double>(k) * (ph + kGap), pw, ph, tmin, tmax, 0, 1};
    svg += state_panel(p, s, t, k, frame);
  }
  const Panel frame{
      kLeft, top + static_cast<double>(n) * (ph + kGap), pw, kErrorHeight, tmin, tmax, 0, 1};
  svg += error_panel(p, s, t, frame);
  return svg + "</svg>\n";
}

}  // namespace obsynth
