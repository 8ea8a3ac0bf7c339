// Sampling around x~(t) and the per-sample constants of one time step (see samples.hpp).
#include "train/samples.hpp"

#include "sampling.hpp"
#include "train/filter_math.hpp"

namespace hinf {

kern::HjieSystemView TimeStepSamples::view() const {
    return {n, nv, m, xt.data(), dA.data(), Bm.data(), dC.data(), q.data()};
}

void samples_build(TimeStepSamples* s, const RunConfig& cfg, const std::vector<double>& x,
                   const std::vector<double>& xhat, std::int64_t step) {
    const int n = cfg.n, nv = cfg.nv, m = cfg.m;
    const std::int64_t N = cfg.samples;
    const double t = double(step) * cfg.dt;
    const System& sys = *cfg.system;
    s->n = n;
    s->nv = nv;
    s->m = m;
    s->xt.resize(N * n);
    s->dA.resize(N * n);
    s->Bm.resize(N * n * nv);
    s->dC.resize(N * m);
    s->q.resize(N);
    s->xs.resize(N * n);
    s->a_hat.resize(n);
    s->c_hat.resize(m);
    std::vector<double> xtilde(n);
    for (int i = 0; i < n; ++i) xtilde[i] = x[i] - xhat[i];
    kern::SamplingParams sp{cfg.local_fraction, cfg.local_spread, cfg.radius_decades};
    kern::sample_errors(s->xt.data(), xtilde.data(), cfg.error_floor.data(), n, N, sp, cfg.seed, step);
    sys.drift(s->a_hat.data(), xhat.data(), t, 1);
    sys.measurement(s->c_hat.data(), xhat.data(), t, 1);
    for (std::int64_t i = 0; i < N; ++i)
        for (int j = 0; j < n; ++j) s->xs[i * n + j] = xhat[j] + s->xt[i * n + j];
    sys.drift(s->dA.data(), s->xs.data(), t, N);
    sys.disturbance_gain(s->Bm.data(), s->xs.data(), t, N);
    sys.measurement(s->dC.data(), s->xs.data(), t, N);
    for (std::int64_t i = 0; i < N; ++i) {
        for (int j = 0; j < n; ++j) s->dA[i * n + j] -= s->a_hat[j];
        for (int j = 0; j < m; ++j) s->dC[i * m + j] -= s->c_hat[j];
        s->q[i] = quadratic_form(cfg.Q.data(), s->xt.data() + i * n, n);
    }
}

}  // namespace hinf
