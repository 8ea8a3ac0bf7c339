// Euler-Maruyama for the Itô delay system (1), the filter (21) with the weights of Step (e), the bounding
// constants (24) from simulation and the Monte Carlo of Table 3. Not the LMIs (delay_lmi.cpp).
#include "lmi/delay_sim.hpp"

#include <omp.h>

#include <cmath>

#include "hinf/error.hpp"
#include "random.hpp"

namespace hinf::lmi {

void DelayHistory::reset(int n, double t_start, double dt) {
    n_ = n;
    t_start_ = t_start;
    dt_ = dt;
    rows_ = 0;
    values_.clear();
}

void DelayHistory::push(const double* x) {
    values_.insert(values_.end(), x, x + n_);
    ++rows_;
}

void DelayHistory::at(double t, double* out) const {
    double s = (t - t_start_) / dt_;
    const double smax = static_cast<double>(rows_ - 1);
    if (s <= 0) s = 0;
    if (s >= smax) s = smax;
    std::int64_t k = static_cast<std::int64_t>(std::floor(s));
    if (k >= rows_ - 1) k = rows_ - 1;
    const double w = s - static_cast<double>(k);
    const double* a = values_.data() + k * n_;
    if (w == 0.0 || k + 1 >= rows_) {
        for (int c = 0; c < n_; ++c) out[c] = a[c];
        return;
    }
    const double* b = a + n_;
    for (int c = 0; c < n_; ++c) out[c] = (1 - w) * a[c] + w * b[c];
}

double delay_tau(DelayTauKind kind, double tau2, double t) {
    if (kind == DELAY_TAU_EXP) return std::exp(-1.0 / (1.0 + t));  // seed 002 sec. 5
    return tau2;
}

double DelayDisturbance::at(double t) const {
    double ph = std::fmod(t, period);
    if (ph < 0) ph += period;
    return ph < duty * period ? high : low;
}

void delay_em_step(const DelaySystem& sys, const double* x, const double* xd, const double* v, double dW, double dt,
                   double* x_next, double* dy) {
    const int n = sys.n, l = sys.l, nv = sys.nv;
    double f[16], h[16], g[64], q[16], k[64], j[16];
    sys.f(x, xd, f);
    sys.h(x, xd, h);
    sys.g(x, xd, g);
    for (int r = 0; r < n; ++r) {
        double gv = 0;
        for (int c = 0; c < nv; ++c) gv += g[r * nv + c] * v[c];
        x_next[r] = x[r] + (f[r] + gv) * dt + h[r] * dW;
    }
    sys.q(x, xd, q);
    sys.j(x, xd, j);
    sys.k(x, xd, k);
    for (int r = 0; r < l; ++r) {
        double kv = 0;
        for (int c = 0; c < nv; ++c) kv += k[r * nv + c] * v[c];
        dy[r] = (q[r] + kv) * dt + j[r] * dW;
    }
}

void delay_filter_step(const DelayFilter& fl, const double* xh, const double* xhd, const double* dy, double dt,
                       double* xh_next) {
    const int m = static_cast<int>(fl.vertices.size());
    const int n = static_cast<int>(fl.vertices[0].A0.rows()), l = static_cast<int>(fl.vertices[0].Q0.rows());
    double w[64];
    delay_interp_weights(xh, fl.points, fl.coordinates, w);
    Eigen::Map<const Eigen::VectorXd> X(xh, n), Xd(xhd, n);
    Eigen::Map<const Eigen::VectorXd> DY(dy, l);
    Eigen::VectorXd dyhat = Eigen::VectorXd::Zero(l);
    for (int k = 0; k < m; ++k) dyhat += w[k] * (fl.vertices[k].Q0 * X + fl.vertices[k].Q1 * Xd) * dt;
    const Eigen::VectorXd innovation = DY - dyhat;
    Eigen::VectorXd dx = Eigen::VectorXd::Zero(n);
    for (int j = 0; j < m; ++j)
        dx += w[j] * ((fl.vertices[j].A0 * X + fl.vertices[j].A1 * Xd) * dt + fl.gains[j] * innovation);
    for (int r = 0; r < n; ++r) xh_next[r] = xh[r] + dx[r];
}

namespace {

// delay_em_step and delay_filter_step use fixed stack buffers (no allocation in the time loop).
void check_sizes(const DelaySystem& sys, const DelayFilter& fl) {
    HINF_CHECK(sys.n >= 1 && sys.n <= 16 && sys.l >= 1 && sys.l <= 16 && sys.n * sys.nv <= 64 && sys.l * sys.nv <= 64,
               "delay simulation supports n, l <= 16 and n*nv, l*nv <= 64");
    HINF_CHECK(!fl.vertices.empty() && fl.vertices.size() <= 64 && fl.points.size() == fl.vertices.size(),
               "filter needs 1..64 vertices and one operating point per vertex");
}

std::int64_t steps_of(const DelaySimSpec& s) { return static_cast<std::int64_t>(std::llround(s.final_time / s.dt)); }

// The run's random numbers: x(theta) = chol(M11) z (b = 0) and dW_k = sqrt(dt) N(0,1) (b = 1).
void draw_run(const DelaySimSpec& s, int n, std::int64_t run, std::vector<double>& x0, std::vector<double>& dW) {
    std::vector<double> z(n);
    kern::rng_normal(z.data(), n, s.seed, kern::RNG_STREAM_WIENER, static_cast<std::uint64_t>(run), 0);
    const Eigen::MatrixXd Lc = s.initial_covariance.llt().matrixL();
    x0.assign(n, 0.0);
    for (int r = 0; r < n; ++r)
        for (int c = 0; c <= r; ++c) x0[r] += Lc(r, c) * z[c];
    const std::int64_t N = steps_of(s);
    dW.resize(N);
    kern::rng_normal(dW.data(), N, s.seed, kern::RNG_STREAM_WIENER, static_cast<std::uint64_t>(run), 1);
    const double sq = std::sqrt(s.dt);
    for (auto& d : dW) d *= sq;
}

// Calls visit(t, x, xd, v) at every step of one truth trajectory; returns false if it left the finite numbers.
template <typename Visit>
bool truth_walk(const DelaySystem& sys, const DelaySimSpec& s, std::int64_t run, Visit&& visit) {
    const int n = sys.n;
    std::vector<double> x0, dW;
    draw_run(s, n, run, x0, dW);
    const std::int64_t N = steps_of(s);
    const std::int64_t pre = static_cast<std::int64_t>(std::ceil(s.tau2 / s.dt - 1e-9));
    DelayHistory hx;
    hx.reset(n, -pre * s.dt, s.dt);
    for (std::int64_t k = 0; k <= pre; ++k) hx.push(x0.data());  // constant initial function on [-tau2, 0]
    std::vector<double> x = x0, xd(n), xn(n), dy(sys.l), v(sys.nv);
    for (std::int64_t k = 0; k < N; ++k) {
        const double t = k * s.dt;
        hx.at(t - delay_tau(s.tau, s.tau2, t), xd.data());
        for (auto& vi : v) vi = s.disturbance.at(t);
        visit(t, x.data(), xd.data(), v.data());
        delay_em_step(sys, x.data(), xd.data(), v.data(), dW[k], s.dt, xn.data(), dy.data());
        x = xn;
        for (double c : x)
            if (!std::isfinite(c)) return false;
        hx.push(x.data());
    }
    return true;
}

}  // namespace

DelayRunResult delay_simulate(const DelaySystem& sys, const DelayFilter& fl, const DelaySimSpec& s,
                              std::int64_t run) {
    const int n = sys.n;
    HINF_CHECK(s.dt > 0 && s.final_time > 0 && s.tau2 > 0, "simulation needs dt > 0, final_time > 0, tau2 > 0");
    HINF_CHECK(s.initial_covariance.rows() == n, "initial covariance must be n x n");
    check_sizes(sys, fl);
    HINF_CHECK(fl.gains.size() == fl.vertices.size(), "filter needs one gain per vertex");
    std::vector<double> x0, dW;
    draw_run(s, n, run, x0, dW);
    const std::int64_t N = steps_of(s);
    const std::int64_t pre = static_cast<std::int64_t>(std::ceil(s.tau2 / s.dt - 1e-9));
    DelayHistory hx, hxh;
    hx.reset(n, -pre * s.dt, s.dt);
    hxh.reset(n, -pre * s.dt, s.dt);
    const std::vector<double> zero(n, 0.0);
    for (std::int64_t k = 0; k <= pre; ++k) {
        hx.push(x0.data());  // x(theta) = x0 on [-tau2, 0]
        hxh.push(zero.data());  // xh(theta) = 0 (eq. 16)
    }
    std::vector<double> x = x0, xh = zero, xd(n), xhd(n), xn(n), xhn(n), dy(sys.l), v(sys.nv);
    DelayRunResult r;
    auto sq_err = [&]() {
        double e = 0;
        for (int c = 0; c < n; ++c) e += (x[c] - xh[c]) * (x[c] - xh[c]);
        return e;
    };
    double prev = sq_err();
    r.squared_error.push_back(prev);
    for (std::int64_t k = 0; k < N; ++k) {
        const double t = k * s.dt;
        const double td = t - delay_tau(s.tau, s.tau2, t);
        hx.at(td, xd.data());
        hxh.at(td, xhd.data());
        for (auto& vi : v) vi = s.disturbance.at(t);
        delay_em_step(sys, x.data(), xd.data(), v.data(), dW[k], s.dt, xn.data(), dy.data());
        delay_filter_step(fl, xh.data(), xhd.data(), dy.data(), s.dt, xhn.data());
        x = xn;
        xh = xhn;
        hx.push(x.data());
        hxh.push(xh.data());
        const double cur = sq_err();
        if (!std::isfinite(cur)) {
            r.finite = false;
            r.error_energy = INFINITY;
            return r;
        }
        r.error_energy += 0.5 * (prev + cur) * s.dt;
        prev = cur;
        if ((k + 1) % s.record_every == 0) r.squared_error.push_back(cur);
    }
    return r;
}

DelayMonteCarlo delay_monte_carlo(const DelaySystem& sys, const DelayFilter& fl, const DelaySimSpec& s, int runs,
                                  int threads) {
    HINF_CHECK(runs >= 2, "Monte Carlo needs at least 2 runs for a confidence interval");
    HINF_CHECK(threads >= 1, "threads must be >= 1");
    std::vector<DelayRunResult> res(runs);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (int r = 0; r < runs; ++r) res[r] = delay_simulate(sys, fl, s, r);
    DelayMonteCarlo mc;
    // sums in run order: the result does not depend on the thread count
    double sum = 0;
    const std::size_t rows = res[0].squared_error.size();
    mc.mean_squared_error.assign(rows, 0.0);
    for (int r = 0; r < runs; ++r) {
        mc.error_energy.push_back(res[r].error_energy);
        if (!res[r].finite) ++mc.diverged;
        sum += res[r].error_energy;
        for (std::size_t i = 0; i < rows && i < res[r].squared_error.size(); ++i)
            mc.mean_squared_error[i] += res[r].squared_error[i] / runs;
    }
    mc.mean = sum / runs;
    double ss = 0;
    for (int r = 0; r < runs; ++r) ss += (res[r].error_energy - mc.mean) * (res[r].error_energy - mc.mean);
    mc.stddev = std::sqrt(ss / (runs - 1));
    const double half = 1.959963984540054 * mc.stddev / std::sqrt(static_cast<double>(runs));
    mc.ci95_low = mc.mean - half;
    mc.ci95_high = mc.mean + half;
    for (std::size_t i = 0; i < rows; ++i) mc.time.push_back(static_cast<double>(i) * s.record_every * s.dt);
    return mc;
}

DelayBounds delay_estimate_bounds(const DelaySystem& sys, const DelayFilter& fl, const DelaySimSpec& s, int runs,
                                  int threads) {
    HINF_CHECK(runs >= 1 && threads >= 1, "bound estimation needs runs >= 1 and threads >= 1");
    check_sizes(sys, fl);
    const int n = sys.n, l = sys.l, nv = sys.nv, m = static_cast<int>(fl.vertices.size());
    std::vector<DelayBounds> per(runs);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (int r = 0; r < runs; ++r) {
        DelayBounds b;
        std::vector<double> f(n), h(n), q(l), j(l), g(n * nv), k(l * nv), w(m);
        truth_walk(sys, s, r, [&](double, const double* x, const double* xd, const double*) {
            Eigen::Map<const Eigen::VectorXd> X(x, n), Xd(xd, n);
            const double zeta = std::sqrt(X.squaredNorm() + Xd.squaredNorm());
            delay_interp_weights(x, fl.points, fl.coordinates, w.data());  // alpha_i(x, x_t) of (20)
            sys.f(x, xd, f.data());
            sys.h(x, xd, h.data());
            sys.q(x, xd, q.data());
            sys.j(x, xd, j.data());
            sys.g(x, xd, g.data());
            sys.k(x, xd, k.data());
            Eigen::VectorXd df = Eigen::Map<Eigen::VectorXd>(f.data(), n), dh = Eigen::Map<Eigen::VectorXd>(h.data(), n);
            Eigen::VectorXd dq = Eigen::Map<Eigen::VectorXd>(q.data(), l), dj = Eigen::Map<Eigen::VectorXd>(j.data(), l);
            Eigen::MatrixXd dgk(n + l, nv);
            for (int a = 0; a < n; ++a)
                for (int c = 0; c < nv; ++c) dgk(a, c) = g[a * nv + c];
            for (int a = 0; a < l; ++a)
                for (int c = 0; c < nv; ++c) dgk(n + a, c) = k[a * nv + c];
            for (int i = 0; i < m; ++i) {  // the remainders of (20)
                const auto& V = fl.vertices[i];
                df -= w[i] * (V.A0 * X + V.A1 * Xd);
                dh -= w[i] * (V.C0 * X + V.C1 * Xd);
                dq -= w[i] * (V.Q0 * X + V.Q1 * Xd);
                dj -= w[i] * (V.J0 * X + V.J1 * Xd);
                dgk.topRows(n) -= w[i] * V.B;
                dgk.bottomRows(l) -= w[i] * V.K;
            }
            if (zeta > 1e-6) {
                b.e1 = std::max(b.e1, df.norm() / zeta);
                b.e2 = std::max(b.e2, dh.norm() / zeta);
                b.e3 = std::max(b.e3, dq.norm() / zeta);
                b.e4 = std::max(b.e4, dj.norm() / zeta);
            }
            const double a2 = (dgk * dgk.transpose()).eval().selfadjointView<Eigen::Lower>().eigenvalues().maxCoeff();
            b.alpha = std::max(b.alpha, a2);
        });
        per[r] = b;
    }
    DelayBounds out;
    for (const auto& b : per) {
        out.e1 = std::max(out.e1, b.e1);
        out.e2 = std::max(out.e2, b.e2);
        out.e3 = std::max(out.e3, b.e3);
        out.e4 = std::max(out.e4, b.e4);
        out.alpha = std::max(out.alpha, b.alpha);
    }
    return out;
}

}  // namespace hinf::lmi
