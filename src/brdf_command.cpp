#include "commands.h"

namespace phongfit {

void addBrdfCommand(CLI::App& app) {
    app.add_subcommand("brdf", "plot the Phong lobe and write f and each sampler's pdf");
}

}  // namespace phongfit
