#include "capture/objects.h"

#include <charconv>
#include <limits>

#include "core/error.h"
#include "io/json.h"

namespace relume {

static std::map<int, std::string> parseObjectNames(const std::filesystem::path& path) {
  const Json j = readJson(path);
  const std::string file = path.string();
  std::map<int, std::string> names;
  if (!j.is_object()) fail("{}: top level must be an object", file);
  if (j.contains("objects")) {
    if (!j["objects"].is_array()) fail("{}: 'objects' must be an array", file);
    for (size_t i = 0; i < j["objects"].size(); ++i) {
      const Json& o = j["objects"][i];
      // Read as 64-bit: get<int>() would wrap 4294967296 onto object 0.
      if (!o.is_object() || !o.contains("id") || !o["id"].is_number_integer() || o["id"].get<int64_t>() < 0 ||
          o["id"].get<int64_t>() > std::numeric_limits<int>::max())
        fail("{}: objects[{}] needs an integer 'id' in [0, {}]", file, i, std::numeric_limits<int>::max());
      if (!o.contains("name") || !o["name"].is_string()) fail("{}: objects[{}] needs a string 'name'", file, i);
      names[static_cast<int>(o["id"].get<int64_t>())] = o["name"].get<std::string>();
    }
    return names;
  }
  for (const auto& [key, value] : j.items()) {
    int id = -1;
    const auto [ptr, ec] = std::from_chars(key.data(), key.data() + key.size(), id);
    if (ec != std::errc() || ptr != key.data() + key.size() || id < 0)
      fail("{}: key '{}' is not an object id", file, key);
    if (!value.is_string()) fail("{}: name of object {} must be a string", file, id);
    names[id] = value.get<std::string>();
  }
  return names;
}

std::map<int, std::string> readObjectNames(const std::filesystem::path& path) {
  return withJsonErrors(path, [&] { return parseObjectNames(path); });
}

}  // namespace relume
