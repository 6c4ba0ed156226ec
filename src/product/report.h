// WORK/report/index.html: what a fit did, readable offline in any browser. Self-contained (images
// beside it, loss curves as inline SVG drawn from metrics.jsonl, no scripts, no network):
// reference / re-render / error / the noise in that error for a few frames (the error is
// |fit - truth|, both rendered with the same random numbers, when the capture has a ground truth),
// albedo (init, fit, truth when the capture has one), coverage, emission textures, the
// per-object material table, per-stage loss curves and timings, peak memory, and the config.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

namespace relume {

struct ReportOptions {
  int frames = 3;  // views shown (spread over the kept frames)
  int spp = 16;    // samples per pixel of their re-renders (the fit's, and the truth's when there is one)
};

// Reads WORK (prepare.json, metrics.jsonl, result/) and writes WORK/report/; returns index.html.
std::filesystem::path writeFitReport(const std::filesystem::path& work, const ReportOptions& options = {});

struct ChartSeries {
  std::string name;  // legend entry (none when empty)
  std::vector<double> x, y;
};
// A line chart, one polyline per series, with min/max labels and a legend; standalone <svg>
// text. Non-finite y values are skipped, and on a log-y axis non-positive ones too.
std::string lineChartSvg(const std::string& title, const std::string& xLabel, const std::vector<ChartSeries>& series,
                         bool logY);
// The loss of one stage against the iteration, log-y.
std::string lossCurveSvg(const std::string& title, const std::vector<double>& x, const std::vector<double>& y);

}  // namespace relume
