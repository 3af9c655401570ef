// The phongfit command line: each module adds its subcommand; errors become one line and exit 1.
// SIGINT/SIGTERM are caught here, once: the libraries only poll interruptRequested().
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "commands.h"
#include "error.h"
#include "interrupt.h"
#include "memory_info.h"

int main(int argc, char** argv) {
    phongfit::mapLargeBuffers();
    CLI::App app{
        "phongfit: recover Modified Phong BRDF parameters from images, and render with them"};
    app.require_subcommand(1);
    phongfit::addCommands(app);
    phongfit::installInterruptHandler();
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        // One line, like every other error (CLI11 would add a "Run with --help" line).
        std::fprintf(stderr, "phongfit: error: %s (see phongfit --help)\n", e.what());
        return e.get_exit_code() != 0 ? e.get_exit_code() : 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "phongfit: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
