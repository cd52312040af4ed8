// SPDX-License-Identifier: MIT
// btf compress-many INPUT... -o DIR [codec options]: one package per material, DIR/NAME.btfpkg.
// Started by mpirun, the materials are shared among the ranks by size (the largest first, each to
// the rank with the least work so far) and each rank compresses its own in one process; one table
// at the end. A material that fails is reported and leaves no package; the others go on.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "btf/codecs/material_source.h"
#include "btf/util/collective.h"
#include "btf/util/error.h"
#include "cli.h"
#include "mpi_world.h"

namespace btf::cli {

namespace {

namespace fs = std::filesystem;

// The inputs, with lists expanded: an input that is a file ending in .txt names one input per line
// (blank lines and lines starting with # skipped; relative paths from the list's folder).
std::vector<std::string> expand_lists(const std::vector<std::string>& inputs) {
    std::vector<std::string> out;
    for (const std::string& input : inputs) {
        if (lower_extension(input) != ".txt" || !fs::is_regular_file(input)) {
            out.push_back(input);
            continue;
        }
        std::ifstream list(input);
        if (!list) fail("{}: cannot read the list", input);
        std::string line;
        int number = 0;
        while (std::getline(list, line)) {
            ++number;
            line.erase(0, line.find_first_not_of(" \t"));
            line.erase(line.find_last_not_of(" \t\r") + 1);
            if (line.empty() || line[0] == '#') continue;
            fs::path path(line);
            if (path.is_relative()) path = fs::path(input).parent_path() / path;
            out.push_back(path.string());
        }
        if (out.empty()) fail("{}: the list names no input", input);
    }
    return out;
}

// The package name of an input: its file or folder name without the extension.
std::string package_name(const std::string& input) {
    fs::path path(input);
    if (!path.has_filename()) path = path.parent_path();  // "folder/"
    return path.stem().string();
}

struct Outcome {
    std::string input, output, error;
    int rank = 0;
    uint64_t bytes = 0;
    double raw = 0, seconds = 0;
    std::optional<double> rmse;
};

nlohmann::json to_json(const Outcome& o) {
    nlohmann::json j = {{"input", o.input},    {"output", o.output}, {"error", o.error},
                        {"rank", o.rank},      {"bytes", o.bytes},   {"raw", o.raw},
                        {"seconds", o.seconds}};
    if (o.rmse) j["rmse"] = *o.rmse;
    return j;
}

Outcome outcome_from(const nlohmann::json& j) {
    Outcome o;
    o.input = j.at("input");
    o.output = j.at("output");
    o.error = j.at("error");
    o.rank = j.at("rank");
    o.bytes = j.at("bytes");
    o.raw = j.at("raw");
    o.seconds = j.at("seconds");
    if (j.contains("rmse")) o.rmse = j["rmse"].get<double>();
    return o;
}

// Rank of each input (−1: it did not open, `errors` says why), the largest first to the rank with
// the least bytes so far (8-bit RGB raw size; ties to the lower rank).
std::vector<int> assign(const std::vector<double>& sizes, int ranks) {
    std::vector<int> order(sizes.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return sizes[a] > sizes[b]; });
    std::vector<double> load(ranks, 0.0);
    std::vector<int> rank(sizes.size(), -1);
    for (int i : order) {
        if (sizes[i] < 0) continue;
        const int r = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
        rank[i] = r;
        load[r] += sizes[i];
    }
    return rank;
}

}  // namespace

Command register_compress_many(CLI::App& app, GlobalOptions& global) {
    auto args = std::make_shared<CompressArgs>();
    CLI::App* cmd = app.add_subcommand(
        "compress-many",
        "Compress many BTFs, one package each (DIR/NAME.btfpkg), with one codec and its options; "
        "started by mpirun, the materials are shared among the ranks by size "
        "(docs/distributed.md). A material that fails is reported and the others go on");
    cmd->add_option("inputs", args->inputs,
                    "BTF files or folders; a file ending in .txt lists inputs, one per line")
        ->required();
    cmd->add_option("-o,--output", args->output, "folder for the packages (made if missing)")
        ->required();
    add_encode_options(*cmd, args->encode);
    add_open_options(*cmd, args->open, args->views);

    return {
        cmd, [args, &global] {
            Collective* world = mpi_world();
            const int rank = world ? world->rank() : 0, ranks = world ? world->size() : 1;
            std::vector<std::string> inputs, outputs;
            Encoder encoder;
            // Checked on every rank alike, the folder made by rank 0.
            together(world, [&] {
                inputs = expand_lists(args->inputs);
                encoder = resolve_encoder(args->encode, 1);
                std::map<std::string, std::string> seen;
                for (const std::string& input : inputs) {
                    const std::string name = package_name(input);
                    if (name.empty()) fail("{}: no name for its package", input);
                    if (auto [it, fresh] = seen.emplace(name, input); !fresh)
                        fail("{} and {} would both be written to {}.btfpkg: rename one", it->second,
                             input, name);
                    outputs.push_back((fs::path(args->output) / (name + ".btfpkg")).string());
                }
                if (rank == 0) {
                    if (fs::exists(args->output) && !fs::is_directory(args->output))
                        fail("{}: not a folder", args->output);
                    fs::create_directories(args->output);
                }
            });

            // Rank 0 opens every input for its size and shares the plan.
            std::vector<Outcome> outcomes(inputs.size());
            std::vector<int> owner;
            std::string plan;
            if (rank == 0) {
                std::vector<double> sizes(inputs.size(), -1.0);
                nlohmann::json j = nlohmann::json::array();
                for (size_t i = 0; i < inputs.size(); ++i) {
                    try {
                        const auto source = open_input(inputs[i], args->open, args->views);
                        sizes[i] = double(source->num_texels()) *
                                   double(source->sampling().num_images()) * 3.0;
                    } catch (const Error& e) {
                        outcomes[i].error = e.what();
                    }
                }
                owner = assign(sizes, ranks);
                for (size_t i = 0; i < inputs.size(); ++i)
                    j.push_back({{"rank", owner[i]}, {"error", outcomes[i].error}});
                plan = j.dump();
            }
            if (world) world->broadcast(plan);
            const nlohmann::json j = nlohmann::json::parse(plan);
            owner.resize(inputs.size());
            for (size_t i = 0; i < inputs.size(); ++i) {
                owner[i] = j[i].at("rank");
                outcomes[i].input = inputs[i];
                outcomes[i].output = outputs[i];
                outcomes[i].error = j[i].at("error");
                outcomes[i].rank = owner[i];
            }

            // This rank's materials, the largest first (the order of the plan).
            Progress progress = make_progress(global);
            std::vector<std::string> mine;
            for (size_t i = 0; i < inputs.size(); ++i) {
                if (owner[i] != rank) continue;
                Outcome& o = outcomes[i];
                const auto start = std::chrono::steady_clock::now();
                try {
                    const auto source = open_input(o.input, args->open, args->views);
                    Package package = encode_one(encoder, *source, progress);
                    write_package(o.output, package, encoder.write, progress);
                    o.bytes = package.file_bytes;
                    o.raw = double(source->num_texels()) * double(source->sampling().num_images()) *
                            3.0;
                    if (!args->encode.no_error)
                        o.rmse = sample_rmse(*source, *open_material(package), progress);
                } catch (const Cancelled&) {
                    throw;
                } catch (const std::bad_alloc&) {
                    o.error = "out of memory";
                } catch (const std::exception& e) {
                    o.error = e.what();
                }
                // A package written before a later step failed is not a result: removed.
                if (!o.error.empty() && o.bytes > 0) {
                    std::error_code ignored;
                    fs::remove(o.output, ignored);
                    o.bytes = 0;
                }
                o.seconds =
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                mine.push_back(to_json(o).dump());
            }

            // Rank 0 collects every rank's outcomes and prints the table.
            int failed = 0;
            if (world) {
                const std::vector<std::string> all = world->gather(nlohmann::json(mine).dump());
                for (const std::string& text : all)
                    for (const auto& line : nlohmann::json::parse(text)) {
                        const Outcome o =
                            outcome_from(nlohmann::json::parse(line.get<std::string>()));
                        for (Outcome& slot : outcomes)
                            if (slot.input == o.input) slot = o;
                    }
            } else {
                for (const std::string& line : mine) {
                    const Outcome o = outcome_from(nlohmann::json::parse(line));
                    for (Outcome& slot : outcomes)
                        if (slot.input == o.input) slot = o;
                }
            }
            for (const Outcome& o : outcomes) failed += !o.error.empty();
            std::string summary;
            if (rank == 0) {
                std::printf("%-40s %4s  %10s  %9s  %9s  %8s\n", "material", "rank", "package",
                            "ratio", "RMSE", "time");
                for (const Outcome& o : outcomes) {
                    if (!o.error.empty()) {
                        std::printf("%-40s %4s  failed: %s\n", o.input.c_str(),
                                    o.rank >= 0 ? std::to_string(o.rank).c_str() : "-",
                                    o.error.c_str());
                        continue;
                    }
                    std::printf("%-40s %4d  %10s  %9s  %9s  %6.1f s\n", o.input.c_str(), o.rank,
                                human_bytes(double(o.bytes)).c_str(),
                                format_ratio(o.raw / double(o.bytes)).c_str(),
                                o.rmse ? fmt::format("{:.3g}", *o.rmse).c_str() : "—", o.seconds);
                }
                std::printf("%zu of %zu materials written to %s%s\n", outcomes.size() - failed,
                            outcomes.size(), args->output.c_str(),
                            world ? fmt::format(" by {} MPI ranks", ranks).c_str() : "");
                std::fflush(stdout);
                summary = std::to_string(failed);
            }
            if (world) world->broadcast(summary);
            failed = std::stoi(summary);
            together(world, [&] {  // every rank fails alike, in order
                if (failed > 0)
                    fail("{} of {} materials failed (the table says why)", failed, outcomes.size());
            });
        }};
}

}  // namespace btf::cli
