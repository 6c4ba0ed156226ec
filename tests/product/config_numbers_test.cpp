// A fit config's numbers are read in the type they are used in: an integer that does not fit an
// int or a negative seed is an error naming the key, never a wrapped value.
#include <gtest/gtest.h>

#include <string>

#include "core/error.h"
#include "product/fit_config.h"

using namespace relume;

TEST(FitConfigNumbers, OutOfTypeNumbersAreRefused) {
  for (const auto& [json, key] : std::vector<std::pair<std::string, std::string>>{
           {R"({"batch_texels": 4294967297})", "batch_texels"},  // would wrap onto 1
           {R"({"seed": -1})", "seed"}}) {
    try {
      FitConfig::fromJson(Json::parse(json), "config.json", FitConfig{});
      ADD_FAILURE() << json << ": no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("'" + key + "'"), std::string::npos) << e.what();
    }
  }
}
