// Global-linearization filter: the vertex LMIs of glf.hpp assembled for lmi::sdp_solve (SDPA), and the
// filter that runs the designed gain. The LMI is affine in (P, Y, rho): each block is read at x = 0 and
// at the unit vectors, as src/lmi/delay_lmi.cpp does.
#include "filters/glf.hpp"

#include "filters/gain_law.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "hinf/error.hpp"
#include "lmi/sdp.hpp"

namespace hinf {

namespace {

using Mat = Eigen::MatrixXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Vertex {
    Mat A, B, C;
};

// decision vector: P (upper triangle, row by row), Y [n x m] row-major, rho
struct GlfVars {
    Mat P, Y;
    double rho = 0;
};

int glf_num_vars(int n, int m) { return n * (n + 1) / 2 + n * m + 1; }

GlfVars glf_unpack(const std::vector<double>& x, int n, int m) {
    GlfVars v;
    v.P = Mat::Zero(n, n);
    v.Y = Mat::Zero(n, m);
    int k = 0;
    for (int i = 0; i < n; ++i)
        for (int j = i; j < n; ++j) v.P(i, j) = v.P(j, i) = x[k++];
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) v.Y(i, j) = x[k++];
    v.rho = x[k];
    return v;
}

// the vertex block of glf.hpp at (P, Y, rho), with Q scaled to Qs
Mat glf_block(const Vertex& vx, const GlfVars& v, const Mat& Qs, double dt) {
    const int n = static_cast<int>(v.P.rows()), nv = static_cast<int>(vx.B.cols()), m = static_cast<int>(v.Y.cols());
    const int sz = 2 * n + nv + m;
    Mat M = Mat::Zero(sz, sz);
    Mat PPhi = v.P + dt * v.P * vx.A - dt * v.Y * vx.C;
    Mat PGam(n, nv + m);
    PGam << dt * v.P * vx.B, -dt * v.Y;
    M.topLeftCorner(n, n) = v.P - dt * Qs;
    M.block(n, n, nv + m, nv + m) = dt * v.rho * Mat::Identity(nv + m, nv + m);
    M.block(n + nv + m, 0, n, n) = PPhi;
    M.block(0, n + nv + m, n, n) = PPhi.transpose();
    M.block(n + nv + m, n, n, nv + m) = PGam;
    M.block(n, n + nv + m, nv + m, n) = PGam.transpose();
    M.bottomRightCorner(n, n) = v.P;
    return M;
}

class GlobalLinearizationFilter final : public OnlineFilter {
public:
    GlobalLinearizationFilter(const FilterModel& model, const GlfDesign& d) : model_(model), gain_(d.gain) {}
    std::string name() const override { return "glf"; }
    void reset(const FilterStart& start) override { xhat_ = start.xhat0; }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), m = sys.output_dim();
        std::vector<double> a(n), c(m), e(m), next(n);
        sys.drift(a.data(), xhat_.data(), in.t, 1);
        sys.measurement(c.data(), xhat_.data(), in.t, 1);
        if (in.y != nullptr) sys.output_difference(e.data(), in.y, c.data());  // missing: e = 0, no correction
        luenberger_advance(next.data(), xhat_.data(), a.data(), gain_.data(), e.data(), n, m, model_.dt);
        if (!filter_estimate_ok(next.data(), n)) return FILTER_DIVERGED;
        xf_.resize(n);
        luenberger_correct(xf_.data(), xhat_.data(), gain_.data(), e.data(), n, m, model_.dt);
        xhat_ = next;
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    const double* filtered() const override { return xf_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<GlobalLinearizationFilter>(*this); }

private:
    FilterModel model_;
    std::vector<double> gain_, xhat_, xf_;
};

}  // namespace

GlfDesign glf_design(const ProblemConfig& problem, int vertices, double rho_max) {
    const System& sys = *problem.system;
    const std::vector<double>&x0 = problem.x0, &Q = problem.Q;
    const double dt = problem.dt;
    const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
    HINF_CHECK(vertices >= 1, "glf: the vertex count must be >= 1");
    // seed 001's design linearizes the vector field A(x) and discretizes by Euler: continuous time only
    HINF_CHECK(!sys.discrete_time(), "--filters glf: the GLF design is for continuous-time systems (an Euler-sampled "
                                     "LMI on dA/dx) and the config's system has [system] time = \"discrete\" (drop glf)");
    HINF_CHECK(static_cast<int>(x0.size()) == n && static_cast<int>(Q.size()) == n * n, "glf: x0 / Q have the wrong size");
    GlfDesign d;
    d.vertices = vertices;
    // vertices along the noise-free Euler trajectory from x0
    const std::int64_t steps = std::max<std::int64_t>(1, problem.steps_until());
    std::vector<std::int64_t> at(vertices);
    for (int i = 0; i < vertices; ++i)
        at[i] = vertices == 1 ? 0 : std::min<std::int64_t>(steps - 1, std::llround(double(i) * double(steps - 1) / (vertices - 1)));
    std::vector<Vertex> vx;
    std::vector<double> x = x0;
    for (std::int64_t s = 0, next = 0; s < steps && next < vertices; ++s) {
        const double t = problem.time_of(s);
        while (next < vertices && at[next] == s) {
            RowMat J(n, n), B(n, nv), H(m, n);
            sys.drift_jacobian(J.data(), x.data(), t);
            sys.disturbance_gain(B.data(), x.data(), t, 1);
            sys.measurement_jacobian(H.data(), x.data(), t);
            vx.push_back(Vertex{J, B, H});
            d.vertex_times.push_back(t);
            ++next;
        }
        system_advance(sys, x.data(), x.data(), nullptr, t, dt);
    }
    // The LMIs are homogeneous in (P, Y, rho, Q): solve with Q / max|Q| (so the margin means the same for
    // any scale of Q) and scale rho back.
    Mat Qm = Eigen::Map<const RowMat>(Q.data(), n, n);
    const double qs = std::max(Qm.cwiseAbs().maxCoeff(), 1e-300);
    Mat Qs = Qm / qs;
    const int nvar = glf_num_vars(n, m);
    const double margin = 1e-7;
    lmi::SdpProblem prob;
    prob.num_vars = nvar;
    prob.cost.assign(nvar, 0.0);
    if (rho_max > 0) {
        // minimise trace P subject to rho <= rho_max
        int k = 0;
        for (int i = 0; i < n; ++i)
            for (int j = i; j < n; ++j) prob.cost[k++] = (i == j ? 1.0 : 0.0);
    } else {
        prob.cost[nvar - 1] = 1.0;  // minimise rho
    }
    std::vector<double> z(nvar, 0.0);
    auto blocks_at = [&](const std::vector<double>& xv) {
        GlfVars v = glf_unpack(xv, n, m);
        std::vector<Mat> out;
        for (const Vertex& w : vx) out.push_back(glf_block(w, v, Qs, dt));
        out.push_back(v.P);  // P > 0
        return out;
    };
    const std::vector<Mat> b0 = blocks_at(z);
    prob.blocks.resize(b0.size());
    for (std::size_t b = 0; b < b0.size(); ++b) {
        prob.blocks[b].name = b + 1 < b0.size() ? "vertex " + std::to_string(b + 1) : "P > 0";
        prob.blocks[b].constant = b0[b] - margin * Mat::Identity(b0[b].rows(), b0[b].cols());
    }
    if (rho_max > 0) {
        lmi::SdpBlock cap;  // rho_max / max|Q| - rho >= 0
        cap.name = "rho <= rho_max";
        cap.constant = Mat::Constant(1, 1, rho_max / qs);
        cap.terms.emplace_back(nvar - 1, Mat::Constant(1, 1, -1.0));
        prob.blocks.push_back(cap);
    }
    for (int k = 0; k < nvar; ++k) {
        z[k] = 1.0;
        const std::vector<Mat> bk = blocks_at(z);
        for (std::size_t b = 0; b < bk.size(); ++b) {
            Mat F = bk[b] - b0[b];
            if (F.cwiseAbs().maxCoeff() > 0) prob.blocks[b].terms.emplace_back(k, F);
        }
        z[k] = 0.0;
    }
    lmi::SdpOptions opt;
    opt.max_iterations = 400;
    lmi::SdpResult res = lmi::sdp_solve(prob, opt);
    d.status = std::string(lmi::sdp_status_name(res.status)) + " (SDPA " + res.solver_phase + ", " +
               std::to_string(res.iterations) + " iterations)";
    if (res.status != lmi::SDP_STATUS_OPTIMAL && res.status != lmi::SDP_STATUS_NOT_CONVERGED) return d;
    // accept the point only if every block really is positive definite (checked here, not taken from the solver)
    bool pd = true;
    for (const auto& blk : prob.blocks) {
        Eigen::SelfAdjointEigenSolver<Mat> es(lmi::sdp_block_value(blk, res.x), Eigen::EigenvaluesOnly);
        pd = pd && es.eigenvalues().minCoeff() >= -1e-9;
    }
    if (!pd) {
        d.status += "; the returned point violates an LMI";
        return d;
    }
    GlfVars v = glf_unpack(res.x, n, m);
    RowMat L = v.P.ldlt().solve(v.Y);
    d.gain.assign(L.data(), L.data() + n * m);
    d.rho = v.rho * qs;
    d.ok = true;
    return d;
}

std::unique_ptr<OnlineFilter> make_glf_filter(const FilterModel& model, const GlfDesign& design) {
    HINF_CHECK(design.ok, "glf: no gain to run (the LMI design failed: " + design.status + ")");
    return std::make_unique<GlobalLinearizationFilter>(model, design);
}

}  // namespace hinf
