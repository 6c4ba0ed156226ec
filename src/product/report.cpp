#include "product/report.h"

#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <fstream>
#include <map>
#include <optional>

#include "capture/capture_folder.h"
#include "capture/frame_image.h"
#include "core/error.h"
#include "core/rng.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "io/image.h"
#include "io/json.h"
#include "product/confidence.h"
#include "product/evaluate.h"
#include "product/prepare.h"
#include "render/lights.h"
#include "scene/texel_map.h"

namespace relume {

namespace fs = std::filesystem;

std::string lineChartSvg(const std::string& title, const std::string& xLabel, const std::vector<ChartSeries>& series,
                         bool logY) {
  constexpr double W = 420, H = 180, L = 60, R = 10, T = 24, B = 28;
  static const char* const colours[] = {"#1f5fbf", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};
  std::vector<std::vector<std::pair<double, double>>> pts(series.size());
  bool any = false;
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (size_t k = 0; k < series.size(); ++k)
    for (size_t i = 0; i < std::min(series[k].x.size(), series[k].y.size()); ++i) {
      const double y = series[k].y[i];
      if (!std::isfinite(y) || (logY && y <= 0)) continue;
      pts[k].push_back({series[k].x[i], logY ? std::log10(y) : y});
      x0 = std::min(x0, series[k].x[i]), x1 = std::max(x1, series[k].x[i]);
      y0 = std::min(y0, pts[k].back().second), y1 = std::max(y1, pts[k].back().second);
      any = true;
    }
  std::string svg =
      fmt::format(R"(<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}">)", W, H, W, H);
  svg += fmt::format(
      R"(<rect width="{}" height="{}" fill="white" stroke="#ccc"/><text x="{}" y="16" font-size="12" font-family="sans-serif">{}</text>)",
      W, H, L, title);
  if (!any) return svg + R"(<text x="60" y="90" font-size="12">no data</text></svg>)";
  if (x1 == x0) x1 = x0 + 1;
  if (y1 == y0) y0 -= 0.5, y1 += 0.5;
  auto sx = [&](double v) { return L + (v - x0) / (x1 - x0) * (W - L - R); };
  auto sy = [&](double v) { return T + (y1 - v) / (y1 - y0) * (H - T - B); };
  auto label = [&](double v) { return logY ? std::pow(10.0, v) : v; };
  for (size_t k = 0; k < series.size(); ++k) {
    std::string line;
    for (const auto& [px, py] : pts[k]) line += fmt::format("{:.1f},{:.1f} ", sx(px), sy(py));
    const char* colour = colours[k % std::size(colours)];
    svg += fmt::format(R"(<polyline fill="none" stroke="{}" stroke-width="1.5" points="{}"/>)", colour, line);
    if (!series[k].name.empty())
      svg += fmt::format(
          R"(<text x="{}" y="{}" font-size="10" font-family="sans-serif" fill="{}" text-anchor="end">{}</text>)",
          W - R - 2, T + 12 * (k + 1), colour, series[k].name);
  }
  svg += fmt::format(
      R"(<g font-size="10" font-family="sans-serif"><text x="2" y="{:.0f}">{:.3g}</text><text x="2" y="{:.0f}">{:.3g}</text>)",
      sy(y1) + 4, label(y1), sy(y0) + 4, label(y0));
  svg +=
      fmt::format(R"(<text x="{}" y="{}">{:g}</text><text x="{}" y="{}" text-anchor="end">{:g} ({})</text></g></svg>)",
                  L, H - 8, x0, W - R, H - 8, x1, xLabel);
  return svg;
}

std::string lossCurveSvg(const std::string& title, const std::vector<double>& x, const std::vector<double>& y) {
  return lineChartSvg(title, "iteration; loss on a log scale", {{"", x, y}}, true);
}

namespace {

std::string html(const std::string& s) {
  std::string out;
  for (char c : s) out += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : std::string(1, c);
  return out;
}

std::vector<Json> readJsonLines(const fs::path& path) {
  std::vector<Json> lines;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line))
    if (!line.empty()) lines.push_back(Json::parse(line, nullptr, false));
  return lines;
}

// One exposure for every picture of the views: the references' 95th percentile maps to 0.8.
float viewExposure(const std::vector<Image>& references) {
  std::vector<float> v;
  for (const Image& img : references)
    for (size_t i = 0; i < img.rgb.size(); i += 7) v.push_back(img.rgb[i]);
  if (v.empty()) return 1.0f;
  std::nth_element(v.begin(), v.begin() + v.size() * 95 / 100, v.end());
  const float p95 = v[v.size() * 95 / 100];
  return p95 > 0 ? 0.8f / p95 : 1.0f;
}

// The views' error and noise are shown per block x block pixels: at 4, the noise is 4 times
// smaller than per pixel, and the picture (64x48 of a 256x192 frame) still shows which surface is off.
constexpr int kErrorBlock = 4;

std::string percentOf(double value, double scale) {
  return fmt::format("{:.2f}%", 100.0 * value / std::max(scale, 1e-12));
}

// Reference, re-render, error and the noise in that error for a few kept frames. With a ground
// truth the fit and the truth are rendered with the same random numbers and the error is
// |fit - truth| (the reconstruction's); without, |re-render - frame| beside the re-render's noise.
std::string viewsSection(const fs::path& out, const SceneDescription& fit, const SceneDescription* truth,
                         const Json& prepare, const std::map<uint32_t, Color>& gains, const ReportOptions& o) {
  const fs::path capture = prepare.at("capture").get<std::string>();
  std::vector<Frame> frames = readCapture(capture).frames;
  applyPreparedResponse(prepare, frames);
  const auto kept = prepare.at("phases").at("frames").at("kept").get<std::vector<uint32_t>>();
  if (kept.empty() || o.frames <= 0) return "<p>No frames.</p>";
  const Scene scene(fit.mesh);
  const LightSampler lights(scene, fit.appearance);
  std::optional<Scene> truthScene;
  std::optional<LightSampler> truthLights;
  if (truth) truthScene.emplace(truth->mesh), truthLights.emplace(*truthScene, truth->appearance);
  struct Shown {
    uint32_t frame;
    Image reference, render;
    ViewError error;
    double truthVsFrame = 0;  // mean |truth re-render - frame|: the noise an error against the frame shows
  };
  std::vector<Shown> shown;
  const size_t n = std::min<size_t>(o.frames, kept.size());
  Progress progress("report views", n);
  for (size_t k = 0; k < n; ++k) {
    const uint32_t f = kept[k * kept.size() / n];
    RenderOptions ro;
    ro.spp = o.spp, ro.seed = f;
    Shown v{f, loadFrameImage(frames[f]), {}, {}, 0.0};
    if (const auto g = gains.find(f); g != gains.end())  // the frame as radiance: its estimated gain divided out
      for (size_t i = 0; i < v.reference.rgb.size(); ++i)
        if (v.reference.rgb[i] >= 0) v.reference.rgb[i] /= g->second[static_cast<int>(i % 3)];
    const SplitRender render = renderSplit(scene, fit.appearance, lights, frames[f].camera, ro);
    if (truth) {
      const SplitRender truthRender = renderSplit(*truthScene, truth->appearance, *truthLights, frames[f].camera, ro);
      v.error = errorAgainstTruth(render, truthRender, v.reference, kErrorBlock);
      v.truthVsFrame = errorAgainstPhoto(truthRender, v.reference, kErrorBlock).errorMean;
    } else {
      v.error = errorAgainstPhoto(render, v.reference, kErrorBlock);
    }
    v.render = render.mean;
    shown.push_back(std::move(v));
    progress.advance();
  }
  // The frames pooled: means weighted by block count, RMS over every block.
  std::vector<Image> refs;
  ViewError all;
  double truthVsFrame = 0;
  for (const Shown& v : shown) {
    refs.push_back(v.reference);
    const double w = static_cast<double>(v.error.samples);
    all.samples += v.error.samples;
    all.errorMean += w * v.error.errorMean, all.noiseMean += w * v.error.noiseMean,
        all.referenceMean += w * v.error.referenceMean;
    all.errorRms += w * v.error.errorRms * v.error.errorRms, all.noiseRms += w * v.error.noiseRms * v.error.noiseRms;
    truthVsFrame += w * v.truthVsFrame;
  }
  const double samples = static_cast<double>(std::max<size_t>(all.samples, 1));
  all.errorMean /= samples, all.noiseMean /= samples, all.referenceMean /= samples, truthVsFrame /= samples;
  all.errorRms = std::sqrt(all.errorRms / samples), all.noiseRms = std::sqrt(all.noiseRms / samples);
  auto pct = [&](double v) { return percentOf(v, all.referenceMean); };
  const float exposure = viewExposure(refs);
  const int half = std::max(1, o.spp / 2);
  std::string s;
  if (truth)
    s = fmt::format(
        "<p>Kept frames re-rendered from the result and from the capture's ground truth with the same random numbers "
        "({} spp "
        "each, as two halves of {}). Where the two scenes agree their Monte Carlo noise is the same and cancels, so "
        "the error "
        "|fit - truth| is the reconstruction's; the noise left in it (paths the two scenes scatter differently), "
        "estimated from "
        "the halves, is shown beside it. Both are averaged over {}x{}-pixel blocks before their magnitude is taken, "
        "which "
        "divides the noise by {} and keeps what is off at that scale. One exposure ({:.3g}) for all; error and noise x "
        "4; "
        "masked pixels black.</p><p>Over these frames, as a share of the frames' mean value: |fit - truth| {} on "
        "average, of "
        "which noise {}; RMS {}, noise RMS {}, so the reconstruction's own RMS error is about {}. For comparison, the "
        "truth "
        "itself re-rendered differs from the frames by {} on average at the same scale: the frames' and the "
        "re-render's "
        "noise, which an error against the frames would mostly show.</p>",
        o.spp, half, kErrorBlock, kErrorBlock, kErrorBlock, exposure, pct(all.errorMean), pct(all.noiseMean),
        pct(all.errorRms), pct(all.noiseRms), pct(all.beyondNoiseRms()), pct(truthVsFrame));
  else
    s = fmt::format(
        "<p>Kept frames re-rendered from the result ({} spp, as two halves of {}). Error = |re-render - frame|; noise "
        "= the "
        "re-render's own Monte Carlo noise, estimated from its halves' difference (the frame's noise is not known, so "
        "not "
        "shown): error that the noise does not explain is the reconstruction's, or the frame's noise. Both are "
        "averaged over "
        "{}x{}-pixel blocks before their magnitude is taken, which divides the noise by {} and keeps what is off at "
        "that "
        "scale. One exposure ({:.3g}) for all; error and noise x 4; masked pixels black.</p><p>Over these frames, as a "
        "share "
        "of the frames' mean value: error {} on average, the re-render's noise {}; RMS {}, noise RMS {}, so the error "
        "beyond "
        "the re-render's noise has an RMS of about {}.</p>",
        o.spp, half, kErrorBlock, kErrorBlock, kErrorBlock, exposure, pct(all.errorMean), pct(all.noiseMean),
        pct(all.errorRms), pct(all.noiseRms), pct(all.beyondNoiseRms()));
  s += fmt::format(
      "<table><tr><th>frame</th><th>reference</th><th>re-render</th><th>{}</th><th>noise in that error</th></tr>",
      truth ? "error |fit - truth|" : "error |re-render - frame|");
  for (const Shown& v : shown) {
    const std::string stem = fmt::format("view_{}", v.frame);
    writePng(out / (stem + "_reference.png"), v.reference, exposure);
    writePng(out / (stem + "_render.png"), v.render, exposure);
    writePng(out / (stem + "_error.png"), v.error.error, 4 * exposure);
    writePng(out / (stem + "_noise.png"), v.error.noise, 4 * exposure);
    s += fmt::format(
        "<tr><td>{}<br>error {}<br>noise {}</td><td><img src=\"{}_reference.png\"></td><td><img "
        "src=\"{}_render.png\"></td>"
        "<td><img src=\"{}_error.png\"></td><td><img src=\"{}_noise.png\"></td></tr>",
        html(frames[v.frame].image.filename().string()), percentOf(v.error.errorMean, v.error.referenceMean),
        percentOf(v.error.noiseMean, v.error.referenceMean), stem, stem, stem, stem);
  }
  return s + "</table>";
}

std::string figure(const std::string& file, const std::string& caption) {
  return fmt::format("<figure><img class=\"tex\" src=\"{}\"><figcaption>{}</figcaption></figure>", file, caption);
}

// The light no light source of the fit supplies (confidence.json's unplaced_light), from
// kUnplacedLightNotice on: the share, and the objects it falls on most (up to six).
std::string unplacedLightParagraph(const Json& summary) {
  const Json u = summary.value("unplaced_light", Json());
  if (!u.is_object() || u.at("share_of_observed").get<double>() < kUnplacedLightNotice) return "";
  std::string objects;
  for (size_t k = 0; k < std::min<size_t>(6, u.at("objects").size()); ++k) {
    const Json& o = u.at("objects")[k];
    objects += fmt::format("{}{} ({:.1f}% of its own)", k ? ", " : "", html(o.at("name").get<std::string>()),
                           100 * o.at("share_of_its_own").get<double>());
  }
  return fmt::format(
      "<p><b>Light the fit cannot place:</b> at least {:.1f}% of the radiance the frames show on reflectors is more "
      "than they return with albedo 1 under the fitted lights: {}. A light no frame shows (a lamp seen only "
      "from behind, a window outside every frame) lights them; their albedo is too bright there and a relit "
      "render lacks that light.</p>",
      100 * u.at("share_of_observed").get<double>(), objects);
}

// Where the reconstruction rests on what the frames showed and where it is guessed
// (result/confidence.*, product/confidence.h): the picture with its legend, and per object the
// shares of its texels by evidence and what its materials rest on.
std::string confidenceSection(const fs::path& work, const fs::path& out) {
  const fs::path picture = work / "result" / "confidence.png", summaryFile = work / "result" / "confidence.json";
  if (!pathExists(picture) || !pathExists(summaryFile))
    return "<p>No confidence texture (a fit before it existed).</p>";
  copyFileOver(picture, out / "confidence.png");
  const Json summary = readJson(summaryFile);
  std::string legend, header, rows;
  for (int k = 0; k < kTexelEvidenceKinds; ++k) {
    const auto e = static_cast<TexelEvidence>(k);
    const Color c = texelEvidenceColour(e);
    legend += fmt::format("<span style=\"background:rgb({},{},{});padding:0 0.6em\">&nbsp;</span> {} &nbsp; ",
                          std::lround(255 * c[0]), std::lround(255 * c[1]), std::lround(255 * c[2]),
                          texelEvidenceName(e));
    header += fmt::format("<th>{}</th>", texelEvidenceName(e));
  }
  const auto shareCells = [](const Json& row) {
    std::string cells = fmt::format("<td>{}</td>", row.at("texels").get<size_t>());
    for (int k = 0; k < kTexelEvidenceKinds; ++k) {
      const double share = row.value(texelEvidenceName(static_cast<TexelEvidence>(k)), 0.0);
      cells += share > 0 ? fmt::format("<td>{:.1f}%</td>", 100 * share) : "<td></td>";
    }
    return cells;
  };
  for (const Json& row : summary.at("objects")) {
    const Json materials = row.value("materials_from", Json("(a light)"));
    rows += fmt::format("<tr><td>{}</td><td>{}</td>{}<td>{}</td></tr>", row.at("id").get<int>(),
                        html(row.at("name").get<std::string>()), shareCells(row),
                        html(materials.is_string() ? materials.get<std::string>() : materials.dump()));
  }
  const Json& t = summary.at("thresholds");
  return figure("confidence.png", "evidence per texel: " + legend) +
         fmt::format("<p>unseen: no frame saw it; few: under {:g} observations; disagree: over {:.0f}% of its "
                     "observations beyond a factor {:g} of its median (the mesh is not where the frames saw the "
                     "surface, or a highlight); under-lit: brighter than albedo 1 returns under the fitted lights "
                     "(by over {:g} and {:g} standard errors), lit by a light the fit does not have; uncertain: a "
                     "standard error over {:g}; light saturated: over {:.0f}% of its observations clipped, its "
                     "emission inferred.</p>",
                     t.at("few_observations").get<double>(), 100 * t.at("disagree_share").get<double>(),
                     t.at("agreement_ratio").get<double>(), t.value("under_lit_excess", 0.0),
                     t.value("under_lit_errors", 0.0), t.at("uncertain_albedo").get<double>(),
                     100 * t.at("saturated_share").get<double>()) +
         unplacedLightParagraph(summary) +
         "<table><tr><th>id</th><th>name</th><th>texels</th>" + header + "<th>materials from</th></tr>" +
         "<tr><td></td><td>all</td>" + shareCells(summary.at("all")) + "<td></td></tr>" + rows + "</table>";
}

// Every texel in its object's colour (a hash of the id, light sources in white): where the objects
// are, whether the mesh's or computed by prepare.
std::string objectsFigure(const fs::path& out, const SceneDescription& fit, const Json& prepare) {
  const int res = fit.appearance.albedo.width;
  if (res <= 0) return "";  // constant albedo per object: no atlas to draw in
  const TexelMap map(fit.mesh, res);
  Image img(res, res);
  for (size_t t = 0; t < map.texelCount(); ++t) {
    if (!map.valid(t)) continue;
    const int object = fit.mesh.faceObject[map.triangle(t)];
    const uint64_t h = hashTuple({static_cast<uint64_t>(object), 0x0b1ec75ull});
    const Color c = fit.appearance.isEmissive(object)
                        ? Color::Ones()
                        : Color(0.1f + 0.7f * ((h & 0xff) / 255.0f), 0.1f + 0.7f * ((h >> 8 & 0xff) / 255.0f),
                                0.1f + 0.7f * ((h >> 16 & 0xff) / 255.0f));
    img.set(static_cast<int>(t % res), static_cast<int>(t / res), c);
  }
  writeSrgbPng(out / "objects.png", img, 8);
  const bool computed = prepare.at("phases").contains("segmentation");
  return figure("objects.png", fmt::format("objects ({}, each its own colour, lights white; {})",
                                           fit.appearance.objectCount(),
                                           computed ? "computed by prepare: the mesh has none" : "the mesh's own"));
}

// Albedo init / fit / truth (in the fit's atlas), coverage, objects, emission textures.
std::string texturesSection(const fs::path& work, const fs::path& out, const SceneDescription& fit,
                            const SceneDescription* truth, const Json& prepare, TruthComparison* scores) {
  // prepare's pictures: a work folder copied without them still gets its report.
  auto prepared = [&](const std::string& file, const std::string& caption) -> std::string {
    if (!pathExists(work / file)) {
      spdlog::warn("report: {} is missing (prepare writes it): figure skipped", (work / file).string());
      return "";
    }
    copyFileOver(work / file, out / file);
    return figure(file, caption);
  };
  std::string s = prepared("albedo_init.png", "albedo init (median)");
  Image albedo(fit.appearance.albedo.width, fit.appearance.albedo.height);
  albedo.rgb = fit.appearance.albedo.rgb;
  writeSrgbPng(out / "albedo.png", albedo, 8);
  s += figure("albedo.png", "albedo (fit)");
  const fs::path standardError = work / "result" / "albedo_stderr.png";
  if (pathExists(standardError)) {
    copyFileOver(standardError, out / "albedo_stderr.png");
    s += figure("albedo_stderr.png", "albedo standard error (black 0, white 0.1 or more: where the frames left it uncertain)");
  }
  if (truth) {
    Image truthAlbedo;
    TruthOptions options;
    if (const fs::path e = work / "result" / "albedo_stderr.exr"; pathExists(e)) options.albedoStandardError = readImage(e);
    *scores = compareWithTruth(fit, *truth, readImage(work / "coverage.exr"), options, &truthAlbedo);
    if (!truthAlbedo.rgb.empty()) {
      writeSrgbPng(out / "albedo_truth.png", truthAlbedo, 8);
      s += figure("albedo_truth.png", "albedo (truth, in the fit's atlas)");
    }
  }
  s += prepared("coverage.png", "coverage (observations per texel: black never, blue once, red most)");
  s += objectsFigure(out, fit, prepare);
  for (int o = 0; o < fit.appearance.objectCount(); ++o)
    if (const Texture* t = fit.appearance.emissionTexture(o)) {
      Image img(t->width, t->height);
      img.rgb = t->rgb;
      float peak = 0;
      for (float v : img.rgb) peak = std::max(peak, v);
      const std::string file = fmt::format("emission_{}.png", o);
      writePng(out / file, img, peak > 0 ? 1.0f / peak : 1.0f);
      s +=
          figure(file, fmt::format("emission of {} (divided by its peak {:.3g})", html(fit.appearance.names[o]), peak));
    }
  return s;
}

// Whether the frames show a highlight on the object, and if not, what that rules out.
std::string highlightCell(const Json& o) {
  if (o.at("highlight_observed").get<bool>()) return "yes: roughness and specular fitted";
  const Json bound = o.value("roughness_at_least", Json(nullptr));
  if (!bound.is_number()) return "no: roughness and specular not constrained";
  const Json sharper = o.value("or_sharper_than", Json(nullptr));
  return sharper.is_number() ? fmt::format("no: roughness at least {:.1f}, or below {:.2f} (a lobe too sharp to have "
                                           "pointed at a light from the frames' views)",
                                           bound.get<double>(), sharper.get<double>())
                             : fmt::format("no: roughness at least {:.1f}", bound.get<double>());
}

std::string materialsSection(const Json& materials, const SceneDescription* truth) {
  std::string s =
      "<table><tr><th>id</th><th>name</th><th>roughness</th><th>specular</th><th>emission</th><th>light</th>"
      "<th>highlights seen</th><th>texels observed</th>";
  if (truth) s += "<th>truth roughness</th><th>truth specular</th><th>truth emission</th>";
  s += "</tr>";
  auto rgb = [](const Json& e) {
    return fmt::format("{:.3g} {:.3g} {:.3g}", e[0].get<double>(), e[1].get<double>(), e[2].get<double>());
  };
  for (const Json& o : materials.at("objects")) {
    const int id =
        static_cast<int>(jsonInteger(o.at("id"), 0, INT32_MAX, "materials.json", "id"));  // indexes the truth
    s += fmt::format(
        "<tr><td>{}</td><td>{}</td><td>{:.3f}</td><td>{:.3f}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.0f}%</td>", id,
        html(o.at("name").get<std::string>()), o.at("roughness").get<double>(), o.at("specular").get<double>(),
        rgb(o.at("emission")),
        o.at("is_emitter").get<bool>()   ? "yes"
        : o.value("out_of_model", false) ? "out of model"
                                         : "",
        highlightCell(o), 100 * o.at("observed_texel_fraction").get<double>());
    if (truth && id < truth->appearance.objectCount()) {
      const Appearance& t = truth->appearance;
      const Color e = t.meanEmission(id);
      s += fmt::format("<td>{:.3f}</td><td>{:.3f}</td><td>{:.3g} {:.3g} {:.3g}</td>", t.roughness[id], t.specular[id],
                       e[0], e[1], e[2]);
    }
    s += "</tr>";
  }
  return s + "</table>";
}

// Each light-source decision (result/lights.json): per object, the verdict and its evidence.
std::string lightsSection(const fs::path& file) {
  if (!pathExists(file)) return "<p>No light-source decisions recorded.</p>";
  const Json lights = readJson(file);
  if (!lights.value("hint", Json::array()).empty())
    return "<p>The light sources were given (<code>lights</code>): " + html(lights["hint"].dump()) +
           "; no decision taken.</p>";
  const std::string test = lights.value("light_test", std::string());
  std::string s = test == "reflector"
                      ? "<p>Test <code>reflector</code>: an object is a light source when a reflector with albedo "
                        "&le; 1 and the model's specular lobe cannot return what its pixels show "
                        "(docs/design/light-sources.md).</p>"
                      : "<p>Test <code>" + html(test) + "</code>.</p>";
  for (const Json& d : lights.value("decisions", Json::array())) {
    if (const Json outline = d.value("silhouette_colour", Json()); outline.is_array()) {
      s += "<h3>Colours of the lights seen only saturated, from their outlines, after " +
           html(d.value("after", std::string())) +
           "</h3><table><tr><th>light</th><th>colour (luminance 1)</th><th>log error</th><th>pixels</th>"
           "<th>frames</th><th>used</th></tr>";
      const auto channels = [](const Json& v) {
        std::vector<std::string> text;
        if (!v.is_array()) return std::string("too few pixels");
        for (const Json& c : v) text.push_back(c.is_null() ? std::string("?") : fmt::format("{:.3f}", c.get<double>()));
        return fmt::format("{}", fmt::join(text, " "));
      };
      for (const Json& m : outline) {
        s += fmt::format("<tr><td>{} {}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>", m.value("id", 0),
                         html(m.value("name", std::string())), channels(m.value("colour", Json::array())),
                         channels(m.value("log_error", Json::array())), m.value("pixels", 0), m.value("frames", 0),
                         m.value("known", false) ? "yes" : "no: its colour kept");
      }
      s += "</table>";
      continue;
    }
    if (const Json scale = d.value("clipped_light_scale", Json()); scale.is_object()) {
      s += "<h3>Lights seen only saturated, after " + html(d.value("after", std::string())) + "</h3><p>" +
           html(scale.value("why", std::string())) + ".</p>";
      continue;
    }
    s += "<h3>After " + html(d.value("after", std::string())) +
         "</h3><table><tr><th>object</th><th>decision</th><th>rays</th>"
         "<th>observed</th><th>reflector bound</th><th>unexplained</th><th>power "
         "share</th><th>why</th><th>under-lit</th></tr>";
    for (const Json& o : d.value("objects", Json::array())) {
      if (o.value("decision", std::string()) == "not_a_candidate") continue;
      std::string under;
      if (const Json u = o.value("under_lit", Json()); u.is_object())
        under = fmt::format("{:.3g} missing; light from ({:.2f}, {:.2f}, {:.2f})", u.value("missing_radiance", 0.0),
                            u["light_from"][0].get<double>(), u["light_from"][1].get<double>(),
                            u["light_from"][2].get<double>());
      const double error = o.value("unexplained_error", -1.0);  // -1: fewer than 2 rays
      s += fmt::format(
          "<tr><td>{} {}</td><td>{}</td><td>{}</td><td>{:.3g}</td><td>{:.3g}</td><td>{:.0f}% &plusmn; {}</td>"
          "<td>{:.1f}%</td><td>{}</td><td>{}</td></tr>",
          o.value("id", 0), html(o.value("name", std::string())), html(o.value("decision", std::string())),
          o.value("rays", 0), o.value("observed", 0.0), o.value("reflector_bound", 0.0),
          100 * o.value("unexplained_share", 0.0),
          error < 0 ? std::string("?")
                    : fmt::format("{:.0f}%", 100 * error / std::max(1e-30, o.value("observed", 0.0))),
          100 * o.value("power_share", 0.0), html(o.value("why", std::string())), under);
    }
    s += "</table>";
  }
  return s;
}

// The frames' encodings and saturation (prepare.json) and, where the fit estimated them, their
// gains (result/frames.json).
std::string framesSection(const Json& prepare, const Json& gains, const Json& consistency) {
  const Json frames = prepare.at("phases").at("frames");
  std::string s = "<p>Encodings: ";
  const Json encodings = frames.value("encodings", Json::object());  // items() of a temporary would dangle
  for (const auto& [encoding, count] : encodings.items())
    s += fmt::format("{} frames {}; ", count.get<int>(), html(encoding));
  const Json saturated = frames.value("saturated_pixel_fraction", Json::object());
  double worst = 0;
  for (const auto& [frame, fraction] : saturated.items()) worst = std::max(worst, fraction.get<double>());
  s += fmt::format(
      "{} frames have saturated pixels (at most {:.1f}% of a frame); those pixels only bound the loss from "
      "below.</p>",
      saturated.size(), 100 * worst);
  if (gains.value("mode", std::string("none")) == "none")
    return s + "<p>Frame gains not estimated (<code>frame_gains</code>: every exposure known).</p>";
  s += fmt::format("<p>Frame gains estimated (<code>{}</code>), gauge: {}.</p>", html(gains["mode"].get<std::string>()),
                   html(gains.value("gauge", std::string())));
  std::map<uint32_t, uint32_t> ties;  // per frame: the texels that tie it to other frames (prepare's solve)
  const Json solved = consistency.value("frames", Json::array());
  for (const Json& f : solved) ties[f.value("frame", 0u)] = f.value("texels", 0u);
  s += "<table><tr><th>frame</th><th>image</th><th>gain R</th><th>gain G</th><th>gain B</th><th>texels tying it "
       "to other frames</th></tr>";
  const Json list = gains.value("frames", Json::array());
  for (const Json& f : list)
    s += fmt::format("<tr><td>{}</td><td>{}</td><td>{:.4f}</td><td>{:.4f}</td><td>{:.4f}</td><td>{}</td></tr>",
                     f.value("frame", 0), html(f.value("image", std::string())), f["gain"][0].get<double>(),
                     f["gain"][1].get<double>(), f["gain"][2].get<double>(), ties[f.value("frame", 0u)]);
  return s + "</table>";
}

// The frame gains of result/frames.json by frame (empty when not estimated).
std::map<uint32_t, Color> frameGainsOf(const Json& gains) {
  std::map<uint32_t, Color> out;
  if (gains.value("mode", std::string("none")) == "none") return out;
  const Json list = gains.value("frames", Json::array());
  for (const Json& f : list)
    out[f.at("frame").get<uint32_t>()] =
        Color(f["gain"][0].get<float>(), f["gain"][1].get<float>(), f["gain"][2].get<float>());
  return out;
}

// Per stage: a loss curve and the phase times of its last record (cumulative within the stage).
std::string stagesSection(const std::vector<Json>& metrics) {
  std::vector<std::string> order;
  std::map<std::string, std::pair<std::vector<double>, std::vector<double>>> curves;
  std::map<std::string, Json> last;
  for (const Json& m : metrics) {
    if (!m.is_object() || !m.contains("stage") || !m.contains("loss")) continue;
    const std::string stage = m["stage"].get<std::string>();
    if (!curves.count(stage)) order.push_back(stage);
    curves[stage].first.push_back(m.value("iteration", 0.0));
    curves[stage].second.push_back(m["loss"].get<double>());
    last[stage] = m;
  }
  std::string svgs, rows;
  for (const std::string& stage : order) {
    svgs += lossCurveSvg("loss, stage " + html(stage), curves[stage].first, curves[stage].second);
    const Json& m = last[stage];
    double total = 0;
    std::string phases;
    const Json seconds = m.value("seconds", Json::object());
    for (const auto& [phase, sec] : seconds.items()) {
      total += sec.get<double>();
      phases += fmt::format("{} {:.2f} s, ", phase, sec.get<double>());
    }
    rows +=
        fmt::format("<tr><td>{}</td><td>{}</td><td>{:.3e}</td><td>{:.1f} s</td><td>{}</td></tr>", html(stage),
                    m.value("stage_iteration", 0), m["loss"].get<double>(), total, phases.substr(0, phases.size() - 2));
  }
  return "<div class=\"curves\">" + svgs +
         "</div><table><tr><th>stage</th><th>iterations</th><th>final loss</th><th>time</th>"
         "<th>by phase</th></tr>" +
         rows + "</table>";
}

// With a time budget, what it chose (materials.json's time_budget; empty without one).
std::string budgetSentence(const Json& budget) {
  if (!budget.is_object()) return "";
  std::string lengths;
  for (const Json& stage : budget.value("iterations", Json::array()))
    lengths += fmt::format("{} {}, ", html(stage[0].get<std::string>()), stage[1].get<int>());
  const Json plan = budget.value("last_plan", Json::object());
  return fmt::format(
      "<p>Time budget {:.0f} s: the fit took {:.0f} s. Stage lengths chosen for it from the measured cost of the "
      "iterations: {}{}.</p>",
      budget.value("budget_seconds", 0.0), budget.value("fit_seconds", 0.0), lengths.substr(0, lengths.size() - 2),
      plan.contains("scale") ? fmt::format(" (the default schedule x{:.2f} in its last plan, at {:.1f} ms per "
                                           "iteration of {})",
                                           plan["scale"].get<double>(), plan.value("ms_per_iteration", 0.0),
                                           html(plan.value("stage", std::string())))
                             : std::string());
}

// With stop_on_convergence, where each albedo stage ended (materials.json's convergence; empty
// without it).
std::string convergenceSentence(const Json& convergence) {
  if (!convergence.is_object()) return "";
  std::string stages;
  for (const Json& st : convergence.value("stages", Json::array())) {
    const int at = st.value("converged_at", 0), n = st.value("iterations", 0), longest = st.value("longest", 0);
    stages += at > 0 ? fmt::format("{} converged after {} iterations{} (of at most {}), ", html(st.value("stage", "")), at,
                                   n > at ? fmt::format(" and settled until {}", n) : std::string(), longest)
                     : fmt::format("{} ran all its {} iterations, ", html(st.value("stage", "")), n);
  }
  return fmt::format(
      "<p>Albedo stages ended on convergence, once their albedo moved by at most {:.2f}x what its noise gives and "
      "its median standard error was at most {:.3f}: {}.</p>",
      convergence.value("ratio", 0.0), convergence.value("standard_error", 0.0), stages.substr(0, stages.size() - 2));
}

std::string prepareSection(const Json& prepare, const Json& materials) {
  std::string s = "<table><tr><th>phase</th><th>time</th></tr>";
  for (const auto& [phase, p] : prepare.at("phases").items())
    if (p.contains("seconds"))
      s += fmt::format("<tr><td>prepare: {}</td><td>{:.2f} s</td></tr>", html(phase), p["seconds"].get<double>());
  s += "</table>";
  s += fmt::format("<p>Peak RSS: prepare {:.0f} MiB, fit {:.0f} MiB.", prepare.value("peak_rss_mib", 0.0),
                   materials.value("peak_rss_mib", 0.0));
  // With a memory budget, what it predicted for each resolution and which it took.
  if (const Json plan = materials.value("memory_budget", Json()); plan.is_object()) {
    std::string predicted;
    for (const Json& e : plan.value("predicted", Json::array()))
      predicted += fmt::format("{} at {}^2, ", formatBytes(e.value("peak_bytes", 0.0)), e.value("resolution", 0));
    s += fmt::format(" Memory budget {}: predicted peak {}so the albedo went up to {}^2.",
                     formatBytes(plan.value("budget_bytes", 0.0)), predicted, plan.value("resolution", 0));
  }
  return s + "</p>";
}

}  // namespace

namespace {
fs::path writeReport(const fs::path& work, const ReportOptions& o) {
  const fs::path out = work / "report";
  createDirectories(out);
  const Json prepare = readJson(work / "prepare.json");
  const Json materials = readJson(work / "result" / "materials.json");
  const SceneDescription fit = loadSceneFile(work / "result" / "scene.json");
  const fs::path capture = capturePreparedIn(work);
  const fs::path truthFile = capture / "gt" / "scene.json";
  const fs::path gainsFile = work / "result" / "frames.json";
  const Json gains = pathExists(gainsFile) ? readJson(gainsFile) : Json::object();
  std::optional<SceneDescription> truthScene;
  if (pathExists(truthFile)) truthScene = loadSceneFile(truthFile);
  const SceneDescription* truth = truthScene ? &*truthScene : nullptr;  // scored: null when on other triangles
  TruthComparison scores;
  std::string textures;
  try {
    textures = texturesSection(work, out, fit, truth, prepare, &scores);
  } catch (const Error& e) {  // a truth on other triangles (the `scan` capture) cannot be scored texel by texel
    spdlog::warn("report: truth not compared: {}", e.what());
    truth = nullptr;
    textures = texturesSection(work, out, fit, nullptr, prepare, &scores);
  }
  std::string page = R"(<!DOCTYPE html><html><head><meta charset="utf-8"><title>relume fit report</title><style>
body{font-family:sans-serif;margin:1.5em;max-width:1400px} table{border-collapse:collapse;margin:.5em 0}
td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px;text-align:left} td img{image-rendering:pixelated;width:320px}
img.tex{width:256px;height:256px} figure{display:inline-block;margin:4px} figcaption{font-size:12px;max-width:256px}
.curves svg{margin:4px} pre{background:#f4f4f4;padding:8px;font-size:12px}</style></head><body>)";
  page += fmt::format(
      "<h1>relume fit report</h1><p>Work folder <code>{}</code>; capture <code>{}</code>. {} iterations, final "
      "loss {:.3e}, albedo {}&sup2;.</p>",
      html(absolutePath(work).string()), html(capture.string()), materials.value("iterations", 0),
      materials.value("final_loss", 0.0), materials.value("albedo_resolution", 0));
  if (truth)
    page += fmt::format(
        "<p>Against the capture's ground truth: albedo MAE {:.4f} (PSNR {:.2f} dB) over {} texels observed "
        "&ge; 5 times; roughness MAE {:.3f}, specular MAE {:.3f} over the {} objects that are no light ({:.3f}, "
        "{:.3f} over the {} with observed highlights); emitters {}/{} found; emission error {:.1f}%. "
        "Peers' measures: albedo PSNR {:.2f} dB and roughness PSNR {:.2f} dB on 8-bit maps, emission IoU {:.3f}.</p>",
        scores.albedoMae, scores.albedoPsnr, scores.albedoTexels, scores.roughnessMaeAll, scores.specularMaeAll,
        scores.opaqueObjects, scores.roughnessMae, scores.specularMae, scores.materialObjects, scores.emittersCorrect,
        scores.emittersTrue, 100 * scores.emissionRelError, scores.albedoPsnr8,
        scores.roughnessPsnr8, scores.emissionIou);
  if (truth && scores.albedoStandardErrorRms >= 0)
    page += fmt::format(
        "<p>The albedo's own standard errors over the same texels: RMS {:.4f} against an error RMS of {:.4f}; "
        "{:.1f}% of the errors are within two of them (95% if they are honest and the albedo unbiased).</p>",
        scores.albedoStandardErrorRms, scores.albedoErrorRms(), 100 * scores.albedoWithinTwoStandardErrors);
  page += "<h2>Views</h2>";
  try {
    page += viewsSection(out, fit, truthScene ? &*truthScene : nullptr, prepare, frameGainsOf(gains),
                         o);  // any truth renders
  } catch (const Error& e) {  // the capture moved or lost images: the rest of the report still stands
    spdlog::warn("report: views not rendered: {}", e.what());
    page += "<p>Views not rendered: " + html(e.what()) + "</p>";
  }
  page += "<h2>Textures</h2>" + textures;
  page += "<h2>Where the reconstruction is guessed</h2>" + confidenceSection(work, out);
  page += "<h2>Materials</h2>" + materialsSection(materials, truth);
  page += "<h2>Light sources</h2>" + lightsSection(work / "result" / "lights.json");
  const fs::path consistencyFile = work / "frame_gains.json";
  page += "<h2>Frames</h2>" +
          framesSection(prepare, gains, pathExists(consistencyFile) ? readJson(consistencyFile) : Json::object());
  page += "<h2>Loss and time per stage</h2>" + budgetSentence(materials.value("time_budget", Json())) +
          convergenceSentence(materials.value("convergence", Json())) +
          stagesSection(readJsonLines(work / "metrics.jsonl"));
  page += "<h2>Prepare and memory</h2>" + prepareSection(prepare, materials);
  page += "<h2>Config</h2><pre>" + html(materials.value("config", Json::object()).dump(2)) + "</pre></body></html>\n";
  writeTextAtomically(out / "index.html", page);
  spdlog::info("fit: report {}", (out / "index.html").string());
  return out / "index.html";
}

}  // namespace

// The work folder's JSON files (prepare.json, result/*.json) are relume's own, but may have been
// edited or truncated: a field of the wrong type is an error naming the folder.
fs::path writeFitReport(const fs::path& work, const ReportOptions& o) {
  return withJsonErrors(work, [&] { return writeReport(work, o); });
}

}  // namespace relume
