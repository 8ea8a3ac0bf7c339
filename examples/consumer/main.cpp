// An example program built against an installed hinf (find_package(hinf), target hinf::hinf): trains a DNN filter
// for a config with a progress callback, simulates a noisy record with the config's own system, then runs the
// trained filter and the EKF on it, one step at a time and over the whole record. docs/library.md.
//
// Usage: consumer CONFIG OUT_DIR [UNTIL_S [KEY=VALUE ...]]   e.g. consumer runs/vanderpol.toml /tmp/vdp 1.0
#include <hinf/hinf.hpp>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: consumer CONFIG OUT_DIR [UNTIL_S [KEY=VALUE ...]]\n");
        return 2;
    }
    try {
        std::vector<std::string> overrides(argv + std::min(argc, 4), argv + argc);
        const hinf::Config cfg = hinf::Config::load(argv[1], overrides);
        std::printf("hinf %s: system %s, %d states, %d outputs, dt = %g s\n", hinf::version().c_str(),
                    cfg.system().c_str(), cfg.states(), cfg.outputs(), cfg.dt());

        // 1. train, watching the progress
        hinf::TrainSettings settings;
        settings.out_dir = argv[2];
        settings.until = argc > 3 ? std::stod(argv[3]) : 1.0;
        settings.force = true;
        settings.on_progress = [](const hinf::TrainProgress& p) {
            if (p.step % 20 == 0 || p.step == p.last_step)
                std::printf("  step %lld/%lld t = %.2f s loss %.4g\n", static_cast<long long>(p.step),
                            static_cast<long long>(p.last_step), p.t, p.loss_last);
        };
        const hinf::TrainReport report = hinf::train(cfg, settings);
        if (report.diverged) {
            std::fprintf(stderr, "consumer: training diverged\n");
            return 1;
        }
        std::printf("trained %lld steps in %.2f s -> %s\n", static_cast<long long>(report.last_step),
                    report.wall_seconds, report.checkpoint.c_str());

        // 2. a record: the config's system, its Euler step, Gaussian disturbance and noise
        const int n = cfg.states(), m = cfg.outputs(), nv = cfg.disturbances();
        const std::int64_t K = 1000;
        std::mt19937_64 rng(1);
        std::normal_distribution<double> gauss(0.0, 1.0);
        std::vector<double> x = cfg.initial_state(), t(K), y(K * m), truth(K * n);
        for (std::int64_t k = 0; k < K; ++k) {
            t[k] = double(k) * cfg.dt();
            std::vector<double> c = cfg.measure(x, t[k]), v(nv);
            for (int j = 0; j < m; ++j) y[k * m + j] = c[j] + 0.1 * gauss(rng);
            for (int i = 0; i < n; ++i) truth[k * n + i] = x[i];
            for (double& vi : v) vi = 0.5 * gauss(rng);
            x = cfg.advance(x, v, t[k], cfg.dt());
        }

        // 3. filters by name: the trained network and the EKF
        hinf::FilterOptions options;
        options.networks = {hinf::TrainedNetwork::load(report.checkpoint)};
        for (const char* name : {"dnn", "ekf"}) {
            hinf::Filter f = hinf::Filter::create(cfg, name, options);
            double sq = 0;  // one step at a time: estimate() before step k estimates x(t_k)
            for (std::int64_t k = 0; k < K; ++k) {
                const std::vector<double> xh = f.estimate();
                for (int i = 0; i < n; ++i) sq += (xh[i] - truth[k * n + i]) * (xh[i] - truth[k * n + i]);
                f.step(&y[k * m], t[k]);
            }
            const hinf::FilterTrace trace = f.run(t, y);  // the whole record at once, as `hinf filter`
            std::printf("%-26s rms error %.4f (one step at a time), final estimate", trace.name.c_str(),
                        std::sqrt(sq / double(K)));
            for (double v : trace.xhat_final) std::printf(" %.4f", v);
            std::printf("%s\n", f.has_covariance() ? ", with covariance" : "");
        }
        // 4. bad use is an exception with one line
        try {
            hinf::Filter::create(cfg, "kalman");
        } catch (const hinf::Error& e) {
            std::printf("as expected: %s\n", e.what());
        }
    } catch (const hinf::Error& e) {
        std::fprintf(stderr, "consumer: %s\n", e.what());
        return 2;
    }
    return 0;
}
