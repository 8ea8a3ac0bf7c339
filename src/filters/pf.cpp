// Bootstrap particle filter (Gordon, Salmond & Smith 1993) on the discrete model of filter.hpp (the system's
// own step, system_advance): the transition prior as proposal, log-weights, systematic resampling when the effective sample size
// drops below a fraction of the particle count. Draws keyed by (seed, run, step): thread-count independent.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "filters/pf.hpp"
#include "filters/psd_sqrt.hpp"
#include "hinf/error.hpp"
#include "models/weighted_system.hpp"
#include "random.hpp"

namespace hinf {

namespace {

class ParticleFilter final : public OnlineFilter {
public:
    ParticleFilter(const FilterModel& model, std::int64_t particles, double ess_fraction, double roughening,
                   bool stratified)
        : model_(model), np_(particles), ess_fraction_(ess_fraction), roughening_(roughening), stratified_(stratified) {
        HINF_CHECK(roughening >= 0, "particle filter: roughening must be >= 0");
        HINF_CHECK(particles >= 1, "particle filter: the particle count must be >= 1 (got " +
                                       std::to_string(particles) + ")");
    }
    std::string name() const override { return roughening_ > 0 ? "pf_roughened" : "pf"; }
    void reset(const FilterStart& start) override {
        const int n = model_.system->state_dim();
        seed_ = start.seed;
        run_ = start.run;
        resamples_ = 0;
        // initial cloud ~ N(x^0, P0)
        Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> P0(start.P0.data(), n, n);
        const Eigen::MatrixXd P0d = P0;
        Eigen::MatrixXd L;  // lower triangular when P0 is positive definite; P0 = 0 (a known start) gives L = 0
        HINF_CHECK(psd_sqrt(P0d, &L), "particle filter: the initial covariance is not positive semidefinite");
        X_.assign(static_cast<std::size_t>(np_) * n, 0.0);
        std::vector<double> z(static_cast<std::size_t>(np_) * n);
        kern::rng_normal(z.data(), np_ * n, seed_, kern::RNG_STREAM_PARTICLES, run_, 0);
        for (std::int64_t p = 0; p < np_; ++p)
            for (int i = 0; i < n; ++i) {
                double s = start.xhat0[i];
                for (int j = 0; j < n; ++j) s += L(i, j) * z[p * n + j];
                X_[p * n + i] = s;
            }
        w_.assign(np_, 1.0 / double(np_));
        mean(xhat_);
        cov_.clear();
        nis_pending_ = false;
        nis_ = NAN;
    }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
        // weight update: log w += log N(y; C(x), sn^2 I); a missing measurement (in.y == nullptr): weights
        // unchanged, no resampling, the filtered estimate is the prediction
        if (in.y != nullptr) {
            // normalised with the max subtracted
            // the prior cloud's outputs, weights and y stay for nis(), which is computed only when asked
            c_.resize(static_cast<std::size_t>(np_) * m);
            std::vector<double>& c = c_;
            std::vector<double> logw(np_);
            sys.measurement(c.data(), X_.data(), in.t, np_);
            prior_w_ = w_;
            y_.assign(in.y, in.y + m);
            nis_pending_ = true;
            const double inv_r = 1.0 / (model_.noise_std * model_.noise_std);
            std::vector<double> wj(m, 1.0);  // (sn / sn_j)^2 per output (model_.noise_weight)
            for (int j = 0; j < m && !model_.noise_weight.empty(); ++j)
                wj[j] = 1.0 / (model_.noise_weight[j] * model_.noise_weight[j]);
            double top = -INFINITY;
            std::vector<double> e(static_cast<std::size_t>(m));
            for (std::int64_t p = 0; p < np_; ++p) {
                double q = 0;
                sys.output_difference(e.data(), in.y, c.data() + p * m);  // an angle output's wrapped
                if (!model_.noise_chol.empty()) {  // correlated: |L^-1 e|^2 (filters/filter.hpp)
                    lower_solve(model_.noise_chol, m, e.data());
                    for (int j = 0; j < m; ++j) q += e[j] * e[j];
                } else
                    for (int j = 0; j < m; ++j) q += e[j] * e[j] * wj[j];
                logw[p] = std::log(w_[p]) - 0.5 * inv_r * q;
                top = std::max(top, logw[p]);
            }
            if (!std::isfinite(top)) return FILTER_DIVERGED;
            double total = 0;
            for (std::int64_t p = 0; p < np_; ++p) total += (w_[p] = std::exp(logw[p] - top));
            double sq = 0;
            for (std::int64_t p = 0; p < np_; ++p) {
                w_[p] /= total;
                sq += w_[p] * w_[p];
            }
            // the filtered estimate x^_{k|k}: the weighted mean before resampling (resampling adds only noise)
            mean(xf_);
            // systematic (or stratified) resampling when ESS = 1 / sum w^2 < fraction * N
            if (1.0 / sq < ess_fraction_ * double(np_)) {
                std::vector<double> u0(stratified_ ? std::size_t(np_) : 1u);
                kern::rng_uniform(u0.data(), std::int64_t(u0.size()), seed_, kern::RNG_STREAM_RESAMPLE, run_,
                                  std::uint64_t(in.step));
                std::vector<double> Xr(X_.size());
                double cum = w_[0];
                std::int64_t src = 0;
                for (std::int64_t p = 0; p < np_; ++p) {
                    // u0 in (0, 1]: offset in [0, 1); one offset for all (systematic) or one per stratum (stratified)
                    const double u = (double(p) + (1.0 - u0[stratified_ ? std::size_t(p) : 0u])) / double(np_);
                    while (cum < u && src < np_ - 1) cum += w_[++src];
                    std::copy(X_.begin() + src * n, X_.begin() + (src + 1) * n, Xr.begin() + p * n);
                }
                X_.swap(Xr);
                std::fill(w_.begin(), w_.end(), 1.0 / double(np_));
                ++resamples_;
                if (roughening_ > 0) {
                    // roughening: sigma_i = K E_i N^(-1/n), E_i = max - min of the resampled cloud in state i
                    std::vector<double> lo(X_.begin(), X_.begin() + n), hi(lo), z(X_.size()), d(n);
                    for (std::int64_t p = 1; p < np_; ++p)
                        for (int i = 0; i < n; ++i) {
                            lo[i] = std::min(lo[i], X_[p * n + i]);
                            hi[i] = std::max(hi[i], X_[p * n + i]);
                        }
                    for (int i : sys.angle_states()) lo[i] = hi[i] = 0.0;  // an angle: the spread of the offsets
                    for (std::int64_t p = 1; p < np_ && !sys.angle_states().empty(); ++p) {
                        sys.state_difference(d.data(), &X_[p * n], &X_[0]);
                        for (int i : sys.angle_states()) {
                            lo[i] = std::min(lo[i], d[i]);
                            hi[i] = std::max(hi[i], d[i]);
                        }
                    }
                    kern::rng_normal(z.data(), np_ * n, seed_, kern::RNG_STREAM_ROUGHEN, run_, std::uint64_t(in.step));
                    const double shrink = roughening_ * std::pow(double(np_), -1.0 / n);
                    for (std::int64_t p = 0; p < np_; ++p)
                        for (int i = 0; i < n; ++i) X_[p * n + i] += shrink * (hi[i] - lo[i]) * z[p * n + i];
                }
            }
        } else {
            mean(xf_);
            nis_pending_ = false;
            nis_ = NAN;
        }
        // propagate through the transition (the shared step: Euler or the discrete map), v ~ sv N(0, I)
        std::vector<double> v(static_cast<std::size_t>(np_) * nv);
        kern::rng_normal(v.data(), np_ * nv, seed_, kern::RNG_STREAM_PARTICLES, run_, std::uint64_t(in.step) + 1);
        if (!model_.disturbance_chol.empty())  // correlated: sv L z
            for (std::int64_t p = 0; p < np_; ++p) {
                lower_multiply(model_.disturbance_chol, nv, v.data() + p * nv);
                for (int k = 0; k < nv; ++k) v[std::size_t(p * nv + k)] *= model_.disturbance_std;
            }
        else
            for (std::size_t i = 0; i < v.size(); ++i) v[i] *= model_.disturbance_std_of(int(i % std::size_t(nv)));
        system_advance(sys, X_.data(), X_.data(), v.data(), in.t, model_.dt, np_);
        std::vector<double> xn(n);
        mean(xn);
        if (!filter_estimate_ok(xn.data(), n)) return FILTER_DIVERGED;
        xhat_ = xn;
        cov_.clear();
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    const double* filtered() const override { return xf_.data(); }
    /// The weighted covariance of the cloud about estimate() (computed when asked: O(N n^2)).
    const double* covariance() const override {
        const int n = model_.system->state_dim();
        if (X_.size() != std::size_t(np_) * n) return nullptr;  // never reset: no cloud
        if (cov_.size() != std::size_t(n) * n) {
            cov_.assign(std::size_t(n) * n, 0.0);
            std::vector<double> d(n);
            for (std::int64_t p = 0; p < np_; ++p) {
                model_.system->state_difference(d.data(), &X_[p * n], xhat_.data());  // an angle's wrapped
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j <= i; ++j) cov_[std::size_t(i) * n + j] += w_[p] * d[i] * d[j];
            }
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < i; ++j) cov_[std::size_t(j) * n + i] = cov_[std::size_t(i) * n + j];
        }
        return cov_.data();
    }
    bool covariance_is_statistical() const override { return true; }
    /// The last measurement's NIS against the prior cloud's weighted output covariance plus R (computed when asked:
    /// O(N m^2)); an angle output's offsets are taken from the heaviest particle's output, as mean() does for states.
    double nis() const override {
        if (!nis_pending_) return nis_;
        nis_pending_ = false;
        const System& sys = *model_.system;
        const int m = sys.output_dim();
        const std::int64_t ref = std::max_element(prior_w_.begin(), prior_w_.end()) - prior_w_.begin();
        const double* cref = &c_[std::size_t(ref) * m];
        Eigen::VectorXd off = Eigen::VectorXd::Zero(m), d(m);
        for (std::int64_t p = 0; p < np_; ++p) {
            sys.output_difference(d.data(), &c_[std::size_t(p) * m], cref);
            off += prior_w_[p] * d;
        }
        Eigen::MatrixXd S = noise_covariance(model_, m);
        for (std::int64_t p = 0; p < np_; ++p) {
            sys.output_difference(d.data(), &c_[std::size_t(p) * m], cref);
            d -= off;
            S.noalias() += prior_w_[p] * d * d.transpose();
        }
        Eigen::VectorXd chat(m), nu(m);  // the predicted output: the heaviest particle's plus the mean offset
        for (int j = 0; j < m; ++j) chat[j] = cref[j] + off[j];
        sys.output_difference(nu.data(), y_.data(), chat.data());
        nis_ = normalised_square(Eigen::LLT<Eigen::MatrixXd>(S), nu);
        return nis_;
    }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<ParticleFilter>(*this); }
    std::int64_t resamples() const { return resamples_; }

private:
    void mean(std::vector<double>& out) const {
        const System& sys = *model_.system;
        const int n = sys.state_dim();
        out.assign(n, 0.0);
        for (std::int64_t p = 0; p < np_; ++p)
            for (int i = 0; i < n; ++i) out[i] += w_[p] * X_[p * n + i];
        if (sys.angle_states().empty()) return;
        // an angle state: the weighted mean of the particles' offsets from the heaviest one (the cloud may straddle
        // +-pi, where the plain mean of 3.1 and -3.1 is 0)
        const std::int64_t ref = std::max_element(w_.begin(), w_.end()) - w_.begin();
        std::vector<double> d(n);
        for (int i : sys.angle_states()) out[i] = 0.0;
        for (std::int64_t p = 0; p < np_; ++p) {
            sys.state_difference(d.data(), &X_[p * n], &X_[ref * n]);
            for (int i : sys.angle_states()) out[i] += w_[p] * d[i];
        }
        for (int i : sys.angle_states()) out[i] += X_[ref * n + i];
    }

    FilterModel model_;
    std::int64_t np_;
    double ess_fraction_, roughening_;
    bool stratified_;
    std::uint64_t seed_ = 0, run_ = 0;
    std::int64_t resamples_ = 0;
    std::vector<double> X_, w_, xhat_, xf_;  // X_ [np x n], w_ [np] normalised; x^_{k+1|k}, x^_{k|k}
    mutable std::vector<double> cov_;          // covariance() of the current cloud; empty: not computed yet
    std::vector<double> c_, prior_w_, y_;      // the last update's prior outputs [np x m], weights [np] and y [m]
    mutable bool nis_pending_ = false;         // nis() not yet computed from them
    mutable double nis_ = NAN;
};

}  // namespace

std::unique_ptr<OnlineFilter> make_particle_filter(const FilterModel& model, std::int64_t particles,
                                                   double ess_fraction, double roughening, bool stratified) {
    return std::make_unique<ParticleFilter>(model, particles, ess_fraction, roughening, stratified);
}

}  // namespace hinf
