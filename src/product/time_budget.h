// A fit within a time budget (`relume fit --time-budget`, the time_budget key): the stage lengths
// are chosen from the iteration costs the fit measures as it runs, so that it ends when the
// budget does.
//
// Cost model: an iteration costs the texels it draws (batch_texels and the stage's focus texels)
// times the seconds per drawn texel last measured; stage boundaries (light decisions, upsampling,
// checkpoints, the result) cost their mean so far. Every stage is replanned after its first few
// iterations and then every tenth of its length up to its settling half, with its own measured
// cost (over its iterations since the last plan) and the stages before it as they ran.
//
// Allocation: the default schedule scaled by one factor s. The stages whose lengths are albedo
// passes go from kMinPassFraction of their default up to the albedo_passes that
// max_stage_iterations cut (Stage::longest); the others (emission, materials, emission textures)
// from kMinFixedFraction up to their default, which their unknowns settle within. s is the
// largest whose predicted end is within the budget; a budget longer than every stage at its
// longest ends early. When even the shortest schedule does not fit, the first plan refuses the
// budget, naming the time it needs (docs/design/fit.md, "Time budget").
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "io/json.h"
#include "product/fit_checkpoint.h"
#include "product/fit_schedule.h"

namespace relume {

class TimeBudget {
 public:
  static constexpr double kMinPassFraction = 0.05;   // albedo stages: at least this x their length
  static constexpr double kMinFixedFraction = 0.25;  // the other stages

  // `stages` as the schedule built them (their default lengths); `texelsDrawn[i]` what an iteration
  // of stage i draws.
  TimeBudget(double seconds, const std::vector<Stage>& stages, std::vector<double> texelsDrawn);

  double seconds() const { return seconds_; }
  // Whether stage `stage` is planned again after `done` of its iterations: after its first few
  // (the first is left out of its cost: it allocates the stage's buffers), then every tenth of
  // its length until its settling half begins (the machine's speed may change as it runs).
  bool due(size_t stage, const Stage& st, int done) const;
  // One iteration of stage `stage` took `seconds`.
  void recordIteration(size_t stage, double seconds);
  // Time spent outside iterations between the previous stage's end and this one's start.
  void recordBoundary(double seconds);

  // Sets the lengths of stages[current..] (stages[current] has run `done` iterations; those of
  // stages it skips are 0) so that the fit is predicted to end at the budget, `elapsed` seconds
  // having been spent. `runs(i)` says whether stage i > current will run, as far as is known.
  // Throws relume::Error when the first plan finds the budget too short for the shortest
  // schedule. Returns the plan, for the log and metrics.
  Json plan(std::vector<Stage>& stages, size_t current, int done, double elapsed, const std::vector<bool>& runs);

  // Stage `stage` ends after `length` iterations, before its plan's end (it converged): no later
  // plan lengthens it, and the stages after it are planned with the time it leaves.
  void endStage(size_t stage, int length);

  // The planned lengths onto `stages` (a resumed fit's schedule, built with the defaults).
  void apply(std::vector<Stage>& stages) const;

  // The budget's state in a checkpoint (what it measured and planned, and `elapsed`, the fit's
  // seconds so far), so a resumed fit keeps its plan and its clock; errors name `where`.
  void serialise(CheckpointIo& io, double& elapsed, const std::string& where);

 private:
  double predictedSeconds(const std::vector<Stage>& stages, size_t current, int done, const std::vector<bool>& runs,
                          double s, std::vector<int>* lengths) const;
  int lengthAt(size_t i, double s) const;
  double secondsPerIteration() const;  // of the stage measured

  double seconds_;
  std::vector<int> defaults_;         // each stage's default length
  std::vector<int> longest_;          // and the most it may run
  double maxScale_ = 1;               // the s at which every stage is at its longest
  std::vector<uint8_t> byPasses_;     // whose length is albedo passes
  std::vector<double> texelsDrawn_;   // per iteration
  std::vector<int> lengths_;          // as planned (the defaults until the first plan)
  std::vector<int> plannedAt_;        // per stage, its iterations at its last plan (-1: none yet)
  // The measurements: the iterations of the stage last measured since its last plan (its first
  // left out, and standing for it until another is measured), and the boundaries so far.
  int measuredStage_ = -1;
  double firstSeconds_ = 0, recentSeconds_ = 0;
  int recentIterations_ = 0;
  double boundarySeconds_ = 0;
  int boundaries_ = 0;
};

}  // namespace relume
