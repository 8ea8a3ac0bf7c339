// The public facade (include/hinf/hinf.hpp) over the library's modules: configs, checkpoints, the filter
// factory, the recorded-data loop of `hinf filter` and the trainer. Thin: every number comes from the code the
// `hinf` program runs. Not the command line (src/cli).
#include "hinf/hinf.hpp"

#include <omp.h>

#include <cmath>
#include <filesystem>
#include <mutex>

#include "config/game_level.hpp"
#include "config/run_config.hpp"
#include "eval/acceptance.hpp"
#include "eval/compare.hpp"
#include "eval/engine.hpp"
#include "eval/filter_recorded.hpp"
#include "eval/observability.hpp"
#include "eval/training_run.hpp"
#include "eval/worst.hpp"
#include "export/export_c.hpp"
#include "filters/factory.hpp"
#include "hinf/config.hpp"
#include "io/checkpoint.hpp"
#include "io/measurements.hpp"
#include "io/run_lock.hpp"
#include "models/expr_system.hpp"
#include "models/system.hpp"
#include "net/network.hpp"
#include "sim/truth.hpp"
#include "train/gain_samples.hpp"
#include "train/storage_check.hpp"
#include "train/trainer.hpp"

namespace hinf {

std::string version() { return "0.1.0"; }

// ---------------------------------------------------------------------------------------------- Config

struct Config::Impl {
    RunConfig cfg;
};

namespace {
Config config_of(RunConfig cfg) {
    auto impl = std::make_shared<Config::Impl>();
    impl->cfg = std::move(cfg);
    Config c;
    c.impl = impl;
    return c;
}
const RunConfig& run_config(const Config& c) {
    HINF_CHECK(c.impl != nullptr, "hinf::Config is empty (make it with Config::load or Config::from_text)");
    return c.impl->cfg;
}
void check_size(std::size_t got, std::size_t want, const std::string& what) {
    HINF_CHECK(got == want, what + " has " + std::to_string(got) + " values, expected " + std::to_string(want));
}
}  // namespace

Config Config::load(const std::string& path, const std::vector<std::string>& overrides) {
    ConfigDoc doc = ConfigDoc::from_file(path);
    for (const auto& s : overrides) doc.set(s);
    return config_of(load_run_config(std::move(doc)));
}

Config Config::from_text(const std::string& toml, const std::string& name, const std::vector<std::string>& overrides) {
    ConfigDoc doc = ConfigDoc::from_text(toml, name);
    for (const auto& s : overrides) doc.set(s);
    return config_of(load_run_config(std::move(doc)));
}

int Config::states() const { return run_config(*this).n; }
int Config::outputs() const { return run_config(*this).m; }
int Config::disturbances() const { return run_config(*this).nv; }
double Config::dt() const { return run_config(*this).dt; }
double Config::t_final() const { return run_config(*this).t_final; }
double Config::rho() const { return run_config(*this).rho; }
double Config::rho_bound() const { return game_level_rho_star(run_config(*this)); }
double Config::rho_run_on() const { return game_level_rho_run_on(run_config(*this)); }
double Config::constant_storage_violation() const {
    const RunConfig& cfg = run_config(*this);
    if (cfg.variant != "gain" || !cfg.system->discrete_time()) return NAN;
    const StorageCheck c = constant_storage_check(cfg, gain_pool_build(cfg));
    return c.ran && c.solved && c.q_scale > 0 ? c.mu_lower / c.q_scale : NAN;
}
std::vector<double> Config::unseen_share() const {
    const StateInformation s = state_information(run_config(*this));
    return s.ran ? s.ratio : std::vector<double>{};
}
std::string Config::system() const { return run_config(*this).system->name(); }
std::vector<std::string> Config::state_names() const { return run_config(*this).system->state_names(); }
std::vector<std::string> Config::state_units() const { return run_config(*this).system->state_units(); }
std::vector<std::string> Config::input_names() const {
    const ExprSystem* e = expr_system_of(*run_config(*this).system);
    return e ? e->inputs() : std::vector<std::string>{};
}
std::vector<double> Config::inputs_at(double t) const {
    const ExprSystem* e = expr_system_of(*run_config(*this).system);
    std::vector<double> u(e ? e->inputs().size() : 0);
    if (!u.empty()) e->inputs_at(t, u.data());
    return u;
}
Config Config::with_inputs(const std::vector<double>& t, const std::vector<double>& values) const {
    const RunConfig& cfg = run_config(*this);
    const std::vector<std::string> names = input_names();
    HINF_CHECK(!names.empty(), "with_inputs: " + cfg.doc.source() + " [system] has no known inputs ([system] inputs)");
    check_size(values.size(), t.size() * names.size(), "with_inputs: the values (one per time and input)");
    ConfigDoc doc = cfg.doc;
    set_known_inputs(doc, names, t, values, "with_inputs");
    return config_of(load_run_config(std::move(doc), true, false));
}
std::vector<double> Config::initial_state() const { return run_config(*this).x0; }
std::vector<double> Config::initial_estimate() const { return run_config(*this).xhat0; }
std::string Config::text() const { return run_config(*this).doc.text(); }

std::vector<double> Config::measure(const std::vector<double>& x, double t) const {
    const RunConfig& cfg = run_config(*this);
    check_size(x.size(), std::size_t(cfg.n), "measure: the state x");
    std::vector<double> y(cfg.m);
    cfg.system->measurement(y.data(), x.data(), t, 1);
    outputs_to_user(cfg, y.data(), 1);  // the model's units are the noise-weighted ones ([online] noise_std list)
    return y;
}

std::vector<double> Config::advance(const std::vector<double>& x, const std::vector<double>& v, double t,
                                    double dt) const {
    const RunConfig& cfg = run_config(*this);
    check_size(x.size(), std::size_t(cfg.n), "advance: the state x");
    HINF_CHECK(v.empty() || v.size() == std::size_t(cfg.nv),
               "advance: the disturbance v has " + std::to_string(v.size()) + " values, expected " +
                   std::to_string(cfg.nv) + " (or none for v = 0)");
    std::vector<double> out(cfg.n), vm = v;
    disturbances_to_model(cfg, vm.data(), vm.empty() ? 0 : 1);  // v in the input's units ([online] disturbance_std list)
    system_advance(*cfg.system, out.data(), x.data(), vm.empty() ? nullptr : vm.data(), t, dt);
    return out;
}

// --------------------------------------------------------------------------------------------- Network

struct TrainedNetwork::Impl {
    std::string path, precision;
    RunConfig cfg;
    std::unique_ptr<FrozenNetwork> net;
    std::mutex mutex;  // FrozenNetwork::gradient uses the network's own workspace
};

namespace {
TrainedNetwork::Impl& network_impl(const TrainedNetwork& n) {
    HINF_CHECK(n.impl != nullptr, "hinf::Network is empty (make it with TrainedNetwork::load)");
    return *n.impl;
}
}  // namespace

TrainedNetwork TrainedNetwork::load(const std::string& checkpoint_path) {
    auto impl = std::make_shared<Impl>();
    impl->path = checkpoint_path;
    impl->net = ckpt_frozen_network(checkpoint_path, &impl->cfg);
    impl->precision = ckpt_precision(checkpoint_path);
    TrainedNetwork n;
    n.impl = impl;
    return n;
}

std::string TrainedNetwork::path() const { return network_impl(*this).path; }
Config TrainedNetwork::config() const { return config_of(network_impl(*this).cfg); }
std::string TrainedNetwork::variant() const { return network_impl(*this).cfg.variant; }
std::string TrainedNetwork::precision() const { return network_impl(*this).precision; }

std::vector<double> TrainedNetwork::gradient(const std::vector<double>& xtilde) const {
    Impl& im = network_impl(*this);
    const std::size_t n = std::size_t(im.cfg.n);
    HINF_CHECK(im.cfg.variant != "gain", "TrainedNetwork::gradient: '" + im.path + "' is a \"gain\" network, which has "
                                         "no dV/dx~ (its gain sees x^ alone: use gain(x^, t))");
    HINF_CHECK(!xtilde.empty() && xtilde.size() % n == 0,
               "TrainedNetwork::gradient: x~ has " + std::to_string(xtilde.size()) + " values, not a multiple of the " +
                   std::to_string(n) + " states (pass count x n values)");
    std::vector<double> p(xtilde.size());
    std::lock_guard<std::mutex> lock(im.mutex);
    im.net->gradient(p.data(), xtilde.data(), std::int64_t(xtilde.size() / n));
    return p;
}

std::vector<double> TrainedNetwork::gain(const std::vector<double>& xhat, double t) const {
    Impl& im = network_impl(*this);
    const std::size_t n = std::size_t(im.cfg.n);
    HINF_CHECK(im.cfg.variant == "gain", "TrainedNetwork::gain: '" + im.path + "' is a \"" + im.cfg.variant +
                                             "\" network, whose gain needs the error (use gradient(x~))");
    HINF_CHECK(!xhat.empty() && xhat.size() % n == 0,
               "TrainedNetwork::gain: x^ has " + std::to_string(xhat.size()) + " values, not a multiple of the " +
                   std::to_string(n) + " states (pass count x n values)");
    const std::int64_t count = std::int64_t(xhat.size() / n);
    std::vector<double> K(std::size_t(count) * n * std::size_t(im.cfg.m));
    std::lock_guard<std::mutex> lock(im.mutex);
    im.net->gain(K.data(), nullptr, nullptr, xhat.data(), t, *im.cfg.system, count);
    return K;
}

double TrainedNetwork::value(const std::vector<double>& xtilde) const {
    Impl& im = network_impl(*this);
    HINF_CHECK(im.cfg.variant != "gain", "TrainedNetwork::value: '" + im.path + "' is a \"gain\" network: its storage is "
                                         "x~'S(t)x~, not a network of x~ (use gain(x^, t))");
    check_size(xtilde.size(), std::size_t(im.cfg.n), "TrainedNetwork::value: x~");
    std::lock_guard<std::mutex> lock(im.mutex);
    return im.net->value(xtilde.data(), im.cfg.n);
}

// ---------------------------------------------------------------------------------------------- Filter

struct Filter::Impl {
    std::shared_ptr<const Config::Impl> config;
    std::string request;  // the one name asked for
    FilterOptions options;
    double dt = 0;
    std::vector<double> xhat0, P0;
    FilterSet set;  // owns the filter (and the networks it was built from)
    OnlineFilter* filter = nullptr;
    std::int64_t steps = 0;
    bool diverged = false;

    const RunConfig& cfg() const { return config->cfg; }

    // The filter set `hinf filter` builds for this one name, stepping by dt.
    FilterSet build(double step_dt) const {
        const RunConfig& c = cfg();
        // as filter_cmd.cpp: EKF/UKF/PF are told the config's [baseline] model and statistics
        FilterModel told = scenario_told_model(c, scenario_named("nominal")), model = filter_model(c);
        told.dt = model.dt = step_dt;
        std::vector<std::string> paths;
        for (const TrainedNetwork& n : options.networks) paths.push_back(network_impl(n).path);
        return build_filter_set(c, FilterSetArgs{request, paths, "measured", options.particles, options.roughening,
                                                 options.glf_vertices, options.ensemble, Spelling::library},
                                told, model);
    }
    void reset() {
        FilterStart start;
        start.xhat0 = xhat0;
        start.P0 = P0;
        filter->reset(start);
        steps = 0;
        diverged = false;
    }
};

namespace {
Filter::Impl& filter_impl(const Filter& f) {
    HINF_CHECK(f.impl != nullptr, "hinf::Filter is empty (make it with Filter::create)");
    return *f.impl;
}
}  // namespace

std::string Filter::names() { return filter_names(); }

Filter Filter::create(const Config& cfg, const std::string& name, const FilterOptions& options) {
    const RunConfig& c = run_config(cfg);
    HINF_CHECK(name.find(',') == std::string::npos,
               "Filter::create: '" + name + "' names several filters; create takes one (use create_all for a list)");
    bool known = false;
    for (const std::string& k : split_list(filter_names() + ",")) known = known || k == name || " " + name == k;
    HINF_CHECK(known, "unknown filter '" + name + "' (use one of: " + filter_names() + ")");
    HINF_CHECK(name != "dnn" || !options.networks.empty(),
               "the dnn filter needs a trained network: pass one (a DIR/checkpoint.h5 of `hinf train` or hinf.train)");
    HINF_CHECK(name != "dnn" || options.networks.size() <= 1 || options.ensemble,
               "Filter::create: dnn with " + std::to_string(options.networks.size()) +
                   " networks gives one filter per network (use create_all, or ensemble for one with their mean gain)");
    HINF_CHECK(options.particles >= 1, "particles must be >= 1 (got " + std::to_string(options.particles) + ")");
    HINF_CHECK(options.dt >= 0, "dt must be > 0, or 0 for the config's dt (got " + std::to_string(options.dt) + ")");
    auto im = std::make_shared<Impl>();
    im->config = cfg.impl;
    im->request = name;
    im->options = options;
    im->dt = options.dt > 0 ? options.dt : c.dt;
    im->xhat0 = options.initial_estimate.empty() ? c.xhat0 : options.initial_estimate;
    HINF_CHECK(int(im->xhat0.size()) == c.n, "initial_estimate has " + std::to_string(im->xhat0.size()) +
                                                 " values, the system has " + std::to_string(c.n) + " states");
    im->P0 = baseline_initial_covariance(c, options.initial_std);
    im->set = im->build(im->dt);
    HINF_CHECK(im->set.filters.size() == 1, "Filter::create: '" + name + "' gave " +
                                                std::to_string(im->set.filters.size()) + " filters (use create_all)");
    im->filter = im->set.filters.front().get();
    im->reset();
    Filter f;
    f.impl = im;
    return f;
}

std::vector<Filter> Filter::create_all(const Config& cfg, const std::string& names, const FilterOptions& options) {
    std::vector<Filter> out;
    const std::vector<std::string> list = split_list(names);
    HINF_CHECK(!list.empty(), "no filter named (use " + filter_names() + ")");
    for (const std::string& name : list) {
        if (name == "dnn" && options.networks.size() > 1) {
            for (const TrainedNetwork& n : options.networks) {
                FilterOptions one = options;
                one.networks = {n};
                out.push_back(create(cfg, name, one));
            }
        } else
            out.push_back(create(cfg, name, options));
    }
    for (std::size_t i = 0; i < out.size(); ++i)
        for (std::size_t j = 0; j < i; ++j)
            HINF_CHECK(out[i].name() != out[j].name(),
                       "two filters are named '" + out[i].name() + "' (the same filter or network variant twice)");
    return out;
}

std::string Filter::name() const { return filter_impl(*this).filter->name(); }
int Filter::states() const { return filter_impl(*this).cfg().n; }
int Filter::outputs() const { return filter_impl(*this).cfg().m; }
double Filter::dt() const { return filter_impl(*this).dt; }
bool Filter::has_covariance() const { return filter_impl(*this).filter->covariance() != nullptr; }
const FilterOptions& Filter::options() const { return filter_impl(*this).options; }
void Filter::reset() { filter_impl(*this).reset(); }
bool Filter::diverged() const { return filter_impl(*this).diverged; }

bool Filter::step(const double* y, double t) {
    Impl& im = filter_impl(*this);
    HINF_CHECK(y != nullptr, "Filter::step: no measurement");
    if (im.diverged) return false;  // frozen at its last finite estimate, as in `hinf filter`
    std::vector<double> ym(y, y + im.cfg().m);
    outputs_to_model(im.cfg(), ym.data(), 1);  // ([online] noise_std list: the model's noise-weighted units)
    const FilterStatus st = im.filter->step(FilterInput{ym.data(), t, im.steps, nullptr});
    ++im.steps;
    im.diverged = st != FILTER_OK;
    return !im.diverged;
}

bool Filter::step(const std::vector<double>& y, double t) {
    check_size(y.size(), std::size_t(outputs()), "Filter::step: the measurement y");
    return step(y.data(), t);
}

std::vector<double> Filter::estimate() const {
    const Impl& im = filter_impl(*this);
    const double* x = im.filter->estimate();
    return std::vector<double>(x, x + im.cfg().n);
}

std::vector<double> Filter::covariance() const {
    const Impl& im = filter_impl(*this);
    const double* P = im.filter->covariance();
    if (P == nullptr) return {};
    return std::vector<double>(P, P + std::size_t(im.cfg().n) * im.cfg().n);
}

FilterTrace Filter::run(const std::vector<double>& t, const std::vector<double>& y) const {
    const int m = outputs();
    HINF_CHECK(y.size() == t.size() * std::size_t(m),
               "Filter::run: y has " + std::to_string(y.size()) + " values for " + std::to_string(t.size()) +
                   " times; expected times x outputs = " + std::to_string(t.size() * std::size_t(m)));
    return run(t.data(), y.data(), std::int64_t(t.size()));
}

FilterTrace Filter::run(const double* t, const double* y, std::int64_t K) const {
    const Impl& im = filter_impl(*this);
    const RunConfig& c = im.cfg();
    Measurements ms = measurements_from_arrays(t, y, K, c.m, "the record");
    recorded_check_sampling(c, ms, "the record");  // a discrete-time system needs the record at its dt
    // `hinf filter` builds its filters on the record's interval: the same here, so the numbers are the same bits
    FilterSet fresh;
    std::unique_ptr<OnlineFilter> copy;
    OnlineFilter* f = nullptr;
    if (ms.dt == im.dt) {
        copy = im.filter->clone();
        f = copy.get();
    } else {
        fresh = im.build(ms.dt);
        f = fresh.filters.front().get();
    }
    RecordedPath path;
    RecordedResult r = filter_record_path(*f, c, ms, im.xhat0, im.P0, true, &path);
    FilterTrace tr;
    tr.name = r.name;
    tr.steps = K;
    tr.n = c.n;
    tr.m = c.m;
    tr.xhat = std::move(path.xhat);
    tr.covariance = std::move(path.P);
    tr.innovation = std::move(path.innov);
    tr.xhat_final = std::move(path.xhat_final);
    tr.diverged_at = r.diverged_at;
    tr.innovation_rms = r.innovation_rms;
    tr.innovation_mean = r.innovation_mean;
    tr.nis = std::move(path.nis);
    tr.nis_per_output = r.nis_per_output;
    tr.note = r.note;
    return tr;
}

// ------------------------------------------------------------------------------------------------ train

namespace {
TrainOptions train_options(const TrainSettings& s) {
    HINF_CHECK(s.threads >= 0 && s.threads <= 1024, "threads " + std::to_string(s.threads) + " must be between 0 and 1024");
    if (s.threads > 0) omp_set_num_threads(s.threads);
    TrainOptions opt;
    opt.out_dir = s.out_dir;
    opt.until = s.until;
    opt.quiet = s.quiet;
    if (s.on_progress) {
        auto cb = s.on_progress;
        opt.on_step = [cb](const TrainStepInfo& i) {
            cb(TrainProgress{i.step, i.last_step, i.t, i.loss_first, i.loss_last, i.rel_median, i.violation});
        };
    }
    return opt;
}

TrainReport report_of(const TrainSummary& s, const std::string& dir) {
    TrainReport r;
    r.diverged = s.status != 0;
    r.first_step = s.first_step;
    r.last_step = s.last_step;
    r.wall_seconds = s.wall_seconds;
    r.final_loss = s.final_loss;
    r.median_rel_residual = s.median_rel_residual;
    r.fraction_steps_violation_ok = s.fraction_steps_violation_ok;
    r.mean_cosine = s.mean_cosine;
    r.checkpoint = dir + "/checkpoint.h5";
    r.knot_runaway_step = s.runaway_step;
    r.knot_runaway_knot = s.runaway_knot;
    return r;
}

// the report of a run as it ended: the trainer's summary, the selection's and the acceptance check's results, as
// `hinf train`/`resume` print them
TrainReport report_of(const TrainingRun& run, const std::string& dir) {
    TrainReport r = report_of(run.summary, dir);
    if (run.best != nullptr && run.best->step >= 0) {  // after the check: it may keep the last checkpoint instead
        r.best_checkpoint = dir + "/best.h5";
        r.best_step = run.best->step;
    }
    const AcceptanceOutcome& a = run.acceptance;
    if (a.ran) {
        r.acceptance = a.pass ? "pass" : "fail";
        r.acceptance_checkpoint = a.file;
        r.acceptance_line = a.line;
        r.acceptance_advice = a.advice;
        r.acceptance_note = a.note;
        r.acceptance_selection_note = a.selection_note;
        r.acceptance_settle_note = a.settle_note;
        r.acceptance_rmse_settled = a.rmse_position_settled;
        r.acceptance_rmse_settled_ekf = a.rmse_position_settled_ekf;
        r.acceptance_rms_q_settled = a.rms_q_settled;
        r.acceptance_rms_q_settled_ekf = a.rms_q_settled_ekf;
    }
    return r;
}
}  // namespace

TrainReport train(const Config& cfg, const TrainSettings& settings) {
    RunConfig c = run_config(cfg);
    check_inputs_cover_run(c.doc, *c.system, c.dt, c.t_final);  // a config of with_inputs need not cover its run
    HINF_CHECK(!settings.out_dir.empty(), "train: out_dir is required (the directory for trajectory.h5 and checkpoint.h5)");
    // the directory is this call's until it returns: the training, the selection, the check, a run swapped in
    const RunDirLock lock(settings.out_dir, "hinf train (library)");
    HINF_CHECK(settings.force || !std::filesystem::exists(settings.out_dir + "/checkpoint.h5"),
               settings.out_dir + " already holds a run (checkpoint.h5): continue it with resume(\"" +
                   settings.out_dir + "/checkpoint.h5\"), or start afresh with force or another out_dir");
    return report_of(training_run_fresh(std::move(c), train_options(settings), {}), settings.out_dir);
}

TrainReport resume(const std::string& checkpoint_path, const TrainSettings& settings) {
    std::string dir = std::filesystem::path(checkpoint_path).parent_path().string();
    if (dir.empty()) dir = ".";
    return report_of(training_run_resume(checkpoint_path, train_options(settings), "hinf resume (library)", {}), dir);
}

// ---------------------------------------------------------------------------------------------- compare, worst

namespace {
// compare's, worst's and replay_worst's filter set, as the program builds it (`who` names the call in errors): the
// classical filters told `told`, the others the config's own model; the settings' threads applied
struct SimulationFilters {
    FilterSet set;
    std::vector<const OnlineFilter*> filters;  // set's, in its order
    std::vector<std::string> paths;            // the networks' checkpoints
};
template <class Settings>
SimulationFilters simulation_filters(const RunConfig& c, const Settings& s, const char* who, const FilterModel& told) {
    HINF_CHECK(!s.out_dir.empty(), std::string(who) + ": out_dir is required (the directory for its result file)");
    HINF_CHECK(s.particles >= 1, std::string(who) + ": particles must be >= 1");
    HINF_CHECK(std::isfinite(s.roughening) && s.roughening >= 0,
               std::string(who) + ": roughening must be a finite number >= 0 (0: the plain bootstrap PF)");
    HINF_CHECK(s.threads >= 0 && s.threads <= 1024,
               "threads " + std::to_string(s.threads) + " must be between 0 and 1024");
    if (s.threads > 0) omp_set_num_threads(s.threads);
    SimulationFilters out;
    for (const TrainedNetwork& n : s.networks) out.paths.push_back(network_impl(n).path);
    const FilterSetArgs args{s.filters,      out.paths,  s.modes, s.particles, s.roughening,
                             s.glf_vertices, s.ensemble, Spelling::library};
    out.set = build_filter_set(c, args, told, filter_model(c));
    for (const auto& f : out.set.filters) out.filters.push_back(f.get());  // the pointees stay where they are
    return out;
}
}  // namespace

CompareReport compare(const Config& cfg, const CompareSettings& settings) {
    const RunConfig& c = run_config(cfg);
    HINF_CHECK(settings.runs >= 1, "compare: runs must be >= 1");
    CompareOptions opt;
    opt.scenario = scenario_named(settings.scenario, Spelling::library);
    opt.runs = settings.runs;
    opt.until = settings.until;
    opt.quiet = settings.quiet;
    opt.out_dir = settings.out_dir;
    // as compare_cmd.cpp: the Bayesian filters are told the true statistics, or wrong ones by scenario
    const SimulationFilters sf = simulation_filters(c, settings, "compare", scenario_told_model(c, opt.scenario));
    const CompareSummary s = compare_run(c, sf.filters, opt);
    CompareReport r;
    r.scenario = s.scenario;
    r.file = settings.out_dir + "/compare.h5";
    r.runs = s.runs;
    r.steps = s.steps;
    r.truth_escaped_runs = s.truth_escaped_runs;
    r.wall_seconds = s.wall_seconds;
    for (const auto& f : s.filters) {
        r.streams_identical = r.streams_identical && f.stream_hash == s.truth_stream_hash;
        CompareRow row;
        row.name = f.name;
        row.mode = f.mode;
        row.diverged_runs = f.diverged_runs;
        row.rmse_position = f.rmse_position;
        row.rmse_position_settled = f.rmse_position_settled;
        row.rmse_velocity = f.rmse_velocity;
        row.rmse_velocity_settled = f.rmse_velocity_settled;
        row.attenuation_ratio = f.attenuation_ratio;
        row.mse_db = f.mse_db;
        row.mse_filtered_db = f.mse_filtered_db;
        row.us_per_step = f.us_per_step;
        row.nees_per_state = f.nees_per_state;
        r.filters.push_back(row);
    }
    HINF_CHECK(r.streams_identical, "compare: a filter was fed a different measurement stream (bug)");
    return r;
}

// ---------------------------------------------------------------------------------------------- worst

WorstReport worst(const Config& cfg, const WorstSettings& settings) {
    const RunConfig& c = run_config(cfg);
    HINF_CHECK(std::isnan(settings.energy) || (std::isfinite(settings.energy) && settings.energy > 0),
               "worst: energy must be a finite number > 0 (or NaN: the nominal draws' energy)");
    WorstOptions opt;  // hinf worst's defaults but what the settings name
    if (!std::isnan(settings.energy)) opt.energy = settings.energy;
    opt.until = settings.until;
    opt.evals = settings.evals;
    opt.random_starts = settings.random_starts;
    opt.linear_pieces = settings.linear_pieces;
    opt.keep_initial_error = settings.keep_initial_error;
    opt.quiet = settings.quiet;
    opt.spelling = Spelling::library;
    // as worst_cmd.cpp: the signals are found for a budget, so the Bayesian filters are told the nominal statistics
    const SimulationFilters sf =
        simulation_filters(c, settings, "worst", scenario_told_model(c, scenario_named("nominal")));
    const WorstNetworks wn = worst_networks(sf.filters, sf.paths);
    const WorstResult r = worst_search(c, sf.filters, wn.games, opt);
    const RunDirLock lock(settings.out_dir, "hinf worst (library)");
    worst_write(settings.out_dir + "/worst.h5", worst_config(c, opt), opt, r);
    WorstReport w;
    w.file = settings.out_dir + "/worst.h5";
    w.energy = r.energy;
    w.steps = r.steps;
    w.wall_seconds = r.wall_seconds;
    const std::size_t F = r.filters.size();
    for (std::size_t i = 0; i < F; ++i) {
        const WorstFilterResult& f = r.filters[i];
        WorstRow row;
        row.name = f.name;
        row.ratio = f.worst.ratio;
        row.small_signal = f.linear_gain;
        row.diverged = r.cross.diverged_at[i * F + i] >= 0;  // row i: the worst set found for filter i
        row.found_from = f.restarts[std::size_t(f.best)].start;
        w.filters.push_back(row);
    }
    return w;
}

ReplayReport replay_worst(const Config& cfg, const std::string& worst_file, const WorstSettings& settings) {
    const RunConfig& c = run_config(cfg);
    HINF_CHECK(!worst_file.empty(), "replay_worst: worst_file is required (a worst.h5 of hinf worst or hinf::worst)");
    WorstOptions opt;
    opt.quiet = settings.quiet;
    opt.spelling = Spelling::library;
    // as worst_cmd.cpp: the signals were found for a budget, so the Bayesian filters are told the nominal statistics
    const SimulationFilters sf =
        simulation_filters(c, settings, "replay_worst", scenario_told_model(c, scenario_named("nominal")));
    const WorstReplayRun run =
        worst_replay_file(c, sf.filters, worst_file, settings.out_dir, opt, "hinf replay_worst (library)");
    ReplayReport r;
    r.file = run.file;
    r.steps = run.steps;
    r.keep_initial_error = run.keep_initial_error;
    r.sets = run.table.sets;
    r.energy = run.table.signal_energy;
    r.filters = run.table.filters;
    r.ratio = run.table.ratio;
    for (double at : run.table.diverged_at) r.diverged.push_back(at >= 0);
    return r;
}

// ---------------------------------------------------------------------------------------------- export

ExportReport export_c99(const std::vector<std::string>& checkpoints, const std::string& dir, const std::string& prefix,
                        bool ensemble) {
    ExportOptions opt;
    opt.dir = dir;
    opt.prefix = prefix;
    opt.ensemble = ensemble;
    const ExportResult r = export_c(checkpoints, opt);
    ExportReport out;
    out.files = r.files;
    out.parameters = r.parameters;
    out.weight_bytes = r.weight_bytes;
    out.flops_per_step = r.flops_per_step;
    out.networks = r.networks;
    out.variant = r.variant;
    out.precision = r.precision;
    out.system = r.system;
    return out;
}

}  // namespace hinf
