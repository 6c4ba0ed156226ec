// Enumerations that users name in text (config keys, command-line options): one table of names
// per enum, parsed once at the boundary, with an error that names the option and the choices.
// A module declares its table beside its enum:
//   template <> struct EnumNames<Pairing> {
//     static constexpr std::array<std::pair<Pairing, std::string_view>, 3> values{{...}};
//   };
#pragma once
#include <string>
#include <string_view>
#include <utility>

#include "core/error.h"

namespace relume {

template <typename E>
struct EnumNames;

template <typename E>
const char* enumName(E value) {
  for (const auto& [v, name] : EnumNames<E>::values)
    if (v == value) return name.data();  // the table's names are string literals
  return "?";
}

// "a, b or c": the names a value may take.
template <typename E>
std::string enumChoices() {
  std::string s;
  const auto& values = EnumNames<E>::values;
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) s += i + 1 == values.size() ? " or " : ", ";
    s += values[i].second;
  }
  return s;
}

template <typename E>
bool enumFromName(std::string_view text, E& out) {
  for (const auto& [v, name] : EnumNames<E>::values)
    if (name == text) {
      out = v;
      return true;
    }
  return false;
}

// `what` names the option in the error ("--pairing", "fit.json: 'sampler'").
template <typename E>
E parseEnum(std::string_view text, std::string_view what) {
  E value{};
  if (!enumFromName(text, value)) fail("{} must be {}, not '{}'", what, enumChoices<E>(), text);
  return value;
}

}  // namespace relume
