// Network creation (shapes, scales, initialisation) and the frozen-network wrapper.
#include "net/network.hpp"

#include <cmath>

#include "random.hpp"

namespace hinf {

kern::StepConfig network_step_config(const RunConfig& cfg) {
    kern::StepConfig sc;
    const bool paper = cfg.variant == "paper";
    sc.head.kind = paper ? kern::HEAD_GRADIENT : kern::HEAD_QUADRATIC;
    sc.head.n = cfg.n;
    sc.input_scale = cfg.resolved_input_scale();
    // gradient head: p = c s_in o, so o ~ z = x~/s_in when dV/dx~ ~ c x~; quadratic head: P = c (M M^T + eps I)
    sc.head.scale = paper ? cfg.resolved_output_scale() * sc.input_scale : cfg.resolved_output_scale();
    sc.head.eps = cfg.resolved_eps();
    sc.shape.sizes.push_back(cfg.n);
    for (int h : cfg.hidden) sc.shape.sizes.push_back(h);
    sc.shape.sizes.push_back(kern::head_outputs(sc.head.kind, cfg.n));
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
    return sc;
}

template <typename T>
Network<T> network_shell(const RunConfig& cfg) {
    Network<T> net;
    net.step = network_step_config(cfg);
    net.theta.assign(static_cast<std::size_t>(net.step.shape.param_count()), T(0));
    return net;
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
    return net;
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
        kern::network_eval(p, nullptr, net_.theta.data(), xt, count, net_.step, ws_);
    }
    const kern::StepConfig& step_config() const override { return net_.step; }
    std::unique_ptr<FrozenNetwork> clone() const override { return std::make_unique<FrozenImpl<T>>(net_); }

private:
    Network<T> net_;
    kern::StepWorkspace<T> ws_;
};
}  // namespace

template <typename T>
std::unique_ptr<FrozenNetwork> network_freeze(Network<T> net) {
    return std::make_unique<FrozenImpl<T>>(std::move(net));
}

template Network<float> network_create<float>(const RunConfig&);
template Network<float> network_shell<float>(const RunConfig&);
template Network<double> network_shell<double>(const RunConfig&);
template Network<double> network_create<double>(const RunConfig&);
template std::unique_ptr<FrozenNetwork> network_freeze<float>(Network<float>);
template std::unique_ptr<FrozenNetwork> network_freeze<double>(Network<double>);

}  // namespace hinf
