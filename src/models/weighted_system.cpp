// See weighted_system.hpp.
#include "models/weighted_system.hpp"

#include <utility>

namespace hinf {

void lower_multiply(const std::vector<double>& L, int k, double* x) {
    for (int j = k - 1; j >= 0; --j) {  // row j reads x_0 .. x_j, which rows below j have not overwritten yet
        double s = 0;
        for (int i = 0; i <= j; ++i)
            if (L[std::size_t(j) * k + i] != 0) s += L[std::size_t(j) * k + i] * x[i];
        x[j] = s;
    }
}

void lower_solve(const std::vector<double>& L, int k, double* x) {
    for (int j = 0; j < k; ++j) {
        double s = x[j];
        for (int i = 0; i < j; ++i)
            if (L[std::size_t(j) * k + i] != 0) s -= L[std::size_t(j) * k + i] * x[i];
        x[j] = s / L[std::size_t(j) * k + j];
    }
}

std::vector<double> lower_inverse(const std::vector<double>& L, int k) {
    std::vector<double> inv(static_cast<std::size_t>(k) * k, 0.0), col(static_cast<std::size_t>(k));
    for (int c = 0; c < k; ++c) {
        for (int j = 0; j < k; ++j) col[std::size_t(j)] = j == c ? 1.0 : 0.0;
        lower_solve(L, k, col.data());
        for (int j = 0; j < k; ++j) inv[std::size_t(j) * k + c] = col[std::size_t(j)];
    }
    return inv;
}

bool is_diagonal(const std::vector<double>& M, int k) {
    for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i)
            if (i != j && M[std::size_t(j) * k + i] != 0) return false;
    return true;
}

std::vector<double> diagonal_of(const std::vector<double>& M, int k) {
    if (M.empty() || !is_diagonal(M, k)) return {};
    std::vector<double> d(static_cast<std::size_t>(k));
    for (int j = 0; j < k; ++j) d[std::size_t(j)] = M[std::size_t(j) * k + j];
    return d;
}

WeightedSystem::WeightedSystem(std::shared_ptr<const System> inner, std::vector<double> W, std::vector<double> U)
    : inner_(std::move(inner)), W_(std::move(W)), U_(std::move(U)) {
    w_diag_ = diagonal_of(W_, output_dim());
    u_diag_ = diagonal_of(U_, disturbance_dim());
}

void WeightedSystem::disturbance_gain(double* B, const double* x, double t, std::int64_t count) const {
    inner_->disturbance_gain(B, x, t, count);
    if (U_.empty()) return;
    const int n = state_dim(), nv = disturbance_dim();
    if (!u_diag_.empty()) {
        for (std::int64_t r = 0; r < count * n; ++r)
            for (int k = 0; k < nv; ++k) B[r * nv + k] *= u_diag_[std::size_t(k)];
        return;
    }
    std::vector<double> row(static_cast<std::size_t>(nv), 0.0);
    for (std::int64_t r = 0; r < count * n; ++r) {  // row r of B times U (U lower triangular: l >= k)
        double* b = B + r * nv;
        for (int k = 0; k < nv; ++k) {
            double s = 0;
            for (int l = k; l < nv; ++l)
                if (U_[std::size_t(l) * nv + k] != 0) s += b[l] * U_[std::size_t(l) * nv + k];
            row[std::size_t(k)] = s;
        }
        for (int k = 0; k < nv; ++k) b[k] = row[std::size_t(k)];
    }
}

void WeightedSystem::measurement(double* c, const double* x, double t, std::int64_t count) const {
    inner_->measurement(c, x, t, count);
    if (W_.empty()) return;
    const int m = output_dim();
    if (!w_diag_.empty()) {
        for (std::int64_t p = 0; p < count; ++p)
            for (int j = 0; j < m; ++j) c[p * m + j] *= w_diag_[std::size_t(j)];
        return;
    }
    for (std::int64_t p = 0; p < count; ++p) lower_multiply(W_, m, c + p * m);
}

void WeightedSystem::output_difference(double* r, const double* y, const double* c, std::int64_t count) const {
    const int m = output_dim();
    if (W_.empty() || !inner_->wraps_outputs()) {  // no weight, or no angle: the plain difference, bit for bit
        if (W_.empty()) inner_->output_difference(r, y, c, count);
        else
            for (std::int64_t k = 0; k < count * m; ++k) r[k] = y[k] - c[k];
        return;
    }
    std::vector<double> yo(static_cast<std::size_t>(m)), co(static_cast<std::size_t>(m));
    for (std::int64_t p = 0; p < count; ++p) {  // back to the user's units, wrapped there, weighted again
        std::copy(y + p * m, y + (p + 1) * m, yo.begin());
        std::copy(c + p * m, c + (p + 1) * m, co.begin());
        lower_solve(W_, m, yo.data());
        lower_solve(W_, m, co.data());
        inner_->output_difference(r + p * m, yo.data(), co.data(), 1);
        lower_multiply(W_, m, r + p * m);
    }
}

void WeightedSystem::measurement_jacobian(double* H, const double* x, double t) const {
    inner_->measurement_jacobian(H, x, t);
    if (W_.empty()) return;
    const int m = output_dim(), n = state_dim();
    if (!w_diag_.empty()) {
        for (int j = 0; j < m; ++j)
            for (int k = 0; k < n; ++k) H[j * n + k] *= w_diag_[std::size_t(j)];
        return;
    }
    std::vector<double> col(static_cast<std::size_t>(m));
    for (int k = 0; k < n; ++k) {  // column k of W H
        for (int j = 0; j < m; ++j) col[std::size_t(j)] = H[j * n + k];
        lower_multiply(W_, m, col.data());
        for (int j = 0; j < m; ++j) H[j * n + k] = col[std::size_t(j)];
    }
}

}  // namespace hinf
