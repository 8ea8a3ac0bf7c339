// Output heads (see head.hpp). Small dense loops over any n; one sample per call; the n x n temporaries live in
// the caller's workspace (head_workspace), so nothing is allocated here and no state count is too large.
#include "head.hpp"


namespace hinf::kern {

namespace {
// M = I + tril(o), row-major lower-triangular packing of o: (0,0), (1,0), (1,1), (2,0), ...
template <typename T>
void unpack_m(double* M, const T* o, int n) {
    int k = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) M[a * n + b] = (a == b) ? 1.0 : 0.0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) M[a * n + b] += double(o[k++]);
}
}  // namespace

int head_outputs(Head kind, int n) { return kind == HEAD_GRADIENT ? n : n * (n + 1) / 2; }

std::int64_t head_workspace(Head kind, int n) { return kind == HEAD_GRADIENT ? 0 : 2 * std::int64_t(n) * n; }

namespace {

template <int N, typename T>
void head_forward_n(double* p, double* P, const T* o, const double* xt, const HeadParams& hp, double* work) {
    const int n = N > 0 ? N : hp.n;
    if (hp.kind == HEAD_GRADIENT) {
        for (int a = 0; a < n; ++a) p[a] = hp.scale * double(o[a]);
        return;
    }
    double* M = work;  // [n x n]
    unpack_m(M, o, n);
    // P = c (M M^T + eps I)
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) {
            double s = 0;
            for (int k = 0; k <= b; ++k) s += M[a * n + k] * M[b * n + k];  // both lower-triangular
            s = hp.scale * (s + (a == b ? hp.eps : 0.0));
            P[a * n + b] = s;
            P[b * n + a] = s;
        }
    for (int a = 0; a < n; ++a) {
        double s = 0;
        for (int b = 0; b < n; ++b) s += P[a * n + b] * xt[b];
        p[a] = s;
    }
}

template <int N, typename T>
void head_backward_n(T* d_o, const double* gp, const double* gP, const T* o, const double* xt, const HeadParams& hp,
                     double* work) {
    const int n = N > 0 ? N : hp.n;
    if (hp.kind == HEAD_GRADIENT) {
        for (int a = 0; a < n; ++a) d_o[a] = T(hp.scale * gp[a]);
        return;
    }
    double* M = work;          // [n x n]
    double* S = work + n * n;  // [n x n]
    unpack_m(M, o, n);
    // G = dL/dP (as a function of all n^2 entries): explicit gP plus p = P x~  =>  gp x~^T
    // P = c M M^T  =>  dL/dM = c (G + G^T) M ; only the lower triangle of M is free. S = G + G^T once, each
    // G entry formed where it is used (no G array); M[j][b] = 0 for j < b, so the sum starts at j = b (the
    // skipped terms are exact zeros: same bits)
    for (int a = 0; a < n; ++a)
        for (int j = 0; j < n; ++j) {
            const double g_aj = (gP ? gP[a * n + j] : 0.0) + gp[a] * xt[j];
            const double g_ja = (gP ? gP[j * n + a] : 0.0) + gp[j] * xt[a];
            S[a * n + j] = g_aj + g_ja;
        }
    int k = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) {
            double s = 0;
            for (int j = b; j < n; ++j) s += S[a * n + j] * M[j * n + b];
            d_o[k++] = T(hp.scale * s);
        }
}

}  // namespace

// n = 6 (the missile models) compiled with the state dimension known, so the small loops unroll;
// the same operations in the same order as the general version
template <typename T>
void head_forward(double* p, double* P, const T* o, const double* xt, const HeadParams& hp, double* work) {
    if (hp.n == 6) return head_forward_n<6>(p, P, o, xt, hp, work);
    head_forward_n<0>(p, P, o, xt, hp, work);
}

template <typename T>
void head_backward(T* d_o, const double* gp, const double* gP, const T* o, const double* xt, const HeadParams& hp,
                   double* work) {
    if (hp.n == 6) return head_backward_n<6>(d_o, gp, gP, o, xt, hp, work);
    head_backward_n<0>(d_o, gp, gP, o, xt, hp, work);
}

template void head_forward<float>(double*, double*, const float*, const double*, const HeadParams&, double*);
template void head_forward<double>(double*, double*, const double*, const double*, const HeadParams&, double*);
template void head_backward<float>(float*, const double*, const double*, const float*, const double*, const HeadParams&,
                                   double*);
template void head_backward<double>(double*, const double*, const double*, const double*, const double*,
                                    const HeadParams&, double*);

}  // namespace hinf::kern
