// The linearised game's smallest level (docs/method.md section 16.12).
#include "config/game_level.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>

namespace hinf {

double game_level_lost_at(const ProblemConfig& c, double rho, int repeats) {
    using Mat = Eigen::MatrixXd;
    using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const int n = c.n, m = c.m, nv = c.nv;
    const System& sys = *c.system;
    const bool discrete = sys.discrete_time();
    const double w = discrete ? 1.0 : c.dt;
    const Mat Qr = Eigen::Map<const RowMat>(c.Q.data(), n, n) / rho;
    const Mat I = Mat::Identity(n, n);
    Mat P = Mat::Zero(n, n);
    RowMat H(m, n), F(n, n), G(n, nv);
    // the step's matrices, sized once: a bisection walks up to kGameLevelMaxSteps steps for each level it tries. Each
    // product below is one that Eigen evaluated nested inside a longer expression before, now evaluated into the
    // type of Eigen's own temporary for it (F R S is row-major, as that of F * (R * S) was): the same bits as before
    Mat R(n, n), Rt(n, n), A(n, n), B(n, n), HtH(n, n), S(n, n), RS(n, n), FRSFt(n, n), GGt(n, n);
    RowMat FRS(n, n);
    Eigen::LLT<Mat> chol(n), cond(n), z(n);
    Eigen::SelfAdjointEigenSolver<Mat> es(n);
    std::vector<double> x = c.x0, x_half;
    const std::int64_t steps = std::min(c.steps_until(), kGameLevelMaxSteps), half = steps / 2;
    // repeats > 0: then the walk's second half again that many times, from the state and the time at its middle, P
    // carried over (not its first half: a transient from x0 the run does not meet again)
    const std::int64_t total = steps + std::max(repeats, 0) * (steps - half);
    for (std::int64_t kk = 0; kk < total; ++kk) {
        const std::int64_t k = kk < steps ? kk : half + (kk - steps) % (steps - half);
        if (kk == half) x_half = x;
        else if (k == half) x = x_half;
        const double t = c.time_of(k), t_walk = c.time_of(kk);
        // a factor P = R R': Cholesky where P is positive definite; the symmetric square root where it is singular
        // (P(0) = 0, and G G' in general). Any factor gives the same conditions (R = P^1/2 U with U orthogonal: the
        // matrices below change by the congruence U) and the same P+ = R (I + w R'(H'H - Q/rho) R)^-1 R'
        chol.compute(P);
        if (chol.info() == Eigen::Success && chol.matrixLLT().diagonal().minCoeff() > 0) {  // L's diagonal
            R = chol.matrixL();
        } else {
            es.compute(0.5 * (P + P.transpose()));
            if (es.info() != Eigen::Success) return -1;
            R = es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() *
                es.eigenvectors().transpose();
        }
        // the existence condition at step k: no error direction whose weight Q/rho outgrows what P allows:
        // I - w R' (Q/rho) R > 0
        A.noalias() = w * R.transpose() * Qr;
        B = I;
        B.noalias() -= A * R;
        cond.compute(B);
        if (cond.info() != Eigen::Success) return t_walk;
        sys.measurement_jacobian(H.data(), x.data(), t);
        system_advance_jacobian(sys, F.data(), G.data(), x.data(), t, c.dt);
        if (!H.allFinite() || !F.allFinite() || !G.allFinite()) return -1;
        // Z = I + w R' (H'H - Q/rho) R > 0, then P+ = F R Z^-1 R' F' + G G' / w
        HtH.noalias() = H.transpose() * H;
        B = HtH - Qr;
        A.noalias() = w * R.transpose() * B;
        B = I;
        B.noalias() += A * R;
        z.compute(B);
        if (z.info() != Eigen::Success) return t_walk;
        Rt = R.transpose();
        S = z.solve(Rt);
        RS.noalias() = R * S;
        FRS.noalias() = F * RS;
        FRSFt.noalias() = FRS * F.transpose();
        GGt.noalias() = G * G.transpose();
        P = FRSFt + GGt / w;
        B = P + P.transpose();
        P = 0.5 * B;
        if (!P.allFinite()) return -1;
        system_advance(sys, x.data(), x.data(), nullptr, t, c.dt);
        for (double v : x)
            if (!std::isfinite(v)) return -1;
    }
    return -1;
}

double noise_free_escape_time(const ProblemConfig& c) {
    std::vector<double> x = c.x0;
    const std::int64_t steps = std::min(c.steps_until(), kGameLevelMaxSteps);
    for (std::int64_t k = 0; k < steps; ++k) {
        system_advance(*c.system, x.data(), x.data(), nullptr, c.time_of(k), c.dt);
        for (double v : x)
            if (!std::isfinite(v)) return c.time_of(k + 1);
    }
    return -1;
}

std::vector<int> constant_states(const ProblemConfig& c) {
    const int n = c.n, nv = c.nv;
    const System& sys = *c.system;
    std::vector<char> constant(static_cast<std::size_t>(n), 1);
    std::vector<double> F(static_cast<std::size_t>(n) * n), G(static_cast<std::size_t>(n) * nv), next(n);
    const std::int64_t steps = std::min(c.steps_until(), kConstantStateSteps);
    for (const std::vector<double>* start : {&c.x0, &c.xhat0}) {
        std::vector<double> x = *start;
        for (std::int64_t k = 0; k < steps; ++k) {
            const double t = c.time_of(k);
            system_advance_jacobian(sys, F.data(), G.data(), x.data(), t, c.dt);
            system_advance(sys, next.data(), x.data(), nullptr, t, c.dt);
            bool finite = true;
            for (int i = 0; i < n; ++i) finite = finite && std::isfinite(next[i]);
            if (!finite) break;  // the rest of this trajectory says nothing
            for (int i = 0; i < n; ++i) {
                if (!constant[i]) continue;
                bool held = next[i] == x[i];
                for (int j = 0; j < n && held; ++j) held = F[i * n + j] == (i == j ? 1.0 : 0.0);
                for (int j = 0; j < nv && held; ++j) held = G[i * nv + j] == 0.0;
                constant[i] = held;
            }
            x.swap(next);
        }
    }
    std::vector<int> out;
    for (int i = 0; i < n; ++i)
        if (constant[i]) out.push_back(i);
    return out;
}

double game_level_rho_star(const ProblemConfig& c) {
    if (c.rho_auto) return c.rho_bound;
    const GameLevel g = game_level_bound(c);
    return g.bracketed ? g.bound : 0.0;
}

GameLevel game_level_bound(const ProblemConfig& c, double rel_tol, int repeats, double from) {
    GameLevel r;
    auto holds = [&](double rho) { return game_level_lost_at(c, rho, repeats) < 0; };
    if (from > 0 && holds(from)) {  // a level known to hold on one walk is the lowest the repeated one can give
        r.bound = from;
        r.bracketed = true;
        return r;
    }
    // bracket by factors of 4 from 1 (or from `from`, where it fails), then bisect in log(rho)
    double lo = from > 0 ? from : 1.0, hi = lo;
    if (from <= 0 && holds(1.0)) {
        while (lo > 1e-12 && holds(lo / 4)) lo /= 4;
        if (lo <= 1e-12) return r;  // holds at every level: no bound found
        hi = lo;
        lo /= 4;
    } else {
        while (hi < 1e15 && !holds(hi * 4)) hi *= 4;
        if (hi >= 1e15) {
            r.bound = hi;
            return r;
        }
        lo = hi;
        hi *= 4;
    }
    while (hi / lo > 1 + rel_tol) {
        const double mid = std::sqrt(lo * hi);
        (holds(mid) ? hi : lo) = mid;
    }
    r.bound = hi;
    r.bracketed = true;
    return r;
}

GameLevel game_level_sustained(const ProblemConfig& c, double rho_star) {
    return game_level_bound(c, 0.01, kRunOnRepeats, rho_star);
}

double game_level_rho_run_on(const ProblemConfig& c, double rho_star) {
    const double star = rho_star > 0 ? rho_star : game_level_rho_star(c);
    if (!(star > 0)) return 0.0;
    const GameLevel g = game_level_sustained(c, star);
    return g.bracketed ? g.bound : 0.0;
}

}  // namespace hinf
