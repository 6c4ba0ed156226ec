// One error type for every bad input: a one-line message naming the file and what is wrong.
#pragma once
#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace relume {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

template <typename... Args>
[[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace relume
