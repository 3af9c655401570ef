// `phongfit brdf`: a polar plot of the lobe and a CSV of f and every sampler's pdf over the plane
// of incidence, to see what parameters mean and to check samplers against the BRDF.
#include <fmt/format.h>

#include <charconv>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include "atomic_file.h"
#include "color_option.h"
#include "commands.h"
#include "error.h"
#include "image.h"
#include "lobe_plot.h"
#include "phong_sampler.h"

namespace phongfit {
namespace {

struct BrdfOptions {
    std::string kd = "0.5", ks = "0.3";
    std::vector<double> exponents;
    double thetaODeg = 30;
    std::string plotPath, csvPath;
    bool logRadius = false;
};

// One row per (n, theta_i): theta_i from -90 to 90 degrees in 0.5 degree steps, negative on the
// side of wo, so the mirror direction is at +theta_o.
std::string samplerTable(const Color3& kd, const Color3& ks, const std::vector<double>& exponents,
                         double thetaODeg, std::size_t& rows) {
    std::vector<std::unique_ptr<PhongSampler<double>>> samplers;
    std::string out = "theta_i_deg,n,f_r,f_g,f_b";
    for (const std::string& name : phongSamplerNames()) {
        samplers.push_back(makePhongSampler<double>(name));
        out += ",pdf_" + name;
    }
    out += '\n';
    const Vec3d wo = planeOfIncidenceDirection(-thetaODeg);
    rows = 0;
    for (double n : exponents) {
        const PhongMaterial m{kd, ks, n};
        for (int i = 0; i <= 360; ++i) {
            const double theta = -90 + 0.5 * i;
            const Vec3d wi = planeOfIncidenceDirection(theta);
            const Color3 f = phongEval(m, wi, wo);
            out += fmt::format("{},{},{},{},{}", theta, n, f[0], f[1], f[2]);
            for (const auto& sampler : samplers) out += fmt::format(",{}", sampler->pdf(m, wo, wi));
            out += '\n';
            ++rows;
        }
    }
    return out;
}

void writeText(const std::string& path, const std::string& text) {
    writeAtomically(path, [&](const std::filesystem::path& temporary) {
        std::ofstream out(temporary, std::ios::binary);
        out << text;
        out.close();
        if (!out) throw Error(fmt::format("cannot write '{}': I/O error", path));
    });
}

void runBrdf(const BrdfOptions& options) {
    const Color3 kd = parseColorOption(options.kd, "--kd"),
                 ks = parseColorOption(options.ks, "--ks");
    for (double n : options.exponents) validatePhong(PhongMaterial{kd, ks, n}, "brdf options");
    if (!(options.thetaODeg >= 0 && options.thetaODeg < 90))
        throw Error(fmt::format("--theta-o {}: the viewing angle must be in [0, 90) degrees",
                                options.thetaODeg));

    const cv::Mat plot =
        plotLobes({kd, ks, options.exponents, options.thetaODeg, options.logRadius});
    std::size_t rows = 0;
    const std::string table =
        options.csvPath.empty() ? std::string()
                                : samplerTable(kd, ks, options.exponents, options.thetaODeg, rows);
    writePng(plot, options.plotPath);
    std::string wrote = fmt::format("wrote {} ({}x{}, f cos(theta_i), {} radius)", options.plotPath,
                                    plot.cols, plot.rows, options.logRadius ? "log" : "linear");
    if (!options.csvPath.empty()) {
        writeText(options.csvPath, table);
        wrote += fmt::format(" and {} ({} rows)", options.csvPath, rows);
    }
    fmt::print("{}\n", wrote);
}

}  // namespace

void addBrdfCommand(CLI::App& app) {
    auto options = std::make_shared<BrdfOptions>();
    CLI::App* cmd =
        app.add_subcommand("brdf", "plot the Phong lobe and write f and each sampler's pdf");
    cmd->add_option("--kd", options->kd, "diffuse reflectance: R,G,B or one grey value")
        ->capture_default_str();
    cmd->add_option("--ks", options->ks, "specular reflectance: R,G,B or one grey value")
        ->capture_default_str();
    cmd->add_option("--n", options->exponents, "Phong exponent; repeat (or N1,N2) for several")
        ->required()
        ->delimiter(',');
    cmd->add_option("--theta-o", options->thetaODeg, "angle of wo from the normal, degrees")
        ->capture_default_str();
    cmd->add_option("-o,--output", options->plotPath, "plot, PNG")->required();
    cmd->add_option("--csv", options->csvPath,
                    "table of f and each sampler's pdf over theta_i in the plane of incidence");
    cmd->add_flag("--log", options->logRadius,
                  "log-scale radius, so the diffuse part of a sharp lobe stays visible");
    cmd->callback([options] { runBrdf(*options); });
}

}  // namespace phongfit
