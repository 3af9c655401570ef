// Generates a synthetic dataset (phongfit synth): per sample a folder with the scene file (the
// drawn values baked into its defaults), the rendered EXR and truth.json, plus index.json.
//
// A sample is complete when its truth.json exists: it is written last, atomically, after the
// other files (atomic too). A rerun into the same folder redoes only the incomplete samples; the
// dataset's config.json (the config as read, and a digest of each base scene) guards against
// resuming with another config. Each sample's values and render seed are functions of the
// config's seed and the sample's index, and renders are bit-identical whatever the thread count,
// so an interrupted and resumed run writes exactly the files an uninterrupted one does.
//
// Shards (--shard I/N, or a Slurm array task) render the samples k with k mod N = I into the same
// folder; whichever finds every sample complete when it ends writes index.json (as does
// `synth --merge DIR`), so the folder is bit-identical to one machine's run.
#pragma once

#include <string>

#include "shard.h"
#include "synth_config.h"

namespace phongfit {

struct SynthOptions {
    std::string output;
    int jobs = 1;     // samples rendered at once, sharing `threads`
    int threads = 0;  // render threads in all; 0: every hardware thread
    Shard shard;
    bool quiet = false;
};

struct SynthSummary {
    int total = 0;            // samples of this run's shard
    int rendered = 0;         // by this run
    int alreadyComplete = 0;  // found complete and kept
    bool interrupted = false;
    int datasetTotal = 0, datasetComplete = 0;  // over every shard, when this run ended
    bool indexWritten = false;
    double seconds = 0;
};

// Stops between samples on SIGINT/SIGTERM (src/interrupt.h); a render interrupted mid-way is
// discarded, never saved as a sample. index.json is written only once every sample is complete.
// Throws Error for an unusable output folder or a config that differs from the folder's.
SynthSummary runSynth(const SynthConfig& config, const SynthOptions& options);

// `synth --merge DIR`: writes DIR/index.json from the samples the shards rendered. Throws Error
// when DIR is not a synth dataset or samples are missing (naming how many and the first ones).
SynthSummary mergeSynth(const std::string& dir);

}  // namespace phongfit
