// Errors per estimate (sampling.errors_per_estimate, docs/method.md section 16.3): the gain variant's samples come in
// groups of G errors around one estimate, so the network and the storage run once per estimate. The group's first
// sample is the draw of an ungrouped run; the others share its estimate and time. The default is the largest of
// 4, 2, 1 that divides training.samples and training.batch.
#include <catch2/catch.hpp>
#include <string>

#include "config/run_config.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "net/network.hpp"
#include "train/gain_samples.hpp"

namespace {
using hinf::test::config_from_text;

std::string with_training(const std::string& lines) {
    std::string text = hinf::test::tiny_vdp_gain_config("0.5");
    const std::string from = "samples = 100\nbatch = 40\n";
    const std::size_t at = text.find(from);
    REQUIRE(at != std::string::npos);
    return text.replace(at, from.size(), lines);
}
}  // namespace

TEST_CASE("errors_per_estimate: the default divides the samples and the minibatch", "[gain][groups]") {
    CHECK(config_from_text(hinf::test::tiny_vdp_gain_config("0.5")).errors_per_estimate == 4);  // 100 and 40
    CHECK(config_from_text(with_training("samples = 60\nbatch = 30\n")).errors_per_estimate == 2);
    CHECK(config_from_text(with_training("samples = 63\nbatch = 21\n")).errors_per_estimate == 1);
    std::string five = hinf::test::tiny_vdp_gain_config("0.5");
    five.replace(five.find("trajectories = 3"), 16, "trajectories = 3\nerrors_per_estimate = 5");
    CHECK(config_from_text(five).errors_per_estimate == 5);
    std::string dissipative = hinf::test::tiny_vdp_gain_config("0.5");
    dissipative.replace(dissipative.find("variant = \"gain\""), 16, "variant = \"dissipative\"");
    CHECK(config_from_text(dissipative).errors_per_estimate == 1);
}

TEST_CASE("errors_per_estimate: a group shares its first sample's estimate and time, which an ungrouped run draws",
          "[gain][groups]") {
    const hinf::RunConfig grouped = config_from_text(hinf::test::tiny_vdp_gain_config("0.5"));
    hinf::RunConfig single = grouped;
    single.errors_per_estimate = 1;
    REQUIRE(grouped.errors_per_estimate == 4);
    const hinf::kern::GainSpec g4 = hinf::network_step_config(grouped).gain, g1 = hinf::network_step_config(single).gain;
    REQUIRE(g4.group == 4);
    REQUIRE(g1.group == 1);
    const hinf::GainPool pool = hinf::gain_pool_build(grouped);
    hinf::GainSamples a, b;
    const std::int64_t N = grouped.samples;
    hinf::gain_samples_build(&a, grouped, pool, g4, N, 3);
    hinf::gain_samples_build(&b, single, pool, g1, N, 3);
    const int n = grouped.n;
    int distinct = 0;
    for (std::int64_t i = 0; i < N; ++i) {
        const std::int64_t lead = i - i % 4;
        INFO("sample " << i);
        CHECK(a.t[i] == a.t[lead]);
        for (int j = 0; j < n; ++j) {
            CHECK(a.xt[i * n + j] == b.xt[i * n + j]);  // the errors are the same draws
            CHECK(a.xhat[i * n + j] == a.xhat[lead * n + j]);
            CHECK(a.z[i * n + j] == a.z[lead * n + j]);
            if (i == lead) {
                CHECK(a.x[i * n + j] == b.x[i * n + j]);
                CHECK(a.xhat[i * n + j] == b.xhat[i * n + j]);
            } else {
                CHECK(a.x[i * n + j] == a.xhat[i * n + j] + a.xt[i * n + j]);
            }
        }
        if (i == lead) CHECK(a.t[i] == b.t[i]);
        distinct += a.xhat[i * n] != b.xhat[i * n] ? 1 : 0;
    }
    CHECK(distinct > N / 2);  // the other members' estimates are not the ungrouped run's
}
