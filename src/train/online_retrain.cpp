// On-line checking and retraining of the gain variant (see online_retrain.hpp; docs/method.md section 16.6).
#include "train/online_retrain.hpp"

#include <cmath>

#include "adam.hpp"
#include "filters/gain_law.hpp"
#include "gain.hpp"
#include "hinf/error.hpp"
#include "net/network.hpp"

namespace hinf {

std::vector<double> OnlineRetrainCounts::to_vector() const {
    return {check_violations, check_samples, triggers, adam_steps, rejected, eps_before, eps_after};
}

OnlineRetrainCounts OnlineRetrainCounts::from_vector(const std::vector<double>& v) {
    OnlineRetrainCounts c;
    if (v.size() < 7) return c;
    c.check_violations = v[0];
    c.check_samples = v[1];
    c.triggers = v[2];
    c.adam_steps = v[3];
    c.rejected = v[4];
    c.eps_before = v[5];
    c.eps_after = v[6];
    return c;
}

double online_check_violation(const GainSamples& check, const double* K, const double* S, const double* Sdot,
                              double rho, bool discrete, double* violations) {
    kern::GainLossParams lp;
    lp.rho = rho;
    lp.discrete = discrete;
    const kern::HjieSystemView view = check.view();
    const std::int64_t N = std::int64_t(check.q.size());
    double eps = -1;
    for (std::int64_t i = 0; i < N; ++i) {
        const kern::GainSampleValue v = kern::gain_sample_forward(K, S, view, i, lp, Sdot);
        // a discrete step that lost concavity has sup = +inf: its relative residual at the limit 1 (gain_discrete.cpp)
        const double rel = std::isinf(v.residual) ? 1.0 : v.abs_sum > 0 ? v.residual / v.abs_sum : 0.0;
        eps = std::max(eps, rel);
        if (violations != nullptr) *violations += v.residual > 0.01 * v.abs_sum ? 1 : 0;
    }
    return eps;
}

namespace {

template <typename T>
Checkpoint<T> read_typed(const std::string& path) {
    return ckpt_read<T>(path);
}

double checkpoint_rate_scale(const std::string& path) {
    return ckpt_precision(path) == "double" ? ckpt_read<double>(path).state.learning_rate_scale
                                            : ckpt_read<float>(path).state.learning_rate_scale;
}

template <typename T>
bool all_finite(const std::vector<T>& v) {
    for (T x : v)
        if (!std::isfinite(x)) return false;
    return true;
}

// x^' = A(x^) + K(x^)(y - C(x^)) (discrete time: x^+ = f(x^) + K e) with K from its own, retrainable network
// (GainFilter of filters/dnn.cpp plus the check and the Adam steps).
template <typename T>
class RetrainGainFilter final : public OnlineFilter {
public:
    RetrainGainFilter(const FilterModel& model, std::shared_ptr<const RunConfig> cfg,
                      std::shared_ptr<const Checkpoint<T>> origin, std::shared_ptr<const RunConfig> origin_cfg,
                      const OnlineRetrainSettings& st, std::string name)
        : model_(model), cfg_(std::move(cfg)), origin_(std::move(origin)), origin_cfg_(std::move(origin_cfg)), st_(st),
          name_(std::move(name)) {
        restore_origin();
    }
    std::string name() const override { return name_; }
    bool uses_true_state() const override { return false; }
    void reset(const FilterStart& start) override {
        restore_origin();  // every run starts from the checkpoint's network: nothing learned leaks between runs
        xhat_ = start.xhat0;
        run_ = start.run;
        next_step_ = 0;
        counts_ = OnlineRetrainCounts();
        far_ = BoxExcursion();
    }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = cfg_->n, m = cfg_->m;
        a_.resize(n);
        ch_.resize(m);
        e_.resize(m);
        K_.resize(std::size_t(n) * m);
        S_.resize(std::size_t(n) * n);
        Sd_.resize(std::size_t(n) * n);
        sys.drift(a_.data(), xhat_.data(), in.t, 1);
        sys.measurement(ch_.data(), xhat_.data(), in.t, 1);
        std::fill(e_.begin(), e_.end(), 0.0);  // missing: no correction
        if (in.y != nullptr) sys.output_difference(e_.data(), in.y, ch_.data());
        next_step_ = in.step + 1;
        far_.see(net_.step.gain, xhat_.data(), 1, n, in.t);  // the input it holds (retraining changes theta, not the box)
        if (!filter_estimate_ok(xhat_.data(), n)) return FILTER_DIVERGED;
        // 1. the on-line check (docs/method.md section 16.5): kOnlineCheckErrors errors around x^, current network
        const kern::GainSpec& g = net_.step.gain;
        gain_samples_at(&check_, *cfg_, g, xhat_.data(), in.t, kOnlineCheckErrors, online_check_counter(run_, in.step));
        eval(K_.data(), S_.data(), Sd_.data(), in.t);
        const double eps =
            online_check_violation(check_, K_.data(), S_.data(), Sd_.data(), cfg_->rho, sys.discrete_time(),
                                   &counts_.check_violations);
        counts_.check_samples += double(kOnlineCheckErrors);
        // 2. retrain when the violation exceeds delta (seed 000 Fig. 3), then go on with the updated network
        if (st_.retrain && eps > st_.delta) {
            retrain(in.t, in.step);
            counts_.triggers += 1;
            counts_.eps_before += eps;
            eval(K_.data(), S_.data(), Sd_.data(), in.t);
            counts_.eps_after += online_check_violation(check_, K_.data(), S_.data(), Sd_.data(), cfg_->rho,
                                                        sys.discrete_time(), nullptr);
        }
        for (double k : K_)
            if (!std::isfinite(k)) return FILTER_DIVERGED;
        // continuous time Euler-sampled, discrete time the one-step predictor f(x^) + K e (as filters/dnn.cpp)
        gain_filter_advance(xhat_.data(), xhat_.data(), a_.data(), K_.data(), e_.data(), n, m, model_.dt,
                            sys.discrete_time());
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    std::vector<double> run_report() const override { return counts_.to_vector(); }
    std::string run_note() const override { return far_.filter_note(model_.system->state_names()); }
    std::unique_ptr<OnlineFilter> clone() const override {
        return std::make_unique<RetrainGainFilter<T>>(model_, cfg_, origin_, origin_cfg_, st_, name_);
    }

    void write(const std::string& path) const {
        Checkpoint<T> ck;
        ck.net = net_;
        ck.adam_m = m_;
        ck.adam_v = v_;
        ck.state = origin_->state;
        ck.state.step = next_step_;
        ck.state.adam_step = adam_step_;
        ck.state.xhat = xhat_;
        ck.state.x = xhat_;  // an on-line run has no true state to keep
        ck.config_text = origin_->config_text;
        ckpt_write(path, ck, *origin_cfg_);
    }

private:
    void restore_origin() {
        net_ = origin_->net;
        step1_ = net_.step;
        step1_.gain.group = 1;  // every retraining sample has this x^: one network row each (the bits of before)
        m_ = origin_->adam_m;
        v_ = origin_->adam_v;
        adam_step_ = origin_->state.adam_step;
        pack_.stale();
    }

    // K(x^, t) [n x m], S(t) and dS/dt [n x n] of the current network at the current estimate (FrozenNetwork::gain's
    // arithmetic)
    void eval(double* K, double* S, double* Sdot, double t) {
        const int n = cfg_->n, m = cfg_->m;
        const kern::GainSpec& g = net_.step.gain;
        z_.resize(g.input_count(n));
        g.input_row(z_.data(), xhat_.data(), n, true);
        hx_.resize(std::size_t(m) * n);
        fx_.resize(std::size_t(n) * n);
        if (g.knots > 0 || g.kalman) cfg_->system->measurement_jacobian(hx_.data(), xhat_.data(), t);
        if (g.kalman) cfg_->system->drift_jacobian(fx_.data(), xhat_.data(), t);
        // theta changes only when retraining: its GEMM panels are packed once per change
        kern::gain_network_eval(K, net_.theta.data(), z_.data(), hx_.data(), &t, 1, net_.step, ws_, fx_.data(),
                                nullptr, pack_.get(net_.theta.data(), net_.step.shape));
        kern::gain_storage_eval(S, Sdot, net_.theta.data(), t, net_.step);
    }

    // retrain_steps Adam steps (seed 000 eqs. (14)-(15)) on retrain_samples errors drawn around x^ as training
    // draws them, one full batch each step, with the training's gradient kernel; a non-finite result is undone.
    void retrain(double t, std::int64_t step) {
        const std::int64_t N = st_.samples;
        gain_samples_at(&train_, *cfg_, net_.step.gain, xhat_.data(), t, N, online_retrain_counter(run_, step));
        idx_.resize(N);
        for (std::int64_t i = 0; i < N; ++i) idx_[i] = i;
        grad_.resize(net_.theta.size());
        const std::vector<T> theta0 = net_.theta, m0 = m_, v0 = v_;
        const std::int64_t k0 = adam_step_;
        if (st_.reset_adam) {  // as training does at each time step (training.reset_adam_each_step)
            std::fill(m_.begin(), m_.end(), T(0));
            std::fill(v_.begin(), v_.end(), T(0));
            adam_step_ = 0;
        }
        const kern::AdamParams ap{st_.learning_rate, st_.beta1, st_.beta2, st_.tau};
        const kern::HjieSystemView view = train_.view();
        bool ok = true;
        for (std::int64_t k = 0; k < st_.steps && ok; ++k) {
            const kern::StepLoss L = kern::gain_step_gradient(grad_.data(), net_.theta.data(), view, train_.z.data(),
                                                              idx_.data(), int(N), step1_, ws_);
            ok = std::isfinite(L.loss);
            if (!ok) break;
            ++adam_step_;
            kern::adam_update(net_.theta.data(), m_.data(), v_.data(), grad_.data(), std::int64_t(grad_.size()),
                              adam_step_, ap);
            counts_.adam_steps += 1;
        }
        if (!ok || !all_finite(net_.theta) || !all_finite(m_) || !all_finite(v_)) {
            net_.theta = theta0;
            m_ = m0;
            v_ = v0;
            adam_step_ = k0;
            counts_.rejected += 1;
        }
        pack_.stale();
    }

    FilterModel model_;
    std::shared_ptr<const RunConfig> cfg_;
    std::shared_ptr<const Checkpoint<T>> origin_;   // the network and Adam state every run starts from
    std::shared_ptr<const RunConfig> origin_cfg_;   // the checkpoint's own config (written with an on-line checkpoint)
    OnlineRetrainSettings st_;
    std::string name_;
    Network<T> net_;  // this filter's own copy, changed by retraining
    kern::StepConfig step1_;  // net_.step with one sample per network row (errors_per_estimate = 1)
    std::vector<T> m_, v_, grad_;
    std::int64_t adam_step_ = 0;
    kern::StepWorkspace<T> ws_;
    kern::PackedWeights<T> pack_;  // eval's weight panels of net_.theta (ws_.pack is the gradient's)
    GainSamples check_, train_;
    std::vector<std::int64_t> idx_;
    std::vector<double> xhat_, a_, ch_, e_, K_, S_, Sd_, z_, hx_, fx_;
    std::uint64_t run_ = 0;
    std::int64_t next_step_ = 0;
    OnlineRetrainCounts counts_;
    BoxExcursion far_;  // how far the estimates went beyond the network's input box since reset()
};

template <typename T>
std::unique_ptr<OnlineFilter> make_typed(const FilterModel& model, const RunConfig& cfg, const std::string& path,
                                         const OnlineRetrainSettings& st, const std::string& name) {
    auto origin = std::make_shared<const Checkpoint<T>>(read_typed<T>(path));
    HINF_CHECK(origin->net.step.gain.enabled,
               "network '" + path + "' is not of variant \"gain\": on-line retraining (online.retrain = true) needs a "
               "gain K(x^) (train with [filter] variant = \"gain\", or set online.retrain = false)");
    auto origin_cfg = std::make_shared<const RunConfig>(ckpt_config(path));
    return std::make_unique<RetrainGainFilter<T>>(model, std::make_shared<const RunConfig>(cfg), origin, origin_cfg, st,
                                                  name);
}

}  // namespace

OnlineRetrainSettings online_retrain_settings(const RunConfig& cfg, const std::string& checkpoint_path) {
    const RunConfig trained = ckpt_config(checkpoint_path);
    OnlineRetrainSettings s;
    s.retrain = cfg.retrain;
    s.delta = cfg.retrain_delta;
    s.steps = cfg.retrain_steps;
    s.samples = cfg.retrain_samples;
    s.learning_rate = cfg.retrain_learning_rate > 0
                          ? cfg.retrain_learning_rate
                          : trained.learning_rate * checkpoint_rate_scale(checkpoint_path);
    s.beta1 = trained.beta1;
    s.beta2 = trained.beta2;
    s.tau = trained.tau;
    s.reset_adam = trained.reset_adam;
    return s;
}

std::unique_ptr<OnlineFilter> make_retrain_gain_filter(const FilterModel& model, const RunConfig& cfg,
                                                       const std::string& checkpoint_path,
                                                       const OnlineRetrainSettings& settings, const std::string& name) {
    return ckpt_precision(checkpoint_path) == "double"
               ? make_typed<double>(model, cfg, checkpoint_path, settings, name)
               : make_typed<float>(model, cfg, checkpoint_path, settings, name);
}

void online_retrain_write(const OnlineFilter& filter, const std::string& path) {
    if (const auto* d = dynamic_cast<const RetrainGainFilter<double>*>(&filter)) return d->write(path);
    if (const auto* f = dynamic_cast<const RetrainGainFilter<float>*>(&filter)) return f->write(path);
    HINF_FAIL("online_retrain_write: filter '" + filter.name() + "' is not a retraining gain filter");
}

}  // namespace hinf
