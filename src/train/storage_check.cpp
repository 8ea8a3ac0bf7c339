// The constant-storage check of a discrete-time `gain` filter (storage_check.hpp; docs/method.md section 16.8).
#include "train/storage_check.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <unordered_set>
#include <vector>

#include "lmi/sdp.hpp"

namespace hinf {

namespace {

using Eigen::MatrixXd;

struct Estimate {
    MatrixXd Z, F;  // ker H basis and the map's Jacobian, in the error scales
    std::int64_t run = 0, step = 0;
};

// lambda_max(Z'(F'SF - S + Q)Z) at one estimate (all in the error scales)
double violation(const Estimate& e, const MatrixXd& S, const MatrixXd& Q) {
    const MatrixXd M = e.Z.transpose() * (e.F.transpose() * S * e.F - S + Q) * e.Z;
    Eigen::SelfAdjointEigenSolver<MatrixXd> es(0.5 * (M + M.transpose()), Eigen::EigenvaluesOnly);
    return es.eigenvalues().maxCoeff();
}

// The estimates of the check: the pool's truth states, at most storage_check_estimates(n) spread evenly over its steps
// and runs, where the model's Jacobians are finite and ker H(x) is not empty; Qs = DQD in the error scales
std::vector<Estimate> storage_estimates(const RunConfig& cfg, const GainPool& pool, MatrixXd* Qs) {
    std::vector<Estimate> est;
    if (cfg.variant != "gain" || cfg.system == nullptr || !cfg.system->discrete_time() || pool.runs.empty() ||
        pool.steps <= 0)
        return est;
    const int n = cfg.n, m = cfg.m;
    // the error scales dx of section 16.4: errors of that size are unit vectors u, x~ = D u
    Eigen::VectorXd dx(n);
    for (int j = 0; j < n; ++j) {
        const double s = std::fabs(cfg.x0[j] - cfg.xhat0[j]) + (j < int(cfg.error_floor.size()) ? cfg.error_floor[j] : 0);
        dx[j] = s > 0 && std::isfinite(s) ? s : 1.0;
    }
    MatrixXd Q(n, n);
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) Q(a, b) = cfg.Q[std::size_t(a) * n + b];
    *Qs = dx.asDiagonal() * (0.5 * (Q + Q.transpose())) * dx.asDiagonal();
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const std::int64_t total = std::int64_t(pool.runs.size()) * pool.steps;
    const std::int64_t count = std::min(total, storage_check_estimates(n));
    std::vector<double> J(std::size_t(n) * n), Hj(std::size_t(m) * n);
    std::unordered_set<std::size_t> seen;  // a linear system's estimates are one: pose it once
    for (std::int64_t i = 0; i < count; ++i) {
        // step-major: consecutive picks take the runs in turn at one step, so a few picks still spread over time
        const std::int64_t runs = std::int64_t(pool.runs.size());
        const std::int64_t g = i * total / count, r = g % runs, k = g / runs;
        const double* x = pool.runs[std::size_t(r)].x.data() + k * n;
        const double t = cfg.time_of(k);
        cfg.system->drift_jacobian(J.data(), x, t);
        cfg.system->measurement_jacobian(Hj.data(), x, t);
        bool finite = true;
        for (double v : J) finite = finite && std::isfinite(v);
        for (double v : Hj) finite = finite && std::isfinite(v);
        if (!finite) continue;  // a state where the model is undefined says nothing about the storage
        const std::string bytes(reinterpret_cast<const char*>(J.data()), J.size() * sizeof(double));
        const std::string hbytes(reinterpret_cast<const char*>(Hj.data()), Hj.size() * sizeof(double));
        if (!seen.insert(std::hash<std::string>{}(bytes + hbytes)).second) continue;  // (a collision drops one: weaker, never wrong)
        const MatrixXd F = Eigen::Map<const RowMajor>(J.data(), n, n);
        const MatrixXd Hs = Eigen::Map<const RowMajor>(Hj.data(), m, n) * dx.asDiagonal();
        Eigen::JacobiSVD<MatrixXd> svd(Hs, Eigen::ComputeFullV);
        const Eigen::VectorXd sv = svd.singularValues();
        const double top = sv.size() > 0 ? sv[0] : 0.0;
        int rank = 0;
        for (int j = 0; j < sv.size(); ++j) rank += top > 0 && sv[j] > 1e-9 * top ? 1 : 0;
        if (rank == n) continue;
        Estimate e;
        e.Z = svd.matrixV().rightCols(n - rank);
        e.F = dx.cwiseInverse().asDiagonal() * F * dx.asDiagonal();
        e.run = r;
        e.step = k;
        est.push_back(std::move(e));
    }
    return est;
}

}  // namespace

std::int64_t storage_check_estimates(int n) {
    const double p = 0.5 * n * (n + 1);  // SDPA's work grows as p^2 times the blocks' entries (at most n^2 each)
    const double fit = 5e8 / (p * p * double(n) * double(n));
    return std::clamp<std::int64_t>(std::int64_t(fit), 16, kStorageCheckEstimates);
}

double constant_storage_violation(const RunConfig& cfg, const GainPool& pool, const Eigen::MatrixXd& S) {
    MatrixXd Qs;
    double worst = -INFINITY;
    for (const Estimate& e : storage_estimates(cfg, pool, &Qs)) worst = std::max(worst, violation(e, S, Qs));
    return worst;
}

StorageCheck constant_storage_check(const RunConfig& cfg, const GainPool& pool) {
    StorageCheck c;
    MatrixXd Qs;
    const std::vector<Estimate> est = storage_estimates(cfg, pool, &Qs);
    const int n = cfg.n;
    for (const Estimate& e : est) {
        c.kernel_dim = std::max(c.kernel_dim, int(e.Z.cols()));
        c.q_scale = std::max(c.q_scale, violation(e, MatrixXd::Zero(n, n), Qs));  // S = 0: the Q term alone
    }
    c.estimates = std::int64_t(est.size());
    if (est.empty()) return c;  // every output Jacobian sees every error: nothing to check
    c.ran = true;
    if (!(c.q_scale > 0)) {  // Q vanishes on every unseen error: S = 0 keeps the inequality there
        c.solved = true;
        c.S = MatrixXd::Zero(n, n);
        return c;
    }
    // the SDP in units of the Q term (the problem is homogeneous in (S, mu, Q)): a system whose Q term is 1e5 or
    // 1e-5 in the error scales poses the same numbers to SDPA
    const MatrixXd Qn = Qs / c.q_scale;

    // minimise mu over (S, mu): mu I - Z'(F'SF - S + Q)Z >= 0 at every estimate, S >= 0, mu >= -1 (Q = Qn)
    const int p = n * (n + 1) / 2, nvar = p + 1;
    std::vector<std::pair<int, int>> entry;
    for (int a = 0; a < n; ++a)
        for (int b = a; b < n; ++b) entry.emplace_back(a, b);
    auto unit = [&](int v) {
        MatrixXd E = MatrixXd::Zero(n, n);
        E(entry[v].first, entry[v].second) = 1;
        E(entry[v].second, entry[v].first) = 1;
        return E;
    };
    lmi::SdpProblem prob;
    prob.num_vars = nvar;
    prob.cost.assign(nvar, 0.0);
    prob.cost[p] = 1.0;
    for (const Estimate& e : est) {
        lmi::SdpBlock b;
        b.name = "ker H";
        const int d = int(e.Z.cols());
        b.constant = -e.Z.transpose() * Qn * e.Z;
        for (int v = 0; v < p; ++v) {
            const MatrixXd E = unit(v);
            MatrixXd T = -e.Z.transpose() * (e.F.transpose() * E * e.F - E) * e.Z;
            T = 0.5 * (T + T.transpose());
            if (T.cwiseAbs().maxCoeff() > 0) b.terms.emplace_back(v, T);
        }
        b.terms.emplace_back(p, MatrixXd::Identity(d, d));
        prob.blocks.push_back(std::move(b));
    }
    lmi::SdpBlock psd;
    psd.name = "S >= 0";
    psd.constant = MatrixXd::Zero(n, n);
    for (int v = 0; v < p; ++v) psd.terms.emplace_back(v, unit(v));
    prob.blocks.push_back(std::move(psd));
    lmi::SdpBlock floor;
    floor.name = "mu >= -1";
    floor.constant = MatrixXd::Ones(1, 1);
    floor.terms.emplace_back(p, MatrixXd::Ones(1, 1));
    prob.blocks.push_back(std::move(floor));

    const lmi::SdpResult r = lmi::sdp_solve(prob);
    c.solver_phase = r.solver_phase;
    // the returned S, checked by eigenvalues: its largest violation over the estimates is what it achieves
    MatrixXd S = MatrixXd::Zero(n, n);
    for (int v = 0; v < p; ++v) S += r.x[std::size_t(v)] * unit(v);
    Eigen::SelfAdjointEigenSolver<MatrixXd> ps(S, Eigen::EigenvaluesOnly);
    const bool psd_ok = ps.eigenvalues().minCoeff() >= -1e-7 * std::max(1.0, ps.eigenvalues().cwiseAbs().maxCoeff());
    double worst = -INFINITY;
    for (const Estimate& e : est) {
        const double w = violation(e, S, Qn);
        if (w > worst) {
            worst = w;
            c.worst_run = e.run;
            c.worst_step = e.step;
        }
    }
    c.solved = r.status == lmi::SDP_STATUS_OPTIMAL && psd_ok && std::isfinite(worst);
    c.mu = std::max(worst, -1.0) * c.q_scale;
    c.S = S * c.q_scale;
    // the claim that no S does better rests on a lower bound (weak duality): the smaller of SDPA's two objectives
    c.mu_lower = std::max(std::min(r.primal_objective, r.dual_objective), -1.0) * c.q_scale;
    return c;
}

std::string constant_storage_note(const RunConfig& cfg, const StorageCheck& c) {
    if (!c.infeasible()) return "";
    char buf[1400];
    std::snprintf(buf, sizeof buf,
                  "hinf: note: %s: no constant storage V = x~'Sx~ keeps the one-step inequality for the errors the "
                  "outputs do not see within a step (up to %d directions, at %lld estimates along training's runs): "
                  "every S leaves a violation of at least %.3g against the Q term's %.3g there, at any level rho and "
                  "with any gain (the best S found: %.3g, worst at run %lld, step %lld). Training cannot satisfy its "
                  "inequality here, so the DNN filter it gives has no certificate of its level and may settle far "
                  "behind the EKF (on two such systems 4.8x and more): compare them before use (docs/method.md "
                  "section 16.8, \"Errors the outputs do not see\")\n",
                  cfg.doc.source().c_str(), c.kernel_dim, static_cast<long long>(c.estimates), c.mu_lower, c.q_scale,
                  c.mu, static_cast<long long>(c.worst_run), static_cast<long long>(c.worst_step));
    return buf;
}

}  // namespace hinf
