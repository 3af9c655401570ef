// Subcommands of the phongfit executable; each module defines its own. With `parseOnly`, a
// command checks its arguments and does nothing (phongfit slurm checks what it will submit).
#pragma once

#include <CLI/CLI.hpp>

namespace phongfit {

void addBrdfCommand(CLI::App& app);
void addRenderCommand(CLI::App& app);
void addFitCommand(CLI::App& app);
void addDemoCommand(CLI::App& app);
void addHdrMergeCommand(CLI::App& app);
void addSynthCommand(CLI::App& app, bool parseOnly = false);
void addBenchCommand(CLI::App& app, bool parseOnly = false);
void addSlurmCommand(CLI::App& app);

inline void addCommands(CLI::App& app) {
    addBrdfCommand(app);
    addRenderCommand(app);
    addFitCommand(app);
    addDemoCommand(app);
    addHdrMergeCommand(app);
    addSynthCommand(app);
    addBenchCommand(app);
    addSlurmCommand(app);
}

}  // namespace phongfit
