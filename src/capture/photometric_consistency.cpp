#include "capture/photometric_consistency.h"

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstring>

#include "core/check.h"
#include "core/error.h"
#include "core/ranks.h"
#include "io/json.h"

namespace relume {
namespace {

// Huber's threshold in log units: within it an observation weighs 1 (a few percent of noise), beyond
// it 1/|e| (a highlight, a shadow edge the mesh misplaces).
constexpr double kHuber = 0.05;
constexpr int kReweightings = 4;

}  // namespace

ConsistencyGains solveConsistencyGains(const std::vector<std::vector<GainObservation>>& observations, size_t frameCount,
                                       std::span<const uint32_t> kept) {
  ConsistencyGains out;
  out.gain.assign(frameCount, Color::Ones());
  out.texels.assign(frameCount, 0);
  out.residualRms.assign(3, 0.0);
  std::vector<int> index(frameCount, -1);  // frame -> unknown
  for (size_t k = 0; k < kept.size(); ++k) index[kept[k]] = static_cast<int>(k);
  const int n = static_cast<int>(kept.size());
  for (const auto& obs : observations)
    if (obs.size() >= 2)
      for (const GainObservation& o : obs) ++out.texels[o.frame];
  if (n < 2) return out;
  // The channels are independent: over MPI ranks channel c is solved by rank c mod N (core/ranks.h)
  // and the log gains are exchanged. One at a time within a process: each holds two n x n matrices.
  Ranks& ranks = Ranks::world();
  std::array<std::vector<double>, 3> logGain;
  for (int c = 0; c < 3; ++c) {
    if (!ranks.ownsChunk(static_cast<size_t>(c))) continue;
    Eigen::VectorXd a = Eigen::VectorXd::Zero(n);  // log gains
    std::vector<std::vector<double>> weight(observations.size());
    for (size_t x = 0; x < observations.size(); ++x) weight[x].assign(observations[x].size(), 1.0);
    double rms = 0;
    for (int round = 0; round <= kReweightings; ++round) {
      Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
      Eigen::VectorXd r = Eigen::VectorXd::Zero(n);
      for (size_t x = 0; x < observations.size(); ++x) {
        const auto& obs = observations[x];
        if (obs.size() < 2) continue;
        double W = 0, wy = 0;
        for (size_t i = 0; i < obs.size(); ++i) W += weight[x][i], wy += weight[x][i] * std::log(obs[i].value[c]);
        const double mean = wy / W;
        for (size_t i = 0; i < obs.size(); ++i) {
          const int fi = index[obs[i].frame];
          CHECK(fi >= 0);
          const double wi = weight[x][i];
          A(fi, fi) += wi;
          r[fi] += wi * (std::log(obs[i].value[c]) - mean);
          // Column fi (A is symmetric): contiguous in the column-major matrix, and walked in frame
          // order, as the observations are.
          for (size_t j = 0; j < obs.size(); ++j) A(index[obs[j].frame], fi) -= wi * weight[x][j] / W;
        }
      }
      // The gauge: the log gains sum to 0 (A's null space is the constant vector); a frame tied to
      // no other (a disconnected part) is held at gain 1 by a vanishing ridge.
      A += Eigen::MatrixXd::Constant(n, n, 1.0 / n);
      A.diagonal().array() += 1e-9 * (1.0 + A.diagonal().maxCoeff());
      a = A.ldlt().solve(r);
      // Residuals under these gains, and the next round's weights.
      double squares = 0, weights = 0;
      for (size_t x = 0; x < observations.size(); ++x) {
        const auto& obs = observations[x];
        if (obs.size() < 2) continue;
        double W = 0, wb = 0;
        for (size_t i = 0; i < obs.size(); ++i)
          W += weight[x][i], wb += weight[x][i] * (std::log(obs[i].value[c]) - a[index[obs[i].frame]]);
        const double b = wb / W;
        for (size_t i = 0; i < obs.size(); ++i) {
          const double e = std::log(obs[i].value[c]) - a[index[obs[i].frame]] - b;
          squares += weight[x][i] * e * e, weights += weight[x][i];
          weight[x][i] = std::abs(e) <= kHuber ? 1.0 : kHuber / std::abs(e);
        }
      }
      rms = weights > 0 ? std::sqrt(squares / weights) : 0.0;
    }
    logGain[c].assign(a.data(), a.data() + n);
    out.residualRms[c] = rms;
  }
  if (ranks.distributed()) {
    std::vector<uint8_t> mine;  // per channel solved here: its residual, then its n log gains
    for (int c = 0; c < 3; ++c) {
      if (!ranks.ownsChunk(static_cast<size_t>(c))) continue;
      const auto* rms = reinterpret_cast<const uint8_t*>(&out.residualRms[c]);
      const auto* gains = reinterpret_cast<const uint8_t*>(logGain[c].data());
      mine.insert(mine.end(), rms, rms + sizeof(double));
      mine.insert(mine.end(), gains, gains + n * sizeof(double));
    }
    const std::vector<std::vector<uint8_t>> all = ranks.allGather(mine);
    std::vector<size_t> at(all.size(), 0);
    for (int c = 0; c < 3; ++c) {
      const size_t r = static_cast<size_t>(ranks.ownerOf(static_cast<size_t>(c)));
      CHECK(at[r] + (n + 1) * sizeof(double) <= all[r].size());
      std::memcpy(&out.residualRms[c], all[r].data() + at[r], sizeof(double));
      logGain[c].resize(n);
      std::memcpy(logGain[c].data(), all[r].data() + at[r] + sizeof(double), n * sizeof(double));
      at[r] += (n + 1) * sizeof(double);
    }
  }
  for (int c = 0; c < 3; ++c)
    for (int k = 0; k < n; ++k) out.gain[kept[k]][c] = static_cast<float>(std::exp(logGain[c][k]));
  return out;
}

void writeConsistencyGains(const std::filesystem::path& file, const ConsistencyGains& gains,
                           std::span<const uint32_t> kept) {
  Json frames = Json::array();
  for (uint32_t f : kept) {
    const Color& g = gains.gain[f];
    frames.push_back({{"frame", f}, {"gain", {g[0], g[1], g[2]}}, {"texels", gains.texels[f]}});
  }
  writeJson(file, {{"frames", frames}, {"log_residual_rms", gains.residualRms}});
}

std::vector<Color> readConsistencyGains(const std::filesystem::path& file, size_t frameCount) {
  std::vector<Color> gains(frameCount, Color::Ones());
  const Json j = readJson(file);
  withJsonErrors(file, [&] {
    for (const Json& f : j.at("frames")) {
      const int64_t frame =
          jsonInteger(f.at("frame"), 0, static_cast<int64_t>(frameCount) - 1, file.string(), "frame");
      const Json& g = f.at("gain");
      const Color c(g.at(0).get<float>(), g.at(1).get<float>(), g.at(2).get<float>());
      if (!(isFinite(c) && (c > 0.0f).all()))
        fail("{}: frame {}: gain must be positive and finite", file.string(), frame);
      gains[static_cast<size_t>(frame)] = c;
    }
    return 0;
  });
  return gains;
}

}  // namespace relume
