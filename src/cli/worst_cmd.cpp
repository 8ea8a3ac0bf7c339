// `hinf worst`: the worst-case search per filter (eval/worst.hpp) and `--replay FILE` of saved worst signals
// against any filter set; argument parsing and printing only.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "eval/worst.hpp"
#include "filters/factory.hpp"
#include "io/run_lock.hpp"

namespace hinf::cli {

namespace {

struct WorstArgs {
    std::string config, out, replay;
    std::string scenario_starts = "nominal,energy_pulse,bias", algorithm = "LN_SBPLX";
    std::vector<std::string> sets;
    FilterSetArgs set{"dnn,ekf,ukf,pf,open_loop", {}, "oracle,measured"};  // --filters, --network, --mode, ...
    int pieces = 4, sines = 2, random_starts = 4, evals = 200, threads = 0;
    int linear_pieces = 20;
    double linear_steps = 1e7;
    double energy = std::numeric_limits<double>::quiet_NaN(), until = -1;
    bool keep_initial_error = false, no_game_start = false, no_cross_starts = false, quiet = false, plot = false;
};

void print_cross(const WorstReplay& r) {
    std::printf("\nattenuation ratio of each filter (columns) under each set of worst signals (rows: found for):\n");
    std::printf("%-26s", "signals found for");
    for (const auto& f : r.filters) std::printf(" %14.14s", f.c_str());
    std::printf("\n");
    const std::size_t F = r.filters.size();
    for (std::size_t d = 0; d < r.sets.size(); ++d) {
        std::printf("%-26s", r.sets[d].c_str());
        for (std::size_t f = 0; f < F; ++f)
            std::printf(" %13.4g%s", r.ratio[d * F + f], r.diverged_at[d * F + f] >= 0 ? "!" : " ");
        std::printf("\n");
    }
    std::printf("(! = the filter diverged under these signals and was frozen)\n");
    // a gain network's filter whose estimate went far beyond its training region under some sets: which sets, and
    // the first one's excursion (its gain there is the region's edge's, which can be what broke it)
    for (std::size_t f = 0; f < F; ++f) {
        std::string under, first;
        for (std::size_t d = 0; d < r.sets.size(); ++d) {
            if (d * F + f >= r.note.size() || r.note[d * F + f].empty()) continue;
            under += (under.empty() ? "" : ", ") + r.sets[d];
            if (first.empty()) first = r.note[d * F + f];
        }
        if (!first.empty())
            std::printf("note: %s, under the signals found for %s: %s\n", r.filters[f].c_str(), under.c_str(),
                        first.c_str());
    }
}

void plot(const std::string& file, const std::string& dir) {
    if (std::system("test -x /usr/bin/python3") != 0) {
        std::printf("--plot: /usr/bin/python3 not found, no plots drawn\n");
        return;
    }
    const std::string cmd = "/usr/bin/python3 " + std::string(HINF_SOURCE_DIR) + "/scripts/plot " + file + " --out " + dir;
    int rc = std::system(cmd.c_str());
    std::printf("--plot: %s\n", rc == 0 ? ("PNGs in " + dir).c_str() : "scripts/plot failed (see above)");
}

}  // namespace

void add_worst_command(CLI::App& app) {
    auto a = std::make_shared<WorstArgs>();
    CLI::App* c = app.add_subcommand(
        "worst", "Search each filter's worst-case disturbance and noise under one energy budget (or --replay saved ones)");
    c->add_option("config", a->config, "Scenario config (TOML): system, noise levels, x0, Q")->required();
    add_filter_set_options(c, a->set, "dnn,ekf,ukf,pf,open_loop", true);
    CLI::Option* energy_opt = c->add_option("--energy", a->energy,
                  "Energy budget int (v'v + n'n) dt of every candidate (default: the nominal draws' expected energy "
                  "(disturbance_std^2 nv + noise_std^2 m) T)");
    c->add_option("--until", a->until, "Horizon [s] (default t_final)");
    c->add_option("--pieces", a->pieces, "Piecewise-constant segments per signal channel (default 4)");
    c->add_option("--sines", a->sines, "Sinusoids (a free frequency each, sin and cos amplitude per channel; default 2)");
    c->add_option("--random-starts", a->random_starts, "Random starts per filter (default 4; the same for every filter)");
    c->add_option("--scenario-starts", a->scenario_starts,
                  "Compare scenarios whose signals are starts, comma list or 'none' (default nominal,energy_pulse,bias)");
    c->add_flag("--no-game-start", a->no_game_start, "Do not start DNN filters from the game's v* = B'p/(2 rho), n* = -dC");
    c->add_flag("--no-cross-starts", a->no_cross_starts,
                "Do not search on from another filter's worst signals where they beat a filter's own best");
    c->add_option("--linear-pieces", a->linear_pieces,
                  "The linear start: each filter's small-signal worst case over piecewise-constant signals of this many "
                  "pieces a channel, doubled until it moves by less than 5 %, searched on from there (default 20; 0: "
                  "none; docs/compare.md \"The linear start\")");
    c->add_option("--linear-steps", a->linear_steps,
                  "The linear start's doubling stops before it would simulate more steps than this for a filter (default "
                  "1e7; 0: the first level only)");
    c->add_option("--evals", a->evals, "Objective evaluations per restart (default 200)");
    c->add_option("--algorithm", a->algorithm, "NLopt algorithm: " + worst_algorithms() + " (default LN_SBPLX)");
    c->add_flag("--keep-initial-error", a->keep_initial_error,
                "Start the filters at the config's x^0 (default: at x0, so the ratio is the pure energy gain)");
    c->add_option("--replay", a->replay, "Run the worst signals saved in FILE (worst.h5) against the filters instead of searching");
    c->add_option("--out", a->out, "Output directory (default runs/out/<config name>/worst)");
    c->add_option("--threads", a->threads, "OpenMP threads (restarts are split over them)");
    c->add_option("--set", a->sets, "Override a config key, e.g. --set online.noise_std=10 (repeatable)");
    c->add_flag("--plot", a->plot, "Draw PNGs with scripts/plot (needs /usr/bin/python3 with h5py and matplotlib)");
    c->add_flag("--quiet", a->quiet, "No progress lines");
    c->callback([a, energy_opt]() {
        apply_threads(a->threads);
        check_filter_set_options(a->set);
        RunConfig cfg = load_config_with_overrides(a->config, a->sets, filters_need_level(a->set.filters));
        WorstOptions opt;
        if (energy_opt->count() > 0) {
            HINF_CHECK(std::isfinite(a->energy) && a->energy > 0,
                       "--energy must be a finite number > 0 (got " + std::to_string(a->energy) + ")");
            opt.energy = a->energy;
        }
        opt.until = a->until;
        opt.pieces = a->pieces;
        opt.sines = a->sines;
        opt.random_starts = a->random_starts;
        opt.scenario_starts = a->scenario_starts == "none" ? std::vector<std::string>{} : split_list(a->scenario_starts);
        for (const auto& s : opt.scenario_starts) scenario_named(s);  // names checked before any work
        opt.game_start = !a->no_game_start;
        opt.cross_starts = !a->no_cross_starts;
        opt.linear_pieces = a->linear_pieces;
        HINF_CHECK(std::isfinite(a->linear_steps) && a->linear_steps >= 0,
                   "--linear-steps must be a finite number >= 0 (got " + std::to_string(a->linear_steps) + ")");
        opt.linear_steps = a->linear_steps;
        opt.evals = a->evals;
        opt.algorithm = a->algorithm;
        opt.keep_initial_error = a->keep_initial_error;
        opt.quiet = a->quiet;
        const std::string out = a->out.empty() ? default_out_dir(a->config, "worst") : a->out;

        // the worst signals were found for a budget, not a scenario: the Bayesian filters are told the nominal statistics
        const FilterModel exact = filter_model(cfg), told = scenario_told_model(cfg, scenario_named("nominal"));
        FilterSet set = build_filter_set(
            cfg, a->set, told, exact);
        for (const std::string& note : set.notes) std::printf("%s\n", note.c_str());
        std::vector<const OnlineFilter*> filters;
        for (const auto& o : set.filters) filters.push_back(o.get());

        if (!a->replay.empty()) {
            const WorstReplayRun run = worst_replay_file(cfg, filters, a->replay, out, opt, "hinf worst");
            std::printf("worst --replay %s: %zu signal set(s), %lld steps of %g s, energy %.6g, initial error %s\n",
                        a->replay.c_str(), run.sets.size(), static_cast<long long>(run.steps), cfg.dt,
                        run.table.signal_energy[0], run.keep_initial_error ? "from the config" : "zero");
            print_cross(run.table);
            std::printf("file: %s/replay.h5\n", out.c_str());
            if (a->plot) plot(out + "/replay.h5", out);
            return;
        }

        // the game's worst case needs each DNN filter's network and rho: dnn_<variant>_<mode> from the network file
        const WorstNetworks wn = worst_networks(filters, a->set.networks);
        WorstResult r = worst_search(cfg, filters, wn.games, opt);
        const RunDirLock lock(out, "hinf worst");
        worst_write(out + "/worst.h5", worst_config(cfg, opt), opt, r);
        std::printf("worst: %lld steps of %g s, energy budget %.6g, initial error %s, %d parameters per signal pair, "
                    "%s, %d evaluations per restart\n",
                    static_cast<long long>(r.steps), cfg.dt, r.energy, opt.keep_initial_error ? "from the config" : "zero",
                    r.parameters, opt.algorithm.c_str(), opt.evals);
        std::printf("%-26s %12s %12s %12s %12s  %-24s %8s\n", "filter", "worst ratio", "min restart", "median",
                    "best start", "found from", "restarts");
        for (const auto& fr : r.filters) {
            std::vector<double> v;
            for (const auto& rs : fr.restarts) v.push_back(rs.ratio);
            std::sort(v.begin(), v.end());
            const double median = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
            double best_start = 0;
            for (const auto& rs : fr.restarts) best_start = std::max(best_start, rs.start_ratio);
            std::printf("%-26s %12.4g %12.4g %12.4g %12.4g  %-24s %8zu\n", fr.name.c_str(), fr.worst.ratio, v.front(),
                        median, best_start, fr.restarts[fr.best].start.c_str(), fr.restarts.size());
        }
        if (opt.linear_pieces > 0) {  // the exact small-signal figure beside what the search found from it
            std::printf("small signals (the linear start, pieces a channel doubled from %d until it moves by less than 5 %%), "
                        "the ratio they reach:", opt.linear_pieces);
            bool none = false;
            for (const auto& fr : r.filters)
                if (std::isfinite(fr.linear_gain))
                    std::printf(" %s %.4g (%d pieces%s)", fr.name.c_str(), fr.linear_gain, fr.linear_pieces,
                                fr.linear_converged ? "" : ", not settled by doubling: more pieces may raise it");
                else {
                    std::printf(" %s -", fr.name.c_str());
                    none = true;
                }
            std::printf("%s\n", none ? " (-: none: the filter does not respond linearly to small signals, as a particle "
                                        "filter's resampling, a small signal's run ran away, or the differences would "
                                        "take more than 512 MiB: fewer --linear-pieces or a shorter --until)"
                                      : "");
        }
        print_cross(r.cross);
        // a gain network's filter: where its worst signals drove the truth far beyond training's region, its gain
        // there is the region's edge's (network.input_box), and the ratio measures that, not what training shaped
        for (std::size_t i = 0; i < filters.size(); ++i)
            for (std::size_t j = 0; j < wn.nets.size(); ++j) {
                if (filters[i]->name().rfind(wn.prefixes[j], 0) != 0 || !wn.nets[j]->step_config().gain.enabled)
                    continue;
                const std::string out_of = worst_truth_outside_training(cfg, wn.nets[j]->step_config().gain,
                                                                        r.filters[i].worst.signals, r.steps);
                if (!out_of.empty())
                    std::printf("note: under %s's worst signals the true state left the region training covered (%s, "
                                "more than the region's width beyond it): the filter's gain there is the region's "
                                "edge's; where the system is not meant to go there, a smaller --energy measures "
                                "inside it, else train over it (docs/byos.md section 4)\n",
                                filters[i]->name().c_str(), out_of.c_str());
                break;
            }
        std::printf("wall %.1f s; file: %s/worst.h5; replay: hinf worst %s --replay %s/worst.h5 --filters ...\n",
                    r.wall_seconds, out.c_str(), a->config.c_str(), out.c_str());
        if (a->plot) plot(out + "/worst.h5", out);
    });
}

}  // namespace hinf::cli
