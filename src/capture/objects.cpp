#include "capture/objects.h"

#include <charconv>

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
      if (!o.is_object() || !o.contains("id") || !o["id"].is_number_integer() || o["id"].get<int>() < 0)
        fail("{}: objects[{}] needs a non-negative integer 'id'", file, i);
      if (!o.contains("name") || !o["name"].is_string()) fail("{}: objects[{}] needs a string 'name'", file, i);
      names[o["id"].get<int>()] = o["name"].get<std::string>();
    }
    return names;
  }
  for (const auto& [key, value] : j.items()) {
    int id = -1;
    const auto [ptr, ec] = std::from_chars(key.data(), key.data() + key.size(), id);
    if (ec != std::errc() || ptr != key.data() + key.size() || id < 0) fail("{}: key '{}' is not an object id", file, key);
    if (!value.is_string()) fail("{}: name of object {} must be a string", file, id);
    names[id] = value.get<std::string>();
  }
  return names;
}

std::map<int, std::string> readObjectNames(const std::filesystem::path& path) {
  return withJsonErrors(path, [&] { return parseObjectNames(path); });
}

}  // namespace relume
