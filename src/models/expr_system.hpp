// A system written in the config ([system] kind = "expr"): f, g, h as expressions in the states, named
// parameters and t, read by GiNaC (parsing, exact symbolic Jacobians dA/dx, dC/dx) and evaluated over a batch
// of states by muParser's byte code. Not a parser of our own: both grammars are the libraries'; see docs/formats.md.
#pragma once
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "models/system.hpp"

namespace hinf {

class ConfigSection;

/// One expression with the text that locates it in error messages ("file.toml:7: [system] f[2]").
struct ExprText {
    std::string where;
    std::string text;
};

/// Everything [system] kind = "expr" says, before any expression is read.
struct ExprSpec {
    std::vector<std::string> states, units;                     // n names, n units ("" if not given)
    std::vector<std::pair<std::string, double>> parameters;     // named constants
    std::vector<std::pair<std::string, ExprText>> definitions;  // name = expression, in order (may use earlier ones)
    int disturbance_dim = 1, output_dim = 1;                    // nv, m as declared
    std::vector<ExprText> f;                                    // n entries: A(x, t)
    std::vector<std::vector<ExprText>> g;                       // n rows of nv entries: B(x, t)
    std::vector<ExprText> h;                                    // m entries: C(x, t)
    std::string where;                                          // "file.toml: [system]" for shape errors
    bool discrete = false;  // [system] time = "discrete": f is the map x_{k+1} = f + g v, and k may be used
    double period = 0.0;    // discrete only: the sampling period dt ([filter] dt), k = round(t / period)
    std::vector<int> angle_outputs;  // outputs that are angles in radians (0-based, ascending): differences wrap
    std::vector<int> angle_states;   // states that are angles in radians (0-based, ascending): differences wrap
    // known inputs u(t) ([system] inputs): their names, the table's strictly increasing times [rows >= 2] and values
    // [rows x inputs] row-major; between rows a zero-order hold (the last row at or before t) or linear interpolation
    std::vector<std::string> inputs;
    std::vector<double> input_t, input_values;
    bool input_linear = false;
};

/// The system of an ExprSpec (seed 000 eq. (1) with A = f, B = g, C = h; in discrete time
/// x_{k+1} = f(x_k, k) + g(x_k, k) w_k, y_k = h(x_k, k) + v_k, the step index k beside t = k dt). Every expression is checked
/// (syntax, unknown symbols, shapes) in the constructor, which throws hinf::Error naming the key, the
/// expression and the position. Safe to call from several threads at once (compare and operate split
/// their runs over OpenMP threads): each concurrent call takes its own workspace from a pool.
class ExprSystem : public System {
  public:
    explicit ExprSystem(const ExprSpec& spec);
    ~ExprSystem() override;
    std::string name() const override { return "expr"; }
    int state_dim() const override { return n_; }
    int disturbance_dim() const override { return nv_; }
    int output_dim() const override { return m_; }
    void drift(double* a, const double* x, double t, std::int64_t count) const override;
    void disturbance_gain(double* B, const double* x, double t, std::int64_t count) const override;
    void measurement(double* c, const double* x, double t, std::int64_t count) const override;
    void drift_jacobian(double* J, const double* x, double t) const override;
    void measurement_jacobian(double* H, const double* x, double t) const override;
    std::vector<std::string> state_names() const override { return states_; }
    std::vector<std::string> state_units() const override { return units_; }
    bool discrete_time() const override { return discrete_; }
    const std::vector<int>& angle_outputs() const override { return angles_; }
    const std::vector<int>& angle_states() const override { return angle_states_; }
    std::pair<double, double> time_span() const override;
    /// The names of the known inputs ([system] inputs), in the table's order; empty without a table.
    const std::vector<std::string>& inputs() const { return inputs_; }
    /// u(t) [inputs]: the table's zero-order hold or linear interpolation; before its first row (after its last) the
    /// first (last) row. A row stamped up to a billionth of the table's mean step after t already holds at t (t = k dt
    /// and the row's k dt may differ in the last bit).
    void inputs_at(double t, double* u) const;
    /// The table behind inputs_at (the C export writes it out): times [rows], values [rows x inputs], linear or held,
    /// and how early a row takes hold (a billionth of the mean step).
    const std::vector<double>& input_times() const { return input_t_; }
    const std::vector<double>& input_values() const { return input_values_; }
    bool input_linear() const { return input_linear_; }
    double input_early() const { return input_early_; }
    /// Discrete time: the sampling period that stamps the steps (k = round(t / period)); 0 in continuous time.
    double period() const { return period_; }
    /// The expressions muParser evaluates (GiNaC's C-style print): "f", "g", "h", "df" (dA/dx), "dh" (dC/dx).
    std::vector<std::string> compiled(const std::string& which) const;
    /// The named constants of [system] parameters, in order (the C export declares them).
    const std::vector<std::pair<std::string, double>>& parameters() const { return parameters_; }

    struct Compiled;   // one entry: a constant, or the index of its muParser program
    struct Workspace;  // muParser programs bound to their own state buffer: one per concurrent caller

  private:
    void evaluate(double* out, const std::vector<Compiled>& exprs, const double* x, double t, std::int64_t count) const;
    std::unique_ptr<Workspace> workspace_acquire() const;
    void workspace_release(std::unique_ptr<Workspace> ws) const;

    int n_ = 0, nv_ = 0, m_ = 0;
    bool discrete_ = false;
    double period_ = 0.0;
    std::vector<std::string> states_, units_;
    std::vector<int> angles_;
    std::vector<int> angle_states_;
    std::vector<std::pair<std::string, double>> parameters_;
    std::vector<std::string> inputs_;
    std::vector<double> input_t_, input_values_;
    bool input_linear_ = false;
    double input_early_ = 0.0;  // a billionth of the table's mean step (inputs_at)
    std::vector<Compiled> f_, g_, h_, df_, dh_;  // row-major [n], [n x nv], [m], [n x n], [m x n]
    std::vector<std::string> programs_;          // the texts of the non-constant entries
    mutable std::mutex pool_mutex_;
    mutable std::vector<std::unique_ptr<Workspace>> pool_;  // idle workspaces
    // this system's mark in the threads' workspace caches (expr_system.cpp): a cached workspace whose mark has
    // expired belonged to a system that is gone and is dropped
    std::shared_ptr<const char> alive_ = std::make_shared<const char>('\0');
};

/// The expression system `sys` is, or the one inside its noise weighting (models/weighted_system.hpp); null for a
/// built-in system.
const ExprSystem* expr_system_of(const System& sys);

/// "GiNaC 1.8.6 (parse, differentiate), muParser 2.3.3 (evaluate)": the libraries doing the work.
std::string expr_library_versions();

/// Reads [system] kind = "expr" (every key but kind) into a checked ExprSystem; `period` is [filter] dt, the
/// sampling period a discrete system's steps are stamped with (t_k = k period).
std::unique_ptr<System> make_expr_system(ConfigSection& s, double period);

}  // namespace hinf
