#include "cli/commands.h"

#include <spdlog/spdlog.h>

#include <limits>
#include <map>
#include <sstream>

#include "core/error.h"
#include "core/ranks.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "lab/bench.h"
#include "lab/gradcheck_command.h"
#include "lab/profile_command.h"
#include "product/evaluate.h"
#include "product/export.h"
#include "product/fit.h"
#include "product/prepare.h"
#include "product/render_views.h"
#include "product/report.h"
#include "render/film.h"
#include "scenes/demo.h"
#include "scenes/degrade.h"
#include "scenes/synth.h"

namespace relume {
namespace {

// CLI::Range lets NaN through (every comparison with it is false); this check does not.
CLI::Validator inRange(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(text, v)) return fmt::format("'{}' is not a number", text);
        if (!(v >= lo && v <= hi)) return fmt::format("{} is not in [{}, {}]", text, lo, hi);
        return "";
      },
      fmt::format("in [{}, {}]", lo, hi));
}
constexpr double kInf = std::numeric_limits<double>::infinity();

// CLI::ExistingFile and CLI::ExistingDirectory, except that a path which cannot be examined (a
// symlink loop, a folder without permission) says why instead of "does not exist".
CLI::Validator existingPath(bool folder) {
  return CLI::Validator(
      [folder](std::string& text) -> std::string {
        try {
          if (!pathExists(text)) return fmt::format("{}: not found", text);
          if (isDirectory(text) != folder) return fmt::format("{}: {}", text, folder ? "not a folder" : "is a folder");
        } catch (const Error& e) {
          return e.what();
        }
        return "";
      },
      folder ? "FOLDER" : "FILE");
}
const CLI::Validator kExistingFile = existingPath(false), kExistingFolder = existingPath(true);

// An option naming a value of enum E (core/enum_names.h): parsed here, once; any other text is
// an error naming the option and the choices.
template <typename E>
CLI::Option* addEnumOption(CLI::App* c, const std::string& name, E& target, const std::string& help) {
  std::map<std::string, E> byName;
  for (const auto& [value, text] : EnumNames<E>::values) byName.emplace(std::string(text), value);
  return c->add_option(name, target, fmt::format("{}: {} (default {})", help, enumChoices<E>(), enumName(target)))
      ->transform(CLI::CheckedTransformer(byName));
}
constexpr int kMaxSide = 65536, kMaxSpp = 1 << 20, kMaxDepthLimit = 1024;

// --memory-budget's value in bytes.
double parseMemoryBudget(const std::string& text) {
  const std::optional<double> bytes = parseByteSize(text);
  if (!bytes || *bytes < 1 << 20) fail("--memory-budget: '{}' is not a size of 1M or more (2G, 800M)", text);
  return *bytes;
}

constexpr const char* kMaxDepthHelp =
    "scattering vertices per path, each with light sampling (1 = direct light only; Cycles' max bounces B is depth B + "
    "1)";

void registerPrepare(CLI::App& app, CommandTable& table) {
  auto o = std::make_shared<PrepareOptions>();
  auto capture = std::make_shared<std::string>();
  auto work = std::make_shared<std::string>();
  auto res = std::make_shared<std::string>("1024,2048,4096");
  auto init = std::make_shared<std::string>("median");
  CLI::App* c =
      app.add_subcommand("prepare", "build the texture-space data of a capture: atlas, frame cache, visibility, init");
  c->add_option("capture", *capture, "capture folder (mesh.ply|obj; transforms.json or a COLMAP sparse/0 + images/)")
      ->required()
      ->check(kExistingFolder);
  c->add_option("--out", *work, "work folder")->required();
  c->add_option("--res", *res, "texture resolutions, coarse to fine (the first is the init resolution)")
      ->capture_default_str();
  c->add_option("--init", *init, "median or mean of the observations")->capture_default_str();
  c->add_option("--max-overexposed", o->maxOverexposed, "drop frames with more saturated pixels than this")
      ->capture_default_str()
      ->check(inRange(0, 1));
  c->add_option("--max-underexposed", o->maxUnderexposed)->capture_default_str()->check(inRange(0, 1));
  c->add_option("--max-speed", o->maxSpeed, "metres between neighbouring frames")
      ->capture_default_str()
      ->check(inRange(0, kInf));
  c->add_option("--max-angular-speed", o->maxAngularSpeed, "degrees between neighbouring frames")
      ->capture_default_str()
      ->check(inRange(0, 180));
  c->add_option("--tile", o->tileTexels, "visibility tile size in texels at the init resolution")
      ->capture_default_str()
      ->check(inRange(1, 4096));
  c->add_option("--gutter-res", o->atlas.gutterResolution, "resolution at which charts keep a 2-texel gutter")
      ->capture_default_str()
      ->check(inRange(1, kMaxSide));
  c->add_option("--downscale", o->downscale, "box-filter frames by this integer factor in the cache")
      ->capture_default_str()
      ->check(inRange(1, 64));
  c->add_option("--response", o->response,
                "camera response of 8/16-bit frames: srgb, linear, gamma:G or table:FILE (default: the capture's "
                "`response`, else srgb)");
  c->add_flag("!--no-encoding-clips", o->encodingClips,
              "ablation: treat 8/16-bit frames' largest and smallest codes as exact values, not bounds");
  addEnumOption(c, "--segmentation", o->segmentation,
                "objects: the mesh's own ids, computed from the mesh and the frames, or auto (computed when the mesh "
                "has a single object)");
  c->add_flag("--force", o->force, "redo every phase");
  auto memory = std::make_shared<std::string>();
  c->add_option("--memory-budget", *memory,
                "stay within this memory (2G, 1.5G, 800M): the init phase planned to fit, or a refusal before it "
                "(before any work when even the atlas or the leanest init phase cannot fit)");
  table[c] = [=] {
    if (!memory->empty()) o->memoryBudgetBytes = parseMemoryBudget(*memory);
    o->resolutions.clear();
    std::stringstream ss(*res);
    std::string item;
    while (std::getline(ss, item, ',')) {
      try {
        o->resolutions.push_back(std::stoi(item));
      } catch (const std::exception&) {
        fail("--res: '{}' is not a resolution", item);
      }
    }
    if (o->resolutions.empty()) fail("--res needs at least one resolution");
    if (*init == "median")
      o->init = InitStatistic::Median;
    else if (*init == "mean")
      o->init = InitStatistic::Mean;
    else
      fail("--init must be median or mean, not '{}'", *init);
    if (Ranks::world().distributed())
      spdlog::info("prepare: {} MPI ranks, {} thread(s) each; the frames and the init are split, rank 0 writes the "
                   "files", Ranks::world().size(), threadCount());
    const PrepareSummary s = prepareCapture(*capture, *work, *o);
    spdlog::info("prepared {}: {} triangles, {}/{} frames kept, {:.2f}% of texels never observed, {:.1f}s", *work,
                 s.triangles, s.keptFrames, s.frames, 100 * s.fractionUnobserved, s.seconds);
    return 0;
  };
}

void registerProfile(CLI::App& app, CommandTable& table) {
  auto a = std::make_shared<ProfileRequest>();
  CLI::App* c = app.add_subcommand(
      "profile", "measure speed: renderer, adjoint passes, fit iterations, pairings, gradient scatter");
  c->add_option("--what", a->what,
                "comma list of render, adjoint, pairing, scatter, leaks, visibility (+ texel maps), fit")
      ->capture_default_str();
  c->add_option("--work", a->work, "fit: a prepared work folder (default: the demo's room, prepared in --scratch)")
      ->check(kExistingFolder);
  c->add_option("--scratch", a->scratch, "fit: where the room is prepared when no --work is given (reused)")
      ->capture_default_str();
  c->add_option("--config", a->config, "fit: config JSON (default: the demo's, 20 warm-up emission iterations)")
      ->check(kExistingFile);
  c->add_option("--stage", a->stage, "fit: profile the first stage whose name starts with this")->capture_default_str();
  c->add_option("--iterations", a->iterations, "fit: iterations timed")
      ->capture_default_str()
      ->check(inRange(1, 100000));
  c->add_option("--json", a->json, "fit: also write the profile as JSON here");
  c->add_option("--synth", a->synth, "room, cornell or furnace")->capture_default_str();
  auto* scene = c->add_option("--scene", a->scene, "render: this scene.json instead of --synth")->check(kExistingFile);
  c->add_option(
       "--cameras", a->cameras,
       "render: with --scene, a transforms.json; its first camera is rendered (its size, not --width/--height)")
      ->check(kExistingFile)
      ->needs(scene);
  scene->needs("--cameras");
  c->add_option("--rays-out", a->raysOut,
                "render: also write the replayed rays here (float32 records of 8: origin, "
                "direction, tmax, shadow) for another tracer");
  c->add_option("--width", a->width)->capture_default_str()->check(inRange(8, kMaxSide));
  c->add_option("--height", a->height)->capture_default_str()->check(inRange(8, kMaxSide));
  c->add_option("--spp", a->spp)->capture_default_str()->check(inRange(1, kMaxSpp));
  c->add_option("--max-depth", a->maxDepth, kMaxDepthHelp)->capture_default_str()->check(inRange(0, kMaxDepthLimit));
  c->add_option("--rays", a->rays, "adjoint batch size")->capture_default_str()->check(inRange(1, 1 << 26));
  c->add_option("--repeats", a->repeats)->capture_default_str()->check(inRange(1, 1000));
  c->add_option("--batches", a->batches, "pairing study batches")->capture_default_str()->check(inRange(2, 1 << 20));
  c->add_option("--study-rays", a->studyRays, "pairing study batch size")
      ->capture_default_str()
      ->check(inRange(1, 1 << 24));
  c->add_option("--scatter-res", a->scatterRes)->capture_default_str()->check(inRange(1, 1 << 15));
  table[c] = [=] {
    a->maxDepthGiven = c->count("--max-depth") > 0;
    return runProfileCommand(*a);
  };
}

void registerBench(CLI::App& app, CommandTable& table) {
  auto o = std::make_shared<BenchOptions>();
  auto sweeps = std::make_shared<std::string>();
  auto config = std::make_shared<std::string>();
  std::string names;
  for (const BenchSweep& sw : benchSweeps()) names += (names.empty() ? "" : ",") + sw.name;
  CLI::App* c =
      app.add_subcommand("bench", "speed vs accuracy: fits with one setting changed at a time, error vs time");
  c->add_option("--work", o->work, "a prepared work folder (default: the demo's room, prepared in --scratch)")
      ->check(kExistingFolder);
  c->add_option("--scratch", o->scratch, "where the room is prepared when no --work is given (reused)")
      ->capture_default_str();
  c->add_option("--out", o->out, "where bench.md, bench.csv, curves.csv and the charts go")->capture_default_str();
  c->add_option("--sweeps", *sweeps, "comma list of " + names + " (default: all)");
  c->add_option("--config", *config, "base fit config JSON (default: the demo's, shortened; the budget sweep: the fit's defaults)")
      ->check(kExistingFile);
  c->add_option("--truth", o->truth, "ground-truth scene.json (default: CAPTURE/gt/scene.json)")->check(kExistingFile);
  c->add_option("--test-cameras", o->testCameras, "held-out frames (default: CAPTURE/transforms_test.json)")
      ->check(kExistingFile);
  c->add_option("--eval-every", o->evaluateEvery, "iterations between error-vs-time points")
      ->capture_default_str()
      ->check(inRange(1, 1 << 20));
  c->add_option("--test-spp", o->testSpp, "samples per pixel of the held-out re-renders")
      ->capture_default_str()
      ->check(inRange(1, kMaxSpp));
  table[c] = [=] {
    std::stringstream ss(*sweeps);
    for (std::string item; std::getline(ss, item, ',');)
      if (!item.empty()) o->sweeps.push_back(item);
    if (!config->empty()) o->base = o->schedule = FitConfig::load(*config);
    runBench(*o);
    spdlog::info("bench: {}", (o->out / "bench.md").string());
    return 0;
  };
}

void registerFit(CLI::App& app, CommandTable& table) {
  auto work = std::make_shared<std::string>();
  auto config = std::make_shared<std::string>();
  auto resume = std::make_shared<bool>(false);
  auto maxRes = std::make_shared<int>(0);
  CLI::App* c =
      app.add_subcommand("fit", "reconstruct albedo, roughness, specular and emission from a prepared work folder");
  c->add_option("work", *work, "work folder written by `relume prepare`")->required()->check(kExistingFolder);
  c->add_option("--config", *config, "fit config JSON (keys: docs/user/fit-config.md)")->check(kExistingFile);
  c->add_option("--res", *maxRes, "cap on the final albedo resolution (default: what the frames resolve)")
      ->check(CLI::NonNegativeNumber);
  c->add_flag("--resume", *resume, "continue from WORK/checkpoint.bin");
  auto quality = std::make_shared<std::string>("default");
  c->add_option("--quality", *quality,
                "draft (about a third of the default's time), default, or best (the albedo stages up to twice as "
                "long): the schedule --config's keys and --time-budget then apply over")
      ->capture_default_str();
  auto budget = std::make_shared<std::string>();
  c->add_option("--time-budget", *budget,
                "end the fit in this time (600, 90s, 10m, 1.5h): the stage lengths follow from the measured cost of "
                "its iterations (sets time_budget)");
  auto memory = std::make_shared<std::string>();
  c->add_option("--memory-budget", *memory,
                "stay within this memory (2G, 1.5G, 800M): the finest albedo resolution whose predicted peak fits, or "
                "a refusal up front (sets memory_budget_mib)");
  auto untilConverged = std::make_shared<bool>(false);
  c->add_flag("--until-converged", *untilConverged,
              "end each albedo stage once its albedo has stopped moving by more than its noise, up to albedo_passes "
              "or what --time-budget plans for it (sets stop_on_convergence)");
  auto noReport = std::make_shared<bool>(false);
  c->add_flag("--no-report", *noReport, "skip WORK/report/ (`relume report WORK` writes it later)");
  table[c] = [=] {
    const FitConfig base = FitConfig::forQuality(parseEnum<FitQuality>(*quality, "--quality"));
    FitConfig cfg = config->empty() ? base : FitConfig::load(*config, base);
    if (*untilConverged) cfg.stopOnConvergence = true;
    spdlog::info("fit: quality {}: emission {}, albedo stages {}, materials {}, emission textures {} iterations",
                 *quality, cfg.emissionIterations,
                 cfg.stopOnConvergence ? fmt::format("until converged (at most {} passes)", cfg.albedoPasses)
                                       : fmt::format("at most {}", cfg.maxStageIterations),
                 cfg.materialIterations, cfg.emissionTextureIterations);
    if (*maxRes > 0) cfg.maxResolution = *maxRes;
    if (!budget->empty()) {
      const std::optional<double> seconds = parseDuration(*budget);
      if (!seconds || *seconds <= 0) fail("--time-budget: '{}' is not a duration (600, 90s, 10m, 1.5h)", *budget);
      cfg.timeBudget = static_cast<float>(*seconds);
    }
    if (!memory->empty()) {
      cfg.memoryBudgetMib = static_cast<float>(parseMemoryBudget(*memory) / (1 << 20));
    }
    // Over MPI ranks the root writes every file; the others hold the same state (core/ranks.h).
    const Ranks& ranks = Ranks::world();
    // Its checkpoint is written atomically into the work folder: clear what killed runs left.
    if (ranks.root())
      if (const size_t stale = removeStaleTemporaries(*work))
        spdlog::info("fit: removed {} temporaries of killed runs", stale);
    if (ranks.distributed())
      spdlog::info("fit: {} MPI ranks, {} thread(s) each; rank 0 writes the files", ranks.size(), threadCount());
    FitHooks hooks;
    hooks.writeFiles = ranks.root();
    const FitSummary s = runFit(*work, cfg, *resume, hooks);
    if (s.stopped || !ranks.root()) return 0;
    spdlog::info("fit: {} iterations in {:.0f}s, albedo {}^2, {} light source(s), result in {}", s.iterations,
                 s.seconds, s.finalResolution, s.emitters.size(), s.resultDir.string());
    if (!*noReport) writeFitReport(*work);  // re-renders a few frames: tens of seconds
    return 0;
  };
}

void registerEval(CLI::App& app, CommandTable& table) {
  auto paths = std::make_shared<std::array<std::string, 5>>();
  auto spp = std::make_shared<int>(64);
  CLI::App* c =
      app.add_subcommand("eval", "re-render a scene at held-out frames and compare (and with a ground truth)");
  c->add_option("--scene", (*paths)[0], "scene.json to evaluate")->required()->check(kExistingFile);
  c->add_option("--cameras", (*paths)[1], "transforms.json of the reference frames")->required()->check(kExistingFile);
  c->add_option("--out", (*paths)[2], "output folder (renders, eval.json)")->required();
  c->add_option("--truth", (*paths)[3], "ground-truth scene.json (same triangles)")->check(kExistingFile);
  c->add_option("--coverage", (*paths)[4], "coverage.exr of the work folder (albedo scored where observed >= 5 times)")
      ->check(kExistingFile);
  c->add_option("--spp", *spp)->capture_default_str()->check(CLI::Range(1, 1 << 16));
  table[c] = [=] {
    const auto& [scenePath, cameras, out, truthPath, coveragePath] = *paths;
    runEvaluation({scenePath, cameras, out, truthPath, coveragePath, *spp});
    return 0;
  };
}

void registerExport(CLI::App& app, CommandTable& table) {
  auto input = std::make_shared<std::string>();
  auto paths = std::make_shared<std::array<std::string, 3>>();
  auto maxDepth = std::make_shared<int>(kDefaultMaxDepth);
  CLI::App* c =
      app.add_subcommand("export", "write a reconstruction as glTF 2.0 (.glb), a Mitsuba 3 scene and EXR/PNG textures");
  c->add_option("input", *input, "work folder (its result/scene.json) or a scene.json")->required();
  c->add_option("--gltf", (*paths)[0], "binary glTF file to write (.glb)");
  c->add_option("--mitsuba", (*paths)[1], "folder for the Mitsuba 3 scene (scene.xml, meshes/, textures/)");
  c->add_option("--textures", (*paths)[2], "folder for the textures: linear EXR, sRGB PNG 8 and 16 bit");
  c->add_option("--max-depth", *maxDepth, "path depth written into the Mitsuba integrator (relume's convention)")
      ->capture_default_str()
      ->check(inRange(0, kMaxDepthLimit));
  table[c] = [=] {
    ExportOptions o;
    o.gltf = (*paths)[0], o.mitsuba = (*paths)[1], o.textures = (*paths)[2];
    o.maxDepth = *maxDepth;
    exportScene(*input, o);
    return 0;
  };
}

void registerReport(CLI::App& app, CommandTable& table) {
  auto work = std::make_shared<std::string>();
  auto o = std::make_shared<ReportOptions>();
  CLI::App* c =
      app.add_subcommand("report", "(re)write WORK/report/index.html from a finished fit (fit writes it too)");
  c->add_option("work", *work, "work folder with result/")->required()->check(kExistingFolder);
  c->add_option("--frames", o->frames, "views shown")->capture_default_str()->check(inRange(0, 1000));
  c->add_option("--spp", o->spp, "samples per pixel of their re-renders")
      ->capture_default_str()
      ->check(inRange(1, kMaxSpp));
  table[c] = [=] {
    writeFitReport(*work, *o);
    return 0;
  };
}

void registerGradcheck(CLI::App& app, CommandTable& table) {
  auto a = std::make_shared<GradcheckRequest>();
  CLI::App* c =
      app.add_subcommand("gradcheck", "adjoint gradients vs central finite differences (common random numbers)");
  c->add_option("--scene", a->scene, "scene.json (default: a synthetic scene)");
  c->add_option("--cameras", a->cameras, "transforms.json whose cameras aim the rays (with --scene)");
  c->add_option("--synth", a->synth, "room, cornell or furnace")->capture_default_str();
  c->add_option("--param", a->param, "albedo, roughness, specular, emission, emission_tex or all")
      ->capture_default_str();
  addEnumOption(c, "--gradients", a->gradients, "parameters at the first vertex only, or along the whole path");
  addEnumOption(c, "--emitter-gradients", a->emitters,
                "with direct: emitters reached from the first vertex only, or any");
  addEnumOption(c, "--pairing", a->pairing, "how the primal and adjoint passes share random numbers");
  c->add_option("--level", a->level, "sample, loss or both")
      ->capture_default_str()
      ->check(CLI::IsMember({"sample", "loss", "both"}));
  c->add_option("--rays", a->rays, "rays per batch")->capture_default_str()->check(inRange(1, 1 << 26));
  c->add_option("--batches", a->batches, "independent batches for the whole-loss check")
      ->capture_default_str()
      ->check(inRange(2, 1 << 20));
  c->add_option("--params-per-kind", a->perKind)->capture_default_str()->check(inRange(1, 1 << 20));
  c->add_option("--eps", a->eps, "finite-difference step (relative for emission)")
      ->capture_default_str()
      ->check(inRange(1e-6, 0.5));
  c->add_option("--max-depth", a->maxDepth, kMaxDepthHelp)->capture_default_str()->check(inRange(0, kMaxDepthLimit));
  c->add_option("--atlas-res", a->atlas, "synthetic albedo atlas resolution")
      ->capture_default_str()
      ->check(inRange(1, 1 << 14));
  c->add_option("--emission-scale", a->emissionScale, "multiply emitters (e.g. 1e4 to stress)")
      ->capture_default_str()
      ->check(inRange(1e-6, kMaxEmission));  // the scaled emissions are checked against the bound too
  c->add_option("--clip-high", a->clipHigh, "reference saturation threshold (one-sided loss)")
      ->check(inRange(1e-30, kInf));
  c->add_flag("--russian-roulette", a->roulette);
  table[c] = [=] { return runGradcheckCommand(*a); };
}

}  // namespace

CommandTable registerCommands(CLI::App& app) {
  CommandTable table;

  auto synthArgs = std::make_shared<SynthCaptureOptions>();
  auto synthScene = std::make_shared<std::string>("room");
  auto outDir = std::make_shared<std::string>();
  CLI::App* synth = app.add_subcommand("synth", "write a synthetic capture with known ground truth");
  synth->add_option("--scene", *synthScene, "room, cornell, furnace, scan or lounge")->capture_default_str();
  synth->add_option("--out", *outDir, "output capture folder")->required();
  synth->add_option("--frames", synthArgs->frames, "training frames")
      ->capture_default_str()
      ->check(inRange(1, 1 << 20));
  synth->add_option("--test-frames", synthArgs->testFrames, "held-out frames")
      ->capture_default_str()
      ->check(inRange(0, 1 << 20));
  synth->add_option("--width", synthArgs->width)->capture_default_str()->check(inRange(8, kMaxSide));
  synth->add_option("--height", synthArgs->height)->capture_default_str()->check(inRange(8, kMaxSide));
  synth->add_option("--spp", synthArgs->spp, "samples per pixel of the training frames")
      ->capture_default_str()
      ->check(inRange(1, kMaxSpp));
  synth
      ->add_option("--test-spp", synthArgs->testSpp, "samples per pixel of the held-out frames (evaluation references)")
      ->capture_default_str()
      ->check(inRange(1, kMaxSpp));
  synth->add_option("--max-depth", synthArgs->maxDepth, kMaxDepthHelp)
      ->capture_default_str()
      ->check(inRange(0, kMaxDepthLimit));
  synth->add_option("--seed", synthArgs->seed)->capture_default_str();
  synth->add_option("--atlas-res", synthArgs->atlasResolution, "ground-truth albedo atlas resolution")
      ->capture_default_str()
      ->check(inRange(1, 1 << 15));
  synth->add_flag("--with-uv", synthArgs->withUv, "keep uv coordinates in the capture's mesh.ply");
  synth->add_option("--triangles", synthArgs->scanTriangles, "size of the `scan` mesh")
      ->capture_default_str()
      ->check(inRange(1000, 1e8));
  auto synthFilter = std::make_shared<std::string>("box");
  synth
      ->add_option("--pixel-filter", *synthFilter,
                   "the frames' pixel filter, TYPE[:WIDTH]: box (width 1), gaussian or blackman-harris (Cycles' "
                   "definitions, width 1.5)")
      ->capture_default_str();
  auto imperfect = std::make_shared<std::string>();
  CLI::Option* imperfectOption = synth->add_option(
      "--imperfect", *imperfect,
      "a hand-held camera's flaws in the training frames, truth in gt/imperfections.json: KEY=VALUE;... with keys "
      "pose=D,A bracket=E1,E2,.. wb=S exposure-drift=S noise=F,R ldr=8|16 mesh=D segmentation=none missing=P "
      "absent=NAME unseen=NAME (docs/user/commands.md#imperfect-captures)");
  table[synth] = [=] {
    synthArgs->kind = parseSynthScene(*synthScene);
    synthArgs->pixelFilter = PixelFilter::parseSpec(*synthFilter);
    if (imperfectOption->count()) synthArgs->imperfections = parseImperfections(*imperfect);
    synthArgs->out = *outDir;
    const int n = writeSynthCapture(*synthArgs);
    spdlog::info("wrote {} frames of '{}' to {}", n, *synthScene, *outDir);
    return 0;
  };

  auto degradeArgs = std::make_shared<DegradeOptions>();
  auto degradePaths = std::make_shared<std::array<std::string, 3>>();
  CLI::App* degrade = app.add_subcommand(
      "degrade", "a clean capture with float frames (e.g. a Cycles render) as a hand-held camera delivers it");
  degrade->add_option("capture", (*degradePaths)[0], "capture folder (transforms.json or COLMAP), float frames")
      ->required()
      ->check(CLI::ExistingDirectory);
  degrade->add_option("--out", (*degradePaths)[1], "new capture folder (absent or empty)")->required();
  degrade
      ->add_option("--imperfect", (*degradePaths)[2],
                   "the flaws, as synth --imperfect: KEY=VALUE;... (docs/user/commands.md#imperfect-captures)")
      ->required();
  degrade->add_option("--seed", degradeArgs->seed)->capture_default_str();
  table[degrade] = [=] {
    degradeArgs->capture = (*degradePaths)[0];
    degradeArgs->out = (*degradePaths)[1];
    degradeArgs->spec = parseImperfections((*degradePaths)[2]);
    const DegradeSummary s = degradeCapture(*degradeArgs);
    spdlog::info("wrote {} training frames ({} left out) and {} held-out frames to {}", s.framesWritten,
                 s.framesLeftOut, s.heldOutCopied, degradeArgs->out.string());
    return 0;
  };

  auto renderArgs = std::make_shared<RenderViewsOptions>();
  renderArgs->render.spp = 64;
  auto renderPaths = std::make_shared<std::array<std::string, 3>>();
  CLI::App* render = app.add_subcommand("render", "render a scene.json from the cameras of a transforms.json");
  render->add_option("--scene", (*renderPaths)[0], "scene.json")->required()->check(kExistingFile);
  render->add_option("--cameras", (*renderPaths)[1], "transforms.json")->required()->check(kExistingFile);
  render->add_option("--out", (*renderPaths)[2], "output folder")->required();
  render->add_option("--spp", renderArgs->render.spp)->capture_default_str()->check(inRange(1, kMaxSpp));
  render->add_option("--max-depth", renderArgs->render.path.maxDepth, kMaxDepthHelp)
      ->capture_default_str()
      ->check(inRange(0, kMaxDepthLimit));
  render->add_option("--seed", renderArgs->render.seed)->capture_default_str();
  render->add_flag("--russian-roulette", renderArgs->render.path.russianRoulette);
  render->add_option("--aov", renderArgs->aovs, "comma list of albedo,normal,depth,object");
  render
      ->add_option(
          "--edit", renderArgs->edit,
          "EDIT.json: switch off/rescale emitters, change materials, add lights and meshes (docs/user/edit-file.md)")
      ->check(kExistingFile);
  table[render] = [=] {
    renderViews((*renderPaths)[0], (*renderPaths)[1], (*renderPaths)[2], *renderArgs);
    return 0;
  };

  auto demo = std::make_shared<DemoOptions>();
  auto demoOut = std::make_shared<std::string>("out/demo");
  CLI::App* demoCmd =
      app.add_subcommand("demo", "end to end on the built-in synthetic room: synth, prepare, fit, evaluate");
  demoCmd->add_option("--out", *demoOut, "output folder")->capture_default_str();
  table[demoCmd] = [=] {
    demo->out = *demoOut;
    const Json s = runDemo(*demo);
    fmt::print(
        "\nrelume demo: fit {:.0f} s ({} iterations), albedo MAE {:.4f} (PSNR {:.1f} dB), roughness MAE {:.3f}, "
        "specular MAE {:.3f}, emitters {}/{} found, emission error {:.1f}%; held-out views: {:.1f} dB against the "
        "references, whose noise alone scores {:.1f} dB; {:.1f} dB against the truth with the same random numbers\n",
        s["fit_seconds"].get<double>(), s["fit_iterations"].get<int>(), s["albedo_mae"].get<double>(),
        s["albedo_psnr"].get<double>(), s["roughness_mae"].get<double>(), s["specular_mae"].get<double>(),
        s["emitters_found"].get<int>(), s["emitters_true"].get<int>(), 100 * s["emission_rel_error"].get<double>(),
        s["test_psnr"].get<double>(), s["test_noise_floor_psnr"].get<double>(), s["test_truth_psnr"].get<double>());
    spdlog::info("report: {}   summary: {}   result: {}", (demo->out / "report.md").string(),
                 (demo->out / "summary.json").string(), (demo->out / "work" / "result").string());
    return 0;
  };
  registerProfile(app, table);
  registerBench(app, table);
  registerPrepare(app, table);
  registerFit(app, table);
  registerEval(app, table);
  registerExport(app, table);
  registerReport(app, table);
  registerGradcheck(app, table);
  return table;
}

}  // namespace relume
