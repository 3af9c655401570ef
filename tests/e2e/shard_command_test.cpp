// Running synth and bench fit in shards (--shard I/N, or a Slurm array task's variables) gives
// the files and numbers of one run; `--merge` finishes what the shards left; `phongfit slurm
// --dry-run` writes the array script. The real-Slurm run is tests/slurm/slurm_test.sh.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "error.h"
#include "file_snapshot.h"
#include "shard.h"
#include "subprocess.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

const std::string kSmall = PHONGFIT_CONFIGS_DIR "/small.json";

using test::snapshot;

std::string readFile(const fs::path& path) { return test::readFileBytes(path); }

// A CSV with the named timing columns blanked: what must be equal between runs.
std::string withoutTimes(const fs::path& csv) {
    std::istringstream in(readFile(csv));
    std::string header, line, out;
    std::getline(in, header);
    std::vector<int> timeColumns;
    std::stringstream h(header);
    int c = 0;
    for (std::string f; std::getline(h, f, ','); ++c)
        if (f == "time_s") timeColumns.push_back(c);
    out = header + "\n";
    while (std::getline(in, line)) {
        std::stringstream s(line);
        c = 0;
        for (std::string f; std::getline(s, f, ','); ++c) {
            const bool time =
                std::find(timeColumns.begin(), timeColumns.end(), c) != timeColumns.end();
            out += (time ? std::string("-") : f) + ",";
        }
        out += "\n";
    }
    return out;
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

TEST(Shard, ParsesIOfNAndRefusesTheRest) {
    const Shard s = parseShard("2/5");
    EXPECT_EQ(s.index, 2);
    EXPECT_EQ(s.count, 5);
    EXPECT_TRUE(s.contains(7));
    EXPECT_FALSE(s.contains(8));
    EXPECT_EQ(s.text(), "2/5");
    for (const char* bad : {"5/5", "-1/3", "1", "1/0", "a/3", "1/3x", "", "/", "1/2000000"})
        EXPECT_THROW(parseShard(bad), Error) << bad;
    try {
        parseShard("4/4");
    } catch (const Error& e) {
        EXPECT_TRUE(contains(e.what(), "--shard '4/4'")) << e.what();
        EXPECT_TRUE(contains(e.what(), "0 <= I < N")) << e.what();
    }
}

// Every item belongs to exactly one shard.
TEST(Shard, ShardsPartitionTheItems) {
    for (int n = 1; n <= 7; ++n)
        for (int item = 0; item < 50; ++item) {
            int owners = 0;
            for (int i = 0; i < n; ++i) owners += Shard{i, n}.contains(item);
            EXPECT_EQ(owners, 1) << item << " of " << n;
        }
}

TEST(Shard, ComesFromTheSlurmArrayTask) {
    unsetenv("SLURM_ARRAY_TASK_ID");
    unsetenv("SLURM_ARRAY_TASK_COUNT");
    EXPECT_FALSE(shardFromSlurmEnvironment());
    EXPECT_TRUE(chooseShard(std::nullopt).whole());
    setenv("SLURM_ARRAY_TASK_ID", "7", 1);
    setenv("SLURM_ARRAY_TASK_COUNT", "4", 1);
    setenv("SLURM_ARRAY_TASK_MIN", "4", 1);
    setenv("SLURM_ARRAY_TASK_STEP", "1", 1);
    EXPECT_EQ(chooseShard(std::nullopt).text(), "3/4");        // --array=4-7
    EXPECT_EQ(chooseShard(std::string("1/2")).text(), "1/2");  // --shard wins
    setenv("SLURM_ARRAY_TASK_MIN", "1", 1);
    setenv("SLURM_ARRAY_TASK_STEP", "2", 1);
    setenv("SLURM_ARRAY_TASK_ID", "5", 1);
    EXPECT_EQ(chooseShard(std::nullopt).text(), "2/4");  // --array=1-7:2
    setenv("SLURM_ARRAY_TASK_ID", "x", 1);
    EXPECT_THROW(chooseShard(std::nullopt), Error);
    // A task ID without the count: every task would do the whole run into one folder.
    setenv("SLURM_ARRAY_TASK_ID", "2", 1);
    unsetenv("SLURM_ARRAY_TASK_COUNT");
    EXPECT_THROW(chooseShard(std::nullopt), Error);
    for (const char* v : {"SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT", "SLURM_ARRAY_TASK_MIN",
                          "SLURM_ARRAY_TASK_STEP"})
        unsetenv(v);
}

TEST(ShardedSynth, ShardsWriteTheFilesOfOneRun) {
    const test::TempDir dir("shard_synth");
    const fs::path whole = dir.path() / "whole", sharded = dir.path() / "sharded";
    ASSERT_EQ(test::runPhongfit({"synth", kSmall, "-o", whole.string(), "--quiet"}).exitCode, 0);

    const auto first =
        test::runPhongfit({"synth", kSmall, "-o", sharded.string(), "--shard", "0/3", "--quiet"});
    ASSERT_EQ(first.exitCode, 0) << first.err;
    EXPECT_TRUE(contains(first.out, "shard 0/3: 2 samples (2 rendered")) << first.out;
    EXPECT_TRUE(contains(first.out, "2 of the dataset's 4 samples are complete")) << first.out;
    EXPECT_FALSE(fs::exists(sharded / "index.json"));
    EXPECT_TRUE(fs::exists(sharded / "sample_0003/truth.json"));  // 3 mod 3 = 0
    const auto early = test::runPhongfit({"synth", "--merge", sharded.string()});
    EXPECT_NE(early.exitCode, 0);
    EXPECT_TRUE(contains(early.err, "2 of 4 samples are not complete (sample_0001, sample_0002)"))
        << early.err;
    EXPECT_FALSE(fs::exists(sharded / "index.json"));

    // Shard 1 of 3 from a Slurm array task's variables (as a task of --array=0-2).
    setenv("SLURM_ARRAY_TASK_ID", "1", 1);
    setenv("SLURM_ARRAY_TASK_COUNT", "3", 1);
    const auto second = test::runPhongfit({"synth", kSmall, "-o", sharded.string(), "--quiet"});
    unsetenv("SLURM_ARRAY_TASK_ID");
    unsetenv("SLURM_ARRAY_TASK_COUNT");
    ASSERT_EQ(second.exitCode, 0) << second.err;
    EXPECT_TRUE(contains(second.out, "shard 1/3: 1 samples (1 rendered")) << second.out;
    // The last shard finds every sample and writes the index.
    const auto last =
        test::runPhongfit({"synth", kSmall, "-o", sharded.string(), "--shard", "2/3", "--quiet"});
    ASSERT_EQ(last.exitCode, 0) << last.err;
    EXPECT_TRUE(contains(last.out, "-> " + (sharded / "index.json").string())) << last.out;
    EXPECT_EQ(snapshot(whole), snapshot(sharded));

    // --merge rewrites the same index; a rerun of a shard renders nothing.
    fs::remove(sharded / "index.json");
    const auto merged = test::runPhongfit({"synth", "--merge", sharded.string()});
    ASSERT_EQ(merged.exitCode, 0) << merged.err;
    EXPECT_EQ(snapshot(whole), snapshot(sharded));
    const auto again =
        test::runPhongfit({"synth", kSmall, "-o", sharded.string(), "--shard", "0/3", "--quiet"});
    EXPECT_TRUE(contains(again.out, "(0 rendered, 2 already complete)")) << again.out;

    for (const auto& [args, message] :
         std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"synth", "--merge", dir.at("nothing")}, "not a synth dataset"},
             {{"synth", kSmall, "-o", dir.at("x"), "--shard", "3/3"}, "--shard '3/3'"},
             {{"synth", kSmall, "--merge", sharded.string()}, "--merge DIR takes no CONFIG"},
             {{"synth", kSmall}, "needs CONFIG and -o DIR"}}) {
        const auto r = test::runPhongfit(args);
        EXPECT_NE(r.exitCode, 0) << message;
        EXPECT_TRUE(contains(r.err, message)) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
}

// Two shards running at once into one empty folder: neither refuses the other's files.
TEST(ShardedSynth, ConcurrentShardsStartTogether) {
    const test::TempDir dir("shard_concurrent");
    const fs::path out = dir.path() / "ds";
    for (int attempt = 0; attempt < 3; ++attempt) {
        fs::remove_all(out);
        std::vector<test::ProcessResult> results(2);
        std::thread other([&] {
            results[1] = test::runPhongfit(
                {"synth", kSmall, "-o", out.string(), "--shard", "1/2", "--quiet"});
        });
        results[0] =
            test::runPhongfit({"synth", kSmall, "-o", out.string(), "--shard", "0/2", "--quiet"});
        other.join();
        for (const auto& r : results) ASSERT_EQ(r.exitCode, 0) << r.err;
        EXPECT_TRUE(fs::exists(out / "index.json"));
    }
}

TEST(ShardedBenchFit, ShardsAndMergeGiveTheNumbersOfOneRun) {
    const test::TempDir dir("shard_bench");
    const std::string data = dir.at("data");
    ASSERT_EQ(test::runPhongfit({"synth", kSmall, "-o", data, "--quiet"}).exitCode, 0);
    const std::vector<std::string> settings = {"--spp-per-round", "4,8", "--rounds", "3",
                                               "--quiet"};
    auto bench = [&](const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> args = {"bench", "fit", data, "-o", out};
        args.insert(args.end(), settings.begin(), settings.end());
        args.insert(args.end(), extra.begin(), extra.end());
        return test::runPhongfit(args);
    };
    const auto whole = bench(dir.at("whole"), {"--threads", "2"});
    ASSERT_EQ(whole.exitCode, 0) << whole.err;

    const fs::path sharded = dir.path() / "sharded";
    const auto a = bench(sharded.string(), {"--shard", "0/3", "--threads", "1"});
    ASSERT_EQ(a.exitCode, 0) << a.err;
    EXPECT_TRUE(contains(a.out, "shard 0/3: 3 fits done; 3 of the run's 8 fits are done")) << a.out;
    EXPECT_FALSE(fs::exists(sharded / "recovery.csv"));
    const auto early = test::runPhongfit({"bench", "fit", "--merge", sharded.string()});
    EXPECT_NE(early.exitCode, 0);
    EXPECT_TRUE(contains(early.err, "5 of 8 fits are not done")) << early.err;
    ASSERT_EQ(bench(sharded.string(), {"--shard", "1/3"}).exitCode, 0);
    const fs::path row = sharded / "fits/spp4/sample_0000/bench_row.json";
    const auto rowTime = fs::last_write_time(row);
    const auto last = bench(sharded.string(), {"--shard", "2/3"});
    ASSERT_EQ(last.exitCode, 0) << last.err;
    EXPECT_TRUE(contains(last.out, "kd median")) << last.out;  // it wrote the tables
    EXPECT_EQ(withoutTimes(dir.path() / "whole/recovery.csv"),
              withoutTimes(sharded / "recovery.csv"));
    EXPECT_EQ(withoutTimes(dir.path() / "whole/rounds.csv"), withoutTimes(sharded / "rounds.csv"));

    // --merge writes the same tables again; a rerun refits nothing.
    fs::remove(sharded / "recovery.csv");
    const auto merged = test::runPhongfit({"bench", "fit", "--merge", sharded.string()});
    ASSERT_EQ(merged.exitCode, 0) << merged.err;
    EXPECT_EQ(withoutTimes(dir.path() / "whole/recovery.csv"),
              withoutTimes(sharded / "recovery.csv"));
    const auto rerun = bench(sharded.string(), {"--shard", "0/3"});
    ASSERT_EQ(rerun.exitCode, 0) << rerun.err;
    EXPECT_TRUE(contains(rerun.out, "shard 0/3: 3 fits done earlier")) << rerun.out;
    EXPECT_EQ(fs::last_write_time(row), rowTime);
    // A damaged row is fitted again.
    std::ofstream(sharded / "fits/spp8/sample_0000/bench_row.json") << "{\"run\": ";
    const auto mended = bench(sharded.string(), {"--shard", "1/3"});
    ASSERT_EQ(mended.exitCode, 0) << mended.err;
    EXPECT_TRUE(contains(mended.out, "kd median")) << mended.out;
    EXPECT_EQ(withoutTimes(dir.path() / "whole/recovery.csv"),
              withoutTimes(sharded / "recovery.csv"));
    // Other settings are another run: its fits are redone, not taken from the folder.
    const auto other = test::runPhongfit({"bench", "fit", data, "-o", sharded.string(),
                                          "--spp-per-round", "4", "--rounds", "2", "--quiet"});
    ASSERT_EQ(other.exitCode, 0) << other.err;
    EXPECT_NE(fs::last_write_time(row), rowTime);

    const auto wrong =
        test::runPhongfit({"bench", "fit", "--merge", sharded.string(), "--rounds", "2"});
    EXPECT_NE(wrong.exitCode, 0);
    EXPECT_TRUE(contains(wrong.err, "--merge DIR takes no --rounds")) << wrong.err;

    // A damaged record of the run's settings is refused on one line naming the file and value.
    const fs::path record = sharded / "bench_run.json";
    nlohmann::json broken = nlohmann::json::parse(std::ifstream(record));
    broken["settings"]["start_kd"] = "grey";
    std::ofstream(record) << broken.dump();
    const auto damaged = test::runPhongfit({"bench", "fit", "--merge", sharded.string()});
    EXPECT_NE(damaged.exitCode, 0);
    EXPECT_TRUE(contains(damaged.err,
                         record.string() + ": 'settings.start_kd' = \"grey\": expected [r, g, b]"))
        << damaged.err;
    EXPECT_EQ(std::count(damaged.err.begin(), damaged.err.end(), '\n'), 1) << damaged.err;
}

TEST(SlurmCommand, DryRunPrintsTheArrayScript) {
    const test::TempDir dir("slurm_dry");
    const std::string out = dir.at("ds");
    const auto r = test::runPhongfit({"slurm", "synth", "--tasks", "4", "--partition", "batch",
                                      "--time", "0:30:00", "--mem", "2G", "--cpus-per-task", "2",
                                      "--dry-run", kSmall, "-o", out, "--jobs", "1"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    for (const std::string& line : std::vector<std::string>{
             "#!/bin/bash\n", "#SBATCH --array=0-3\n", "#SBATCH --partition=batch\n",
             "#SBATCH --time=0:30:00\n", "#SBATCH --mem=2G\n", "#SBATCH --cpus-per-task=2\n",
             "#SBATCH --output=" + out + ".slurm/logs/%A_%a.out\n",
             " synth " + kSmall + " -o " + out +
                 " --jobs 1 --threads 2 --shard \"${SLURM_ARRAY_TASK_ID}/4\"\n"})
        EXPECT_TRUE(contains(r.out, line)) << line << "\n" << r.out;
    EXPECT_FALSE(fs::exists(out));  // nothing written
    EXPECT_FALSE(fs::exists(out + ".slurm"));

    for (const auto& [args, message] :
         std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"slurm", "synth", "--tasks", "2", "--dry-run", kSmall, "-o", out, "--shard", "0/2"},
              "--shard is set by phongfit slurm"},
             {{"slurm", "synth", "--tasks", "2", "--dry-run", dir.at("none.json"), "-o", out},
              "none.json"},
             {{"slurm", "synth", "--tasks", "2", "--dry-run", kSmall, "-o", out, "--bogus"},
              "--bogus"},
             {{"slurm", "synth", "--tasks", "2", "--mem", "2G; rm -rf /", "--dry-run", kSmall, "-o",
               out},
              "--mem '2G; rm -rf /'"},
             {{"slurm", "bench-fit", "--tasks", "2", "--dry-run", dir.at("nodata"), "-o", out},
              "index.json"},
             {{"slurm", "synth", "--dry-run", kSmall, "-o", out}, "--tasks"}}) {
        const auto bad = test::runPhongfit(args);
        EXPECT_NE(bad.exitCode, 0) << message;
        EXPECT_TRUE(contains(bad.err, message)) << bad.err;
        EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
    }
}

}  // namespace
}  // namespace phongfit
