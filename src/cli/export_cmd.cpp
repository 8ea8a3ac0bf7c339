// `hinf export CHECKPOINT... [--ensemble] --c DIR [--name PREFIX]`: argument parsing and the summary of src/export.
#include <cstdio>

#include "cli/commands.hpp"
#include "export/export_c.hpp"

namespace hinf::cli {

void add_export_command(CLI::App& app) {
    auto checkpoints = std::make_shared<std::vector<std::string>>();
    auto opt = std::make_shared<ExportOptions>();
    CLI::App* c = app.add_subcommand(
        "export", "Write a trained DNN filter (measured mode) as a dependency-free C99 header/source pair");
    c->add_option("checkpoint", *checkpoints,
                  "Trained network DIR/best.h5 (or checkpoint.h5); with --ensemble, two or more gain networks")
        ->required();
    // --out as every other command names its output directory; --c as the export was first written
    c->add_option("--out,--c", opt->dir, "Directory for PREFIX.h and PREFIX.c")->required();
    c->add_option("--name", opt->prefix, "C identifier prefix and file stem (default hinf_filter)");
    c->add_flag("--ensemble", opt->ensemble,
                "One filter with the mean gain of the gain networks given (as compare --ensemble; docs/method.md 16.15)");
    c->callback([checkpoints, opt]() {
        ExportResult r = export_c(*checkpoints, *opt);
        if (r.networks > 1)
            std::printf("export: ensemble of %d %s networks (%s, %s system; the mean of their gains), %lld parameters "
                        "(%lld bytes of const data), about %lld flops per step besides the system's A, C, dC/dx\n",
                        r.networks, r.variant.c_str(), r.precision.c_str(), r.system.c_str(), r.parameters,
                        r.weight_bytes, r.flops_per_step);
        else
            std::printf("export: %s network (%s, %s system), %lld parameters (%lld bytes of const data), about %lld "
                        "flops per step besides the system's A, C, dC/dx\n",
                        r.variant.c_str(), r.precision.c_str(), r.system.c_str(), r.parameters, r.weight_bytes,
                        r.flops_per_step);
        for (const auto& f : r.files) std::printf("wrote %s\n", f.c_str());
        std::printf("build: cc -std=c99 -O2 -c %s/%s.c   (link with -lm)\n", opt->dir.c_str(), opt->prefix.c_str());
    });
}

}  // namespace hinf::cli
