// See export_c.hpp. The C written here mirrors, operation for operation, what `hinf filter` runs for a DNN
// filter in measured mode (filters/dnn.cpp): the naive forward pass of kernels/mlp.cpp, the heads of
// kernels/head.cpp, the gain law of filters/gain_law.hpp and luenberger_advance. The network's GEMMs in hinf
// sum in another order (blocked, FMA), so the two agree to round-off, not bit for bit (docs/export.md).
#include "export/export_c.hpp"

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <set>
#include <sstream>

#include "config/run_config.hpp"
#include "hinf/error.hpp"
#include "io/atomic.hpp"
#include "io/checkpoint.hpp"
#include "models/expr_system.hpp"
#include "models/maneuvering_missile.hpp"
#include "models/missile.hpp"
#include "models/weighted_system.hpp"

namespace hinf {

namespace {

// a double literal that reads back to the same bits
std::string lit(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    std::string s = buf;
    if (s.find_first_of(".eEn") == std::string::npos) s += ".0";  // "2" -> "2.0" (a double, not an int)
    return "(" + s + ")";
}
std::string flit(float v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.9g", double(v));
    std::string s = buf;
    if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
    return s + "f";
}

// ------------------------------------------------------------------------------------------- systems
// Each writer emits four static functions of one state: PREFIX_drift (A [n]), PREFIX_disturbance_gain (B [n x nv]),
// PREFIX_measurement (C [m]), PREFIX_measurement_jacobian (dC/dx [m x n]).

std::string missile_c(const MissileParams& p, const std::string& P) {
    std::ostringstream c;
    c << "/* seed 000's ballistic missile (models/missile.cpp), parameters of the checkpoint's config */\n"
      << "static double " << P << "_density(double z) {\n"
      << "    const int high = z >= " << lit(p.switch_altitude) << ";\n"
      << "    const double r0 = high ? " << lit(p.rho_high) << " : " << lit(p.rho_low) << ";\n"
      << "    const double al = high ? " << lit(p.alpha_high) << " : " << lit(p.alpha_low) << ";\n"
      << "    return r0 * exp(-al * z);\n}\n\n"
      << "static void " << P << "_drift(double* A, const double* X, double t) {\n"
      << "    const double speed = sqrt(X[3] * X[3] + X[4] * X[4] + X[5] * X[5]);\n"
      << "    const double drag = " << P << "_density(X[2]) * " << lit(p.gravity) << " * speed / (2.0 * "
      << lit(p.ballistic) << ");\n"
      << "    int i;\n    (void)t;\n";
    for (int i = 0; i < 3; ++i) c << "    A[" << i << "] = -" << lit(p.position_gain[i]) << " * X[" << i << "];\n";
    c << "    for (i = 3; i < 6; ++i) A[i] = -drag * X[i] - " << lit(p.velocity_damping) << " * X[i];\n"
      << "    A[5] -= " << lit(p.gravity) << ";\n}\n\n"
      << "static void " << P << "_disturbance_gain(double* B, const double* X, double t) {\n"
      << "    int i;\n    (void)X;\n    (void)t;\n"
      << "    for (i = 0; i < 6; ++i) B[i] = i < 3 ? 0.0 : 1.0;\n}\n\n"
      << "static void " << P << "_measurement(double* C, const double* X, double t) {\n    (void)t;\n";
    for (int i = 0; i < 3; ++i) c << "    C[" << i << "] = X[" << i << "] - " << lit(p.radar[i]) << ";\n";
    c << "    C[3] = X[3];\n    C[4] = X[4];\n    C[5] = X[5];\n}\n\n";
    return c.str();
}

std::string maneuvering_missile_c(const ManeuverParams& mp, const std::string& P) {
    const MissileParams& p = mp.base;
    std::ostringstream c;
    c << "/* seed 001's maneuvering missile (models/maneuvering_missile.cpp), parameters of the checkpoint's config */\n"
      << "static double " << P << "_density(double z) {\n"
      << "    const int high = z >= " << lit(p.switch_altitude) << ";\n"
      << "    const double r0 = high ? " << lit(p.rho_high) << " : " << lit(p.rho_low) << ";\n"
      << "    const double al = high ? " << lit(p.alpha_high) << " : " << lit(p.alpha_low) << ";\n"
      << "    return r0 * exp(-al * z);\n}\n\n"
      << "static void " << P << "_drift(double* A, const double* X, double t) {\n"
      << "    const double at = " << lit(mp.amplitude) << " * exp(-" << lit(mp.decay) << " * t) * (4.0 / "
      << P << "_PI) * sin(" << lit(mp.wave_frequency) << " * t);\n"
      << "    const double mt = exp(-" << lit(mp.decay) << " * t) * sin(" << lit(mp.maneuver_frequency) << " * t);\n"
      << "    const double speed = sqrt(X[3] * X[3] + X[4] * X[4] + X[5] * X[5]);\n"
      << "    const double drag = " << P << "_density(X[2]) * " << lit(p.gravity) << " * speed / (2.0 * "
      << lit(p.ballistic) << ");\n";
    for (int i = 0; i < 3; ++i) c << "    A[" << i << "] = -" << lit(p.position_gain[i]) << " * X[" << i << "];\n";
    c << "    A[0] += at;\n"
      << "    A[3] = -drag * X[3] - mt * X[3];\n"
      << "    A[4] = -drag * X[4] - " << lit(p.velocity_damping) << " * X[4];\n"
      << "    A[5] = -drag * X[5] - " << lit(p.velocity_damping) << " * X[5] - " << lit(p.gravity) << ";\n}\n\n"
      << "static void " << P << "_disturbance_gain(double* B, const double* X, double t) {\n"
      << "    int i;\n    (void)X;\n    (void)t;\n"
      << "    for (i = 0; i < 36; ++i) B[i] = 0.0;\n"
      << "    for (i = 3; i < 6; ++i) B[i * 6 + i] = 1.0;\n}\n\n"
      << "static void " << P << "_measurement(double* C, const double* X, double t) {\n    (void)t;\n";
    for (int i = 0; i < 3; ++i) c << "    C[" << i << "] = X[" << i << "] - " << lit(p.radar[i]) << ";\n";
    c << "    C[3] = X[3];\n    C[4] = X[4];\n    C[5] = X[5];\n}\n\n";
    return c.str();
}

// dC/dx of both missiles: the identity
std::string identity_jacobian_c(const std::string& P) {
    return "static void " + P + "_measurement_jacobian(double* H, const double* X, double t) {\n" +
           "    int i;\n    (void)X;\n    (void)t;\n    for (i = 0; i < 36; ++i) H[i] = 0.0;\n" +
           "    for (i = 0; i < 6; ++i) H[i * 6 + i] = 1.0;\n}\n\n";
}

const std::set<std::string>& c_reserved() {
    // C99 keywords and the macros of <math.h>, <float.h> a local name cannot shadow
    static const std::set<std::string> names = {
        "auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else", "enum", "extern",
        "float", "for", "goto", "if", "inline", "int", "long", "register", "restrict", "return", "short", "signed",
        "sizeof", "static", "struct", "switch", "typedef", "union", "unsigned", "void", "volatile", "while",
        "_Bool", "_Complex", "_Imaginary", "bool", "true", "false", "NAN", "INFINITY", "HUGE_VAL", "HUGE_VALF",
        "HUGE_VALL", "M_PI", "Pi", "errno", "isfinite", "isnan", "isinf", "signbit", "fpclassify", "isnormal",
        "DBL_EPSILON", "FLT_EPSILON", "NULL", "step"};
    return names;
}

// The known inputs u(t) of an expression system ([system] inputs): the table the checkpoint was trained with, held or
// interpolated as ExprSystem::inputs_at does, so that the C reproduces `hinf filter` on the record the table belongs to.
// Built with -DPREFIX_EXTERNAL_INPUTS the table is left out and the caller defines PREFIX_inputs_at (live inputs).
std::string inputs_c(const ExprSystem& sys, const std::string& P) {
    const std::vector<std::string>& inputs = sys.inputs();
    const std::vector<double>& times = sys.input_times();
    const std::vector<double>& values = sys.input_values();
    const std::size_t q = inputs.size(), rows = times.size();
    std::string names;
    for (const auto& u : inputs) names += (names.empty() ? "" : ", ") + u;
    std::ostringstream c;
    c << "/* the known inputs u(t) = (" << names << ") of [system] inputs. Compiled as it is, the table of the\n"
      << "   checkpoint's config (" << rows << " rows, " << (sys.input_linear() ? "linear between rows" : "each row held until the next")
      << "; the first and last rows beyond its ends);\n   with -D" << P
      << "_EXTERNAL_INPUTS define void " << P << "_inputs_at(double t, double* u) [" << q << "] yourself (live inputs) */\n"
      << "#ifdef " << P << "_EXTERNAL_INPUTS\nvoid " << P << "_inputs_at(double t, double* u);\n#else\n"
      << "static const double " << P << "_input_t[" << rows << "] = {";
    for (std::size_t r = 0; r < rows; ++r) c << (r ? ", " : "") << (r % 4 == 0 ? "\n    " : "") << lit(times[r]);
    c << "};\nstatic const double " << P << "_input_u[" << rows * q << "] = {";
    for (std::size_t k = 0; k < rows * q; ++k) c << (k ? ", " : "") << (k % 4 == 0 ? "\n    " : "") << lit(values[k]);
    c << "};\n"
      << "static void " << P << "_inputs_at(double t, double* u) {\n"
      << "    /* the last row at or before t; a row stamped up to a billionth of the mean step after t counts */\n"
      << "    const double s = t + " << lit(sys.input_early()) << ";\n"
      << "    int lo = 0, hi = " << rows << ", j, i;\n    const double* a;\n"
      << "    while (lo < hi) {\n        const int mid = lo + (hi - lo) / 2;\n"
      << "        if (" << P << "_input_t[mid] > s) hi = mid;\n        else lo = mid + 1;\n    }\n"
      << "    j = lo == 0 ? 0 : lo - 1;\n    a = " << P << "_input_u + j * " << q << ";\n";
    if (sys.input_linear())
        c << "    if (j + 1 < " << rows << " && t > " << P << "_input_t[j]) {\n"
          << "        double w = (t - " << P << "_input_t[j]) / (" << P << "_input_t[j + 1] - " << P << "_input_t[j]);\n"
          << "        if (w > 1.0) w = 1.0;\n"
          << "        for (i = 0; i < " << q << "; ++i) u[i] = a[i] + w * (a[i + " << q << "] - a[i]);\n"
          << "        return;\n    }\n";
    c << "    for (i = 0; i < " << q << "; ++i) u[i] = a[i];\n}\n#endif\n\n";
    return c.str();
}

// An expression system through GiNaC's C print (the texts muParser evaluates in hinf, models/expr_system.cpp):
// the states, parameters and t (and a discrete system's step index k) become local constants of each function.
// In discrete time PREFIX_drift is the map f(x, k), not a vector field.
std::string expr_c(const ExprSystem& sys, const std::string& P) {
    const std::vector<std::string> states = sys.state_names();
    const std::vector<std::pair<std::string, double>>& params = sys.parameters();
    auto check_name = [&](const std::string& name, const std::string& what) {
        HINF_CHECK(!c_reserved().count(name) && name.rfind("hinf_", 0) != 0,
                   "export: the " + what + " '" + name + "' is a C keyword or a name the exported C uses; rename it "
                   "in [system] and train again to export this system");
    };
    const std::vector<std::string>& inputs = sys.inputs();
    for (const auto& s : states) check_name(s, "state");
    for (const auto& p : params) check_name(p.first, "parameter");
    for (const auto& u : inputs) check_name(u, "input");
    auto locals = [&]() {
        std::ostringstream c;
        for (std::size_t i = 0; i < states.size(); ++i)
            c << "    const double " << states[i] << " = hinf_x_[" << i << "];\n";
        for (const auto& p : params) c << "    const double " << p.first << " = " << lit(p.second) << ";\n";
        if (!inputs.empty()) {
            c << "    double hinf_u_[" << inputs.size() << "];\n    " << P << "_inputs_at(hinf_t_, hinf_u_);\n";
            for (std::size_t i = 0; i < inputs.size(); ++i)
                c << "    const double " << inputs[i] << " = hinf_u_[" << i << "];\n    (void)" << inputs[i] << ";\n";
        }
        c << "    const double t = hinf_t_;\n";
        // a discrete system's step index, rounded as models/expr_system.cpp does (t = k dt)
        if (sys.discrete_time()) c << "    const double k = nearbyint(hinf_t_ / " << lit(sys.period()) << ");\n";
        for (const auto& s : states) c << "    (void)" << s << ";\n";
        for (const auto& p : params) c << "    (void)" << p.first << ";\n";
        c << "    (void)t;\n";
        if (sys.discrete_time()) c << "    (void)k;\n";
        return c.str();
    };
    auto function = [&](const std::string& name, const std::string& which, const std::string& what) {
        std::ostringstream c;
        c << "/* " << what << " */\nstatic void " << P << "_" << name
          << "(double* hinf_out_, const double* hinf_x_, double hinf_t_) {\n"
          << locals();
        const std::vector<std::string> texts = sys.compiled(which);
        for (std::size_t k = 0; k < texts.size(); ++k) c << "    hinf_out_[" << k << "] = " << texts[k] << ";\n";
        c << "}\n\n";
        return c.str();
    };
    bool uses_step = false;
    const bool discrete = sys.discrete_time();  // and the map's Jacobian (the Kalman-form gain head, method.md 16.16)
    for (const char* which : {"f", "g", "h", "dh", "df"}) {
        if (std::string(which) == "df" && !discrete) continue;
        for (const std::string& text : sys.compiled(which)) uses_step = uses_step || text.find("step(") != std::string::npos;
    }
    std::ostringstream c;
    if (!inputs.empty()) c << inputs_c(sys, P);
    c << "/* the expression system of the checkpoint's config ([system] kind = \"expr\"), printed by GiNaC as C */\n"
      << (uses_step ? "static double step(double s) { return s >= 0 ? 1.0 : 0.0; } /* as models/expr_system.cpp */\n" : "")
      << "#define Pi " << P << "_PI\n\n"
      << function("drift", "f", "A(x, t) [n]") << function("disturbance_gain", "g", "B(x, t) [n x nv]")
      << function("measurement", "h", "C(x, t) [m]") << function("measurement_jacobian", "dh", "dC/dx [m x n]");
    if (discrete) c << function("drift_jacobian", "df", "dA/dx [n x n], the map's Jacobian");
    return c.str();
}

// A system seen in units of its noise (models/weighted_system.hpp): the inner system's functions renamed
// *_unweighted, wrapped by ones that weigh C and dC/dx by PREFIX_output_weight and scale B by
// PREFIX_disturbance_scale; PREFIX_step weighs the y it is given (the user's units) the same way. A diagonal weight
// (std lists) is written as its diagonal, a correlated one (noise_cov, disturbance_cov) as the lower-triangular matrix.
std::string system_c(const System& sys, const std::string& P);
std::string weighted_system_c(const WeightedSystem& sys, const std::string& P) {
    std::string text = system_c(sys.inner(), P);
    auto rename = [&](const std::string& from, const std::string& to) {
        for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
            text.replace(at, from.size(), to);
    };
    const int n = sys.state_dim(), m = sys.output_dim(), nv = sys.disturbance_dim();
    const std::vector<double>& W = sys.output_weight();
    const std::vector<double>& U = sys.disturbance_scale();
    auto entries = [](const std::vector<double>& M, int k, bool diagonal) {
        std::ostringstream e;
        for (int j = 0; j < k; ++j)
            for (int i = 0; i < k; ++i)
                if (!diagonal || i == j)
                    e << (j + i ? ", " : "") << lit(M[std::size_t(j) * k + i]);
        return e.str();
    };
    std::ostringstream c;
    if (!W.empty() && is_diagonal(W, m)) {
        rename(P + "_measurement(", P + "_measurement_unweighted(");
        rename(P + "_measurement_jacobian(", P + "_measurement_jacobian_unweighted(");
        c << "/* outputs in units of their noise ([online] noise_std list): y~_j = w_j y_j */\n"
          << "static const double " << P << "_output_weight[" << m << "] = {" << entries(W, m, true) << "};\n\n"
          << "static void " << P << "_measurement(double* C, const double* X, double t) {\n"
          << "    int j;\n    " << P << "_measurement_unweighted(C, X, t);\n"
          << "    for (j = 0; j < " << m << "; ++j) C[j] *= " << P << "_output_weight[j];\n}\n\n"
          << "static void " << P << "_measurement_jacobian(double* H, const double* X, double t) {\n"
          << "    int j, i;\n    " << P << "_measurement_jacobian_unweighted(H, X, t);\n"
          << "    for (j = 0; j < " << m << "; ++j)\n        for (i = 0; i < " << n << "; ++i) H[j * " << n
          << " + i] *= " << P << "_output_weight[j];\n}\n\n";
    } else if (!W.empty()) {
        rename(P + "_measurement(", P + "_measurement_unweighted(");
        rename(P + "_measurement_jacobian(", P + "_measurement_jacobian_unweighted(");
        c << "/* outputs in units of their noise ([online] noise_cov R = L L'): y~ = W y, W = L^-1 lower triangular,\n"
          << "   row-major (zero entries skipped, as models/weighted_system.cpp) */\n"
          << "static const double " << P << "_output_weight[" << m << " * " << m << "] = {" << entries(W, m, false)
          << "};\n\n"
          << "static void " << P << "_weigh(double* y) {\n"
          << "    int j, i;\n    double s;\n"
          << "    for (j = " << m - 1 << "; j >= 0; --j) {\n        s = 0;\n"
          << "        for (i = 0; i <= j; ++i)\n"
          << "            if (" << P << "_output_weight[j * " << m << " + i] != 0) s += " << P << "_output_weight[j * "
          << m << " + i] * y[i];\n        y[j] = s;\n    }\n}\n\n"
          << "static void " << P << "_measurement(double* C, const double* X, double t) {\n"
          << "    " << P << "_measurement_unweighted(C, X, t);\n    " << P << "_weigh(C);\n}\n\n"
          << "static void " << P << "_measurement_jacobian(double* H, const double* X, double t) {\n"
          << "    double col[" << m << "];\n    int j, i;\n    " << P << "_measurement_jacobian_unweighted(H, X, t);\n"
          << "    for (i = 0; i < " << n << "; ++i) {\n"
          << "        for (j = 0; j < " << m << "; ++j) col[j] = H[j * " << n << " + i];\n"
          << "        " << P << "_weigh(col);\n"
          << "        for (j = 0; j < " << m << "; ++j) H[j * " << n << " + i] = col[j];\n    }\n}\n\n";
    }
    if (!U.empty() && is_diagonal(U, nv)) {
        rename(P + "_disturbance_gain(", P + "_disturbance_gain_unweighted(");
        c << "/* disturbances in units of their std ([online] disturbance_std list): B~ = B diag(u) */\n"
          << "static const double " << P << "_disturbance_scale[" << nv << "] = {" << entries(U, nv, true) << "};\n\n"
          << "static void " << P << "_disturbance_gain(double* B, const double* X, double t) {\n"
          << "    int i, k;\n    " << P << "_disturbance_gain_unweighted(B, X, t);\n"
          << "    for (i = 0; i < " << n << "; ++i)\n        for (k = 0; k < " << nv << "; ++k) B[i * " << nv
          << " + k] *= " << P << "_disturbance_scale[k];\n}\n\n";
    } else if (!U.empty()) {
        rename(P + "_disturbance_gain(", P + "_disturbance_gain_unweighted(");
        c << "/* disturbances in units of their covariance ([online] disturbance_cov V = U U'): B~ = B U, U lower\n"
          << "   triangular, row-major */\n"
          << "static const double " << P << "_disturbance_scale[" << nv << " * " << nv << "] = {"
          << entries(U, nv, false) << "};\n\n"
          << "static void " << P << "_disturbance_gain(double* B, const double* X, double t) {\n"
          << "    double row[" << nv << "], s;\n    int i, k, l;\n    " << P << "_disturbance_gain_unweighted(B, X, t);\n"
          << "    for (i = 0; i < " << n << "; ++i) {\n"
          << "        for (k = 0; k < " << nv << "; ++k) {\n            s = 0;\n"
          << "            for (l = k; l < " << nv << "; ++l)\n"
          << "                if (" << P << "_disturbance_scale[l * " << nv << " + k] != 0) s += B[i * " << nv
          << " + l] * " << P << "_disturbance_scale[l * " << nv << " + k];\n"
          << "            row[k] = s;\n        }\n"
          << "        for (k = 0; k < " << nv << "; ++k) B[i * " << nv << " + k] = row[k];\n    }\n}\n\n";
    }
    return text + c.str();
}

std::string system_c(const System& sys, const std::string& P) {
    if (auto* s = dynamic_cast<const WeightedSystem*>(&sys)) return weighted_system_c(*s, P);
    if (auto* s = dynamic_cast<const ManeuveringMissileSystem*>(&sys))
        return maneuvering_missile_c(s->params(), P) + identity_jacobian_c(P);
    if (auto* s = dynamic_cast<const MissileSystem*>(&sys)) return missile_c(s->params(), P) + identity_jacobian_c(P);
    if (auto* s = dynamic_cast<const ExprSystem*>(&sys)) return expr_c(*s, P);
    HINF_FAIL("export: the system '" + sys.name() + "' has no C writer (src/export/export_c.cpp: add one beside "
              "missile_c)");
}

// `static void PREFIX_error_from_innovation(double* xt, const double* xhat, double t, const double* e)`: x~ from
// the innovation as filters/dnn.cpp dnn_error_from_innovation computes it (the measured-mode network input)
std::string innovation_lsq_c(const RunConfig& cfg, const std::string& P) {
    std::ostringstream c;
    const std::string N = P + "_N", M = P + "_M";
    c << "/* x~ from the innovation e = y - C(x^): the minimum-norm least-squares solution of dC/dx(x^) x~ = e\n"
      << "   (hinf: Eigen's complete orthogonal decomposition; here a one-sided Jacobi SVD, singular values below\n"
      << "   min(m, n) eps sigma_max dropped as Eigen's rank threshold does) */\n"
      << "static void " << P << "_error_from_innovation(double* xt, const double* xhat, double t, const double* e) {\n"
      << "    double H[" << M << " * " << N << "], A[" << M << " * " << N << "], V[" << N << " * " << N << "];\n"
      << "    const int tall = " << M << " >= " << N << ";\n"
      << "    const int r = tall ? " << M << " : " << N << ", c = tall ? " << N << " : " << M << ";\n"
      << "    double smax = 0, tol;\n"
      << "    int i, j, q, sweep;\n"
      << "    " << P << "_measurement_jacobian(H, xhat, t);\n"
      << "    /* A [r x c] = H (tall) or H^T */\n"
      << "    for (i = 0; i < r; ++i)\n"
      << "        for (j = 0; j < c; ++j) A[i * c + j] = tall ? H[i * " << N << " + j] : H[j * " << N << " + i];\n"
      << "    for (i = 0; i < c; ++i)\n"
      << "        for (j = 0; j < c; ++j) V[i * c + j] = i == j ? 1.0 : 0.0;\n"
      ;
    if (std::min(cfg.n, cfg.m) > 1) {  // one column needs no rotation (and none written keeps compilers quiet)
    c << "    /* one-sided Jacobi: rotate column pairs of A (and V) until they are orthogonal */\n"
      << "    for (sweep = 0; sweep < 60; ++sweep) {\n"
      << "        int rotated = 0;\n"
      << "        for (j = 0; j < c; ++j)\n"
      << "            for (q = j + 1; q < c; ++q) {\n"
      << "                double al = 0, be = 0, ga = 0, zeta, tn, cs, sn;\n"
      << "                for (i = 0; i < r; ++i) {\n"
      << "                    al += A[i * c + j] * A[i * c + j];\n"
      << "                    be += A[i * c + q] * A[i * c + q];\n"
      << "                    ga += A[i * c + j] * A[i * c + q];\n"
      << "                }\n"
      << "                if (ga == 0 || fabs(ga) <= 1e-15 * sqrt(al * be)) continue;\n"
      << "                rotated = 1;\n"
      << "                zeta = (be - al) / (2 * ga);\n"
      << "                tn = (zeta >= 0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1 + zeta * zeta));\n"
      << "                cs = 1 / sqrt(1 + tn * tn);\n"
      << "                sn = cs * tn;\n"
      << "                for (i = 0; i < r; ++i) {\n"
      << "                    const double aj = A[i * c + j], aq = A[i * c + q];\n"
      << "                    A[i * c + j] = cs * aj - sn * aq;\n"
      << "                    A[i * c + q] = sn * aj + cs * aq;\n"
      << "                }\n"
      << "                for (i = 0; i < c; ++i) {\n"
      << "                    const double vj = V[i * c + j], vq = V[i * c + q];\n"
      << "                    V[i * c + j] = cs * vj - sn * vq;\n"
      << "                    V[i * c + q] = sn * vj + cs * vq;\n"
      << "                }\n"
      << "            }\n"
      << "        if (!rotated) break;\n"
      << "    }\n"
      ;
    }
    c << "    (void)sweep;\n    (void)q;\n"
      << "    for (j = 0; j < c; ++j) {\n"
      << "        double s2 = 0;\n"
      << "        for (i = 0; i < r; ++i) s2 += A[i * c + j] * A[i * c + j];\n"
      << "        if (sqrt(s2) > smax) smax = sqrt(s2);\n"
      << "    }\n"
      << "    tol = (double)c * DBL_EPSILON * smax;\n"
      << "    for (i = 0; i < " << N << "; ++i) xt[i] = 0.0;\n"
      << "    for (j = 0; j < c; ++j) {\n"
      << "        /* column j of A is sigma_j u_j */\n"
      << "        double s2 = 0, w = 0;\n"
      << "        for (i = 0; i < r; ++i) s2 += A[i * c + j] * A[i * c + j];\n"
      << "        if (!(sqrt(s2) > tol)) continue;\n"
      << "        if (tall) { /* x = V S^-1 U^T e */\n"
      << "            for (i = 0; i < r; ++i) w += A[i * c + j] * e[i];\n"
      << "            for (i = 0; i < c; ++i) xt[i] += V[i * c + j] * (w / s2);\n"
      << "        } else { /* H^T = U S V^T: x = U S^-1 V^T e */\n"
      << "            for (i = 0; i < c; ++i) w += V[i * c + j] * e[i];\n"
      << "            for (i = 0; i < r; ++i) xt[i] += A[i * c + j] * (w / s2);\n"
      << "        }\n"
      << "    }\n"
      << "}\n\n";
    return c.str();
}

// ------------------------------------------------------------------------------------------ gain laws
// One entry per training variant. It writes, after the system and PREFIX_forward (the raw network),
//   static void PREFIX_gain(double* k, const double* xhat, double t, const double* e, const double* B)
// k [n x m] from the estimate, the time, the innovation e = y - C(x^) [m] and B(x^) [n x nv], with whatever it
// needs on the way (its head, the network's input), plus public functions for the header. Another variant's gain
// (one that reads x^ alone, say) is one more function and one more row of kGainLaws; the step does not change.

struct LawC {
    std::string code, header;  // definitions; extra prototypes for PREFIX.h
    long long flops = 0;       // per step, besides PREFIX_forward and the system functions
};

// C for a positive-definite matrix from a network's packed output (kernels/head.cpp's quadratic head, kernels/gain.cpp
// storage_forward): M = I + tril(o) (row-major lower-triangular packing), dst = c (M M' + eps I), divided by
// dinv_a dinv_b where `dinv` names an array (empty: not divided); both halves stored, the sums in the kernels' order.
// One block with its own loop variables, indented by `in` spaces.
std::string packed_mmt_c(const std::string& dst, int n, double c, double eps, const std::string& dinv, int in) {
    const std::string i(static_cast<std::size_t>(in), ' ');
    std::ostringstream s;
    s << i << "{\n"
      << i << "    double hM[" << n * n << "];\n"
      << i << "    int ha, hb, hk = 0;\n"
      << i << "    for (ha = 0; ha < " << n << "; ++ha)\n"
      << i << "        for (hb = 0; hb < " << n << "; ++hb) hM[ha * " << n << " + hb] = ha == hb ? 1.0 : 0.0;\n"
      << i << "    for (ha = 0; ha < " << n << "; ++ha)\n"
      << i << "        for (hb = 0; hb <= ha; ++hb) hM[ha * " << n << " + hb] += (double)o[hk++];\n"
      << i << "    for (ha = 0; ha < " << n << "; ++ha)\n"
      << i << "        for (hb = 0; hb <= ha; ++hb) {\n"
      << i << "            double x = 0;\n"
      << i << "            for (hk = 0; hk <= hb; ++hk) x += hM[ha * " << n << " + hk] * hM[hb * " << n << " + hk];\n"
      << i << "            x = " << lit(c) << " * (x + (ha == hb ? " << lit(eps) << " : 0.0))"
      << (dinv.empty() ? "" : " / (" + dinv + "[ha] * " + dinv + "[hb])") << ";\n"
      << i << "            " << dst << "[ha * " << n << " + hb] = x;\n"
      << i << "            " << dst << "[hb * " << n << " + ha] = x;\n"
      << i << "        }\n"
      << i << "}\n";
    return s.str();
}

// dissipative / paper: x~ from the innovation, p = dV/dx~ from the network's head, seed 000 eq. (8) with dC = e
LawC hinf_gain_c(const RunConfig& cfg, const kern::StepConfig& sc, const std::string& P) {
    const int n = sc.head.n, m = cfg.m;
    const bool quad = sc.head.kind == kern::HEAD_QUADRATIC;
    LawC law;
    std::ostringstream c;
    c << innovation_lsq_c(cfg, P)
      << "/* p = dV/dx~ at x~ [n]: the network at x~, then the "
      << (quad ? "quadratic head p = c (M M^T + eps I) x~, M = I + tril(o)" : "gradient head p = c o")
      << " (kernels/head.cpp) */\n"
      << "void " << P << "_gradient(double* p, const double* xt) {\n"
      << "    " << P << "_real buf[2][" << P << "_WIDEST];\n"
      << "    const " << P << "_real* o = " << P << "_forward(buf, xt);\n";
    if (quad) {
        c << "    double Pm[" << n * n << "];\n"
          << "    int a, b;\n"
          << packed_mmt_c("Pm", n, sc.head.scale, sc.head.eps, "", 4)
          << "    for (a = 0; a < " << n << "; ++a) {\n"
          << "        double s = 0;\n"
          << "        for (b = 0; b < " << n << "; ++b) s += Pm[a * " << n << " + b] * xt[b];\n"
          << "        p[a] = s;\n"
          << "    }\n";
    } else {
        c << "    int i;\n"
          << "    for (i = 0; i < " << n << "; ++i) p[i] = " << lit(sc.head.scale) << " * (double)o[i];\n";
    }
    c << "}\n\n"
      << "/* seed 000 eq. (8) as filters/gain_law.hpp worst_case: k* = 2 rho p dC^T / |p|^2 (zero when p = 0), with\n"
      << "   dC = e and p at x~ from the innovation (measured mode); rho of the network's training config */\n"
      << "static void " << P << "_gain(double* k, const double* xhat, double t, const double* e, const double* B) {\n"
      << "    const double rho = " << lit(cfg.rho) << ";\n"
      << "    double xt[" << P << "_N], p[" << P << "_N], pp = 0;\n"
      << "    int i, j;\n"
      << "    (void)B;\n"
      << "    " << P << "_error_from_innovation(xt, xhat, t, e);\n"
      << "    " << P << "_gradient(p, xt);\n"
      << "    for (i = 0; i < " << P << "_N; ++i) pp += p[i] * p[i];\n"
      << "    for (i = 0; i < " << P << "_N * " << P << "_M; ++i) k[i] = 0.0;\n"
      << "    if (pp > 0)\n"
      << "        for (i = 0; i < " << P << "_N; ++i)\n"
      << "            for (j = 0; j < " << P << "_M; ++j) k[i * " << P << "_M + j] = 2.0 * rho * p[i] * e[j] / pp;\n"
      << "}\n\n";
    law.code = c.str();
    law.header = "/* the frozen network: p = dV/dx~ [n] at x~ [n] */\nvoid " + P +
                 "_gradient(double* p, const double* xtilde);\n\n";
    // the head, the least squares (about 6 r c per column pair and sweep, one sweep counted), the gain
    long long f = 0;
    if (quad) {
        f += n * (n + 1) / 2;
        for (int a = 0; a < n; ++a)
            for (int b = 0; b <= a; ++b) f += 2LL * (b + 1) + 2;
        f += 2LL * n * n;
    } else
        f += n;
    const long long r = std::max(n, m), cc = std::min(n, m);
    law.flops = f + 6LL * r * cc * cc + 2LL * n + 4LL * n * m;
    return law;
}

// C for kernels/gain.cpp chol and chol_solve, operation for operation: the Cholesky factor L of the symmetric
// positive-definite A [dim x dim] (its diagonal floored at 1e-300), then X [dim x cols] <- A^-1 X row by row, with
// the scratch row tt; the generated function's loop variables a, b, q, kk and arrays L, tt hold them.
std::string chol_solve_c(const std::string& A, const std::string& X, int dim, int cols, const std::string& what) {
    std::ostringstream c;
    c << "        /* Cholesky " << what << " row by row (kernels/gain.cpp chol, chol_solve) */\n"
      << "        for (a = 0; a < " << dim << "; ++a)\n"
      << "            for (b = 0; b <= a; ++b) {\n"
      << "                double x = " << A << "[a * " << dim << " + b];\n"
      << "                for (kk = 0; kk < b; ++kk) x -= L[a * " << dim << " + kk] * L[b * " << dim << " + kk];\n"
      << "                L[a * " << dim << " + b] = a == b ? sqrt(x > 1e-300 ? x : 1e-300) : x / L[b * " << dim
      << " + b];\n"
      << "            }\n"
      << "        for (a = 0; a < " << dim << "; ++a) {\n"
      << "            for (q = 0; q < " << cols << "; ++q) tt[q] = " << X << "[a * " << cols << " + q];\n"
      << "            for (kk = 0; kk < a; ++kk)\n"
      << "                for (q = 0; q < " << cols << "; ++q) tt[q] -= L[a * " << dim << " + kk] * " << X << "[kk * "
      << cols << " + q];\n"
      << "            for (q = 0; q < " << cols << "; ++q) " << X << "[a * " << cols << " + q] = tt[q] / L[a * " << dim
      << " + a];\n"
      << "        }\n"
      << "        for (a = " << dim - 1 << "; a >= 0; --a) {\n"
      << "            for (q = 0; q < " << cols << "; ++q) tt[q] = " << X << "[a * " << cols << " + q];\n"
      << "            for (kk = a + 1; kk < " << dim << "; ++kk)\n"
      << "                for (q = 0; q < " << cols << "; ++q) tt[q] -= L[kk * " << dim << " + a] * " << X << "[kk * "
      << cols << " + q];\n"
      << "            for (q = 0; q < " << cols << "; ++q) " << X << "[a * " << cols << " + q] = tt[q] / L[a * " << dim
      << " + a];\n"
      << "        }\n";
    return c.str();
}

// gain (docs/method.md section 16): K(x^, t) from the network at z = (x^ - shift) / spread alone, as
// kernels/gain.cpp gain_network_eval computes it: the constant-storage head K = rate dx_a o_aq / dy_q, or the
// Riccati-form head K = rho S(t)^-1 (H(x^)' + o .* w) with S(t) from the storage's knots (linear in t between
// knots, M = diag(exp) + strict tril, S = c Ds^-1 (M M' + eps I) Ds^-1) and a Cholesky solve. The innovation is not
// an input of the gain: the step multiplies it. P names the network's data and functions, S the system's
// (PREFIX_measurement_jacobian); a member of an ensemble writes a static PREFIX_mE_gain_matrix with S = PREFIX.
LawC gain_matrix_c(const kern::StepConfig& sc, const std::string& P, const std::string& S, bool member) {
    const kern::GainSpec& g = sc.gain;
    const int n = sc.head.n, m = g.m, np = n * (n + 1) / 2;
    const bool tv = g.knots > 0, graded = tv && g.knots > 1 && g.knot_ratio != 1.0;
    auto array = [](const std::string& name, const double* v, int count) {
        std::ostringstream c;
        c << "static const double " << name << "[" << count << "] = {";
        for (int i = 0; i < count; ++i) c << (i ? ", " : "") << lit(v[i]);
        c << "};\n";
        return c.str();
    };
    LawC law;
    std::ostringstream c;
    c << "/* variant gain: the network input z = (x^ - shift) / spread (its scales from the training config) */\n"
      << array(P + "_shift", g.shift.data(), n) << array(P + "_spread", g.spread.data(), n);
    const bool held = !g.zlo.empty();
    if (held)
        c << "/* the filter holds z inside the box of its training estimates (network.input_box, docs/method.md 16.10) */\n"
          << array(P + "_zlo", g.zlo.data(), n) << array(P + "_zhi", g.zhi.data(), n);
    if (!tv || g.corr.empty()) c << array(P + "_dx", g.dx.data(), n) << array(P + "_dy", g.dy.data(), m);
    if (tv) {
        c << array(P + "_sdx", g.storage_dx(), n);
        if (!g.corr.empty()) c << array(P + "_corr", g.corr.data(), n * m);
        if (graded) {
            std::vector<double> tk(static_cast<std::size_t>(g.knots + 1));
            for (int j = 0; j <= g.knots; ++j) tk[static_cast<std::size_t>(j)] = g.knot_time(j);
            c << "/* the knot times t_j (network.knot_ratio, docs/method.md 16.7) */\n"
              << array(P + "_knot_t", tk.data(), g.knots + 1);
        }
    }
    c << "\n/* K(x^, t) [n x m], the trained gain (kernels/gain.cpp gain_network_eval) */\n"
      << (member || !g.mask.empty() ? "static " : "") << "void " << P
      << (g.mask.empty() ? "_gain_matrix" : "_gain_matrix_unmasked") << "(double* k, const double* xhat, double t) {\n"
      << "    " << P << "_real buf[2][" << P << "_WIDEST];\n"
      << "    double z[" << g.input_count(n) << "];\n"
      << "    const " << P << "_real* o;\n"
      << "    int a, q;\n";
    if (g.periodic.empty()) {
        c << "    for (a = 0; a < " << n << "; ++a) z[a] = (xhat[a] - " << P << "_shift[a]) / " << P << "_spread[a];\n";
        if (held)
            c << "    for (a = 0; a < " << n << "; ++a) z[a] = z[a] > " << P << "_zhi[a] ? " << P
              << "_zhi[a] : z[a] < " << P << "_zlo[a] ? " << P << "_zlo[a] : z[a];\n";
    } else {  // an angle state as (cos, sin) in its place (network.angle_inputs, docs/method.md 16.19)
        for (int a = 0, k = 0; a < n; ++a) {
            if (g.is_periodic(a)) {
                c << "    z[" << k << "] = cos(xhat[" << a << "]);\n    z[" << k + 1 << "] = sin(xhat[" << a << "]);\n";
                k += 2;
                continue;
            }
            c << "    z[" << k << "] = (xhat[" << a << "] - " << P << "_shift[" << a << "]) / " << P << "_spread[" << a
              << "];\n";
            if (held)
                c << "    z[" << k << "] = z[" << k << "] > " << P << "_zhi[" << a << "] ? " << P << "_zhi[" << a
                  << "] : z[" << k << "] < " << P << "_zlo[" << a << "] ? " << P << "_zlo[" << a << "] : z[" << k
                  << "];\n";
            ++k;
        }
    }
    c << "    o = " << P << "_forward(buf, z);\n";
    if (g.kalman) {
        // kernels/gain.cpp gain_kalman_forward, operation for operation (its storage_forward with d = 1 / dx, chol,
        // chol_solve over n columns), so the C gives hinf's bits up to the compiler's contractions
        c << "    {\n"
          << "        /* the Kalman-form head (docs/method.md 16.16): P = c D (M M' + eps I) D, M = I + tril(o),\n"
          << "           D = diag(dx); W = H P H' + diag(dy)^2, A' = W^-1 H P, K = F A; F, H the Jacobians at x^ */\n"
          << "        double Pm[" << n * n << "], F[" << n * n << "], H[" << m * n << "], At[" << m * n << "], W["
          << m * m << "], L[" << m * m << "], tt[" << n << "], dinv[" << n << "];\n"
          << "        int b, kk;\n"
          << "        for (a = 0; a < " << n << "; ++a) dinv[a] = 1.0 / " << P << "_dx[a];\n"
          << packed_mmt_c("Pm", n, g.kalman_scale, g.eps, "dinv", 8)
          << "        " << S << "_measurement_jacobian(H, xhat, t);\n"
          << "        " << S << "_drift_jacobian(F, xhat, t);\n"
          << "        for (q = 0; q < " << m << "; ++q)\n"
          << "            for (a = 0; a < " << n << "; ++a) {\n"
          << "                double x = 0;\n"
          << "                for (kk = 0; kk < " << n << "; ++kk) x += Pm[a * " << n << " + kk] * H[q * " << n
          << " + kk];\n"
          << "                At[q * " << n << " + a] = x;\n"
          << "            }\n"
          << "        for (q = 0; q < " << m << "; ++q)\n"
          << "            for (b = 0; b <= q; ++b) {\n"
          << "                double x = 0;\n"
          << "                for (a = 0; a < " << n << "; ++a) x += H[q * " << n << " + a] * At[b * " << n << " + a];\n"
          << "                if (q == b) x += " << P << "_dy[q] * " << P << "_dy[q];\n"
          << "                W[q * " << m << " + b] = x;\n"
          << "                W[b * " << m << " + q] = x;\n"
          << "            }\n"
          << chol_solve_c("W", "At", m, n, "W = L L', then At <- W^-1 At")
          << "        for (a = 0; a < " << n << "; ++a)\n"
          << "            for (q = 0; q < " << m << "; ++q) {\n"
          << "                double x = 0;\n"
          << "                for (kk = 0; kk < " << n << "; ++kk) x += F[a * " << n << " + kk] * At[q * " << n
          << " + kk];\n"
          << "                k[a * " << m << " + q] = x;\n"
          << "            }\n"
          << "    }\n"
          << "}\n\n";
    } else if (!tv) {
        c << "    (void)t;\n"
          << (g.loss.discrete ? "    (void)" + S + "_drift_jacobian; /* the direct head needs no dA/dx */\n" : "")
          << "    (void)" << S << "_measurement_jacobian; /* the constant-storage head needs no dC/dx */\n"
          << "    /* the constant-storage head: K_aq = rate dx_a o_aq / dy_q */\n"
          << "    for (a = 0; a < " << n << "; ++a)\n"
          << "        for (q = 0; q < " << m << "; ++q)\n"
          << "            k[a * " << m << " + q] = " << lit(g.rate) << " * " << P << "_dx[a] * (double)o[a * " << m
          << " + q] / " << P << "_dy[q];\n"
          << "}\n\n";
    } else {
        const std::int64_t off = sc.shape.param_count();
        c << "    {\n";
        if (graded)
            c << "        /* S(t) from knots j, j + 1 at t_j = " << P << "_knot_t[j] (clamped after the last) */\n"
              << "        const " << P << "_real* s = " << P << "_theta + " << off << ";\n"
              << "        double v[" << np << "], M[" << n * n << "], S[" << n * n << "], L[" << n * n << "], H["
              << m * n << "], tt[" << m << "], w = 0.0;\n"
              << "        int j = 0, b, e, kk;\n"
              << "        if (t >= " << P << "_knot_t[" << g.knots << "]) {\n"
              << "            j = " << g.knots - 1 << ";\n"
              << "            w = 1.0;\n"
              << "        } else if (t > 0) {\n"
              << "            while (j < " << g.knots - 1 << " && t >= " << P << "_knot_t[j + 1]) ++j;\n"
              << "            w = (t - " << P << "_knot_t[j]) / (" << P << "_knot_t[j + 1] - " << P << "_knot_t[j]);\n"
              << "        }\n";
        else
            c << "        /* S(t) from knots j, j + 1 at t_j = j span / J (clamped after span) */\n"
              << "        const " << P << "_real* s = " << P << "_theta + " << off << ";\n"
              << "        const double h = " << lit(g.knot_span) << " / " << g.knots << ".0;\n"
              << "        double v[" << np << "], M[" << n * n << "], S[" << n * n << "], L[" << n * n << "], H["
              << m * n << "], tt[" << m << "], w = 0.0;\n"
              << "        int j = 0, b, e, kk;\n"
              << "        if (t >= " << lit(g.knot_span) << ") {\n"
              << "            j = " << g.knots - 1 << ";\n"
              << "            w = 1.0;\n"
              << "        } else if (t > 0) {\n"
              << "            const double u = t / h;\n"
              << "            j = (int)u;\n"
              << "            if (j > " << g.knots - 1 << ") j = " << g.knots - 1 << ";\n"
              << "            w = u - j;\n"
              << "        }\n";
        c
          << "        for (e = 0; e < " << np << "; ++e)\n"
          << "            v[e] = (1.0 - w) * (double)s[j * " << np << " + e] + w * (double)s[(j + 1) * " << np << " + e];\n"
          << "        for (e = 0; e < " << n * n << "; ++e) M[e] = 0.0;\n"
          << "        for (a = 0, e = 0; a < " << n << "; ++a)\n"
          << "            for (b = 0; b <= a; ++b, ++e) M[a * " << n << " + b] = a == b ? exp(v[e]) : v[e];\n"
          << "        for (a = 0; a < " << n << "; ++a)\n"
          << "            for (b = 0; b <= a; ++b) {\n"
          << "                double mm = 0;\n"
          << "                for (kk = 0; kk <= b; ++kk) mm += M[a * " << n << " + kk] * M[b * " << n << " + kk];\n"
          << "                S[a * " << n << " + b] = " << lit(g.storage_scale) << " / (" << P << "_sdx[a] * " << P
          << "_sdx[b]) * (mm + (a == b ? " << lit(g.eps) << " : 0.0));\n"
          << "                S[b * " << n << " + a] = S[a * " << n << " + b]; /* two statements: one object at a == b */\n"
          << "            }\n"
          << "        /* K = rho S^-1 (H' + o .* w), H = dC/dx at x^ */\n"
          << "        " << S << "_measurement_jacobian(H, xhat, t);\n"
          << "        for (a = 0; a < " << n << "; ++a)\n"
          << "            for (q = 0; q < " << m << "; ++q)\n"
          << "                k[a * " << m << " + q] = " << lit(g.loss.rho) << " * (H[q * " << n << " + a] + "
          << (g.corr.empty() ? "(double)o[a * " + std::to_string(m) + " + q] * " + P + "_dy[q] / " + P + "_dx[a]"
                             : "(double)o[a * " + std::to_string(m) + " + q] * " + P + "_corr[a * " +
                                   std::to_string(m) + " + q]")
          << ");\n"
          << chol_solve_c("S", "k", n, m, "S = L L', then k <- S^-1 k")
          << "    }\n"
          << "}\n\n";
    }
    if (!g.mask.empty()) {  // the structural zeros (network.gain_structure = "components", docs/method.md 16.17)
        c << "/* the gain's structural zeros: K_aq = 0 where state a and output q lie in different components of the\n"
          << "   system's dependency graph (network.gain_structure = \"components\", docs/method.md 16.17) */\n"
          << array(P + "_mask", g.mask.data(), n * m)
          << (member ? "static " : "") << "void " << P << "_gain_matrix(double* k, const double* xhat, double t) {\n"
          << "    int e;\n"
          << "    " << P << "_gain_matrix_unmasked(k, xhat, t);\n"
          << "    for (e = 0; e < " << n * m << "; ++e)\n"
          << "        if (" << P << "_mask[e] == 0.0) k[e] = 0.0;\n"
          << "}\n\n";
    }
    law.code = c.str();
    // z, the head; with S(t): the knots' interpolation, M M', the right-hand side, Cholesky and two solves
    law.flops = 2LL * n + (tv ? 3LL * np + 2LL * n * (n + 1) * (n + 2) / 6 + 4LL * n * m + n * n * n / 3 + 2LL * n * n * m
                           : g.kalman ? n * (n + 1) * (n + 2) / 3 + 4LL * n * n * m + 2LL * m * m * n + m * m * m / 3 + 2LL * n * m * m
                                      : 3LL * n * m);
    return law;
}

// the step's gain law of a gain network (or of an ensemble's mean, whose PREFIX_gain_matrix is written beside its
// members'): K(x^, t) alone, the innovation multiplies it in the step
std::string gain_step_law_c(const std::string& P) {
    return "/* the step's gain law: K(x^, t) alone (the innovation multiplies it in the step) */\n"
           "static void " + P + "_gain(double* k, const double* xhat, double t, const double* e, const double* B) {\n"
           "    (void)e;\n    (void)B;\n"
           "    " + P + "_gain_matrix(k, xhat, t);\n"
           "}\n\n";
}

LawC gain_gain_c(const RunConfig&, const kern::StepConfig& sc, const std::string& P) {
    LawC law = gain_matrix_c(sc, P, P, false);
    law.code += gain_step_law_c(P);
    law.header = "/* the frozen network's gain K(x^, t) [n x m] (row-major) at the estimate x^ [n] and time t */\nvoid " +
                 P + "_gain_matrix(double* k, const double* xhat, double t);\n\n";
    return law;
}

struct CGainLaw {
    const char* variant;
    LawC (*emit)(const RunConfig& cfg, const kern::StepConfig& sc, const std::string& prefix);
};
const CGainLaw kGainLaws[] = {
    {"dissipative", hinf_gain_c},
    {"paper", hinf_gain_c},
    {"gain", gain_gain_c},
};

// ---------------------------------------------------------------------------------------------- network

template <typename T>
struct NetworkC {
    std::string data, code;  // the weights; PREFIX_forward
    long long flops = 0, bytes = 0;
};

// The weights and `static const TT* PREFIX_forward(TT buf[2][W], const double* input)`: input / s_in rounded to
// the network's precision, LeakyReLU hidden layers, the linear output layer (mlp_forward_naive's sums); returns
// the raw output o [D_L] (inside buf). What o means is the head's business (the gain law's entry).
template <typename T>
NetworkC<T> network_c(const Network<T>& net, const std::string& P) {
    const kern::StepConfig& sc = net.step;
    const kern::MlpShape& sh = sc.shape;
    const bool single = sizeof(T) == sizeof(float);
    const std::string TT = single ? "float" : "double";
    const int L = sh.layers();
    NetworkC<T> out;
    std::ostringstream d;
    d << "/* the network's parameters (kernels/mlp.hpp layout): for l = 1..L, W_l [D_l x D_(l-1)] row-major, "
         "then b_l [D_l] */\n"
      << "static const " << TT << " " << P << "_theta[" << net.theta.size() << "] = {\n";
    for (std::size_t i = 0; i < net.theta.size(); ++i) {
        d << (i % 8 == 0 ? "    " : " ") << (single ? flit(float(net.theta[i])) : lit(double(net.theta[i])))
          << (i + 1 < net.theta.size() ? "," : "") << (i % 8 == 7 || i + 1 == net.theta.size() ? "\n" : "");
    }
    d << "};\n";
    d << "static const int " << P << "_sizes[" << L + 1 << "] = {";
    for (int l = 0; l <= L; ++l) d << (l ? ", " : "") << sh.sizes[l];
    d << "};\nstatic const long " << P << "_offsets[" << L + 1 << "] = {0";
    for (int l = 1; l <= L; ++l) d << ", " << sh.weight_offset(l);
    d << "};\n\n";
    out.data = d.str();
    out.bytes = (long long)(net.theta.size() * sizeof(T));

    int widest = 0;
    for (int l = 0; l <= L; ++l) widest = std::max(widest, sh.sizes[l]);
    std::ostringstream c;
    c << "typedef " << TT << " " << P << "_real; /* the network's precision */\n"
      << "#define " << P << "_WIDEST " << widest << "\n\n"
      << "/* the network: input / s_in, LeakyReLU hidden layers, linear output (kernels/mlp.cpp, naive twin) */\n"
      << "static const " << TT << "* " << P << "_forward(" << TT << " buf[2][" << widest << "], const double* input) {\n"
      << "    const double inv = 1.0 / " << lit(sc.input_scale) << ";\n"
      << "    const " << TT << " a1 = (" << TT << ")" << lit(sh.slope_positive) << ", a2 = (" << TT << ")"
      << lit(sh.slope_negative) << ";\n"
      << "    const " << TT << "* in = buf[0];\n    " << TT << "* o = buf[1];\n"
      << "    int l, i, j;\n"
      << "    for (i = 0; i < " << sh.sizes[0] << "; ++i) buf[0][i] = (" << TT << ")(input[i] * inv);\n"
      << "    for (l = 1; l <= " << L << "; ++l) {\n"
      << "        const int din = " << P << "_sizes[l - 1], dout = " << P << "_sizes[l];\n"
      << "        const " << TT << "* W = " << P << "_theta + " << P << "_offsets[l];\n"
      << "        const " << TT << "* b = W + (long)dout * din;\n"
      << "        o = buf[l % 2];\n"
      << "        for (j = 0; j < dout; ++j) {\n"
      << "            " << TT << " z = b[j];\n"
      << "            for (i = 0; i < din; ++i) z += W[(long)j * din + i] * in[i];\n"
      << "            if (l < " << L << ") z = z > (" << TT << ")0 ? a1 * z : a2 * z;\n"
      << "            o[j] = z;\n"
      << "        }\n"
      << "        in = o;\n"
      << "    }\n"
      << "    return in;\n"
      << "}\n\n";
    out.code = c.str();
    // FLOPs: input scaling, per layer a multiply-add per weight, the bias, LeakyReLU's multiply
    long long f = sh.sizes[0];
    for (int l = 1; l <= L; ++l) f += 2LL * sh.sizes[l] * sh.sizes[l - 1] + (l < L ? sh.sizes[l] : 0);
    out.flops = f;
    return out;
}

// ------------------------------------------------------------------------------------------- assembly

// e = y - C(x^) of the filter step, in the units the network was trained in: y weighed as the outputs are (a list:
// w_j y_j; a covariance: W y), an angle output's difference wrapped into [-pi, pi] in the user's units first
// (models/system.hpp output_difference: W wrap(y - C_user(x^)))
std::string innovation_c(const RunConfig& cfg, const std::string& P, bool correlated) {
    const std::string M = P + "_M";
    const std::vector<int>& angles = cfg.system->angle_outputs();
    if (angles.empty())
        return correlated ? "    for (j = 0; j < " + M + "; ++j) e[j] = y[j];\n    " + P + "_weigh(e);\n    for (j = 0; j < " +
                                M + "; ++j) e[j] -= ch[j];\n"
                          : "    for (j = 0; j < " + M + "; ++j) e[j] = " +
                                (cfg.output_weight.empty() ? "" : P + "_output_weight[j] * ") + "y[j] - ch[j];\n";
    std::string c = cfg.output_weight.empty() ? "    for (j = 0; j < " + M + "; ++j) e[j] = y[j] - ch[j];\n"
                                              : "    " + P + "_measurement_unweighted(e, s->xhat, t);\n    for (j = 0; j < " +
                                                    M + "; ++j) e[j] = y[j] - e[j];\n";
    for (int j : angles)  // 2 pi to the last bit: remainder() is exact, as models/system.cpp wrap_angle
        c += "    e[" + std::to_string(j) + "] = remainder(e[" + std::to_string(j) + "], 6.2831853071795862);\n";
    if (correlated) c += "    " + P + "_weigh(e);\n";
    else if (!cfg.output_weight.empty()) c += "    for (j = 0; j < " + M + "; ++j) e[j] *= " + P + "_output_weight[j];\n";
    return c;
}

std::string filter_c(const RunConfig& cfg, const std::string& P) {
    std::ostringstream c;
    const std::string N = P + "_N", M = P + "_M", NV = P + "_NV";
    // a correlated output weight (noise_cov) weighs y by the matrix PREFIX_weigh (weighted_system_c)
    const bool correlated = !cfg.output_weight.empty() && !is_diagonal(cfg.output_weight, cfg.m);
    const bool discrete = cfg.system->discrete_time();
    c << "void " << P << "_init(" << P << "_state* s, const double* xhat0) {\n"
      << "    static const double config_xhat0[" << N << "] = {";
    for (int i = 0; i < cfg.n; ++i) c << (i ? ", " : "") << lit(cfg.xhat0[i]);
    c << "};\n"
      << "    int i;\n"
      << "    for (i = 0; i < " << N << "; ++i) s->xhat[i] = xhat0 ? xhat0[i] : config_xhat0[i];\n"
      << "    s->diverged = 0;\n"
      << "}\n\n"
      << (discrete ? "/* the discrete-time gain filter in measured mode (filters/dnn.cpp, docs/method.md 16.8): k from the gain\n"
                     "   law, then the one-step predictor x^ <- f(x^, k) + k e with e = y - C(x^) (gain_filter_advance) */\n"
                   : "/* seed 000 eq. (19) in measured mode (filters/dnn.cpp): k from the variant's gain law, then\n"
                     "   x^ <- x^ + dt (A(x^, t) + k e) with e = y - C(x^) (luenberger_advance) */\n")
      << "int " << P << "_step(" << P << "_state* s, const double* y, double t, double dt) {\n"
      << "    double a[" << N << "], B[" << N << " * " << NV << "], ch[" << M << "], e[" << M << "], k[" << N
      << " * " << M << "];\n"
      << "    int i, j, finite = 1;\n"
      << (discrete ? "    (void)dt; /* a discrete system's step is its map */\n" : "")
      << "    if (s->diverged) return 1;\n"
      << "    " << P << "_drift(a, s->xhat, t);\n"
      << "    " << P << "_measurement(ch, s->xhat, t);\n"
      << innovation_c(cfg, P, correlated)
      << "    " << P << "_disturbance_gain(B, s->xhat, t);\n"
      << "    " << P << "_gain(k, s->xhat, t, e, B);\n"
      << "    /* filters/filter.hpp filter_estimate_ok: finite and |x^| < 1e12; the gain finite */\n"
      << "    for (i = 0; i < " << N << "; ++i)\n"
      << "        if (!(s->xhat[i] == s->xhat[i]) || s->xhat[i] >= 1e12 || s->xhat[i] <= -1e12) finite = 0;\n"
      << "    for (i = 0; i < " << N << " * " << M << "; ++i)\n"
      << "        if (!isfinite(k[i])) finite = 0;\n"
      << "    if (!finite) {\n"
      << "        s->diverged = 1;\n"
      << "        return 1;\n"
      << "    }\n"
      << "    for (i = 0; i < " << N << "; ++i) {\n"
      << "        double ke = 0;\n"
      << "        for (j = 0; j < " << M << "; ++j) ke += k[i * " << M << " + j] * e[j];\n"
      << (discrete ? "        s->xhat[i] = a[i] + ke;\n" : "        s->xhat[i] = s->xhat[i] + dt * (a[i] + ke);\n")
      << "    }\n"
      << "    return 0;\n"
      << "}\n";
    return c.str();
}

bool is_c_identifier(const std::string& s) {
    if (s.empty() || s.size() > 40 || std::isdigit(static_cast<unsigned char>(s[0]))) return false;
    for (char ch : s)
        if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_')) return false;
    return true;
}

// What one network contributes to the C: its weights, forward pass and gain law (the variant's law, or an
// ensemble member's static PREFIX_mE_gain_matrix when law is null), and its counts.
struct Parts {
    std::string code, header;  // definitions; prototypes for PREFIX.h
    std::string shape;         // "double network 6-8-8-21 (261 parameters), rho = 0.03", for PREFIX.h's comment
    long long parameters = 0, bytes = 0, flops = 0;
    std::string precision;
};

template <typename T>
Parts network_parts(const std::string& path, const RunConfig& cfg, const CGainLaw* law, const std::string& P,
                    const std::string& S) {
    Checkpoint<T> ck = ckpt_read<T>(path);
    NetworkC<T> net = network_c(ck.net, P);
    const LawC lawc = law ? law->emit(cfg, ck.net.step, P) : gain_matrix_c(ck.net.step, P, S, true);
    Parts out;
    out.code = net.data + net.code + lawc.code;
    out.header = lawc.header;
    out.parameters = (long long)ck.net.theta.size();
    out.bytes = net.bytes;
    out.flops = net.flops + lawc.flops;
    out.precision = sizeof(T) == sizeof(float) ? "float" : "double";
    std::ostringstream sh;
    sh << out.precision << " network ";
    for (std::size_t l = 0; l < ck.net.step.shape.sizes.size(); ++l) sh << (l ? "-" : "") << ck.net.step.shape.sizes[l];
    sh << " (" << out.parameters << " parameters), rho = " << cfg.rho;
    out.shape = sh.str();
    return out;
}

Parts parts_of(const std::string& path, const RunConfig& cfg, const CGainLaw* law, const std::string& P,
               const std::string& S) {
    return ckpt_precision(path) == "double" ? network_parts<double>(path, cfg, law, P, S)
                                            : network_parts<float>(path, cfg, law, P, S);
}

// An ensemble (method.md 16.15): the members' gains PREFIX_mE_gain_matrix, and PREFIX_gain_matrix their mean,
// added in the order given and then divided, as filters/dnn.cpp GainFilter does.
Parts ensemble_parts(const std::vector<std::string>& paths, const std::vector<RunConfig>& cfgs, const std::string& P) {
    Parts out;
    std::ostringstream mean;
    const int nm = cfgs[0].n * cfgs[0].m;
    mean << "/* K(x^, t) [n x m]: the mean of the " << paths.size()
         << " networks' gains, added in their order, then divided (filters/dnn.cpp GainFilter) */\n"
         << "void " << P << "_gain_matrix(double* k, const double* xhat, double t) {\n"
         << "    double ki[" << P << "_N * " << P << "_M];\n"
         << "    int i;\n";
    for (std::size_t e = 0; e < paths.size(); ++e) {
        const std::string Pm = P + "_m" + std::to_string(e);
        Parts p = parts_of(paths[e], cfgs[e], nullptr, Pm, P);
        out.code += "/* ensemble member " + std::to_string(e) + ": " + paths[e] + " */\n" + p.code;
        out.shape += std::string(e ? "\n" : "") + "   member " + std::to_string(e) + ": " + paths[e] + ", " + p.shape;
        out.parameters += p.parameters;
        out.bytes += p.bytes;
        out.flops += p.flops;
        if (out.precision.find(p.precision) == std::string::npos)
            out.precision += (out.precision.empty() ? "" : " and ") + p.precision;
        if (e == 0) {
            mean << "    " << Pm << "_gain_matrix(k, xhat, t);\n";
        } else {
            mean << "    " << Pm << "_gain_matrix(ki, xhat, t);\n"
                 << "    for (i = 0; i < " << P << "_N * " << P << "_M; ++i) k[i] += ki[i];\n";
        }
    }
    mean << "    for (i = 0; i < " << P << "_N * " << P << "_M; ++i) k[i] /= " << lit(double(paths.size())) << ";\n"
         << "}\n\n";
    out.code += mean.str() + gain_step_law_c(P);
    out.header = "/* the ensemble's gain K(x^, t) [n x m] (row-major), the mean of its networks' gains, at the estimate "
                 "x^ [n] and time t */\nvoid " + P + "_gain_matrix(double* k, const double* xhat, double t);\n\n";
    out.flops += (long long)(paths.size()) * nm;  // the E - 1 sums and the division
    return out;
}

ExportResult write_export(const std::vector<std::string>& paths, const RunConfig& cfg, const Parts& parts,
                          const ExportOptions& opt) {
    const std::string& P = opt.prefix;
    const bool ensemble = paths.size() > 1;
    const std::string sys = system_c(*cfg.system, P);
    const int n = cfg.n, m = cfg.m, nv = cfg.nv;

    ExportResult res;
    res.parameters = parts.parameters;
    res.weight_bytes = parts.bytes;
    res.variant = cfg.variant;
    res.precision = parts.precision;
    res.system = cfg.system->name();
    res.networks = (int)paths.size();
    // per step, besides the system's functions: the network(s), the law (head, least squares, gain; an ensemble's
    // mean), e = y - C, the update
    res.flops_per_step = parts.flops + m + n * (2LL * m + 2);

    std::string upper = P;
    for (char& ch : upper) ch = char(std::toupper(static_cast<unsigned char>(ch)));
    std::ostringstream h;
    h << "/* " << P << ".h: a trained hinf DNN filter, exported by `hinf export` (docs/export.md). C99, no dependency\n"
      << "   but libm. ";
    if (ensemble)
        h << "An ensemble of " << paths.size() << " '" << res.variant << "' networks for the system '" << res.system
          << "', mode measured:\n   the mean of their gains (docs/method.md 16.15), x^(0) and dt from member 0.\n"
          << parts.shape << "\n";
    else
        h << "From: " << paths[0] << "\n   system '" << res.system << "', variant '" << res.variant << "', " << parts.shape
          << ", mode measured.\n";
    h << "   Use: " << P << "_state s; " << P << "_init(&s, NULL); then per measurement y(t_k) [m]:\n"
      << "   " << P << "_step(&s, y, t_k, " << P << "_DT); s.xhat [n] is then the estimate of x(t_k + dt)"
      << (cfg.system->discrete_time() ? ",\n   the one-step prediction of x_(k+1) (a discrete-time system: t_k = k dt gives the step index k)"
                                      : "")
      << ". */\n";
    std::vector<std::string> known_inputs;
    if (const ExprSystem* e = expr_system_of(*cfg.system)) known_inputs = e->inputs();
    if (!known_inputs.empty()) {
        std::string names;
        for (const auto& u : known_inputs) names += (names.empty() ? "" : ", ") + u;
        h << "/* The system reads known inputs u(t) = (" << names << "): " << P << ".c holds the table of the config it was\n"
          << "   trained with. To feed live inputs, compile " << P << ".c with -D" << P << "_EXTERNAL_INPUTS and define\n"
          << "   void " << P << "_inputs_at(double t, double* u); u [" << known_inputs.size() << "] is read at each time the step evaluates the model. */\n";
    }
    h << "#ifndef " << upper << "_H\n#define " << upper << "_H\n\n"
      << "#ifdef __cplusplus\nextern \"C\" {\n#endif\n\n"
      << "#define " << P << "_N " << n << "  /* states */\n"
      << "#define " << P << "_M " << m << "  /* outputs */\n"
      << "#define " << P << "_NV " << nv << " /* disturbance inputs */\n"
      << "#define " << P << "_DT " << lit(cfg.dt) << " /* the training config's dt [s] */\n\n"
      << "typedef struct {\n"
      << "    double xhat[" << P << "_N]; /* the estimate */\n"
      << "    int diverged;            /* 1 once a step met a non-finite estimate or gain: x^ stays frozen */\n"
      << "} " << P << "_state;\n\n"
      << "/* x^(t_0) = xhat0 [n], or the config's [filter] xhat0 when xhat0 is NULL */\n"
      << "void " << P << "_init(" << P << "_state* s, const double* xhat0);\n"
      << "/* consumes y(t) [m] (t: the time of the measurement, dt: the step to the next one); 0: ok, 1: diverged */\n"
      << "int " << P << "_step(" << P << "_state* s, const double* y, double t, double dt);\n"
      << parts.header
      << "#ifdef __cplusplus\n}\n#endif\n\n#endif\n";

    std::ostringstream c;
    c << "/* " << P << ".c: see " << P << ".h. Generated by `hinf export`; regenerate rather than edit. */\n"
      << "#include \"" << P << ".h\"\n\n#include <float.h>\n#include <math.h>\n\n"
      << "#define " << P << "_PI 3.14159265358979323846\n\n"
      << sys << parts.code << filter_c(cfg, P);

    std::filesystem::create_directories(opt.dir);
    const std::string hpath = opt.dir + "/" + P + ".h", cpath = opt.dir + "/" + P + ".c";
    write_text_atomic(hpath, [&](std::ostream& o) { o << h.str(); });
    write_text_atomic(cpath, [&](std::ostream& o) { o << c.str(); });
    res.files = {hpath, cpath};
    return res;
}

}  // namespace

ExportResult export_c(const std::vector<std::string>& paths, const ExportOptions& opt) {
    HINF_CHECK(is_c_identifier(opt.prefix), "--name '" + opt.prefix +
                                                "' is not a C identifier (letters, digits, _, not starting with a "
                                                "digit, at most 40 characters)");
    HINF_CHECK(!opt.dir.empty(), "--c needs a directory");
    HINF_CHECK(!paths.empty(), "export: give the checkpoint of a trained network");
    HINF_CHECK(paths.size() == 1 || opt.ensemble,
               "export: " + std::to_string(paths.size()) + " checkpoints given; give one, or add --ensemble to export "
               "the mean gain of several gain networks (as compare --ensemble; ensemble=True from the library)");
    HINF_CHECK(!opt.ensemble || paths.size() >= 2, "export --ensemble averages the gains of two or more networks: "
                                                   "give their checkpoints (" + std::to_string(paths.size()) + " given)");
    std::vector<RunConfig> cfgs;
    for (const std::string& path : paths) {
        ckpt_verify(path);
        cfgs.push_back(ckpt_config(path));
        const RunConfig& c = cfgs.back();
        // a discrete system's filter is the gain variant's one-step predictor (the other variants are continuous)
        HINF_CHECK(!c.system->discrete_time() || c.variant == "gain",
                   "export: checkpoint '" + path + "' is a '" + c.variant + "' network of a discrete-time system; "
                   "only variant \"gain\" filters discrete-time systems (docs/method.md 16.8)");
        if (!opt.ensemble) continue;
        HINF_CHECK(c.variant == "gain", "export --ensemble: network '" + path + "' is variant \"" + c.variant +
                                            "\"; only variant \"gain\" networks (a gain K(x^)) can be averaged");
        HINF_CHECK(same_trained_model(c, cfgs[0]),
                   "export --ensemble: network '" + path + "' was trained on another model than '" + paths[0] +
                       "' (its [system] table or its noise levels differ); an ensemble averages networks trained on "
                       "one model, e.g. with different training.seed");
    }
    const RunConfig& cfg = cfgs[0];
    if (opt.ensemble) return write_export(paths, cfg, ensemble_parts(paths, cfgs, opt.prefix), opt);
    const CGainLaw* law = nullptr;
    std::string variants;
    for (const CGainLaw& g : kGainLaws) {
        variants += std::string(variants.empty() ? "" : ", ") + g.variant;
        if (cfg.variant == g.variant) law = &g;
    }
    HINF_CHECK(law != nullptr, "export: checkpoint '" + paths[0] + "' is a '" + cfg.variant +
                                   "' network, which has no C gain law (exportable: " + variants +
                                   "; add one to kGainLaws in src/export/export_c.cpp)");
    return write_export(paths, cfg, parts_of(paths[0], cfg, law, opt.prefix, opt.prefix), opt);
}

}  // namespace hinf
