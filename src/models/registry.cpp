// make_system: builds the system named by [system] kind, reading and checking every key of [system].
#include <algorithm>

#include <toml++/toml.h>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "models/expr_system.hpp"
#include "models/maneuvering_missile.hpp"
#include "models/missile.hpp"
#include "models/system.hpp"

namespace hinf {

std::vector<int> state_unit_group(const System& sys, int group) {
    const std::vector<std::string> units = sys.state_units();
    std::vector<std::string> seen;
    for (const auto& u : units)
        if (std::find(seen.begin(), seen.end(), u) == seen.end()) seen.push_back(u);
    std::vector<int> out;
    if (group < 0 || group >= int(seen.size())) return out;
    for (int i = 0; i < int(units.size()); ++i)
        if (units[i] == seen[group]) out.push_back(i);
    return out;
}

std::unique_ptr<System> make_system(const ConfigDoc& doc) {
    ConfigSection s(doc, "system");
    std::string kind = s.get_string("kind", "missile", {"missile", "maneuvering_missile", "expr"});
    if (kind == "expr") {
        // a discrete system's k = t / dt needs the period; [filter] dt itself is read and checked by load_run_config
        const double period = doc.root()["filter"]["dt"].value<double>().value_or(0.01);
        std::unique_ptr<System> sys = make_expr_system(s, period);
        s.finish();
        return sys;
    }
    const bool maneuver = kind == "maneuvering_missile";
    ManeuverParams mp;
    MissileParams p = maneuver ? mp.base : MissileParams{};
    p.gravity = s.get_double("gravity", p.gravity, 0.0, 100.0);
    p.ballistic = s.get_double("ballistic_coefficient", p.ballistic, 1e-6, 1e12);
    std::vector<double> radar = s.get_doubles("radar", {p.radar[0], p.radar[1], p.radar[2]}, 3);
    std::copy(radar.begin(), radar.end(), p.radar);
    p.rho_high = s.get_double("density_high", p.rho_high, 0.0, 1e3);
    p.alpha_high = s.get_double("decay_high", p.alpha_high, 0.0, 1.0);
    p.rho_low = s.get_double("density_low", p.rho_low, 0.0, 1e3);
    p.alpha_low = s.get_double("decay_low", p.alpha_low, 0.0, 1.0);
    p.switch_altitude = s.get_double("switch_altitude", p.switch_altitude, -1e9, 1e9);
    std::vector<double> kp = s.get_doubles("position_gain", {p.position_gain[0], p.position_gain[1], p.position_gain[2]}, 3);
    std::copy(kp.begin(), kp.end(), p.position_gain);
    p.velocity_damping = s.get_double("velocity_damping", p.velocity_damping, -1e3, 1e3);
    if (maneuver) {
        mp.base = p;
        mp.amplitude = s.get_double("maneuver_amplitude", mp.amplitude, -1e9, 1e9);
        mp.decay = s.get_double("maneuver_decay", mp.decay, 0.0, 1e3);
    }
    s.finish();
    if (maneuver) return std::make_unique<ManeuveringMissileSystem>(mp);
    return std::make_unique<MissileSystem>(p);
}

}  // namespace hinf
