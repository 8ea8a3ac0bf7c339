// Bitwise comparison of two training runs' files (checkpoint arrays and every trajectory dataset),
// shared by the resume, thread-count and kill -9 tests.
#pragma once
#include <catch2/catch.hpp>
#include <string>
#include <vector>

#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"

namespace hinf::test {

template <typename T>
void require_same_checkpoint(const std::string& a, const std::string& b) {
    Checkpoint<T> A = ckpt_read<T>(a), B = ckpt_read<T>(b);
    CHECK(A.state.step == B.state.step);
    CHECK(bitwise_equal(A.net.theta, B.net.theta));
    CHECK(bitwise_equal(A.adam_m, B.adam_m));
    CHECK(bitwise_equal(A.adam_v, B.adam_v));
    CHECK(bitwise_equal(A.state.x, B.state.x));
    CHECK(bitwise_equal(A.state.xhat, B.state.xhat));
    CHECK(A.state.adam_step == B.state.adam_step);
}

inline void require_same_trajectory(const std::string& a, const std::string& b, bool mixed = false) {
    h5::Handle fa = h5::open_file(a, false), fb = h5::open_file(b, false);
    std::vector<std::string> names = {"t", "x", "xhat", "xtilde", "y", "gain", "v_star", "n_star", "p", "loss",
                                      "hjie_residual", "hjie_rel_residual_median", "hjie_rel_residual_p95",
                                      "hji_violation_fraction", "hji_positive_fraction", "cosine_mean"};
    if (mixed)
        for (const char* extra : {"hjie2_residual", "hjie2_rel_residual_median", "hjie2_rel_residual_p95",
                                  "hji2_violation_fraction", "consistency_gap", "consistency_gap_printed"})
            names.push_back(extra);
    for (const std::string& name : names) {
        INFO(name);
        std::vector<hsize_t> da, db;
        CHECK(bitwise_equal(h5::read_doubles(fa.get(), name, &da), h5::read_doubles(fb.get(), name, &db)));
        CHECK(da == db);
    }
}

}  // namespace hinf::test
