// See open_loop.hpp.
#include "filters/open_loop.hpp"

namespace hinf {

namespace {

class OpenLoopFilter final : public OnlineFilter {
public:
    explicit OpenLoopFilter(const FilterModel& model) : model_(model), next_(model.system->state_dim()) {}
    std::string name() const override { return "open_loop"; }
    void reset(const FilterStart& start) override { xhat_ = start.xhat0; }
    FilterStatus step(const FilterInput& in) override {
        const int n = model_.system->state_dim();
        system_advance(*model_.system, next_.data(), xhat_.data(), nullptr, in.t, model_.dt);
        if (!filter_estimate_ok(next_.data(), n)) return FILTER_DIVERGED;
        xf_ = xhat_;  // no measurement update: x^_{k|k} = x^_{k|k-1}
        xhat_ = next_;
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    const double* filtered() const override { return xf_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<OpenLoopFilter>(*this); }

private:
    FilterModel model_;
    std::vector<double> xhat_, next_, xf_;
};

}  // namespace

std::unique_ptr<OnlineFilter> make_open_loop_filter(const FilterModel& model) {
    return std::make_unique<OpenLoopFilter>(model);
}

}  // namespace hinf
