// See factory.hpp.
#include "filters/factory.hpp"

#include <algorithm>
#include <cstdio>
#include <sstream>

#include <toml++/toml.h>

#include "filters/dnn.hpp"
#include "filters/glf.hpp"
#include "hinf/error.hpp"
#include "io/checkpoint.hpp"
#include "models/expr_system.hpp"
#include "models/weighted_system.hpp"
#include "filters/ehf.hpp"
#include "filters/ekf.hpp"
#include "filters/open_loop.hpp"
#include "filters/pf.hpp"
#include "filters/ukf.hpp"

namespace hinf {

std::vector<std::string> split_list(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ','))
        if (!item.empty()) out.push_back(item);
    return out;
}

bool filters_need_level(const std::string& filters) {
    for (const std::string& name : split_list(filters))
        if (name == "glf" || name == "ehf") return true;
    return false;
}

namespace {

// Filters built from the told model alone: name -> maker. dnn and glf need more (networks, an LMI design).
struct SimpleFilter {
    const char* name;
    std::unique_ptr<OnlineFilter> (*make)(const RunConfig& cfg, const FilterSetArgs& a, const FilterModel& told,
                                          const FilterModel& exact);
};
// the tuning of UKF and PF: the config's [baseline] keys
const SimpleFilter kSimpleFilters[] = {
    {"ekf", [](const RunConfig&, const FilterSetArgs&, const FilterModel& told, const FilterModel&) { return make_ekf(told); }},
    {"ukf",
     [](const RunConfig& cfg, const FilterSetArgs&, const FilterModel& told, const FilterModel&) {
         return make_ukf(told, cfg.ukf_alpha, cfg.ukf_beta, cfg.ukf_kappa);
     }},
    {"pf",
     [](const RunConfig& cfg, const FilterSetArgs& a, const FilterModel& told, const FilterModel&) {
         return make_particle_filter(told, a.particles, cfg.pf_ess_fraction, a.roughening,
                                     cfg.pf_resampling == "stratified");
     }},
    {"ehf",  // the game's extended H-infinity filter at [filter] rho and Q
     [](const RunConfig& cfg, const FilterSetArgs&, const FilterModel& told, const FilterModel&) {
         HINF_CHECK(cfg.rho > 0, cfg.rho_unset);
         return make_ehf(told, cfg.Q, cfg.rho);
     }},
    {"open_loop",
     [](const RunConfig&, const FilterSetArgs&, const FilterModel&, const FilterModel& exact) {
         return make_open_loop_filter(exact);
     }},
};

// A gain network filters with its own model (its checkpoint's [system] and channel weights, method.md 16.13); the
// measurements come weighted as the config weighs them. Where the two differ (a network trained with [online]
// noise_std as a list, a config with a plain number, or other values), y is taken back to the user's units and
// weighted as the network was trained: y_net = W_net W_cfg^-1 y.
class OutputsReweighted : public OnlineFilter {
public:
    OutputsReweighted(std::unique_ptr<OnlineFilter> inner, std::vector<double> w_cfg, std::vector<double> w_net, int m)
        : inner_(std::move(inner)), w_cfg_(std::move(w_cfg)), w_net_(std::move(w_net)), m_(m), y_(m) {}
    std::string name() const override { return inner_->name(); }
    void reset(const FilterStart& start) override { inner_->reset(start); }
    FilterStatus step(const FilterInput& in) override {
        FilterInput own = in;
        if (in.y != nullptr) {
            std::copy(in.y, in.y + m_, y_.begin());
            if (!w_cfg_.empty()) lower_solve(w_cfg_, m_, y_.data());
            if (!w_net_.empty()) lower_multiply(w_net_, m_, y_.data());
            own.y = y_.data();
        }
        return inner_->step(own);
    }
    const double* estimate() const override { return inner_->estimate(); }
    const double* filtered() const override { return inner_->filtered(); }
    const double* covariance() const override { return inner_->covariance(); }
    bool covariance_is_statistical() const override { return inner_->covariance_is_statistical(); }
    double nis() const override { return inner_->nis(); }  // S and nu both in the inner filter's units
    bool uses_true_state() const override { return inner_->uses_true_state(); }
    std::vector<double> run_report() const override { return inner_->run_report(); }
    std::string run_note() const override { return inner_->run_note(); }
    std::unique_ptr<OnlineFilter> clone() const override {
        return std::make_unique<OutputsReweighted>(inner_->clone(), w_cfg_, w_net_, m_);
    }

private:
    std::unique_ptr<OnlineFilter> inner_;
    std::vector<double> w_cfg_, w_net_;
    int m_;
    std::vector<double> y_;
};

// "missile (states x, y, z, vx, vy, vz; 1 disturbance, 6 outputs)": what a network is tied to
std::string system_signature(const System& sys) {
    std::string names;
    for (const auto& s : sys.state_names()) names += (names.empty() ? "" : ", ") + s;
    return "'" + sys.name() + "' (states " + names + "; " + std::to_string(sys.disturbance_dim()) +
           " disturbance(s), " + std::to_string(sys.output_dim()) + " output(s))";
}

// Known inputs ([system] inputs) are the run's, not the training's: the model a network was trained on reads this
// config's table (the voltage applied during this record), with the names it was trained with.
void take_run_inputs(const std::string& path, const RunConfig& cfg, RunConfig* ncfg) {
    const ExprSystem* here = expr_system_of(*cfg.system);
    const ExprSystem* trained = expr_system_of(*ncfg->system);
    const std::vector<std::string> none, &ours = here ? here->inputs() : none, &theirs = trained ? trained->inputs() : none;
    auto names = [](const std::vector<std::string>& list) {
        std::string out;
        for (const auto& u : list) out += (out.empty() ? "" : ", ") + u;
        return list.empty() ? std::string("none") : out;
    };
    HINF_CHECK(ours == theirs, "network '" + path + "' was trained with the known inputs (" + names(theirs) +
                                   "), the config's system has (" + names(ours) +
                                   ") in [system] inputs (use a network trained on this config's system)");
    if (ours.empty()) return;
    ConfigDoc doc = ncfg->doc;
    toml::table& sys = *doc.root()["system"].as_table();
    const toml::table& run = *cfg.doc.root()["system"].as_table();
    sys.insert_or_assign("inputs", *run.get("inputs"));
    if (const toml::node* hold = run.get("input_interpolation")) sys.insert_or_assign("input_interpolation", *hold);
    else sys.erase("input_interpolation");
    // the record's times, checked by the caller, are what the table covers
    RunConfig with_ours = load_run_config(std::move(doc), true, false);
    ncfg->system = with_ours.system;
    ncfg->doc = with_ours.doc;
}

// A trained network for this config's system: the same state count is not the same system, so the kind, the outputs
// and the state names must agree (one line naming the network otherwise).
std::unique_ptr<FrozenNetwork> network_for(const std::string& path, const RunConfig& cfg, RunConfig* ncfg) {
    std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(path, ncfg);
    const std::string trained = system_signature(*ncfg->system), here = system_signature(*cfg.system);
    HINF_CHECK(ncfg->n != cfg.n || trained == here,
               "network '" + path + "' was trained for the system " + trained + ", the config's system is " + here +
                   " (use a network trained on this config's system)");
    HINF_CHECK(ncfg->n == cfg.n, "network '" + path + "' was trained for " + std::to_string(ncfg->n) +
                                     " states, the config's system has " + std::to_string(cfg.n));
    take_run_inputs(path, cfg, ncfg);
    return net;
}

// --mode's list, each checked.
std::vector<std::string> dnn_modes(const std::string& modes, Spelling spelling) {
    std::vector<std::string> out = split_list(modes);
    for (const std::string& mode : out)
        HINF_CHECK(mode == "oracle" || mode == "measured",
                   option_name("--mode", spelling) + " '" + mode + "' is not one of: oracle, measured");
    return out;
}

// how the caller asks for the measured mode only
std::string measured_mode(Spelling s) { return s == Spelling::program ? "--mode measured" : "modes = \"measured\""; }

bool has_measured(const std::vector<std::string>& modes) {
    return std::find(modes.begin(), modes.end(), "measured") != modes.end();
}

// --ensemble: one filter "dnn_gain_ensemble" with the mean of the networks' gains (method.md 16.15)
std::unique_ptr<OnlineFilter> gain_ensemble(const RunConfig& cfg, const FilterSetArgs& a, const FilterModel& exact,
                                            FilterSet& set) {
    const auto o = [&](const char* flag) { return option_name(flag, a.spelling); };
    HINF_CHECK(has_measured(dnn_modes(a.modes, a.spelling)),
               o("--ensemble") + ": gain networks run from measurements only (use " + measured_mode(a.spelling) + ")");
    RunConfig first;
    std::vector<std::unique_ptr<FrozenNetwork>> loaded = load_gain_ensemble(cfg, a.networks, &first, a.spelling);
    set.models.push_back(first.system);
    std::vector<const FrozenNetwork*> nets;
    for (auto& net : loaded) {
        nets.push_back(net.get());
        set.networks.push_back(std::move(net));
    }
    // it filters with the model the networks were trained on, as one gain network does
    FilterModel trained = exact;
    trained.system = first.system.get();
    return outputs_as_trained(make_gain_ensemble_filter(trained, nets, "dnn_gain_ensemble"), cfg, first);
}

}  // namespace

std::unique_ptr<OnlineFilter> outputs_as_trained(std::unique_ptr<OnlineFilter> filter, const RunConfig& cfg,
                                                 const RunConfig& trained) {
    if (cfg.output_weight == trained.output_weight) return filter;
    return std::make_unique<OutputsReweighted>(std::move(filter), cfg.output_weight, trained.output_weight, cfg.m);
}

std::vector<std::unique_ptr<FrozenNetwork>> load_gain_ensemble(const RunConfig& cfg, const std::vector<std::string>& paths,
                                                               RunConfig* first, Spelling spelling) {
    const auto o = [&](const char* flag) { return option_name(flag, spelling); };
    HINF_CHECK(paths.size() >= 2, o("--ensemble") + " averages the gains of two or more networks: give " +
                                      (spelling == Spelling::program ? "--network once per network"
                                                                     : "two or more in networks") +
                                      " (" + std::to_string(paths.size()) + " given)");
    std::vector<std::unique_ptr<FrozenNetwork>> nets;
    for (std::size_t i = 0; i < paths.size(); ++i) {
        const std::string& path = paths[i];
        RunConfig ncfg;
        std::unique_ptr<FrozenNetwork> net = network_for(path, cfg, &ncfg);
        HINF_CHECK(ncfg.variant == "gain", o("--ensemble") + ": network '" + path + "' is variant \"" + ncfg.variant +
                                               "\"; only variant \"gain\" networks (a gain K(x^)) can be averaged");
        if (i == 0) {
            gain_filter_check_time(*net, *cfg.system, "dnn_gain_ensemble");
            *first = ncfg;
        } else {
            HINF_CHECK(same_trained_model(ncfg, *first),
                       o("--ensemble") + ": network '" + path + "' was trained on another model than '" + paths[0] +
                           "' (its [system] table or its noise levels differ); an ensemble averages networks "
                           "trained on one model, e.g. with different training.seed");
        }
        nets.push_back(std::move(net));
    }
    return nets;
}

std::string filter_names() {
    std::string all;
    for (const SimpleFilter& f : kSimpleFilters) all += std::string(all.empty() ? "" : ", ") + f.name;
    return all + ", glf, dnn";
}

FilterSet build_filter_set(const RunConfig& cfg, const FilterSetArgs& a, const FilterModel& told,
                           const FilterModel& exact) {
    FilterSet set;
    auto& owned = set.filters;
    const auto o = [&](const char* flag) { return option_name(flag, a.spelling); };
    const std::string two_networks = a.spelling == Spelling::program ? "two --network files" : "two networks";
    for (const std::string& name : split_list(a.filters)) {
        const SimpleFilter* simple = nullptr;
        for (const SimpleFilter& f : kSimpleFilters)
            if (name == f.name) simple = &f;
        if (simple != nullptr) owned.push_back(simple->make(cfg, a, told, exact));
        else if (name == "glf") {
            // seed 001's comparison filter: N vertex linearizations along the nominal trajectory, one gain
            HINF_CHECK(cfg.rho > 0, cfg.rho_unset);  // the GLF designs at [filter] rho
            GlfDesign g = glf_design(cfg, a.glf_vertices, cfg.rho);
            if (!g.ok && cfg.rho > 0) {  // name the rho that fixes it
                auto feasible = [&](double r) {
                    return glf_design(cfg, a.glf_vertices, r).ok;
                };
                // the smallest level these vertices allow (minimise rho), checked by designing at it; the
                // minimisation can fail numerically where a cap works, so decades above [filter] rho next
                double fix = 0;
                const GlfDesign least = glf_design(cfg, a.glf_vertices, 0.0);
                if (least.ok && least.rho > cfg.rho && feasible(1.01 * least.rho)) fix = 1.01 * least.rho;
                for (double r = 10 * cfg.rho; fix == 0 && r <= 1e12 * cfg.rho; r *= 10)
                    if (feasible(r)) fix = r;
                char line[240];
                if (fix > 0)
                    std::snprintf(line, sizeof line, "with [filter] rho = %.4g; these %d vertices allow rho = %.4g: pass "
                                  "%s filter.rho=%.4g (or another %s, or drop glf)",
                                  cfg.rho, a.glf_vertices, fix, o("--set").c_str(), fix, o("--glf-vertices").c_str());
                else
                    std::snprintf(line, sizeof line, "at [filter] rho = %.4g nor at any rho up to 1e12 times it (%d "
                                  "vertices): try another %s, or drop glf", cfg.rho, a.glf_vertices,
                                  o("--glf-vertices").c_str());
                HINF_FAIL(o("--filters") + " glf: the LMI design found no gain " + std::string(line) + " (" + g.status +
                          ")");
            }
            HINF_CHECK(g.ok, o("--filters") + " glf: the LMI design found no gain: " + g.status + " (try another " +
                                 o("--glf-vertices") + ", or drop glf)");
            char note[160];
            std::snprintf(note, sizeof note, "glf: %d vertices at t =", g.vertices);
            std::string line = note;
            for (double t : g.vertex_times) {
                std::snprintf(note, sizeof note, " %.4g", t);
                line += note;
            }
            std::snprintf(note, sizeof note, " s; rho = %.4g (<= [filter] rho) on the polytope, min trace P; ", g.rho);
            set.notes.push_back(line + note + g.status);
            owned.push_back(make_glf_filter(exact, g));
        } else if (name == "dnn") {
            HINF_CHECK(!a.networks.empty(), a.spelling == Spelling::program
                                                ? "--filters dnn needs --network DIR/checkpoint.h5 (repeatable)"
                                                : "filters dnn needs a trained network in networks (a DIR/checkpoint.h5 "
                                                  "each)");
            HINF_CHECK(!cfg.retrain, "[online] retrain = true: on-line retraining runs in hinf operate only; here the "
                                     "DNN filter would run its checkpoint as trained (set online.retrain = false, or use "
                                     "hinf operate)");
            if (a.ensemble) {
                owned.push_back(gain_ensemble(cfg, a, exact, set));
                continue;
            }
            for (const std::string& path : a.networks) {
                RunConfig ncfg;
                std::unique_ptr<FrozenNetwork> net = network_for(path, cfg, &ncfg);
                const std::vector<std::string> modes = dnn_modes(a.modes, a.spelling);
                if (ncfg.variant == "gain") {  // its gain never sees x~: it runs from measurements only
                    HINF_CHECK(has_measured(modes), "network '" + path + "' is variant \"gain\": its gain K(x^) never "
                                                    "sees the true error, so " + o("--mode") +
                                                    " oracle is meaningless for it (use " + measured_mode(a.spelling) +
                                                    ")");
                    std::string label = "dnn_gain_measured";
                    for (const auto& f : owned)
                        HINF_CHECK(f->name() != label,
                                   two_networks + " give the filter name '" + label +
                                       "' (same variant twice; " + o("--ensemble") +
                                       " averages the gains of several gain networks into one filter)");
                    // it filters with the model it was trained on (its checkpoint's [system], e.g. a mismatched H),
                    // which the check above ties to this config's system by kind, states and outputs
                    gain_filter_check_time(*net, *cfg.system, label);
                    set.models.push_back(ncfg.system);
                    FilterModel trained = exact;
                    trained.system = ncfg.system.get();
                    owned.push_back(outputs_as_trained(make_gain_filter(trained, *net, label), cfg, ncfg));
                    set.networks.push_back(std::move(net));
                    continue;
                }
                for (const std::string& mode : modes) {
                    std::string label = "dnn_" + ncfg.variant + "_" + mode;
                    for (const auto& f : owned)
                        HINF_CHECK(f->name() != label,
                                   two_networks + " give the filter name '" + label + "' (same variant twice)");
                    // the gain uses rho of the network's own training config
                    if (mode == "measured") {
                        const std::string warning = dnn_measured_warning(ncfg.variant, cfg.n, cfg.m);
                        if (!warning.empty()) set.notes.push_back(warning);
                    }
                    owned.push_back(make_dnn_filter(exact, *net, *make_hinf_gain_law(ncfg.rho), mode == "measured", label));
                }
                set.networks.push_back(std::move(net));
            }
        } else
            HINF_FAIL(o("--filters") + ": unknown filter '" + name + "' (use " + filter_names() + ")");
    }
    HINF_CHECK(!owned.empty(), o("--filters") + ": no filter named (use " + filter_names() + ")");
    const std::vector<std::string> names = split_list(a.filters);
    HINF_CHECK(!a.ensemble || std::find(names.begin(), names.end(), "dnn") != names.end(),
               o("--ensemble") + " averages DNN filters: add dnn to " + o("--filters") +
                   (a.spelling == Spelling::program ? " (e.g. --filters dnn,ekf)" : " (e.g. \"dnn,ekf\")"));
    return set;
}

}  // namespace hinf
