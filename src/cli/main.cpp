// The `hinf` command line: dispatches subcommands; turns hinf::Error into one line on stderr + exit 2.
#include <cstdio>
#include <iostream>

#include "cli/commands.hpp"
#include "hinf/error.hpp"

int main(int argc, char** argv) {
    CLI::App app{"hinf: robust nonlinear filters by deep-network solutions of the Hamilton-Jacobi-Isaacs equation"};
    app.set_version_flag("--version", "hinf 0.1.0");
    app.require_subcommand(1);
    hinf::cli::add_train_commands(app);
    hinf::cli::add_operate_command(app);
    hinf::cli::add_lmi_command(app);
    hinf::cli::add_compare_command(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const hinf::Error& e) {
        std::cerr << "hinf: error: " << e.what() << "\n";
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "hinf: internal error: " << e.what() << " (please report this with the command you ran)\n";
        return 3;
    }
    return 0;
}
