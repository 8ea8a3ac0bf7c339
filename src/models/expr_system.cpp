// Expression systems: GiNaC reads f, g, h and differentiates them exactly; muParser's byte code evaluates the
// printed results over a batch of states (docs/method.md §12). Not a parser of our own.
#include "models/expr_system.hpp"

#include <ginac/ginac.h>
#include <muParser.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <set>
#include <sstream>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "models/weighted_system.hpp"

namespace hinf {

struct ExprSystem::Compiled {
    bool constant = true;
    double value = 0;  // if constant
    int program = -1;  // else: index into programs_ and Workspace::parsers
    std::string text;  // what muParser evaluates (CanonicalPrinter: GiNaC's tree in an order of ours)
};

struct ExprSystem::Workspace {
    std::vector<std::unique_ptr<mu::Parser>> parsers;  // one per program
    std::vector<double> point;                         // [n + 2 + inputs]: the state being evaluated, t, k, u(t)
};

namespace {
// Each thread keeps the workspaces it released last (two systems: a truth and a filter's model), so that the
// one-state calls made from every OpenMP thread (training's per-sample f, g, h, each at its own t) take no lock;
// the shared pool is the fallback. A workspace reads only its own buffer, so one cached here never depends on
// its system; one whose system is gone (its mark expired) is dropped when the slot is needed.
struct CachedWorkspace {
    std::weak_ptr<const char> owner;
    std::unique_ptr<ExprSystem::Workspace> ws;
};
thread_local CachedWorkspace t_workspaces[2];

bool same_owner(const std::weak_ptr<const char>& a, const std::shared_ptr<const char>& b) {
    return !a.owner_before(b) && !b.owner_before(a);
}


// step(s) = 1 for s >= 0, else 0: a switch such as the missile's atmosphere at 9144 m (z >= 9144 is the
// upper layer). Its derivative is zero except at the switch itself, where it does not exist: the Jacobians
// use zero (docs/method.md).
double mu_step(double s) {
    return s >= 0 ? 1.0 : 0.0;
}
double mu_pow(double a, double b) {
    return std::pow(a, b);
}
double mu_fabs(double a) {
    return std::fabs(a);
}
double mu_atan2(double a, double b) {
    return std::atan2(a, b);
}

// The functions GiNaC's C print uses beyond muParser's own (sin, cos, exp, log, sqrt, tanh, ...).
void define_functions(mu::Parser& p) {
    p.DefineFun("step", mu_step);
    p.DefineFun("pow", mu_pow);
    p.DefineFun("fabs", mu_fabs);
    p.DefineFun("atan2", mu_atan2);
    p.DefineConst("pi", M_PI);
    p.DefineConst("Pi", M_PI);
}

const std::set<std::string>& reserved_names() {
    static const std::set<std::string> names = {
        "t",     "pi",   "Pi",   "I",     "Euler", "Catalan", "Digits", "sin", "cos", "tan",  "asin", "acos", "atan",
        "atan2", "sinh", "cosh", "tanh",  "asinh", "acosh",   "atanh",  "exp", "log", "sqrt", "abs",  "fabs", "pow",
        "step",  "ln",   "log2", "log10", "sign",  "rint",    "min",    "max", "sum", "avg",  "_pi",  "_e"};
    return names;
}

// at most 64 characters: muParser refuses identifiers of 100 and more (found by fuzz/fuzz_config.cpp)
bool is_identifier(const std::string& s) {
    if (s.empty() || s.size() > 64 || std::isdigit(static_cast<unsigned char>(s[0]))) return false;
    for (char c : s)
        if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
    return true;
}

std::string quoted(const ExprText& e) {
    return e.where + " \"" + e.text + "\"";
}

std::string first_line(const std::string& s) {
    return s.substr(0, s.find('\n'));
}

std::string c_text_plain(const GiNaC::ex& e) {
    std::ostringstream os;
    os << e;
    return os.str();
}

// muParser reads the user's text first: it reports unknown symbols and syntax errors with a position. One parser
// serves a system's expressions (building one per expression was a fifth of a 40-state system's construction);
// symbols added since the last call (the definitions, in order) are defined on it first.
struct SyntaxParser {
    mu::Parser p;
    std::deque<double> values;  // the symbols' dummy values (a deque: their addresses stay put as it grows)
    std::size_t defined = 0;
};
void check_syntax(SyntaxParser& sp, const ExprText& e, const std::vector<std::string>& symbols, const std::string& known) {
    // GiNaC's parser and diff recurse on the nesting: bound it before either sees the text
    const std::size_t max_length = 5000;
    int depth = 0, max_depth = 0;
    for (char c : e.text) {
        depth += c == '(' ? 1 : c == ')' ? -1 : 0;
        max_depth = std::max(max_depth, depth);
    }
    HINF_CHECK(e.text.size() <= max_length, e.where + ": the expression has " + std::to_string(e.text.size()) +
                                                " characters, more than " + std::to_string(max_length) +
                                                " (split it with definitions = [\"name = ...\"])");
    HINF_CHECK(max_depth <= 100, quoted(e) + ": parentheses nest " + std::to_string(max_depth) +
                                     " deep, more than 100 (split it with definitions = [\"name = ...\"])");
    mu::Parser& p = sp.p;
    try {
        for (; sp.defined < symbols.size(); ++sp.defined) {
            sp.values.push_back(1.0);
            p.DefineVar(symbols[sp.defined], &sp.values.back());
        }
        p.SetExpr(e.text);
        p.Eval();
    } catch (const mu::Parser::exception_type& err) {
        const int at = err.GetPos() + 1;  // muParser counts from 0
        if (err.GetCode() == mu::ecUNASSIGNABLE_TOKEN)
            HINF_FAIL(quoted(e) + ": unknown symbol '" + err.GetToken() + "' at character " + std::to_string(at) +
                      " (known: " + known + ")");
        std::string msg = err.GetMsg();
        auto cut = msg.find(" at position");
        if (cut != std::string::npos) msg.resize(cut);
        if (!msg.empty() && msg.back() == '.') msg.pop_back();
        HINF_FAIL(quoted(e) + ": " + msg + (at > 0 ? " at character " + std::to_string(at) : std::string()) +
                  " (fix the expression; operators + - * / ^, functions as in docs/formats.md)");
    }
}

// Definitions are substituted, not evaluated by name: a chain where each uses the one before twice doubles the
// expression per definition (2^40 nodes at 40). Count the tree's nodes up to a bound, iteratively (no recursion,
// at most `limit` visits), before GiNaC differentiates or prints anything.
constexpr std::size_t kMaxExpressionNodes = 20000;
std::size_t expression_nodes(const GiNaC::ex& e, std::size_t limit) {
    std::vector<GiNaC::ex> stack{e};
    std::size_t count = 0;
    while (!stack.empty() && count <= limit) {
        GiNaC::ex x = stack.back();
        stack.pop_back();
        ++count;
        for (std::size_t i = 0; i < x.nops(); ++i) stack.push_back(x.op(i));
    }
    return count;
}
void check_expression_size(const GiNaC::ex& e, const std::string& what) {
    HINF_CHECK(expression_nodes(e, kMaxExpressionNodes) <= kMaxExpressionNodes,
               what + ": expands to more than " + std::to_string(kMaxExpressionNodes) +
                   " terms once its definitions are substituted (a definition that uses the one before it twice "
                   "doubles the size each time: rewrite the chain, or fold it into parameters)");
}

// GiNaC's message without its "GiNaC: parse error at line 0, column 0: " preamble (it has no positions).
std::string ginac_reason(const std::exception& err) {
    std::string msg = first_line(err.what());
    for (const std::string noise : {"GiNaC: ", "parse error at line 0, column 0: "})
        for (auto at = msg.find(noise); at != std::string::npos; at = msg.find(noise)) msg.erase(at, noise.size());
    return msg;
}

// min(a, b) and max(a, b) (more arguments: folded from the left) written with step(), which GiNaC reads and whose
// derivative is 0 wherever it exists, so each has the derivative of the argument it takes:
//   min(a, b) = a + step(a - b)*(b - a),   max(a, b) = a + step(b - a)*(b - a)   (a tie takes b, equal to a)
// muParser has both itself and checks the user's text first; text it would refuse is left for it to report.
std::string rewrite_min_max(const std::string& s) {
    auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
    std::string out;
    std::size_t i = 0;
    while (i < s.size()) {
        if (!word(s[i])) {
            out += s[i++];
            continue;
        }
        std::size_t j = i;
        while (j < s.size() && word(s[j])) ++j;
        const std::string name = s.substr(i, j - i);
        std::size_t open = j;
        while (open < s.size() && s[open] == ' ') ++open;
        if ((name != "min" && name != "max") || open >= s.size() || s[open] != '(') {
            out += name;
            i = j;
            continue;
        }
        std::vector<std::string> args;
        std::size_t start = open + 1, p = open + 1;
        for (int depth = 0; p < s.size(); ++p) {
            const char c = s[p];
            if (c == '(') ++depth;
            else if (c == ')' && depth-- == 0) break;
            else if (c == ',' && depth == 0) {
                args.push_back(s.substr(start, p - start));
                start = p + 1;
            }
        }
        if (p >= s.size()) return out + s.substr(i);  // unbalanced: GiNaC says so
        args.push_back(s.substr(start, p - start));
        std::string acc = "(" + rewrite_min_max(args[0]) + ")";
        for (std::size_t a = 1; a < args.size(); ++a) {
            const std::string b = "(" + rewrite_min_max(args[a]) + ")";
            const std::string d = name == "min" ? acc + " - " + b : b + " - " + acc;
            acc = "(" + acc + " + step(" + d + ")*(" + b + " - " + acc + "))";
        }
        out += acc;
        i = p + 1;
    }
    return out;
}

// GiNaC reads it again for the symbolic work; its grammar is a subset of muParser's (no comparisons, no ?:).
GiNaC::ex read_symbolic(const ExprText& e, const GiNaC::symtab& table) {
    GiNaC::parser reader(table, true);
    GiNaC::ex out;
    try {
        out = reader(rewrite_min_max(e.text));
    } catch (const std::exception& err) {
        HINF_FAIL(quoted(e) + ": GiNaC, which differentiates it, cannot read it (" + ginac_reason(err) +
                  "); use + - * / ^ (with parentheses: (a^b)^c), numbers and sin cos tan asin acos atan atan2 sinh "
                  "cosh tanh asinh acosh atanh exp log sqrt abs pow step min max; write a switch as step(s) (1 for s >= 0, "
                  "else 0)");
    }
    GiNaC::ex numeric_form;  // sqrt(-2) stays a power until evaluated in floating point
    try {
        numeric_form = out.evalf();
    } catch (const std::exception& err) {
        HINF_FAIL(quoted(e) + ": GiNaC cannot evaluate it (" + ginac_reason(err) + ")");
    }
    // GiNaC prints an exact power x^n for muParser by repeated multiplication: with n = 10^20 that never
    // ends (found by the config fuzzer), so exact exponents are bounded; 2.5e3 or 1e20 (floats) are not
    for (auto it = out.preorder_begin(); it != out.preorder_end(); ++it) {
        if (!GiNaC::is_a<GiNaC::power>(*it) || !GiNaC::is_a<GiNaC::numeric>(it->op(1))) continue;
        const GiNaC::numeric& k = GiNaC::ex_to<GiNaC::numeric>(it->op(1));
        if (k.is_rational() && (GiNaC::abs(k.numer()) > 1000 || GiNaC::abs(k.denom()) > 1000))
            HINF_FAIL(quoted(e) + ": the exact exponent " + c_text_plain(it->op(1)) +
                      " is too large (at most 1000 in numerator and denominator; write it as a float, e.g. 2.5e3, "
                      "or rescale the quantity)");
    }
    for (auto it = numeric_form.preorder_begin(); it != numeric_form.preorder_end(); ++it)
        if (GiNaC::is_a<GiNaC::numeric>(*it) && !GiNaC::ex_to<GiNaC::numeric>(*it).is_real())
            HINF_FAIL(quoted(e) + ": has the complex value " + c_text_plain(*it) +
                      " (a square root or log of a negative constant?): f, g, h must be real");
    return out;
}

// d/dx step(s) is zero wherever it exists; GiNaC leaves it as D[0](step)(s).
struct zero_step_derivative : public GiNaC::map_function {
    GiNaC::ex operator()(const GiNaC::ex& e) override {
        if (GiNaC::is_a<GiNaC::fderivative>(e) &&
            GiNaC::ex_to<GiNaC::fderivative>(e).get_serial() == GiNaC::step_SERIAL::serial)
            return 0;
        return e.map(*this);
    }
};

std::string c_text(const GiNaC::ex& e) {
    std::ostringstream os;
    e.print(GiNaC::print_csrc_double(os));
    return os.str();
}

// The text muParser evaluates, in an order hinf defines (docs/method.md §12). GiNaC keeps the operands of sums
// and products in the order of hash values that depend on the load address of its library (address-space
// randomisation) and on how many symbols the process made before, so its own print_csrc_double gives
// another order, and other round-off, from one process (MPI rank, resumed run, Python module) to the next.
// This printer walks GiNaC's tree and sorts the operands of every sum and product by their own canonical
// text; it also picks the sign of a sum itself (its first sorted term positive), because GiNaC normalises
// (a - b)^-1 to -(b - a)^-1 by whichever term its hash order puts first. Leaves (numbers, symbols, pi) and
// the powers of symbols keep GiNaC's C syntax: numbers with 17 digits, x^3 as (x*x*x).
class CanonicalPrinter {
public:
    std::string operator()(const GiNaC::ex& e) const { return print(e).with_sign; }

private:
    struct Text {
        std::string magnitude;  // |value| (a sum: with the signs that make its first term positive)
        bool negative = false;  // value = -magnitude
        std::string with_sign;  // the value itself (a sum: its terms with their own signs)
        bool sum = false;       // magnitude is a sum: parenthesised as an operand of * / or a term
    };

    static Text plain(std::string s, bool negative = false) {
        Text t;
        t.magnitude = std::move(s);
        t.negative = negative;
        t.with_sign = negative ? "-" + t.magnitude : t.magnitude;
        return t;
    }
    static std::string operand(const Text& t) { return t.sum ? "(" + t.magnitude + ")" : t.magnitude; }
    // a divisor: anything but a name, a number, a call or a parenthesised group gets parentheses
    static std::string divisor(const Text& t) {
        int depth = 0;
        for (char c : t.magnitude) {
            depth += c == '(' ? 1 : c == ')' ? -1 : 0;
            if (depth == 0 && (c == '*' || c == '/' || c == '+' || c == '-')) return "(" + t.magnitude + ")";
        }
        return t.magnitude;
    }
    static bool before(const Text& a, const Text& b) {
        return a.magnitude != b.magnitude ? a.magnitude < b.magnitude : a.negative < b.negative;
    }

    static Text number(const GiNaC::numeric& v) {
        std::string s = c_text(GiNaC::abs(v));
        if (s.find('/') != std::string::npos && s.front() != '(') s = "(" + s + ")";
        return plain(s, v.is_negative());
    }

    // GiNaC's x^n for a symbol (or pi) and an integer n: repeated multiplication, as print_csrc_double does
    static std::string symbol_power(const std::string& x, long n) {
        if (n == 1) return x;
        if (n == 2) return x + "*" + x;
        if (n % 2) return x + "*" + symbol_power(x, n - 1);
        const std::string half = symbol_power(x, n / 2);
        return "(" + half + ")*(" + half + ")";
    }

    Text power(const GiNaC::ex& base, const GiNaC::ex& exponent) const {
        if (GiNaC::is_a<GiNaC::numeric>(exponent) && exponent.info(GiNaC::info_flags::integer)) {
            const long n = GiNaC::ex_to<GiNaC::numeric>(exponent).to_long();
            if (GiNaC::is_a<GiNaC::symbol>(base) || GiNaC::is_a<GiNaC::constant>(base)) {
                const std::string x = c_text(base);
                return plain(n > 0 ? "(" + symbol_power(x, n) + ")" : "1.0/(" + symbol_power(x, -n) + ")");
            }
            // an integer power of -b is (-1)^n b^n: the sign goes to the caller, b is printed positive
            const Text b = print(base);
            const bool negative = b.negative && n % 2 != 0;
            if (n == -1) return plain("1.0/(" + b.magnitude + ")", negative);
            return plain("pow(" + b.magnitude + "," + number(GiNaC::numeric(n)).with_sign + ")", negative);
        }
        return plain("pow(" + print(base).with_sign + "," + print(exponent).with_sign + ")");
    }

    Text product(const GiNaC::ex& e) const {
        bool negative = false;
        std::string coefficient;
        std::vector<Text> up, down;  // factors x^k (k not a negative integer) and divisors x^n (x^-n, n > 0)
        for (std::size_t i = 0; i < e.nops(); ++i) {
            const GiNaC::ex& f = e.op(i);
            Text t;
            if (GiNaC::is_a<GiNaC::numeric>(f)) {
                t = number(GiNaC::ex_to<GiNaC::numeric>(f));
                if (t.magnitude != "1.0") coefficient = t.magnitude;
            } else if (GiNaC::is_a<GiNaC::power>(f) && GiNaC::is_a<GiNaC::numeric>(f.op(1)) &&
                       f.op(1).info(GiNaC::info_flags::negint)) {
                t = f.op(1).is_equal(-1) ? print(f.op(0)) : power(f.op(0), -f.op(1));
                down.push_back(t);
            } else {
                t = print(f);
                up.push_back(t);
            }
            negative = negative != t.negative;
        }
        std::sort(up.begin(), up.end(), before);
        std::sort(down.begin(), down.end(), before);
        std::string s = coefficient;
        for (const Text& t : up) s += (s.empty() ? "" : "*") + operand(t);
        if (s.empty()) s = "1.0";
        for (const Text& t : down) s += "/" + divisor(t);
        return plain(s, negative);
    }

    Text sum(const GiNaC::ex& e) const {
        std::vector<Text> terms;
        Text constant;
        bool has_constant = false;
        for (std::size_t i = 0; i < e.nops(); ++i) {
            if (GiNaC::is_a<GiNaC::numeric>(e.op(i))) {
                constant = number(GiNaC::ex_to<GiNaC::numeric>(e.op(i)));
                has_constant = true;
            } else {
                terms.push_back(print(e.op(i)));
            }
        }
        std::sort(terms.begin(), terms.end(), before);
        if (has_constant) terms.push_back(constant);  // the number last, as GiNaC prints it
        auto join = [&](bool flip) {
            std::string s;
            for (std::size_t i = 0; i < terms.size(); ++i) {
                const bool minus = terms[i].negative != flip;
                s += (minus ? "-" : i == 0 ? "" : "+") + operand(terms[i]);
            }
            return s;
        };
        Text t;
        t.negative = !terms.empty() && terms.front().negative;
        t.magnitude = join(t.negative);
        t.with_sign = join(false);
        t.sum = true;
        return t;
    }

    Text print(const GiNaC::ex& e) const {
        if (GiNaC::is_a<GiNaC::numeric>(e)) return number(GiNaC::ex_to<GiNaC::numeric>(e));
        if (GiNaC::is_a<GiNaC::symbol>(e) || GiNaC::is_a<GiNaC::constant>(e)) return plain(c_text(e));
        if (GiNaC::is_a<GiNaC::add>(e)) return sum(e);
        if (GiNaC::is_a<GiNaC::mul>(e)) return product(e);
        if (GiNaC::is_a<GiNaC::power>(e)) return power(e.op(0), e.op(1));
        if (GiNaC::is_a<GiNaC::function>(e) && !GiNaC::is_a<GiNaC::fderivative>(e)) {
            std::string s = GiNaC::ex_to<GiNaC::function>(e).get_name() + "(";
            for (std::size_t i = 0; i < e.nops(); ++i) s += (i ? "," : "") + print(e.op(i)).with_sign;
            return plain(s + ")");
        }
        throw std::runtime_error("no muParser form for " + c_text_plain(e) + " (class " +
                                 GiNaC::ex_to<GiNaC::basic>(e).class_name() + ")");
    }
};

// A constant entry (g = 0/1, dC/dx of a linear h, 2*pi) is evaluated once, from its canonical text, by a parser
// the caller keeps for all of them (a muParser parser is costly to build: one per entry of a 40-state Jacobian made
// the system's construction most of a short training run, 14x slower under AddressSanitizer)
double constant_value(mu::Parser& p, const std::string& text) {
    try {
        p.SetExpr(text);
        return p.Eval();
    } catch (const mu::Parser::exception_type& err) {
        throw std::runtime_error("muParser cannot read the constant \"" + text + "\": " + err.GetMsg());
    }
}

}  // namespace

ExprSystem::~ExprSystem() = default;

ExprSystem::ExprSystem(const ExprSpec& spec)
    : n_(int(spec.states.size())),
      nv_(spec.disturbance_dim),
      m_(spec.output_dim),
      discrete_(spec.discrete),
      period_(spec.period),
      states_(spec.states),
      units_(spec.units),
      angles_(spec.angle_outputs),
      angle_states_(spec.angle_states),
      parameters_(spec.parameters),
      inputs_(spec.inputs),
      input_t_(spec.input_t),
      input_values_(spec.input_values),
      input_linear_(spec.input_linear) {
    // names: identifiers, distinct, not t / pi / a function
    HINF_CHECK(n_ >= 1, spec.where + " states: give at least one state name, e.g. states = [\"x1\", \"x2\"]");
    if (units_.empty()) units_.assign(n_, "");
    std::set<std::string> seen;
    std::vector<std::string> symbols;
    auto add_name = [&](const std::string& name, const std::string& what) {
        HINF_CHECK(is_identifier(name), spec.where + " " + what + " '" + name +
                                            "' is not a name (letters, digits and _, not starting with a digit, at most 64 characters)");
        HINF_CHECK(!reserved_names().count(name) && !(discrete_ && name == "k"),
                   spec.where + " " + what + " '" + name +
                       "' is reserved (the time t, a constant of the expression parsers: pi, Pi, I, the imaginary "
                       "unit, Euler, Catalan, Digits, _pi, _e, or a function name" +
                       (discrete_ ? ", or k, the step index of a discrete system" : "") + "): rename it");
        HINF_CHECK(seen.insert(name).second, spec.where + " " + what + " '" + name + "' is defined twice: rename one");
        symbols.push_back(name);
    };
    for (const auto& s : states_) add_name(s, "state");
    for (const auto& p : parameters_) add_name(p.first, "parameter");
    for (const auto& u : inputs_) add_name(u, "input");
    if (!inputs_.empty()) {
        const std::size_t rows = input_t_.size();
        HINF_CHECK(rows >= 2 && input_values_.size() == rows * inputs_.size(),
                   spec.where + " inputs: the table needs at least 2 rows and one value per input and row");
        for (std::size_t r = 0; r < rows; ++r)
            HINF_CHECK(std::isfinite(input_t_[r]) && (r == 0 || input_t_[r] > input_t_[r - 1]),
                       spec.where + " inputs: time " + std::to_string(input_t_[r]) + " s of row " + std::to_string(r + 1) +
                           " is not after the row before it (the table's times must increase strictly)");
        for (double v : input_values_)
            HINF_CHECK(std::isfinite(v), spec.where + " inputs: the table holds a value that is not finite");
        input_early_ = 1e-9 * (input_t_.back() - input_t_.front()) / double(rows - 1);
    }
    symbols.push_back("t");
    if (discrete_) {
        HINF_CHECK(period_ > 0 && std::isfinite(period_),
                   spec.where + " time = \"discrete\" needs [filter] dt > 0 (the sampling period that stamps the steps)");
        symbols.push_back("k");
    }

    // shapes, before any expression is read
    auto shape = [&](std::size_t got, std::size_t want, const std::string& key, const std::string& why) {
        HINF_CHECK(got == want, spec.where + " " + key + " has " + std::to_string(got) + " entries, expected " +
                                    std::to_string(want) + " (" + why + ")");
    };
    shape(spec.f.size(), std::size_t(n_), "f", "one per state");
    shape(spec.g.size(), std::size_t(n_), "g", "one row per state");
    for (std::size_t i = 0; i < spec.g.size(); ++i)
        shape(spec.g[i].size(), std::size_t(nv_), "g row " + std::to_string(i + 1), "one entry per disturbance");
    shape(spec.h.size(), std::size_t(m_), "h", "one per measurement");

    GiNaC::symtab table;
    std::vector<GiNaC::realsymbol> state_symbols;
    for (const auto& s : states_) {
        state_symbols.emplace_back(s);
        table[s] = state_symbols.back();
    }
    for (const auto& p : parameters_) table[p.first] = GiNaC::realsymbol(p.first);
    for (const auto& u : inputs_) table[u] = GiNaC::realsymbol(u);  // known signals: no derivative in x
    table["t"] = GiNaC::realsymbol("t");
    if (discrete_) table["k"] = GiNaC::realsymbol("k");
    table["pi"] = GiNaC::Pi;

    auto known_list = [&]() {
        std::string out;
        for (const auto& s : symbols) out += (out.empty() ? "" : ", ") + s;
        return out + ", pi";
    };
    SyntaxParser syntax;
    define_functions(syntax.p);
    auto read = [&](const ExprText& e) {
        check_syntax(syntax, e, symbols, known_list());
        GiNaC::ex x = read_symbolic(e, table);
        check_expression_size(x, quoted(e));
        return x;
    };
    // definitions: each may use the states, parameters, t and the definitions above it
    for (const auto& d : spec.definitions) {
        GiNaC::ex e = read(d.second);
        add_name(d.first, "definition");
        table[d.first] = e;
    }

    std::vector<GiNaC::ex> f, g, h;
    for (const auto& e : spec.f) f.push_back(read(e));
    for (const auto& row : spec.g)
        for (const auto& e : row) g.push_back(read(e));
    for (const auto& e : spec.h) h.push_back(read(e));

    // exact Jacobians dA/dx [n x n] and dC/dx [m x n]; GiNaC reports trouble (a pole met while simplifying,
    // say) as its own exception types, turned into one line here
    try {
        zero_step_derivative no_step;
        std::vector<GiNaC::ex> df, dh;
        for (const auto& fi : f)
            for (const auto& xj : state_symbols) df.push_back(no_step(fi.diff(xj)));
        for (const auto& hi : h)
            for (const auto& xj : state_symbols) dh.push_back(no_step(hi.diff(xj)));

        const CanonicalPrinter canonical;
        mu::Parser constants;
        define_functions(constants);
        auto compile = [&](const std::vector<GiNaC::ex>& exprs, std::vector<Compiled>* out) {
            for (const auto& e : exprs) {
                Compiled c;
                check_expression_size(e, spec.where + ": a derivative of f or h");
                c.text = canonical(e);
                GiNaC::ex value = e.evalf();
                if (GiNaC::is_a<GiNaC::numeric>(value) && GiNaC::ex_to<GiNaC::numeric>(value).is_real()) {
                    // the number muParser gives for the canonical text: GiNaC's evalf sums in its hash order. An
                    // integer below 2^53 (the zeros of a Jacobian, mostly) is that number exactly either way
                    const bool integer = GiNaC::is_a<GiNaC::numeric>(e) && GiNaC::ex_to<GiNaC::numeric>(e).is_integer() &&
                                         std::fabs(GiNaC::ex_to<GiNaC::numeric>(e).to_double()) < 9007199254740992.0;
                    c.value = integer ? GiNaC::ex_to<GiNaC::numeric>(e).to_double() : constant_value(constants, c.text);
                } else {
                    c.constant = false;
                    HINF_CHECK(c.text.size() <= std::size_t(mu::MaxLenExpression),
                               spec.where + ": an expression (or its derivative) prints to " +
                                   std::to_string(c.text.size()) + " characters once its definitions are "
                                   "substituted, more than the " + std::to_string(mu::MaxLenExpression) +
                                   " muParser evaluates (shorten the expressions or the chain of definitions)");
                    c.program = int(programs_.size());
                    programs_.push_back(c.text);
                }
                out->push_back(std::move(c));
            }
        };
        compile(f, &f_);
        compile(g, &g_);
        compile(h, &h_);
        compile(df, &df_);
        compile(dh, &dh_);
    } catch (const Error&) {
        throw;
    } catch (const std::exception& err) {
        HINF_FAIL(spec.where + ": GiNaC failed on the expressions: " + ginac_reason(err) +
                  " (check f, g, h for divisions by zero or undefined functions)");
    }
    // a first workspace evaluates every program once: a print muParser cannot read is our bug, said here
    std::unique_ptr<Workspace> ws = workspace_acquire();
    for (std::size_t k = 0; k < programs_.size(); ++k) {
        try {
            ws->parsers[k]->Eval();
        } catch (const mu::Parser::exception_type& err) {
            HINF_FAIL(spec.where + ": muParser cannot read GiNaC's print \"" + programs_[k] + "\": " + err.GetMsg() +
                      " (please report this expression)");
        }
    }
    workspace_release(std::move(ws));
}

std::unique_ptr<ExprSystem::Workspace> ExprSystem::workspace_acquire() const {
    for (CachedWorkspace& c : t_workspaces)
        if (c.ws && same_owner(c.owner, alive_)) return std::move(c.ws);
    {
        std::lock_guard<std::mutex> lock(pool_mutex_);
        if (!pool_.empty()) {
            std::unique_ptr<Workspace> ws = std::move(pool_.back());
            pool_.pop_back();
            return ws;
        }
    }
    auto ws = std::make_unique<Workspace>();
    ws->point.assign(std::size_t(n_ + 2) + inputs_.size(), 0.0);
    for (const auto& text : programs_) {
        auto p = std::make_unique<mu::Parser>();
        define_functions(*p);
        for (const auto& par : parameters_) p->DefineConst(par.first, par.second);
        for (int j = 0; j < n_; ++j) p->DefineVar(states_[j], &ws->point[std::size_t(j)]);
        p->DefineVar("t", &ws->point[std::size_t(n_)]);
        if (discrete_) p->DefineVar("k", &ws->point[std::size_t(n_ + 1)]);
        for (std::size_t i = 0; i < inputs_.size(); ++i) p->DefineVar(inputs_[i], &ws->point[std::size_t(n_ + 2) + i]);
        p->SetExpr(text);
        ws->parsers.push_back(std::move(p));
    }
    return ws;
}

void ExprSystem::workspace_release(std::unique_ptr<Workspace> ws) const {
    // first the slot it came from: the owner stays, so the steady state writes no reference count (the threads
    // would otherwise bounce the system's control block between their caches at every evaluate)
    for (CachedWorkspace& c : t_workspaces)
        if (!c.ws && same_owner(c.owner, alive_)) {
            c.ws = std::move(ws);
            return;
        }
    for (CachedWorkspace& c : t_workspaces)
        if (!c.ws || c.owner.expired()) {
            c.owner = alive_;
            c.ws = std::move(ws);
            return;
        }
    std::lock_guard<std::mutex> lock(pool_mutex_);
    pool_.push_back(std::move(ws));
}

void ExprSystem::evaluate(double* out, const std::vector<Compiled>& exprs, const double* x, double t,
                          std::int64_t count) const {
    // One state at a time through muParser's byte code (about 40 ns per entry): its bulk mode costs ~25 us per
    // call in fixed overhead, which dominated the one-state and sigma-point calls of EKF/UKF. Large batches
    // (the N training samples, PF particles) are split over threads, each with its own workspace; per-state
    // results do not depend on the split. Inside compare's/operate's parallel runs this stays serial.
    const std::int64_t k_count = std::int64_t(exprs.size());
    bool all_constant = true;
    for (const Compiled& c : exprs) all_constant = all_constant && c.constant;
    if (all_constant) {  // g = [0, 1], dC/dx of a linear h: no byte code to run
        for (std::int64_t s = 0; s < count; ++s)
            for (std::int64_t k = 0; k < k_count; ++k) out[s * k_count + k] = exprs[k].value;
        return;
    }
    // the states [begin, end) through one workspace
    auto run = [&](Workspace& ws, std::int64_t begin, std::int64_t end) {
        double* point = ws.point.data();
        point[n_] = t;
        point[n_ + 1] = discrete_ ? std::nearbyint(t / period_) : 0.0;  // t = k dt, so k is exact after rounding
        if (!inputs_.empty()) inputs_at(t, point + n_ + 2);
        for (std::int64_t s = begin; s < end; ++s) {
            for (int j = 0; j < n_; ++j) point[j] = x[s * n_ + j];
            double* o = out + s * k_count;
            for (std::int64_t k = 0; k < k_count; ++k)
                o[k] = exprs[k].constant ? exprs[k].value : ws.parsers[exprs[k].program]->Eval();
        }
    };
    if (count < 256 || omp_in_parallel()) {
        // serial, and outside any OpenMP construct: `omp parallel if (false)` still builds a one-thread team, and
        // libgomp allocates it on the heap each time, once per sample in gain training's per-sample calls
        std::unique_ptr<Workspace> ws = workspace_acquire();
        run(*ws, 0, count);
        workspace_release(std::move(ws));
        return;
    }
#pragma omp parallel
    {
        std::unique_ptr<Workspace> ws = workspace_acquire();
        const int threads = omp_get_num_threads(), me = omp_get_thread_num();
        // the contiguous blocks of schedule(static)
        const std::int64_t chunk = count / threads, extra = count % threads;
        const std::int64_t begin = me * chunk + std::min<std::int64_t>(me, extra);
        run(*ws, begin, begin + chunk + (me < extra ? 1 : 0));
        workspace_release(std::move(ws));
    }
}

std::pair<double, double> ExprSystem::time_span() const {
    if (inputs_.empty()) return System::time_span();
    return {input_t_.front(), input_t_.back()};
}

void ExprSystem::inputs_at(double t, double* u) const {
    const std::size_t q = inputs_.size(), rows = input_t_.size();
    if (q == 0) return;
    const auto after = std::upper_bound(input_t_.begin(), input_t_.end(), t + input_early_);
    const std::size_t j = after == input_t_.begin() ? 0 : std::size_t(after - input_t_.begin()) - 1;
    const double* a = input_values_.data() + j * q;
    if (!input_linear_ || j + 1 == rows || t <= input_t_[j]) {
        std::copy(a, a + q, u);
        return;
    }
    const double* b = a + q;
    const double w = std::min(1.0, (t - input_t_[j]) / (input_t_[j + 1] - input_t_[j]));
    for (std::size_t i = 0; i < q; ++i) u[i] = a[i] + w * (b[i] - a[i]);
}

void ExprSystem::drift(double* a, const double* x, double t, std::int64_t count) const {
    evaluate(a, f_, x, t, count);
}

void ExprSystem::disturbance_gain(double* B, const double* x, double t, std::int64_t count) const {
    evaluate(B, g_, x, t, count);
}

void ExprSystem::measurement(double* c, const double* x, double t, std::int64_t count) const {
    evaluate(c, h_, x, t, count);
}

void ExprSystem::drift_jacobian(double* J, const double* x, double t) const {
    evaluate(J, df_, x, t, 1);
}

void ExprSystem::measurement_jacobian(double* H, const double* x, double t) const {
    evaluate(H, dh_, x, t, 1);
}

std::vector<std::string> ExprSystem::compiled(const std::string& which) const {
    const std::vector<Compiled>* list = which == "f"    ? &f_
                                        : which == "g"  ? &g_
                                        : which == "h"  ? &h_
                                        : which == "df" ? &df_
                                        : which == "dh" ? &dh_
                                                        : nullptr;
    HINF_CHECK(list, "ExprSystem::compiled: '" + which + "' is not one of f, g, h, df, dh");
    std::vector<std::string> out;
    for (const auto& c : *list) out.push_back(c.text);
    return out;
}

const ExprSystem* expr_system_of(const System& sys) {
    const System* s = &sys;
    if (const auto* w = dynamic_cast<const WeightedSystem*>(s)) s = &w->inner();
    return dynamic_cast<const ExprSystem*>(s);
}

std::string expr_library_versions() {
    return "GiNaC " + std::to_string(GiNaC::version_major) + "." + std::to_string(GiNaC::version_minor) + "." +
           std::to_string(GiNaC::version_micro) + " (parse, differentiate), muParser " +
           std::string(mu::ParserVersion.substr(0, mu::ParserVersion.find(' '))) + " (evaluate)";
}

std::unique_ptr<System> make_expr_system(ConfigSection& s, double period) {
    ExprSpec spec;
    spec.where = s.where("kind");
    spec.where = spec.where.substr(0, spec.where.rfind(" kind"));  // "file.toml:3: [system]"
    auto require = [&](const std::string& key, const std::string& example) {
        s.require(key, "is required for kind = \"expr\" (e.g. " + example + ", see docs/byos.md)");
    };
    require("states", "states = [\"x1\", \"x2\"]");
    require("f", "f = [\"x2\", \"-x1\"]");
    require("g", "g = [[\"0\"], [\"1\"]]");
    require("h", "h = [\"x1\"]");
    require("measurements", "measurements = 1");
    spec.states = s.get_strings("states", {});
    const int n = int(spec.states.size());
    spec.units = s.get_strings("units", std::vector<std::string>(std::size_t(n), ""), n);
    spec.disturbance_dim = int(s.get_int("disturbances", 1, 1, 10000));
    spec.output_dim = int(s.get_int("measurements", 1, 1, 10000));
    spec.parameters = s.get_number_table("parameters");
    // known inputs: config/run_config.cpp has put a file's table in place (inputs = "file.csv" reads as this table)
    const std::vector<std::pair<std::string, std::vector<double>>> columns = s.get_column_table("inputs");
    if (!columns.empty()) {
        const auto time = std::find_if(columns.begin(), columns.end(), [](const auto& c) { return c.first == "t"; });
        if (time == columns.end())
            s.reject("inputs", "has no column t (the times of its rows, in s; e.g. inputs = { t = [0, 10], u = [1, 1] })");
        if (columns.size() < 2) s.reject("inputs", "has only the times t: name at least one input beside them");
        spec.input_t = time->second;
        const std::size_t rows = spec.input_t.size();
        for (const auto& c : columns)
            if (c.first != "t") spec.inputs.push_back(c.first);
        spec.input_values.resize(rows * spec.inputs.size());
        std::size_t i = 0;
        for (const auto& c : columns) {
            if (c.first == "t") continue;
            for (std::size_t r = 0; r < rows; ++r) spec.input_values[r * spec.inputs.size() + i] = c.second[r];
            ++i;
        }
    }
    if (spec.inputs.empty() && s.has("input_interpolation"))
        s.reject("input_interpolation", "applies to a table of known inputs, and [system] names none (inputs = \"file.csv\")");
    spec.input_linear = s.get_string("input_interpolation", "hold", {"hold", "linear"}) == "linear";
    auto texts = [&](const std::string& key, const std::vector<std::string>& list) {
        std::vector<ExprText> out;
        for (std::size_t i = 0; i < list.size(); ++i)
            out.push_back({s.where(key) + " entry " + std::to_string(i + 1), list[i]});
        return out;
    };
    std::vector<std::string> defs = s.get_strings("definitions", {});
    for (std::size_t i = 0; i < defs.size(); ++i) {
        const auto eq = defs[i].find('=');
        const std::string where = s.where("definitions") + " entry " + std::to_string(i + 1);
        HINF_CHECK(eq != std::string::npos, where + " \"" + defs[i] + "\" must read \"name = expression\"");
        std::string name = defs[i].substr(0, eq);
        name.erase(0, name.find_first_not_of(" \t"));
        name.erase(name.find_last_not_of(" \t") + 1);
        spec.definitions.push_back({name, {where, defs[i].substr(eq + 1)}});
    }
    spec.f = texts("f", s.get_strings("f", {}));
    std::vector<std::vector<std::string>> g = s.get_string_rows("g");
    for (std::size_t i = 0; i < g.size(); ++i) {
        std::vector<ExprText> row;
        for (std::size_t j = 0; j < g[i].size(); ++j)
            row.push_back(
                {s.where("g") + " row " + std::to_string(i + 1) + " entry " + std::to_string(j + 1), g[i][j]});
        spec.g.push_back(row);
    }
    spec.h = texts("h", s.get_strings("h", {}));
    spec.discrete = s.get_string("time", "continuous", {"continuous", "discrete"}) == "discrete";
    spec.period = period;
    // outputs that are angles (a bearing, a phase): 1-based like the error messages' "h entry j"
    std::vector<std::int64_t> angles = s.get_ints("angle_outputs", {}, 1, spec.output_dim);
    std::sort(angles.begin(), angles.end());
    if (std::adjacent_find(angles.begin(), angles.end()) != angles.end())
        s.reject("angle_outputs", "names output " + std::to_string(*std::adjacent_find(angles.begin(), angles.end())) +
                                      " twice (list each output that is an angle in radians once, 1-based as in h)");
    for (std::int64_t j : angles) spec.angle_outputs.push_back(int(j - 1));
    // states that are angles (a heading, a pendulum that spins): 1-based like the states list
    std::vector<std::int64_t> angle_states = s.get_ints("angle_states", {}, 1, std::int64_t(spec.states.size()));
    std::sort(angle_states.begin(), angle_states.end());
    if (std::adjacent_find(angle_states.begin(), angle_states.end()) != angle_states.end())
        s.reject("angle_states", "names state " +
                                     std::to_string(*std::adjacent_find(angle_states.begin(), angle_states.end())) +
                                     " twice (list each state that is an angle in radians once, 1-based as in states)");
    for (std::int64_t j : angle_states) spec.angle_states.push_back(int(j - 1));
    return std::make_unique<ExprSystem>(spec);
}

}  // namespace hinf
