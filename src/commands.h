// Subcommands of the phongfit executable; each module defines its own.
#pragma once

#include <CLI/CLI.hpp>

namespace phongfit {

void addBrdfCommand(CLI::App& app);
void addRenderCommand(CLI::App& app);
void addFitCommand(CLI::App& app);
void addDemoCommand(CLI::App& app);

inline void addCommands(CLI::App& app) {
    addBrdfCommand(app);
    addRenderCommand(app);
    addFitCommand(app);
    addDemoCommand(app);
}

}  // namespace phongfit
