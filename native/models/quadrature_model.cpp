// quadrature_model.cpp: the reference, adaptive Gauss-Kronrod quadrature of the single-
// scattering integral for every light type and phase function, and of Gaussian fog exactly.
#include <stdexcept>

#include "core/quadrature.h"
#include "homogeneous/biri06.h"
#include "models/registry.h"

namespace airlight {

namespace {

class Quadrature final : public FogModel {
  public:
    explicit Quadrature(const SceneDescription& scene)
        : sigma_t_(scene.medium.sigma_t), phase_(scene.medium.phase), isotropic_(phase_is_isotropic(phase_)) {}
    double point_airlight(double Dsv, double cos_gamma, double Dvp) const override {
        return isotropic_ ? sun05_airlight_quadrature(sigma_t_, Dsv, cos_gamma, Dvp, kQuadratureRelTol)
                          : phase_airlight_quadrature(phase_, sigma_t_, Dsv, cos_gamma, Dvp, kQuadratureRelTol);
    }
    SpotMethod spot_method() const override { return SpotMethod::Quadrature; }
    bool sun_quadrature() const override { return true; }
    GaussianMethod gaussian_method() const override { return GaussianMethod::Quadrature; }
    bool visibility_in_integrand() const override { return true; }

  private:
    double sigma_t_;
    PhaseFunction phase_;
    bool isotropic_;
};

void validate(const SceneDescription& scene, const BakeSettings&) {
    const Gaussians& gauss = scene.gaussians;
    if (gauss.empty()) return;
    if (!gauss.albedo.empty())
        throw std::invalid_argument("per-Gaussian colours are not supported by the 'quadrature' reference model; "
                                    "use 'sun05' or 'sun05_exact'");
    if (gauss.noise_amplitude != 0.0)
        throw std::invalid_argument("fog noise is not supported by the 'quadrature' reference model; set the noise "
                                    "amplitude to 0 or use 'sun05'");
}

}  // namespace

ModelEntry quadrature_entry() {
    ModelEntry e{ModelId::Quadrature, "quadrature",
                 "Adaptive quadrature of the single-scattering integral, any phase function (slow reference)"};
    e.validate = validate;
    e.make = [](const SceneDescription& scene, const BakeSettings&) -> std::unique_ptr<FogModel> {
        return std::make_unique<Quadrature>(scene);
    };
    return e;
}

}  // namespace airlight
