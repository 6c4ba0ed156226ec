#include "product/clipped_light_scale.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>

#include <Eigen/Dense>

#include "adjoint/solver.h"
#include "core/check.h"
#include "core/random_streams.h"
#include "core/rng.h"
#include "product/light_evidence.h"
#include "render/lights.h"
#include "sampling/samplers.h"

namespace relume {
namespace {

constexpr double kRange = 16;       // the common scale is searched in [1/16, 16]
constexpr int kGridSteps = 160;     // log-spaced: 3.5% apart
constexpr double kApartRange = 8;   // each group's own within [1/8, 8] of the common scale
constexpr int kApartSteps = 120;    // 3.5% apart
constexpr double kApartSigmas = 3;  // two groups stay apart when their log ratio exceeds this many of its errors
constexpr int kMaxLightsApart = 8;  // beyond, one scale for all
constexpr int kSweeps = 6;          // of the coordinate descent
constexpr int kNewtonSteps = 20;    // at most, after it
constexpr size_t kMinTexels = 32;   // an object's texels for it to count
constexpr int kChoiceRounds = 3;    // of choosing the first vertex's materials and fitting the scale again
// Paths traced at a time (their rays and terms held: about 50 MB with both lobes of 3 lights).
constexpr size_t kChunkPaths = size_t{1} << 18;

bool saturated(const BatchRay& r) { return (r.reference >= r.clip.high).any(); }
bool usable(const BatchRay& r) {
  return r.reference.allFinite() && r.reference.minCoeff() >= 0 && !saturated(r) && (r.reference > r.clip.low).all();
}

// Point i of a log grid of `steps` intervals over [1/range, range].
double gridLog(int i, int steps, double range) { return std::log(range) * (2.0 * i / steps - 1.0); }

// The minimiser of J on its grid refined by the parabola through its neighbours; NaN on the grid's
// edge (the minimum may lie beyond it) or where J is flat (nothing depends on it).
double argminLog(const std::vector<double>& J, double range) {
  const int steps = static_cast<int>(J.size()) - 1;
  const auto [lowest, highest] = std::minmax_element(J.begin(), J.end());
  const int i = static_cast<int>(lowest - J.begin());
  if (i == 0 || i == steps || !(*highest - *lowest > 1e-6)) return std::numeric_limits<double>::quiet_NaN();
  const double a = J[i - 1], b = J[i], c = J[i + 1], step = gridLog(1, steps, range) - gridLog(0, steps, range);
  const double curvature = a - 2 * b + c;
  const double offset = curvature > 0 ? 0.5 * (a - c) / curvature : 0.0;
  return gridLog(i, steps, range) + std::clamp(offset, -0.5, 0.5) * step;
}

// Jackknife standard error of estimates each made with one object left out (NaN in: infinite).
double jackknifeError(const std::vector<double>& leftOut) {
  const double n = static_cast<double>(leftOut.size());
  double mean = 0, variance = 0;
  for (double l : leftOut) mean += l / n;
  for (double l : leftOut) variance += (l - mean) * (l - mean);
  return std::isnan(variance) ? INFINITY : std::sqrt((n - 1) / n * variance);
}

using Objects = std::vector<std::vector<const ScaleTexel*>>;

// Per light: the group whose scale it takes.
using Grouping = std::vector<int>;
int groupCount(const Grouping& groupOf) { return *std::max_element(groupOf.begin(), groupOf.end()) + 1; }
std::vector<double> perLight(const std::vector<double>& groupScale, const Grouping& groupOf) {
  std::vector<double> s(groupOf.size());
  for (size_t c = 0; c < groupOf.size(); ++c) s[c] = groupScale[groupOf[c]];
  return s;
}
// Each of K lights in a group of its own.
Grouping eachOwn(size_t K) {
  Grouping groupOf(K);
  for (size_t c = 0; c < K; ++c) groupOf[c] = static_cast<int>(c);
  return groupOf;
}

// Of what the frames show of a texel, the diffuse lobe explains at least this share: where the
// specular lobe would explain more, the texel says little of its albedo, and its log stays finite.
constexpr double kMinDiffuseShare = 0.1;

// The powers of G groups' scales t that a texel's terms are polynomials in: u = (1, t_1..t_G),
// and the products u_p u_q (p <= q, row by row).
struct Monomials {
  std::vector<double> linear, quadratic;
};
Monomials monomials(const std::vector<double>& t) {
  Monomials m;
  m.linear.push_back(1.0);
  m.linear.insert(m.linear.end(), t.begin(), t.end());
  for (size_t p = 0; p < m.linear.size(); ++p)
    for (size_t q = p; q < m.linear.size(); ++q) m.quadratic.push_back(m.linear[p] * m.linear[q]);
  return m;
}
double dot(const double* x, const std::vector<double>& y) {
  double sum = 0;
  for (size_t i = 0; i < y.size(); ++i) sum += x[i] * y[i];
  return sum;
}

// At the groups' scales: what a texel's diffuse lobe receives (s.D + R) and shows (I - s.G - G_R,
// at least kMinDiffuseShare I; `floored` when held there).
struct DiffuseTerms {
  double received = 0, shown = 0;
  bool floored = false;
};

// Texels whose terms are polynomials in the scales of groups of lights (each light at its
// group's): what the diffuse lobe receives and the specular lobe returns are linear in u, the
// covariance of the means weighted by the scales is quadratic, in three blocks: diffuse-diffuse,
// diffuse-specular (both off-diagonal blocks), specular-specular. The coefficients are summed
// once per grouping from the texels' terms; each of the fit's thousands of evaluations is then a
// few short dot products per texel.
class GroupedTexels {
 public:
  GroupedTexels(const std::vector<const ScaleTexel*>& texels, const Grouping& groupOf) {
    U_ = static_cast<size_t>(groupCount(groupOf)) + 1, P_ = U_ * (U_ + 1) / 2, stride_ = 1 + 2 * U_ + 3 * P_;
    count_ = texels.size();
    data_.assign(stride_ * count_, 0.0);
    const size_t K = groupOf.size();
    // The power of u each term is weighed by: its light's group, 0 for R and G_R.
    auto power = [&](size_t i) { return i % (K + 1) == K ? size_t{0} : 1 + static_cast<size_t>(groupOf[i % (K + 1)]); };
    auto pair = [&](size_t p, size_t q) {
      if (p > q) std::swap(p, q);
      return p * U_ - p * (p - 1) / 2 + (q - p);
    };
    for (size_t k = 0; k < count_; ++k) {
      const ScaleTexel& t = *texels[k];
      CHECK_EQ(t.mean.size(), K + 1);
      const size_t n = t.specular.empty() ? K + 1 : 2 * (K + 1);
      double* x = &data_[k * stride_];
      x[0] = t.shown;
      for (size_t i = 0; i <= K; ++i) {
        x[1 + power(i)] += t.mean[i];
        if (!t.specular.empty()) x[1 + U_ + power(i)] += t.specular[i];
      }
      for (size_t i = 0; i < n; ++i)
        for (size_t j = 0; j < n; ++j) {
          const size_t block = i <= K && j <= K ? 0 : i > K && j > K ? 2 : 1;
          x[1 + 2 * U_ + block * P_ + pair(power(i), power(j))] += t.covariance[i * n + j];
        }
    }
  }
  DiffuseTerms diffuse(size_t k, const Monomials& m) const {
    const double* x = &data_[k * stride_];
    DiffuseTerms d;
    d.received = dot(x + 1, m.linear);
    const double specular = dot(x + 1 + U_, m.linear), least = kMinDiffuseShare * x[0];
    d.floored = x[0] - specular < least;
    d.shown = d.floored ? least : x[0] - specular;
    return d;
  }
  // The object's term of the negative log-likelihood, profiled over its mean log-albedo and its
  // own variance: n/2 log(S/n), S the sum of squared deviations of log(I - s.G - G_R) -
  // log(s.D + R) from their mean, less the paths' noise (the delta method: the variance of the
  // log-albedo is g' C g, g its gradient in the means, C their covariance).
  double term(const Monomials& m) const {
    double sum = 0, squares = 0, noise = 0;
    for (size_t k = 0; k < count_; ++k) {
      const DiffuseTerms d = diffuse(k, m);
      const double* variances = &data_[k * stride_ + 1 + 2 * U_];
      double variance = dot(variances, m.quadratic) / (d.received * d.received);
      if (!d.floored)
        variance += 2 * dot(variances + P_, m.quadratic) / (d.received * d.shown) +
                    dot(variances + 2 * P_, m.quadratic) / (d.shown * d.shown);
      const double logAlbedo = std::log(d.shown / d.received);
      sum += logAlbedo, squares += logAlbedo * logAlbedo, noise += variance;
    }
    // The delta method holds for small noise: it may take at most 90% of the spread away.
    const double n = static_cast<double>(count_), spread = squares - sum * sum / n;
    return 0.5 * n * std::log(std::max(1e-300, std::max(spread - noise * (n - 1) / n, 0.1 * spread) / n));
  }

 private:
  size_t U_ = 0, P_ = 0, stride_ = 0, count_ = 0;
  std::vector<double> data_;  // per texel: I, then the coefficients of s.D + R, s.G + G_R, and the three blocks
};

std::vector<GroupedTexels> groupedObjects(const Objects& objects, const Grouping& groupOf) {
  std::vector<GroupedTexels> out(objects.size(), GroupedTexels({}, groupOf));
  tbb::parallel_for(size_t{0}, objects.size(), [&](size_t o) { out[o] = GroupedTexels(objects[o], groupOf); });
  return out;
}

// Per object (rows), the term at every common scale of the grid.
std::vector<std::vector<double>> commonTerms(const Objects& objects, size_t K) {
  const std::vector<GroupedTexels> one = groupedObjects(objects, Grouping(K, 0));
  std::vector<std::vector<double>> terms(objects.size(), std::vector<double>(kGridSteps + 1));
  tbb::parallel_for(size_t{0}, objects.size(), [&](size_t o) {
    for (int i = 0; i <= kGridSteps; ++i) terms[o][i] = one[o].term(monomials({std::exp(gridLog(i, kGridSteps, kRange))}));
  });
  return terms;
}

// The pooled negative log-likelihood at group scales s, over the objects not left out (`leftOut`
// < 0: none).
double pooledTerm(const std::vector<GroupedTexels>& objects, const std::vector<double>& s, int leftOut) {
  const Monomials m = monomials(s);
  double sum = 0;
  for (size_t o = 0; o < objects.size(); ++o)
    if (static_cast<int>(o) != leftOut) sum += objects[o].term(m);
  return sum;
}

// Its gradient and Hessian in the log scales at s, by central differences.
struct Curvature {
  Eigen::VectorXd gradient;
  Eigen::MatrixXd hessian;
};
Curvature curvature(const std::vector<GroupedTexels>& objects, const std::vector<double>& s, int leftOut) {
  constexpr double h = 0.002;
  const size_t G = s.size();
  auto at = [&](size_t c, double hc, size_t d, double hd) {
    std::vector<double> step = s;
    step[c] *= std::exp(hc), step[d] *= std::exp(hd);
    return pooledTerm(objects, step, leftOut);
  };
  Curvature out{Eigen::VectorXd(G), Eigen::MatrixXd(G, G)};
  for (size_t c = 0; c < G; ++c) {
    out.gradient(c) = (at(c, h, c, 0) - at(c, -h, c, 0)) / (2 * h);
    for (size_t d = c; d < G; ++d)
      out.hessian(c, d) = out.hessian(d, c) =
          (at(c, h, d, h) - at(c, h, d, -h) - at(c, -h, d, h) + at(c, -h, d, -h)) / (4 * h * h);
  }
  return out;
}

// Each group's own scale from `s`: coordinate descent on a log grid within [1/8, 8] of `common`
// (a group's step may stop at the grid's edge on the way, while the others are still far off),
// then Newton steps in the log scales, which coordinate descent takes many sweeps to match where
// two groups' light falls in similar proportions. NaN entries where a group ends on the grid's
// edge or the Newton steps leave it.
std::vector<double> scalesApart(const std::vector<GroupedTexels>& objects, std::vector<double> s, double common,
                                int leftOut) {
  std::vector<uint8_t> onEdge(s.size(), 0);
  for (int sweep = 0; sweep < kSweeps; ++sweep)
    for (size_t g = 0; g < s.size(); ++g) {
      std::vector<double> J(kApartSteps + 1, 0.0);
      tbb::parallel_for(0, kApartSteps + 1, [&](int i) {
        std::vector<double> trial = s;
        trial[g] = common * std::exp(gridLog(i, kApartSteps, kApartRange));
        J[i] = pooledTerm(objects, trial, leftOut);
      });
      const double u = argminLog(J, kApartRange);
      onEdge[g] = std::isnan(u);
      const int lowest = static_cast<int>(std::min_element(J.begin(), J.end()) - J.begin());
      s[g] = common * std::exp(onEdge[g] ? gridLog(lowest, kApartSteps, kApartRange) : u);
    }
  const auto nan = std::vector<double>(s.size(), std::numeric_limits<double>::quiet_NaN());
  if (std::any_of(onEdge.begin(), onEdge.end(), [](uint8_t e) { return e; })) return nan;
  for (int step = 0; step < kNewtonSteps; ++step) {
    const Curvature c = curvature(objects, s, leftOut);
    const Eigen::LLT<Eigen::MatrixXd> llt(c.hessian);
    if (llt.info() != Eigen::Success) break;  // not convex here: the grid's answer stands
    const Eigen::VectorXd delta = -llt.solve(c.gradient);
    const double before = pooledTerm(objects, s, leftOut);
    std::vector<double> next = s;
    for (double t = 1; t > 1.0 / 64; t /= 2) {
      for (size_t g = 0; g < s.size(); ++g) next[g] = s[g] * std::exp(t * delta(g));
      if (pooledTerm(objects, next, leftOut) < before) break;
      next = s;
    }
    if (next == s) break;
    s = next;
    if (delta.lpNorm<Eigen::Infinity>() < 1e-5) break;
  }
  for (double x : s)
    if (!(std::abs(std::log(x / common)) < std::log(kApartRange))) return nan;
  return s;
}

// The groups' own scales, each group's log error and the error of each pair's log ratio: the larger
// of the jackknife over objects (which sees objects that disagree) and the curvature (which alone
// sees a direction along which no object's albedo changes: two lights whose light falls
// everywhere in the same proportion move no left-out solution).
struct GroupScales {
  std::vector<double> scale, logError;
  Eigen::MatrixXd ratioError;  // (g, h): of log(scale_g / scale_h)
  // Of the log scales: the jackknife's covariance plus the curvature's (where it is regular).
  Eigen::MatrixXd covariance;
};
std::optional<GroupScales> fitGroups(const Objects& objects, const Grouping& groupOf, double common) {
  const int G = groupCount(groupOf);
  const std::vector<GroupedTexels> inGroups = groupedObjects(objects, groupOf);
  GroupScales out;
  out.scale = scalesApart(inGroups, std::vector<double>(G, common), common, -1);
  if (std::any_of(out.scale.begin(), out.scale.end(), [](double x) { return std::isnan(x); })) return std::nullopt;
  Eigen::MatrixXd leftOut(objects.size(), G);  // the log scales with each object left out
  for (size_t o = 0; o < objects.size(); ++o) {
    const std::vector<double> s = scalesApart(inGroups, out.scale, common, static_cast<int>(o));
    for (int g = 0; g < G; ++g) leftOut(o, g) = std::log(s[g]);
  }
  // The covariance from the curvature: the inverse Hessian, where it is regular.
  const Eigen::MatrixXd H = curvature(inGroups, out.scale, -1).hessian;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(H);
  std::optional<Eigen::MatrixXd> C;
  if (eigen.info() == Eigen::Success && eigen.eigenvalues().minCoeff() > 0) C = H.inverse();
  // The jackknife's covariance over objects (NaN where a left-out fit found no answer).
  const double n = static_cast<double>(objects.size());
  const Eigen::MatrixXd centred = leftOut.rowwise() - leftOut.colwise().mean();
  const Eigen::MatrixXd jackknife = (n - 1) / n * centred.transpose() * centred;
  out.covariance = C ? Eigen::MatrixXd(jackknife + *C) : jackknife;
  // A standard error from a variance, infinite where it is unknown.
  auto error = [](double variance) { return std::isnan(variance) ? INFINITY : std::sqrt(std::max(0.0, variance)); };
  auto ratioVariance = [](const Eigen::MatrixXd& V, int g, int h) { return V(g, g) + V(h, h) - 2 * V(g, h); };
  out.logError.resize(G);
  out.ratioError.setZero(G, G);
  for (int g = 0; g < G; ++g) {
    out.logError[g] = std::max(error(jackknife(g, g)), C ? error((*C)(g, g)) : INFINITY);
    for (int h = 0; h < g; ++h)
      out.ratioError(g, h) = out.ratioError(h, g) =
          std::max(error(ratioVariance(jackknife, g, h)), C ? error(ratioVariance(*C, g, h)) : INFINITY);
  }
  return out;
}

// A texel the fit can use: something shown, something received, no negative term.
bool usableTexel(const ScaleTexel& t, size_t K) {
  bool valid = t.shown > 0 && t.mean[K] > 0;
  for (size_t c = 0; c < K; ++c) valid &= t.mean[c] >= 0;
  for (double g : t.specular) valid &= g >= 0;
  return valid;
}

// One past the largest object id among the texels.
int objectsIn(const std::vector<ScaleTexel>& texels) {
  int count = 0;
  for (const ScaleTexel& t : texels) count = std::max(count, t.object + 1);
  return count;
}

// The usable texels (K clipped lights) of each of `objectCount` objects.
Objects usableByObject(const std::vector<ScaleTexel>& texels, int objectCount, size_t K) {
  Objects byObject(objectCount);
  for (const ScaleTexel& t : texels) {
    CHECK_EQ(t.mean.size(), K + 1);
    CHECK(t.specular.empty() || t.specular.size() == K + 1);
    const size_t n = t.mean.size() + t.specular.size();
    CHECK_EQ(t.covariance.size(), n * n);
    if (usableTexel(t, K)) byObject[t.object].push_back(&t);
  }
  return byObject;
}

}  // namespace

bool ScaleFit::known(double maxLogError) const {
  return std::any_of(logError.begin(), logError.end(), [&](double e) { return e <= maxLogError; });
}

bool ScaleFit::movesLights() const {
  for (size_t k = 0; k < scale.size(); ++k)
    if (std::abs(std::log(scale[k])) > logError[k]) return true;
  return false;
}

ScaleFit fitClippedScales(const std::vector<ScaleTexel>& texels, size_t minTexels, double maxLogError,
                          const std::vector<int>& groups) {
  const size_t K = texels.empty() ? 0 : texels.front().mean.size() - 1;
  const int objectCount = objectsIn(texels);
  const Objects byObject = usableByObject(texels, objectCount, K);
  ScaleFit fit;
  fit.scale.assign(K, 1.0);
  fit.logError.assign(K, INFINITY);
  Objects objects;
  std::vector<int> ids;
  for (int o = 0; o < objectCount; ++o)
    if (byObject[o].size() >= std::max<size_t>(minTexels, 2)) objects.push_back(byObject[o]), ids.push_back(o);
  fit.objects = static_cast<int>(objects.size());
  for (const auto& o : objects) fit.texels += o.size();
  if (K == 0 || objects.empty()) return fit;

  // One scale for all.
  const std::vector<std::vector<double>> terms = commonTerms(objects, K);
  std::vector<double> J(kGridSteps + 1, 0.0);
  for (size_t o = 0; o < objects.size(); ++o) {
    for (int i = 0; i <= kGridSteps; ++i) J[i] += terms[o][i];
    fit.perObject.push_back({ids[o], std::exp(argminLog(terms[o], kRange))});
  }
  const double logCommon = argminLog(J, kRange);
  if (std::isnan(logCommon)) return fit;
  const double common = std::exp(logCommon);
  fit.scale.assign(K, common);
  if (objects.size() < 3) return fit;
  std::vector<double> leftOut;
  for (size_t out = 0; out < objects.size(); ++out) {
    std::vector<double> Jo(J);
    for (int i = 0; i <= kGridSteps; ++i) Jo[i] -= terms[out][i];
    leftOut.push_back(argminLog(Jo, kRange));
  }
  fit.logError.assign(K, jackknifeError(leftOut));
  if (K < 2 || K > static_cast<size_t>(kMaxLightsApart)) return fit;

  // Each light its own scale where each is known to maxLogError, or else where the surfaces tell
  // it apart from the others': starting from every light in a group of its own, two groups are
  // merged while some pair's ratio is within kApartSigmas of its error, down to one group for
  // all. (A pendant lamp seven times brighter than the windows beside it is told apart at 7
  // errors, two windows alike in a wall are not.)
  Grouping groupOf = groups;
  if (groupOf.empty()) groupOf = eachOwn(K);
  CHECK_EQ(groupOf.size(), K);
  while (groupCount(groupOf) > 1) {
    const std::optional<GroupScales> apart = fitGroups(objects, groupOf, common);
    if (!apart) break;
    const int G = groupCount(groupOf);
    // Of the pairs not told apart, the one the surfaces trade against each other most (the most
    // negative correlation: more of one explains the same as more of the other). Not the one whose
    // ratio is least known: with a pair no surface tells apart, each of the pair's ratios to any
    // other light is as unknown as their own split.
    int merge = -1, into = -1;
    double mostTraded = INFINITY;
    for (int g = 0; g < G; ++g)
      for (int h = 0; h < g; ++h) {
        const double z = std::abs(std::log(apart->scale[g] / apart->scale[h])) / apart->ratioError(g, h);
        const double correlation =
            apart->covariance(g, h) / std::sqrt(apart->covariance(g, g) * apart->covariance(h, h));
        if (!(z >= kApartSigmas) && !(correlation >= mostTraded)) mostTraded = correlation, merge = g, into = h;
      }
    const bool eachKnown = G == static_cast<int>(K) && std::all_of(apart->logError.begin(), apart->logError.end(),
                                                                   [&](double e) { return e <= maxLogError; });
    if (merge < 0 || eachKnown || !groups.empty()) {  // told apart, each known, or the grouping was given
      fit.scale = perLight(apart->scale, groupOf), fit.logError = perLight(apart->logError, groupOf);
      fit.groupOf = groupOf, fit.common = false;
      break;
    }
    for (int& g : groupOf) g = g == merge ? into : g > merge ? g - 1 : g;
  }
  return fit;
}

std::vector<int> chooseFirstVertexMaterials(const std::vector<std::vector<ScaleTexel>>& under, int objectCount,
                                            size_t minTexels, const std::vector<double>& scale) {
  std::vector<int> choice(objectCount, 0);
  std::vector<double> least(objectCount, INFINITY);
  for (size_t h = 0; h < under.size(); ++h) {
    if (under[h].empty()) continue;
    const size_t K = under[h].front().mean.size() - 1;
    CHECK_EQ(scale.size(), K);
    const Objects byObject = usableByObject(under[h], objectCount, K);
    const Monomials m = monomials(scale);
    for (int o = 0; o < objectCount; ++o) {
      if (byObject[o].size() < std::max<size_t>(minTexels, 2)) continue;
      const double spread = GroupedTexels(byObject[o], eachOwn(K)).term(m) / static_cast<double>(byObject[o].size());
      if (spread < least[o]) least[o] = spread, choice[o] = static_cast<int>(h);
    }
  }
  return choice;
}

std::vector<ScaleTexel> chosenTexels(const std::vector<std::vector<ScaleTexel>>& under, const std::vector<int>& choice) {
  std::vector<ScaleTexel> chosen;
  for (size_t h = 0; h < under.size(); ++h)
    for (const ScaleTexel& t : under[h])
      if (choice[t.object] == static_cast<int>(h)) chosen.push_back(t);
  return chosen;
}

AlbedoCeiling albedoCeiling(const std::vector<ScaleTexel>& texels, size_t minTexels, const std::vector<double>& scale,
                            double sigmas) {
  const size_t K = scale.size();
  const int objectCount = objectsIn(texels);
  const Objects byObject = usableByObject(texels, objectCount, K);
  AlbedoCeiling ceiling;
  for (int o = 0; o < objectCount; ++o) {
    const auto& own = byObject[o];
    if (own.size() < std::max<size_t>(minTexels, 2)) continue;
    // Per texel: what t must make up (I - G_R - R) and what t scales (s.D + s.G).
    std::vector<std::pair<double, double>> terms;
    double missing = 0, scaled = 0;
    for (const ScaleTexel* t : own) {
      const auto specular = [&](size_t c) { return t->specular.empty() ? 0.0 : t->specular[c]; };
      double received = 0;
      for (size_t c = 0; c < K; ++c) received += scale[c] * (t->mean[c] + specular(c));
      const double unexplained = t->shown - t->mean[K] - specular(K);
      terms.emplace_back(unexplained, received);
      missing += unexplained, scaled += received;
    }
    if (!(scaled > 0)) continue;
    const double factor = missing / scaled;
    double squares = 0;
    for (const auto& [m, r] : terms) squares += (m - factor * r) * (m - factor * r);
    const double n = static_cast<double>(terms.size());
    const double error = std::sqrt(squares * n / (n - 1)) / scaled;
    ceiling.perObject.push_back({o, factor, error});
    if (const double bound = factor - sigmas * error; bound > ceiling.factor) ceiling.factor = bound, ceiling.object = o;
  }
  return ceiling;
}

Json AlbedoCeiling::toJson(const Appearance& a) const {
  Json perObjectJson = Json::array();
  for (const CeilingBound& b : perObject)
    perObjectJson.push_back({{"id", b.object}, {"name", a.names[b.object]}, {"factor", b.factor}, {"error", b.error}});
  return {{"factor", factor},
          {"object", object >= 0 ? Json(a.names[object]) : Json(nullptr)},
          {"per_object", perObjectJson}};
}

bool ClippedLightScale::movesLights() const { return applied && (fit.movesLights() || ceiling.factor > 1); }

Json ClippedLightScale::toJson(const Appearance& a) const {
  Json perLight = Json::array(), perObject = Json::array();
  for (size_t k = 0; k < lights.size(); ++k)
    perLight.push_back({{"id", lights[k]},
                        {"name", a.names[lights[k]]},
                        {"scale", fit.scale[k]},
                        {"log_error", std::isfinite(fit.logError[k]) ? Json(fit.logError[k]) : Json(nullptr)},
                        {"group", fit.common ? 0 : fit.groupOf[k]},
                        {"lower_bound", floors[k].lowerBound},
                        {"darkest_clip", floors[k].darkestClip},
                        {"darker_frame_ev", darkerFrameEv[k]}});
  for (const auto& [o, scale] : fit.perObject) {
    Json entry = {{"id", o}, {"name", a.names[o]}, {"scale", std::isfinite(scale) ? Json(scale) : Json(nullptr)}};
    if (!firstVertexMaterial.empty()) {
      const int h = firstVertexMaterial[o];
      entry["first_vertex_material"] =
          h == 0 ? Json("fit")
                 : Json::array({kFirstVertexMaterials[h - 1].roughness, kFirstVertexMaterials[h - 1].specular});
    }
    perObject.push_back(std::move(entry));
  }
  return {{"lights", perLight},   {"common", fit.common},    {"coloured", coloured}, {"objects", fit.objects},
          {"texels", fit.texels}, {"per_object", perObject}, {"applied", applied},   {"why", why},
          {"materials_deferred", materialsDeferred}, {"albedo_ceiling", ceiling.toJson(a)}};
}

namespace {

// `settings.texelsPerObject` of object o's texels, `framesPerTexel` rays each, with the frames' gains.
Batch drawTexels(const Workspace& w, const TexelSpace& space, const std::vector<uint32_t>& texels, int o,
                 const FrameGains& gains, const ClippedLightSettings& settings, uint64_t stream) {
  const TextureSpaceSampler own(*w.scene, space.map, texels, w.vis, w.trainingFrames());
  Batch b = own.sample(hashTuple({stream, static_cast<uint64_t>(o)}), 0,
                       {settings.texelsPerObject, settings.framesPerTexel, RayFootprint::Point, 1});
  gains.apply(b.rays, b.frame);
  return b;
}

// A colour's band: a channel (0-2) or its luminance (3).
double bandOf(const Color& x, int band) { return band < 3 ? x[band] : luminance(x); }

// Per drawn texel, in each band (red, green, blue, luminance): the mean of what its rays show and
// the means over its paths of each traced term (the first `diffuse` the diffuse terms D_1..D_K, R,
// any after them the specular ones G_1..G_K, G_R) with their covariance, summed chunk by chunk of
// traced rays (add: traced[c][i] is term c of traced ray i, which repeats batch ray rayOf[i]).
// Texels with fewer than two paths are left out.
class TexelSums {
 public:
  TexelSums(const Batch& batch, const TexelSpace& space, const TriangleMesh& mesh, size_t terms, size_t diffuse)
      : batch_(batch), terms_(terms), diffuse_(diffuse), samples_(batch.texel.size(), 0.0) {
    for (int band = 0; band < 4; ++band) {
      perTexel_[band].resize(batch.texel.size());
      sums_[band].assign(batch.texel.size(), std::vector<double>(terms, 0.0));
      for (size_t s = 0; s < batch.texel.size(); ++s) {
        perTexel_[band][s].object = space.objectOf(batch.texel[s], mesh);
        perTexel_[band][s].texel = batch.texel[s];
        perTexel_[band][s].covariance.assign(terms * terms, 0.0);
      }
    }
  }

  void add(const std::vector<std::vector<Color>>& traced, const std::vector<size_t>& rayOf) {
    CHECK(traced.size() == terms_);
    for (size_t i = 0; i < rayOf.size(); ++i) {
      const size_t j = rayOf[i];
      for (int band = 0; band < 4; ++band) {
        ScaleTexel& t = perTexel_[band][batch_.slot[j]];
        std::vector<double>& sum = sums_[band][batch_.slot[j]];
        t.shown += bandOf(batch_.rays[j].reference / batch_.rays[j].gain, band);
        for (size_t c = 0; c < terms_; ++c) {
          const double x = bandOf(traced[c][i], band);
          sum[c] += x;
          for (size_t d = 0; d < terms_; ++d) t.covariance[c * terms_ + d] += x * bandOf(traced[d][i], band);
        }
      }
      samples_[batch_.slot[j]] += 1;
    }
  }

  std::array<std::vector<ScaleTexel>, 4> finish() {
    for (int band = 0; band < 4; ++band) {
      for (size_t s = 0; s < perTexel_[band].size(); ++s) {
        const double n = samples_[s];
        ScaleTexel& t = perTexel_[band][s];
        if (n < 2) {
          t.shown = 0;
          continue;
        }
        t.shown /= n;
        std::vector<double>& mean = sums_[band][s];
        for (double& m : mean) m /= n;
        for (size_t c = 0; c < terms_; ++c)
          for (size_t d = 0; d < terms_; ++d) {
            double& v = t.covariance[c * terms_ + d];
            v = (v / n - mean[c] * mean[d]) / (n - 1);
          }
        t.mean.assign(mean.begin(), mean.begin() + diffuse_);
        t.specular.assign(mean.begin() + diffuse_, mean.end());
      }
      std::erase_if(perTexel_[band], [&](const ScaleTexel& t) { return t.shown <= 0; });
    }
    return std::move(perTexel_);
  }

 private:
  const Batch& batch_;
  size_t terms_, diffuse_;
  std::array<std::vector<ScaleTexel>, 4> perTexel_;
  std::array<std::vector<std::vector<double>>, 4> sums_;
  std::vector<double> samples_;
};

// Per object and channel, what the frames show of its drawn texels over what the fit renders of
// them (their albedo in `a` times the first `diffuse` traced terms' sum, plus the rest), summed
// chunk by chunk as TexelSums: 1 for objects with fewer than kMinRatioRays rays, and within
// [1/8, 8].
class ShownOverRendered {
 public:
  ShownOverRendered(const Batch& batch, const Appearance& a, const TexelSpace& space, const TriangleMesh& mesh,
                    size_t diffuse)
      : batch_(batch),
        a_(a),
        space_(space),
        mesh_(mesh),
        diffuse_(diffuse),
        seen_(a.objectCount(), Eigen::Array3d::Zero()),
        sent_(a.objectCount(), Eigen::Array3d::Zero()),
        count_(a.objectCount(), 0) {}

  void add(const std::vector<std::vector<Color>>& traced, const std::vector<size_t>& rayOf) {
    for (size_t i = 0; i < rayOf.size(); ++i) {
      const size_t j = rayOf[i];
      const uint32_t t = batch_.texel[batch_.slot[j]];
      const int o = space_.objectOf(t, mesh_);
      Eigen::Array3d received = Eigen::Array3d::Zero(), specular = Eigen::Array3d::Zero();
      for (size_t c = 0; c < traced.size(); ++c) (c < diffuse_ ? received : specular) += traced[c][i].cast<double>();
      const Eigen::Array3d albedo(a_.albedo.rgb[3 * t], a_.albedo.rgb[3 * t + 1], a_.albedo.rgb[3 * t + 2]);
      seen_[o] += (batch_.rays[j].reference / batch_.rays[j].gain).cast<double>();
      sent_[o] += albedo * received + specular;
      ++count_[o];
    }
  }

  std::vector<Color> ratio() const {
    constexpr size_t kMinRatioRays = 64;
    std::vector<Color> ratio(seen_.size(), Color::Ones());
    for (size_t o = 0; o < seen_.size(); ++o)
      if (count_[o] >= kMinRatioRays && (sent_[o] > 0).all() && (seen_[o] > 0).all())
        ratio[o] = (seen_[o] / sent_[o]).min(8.0).max(0.125).cast<float>();
    return ratio;
  }

 private:
  const Batch& batch_;
  const Appearance& a_;
  const TexelSpace& space_;
  const TriangleMesh& mesh_;
  size_t diffuse_;
  std::vector<Eigen::Array3d> seen_, sent_;
  std::vector<size_t> count_;
};

// "one scale for all", "each its own", or the groups by name ("one scale per group: window_a,
// window_b; pendant_lamp").
std::string groupingText(const ScaleFit& fit, const std::vector<int>& lights, const Appearance& a) {
  if (fit.common) return "one scale for all";
  const int G = groupCount(fit.groupOf);
  if (G == static_cast<int>(lights.size())) return "each its own";
  std::string text = "one scale per group:";
  for (int g = 0; g < G; ++g) {
    std::string members;
    for (size_t c = 0; c < lights.size(); ++c)
      if (fit.groupOf[c] == g) members += fmt::format("{}{}", members.empty() ? " " : ", ", a.names[lights[c]]);
    text += (g ? ";" : "") + members;
  }
  return text;
}

// Fills out.darkerFrameEv from the lights' emission in `a` and says what it means (for `why`).
// The margin above the emission: two of its errors (0.5 in log where the scale is not resolved)
// and one EV, as the scale has fallen short of the truth by up to 30% with errors of 5-16%
// (docs/notes/2026-11-26-shown-radiance-and-kill-points.md).
std::string adviseDarkerFrames(ClippedLightScale& out, const Appearance& a) {
  out.darkerFrameEv.clear();
  double most = 0;
  for (size_t k = 0; k < out.lights.size(); ++k) {
    const double error = std::min(out.fit.logError[k], 0.5);
    const double stops = std::log2(luminance(a.emission[out.lights[k]]) / out.floors[k].darkestClip);
    const double ev = std::isfinite(stops) ? std::ceil(2 * (stops + 1 + 2 * error / std::log(2.0))) / 2 : 0;
    out.darkerFrameEv.push_back(ev);
    most = std::max(most, ev);
  }
  return fmt::format(
      "; a frame {:.1f} EV darker than the darkest that sees them would show them unclipped and measure them", most);
}

// lightsSeenOnlySaturated on texels already grouped by object.
std::vector<int> saturatedLights(const Workspace& w, const TexelSpace& space,
                                 const std::vector<std::vector<uint32_t>>& texels, const Appearance& a,
                                 const std::vector<uint8_t>& emitter, const FrameGains& gains,
                                 const ClippedLightSettings& settings, uint64_t stream,
                                 std::vector<SaturatedFloor>* floors) {
  std::vector<int> lights;
  if (floors) floors->clear();
  for (int o = 0; o < a.objectCount(); ++o) {
    if (!emitter[o] || !a.isEmissive(o) || texels[o].empty()) continue;
    size_t rays = 0, clipped = 0;
    double bound = 0, darkest = 0;
    for (const BatchRay& r : drawTexels(w, space, texels[o], o, gains, settings, stream).rays) {
      if (!r.reference.allFinite() || r.reference.minCoeff() < 0) continue;
      ++rays;
      const double radiance = luminance(r.reference / r.gain);
      bound += radiance;
      if (saturated(r)) ++clipped, darkest = std::max(darkest, radiance);
    }
    if (!onlySaturated(clipped, rays)) continue;
    lights.push_back(o);
    if (floors) floors->push_back({bound / static_cast<double>(rays) / luminance(a.emission[o]), darkest});
  }
  return lights;
}

}  // namespace

std::vector<int> lightsSeenOnlySaturated(const Workspace& w, const TexelSpace& space, const Appearance& a,
                                         const std::vector<uint8_t>& emitter, const FrameGains& gains,
                                         const ClippedLightSettings& settings, uint64_t seed) {
  return saturatedLights(w, space, space.sampleableByObject(w.mesh, a.objectCount()), a, emitter, gains, settings,
                         hashTuple({seed, streamTag(RandomStream::ClippedLightScale)}), nullptr);
}

ClippedLightScale scaleClippedLights(const Workspace& w, const TexelSpace& space, Appearance& a,
                                     const std::vector<uint8_t>& emitter, const std::vector<uint8_t>& outOfModel,
                                     const FrameGains& gains, const PathSettings& path,
                                     const ClippedLightSettings& settings, uint64_t seed) {
  CHECK(a.emissionTextures.empty());  // runs before the emission textures exist
  const int objectCount = a.objectCount();
  const std::vector<std::vector<uint32_t>> texels = space.sampleableByObject(w.mesh, objectCount);
  const uint64_t stream = hashTuple({seed, streamTag(RandomStream::ClippedLightScale)});
  ClippedLightScale out;
  out.lights = saturatedLights(w, space, texels, a, emitter, gains, settings, stream, &out.floors);
  if (out.lights.empty()) return out;
  const size_t K = out.lights.size();

  // Each reflector's texels. A ray counts when its pixel is unsaturated and shows the object alone
  // (a pixel at a silhouette mixes in its neighbours), and when no light lies near its mirror
  // direction (a highlight adds radiance the albedo does not scale, and the lobe is not fitted yet).
  Batch batch;
  for (int o = 0; o < objectCount; ++o)
    if (!emitter[o] && !outOfModel[o] && !texels[o].empty())
      batch.append(drawTexels(w, space, texels[o], o, gains, settings, stream));
  std::vector<uint8_t> counts(batch.rays.size(), 0);
  tbb::parallel_for(size_t{0}, batch.rays.size(), [&](size_t j) {
    const BatchRay& r = batch.rays[j];
    if (!usable(r)) return;
    const auto hit = w.scene->intersect(r.origin, r.dir);
    if (!hit || hit->object != batch.object[j] ||
        !interiorPixel(*w.scene, w.frames[batch.frame[j]].camera, hit->p, batch.object[j]))
      return;
    bool seesLight = false;
    forEachMirrorDirection(*hit, r.dir, [&](const Vec3& d) {
      const auto other = w.scene->intersect(Scene::offsetOrigin(*hit, d), d);
      seesLight = other && emitter[other->object] && a.isEmissive(other->object);
      return !seesLight;
    });
    counts[j] = !seesLight;
  });
  std::vector<size_t> counted;  // the batch rays that count
  for (size_t j = 0; j < batch.rays.size(); ++j)
    if (counts[j]) counted.push_back(j);

  // D_c: reached from the first vertex (albedo 1) straight from clipped light c; R: everything else.
  // With the material choice, each through the first vertex's diffuse lobe and, apart, its
  // specular lobe: both models are affine in the albedo (bsdf.h), so the specular lobe is the BSDF
  // at albedo 0 and the diffuse lobe the difference from albedo 1, traced along the same paths (the
  // same random numbers, and sampling with `a` alone). A highlight adds radiance the albedo does
  // not scale. Without it, as one: apart but at the fit's init materials, the lobes moved the
  // room's scale by nothing and the single-exposure test capture's the wrong way (the note).
  const bool lobesApart = settings.materialChoice;
  Appearance none = a, notClipped = a;
  for (int o = 0; o < objectCount; ++o) none.emission[o] = Color::Zero();
  for (int o : out.lights) notClipped.emission[o] = Color::Zero();
  const LightSampler lights(*w.scene, a);
  // The terms (D_1..D_K, R, then G_1..G_K, G_R) of every counted ray's paths, each ray repeated
  // pathsPerRay times, the first vertex with the roughness and specular of `firstVertex`, the
  // second's albedo `secondVertex`'s (nullptr: a's). Traced in chunks of at most kChunkPaths paths,
  // each chunk's terms handed to `use` (traced[c][i]: term c of path i, which repeats batch ray
  // rayOf[i]) before the next is traced, so that the memory is a chunk's whatever the paths per
  // ray; path i is seeded by its place among all paths, as if they were traced at once.
  const size_t terms = lobesApart ? 2 * (K + 1) : K + 1;
  using TermsOfChunk = std::function<void(const std::vector<std::vector<Color>>&, const std::vector<size_t>&)>;
  auto traceTerms = [&](const Appearance& firstVertex, const Appearance* secondVertex, const TermsOfChunk& use) {
    const Appearance white = albedoOneAppearance(firstVertex);
    Appearance black = white;
    std::fill(black.albedoConstant.begin(), black.albedoConstant.end(), Color::Zero());
    const size_t paths = static_cast<size_t>(settings.pathsPerRay);
    const size_t raysPerChunk = std::max<size_t>(1, kChunkPaths / paths);
    std::vector<BatchRay> rays;
    std::vector<size_t> rayOf;
    std::vector<std::vector<Color>> traced(terms);
    for (size_t first = 0; first < counted.size(); first += raysPerChunk) {
      rays.clear(), rayOf.clear();
      for (size_t n = first; n < std::min(counted.size(), first + raysPerChunk); ++n)
        for (size_t k = 0; k < paths; ++k) rays.push_back(batch.rays[counted[n]]), rayOf.push_back(counted[n]);
      auto traceTerm = [&](size_t term, AppearanceScope scope, uint64_t tag) {
        auto seedOf = [&](size_t i) { return hashTuple({stream, tag, first * paths + i}); };
        scope.bsdfFirst = &white;
        traced[term] = traceRays(*w.scene, lights, scope, rays, path, seedOf);
        if (!lobesApart) return;
        scope.bsdfFirst = &black;
        traced[K + 1 + term] = traceRays(*w.scene, lights, scope, rays, path, seedOf);
        for (size_t i = 0; i < rays.size(); ++i) traced[term][i] -= traced[K + 1 + term][i];
      };
      for (size_t c = 0; c < K; ++c) {
        Appearance only = none;
        only.emission[out.lights[c]] = a.emission[out.lights[c]];
        traceTerm(c, {&a, &white, &a, &only, &none}, 1 + c);
      }
      traceTerm(K, {&a, &white, &a, &notClipped, &a, secondVertex}, 0);
      use(traced, rayOf);
    }
  };
  // Per texel and band (red, green, blue, luminance): the means over its paths, their covariance.
  auto sumBands = [&](const Appearance& firstVertex, const Appearance* secondVertex) {
    TexelSums sums(batch, space, w.mesh, terms, K + 1);
    traceTerms(firstVertex, secondVertex, [&](const auto& traced, const auto& rayOf) { sums.add(traced, rayOf); });
    return sums.finish();
  };
  // R is the light the surfaces in view send the texels: what the frames show of them, which a
  // change of scale leaves as it is. Traced, it is their albedo times the light they receive, which
  // falls short of what the frames show wherever the albedo sits at its ceiling of 1 because the
  // clipped lights are still too dark (the surfaces they light most): that would hold the scale near
  // where it is. So R is traced again with the albedo at the vertex after the texel (x1) scaled, per
  // object and with no ceiling, by what the frames show of the object over what the fit renders of
  // it. Only there: scaled at every vertex, the light would grow without bound in a closed room.
  Appearance shown = a;
  if (settings.shownRadiance) {
    ShownOverRendered shownOver(batch, a, space, w.mesh, K + 1);
    traceTerms(a, nullptr, [&](const auto& traced, const auto& rayOf) { shownOver.add(traced, rayOf); });
    const std::vector<Color> ratio = shownOver.ratio();
    for (size_t t = 0; t < space.map.texelCount(); ++t)
      if (space.map.valid(t))
        for (int band = 0; band < 3; ++band) shown.albedo.rgb[3 * t + band] *= ratio[space.objectOf(t, w.mesh)][band];
  }
  const Appearance* secondVertex = settings.shownRadiance ? &shown : nullptr;
  std::array<std::vector<ScaleTexel>, 4> bands = sumBands(a, secondVertex);
  if (settings.keepTexels) out.texels = bands;
  // The first vertex's roughness and specular are the fit's, which have not seen a highlight yet
  // (the material stage comes later): at the init's 0.5 and 0.5 the scale of the room's panels
  // held 10-16% short even with the true albedo, within 2% with the true materials. With the
  // choice, each object also takes each of kFirstVertexMaterials, and keeps the one under which
  // its albedo is most uniform (docs/notes/2026-11-28-clipped-lights-materials.md).
  // The choice waits until the scale under the fit's own materials has settled (moves the lights
  // by less than its error): until then the albedo the lights reach most sits at its ceiling of 1,
  // and a glossy material explains that excess as a highlight, pulling the scale back from where it
  // is headed (the single-exposure test capture, whose panels start 4x dark: emission error 0.38
  // with the choice at every probe, 0.29 with it waiting).
  out.fit = fitClippedScales(bands[3], kMinTexels, settings.maxLogError);
  out.materialsDeferred = settings.materialChoice && out.fit.movesLights();
  if (settings.materialChoice && !out.materialsDeferred) {
    std::vector<std::array<std::vector<ScaleTexel>, 4>> under = {std::move(bands)};
    for (const FirstVertexMaterial& m : kFirstVertexMaterials) {
      Appearance candidate = a;
      std::fill(candidate.roughness.begin(), candidate.roughness.end(), m.roughness);
      std::fill(candidate.specular.begin(), candidate.specular.end(), m.specular);
      under.push_back(sumBands(candidate, secondVertex));
    }
    // Judged at the scale all objects share: each at its own best scale, a glossy material let an
    // object agree with a scale no other did, and the common scale followed (single-exposure test
    // capture: emission error 0.34 against 0.29). Chosen, the scale is fitted again and the choice
    // made again at it, until it repeats.
    std::vector<std::vector<ScaleTexel>> luminance;
    for (auto& u : under) luminance.push_back(std::move(u[3]));
    for (int round = 0; round < kChoiceRounds; ++round) {
      std::vector<int> choice = chooseFirstVertexMaterials(luminance, objectCount, kMinTexels, out.fit.scale);
      if (choice == out.firstVertexMaterial) break;
      out.firstVertexMaterial = std::move(choice);
      out.fit = fitClippedScales(chosenTexels(luminance, out.firstVertexMaterial), kMinTexels, settings.maxLogError);
    }
    bands[3] = chosenTexels(luminance, out.firstVertexMaterial);
    for (int band = 0; band < 3; ++band) {
      std::vector<std::vector<ScaleTexel>> inBand;
      for (auto& u : under) inBand.push_back(std::move(u[band]));
      bands[band] = chosenTexels(inBand, out.firstVertexMaterial);
    }
  }

  std::string names;
  for (int o : out.lights) names += fmt::format("{}{} ({})", names.empty() ? "" : ", ", o, a.names[o]);
  // The uniformity's scale is applied when some group's is known to maxLogError: the others'
  // ratios to it are known to a third of themselves (a lamp 3x brighter than the windows beside it
  // keeps that ratio even where its own scale is known only to 28%). Then, or in its place, the
  // lights are raised until no object's albedo exceeds 1: in a room of white furniture, what the
  // uniformity may not tell, the ceiling does.
  const bool known = out.fit.known(settings.maxLogError);
  const std::vector<double> base = known ? out.fit.scale : std::vector<double>(K, 1.0);
  if (settings.albedoCeiling) out.ceiling = albedoCeiling(bands[3], kMinTexels, base, settings.ceilingSigmas);
  const std::string ceilingText =
      out.ceiling.factor > 1 ? fmt::format("; raised x {:.3g} so that no albedo exceeds 1 ({}'s)", out.ceiling.factor,
                                           a.names[out.ceiling.object])
                             : std::string();
  const double best = *std::min_element(out.fit.logError.begin(), out.fit.logError.end());
  const std::string unknownText = fmt::format(
      "the surfaces they light do not tell their emission apart from the albedo (scale {:.3g}, log error {:.3g} over "
      "{} objects)",
      out.fit.scale.front(), best, out.fit.objects);
  if (!known && out.ceiling.factor <= 1) {
    out.why = fmt::format(
        "lights {} are seen only saturated and {}: both keep the scale init_white_point gave them{}", names,
        unknownText, adviseDarkerFrames(out, a));
    return out;
  }
  // The colour as well when each channel's own fit is resolved (a warm light's pixels clip white,
  // and its colour, like its scale, shows only in how the surfaces' colour changes where it
  // reaches them directly); else the luminance scale for all three.
  std::vector<Color> scale(K);
  for (size_t c = 0; c < K; ++c) scale[c] = Color::Constant(static_cast<float>(base[c]));
  // Where the luminance put the lights in groups, each channel keeps them (alone, it would have to
  // find them with a third of the signal); where it found one scale for all or each its own, a
  // channel decides for itself (a warm and a cool panel differ more in colour than in brightness:
  // held to each its own, the room's channels were not resolved, and its warm panel kept the
  // emission stage's bluish colour).
  const bool grouped = !out.fit.common && groupCount(out.fit.groupOf) < static_cast<int>(K);
  bool coloured = known;
  std::array<ScaleFit, 3> channel;
  for (int band = 0; band < 3 && known; ++band) {
    channel[band] =
        fitClippedScales(bands[band], kMinTexels, settings.maxLogError, grouped ? out.fit.groupOf : std::vector<int>{});
    for (double e : channel[band].logError) coloured &= e <= settings.maxLogError;
  }
  out.coloured = coloured;
  for (size_t c = 0; c < K; ++c) {
    if (coloured)
      for (int band = 0; band < 3; ++band) scale[c][band] = static_cast<float>(channel[band].scale[c]);
    scale[c] *= static_cast<float>(out.ceiling.factor);
    // Never below what the light's pixels bound it by.
    const Color raised = a.emission[out.lights[c]] * scale[c];
    const double atLeast = out.floors[c].lowerBound * luminance(a.emission[out.lights[c]]);
    if (luminance(raised) < atLeast) scale[c] *= static_cast<float>(atLeast / luminance(raised));
  }
  out.applied = true;
  std::string scales;
  for (size_t c = 0; c < K; ++c) {
    const Color before = a.emission[out.lights[c]];
    a.emission[out.lights[c]] *= scale[c];
    const Color& after = a.emission[out.lights[c]];
    scales += fmt::format("{}{} x {:.3g}{}: {:.3g} {:.3g} {:.3g}", c ? ", " : "", a.names[out.lights[c]],
                          luminance(after) / luminance(before),
                          known ? fmt::format(" (+-{:.0f}%)", 100 * out.fit.logError[c]) : std::string(), after[0],
                          after[1], after[2]);
  }
  if (known)
    out.why = fmt::format(
        "lights {} are seen only saturated; the albedo is most uniform within each object at emission {} ({}, {}; "
        "{} objects, {} texels){}{}",
        names, scales, groupingText(out.fit, out.lights, a), coloured ? "colour from each channel" : "colour kept",
        out.fit.objects, out.fit.texels, ceilingText, adviseDarkerFrames(out, a));
  else
    out.why = fmt::format("lights {} are seen only saturated and {}; emission {}{}{}", names, unknownText, scales,
                          ceilingText, adviseDarkerFrames(out, a));
  // Each reflector's albedo by its texels' mean ratio a(s) / a(1), per channel (the next stages
  // refit it).
  std::vector<Eigen::Array3d> logRatio(objectCount, Eigen::Array3d::Zero());
  std::vector<Eigen::Array3d> count(objectCount, Eigen::Array3d::Zero());
  for (int band = 0; band < 3; ++band) {
    std::vector<double> after(K);
    for (size_t c = 0; c < K; ++c) after[c] = scale[c][band];
    std::vector<const ScaleTexel*> all;
    for (const ScaleTexel& t : bands[band]) all.push_back(&t);
    const GroupedTexels texels(all, eachOwn(K));
    const Monomials unscaled = monomials(std::vector<double>(K, 1.0)), scaled = monomials(after);
    for (size_t k = 0; k < all.size(); ++k) {
      const ScaleTexel& t = *all[k];
      const DiffuseTerms before = texels.diffuse(k, unscaled), now = texels.diffuse(k, scaled);
      const double ratio = now.shown / before.shown * (before.received / now.received);
      if (ratio > 0 && std::isfinite(ratio)) logRatio[t.object][band] += std::log(ratio), count[t.object][band] += 1;
    }
  }
  for (size_t t = 0; t < space.map.texelCount(); ++t) {
    if (!space.map.valid(t)) continue;
    const int o = space.objectOf(t, w.mesh);
    for (int band = 0; band < 3; ++band)
      if (count[o][band] > 0)
        a.albedo.rgb[3 * t + band] = std::clamp(
            a.albedo.rgb[3 * t + band] * static_cast<float>(std::exp(logRatio[o][band] / count[o][band])), 0.0f, 1.0f);
  }
  return out;
}

}  // namespace relume
