// baseline_model.cpp: the bar to beat, what Blender's Mist pass and OpenGL fog do:
// L = C_fog (1 - Tr) with one fog colour for the whole image (baseline_fog.h).
#include "homogeneous/baseline_fog.h"
#include "models/registry.h"

namespace airlight {

namespace {

// C_fog is the least-squares fit per channel to the physically based airlight of the same
// view (sun05's table model for isotropic fog, biri06 for any other phase; every light type
// included): the best a constant fog colour can do, so the baseline's reported error is a
// lower bound of any hand-picked colour's. 1 - Tr is 1 - e^{-sigma_t D} with D from the near
// plane to the first hit (1 for misses).
BakeResult bake_baseline(const SceneDescription& scene, const BakeSettings& settings, const ProgressFn& progress) {
    BakeSettings reference = settings;
    reference.model = phase_is_isotropic(scene.medium.phase) ? ModelId::Sun05Table : ModelId::Biri06;
    BakeResult result = bake(scene, reference, progress);
    const size_t n = size_t(result.width) * size_t(result.height);
    for (int c = 0; c < 3; ++c) {
        double num = 0.0, den = 0.0;
        for (size_t i = 0; i < n; ++i) {
            const double f = 1.0 - double(result.transmittance[3 * i + c]);
            num += double(result.airlight[3 * i + c]) * f;
            den += f * f;
        }
        const double C_fog = den > 0.0 ? num / den : 0.0;
        for (size_t i = 0; i < n; ++i)
            result.airlight[3 * i + c] = float(C_fog * (1.0 - double(result.transmittance[3 * i + c])));
    }
    return result;
}

}  // namespace

ModelEntry baseline_entry() {
    ModelEntry e{ModelId::Baseline, "baseline",
                 "Constant-colour fog (Blender Mist / OpenGL fog) with the best-fitting colour: the bar to beat"};
    e.bake = bake_baseline;
    return e;
}

}  // namespace airlight
