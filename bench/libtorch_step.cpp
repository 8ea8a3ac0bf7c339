// Side by side with LibTorch (issue 8): the `paper` variant's training step — same weights (read from
// one of our checkpoints), same minibatch, same loss sqrt(mean eps_i^2) of seed 000 eq. (16) — in hinf's
// kernels and in LibTorch. Checks that loss and gradients agree to float tolerance, then times both
// interleaved (ours, theirs, ours, theirs...) and prints the ratio. Optional target: built only when
// Debian's libtorch-dev is installed (scripts/bench-libtorch installs it and runs this).
#include <malloc.h>
#include <omp.h>
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "adam.hpp"
#include "hinf/error.hpp"
#include "io/checkpoint.hpp"
#include "sampling.hpp"
#include "train/samples.hpp"

extern "C" void openblas_set_num_threads(int);

using namespace hinf;
using Clock = std::chrono::steady_clock;

namespace {

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: hinf-bench-libtorch CHECKPOINT.h5 [repeats=200] [threads=2]\n");
        return 2;
    }
    try {
        const std::string path = argv[1];
        const int repeats = argc > 2 ? std::atoi(argv[2]) : 200;
        const int threads = argc > 3 ? std::atoi(argv[3]) : 2;
        Checkpoint<float> ck = ckpt_read<float>(path);
        RunConfig cfg = ckpt_config(path);
        HINF_CHECK(cfg.variant == "paper", "the LibTorch harness implements the `paper` variant's network and loss; '" +
                                               path + "' holds a " + cfg.variant + " network");
        const kern::StepConfig& sc = ck.net.step;
        const int n = cfg.n, nv = cfg.nv, m = cfg.m, M = int(cfg.batch);

        // the same minibatch as the trainer's first Adam step of the checkpoint's time step
        TimeStepSamples s;
        samples_build(&s, cfg, ck.state.x, ck.state.xhat, ck.state.step);
        std::vector<std::int64_t> idx(M), perm(cfg.samples);
        std::vector<double> work(std::max<std::int64_t>(cfg.samples, M));
        kern::sample_minibatch(idx.data(), M, cfg.samples, cfg.seed, ck.state.step, 1, work.data(), perm.data());

        // LibTorch with its best settings here: one intra-op thread, OpenBLAS on `threads`, malloc kept warm
        torch::set_num_threads(1);
        openblas_set_num_threads(threads);
        mallopt(M_MMAP_THRESHOLD, 1 << 30);
        mallopt(M_TRIM_THRESHOLD, 1 << 30);
        omp_set_num_threads(threads);

        auto opt32 = torch::TensorOptions().dtype(torch::kFloat32);
        auto opt64 = torch::TensorOptions().dtype(torch::kFloat64);
        torch::Tensor z = torch::empty({M, n}, opt32), dA = torch::empty({M, n}, opt64), Bt = torch::empty({M, n, nv}, opt64),
                      dC = torch::empty({M, m}, opt64), q = torch::empty({M}, opt64);
        for (int i = 0; i < M; ++i) {
            std::int64_t k = idx[i];
            for (int a = 0; a < n; ++a) {
                z[i][a] = float(s.xt[k * n + a] / sc.input_scale);
                dA[i][a] = s.dA[k * n + a];
                for (int j = 0; j < nv; ++j) Bt[i][a][j] = s.Bm[(k * n + a) * nv + j];
            }
            for (int j = 0; j < m; ++j) dC[i][j] = s.dC[k * m + j];
            q[i] = s.q[k];
        }
        std::vector<torch::Tensor> W, b;
        for (int l = 1; l <= sc.shape.layers(); ++l) {
            const int din = sc.shape.sizes[l - 1], dout = sc.shape.sizes[l];
            const float* w = ck.net.theta.data() + sc.shape.weight_offset(l);
            W.push_back(torch::from_blob(const_cast<float*>(w), {dout, din}, opt32).clone().requires_grad_(true));
            b.push_back(torch::from_blob(const_cast<float*>(w) + std::int64_t(din) * dout, {dout}, opt32)
                            .clone()
                            .requires_grad_(true));
        }
        const double rho = sc.hjie.rho, cscale = sc.head.scale;
        const double a1 = sc.shape.slope_positive, a2 = sc.shape.slope_negative;
        auto torch_loss = [&]() {
            torch::Tensor h = z;
            for (std::size_t l = 0; l < W.size(); ++l) {
                h = torch::addmm(b[l], h, W[l].t());
                if (l + 1 < W.size()) h = torch::where(h > 0, h * a1, h * a2);
            }
            torch::Tensor p = h.to(torch::kFloat64) * cscale;                       // dV/dx~ (gradient head)
            torch::Tensor btp = torch::bmm(Bt.transpose(1, 2), p.unsqueeze(2)).squeeze(2);  // B^T p
            torch::Tensor eps = q + (p * dA).sum(1) + btp.pow(2).sum(1) / (4 * rho) - rho * dC.pow(2).sum(1);
            return eps.pow(2).mean().sqrt();
        };
        std::vector<torch::Tensor> params;
        for (std::size_t l = 0; l < W.size(); ++l) {
            params.push_back(W[l]);
            params.push_back(b[l]);
        }

        // 1. agreement of loss and gradient
        std::vector<float> grad(ck.net.theta.size());
        kern::StepWorkspace<float> ws;
        kern::HjieSystemView view = s.view();
        kern::StepLoss ours = kern::step_gradient(grad.data(), ck.net.theta.data(), view, idx.data(), M, sc, ws);
        for (auto& t : params) t.mutable_grad() = torch::Tensor();
        torch::Tensor L = torch_loss();
        L.backward();
        double worst = 0, gnorm = 0;
        for (int l = 1; l <= sc.shape.layers(); ++l) {
            const int din = sc.shape.sizes[l - 1], dout = sc.shape.sizes[l];
            const float* g = grad.data() + sc.shape.weight_offset(l);
            auto gw = W[l - 1].grad().contiguous(), gb = b[l - 1].grad().contiguous();
            const float* tw = gw.data_ptr<float>();
            const float* tb = gb.data_ptr<float>();
            for (std::int64_t i = 0; i < std::int64_t(din) * dout; ++i) gnorm = std::max(gnorm, double(std::fabs(tw[i])));
            for (std::int64_t i = 0; i < std::int64_t(din) * dout; ++i)
                worst = std::max(worst, double(std::fabs(g[i] - tw[i])));
            for (int i = 0; i < dout; ++i) worst = std::max(worst, double(std::fabs(g[std::int64_t(din) * dout + i] - tb[i])));
        }
        const double rel_loss = std::fabs(ours.loss - L.item<double>()) / std::fabs(L.item<double>());
        std::printf("loss: hinf %.9g  LibTorch %.9g  (relative difference %.2e)\n", ours.loss, L.item<double>(), rel_loss);
        std::printf("gradient: largest |difference| %.3e, relative to the largest |component| %.3e: %.2e\n", worst,
                    gnorm, worst / gnorm);
        const bool agree = rel_loss < 1e-4 && worst / gnorm < 1e-3;
        std::printf("agreement to float tolerance (loss 1e-4, gradient 1e-3 of its largest component): %s\n",
                    agree ? "yes" : "NO");

        // 2. interleaved timing of one training step (forward, loss, backward, Adam)
        torch::optim::Adam adam(params, torch::optim::AdamOptions(cfg.learning_rate).betas({cfg.beta1, cfg.beta2}).eps(cfg.tau));
        std::vector<float> mom(grad.size(), 0.f), vel(grad.size(), 0.f), theta = ck.net.theta;
        kern::AdamParams ap{cfg.learning_rate, cfg.beta1, cfg.beta2, cfg.tau};
        std::vector<double> t_ours, t_torch;
        for (int r = 0; r < repeats + 10; ++r) {
            // LibTorch's lazy thread-pool initialisation sets OpenMP to its own count (1) on the calling
            // thread after our omp_set_num_threads above: restore ours before each of our steps
            omp_set_num_threads(threads);
            auto t0 = Clock::now();
            kern::step_gradient(grad.data(), theta.data(), view, idx.data(), M, sc, ws);
            kern::adam_update(theta.data(), mom.data(), vel.data(), grad.data(), std::int64_t(grad.size()), r % 30 + 1, ap);
            auto t1 = Clock::now();
            openblas_set_num_threads(threads);  // ours ran OpenBLAS serially per chunk (kern::gemm_prepare)
            adam.zero_grad();
            torch::Tensor loss = torch_loss();
            loss.backward();
            adam.step();
            auto t2 = Clock::now();
            if (r >= 10) {
                t_ours.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
                t_torch.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
            }
        }
        double mo = median(t_ours), mt = median(t_torch);
        std::printf("hinf GEMMs: %s\n", kern::gemm_description(kern::default_gemm_path()).c_str());
        std::printf("training step, %d threads, M = %d, median of %d interleaved repeats: hinf %.3f ms, LibTorch %s %.3f ms "
                    "(torch threads 1, OpenBLAS threads %d): LibTorch/hinf = %.2f\n",
                    threads, M, repeats, mo, TORCH_VERSION, mt, threads, mt / mo);
        return agree ? 0 : 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "hinf-bench-libtorch: error: %s\n", e.what());
        return 2;
    }
}
