// Sampling around x~(t) and the per-sample constants of one time step (see samples.hpp).
#include "train/samples.hpp"

#include <algorithm>

#include "sampling.hpp"
#include "filters/gain_law.hpp"

namespace hinf {

kern::HjieSystemView TimeStepSamples::view() const {
    return {n, nv, m, xt.data(), dA.data(), Bm.data(), dC.data(), q.data()};
}

void samples_build(TimeStepSamples* s, const RunConfig& cfg, const std::vector<double>& x,
                   const std::vector<double>& xhat, std::int64_t step) {
    const int n = cfg.n, nv = cfg.nv, m = cfg.m;
    const std::int64_t N = cfg.samples;
    const double t = cfg.time_of(step);
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
    sys.state_difference(xtilde.data(), x.data(), xhat.data());  // an angle state's wrapped
    kern::SamplingParams sp{cfg.local_fraction, cfg.local_spread, cfg.radius_decades};
    kern::sample_errors(s->xt.data(), xtilde.data(), cfg.error_floor.data(), n, N, sp, cfg.seed, step);
    sys.drift(s->a_hat.data(), xhat.data(), t, 1);
    sys.measurement(s->c_hat.data(), xhat.data(), t, 1);
    // the model per block of samples over threads: each sample's constants are its own (System's
    // batch calls are per-sample and const), so the bits do not depend on the split
    constexpr std::int64_t kBlock = 256;
    const std::int64_t blocks = (N + kBlock - 1) / kBlock;
#pragma omp parallel for schedule(static)
    for (std::int64_t b = 0; b < blocks; ++b) {
        const std::int64_t i0 = b * kBlock, cnt = std::min(kBlock, N - i0);
        for (std::int64_t i = i0; i < i0 + cnt; ++i)
            for (int j = 0; j < n; ++j) s->xs[i * n + j] = xhat[j] + s->xt[i * n + j];
        sys.drift(s->dA.data() + i0 * n, s->xs.data() + i0 * n, t, cnt);
        sys.disturbance_gain(s->Bm.data() + i0 * n * nv, s->xs.data() + i0 * n, t, cnt);
        sys.measurement(s->dC.data() + i0 * m, s->xs.data() + i0 * n, t, cnt);
        for (std::int64_t i = i0; i < i0 + cnt; ++i) {
            for (int j = 0; j < n; ++j) s->dA[i * n + j] -= s->a_hat[j];
            sys.output_difference(s->dC.data() + i * m, s->dC.data() + i * m, s->c_hat.data());
            s->q[i] = quadratic_form(cfg.Q.data(), s->xt.data() + i * n, n);
        }
    }
}

}  // namespace hinf
