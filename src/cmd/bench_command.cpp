// phongfit bench render SCENE.xml ... -o DIR  and  phongfit bench fit DATASET_DIR ... -o DIR
// [--shard I/N], phongfit bench fit --merge DIR
#include <fmt/format.h>

#include <optional>

#include "bench_fit.h"
#include "bench_render.h"
#include "color_option.h"
#include "commands.h"
#include "error.h"

namespace phongfit {

void addBenchCommand(CLI::App& app, bool parseOnly) {
    CLI::App* bench = app.add_subcommand(
        "bench", "error against run time: of the samplers (render), of the fitter (fit)");
    bench->require_subcommand(1);

    auto r = std::make_shared<BenchRenderOptions>();
    CLI::App* render = bench->add_subcommand(
        "render",
        "RMSE, relative MSE and efficiency against time of every sampler, with and without MIS");
    render->add_option("scene", r->scene, "scene file (Mitsuba 0.6 XML subset)")->required();
    render->add_option("-o,--output", r->output, "output directory")->required();
    render->add_option("--reference", r->reference,
                       "reference EXR (default: rendered with the defaults at --reference-spp)");
    render->add_option("--reference-spp", r->referenceSpp, "spp of the rendered reference")
        ->check(CLI::Range(1, 1 << 20))
        ->capture_default_str();
    render->add_option("--budget", r->budget, "seconds of rendering per strategy")
        ->capture_default_str();
    render->add_option("--spp-max", r->sppMax, "stop doubling the spp at this count")
        ->check(CLI::Range(1, 1 << 20))
        ->capture_default_str();
    render
        ->add_option("--strategies", r->strategies,
                     "strategies to run, e.g. lafortune+mis,sobol/mixture+mis (default: all: "
                     "each Phong sampler with and without +mis, and each again on sobol/)")
        ->delimiter(',');
    render
        ->add_option("--baseline", r->baseline,
                     "strategy the efficiencies are relative to (always run)")
        ->capture_default_str();
    render->add_option("-D", r->defines, "override a scene default: name=value");
    render->add_option("--seed", r->seed,
                       "seed of the measured renders (the reference uses seed + 1)");
    render->add_option("--threads", r->threads, "worker threads (default: all)")
        ->check(CLI::Range(1, 1024));
    render->add_flag("--quiet", r->quiet, "no progress output");
    render->callback([r] { runBenchRender(*r); });

    auto f = std::make_shared<BenchFitOptions>();
    CLI::App* fit = bench->add_subcommand(
        "fit",
        "fit every sample of a synth dataset; recovered against true parameters, error "
        "against time");
    fit->add_option("dataset", f->dataset, "dataset directory written by phongfit synth");
    fit->add_option("-o,--output", f->output, "output directory");
    fit->add_option("--spp-per-round", f->sppPerRound, "paths recorded per pixel and round; a list")
        ->delimiter(',')
        ->capture_default_str();
    auto startKd = std::make_shared<std::string>("0.25"),
         startKs = std::make_shared<std::string>("0.25");
    fit->add_option("--start-kd", *startKd, "start kd for every sample (R,G,B or one number)")
        ->capture_default_str();
    fit->add_option("--start-ks", *startKs, "start ks for every sample")->capture_default_str();
    fit->add_option("--start-n", f->startN, "start exponent for every sample")
        ->capture_default_str();
    fit->add_option("--start-n-factor", f->startNFactor,
                    "start each sample's exponent this factor off its truth (times it, or "
                    "divided where that would pass 1e5) instead of --start-n")
        ->check(CLI::Range(1.0, 1e6));
    fit->add_option("--rounds", f->rounds, "at most this many rounds per fit")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    fit->add_option("--adaptive-spp", f->adaptiveSpp,
                    "extra paths per pixel after the first round, as fit --adaptive-spp")
        ->check(CLI::Range(0, 4096))
        ->capture_default_str();
    fit->add_flag("--sampled-area-lights", f->sampledAreaLights,
                  "record area lights by sampling alone, as fit --sampled-area-lights");
    fit->add_option("--precision", f->precision,
                    "target relative standard error of every free parameter, as fit --precision")
        ->check(CLI::Range(0.0, 0.5))
        ->capture_default_str();
    fit->add_option("--time-budget", f->timeBudget,
                    "seconds each fit may take, as fit --time-budget (0: no budget)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    fit->add_option("--fail-threshold", f->failThreshold,
                    "a fit with a relative error above this fails")
        ->capture_default_str();
    fit->add_option("--threads", f->threads, "worker threads (default: all)")
        ->check(CLI::Range(1, 1024));
    fit->add_flag("--quiet", f->quiet, "no per-fit lines");
    auto shard = std::make_shared<std::optional<std::string>>();
    fit->add_option("--shard", *shard,
                    "fit only shard I of N (from 0): fit k (spp index x samples + sample index) "
                    "with k mod N = I; default from SLURM_ARRAY_TASK_ID and "
                    "SLURM_ARRAY_TASK_COUNT in a Slurm array job");
    auto merge = std::make_shared<std::string>();
    fit->add_option("--merge", *merge, "write the tables of DIR once every shard's fits are done");
    fit->callback([fit, f, startKd, startKs, shard, merge, parseOnly] {
        if (!merge->empty()) {
            for (const char* option :
                 {"dataset", "--output", "--shard", "--spp-per-round", "--start-kd", "--start-ks",
                  "--start-n", "--start-n-factor", "--rounds", "--adaptive-spp", "--precision",
                  "--sampled-area-lights", "--time-budget", "--fail-threshold"})
                if (fit->count(option) > 0)
                    throw Error(fmt::format(
                        "--merge DIR takes no {}: the run's settings are in DIR/bench_run.json",
                        option));
            if (!parseOnly) mergeBenchFit(*merge, f->threads);
            return;
        }
        if (f->dataset.empty() || f->output.empty())
            throw Error("bench fit needs DATASET and -o DIR (or --merge DIR)");
        f->startKd = parseColorOption(*startKd, "--start-kd");
        f->startKs = parseColorOption(*startKs, "--start-ks");
        f->shard = chooseShard(*shard);
        if (!parseOnly) runBenchFit(*f);
    });
}

}  // namespace phongfit
