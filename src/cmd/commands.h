// Subcommands of the phongfit executable; each module defines its own.
#pragma once

#include <CLI/CLI.hpp>

namespace phongfit {

void addBrdfCommand(CLI::App& app);
void addRenderCommand(CLI::App& app);
void addFitCommand(CLI::App& app);
void addDemoCommand(CLI::App& app);
void addHdrMergeCommand(CLI::App& app);
void addSynthCommand(CLI::App& app);
void addBenchCommand(CLI::App& app);

inline void addCommands(CLI::App& app) {
    addBrdfCommand(app);
    addRenderCommand(app);
    addFitCommand(app);
    addDemoCommand(app);
    addHdrMergeCommand(app);
    addSynthCommand(app);
    addBenchCommand(app);
}

}  // namespace phongfit
