// MLP forward/backward with Eigen products (single-threaded per chunk; the caller splits samples
// over threads), and their naive twins. See mlp.hpp for the shape legend.
#include "mlp.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cstring>

namespace hinf::kern {

int MlpShape::max_width() const { return *std::max_element(sizes.begin(), sizes.end()); }

std::int64_t MlpShape::param_count() const {
    std::int64_t n = 0;
    for (int l = 1; l <= layers(); ++l) n += std::int64_t(sizes[l]) * sizes[l - 1] + sizes[l];
    return n;
}

std::int64_t MlpShape::weight_offset(int l) const {
    std::int64_t n = 0;
    for (int k = 1; k < l; ++k) n += std::int64_t(sizes[k]) * sizes[k - 1] + sizes[k];
    return n;
}

std::int64_t MlpShape::act_per_sample() const {
    std::int64_t n = 0;
    for (int l = 1; l <= layers(); ++l) n += sizes[l];
    return n;
}

std::int64_t MlpShape::act_offset(int l, int B) const {
    std::int64_t n = 0;
    for (int k = 1; k < l; ++k) n += std::int64_t(sizes[k]) * B;
    return n;
}

namespace {

template <typename T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <typename T>
using MapM = Eigen::Map<RowMat<T>>;
template <typename T>
using MapCM = Eigen::Map<const RowMat<T>>;
template <typename T>
using MapCV = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 1>>;
template <typename T>
using MapV = Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, 1>>;

}  // namespace

template <typename T>
void mlp_forward(T* acts, const T* theta, const T* x, int B, const MlpShape& shape) {
    const T a1 = T(shape.slope_positive), a2 = T(shape.slope_negative);
    const T* in = x;
    for (int l = 1; l <= shape.layers(); ++l) {
        const int din = shape.sizes[l - 1], dout = shape.sizes[l];
        const T* W = theta + shape.weight_offset(l);
        const T* b = W + std::int64_t(dout) * din;
        T* H = acts + shape.act_offset(l, B);
        MapM<T> Hm(H, B, dout);
        // H_l = H_{l-1} W_l^T + 1 b_l^T
        Hm.noalias() = MapCM<T>(in, B, din) * MapCM<T>(W, dout, din).transpose();
        Hm.rowwise() += MapCV<T>(b, dout).transpose();
        if (l < shape.layers()) {
            const std::int64_t cnt = std::int64_t(B) * dout;
            for (std::int64_t i = 0; i < cnt; ++i) H[i] = H[i] > T(0) ? a1 * H[i] : a2 * H[i];
        }
        in = H;
    }
}

template <typename T>
void mlp_backward(T* dtheta, T* dx, const T* theta, const T* x, const T* acts, const T* dout_in, int B,
                  const MlpShape& shape, T* scratch) {
    const T a1 = T(shape.slope_positive), a2 = T(shape.slope_negative);
    const int L = shape.layers(), wmax = shape.max_width();
    T* G = scratch;                             // dL/dz_l   [B x D_l]
    T* Gprev = scratch + std::int64_t(B) * wmax;  // dL/dz_{l-1}
    std::memcpy(G, dout_in, sizeof(T) * std::size_t(B) * shape.outputs());
    for (int l = L; l >= 1; --l) {
        const int din = shape.sizes[l - 1], dl = shape.sizes[l];
        const T* W = theta + shape.weight_offset(l);
        T* dW = dtheta + shape.weight_offset(l);
        T* db = dW + std::int64_t(dl) * din;
        const T* Hin = (l == 1) ? x : acts + shape.act_offset(l - 1, B);
        MapCM<T> Gm(G, B, dl);
        // dW_l += G_l^T H_{l-1};  db_l += column sums of G_l
        MapM<T>(dW, dl, din).noalias() += Gm.transpose() * MapCM<T>(Hin, B, din);
        // plain loop, not Eigen's colwise().sum(): a vectorised reduction peels by address alignment,
        // which would make the bits depend on where the buffers happen to live
        for (int s = 0; s < B; ++s)
            for (int o = 0; o < dl; ++o) db[o] += G[std::int64_t(s) * dl + o];
        if (l == 1 && !dx) break;
        // dL/dH_{l-1} = G_l W_l
        T* target = (l == 1) ? dx : Gprev;
        MapM<T>(target, B, din).noalias() = Gm * MapCM<T>(W, dl, din);
        if (l > 1) {
            // through LeakyReLU: H and z share their sign (both slopes positive)
            const std::int64_t cnt = std::int64_t(B) * din;
            for (std::int64_t i = 0; i < cnt; ++i) Gprev[i] *= Hin[i] > T(0) ? a1 : a2;
            std::swap(G, Gprev);
        }
    }
}

template <typename T>
void mlp_forward_naive(T* acts, const T* theta, const T* x, int B, const MlpShape& shape) {
    const int L = shape.layers();
    for (int s = 0; s < B; ++s) {
        for (int l = 1; l <= L; ++l) {
            const int din = shape.sizes[l - 1], dout = shape.sizes[l];
            const T* W = theta + shape.weight_offset(l);
            const T* b = W + std::int64_t(dout) * din;
            const T* in = (l == 1) ? x + std::int64_t(s) * din : acts + shape.act_offset(l - 1, B) + std::int64_t(s) * din;
            T* out = acts + shape.act_offset(l, B) + std::int64_t(s) * dout;
            for (int o = 0; o < dout; ++o) {
                T z = b[o];
                for (int i = 0; i < din; ++i) z += W[std::int64_t(o) * din + i] * in[i];
                if (l < L) z = z > T(0) ? T(shape.slope_positive) * z : T(shape.slope_negative) * z;
                out[o] = z;
            }
        }
    }
}

template <typename T>
void mlp_backward_naive(T* dtheta, T* dx, const T* theta, const T* x, const T* acts, const T* dout_in, int B,
                        const MlpShape& shape) {
    const int L = shape.layers();
    std::vector<T> g, gprev;
    for (int s = 0; s < B; ++s) {
        g.assign(dout_in + std::int64_t(s) * shape.outputs(), dout_in + std::int64_t(s + 1) * shape.outputs());
        for (int l = L; l >= 1; --l) {
            const int din = shape.sizes[l - 1], dl = shape.sizes[l];
            const T* W = theta + shape.weight_offset(l);
            T* dW = dtheta + shape.weight_offset(l);
            T* db = dW + std::int64_t(dl) * din;
            const T* in = (l == 1) ? x + std::int64_t(s) * din : acts + shape.act_offset(l - 1, B) + std::int64_t(s) * din;
            gprev.assign(din, T(0));
            for (int o = 0; o < dl; ++o) {
                db[o] += g[o];
                for (int i = 0; i < din; ++i) {
                    dW[std::int64_t(o) * din + i] += g[o] * in[i];
                    gprev[i] += g[o] * W[std::int64_t(o) * din + i];
                }
            }
            if (l > 1)
                for (int i = 0; i < din; ++i) gprev[i] *= in[i] > T(0) ? T(shape.slope_positive) : T(shape.slope_negative);
            else if (dx)
                for (int i = 0; i < din; ++i) dx[std::int64_t(s) * din + i] = gprev[i];
            g.swap(gprev);
        }
    }
}

#define HINF_INSTANTIATE_MLP(T)                                                                              \
    template void mlp_forward<T>(T*, const T*, const T*, int, const MlpShape&);                              \
    template void mlp_backward<T>(T*, T*, const T*, const T*, const T*, const T*, int, const MlpShape&, T*);  \
    template void mlp_forward_naive<T>(T*, const T*, const T*, int, const MlpShape&);                        \
    template void mlp_backward_naive<T>(T*, T*, const T*, const T*, const T*, const T*, int, const MlpShape&);
HINF_INSTANTIATE_MLP(float)
HINF_INSTANTIATE_MLP(double)

}  // namespace hinf::kern
