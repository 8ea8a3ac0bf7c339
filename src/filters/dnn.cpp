// DNN filter adapter (seed 000 eq. (19), Fig. 3 on-line phase) over any frozen network and gain law.
// The trainer advances x^ through the same luenberger_advance (filters/gain_law.hpp).
#include "filters/dnn.hpp"
#include "hinf/error.hpp"

#include <set>

#include <Eigen/Dense>

#include "filters/gain_law.hpp"

namespace hinf {

namespace {

class HinfGainLaw final : public DnnGainLaw {
public:
    explicit HinfGainLaw(double rho) : rho_(rho) {}
    void gain(double* k, const DnnGainInput& in) const override {
        WorstCase wc = worst_case(in.p, in.B, in.dc, in.n, in.nv, in.m, rho_);
        std::copy(wc.gain.begin(), wc.gain.end(), k);
    }
    std::unique_ptr<DnnGainLaw> clone() const override { return std::make_unique<HinfGainLaw>(*this); }

private:
    double rho_;
};

class DnnFilter final : public OnlineFilter {
public:
    DnnFilter(const FilterModel& model, std::unique_ptr<FrozenNetwork> net, std::unique_ptr<DnnGainLaw> law,
              bool measured, std::string name)
        : model_(model), net_(std::move(net)), law_(std::move(law)), measured_(measured), name_(std::move(name)) {}
    std::string name() const override { return name_; }
    void reset(const FilterStart& start) override { xhat_ = start.xhat0; }
    bool uses_true_state() const override { return !measured_; }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
        std::vector<double> a(n), B(static_cast<std::size_t>(n) * nv), ch(m), e(m), dc(m), xt(n), p(n),
            k(static_cast<std::size_t>(n) * m);
        sys.drift(a.data(), xhat_.data(), in.t, 1);
        sys.measurement(ch.data(), xhat_.data(), in.t, 1);
        if (in.y != nullptr) sys.output_difference(e.data(), in.y, ch.data());  // missing: e = 0, no correction
        if (measured_) {
            sys.disturbance_gain(B.data(), xhat_.data(), in.t, 1);
            dnn_error_from_innovation(xt.data(), sys, xhat_.data(), in.t, e.data());
            dc = e;
        } else {
            std::vector<double> cx(m);
            sys.disturbance_gain(B.data(), in.x_true, in.t, 1);
            sys.measurement(cx.data(), in.x_true, in.t, 1);
            sys.output_difference(dc.data(), cx.data(), ch.data());
            sys.state_difference(xt.data(), in.x_true, xhat_.data());  // an angle state's wrapped
        }
        net_->gradient(p.data(), xt.data(), 1);
        law_->gain(k.data(), DnnGainInput{p.data(), B.data(), dc.data(), n, nv, m});
        bool finite = filter_estimate_ok(xhat_.data(), n);
        for (double g : k) finite = finite && std::isfinite(g);
        if (!finite) return FILTER_DIVERGED;  // the estimate stays frozen at its last value
        xf_.resize(n);
        luenberger_correct(xf_.data(), xhat_.data(), k.data(), e.data(), n, m, model_.dt);
        luenberger_advance(xhat_.data(), xhat_.data(), a.data(), k.data(), e.data(), n, m, model_.dt);
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    const double* filtered() const override { return xf_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override {
        return std::make_unique<DnnFilter>(model_, net_->clone(), law_->clone(), measured_, name_);
    }

private:
    FilterModel model_;
    std::unique_ptr<FrozenNetwork> net_;
    std::unique_ptr<DnnGainLaw> law_;
    bool measured_;
    std::string name_;
    std::vector<double> xhat_, xf_;  // x^_{k+1}, and x^_k corrected by y_k (filtered())
};

// Variant gain (docs/method.md section 14): x^' = A(x^) + K(x^)(y - C(x^)), K from the network at x^ alone.
class GainFilter final : public OnlineFilter {
public:
    // one network, or an ensemble: K(x^) is the mean of the networks' gains (added in their order, then divided)
    GainFilter(const FilterModel& model, std::vector<std::unique_ptr<FrozenNetwork>> nets, std::string name)
        : model_(model), nets_(std::move(nets)), name_(std::move(name)) {}
    std::string name() const override { return name_; }
    void reset(const FilterStart& start) override {
        xhat_ = start.xhat0;
        far_ = BoxExcursion();
    }
    bool uses_true_state() const override { return false; }
    std::string run_note() const override { return far_.filter_note(model_.system->state_names()); }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), m = sys.output_dim();
        std::vector<double> a(n), ch(m), e(m), k(static_cast<std::size_t>(n) * m);
        for (const auto& net : nets_) far_.see(net->step_config().gain, xhat_.data(), 1, n, in.t);  // the input it holds
        sys.drift(a.data(), xhat_.data(), in.t, 1);
        sys.measurement(ch.data(), xhat_.data(), in.t, 1);
        if (in.y != nullptr) sys.output_difference(e.data(), in.y, ch.data());  // missing: e = 0, no correction
        nets_[0]->gain(k.data(), nullptr, nullptr, xhat_.data(), in.t, sys, 1);
        if (nets_.size() > 1) {
            std::vector<double> ki(k.size());
            for (std::size_t i = 1; i < nets_.size(); ++i) {
                nets_[i]->gain(ki.data(), nullptr, nullptr, xhat_.data(), in.t, sys, 1);
                for (std::size_t j = 0; j < k.size(); ++j) k[j] += ki[j];
            }
            for (double& g : k) g /= static_cast<double>(nets_.size());
        }
        bool finite = filter_estimate_ok(xhat_.data(), n);
        for (double g : k) finite = finite && std::isfinite(g);
        if (!finite) return FILTER_DIVERGED;
        xf_.resize(n);
        gain_filter_correct(xf_.data(), sys, xhat_.data(), in.t, k.data(), e.data(), model_.dt);
        // continuous time Euler-sampled, discrete time the one-step predictor f(x^) + K e (method.md 16.8)
        gain_filter_advance(xhat_.data(), xhat_.data(), a.data(), k.data(), e.data(), n, m, model_.dt,
                            sys.discrete_time());
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    const double* filtered() const override { return xf_.empty() ? nullptr : xf_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override {
        std::vector<std::unique_ptr<FrozenNetwork>> nets;
        for (const auto& net : nets_) nets.push_back(net->clone());
        return std::make_unique<GainFilter>(model_, std::move(nets), name_);
    }

private:
    FilterModel model_;
    std::vector<std::unique_ptr<FrozenNetwork>> nets_;
    std::string name_;
    std::vector<double> xhat_, xf_;  // x^_{k+1}, and x^_k corrected by y_k (filtered())
    BoxExcursion far_;               // how far the estimates went beyond the networks' input boxes since reset()
};

}  // namespace

void gain_filter_check_time(const FrozenNetwork& network, const System& here, const std::string& name) {
    const bool discrete = network.step_config().gain.loss.discrete;
    HINF_CHECK(discrete || !here.discrete_time(),
               "the DNN filter '" + name + "' is a continuous-time (Euler-sampled) filter: its network was trained on a "
               "continuous-time system, and the config's system has [system] time = \"discrete\" (train it on this "
               "config, or filter with ekf, ukf, pf or open_loop)");
    HINF_CHECK(!discrete || here.discrete_time(),
               "the DNN filter '" + name + "' is a discrete-time one-step predictor: its network was trained on a "
               "[system] time = \"discrete\" system, and the config's system is continuous-time (train it on this "
               "config)");
}

std::unique_ptr<OnlineFilter> make_gain_filter(const FilterModel& model, const FrozenNetwork& network,
                                               const std::string& name) {
    return make_gain_ensemble_filter(model, {&network}, name);
}

std::unique_ptr<OnlineFilter> make_gain_ensemble_filter(const FilterModel& model,
                                                        const std::vector<const FrozenNetwork*>& networks,
                                                        const std::string& name) {
    HINF_CHECK(!networks.empty(), "the DNN filter '" + name + "' needs at least one network");
    std::vector<std::unique_ptr<FrozenNetwork>> nets;
    for (const FrozenNetwork* network : networks) {
        HINF_CHECK(network->step_config().gain.enabled,
                   "the DNN filter '" + name + "' averages gains K(x^): every network must be variant \"gain\"");
        gain_filter_check_time(*network, *model.system, name);
        nets.push_back(network->clone());
    }
    return std::make_unique<GainFilter>(model, std::move(nets), name);
}

std::unique_ptr<DnnGainLaw> make_hinf_gain_law(double rho) { return std::make_unique<HinfGainLaw>(rho); }

void dnn_error_from_innovation(double* xt, const System& sys, const double* xhat, double t, const double* e) {
    const int n = sys.state_dim(), m = sys.output_dim();
    Eigen::MatrixXd H(m, n);
    std::vector<double> Hrow(static_cast<std::size_t>(m) * n);
    sys.measurement_jacobian(Hrow.data(), xhat, t);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < n; ++j) H(i, j) = Hrow[i * n + j];
    Eigen::VectorXd ev = Eigen::Map<const Eigen::VectorXd>(e, m);
    Eigen::VectorXd sol = H.completeOrthogonalDecomposition().solve(ev);
    for (int j = 0; j < n; ++j) xt[j] = sol[j];
}

std::unique_ptr<OnlineFilter> make_dnn_filter(const FilterModel& model, const FrozenNetwork& network,
                                              const DnnGainLaw& law, bool measured, const std::string& name) {
    // the filter steps x^ by the sampled-data law x^ + dt (A(x^) + k e) (seed 000 eq. (19)): continuous time only
    HINF_CHECK(!model.system->discrete_time(),
               "the DNN filter '" + name + "' is a continuous-time (Euler-sampled) filter and the config's system has "
               "[system] time = \"discrete\" (filter it with ekf, ukf, pf or open_loop, or write the system in continuous time)");
    return std::make_unique<DnnFilter>(model, network.clone(), law.clone(), measured, name);
}

std::string dnn_measured_warning(const std::string& variant, int n, int m) {
    // variants whose measured filter handles m < n itself (none yet: issue 15; a new variant adds its name here)
    static const std::set<std::string> kMeasuredNative = {"gain"};  // K(x^) from x^ alone (method §16)
    if (m >= n || kMeasuredNative.count(variant) != 0) return "";
    return "hinf: warning: the '" + variant + "' DNN filter in measured mode sees " + std::to_string(m) +
           " measurement(s) of " + std::to_string(n) + " states: it rebuilds x~ from the innovation by least squares, "
           "so the " + std::to_string(n - m) + " unmeasured direction(s) of the error are zero to it and it can do "
           "worse than the open-loop predictor (compare with --filters ekf,ukf, or use --mode oracle to see the network "
           "itself)";
}

}  // namespace hinf
