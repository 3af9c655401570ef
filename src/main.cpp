// The phongfit command line: each module adds its subcommand; errors become one line and exit 1.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "commands.h"
#include "error.h"

int main(int argc, char** argv) {
    CLI::App app{"phongfit: recover Modified Phong BRDF parameters from images, and render with them"};
    app.require_subcommand(1);
    phongfit::addCommands(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "phongfit: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
