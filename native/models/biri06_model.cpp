// biri06_model.cpp: Biri, Arques, Michelin 2006, point lights with any phase function through
// the Gamma table of that phase (the exact difference where the table would cancel).
#include "homogeneous/biri06.h"
#include "models/registry.h"

namespace airlight {

namespace {

class Biri06 final : public FogModel {
  public:
    Biri06(const SceneDescription& scene, const BakeSettings& settings)
        : sigma_t_(scene.medium.sigma_t),
          phase_(scene.medium.phase),
          table_(shared_biri06_table(phase_, settings.table_nu, settings.table_nT)) {}
    double point_airlight(double Dsv, double cos_gamma, double Dvp) const override {
        return biri06_airlight(phase_, sigma_t_, Dsv, cos_gamma, Dvp, table_.get(), GammaEval::Table);
    }

  private:
    double sigma_t_;
    PhaseFunction phase_;
    std::shared_ptr<const Biri06Table> table_;
};

}  // namespace

ModelEntry biri06_entry() {
    ModelEntry e{ModelId::Biri06, "biri06", "Biri et al. 2006 airlight with the Gamma table of any phase function"};
    e.validate = [](const SceneDescription& scene, const BakeSettings&) { biri06_check_phase(scene.medium.phase); };
    e.make = [](const SceneDescription& scene, const BakeSettings& settings) -> std::unique_ptr<FogModel> {
        return std::make_unique<Biri06>(scene, settings);
    };
    return e;
}

}  // namespace airlight
