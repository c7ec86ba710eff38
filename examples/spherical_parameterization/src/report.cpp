#include "report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace sphparam {
namespace {

std::string num(double x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", x);
  return b;
}

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

}  // namespace

std::string histogram_svg(const std::vector<double>& initial, const std::vector<double>& final_d,
                          const std::string& title) {
  double range = 0.5;
  for (const auto* v : {&initial, &final_d})
    for (double d : *v)
      if (std::isfinite(d)) range = std::max(range, std::abs(d));
  range = std::min(range, 6.0);
  const int bins = 80;
  auto hist = [&](const std::vector<double>& v) {
    std::vector<double> h(bins, 0.0);
    std::size_t n = 0;
    for (double d : v) {
      if (!std::isfinite(d)) continue;
      const double c = std::clamp(d, -range, range);
      const int b = std::min(bins - 1, static_cast<int>((c + range) / (2 * range) * bins));
      h[static_cast<std::size_t>(b)] += 1, ++n;
    }
    for (double& x : h) x /= std::max<std::size_t>(n, 1);
    return h;
  };
  const auto hi = hist(initial), hf = hist(final_d);
  double top = 1e-9;
  for (double x : hi) top = std::max(top, x);
  for (double x : hf) top = std::max(top, x);
  const double W = 720, H = 420, left = 60, right = 20, upper = 50, lower = 50;
  const double pw = W - left - right, ph = H - upper - lower;
  auto X = [&](double d) { return left + (d + range) / (2 * range) * pw; };
  auto Y = [&](double f) { return upper + ph - f / top * ph; };
  std::string s;
  s += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(W) + "\" height=\"" + num(H) +
       "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  s += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s += "<text x=\"" + num(W / 2) + "\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">" + escape(title) + "</text>\n";
  auto bars = [&](const std::vector<double>& h, const char* fill, const char* stroke) {
    std::string path = "M" + num(X(-range)) + "," + num(Y(0));
    for (int b = 0; b < bins; ++b) {
      const double d0 = -range + 2 * range * b / bins, d1 = -range + 2 * range * (b + 1) / bins;
      path += " L" + num(X(d0)) + "," + num(Y(h[static_cast<std::size_t>(b)])) + " L" + num(X(d1)) + "," +
              num(Y(h[static_cast<std::size_t>(b)]));
    }
    path += " L" + num(X(range)) + "," + num(Y(0)) + " Z";
    s += std::string("<path d=\"") + path + "\" fill=\"" + fill + "\" fill-opacity=\"0.45\" stroke=\"" + stroke +
         "\" stroke-width=\"1.2\"/>\n";
  };
  bars(hi, "#bbbbbb", "#555555");
  bars(hf, "#3b7dd8", "#1a4f9c");
  // axes
  s += "<line x1=\"" + num(left) + "\" y1=\"" + num(upper + ph) + "\" x2=\"" + num(left + pw) + "\" y2=\"" +
       num(upper + ph) + "\" stroke=\"black\"/>\n";
  s += "<line x1=\"" + num(left) + "\" y1=\"" + num(upper) + "\" x2=\"" + num(left) + "\" y2=\"" + num(upper + ph) +
       "\" stroke=\"black\"/>\n";
  for (int k = -4; k <= 4; ++k) {
    const double d = range * k / 4;
    s += "<line x1=\"" + num(X(d)) + "\" y1=\"" + num(upper + ph) + "\" x2=\"" + num(X(d)) + "\" y2=\"" +
         num(upper + ph + 5) + "\" stroke=\"black\"/>\n";
    s += "<text x=\"" + num(X(d)) + "\" y=\"" + num(upper + ph + 18) + "\" text-anchor=\"middle\">" + num(d) +
         "</text>\n";
  }
  for (int k = 0; k <= 4; ++k) {
    const double f = top * k / 4;
    s += "<text x=\"" + num(left - 6) + "\" y=\"" + num(Y(f) + 4) + "\" text-anchor=\"end\">" + num(f) + "</text>\n";
  }
  s += "<text x=\"" + num(left + pw / 2) + "\" y=\"" + num(H - 10) +
       "\" text-anchor=\"middle\">d = log((A_sphere/4&#960;) / (A_mesh/A_total)) per face</text>\n";
  s += "<text x=\"14\" y=\"" + num(upper + ph / 2) + "\" text-anchor=\"middle\" transform=\"rotate(-90 14 " +
       num(upper + ph / 2) + ")\">fraction of faces</text>\n";
  s += "<rect x=\"" + num(W - 200) + "\" y=\"40\" width=\"14\" height=\"14\" fill=\"#bbbbbb\" stroke=\"#555555\"/>\n";
  s += "<text x=\"" + num(W - 180) + "\" y=\"52\">initial map</text>\n";
  s += "<rect x=\"" + num(W - 200) + "\" y=\"60\" width=\"14\" height=\"14\" fill=\"#3b7dd8\" stroke=\"#1a4f9c\"/>\n";
  s += "<text x=\"" + num(W - 180) + "\" y=\"72\">final map</text>\n";
  s += "</svg>\n";
  return s;
}

}  // namespace sphparam
