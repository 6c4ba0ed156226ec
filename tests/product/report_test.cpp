// The fit report: written by `fit`, self-contained (every image beside the page, nothing remote),
// a loss curve per stage drawn from metrics.jsonl, a material row per object.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "io/json.h"
#include "product/fit.h"
#include "product/report.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

TEST(Report, FitWritesASelfContainedPageWithCurvesImagesAndMaterials) {
  SynthCaptureOptions so;
  so.kind = SynthSceneKind::Cornell;
  so.frames = 4, so.testFrames = 0, so.width = 32, so.height = 24, so.spp = 2, so.atlasResolution = 64, so.maxDepth = 3;
  const fs::path dir = preparedCapture("report", so, 64);
  FitConfig fc;
  fc.batchTexels = 256, fc.maxDepth = 2, fc.emissionIterations = 20, fc.materialIterations = 10, fc.albedoPasses = 1;
  fc.emissionTextureIterations = 0, fc.checkpointEvery = 1000, fc.metricsEvery = 2;
  runFit(dir / "work", fc, false);
  EXPECT_FALSE(fs::exists(dir / "work" / "report")) << "the fit writes its result; the report is the command's";
  const fs::path page = writeFitReport(dir / "work");
  EXPECT_EQ(page, dir / "work" / "report" / "index.html");
  ASSERT_TRUE(fs::exists(page));
  std::stringstream ss;
  ss << std::ifstream(page).rdbuf();
  const std::string html = ss.str();
  int images = 0;
  const std::regex src(R"re((src|href)="([^"]*)")re");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), src); it != std::sregex_iterator(); ++it, ++images) {
    const std::string file = (*it)[2];
    EXPECT_EQ(file.find('/'), std::string::npos) << file;  // beside the page: no path, no URL
    EXPECT_TRUE(fs::exists(page.parent_path() / file)) << file;
  }
  EXPECT_GE(images, 3 * 4 + 4);  // 3 views x (reference, render, error, noise) + init, fit, truth albedo, coverage
  // The capture has a ground truth: the views' error is the fit's against it, with the same random numbers.
  EXPECT_NE(html.find("with the same random numbers"), std::string::npos);
  EXPECT_NE(html.find("error |fit - truth|"), std::string::npos);
  // One curve per stage that logged metrics, each a polyline with a point per record.
  size_t records = 0;
  std::ifstream metrics(dir / "work" / "metrics.jsonl");
  for (std::string line; std::getline(metrics, line);) records += !line.empty();
  const std::regex polyline(R"re(<polyline[^>]*points="([^"]*)")re");
  size_t curves = 0, points = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), polyline); it != std::sregex_iterator();
       ++it, ++curves) {
    const std::string p = (*it)[1];
    points += static_cast<size_t>(std::count(p.begin(), p.end(), ','));
  }
  EXPECT_EQ(curves, 3u);  // emission, albedo@64, materials
  EXPECT_EQ(points, records);
  const Json materials =
      readJson(dir / "work" / "result" / "materials.json");  // a range-for over a temporary's member dangles
  for (const Json& o : materials["objects"])
    EXPECT_NE(html.find("<td>" + o["name"].get<std::string>() + "</td>"), std::string::npos);
  EXPECT_NE(html.find("\"lr_albedo\""), std::string::npos);  // the config
  // The light-source decisions: a table per decision. No frame of this capture sees the box's
  // light, so the last decision finds the walls under-lit, with the direction of the missing light.
  EXPECT_NE(html.find("<h2>Light sources</h2>"), std::string::npos);
  const Json lights = readJson(dir / "work" / "result" / "lights.json");
  ASSERT_FALSE(lights["decisions"].empty());
  for (const Json& d : lights["decisions"])
    EXPECT_NE(html.find("<h3>After " + d["after"].get<std::string>() + "</h3>"), std::string::npos);
  EXPECT_NE(html.find("missing; light from"), std::string::npos);
  // The colours of lights seen only saturated, from their outlines: a table row per light.
  Json withOutline = lights;
  withOutline["decisions"].push_back(
      {{"after", "emission"},
       {"silhouette_colour", Json::array({{{"id", 1}, {"name", "lamp"}, {"colour", {1.1, 0.98, 0.8}},
                                           {"log_error", {0.01, 0.002, nullptr}}, {"pixels", 40}, {"frames", 3},
                                           {"known", true}}})}});
  writeJson(dir / "work" / "result" / "lights.json", withOutline);
  writeFitReport(dir / "work");
  std::stringstream outline;
  outline << std::ifstream(page).rdbuf();
  EXPECT_NE(outline.str().find("from their outlines, after emission</h3>"), std::string::npos);
  EXPECT_NE(outline.str().find("<td>1 lamp</td><td>1.100 0.980 0.800</td><td>0.010 0.002 ?</td><td>40</td><td>3</td>"
                               "<td>yes</td>"),
            std::string::npos);
  // A work folder copied without prepare's pictures still gets its report, without those figures.
  fs::remove(dir / "work" / "albedo_init.png");
  fs::remove(dir / "work" / "report" / "albedo_init.png");
  EXPECT_NO_THROW(writeFitReport(dir / "work"));
  std::stringstream again;
  again << std::ifstream(page).rdbuf();
  EXPECT_EQ(again.str().find("albedo_init.png"), std::string::npos);
  EXPECT_NE(again.str().find("coverage.png"), std::string::npos);
  // Without a ground truth (a real capture) the error is against the frames, beside the re-render's own noise.
  fs::remove(dir / "capture" / "gt" / "scene.json");
  writeFitReport(dir / "work", {2, 4});
  std::stringstream photo;
  photo << std::ifstream(page).rdbuf();
  EXPECT_NE(photo.str().find("error |re-render - frame|"), std::string::npos);
  EXPECT_NE(photo.str().find("re-render's own Monte Carlo noise"), std::string::npos);
  EXPECT_EQ(photo.str().find("same random numbers"), std::string::npos);
}

TEST(Report, LossCurveSkipsNonPositiveLossesOnItsLogAxis) {
  const std::string svg = lossCurveSvg("t", {1, 2, 3, 4}, {1.0, 0.0, 0.01, -1.0});
  const std::smatch m = [&] {
    std::smatch r;
    std::regex_search(svg, r, std::regex(R"re(points="([^"]*)")re"));
    return r;
  }();
  ASSERT_EQ(m.size(), 2u);
  const std::string points = m[1];
  EXPECT_EQ(std::count(points.begin(), points.end(), ','), 2);
  EXPECT_NE(svg.find(">1<"), std::string::npos);     // top label: the largest loss
  EXPECT_NE(svg.find(">0.01<"), std::string::npos);  // bottom label: the smallest
  EXPECT_NE(lossCurveSvg("t", {}, {}).find("no data"), std::string::npos);
}
