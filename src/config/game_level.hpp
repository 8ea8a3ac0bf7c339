// The smallest attenuation level of the linearised filtering game (docs/method.md section 16.12): what a sensible rho
// is for a system of one's own, computed from the system, never another system's value.
#pragma once
#include <cstdint>
#include <vector>

#include "config/run_config.hpp"

namespace hinf {

/// Walks the H-infinity filter's Riccati recursion of level rho for the system linearised along its noise-free
/// trajectory from x0 over [0, t_final], from P(0) = 0 (a zero initial error, as the worst-case search starts):
///   P+ = R (I + w R'(H'H - Q/rho) R)^-1 R',   P <- F P+ F' + G G' / w,   P = R R'
/// (F, G the Jacobians of one step of system_advance, H of the output; w = dt in continuous time, 1 in discrete
/// time), and checks the predictor's existence condition I - w R'(Q/rho) R > 0 at every step (Hassibi, Sayed and
/// Kailath's a-priori condition P^-1 - Q/rho > 0, here in a form that needs no inverse of a singular P).
/// Returns the first time it fails, or a negative number when it holds over the horizon walked. A non-finite
/// trajectory, Jacobian or P ends the walk there (counted as holding). repeats > 0 walks on over the horizon's second
/// half that many times more, each from the trajectory's state and time at the middle, P carried over (the returned
/// time counts along the whole walk: past t_final where a repeat fails).
double game_level_lost_at(const ProblemConfig& c, double rho, int repeats = 0);

/// The first time the noise-free trajectory from x0 leaves the finite numbers over the walk's horizon (-1: never):
/// where it does, the walk's Jacobians run away with it and no level brackets.
double noise_free_escape_time(const ProblemConfig& c);

/// The walk covers at most the horizon's first kGameLevelMaxSteps steps, so that reading a config stays quick whatever
/// its horizon (each level tried walks them once); over a longer horizon rho* is that of its first part (a lower value:
/// the level needed can only grow with the horizon).
constexpr std::int64_t kGameLevelMaxSteps = 20000;

struct GameLevel {
    double bound = 0;       // rho*: the recursion fails below it, holds above it (to rel_tol)
    bool bracketed = false; // false: it held at every level down to 1e-12 or failed at every level up to 1e15
};
/// The smallest level rho* for which game_level_lost_at holds, bisected in log(rho) to a relative tolerance: a lower
/// bound, for signals small enough that system and filter act as their linearisations, on the worst-case attenuation
/// ratio of every smooth filter (the discrete one also >= lambda_max(B'Q B), the floor of the one-step game).
/// repeats > 0: the level of the walk run on (game_level_lost_at); from > 0: a level known to hold on the walk without
/// repeats, where the search starts (the longer walk's level is never below it).
GameLevel game_level_bound(const ProblemConfig& c, double rel_tol = 0.01, int repeats = 0, double from = 0);

/// rho*_on, the level a filter needs when the run does not end at t_final: the walk of rho* run on over the horizon's
/// second half kRunOnRepeats times more (4 horizons in all), never below rho*. Over [0, t_final] the game's filter may
/// spend its margin knowing when the run ends (its P reaches its escape only after the end); a filter that does not
/// know it -- a gain K(x^) of the estimate alone, a stationary filter -- cannot (docs/method.md section 16.12, "Where
/// the run ends"). For a marginally stable measured state (a shaft angle, a position) it tends to the floor Q_ii that
/// measurement noise of low frequency passes at a DC gain of 1.
constexpr int kRunOnRepeats = 6;
GameLevel game_level_sustained(const ProblemConfig& c, double rho_star);

/// rho*_on of a loaded config, 0 where none is bracketed: game_level_sustained's from rho_star (> 0: game_level_rho_star's,
/// known to the caller; else game_level_rho_star's). Computed when asked, not on load: it walks four horizons per level
/// tried, which the commands that only read a config (filter, worst, operate, the library's load) do not need.
double game_level_rho_run_on(const ProblemConfig& c, double rho_star = 0);

/// rho* of a loaded config, 0 where no level is bracketed: the value loading computed for a config naming no rho
/// (rho_auto), else game_level_bound's (one walk per level tried).
double game_level_rho_star(const ProblemConfig& c);

/// The states the model holds constant: one step of system_advance leaves state i unchanged (its row of the step's
/// Jacobian F is e_i) and no disturbance reaches it (its row of G is 0), at every step of the noise-free trajectories
/// from x0 and from x^0 (their first kConstantStateSteps steps) -- a parameter estimated as a state (f_i = 0 and
/// g_i = 0 in continuous time, x_i+ = x_i in discrete time). Indices in increasing order.
std::vector<int> constant_states(const ProblemConfig& c);
constexpr std::int64_t kConstantStateSteps = 2000;

/// The level a system of one's own trains at when its config names no [filter] rho: kAutoRhoFactor times rho*.
constexpr double kAutoRhoFactor = 1.25;

}  // namespace hinf
