// sun05_model.cpp: Sun, Ramamoorthi, Narasimhan, Nayar 2005, isotropic point lights through
// the special function F: tabulated (model "sun05", the default) or exact ("sun05_exact").
#include <stdexcept>
#include <string>

#include "homogeneous/sun05.h"
#include "homogeneous/sun05_inline.h"
#include "models/registry.h"

namespace airlight {

namespace {

// The Sun 2005 models integrate the isotropic phase only: refuse rather than bake wrong fog.
void require_isotropic(const SceneDescription& scene, const char* name) {
    const PhaseFunction& phase = scene.medium.phase;
    if (!phase_is_isotropic(phase))
        throw std::invalid_argument(std::string("model '") + name + "' supports only the isotropic phase, got '" +
                                    phase_name(phase.kind) + "' (g = " + std::to_string(phase.g) +
                                    "); use 'biri06' or 'quadrature'");
}

class Sun05Table final : public FogModel {
  public:
    Sun05Table(const SceneDescription& scene, const BakeSettings& settings)
        : sigma_t_(scene.medium.sigma_t),
          table_(shared_special_F_table(settings.table_nu, settings.table_nT, settings.table_interp)) {}
    double point_airlight(double Dsv, double cos_gamma, double Dvp) const override {
        // inlined fast path, the same as sun05_airlight(..., FEval::Table)
        return sun05_airlight_table(table_->data().data(), table_->nu(), table_->nT(), sigma_t_, Dsv, cos_gamma, Dvp,
                                    0.0, table_->interp());
    }
    bool own_gaussian_background() const override { return false; }
    const SpecialFTable* f_table() const override { return table_.get(); }

  private:
    double sigma_t_;
    std::shared_ptr<const SpecialFTable> table_;
};

class Sun05Exact final : public FogModel {
  public:
    explicit Sun05Exact(const SceneDescription& scene) : sigma_t_(scene.medium.sigma_t) {}
    double point_airlight(double Dsv, double cos_gamma, double Dvp) const override {
        return sun05_airlight(sigma_t_, Dsv, cos_gamma, Dvp, nullptr, FEval::Exact);
    }
    bool own_gaussian_background() const override { return false; }

  private:
    double sigma_t_;
};

}  // namespace

ModelEntry sun05_table_entry() {
    ModelEntry e{ModelId::Sun05Table, "sun05", "Sun et al. 2005 airlight with the tabulated F (fast, default)"};
    e.validate = [](const SceneDescription& scene, const BakeSettings&) { require_isotropic(scene, "sun05"); };
    e.make = [](const SceneDescription& scene, const BakeSettings& settings) -> std::unique_ptr<FogModel> {
        return std::make_unique<Sun05Table>(scene, settings);
    };
    return e;
}

ModelEntry sun05_exact_entry() {
    ModelEntry e{ModelId::Sun05Exact, "sun05_exact", "Sun et al. 2005 airlight with the exact F (slower reference)"};
    e.validate = [](const SceneDescription& scene, const BakeSettings&) { require_isotropic(scene, "sun05_exact"); };
    e.make = [](const SceneDescription& scene, const BakeSettings&) -> std::unique_ptr<FogModel> {
        return std::make_unique<Sun05Exact>(scene);
    };
    return e;
}

}  // namespace airlight
