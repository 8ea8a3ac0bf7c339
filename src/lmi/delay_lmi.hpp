// LMI conditions of seed 002 (Mao, Deng & Wan 2016): Theorem 1 (H-infinity, eqs. 27/34, LP 35) and
// Theorem 2 (mixed H2/H-infinity, eqs. 38/45, objective 46) for the globally linearized delay filter (21).
// Not the simulation of the system or the filter (delay_sim.hpp), and not the solver (sdp.hpp).
#pragma once
#include <Eigen/Dense>
#include <string>
#include <vector>

#include "lmi/sdp.hpp"

namespace hinf::lmi {

// n = states, l = outputs (measurements), nv = disturbances, m = vertices.
/// One vertex of the polytope (18): the linear delay system (19) at one operating point.
struct DelayVertex {
    Eigen::MatrixXd A0, A1;  // n x n   drift: x, x(t - tau)
    Eigen::MatrixXd C0, C1;  // n x n   diffusion (dW): x, x(t - tau)
    Eigen::MatrixXd B;       // n x nv  disturbance
    Eigen::MatrixXd Q0, Q1;  // l x n   measurement drift
    Eigen::MatrixXd J0, J1;  // l x n   measurement diffusion
    Eigen::MatrixXd K;       // l x nv  disturbance into the measurement
};

enum DelayDesign {
    DELAY_DESIGN_HINF = 0,    // Theorem 1: minimise gamma^2 (LP 35)
    DELAY_DESIGN_H2HINF = 1,  // Theorem 2: gamma given, minimise the H2 bound (46)
};

/// Where the bounding term (beta_j + beta_k) sigma I of Pi_ijk acts (see docs/method_lmi.md, choice C3).
enum DelaySigmaPlacement {
    DELAY_SIGMA_THEOREM = 0,  // on all of xi and xi_t, as Theorem 1 prints it (Gamma11, 22, 33, 44)
    DELAY_SIGMA_STATE = 1,    // on x and x_t only: what the proof's ||zeta|| bound needs
};

/// Sign of the off-diagonal block of P (choice C4): (33) prints P = [P1 P2; P2 P2]; the error-coordinate
/// form P = [P1 -P2; -P2 P2] makes xi'P xi = x'(P1 - P2)x + e'P2 e with e = x - xhat.
enum DelayPStructure {
    DELAY_P_PAPER = 0,  // P = [P1 P2; P2 P2]  (33) as printed
    DELAY_P_ERROR = 1,  // P = [P1 -P2; -P2 P2]
};

struct DelayLmiSpec {
    std::vector<DelayVertex> vertices;
    Eigen::MatrixXd G;  // ns x n, s = G x (eq. 1)
    double tau2 = 1.0;     // tau_2: upper bound of the delay (eq. 2)
    double tau_bar = 0.0;  // bar tau: bound of d tau/dt (eq. 2)
    double e1 = 0, e2 = 0, e3 = 0, e4 = 0, alpha = 0;  // Assumption 1 (24)
    DelayDesign design = DELAY_DESIGN_HINF;
    double gamma2 = 0;  // prescribed gamma^2 for DELAY_DESIGN_H2HINF
    // Remark 7: E xi xi' = M, E int_{-tau(0)}^0 xi xi' = N N', E int_{-tau2}^0 (s + tau2) xi xi' = L L' (2n x 2n)
    Eigen::MatrixXd M, NNt, LLt;
    DelaySigmaPlacement sigma_placement = DELAY_SIGMA_THEOREM;
    double margin = 1e-6;  // strict LMI  X < 0  is posed as  X <= -margin I
    DelayPStructure p_structure = DELAY_P_PAPER;
};

/// One point of the decision space, structured as in (33): P = [P1 P2; P2 P2], Q = [Q1 Q2; Q2' Q3],
/// R = [R1 R2; R2' R3] (Q2, R2 full n x n), beta_j > 0, Y_j = P2 L_j (n x l), and gamma^2.
struct DelayLmiPoint {
    Eigen::MatrixXd P1, P2, Q1, Q2, Q3, R1, R2, R3;
    std::vector<double> beta;
    std::vector<Eigen::MatrixXd> Y;
    double gamma2 = 0;
};

/// A named symmetric matrix that the conditions require to be negative definite.
struct LmiBlockValue {
    std::string name;
    Eigen::MatrixXd value;
};

/// Checks the sizes of every vertex matrix; throws hinf::Error naming the first wrong one.
void delay_lmi_check_spec(const DelayLmiSpec& spec);

/// Pi_2 of (34) (design HINF) or (45) (design H2HINF) for vertices i, j, k (0-based), expanded in
/// P1, P2, Q*, R*, Y_j, beta: affine in the decision variables.
Eigen::MatrixXd delay_lmi_pi2(const DelayLmiSpec& spec, const DelayLmiPoint& p, int i, int j, int k);
/// Theta_j of (34)/(45): the Schur form of  Lbar_j' P Lbar_j < beta_j I.
Eigen::MatrixXd delay_lmi_theta(const DelayLmiSpec& spec, const DelayLmiPoint& p, int j);
/// Every block the design requires negative definite: Pi2 for all (i,j,k), Theta_j, -P, -Q, -R, -beta_j.
std::vector<LmiBlockValue> delay_lmi_blocks(const DelayLmiSpec& spec, const DelayLmiPoint& p);

/// Theorem forms with a general symmetric P, Q, R (2n x 2n) and gains L (n x l): Pi_1 of (27)/(38) ...
Eigen::MatrixXd delay_lmi_pi1(const DelayLmiSpec& spec, const Eigen::MatrixXd& P, const Eigen::MatrixXd& Q,
                              const Eigen::MatrixXd& R, const std::vector<Eigen::MatrixXd>& L,
                              const std::vector<double>& beta, double gamma2, int i, int j, int k);
/// ... and the un-Schured condition (32) (HINF) / (42) (H2HINF), 6n x 6n.
Eigen::MatrixXd delay_lmi_condition(const DelayLmiSpec& spec, const Eigen::MatrixXd& P, const Eigen::MatrixXd& Q,
                                    const Eigen::MatrixXd& R, const std::vector<Eigen::MatrixXd>& L,
                                    const std::vector<double>& beta, double gamma2, int i, int j, int k);

/// Full 2n x 2n P, Q, R of a structured point (33) (P with the spec's sign of P2 off the diagonal).
Eigen::MatrixXd delay_lmi_full_P(const DelayLmiPoint& p, DelayPStructure structure = DELAY_P_PAPER);
Eigen::MatrixXd delay_lmi_full_Q(const DelayLmiPoint& p);
Eigen::MatrixXd delay_lmi_full_R(const DelayLmiPoint& p);
/// L_j = P2^{-1} Y_j (Table 1 Step 4).
std::vector<Eigen::MatrixXd> delay_lmi_gains(const DelayLmiPoint& p);
/// The design objective at p: gamma^2 (HINF) or tr(M P) + tr(N' Q N) + tr(L' tau2 R L) (eq. 46, H2HINF).
double delay_lmi_objective(const DelayLmiSpec& spec, const DelayLmiPoint& p);

/// Decision vector <-> structured point.
int delay_lmi_num_vars(const DelayLmiSpec& spec);
DelayLmiPoint delay_lmi_unpack(const DelayLmiSpec& spec, const std::vector<double>& x);
std::vector<double> delay_lmi_pack(const DelayLmiSpec& spec, const DelayLmiPoint& p);
/// The SDP in standard form: each block -X(x) - margin I >= 0 for every X of delay_lmi_blocks.
SdpProblem delay_lmi_problem(const DelayLmiSpec& spec);

struct BlockCheck {
    std::string name;
    double max_eigenvalue = 0;  // largest eigenvalue of the block (must be < 0)
};
/// Largest eigenvalue of every block at p (independent of the solver).
std::vector<BlockCheck> delay_lmi_verify(const DelayLmiSpec& spec, const DelayLmiPoint& p);

struct DelayLmiResult {
    SdpResult sdp;
    bool verified = false;          // every block's largest eigenvalue < 0 at the returned point
    double worst_eigenvalue = 0;    // the largest of them
    std::string worst_block;
    DelayLmiPoint point;
    std::vector<Eigen::MatrixXd> gains;  // L_j
    double objective = 0;                // gamma^2 or the H2 bound J2
    double wall_seconds = 0;
    bool ok() const { return sdp.status == SDP_STATUS_OPTIMAL && verified; }
    /// "optimal", "infeasible", ..., or "unverified" when the solver said optimal but a block is not < 0.
    std::string status_word() const;
};

/// Assembles, solves and verifies. Never throws on numerical failure (see status_word()).
DelayLmiResult delay_lmi_solve(const DelayLmiSpec& spec, const SdpOptions& options = {});

}  // namespace hinf::lmi
