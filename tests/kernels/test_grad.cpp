// The whole training loss's gradient with respect to every weight and bias, against central finite
// differences in double precision, for both heads/objectives (paper and dissipative) and both games
// (seed 000's one HJIE, seed 001's two coupled HJIEs).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <random>

#include "train_step.hpp"

using namespace hinf::kern;

namespace {

struct Problem {
    int n = 3, nv = 1, m = 2, N = 23;
    std::vector<double> xt, dA, Bm, dC, q;
    HjieSystemView view() const { return {n, nv, m, xt.data(), dA.data(), Bm.data(), dC.data(), q.data()}; }
};

Problem make_problem(unsigned seed) {
    Problem p;
    std::mt19937 gen(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    auto fill = [&](std::vector<double>& v, std::size_t k) {
        v.resize(k);
        for (auto& x : v) x = u(gen);
    };
    fill(p.xt, std::size_t(p.N) * p.n);
    fill(p.dA, std::size_t(p.N) * p.n);
    fill(p.Bm, std::size_t(p.N) * p.n * p.nv);
    fill(p.dC, std::size_t(p.N) * p.m);
    p.q.resize(p.N);
    for (int i = 0; i < p.N; ++i) p.q[i] = 0.1 * (1 + u(gen));
    return p;
}

void check_gradient(Head head, HjieObjective obj, HjieGame game = HJIE_GAME_HINF) {
    const unsigned seed = 2024;
    INFO("seed " << seed);
    Problem pr = make_problem(seed);
    if (game == HJIE_GAME_MIXED) {
        // seed 001's g is square (nv = n): a full disturbance matrix per sample
        pr.nv = pr.n;
        std::mt19937 g2(seed + 7);
        std::uniform_real_distribution<double> u2(-1, 1);
        pr.Bm.resize(std::size_t(pr.N) * pr.n * pr.nv);
        for (auto& x : pr.Bm) x = u2(g2);
    }
    StepConfig cfg;
    cfg.head.kind = head;
    cfg.head.n = pr.n;
    cfg.head.scale = 0.7;
    cfg.head.eps = 0.05;
    cfg.shape.sizes = {pr.n, 7, 5, head_outputs(head, pr.n)};
    cfg.shape.slope_positive = 0.9;
    cfg.shape.slope_negative = 0.1;
    cfg.objective = obj;
    cfg.hjie.rho = 0.4;
    cfg.hjie.game = game;
    cfg.hjie.margin = 0.3;  // keeps part of the samples inside the hinge
    cfg.hjie.h2_weight = 0.5;
    cfg.hjie.horizon = 2.0;
    cfg.hjie.h2_reference = 1.5;
    cfg.input_scale = 1.3;
    cfg.chunk = 5;  // several chunks, the last one partial
    std::mt19937 gen(seed + 1);
    std::uniform_real_distribution<double> u(-0.6, 0.6);
    std::vector<double> theta(cfg.shape.param_count());
    for (auto& v : theta) v = u(gen);
    std::vector<std::int64_t> idx(pr.N);
    for (int i = 0; i < pr.N; ++i) idx[i] = (i * 7) % pr.N;
    StepWorkspace<double> ws;
    std::vector<double> grad(theta.size());
    StepLoss L0 = step_gradient(grad.data(), theta.data(), pr.view(), idx.data(), pr.N, cfg, ws);
    REQUIRE(L0.loss > 0);
    if (obj == HJIE_OBJECTIVE_DISSIPATIVE) REQUIRE(L0.hinge > 0);
    std::vector<double> scratch(theta.size());
    double worst = 0;
    for (std::size_t j = 0; j < theta.size(); ++j) {
        const double h = 1e-6 * std::max(1.0, std::fabs(theta[j]));
        std::vector<double> tp = theta, tm = theta;
        tp[j] += h;
        tm[j] -= h;
        double lp = step_gradient(scratch.data(), tp.data(), pr.view(), idx.data(), pr.N, cfg, ws).loss;
        double lm = step_gradient(scratch.data(), tm.data(), pr.view(), idx.data(), pr.N, cfg, ws).loss;
        double fd = (lp - lm) / (2 * h);
        double rel = std::fabs(fd - grad[j]) / std::max({std::fabs(fd), std::fabs(grad[j]), 1e-3 * std::fabs(L0.loss)});
        worst = std::max(worst, rel);
    }
    INFO("largest relative error " << worst << " over " << theta.size() << " parameters");
    CHECK(worst < 1e-6);
}

}  // namespace

TEST_CASE("loss gradient matches central differences: paper variant", "[kernel][grad]") {
    check_gradient(HEAD_GRADIENT, HJIE_OBJECTIVE_PAPER);
}

TEST_CASE("loss gradient matches central differences: dissipative variant", "[kernel][grad]") {
    check_gradient(HEAD_QUADRATIC, HJIE_OBJECTIVE_DISSIPATIVE);
}

TEST_CASE("two-residual loss gradient matches central differences: paper variant", "[kernel][grad][mixed]") {
    check_gradient(HEAD_GRADIENT, HJIE_OBJECTIVE_PAPER, HJIE_GAME_MIXED);
}

TEST_CASE("two-residual loss gradient matches central differences: dissipative variant", "[kernel][grad][mixed]") {
    check_gradient(HEAD_QUADRATIC, HJIE_OBJECTIVE_DISSIPATIVE, HJIE_GAME_MIXED);
}
