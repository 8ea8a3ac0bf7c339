// The DNN filters of seeds 000/001 as on-line filters: x^' = A(x^) + k(p, ...) (y - C(x^)) (seed 000
// eq. (19)) with p = dV/dx~ from a frozen network and a gain law (H-infinity: eq. (8)). Not the training.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "filters/filter.hpp"
#include "net/network.hpp"

namespace hinf {

/// What a gain law sees at one step. dc is C(x) - C(x^) in `oracle` mode (the papers' protocol) and the
/// innovation y - C(x^) in `measured` mode; B is B(x) (oracle) or B(x^) (measured).
struct DnnGainInput {
    const double* p = nullptr;   // [n] dV/dx~ at the network input
    const double* B = nullptr;   // [n x nv]
    const double* dc = nullptr;  // [m]
    int n = 0, nv = 0, m = 0;
};

/// A gain law k = k(p, B, dC) [n x m]. The H-infinity law is eq. (8); the mixed H2/H-infinity filter
/// (seed 001) adds its own law (and its own network) without touching the adapter.
class DnnGainLaw {
public:
    virtual ~DnnGainLaw() = default;
    virtual void gain(double* k, const DnnGainInput& in) const = 0;
    virtual std::unique_ptr<DnnGainLaw> clone() const = 0;
};

/// seed 000 eq. (8): k* = 2 rho p dC^T / |p|^2 (zero when p = 0), via filters/gain_law.hpp.
std::unique_ptr<DnnGainLaw> make_hinf_gain_law(double rho);

/// x~ estimated from the innovation e = y - C(x^): least squares through dC/dx at x^ (`measured` input).
void dnn_error_from_innovation(double* xt, const System& sys, const double* xhat, double t, const double* e);

/// The adapter: `oracle` feeds the network the true x~ = x - x^ and uses C(x) - C(x^) in the gain;
/// `measured` feeds it the innovation-based x~ and uses y - C(x^). The state update always uses y - C(x^).
std::unique_ptr<OnlineFilter> make_dnn_filter(const FilterModel& model, const FrozenNetwork& network,
                                              const DnnGainLaw& law, bool measured, const std::string& name);

/// "" when the DNN filter's `measured` mode sees every component of the error; else one warning line. Today's
/// variants (`paper`, `dissipative`) rebuild x~ from the innovation by least squares, so with fewer measurements
/// than states (m < n) every unmeasured component of x~ is zero to the filter. The one place this is decided:
/// a variant that handles m < n natively is listed in dnn.cpp's kMeasuredNative and gets "".
std::string dnn_measured_warning(const std::string& variant, int n, int m);
/// Variant gain: x^' = A(x^) + K(x^)(y - C(x^)) with K from the network at x^ alone (measured by construction).
/// Refuses (gain_filter_check_time) a network trained in the other time domain than model's system.
std::unique_ptr<OnlineFilter> make_gain_filter(const FilterModel& model, const FrozenNetwork& network,
                                               const std::string& name);
/// An ensemble of gain networks (trained on one model, e.g. with different training seeds): the same filter with
/// K(x^) = the mean of the networks' gains, summed in the order given (docs/method.md 16.15). One network is
/// make_gain_filter. Refuses a network of another variant or time domain.
std::unique_ptr<OnlineFilter> make_gain_ensemble_filter(const FilterModel& model,
                                                        const std::vector<const FrozenNetwork*>& networks,
                                                        const std::string& name);
/// One line when a gain network trained on a continuous-time system (an Euler-sampled filter) meets a config whose
/// system is discrete-time, or the other way round (a one-step predictor): its gain means another thing there.
void gain_filter_check_time(const FrozenNetwork& network, const System& here, const std::string& name);

}  // namespace hinf
