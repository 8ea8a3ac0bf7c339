// Network creation (shapes, scales, initialisation) and the frozen-network wrapper.
#include "net/network.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Dense>

#include "gain.hpp"
#include "hinf/error.hpp"
#include "random.hpp"

namespace hinf {

double gain_discrete_rho_floor(const RunConfig& cfg) {
    const int n = cfg.n, nv = cfg.nv;
    std::vector<double> B(static_cast<std::size_t>(n) * nv);
    cfg.system->disturbance_gain(B.data(), cfg.x0.data(), 0.0, 1);
    Eigen::MatrixXd BQB = Eigen::MatrixXd::Zero(nv, nv);
    for (int j = 0; j < nv; ++j)
        for (int l = 0; l < nv; ++l)
            for (int a = 0; a < n; ++a)
                for (int c = 0; c < n; ++c) BQB(j, l) += B[a * nv + j] * cfg.Q[a * n + c] * B[c * nv + l];
    return nv > 0 ? Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(BQB).eigenvalues().maxCoeff() : 0.0;
}

std::vector<double> gain_component_mask(const RunConfig& cfg, std::vector<int>* component,
                                        const std::vector<double>* mean_given, const std::vector<double>* sd_given) {
    const int n = cfg.n, m = cfg.m, nv = cfg.nv;
    const System& sys = *cfg.system;
    std::vector<int> parent(static_cast<std::size_t>(n + m));
    for (int i = 0; i < n + m; ++i) parent[i] = i;
    auto find = [&](int i) {
        while (parent[i] != i) i = parent[i] = parent[parent[i]];
        return i;
    };
    auto join = [&](int a, int b) { parent[find(a)] = find(b); };
    // the points: x0 and x^0 at t = 0, and 16 points of the estimates' region (the noise-free trajectory's mean
    // and spread widened by the error scale, as the network's input standardisation) at times across the horizon
    std::vector<double> mean, sd;
    if (mean_given != nullptr && sd_given != nullptr) {
        mean = *mean_given;
        sd = *sd_given;
    } else {
        nominal_moments(cfg, &mean, &sd);
    }
    std::vector<std::vector<double>> points = {cfg.x0, cfg.xhat0};
    std::vector<double> times = {0.0, 0.0};
    std::uint64_t h = 0x9e3779b97f4a7c15ULL;
    auto uniform = [&h]() {  // splitmix64 to [-1, 1): the same points on every machine
        std::uint64_t z = (h += 0x9e3779b97f4a7c15ULL);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        z ^= z >> 31;
        return double(z >> 11) / double(1ULL << 52) - 1.0;
    };
    for (int k = 0; k < 16; ++k) {
        std::vector<double> x(n);
        for (int a = 0; a < n; ++a) {
            const double scale = std::fabs(cfg.x0[a] - cfg.xhat0[a]) + cfg.error_floor[a];
            const double mu = std::isfinite(mean[a]) ? mean[a] : cfg.x0[a];
            const double spread = (std::isfinite(sd[a]) ? sd[a] : 0.0) + scale;
            x[a] = mu + spread * uniform();
        }
        points.push_back(x);
        times.push_back(cfg.t_final * (k + 0.5) / 16.0);
    }
    std::vector<double> J(static_cast<std::size_t>(n) * n), B(static_cast<std::size_t>(n) * nv),
        H(static_cast<std::size_t>(m) * n);
    for (std::size_t p = 0; p < points.size(); ++p) {
        const double* x = points[p].data();
        sys.drift_jacobian(J.data(), x, times[p]);
        sys.disturbance_gain(B.data(), x, times[p], 1);
        sys.measurement_jacobian(H.data(), x, times[p]);
        for (int l = 0; l < n; ++l)
            for (int k = 0; k < n; ++k)
                if (k != l && J[l * n + k] != 0.0) join(k, l);  // NaN counts as non-zero
        for (int s = 0; s < nv; ++s) {
            int first = -1;
            for (int l = 0; l < n; ++l)
                if (B[l * nv + s] != 0.0) {
                    if (first >= 0) join(first, l);
                    first = l;
                }
        }
        for (int j = 0; j < m; ++j)
            for (int k = 0; k < n; ++k)
                if (H[j * n + k] != 0.0) join(n + j, k);
    }
    for (int k = 0; k < n; ++k)
        for (int l = 0; l < n; ++l)
            if (k != l && cfg.Q[k * n + l] != 0.0) join(k, l);
    std::vector<double> mask(static_cast<std::size_t>(n) * m);
    for (int a = 0; a < n; ++a)
        for (int j = 0; j < m; ++j) mask[a * m + j] = find(a) == find(n + j) ? 1.0 : 0.0;
    if (component != nullptr) {
        component->assign(static_cast<std::size_t>(n + m), 0);
        std::vector<int> number(static_cast<std::size_t>(n + m), -1);
        int next = 0;
        for (int i = 0; i < n + m; ++i) {
            const int r = find(i);
            if (number[r] < 0) number[r] = next++;
            (*component)[i] = number[r];
        }
    }
    return mask;
}

namespace {

// network.angle_inputs = "periodic" (docs/method.md section 16.19): 1 for each state of [system] angle_states [n];
// empty where none is an angle or the inputs are "raw"
std::vector<int> angle_input_flags(const RunConfig& cfg) {
    const std::vector<int>& angles = cfg.system->angle_states();
    if (cfg.angle_inputs != "periodic" || angles.empty()) return {};
    std::vector<int> flags(static_cast<std::size_t>(cfg.n), 0);
    for (int a : angles) flags[static_cast<std::size_t>(a)] = 1;
    return flags;
}

// The gain variant's fixed scales (docs/method.md section 14.4), all from the config: the error scale
// dx_j = |x0_j - x^0_j| + error_floor_j, the innovation scale dy = |H(x^0) diag(dx)| row norms, the input
// standardisation from the noise-free trajectory from x0 over [0, t_final], the gain rate 10 / t_final and the
// storage scale mean_j(Q_jj dx_j^2) t_final / 10.
kern::GainSpec gain_spec(const RunConfig& cfg) {
    const int n = cfg.n, m = cfg.m;
    const System& sys = *cfg.system;
    kern::GainSpec g;
    g.enabled = true;
    g.m = m;
    g.periodic = angle_input_flags(cfg);
    g.group = int(cfg.errors_per_estimate);
    g.dx.resize(n);
    g.xt0.resize(n);
    for (int j = 0; j < n; ++j) {
        g.xt0[j] = cfg.x0[j] - cfg.xhat0[j];
        g.dx[j] = std::fabs(g.xt0[j]) + cfg.error_floor[j];
        if (!(g.dx[j] > 0)) g.dx[j] = 1.0;
    }
    std::vector<double> H(static_cast<std::size_t>(m) * n), c0(m), c1(m);
    sys.measurement_jacobian(H.data(), cfg.xhat0.data(), 0.0);
    sys.measurement(c0.data(), cfg.x0.data(), 0.0, 1);
    sys.measurement(c1.data(), cfg.xhat0.data(), 0.0, 1);
    g.dy.resize(m);
    for (int j = 0; j < m; ++j) {
        double s = 0;
        for (int a = 0; a < n; ++a) s += std::pow(H[j * n + a] * g.dx[a], 2);
        g.dy[j] = std::sqrt(s);
        if (!(g.dy[j] > 0)) {
            std::vector<double> d(m);
            sys.output_difference(d.data(), c0.data(), c1.data());
            g.dy[j] = std::fabs(d[j]);
        }
        if (!(g.dy[j] > 0) || !std::isfinite(g.dy[j])) g.dy[j] = 1.0;
    }
    // the noise-free trajectory: where the estimates will be
    std::vector<double> sd;
    nominal_moments(cfg, &g.shift, &sd);
    const std::vector<double> mean = g.shift;  // before the escape check below changes it
    g.spread.resize(n);
    for (int j = 0; j < n; ++j) {
        g.spread[j] = sd[j] + g.dx[j];
        if (!std::isfinite(g.shift[j]) || !std::isfinite(g.spread[j])) {  // a trajectory that escapes: no shift
            g.shift[j] = 0.0;
            g.spread[j] = g.dx[j];
        }
    }
    const double T = cfg.t_final;
    // a discrete system (docs/method.md section 16.8): K is per step (rate 1: K H ~ I corrects a whole error in one
    // step) and S starts at s Q with s = sqrt(rho / floor), the geometric middle between the one-step floor S >= Q
    // and the concavity ceiling B'S B < rho (floor = lambda_max(B'Q B))
    const bool discrete = sys.discrete_time();
    g.rate = cfg.output_scale > 0 ? cfg.output_scale : discrete ? 1.0 : 10.0 / T;
    double qd = 0;
    for (int j = 0; j < n; ++j) qd += cfg.Q[j * n + j] * g.dx[j] * g.dx[j];
    const double floor = discrete ? gain_discrete_rho_floor(cfg) : 0.0;
    const double s_mid = floor > 0 && cfg.rho > floor ? std::sqrt(cfg.rho / floor) : 2.0;
    g.storage_scale = qd > 0 ? qd / n * (discrete ? s_mid : T / 10.0) : 1.0;
    if (cfg.storage_knots > 0) {  // section 16.7: S(t) on knots; the scale makes the initial head's gain ~ rate
        g.knots = static_cast<int>(cfg.storage_knots);
        g.knot_span = T;
        g.knot_ratio = cfg.knot_ratio;
        double dy2 = 0;
        for (int j = 0; j < m; ++j) dy2 += g.dy[j] * g.dy[j] / m;
        g.storage_scale = cfg.rho * dy2 / g.rate;
        // "output" (section 16.7, Scales): per state, S's initial diagonal is (rho / rate) (H0'H0)_jj, H0 = H(x^0), so
        // that the initial gain K = rho S^-1 H' gives K H ~ rate on every measured state; a state no output sees
        // gets the measured states' mean of (H0'H0)_jj dx_j^2 in its own scale. One scalar c alone ("mean", the
        // first S(t)) starts state j at rate dx_j^2 / mean(dy^2): 4e-4 1/s for the missile's velocities. Where the
        // two agree (one output: Van der Pol, Lorenz-63 with x measured) the error scale is kept as it is.
        if (cfg.storage_scaling == "output") {
            std::vector<double> hh(n, 0.0);
            for (int j = 0; j < m; ++j)
                for (int a = 0; a < n; ++a) hh[a] += H[j * n + a] * H[j * n + a];
            double seen = 0;
            int count = 0;
            for (int a = 0; a < n; ++a)
                if (hh[a] > 0 && std::isfinite(hh[a])) {
                    seen += hh[a] * g.dx[a] * g.dx[a];
                    ++count;
                }
            if (count > 0) {
                seen /= count;
                g.sdx = g.dx;
                g.corr.assign(static_cast<std::size_t>(n) * m, 0.0);
                bool differs = false;
                for (int a = 0; a < n; ++a) {
                    // a state whose output share is a vanishing part of the others' (a Jacobian that is zero but
                    // for rounding at x^0, say) counts as unseen: K H ~ rate would need a gain of 1/H there
                    const bool sees = hh[a] > 0 && std::isfinite(hh[a]) && hh[a] * g.dx[a] * g.dx[a] >= 1e-9 * seen;
                    const double target = sees ? hh[a] : seen / (g.dx[a] * g.dx[a]);
                    const double sd = std::sqrt(g.storage_scale * g.rate / (cfg.rho * target));
                    if (std::isfinite(sd) && sd > 0 && std::fabs(sd - g.dx[a]) > 1e-9 * g.dx[a]) g.sdx[a] = sd;
                    // the correction: rho S(0)^-1 (o .* w) = rate dx_a o_aj / dy_j, the constant head's gain scale
                    // (S(0) = (rho / rate) diag(target)), so w_aj = target_a dx_a / dy_j (= dy_j / dx_a with one output)
                    for (int j = 0; j < m; ++j) {
                        const double w = target * g.dx[a] / g.dy[j], w0 = g.dy[j] / g.dx[a];
                        if (std::isfinite(w) && std::fabs(w - w0) > 1e-9 * std::fabs(w0)) {
                            g.corr[a * m + j] = w;
                            differs = true;
                        } else {
                            g.corr[a * m + j] = w0;
                        }
                    }
                }
                if (!differs) g.corr.clear();  // one output: the first S(t)'s head, its arithmetic and bits
            }
        }
    }
    // the Kalman-form head (section 16.16): P(x^) starts at D^2 (1 + eps), so that K H ~ F / 2 on a measured state
    // (dy_j^2 = sum_a (H_ja dx_a)^2: H P H' = diag(dy)^2 for one output)
    g.kalman = discrete && cfg.gain_head == "kalman";
    // the structural zeros (section 16.17); a mask of ones is no mask (the same arithmetic and bits as before it)
    if (cfg.gain_structure == "components" && !g.kalman) {
        std::vector<int> comp;
        g.mask = gain_component_mask(cfg, &comp, &mean, &sd);
        if (std::all_of(g.mask.begin(), g.mask.end(), [](double v) { return v != 0.0; })) g.mask.clear();
        for (int a = 0; a < n; ++a)  // the storage's entries (a, b <= a), tril's packing
            for (int b = 0; b <= a; ++b) g.smask.push_back(comp[a] == comp[b] ? 1.0 : 0.0);
        if (std::all_of(g.smask.begin(), g.smask.end(), [](double v) { return v != 0.0; })) g.smask.clear();
    }
    g.eps = cfg.eps > 0 ? cfg.eps : 1e-3;
    g.h2_weight = cfg.h2_weight;
    g.loss.rho = cfg.rho;
    g.loss.margin = cfg.margin;
    g.loss.disturbance_intensity = cfg.disturbance_intensity;
    g.loss.noise_intensity = cfg.noise_intensity;
    g.loss.horizon = cfg.resolved_horizon() / (discrete ? cfg.dt : 1.0);  // in steps for a discrete system
    g.loss.initial_weight = cfg.initial_weight;
    g.loss.dt = discrete ? 0.0 : cfg.dt;  // the sampled-data cap: continuous time only
    g.loss.discrete = discrete;
    g.loss.kappa = cfg.max_step_correction;
    g.loss.cap_in_storage = cfg.step_cap == "storage";
    // h2 at S = c D^-2, o = all ones: x~0'S x~0 / T + sv2 tr(B'S B) + sn2 rate^2 c n sum_j dy_j^-2
    std::vector<double> B(static_cast<std::size_t>(n) * cfg.nv);
    sys.disturbance_gain(B.data(), cfg.x0.data(), 0.0, 1);
    double ref = 0, bsb = 0, ky = 0;
    for (int j = 0; j < n; ++j) ref += g.loss.initial_weight * std::pow(g.xt0[j] / g.dx[j], 2) / g.loss.horizon;
    for (std::size_t e = 0; e < B.size(); ++e) bsb += std::pow(B[e] / g.dx[e / cfg.nv], 2);
    for (int j = 0; j < m; ++j) ky += 1.0 / (g.dy[j] * g.dy[j]);
    ref += g.loss.disturbance_intensity * bsb + g.loss.noise_intensity * g.rate * g.rate * n * ky;
    g.loss.h2_reference = g.storage_scale * (ref > 0 && std::isfinite(ref) ? ref : 1.0);
    return g;
}

}  // namespace

kern::StepConfig network_step_config(const RunConfig& cfg) {
    kern::StepConfig sc;
    const bool paper = cfg.variant == "paper", gain = cfg.variant == "gain";
    sc.head.kind = paper ? kern::HEAD_GRADIENT : kern::HEAD_QUADRATIC;
    sc.head.n = cfg.n;
    sc.input_scale = cfg.resolved_input_scale();
    // gradient head: p = c s_in o, so o ~ z = x~/s_in when dV/dx~ ~ c x~; quadratic head: P = c (M M^T + eps I)
    sc.head.scale = paper ? cfg.resolved_output_scale() * sc.input_scale : cfg.resolved_output_scale();
    sc.head.eps = cfg.resolved_eps();
    int inputs = cfg.n;  // a gain network sees each angle state as (cos, sin): one entry more each
    for (int f : gain ? angle_input_flags(cfg) : std::vector<int>{}) inputs += f;
    sc.shape.sizes.push_back(inputs);
    for (int h : cfg.hidden) sc.shape.sizes.push_back(h);
    const bool kalman = gain && cfg.gain_head == "kalman";  // P(x^): n(n+1)/2 outputs (section 16.16)
    sc.shape.sizes.push_back(kalman ? cfg.n * (cfg.n + 1) / 2
                             : gain ? cfg.n * cfg.m
                                    : kern::head_outputs(sc.head.kind, cfg.n));
    sc.shape.slope_positive = cfg.slope_positive;
    sc.shape.slope_negative = cfg.slope_negative;
    // the GEMM kernels sum in different orders: the choice is part of the run (and of its checkpoint's config)
    sc.shape.gemm = cfg.gemm == "own"        ? kern::GEMM_OWN
                    : cfg.gemm == "openblas" ? kern::GEMM_OPENBLAS
                    : cfg.gemm == "eigen"    ? kern::GEMM_EIGEN
                                             : kern::default_gemm_path();
    sc.objective = paper ? kern::HJIE_OBJECTIVE_PAPER : kern::HJIE_OBJECTIVE_DISSIPATIVE;
    sc.hjie.rho = cfg.rho;
    sc.hjie.game = cfg.type == "h2hinf" ? kern::HJIE_GAME_MIXED : kern::HJIE_GAME_HINF;
    sc.hjie.margin = cfg.margin;
    sc.hjie.h2_weight = cfg.h2_weight;
    sc.hjie.disturbance_intensity = cfg.disturbance_intensity;
    sc.hjie.noise_intensity = cfg.noise_intensity;
    // H2 rates in units of rho * s_in^2 (the size of the HJIE's measurement term at a typical error)
    sc.hjie.h2_reference = cfg.rho * sc.input_scale * sc.input_scale;
    sc.hjie.horizon = cfg.resolved_horizon();
    sc.chunk = cfg.chunk;
    if (gain) {
        sc.gain = gain_spec(cfg);
        sc.input_scale = 1.0;  // the gain network sees z = (x^ - shift) / spread (sc.gain)
    }
    return sc;
}

template <typename T>
Network<T> network_shell(const RunConfig& cfg) {
    Network<T> net;
    net.step = network_step_config(cfg);
    // theta = [MLP parameters | storage parameters (gain variant: M = I + tril(s), all zero: S = c (1 + eps) D^-2)]
    net.theta.assign(static_cast<std::size_t>(net.step.shape.param_count() + net.step.gain.storage_params(cfg.n)), T(0));
    return net;
}

namespace {
// network.storage_init = "riccati" (docs/method.md section 16.7, "Initial knots"): the knots of S(t) on the game's
// Riccati solution for the system linearised along the noise-free trajectory from x0, i.e. (16.7.1) with equality
// and o = 0, integrated in its sampled information form from the flat S(0):
//   P = rho S^-1,  P+ = (P^-1 + dt (H'H - Q / rho))^-1,  P <- F P+ F' + G G' / dt
// (F, G the Jacobians of the Euler step, H of the output). Where P^-1 + dt (H'H - Q / rho) falls below a floor in S's
// scale (S^ = Ds S Ds / c; the start is (1 + eps) I, where K H ~ rate) -- on its way to losing positive definiteness
// when the -Q/rho term outweighs what the outputs bring (no H-infinity filter of level rho from this start) -- its
// eigenvalues are held at that floor, and a knot's S^ likewise: max(2 eps, rate dt / kappa), so the held gain's step,
// about rate dt / S^, stays within the sampled-data cap kappa (objective.max_step_correction).
struct RiccatiStart {
    double held = -1;     // first time the floor held the information (negative: never)
    int held_knot = 0;    // the first knot made after the floor held (0: never held)
    double floor = 0;     // the floor, in S's scale (the flat start is 1 + eps there)
    double stopped = -1;  // time the recursion stopped (a non-finite trajectory or Jacobian, a singular step): the
                          // later knots keep the last knot's values (negative: it ran to the end)
    // the same recursion without the floor, along the same trajectory: the first time its information lost positive
    // definiteness (no H-infinity filter of level rho from this start for the linearisation), negative where it kept
    // it as far as the walk went; followed = false where it stopped without a verdict (a singular step)
    double lost = -1;
    bool followed = true;
};

// Why a Riccati start was held at its floor, for the notes below: the unfloored equation's verdict, and which term
// of the floor max(2 eps, rate dt / kappa) held it where that verdict is "still definite"
std::string riccati_held_why(const RiccatiStart& r, const kern::GainSpec& g, double rho) {
    char buf[320];
    if (r.lost >= 0)
        std::snprintf(buf, sizeof buf, "without the floor its information loses positive definiteness at t = %.4g s: "
                      "no H-infinity filter of level rho = %g from this start for the linearised system", r.lost, rho);
    else if (r.followed && r.stopped < 0 && r.floor > 2.0 * g.eps)
        std::snprintf(buf, sizeof buf, "without the floor it stays positive definite to the end of the run: the floor "
                      "is the sampled-data cap on the gain's step (objective.max_step_correction), not a lost level "
                      "rho = %g", rho);
    else if (r.followed && r.stopped < 0)
        std::snprintf(buf, sizeof buf, "without the floor it stays positive definite to the end of the run, below the "
                      "least the storage's form holds (2 network.eps in its scale): not a lost level rho = %g", rho);
    else
        std::snprintf(buf, sizeof buf, "no H-infinity filter of level rho = %g from this start for the linearised "
                      "system, or none whose gain stays within the sampled-data cap", rho);
    return buf;
}
template <typename T>
RiccatiStart riccati_knots(T* knots, const RunConfig& cfg, const kern::GainSpec& g) {
    using Mat = Eigen::MatrixXd;
    using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const int n = cfg.n, m = cfg.m, nv = cfg.nv, np = n * (n + 1) / 2, J = g.knots;
    const System& sys = *cfg.system;
    const double rho = cfg.rho, dt = cfg.dt, c = g.storage_scale;
    const Eigen::VectorXd ds = Eigen::Map<const Eigen::VectorXd>(g.storage_dx(), n);
    const Mat Q = Eigen::Map<const RowMat>(cfg.Q.data(), n, n);
    RiccatiStart r;
    double& held = r.held;
    int next = 1;  // knot 0 is the flat S(0)
    const double lo = std::max(2.0 * g.eps, g.loss.dt > 0 ? g.rate * g.loss.dt / g.loss.kappa : 0.0);
    r.floor = lo;
    // X (an information matrix, S / rho) with the eigenvalues of its scaled form (rho / c) Ds X Ds held >= lo
    // (X itself where they already are: the same bits)
    auto hold = [&](const Mat& X, double t) -> Mat {
        const Mat D = ds.asDiagonal(), Di = ds.cwiseInverse().asDiagonal();
        const Mat Xs = 0.5 * (X + X.transpose());
        Eigen::SelfAdjointEigenSolver<Mat> es((rho / c) * D * Xs * D);
        if (es.info() != Eigen::Success || es.eigenvalues().minCoeff() >= lo) return X;
        if (held < 0) {
            held = t;
            r.held_knot = next;
        }
        const Eigen::VectorXd l = es.eigenvalues().cwiseMax(lo);
        return (c / rho) * Di * (es.eigenvectors() * l.asDiagonal() * es.eigenvectors().transpose()) * Di;
    };
    Mat P = Mat::Zero(n, n);
    for (int a = 0; a < n; ++a) P(a, a) = rho * ds[a] * ds[a] / (c * (1.0 + g.eps));
    Mat Pu = P;  // the unfloored recursion (RiccatiStart::lost)
    const std::int64_t steps = cfg.steps_until();
    std::vector<double> x = cfg.x0;
    RowMat H(m, n), F(n, n), G(n, nv);
    for (std::int64_t k = 0; k < steps && next <= J && r.stopped < 0; ++k) {
        const double t = cfg.time_of(k);
        sys.measurement_jacobian(H.data(), x.data(), t);
        system_advance_jacobian(sys, F.data(), G.data(), x.data(), t, dt);
        if (r.lost < 0 && r.followed) {
            Eigen::LLT<Mat> lu(Pu);
            const Mat Yu = lu.info() == Eigen::Success
                               ? Mat(lu.solve(Mat::Identity(n, n)) + dt * (Mat(H.transpose() * H) - Q / rho))
                               : Mat();
            Eigen::SelfAdjointEigenSolver<Mat> eu;
            if (lu.info() == Eigen::Success && Yu.allFinite()) eu.compute(0.5 * (Yu + Yu.transpose()));
            if (lu.info() != Eigen::Success || !Yu.allFinite() || eu.info() != Eigen::Success) r.followed = false;
            else if (eu.eigenvalues().minCoeff() <= 0) r.lost = t;
            else Pu = F * Yu.llt().solve(Mat::Identity(n, n)) * F.transpose() + G * G.transpose() / dt;
            Pu = 0.5 * (Pu + Pu.transpose()).eval();
        }
        Eigen::LLT<Mat> lp(P);
        if (lp.info() != Eigen::Success) {
            r.stopped = t;
            break;
        }
        const Mat Y = hold(lp.solve(Mat::Identity(n, n)) + dt * (Mat(H.transpose() * H) - Q / rho), t);
        Eigen::LLT<Mat> ly(Y);
        if (ly.info() != Eigen::Success || !Y.allFinite()) {
            r.stopped = t;
            break;
        }
        P = F * ly.solve(Mat::Identity(n, n)) * F.transpose() + G * G.transpose() / dt;
        P = 0.5 * (P + P.transpose()).eval();
        system_advance(sys, x.data(), x.data(), nullptr, t, dt);
        if (!P.allFinite()) {
            r.stopped = t;
            break;
        }
        // knot `next` at t_j (j T / J evenly): S = rho P^-1 there, M = chol(Ds S Ds / c - eps I)
        while (next <= J && cfg.time_of(k + 1) >= g.knot_time(next) - 0.5 * dt) {
            Eigen::LLT<Mat> lk(P);
            if (lk.info() != Eigen::Success) {
                r.stopped = t;
                break;
            }
            const Mat S = rho * hold(lk.solve(Mat::Identity(n, n)), t);
            Mat A(n, n);
            for (int a = 0; a < n; ++a)
                for (int b = 0; b < n; ++b) A(a, b) = ds[a] * S(a, b) * ds[b] / c - (a == b ? g.eps : 0.0);
            Eigen::LLT<Mat> lm(A);
            const Mat L = lm.matrixL();
            bool finite = lm.info() == Eigen::Success;
            for (int a = 0; a < n && finite; ++a) finite = std::isfinite(std::log(L(a, a))) && L.row(a).allFinite();
            if (!finite) {
                r.stopped = t;
                break;
            }
            int e = 0;
            for (int a = 0; a < n; ++a)
                for (int b = 0; b <= a; ++b, ++e) knots[std::int64_t(next) * np + e] = T(a == b ? std::log(L(a, a)) : L(a, b));
            ++next;
        }
    }
    // knots after the last step (a horizon beyond t_final) or after a stop: the last knot's values
    for (; next <= J; ++next)
        for (int e = 0; e < np; ++e) knots[std::int64_t(next) * np + e] = knots[std::int64_t(next - 1) * np + e];
    return r;
}

// the rule of network_create below: held before the first knot, with the flat start not itself below the floor
bool held_at_once(const RiccatiStart& r, const kern::GainSpec& g) {
    return r.held >= 0 && r.held_knot <= 1 && 1.0 + g.eps > r.floor;
}

// The Riccati start's walk for a config that has one (a gain run with knots and storage_init = "riccati"): its
// RiccatiStart, and `at_once` as network_create's rule reads it; false where the config has no such start
bool riccati_start_walk(const RunConfig& cfg, RiccatiStart* r, bool* at_once) {
    if (!(cfg.variant == "gain" && cfg.storage_knots > 0 && cfg.storage_init == "riccati")) return false;
    const kern::StepConfig step = network_step_config(cfg);
    if (!step.gain.enabled || step.gain.knots <= 0) return false;
    std::vector<double> knots(static_cast<std::size_t>(step.gain.storage_params(cfg.n)), 0.0);
    *r = riccati_knots(knots.data(), cfg, step.gain);
    *at_once = held_at_once(*r, step.gain);
    return true;
}

}  // namespace

bool riccati_start_held_at_once(const RunConfig& cfg) {
    RiccatiStart r;
    bool at_once = false;
    return riccati_start_walk(cfg, &r, &at_once) && at_once;
}

double riccati_start_held_later(const RunConfig& cfg) {
    RiccatiStart r;
    bool at_once = false;
    return riccati_start_walk(cfg, &r, &at_once) && r.held >= 0 && !at_once ? r.held : -1.0;
}

double riccati_start_lost(const RunConfig& cfg) {
    RiccatiStart r;
    bool at_once = false;
    if (!riccati_start_walk(cfg, &r, &at_once)) return NAN;
    return r.lost >= 0 ? r.lost : r.followed && r.stopped < 0 ? -1.0 : NAN;
}

template <typename T>
Network<T> network_create(const RunConfig& cfg) {
    Network<T> net = network_shell<T>(cfg);
    const kern::MlpShape& sh = net.step.shape;
    for (int l = 1; l <= sh.layers(); ++l) {
        const int din = sh.sizes[l - 1], dout = sh.sizes[l];
        const std::int64_t cnt = std::int64_t(din) * dout;
        std::vector<double> u(static_cast<std::size_t>(cnt));
        kern::rng_uniform(u.data(), cnt, cfg.seed, kern::RNG_STREAM_INIT, static_cast<std::uint64_t>(l), 0);
        const double a2 = sh.slope_negative / sh.slope_positive;
        double bound = std::sqrt(6.0 / ((1.0 + a2 * a2) * din)) / sh.slope_positive;
        if (l == sh.layers()) bound *= 0.1;
        T* W = net.theta.data() + sh.weight_offset(l);
        for (std::int64_t i = 0; i < cnt; ++i) W[i] = T(bound * (2.0 * u[i] - 1.0));
        // biases start at zero
    }
    const kern::GainSpec& g = net.step.gain;
    if (g.enabled && !g.mask.empty()) {
        std::vector<int> comp;
        gain_component_mask(cfg, &comp);
        std::fprintf(stderr,
                     "hinf: note: network.gain_structure = \"components\": the system splits into %d independent "
                     "parts, so the gain takes each state's correction only from the outputs of its own part (%d of "
                     "%d entries) and the storage is block-diagonal; \"full\" learns every entry (docs/method.md "
                     "section 16.17)\n",
                     *std::max_element(comp.begin(), comp.end()) + 1,
                     int(std::count(g.mask.begin(), g.mask.end(), 1.0)), int(g.mask.size()));
    }
    if (g.enabled && g.knots > 0 && cfg.storage_init == "riccati") {
        T* knots = net.theta.data() + sh.param_count();
        const RiccatiStart r = riccati_knots(knots, cfg, g);
        g.hold_storage(knots, cfg.n);  // zero already for a block-diagonal Riccati solution; held there (16.17)
        // held before its first knot: every knot after S(0) sits at the floor, where the gain is at the sampled-data
        // cap, and none carries the game's solution (there is none of level rho from this start, or none within the
        // cap). Such a start was far worse than the flat one (a stiff spring chain, continuous Lorenz-63 with x
        // measured: docs/method.md section 16.7); start flat -- unless the flat start is itself below the floor (a
        // short run's large rate: its gain beyond the cap; the held knots are then the safer start)
        if (held_at_once(r, g)) {
            std::fill(knots, knots + g.storage_params(cfg.n), T(0));
            std::fprintf(stderr,
                         "hinf: note: network.storage_init = \"riccati\": the game's Riccati equation falls to the "
                         "storage's floor from t = %.4g s, before its first knot (t = %.4g s; %s). The knots start "
                         "flat instead; %snetwork.storage_knots = 0 (a constant storage) may do better on this system "
                         "(docs/method.md section 16.7)\n",
                         r.held, g.knot_time(1), riccati_held_why(r, g, cfg.rho).c_str(),
                         r.lost >= 0 ? "a larger rho, or " : "");
            return net;
        }
        if (r.stopped >= 0)
            std::fprintf(stderr,
                         "hinf: note: network.storage_init = \"riccati\": the game's Riccati equation stopped at "
                         "t = %.4g s (a non-finite noise-free trajectory or Jacobian, or a singular step); the later "
                         "knots start at the last one\n",
                         r.stopped);
        if (r.held >= 0)
            std::fprintf(stderr,
                         "hinf: note: network.storage_init = \"riccati\": from t = %.4g s the game's Riccati equation "
                         "falls to the storage's floor (%s); it is held there. Where the filter does poorly, compare "
                         "network.storage_init = \"flat\" and network.storage_knots = 0 (a constant storage) "
                         "(docs/method.md section 16.7)\n",
                         r.held, riccati_held_why(r, g, cfg.rho).c_str());
    }
    return net;
}

void BoxExcursion::see(const kern::GainSpec& g, const double* x, std::int64_t count, int n, double t0, double dt) {
    if (g.zlo.empty()) return;
    for (int i = 0; i < n && i < int(g.zlo.size()); ++i) {
        if (g.is_periodic(i)) continue;  // seen as (cos, sin): a turn on is inside the region
        const double a = g.shift[i] + g.spread[i] * g.zlo[i], b = g.shift[i] + g.spread[i] * g.zhi[i];
        const double w = b - a;
        if (!(w > 0)) continue;
        for (std::int64_t k = 0; k < count; ++k) {
            const double v = x[k * n + i];
            const double past = !std::isfinite(v) ? INFINITY : std::max(v - b, a - v) / w;
            if (past > 1 && std::isfinite(t0) && !(t0 + double(k) * dt >= first_t)) {  // earliest; a tie keeps the first state
                first_t = t0 + double(k) * dt;
                first_state = i;
            }
            if (past > widths) {
                widths = past;
                state = i;
                value = v;
                lo = a;
                hi = b;
            }
        }
    }
}

std::string BoxExcursion::text(const std::vector<std::string>& names) const {
    if (state < 0) return "";
    const std::string name = std::size_t(state) < names.size() ? names[std::size_t(state)] : std::to_string(state + 1);
    char buf[256];
    if (std::isfinite(value))
        std::snprintf(buf, sizeof buf, "%s reached %.4g where training's estimates spanned [%.4g, %.4g]", name.c_str(),
                      value, lo, hi);
    else
        std::snprintf(buf, sizeof buf, "%s ran away where training's estimates spanned [%.4g, %.4g]", name.c_str(), lo,
                      hi);
    std::string out = buf;
    if (std::isfinite(first_t) && first_state >= 0) {
        const std::string fname =
            std::size_t(first_state) < names.size() ? names[std::size_t(first_state)] : std::to_string(first_state + 1);
        std::snprintf(buf, sizeof buf, ", first more than a width beyond at t = %.4g (%s)", first_t, fname.c_str());
        out += buf;
    }
    return out;
}

std::string BoxExcursion::filter_note(const std::vector<std::string>& names) const {
    const std::string where = text(names);
    if (where.empty()) return "";
    return "its estimate went far beyond the region its network was trained on (" + where +
           "): more than the region's width beyond it, where its gain is the one at the region's edge "
           "(docs/method.md section 16.10)";
}

void FrozenNetwork::gain(double*, double*, double*, const double*, double, const System&, std::int64_t) {
    HINF_FAIL("this network is not of variant \"gain\": it has no gain K(x^) (train with [filter] variant = \"gain\")");
}

double FrozenNetwork::value(const double* xt, int n) {
    // 16-point Gauss-Legendre on [0, 1]: V(x~) = int_0^1 p(s x~)^T x~ ds
    static const double node[8] = {0.0950125098376374, 0.2816035507792589, 0.4580167776572274, 0.6178762444026438,
                                   0.7554044083550030, 0.8656312023878318, 0.9445750230732326, 0.9894009349916499};
    static const double weight[8] = {0.1894506104550685, 0.1826034150449236, 0.1691565193950025, 0.1495959888165767,
                                     0.1246289712555339, 0.0951585116824928, 0.0622535239386479, 0.0271524594117541};
    std::vector<double> pts(static_cast<std::size_t>(16 * n)), p(static_cast<std::size_t>(16 * n));
    double w16[16];
    for (int k = 0; k < 8; ++k) {
        double s1 = 0.5 * (1 - node[k]), s2 = 0.5 * (1 + node[k]);
        for (int j = 0; j < n; ++j) {
            pts[(2 * k) * n + j] = s1 * xt[j];
            pts[(2 * k + 1) * n + j] = s2 * xt[j];
        }
        w16[2 * k] = w16[2 * k + 1] = 0.5 * weight[k];
    }
    gradient(p.data(), pts.data(), 16);
    double v = 0;
    for (int k = 0; k < 16; ++k)
        for (int j = 0; j < n; ++j) v += w16[k] * p[k * n + j] * xt[j];
    return v;
}

namespace {
template <typename T>
class FrozenImpl : public FrozenNetwork {
public:
    explicit FrozenImpl(Network<T> net) : net_(std::move(net)) {}
    void gradient(double* p, const double* xt, std::int64_t count) override {
        kern::network_eval(p, nullptr, net_.theta.data(), xt, count, net_.step, ws_, packed());
    }
    void gain(double* K, double* S, double* Sdot, const double* xhat, double t, const System& sys,
              std::int64_t count) override {
        const int n = net_.step.head.n;
        const kern::GainSpec& g = net_.step.gain;
        const std::int64_t c = std::max<std::int64_t>(count, 0);
        const int D0 = g.input_count(n);
        z_.resize(static_cast<std::size_t>(c * D0));
        for (std::int64_t i = 0; i < count; ++i) g.input_row(z_.data() + i * D0, xhat + i * n, n, true);
        if (g.knots > 0 || g.kalman) {  // the Riccati- and Kalman-form heads: the output Jacobian at each estimate
            hx_.resize(static_cast<std::size_t>(c * g.m * n));
            tt_.assign(static_cast<std::size_t>(c), t);
            for (std::int64_t i = 0; i < count; ++i) sys.measurement_jacobian(hx_.data() + i * g.m * n, xhat + i * n, t);
        }
        if (g.kalman) {  // and the map's
            fx_.resize(static_cast<std::size_t>(c * n * n));
            for (std::int64_t i = 0; i < count; ++i) sys.drift_jacobian(fx_.data() + i * n * n, xhat + i * n, t);
        }
        kern::gain_network_eval(K, net_.theta.data(), z_.data(), hx_.data(), tt_.data(), count, net_.step, ws_,
                                fx_.data(), nullptr, packed());
        kern::gain_storage_eval(S, Sdot, net_.theta.data(), t, net_.step);
    }
    const kern::StepConfig& step_config() const override { return net_.step; }
    std::unique_ptr<FrozenNetwork> clone() const override { return std::make_unique<FrozenImpl<T>>(net_); }

private:
    // the weights never change: packed for the own GEMM kernels once, not at every evaluation (a filter evaluates
    // one estimate a step, where packing both directions' panels cost more than the forward pass itself)
    const T* packed() { return pack_.get(net_.theta.data(), net_.step.shape); }
    Network<T> net_;
    kern::StepWorkspace<T> ws_;
    std::vector<double> z_, hx_, tt_, fx_;
    kern::PackedWeights<T> pack_;
};
}  // namespace

template <typename T>
std::unique_ptr<FrozenNetwork> network_freeze(Network<T> net) {
    return std::make_unique<FrozenImpl<T>>(std::move(net));
}

template <typename T>
StorageLow storage_lowest_log_diagonal(const Network<T>& net) {
    StorageLow low;
    const kern::GainSpec& g = net.step.gain;
    if (!g.enabled || g.knots <= 0) return low;
    const int n = net.step.head.n, np = n * (n + 1) / 2;
    const T* sp = net.theta.data() + net.step.shape.param_count();
    for (int j = 0; j <= g.knots; ++j)
        for (int a = 0; a < n; ++a) {
            const double v = double(sp[std::int64_t(j) * np + a * (a + 1) / 2 + a]);  // packed tril, row by row
            if (low.knot < 0 || v < low.value) low = StorageLow{v, j, a};
        }
    return low;
}

double storage_runaway_level(const kern::GainSpec& g) { return 0.5 * std::log(g.eps) - 3.0; }

template StorageLow storage_lowest_log_diagonal<float>(const Network<float>&);
template StorageLow storage_lowest_log_diagonal<double>(const Network<double>&);
template Network<float> network_create<float>(const RunConfig&);
template Network<float> network_shell<float>(const RunConfig&);
template Network<double> network_shell<double>(const RunConfig&);
template Network<double> network_create<double>(const RunConfig&);
template std::unique_ptr<FrozenNetwork> network_freeze<float>(Network<float>);
template std::unique_ptr<FrozenNetwork> network_freeze<double>(Network<double>);

}  // namespace hinf
