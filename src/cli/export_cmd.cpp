// `hinf export CHECKPOINT --c DIR [--name PREFIX]`: argument parsing and the summary of src/export.
#include <cstdio>

#include "cli/commands.hpp"
#include "export/export_c.hpp"

namespace hinf::cli {

void add_export_command(CLI::App& app) {
    auto checkpoint = std::make_shared<std::string>();
    auto opt = std::make_shared<ExportOptions>();
    CLI::App* c = app.add_subcommand(
        "export", "Write a trained DNN filter (measured mode) as a dependency-free C99 header/source pair");
    c->add_option("checkpoint", *checkpoint, "Trained network DIR/checkpoint.h5")->required();
    c->add_option("--c", opt->dir, "Directory for PREFIX.h and PREFIX.c")->required();
    c->add_option("--name", opt->prefix, "C identifier prefix and file stem (default hinf_filter)");
    c->callback([checkpoint, opt]() {
        ExportResult r = export_c(*checkpoint, *opt);
        std::printf("export: %s network (%s, %s system), %lld parameters (%lld bytes of const data), about %lld "
                    "flops per step besides the system's A, C, dC/dx\n",
                    r.variant.c_str(), r.precision.c_str(), r.system.c_str(), r.parameters, r.weight_bytes,
                    r.flops_per_step);
        for (const auto& f : r.files) std::printf("wrote %s\n", f.c_str());
        std::printf("build: cc -std=c99 -O2 -c %s/%s.c   (link with -lm)\n", opt->dir.c_str(), opt->prefix.c_str());
    });
}

}  // namespace hinf::cli
