// A file's bytes, for tests that compare two runs' outputs byte for byte.
#pragma once
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace relume {

inline std::string fileBytes(const std::filesystem::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace relume
