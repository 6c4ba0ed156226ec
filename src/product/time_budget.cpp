#include "product/time_budget.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/error.h"

namespace relume {

TimeBudget::TimeBudget(double seconds, const std::vector<Stage>& stages, std::vector<double> texelsDrawn)
    : seconds_(seconds), texelsDrawn_(std::move(texelsDrawn)), plannedAt_(stages.size(), -1) {
  CHECK(seconds > 0 && texelsDrawn_.size() == stages.size());
  for (const Stage& st : stages) {
    defaults_.push_back(st.iterations);
    longest_.push_back(st.lengthFromPasses ? std::max(st.iterations, st.longest) : st.iterations);
    byPasses_.push_back(st.lengthFromPasses);
    maxScale_ = std::max(maxScale_, static_cast<double>(longest_.back()) / std::max(1, st.iterations));
  }
  lengths_ = defaults_;
}

bool TimeBudget::due(size_t stage, const Stage& st, int done) const {
  const int probe = std::clamp(st.iterations / 4, 1, 10) + 1;
  if (plannedAt_[stage] < 0) return done >= std::min(st.iterations, probe);
  return 2 * done <= st.iterations && done >= plannedAt_[stage] + std::max(probe, st.iterations / 10);
}

void TimeBudget::recordIteration(size_t stage, double seconds) {
  // A stage's first iteration allocates its buffers: it stands for the stage only until another
  // has been measured.
  if (measuredStage_ != static_cast<int>(stage)) {
    measuredStage_ = static_cast<int>(stage);
    firstSeconds_ = seconds;
    recentSeconds_ = 0;
    recentIterations_ = 0;
    return;
  }
  recentSeconds_ += seconds;
  ++recentIterations_;
}

double TimeBudget::secondsPerIteration() const {
  return recentIterations_ > 0 ? recentSeconds_ / recentIterations_ : firstSeconds_;
}

void TimeBudget::recordBoundary(double seconds) {
  boundarySeconds_ += std::max(0.0, seconds);
  ++boundaries_;
}

int TimeBudget::lengthAt(size_t i, double s) const {
  const int d = defaults_[i];
  if (d == 0) return 0;
  const double least = byPasses_[i] ? kMinPassFraction : kMinFixedFraction;
  const int want = static_cast<int>(std::min(std::round(s * d), 1e9));
  return std::clamp(want, std::max(1, static_cast<int>(std::ceil(least * d))), longest_[i]);
}

double TimeBudget::predictedSeconds(const std::vector<Stage>& stages, size_t current, int done,
                                    const std::vector<bool>& runs, double s, std::vector<int>* lengths) const {
  CHECK(measuredStage_ == static_cast<int>(current));
  const double perIteration = secondsPerIteration();
  const double perTexel = perIteration / std::max(1.0, texelsDrawn_[current]);
  const double perBoundary = boundaries_ > 0 ? boundarySeconds_ / boundaries_ : 0.0;
  double t = 0;
  for (size_t i = current; i < stages.size(); ++i) {
    // The current stage keeps its settling half ahead of it: lr decay and averages are set by
    // its length, and the iterations run so far had the constant rate.
    const int len =
        i == current ? std::max(done, std::min(longest_[i], std::max(lengthAt(i, s), 2 * done))) : lengthAt(i, s);
    if (lengths) (*lengths)[i] = len;
    if (i != current && !runs[i]) continue;
    const int left = i == current ? len - done : len;
    t += left * (i == current ? perIteration : perTexel * texelsDrawn_[i]) + perBoundary;
  }
  return t;
}

Json TimeBudget::plan(std::vector<Stage>& stages, size_t current, int done, double elapsed,
                      const std::vector<bool>& runs) {
  CHECK(stages.size() == defaults_.size() && runs.size() == stages.size() && current < stages.size());
  const bool first = std::all_of(plannedAt_.begin(), plannedAt_.end(), [](int p) { return p < 0; });
  const double left = seconds_ - elapsed;
  double s = maxScale_;
  std::vector<int> lengths = lengths_;
  const double shortest = predictedSeconds(stages, current, done, runs, 0.0, &lengths);
  if (predictedSeconds(stages, current, done, runs, s, &lengths) > left) {
    if (shortest > left) {
      if (first)
        fail("time budget {:.0f} s is too short for this fit: its shortest schedule (albedo stages at {:.0f}%, the "
             "others at {:.0f}% of their length) is predicted to end at {:.0f} s on this machine, "
             "measured over the first iterations of stage {}",
             seconds_, 100 * kMinPassFraction, 100 * kMinFixedFraction, elapsed + shortest, stages[current].name);
      s = 0;
    } else {
      double lo = 0, hi = s;  // predicted(lo) <= left < predicted(hi)
      for (int k = 0; k < 60; ++k) {
        const double mid = 0.5 * (lo + hi);
        (predictedSeconds(stages, current, done, runs, mid, nullptr) <= left ? lo : hi) = mid;
      }
      s = lo;
    }
  }
  const double predicted = predictedSeconds(stages, current, done, runs, s, &lengths);
  const double perIteration = secondsPerIteration();
  for (size_t i = current; i < stages.size(); ++i) lengths_[i] = lengths[i];
  plannedAt_[current] = done;
  recentSeconds_ = 0, recentIterations_ = 0;
  apply(stages);
  Json j = {{"stage", stages[current].name},
            {"budget_seconds", seconds_},
            {"elapsed_seconds", elapsed},
            {"scale", s},
            {"predicted_end_seconds", elapsed + predicted},
            {"shortest_end_seconds", elapsed + shortest},
            {"ms_per_iteration", 1e3 * perIteration},
            {"boundary_seconds", boundaries_ > 0 ? boundarySeconds_ / boundaries_ : 0.0}};
  for (size_t i = current; i < stages.size(); ++i)
    if (i == current || runs[i]) j["iterations"].push_back({stages[i].name, lengths_[i]});
  return j;
}

void TimeBudget::endStage(size_t stage, int length) {
  CHECK(stage < lengths_.size() && length >= 0 && length <= lengths_[stage]);
  lengths_[stage] = length;
  longest_[stage] = std::min(longest_[stage], length);
}

void TimeBudget::apply(std::vector<Stage>& stages) const {
  CHECK(stages.size() == lengths_.size());
  for (size_t i = 0; i < stages.size(); ++i) stages[i].iterations = lengths_[i];
}

void TimeBudget::serialise(CheckpointIo& io, double& elapsed, const std::string& where) {
  io.array("budget.lengths", lengths_);
  io.array("budget.planned_at", plannedAt_);
  std::vector<double> numbers{elapsed, firstSeconds_, recentSeconds_, boundarySeconds_};
  std::vector<int> counts{measuredStage_, recentIterations_, boundaries_};
  io.array("budget.numbers", numbers);
  io.array("budget.counts", counts);
  if (io.writing()) return;
  for (size_t i = 0; i < lengths_.size(); ++i)
    if (lengths_[i] < 0 || lengths_[i] > std::max(1, longest_[i]) ||
        plannedAt_[i] < -1 || plannedAt_[i] > lengths_[i])
      fail("{}: the time budget's plan for stage {} ({} iterations) is not one this fit makes", where, i, lengths_[i]);
  for (double x : numbers)
    if (!std::isfinite(x) || x < 0)
      fail("{}: the time budget's measured seconds ({}) are not finite and >= 0", where, x);
  if (counts[0] < -1 || counts[0] >= static_cast<int>(lengths_.size()) || counts[1] < 0 || counts[2] < 0)
    fail("{}: the time budget's counts ({}, {}, {}) are out of range", where, counts[0], counts[1], counts[2]);
  elapsed = numbers[0], firstSeconds_ = numbers[1], recentSeconds_ = numbers[2], boundarySeconds_ = numbers[3];
  measuredStage_ = counts[0], recentIterations_ = counts[1], boundaries_ = counts[2];
}

}  // namespace relume
