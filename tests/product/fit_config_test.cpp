// The fit configuration: its reference in docs/user/fit-config.md lists exactly the keys the code
// reads, with the code's defaults; enumerations are named in JSON and rejected with the choices.
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace relume
