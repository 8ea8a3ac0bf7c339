// Assembly of seed 002's LMIs (34)/(45) over all vertex triples (i, j, k), their theorem forms (27)/(38)
// and (32)/(42) for checking the Schur-complement derivation, and the solve + independent verification.
// Not the solver (sdp_sdpa.cpp) and not the filter simulation (delay_sim.cpp).
#include "lmi/delay_lmi.hpp"

#include <chrono>
#include <cmath>

#include "hinf/error.hpp"

namespace hinf::lmi {

using Eigen::MatrixXd;

namespace {

struct Dims {
    int n = 0, l = 0, nv = 0, ns = 0, m = 0;
};

Dims dims_of(const DelayLmiSpec& spec) {
    Dims d;
    d.m = static_cast<int>(spec.vertices.size());
    d.n = static_cast<int>(spec.vertices[0].A0.rows());
    d.l = static_cast<int>(spec.vertices[0].Q0.rows());
    d.nv = static_cast<int>(spec.vertices[0].B.cols());
    d.ns = static_cast<int>(spec.G.rows());
    return d;
}

// The bounding constant sigma = (e1^2 + e3^2)/2 + (e2^2 + e4^2) of Remark 5.
double sigma_of(const DelayLmiSpec& s) { return 0.5 * (s.e1 * s.e1 + s.e3 * s.e3) + (s.e2 * s.e2 + s.e4 * s.e4); }

// Coefficients of the Schur blocks: (34) has -gamma^2/2 I and -gamma^2/alpha I; (45) has -gamma^2/4 I and
// -gamma^2/(2 alpha) I. Returns the positive numbers c_B, c_L (the block is -c I).
void schur_coefficients(const DelayLmiSpec& s, double gamma2, double* cB, double* cL) {
    if (s.design == DELAY_DESIGN_HINF) {
        *cB = gamma2 / 2.0;
        *cL = s.alpha > 0 ? gamma2 / s.alpha : 0.0;
    } else {
        *cB = gamma2 / 4.0;
        *cL = s.alpha > 0 ? gamma2 / (2.0 * s.alpha) : 0.0;
    }
}

// (beta_j + beta_k) sigma on the diagonal of the xi block (x then x-hat, 2n x 2n).
MatrixXd sigma_block(const DelayLmiSpec& s, int n, double betas) {
    MatrixXd S = MatrixXd::Zero(2 * n, 2 * n);
    const double v = betas * sigma_of(s);
    for (int a = 0; a < n; ++a) S(a, a) = v;
    if (s.sigma_placement == DELAY_SIGMA_THEOREM)
        for (int a = n; a < 2 * n; ++a) S(a, a) = v;
    return S;
}

MatrixXd gbar_of(const DelayLmiSpec& s) {
    const int n = static_cast<int>(s.G.cols());
    MatrixXd Gb(s.G.rows(), 2 * n);
    Gb << s.G, -s.G;
    return Gb;
}

// Puts the upper-triangular block `b` at (r, c) and its transpose at (c, r).
void put_sym(MatrixXd& M, int r, int c, const MatrixXd& b) {
    M.block(r, c, b.rows(), b.cols()) = b;
    if (r != c) M.block(c, r, b.cols(), b.rows()) = b.transpose();
}

MatrixXd sym_of(const MatrixXd& a) { return 0.5 * (a + a.transpose()); }

}  // namespace

void delay_lmi_check_spec(const DelayLmiSpec& s) {
    HINF_CHECK(!s.vertices.empty(), "LMI design needs at least one vertex (give [[vertex]] tables or operating points)");
    const auto& v0 = s.vertices[0];
    const auto n = v0.A0.rows(), l = v0.Q0.rows(), nv = v0.B.cols();
    HINF_CHECK(n > 0 && l > 0 && nv > 0, "vertex 1: A0, Q0 and B must be non-empty");
    for (std::size_t i = 0; i < s.vertices.size(); ++i) {
        const auto& v = s.vertices[i];
        const std::string w = "vertex " + std::to_string(i + 1) + ": ";
        auto chk = [&](const MatrixXd& M, long r, long c, const char* name) {
            HINF_CHECK(M.rows() == r && M.cols() == c, w + name + " is " + std::to_string(M.rows()) + "x" +
                                                           std::to_string(M.cols()) + ", expected " +
                                                           std::to_string(r) + "x" + std::to_string(c));
            HINF_CHECK(M.allFinite(), w + name + " has a non-finite entry");
        };
        chk(v.A0, n, n, "A0");
        chk(v.A1, n, n, "A1");
        chk(v.C0, n, n, "C0");
        chk(v.C1, n, n, "C1");
        chk(v.B, n, nv, "B");
        chk(v.Q0, l, n, "Q0");
        chk(v.Q1, l, n, "Q1");
        chk(v.J0, l, n, "J0");
        chk(v.J1, l, n, "J1");
        chk(v.K, l, nv, "K");
    }
    HINF_CHECK(s.G.cols() == n && s.G.rows() > 0, "G must have as many columns as there are states");
    HINF_CHECK(s.tau2 > 0 && s.tau_bar < 1, "need tau2 > 0 and tau_bar < 1 (eq. 2)");
    HINF_CHECK(s.alpha >= 0 && s.e1 >= 0 && s.e2 >= 0 && s.e3 >= 0 && s.e4 >= 0, "bounding constants must be >= 0");
    HINF_CHECK(s.margin > 0, "LMI margin must be > 0");
    if (s.design == DELAY_DESIGN_H2HINF) {
        HINF_CHECK(s.gamma2 > 0, "mixed H2/Hinf design needs gamma^2 > 0");
        HINF_CHECK(s.M.rows() == 2 * n && s.NNt.rows() == 2 * n && s.LLt.rows() == 2 * n,
                   "mixed design needs 2n x 2n weights M, NN', LL'");
    }
}

MatrixXd delay_lmi_full_P(const DelayLmiPoint& p, DelayPStructure structure) {
    const auto n = p.P1.rows();
    const double sg = structure == DELAY_P_PAPER ? 1.0 : -1.0;
    MatrixXd P(2 * n, 2 * n);
    P << p.P1, sg * p.P2, sg * p.P2, p.P2;  // (33), or the error-coordinate sign (choice C4)
    return P;
}
MatrixXd delay_lmi_full_Q(const DelayLmiPoint& p) {
    const auto n = p.Q1.rows();
    MatrixXd Q(2 * n, 2 * n);
    Q << p.Q1, p.Q2, p.Q2.transpose(), p.Q3;  // (33) with Q2' below the diagonal (choice C2)
    return Q;
}
MatrixXd delay_lmi_full_R(const DelayLmiPoint& p) {
    const auto n = p.R1.rows();
    MatrixXd R(2 * n, 2 * n);
    R << p.R1, p.R2, p.R2.transpose(), p.R3;
    return R;
}

std::vector<MatrixXd> delay_lmi_gains(const DelayLmiPoint& p) {
    std::vector<MatrixXd> L;
    Eigen::FullPivLU<MatrixXd> lu(p.P2);
    for (const auto& Y : p.Y) L.push_back(lu.solve(Y));  // Y_j = P2 L_j (Remark 5)
    return L;
}

MatrixXd delay_lmi_pi2(const DelayLmiSpec& s, const DelayLmiPoint& p, int i, int j, int k) {
    const Dims d = dims_of(s);
    const int n = d.n, l = d.l, nv = d.nv;
    const auto &vi = s.vertices[i], &vj = s.vertices[j], &vk = s.vertices[k];
    const MatrixXd& Yj = p.Y[j];
    const MatrixXd& Yk = p.Y[k];
    double cB, cL;
    schur_coefficients(s, s.design == DELAY_DESIGN_HINF ? p.gamma2 : s.gamma2, &cB, &cL);
    const bool with_L = s.alpha > 0;
    const int oxt = 2 * n, oint = 4 * n, oD = 6 * n, oB = 8 * n, oLj = 8 * n + nv, oLk = oLj + n + l;
    const int size = with_L ? oLk + n + l : oB + nv;
    MatrixXd M = MatrixXd::Zero(size, size);

    // P Abar_0ijk and P Abar_1ijk with P = [P1 sg P2; sg P2 P2], P2 L_j = Y_j (Gamma_11..Gamma_24 of (34), sg = +1)
    const double sg = s.p_structure == DELAY_P_PAPER ? 1.0 : -1.0;
    MatrixXd PA0(2 * n, 2 * n), PA1(2 * n, 2 * n);
    PA0 << p.P1 * vi.A0 + sg * Yj * vi.Q0, sg * (p.P2 * vj.A0 - Yj * vk.Q0), sg * p.P2 * vi.A0 + Yj * vi.Q0,
        p.P2 * vj.A0 - Yj * vk.Q0;
    PA1 << p.P1 * vi.A1 + sg * Yj * vi.Q1, sg * (p.P2 * vj.A1 - Yj * vk.Q1), sg * p.P2 * vi.A1 + Yj * vi.Q1,
        p.P2 * vj.A1 - Yj * vk.Q1;
    const MatrixXd P = delay_lmi_full_P(p, s.p_structure), Q = delay_lmi_full_Q(p), R = delay_lmi_full_R(p);
    const MatrixXd Gb = gbar_of(s);
    const double betas = p.beta[j] + p.beta[k];
    const double t22 = s.tau2 * s.tau2;

    // (1,1): Pi_ijk's xi and xi_t rows (Gamma_11 ... Gamma_44)
    put_sym(M, 0, 0, PA0 + PA0.transpose() + Gb.transpose() * Gb + P + Q + t22 * R + sigma_block(s, n, betas));
    put_sym(M, 0, oxt, PA1);
    put_sym(M, oxt, oxt, -(1.0 - s.tau_bar) * Q + sigma_block(s, n, betas));
    // Jensen block of the integral term: -tau2^2 R
    put_sym(M, oint, oint, -t22 * R);
    // D~_ij' P (Gamma_17, 18, 37, 38): Dbar_0ij' P = [C0i' P1 + sg J0i' Yj', sg C0i' P2 + J0i' Yj'; 0 0]
    MatrixXd D0P = MatrixXd::Zero(2 * n, 2 * n), D1P = MatrixXd::Zero(2 * n, 2 * n);
    D0P.topRows(n) << vi.C0.transpose() * p.P1 + sg * vi.J0.transpose() * Yj.transpose(),
        sg * vi.C0.transpose() * p.P2 + vi.J0.transpose() * Yj.transpose();
    D1P.topRows(n) << vi.C1.transpose() * p.P1 + sg * vi.J1.transpose() * Yj.transpose(),
        sg * vi.C1.transpose() * p.P2 + vi.J1.transpose() * Yj.transpose();
    put_sym(M, 0, oD, D0P);
    put_sym(M, oxt, oD, D1P);
    put_sym(M, oD, oD, -0.5 * P);
    // P~ Bbar_ij (Gamma_19, Gamma_29)
    MatrixXd PB(2 * n, nv);
    PB << p.P1 * vi.B + sg * Yj * vi.K, sg * p.P2 * vi.B + Yj * vi.K;
    put_sym(M, 0, oB, PB);
    put_sym(M, oB, oB, -cB * MatrixXd::Identity(nv, nv));
    if (with_L) {
        // P~ Lbar_j = [P1 sg Y_j; sg P2 Y_j], P~ Lbar_k likewise
        MatrixXd PLj(2 * n, n + l), PLk(2 * n, n + l);
        PLj << p.P1, sg * Yj, sg * p.P2, Yj;
        PLk << p.P1, sg * Yk, sg * p.P2, Yk;
        put_sym(M, 0, oLj, PLj);
        put_sym(M, 0, oLk, PLk);
        put_sym(M, oLj, oLj, -cL * MatrixXd::Identity(n + l, n + l));
        put_sym(M, oLk, oLk, -cL * MatrixXd::Identity(n + l, n + l));
    }
    return M;
}

MatrixXd delay_lmi_theta(const DelayLmiSpec& s, const DelayLmiPoint& p, int j) {
    const Dims d = dims_of(s);
    const int n = d.n, l = d.l;
    MatrixXd T = MatrixXd::Zero(3 * n + l, 3 * n + l);
    const double sg = s.p_structure == DELAY_P_PAPER ? 1.0 : -1.0;
    MatrixXd LtP(n + l, 2 * n);  // Lbar_j' P = [P1 sg P2; sg Y_j' Y_j']
    LtP << p.P1, sg * p.P2, sg * p.Y[j].transpose(), p.Y[j].transpose();
    put_sym(T, 0, 0, -p.beta[j] * MatrixXd::Identity(n + l, n + l));
    put_sym(T, 0, n + l, LtP);
    put_sym(T, n + l, n + l, -delay_lmi_full_P(p, s.p_structure));
    return T;
}

std::vector<LmiBlockValue> delay_lmi_blocks(const DelayLmiSpec& s, const DelayLmiPoint& p) {
    const Dims d = dims_of(s);
    std::vector<LmiBlockValue> out;
    for (int i = 0; i < d.m; ++i)
        for (int j = 0; j < d.m; ++j)
            for (int k = 0; k < d.m; ++k)
                out.push_back({"Pi2[" + std::to_string(i + 1) + "," + std::to_string(j + 1) + "," +
                                   std::to_string(k + 1) + "]",
                               delay_lmi_pi2(s, p, i, j, k)});
    for (int j = 0; j < d.m; ++j) out.push_back({"Theta[" + std::to_string(j + 1) + "]", delay_lmi_theta(s, p, j)});
    out.push_back({"-P", -delay_lmi_full_P(p, s.p_structure)});
    out.push_back({"-Q", -delay_lmi_full_Q(p)});
    out.push_back({"-R", -delay_lmi_full_R(p)});
    for (int j = 0; j < d.m; ++j)
        out.push_back({"-beta[" + std::to_string(j + 1) + "]", MatrixXd::Constant(1, 1, -p.beta[j])});
    return out;
}

namespace {

struct TheoremParts {
    MatrixXd Pi;     // Pi_ijk, 6n x 6n
    MatrixXd DtP;    // D~_ij' P, 6n x 2n
    MatrixXd PB;     // P~ Bbar_ij, 6n x nv
    MatrixXd PLj;    // P~ Lbar_j, 6n x (n + l)
    MatrixXd PLk;
};

// Pi_ijk and the off-diagonal columns of (27) with a general P and gains L (no structure (33)).
TheoremParts theorem_parts(const DelayLmiSpec& s, const MatrixXd& P, const MatrixXd& Q, const MatrixXd& R,
                           const std::vector<MatrixXd>& L, const std::vector<double>& beta, int i, int j, int k) {
    const Dims d = dims_of(s);
    const int n = d.n, l = d.l;
    const auto &vi = s.vertices[i], &vj = s.vertices[j], &vk = s.vertices[k];
    const MatrixXd Z = MatrixXd::Zero(n, n);
    // (23): Abar_0ijk, Abar_1ijk, Bbar_ij, Dbar_0ij, Dbar_1ij
    MatrixXd A0(2 * n, 2 * n), A1(2 * n, 2 * n), B(2 * n, d.nv), D0(2 * n, 2 * n), D1(2 * n, 2 * n);
    A0 << vi.A0, Z, L[j] * vi.Q0, vj.A0 - L[j] * vk.Q0;
    A1 << vi.A1, Z, L[j] * vi.Q1, vj.A1 - L[j] * vk.Q1;
    B << vi.B, L[j] * vi.K;
    D0 << vi.C0, Z, L[j] * vi.J0, Z;
    D1 << vi.C1, Z, L[j] * vi.J1, Z;
    const MatrixXd Gb = gbar_of(s);
    const double t22 = s.tau2 * s.tau2;
    const double betas = beta[j] + beta[k];
    TheoremParts t;
    t.Pi = MatrixXd::Zero(6 * n, 6 * n);
    put_sym(t.Pi, 0, 0, P * A0 + A0.transpose() * P + Gb.transpose() * Gb + P + Q + t22 * R + sigma_block(s, n, betas));
    put_sym(t.Pi, 0, 2 * n, P * A1);
    put_sym(t.Pi, 2 * n, 2 * n, -(1.0 - s.tau_bar) * Q + sigma_block(s, n, betas));
    put_sym(t.Pi, 4 * n, 4 * n, -t22 * R);
    MatrixXd Dt(2 * n, 6 * n);  // D~_ij = [Dbar_0 Dbar_1 0]
    Dt << D0, D1, MatrixXd::Zero(2 * n, 2 * n);
    t.DtP = Dt.transpose() * P;
    MatrixXd Pt = MatrixXd::Zero(6 * n, 2 * n);  // P~ = [P 0 0]'
    Pt.topRows(2 * n) = P;
    t.PB = Pt * B;
    MatrixXd Lj = MatrixXd::Zero(2 * n, n + l), Lk = MatrixXd::Zero(2 * n, n + l);  // Lbar = diag{I, L}
    Lj.topLeftCorner(n, n).setIdentity();
    Lj.bottomRightCorner(n, l) = L[j];
    Lk.topLeftCorner(n, n).setIdentity();
    Lk.bottomRightCorner(n, l) = L[k];
    t.PLj = Pt * Lj;
    t.PLk = Pt * Lk;
    return t;
}

}  // namespace

MatrixXd delay_lmi_pi1(const DelayLmiSpec& s, const MatrixXd& P, const MatrixXd& Q, const MatrixXd& R,
                       const std::vector<MatrixXd>& L, const std::vector<double>& beta, double gamma2, int i, int j,
                       int k) {
    const Dims d = dims_of(s);
    const int n = d.n, l = d.l, nv = d.nv;
    const TheoremParts t = theorem_parts(s, P, Q, R, L, beta, i, j, k);
    double cB, cL;
    schur_coefficients(s, gamma2, &cB, &cL);
    const bool with_L = s.alpha > 0;
    const int oD = 6 * n, oB = 8 * n, oLj = 8 * n + nv, oLk = oLj + n + l;
    const int size = with_L ? oLk + n + l : oB + nv;
    MatrixXd M = MatrixXd::Zero(size, size);
    put_sym(M, 0, 0, t.Pi);
    put_sym(M, 0, oD, t.DtP);
    put_sym(M, oD, oD, -0.5 * P);
    put_sym(M, 0, oB, t.PB);
    put_sym(M, oB, oB, -cB * MatrixXd::Identity(nv, nv));
    if (with_L) {
        put_sym(M, 0, oLj, t.PLj);
        put_sym(M, 0, oLk, t.PLk);
        put_sym(M, oLj, oLj, -cL * MatrixXd::Identity(n + l, n + l));
        put_sym(M, oLk, oLk, -cL * MatrixXd::Identity(n + l, n + l));
    }
    return M;
}

MatrixXd delay_lmi_condition(const DelayLmiSpec& s, const MatrixXd& P, const MatrixXd& Q, const MatrixXd& R,
                             const std::vector<MatrixXd>& L, const std::vector<double>& beta, double gamma2, int i,
                             int j, int k) {
    const TheoremParts t = theorem_parts(s, P, Q, R, L, beta, i, j, k);
    // (32): Pi + 2 g^-2 P~B B'P~' + 2 D~'P D~ + a g^-2 (P~Lj Lj'P~' + P~Lk Lk'P~')
    // (42): Pi + 4 g^-2 P~B B'P~' + 2 D~'P D~ + 2 a g^-2 (...)
    const double kB = (s.design == DELAY_DESIGN_HINF ? 2.0 : 4.0) / gamma2;
    const double kL = (s.design == DELAY_DESIGN_HINF ? 1.0 : 2.0) * s.alpha / gamma2;
    const MatrixXd Pinv = P.inverse();
    MatrixXd C = t.Pi + kB * t.PB * t.PB.transpose() + 2.0 * t.DtP * Pinv * t.DtP.transpose() +
                 kL * (t.PLj * t.PLj.transpose() + t.PLk * t.PLk.transpose());
    return sym_of(C);
}

double delay_lmi_objective(const DelayLmiSpec& s, const DelayLmiPoint& p) {
    if (s.design == DELAY_DESIGN_HINF) return p.gamma2;
    // (46): tr(M P) + tr(N' Q N) + tr(L' (tau2 R) L) = tr(M P) + tr(Q N N') + tau2 tr(R L L')
    return (s.M * delay_lmi_full_P(p, s.p_structure)).trace() + (delay_lmi_full_Q(p) * s.NNt).trace() +
           s.tau2 * (delay_lmi_full_R(p) * s.LLt).trace();
}

int delay_lmi_num_vars(const DelayLmiSpec& s) {
    const Dims d = dims_of(s);
    const int sym = d.n * (d.n + 1) / 2, full = d.n * d.n;
    return 6 * sym + 2 * full + d.m + d.m * d.n * d.l + (s.design == DELAY_DESIGN_HINF ? 1 : 0);
}

namespace {

// Walks the decision vector in a fixed order: P1 P2 Q1 Q2 Q3 R1 R2 R3 (symmetric: upper triangle; Q2, R2
// full, row-major), beta_1..m, Y_1..m (row-major), gamma^2 (HINF only).
template <typename Fn>
void walk_layout(const DelayLmiSpec& s, DelayLmiPoint& p, Fn&& fn) {
    const Dims d = dims_of(s);
    int idx = 0;
    auto sym = [&](MatrixXd& A) {
        A.resize(d.n, d.n);
        for (int a = 0; a < d.n; ++a)
            for (int b = a; b < d.n; ++b) {
                fn(idx++, A(a, b));
                A(b, a) = A(a, b);
            }
    };
    auto full = [&](MatrixXd& A, int r, int c) {
        A.resize(r, c);
        for (int a = 0; a < r; ++a)
            for (int b = 0; b < c; ++b) fn(idx++, A(a, b));
    };
    sym(p.P1);
    sym(p.P2);
    sym(p.Q1);
    full(p.Q2, d.n, d.n);
    sym(p.Q3);
    sym(p.R1);
    full(p.R2, d.n, d.n);
    sym(p.R3);
    p.beta.resize(d.m);
    for (int j = 0; j < d.m; ++j) fn(idx++, p.beta[j]);
    p.Y.resize(d.m);
    for (int j = 0; j < d.m; ++j) full(p.Y[j], d.n, d.l);
    if (s.design == DELAY_DESIGN_HINF)
        fn(idx++, p.gamma2);
    else
        p.gamma2 = s.gamma2;
}

}  // namespace

DelayLmiPoint delay_lmi_unpack(const DelayLmiSpec& s, const std::vector<double>& x) {
    HINF_CHECK(static_cast<int>(x.size()) == delay_lmi_num_vars(s), "decision vector has the wrong length");
    DelayLmiPoint p;
    walk_layout(s, p, [&](int i, double& v) { v = x[i]; });
    return p;
}

std::vector<double> delay_lmi_pack(const DelayLmiSpec& s, const DelayLmiPoint& p) {
    std::vector<double> x(delay_lmi_num_vars(s), 0.0);
    DelayLmiPoint probe = p;  // symmetric parts are read from their upper triangle
    walk_layout(s, probe, [&](int i, double& v) { x[i] = v; });
    return x;
}

SdpProblem delay_lmi_problem(const DelayLmiSpec& s) {
    delay_lmi_check_spec(s);
    const int nvar = delay_lmi_num_vars(s);
    SdpProblem prob;
    prob.num_vars = nvar;
    prob.cost.assign(nvar, 0.0);
    // Every block and the objective are affine in x: read F0 at x = 0 and F_i = X(e_i) - X(0).
    std::vector<double> x(nvar, 0.0);
    const DelayLmiPoint p0 = delay_lmi_unpack(s, x);
    const std::vector<LmiBlockValue> b0 = delay_lmi_blocks(s, p0);
    const double obj0 = delay_lmi_objective(s, p0);
    prob.blocks.resize(b0.size());
    for (std::size_t b = 0; b < b0.size(); ++b) {
        prob.blocks[b].name = b0[b].name;
        const auto sz = b0[b].value.rows();
        prob.blocks[b].constant = -b0[b].value - s.margin * MatrixXd::Identity(sz, sz);  // -X(x) - eps I >= 0
    }
    for (int i = 0; i < nvar; ++i) {
        x[i] = 1.0;
        const DelayLmiPoint pi = delay_lmi_unpack(s, x);
        const std::vector<LmiBlockValue> bi = delay_lmi_blocks(s, pi);
        prob.cost[i] = delay_lmi_objective(s, pi) - obj0;
        for (std::size_t b = 0; b < bi.size(); ++b) {
            MatrixXd F = -(bi[b].value - b0[b].value);
            const double scale = 1e-13 * std::max(1.0, b0[b].value.cwiseAbs().maxCoeff());
            F = F.unaryExpr([scale](double v) { return std::fabs(v) < scale ? 0.0 : v; });
            if (F.cwiseAbs().maxCoeff() > 0) prob.blocks[b].terms.emplace_back(i, sym_of(F));
        }
        x[i] = 0.0;
    }
    return prob;
}

std::vector<BlockCheck> delay_lmi_verify(const DelayLmiSpec& s, const DelayLmiPoint& p) {
    std::vector<BlockCheck> out;
    for (const auto& b : delay_lmi_blocks(s, p)) {
        Eigen::SelfAdjointEigenSolver<MatrixXd> es(sym_of(b.value), Eigen::EigenvaluesOnly);
        out.push_back({b.name, es.eigenvalues().maxCoeff()});
    }
    return out;
}

std::string DelayLmiResult::status_word() const {
    if (sdp.status == SDP_STATUS_OPTIMAL && !verified) return "unverified";
    return sdp_status_name(sdp.status);
}

DelayLmiResult delay_lmi_solve(const DelayLmiSpec& s, const SdpOptions& options) {
    const auto t0 = std::chrono::steady_clock::now();
    DelayLmiResult r;
    const SdpProblem prob = delay_lmi_problem(s);
    r.sdp = sdp_solve(prob, options);
    r.point = delay_lmi_unpack(s, r.sdp.x);
    r.objective = delay_lmi_objective(s, r.point);
    r.worst_eigenvalue = -INFINITY;
    for (const auto& c : delay_lmi_verify(s, r.point))
        if (!(c.max_eigenvalue <= r.worst_eigenvalue)) {
            r.worst_eigenvalue = c.max_eigenvalue;
            r.worst_block = c.name;
        }
    r.verified = r.worst_eigenvalue < 0;
    if (r.sdp.status == SDP_STATUS_OPTIMAL && r.verified) r.gains = delay_lmi_gains(r.point);
    r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

}  // namespace hinf::lmi
