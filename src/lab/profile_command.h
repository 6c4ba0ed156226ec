// `relume profile`: the speed measurements (renderer, adjoint passes, fit iterations, pairings,
// gradient scatter, edge leaks, visibility), printed as tables on stdout.
#pragma once
#include <string>

#include "render/path_tracer.h"

namespace relume {

struct ProfileRequest {  // `relume profile --help` says what each is
  std::string synth = "room", what = "render,adjoint";
  std::string work, config, stage = "albedo", json, scratch = "out/room";
  std::string scene, cameras, raysOut;  // render: a scene.json seen from a transforms.json's first camera
  int iterations = 20;
  bool maxDepthGiven = false;  // fit: --max-depth overrides the config's
  int width = 320, height = 240, spp = 4, maxDepth = kDefaultMaxDepth, rays = 65536, repeats = 3, batches = 32,
      studyRays = 4096;
  int scatterRes = 4096;
};

// Runs what `what` names (a comma list) and prints its tables; returns the exit code.
int runProfileCommand(const ProfileRequest& a);

}  // namespace relume
