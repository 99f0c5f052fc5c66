// pegoraro10_model.cpp: Pegoraro, Schott, Parker 2010, the closed form of single scattering
// for a phase function given as a Legendre polynomial (Henyey-Greenstein truncated), for
// point and spot lights.
#include <stdexcept>
#include <string>

#include "homogeneous/pegoraro10.h"
#include "models/registry.h"

namespace airlight {

namespace {

class Pegoraro10 final : public FogModel {
  public:
    explicit Pegoraro10(const SceneDescription& scene)
        : sigma_t_(scene.medium.sigma_t),
          phase_(pegoraro_phase_auto(scene.medium.phase, kPegoraroPhaseTol, kPegoraroMaxOrder)) {}
    double point_airlight(double Dsv, double cos_gamma, double Dvp) const override {
        return pegoraro10_airlight(phase_, sigma_t_, Dsv, cos_gamma, Dvp);
    }
    SpotMethod spot_method() const override { return SpotMethod::ClosedForm; }

  private:
    double sigma_t_;
    PegoraroPhase phase_;
};

// HG lobes that order kPegoraroMaxOrder cannot represent (|g| >~ 0.79) would bake wrong
// (even negative) fog: refuse them.
void validate(const SceneDescription& scene, const BakeSettings&) {
    const PhaseFunction& phase = scene.medium.phase;
    if (phase.kind == PhaseKind::HenyeyGreenstein && pegoraro_hg_order(phase.g, kPegoraroPhaseTol, kPegoraroMaxOrder) < 0)
        throw std::invalid_argument("model 'pegoraro10': Henyey-Greenstein g = " + std::to_string(phase.g) +
                                    " needs a Legendre order above " + std::to_string(kPegoraroMaxOrder) +
                                    " (|g| <= 0.78 works); use 'biri06' or 'quadrature'");
}

}  // namespace

ModelEntry pegoraro10_entry() {
    ModelEntry e{ModelId::Pegoraro10, "pegoraro10",
                 "Pegoraro et al. 2010 closed form (complex E1), any phase function as a Legendre polynomial"};
    e.validate = validate;
    e.make = [](const SceneDescription& scene, const BakeSettings&) -> std::unique_ptr<FogModel> {
        return std::make_unique<Pegoraro10>(scene);
    };
    return e;
}

}  // namespace airlight
