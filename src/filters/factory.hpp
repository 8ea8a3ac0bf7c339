// The filter factory: the on-line filters named by a list (`hinf compare`, `hinf filter`, the library): EKF, UKF, PF,
// open loop, GLF and one DNN filter per network and mode. The filters themselves live beside it.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/spelling.hpp"
#include "filters/filter.hpp"
#include "net/network.hpp"
#include "config/run_config.hpp"

namespace hinf {

struct FilterSetArgs {
    std::string filters;                // comma list: dnn, ekf, ukf, pf, ehf, open_loop, glf
    std::vector<std::string> networks;  // checkpoints for dnn
    std::string modes;                  // comma list: oracle, measured
    std::int64_t particles = 2000;
    double roughening = 0.0;
    int glf_vertices = 8;
    bool ensemble = false;  // dnn: one filter averaging the gains of every network (all variant gain, one model)
    Spelling spelling = Spelling::program;  // how error lines name these arguments (the program's flags or the library's)
};

struct FilterSet {
    std::vector<std::unique_ptr<OnlineFilter>> filters;
    std::vector<std::unique_ptr<FrozenNetwork>> networks;  // owned here: the dnn filters hold clones
    std::vector<std::string> notes;                         // what a design step found (GLF vertices), to print
    std::vector<std::shared_ptr<System>> models;            // the systems gain networks were trained on (their filters')
};

/// The names build_filter_set knows, comma-separated.
std::string filter_names();

std::vector<std::string> split_list(const std::string& s);
/// Whether build_filter_set reads [filter] rho for this --filters list: it does for the GLF (designed at that level);
/// a DNN filter takes its level from its checkpoint, the others have none.
bool filters_need_level(const std::string& filters);

/// --ensemble's networks (`paths`, two or more): variant-gain checkpoints trained on one model (the [system] table and
/// the noise weights of their checkpoints agree), each for cfg's system and time domain; one line names the network
/// that differs. `first` gets the first checkpoint's effective config (the model they were trained on).
std::vector<std::unique_ptr<FrozenNetwork>> load_gain_ensemble(const RunConfig& cfg, const std::vector<std::string>& paths,
                                                               RunConfig* first, Spelling spelling = Spelling::program);

/// A gain network's filter takes y weighted as the config weighs its outputs ([online] noise_std as a list or
/// noise_cov: each output in units of its own noise; plain numbers: the user's units) and filters with its own model,
/// weighted as it was trained (method.md 16.13): where the two differ, the returned filter converts y on the way in.
std::unique_ptr<OnlineFilter> outputs_as_trained(std::unique_ptr<OnlineFilter> filter, const RunConfig& cfg,
                                                 const RunConfig& trained);

/// `told`: the statistics EKF/UKF/PF are given; `exact`: the model of open loop, GLF and the DNN filters but the
/// `gain` variant's, which filters with the system in its checkpoint (the model it was trained on, docs/compare.md).
/// Throws hinf::Error naming the option for an unknown filter or mode, a missing --network, or a network
/// trained for another state dimension.
FilterSet build_filter_set(const RunConfig& cfg, const FilterSetArgs& a, const FilterModel& told,
                           const FilterModel& exact);

}  // namespace hinf
