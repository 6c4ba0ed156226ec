#include "lab/gradcheck_command.h"

#include <fmt/format.h>

#include <algorithm>

#include "adjoint/gradcheck.h"
#include "capture/transforms.h"
#include "core/error.h"
#include "core/system.h"
#include "lab/experiment.h"
#include "scenes/synth.h"

namespace relume {

int runGradcheckCommand(const GradcheckRequest& a) {
  ExperimentOptions eo;
  eo.rays = a.rays;
  eo.maxDepth = a.maxDepth;
  eo.atlasResolution = a.atlas;
  eo.emissionScale = a.emissionScale;
  eo.clipHigh = a.clipHigh;
  GradcheckOptions go;
  go.kinds = a.param == "all" ? std::vector<ParamKind>(kAllParamKinds.begin(), kAllParamKinds.end())
                              : std::vector<ParamKind>{parseParamKind(a.param)};
  eo.emissionTextures = std::find(go.kinds.begin(), go.kinds.end(), ParamKind::EmissionTexture) != go.kinds.end();
  GradientExperiment e;
  if (!a.scene.empty()) {
    if (a.cameras.empty()) fail("gradcheck: --scene needs --cameras transforms.json to aim rays");
    std::vector<Camera> cams;
    for (const Frame& f : readTransforms(a.cameras).frames) cams.push_back(f.camera);
    e = makeGradientExperiment(loadSceneFile(a.scene), cams, eo);
  } else {
    e = makeGradientExperiment(parseSynthScene(a.synth), eo);
  }
  go.settings.mode = a.gradients;
  go.settings.emitters = a.emitters;
  go.settings.pairing = a.pairing;
  go.settings.path.maxDepth = a.maxDepth;
  go.settings.path.russianRoulette = a.roulette;
  go.eps = a.eps;
  go.batches = a.batches;
  go.paramsPerKind = a.perKind;
  go.level1 = a.level != "loss";
  go.level2 = a.level != "sample";
  const Scene scene(e.truth.mesh);
  Timer t;
  const GradcheckReport report = runGradcheck(scene, e.current, e.rays, go);
  fmt::print("gradcheck: {} rays, gradients {}, emitter gradients {}, pairing {}, depth {}, eps {}\n", e.rays.size(),
             enumName(a.gradients), enumName(a.emitters), enumName(a.pairing), a.maxDepth, a.eps);
  fmt::print("{}", report.table());
  if (go.settings.mode == GradientMode::Direct && go.level2)
    fmt::print("\n{}", directVersusFull(scene, e.current, e.rays, go.settings, report, go.batches));
  fmt::print("{} in {:.1f}s\n", report.pass() ? "PASS" : "FAIL", t.seconds());
  return report.pass() ? 0 : 1;
}

}  // namespace relume
