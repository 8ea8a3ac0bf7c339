// The training-step benchmark (see bench.hpp). Timing is medians over repeats after warm-up; the
// FLOP count is that of the GEMMs (2 flops per multiply-add), as in issue 8.
#include "eval/bench.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "adam.hpp"
#include "hinf/config.hpp"
#include "models/expr_system.hpp"
#include "models/missile.hpp"
#include "gemm.hpp"
#include "mlp.hpp"
#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/atomic.hpp"
#include "peak.hpp"
#include "sampling.hpp"
#include "net/network.hpp"
#include "train/samples.hpp"
#include "train/trainer.hpp"
#include "io/run_lock.hpp"

namespace hinf {

namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

// GEMM flops of one training step: forward H_l = H_{l-1} W^T, backward dW and dH (no dH for the input).
double step_flops(const kern::MlpShape& sh, int M) {
    double macs = 0;
    for (int l = 1; l <= sh.layers(); ++l) {
        double lay = double(sh.sizes[l]) * sh.sizes[l - 1];
        macs += (l == 1 ? 2 : 3) * lay;
    }
    return 2.0 * macs * M;
}

double measure_peak(int threads, bool dbl) {
    omp_set_num_threads(threads);
    const std::int64_t iters = 20000000;
    kern::fma_peak_loop(iters / 10, dbl);  // warm-up (clocks up)
    double best = 0;
    for (int rep = 0; rep < 3; ++rep) {
        double flops = 0;
        auto t0 = Clock::now();
#pragma omp parallel reduction(+ : flops)
        flops += kern::fma_peak_loop(iters, dbl);
        double s = std::chrono::duration<double>(Clock::now() - t0).count();
        best = std::max(best, flops / s * 1e-9);
    }
    return best;
}

RunConfig bench_config(const BenchOptions& opt) {
    std::string text = "[filter]\nvariant = \"" + opt.variant + "\"\n[training]\nbatch = " + std::to_string(opt.batch) +
                       "\nsamples = " + std::to_string(std::max(2000, opt.batch)) + "\n";
    return load_run_config(ConfigDoc::from_text(text, "bench"));
}

kern::GemmPath parse_gemm(const std::string& g) {
    return g == "eigen" ? kern::GEMM_EIGEN : g == "openblas" ? kern::GEMM_OPENBLAS : g == "own" ? kern::GEMM_OWN
                                                                                              : kern::default_gemm_path();
}

std::string gemm_name(kern::GemmPath p) {
    return p == kern::GEMM_EIGEN ? "eigen" : p == kern::GEMM_OPENBLAS ? "openblas" : "own";
}

// One row per GEMM path; the paths' steps are interleaved (A, B, A, B, ...) so that the machine's
// load drifts alike over all of them.
template <typename T>
std::vector<BenchRow> time_step(const BenchOptions& opt, int threads, const std::vector<kern::GemmPath>& paths) {
    RunConfig cfg = bench_config(opt);
    Network<T> net = network_create<T>(cfg);
    TimeStepSamples s;
    samples_build(&s, cfg, cfg.x0, cfg.xhat0, 0);
    kern::HjieSystemView view = s.view();
    std::vector<std::int64_t> idx(opt.batch), perm(cfg.samples);
    std::vector<double> work(std::max<std::int64_t>(cfg.samples, opt.batch));
    kern::sample_minibatch(idx.data(), opt.batch, cfg.samples, cfg.seed, 0, 1, work.data(), perm.data());
    std::vector<T> grad(net.theta.size()), m(net.theta.size(), T(0)), v(net.theta.size(), T(0));
    kern::StepWorkspace<T> ws;
    kern::AdamParams ap{cfg.learning_rate, cfg.beta1, cfg.beta2, cfg.tau};
    omp_set_num_threads(threads);
    std::vector<std::vector<double>> ms(paths.size());
    std::vector<kern::StepConfig> steps(paths.size(), net.step);  // the same network on each GEMM path
    for (std::size_t k = 0; k < paths.size(); ++k) steps[k].shape.gemm = paths[k];
    for (int r = 0; r < opt.repeats + 5; ++r)
        for (std::size_t k = 0; k < paths.size(); ++k) {
            auto t0 = Clock::now();
            kern::step_gradient(grad.data(), net.theta.data(), view, idx.data(), opt.batch, steps[k], ws);
            kern::adam_update(net.theta.data(), m.data(), v.data(), grad.data(), std::int64_t(grad.size()), r % 30 + 1,
                              ap);
            double dt = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
            if (r >= 5) ms[k].push_back(dt);  // the first five rounds are warm-up
        }
    std::vector<BenchRow> rows;
    for (std::size_t k = 0; k < paths.size(); ++k) {
        BenchRow row;
        row.precision = sizeof(T) == 4 ? "f32" : "f64";
        row.variant = opt.variant;
        row.gemm = gemm_name(paths[k]);
        row.threads = threads;
        row.median_ms = median(ms[k]);
        row.min_ms = *std::min_element(ms[k].begin(), ms[k].end());
        row.max_ms = *std::max_element(ms[k].begin(), ms[k].end());
        row.gflops = step_flops(net.step.shape, opt.batch) / (row.median_ms * 1e-3) * 1e-9;

        // per-time-step work outside the Adam steps: a time step with K = 1, minus one step
        std::string dir = opt.out_dir + "/bench-train-tmp";
        RunConfig one = bench_config(opt);
        one.gemm = gemm_name(paths[k]);
        one.adam_steps = 1;
        one.checkpoint_every = 1000000000;
        one.precision = sizeof(T) == 4 ? "float" : "double";
        TrainOptions to;
        to.out_dir = dir;
        to.until = 20 * one.dt;
        to.quiet = true;
        TrainSummary ts = train_start(one, to);
        std::filesystem::remove_all(dir);
        row.outside_ms = std::max(0.0, 1e3 * ts.wall_seconds / double(ts.last_step - ts.first_step) - row.median_ms);
        rows.push_back(row);
    }
    return rows;
}

// Expression systems (issue 7): f, g, h evaluated over the N sample states of a training time step,
// the Jacobians at one state, against the hand-written missile; and the share of a whole training time step.
template <typename F>
double median_ms(int repeats, F&& work) {
    std::vector<double> ms;
    for (int r = 0; r < repeats + 2; ++r) {
        auto t0 = Clock::now();
        work();
        double dt = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        if (r >= 2) ms.push_back(dt);  // two warm-up calls
    }
    return median(ms);
}

void bench_system(const System& sys, const std::vector<double>& xs, int repeats, double* f_ns, double* g_ns,
                  double* h_ns, double* df_us, double* dh_us) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
    const std::int64_t N = std::int64_t(xs.size()) / n;
    std::vector<double> a(N * n), B(N * n * nv), c(N * m), J(n * n), H(m * n);
    *f_ns = 1e6 * median_ms(repeats, [&] { sys.drift(a.data(), xs.data(), 0.5, N); }) / double(N);
    *g_ns = 1e6 * median_ms(repeats, [&] { sys.disturbance_gain(B.data(), xs.data(), 0.5, N); }) / double(N);
    *h_ns = 1e6 * median_ms(repeats, [&] { sys.measurement(c.data(), xs.data(), 0.5, N); }) / double(N);
    const int per = 100;
    *df_us = 1e3 * median_ms(repeats, [&] {
        for (int i = 0; i < per; ++i) sys.drift_jacobian(J.data(), &xs[std::size_t(i % N) * n], 0.5);
    }) / per;
    *dh_us = 1e3 * median_ms(repeats, [&] {
        for (int i = 0; i < per; ++i) sys.measurement_jacobian(H.data(), &xs[std::size_t(i % N) * n], 0.5);
    }) / per;
}

BenchExpr bench_expr(const BenchOptions& opt, int threads) {
    BenchExpr b;
    RunConfig cfg = load_run_config(ConfigDoc::from_file(opt.expr_config));
    omp_set_num_threads(threads);
    TimeStepSamples s;
    samples_build(&s, cfg, cfg.x0, cfg.xhat0, 0);  // the N states of the first time step
    bench_system(*cfg.system, s.xs, opt.repeats, &b.f_ns, &b.g_ns, &b.h_ns, &b.df_us, &b.dh_us);
    if (cfg.n == 6 && cfg.nv == 1 && cfg.m == 6) {
        MissileSystem ref{MissileParams{}};
        bench_system(ref, s.xs, opt.repeats, &b.ref_f_ns, &b.ref_g_ns, &b.ref_h_ns, &b.ref_df_us, &b.ref_dh_us);
    }
    // a time step calls f and h at x^ and f, g, h on the N states (train/samples.cpp)
    const double N = double(cfg.samples);
    b.eval_ms = 1e-6 * (N * (b.f_ns + b.g_ns + b.h_ns) + b.f_ns + b.h_ns);
    // the whole training time step of this config, measured: 10 time steps (K Adam steps each)
    std::string dir = opt.out_dir + "/bench-expr-tmp";
    TrainOptions to;
    to.out_dir = dir;
    to.until = 10 * cfg.dt;
    to.quiet = true;
    cfg.checkpoint_every = 1000000000;
    TrainSummary ts = train_start(cfg, to);
    std::filesystem::remove_all(dir);
    b.time_step_ms = 1e3 * ts.wall_seconds / double(std::max<std::int64_t>(1, ts.last_step - ts.first_step));
    return b;
}

void bench_expr_report(const BenchOptions& opt, hid_t file) {
    if (opt.expr_config.empty()) return;
    const int threads = opt.threads.back();
    BenchExpr b = bench_expr(opt, threads);
    std::printf("\nexpression system %s, %d thread(s): expressions by %s, over the N sample "
                "states of a time step\n",
                opt.expr_config.c_str(), threads, expr_library_versions().c_str());
    std::printf("%-18s %12s %12s %12s %12s %12s\n", "", "f ns/state", "g ns/state", "h ns/state", "dA/dx us",
                "dC/dx us");
    std::printf("%-18s %12.1f %12.1f %12.1f %12.2f %12.2f\n", "expr", b.f_ns, b.g_ns, b.h_ns, b.df_us, b.dh_us);
    if (b.ref_f_ns > 0)
        std::printf("%-18s %12.1f %12.1f %12.1f %12.2f %12.2f\n", "built-in missile", b.ref_f_ns, b.ref_g_ns,
                    b.ref_h_ns, b.ref_df_us, b.ref_dh_us);
    std::printf("per training time step: expression evaluation %.3f ms of %.1f ms (%.1f%%)\n", b.eval_ms,
                b.time_step_ms, 100 * b.eval_ms / b.time_step_ms);
    h5::set_attr(file, "expr_config", opt.expr_config);
    h5::set_attr(file, "expr_f_ns_per_state", b.f_ns);
    h5::set_attr(file, "expr_g_ns_per_state", b.g_ns);
    h5::set_attr(file, "expr_h_ns_per_state", b.h_ns);
    h5::set_attr(file, "expr_drift_jacobian_us", b.df_us);
    h5::set_attr(file, "expr_measurement_jacobian_us", b.dh_us);
    h5::set_attr(file, "expr_eval_ms_per_time_step", b.eval_ms);
    h5::set_attr(file, "expr_time_step_ms", b.time_step_ms);
    if (b.ref_f_ns > 0) {
        h5::set_attr(file, "missile_f_ns_per_state", b.ref_f_ns);
        h5::set_attr(file, "missile_g_ns_per_state", b.ref_g_ns);
        h5::set_attr(file, "missile_h_ns_per_state", b.ref_h_ns);
    }
}

}  // namespace

std::vector<BenchRow> bench_run(const BenchOptions& opt) {
    HINF_CHECK(opt.batch >= 1 && opt.batch <= 1000000, "--batch must be between 1 and 1000000");
    HINF_CHECK(opt.repeats >= 3, "--repeats must be >= 3");
    for (int t : opt.threads) HINF_CHECK(t >= 1 && t <= 1024, "--threads entries must be between 1 and 1024");
    for (const auto& p : opt.precisions)
        HINF_CHECK(p == "f32" || p == "f64", "--precision '" + p + "' is not one of: f32, f64");
    std::vector<kern::GemmPath> paths;
    std::stringstream gs(opt.gemm);
    for (std::string g; std::getline(gs, g, ',');) {
        HINF_CHECK(g == "default" || g == "own" || g == "openblas" || g == "eigen",
                   "--gemm '" + g + "' is not one of: default, own, openblas, eigen");
        HINF_CHECK(g != "own" || kern::gemm_own_available(),
                   "--gemm own: this build has no AVX-512 kernels (configure on an AVX-512 machine with HINF_NATIVE=ON), "
                   "use --gemm openblas");
        paths.push_back(parse_gemm(g));
    }
    HINF_CHECK(!paths.empty(), "--gemm needs at least one of: default, own, openblas, eigen");
    const RunDirLock lock(opt.out_dir, "hinf bench");
    std::printf("hinf bench: %s network 6-256-128-32, batch M = %d, %d repeats after 5 warm-up steps%s\n",
                opt.variant.c_str(), opt.batch, opt.repeats, paths.size() > 1 ? ", GEMM paths interleaved" : "");
    std::vector<std::string> descriptions;
    for (kern::GemmPath p : paths) {
        descriptions.push_back(kern::gemm_description(p));
        std::printf("GEMMs (%s): %s\n", gemm_name(p).c_str(), descriptions.back().c_str());
    }
    std::printf("other loops compiled for %s\n", kern::simd_name().c_str());
    std::vector<BenchRow> rows;
    for (const auto& p : opt.precisions)
        for (int t : opt.threads) {
            std::vector<BenchRow> rs = p == "f32" ? time_step<float>(opt, t, paths) : time_step<double>(opt, t, paths);
            const double peak = measure_peak(t, p == "f64");
            for (auto& r : rs) {
                r.peak_gflops = peak;
                rows.push_back(r);
            }
        }
    std::printf("%-5s %-8s %-7s %10s %17s %9s %11s %9s %16s\n", "prec", "gemm", "threads", "ms/step", "min-max",
                "GFLOP/s", "peak GF/s", "of peak", "outside ms/tstep");
    for (const auto& r : rows)
        std::printf("%-5s %-8s %-7d %10.3f %8.3f-%-8.3f %9.1f %11.1f %8.1f%% %16.2f\n", r.precision.c_str(),
                    r.gemm.c_str(), r.threads, r.median_ms, r.min_ms, r.max_ms, r.gflops, r.peak_gflops,
                    100 * r.gflops / r.peak_gflops, r.outside_ms);
    AtomicH5 f(opt.out_dir + "/bench.h5");
    h5::set_attr(f.get(), "format", "hinf-bench");
    h5::set_attr(f.get(), "variant", opt.variant);
    h5::set_attr(f.get(), "batch", std::int64_t(opt.batch));
    h5::set_attr(f.get(), "simd", kern::simd_name());
    h5::set_attr(f.get(), "gemm", descriptions.front());
    h5::set_attr(f.get(), "meaning",
                 "step_ms_<prec>_<threads>t: median ms of one training step (forward, loss, backward, Adam) on M "
                 "samples; peak_gflops_*: register-FMA loop; gflops_*: GEMM flops (2 per multiply-add) / median; "
                 "outside_ms_*: per time step outside the Adam steps (sampling, constants, statistics, gain, "
                 "propagation, HDF5 row); gemm: the first GEMM path's kernels, whose rows carry the plain names; "
                 "further paths of --gemm (timed interleaved with it) append _<path> (own, openblas, eigen)");
    std::string others;
    for (std::size_t k = 1; k < paths.size(); ++k) others += (others.empty() ? "" : ",") + gemm_name(paths[k]);
    h5::set_attr(f.get(), "gemm_paths", gemm_name(paths.front()) + (others.empty() ? "" : "," + others));
    for (const auto& r : rows) {
        // the first GEMM path's rows under the plain names; the others' with the path appended
        std::string key = r.precision + "_" + std::to_string(r.threads) + "t" +
                          (r.gemm == gemm_name(paths.front()) ? "" : "_" + r.gemm);
        h5::set_attr(f.get(), "step_ms_" + key, r.median_ms);
        h5::set_attr(f.get(), "step_ms_min_" + key, r.min_ms);
        h5::set_attr(f.get(), "step_ms_max_" + key, r.max_ms);
        h5::set_attr(f.get(), "gflops_" + key, r.gflops);
        h5::set_attr(f.get(), "peak_gflops_" + key, r.peak_gflops);
        h5::set_attr(f.get(), "outside_ms_" + key, r.outside_ms);
    }
    bench_expr_report(opt, f.get());
    f.commit();
    return rows;
}

}  // namespace hinf
