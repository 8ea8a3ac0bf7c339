// `hinf rho CONFIG [--rho R]`: the smallest attenuation level of the linearised game (src/config/game_level.cpp), what
// the outputs tell about each state (src/eval/observability.hpp), and for a discrete-time gain config the
// constant-storage check (src/train/storage_check.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "config/game_level.hpp"
#include "eval/observability.hpp"
#include "train/gain_samples.hpp"
#include "train/storage_check.hpp"

namespace hinf::cli {

void add_rho_command(CLI::App& app) {
    struct Args {
        std::string config;
        double rho = -1;
        std::vector<std::string> sets;
    };
    auto a = std::make_shared<Args>();
    CLI::App* c = app.add_subcommand(
        "rho", "The smallest attenuation level rho* any filter can promise for the system, linearised along its "
               "noise-free trajectory (docs/method.md section 16.12); for a discrete-time gain config also whether a "
               "constant storage can keep the one-step inequality for the errors the outputs do not see (section 16.8)");
    c->add_option("config", a->config, "Scenario config (TOML), e.g. runs/vanderpol.toml")->required();
    CLI::Option* rho = c->add_option("--rho", a->rho, "Also say whether, and where, the game of this level has no filter");
    c->add_option("--set", a->sets, "Override a config key, e.g. --set filter.t_final=5 (repeatable)");
    c->callback([a, rho]() {
        HINF_CHECK(rho->count() == 0 || a->rho > 0, "--rho " + rho->as<std::string>() + ": must be > 0 (a level to check)");
        const RunConfig cfg = load_config_with_overrides(a->config, a->sets);
        // a config naming no rho has walked the game on load (rho_auto): its rho* is not walked again (the walk is
        // n^3 a step: seconds for a large system)
        const GameLevel g = cfg.rho_auto && cfg.rho > 0 ? GameLevel{cfg.rho_bound, true} : game_level_bound(cfg);
        double run_on = 0;  // rho*_on, where rho* is bracketed
        const char* horizon = cfg.system->discrete_time() ? "steps" : "s";
        const std::int64_t walked = std::min(cfg.steps_until(), kGameLevelMaxSteps);
        const double span = cfg.system->discrete_time() ? double(walked) : cfg.time_of(walked);
        if (walked < cfg.steps_until())
            std::printf("(the horizon's first %lld of %lld steps: rho* over the whole horizon can only be larger)\n",
                        static_cast<long long>(walked), static_cast<long long>(cfg.steps_until()));
        if (g.bracketed)
            std::printf("rho* = %.4g: the linearised game over [0, %g] %s from x~(0) = 0 has a filter of level rho "
                        "only for rho > rho*; no filter's worst-case attenuation ratio is below it for small "
                        "signals\n",
                        g.bound, span, horizon);
        else if (g.bound > 0 && noise_free_escape_time(cfg) >= 0)
            std::printf("rho* > %.4g: the linearised game has no filter of any level up to there, because the noise-free "
                        "trajectory from [filter] x0 leaves the finite numbers at t = %g s%s\n",
                        g.bound, noise_free_escape_time(cfg),
                        cfg.system->discrete_time() ? "" : " (a shorter [filter] dt? the truth is stepped by forward Euler)");
        else if (g.bound > 0)
            std::printf("rho* > %.4g: the linearised game has no filter of any level up to there\n", g.bound);
        else
            std::printf("rho* < 1e-12: the linearised game has a filter of every level tried\n");
        if (g.bracketed) {  // the level a filter needs when the run does not end at t_final (section 16.12)
            const GameLevel s = game_level_sustained(cfg, g.bound);
            run_on = s.bracketed ? s.bound : 0.0;
            if (s.bracketed && s.bound > g.bound)
                std::printf("rho*_on = %.4g: where the run goes on past t_final (the walk run on over the horizon's "
                            "second half, %d horizons in all) the game needs a higher level; between rho* and it only a "
                            "filter that knows when the run ends keeps the level, not a gain of the estimate alone "
                            "(docs/method.md section 16.12, \"Where the run ends\")\n",
                            s.bound, kRunOnRepeats / 2 + 1);
            else if (s.bracketed)
                std::printf("rho*_on = rho*: where the run goes on past t_final (the walk run on over the horizon's "
                            "second half, %d horizons in all) the game needs no higher level\n", kRunOnRepeats / 2 + 1);
            else
                std::printf("rho*_on: where the run goes on past t_final the game has no filter of any level tried "
                            "(up to 1e15)\n");
        }
        if (cfg.rho_auto && cfg.rho <= 0)
            std::printf("the config names no rho, and no default follows from rho*: train refuses it until it names one\n");
        else if (cfg.rho_auto)
            std::printf("the config names no rho: it trains at %g = %g rho* (the default for a system of one's own)%s\n",
                        cfg.rho, kAutoRhoFactor,
                        run_on >= cfg.rho
                            ? ", at or below rho*_on: a gain of the estimate alone is not expected to keep it"
                            : "");
        else std::printf("the config's rho = %g\n", cfg.rho);
        {  // what the outputs tell about each state (docs/method.md section 16.18)
            const StateInformation info = state_information(cfg);
            const std::string note = unseen_states_note(cfg, info);
            if (!note.empty()) std::printf("%s\n", note.c_str() + std::strlen("hinf: note: "));
            else if (info.ran) {
                int most = -1;  // the state the outputs tell least about (NaN: nothing to tell, left out)
                for (int i = 0; i < cfg.n; ++i)
                    if (std::isfinite(info.ratio[std::size_t(i)]) &&
                        (most < 0 || info.ratio[std::size_t(i)] > info.ratio[std::size_t(most)]))
                        most = i;
                if (most >= 0) std::printf("the outputs see every state: along the noise-free run the EKF's covariance "
                            "equation, told every measurement with a thousandth of its noise, keeps at most %.3g %% of "
                            "the open-loop predictor's error variance (%s) over the run's second half\n",
                            100 * info.ratio[std::size_t(most)], cfg.system->state_names()[std::size_t(most)].c_str());
            }
        }
        if (cfg.variant == "gain" && cfg.system->discrete_time()) {  // docs/method.md section 16.8
            const StorageCheck sc = constant_storage_check(cfg, gain_pool_build(cfg));
            if (sc.infeasible()) std::fputs(constant_storage_note(cfg, sc).c_str(), stdout);
            else if (sc.ran && sc.solved)
                std::printf("a constant storage keeps the one-step inequality for the errors the outputs do not see within a "
                            "step (%lld estimates along training's runs; best S: %.3g against the Q term's %.3g)\n",
                            static_cast<long long>(sc.estimates), sc.mu, sc.q_scale);
            else if (sc.ran)
                std::printf("the constant-storage check did not converge (SDPA: %s): no verdict\n", sc.solver_phase.c_str());
            else
                std::printf("every error is seen by the outputs within a step at the estimates along training's runs: "
                            "no constant-storage check to make\n");
        }
        if (rho->count() > 0) {
            const double at = game_level_lost_at(cfg, a->rho);
            const double on = at < 0 ? game_level_lost_at(cfg, a->rho, kRunOnRepeats) : -1;
            if (at < 0 && on >= 0)
                std::printf("rho = %g: a filter of this level exists for the linearised game over the horizon, but "
                            "where the run goes on its Riccati equation loses definiteness at t = %g %s of the walk run "
                            "on (above rho*_on it does not)\n",
                            a->rho, on, horizon);
            else if (at < 0) std::printf("rho = %g: a filter of this level exists for the linearised game\n", a->rho);
            else
                std::printf("rho = %g: the Riccati equation loses definiteness at t = %g s: no filter of this level "
                            "for the linearised game\n",
                            a->rho, at);
        }
    });
}

}  // namespace hinf::cli
