// The offline training driver: per time step, N samples around x~(t), per-sample constants once,
// K Adam steps on minibatches, then p at x~(t), gain k*, worst case v*, n* (seed 000 eqs. (6)-(8))
// and the sampled-data updates (eqs. (18)-(20)); for [filter] type = "h2hinf" the same loop serves seed 001
// (l*, v*, n* of eqs. (9)-(11), (21)-(23)) and also logs the second residual and the consistency of (23).
// The numerics are in kernels/.
#include "train/trainer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "adam.hpp"
#include "config/game_level.hpp"
#include "hinf/error.hpp"
#include "io/checkpoint.hpp"
#include "io/progress.hpp"
#include "io/run_lock.hpp"
#include "io/trajectory.hpp"
#include "net/network.hpp"
#include "par/par.hpp"
#include "sampling.hpp"
#include "filters/gain_law.hpp"
#include "gain.hpp"
#include "train/gain_samples.hpp"
#include "train/samples.hpp"
#include "train/storage_check.hpp"

namespace hinf {

RunConfig flat_start_config(const RunConfig& cfg, bool by_hinf) {
    RunConfig flat = cfg;
    if (by_hinf && !ConfigSection(cfg.doc, "network").has("storage_init")) flat.chosen.push_back("network.storage_init");
    if (by_hinf && !ConfigSection(cfg.doc, "objective").has("margin")) flat.chosen.push_back("objective.margin");
    flat.storage_init = "flat";
    flat.doc.set("network.storage_init=\"flat\"");
    char margin[64];
    std::snprintf(margin, sizeof margin, "objective.margin=%.17g", cfg.margin);
    flat.doc.set(margin);
    return flat;
}

namespace {

// Whether hinf may replace the run's Riccati start by the flat one (docs/method.md section 16.7, "A start that
// diverges"): a gain run with S(t) whose config does not name network.storage_init
bool riccati_start_replaceable(const RunConfig& cfg) {
    return cfg.variant == "gain" && cfg.storage_knots > 0 && cfg.storage_init == "riccati" &&
           !ConfigSection(cfg.doc, "network").has("storage_init");
}

// The trajectory columns of a config: one list, used to create, reopen (resume, roll-back) and fill the file.
std::vector<TrajectoryColumn> trajectory_columns(const RunConfig& c) {
    const int n = c.n, m = c.m, nv = c.nv;
    std::vector<TrajectoryColumn> cols = {
        {"t", 1, "s", "time of the row"},
        {"x", n, "state units", "true state x(t) (training: driven by the worst-case v*)"},
        {"xhat", n, "state units", "estimate x^(t)"},
        {"xtilde", n, "state units", "estimation error x~(t) = x - x^"},
        {"y", m, "output units", "measurement y(t) = C(x) + n*(t)"},
        {"gain", n * m, "state/output per s", "filter gain k*(x^) of eq. (8), row-major n x m"},
        {"v_star", nv, "disturbance units", "worst-case disturbance v* of eq. (6)"},
        {"n_star", m, "output units", "worst-case noise n* = -k*^T p/(2 rho) (eq. (7), sign per Theorem 1's proof)"},
        {"p", n, "V per state unit", "network output dV/dx~ at x~(t) after the K Adam steps"},
        {"loss", 2, "1", "minibatch loss at the first and the last (K-th) Adam step of the time step, before its update"},
        {"hjie_residual", 1, "V per s", "HJIE residual of eq. (16) at x~(t)"},
        {"hjie_rel_residual_median", 1, "1", "median over the N samples of |eps_i| / S_i after the K steps"},
        {"hjie_rel_residual_p95", 1, "1", "95th percentile of |eps_i| / S_i"},
        {"hji_violation_fraction", 1, "1", "share of samples with HJIE_i > 0.01 S_i"},
        {"hji_positive_fraction", 1, "1", "share of samples with HJIE_i > 0"},
        {"cosine_mean", 1, "1", "mean over samples of p_i^T x~_i / (|p_i| |x~_i|)"},
    };
    if (c.type != "h2hinf") return cols;
    // The mixed H2/H-infinity filter (seed 001) adds its second residual and the consistency check of
    // eqs. (21)-(23): x~ propagated by (23) against x - x^ propagated by (21) and (22).
    std::vector<TrajectoryColumn> mixed = {
        {"hjie2_residual", 1, "V per s", "second coupled HJIE residual of seed 001 eq. (20) at x~(t)"},
        {"hjie2_rel_residual_median", 1, "1", "median over the N samples of |eps2_i| / S2_i after the K steps"},
        {"hjie2_rel_residual_p95", 1, "1", "95th percentile of |eps2_i| / S2_i"},
        {"hji2_violation_fraction", 1, "1", "share of samples with HJIE2_i > 0.01 S2_i"},
        {"consistency_gap", 1, "state units",
         "max_j |x~(t+h) by eq. (23) - (x(t+h) by (21) - x^(t+h) by (22))|, signs of n* and (23) per Theorem 1's proof"},
        {"consistency_gap_printed", 1, "state units",
         "the same gap with n* = +l*^T p/(2 r^2) (eq. (11)) and +h l (h(x)-h(x^)) in eq. (23) as printed"},
    };
    cols.insert(cols.end(), mixed.begin(), mixed.end());
    return cols;
}

// What one time step gives: a plain record, turned into a trajectory row by record_row.
struct StepRecord {
    double t = 0;
    std::vector<double> x, xhat, xtilde, y, gain, v_star, n_star, p;
    double loss_first = 0, loss_last = 0;
    double residual = 0, rel_median = 0, rel_p95 = 0, violation = 0, positive = 0, cosine = 0;
    // seed 001 only
    double residual2 = 0, rel_median2 = 0, rel_p95_2 = 0, violation2 = 0, gap = 0, gap_printed = 0;
};

// One row of the trajectory file, holding exactly the columns of trajectory_columns(c).
std::map<std::string, std::vector<double>> record_row(const StepRecord& r, const RunConfig& c) {
    std::map<std::string, std::vector<double>> row = {
        {"t", {r.t}},
        {"x", r.x},
        {"xhat", r.xhat},
        {"xtilde", r.xtilde},
        {"y", r.y},
        {"gain", r.gain},
        {"v_star", r.v_star},
        {"n_star", r.n_star},
        {"p", r.p},
        {"loss", {r.loss_first, r.loss_last}},
        {"hjie_residual", {r.residual}},
        {"hjie_rel_residual_median", {r.rel_median}},
        {"hjie_rel_residual_p95", {r.rel_p95}},
        {"hji_violation_fraction", {r.violation}},
        {"hji_positive_fraction", {r.positive}},
        {"cosine_mean", {r.cosine}},
    };
    if (c.type == "h2hinf") {
        row["hjie2_residual"] = {r.residual2};
        row["hjie2_rel_residual_median"] = {r.rel_median2};
        row["hjie2_rel_residual_p95"] = {r.rel_p95_2};
        row["hji2_violation_fraction"] = {r.violation2};
        row["consistency_gap"] = {r.gap};
        row["consistency_gap_printed"] = {r.gap_printed};
    }
    return row;
}


// max_j |a_j - b_j|
double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
    double g = 0;
    for (std::size_t j = 0; j < a.size(); ++j) g = std::max(g, std::fabs(a[j] - b[j]));
    return g;
}

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0;
    std::size_t k = static_cast<std::size_t>(std::floor(q * double(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[k];
}

bool all_finite(const std::vector<double>& v) {
    for (double x : v)
        if (!std::isfinite(x)) return false;
    return true;
}

template <typename T>
bool all_finite_t(const std::vector<T>& v) {
    for (T x : v)
        if (!std::isfinite(x)) return false;
    return true;
}

// Set by train_request_stop (a signal handler): the signal number, read between time steps.
volatile std::sig_atomic_t g_stop_signal = 0;

template <typename T>
class Trainer {
public:
    Trainer(RunConfig cfg, std::string out_dir) : cfg_(std::move(cfg)), dir_(std::move(out_dir)) {}

    void start_fresh() {
        ck_.net = network_create<T>(cfg_);
        if (gain_ && cfg_.input_box > 0) {  // where the filter holds its network's input (method.md 16.10)
            build_pool();
            gain_input_box(&ck_.net.step.gain, cfg_, pool_);
            if (ck_.net.step.gain.zlo.empty())
                std::fprintf(stderr, "hinf: note: network.input_box: a training truth run is not finite, so the "
                                     "filter's network input is not held (docs/method.md section 16.10)\n");
        }
        ck_.adam_m.assign(ck_.net.theta.size(), T(0));
        ck_.adam_v.assign(ck_.net.theta.size(), T(0));
        ck_.state.step = 0;
        ck_.state.x = cfg_.x0;
        ck_.state.xhat = cfg_.xhat0;
        ck_.config_text = config_record(cfg_);
        std::filesystem::create_directories(dir_);
        if (writer_) std::filesystem::remove_all(dir_ + "/start");  // an earlier run's (train --force)
        if (start_diverged_ && par_size() == 1 && gain_ && cfg_.storage_knots > 0 && cfg_.storage_init == "riccati")
            check_start();
        if (writer_) traj_ = TrajectoryWriter::create(dir_ + "/trajectory.h5", trajectory_columns(cfg_),
                                         {{"format", "hinf-trajectory"},
                                          {"filter_type", cfg_.type},
                                          {"variant", cfg_.variant},
                                          {"system", cfg_.system->name()},
                                          {"config", ck_.config_text}});
    }

    // A start that diverges (docs/method.md section 16.7, "A start that diverges"): the untrained filter from the
    // Riccati knots runs on the validation noise; where some runs diverge, so does the one from flat knots, and the
    // run starts flat when that diverges in fewer -- unless the config names network.storage_init itself. The knots
    // are shaped along the noise-free trajectory from x0; runs that leave it (a chaotic system) can meet them where
    // they fit none of them. The switch is recorded in the config (storage_init and the margin the run trains with)
    void check_start() {
        const std::int64_t first = ck_.net.step.shape.param_count(), count = ck_.net.step.gain.storage_params(cfg_.n);
        if (std::all_of(ck_.net.theta.begin() + first, ck_.net.theta.begin() + first + count, [](T v) { return v == T(0); }))
            return;  // network_create started it flat already (held before the first knot)
        const std::string d = dir_ + "/start";
        std::filesystem::create_directories(d);
        Checkpoint<T> probe = ck_;
        ckpt_write(d + "/riccati.h5", probe, cfg_);
        const std::int64_t riccati = start_diverged_(cfg_, d + "/riccati.h5");
        if (riccati == 0) return;
        RunConfig flat = flat_start_config(cfg_, /*by_hinf=*/true);
        std::fill(probe.net.theta.begin() + first, probe.net.theta.begin() + first + count, T(0));  // flat knots
        probe.config_text = config_record(flat);
        ckpt_write(d + "/flat.h5", probe, flat);
        const std::int64_t flat_diverged = start_diverged_(flat, d + "/flat.h5");
        const bool named = !riccati_start_replaceable(cfg_);
        const bool change = flat_diverged < riccati && !named;
        std::fprintf(stderr,
                     "hinf: note: network.storage_init = \"riccati\": the untrained filter diverged in %lld of %lld "
                     "validation runs from the knots on the game's Riccati solution along the noise-free trajectory, "
                     "in %lld from flat knots; %s (docs/method.md section 16.7, \"A start that diverges\")\n",
                     static_cast<long long>(riccati), static_cast<long long>(cfg_.select_runs),
                     static_cast<long long>(flat_diverged),
                     change ? "the run starts flat (recorded in its config)"
                     : named ? "the config names the Riccati start, so it is kept (remove the key to let hinf choose)"
                             : "the Riccati start is kept");
        if (!change) return;
        cfg_ = std::move(flat);
        ck_.net = std::move(probe.net);
        ck_.config_text = probe.config_text;
    }

    /// written_text: the config the checkpoint and trajectory were written with (differs from ck.config_text
    /// after `resume --set`: the trajectory is checked against the old one, then carries the new one)
    void start_from(Checkpoint<T> ck, const std::string& written_text) {
        ck_ = std::move(ck);
        if (writer_) {
            traj_ = TrajectoryWriter::reopen(dir_ + "/trajectory.h5", trajectory_columns(cfg_), hsize_t(ck_.state.step),
                                             {{"config", written_text}});
            if (written_text != ck_.config_text) traj_.set_text("config", ck_.config_text);
        }
        if (written_text != ck_.config_text) checkpoint();  // the change is recorded before the first step runs
    }

    const GainPool& pool() const { return pool_; }  // the gain variant's truth runs (empty for the others)

    // the gain variant's samples across 0 from truth runs that stay on one side of it, in one line ("" for none;
    // docs/method.md section 16.3, "Where the model holds")
    std::string sign_note() {
        if (!gain_ || !cfg_.state_lo.empty()) return "";
        if (pool_.runs.empty()) build_pool();
        return gain_sign_note(cfg_, gain_sign_crossings(cfg_, pool_, ck_.net.step.gain));
    }

    // the gain variant's truth runs, and a note (rank 0, once) when some ran away
    void build_pool() {
        pool_ = gain_pool_build(cfg_);
        const std::string note = gain_pool_note(cfg_, pool_);
        if (!note.empty() && par_root()) std::fputs(note.c_str(), stderr);
    }

    TrainSummary run(std::int64_t last_step, bool quiet) {
        TrainSummary sum;
        sum.first_step = ck_.state.step;
        const int n = cfg_.n;
        const std::int64_t N = cfg_.samples;
        // per-time-step buffers, allocated once
        grad_.resize(ck_.net.theta.size());
        idx_.resize(cfg_.batch);
        work_.resize(std::max<std::int64_t>(N, cfg_.batch));
        perm_.resize(N);
        p_all_.resize(N * n);
        P_all_.resize(N * n * n);
        vals_.resize(N);
        cos_.resize(N);
        ws_.reserve(ck_.net.step, int(std::max<std::int64_t>(N, cfg_.batch)));

        if (gain_) {  // every process simulates the same pool and draws the same samples (deterministic)
            if (pool_.runs.empty()) build_pool();
            K_all_.resize(N * n * cfg_.m);
        }
        const int chunks = gain_ ? kern::gain_step_chunks(int(cfg_.batch), ck_.net.step)
                                 : int((cfg_.batch + ck_.net.step.chunk - 1) / ck_.net.step.chunk);
        HINF_CHECK(split_.ranks <= chunks,
                   std::to_string(split_.ranks) + " MPI processes for a minibatch of " + std::to_string(chunks) +
                       " chunk(s) (training.batch " + std::to_string(cfg_.batch) + " / network.chunk " +
                       std::to_string(ck_.net.step.chunk) + "): start at most as many processes as chunks");
        Progress progress("train", ck_.state.step, last_step, quiet);
        auto t0 = std::chrono::steady_clock::now();
        std::vector<double> medians, medians2;
        sum.mixed = cfg_.type == "h2hinf";
        std::int64_t rollbacks = 0, cosines = 0;
        StepRecord rec;
        while (ck_.state.step < last_step) {
            if (g_stop_signal != 0 && split_.ranks == 1) {
                // Ctrl-C or SIGTERM: a safe point (between time steps); keep this step and say how to go on
                const int sig = g_stop_signal;
                if (ckpt_non_finite(ck_).empty()) checkpoint();
                if (writer_)
                    std::fprintf(stderr, "\nhinf: stopped by signal %d at time step %lld (t = %.2f s); checkpoint %s/checkpoint.h5 "
                                 "holds it: continue with `hinf resume %s/checkpoint.h5`\n",
                                 sig, static_cast<long long>(ck_.state.step), cfg_.time_of(ck_.state.step), dir_.c_str(),
                                 dir_.c_str());
                sum.status = 128 + sig;
                break;
            }
            if (!time_step(&rec)) {
                if (cfg_.on_divergence == "rollback" && rollbacks < cfg_.max_rollbacks && roll_back(++rollbacks))
                    continue;
                sum.status = 4;
                break;
            }
            ++ck_.state.step;
            if (gain_ && sum.runaway_step < 0) runaway_check(&sum);
            medians.push_back(rec.rel_median);
            sum.fraction_steps_rel_ok += rec.rel_median <= 0.01 ? 1 : 0;
            sum.fraction_steps_violation_ok += rec.violation <= 0.01 ? 1 : 0;
            if (std::isfinite(rec.cosine)) {  // a lost diagnostic filter's row has none (gain_time_step)
                sum.mean_cosine += rec.cosine;
                ++cosines;
            }
            medians2.push_back(rec.rel_median2);
            sum.fraction_steps_violation2_ok += rec.violation2 <= 0.01 ? 1 : 0;
            sum.max_consistency_gap = std::max(sum.max_consistency_gap, rec.gap);
            sum.max_consistency_gap_printed = std::max(sum.max_consistency_gap_printed, rec.gap_printed);
            sum.final_loss = rec.loss_last;
            if (ck_.state.step % cfg_.checkpoint_every == 0 || ck_.state.step == last_step) {
                // only a finite state is kept as good (Adam's v can overflow in float while the loss is finite)
                const std::string bad = ckpt_non_finite(ck_);
                if (!bad.empty()) {
                    --ck_.state.step;
                    const std::size_t eq = bad.find(" = ");
                    diagnose(ck_.state.step, bad.substr(0, eq).c_str(), std::strtod(bad.c_str() + eq + 3, nullptr));
                    sum.status = 4;
                    break;
                }
                checkpoint();
            }
            char detail[160];
            std::snprintf(detail, sizeof detail, "t=%.2fs loss %.3g->%.3g rel.resid %.2g viol %.3f |",
                          cfg_.time_of(ck_.state.step), rec.loss_first, rec.loss_last, rec.rel_median, rec.violation);
            progress.update(ck_.state.step, detail);
            if (on_step_)
                on_step_(TrainStepInfo{ck_.state.step, last_step, cfg_.time_of(ck_.state.step), rec.loss_first,
                                       rec.loss_last, rec.rel_median, rec.violation});
        }
        sum.last_step = ck_.state.step;
        sum.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const double cnt = double(std::max<std::size_t>(1, medians.size()));
        sum.fraction_steps_rel_ok /= cnt;
        sum.fraction_steps_violation_ok /= cnt;
        sum.mean_cosine = cosines > 0 ? sum.mean_cosine / double(cosines) : NAN;
        sum.median_rel_residual = percentile(medians, 0.5);
        sum.median_rel_residual2 = percentile(medians2, 0.5);
        sum.fraction_steps_violation2_ok /= cnt;
        if (writer_) traj_.flush();
        return sum;
    }

private:
    // A knot whose log-diagonal ran below storage_runaway_level: recorded once, and said once, with the way out
    // (docs/method.md section 16.7, "Why 280 knots fail")
    void runaway_check(TrainSummary* sum) {
        const StorageLow low = storage_lowest_log_diagonal(ck_.net);
        if (low.knot < 0 || !(low.value < storage_runaway_level(ck_.net.step.gain))) return;
        sum->runaway_step = ck_.state.step;
        sum->runaway_knot = low.knot;
        sum->runaway_state = low.state;
        sum->runaway_value = low.value;
        if (!writer_) return;
        const int J = ck_.net.step.gain.knots;
        const std::vector<std::string> names = cfg_.system->state_names();
        const std::string state = low.state < int(names.size()) ? names[low.state] : std::to_string(low.state + 1);
        std::string counts = std::to_string(J);  // J, J/2, J/4 in falling order, each once (a small J repeats them)
        if (J / 2 >= 1) counts += "," + std::to_string(J / 2);
        if (J / 4 >= 1 && J / 4 < J / 2) counts += "," + std::to_string(J / 4);
        std::fprintf(stderr,
                     "\nhinf: note: at time step %lld the storage's knot %d (of 0-%d; t = %.4g s) has the log-diagonal of "
                     "state %s at %.3g, below %.3g, where it no longer moves S(t). On seed 000's missile every training "
                     "where this happened gave a filter 5-30 times the EKF's error, every one without it 1.06-1.40 times; "
                     "on a chaotic Roessler system it happened at 1.7 times, and fewer knots were worse. Compare this "
                     "count with fewer knots: hinf sweep CONFIG --vary network.storage_knots=%s (docs/method.md "
                     "section 16.7)\n",
                     static_cast<long long>(ck_.state.step), low.knot, J, ck_.net.step.gain.knot_time(low.knot),
                     state.c_str(), low.value, storage_runaway_level(ck_.net.step.gain), counts.c_str());
    }

    // One time step of the offline phase (docs/architecture.md): four named phases filling one record,
    // which becomes one trajectory row. false on numerical trouble (diagnostic printed).
    bool time_step(StepRecord* rec) {
        const std::int64_t step = ck_.state.step;
        *rec = StepRecord();
        rec->t = cfg_.time_of(step);
        if (gain_) return gain_time_step(rec, step);
        // 1. N samples around x~(t), and their constants (independent of the weights: once per time step)
        samples_build(&smp_, cfg_, ck_.state.x, ck_.state.xhat, step);
        // 2. K Adam steps on minibatches of M (seed 000 eqs. (14)-(15))
        if (!adam_phase(rec, step)) return false;
        // 3. residual statistics over all N samples after the K steps
        if (!residual_statistics(rec, step)) return false;
        // 4. p at x~(t), gain k*, worst case v*, n* (eqs. (6)-(8)), then eqs. (18)-(20)
        return advance_state(rec, step);
    }

    // Variant gain (docs/method.md section 14): samples (x^_i, x~_i) along the pool's truth runs, K Adam steps on
    // the dissipation inequality of V = x~'S x~ with the gain K(x^), then the diagnostic filter (the current
    // network on pool run 0, real noise) advanced one step. One trajectory row per time step.
    bool gain_time_step(StepRecord* rec, std::int64_t step) {
        const kern::GainSpec& g = ck_.net.step.gain;
        gain_samples_build(&gsm_, cfg_, pool_, g, cfg_.samples, std::uint64_t(step));
        const kern::HjieSystemView view = gsm_.view();
        const bool ok = adam_steps(rec, step, [&](T* grad) {
            return kern::gain_step_gradient(grad, ck_.net.theta.data(), view, gsm_.z.data(), idx_.data(),
                                            int(cfg_.batch), ck_.net.step, ws_, split_.ranks > 1 ? &split_ : nullptr);
        });
        if (!ok) return false;
        // statistics over all N samples after the K steps
        const int n = cfg_.n, m = cfg_.m, nv = cfg_.nv;
        const std::int64_t N = cfg_.samples;
        std::vector<double> S(n * n), Sd(n * n);
        kern::gain_network_eval(K_all_.data(), ck_.net.theta.data(), gsm_.z.data(), view.Hx, gsm_.t.data(), N,
                                ck_.net.step, ws_, view.Fx);
        kern::gain_storage_eval(S.data(), Sd.data(), ck_.net.theta.data(), 0.0, ck_.net.step);
        kern::GainLossParams lp = g.loss;
        lp.xt0 = g.xt0.data();
        lp.dx = g.dx.data();
        std::vector<double> rel(N);
        double viol = 0, pos = 0;
        for (std::int64_t i = 0; i < N; ++i) {
            if (g.knots > 0) kern::gain_storage_eval(S.data(), Sd.data(), ck_.net.theta.data(), gsm_.t[i], ck_.net.step);
            kern::GainSampleValue v =
                kern::gain_sample_forward(K_all_.data() + i * n * m, S.data(), view, i, lp, Sd.data());
            rel[i] = v.abs_sum > 0 ? std::fabs(v.residual) / v.abs_sum : 0.0;
            viol += v.residual > 0.01 * v.abs_sum ? 1 : 0;
            pos += v.residual > 0 ? 1 : 0;
        }
        rec->rel_median = percentile(rel, 0.5);
        rec->rel_p95 = percentile(rel, 0.95);
        rec->violation = viol / double(N);
        rec->positive = pos / double(N);
        // the diagnostic filter on pool run 0: x from the truth, x^ by x^' = A(x^) + K(x^)(y - C(x^))
        const TruthRun& run = pool_.runs[0];
        const double t = rec->t;
        const System& sys = *cfg_.system;
        std::vector<double>& x = ck_.state.x;
        std::vector<double>& xhat = ck_.state.xhat;
        x.assign(run.x.begin() + step * n, run.x.begin() + (step + 1) * n);
        std::vector<double> K(n * m), xt(n), s(n), ah(n), ch(m), e(m), y(run.y.begin() + step * m,
                                                                         run.y.begin() + (step + 1) * m);
        std::vector<double> z(g.input_count(n)), B(n * nv);
        g.input_row(z.data(), xhat.data(), n, true);  // the filter's input, held in the box (method.md 16.10)
        sys.state_difference(xt.data(), x.data(), xhat.data());  // an angle state's wrapped
        std::vector<double> Hx(static_cast<std::size_t>(m) * n), Fx(static_cast<std::size_t>(n) * n);
        if (g.knots > 0 || g.kalman) sys.measurement_jacobian(Hx.data(), xhat.data(), t);
        if (g.kalman) sys.drift_jacobian(Fx.data(), xhat.data(), t);
        kern::gain_network_eval(K.data(), ck_.net.theta.data(), z.data(), Hx.data(), &t, 1, ck_.net.step, ws_,
                                Fx.data());
        kern::gain_storage_eval(S.data(), Sd.data(), ck_.net.theta.data(), t, ck_.net.step);
        sys.drift(ah.data(), xhat.data(), t, 1);
        sys.measurement(ch.data(), xhat.data(), t, 1);
        sys.disturbance_gain(B.data(), x.data(), t, 1);
        sys.output_difference(e.data(), y.data(), ch.data());
        for (int a = 0; a < n; ++a) {
            s[a] = 0;
            for (int c = 0; c < n; ++c) s[a] += S[a * n + c] * xt[c];
        }
        // the game's worst case at this x~: v* = B's / rho, n* = -K's / rho; p = dV/dx~ = 2 S x~
        rec->v_star.assign(nv, 0.0);
        rec->n_star.assign(m, 0.0);
        for (int j = 0; j < nv; ++j)
            for (int a = 0; a < n; ++a) rec->v_star[j] += B[a * nv + j] * s[a] / cfg_.rho;
        for (int j = 0; j < m; ++j)
            for (int a = 0; a < n; ++a) rec->n_star[j] -= K[a * m + j] * s[a] / cfg_.rho;
        rec->p.resize(n);
        for (int a = 0; a < n; ++a) rec->p[a] = 2.0 * s[a];
        rec->cosine = cosine(s.data(), xt.data(), n);
        {  // the inequality's value at the diagnostic filter's own error
            GainSamples one;
            one.n = n;
            one.nv = nv;
            one.m = m;
            one.xt = xt;
            one.dA.resize(n);
            sys.drift(one.dA.data(), x.data(), t, 1);
            for (int a = 0; a < n; ++a) one.dA[a] -= ah[a];
            one.Bm = B;
            one.dC.resize(m);
            sys.measurement(one.dC.data(), x.data(), t, 1);
            sys.output_difference(one.dC.data(), one.dC.data(), ch.data());
            one.q = {quadratic_form(cfg_.Q.data(), xt.data(), n)};
            rec->residual = kern::gain_sample_forward(K.data(), S.data(), one.view(), 0, lp, Sd.data()).residual;
        }
        rec->x = x;
        rec->xhat = xhat;
        rec->xtilde = xt;
        rec->y = y;
        rec->gain = K;
        if (writer_) traj_.append(record_row(*rec, cfg_));
        std::vector<double> xhat_next(n);
        gain_filter_advance(xhat_next.data(), xhat.data(), ah.data(), K.data(), e.data(), n, m, cfg_.dt,
                            sys.discrete_time());
        const bool lost = !all_finite(xhat_next) || !all_finite(K);
        // from Riccati knots (still: check_start may have switched cfg_ to flat; held at once, they started flat) a
        // lost diagnostic filter says the start is wrong for the runs, and stops the run as a divergence (method.md
        // 16.7, "A start that diverges"); the Riccati walk runs only then
        if (lost && cfg_.storage_knots > 0 && cfg_.storage_init == "riccati" && !riccati_start_held_at_once(cfg_)) {
            diagnose(step, !all_finite(K) ? "gain" : "diagnostic filter estimate", NAN);
            return false;
        }
        // the state at the next step: the truth of pool run 0 (kept in the checkpoint for the record)
        if (step + 1 < pool_.steps) x.assign(run.x.begin() + (step + 1) * n, run.x.begin() + (step + 2) * n);
        if (!lost) {
            xhat = xhat_next;
        } else {
            // The samples do not depend on this filter (above), so from a flat or constant storage a half-trained
            // network that loses it is no reason to stop training: it starts again at the configured initial error,
            // x^ = x - (x0 - x^0) (deterministic, so a resumed run gives the same bits; docs/method.md section 16.3)
            for (int j = 0; j < n; ++j) xhat[j] = x[j] - (cfg_.x0[j] - cfg_.xhat0[j]);
            if (writer_ && diagnostic_restarts_++ == 0)
                std::fprintf(stderr,
                             "\nhinf: note: at time step %lld (t = %.4g s) the diagnostic filter (the network being "
                             "trained, filtering training run 0: the trajectory file's x^) lost its estimate (%s not "
                             "finite); it starts again from the configured initial error. Training goes on: its "
                             "samples do not depend on that filter, and the selection and the acceptance check judge "
                             "the trained filter (docs/method.md section 16.3)\n",
                             static_cast<long long>(step), t, all_finite(K) ? "x^" : "gain");
        }
        rec_loss_finite_ = rec->loss_last;
        return true;
    }

    bool adam_phase(StepRecord* rec, std::int64_t step) {
        const kern::HjieSystemView view = smp_.view();
        return adam_steps(rec, step, [&](T* grad) {
            return kern::step_gradient(grad, ck_.net.theta.data(), view, idx_.data(), int(cfg_.batch), ck_.net.step,
                                       ws_, split_.ranks > 1 ? &split_ : nullptr);
        });
    }

    // The K Adam steps of one time step, shared by every variant: minibatch k (Philox keyed by step, k), the
    // variant's gradient (seed 000 eqs. (14)-(15)), the loss checks, the update; false (after a diagnostic) on
    // numerical trouble. gradient(grad) fills grad for the minibatch in idx_ and returns its loss.
    template <class Gradient>
    bool adam_steps(StepRecord* rec, std::int64_t step, Gradient&& gradient) {
        kern::AdamParams ap{cfg_.learning_rate * ck_.state.learning_rate_scale, cfg_.beta1, cfg_.beta2, cfg_.tau};
        if (cfg_.reset_adam) {
            std::fill(ck_.adam_m.begin(), ck_.adam_m.end(), T(0));
            std::fill(ck_.adam_v.begin(), ck_.adam_v.end(), T(0));
            ck_.state.adam_step = 0;
        }
        for (std::int64_t k = 1; k <= cfg_.adam_steps; ++k) {
            const std::int64_t G = gain_ ? cfg_.errors_per_estimate : 1;  // whole groups of errors per estimate
            kern::sample_minibatch(idx_.data(), int(cfg_.batch / G), cfg_.samples / G, cfg_.seed, step, k, work_.data(),
                                   perm_.data());
            for (std::int64_t b = cfg_.batch / G - 1; G > 1 && b >= 0; --b)
                for (std::int64_t g = G - 1; g >= 0; --g) idx_[b * G + g] = idx_[b] * G + g;
            kern::StepLoss L = gradient(grad_.data());
            if (k == 1) rec->loss_first = L.loss;
            if (k == cfg_.adam_steps) rec->loss_last = L.loss;
            // the limit applies once this step's updates have acted: the first loss of a time step
            // measures the old weights on new samples, which a roll-back could not change
            if (!std::isfinite(L.loss) || (k > 1 && L.loss > cfg_.loss_limit)) {
                diagnose(step, "training loss", L.loss);
                return false;
            }
            ++ck_.state.adam_step;
            kern::adam_update(ck_.net.theta.data(), ck_.adam_m.data(), ck_.adam_v.data(), grad_.data(),
                              std::int64_t(grad_.size()), ck_.state.adam_step, ap);
        }
        if (!all_finite_t(ck_.net.theta)) {
            diagnose(step, "network weights", NAN);
            return false;
        }
        return true;
    }

    bool residual_statistics(StepRecord* rec, std::int64_t step) {
        const int n = cfg_.n;
        const std::int64_t N = cfg_.samples;
        const kern::HjieSystemView view = smp_.view();
        kern::network_eval(p_all_.data(), P_all_.data(), ck_.net.theta.data(), smp_.xt.data(), N, ck_.net.step, ws_);
        std::vector<double> rel(N), rel2(N);
        double viol = 0, viol2 = 0, pos = 0, cos_sum = 0, loss_hinge = 0, loss_h2 = 0;
        // per-sample values over threads, then every sum in sample order (bits independent of threads)
#pragma omp parallel for schedule(static)
        for (std::int64_t i = 0; i < N; ++i) {
            vals_[i] = kern::hjie_sample_forward(p_all_.data() + i * n, P_all_.data() + i * n * n, view, i,
                                                 ck_.net.step.hjie, ck_.net.step.objective);
            cos_[i] = cosine(p_all_.data() + i * n, smp_.xt.data() + i * n, n);
        }
        for (std::int64_t i = 0; i < N; ++i) {
            const kern::HjieSampleValue& v = vals_[i];
            rel[i] = v.abs_sum > 0 ? std::fabs(v.residual) / v.abs_sum : 0.0;
            viol += v.residual > 0.01 * v.abs_sum ? 1 : 0;
            rel2[i] = v.abs_sum2 > 0 ? std::fabs(v.residual2) / v.abs_sum2 : 0.0;
            viol2 += v.residual2 > 0.01 * v.abs_sum2 ? 1 : 0;
            pos += v.residual > 0 ? 1 : 0;
            cos_sum += cos_[i];
            loss_hinge += v.hinge;
            loss_h2 += v.h2;
        }
        const double h2_weight =
            ck_.net.step.objective == kern::HJIE_OBJECTIVE_DISSIPATIVE ? ck_.net.step.hjie.h2_weight : 0;
        const double loss_after = std::sqrt(loss_hinge / double(N)) + h2_weight * loss_h2 / double(N);
        if (!std::isfinite(loss_after) || loss_after > cfg_.loss_limit) {  // before it reaches a checkpoint
            diagnose(step, "training loss after the Adam steps", loss_after);
            return false;
        }
        rec->rel_median = percentile(rel, 0.5);
        rec->rel_p95 = percentile(rel, 0.95);
        rec->violation = viol / double(N);
        rec->positive = pos / double(N);
        rec->cosine = cos_sum / double(N);
        rec->rel_median2 = percentile(rel2, 0.5);
        rec->rel_p95_2 = percentile(rel2, 0.95);
        rec->violation2 = viol2 / double(N);
        return true;
    }

    bool advance_state(StepRecord* rec, std::int64_t step) {
        const int n = cfg_.n, nv = cfg_.nv, m = cfg_.m;
        const double t = rec->t;
        const System& sys = *cfg_.system;
        std::vector<double>& x = ck_.state.x;
        std::vector<double>& xhat = ck_.state.xhat;
        std::vector<double> xtilde(n);
        sys.state_difference(xtilde.data(), x.data(), xhat.data());  // an angle state's wrapped
        std::vector<double> p(n), Pm(n * n);
        kern::network_eval(p.data(), Pm.data(), ck_.net.theta.data(), xtilde.data(), 1, ck_.net.step, ws_);
        std::vector<double> c_x(m), dc(m), B(n * nv);
        sys.measurement(c_x.data(), x.data(), t, 1);
        sys.disturbance_gain(B.data(), x.data(), t, 1);
        sys.output_difference(dc.data(), c_x.data(), smp_.c_hat.data());
        WorstCase wc = worst_case(p.data(), B.data(), dc.data(), n, nv, m, cfg_.rho);
        std::vector<double> y(m), e(m);
        for (int j = 0; j < m; ++j) y[j] = c_x[j] + wc.n_star[j];
        sys.output_difference(e.data(), y.data(), smp_.c_hat.data());
        double terms[4];  // the residual at x~(t)
        hjie_point_terms(terms, p.data(), sys, x.data(), xhat.data(), t, cfg_.Q.data(), cfg_.rho);
        rec->residual = terms[0] + terms[1] + terms[2] + terms[3];
        if (cfg_.type == "h2hinf")  // seed 001: the second residual (20) at x~(t)
            rec->residual2 = terms[0] + terms[1] + kern::kHjieCoupling[1] * terms[2] + kern::kHjieCoupling[1] * terms[3];

        // sampled-data propagation: x by eq. (18) with v*, x^ by eq. (19) with y; x~ = x - x^ (eq. (20))
        std::vector<double> x_next(n), xhat_next(n);
        system_advance(sys, x_next.data(), x.data(), wc.v_star.data(), t, cfg_.dt);
        luenberger_advance(xhat_next.data(), xhat.data(), smp_.a_hat.data(), wc.gain.data(), e.data(), n, m, cfg_.dt);
        if (cfg_.type == "h2hinf") consistency(rec, xtilde, x_next, xhat_next, B, wc, dc, t);
        rec->x = x;
        rec->xhat = xhat;
        rec->xtilde = xtilde;
        rec->y = y;
        rec->gain = wc.gain;
        rec->v_star = wc.v_star;
        rec->n_star = wc.n_star;
        rec->p = p;
        if (writer_) traj_.append(record_row(*rec, cfg_));
        if (!all_finite(x_next) || !all_finite(xhat_next) || !all_finite(p) || !all_finite(wc.gain)) {
            diagnose(step, !all_finite(p) ? "network output p" : !all_finite(wc.gain) ? "gain" : "state", NAN);
            return false;
        }
        x = x_next;
        xhat = xhat_next;
        rec_loss_finite_ = rec->loss_last;
        return true;
    }

    // x~(t+h) by eq. (23) against x(t+h) - x^(t+h) by (21)-(22): with n* = -l^T p/(2 r^2) and -h l dC in (23)
    // (Theorem 1's proof) the gap is round-off; with (11) and (23) as printed it is 2 h |l dC|.
    void consistency(StepRecord* rec, const std::vector<double>& xtilde, const std::vector<double>& x_next,
                     const std::vector<double>& xhat_next, const std::vector<double>& B, const WorstCase& wc,
                     const std::vector<double>& dc, double t) {
        const int n = cfg_.n, nv = cfg_.nv, m = cfg_.m;
        const double h = cfg_.dt;
        const std::vector<double>& a_hat = smp_.a_hat;
        std::vector<double> a_x(n);
        cfg_.system->drift(a_x.data(), ck_.state.x.data(), t, 1);
        std::vector<double> diff(n), xt23(n), xt23p(n), diffp(n);
        for (int i = 0; i < n; ++i) {
            double bv = 0, ldc = 0, ln = 0;
            for (int j = 0; j < nv; ++j) bv += B[i * nv + j] * wc.v_star[j];
            for (int j = 0; j < m; ++j) {
                ldc += wc.gain[i * m + j] * dc[j];
                ln += wc.gain[i * m + j] * wc.n_star[j];
            }
            const double common = xtilde[i] + h * (a_x[i] - a_hat[i]) + h * bv;
            xt23[i] = common - h * ldc - h * ln;
            diff[i] = x_next[i] - xhat_next[i];
            // printed: n*_p = +l^T p/(2 r^2) = -n*, so y_p - h(x^) = dC - n*; (23) with +h l dC
            xt23p[i] = common + h * ldc + h * ln;
            const double xhat_p = xhat_next[i] - h * ln - h * ln;  // l (y_p - y) = -2 l n*
            diffp[i] = x_next[i] - xhat_p;
        }
        rec->gap = max_abs_diff(xt23, diff);
        rec->gap_printed = max_abs_diff(xt23p, diffp);
    }

    void checkpoint() {
        if (!writer_) return;
        traj_.snapshot();  // before the checkpoint's rename: the snapshot never has fewer rows
        ckpt_write(dir_ + "/checkpoint.h5", ck_, cfg_);
    }

    // training.on_divergence = "rollback": back to the last checkpoint with a smaller learning rate.
    bool roll_back(std::int64_t count) {
        const std::string path = dir_ + "/checkpoint.h5";
        const double scale = ck_.state.learning_rate_scale * cfg_.rollback_factor;
        traj_ = TrajectoryWriter();  // close before the file is replaced
        if (std::filesystem::exists(path)) {
            ck_ = ckpt_read<T>(path);
            if (writer_)
                traj_ = TrajectoryWriter::reopen(dir_ + "/trajectory.h5", trajectory_columns(cfg_), hsize_t(ck_.state.step),
                                         {{"config", ck_.config_text}});
        } else {
            start_fresh();  // no checkpoint yet: back to the initial network and state
        }
        ck_.state.learning_rate_scale = scale;
        if (writer_) std::fprintf(stderr, "hinf: rolled back to time step %lld with learning rate %g (roll-back %lld of %lld)\n",
                     static_cast<long long>(ck_.state.step), cfg_.learning_rate * scale, static_cast<long long>(count),
                     static_cast<long long>(cfg_.max_rollbacks));
        return true;
    }

    // a tenth of the rate the run had, for the advice
    std::string lower_rate() const {
        char b[32];
        std::snprintf(b, sizeof b, "%.3g", 0.1 * cfg_.learning_rate * ck_.state.learning_rate_scale);
        return b;
    }

    // One line: the time step, the quantity, the last finite values, what is kept and what to do.
    void diagnose(std::int64_t step, const char* what, double value) {
        double err = 0;
        for (int i = 0; i < cfg_.n; ++i) err += std::pow(ck_.state.x[i] - ck_.state.xhat[i], 2);
        const std::string ckpt = dir_ + "/checkpoint.h5";
        const std::string kept = std::filesystem::exists(ckpt)
                                     ? "The last good checkpoint " + ckpt + " is kept (for a run that gets past this "
                                       "step, continue it with a lower rate: hinf resume " + ckpt + " --set training.learning_rate=" +
                                       lower_rate() + ", or --set training.on_divergence=rollback)"
                                     : "No checkpoint was written yet (train again with a lower rate: hinf train CONFIG --force "
                                       "--set training.learning_rate=" + lower_rate() + ")";
        // a gain S(t) started on the Riccati solution can be the cause (a stiff system with error scales far apart,
        // a chaotic one whose runs leave the nominal trajectory: method.md section 16.7, "Initial knots"); the flat
        // start and the constant storage are the alternatives
        const std::string alt = restart_flat_ ? "The knots of S(t) started on the game's Riccati solution along the "
                                                "noise-free trajectory can be the cause: the run starts again from "
                                                "flat knots (below)."
                                : cfg_.variant == "gain" && cfg_.storage_knots > 0 && cfg_.storage_init != "flat"
                                    ? " The knots of S(t) started on the game's Riccati solution along the noise-free "
                                      "trajectory can be the cause: try --set network.storage_init=flat or --set "
                                      "network.storage_knots=0."
                                    : "";
        char last_loss[32] = "none yet";  // no time step has ended finite
        if (std::isfinite(rec_loss_finite_)) std::snprintf(last_loss, sizeof last_loss, "%g", rec_loss_finite_);
        if (!writer_) return;  // every process of the run diverges alike; one says so
        std::fprintf(stderr,
                     "\nhinf: error: training diverged at time step %lld (t = %.2f s): %s = %g; last finite values: "
                     "loss %s, |x~| %g, learning rate %g. %s%s\n",
                     static_cast<long long>(step), cfg_.time_of(step), what, value, last_loss, std::sqrt(err),
                     cfg_.learning_rate * ck_.state.learning_rate_scale, restart_flat_ ? "" : kept.c_str(), alt.c_str());
        traj_.flush();
    }

    RunConfig cfg_;
    std::string dir_;
    // under mpirun (or in a sweep's group): every process holds the whole state and takes every step; the
    // minibatch's chunks are split over the processes (data parallel); process 0 alone writes files
    bool writer_ = par_root();
    kern::StepSplit split_{par_rank(), par_size(), par_allgather_items};
    Checkpoint<T> ck_;
    TrajectoryWriter traj_;
    kern::StepWorkspace<T> ws_;
    TimeStepSamples smp_;  // this time step's samples and their constants
    bool gain_ = cfg_.variant == "gain";
    GainPool pool_;        // variant gain: the truth runs the estimates are sampled along (from the config)
    GainSamples gsm_;      // variant gain: this time step's samples
    std::vector<double> K_all_;
    std::vector<double> work_, p_all_, P_all_, cos_;
    std::vector<kern::HjieSampleValue> vals_;  // per-sample statistics of the time step
    std::vector<T> grad_;
    std::vector<std::int64_t> idx_, perm_;
    double rec_loss_finite_ = NAN;  // loss after the last time step that ended finite

public:
    std::function<void(const TrainStepInfo&)> on_step_;  // TrainOptions::on_step
    std::function<std::int64_t(const RunConfig&, const std::string&)> start_diverged_;  // TrainOptions::start_diverged
    std::int64_t diagnostic_restarts_ = 0;  // restarts of the gain variant's diagnostic filter (a note at the first)
    bool restart_flat_ = false;  // a divergence starts the run again from flat knots (start_typed)
    const RunConfig& config() const { return cfg_; }
    void close_files() { traj_ = TrajectoryWriter(); }
};

// What the game to be trained needs, checked before any file is touched: a level (a config naming no rho whose
// system gives no default, game_level.hpp, is refused here), and the time model.
// THE refusal of discrete-time systems for training (issue 13): every variant but `gain` trains the continuous-time
// game (the HJI inequality with Euler-sampled steps, seed 000 eqs. (18)-(20)). Variant gain trains the one-step
// dissipation inequality of a discrete system (kernels/gain_discrete.hpp, docs/method.md section 16.8); its game
// needs rho > lambda_max(B'Q B) (S >= Q and G'S G < rho), checked here at x0.
void train_check_game(const RunConfig& cfg) {
    HINF_CHECK(cfg.rho > 0, cfg.rho_unset);
    if (!cfg.system->discrete_time()) return;
    HINF_CHECK(cfg.variant == "gain",
               cfg.doc.source() + ": [system] time = \"discrete\": variant \"" + cfg.variant + "\" trains the "
               "continuous-time game; for a discrete-time system use [filter] variant = \"gain\" (the one-step "
               "inequality), or run compare, filter or worst with ekf, ukf, pf, open_loop on it");
    const double floor = gain_discrete_rho_floor(cfg);
    char line[320];
    std::snprintf(line, sizeof line, "%s: [filter] rho = %g is at or below the discrete one-step game's floor "
                  "lambda_max(B'Q B) = %g at x0 (the error takes each step's disturbance whole): no storage satisfies "
                  "the inequality; set [filter] rho above it (e.g. --set filter.rho=%g)",
                  cfg.doc.source().c_str(), cfg.rho, floor, 4.0 * floor);
    HINF_CHECK(cfg.rho > floor, line);
}

// A parameter estimated as a state under the default Q = I (docs/method.md section 16.12, "A parameter as a state"):
// one line naming the constant states and the Q that leaves them out of the game's error.
void constant_state_note(const RunConfig& cfg) {
    if (!cfg.q_auto) return;
    const std::vector<int> held = constant_states(cfg);
    if (held.empty() || int(held.size()) == cfg.n) return;
    const std::vector<std::string> names = cfg.system->state_names();
    std::string which, q = "[";
    for (std::size_t k = 0; k < held.size(); ++k) which += (k ? ", " : "") + names[held[k]];
    for (int i = 0; i < cfg.n; ++i)
        q += std::string(i ? ", " : "") + (std::find(held.begin(), held.end(), i) != held.end() ? "0" : "1");
    q += "]";
    std::fprintf(stderr,
                 "hinf: note: %s %s %s constant in the model (no dynamics, no disturbance: a parameter estimated as a "
                 "state), and the default Q = I weighs %s error like the others'. On two such systems a weight of 1 "
                 "settled at 3.9-9.5 times the EKF's error and failed the acceptance check, a weight of 0 at 1.2-2.1 "
                 "times and passed: try --set 'filter.Q=%s' and compare both best.h5 (docs/method.md section 16.12, "
                 "\"A parameter as a state\")\n",
                 held.size() == 1 ? "state" : "states", which.c_str(), held.size() == 1 ? "is" : "are",
                 held.size() == 1 ? "its" : "their", q.c_str());
}

template <typename T>
TrainSummary start_typed(const RunConfig& cfg, const TrainOptions& opt) {
    train_check_game(cfg);
    const RunDirLock lock(opt.out_dir, "hinf train");  // before trajectory.h5 is created (truncated)
    Trainer<T> tr(cfg, opt.out_dir);
    tr.start_diverged_ = opt.start_diverged;
    tr.start_fresh();
    const bool notes = par_root() && opt.config_notes;
    if (cfg.rho_auto && notes)  // after the refusals: a refused run stays one line
        std::fprintf(stderr, "hinf: note: [filter] rho is not set: training at rho = %.4g = %g rho*, where rho* = %.4g is "
                             "the smallest level any filter can promise for the linearised system (hinf rho %s%s; "
                             "docs/method.md section 16.12)\n",
                     cfg.rho, kAutoRhoFactor, cfg.rho_bound, cfg.doc.source().c_str(),
                     game_in_config_units(cfg)
                         ? ""
                         : " with this run's [online] noise_std and disturbance_std, in units of each channel's noise");
    // a default below rho*_on: kept over [0, t_final] only by a filter that knows when the run ends
    const double run_on = cfg.rho_auto && notes ? game_level_rho_run_on(cfg) : 0.0;
    if (run_on >= cfg.rho && run_on > 0)
        std::fprintf(stderr, "hinf: note: that level is at or below rho*_on = %.4g, the smallest one where the run goes "
                             "on past t_final: a gain of the estimate alone does not know when the run ends, so its "
                             "worst-case ratio is not expected below rho*_on, and the acceptance check will likely FAIL the "
                             "level. --set filter.rho=%.4g (%g rho*_on) can be kept, but a higher level is not always "
                             "the more robust filter: train both and compare them (docs/method.md section 16.12, "
                             "\"Where the run ends\")\n",
                     run_on, kAutoRhoFactor * run_on, kAutoRhoFactor);
    // the walk behind rho* covers the horizon's first kGameLevelMaxSteps steps: a longer one can need a larger level
    if (cfg.rho_auto && notes && cfg.steps_until() > kGameLevelMaxSteps)
        std::fprintf(stderr, "hinf: note: that rho* is the linearised game's over the horizon's first %lld of %lld "
                             "steps; over the whole horizon it can only be larger, so the level trained may be one no "
                             "filter keeps there: %s\n",
                     static_cast<long long>(kGameLevelMaxSteps), static_cast<long long>(cfg.steps_until()),
                     cfg.system->discrete_time()
                         ? "name [filter] rho"
                         : "hinf rho with a coarser --set filter.dt (whole horizon in at most that many steps) gives "
                           "the whole horizon's, nearly independent of dt; name [filter] rho from it");
    if (notes) constant_state_note(cfg);
    if (notes) {  // a discrete gain filter whose constant storage cannot exist (docs/method.md section 16.8)
        const std::string note = constant_storage_note(cfg, constant_storage_check(cfg, tr.pool()));
        if (!note.empty()) std::fputs(note.c_str(), stderr);
    }
    if (notes) {  // samples across 0 where the runs stay on one side (docs/method.md section 16.3)
        const std::string note = tr.sign_note();
        if (!note.empty()) std::fputs(note.c_str(), stderr);
    }
    tr.on_step_ = opt.on_step;
    // a run that diverges from a Riccati start hinf chose starts again from flat knots, once (docs/method.md
    // section 16.7, "A start that diverges"); the caller's on_restart forgets what the diverged run validated
    tr.restart_flat_ = opt.on_restart && par_size() == 1 && riccati_start_replaceable(tr.config());
    TrainSummary s = tr.run(cfg.steps_until(opt.until), opt.quiet);
    if (s.status != 4 || !tr.restart_flat_) return s;
    std::fprintf(stderr, "hinf: note: the run diverged from the knots on the game's Riccati solution (network.storage_init "
                         "= \"riccati\", the default; above); it starts again from flat knots, recorded in its config, "
                         "and replaces the diverged run's files (docs/method.md section 16.7, \"A start that "
                         "diverges\")\n");
    opt.on_restart();
    tr.close_files();  // before trajectory.h5 is created again
    Trainer<T> flat(flat_start_config(tr.config(), /*by_hinf=*/true), opt.out_dir);
    flat.start_fresh();
    flat.on_step_ = opt.on_step;
    return flat.run(cfg.steps_until(opt.until), opt.quiet);
}

// The checkpoint's config with `resume --set` applied; only kResumeKeys may change. The change is recorded in the
// config itself (a comment line per resume, kept across later resumes), so the checkpoint and trajectory that
// carry the config carry it too.
std::string resume_config_text(const std::string& text, const std::vector<std::string>& sets, std::int64_t step,
                               const std::string& path, const std::vector<std::string>& as_trained) {
    ConfigDoc doc = ConfigDoc::from_text(text, path + ":/config");
    std::string record;
    for (const std::string& s : as_trained) {  // keys a legacy file fixed implicitly (checkpoint.cpp), not user sets
        doc.set(s);
        record += (record.empty() ? "" : " ") + s;
    }
    for (const std::string& s : sets) {
        std::string key = s.substr(0, s.find('='));
        key.erase(key.find_last_not_of(" \t") + 1);
        key.erase(0, key.find_first_not_of(" \t"));
        bool allowed = false;
        for (const std::string& k : kResumeKeys) allowed = allowed || key == k;
        std::string list;
        for (const std::string& k : kResumeKeys) list += (list.empty() ? "" : ", ") + k;
        HINF_CHECK(allowed, "resume --set " + key + ": this key cannot change on resume (it fixes what the checkpoint "
                            "means); keys that may: " + list + "; for any other, start afresh with hinf train --set");
        doc.set(s);
        record += (record.empty() ? "" : " ") + s;
    }
    std::string history;  // the lines hinf recorded (keys it chose, earlier resumes): a re-serialised config keeps no comments
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);)
        if (line.rfind("# hinf chose:", 0) == 0 || line.rfind("# hinf resume", 0) == 0) history += line + "\n";
    std::string out = doc.text();
    if (!out.empty() && out.back() != '\n') out += '\n';
    return out + history + "# hinf resume at step " + std::to_string(step) + ": --set " + record + "\n";
}

template <typename T>
TrainSummary resume_typed(const std::string& path, const TrainOptions& opt) {
    Checkpoint<T> ck = ckpt_read<T>(path);
    const std::string old_text = ck.config_text;
    // the settings an older file leaves to defaults that have changed since: resumed as trained, and recorded
    const std::vector<std::string> legacy = ckpt_as_trained(path);
    if (!opt.sets.empty() || !legacy.empty())
        ck.config_text = resume_config_text(ck.config_text, opt.sets, ck.state.step, path, legacy);
    RunConfig cfg = load_run_config(ConfigDoc::from_text(ck.config_text, path + ":/config"));
    cfg.chosen = chosen_keys(ck.config_text);
    train_check_game(cfg);
    std::int64_t last = cfg.steps_until(opt.until);
    HINF_CHECK(last > ck.state.step || opt.until < 0 || last == ck.state.step,
               "--until " + std::to_string(opt.until) + " is before the checkpoint's time " +
                   std::to_string(cfg.time_of(ck.state.step)) + " s (pass a later time)");
    std::string dir = std::filesystem::path(path).parent_path().string();
    if (dir.empty()) dir = ".";
    Trainer<T> tr(cfg, dir);
    tr.start_from(std::move(ck), old_text);
    tr.on_step_ = opt.on_step;
    return tr.run(last, opt.quiet);
}

}  // namespace

void train_request_stop(int signal) { g_stop_signal = signal; }

TrainSummary train_start(const RunConfig& cfg, const TrainOptions& opt) {
    return cfg.precision == "double" ? start_typed<double>(cfg, opt) : start_typed<float>(cfg, opt);
}

TrainSummary train_resume(const std::string& checkpoint, const TrainOptions& opt) {
    std::string dir = std::filesystem::path(checkpoint).parent_path().string();
    if (dir.empty()) dir = ".";
    // a checkpoint first (no lock file is left beside a file that is not one), then the directory's lock before
    // anything is written there; the checkpoint is read again under the lock (a run that still wrote it has
    // then finished, or the lock is refused)
    ckpt_verify(checkpoint);
    const RunDirLock lock(dir, "hinf resume");  // one line naming the file and the problem, or the previous checkpoint to use
    return ckpt_precision(checkpoint) == "double" ? resume_typed<double>(checkpoint, opt)
                                                  : resume_typed<float>(checkpoint, opt);
}

}  // namespace hinf
