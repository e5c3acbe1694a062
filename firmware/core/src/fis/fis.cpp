// Mamdani FIS of eq. (10)-(12) / Table I and its lookup table.
//
// fis_evaluate() reproduces scikit-fuzzy's control-API evaluation step by step so that the host's
// oracle and the firmware agree to rounding: antecedent degrees by linear interpolation of the term
// sampled on the input universe; rule strength = min; per output term strength = max over rules;
// implication = min (clipping); the output universe is upsampled with the points where each
// clipped term crosses its cut level; aggregation = max; centroid of the piecewise-linear result.
#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>

#include "fuzzystereo/fis.hpp"
#include "fuzzystereo/image.hpp"
#include "internal.hpp"

namespace fs {

double membership(const FisTerm& t, double x) {
  const auto& p = t.params;
  if (t.mf == "trimf") {
    const double a = p[0], b = p[1], c = p[2];
    if (x == b) return 1.0;
    if (a < x && x < b) return (x - a) / (b - a);
    if (b < x && x < c) return (c - x) / (c - b);
    return 0.0;
  }
  // trapmf [a, b, c, d]
  const double a = p[0], b = p[1], c = p[2], d = p[3];
  if (b <= x && x <= c) return 1.0;
  if (a < x && x < b) return (x - a) / (b - a);
  if (c < x && x < d) return (d - x) / (d - c);
  return 0.0;
}

namespace {

std::vector<double> linspace01(int n) {
  std::vector<double> u(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) u[std::size_t(i)] = n > 1 ? static_cast<double>(i) / (n - 1) : 0.0;
  return u;
}

// np.interp(x, xp, fp) on a uniform grid over [0, 1].
double interp_uniform(const std::vector<double>& fp, double x) {
  const int n = static_cast<int>(fp.size());
  if (x <= 0.0) return fp.front();
  if (x >= 1.0) return fp.back();
  const double pos = x * (n - 1);
  int i = static_cast<int>(pos);
  if (i >= n - 1) i = n - 2;
  const double x0 = static_cast<double>(i) / (n - 1), x1 = static_cast<double>(i + 1) / (n - 1);
  return fp[std::size_t(i)] + (x - x0) * (fp[std::size_t(i) + 1] - fp[std::size_t(i)]) / (x1 - x0);
}

// scikit-fuzzy defuzz 'centroid': moment/area of the piecewise-linear function through (x, y).
// scikit-fuzzy sums moment*area per interval case by case (rectangle / triangle / trapezoid); all its
// cases equal the closed form used here, integral of x*y over [x1, x2] =
// (x2 - x1)/6 * (y1 (2 x1 + x2) + y2 (x1 + 2 x2)), and area (x2 - x1)(y1 + y2)/2 — division-free.
double centroid(const std::vector<double>& x, const std::vector<double>& y) {
  double sum_moment_area = 0.0, sum_area = 0.0;
  for (std::size_t i = 1; i < x.size(); ++i) {
    const double x1 = x[i - 1], x2 = x[i], y1 = y[i - 1], y2 = y[i], dx = x2 - x1;
    sum_moment_area += dx * (y1 * (2.0 * x1 + x2) + y2 * (x1 + 2.0 * x2));
    sum_area += dx * (y1 + y2);
  }
  sum_moment_area /= 6.0;
  sum_area *= 0.5;
  return sum_moment_area / std::max(sum_area, 2.220446049250313e-16);
}

// Everything fis_evaluate needs, sampled once.
struct SampledFis {
  std::vector<std::vector<double>> in1, in2, out;  // term samples on the universes
  std::vector<double> out_u;
  std::vector<std::pair<int, int>> support;         // per output term: sample range that can be > 0
};

SampledFis sample(const FisDefinition& def) {
  SampledFis s;
  const auto ui = linspace01(def.input_points);
  s.out_u = linspace01(def.output_points);
  auto sample_terms = [](const FisVariable& v, const std::vector<double>& u) {
    std::vector<std::vector<double>> r;
    for (const auto& t : v.terms) {
      std::vector<double> m(u.size());
      for (std::size_t i = 0; i < u.size(); ++i) m[i] = membership(t, u[i]);
      r.push_back(std::move(m));
    }
    return r;
  };
  s.in1 = sample_terms(def.in1, ui);
  s.in2 = sample_terms(def.in2, ui);
  s.out = sample_terms(def.out, s.out_u);
  const int n = static_cast<int>(s.out_u.size());
  for (const auto& m : s.out) {
    int a = 0, b = n - 1;
    while (a < n && m[std::size_t(a)] == 0.0) ++a;
    while (b >= 0 && m[std::size_t(b)] == 0.0) --b;
    s.support.emplace_back(std::max(0, a - 1), std::min(n - 1, b + 1));
  }
  return s;
}

// Rule strengths (min) aggregated per output term (max): the cut level of every output term, -1 for
// a term no rule uses.
void cut_levels(const FisDefinition& def, const double* mu1, const double* mu2, std::vector<double>& cut) {
  cut.assign(def.out.terms.size(), -1.0);
  for (const auto& r : def.rules) {
    const double a = std::min(mu1[std::size_t(r.in1)], mu2[std::size_t(r.in2)]);
    double& c = cut[std::size_t(r.out)];
    c = std::max(c, a);
  }
}

// Where term samples m cross the cut level c inside (u[i], u[i+1]), by linear interpolation.
inline double crossing_x(const std::vector<double>& u, const double* m, int i, double c) {
  return u[std::size_t(i)] + (c - m[i]) * (u[std::size_t(i) + 1] - u[std::size_t(i)]) / (m[i + 1] - m[i]);
}

// The aggregated output (max of the clipped active terms) at x between samples i and i + 1.
inline double aggregate_between(const SampledFis& s, const std::vector<double>& cut, const std::vector<std::size_t>& active,
                                int i, double x) {
  const auto& u = s.out_u;
  double y = 0.0;
  const double f = (x - u[std::size_t(i)]) / (u[std::size_t(i) + 1] - u[std::size_t(i)]);
  for (std::size_t t : active) {
    const auto& m = s.out[t];
    y = std::max(y, std::min(cut[t], m[std::size_t(i)] + f * (m[std::size_t(i) + 1] - m[std::size_t(i)])));
  }
  return y;
}

// The reference: one output value from the cut levels, step by step as scikit-fuzzy (see the top).
double evaluate_cut(const SampledFis& s, const std::vector<double>& cut, std::vector<double>& xs, std::vector<double>& ys) {
  // Only the support of the active terms can be non-zero.
  const auto& u = s.out_u;
  const int n = static_cast<int>(u.size());
  int lo = n, hi = -1;
  for (std::size_t t = 0; t < cut.size(); ++t) {
    if (cut[t] <= 0.0) continue;
    lo = std::min(lo, s.support[t].first);
    hi = std::max(hi, s.support[t].second);
  }
  if (hi < lo) throw std::runtime_error("FIS: no rule fires; the output is undefined");
  // Cut-level crossings of every active term: (interval index i, x in (u[i], u[i+1])).
  std::vector<std::pair<int, double>> cross;
  for (std::size_t t = 0; t < cut.size(); ++t) {
    if (cut[t] <= 0.0) continue;
    const auto& m = s.out[t];
    for (int i = s.support[t].first; i < s.support[t].second; ++i) {
      const double d0 = m[std::size_t(i)] - cut[t], d1 = m[std::size_t(i) + 1] - cut[t];
      if ((d0 < 0.0 && d1 > 0.0) || (d0 > 0.0 && d1 < 0.0)) cross.emplace_back(i, crossing_x(u, m.data(), i, cut[t]));
    }
  }
  std::sort(cross.begin(), cross.end());
  std::vector<std::size_t> active;
  for (std::size_t t = 0; t < cut.size(); ++t)
    if (cut[t] > 0.0) active.push_back(t);
  // Aggregated output (max of clipped terms) at one universe sample, or between samples i, i+1.
  auto at_sample = [&](int i) {
    double y = 0.0;
    for (std::size_t t : active) y = std::max(y, std::min(cut[t], s.out[t][std::size_t(i)]));
    return y;
  };
  // Upsampled universe = samples lo..hi merged with the crossings (np.union1d), then centroid.
  xs.clear();
  ys.clear();
  std::size_t c = 0;
  for (int i = lo; i <= hi; ++i) {
    xs.push_back(u[std::size_t(i)]);
    ys.push_back(at_sample(i));
    for (; c < cross.size() && cross[c].first == i; ++c) {
      const double x = cross[c].second;
      if (x <= xs.back() || (i + 1 < n && x >= u[std::size_t(i) + 1])) continue;  // duplicate
      xs.push_back(x);
      ys.push_back(aggregate_between(s, cut, active, i, x));
    }
  }
  return centroid(xs, ys);
}

// The table builder's evaluation: the same value as evaluate_cut to the last bit, with the work
// arranged for ~66k calls (FisLut::FisLut):
// - the aggregate at the universe samples is built term by term over each active term's own support
//   (a term is 0 outside it, and max is exact in any order), not term by term at every sample of the
//   union of the supports;
// - the centroid skips the intervals with y = 0 at both ends: their terms are exactly +0, and adding
//   +0 to the non-negative partial sums changes no bit (the kept terms are added in the same order);
// - no allocation per call (the scratch vectors keep their capacity).
struct FastScratch {
  std::vector<double> cut, agg;
  std::vector<std::pair<int, double>> cross;
  std::vector<std::size_t> active;
};

double evaluate_cut_fast(const SampledFis& s, FastScratch& w) {
  const std::vector<double>& cut = w.cut;
  const auto& u = s.out_u;
  const int n = static_cast<int>(u.size());
  int lo = n, hi = -1;
  w.active.clear();
  for (std::size_t t = 0; t < cut.size(); ++t) {
    if (cut[t] <= 0.0) continue;
    w.active.push_back(t);
    lo = std::min(lo, s.support[t].first);
    hi = std::max(hi, s.support[t].second);
  }
  if (hi < lo) throw std::runtime_error("FIS: no rule fires; the output is undefined");
  w.cross.clear();
  w.agg.assign(std::size_t(hi - lo + 1), 0.0);
  double* agg = w.agg.data() - lo;  // agg[i], i in [lo, hi]
  for (std::size_t t : w.active) {
    const double ct = cut[t];
    const double* m = s.out[t].data();
    const int a = s.support[t].first, b = s.support[t].second;
    for (int i = a; i < b; ++i) {
      const double d0 = m[i] - ct, d1 = m[i + 1] - ct;
      if ((d0 < 0.0 && d1 > 0.0) || (d0 > 0.0 && d1 < 0.0)) w.cross.emplace_back(i, crossing_x(u, m, i, ct));
    }
    for (int i = a; i <= b; ++i) agg[i] = std::max(agg[i], std::min(ct, m[i]));
  }
  std::sort(w.cross.begin(), w.cross.end());
  // centroid() over the merged points, accumulated on the fly: (x1, y1) the previous point.
  double sum_moment_area = 0.0, sum_area = 0.0;
  double px = u[std::size_t(lo)], py = agg[lo];
  auto add = [&](double x2, double y2) {
    if (py != 0.0 || y2 != 0.0) {
      const double x1 = px, y1 = py, dx = x2 - x1;
      sum_moment_area += dx * (y1 * (2.0 * x1 + x2) + y2 * (x1 + 2.0 * x2));
      sum_area += dx * (y1 + y2);
    }
    px = x2;
    py = y2;
  };
  std::size_t c = 0;
  for (int i = lo; i <= hi; ++i) {
    if (i > lo) add(u[std::size_t(i)], agg[i]);
    const double xi = u[std::size_t(i)];
    double last = xi;
    for (; c < w.cross.size() && w.cross[std::size_t(c)].first == i; ++c) {
      const double x = w.cross[std::size_t(c)].second;
      if (x <= last || (i + 1 < n && x >= u[std::size_t(i) + 1])) continue;  // duplicate
      add(x, aggregate_between(s, cut, w.active, i, x));
      last = x;
    }
  }
  sum_moment_area /= 6.0;
  sum_area *= 0.5;
  return sum_moment_area / std::max(sum_area, 2.220446049250313e-16);
}

double evaluate_sampled(const FisDefinition& def, const SampledFis& s, double x1, double x2,
                        std::vector<double>& xs, std::vector<double>& ys) {
  std::vector<double> mu1(s.in1.size()), mu2(s.in2.size()), cut;
  for (std::size_t i = 0; i < s.in1.size(); ++i) mu1[i] = interp_uniform(s.in1[i], x1);
  for (std::size_t i = 0; i < s.in2.size(); ++i) mu2[i] = interp_uniform(s.in2[i], x2);
  cut_levels(def, mu1.data(), mu2.data(), cut);
  return evaluate_cut(s, cut, xs, ys);
}

}  // namespace

double fis_evaluate(const FisDefinition& def, double x1, double x2) {
  const SampledFis s = sample(def);
  std::vector<double> xs, ys;
  return evaluate_sampled(def, s, x1, x2, xs, ys);
}

FisLut::FisLut(const FisDefinition& def, int size) : size_(size), table_(std::size_t(size) * std::size_t(size)) {
  const SampledFis s = sample(def);
  // The antecedent degrees of every node coordinate, once (a node's row and column share them).
  const std::size_t n1 = s.in1.size(), n2 = s.in2.size();
  std::vector<double> mu1(std::size_t(size) * n1), mu2(std::size_t(size) * n2);
  for (int i = 0; i < size; ++i) {
    const double x = static_cast<double>(i) / (size - 1);
    for (std::size_t k = 0; k < n1; ++k) mu1[std::size_t(i) * n1 + k] = interp_uniform(s.in1[k], x);
    for (std::size_t k = 0; k < n2; ++k) mu2[std::size_t(i) * n2 + k] = interp_uniform(s.in2[k], x);
  }
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel
#endif
  {
    FastScratch w;
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(dynamic, 4)
#endif
    for (int i = 0; i < size; ++i) {
      for (int j = 0; j < size; ++j) {
        cut_levels(def, &mu1[std::size_t(i) * n1], &mu2[std::size_t(j) * n2], w.cut);
        const double v = evaluate_cut_fast(s, w);
        table_[std::size_t(i) * std::size_t(size) + std::size_t(j)] =
            static_cast<std::uint32_t>(std::llround(std::clamp(v, 0.0, 1.0) * kQ16One));
      }
    }
  }
}

std::shared_ptr<const FisLut> FisLut::cached(const FisDefinition& def, int size) {
  std::ostringstream key;  // the complete definition, so an edited FIS never hits a stale table
  key.precision(17);
  key << size << '|' << def.input_points << '|' << def.output_points;
  for (const FisVariable* v : {&def.in1, &def.in2, &def.out})
    for (const auto& t : v->terms) {
      key << '|' << t.mf;
      for (double p : t.params) key << ',' << p;
    }
  for (const auto& r : def.rules) key << '|' << r.in1 << ',' << r.in2 << ',' << r.out;
  static std::mutex mu;
  static std::map<std::string, std::shared_ptr<const FisLut>> memo;
  std::lock_guard<std::mutex> lock(mu);
  auto& slot = memo[key.str()];
  if (!slot) slot = std::make_shared<const FisLut>(def, size);
  return slot;
}

}  // namespace fs
