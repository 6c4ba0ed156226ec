#pragma once
#include <CLI/CLI.hpp>
#include <functional>
#include <map>

namespace relume {
using CommandTable = std::map<const CLI::App*, std::function<int()>>;
// Each subcommand binds its options to state captured by its action.
CommandTable registerCommands(CLI::App& app);
}  // namespace relume
