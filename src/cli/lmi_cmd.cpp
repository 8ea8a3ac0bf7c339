// `hinf lmi CONFIG [--out DIR] [--operate --runs R --threads N] [--set key=value]...`: seed 002's LMI design
// (and, until `hinf operate` routes [system] kind = "ito_delay" here, its Monte Carlo). Parsing only.
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.hpp"
#include "hinf/config.hpp"
#include "lmi/delay_run.hpp"

namespace hinf::cli {

namespace {

struct LmiArgs {
    std::string config;
    std::string out;
    bool operate = false;
    int runs = 0;
    int threads = 0;
    std::vector<std::string> sets;
};

}  // namespace

void add_lmi_command(CLI::App& app) {
    auto args = std::make_shared<LmiArgs>();
    CLI::App* cmd = app.add_subcommand(
        "lmi", "Design seed 002's global-linearization H-infinity or mixed H2/H-infinity delay filter by LMIs (SDPA)");
    cmd->add_option("config", args->config, "scenario config (TOML), e.g. runs/delay_hinf.toml")->required();
    cmd->add_option("--out", args->out, "output directory for lmi.h5 / operate.h5 (default runs/out/<config name>)");
    cmd->add_flag("--operate", args->operate, "also run the designed filter: Monte Carlo of Table 3 -> operate.h5");
    cmd->add_option("--runs", args->runs, "Monte Carlo runs for --operate (default: [simulation] runs)")
        ->check(CLI::Range(2, 100000000));
    cmd->add_option("--threads", args->threads, "OpenMP threads for --operate (results do not depend on it)")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--set", args->sets, "override a config key: section.key=value (repeatable)");
    cmd->callback([args]() {
        hinf::ConfigDoc doc = hinf::ConfigDoc::from_file(args->config);
        for (const auto& s : args->sets) doc.set(s);
        std::string out = args->out;
        if (out.empty()) out = "runs/out/" + std::filesystem::path(args->config).stem().string();
        int rc = hinf::lmi::delay_lmi_run(doc, out, std::cout);
        if (rc == 0 && args->operate) rc = hinf::lmi::delay_operate(doc, out, args->runs, args->threads);
        if (rc != 0) throw CLI::RuntimeError(rc);
    });
}

}  // namespace hinf::cli
