// models.cpp: the registry of fog models (names are the Python-facing identifiers).
#include "models/models.h"

#include <stdexcept>

namespace airlight {

const std::vector<ModelInfo>& model_registry() {
    static const std::vector<ModelInfo> registry{
        {ModelId::Sun05Table, "sun05", "Sun et al. 2005 airlight with the tabulated F (fast, default)"},
        {ModelId::Sun05Exact, "sun05_exact", "Sun et al. 2005 airlight with the exact F (slower reference)"},
        {ModelId::Quadrature, "quadrature",
         "Adaptive quadrature of the single-scattering integral, any phase function (slow reference)"},
        {ModelId::Biri06, "biri06", "Biri et al. 2006 airlight with the Gamma table of any phase function"},
        {ModelId::Baseline, "baseline",
         "Constant-colour fog (Blender Mist / OpenGL fog) with the best-fitting colour: the bar to beat"},
        {ModelId::Hoffman02, "hoffman02",
         "Hoffman & Preetham 2002 daylight: Rayleigh (1/lambda^4 per channel) + Mie haze lit by sun lamps only"},
        {ModelId::Pegoraro10, "pegoraro10",
         "Pegoraro et al. 2010 closed form (complex E1), any phase function as a Legendre polynomial"},
    };
    return registry;
}

const std::vector<ModelInfo>& kernel_models_pending_bake() {
    static const std::vector<ModelInfo> pending{};
    return pending;
}

ModelId model_from_name(const std::string& name) {
    std::string valid;
    for (const ModelInfo& info : model_registry()) {
        if (info.name == name) return info.id;
        valid += (valid.empty() ? "" : ", ") + ("'" + info.name + "'");
    }
    throw std::invalid_argument("unknown model '" + name + "'; valid models: " + valid);
}

}  // namespace airlight
