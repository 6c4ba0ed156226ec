// The fit configuration: its reference in docs/user/fit-config.md lists exactly the keys the code
// reads, with the code's defaults; enumerations are named in JSON and rejected with the choices.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>

#include "core/error.h"
#include "product/fit_config.h"

namespace relume {
namespace {

// key -> default literal, from the rows of every "| key | default | range | meaning |" table.
std::map<std::string, std::string> documentedKeys(const std::filesystem::path& file) {
  std::ifstream in(file);
  EXPECT_TRUE(in) << file;
  std::map<std::string, std::string> keys;
  const std::regex row(R"(^\| `([a-z_0-9]+)` \| `([^`]*)` \|)");
  bool inTable = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("| key | default | range | meaning |", 0) == 0)
      inTable = true;
    else if (line.rfind("|", 0) != 0)
      inTable = false;
    std::smatch m;
    if (inTable && std::regex_search(line, m, row)) {
      EXPECT_FALSE(keys.count(m[1])) << m[1] << " is documented twice";
      keys[m[1]] = m[2];
    }
  }
  return keys;
}

TEST(FitConfig, TheReferenceListsEveryKeyWithItsDefault) {
  const auto doc =
      documentedKeys(std::filesystem::path(RELUME_TEST_DATA) / ".." / ".." / "docs" / "user" / "fit-config.md");
  const Json code = FitConfig{}.toJson();
  ASSERT_GT(code.size(), 50u);
  for (const auto& [key, value] : code.items()) {
    const auto it = doc.find(key);
    if (it == doc.end()) {
      ADD_FAILURE() << "docs/user/fit-config.md does not list '" << key << "'";
      continue;
    }
    const Json documented = Json::parse(it->second, nullptr, false);
    ASSERT_FALSE(documented.is_discarded()) << key << ": default `" << it->second << "` is not a JSON literal";
    if (value.is_number() && documented.is_number())
      EXPECT_NEAR(documented.get<double>(), value.get<double>(), 1e-6 * std::abs(value.get<double>())) << key;
    else
      EXPECT_EQ(documented, value) << key;
  }
  for (const auto& [key, value] : doc)
    EXPECT_TRUE(code.contains(key)) << "docs/user/fit-config.md lists '" << key << "', which no code reads";
}

TEST(FitConfig, EnumerationsAreNamesAndOthersAreRejectedWithTheChoices) {
  const FitConfig c =
      FitConfig::fromJson(Json::parse(R"({"sampler": "image", "albedo_step": "adam", "light_test": "radiance_fraction",
                                                          "ray_footprint": "pixel", "pairing": "reuse"})"),
                          "test", FitConfig{});
  EXPECT_EQ(c.sampler, SamplerKind::Image);
  EXPECT_EQ(c.albedoStep, AlbedoStep::Adam);
  EXPECT_EQ(c.lightTest, LightTest::RadianceFraction);
  EXPECT_EQ(c.rayFootprint, RayFootprint::Pixel);
  EXPECT_EQ(c.pairing, Pairing::Reuse);
  EXPECT_EQ(c.toJson()["albedo_step"], "adam");
  EXPECT_EQ(FitConfig::fromJson(c.toJson(), "round trip", FitConfig{}).toJson(), c.toJson());
  try {
    FitConfig::fromJson(Json::parse(R"({"albedo_step": "newton"})"), "fit.json", FitConfig{});
    ADD_FAILURE() << "an unknown albedo_step was accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "fit.json: 'albedo_step' must be gauss-newton or adam, not \"newton\"");
  }
  EXPECT_THROW(FitConfig::fromJson(Json::parse(R"({"sampler": 1})"), "fit.json", FitConfig{}), Error);
}

// `relume fit --quality`: a quality is a schedule, never another method, and what docs/user
// lists for it; a config file's keys apply over it.
TEST(FitConfig, QualitiesAreSchedulesAsDocumentedAndAConfigFileAppliesOverThem) {
  const std::vector<std::string> lengths = {"emission_iterations", "max_stage_iterations", "material_iterations",
                                            "emission_texture_iterations"};
  const Json standard = FitConfig{}.toJson();
  EXPECT_EQ(FitConfig::forQuality(FitQuality::Default).toJson(), standard);
  const Json draft = FitConfig::forQuality(FitQuality::Draft).toJson();
  const Json best = FitConfig::forQuality(FitQuality::Best).toJson();
  for (const auto& [key, value] : standard.items()) {
    if (std::find(lengths.begin(), lengths.end(), key) != lengths.end()) continue;
    EXPECT_EQ(draft[key], value) << key << " differs in draft";
    EXPECT_EQ(best[key], value) << key << " differs in best";
  }
  for (const std::string& key : lengths) {
    EXPECT_LT(draft[key].get<int>(), standard[key].get<int>()) << key;
    EXPECT_GE(best[key].get<int>(), standard[key].get<int>()) << key;
  }
  EXPECT_GT(best["max_stage_iterations"].get<int>(), standard["max_stage_iterations"].get<int>());

  // docs/user/fit-config.md's table: "| `draft` | 100 | 500 | 150 | 50 |", in the order of `lengths`.
  std::ifstream in(std::filesystem::path(RELUME_TEST_DATA) / ".." / ".." / "docs" / "user" / "fit-config.md");
  const std::regex row(R"(^\| `(draft|default|best)` \| (\d+) \| (\d+) \| (\d+) \| (\d+) \|)");
  std::map<std::string, Json> documented;
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (!std::regex_search(line, m, row)) continue;
    Json& q = documented[m[1]];
    for (size_t i = 0; i < lengths.size(); ++i) q[lengths[i]] = std::stoi(m[i + 2]);
  }
  ASSERT_EQ(documented.size(), 3u) << "docs/user/fit-config.md has no row for some quality";
  for (const FitQuality q : {FitQuality::Draft, FitQuality::Default, FitQuality::Best}) {
    const Json code = FitConfig::forQuality(q).toJson();
    for (const std::string& key : lengths) EXPECT_EQ(documented[enumName(q)][key], code[key]) << enumName(q) << " " << key;
  }

  const std::filesystem::path file = std::filesystem::temp_directory_path() / "relume_quality_over.json";
  std::ofstream(file) << R"({"material_iterations": 77})";
  const FitConfig over = FitConfig::load(file, FitConfig::forQuality(FitQuality::Draft));
  EXPECT_EQ(over.materialIterations, 77);
  EXPECT_EQ(over.maxStageIterations, 500);
  EXPECT_EQ(FitConfig::load(file).maxStageIterations, FitConfig{}.maxStageIterations);
  std::filesystem::remove(file);
}

}  // namespace
}  // namespace relume
