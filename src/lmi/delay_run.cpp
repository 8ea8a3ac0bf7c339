// Config reading for seed 002 runs, `hinf lmi` (print + DIR/lmi.h5) and the Table 3 Monte Carlo
// (DIR/operate.h5). Not the numerics: delay_lmi.cpp, delay_sim.cpp.
#include "lmi/delay_run.hpp"

#include <omp.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <sstream>
#include <toml++/toml.h>

#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/atomic.hpp"
#include "io/run_lock.hpp"

namespace hinf::lmi {

using Eigen::MatrixXd;

namespace {

constexpr int kMaxVertices = 16;

MatrixXd to_matrix(const std::vector<double>& v, int rows, int cols) {
    MatrixXd M(rows, cols);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) M(r, c) = v[static_cast<std::size_t>(r) * cols + c];
    return M;
}

std::vector<double> row_major(const MatrixXd& M) {
    std::vector<double> v(static_cast<std::size_t>(M.rows() * M.cols()));
    for (int r = 0; r < M.rows(); ++r)
        for (int c = 0; c < M.cols(); ++c) v[static_cast<std::size_t>(r) * M.cols() + c] = M(r, c);
    return v;
}

MatrixXd read_matrix(ConfigSection& s, const std::string& key, int rows, int cols, const MatrixXd* fallback) {
    if (!s.has(key) && !fallback) s.reject(key, "is required (" + std::to_string(rows) + "x" + std::to_string(cols) + " matrix)");
    std::vector<double> fb = fallback ? row_major(*fallback) : std::vector<double>{};
    return to_matrix(s.get_matrix(key, fb, rows, cols), rows, cols);
}

}  // namespace

DelayConfig delay_config_read(const ConfigDoc& doc) {
    DelayConfig c;
    // [system]
    ConfigSection sys(doc, "system");
    if (!sys.has("kind")) sys.reject("kind", "is required: kind = \"ito_delay\" selects the seed 002 delay system");
    sys.get_string("kind", "ito_delay", {"ito_delay"});
    const std::string model = sys.get_string("model", "example47", {"example47"});
    const std::string tau = sys.get_string("tau", "exp", {"exp", "constant"});
    const double tau2 = sys.get_double("tau2", 1.0, 1e-9, 1e6);
    const double tau_bar = sys.get_double("tau_bar", 0.3679, -1e6, 0.999999);
    sys.finish();
    c.system = delay_example47();
    const int n = c.system.n, l = c.system.l, nv = c.system.nv;

    // [vertices]
    ConfigSection vs(doc, "vertices");
    const std::string source = vs.get_string("source", "config", {"config", "jacobian"});
    if (!vs.has("count")) vs.reject("count", "is required (number of vertices m)");
    const int m = static_cast<int>(vs.get_int("count", 3, 1, kMaxVertices));
    if (!vs.has("operating_points"))
        vs.reject("operating_points", "is required: one row of " + std::to_string(2 * n) + " numbers (x, x(t - tau)) per vertex");
    const std::vector<double> pts = vs.get_matrix("operating_points", {}, m, 2 * n);
    const std::vector<std::int64_t> coords = vs.get_ints("weight_coordinates", {0}, 0, n - 1);
    const double jac_step = vs.get_double("jacobian_step", 1e-6, 1e-12, 1e-2);
    vs.finish();
    for (int i = 0; i < m; ++i) c.filter.points.emplace_back(pts.begin() + i * 2 * n, pts.begin() + (i + 1) * 2 * n);
    for (auto k : coords) c.filter.coordinates.push_back(static_cast<int>(k));
    std::vector<std::string> sections = {"system", "vertices", "bounds", "design", "simulation", "solver"};
    if (source == "config") {
        for (int i = 0; i < m; ++i) {
            const std::string name = "vertex" + std::to_string(i + 1);
            sections.push_back(name);
            HINF_CHECK(doc.root().contains(name), doc.source() + ": [vertices] source = \"config\" needs a section [" +
                                                      name + "] with A0, A1, C0, C1, B, Q0, Q1, J0, J1, K");
            ConfigSection s(doc, name);
            DelayVertex v;
            v.A0 = read_matrix(s, "A0", n, n, nullptr);
            v.A1 = read_matrix(s, "A1", n, n, nullptr);
            v.C0 = read_matrix(s, "C0", n, n, nullptr);
            v.C1 = read_matrix(s, "C1", n, n, nullptr);
            v.B = read_matrix(s, "B", n, nv, nullptr);
            v.Q0 = read_matrix(s, "Q0", l, n, nullptr);
            v.Q1 = read_matrix(s, "Q1", l, n, nullptr);
            v.J0 = read_matrix(s, "J0", l, n, nullptr);
            v.J1 = read_matrix(s, "J1", l, n, nullptr);
            v.K = read_matrix(s, "K", l, nv, nullptr);
            s.finish();
            c.filter.vertices.push_back(v);
        }
    } else {
        c.filter.vertices = delay_vertices_from_jacobians(c.system, c.filter.points, jac_step);
    }

    // [design]
    ConfigSection ds(doc, "design");
    const std::string kind = ds.get_string("kind", "hinf", {"hinf", "h2hinf"});
    c.spec.design = kind == "hinf" ? DELAY_DESIGN_HINF : DELAY_DESIGN_H2HINF;
    if (c.spec.design == DELAY_DESIGN_H2HINF && !ds.has("gamma"))
        ds.reject("gamma", "is required for kind = \"h2hinf\" (the prescribed attenuation level)");
    const double gamma = ds.get_double("gamma", 0.0, 1e-6, 1e6);
    if (c.spec.design == DELAY_DESIGN_HINF && ds.has("gamma"))
        ds.reject("gamma", "is only used with kind = \"h2hinf\" (kind = \"hinf\" minimises gamma^2)");
    c.spec.gamma2 = gamma * gamma;
    const MatrixXd I = MatrixXd::Identity(n, n);
    c.spec.G = read_matrix(ds, "G", n, n, &I);
    const std::string sp = ds.get_string("sigma_placement", "theorem", {"theorem", "state"});
    c.spec.sigma_placement = sp == "theorem" ? DELAY_SIGMA_THEOREM : DELAY_SIGMA_STATE;
    c.spec.margin = ds.get_double("margin", 1e-6, 1e-12, 1.0);
    c.spec.p_structure =
        ds.get_string("p_structure", "paper", {"paper", "error"}) == "paper" ? DELAY_P_PAPER : DELAY_P_ERROR;
    const MatrixXd M11 = read_matrix(ds, "initial_covariance", n, n, &I);
    ds.finish();
    Eigen::SelfAdjointEigenSolver<MatrixXd> es(0.5 * (M11 + M11.transpose()));
    HINF_CHECK((M11 - M11.transpose()).cwiseAbs().maxCoeff() < 1e-12 && es.eigenvalues().minCoeff() > 0,
               doc.source() + ": [design] initial_covariance must be symmetric positive definite");
    c.spec.vertices = c.filter.vertices;
    c.spec.tau2 = tau2;
    c.spec.tau_bar = tau_bar;
    const DelayTauKind tk = tau == "exp" ? DELAY_TAU_EXP : DELAY_TAU_CONSTANT;
    // Remark 7 with x(theta) = x0 constant on [-tau2, 0], xh(theta) = 0: M = diag{M11, 0},
    // N N' = tau(0) M, L L' = tau2^2 / 2 M.
    c.spec.M = MatrixXd::Zero(2 * n, 2 * n);
    c.spec.M.topLeftCorner(n, n) = M11;
    c.spec.NNt = delay_tau(tk, tau2, 0.0) * c.spec.M;
    c.spec.LLt = 0.5 * tau2 * tau2 * c.spec.M;

    // [simulation]
    ConfigSection ss(doc, "simulation");
    c.sim.final_time = ss.get_double("final_time", 15.0, 1e-6, 1e6);
    c.sim.dt = ss.get_double("dt", 1e-3, 1e-7, 1.0);
    c.sim.seed = static_cast<std::uint64_t>(ss.get_int("seed", 2, 0, INT64_MAX));
    c.runs = static_cast<int>(ss.get_int("runs", 100, 2, 1000000));
    c.threads = static_cast<int>(ss.get_int("threads", 0, 0, 4096));
    c.sim.disturbance.high = ss.get_double("disturbance_high", 2.0, -1e6, 1e6);
    c.sim.disturbance.low = ss.get_double("disturbance_low", -2.0, -1e6, 1e6);
    c.sim.disturbance.period = ss.get_double("disturbance_period", 2.0, 1e-9, 1e9);
    c.sim.disturbance.duty = ss.get_double("disturbance_duty", 0.5, 0.0, 1.0);
    c.sim.record_every = static_cast<int>(ss.get_int("record_every", 10, 1, 1000000));
    c.use_paper_gains = ss.get_string("gains", "design", {"design", "paper_solution"}) == "paper_solution";
    ss.finish();
    c.sim.tau2 = tau2;
    c.sim.tau = tk;
    c.sim.initial_covariance = M11;
    HINF_CHECK(c.sim.dt < c.sim.final_time, doc.source() + ": [simulation] dt must be smaller than final_time");

    // [solver]
    ConfigSection so(doc, "solver");
    c.sdp.max_iterations = static_cast<int>(so.get_int("max_iterations", 200, 1, 100000));
    c.sdp.epsilon = so.get_double("gap_epsilon", 1e-6, 1e-14, 1e-2);
    c.sdp.feasibility_epsilon = so.get_double("feasibility_epsilon", 1e-8, 1e-14, 1e-2);
    c.sdp.verbose = so.get_bool("verbose", false);
    so.finish();

    // [bounds]: Assumption 1 (24), the paper's Step (c) values or Table 1 Step 3 from simulation
    ConfigSection bs(doc, "bounds");
    c.bounds_source = bs.get_string("source", "paper", {"paper", "simulation"});
    c.spec.e1 = bs.get_double("e1", 0.0, 0.0, 1e6);
    c.spec.e2 = bs.get_double("e2", 0.0, 0.0, 1e6);
    c.spec.e3 = bs.get_double("e3", 0.0, 0.0, 1e6);
    c.spec.e4 = bs.get_double("e4", 0.0, 0.0, 1e6);
    c.spec.alpha = bs.get_double("alpha", 0.0, 0.0, 1e6);
    c.bound_runs = static_cast<int>(bs.get_int("runs", 20, 1, 100000));
    bs.finish();
    // [paper_solution]: optional published decision matrices (Appendices B, C) to plug into our LMIs
    if (doc.root().contains("paper_solution")) {
        sections.push_back("paper_solution");
        ConfigSection ps(doc, "paper_solution");
        DelayLmiPoint& p = c.paper_point;
        p.P1 = read_matrix(ps, "P1", n, n, nullptr);
        p.P2 = read_matrix(ps, "P2", n, n, nullptr);
        p.Q1 = read_matrix(ps, "Q1", n, n, nullptr);
        p.Q2 = read_matrix(ps, "Q2", n, n, nullptr);
        p.Q3 = read_matrix(ps, "Q3", n, n, nullptr);
        p.R1 = read_matrix(ps, "R1", n, n, nullptr);
        p.R2 = read_matrix(ps, "R2", n, n, nullptr);
        p.R3 = read_matrix(ps, "R3", n, n, nullptr);
        const MatrixXd Y = read_matrix(ps, "Y", m, n * l, nullptr);
        for (int j = 0; j < m; ++j) p.Y.push_back(to_matrix(row_major(Y.row(j)), n, l));
        if (!ps.has("beta")) ps.reject("beta", "is required (one beta_j per vertex)");
        p.beta = ps.get_doubles("beta", {}, m);
        if (c.spec.design == DELAY_DESIGN_HINF && !ps.has("gamma2")) ps.reject("gamma2", "is required for kind = \"hinf\"");
        p.gamma2 = ps.get_double("gamma2", c.spec.gamma2, 0.0, 1e12);
        if (c.spec.design == DELAY_DESIGN_H2HINF) p.gamma2 = c.spec.gamma2;
        ps.finish();
        c.has_paper_point = true;
    }
    HINF_CHECK(!c.use_paper_gains || c.has_paper_point,
               doc.source() + ": [simulation] gains = \"paper_solution\" needs a [paper_solution] section");
    config_check_sections(doc, sections);
    delay_lmi_check_spec(c.spec);
    if (c.bounds_source == "simulation") {
        const int th = c.threads > 0 ? c.threads : omp_get_max_threads();
        const DelayBounds b = delay_estimate_bounds(c.system, c.filter, c.sim, c.bound_runs, th);
        c.spec.e1 = b.e1;
        c.spec.e2 = b.e2;
        c.spec.e3 = b.e3;
        c.spec.e4 = b.e4;
        c.spec.alpha = b.alpha;
    }
    return c;
}

namespace {

std::string fmt(double v, int prec = 6) {
    std::ostringstream o;
    o << std::setprecision(prec) << v;
    return o.str();
}

std::string matrix_text(const MatrixXd& M) {
    std::ostringstream o;
    o << "[";
    for (int r = 0; r < M.rows(); ++r) {
        o << (r ? "; " : "");
        for (int cc = 0; cc < M.cols(); ++cc) o << (cc ? " " : "") << std::fixed << std::setprecision(4) << M(r, cc);
    }
    o << "]";
    return o.str();
}

void write_matrix(hid_t loc, const std::string& name, const MatrixXd& M, const std::string& meaning) {
    const auto v = row_major(M);
    h5::write_doubles(loc, name, v.data(), {static_cast<hsize_t>(M.rows()), static_cast<hsize_t>(M.cols())}, "1",
                      meaning);
}

void write_stack(hid_t loc, const std::string& name, const std::vector<MatrixXd>& Ms, const std::string& units,
                 const std::string& meaning) {
    std::vector<double> v;
    for (const auto& M : Ms) {
        const auto r = row_major(M);
        v.insert(v.end(), r.begin(), r.end());
    }
    h5::write_doubles(loc, name, v.data(),
                      {static_cast<hsize_t>(Ms.size()), static_cast<hsize_t>(Ms[0].rows()),
                       static_cast<hsize_t>(Ms[0].cols())},
                      units, meaning);
}

void write_bounds_attrs(hid_t loc, const DelayConfig& c) {
    h5::set_attr(loc, "bounds_source", c.bounds_source);
    h5::set_attr(loc, "e1", c.spec.e1);
    h5::set_attr(loc, "e2", c.spec.e2);
    h5::set_attr(loc, "e3", c.spec.e3);
    h5::set_attr(loc, "e4", c.spec.e4);
    h5::set_attr(loc, "alpha", c.spec.alpha);
}

const char* design_name(const DelayLmiSpec& s) { return s.design == DELAY_DESIGN_HINF ? "hinf" : "h2hinf"; }

}  // namespace

int delay_lmi_run(const ConfigDoc& doc, const std::string& out_dir, std::ostream& out) {
    const DelayConfig c = delay_config_read(doc);
    const DelayLmiResult r = delay_lmi_solve(c.spec, c.sdp);
    const std::string status = r.status_word();
    const bool hinf = c.spec.design == DELAY_DESIGN_HINF;

    out << "design: " << (hinf ? "H-infinity (seed 002 Theorem 1, LP 35)" : "mixed H2/H-infinity (seed 002 Theorem 2, LP 46)")
        << ", " << c.spec.vertices.size() << " vertices, "
        << c.spec.vertices.size() * c.spec.vertices.size() * c.spec.vertices.size() << " (i,j,k) blocks\n";
    out << "bounds (" << c.bounds_source << "): e1=" << fmt(c.spec.e1, 4) << " e2=" << fmt(c.spec.e2, 4)
        << " e3=" << fmt(c.spec.e3, 4) << " e4=" << fmt(c.spec.e4, 4) << " alpha=" << fmt(c.spec.alpha, 4) << "\n";
    out << "solver: SDPA, status " << status << " (" << r.sdp.solver_phase << "), " << r.sdp.iterations
        << " iterations, primal " << fmt(r.sdp.primal_objective, 8) << ", dual " << fmt(r.sdp.dual_objective, 8)
        << ", " << fmt(r.wall_seconds, 3) << " s\n";
    out << "largest eigenvalue over all blocks at the returned point: " << fmt(r.worst_eigenvalue, 4) << " ("
        << r.worst_block << ")\n";
    if (r.ok()) {
        if (hinf)
            out << "gamma^2 = " << fmt(r.objective, 6) << "  (gamma = " << fmt(std::sqrt(r.objective), 6) << ")\n";
        else
            out << "gamma^2 = " << fmt(c.spec.gamma2, 6) << " (given), J2 = " << fmt(r.objective, 6) << "\n";
        for (std::size_t j = 0; j < r.gains.size(); ++j)
            out << "L" << j + 1 << " = " << matrix_text(r.gains[j]) << "\n";
    } else {
        out << "no gains: the design did not produce a verified solution (status " << status << ")\n";
    }

    const RunDirLock lock(out_dir, "hinf operate/lmi");
    const std::string path = (std::filesystem::path(out_dir) / "lmi.h5").string();
    AtomicH5 f(path);
    const hid_t root = f.get();
    h5::set_attr(root, "status", status);
    h5::set_attr(root, "design", design_name(c.spec));
    h5::set_attr(root, "solver", "SDPA 7 (PARAMETER_STABLE_BUT_SLOW)");
    h5::set_attr(root, "solver_phase", r.sdp.solver_phase);
    h5::set_attr(root, "iterations", static_cast<std::int64_t>(r.sdp.iterations));
    h5::set_attr(root, "primal_objective", r.sdp.primal_objective);
    h5::set_attr(root, "dual_objective", r.sdp.dual_objective);
    h5::set_attr(root, "worst_eigenvalue", r.worst_eigenvalue);
    h5::set_attr(root, "worst_block", r.worst_block);
    h5::set_attr(root, "margin", c.spec.margin);
    h5::set_attr(root, "sigma_placement", c.spec.sigma_placement == DELAY_SIGMA_THEOREM ? "theorem" : "state");
    h5::set_attr(root, "p_structure", c.spec.p_structure == DELAY_P_PAPER ? "paper" : "error");
    h5::set_attr(root, "wall_seconds", r.wall_seconds);
    write_bounds_attrs(root, c);
    h5::write_string(root, "config", doc.text(), "the effective configuration (TOML)");
    std::vector<MatrixXd> A0s;
    for (const auto& v : c.spec.vertices) A0s.push_back(v.A0);
    write_stack(root, "vertex_A0", A0s, "1/s", "A0_i of each vertex (19), vertices x states x states");
    if (r.ok()) {
        h5::set_attr(root, "gamma2", hinf ? r.objective : c.spec.gamma2);
        if (!hinf) h5::set_attr(root, "j2", r.objective);
        write_stack(root, "gains", r.gains, "1", "filter gains L_j = P2^-1 Y_j (21), vertices x states x outputs");
        h5::Handle g = h5::create_group(root, "decision");
        write_matrix(g.get(), "P1", r.point.P1, "P = [P1 P2; P2 P2] (33), or [P1 -P2; -P2 P2] (p_structure)");
        write_matrix(g.get(), "P2", r.point.P2, "P = [P1 P2; P2 P2] (33), or [P1 -P2; -P2 P2] (p_structure)");
        write_matrix(g.get(), "Q1", r.point.Q1, "Q = [Q1 Q2; Q2' Q3] (33)");
        write_matrix(g.get(), "Q2", r.point.Q2, "Q = [Q1 Q2; Q2' Q3] (33)");
        write_matrix(g.get(), "Q3", r.point.Q3, "Q = [Q1 Q2; Q2' Q3] (33)");
        write_matrix(g.get(), "R1", r.point.R1, "R = [R1 R2; R2' R3] (33)");
        write_matrix(g.get(), "R2", r.point.R2, "R = [R1 R2; R2' R3] (33)");
        write_matrix(g.get(), "R3", r.point.R3, "R = [R1 R2; R2' R3] (33)");
        write_stack(g.get(), "Y", r.point.Y, "1", "Y_j = P2 L_j, vertices x states x outputs");
        h5::write_doubles(g.get(), "beta", r.point.beta.data(), {r.point.beta.size()}, "1",
                          "beta_j of Lbar_j' P Lbar_j < beta_j I (27)");
        const auto checks = delay_lmi_verify(c.spec, r.point);
        std::vector<double> ev;
        std::string names;
        for (const auto& ck : checks) {
            ev.push_back(ck.max_eigenvalue);
            names += (names.empty() ? "" : "\n") + ck.name;
        }
        h5::write_doubles(root, "block_max_eigenvalue", ev.data(), {ev.size()}, "1",
                          "largest eigenvalue of each block required negative definite (names in block_names)");
        h5::write_string(root, "block_names", names, "one block name per line, in block_max_eigenvalue's order");
    }
    if (c.has_paper_point) {
        // The published solution plugged into the LMIs assembled here: if a block is not < 0 there, the
        // published gamma^2 / J2 is not a value of these LMIs (docs/method_lmi.md, "paper check").
        DelayLmiSpec as_printed = c.spec;
        as_printed.p_structure = DELAY_P_PAPER;  // the published P is structured as (33) prints it
        const auto checks = delay_lmi_verify(as_printed, c.paper_point);
        const double obj = delay_lmi_objective(as_printed, c.paper_point);
        std::vector<double> ev;
        std::string names;
        double worst = -INFINITY;
        int violated = 0;
        out << "paper solution ([paper_solution]) in these LMIs: " << (hinf ? "gamma^2 = " : "J2 = ") << fmt(obj, 6)
            << "; largest eigenvalue per block:\n";
        for (std::size_t b = 0; b < checks.size(); ++b) {
            ev.push_back(checks[b].max_eigenvalue);
            names += (names.empty() ? "" : "\n") + checks[b].name;
            worst = std::max(worst, checks[b].max_eigenvalue);
            violated += checks[b].max_eigenvalue >= 0 ? 1 : 0;
            out << "  " << std::left << std::setw(14) << checks[b].name << std::right << std::setw(12)
                << fmt(checks[b].max_eigenvalue, 5) << ((b % 3 == 2) ? "\n" : "");
        }
        if (checks.size() % 3) out << "\n";
        const auto paper_gains = delay_lmi_gains(c.paper_point);
        for (std::size_t j = 0; j < paper_gains.size(); ++j)
            out << "  paper L" << j + 1 << " = P2^-1 Y" << j + 1 << " = " << matrix_text(paper_gains[j]) << "\n";
        out << "  " << violated << " of " << checks.size() << " blocks violated (largest eigenvalue " << fmt(worst, 5)
            << ")\n";
        h5::Handle g = h5::create_group(root, "paper_check");
        h5::set_attr(g.get(), "objective", obj);
        h5::set_attr(g.get(), "violated_blocks", static_cast<std::int64_t>(violated));
        h5::set_attr(g.get(), "worst_eigenvalue", worst);
        h5::write_doubles(g.get(), "block_max_eigenvalue", ev.data(), {ev.size()}, "1",
                          "largest eigenvalue of each block at the published solution (names in block_names)");
        h5::write_string(g.get(), "block_names", names, "one block name per line");
    }
    f.commit();
    out << "wrote " << path << "\n";
    return r.ok() ? 0 : 4;
}

int delay_operate(const ConfigDoc& doc, const std::string& out_dir, int runs, int threads) {
    DelayConfig c = delay_config_read(doc);
    if (runs <= 0) runs = c.runs;
    if (threads <= 0) threads = c.threads > 0 ? c.threads : omp_get_max_threads();
    HINF_CHECK(runs >= 2, "operate needs --runs >= 2 for a confidence interval");
    DelayLmiResult r = delay_lmi_solve(c.spec, c.sdp);
    if (!r.ok()) {
        std::fprintf(stderr, "hinf: the LMI design failed (status %s): nothing to operate\n", r.status_word().c_str());
        return 4;
    }
    if (c.use_paper_gains) {  // the published gains, to compare them with ours in the same simulation
        r.gains = delay_lmi_gains(c.paper_point);
        r.objective = delay_lmi_objective(c.spec, c.paper_point);
    }
    c.filter.gains = r.gains;
    const auto t0 = std::chrono::steady_clock::now();
    const DelayMonteCarlo mc = delay_monte_carlo(c.system, c.filter, c.sim, runs, threads);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    const RunDirLock lock(out_dir, "hinf operate/lmi");
    const std::string path = (std::filesystem::path(out_dir) / "operate.h5").string();
    AtomicH5 f(path);
    const hid_t root = f.get();
    h5::set_attr(root, "mean_error_energy", mc.mean);
    h5::set_attr(root, "ci95_low", mc.ci95_low);
    h5::set_attr(root, "ci95_high", mc.ci95_high);
    h5::set_attr(root, "stddev_error_energy", mc.stddev);
    h5::set_attr(root, "runs", static_cast<std::int64_t>(runs));
    h5::set_attr(root, "diverged_runs", static_cast<std::int64_t>(mc.diverged));
    h5::set_attr(root, "design", design_name(c.spec));
    h5::set_attr(root, "gamma2", c.spec.design == DELAY_DESIGN_HINF ? r.objective : c.spec.gamma2);
    if (c.spec.design == DELAY_DESIGN_H2HINF) h5::set_attr(root, "j2", r.objective);
    h5::set_attr(root, "mode", "measured");
    h5::set_attr(root, "gains_source", c.use_paper_gains ? "paper_solution" : "design");
    h5::set_attr(root, "seed", static_cast<std::int64_t>(c.sim.seed));
    h5::set_attr(root, "dt", c.sim.dt);
    h5::set_attr(root, "final_time", c.sim.final_time);
    h5::set_attr(root, "wall_seconds", wall);
    write_bounds_attrs(root, c);
    h5::write_string(root, "config", doc.text(), "the effective configuration (TOML)");
    h5::write_doubles(root, "error_energy", mc.error_energy.data(), {mc.error_energy.size()}, "state^2 s",
                      "int_0^T ||x - xhat||^2 dt per run (trapezoid)");
    h5::write_doubles(root, "t", mc.time.data(), {mc.time.size()}, "s", "time of mean_squared_error rows");
    h5::write_doubles(root, "mean_squared_error", mc.mean_squared_error.data(), {mc.mean_squared_error.size()},
                      "state^2", "E ||x(t) - xhat(t)||^2 over the runs (Figs. 9-10)");
    write_stack(root, "gains", r.gains, "1", "filter gains L_j used, vertices x states x outputs");
    f.commit();
    if (c.use_paper_gains) std::printf("operate: using the paper's gains P2^-1 Y_j from [paper_solution]\n");
    std::printf("operate: %s design, %d runs (%d threads), E int_0^%g ||e||^2 dt = %.5f, 95%% CI [%.5f, %.5f], "
                "sd %.5f, %d diverged, %.2f s\nwrote %s\n",
                design_name(c.spec), runs, threads, c.sim.final_time, mc.mean, mc.ci95_low, mc.ci95_high, mc.stddev,
                mc.diverged, wall, path.c_str());
    return 0;
}

}  // namespace hinf::lmi
